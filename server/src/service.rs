//! The `GraspPlanner` gRPC service: validate, convert, plan, convert back.

use std::{
    pin::Pin,
    sync::Arc,
    time::{Duration, Instant},
};

use futures_util::{Stream, StreamExt};
use mvgrasp_core::{Finished, GraspMaps, Planner};
use mvgrasp_proto::v1::{self as pb, grasp_planner_server::GraspPlanner};
use tokio::sync::Semaphore;
use tonic::{Code, Request, Response, Status, Streaming};
use tracing::Instrument;

use crate::{
    backend::LoadedNet,
    batcher::{BatchLimits, Batcher},
    convert,
    error::{Error, Result},
    metrics::Metrics,
    settings::Settings,
};

/// Frames of one stream planned at once (answers still go out in order).
const STREAM_PIPELINE_DEPTH: usize = 2;

/// Everything a call needs; shared by all calls.
#[derive(Debug)]
pub struct PlannerState {
    planner: Planner,
    batcher: Batcher,
    metrics: Arc<Metrics>,
    settings: Settings,
    info: pb::ModelInfo,
    cpu: Arc<Semaphore>,
}

impl PlannerState {
    /// Starts the inference worker for `net` and builds the pipeline for its contract.
    pub fn new(settings: Settings, net: LoadedNet, metrics: Arc<Metrics>) -> Result<Self> {
        let contract = net.net.contract().clone();
        let config = settings
            .planner_config()
            .map_err(|e| Error::Startup(format!("views.axes: {e}")))?;
        let planner =
            Planner::new(config, contract.clone()).map_err(|e| Error::Startup(format!("pipeline: {e}")))?;
        let info = convert::model_info(&contract, net.backend, settings.batching.max_batch_views);
        metrics
            .model_info
            .with_label_values(&[
                contract.model_version.as_str(),
                contract.data_version.as_str(),
                net.backend,
                &contract.input_size_px.to_string(),
            ])
            .set(1);
        let limits = BatchLimits {
            max_batch_views: settings.batching.max_batch_views,
            max_wait: Duration::from_secs_f64(settings.batching.max_wait_ms / 1e3),
            max_queued_views: settings.batching.max_queued_views,
        };
        metrics.queued_views_limit.set(limits.max_queued_views as i64);
        metrics.in_flight_limit.set(settings.limits.max_in_flight as i64);
        let nets = std::iter::once(net.net).chain(net.more).collect();
        let batcher = Batcher::spawn(nets, net.lone, limits, Arc::clone(&metrics))?;
        let cpu = Arc::new(Semaphore::new(settings.cpu_workers()));
        Ok(Self {
            planner,
            batcher,
            metrics,
            settings,
            info,
            cpu,
        })
    }

    /// The model info that `GetModelInfo` returns.
    pub fn info(&self) -> &pb::ModelInfo {
        &self.info
    }

    /// Plans one frame: CPU stages on the blocking pool, the network through the batcher.
    pub async fn plan(
        self: &Arc<Self>,
        request: pb::PlanGraspsRequest,
        deadline: Option<Instant>,
    ) -> Result<pb::PlanGraspsResponse> {
        let started = Instant::now();
        let request = Arc::new(request);
        let check_deadline = |stage: &'static str| match deadline {
            Some(d) if Instant::now() >= d => Err(Error::DeadlineExceeded { stage }),
            _ => Ok(()),
        };

        let preparing = self.batcher.preparing();
        let permit = self.cpu_permit().await?;
        check_deadline("prepare")?;
        let (state, req) = (Arc::clone(self), Arc::clone(&request));
        let prepared = blocking(move || {
            let _permit = permit;
            let _preparing = preparing;
            let scene = convert::scene_of(&req, &state.settings.limits)?;
            let options = convert::options_of(&req, &state.settings.defaults)?;
            Ok(state.planner.prepare(&scene, &options)?)
        })
        .instrument(tracing::debug_span!("prepare"))
        .await?;

        // The network, then decoding; again for the objects the view cascade
        // sends on to their next view.
        let mut prepared = prepared;
        let mut inference = Duration::ZERO;
        let plan = loop {
            check_deadline("inference")?;
            let (maps, waited) = if prepared.batch().len == 0 {
                let size_px = prepared.batch().size_px;
                let empty = GraspMaps {
                    size_px,
                    len: 0,
                    data: Vec::new(),
                };
                (empty, Duration::ZERO)
            } else {
                self.batcher
                    .infer(prepared.batch().clone(), deadline)
                    .instrument(tracing::debug_span!("inference", views = prepared.batch().len))
                    .await?
            };
            inference += waited;
            prepared.set_inference_time(inference);

            let permit = self.cpu_permit().await?;
            check_deadline("decode")?;
            let state = Arc::clone(self);
            let finished = blocking(move || {
                let _permit = permit;
                Ok(state.planner.finish_or_cascade(prepared, maps)?)
            })
            .instrument(tracing::debug_span!("decode"))
            .await?;
            match finished {
                Finished::Plan(plan) => break *plan,
                Finished::More(next) => prepared = *next,
            }
        };

