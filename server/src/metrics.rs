//! Prometheus metrics, owned by the server state and served on their own port.

use std::{net::SocketAddr, sync::Arc};

use prometheus::{
    Encoder, Histogram, HistogramOpts, HistogramVec, IntCounter, IntCounterVec, IntGauge, IntGaugeVec, Opts,
    Registry, TextEncoder,
};
use tokio::{
    io::{AsyncReadExt, AsyncWriteExt},
    net::TcpListener,
};

use crate::error::{Error, Result};

/// Every metric the server exports (prefix `mvgrasp_`).
#[derive(Debug, Clone)]
pub struct Metrics {
    registry: Registry,
    /// Finished calls by method and gRPC status code.
    pub requests: IntCounterVec,
    /// Call latency by method (s).
    pub request_seconds: HistogramVec,
    /// Time per pipeline stage (s).
    pub stage_seconds: HistogramVec,
    /// Views per network call.
    pub batch_views: Histogram,
    /// Requests per network call.
    pub batch_requests: Histogram,
    /// Network calls run on the lone session (the only call in flight,
    /// `model.lone_call_threads`).
    pub lone_network_calls: IntCounter,
    /// Time a batch spends in the network (views in, the run, maps out), by
    /// session (`lone` or `shared`), in s: the stage `inference` of a call
    /// is this plus its wait in the queue and the hand-overs.
    pub network_seconds: HistogramVec,
    /// Views waiting for the network.
    pub queued_views: IntGauge,
    /// Calls being served.
    pub in_flight: IntGauge,
    /// Objects found per planned frame.
    pub objects_per_request: Histogram,
    /// Grasps returned per planned frame.
    pub grasps_per_request: Histogram,
    /// Grasps dropped because the hand would hit an observed point or the table.
    pub grasps_refused_for_collision: IntCounter,
    /// Grasps returned last because their pads reach past the image border.
    pub grasps_out_of_view: IntCounter,
    /// Grasps turned about their approach to square them to the surfaces
    /// their pads meet.
    pub grasps_turned_square: IntCounter,
    /// Grasps returned after those as planned because they were turned
    /// about their approach away from a neighbour the hand would have hit.
    pub grasps_turned_away: IntCounter,
    /// Grasps dropped because their approach lay outside the request's cone.
    pub grasps_outside_approach_cone: IntCounter,
    /// Grasps dropped because the request's arm reach did not reach them.
    pub grasps_out_of_reach: IntCounter,
    /// Candidate grasps refused per object, by cause (`table`, `neighbour`,
    /// `own_points`, `outside_approach_cone`, `out_of_reach`, `too_wide`,
    /// `no_pose`), as in the
    /// answer's `refused`.
    pub candidates_refused: IntCounterVec,
    /// Queued work dropped before inference, by reason.
    pub dropped: IntCounterVec,
    /// Views the queue takes before calls are refused (the setting).
    pub queued_views_limit: IntGauge,
    /// Calls served at once before more are refused (the setting).
    pub in_flight_limit: IntGauge,
    /// 1, labelled with the loaded model and backend.
    pub model_info: IntGaugeVec,
    /// Planning calls refused for a missing or wrong bearer token.
    pub unauthenticated: IntCounter,
}

/// The `cause` label values of `mvgrasp_grasp_candidates_refused_total`.
pub const REFUSAL_CAUSES: [&str; 7] = mvgrasp_core::ObjectRefusals::CAUSES;

/// The `session` label values of `mvgrasp_network_duration_seconds`.
pub const NETWORK_SESSIONS: [&str; 2] = ["lone", "shared"];

/// The `reason` label values of `mvgrasp_dropped_views_total`.
pub const DROP_REASONS: [&str; 3] = ["queue_full", "caller_gone", "deadline"];

fn metric_error(e: prometheus::Error) -> Error {
    Error::Startup(format!("metrics: {e}"))
}

