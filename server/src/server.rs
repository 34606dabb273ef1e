//! Building and running the server: gRPC (planner, health, reflection) plus
//! the metrics port, with graceful shutdown.

use std::{future::Future, net::SocketAddr, sync::Arc, time::Duration};

use mvgrasp_proto::v1::grasp_planner_server::GraspPlannerServer;
use tokio::{net::TcpListener, sync::oneshot, task::JoinHandle};
use tonic::{
    service::interceptor::InterceptedService,
    transport::{Server, server::TcpIncoming},
};

use crate::{
    admission::AdmissionLayer,
    backend::{self, LoadedNet},
    error::{Error, Result},
    metrics::{self, Metrics},
    security::{self, BearerAuth},
    service::{PlannerService, PlannerState, limit_status},
    settings::Settings,
};

/// HTTP/2 flow-control window per stream (bytes).
const HTTP2_WINDOW_BYTES: u32 = 8 << 20;

/// Largest HTTP/2 frame the server takes (bytes): a depth frame arrives in a
/// few frames instead of dozens of 16 KiB ones.
const HTTP2_MAX_FRAME_BYTES: u32 = 1 << 20;

/// A started server: its addresses and the handle that stops it.
#[derive(Debug)]
pub struct RunningServer {
    /// The bound gRPC address (useful with port 0).
    pub addr: SocketAddr,
    /// The bound metrics address, if any.
    pub metrics_addr: Option<SocketAddr>,
    /// The bound plaintext health address, if any.
    pub health_addr: Option<SocketAddr>,
    /// The shared state (model info, metrics).
    pub state: Arc<PlannerState>,
    stop: Option<oneshot::Sender<()>>,
    task: JoinHandle<Result<()>>,
}

impl RunningServer {
    /// Stops accepting calls, drains those in flight (up to the grace period), and waits.
    pub async fn shutdown(mut self) -> Result<()> {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        self.wait().await
    }

    /// Waits until the server task ends (after [`Self::shutdown`] or a transport failure).
    pub async fn wait(self) -> Result<()> {
        self.task
            .await
            .map_err(|e| Error::Internal(format!("server task: {e}")))?
    }
}

/// Loads the model named by `settings` and starts the server.
pub async fn start(settings: Settings) -> Result<RunningServer> {
    let model = settings.model.clone();
    let batch_views = settings.batching.max_batch_views;
    let net = tokio::task::spawn_blocking(move || backend::load(&model, batch_views))
        .await
        .map_err(|e| Error::Startup(format!("loading the model: {e}")))??;
    start_with_net(settings, net).await
}

