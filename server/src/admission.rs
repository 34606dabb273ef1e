//! Admission at the door: a PlanGrasps call over the in-flight limit is
//! answered RESOURCE_EXHAUSTED from its headers, before its frame (0.5-4 MB)
//! is read or decoded, so that shedding load costs almost nothing and the
//! calls taken keep their latency. The handler's own in-flight check stays
//! for streams (counted per frame) and as the exact count behind the gauge.

use std::{
    sync::{
        Arc,
        atomic::{AtomicUsize, Ordering},
    },
    task::{Context, Poll},
};

use futures_util::future::BoxFuture;
use tonic::{Code, Status, body::Body};

use crate::metrics::Metrics;

const PLAN_PATH: &str = "/mvgrasp.v1.GraspPlanner/PlanGrasps";

/// Wraps the gRPC service with [`Admission`].
#[derive(Debug, Clone)]
pub struct AdmissionLayer {
    admitted: Arc<AtomicUsize>,
    limit: usize,
    metrics: Arc<Metrics>,
}

impl AdmissionLayer {
    /// At most `limit` PlanGrasps calls past the door at once.
    pub fn new(limit: usize, metrics: Arc<Metrics>) -> Self {
        Self {
            admitted: Arc::new(AtomicUsize::new(0)),
            limit,
            metrics,
        }
    }
}

impl<S> tower::Layer<S> for AdmissionLayer {
    type Service = Admission<S>;

    fn layer(&self, inner: S) -> Self::Service {
        Admission {
            inner,
            layer: self.clone(),
        }
    }
}

/// See the module docs.
#[derive(Debug, Clone)]
pub struct Admission<S> {
    inner: S,
    layer: AdmissionLayer,
}

/// Gives an admission back when the call's response is ready.
struct Admitted(Arc<AtomicUsize>);

impl Drop for Admitted {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::AcqRel);
    }
}

impl<S, B> tower::Service<http::Request<B>> for Admission<S>
where
    S: tower::Service<http::Request<B>, Response = http::Response<Body>> + Send + 'static,
    S::Future: Send + 'static,
    S::Error: Send + 'static,
    B: Send + 'static,
{
    type Response = http::Response<Body>;
    type Error = S::Error;
    type Future = BoxFuture<'static, Result<Self::Response, Self::Error>>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, request: http::Request<B>) -> Self::Future {
        if request.uri().path() != PLAN_PATH {
            return Box::pin(self.inner.call(request));
        }
        let layer = &self.layer;
        let before = layer.admitted.fetch_add(1, Ordering::AcqRel);
        let admitted = Admitted(Arc::clone(&layer.admitted));
        if before >= layer.limit {
            drop(admitted);
            layer
                .metrics
                .requests
                .with_label_values(&["PlanGrasps", &format!("{:?}", Code::ResourceExhausted)])
                .inc();
            let status = Status::resource_exhausted(format!(
                "overloaded: {before} calls in flight; the limit is {}",
                layer.limit
            ));
            return Box::pin(std::future::ready(Ok(status.into_http::<Body>())));
        }
        let call = self.inner.call(request);
        Box::pin(async move {
            let response = call.await;
            drop(admitted);
            response
        })
    }
}