impl Metrics {
    /// Registers every metric in a fresh registry.
    pub fn new() -> Result<Self> {
        let registry = Registry::new_custom(Some("mvgrasp".into()), None).map_err(metric_error)?;
        let stage_buckets = vec![
            1e-4, 2.5e-4, 5e-4, 1e-3, 2.5e-3, 5e-3, 1e-2, 2.5e-2, 5e-2, 0.1, 0.25, 0.5, 1.0,
        ];
        let count_buckets = vec![
            1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 32.0, 48.0, 64.0, 128.0, 256.0,
        ];
        let histogram = |name: &str, help: &str, buckets: &Vec<f64>, labels: &[&str]| {
            HistogramVec::new(HistogramOpts::new(name, help).buckets(buckets.clone()), labels)
        };
        let counts = |name: &str, help: &str| {
            Histogram::with_opts(HistogramOpts::new(name, help).buckets(count_buckets.clone()))
                .map_err(metric_error)
        };
        let m = Self {
            requests: IntCounterVec::new(
                Opts::new("requests_total", "Finished calls by method and gRPC status code"),
                &["method", "code"],
            )
            .map_err(metric_error)?,
            request_seconds: histogram(
                "request_duration_seconds",
                "Call latency inside the server",
                &stage_buckets,
                &["method"],
            )
            .map_err(metric_error)?,
            stage_seconds: histogram(
                "stage_duration_seconds",
                "Time per pipeline stage",
                &stage_buckets,
                &["stage"],
            )
            .map_err(metric_error)?,
            batch_views: counts("batch_views", "Views per network call")?,
            batch_requests: counts("batch_requests", "Requests per network call")?,
            queued_views: IntGauge::new("queued_views", "Views waiting for the network")
                .map_err(metric_error)?,
            in_flight: IntGauge::new("in_flight_requests", "Calls being served").map_err(metric_error)?,
            objects_per_request: counts("objects_per_request", "Objects found per planned frame")?,
            grasps_per_request: counts("grasps_per_request", "Grasps returned per planned frame")?,
            grasps_refused_for_collision: IntCounter::new(
                "grasps_refused_for_collision_total",
                "Grasps dropped because the hand would hit an observed point or the table",
            )
            .map_err(metric_error)?,
            grasps_out_of_view: IntCounter::new(
                "grasps_out_of_view_total",
                "Grasps returned last because their pads reach past the image border",
            )
            .map_err(metric_error)?,
            grasps_turned_square: IntCounter::new(
                "grasps_turned_square_total",
                "Grasps turned about their approach to square them to the surfaces their pads meet",
            )
            .map_err(metric_error)?,
            grasps_turned_away: IntCounter::new(
                "grasps_turned_away_total",
                "Grasps returned after those as planned, turned about their approach until the hand passed",
            )
            .map_err(metric_error)?,
            grasps_outside_approach_cone: IntCounter::new(
                "grasps_outside_approach_cone_total",
                "Grasps dropped before ranking because their approach lay outside the request's approach cone",
            )
            .map_err(metric_error)?,
            grasps_out_of_reach: IntCounter::new(
                "grasps_out_of_reach_total",
                "Grasps dropped before ranking because the request's arm reach did not reach them",
            )
            .map_err(metric_error)?,
            candidates_refused: IntCounterVec::new(
                Opts::new(
                    "grasp_candidates_refused_total",
                    "Candidate grasps refused per object, by cause (as in the answer's refused)",
                ),
                &["cause"],
            )
            .map_err(metric_error)?,
            dropped: IntCounterVec::new(
                Opts::new("dropped_views_total", "Queued views dropped before inference"),
                &["reason"],
            )
            .map_err(metric_error)?,
            queued_views_limit: IntGauge::new(
                "queued_views_limit",
                "Views the queue takes before calls are refused",
            )
            .map_err(metric_error)?,
            in_flight_limit: IntGauge::new(
                "in_flight_requests_limit",
                "Calls served at once before more are refused",
            )
            .map_err(metric_error)?,
            model_info: IntGaugeVec::new(
                Opts::new("model_info", "The loaded model (value 1)"),
                &["model_version", "data_version", "backend", "input_size_px"],
            )
            .map_err(metric_error)?,
            unauthenticated: IntCounter::new(
                "unauthenticated_calls_total",
                "Planning calls refused for a missing or wrong bearer token",
            )
            .map_err(metric_error)?,
            lone_network_calls: IntCounter::new(
                "lone_network_calls_total",
                "Network calls run on the lone session (the only call in flight)",
            )
            .map_err(metric_error)?,
            network_seconds: histogram(
                "network_duration_seconds",
                "Time a batch spends in the network, by session",
                &stage_buckets,
                &["session"],
            )
            .map_err(metric_error)?,
            registry,
        };
        let collectors: [Box<dyn prometheus::core::Collector>; 23] = [
            Box::new(m.requests.clone()),
            Box::new(m.request_seconds.clone()),
            Box::new(m.stage_seconds.clone()),
            Box::new(m.batch_views.clone()),
            Box::new(m.batch_requests.clone()),
            Box::new(m.queued_views.clone()),
            Box::new(m.in_flight.clone()),
            Box::new(m.objects_per_request.clone()),
            Box::new(m.grasps_per_request.clone()),
            Box::new(m.grasps_refused_for_collision.clone()),
            Box::new(m.grasps_out_of_view.clone()),
            Box::new(m.grasps_turned_square.clone()),
            Box::new(m.grasps_turned_away.clone()),
            Box::new(m.grasps_outside_approach_cone.clone()),
            Box::new(m.grasps_out_of_reach.clone()),
            Box::new(m.candidates_refused.clone()),
            Box::new(m.dropped.clone()),
            Box::new(m.queued_views_limit.clone()),
            Box::new(m.in_flight_limit.clone()),
            Box::new(m.model_info.clone()),
            Box::new(m.unauthenticated.clone()),
            Box::new(m.lone_network_calls.clone()),
            Box::new(m.network_seconds.clone()),
        ];
        for c in collectors {
            m.registry.register(c).map_err(metric_error)?;
        }
        // Every label value at 0 from the start: a series that appears only
        // after its first event breaks rates and dashboards until then.
        for cause in REFUSAL_CAUSES {
            m.candidates_refused.with_label_values(&[cause]);
        }
        for reason in DROP_REASONS {
            m.dropped.with_label_values(&[reason]);
        }
        for session in NETWORK_SESSIONS {
            m.network_seconds.with_label_values(&[session]);
        }
        for method in ["PlanGrasps", "StreamGrasps", "GetModelInfo"] {
            m.requests.with_label_values(&[method, "Ok"]);
            m.request_seconds.with_label_values(&[method]);
        }
        Ok(m)
    }

