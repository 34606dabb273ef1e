//! Dynamic batching: views of concurrent requests share network calls.
//!
//! One worker thread owns each session of the network (`model.sessions`).
//! The worker whose turn it is takes the oldest queued request, then keeps
//! adding queued requests until the batch holds `max_batch_views` views or
//! the oldest has waited `max_wait`; it then runs that batch while the next
//! worker gathers the next one (on a GPU: one batch copied and handed out
//! while another runs). It waits only while other
//! requests are still in their CPU stages (about to submit views): a lone
//! request never pays `max_wait`. A request's views are never split across
//! calls. Requests whose caller has gone, or whose deadline has
//! passed, are dropped before they reach the network.
//!
//! A batch of one request while no other call is in flight (the
//! `in_flight_requests` gauge) runs on the lone network when there is one:
//! the same file with more threads (`model.lone_call_threads`), as no
//! other call needs the cores; every other batch on the network with
//! `intra_threads`, leaving the rest of the cores to other calls' CPU stages.

use std::{
    sync::{
        Arc, Mutex, PoisonError,
        atomic::{AtomicUsize, Ordering},
        mpsc::{self, RecvTimeoutError, TryRecvError},
    },
    time::{Duration, Instant},
};

use mvgrasp_core::{GraspMaps, GraspNet, ViewBatch};
use tokio::sync::oneshot;

use crate::{
    error::{Error, Result},
    metrics::Metrics,
};

/// How often a waiting worker looks again whether company is still coming.
const POLL: Duration = Duration::from_micros(250);

/// Batching limits.
#[derive(Debug, Clone, Copy)]
pub struct BatchLimits {
    /// Most views per network call.
    pub max_batch_views: usize,
    /// Longest the oldest request waits for others.
    pub max_wait: Duration,
    /// Views allowed to wait before new requests are refused.
    pub max_queued_views: usize,
}

struct Job {
    batch: ViewBatch,
    enqueued: Instant,
    deadline: Option<Instant>,
    reply: oneshot::Sender<Result<(GraspMaps, Duration)>>,
}

/// Submits view batches to the worker; cheap to clone.
#[derive(Clone)]
pub struct Batcher {
    jobs: mpsc::Sender<Job>,
    queued_views: Arc<AtomicUsize>,
    preparing: Arc<AtomicUsize>,
    limits: BatchLimits,
    metrics: Arc<Metrics>,
}

impl std::fmt::Debug for Batcher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Batcher").field("limits", &self.limits).finish()
    }
}

impl Batcher {
    /// Starts one worker thread per session in `nets` (at least one), and
    /// keeps `lone` for a call that has the server to itself. The workers
    /// stop when every `Batcher` is dropped.
    pub fn spawn(
        nets: Vec<Box<dyn GraspNet + Send>>,
        lone: Option<Box<dyn GraspNet + Send>>,
        limits: BatchLimits,
        metrics: Arc<Metrics>,
    ) -> Result<Self> {
        if nets.is_empty() {
            return Err(Error::Startup("no network session to run batches on".into()));
        }
        let (tx, rx) = mpsc::channel();
        let queued_views = Arc::new(AtomicUsize::new(0));
        let preparing = Arc::new(AtomicUsize::new(0));
        let intake = Arc::new(Mutex::new(Intake {
            jobs: rx,
            carried: None,
        }));
        let lone = Arc::new(Mutex::new(lone));
        for (k, net) in nets.into_iter().enumerate() {
            let worker = Worker {
                net,
                lone: Arc::clone(&lone),
                intake: Arc::clone(&intake),
                queued_views: Arc::clone(&queued_views),
                preparing: Arc::clone(&preparing),
                limits,
                metrics: Arc::clone(&metrics),
            };
            std::thread::Builder::new()
                .name(format!("mvgrasp-inference-{k}"))
                .spawn(move || worker.run())
                .map_err(|e| Error::Startup(format!("inference thread: {e}")))?;
        }
        Ok(Self {
            jobs: tx,
            queued_views,
            preparing,
            limits,
            metrics,
        })
    }

    /// Marks a request as being in its CPU stages (it will submit views soon)
    /// for as long as the guard lives.
    pub fn preparing(&self) -> Preparing {
        self.preparing.fetch_add(1, Ordering::SeqCst);
        Preparing(Arc::clone(&self.preparing))
    }