/// Starts the server around an already loaded network (tests use fakes).
pub async fn start_with_net(settings: Settings, net: LoadedNet) -> Result<RunningServer> {
    settings.validate()?;
    let security = security::load(&settings.security)?;
    let metrics = Arc::new(Metrics::new()?);
    let listener = TcpListener::bind(settings.listen)
        .await
        .map_err(|e| Error::Startup(format!("listen {}: {e}", settings.listen)))?;
    let addr = listener
        .local_addr()
        .map_err(|e| Error::Startup(format!("listen address: {e}")))?;
    let (metrics_addr, metrics_task) = match settings.metrics_listen {
        Some(at) => {
            let metrics_listener = metrics::bind(at).await?;
            let bound = metrics_listener
                .local_addr()
                .map_err(|e| Error::Startup(format!("metrics address: {e}")))?;
            (
                Some(bound),
                Some(tokio::spawn(Arc::clone(&metrics).serve(metrics_listener))),
            )
        }
        None => (None, None),
    };
    let grace = Duration::from_secs_f64(settings.shutdown_grace_s);
    let max_message_bytes = settings.limits.max_message_bytes;
    tracing::info!(
        %addr,
        metrics = ?metrics_addr,
        backend = net.backend,
        model_version = %net.net.contract().model_version,
        "mvgrasp-server listening"
    );
    let health_listen = settings.security.health_listen;
    let admission = AdmissionLayer::new(settings.limits.max_in_flight, Arc::clone(&metrics));
    let auth = BearerAuth::new(security.token, metrics.unauthenticated.clone());
    let state = Arc::new(PlannerState::new(settings, net, metrics)?);

    let (health, health_service) = tonic_health::server::health_reporter();
    health.set_serving::<GraspPlannerServer<PlannerService>>().await;
    let reflection = tonic_reflection::server::Builder::configure()
        .register_encoded_file_descriptor_set(mvgrasp_proto::FILE_DESCRIPTOR_SET)
        .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
        .build_v1()
        .map_err(|e| Error::Startup(format!("reflection: {e}")))?;
    let planner = InterceptedService::new(
        GraspPlannerServer::new(PlannerService::new(Arc::clone(&state)))
            .max_decoding_message_size(max_message_bytes)
            .max_encoding_message_size(usize::MAX),
        auth,
    );
    let mut builder = Server::builder();
    if let Some(tls) = security.tls {
        builder = builder
            .tls_config(tls)
            .map_err(|e| Error::Startup(format!("security: TLS: {e}")))?;
    }
    // Probes that cannot speak TLS ask a plaintext port that serves health alone.
    let (health_addr, health_task) = match health_listen {
        Some(at) => {
            let listener = TcpListener::bind(at)
                .await
                .map_err(|e| Error::Startup(format!("health listen {at}: {e}")))?;
            let bound = listener
                .local_addr()
                .map_err(|e| Error::Startup(format!("health address: {e}")))?;
            let serve = Server::builder()
                .add_service(health_service.clone())
                .serve_with_incoming(TcpIncoming::from(listener));
            (Some(bound), Some(tokio::spawn(serve)))
        }
        None => (None, None),
    };

    let (stop, stopped) = oneshot::channel::<()>();
    let task = tokio::spawn(async move {
        let (drain_tx, drain_rx) = oneshot::channel::<()>();
        let signal = async move {
            let _ = stopped.await;
            tracing::info!(
                grace_s = grace.as_secs_f64(),
                "shutting down: draining calls in flight"
            );
            health
                .set_not_serving::<GraspPlannerServer<PlannerService>>()
                .await;
            let _ = drain_tx.send(());
        };
        // Frames are 0.5-4 MB: windows that hold a whole frame, HTTP/2
        // frames of up to 1 MiB to carry it, and no Nagle delay on the small
        // frames (window updates, responses).
        let serve = builder
            .initial_stream_window_size(HTTP2_WINDOW_BYTES)
            .initial_connection_window_size(2 * HTTP2_WINDOW_BYTES)
            .max_frame_size(HTTP2_MAX_FRAME_BYTES)
            .layer(tower::util::MapResponseLayer::new(rewrite_limit_status))
            .layer(admission)
            .add_service(health_service)
            .add_service(reflection)
            .add_service(planner)
            .serve_with_incoming_shutdown(TcpIncoming::from(listener).with_nodelay(Some(true)), signal);
        let result = drained(serve, drain_rx, grace).await;
        if let Some(task) = metrics_task {
            task.abort();
        }
        if let Some(task) = health_task {
            task.abort();
        }
        result
    });
    Ok(RunningServer {
        addr,
        metrics_addr,
        health_addr,
        state,
        stop: Some(stop),
        task,
    })
}

/// Runs `serve`; once `draining` fires, gives it `grace` to finish its calls.
async fn drained(
    serve: impl Future<Output = Result<(), tonic::transport::Error>>,
    draining: oneshot::Receiver<()>,
    grace: Duration,
) -> Result<()> {
    let serve = std::pin::pin!(serve);
    let deadline = async {
        if draining.await.is_ok() {
            tokio::time::sleep(grace).await;
        } else {
            std::future::pending::<()>().await;
        }
    };
    tokio::select! {
        result = serve => result.map_err(|e| Error::Internal(format!("transport: {e}"))),
        () = deadline => {
            tracing::warn!("grace period over: closing with calls still in flight");
            Ok(())
        }
    }
}

/// Unary calls answer an oversized request with the transport's OUT_OF_RANGE
/// in the headers; rewrite it to RESOURCE_EXHAUSTED, as this API promises.
fn rewrite_limit_status<B>(mut response: http::Response<B>) -> http::Response<B> {
    if let Some(status) = tonic::Status::from_header_map(response.headers()) {
        let mapped = limit_status(status.clone());
        if mapped.code() != status.code() {
            let _ = mapped.add_header(response.headers_mut());
        }
    }
    response
}

/// Resolves on SIGTERM or Ctrl-C.
pub async fn termination() {
    let ctrl_c = async {
        if tokio::signal::ctrl_c().await.is_err() {
            std::future::pending::<()>().await;
        }
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {},
        () = term => {},
    }
}