        let total_s = started.elapsed().as_secs_f64();
        self.observe_plan(&plan);
        Ok(convert::response_of(
            &plan,
            &self.info.model_version,
            &request.request_id,
            total_s,
        ))
    }

    async fn cpu_permit(&self) -> Result<tokio::sync::OwnedSemaphorePermit> {
        Arc::clone(&self.cpu)
            .acquire_owned()
            .await
            .map_err(|_| Error::Unavailable("the server is shutting down".into()))
    }

    fn observe_plan(&self, plan: &mvgrasp_core::Plan) {
        let t = &plan.timings;
        let stage = &self.metrics.stage_seconds;
        for (name, d) in [
            ("sensor", t.sensor),
            ("table", t.table),
            ("objects", t.sensor_objects),
            ("cluster", t.cluster),
            ("frames", t.frames),
            ("views", t.views),
            ("select", t.select),
            ("inference", t.inference),
            ("decode", t.decode),
        ] {
            stage.with_label_values(&[name]).observe(d.as_secs_f64());
        }
        self.metrics
            .objects_per_request
            .observe(plan.objects.len() as f64);
        self.metrics.grasps_per_request.observe(plan.grasps.len() as f64);
        self.metrics
            .grasps_refused_for_collision
            .inc_by(plan.refused_for_collision as u64);
        self.metrics
            .grasps_out_of_view
            .inc_by(plan.ranked_last_out_of_view as u64);
        self.metrics
            .grasps_turned_square
            .inc_by(plan.turned_square as u64);
        self.metrics
            .grasps_turned_away
            .inc_by(plan.ranked_after_turned_away as u64);
        self.metrics
            .grasps_outside_approach_cone
            .inc_by(plan.outside_approach_cone as u64);
        self.metrics.grasps_out_of_reach.inc_by(plan.out_of_reach as u64);
        let mut refused = [0; crate::metrics::REFUSAL_CAUSES.len()];
        for o in &plan.objects {
            for (sum, n) in refused.iter_mut().zip(o.refused.counts()) {
                *sum += n;
            }
        }
        for (cause, n) in crate::metrics::REFUSAL_CAUSES.iter().zip(refused) {
            self.metrics
                .candidates_refused
                .with_label_values(&[cause])
                .inc_by(n as u64);
        }
    }

    fn observe_call(&self, method: &str, started: Instant, code: Code) {
        self.metrics
            .requests
            .with_label_values(&[method, &format!("{code:?}")])
            .inc();
        self.metrics
            .request_seconds
            .with_label_values(&[method])
            .observe(started.elapsed().as_secs_f64());
    }
}

/// Runs CPU work on tokio's blocking pool; a panic there becomes `Internal`.
async fn blocking<T: Send + 'static>(f: impl FnOnce() -> Result<T> + Send + 'static) -> Result<T> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| Error::Internal(format!("planning task failed: {e}")))?
}

/// The deadline a `grpc-timeout` header sets, 1 ms early so that this server
/// (not the transport's own timer) answers DEADLINE_EXCEEDED.
fn deadline_of(metadata: &tonic::metadata::MetadataMap, now: Instant) -> Option<Instant> {
    let raw = metadata.get("grpc-timeout")?.to_str().ok()?;
    let (digits, unit) = raw.split_at(raw.len().checked_sub(1)?);
    let value: u64 = digits.parse().ok()?;
    let timeout = match unit {
        "H" => Duration::from_secs(value.saturating_mul(3600)),
        "M" => Duration::from_secs(value.saturating_mul(60)),
        "S" => Duration::from_secs(value),
        "m" => Duration::from_millis(value),
        "u" => Duration::from_micros(value),
        "n" => Duration::from_nanos(value),
        _ => return None,
    };
    now.checked_add(timeout.saturating_sub(Duration::from_millis(1)))
}

/// The tonic service.
#[derive(Debug, Clone)]
pub struct PlannerService {
    state: Arc<PlannerState>,
}

impl PlannerService {
    /// A service over `state`.
    pub fn new(state: Arc<PlannerState>) -> Self {
        Self { state }
    }
}

/// Counts a call in flight for as long as it lives.
struct InFlight<'a>(&'a Metrics);

impl<'a> InFlight<'a> {
    fn enter(metrics: &'a Metrics, limit: usize) -> Result<Self> {
        let now = metrics.in_flight.get();
        if now >= limit as i64 {
            return Err(Error::Overloaded(format!(
                "{now} calls in flight; the limit is {limit}"
            )));
        }
        metrics.in_flight.inc();
        Ok(Self(metrics))
    }
}

