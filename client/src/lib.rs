//! `mvgrasp-client`: a typed async client of the mvgrasp planner, the loaders
//! the `mvgrasp` CLI uses (depth PNG + camera JSON, PLY / PCD clouds), grasp
//! drawings, and the load generator behind `mvgrasp bench`. One client
//! spreads calls over several planner replicas (`"http://a:50051,http://b:50051"`
//! or `"dns:///planner:50051"`) and sends a call that met an unavailable
//! replica on to the others ([`replicas`]).
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
pub mod replicas;
pub mod request;
pub mod scene;
pub mod viz;

use std::{
    sync::Arc,
    time::{Duration, Instant},
};

use futures_util::Stream;
pub use mvgrasp_proto::v1 as pb;
use pb::grasp_planner_client::GraspPlannerClient;
pub use replicas::ReplicaStats;
use replicas::RoundRobin;
use tonic::{
    metadata::AsciiMetadataValue,
    transport::{Certificate, Channel, ClientTlsConfig, Endpoint, Identity},
};
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

/// How long past a call's deadline the client waits before its own timer
/// gives up (tonic's gives up at the deadline; this is the backstop).
const CLIENT_DEADLINE_GRACE: Duration = Duration::from_millis(250);

/// Largest response accepted (debug views can be large).
const MAX_RESPONSE_BYTES: usize = 256 << 20;

/// One planner replica's stubs (clones share its connection).
#[derive(Debug, Clone)]
struct Stubs {
    planner: GraspPlannerClient<Channel>,
    health: HealthClient<Channel>,
}

impl Stubs {
    fn new(channel: Channel) -> Self {
        Self {
            planner: GraspPlannerClient::new(channel.clone())
                .max_decoding_message_size(MAX_RESPONSE_BYTES)
                .max_encoding_message_size(usize::MAX),
            health: HealthClient::new(channel),
        }
    }
}

#[derive(Debug)]
struct Pool {
    endpoints: Vec<String>,
    stubs: Vec<Stubs>,
    turns: RoundRobin,
    /// `Bearer <token>`, sent with every call.
    authorization: Option<AsciiMetadataValue>,
}

/// A connection to the planner: one replica, or several with calls spread
/// round robin (see [`replicas`]); cheap to clone (clones share the
/// connections and the turn order).
#[derive(Debug, Clone)]
pub struct PlannerClient {
    pool: Arc<Pool>,
    timeout: Option<Duration>,
}

/// What a planner that asks for credentials needs (all optional: by default
/// plaintext and no token).
#[derive(Debug, Clone, Default)]
pub struct Credentials {
    /// PEM CA that signed the planner's certificate: calls go over TLS
    /// (`http://` addresses are taken as `https://`).
    pub tls_ca_pem: Option<Vec<u8>>,
    /// PEM certificate and key of this client, for mutual TLS.
    pub tls_identity_pem: Option<(Vec<u8>, Vec<u8>)>,
    /// The name the planner's certificate carries, when the address does
    /// not (e.g. an IP address from `dns:///`).
    pub tls_domain: Option<String>,
    /// Sent as `authorization: Bearer <token>` with every call.
    pub bearer_token: Option<String>,
}

impl Credentials {
    /// Credentials from files: CA, client certificate + key, token (each optional).
    pub fn from_files(
        ca: Option<&std::path::Path>,
        identity: Option<(&std::path::Path, &std::path::Path)>,
        domain: Option<String>,
        token: Option<&std::path::Path>,
    ) -> Result<Self> {
        let read = |path: &std::path::Path| {
            std::fs::read(path).map_err(|e| Error::Input {
                file: path.display().to_string(),
                reason: e.to_string(),
            })
        };
        let bearer_token = match token {
            Some(path) => Some(
                String::from_utf8(read(path)?)
                    .map_err(|_| Error::Input {
                        file: path.display().to_string(),
                        reason: "not UTF-8".into(),
                    })?
                    .trim()
                    .to_owned(),
            ),
            None => None,
        };
        Ok(Self {
            tls_ca_pem: ca.map(read).transpose()?,
            tls_identity_pem: match identity {
                Some((cert, key)) => Some((read(cert)?, read(key)?)),
                None => None,
            },
            tls_domain: domain,
            bearer_token,
        })
    }

    fn uses_tls(&self) -> bool {
        self.tls_ca_pem.is_some() || self.tls_identity_pem.is_some()
    }
}

