//! `mvgrasp-client`: a typed async client of the mvgrasp planner, the loaders
//! the `mvgrasp` CLI uses (depth PNG + camera JSON, PLY / PCD clouds), grasp
//! drawings, and the load generator behind `mvgrasp bench`.
//!
//! ```no_run
//! # async fn demo() -> Result<(), mvgrasp_client::Error> {
//! use mvgrasp_client::{PlannerClient, scene::SceneFiles};
//! let mut client = PlannerClient::connect("http://127.0.0.1:50051").await?;
//! let scene = SceneFiles::load_depth("samples/table6/depth.png".as_ref(), "samples/table6/camera.json".as_ref())?;
//! let response = client.plan(scene.request()).await?;
//! for g in &response.grasps {
//!     println!("object {} quality {:.2} width {:.3} m", g.object_id, g.quality, g.width_m);
//! }
//! # Ok(()) }
//! ```

pub mod bench;
pub mod cloud;
pub mod request;
pub mod scene;
pub mod viz;

use std::time::Duration;

use futures_util::Stream;
pub use mvgrasp_proto::v1 as pb;
use pb::grasp_planner_client::GraspPlannerClient;
use tonic::transport::{Channel, Endpoint};
use tonic_health::pb::{
    HealthCheckRequest, health_check_response::ServingStatus, health_client::HealthClient,
};

/// What a client call can fail with.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The server could not be reached.
    #[error("connecting to {endpoint}: {reason}")]
    Connect {
        /// The address tried.
        endpoint: String,
        /// Why it failed.
        reason: String,
    },
    /// The server answered with an error status.
    #[error("{}: {}", .0.code(), .0.message())]
    Rpc(#[from] tonic::Status),
    /// An input file is unreadable or malformed.
    #[error("{file}: {reason}")]
    Input {
        /// The file (and field, where known).
        file: String,
        /// What is wrong.
        reason: String,
    },
}

/// Shorthand used across the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Largest response accepted (debug views can be large).
const MAX_RESPONSE_BYTES: usize = 256 << 20;

/// A connection to one planner; cheap to clone (clones share the connection).
#[derive(Debug, Clone)]
pub struct PlannerClient {
    planner: GraspPlannerClient<Channel>,
    health: HealthClient<Channel>,
    timeout: Option<Duration>,
}

impl PlannerClient {
    /// Connects to `endpoint` (e.g. `http://127.0.0.1:50051`), failing after 5 s.
    pub async fn connect(endpoint: &str) -> Result<Self> {
        let connect_error = |reason: String| Error::Connect {
            endpoint: endpoint.to_owned(),
            reason,
        };
        let channel = Endpoint::from_shared(endpoint.to_owned())
            .map_err(|e| connect_error(e.to_string()))?
            .connect_timeout(Duration::from_secs(5))
            .tcp_nodelay(true)
            .initial_stream_window_size(8 << 20)
            .initial_connection_window_size(16 << 20)
            .connect()
            .await
            .map_err(|e| connect_error(format!("{e} ({:?})", std::error::Error::source(&e))))?;
        Ok(Self::from_channel(channel))
    }

    /// A client over an existing channel.
    pub fn from_channel(channel: Channel) -> Self {
        Self {
            planner: GraspPlannerClient::new(channel.clone())
                .max_decoding_message_size(MAX_RESPONSE_BYTES)
                .max_encoding_message_size(usize::MAX),
            health: HealthClient::new(channel),
            timeout: None,
        }
    }

    /// Sends a deadline (`grpc-timeout`) with every call.
    pub fn with_timeout(mut self, timeout: Duration) -> Self {
        self.timeout = Some(timeout);
        self
    }

    fn request<T>(&self, message: T) -> tonic::Request<T> {
        let mut request = tonic::Request::new(message);
        if let Some(t) = self.timeout {
            request.set_timeout(t);
        }
        request
    }

    /// Plans grasps for one frame.
    pub async fn plan(&mut self, request: pb::PlanGraspsRequest) -> Result<pb::PlanGraspsResponse> {
        let request = self.request(request);
        Ok(self.planner.plan_grasps(request).await?.into_inner())
    }

    /// Plans a stream of frames; answers come back in order.
    pub async fn stream(
        &mut self,
        requests: impl Stream<Item = pb::PlanGraspsRequest> + Send + 'static,
    ) -> Result<tonic::Streaming<pb::PlanGraspsResponse>> {
        Ok(self.planner.stream_grasps(requests).await?.into_inner())
    }

    /// The loaded model's contract and backend.
    pub async fn model_info(&mut self) -> Result<pb::ModelInfo> {
        let request = self.request(pb::GetModelInfoRequest {});
        Ok(self.planner.get_model_info(request).await?.into_inner())
    }

    /// The standard gRPC health status of the planner service.
    pub async fn health(&mut self) -> Result<ServingStatus> {
        let request = self.request(HealthCheckRequest {
            service: "mvgrasp.v1.GraspPlanner".to_owned(),
        });
        let status = self.health.check(request).await?.into_inner().status;
        Ok(ServingStatus::try_from(status).unwrap_or(ServingStatus::Unknown))
    }
}