    /// Runs `batch` through the network (with others), returning its maps and
    /// the time from queueing to the answer.
    pub async fn infer(&self, batch: ViewBatch, deadline: Option<Instant>) -> Result<(GraspMaps, Duration)> {
        let views = batch.len;
        let queued = self.queued_views.fetch_add(views, Ordering::SeqCst) + views;
        if queued > self.limits.max_queued_views && queued > views {
            self.release(views);
            self.metrics
                .dropped
                .with_label_values(&["queue_full"])
                .inc_by(views as u64);
            return Err(Error::Overloaded(format!(
                "{queued} views would be queued for the network; the limit is {}",
                self.limits.max_queued_views
            )));
        }
        self.metrics.queued_views.set(queued as i64);
        let (reply, answer) = oneshot::channel();
        let job = Job {
            batch,
            enqueued: Instant::now(),
            deadline,
            reply,
        };
        if self.jobs.send(job).is_err() {
            self.release(views);
            return Err(Error::Unavailable("the inference worker has stopped".into()));
        }
        answer
            .await
            .map_err(|_| Error::Unavailable("the inference worker stopped during the call".into()))?
    }

    fn release(&self, views: usize) {
        let left = self.queued_views.fetch_sub(views, Ordering::SeqCst) - views;
        self.metrics.queued_views.set(left as i64);
    }
}

/// See [`Batcher::preparing`].
#[derive(Debug)]
pub struct Preparing(Arc<AtomicUsize>);

impl Drop for Preparing {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// The queue the workers take their batches from, one worker at a time.
struct Intake {
    jobs: mpsc::Receiver<Job>,
    /// A job that did not fit the previous batch.
    carried: Option<Job>,
}

struct Worker {
    net: Box<dyn GraspNet + Send>,
    /// Shared by the workers; used only by a call alone in the server.
    lone: Arc<Mutex<Option<Box<dyn GraspNet + Send>>>>,
    intake: Arc<Mutex<Intake>>,
    queued_views: Arc<AtomicUsize>,
    preparing: Arc<AtomicUsize>,
    limits: BatchLimits,
    metrics: Arc<Metrics>,
}

impl Worker {
    fn run(mut self) {
        loop {
            // Gather under the intake's lock, run outside it: the next worker
            // gathers while this one runs.
            let jobs = {
                let mut intake = self.intake.lock().unwrap_or_else(PoisonError::into_inner);
                match self.gather(&mut intake) {
                    Some(jobs) => jobs,
                    None => return, // every Batcher is gone
                }
            };
            self.run_batch(jobs);
        }
    }

    /// The next batch's jobs; `None` once every `Batcher` is gone.
    fn gather(&self, intake: &mut Intake) -> Option<Vec<Job>> {
        let first = match intake.carried.take() {
            Some(job) => job,
            None => intake.jobs.recv().ok()?,
        };
        let close_at = first.enqueued + self.limits.max_wait;
        let mut views = first.batch.len;
        let mut jobs = vec![first];
        while views < self.limits.max_batch_views {
            let job = match intake.jobs.try_recv() {
                Ok(job) => job,
                Err(TryRecvError::Disconnected) => break,
                Err(TryRecvError::Empty) => {
                    let wait = close_at.saturating_duration_since(Instant::now());
                    if wait.is_zero() || self.preparing.load(Ordering::SeqCst) == 0 {
                        break;
                    }
                    match intake.jobs.recv_timeout(wait.min(POLL)) {
                        Ok(job) => job,
                        Err(RecvTimeoutError::Timeout) => continue,
                        Err(RecvTimeoutError::Disconnected) => break,
                    }
                }
            };
            if views + job.batch.len > self.limits.max_batch_views {
                intake.carried = Some(job);
                break;
            }
            views += job.batch.len;
            jobs.push(job);
        }
        Some(jobs)
    }