fn endpoint(address: &str, credentials: &Credentials) -> Result<Endpoint> {
    let error = |reason: String| Error::Connect {
        endpoint: address.to_owned(),
        reason,
    };
    let address = match address.strip_prefix("http://") {
        Some(rest) if credentials.uses_tls() => format!("https://{rest}"),
        _ => address.to_owned(),
    };
    let mut endpoint = Endpoint::from_shared(address.clone())
        .map_err(|e| error(e.to_string()))?
        .connect_timeout(Duration::from_secs(5))
        .tcp_nodelay(true)
        .initial_stream_window_size(8 << 20)
        .initial_connection_window_size(16 << 20);
    if address.starts_with("https://") {
        let Some(ca) = &credentials.tls_ca_pem else {
            return Err(error(
                "TLS needs the CA that signed the planner's certificate (--tls-ca)".into(),
            ));
        };
        let mut tls = ClientTlsConfig::new().ca_certificate(Certificate::from_pem(ca));
        if let Some((cert, key)) = &credentials.tls_identity_pem {
            tls = tls.identity(Identity::from_pem(cert, key));
        }
        if let Some(domain) = &credentials.tls_domain {
            tls = tls.domain_name(domain.clone());
        }
        endpoint = endpoint.tls_config(tls).map_err(|e| error(e.to_string()))?;
    }
    Ok(endpoint)
}

/// What a failed call's status means, in gRPC's terms. tonic reports its own
/// deadline as CANCELLED ("Timeout expired"): that is DEADLINE_EXCEEDED. A
/// call the connection dropped before an answer (hyper's "operation was
/// canceled" when the server closed or sent GOAWAY first; UNKNOWN, or
/// INTERNAL "h2 protocol error" for a GOAWAY racing the call, with the
/// transport error as its source when the connection broke) is UNAVAILABLE,
/// as grpc-core reports it. `endpoint` and `timeout` go into the message.
fn normalized(status: tonic::Status, endpoint: &str, timeout: Option<Duration>) -> tonic::Status {
    let transport = || {
        std::error::Error::source(&status)
            .is_some_and(|e| e.downcast_ref::<tonic::transport::Error>().is_some())
    };
    match status.code() {
        tonic::Code::Cancelled if status.message() == "Timeout expired" => {
            tonic::Status::deadline_exceeded(format!(
                "no answer from {endpoint} within {:?}",
                timeout.unwrap_or_default()
            ))
        }
        tonic::Code::Cancelled => tonic::Status::unavailable(format!(
            "{endpoint} closed the connection before answering ({})",
            status.message()
        )),
        tonic::Code::Unknown | tonic::Code::Internal if transport() => tonic::Status::unavailable(format!(
            "the connection to {endpoint} broke under the call ({})",
            status.message()
        )),
        _ => status,
    }
}

/// Whether a failed call may be sent again to another replica: the replica
/// could not be reached, refused it while shutting down, or its connection
/// closed or broke under the call (all UNAVAILABLE once [`normalized`]).
/// `PlanGrasps` and the other unary calls are idempotent, so a call the lost
/// replica may have finished is safe to send again.
fn retryable(status: &tonic::Status) -> bool {
    status.code() == tonic::Code::Unavailable
}

impl PlannerClient {
    /// Connects to the planner at `endpoints`: one address
    /// (`http://127.0.0.1:50051`), several separated by commas, or
    /// `dns:///host:port` for every address the name resolves to; fails
    /// after 5 s when none can be reached. Replicas that cannot be reached
    /// now are tried again later.
    pub async fn connect(endpoints: &str) -> Result<Self> {
        Self::connect_with(endpoints, &Credentials::default()).await
    }

    /// [`Self::connect`] to a planner that asks for TLS, a client
    /// certificate or a bearer token.
    pub async fn connect_with(endpoints: &str, credentials: &Credentials) -> Result<Self> {
        Self::connect_all(&replicas::endpoints(endpoints).await?, credentials).await
    }