    /// The text exposition of every metric.
    pub fn render(&self) -> String {
        let mut out = Vec::new();
        // Encoding into a Vec cannot fail on I/O; a failure would be a bug in a
        // metric's labels, and an empty page is the honest answer then.
        if let Err(e) = TextEncoder::new().encode(&self.registry.gather(), &mut out) {
            tracing::error!(error = %e, "encoding metrics");
        }
        String::from_utf8_lossy(&out).into_owned()
    }

    /// Serves `GET /metrics` (anything else: 404) on `listener` until the task is dropped.
    pub async fn serve(self: Arc<Self>, listener: TcpListener) {
        loop {
            let Ok((mut stream, _)) = listener.accept().await else {
                // E.g. out of file descriptors: back off instead of spinning.
                tokio::time::sleep(std::time::Duration::from_millis(50)).await;
                continue;
            };
            let metrics = Arc::clone(&self);
            tokio::spawn(async move {
                let mut head = vec![0u8; 2048];
                let mut read = 0;
                // Read the request head (bounded, with a timeout).
                let complete = tokio::time::timeout(std::time::Duration::from_secs(5), async {
                    while read < head.len() {
                        match stream.read(&mut head[read..]).await {
                            Ok(0) | Err(_) => return false,
                            Ok(n) => read += n,
                        }
                        if head[..read].windows(4).any(|w| w == b"\r\n\r\n") {
                            return true;
                        }
                    }
                    false
                })
                .await
                .unwrap_or(false);
                let line = String::from_utf8_lossy(&head[..read]);
                let (status, body) = if !complete {
                    ("400 Bad Request", String::new())
                } else if line.starts_with("GET /metrics ") || line.starts_with("GET /metrics?") {
                    ("200 OK", metrics.render())
                } else {
                    ("404 Not Found", "try /metrics\n".to_owned())
                };
                let response = format!(
                    "HTTP/1.1 {status}\r\nContent-Type: text/plain; version=0.0.4\r\nContent-Length: {}\r\n\
                     Connection: close\r\n\r\n{body}",
                    body.len()
                );
                let _ = stream.write_all(response.as_bytes()).await;
                let _ = stream.shutdown().await;
            });
        }
    }
}

/// Binds the metrics port.
pub async fn bind(addr: SocketAddr) -> Result<TcpListener> {
    TcpListener::bind(addr)
        .await
        .map_err(|e| Error::Startup(format!("metrics listen {addr}: {e}")))
}
