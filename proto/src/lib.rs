//! The mvgrasp gRPC API (`mvgrasp.v1`), generated from
//! `proto/mvgrasp/v1/grasp_planner.proto` at build time.
//!
//! This is the one place prost types live: the server and the client convert
//! them to and from `mvgrasp-core` types at their edges.
//!
//! ```
//! use mvgrasp_proto::v1::{ViewPolicy, PlanGraspsRequest};
//! let request = PlanGraspsRequest { view_policy: ViewPolicy::Entropy as i32, ..Default::default() };
//! assert_eq!(request.max_grasps, 0);
//! ```

/// `mvgrasp.v1`: messages, the `GraspPlanner` client and server.
#[allow(missing_docs, clippy::all, clippy::pedantic, unused_qualifications)]
pub mod v1 {
    tonic::include_proto!("mvgrasp.v1");
}

/// The encoded `FileDescriptorSet` of the API, for server reflection.
pub const FILE_DESCRIPTOR_SET: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/mvgrasp_descriptor.bin"));

#[cfg(test)]
mod tests {
    use prost::Message;
    use prost::bytes::Bytes;

    use super::v1;

    /// Whether `part` lies inside `whole`'s memory.
    fn inside(part: &[u8], whole: &[u8]) -> bool {
        let range = whole.as_ptr_range();
        range.contains(&part.as_ptr()) && part.as_ptr_range().end <= range.end
    }

    #[test]
    fn frames_and_clouds_are_decoded_without_a_copy() {
        let depth = v1::DepthImage {
            width: 4,
            height: 2,
            data: Bytes::from(vec![7u8; 16]),
            ..Default::default()
        };
        let received = Bytes::from(depth.encode_to_vec());
        let decoded = v1::DepthImage::decode(received.clone()).unwrap();
        assert_eq!(decoded.data, depth.data);
        assert!(
            inside(&decoded.data, &received),
            "the frame was copied out of the message"
        );
        // A clone shares the bytes too.
        let cloned = decoded.clone();
        assert_eq!(cloned.data.as_ptr(), decoded.data.as_ptr());

        let cloud = v1::PointCloud {
            xyz: Bytes::from(vec![1u8; 24]),
            ..Default::default()
        };
        let received = Bytes::from(cloud.encode_to_vec());
        let decoded = v1::PointCloud::decode(received.clone()).unwrap();
        assert_eq!(decoded.xyz, cloud.xyz);
        assert!(
            inside(&decoded.xyz, &received),
            "the cloud was copied out of the message"
        );
    }
}