    /// Connects to each of `endpoints` (one replica each).
    pub async fn connect_all(endpoints: &[String], credentials: &Credentials) -> Result<Self> {
        let authorization = match &credentials.bearer_token {
            Some(token) => Some(format!("Bearer {token}").parse().map_err(|_| Error::Input {
                file: "bearer token".into(),
                reason: "not a valid header value".into(),
            })?),
            None => None,
        };
        let endpoints: Vec<Endpoint> = endpoints
            .iter()
            .map(|a| endpoint(a, credentials))
            .collect::<Result<_>>()?;
        let attempts = futures_util::future::join_all(endpoints.iter().map(Endpoint::connect)).await;
        let mut reasons = Vec::new();
        let mut down = Vec::new();
        let mut stubs = Vec::new();
        for (i, (e, attempt)) in endpoints.iter().zip(attempts).enumerate() {
            let channel = match attempt {
                Ok(channel) => channel,
                Err(err) => {
                    reasons.push(format!(
                        "{}: {err} ({:?})",
                        e.uri(),
                        std::error::Error::source(&err)
                    ));
                    down.push(i);
                    e.connect_lazy()
                }
            };
            stubs.push(Stubs::new(channel));
        }
        let names: Vec<String> = endpoints.iter().map(|e| e.uri().to_string()).collect();
        if stubs.is_empty() || down.len() == stubs.len() {
            return Err(Error::Connect {
                endpoint: names.join(","),
                reason: reasons.join("; "),
            });
        }
        for reason in &reasons {
            tracing::warn!(%reason, "planner replica unreachable; calls go to the others");
        }
        Ok(Self {
            pool: Arc::new(Pool {
                turns: RoundRobin::new(stubs.len(), &down),
                endpoints: names,
                stubs,
                authorization,
            }),
            timeout: None,
        })
    }

    /// A client over an existing channel (one replica).
    pub fn from_channel(channel: Channel) -> Self {
        Self {
            pool: Arc::new(Pool {
                endpoints: vec!["channel".to_owned()],
                stubs: vec![Stubs::new(channel)],
                turns: RoundRobin::new(1, &[]),
                authorization: None,
            }),
            timeout: None,
        }
    }

    /// Sends a deadline (`grpc-timeout`) with every call; a retry gets what
    /// is left of it.
    pub fn with_timeout(mut self, timeout: Duration) -> Self {
        self.timeout = Some(timeout);
        self
    }

    /// What each replica has done so far.
    pub fn replicas(&self) -> Vec<ReplicaStats> {
        self.pool.turns.stats(&self.pool.endpoints)
    }

    /// Calls sent a second time because the first replica was unavailable.
    pub fn retries(&self) -> u64 {
        self.pool.turns.retries()
    }

    fn request<T>(&self, message: T, timeout: Option<Duration>) -> tonic::Request<T> {
        let mut request = tonic::Request::new(message);
        if let Some(t) = timeout {
            request.set_timeout(t);
        }
        if let Some(a) = &self.pool.authorization {
            request.metadata_mut().insert("authorization", a.clone());
        }
        request
    }

    /// Sends `message` through `call` to the next replica; while the answer
    /// is UNAVAILABLE (or a broken connection), to the other replicas in
    /// turn, each once, within the deadline. Two replicas can fail at once
    /// and one client learns of each failure only by meeting it, so one
    /// retry is not enough for no call to be lost. The message is copied
    /// only while another replica may still get it.
    async fn unary<M, R, F, Fut>(&self, message: M, call: F) -> Result<R>
    where
        M: Clone,
        F: Fn(Stubs, tonic::Request<M>) -> Fut,
        Fut: Future<Output = Result<tonic::Response<R>, tonic::Status>>,
    {
        let turns = &self.pool.turns;
        let started = Instant::now();
        let mut tried = vec![false; turns.len()];
        let mut timeout = self.timeout;
        let mut replica = turns.pick();
        loop {
            tried[replica] = true;
            if tried.iter().all(|&t| t) {
                // No replica left to send it on to: its answer is the call's.
                return Ok(self.attempt(replica, message, timeout, &call).await?);
            }
            let status = match self.attempt(replica, message.clone(), timeout, &call).await {
                Ok(answer) => return Ok(answer),
                Err(status) => status,
            };
            if !retryable(&status) {
                return Err(status.into());
            }
            if let Some(t) = self.timeout {
                match t.checked_sub(started.elapsed()) {
                    Some(left) if !left.is_zero() => timeout = Some(left),
                    _ => return Err(status.into()),
                }
            }
            let Some(next) = turns.pick_untried(&tried) else {
                return Err(status.into());
            };
            turns.count_retry();
            tracing::debug!(from = %self.pool.endpoints[replica], to = %self.pool.endpoints[next], %status, "retrying on another replica");
            replica = next;
        }
    }

