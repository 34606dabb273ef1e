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

    /// `message` encoded, then decoded from the received bytes: whether the
    /// decoded `field` equals the sent one and lies inside the received
    /// bytes (a view of them, not a copy), and whether a clone shares it.
    fn shared<M: Message + Default + Clone>(message: &M, field: fn(&M) -> &Bytes) -> (bool, bool, bool) {
        let received = Bytes::from(message.encode_to_vec());
        let decoded = M::decode(received.clone()).unwrap();
        let (bytes, whole) = (field(&decoded), received.as_ptr_range());
        let inside = whole.contains(&bytes.as_ptr()) && bytes.as_ptr_range().end <= whole.end;
        let cloned = decoded.clone();
        (
            bytes == field(message),
            inside,
            field(&cloned).as_ptr() == bytes.as_ptr(),
        )
    }

    #[test]
    fn frames_and_clouds_are_decoded_without_a_copy() {
        let depth = v1::DepthImage {
            width: 4,
            height: 2,
            data: Bytes::from(vec![7u8; 16]),
            ..Default::default()
        };
        assert_eq!(shared(&depth, |m| &m.data), (true, true, true));
        let cloud = v1::PointCloud {
            xyz: Bytes::from(vec![1u8; 24]),
            ..Default::default()
        };
        assert_eq!(shared(&cloud, |m| &m.xyz), (true, true, true));
    }
}