    fn run_batch(&mut self, jobs: Vec<Job>) {
        let now = Instant::now();
        let mut live = Vec::with_capacity(jobs.len());
        for job in jobs {
            let views = job.batch.len;
            let reason = if job.reply.is_closed() {
                Some("caller_gone")
            } else if job.deadline.is_some_and(|d| d <= now) {
                Some("deadline")
            } else {
                None
            };
            match reason {
                Some(reason) => {
                    self.release(views);
                    self.metrics
                        .dropped
                        .with_label_values(&[reason])
                        .inc_by(views as u64);
                    if reason == "deadline" {
                        let _ = job.reply.send(Err(Error::DeadlineExceeded { stage: "queue" }));
                    }
                }
                None => live.push(job),
            }
        }
        if live.is_empty() {
            return;
        }
        let size_px = live[0].batch.size_px;
        let total: usize = live.iter().map(|j| j.batch.len).sum();
        let mut batch = ViewBatch::new(size_px);
        batch.data.reserve(total * size_px * size_px);
        for job in &live {
            batch.data.extend_from_slice(&job.batch.data);
            batch.len += job.batch.len;
        }
        self.metrics.batch_views.observe(total as f64);
        self.metrics.batch_requests.observe(live.len() as f64);
        let alone = live.len() == 1 && self.metrics.in_flight.get() <= 1;
        let run = |net: &mut (dyn GraspNet + Send)| {
            net.infer(&batch)
                .and_then(|maps| maps.check_matches(&batch).map(|()| maps))
        };
        // Held only while the lone network runs, so that other workers' batches do not wait.
        let mut lone = alone
            .then(|| self.lone.lock().unwrap_or_else(PoisonError::into_inner))
            .filter(|held| held.is_some());
        let started = Instant::now();
        let (result, session) = match lone.as_mut().and_then(|held| held.as_mut()) {
            Some(net) => {
                self.metrics.lone_network_calls.inc();
                (run(net.as_mut()), "lone")
            }
            None => (run(self.net.as_mut()), "shared"),
        };
        drop(lone);
        self.metrics
            .network_seconds
            .with_label_values(&[session])
            .observe(started.elapsed().as_secs_f64());
        self.release(total);
        let per_view = 4 * size_px * size_px;
        // Each request's maps are cut off the end of the batch's, the last
        // request's first, and the first request keeps what is left: one
        // copy fewer (a lone call's maps are not copied here at all).
        let (mut data, failed) = match result {
            Ok(maps) => (maps.data, None),
            Err(e) => (Vec::new(), Some(format!("inference: {e}"))),
        };
        let mut answers = Vec::with_capacity(live.len());
        for job in live.into_iter().rev() {
            let n = job.batch.len;
            let answer = match (&failed, data.len().checked_sub(n * per_view)) {
                (None, Some(rest)) => {
                    let own = if rest == 0 {
                        std::mem::take(&mut data)
                    } else {
                        data.split_off(rest)
                    };
                    Ok((
                        GraspMaps {
                            size_px,
                            len: n,
                            data: own,
                        },
                        job.enqueued.elapsed(),
                    ))
                }
                (Some(failed), _) => Err(Error::Internal(failed.clone())),
                (None, None) => Err(Error::Internal(format!(
                    "inference: {} map values left for a request of {n} views",
                    data.len()
                ))),
            };
            answers.push((job, answer));
        }
        for (job, answer) in answers.into_iter().rev() {
            // A caller that left meanwhile simply does not read its answer.
            let _ = job.reply.send(answer);
        }
    }