impl Drop for InFlight<'_> {
    fn drop(&mut self) {
        self.0.in_flight.dec();
    }
}

/// A decode error of the transport for an oversized message says OUT_OF_RANGE;
/// this API answers limits with RESOURCE_EXHAUSTED.
pub(crate) fn limit_status(status: Status) -> Status {
    if status.code() == Code::OutOfRange && status.message().contains("message length too large") {
        Status::resource_exhausted(status.message().to_owned())
    } else {
        status
    }
}

type ResponseStream = Pin<Box<dyn Stream<Item = Result<pb::PlanGraspsResponse, Status>> + Send>>;

#[tonic::async_trait]
impl GraspPlanner for PlannerService {
    async fn plan_grasps(
        &self,
        request: Request<pb::PlanGraspsRequest>,
    ) -> Result<Response<pb::PlanGraspsResponse>, Status> {
        let started = Instant::now();
        let deadline = deadline_of(request.metadata(), started);
        let state = &self.state;
        let span = tracing::info_span!("plan_grasps", request_id = %request.get_ref().request_id);
        let result = async {
            let _in_flight = InFlight::enter(&state.metrics, state.settings.limits.max_in_flight)?;
            let work = state.plan(request.into_inner(), deadline);
            match deadline {
                Some(d) => tokio::time::timeout_at(d.into(), work)
                    .await
                    .unwrap_or(Err(Error::DeadlineExceeded { stage: "planning" })),
                None => work.await,
            }
        }
        .instrument(span)
        .await;
        let result = result.map_err(|e| {
            if e.code() == Code::Internal {
                tracing::error!(error = %e, "PlanGrasps failed");
            }
            Status::from(e)
        });
        state.observe_call(
            "PlanGrasps",
            started,
            result.as_ref().map_or_else(Status::code, |_| Code::Ok),
        );
        result.map(Response::new)
    }

    type StreamGraspsStream = ResponseStream;

    async fn stream_grasps(
        &self,
        request: Request<Streaming<pb::PlanGraspsRequest>>,
    ) -> Result<Response<Self::StreamGraspsStream>, Status> {
        let state = Arc::clone(&self.state);
        let inbound = request.into_inner();
        let answers = inbound
            .enumerate()
            .map(move |(index, item)| {
                let state = Arc::clone(&state);
                async move {
                    let started = Instant::now();
                    let result = match item {
                        Err(status) => Err(limit_status(status)),
                        Ok(request) => {
                            let id = request.request_id.clone();
                            let planned = async {
                                let _in_flight =
                                    InFlight::enter(&state.metrics, state.settings.limits.max_in_flight)?;
                                state.plan(request, None).await
                            }
                            .instrument(tracing::info_span!("stream_frame", index, request_id = %id))
                            .await;
                            planned.map_err(|e| {
                                let status = Status::from(e);
                                Status::new(
                                    status.code(),
                                    format!("frame {index} (request_id {id:?}): {}", status.message()),
                                )
                            })
                        }
                    };
                    state.observe_call(
                        "StreamGrasps",
                        started,
                        result.as_ref().map_or_else(Status::code, |_| Code::Ok),
                    );
                    result
                }
            })
            .buffered(STREAM_PIPELINE_DEPTH);
        // The stream ends after its first error: gRPC carries one status per call.
        let mut failed = false;
        let answers = answers.take_while(move |item| {
            let go = !failed;
            failed |= item.is_err();
            std::future::ready(go)
        });
        Ok(Response::new(Box::pin(answers)))
    }

    async fn get_model_info(
        &self,
        _request: Request<pb::GetModelInfoRequest>,
    ) -> Result<Response<pb::ModelInfo>, Status> {
        let started = Instant::now();
        self.state.observe_call("GetModelInfo", started, Code::Ok);
        Ok(Response::new(self.state.info.clone()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grpc_timeout_header() {
        let now = Instant::now();
        let mut m = tonic::metadata::MetadataMap::new();
        assert_eq!(deadline_of(&m, now), None);
        m.insert("grpc-timeout", "250m".parse().unwrap());
        assert_eq!(deadline_of(&m, now), Some(now + Duration::from_millis(249)));
        m.insert("grpc-timeout", "2S".parse().unwrap());
        assert_eq!(deadline_of(&m, now), Some(now + Duration::from_millis(1999)));
        m.insert("grpc-timeout", "x".parse().unwrap());
        assert_eq!(deadline_of(&m, now), None);
    }

    #[test]
    fn oversized_messages_are_resource_exhausted() {
        let s = limit_status(Status::out_of_range(
            "Error, decoded message length too large: found 9 bytes, the limit is: 4 bytes",
        ));
        assert_eq!(s.code(), Code::ResourceExhausted);
        assert_eq!(
            limit_status(Status::out_of_range("other")).code(),
            Code::OutOfRange
        );
    }
}