    /// One try of `call` on `replica` within `timeout`, counted in its stats.
    async fn attempt<M, R, F, Fut>(
        &self,
        replica: usize,
        message: M,
        timeout: Option<Duration>,
        call: &F,
    ) -> Result<R, tonic::Status>
    where
        F: Fn(Stubs, tonic::Request<M>) -> Fut,
        Fut: Future<Output = Result<tonic::Response<R>, tonic::Status>>,
    {
        let request = self.request(message, timeout);
        let answer = self
            .within(timeout, replica, call(self.pool.stubs[replica].clone(), request))
            .await;
        let turns = &self.pool.turns;
        match &answer {
            Err(status) if retryable(status) => turns.mark_unavailable(replica),
            _ => turns.mark_answered(replica),
        }
        answer.map(tonic::Response::into_inner)
    }

    /// `call` within `timeout`, its failure [`normalized`]. tonic gives up at
    /// the deadline itself; the tokio timer is the backstop for a planner
    /// that answers nothing (a stopped process, a dead host behind a live
    /// connection).
    async fn within<R>(
        &self,
        timeout: Option<Duration>,
        replica: usize,
        call: impl Future<Output = Result<tonic::Response<R>, tonic::Status>>,
    ) -> Result<tonic::Response<R>, tonic::Status> {
        let endpoint = &self.pool.endpoints[replica];
        let answer = match timeout {
            None => call.await,
            Some(t) => tokio::time::timeout(t + CLIENT_DEADLINE_GRACE, call)
                .await
                .unwrap_or_else(|_| Err(tonic::Status::cancelled("Timeout expired"))),
        };
        answer.map_err(|status| normalized(status, endpoint, timeout))
    }

    /// Plans grasps for one frame.
    pub async fn plan(&mut self, request: pb::PlanGraspsRequest) -> Result<pb::PlanGraspsResponse> {
        self.unary(request, |mut s, r| async move { s.planner.plan_grasps(r).await })
            .await
    }

    /// Plans a stream of frames on one replica (the next in turn); answers
    /// come back in order. A stream is not retried elsewhere.
    pub async fn stream(
        &mut self,
        requests: impl Stream<Item = pb::PlanGraspsRequest> + Send + 'static,
    ) -> Result<tonic::Streaming<pb::PlanGraspsResponse>> {
        let turns = &self.pool.turns;
        let i = turns.pick();
        let mut stubs = self.pool.stubs[i].clone();
        match stubs.planner.stream_grasps(self.request(requests, None)).await {
            Ok(response) => {
                turns.mark_answered(i);
                Ok(response.into_inner())
            }
            Err(status) => {
                let status = normalized(status, &self.pool.endpoints[i], None);
                if retryable(&status) {
                    turns.mark_unavailable(i);
                }
                Err(status.into())
            }
        }
    }

    /// The loaded model's contract and backend.
    pub async fn model_info(&mut self) -> Result<pb::ModelInfo> {
        self.unary(pb::GetModelInfoRequest {}, |mut s, r| async move {
            s.planner.get_model_info(r).await
        })
        .await
    }

    /// The standard gRPC health status of the planner service (of the
    /// replica that answered).
    pub async fn health(&mut self) -> Result<ServingStatus> {
        let ask = HealthCheckRequest {
            service: "mvgrasp.v1.GraspPlanner".to_owned(),
        };
        let status = self
            .unary(ask, |mut s, r| async move { s.health.check(r).await })
            .await?
            .status;
        Ok(ServingStatus::try_from(status).unwrap_or(ServingStatus::Unknown))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_unavailable_and_broken_connections_are_retried() {
        let t = Some(Duration::from_millis(5));
        let seen = |status| normalized(status, "http://a:1", t);
        let deadline = seen(tonic::Status::cancelled("Timeout expired"));
        assert_eq!(deadline.code(), tonic::Code::DeadlineExceeded);
        assert!(deadline.message().contains("http://a:1") && deadline.message().contains("5ms"));
        assert!(!retryable(&deadline));
        let dropped = seen(tonic::Status::cancelled("operation was canceled"));
        assert_eq!(dropped.code(), tonic::Code::Unavailable, "{dropped}");
        assert!(retryable(&dropped));
        assert!(retryable(&seen(tonic::Status::unavailable("shutting down"))));
        for code in [
            tonic::Code::InvalidArgument,
            tonic::Code::DeadlineExceeded,
            tonic::Code::ResourceExhausted,
            tonic::Code::Internal,
            tonic::Code::Unknown,
        ] {
            let status = seen(tonic::Status::new(code, "refused"));
            assert_eq!(status.code(), code);
            assert!(!retryable(&status), "{code:?}");
        }
    }
}