    fn release(&self, views: usize) {
        let left = self.queued_views.fetch_sub(views, Ordering::SeqCst) - views;
        self.metrics.queued_views.set(left as i64);
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use mvgrasp_core::{ModelContract, MomentsNet};

    use super::*;

    /// Records the size of every call, answering with the baseline.
    struct Recording {
        inner: MomentsNet,
        calls: Arc<Mutex<Vec<usize>>>,
    }

    impl GraspNet for Recording {
        fn contract(&self) -> &ModelContract {
            self.inner.contract()
        }
        fn infer(&mut self, batch: &ViewBatch) -> mvgrasp_core::Result<GraspMaps> {
            self.calls.lock().unwrap().push(batch.len);
            std::thread::sleep(Duration::from_millis(20));
            self.inner.infer(batch)
        }
    }

    fn views(n: usize, seed: f32) -> ViewBatch {
        let mut b = ViewBatch::new(96);
        for i in 0..n {
            let mut image = vec![0.0f32; 96 * 96];
            for v in 30..60 {
                for u in 40..(50 + i) {
                    image[v * 96 + u] = 0.5 + seed;
                }
            }
            b.push(&image);
        }
        b
    }

    /// A batcher of one session, batches of up to 8 views.
    fn one_session(net: impl GraspNet + Send + 'static, max_wait: Duration) -> Batcher {
        let limits = BatchLimits {
            max_batch_views: 8,
            max_wait,
            max_queued_views: 64,
        };
        Batcher::spawn(
            vec![Box::new(net)],
            None,
            limits,
            Arc::new(Metrics::new().unwrap()),
        )
        .unwrap()
    }

    /// Six concurrent requests of two views each; each gets the maps the
    /// network gives its views alone.
    async fn six_requests_get_their_own_maps(batcher: &Batcher) {
        let mut tasks = Vec::new();
        for k in 0..6 {
            let b = batcher.clone();
            tasks.push(tokio::spawn(async move {
                let batch = views(2, k as f32 * 0.05);
                let (maps, _) = b.infer(batch.clone(), None).await.unwrap();
                assert_eq!(maps, MomentsNet::default().infer(&batch).unwrap(), "request {k}");
            }));
        }
        for t in tasks {
            t.await.unwrap();
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn concurrent_requests_share_calls_and_get_their_own_maps() {
        let calls = Arc::new(Mutex::new(Vec::new()));
        let net = Recording {
            inner: MomentsNet::default(),
            calls: Arc::clone(&calls),
        };
        let batcher = one_session(net, Duration::from_millis(50));
        six_requests_get_their_own_maps(&batcher).await;
        let calls = calls.lock().unwrap().clone();
        assert_eq!(calls.iter().sum::<usize>(), 12);
        assert!(calls.iter().all(|&n| n <= 8), "{calls:?}");
        assert!(
            calls.len() < 6,
            "6 concurrent requests took {} calls: {calls:?}",
            calls.len()
        );
    }

    /// The answers to two requests queued together: the worker holds the
    /// first for company while a call prepares, until both wait.
    async fn in_one_batch(batcher: &Batcher, batches: [ViewBatch; 2]) -> [Result<(GraspMaps, Duration)>; 2] {
        let preparing = batcher.preparing();
        let views: usize = batches.iter().map(|b| b.len).sum();
        let calls = batches.map(|batch| {
            let b = batcher.clone();
            tokio::spawn(async move { b.infer(batch, None).await })
        });
        while batcher.queued_views.load(Ordering::SeqCst) < views {
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
        drop(preparing);
        let [first, second] = calls;
        [first.await.unwrap(), second.await.unwrap()]
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_call_alone_in_the_server_runs_on_the_lone_network() {
        let recording = || {
            let calls = Arc::new(Mutex::new(Vec::new()));
            let net = Recording {
                inner: MomentsNet::default(),
                calls: Arc::clone(&calls),
            };
            (Box::new(net) as Box<dyn GraspNet + Send>, calls)
        };
        let ((busy, busy_calls), (lone, lone_calls)) = (recording(), recording());
        let limits = BatchLimits {
            max_batch_views: 8,
            max_wait: Duration::from_secs(10),
            max_queued_views: 64,
        };
        let metrics = Arc::new(Metrics::new().unwrap());
        let batcher = Batcher::spawn(vec![busy], Some(lone), limits, Arc::clone(&metrics)).unwrap();
        // The service counts its calls in flight; this one is alone.
        metrics.in_flight.set(1);
        let batch = views(3, 0.0);
        let (maps, _) = batcher.infer(batch.clone(), None).await.unwrap();
        assert_eq!(maps, MomentsNet::default().infer(&batch).unwrap());
        assert_eq!(*lone_calls.lock().unwrap(), [3]);
        assert!(busy_calls.lock().unwrap().is_empty());
        assert_eq!(metrics.lone_network_calls.get(), 1);
        let timed = |session: &str| {
            metrics
                .network_seconds
                .with_label_values(&[session])
                .get_sample_count()
        };
        assert_eq!((timed("lone"), timed("shared")), (1, 0));
        // Another call in flight (in its CPU stages, say): the lone call's
        // batch leaves it the other cores.
        metrics.in_flight.set(2);
        batcher.infer(views(2, 0.0), None).await.unwrap();
        assert_eq!(*busy_calls.lock().unwrap(), [2]);
        assert_eq!((timed("lone"), timed("shared")), (1, 1));
        // Requests sharing a call are never alone.
        metrics.in_flight.set(1);
        let [first, second] = in_one_batch(&batcher, [views(1, 0.0), views(1, 0.1)]).await;
        first.unwrap();
        second.unwrap();
        assert_eq!(*busy_calls.lock().unwrap(), [2, 2], "one shared call of both");
        assert_eq!(*lone_calls.lock().unwrap(), [3]);
        assert_eq!(metrics.lone_network_calls.get(), 1);
    }

    /// Counts the calls running at once; each waits (up to 5 s) until
    /// `company` calls run together, so that overlap does not hang on timing.
    struct Overlapping {
        inner: MomentsNet,
        running: Arc<AtomicUsize>,
        most: Arc<AtomicUsize>,
        company: usize,
    }

    impl GraspNet for Overlapping {
        fn contract(&self) -> &ModelContract {
            self.inner.contract()
        }
        fn infer(&mut self, batch: &ViewBatch) -> mvgrasp_core::Result<GraspMaps> {
            let now = self.running.fetch_add(1, Ordering::SeqCst) + 1;
            self.most.fetch_max(now, Ordering::SeqCst);
            let give_up = Instant::now() + Duration::from_secs(5);
            while self.most.load(Ordering::SeqCst) < self.company && Instant::now() < give_up {
                std::thread::sleep(Duration::from_millis(1));
            }
            self.running.fetch_sub(1, Ordering::SeqCst);
            self.inner.infer(batch)
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn sessions_run_batches_at_once_and_answer_every_request() {
        for sessions in [1, 2, 3] {
            let (running, most) = (Arc::new(AtomicUsize::new(0)), Arc::new(AtomicUsize::new(0)));
            let nets = (0..sessions)
                .map(|_| {
                    Box::new(Overlapping {
                        inner: MomentsNet::default(),
                        running: Arc::clone(&running),
                        most: Arc::clone(&most),
                        company: sessions,
                    }) as Box<dyn GraspNet + Send>
                })
                .collect();
            let limits = BatchLimits {
                max_batch_views: 2,
                max_wait: Duration::ZERO,
                max_queued_views: 64,
            };
            let batcher = Batcher::spawn(nets, None, limits, Arc::new(Metrics::new().unwrap())).unwrap();
            six_requests_get_their_own_maps(&batcher).await;
            // Each call waits for the others of its round: all sessions at once, never more.
            assert_eq!(most.load(Ordering::SeqCst), sessions, "{sessions} sessions");
            assert_eq!(batcher.queued_views.load(Ordering::SeqCst), 0);
        }
        let none = Batcher::spawn(
            Vec::new(),
            None,
            BatchLimits {
                max_batch_views: 2,
                max_wait: Duration::ZERO,
                max_queued_views: 2,
            },
            Arc::new(Metrics::new().unwrap()),
        );
        assert!(none.is_err());
    }

    #[tokio::test]
    async fn expired_and_oversized_work_is_refused() {
        let limits = BatchLimits {
            max_batch_views: 4,
            max_wait: Duration::ZERO,
            max_queued_views: 4,
        };
        let metrics = Arc::new(Metrics::new().unwrap());
        let batcher = Batcher::spawn(
            vec![Box::new(MomentsNet::default())],
            None,
            limits,
            Arc::clone(&metrics),
        )
        .unwrap();
        let past = Instant::now().checked_sub(Duration::from_millis(1));
        let err = batcher.infer(views(1, 0.0), past).await.unwrap_err();
        assert!(matches!(err, Error::DeadlineExceeded { .. }), "{err}");
        // A request larger than the whole queue still runs alone when nothing else waits.
        let (maps, _) = batcher.infer(views(6, 0.0), None).await.unwrap();
        assert_eq!(maps.len, 6);
        assert_eq!(metrics.queued_views.get(), 0);
        assert_eq!(metrics.dropped.with_label_values(&["deadline"]).get(), 1);
    }

    /// Fails every call, or answers with one view's maps too few.
    struct Broken {
        inner: MomentsNet,
        short: bool,
    }

    impl GraspNet for Broken {
        fn contract(&self) -> &ModelContract {
            self.inner.contract()
        }
        fn infer(&mut self, batch: &ViewBatch) -> mvgrasp_core::Result<GraspMaps> {
            if !self.short {
                return Err(mvgrasp_core::Error::Backend("the device is gone".into()));
            }
            let mut maps = self.inner.infer(batch)?;
            maps.data
                .truncate(maps.data.len() - 4 * batch.size_px * batch.size_px);
            Ok(maps)
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn every_request_of_a_failed_batch_hears_why() {
        for short in [false, true] {
            let net = Broken {
                inner: MomentsNet::default(),
                short,
            };
            let batcher = one_session(net, Duration::from_millis(200));
            for answer in in_one_batch(&batcher, [views(3, 0.0), views(2, 0.1)]).await {
                let err = answer.unwrap_err();
                let expected = if short {
                    "values; the batch needs"
                } else {
                    "the device is gone"
                };
                assert!(
                    matches!(&err, Error::Internal(m) if m.contains(expected)),
                    "short {short}: {err}"
                );
            }
        }
    }
}
