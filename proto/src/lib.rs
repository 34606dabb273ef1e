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
