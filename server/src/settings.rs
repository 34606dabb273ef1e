//! Configuration in layers: defaults -> TOML file -> `MVGRASP_*` environment
//! -> command-line flags, deserialised into one validated [`Settings`].

use std::{net::SocketAddr, path::PathBuf};

use serde::Deserialize;

use crate::error::{Error, Result};

/// What runs the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum BackendKind {
    /// An ONNX model through ONNX Runtime.
    Onnx,
    /// The analytic baseline of `mvgrasp-core` (no model file; not learned).
    Baseline,
}

/// Where ONNX Runtime runs the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Device {
    /// The CPU execution provider.
    Cpu,
    /// The CUDA execution provider, falling back to the CPU with a warning.
    Cuda,
}

/// How cuDNN picks convolution algorithms under the CUDA execution provider.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum ConvSearch {
    /// Time every algorithm once per input shape, keep the fastest (ONNX
    /// Runtime's default; the server pays it at start-up, see `backend`).
    Exhaustive,
    /// cuDNN's heuristics: no timing runs, maybe slower kernels.
    Heuristic,
    /// cuDNN's default algorithm.
    Default,
}

/// The model and its runtime.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ModelSettings {
    /// `onnx` or `baseline`.
    pub backend: BackendKind,
    /// The ONNX file (its metadata carries the model contract).
    pub path: PathBuf,
    /// `libonnxruntime.so`; unset: `ORT_DYLIB_PATH`, then the loader's search path.
    pub onnxruntime_library: Option<PathBuf>,
    /// `cpu` or `cuda`.
    pub device: Device,
    /// Threads ONNX Runtime uses inside one network call.
    pub intra_threads: usize,
    /// Threads for a call that has the server to itself (one call in
    /// flight): a second session of the same file (CPU only; at or under
    /// `intra_threads`, none).
    pub lone_call_threads: usize,
    /// Let ONNX Runtime's threads spin between calls (lower latency when the
    /// cores are otherwise idle; steals them from the CPU stages when not).
    pub spin_wait: bool,
    /// cuDNN's convolution algorithm search (`device = cuda` only).
    pub cuda_conv_search: ConvSearch,
    /// Sessions of the file, each running its own batches on its own
    /// thread: one gathers the next batch while another runs (on a GPU,
    /// while one batch's maps are copied back and handed out, the next
    /// computes; on two CPU cores, one session's thread alone left a core
    /// idle under load).
    pub sessions: usize,
}

impl Default for ModelSettings {
    fn default() -> Self {
        Self {
            backend: BackendKind::Onnx,
            path: PathBuf::from("models/mvgrasp-9.onnx"),
            onnxruntime_library: None,
            device: Device::Cpu,
            intra_threads: 1,
            lone_call_threads: 2,
            spin_wait: true,
            cuda_conv_search: ConvSearch::Exhaustive,
            sessions: 2,
        }
    }
}

/// Dynamic batching of views across concurrent requests.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BatchSettings {
    /// Most views in one network call (a request's views are never split, so
    /// one request with more views runs alone).
    pub max_batch_views: usize,
    /// Longest a view waits for others to join its batch (ms); 0 disables batching.
    pub max_wait_ms: f64,
    /// Views that may wait for the network before requests are refused.
    pub max_queued_views: usize,
}

impl Default for BatchSettings {
    fn default() -> Self {
        Self {
            max_batch_views: 32,
            max_wait_ms: 2.0,
            max_queued_views: 2048,
        }
    }
}

/// Limits on what one request may ask of the server.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Limits {
    /// Largest encoded request (bytes).
    pub max_message_bytes: usize,
    /// Most pixels of a depth image.
    pub max_image_pixels: usize,
    /// Most points of a cloud.
    pub max_cloud_points: usize,
    /// Requests being planned at once before new ones are refused.
    pub max_in_flight: usize,
    /// Requests running the CPU stages at once (0: one per core).
    pub cpu_workers: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_message_bytes: 32 << 20,
            max_image_pixels: 4096 * 4096,
            max_cloud_points: 4_000_000,
            max_in_flight: 256,
            cpu_workers: 0,
        }
    }
}

/// What a request gets for the fields it leaves unset.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RequestDefaults {
    /// `max_grasps = 0` means this many.
    pub max_grasps: u32,
    /// An absent `min_quality` means this (tau).
    pub min_quality: f32,
}

impl Default for RequestDefaults {
    fn default() -> Self {
        Self {
            max_grasps: 10,
            min_quality: 0.0,
        }
    }
}

/// How depth frames are cut into objects (`core::segment`); the defaults are
/// the planner's, chosen on the referee's train pool.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SegmentSettings {
    /// Points closer than this belong to one object (m).
    pub tolerance_m: f32,
    /// Also cut clusters at concave creases of the depth image (with
    /// `CreaseConfig`'s defaults).
    pub crease_split: bool,
}

impl Default for SegmentSettings {
    fn default() -> Self {
        let cluster = mvgrasp_core::ClusterConfig::default();
        Self {
            tolerance_m: cluster.tolerance_m,
            crease_split: cluster.crease.is_some(),
        }
    }
}

/// How grasps are read from the network's maps and ranked (`core::decode`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DecodeSettings {
    /// Candidate grasps (peaks of the quality map) per view.
    pub peaks_per_view: usize,
    /// Quality taken off per 10 cm between the object's visible centre and
    /// the closing line (`DecodeConfig::centre_weight`; 0: quality alone).
    pub centre_weight: f32,
    /// How much wider than the gripper's stroke a predicted opening may be
    /// and still be decoded at the full stroke for the hand check to judge
    /// (`DecodeConfig::wide_slack_m`, m; 0: the network's width alone refuses it).
    pub wide_slack_m: f64,
    /// How far a grasp whose fingertips stop above the middle of its
    /// object's height may be pushed towards it, where the hand check and
    /// the table allow (`HandConfig::deepen_to_middle_m`, m; 0: never).
    pub deepen_to_middle_m: f64,
    /// Refuse a grasp whose hand, where the approach starts, is inside
    /// another object's box, as the robot-bridge's pre-grasp check would
    /// (`HandConfig::pregrasp_boxes`).
    pub pregrasp_boxes: bool,
}

impl Default for DecodeSettings {
    fn default() -> Self {
        let decode = mvgrasp_core::DecodeConfig::default();
        let hand = mvgrasp_core::PlannerConfig::default().hand;
        Self {
            peaks_per_view: decode.peaks_per_view,
            centre_weight: decode.centre_weight,
            wide_slack_m: decode.wide_slack_m,
            deepen_to_middle_m: hand.deepen_to_middle_m,
            pregrasp_boxes: hand.pregrasp_boxes,
        }
    }
}

/// Which virtual views of each object the planner renders (`core::view`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ViewSettings {
    /// View names (`top`, `front`, `side`, `top_front`, `top_side`), in the
    /// order ties in entropy are broken.
    pub axes: Vec<String>,
}

impl Default for ViewSettings {
    fn default() -> Self {
        Self {
            axes: mvgrasp_core::PlannerConfig::default()
                .views
                .iter()
                .map(|a| a.name().to_owned())
                .collect(),
        }
    }
}

impl ViewSettings {
    /// The named views, or the first name that is unknown or repeated.
    pub fn parse(&self) -> Result<Vec<mvgrasp_core::ViewAxis>, String> {
        let mut axes = Vec::with_capacity(self.axes.len());
        for name in &self.axes {
            let axis = mvgrasp_core::ViewAxis::from_name(name).ok_or_else(|| {
                let known: Vec<&str> = mvgrasp_core::ViewAxis::EVERY.iter().map(|a| a.name()).collect();
                format!("unknown view {name:?} ({})", known.join(", "))
            })?;
            if axes.contains(&axis) {
                return Err(format!("view {name:?} is named twice"));
            }
            axes.push(axis);
        }
        if axes.is_empty() {
            return Err("at least one view is needed".into());
        }
        Ok(axes)
    }
}

/// Transport security and who may plan (`[security]`; all optional: by
/// default the gRPC port is plaintext and open, for a trusted network).
#[derive(Debug, Clone, PartialEq, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SecuritySettings {
    /// PEM certificate chain of the server; with `tls_key`, the gRPC port
    /// speaks TLS only.
    pub tls_cert: Option<PathBuf>,
    /// PEM private key of `tls_cert`.
    pub tls_key: Option<PathBuf>,
    /// PEM CA certificate(s): clients must present a certificate signed by
    /// one of them (mutual TLS); needs `tls_cert`.
    pub tls_client_ca: Option<PathBuf>,
    /// File holding the token planning calls must send as
    /// `authorization: Bearer <token>` (health and reflection stay open).
    pub bearer_token_file: Option<PathBuf>,
    /// Plaintext address serving only the gRPC health service, for probes
    /// that cannot speak TLS (Kubernetes' gRPC probes).
    pub health_listen: Option<SocketAddr>,
}

/// All settings of the server.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Settings {
    /// gRPC address.
    pub listen: SocketAddr,
    /// Prometheus `/metrics` address; unset: no metrics endpoint.
    pub metrics_listen: Option<SocketAddr>,
    /// The model.
    pub model: ModelSettings,
    /// Batching.
    pub batching: BatchSettings,
    /// Limits.
    pub limits: Limits,
    /// Request defaults.
    pub defaults: RequestDefaults,
    /// Segmentation.
    pub segment: SegmentSettings,
    /// Decoding and ranking.
    pub decode: DecodeSettings,
    /// Which views are rendered.
    pub views: ViewSettings,
    /// TLS, mutual TLS, bearer token, the plaintext health port.
    pub security: SecuritySettings,
    /// How long SIGTERM waits for in-flight calls before closing (s).
    pub shutdown_grace_s: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            listen: SocketAddr::from(([0, 0, 0, 0], 50051)),
            metrics_listen: Some(SocketAddr::from(([0, 0, 0, 0], 9464))),
            model: ModelSettings::default(),
            batching: BatchSettings::default(),
            limits: Limits::default(),
            defaults: RequestDefaults::default(),
            segment: SegmentSettings::default(),
            decode: DecodeSettings::default(),
            views: ViewSettings::default(),
            security: SecuritySettings::default(),
            shutdown_grace_s: 10.0,
        }
    }
}

/// Flags; each also reads its `MVGRASP_*` environment variable (flags win).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct Overrides {
    /// TOML file with any of the settings (see deploy/server.toml).
    #[arg(long, env = "MVGRASP_CONFIG")]
    pub config: Option<PathBuf>,
    /// gRPC address, e.g. 0.0.0.0:50051.
    #[arg(long, env = "MVGRASP_LISTEN")]
    pub listen: Option<SocketAddr>,
    /// Prometheus address, e.g. 0.0.0.0:9464.
    #[arg(long, env = "MVGRASP_METRICS_LISTEN")]
    pub metrics_listen: Option<SocketAddr>,
    /// Serve no metrics endpoint.
    #[arg(long, env = "MVGRASP_NO_METRICS")]
    pub no_metrics: bool,
    /// `onnx` (a model file) or `baseline` (analytic, no model).
    #[arg(long, env = "MVGRASP_BACKEND", value_enum)]
    pub backend: Option<BackendKind>,
    /// The ONNX model file.
    #[arg(long, env = "MVGRASP_MODEL")]
    pub model: Option<PathBuf>,
    /// The ONNX Runtime library (libonnxruntime.so.1.31.1).
    #[arg(long, env = "MVGRASP_ONNXRUNTIME")]
    pub onnxruntime: Option<PathBuf>,
    /// `cpu` or `cuda`.
    #[arg(long, env = "MVGRASP_DEVICE", value_enum)]
    pub device: Option<Device>,
    /// ONNX Runtime threads per network call.
    #[arg(long, env = "MVGRASP_INTRA_THREADS")]
    pub intra_threads: Option<usize>,
    /// ONNX Runtime threads for a network call that has the server to itself.
    #[arg(long, env = "MVGRASP_LONE_CALL_THREADS")]
    pub lone_call_threads: Option<usize>,
    /// Let ONNX Runtime's threads spin between calls.
    #[arg(long, env = "MVGRASP_SPIN_WAIT")]
    pub spin_wait: Option<bool>,
    /// cuDNN's convolution algorithm search under `--device cuda`.
    #[arg(long, env = "MVGRASP_CUDA_CONV_SEARCH", value_enum)]
    pub cuda_conv_search: Option<ConvSearch>,
    /// Sessions of the model, each running its own batches.
    #[arg(long, env = "MVGRASP_SESSIONS")]
    pub sessions: Option<usize>,
    /// Most views per network call.
    #[arg(long, env = "MVGRASP_MAX_BATCH_VIEWS")]
    pub max_batch_views: Option<usize>,
    /// Longest wait for a batch to fill (ms); 0 disables batching.
    #[arg(long, env = "MVGRASP_MAX_WAIT_MS")]
    pub max_wait_ms: Option<f64>,
    /// PEM certificate chain: the gRPC port speaks TLS (with --tls-key).
    #[arg(long, env = "MVGRASP_TLS_CERT")]
    pub tls_cert: Option<PathBuf>,
    /// PEM private key of --tls-cert.
    #[arg(long, env = "MVGRASP_TLS_KEY")]
    pub tls_key: Option<PathBuf>,
    /// PEM CA: clients need a certificate it signed (mutual TLS).
    #[arg(long, env = "MVGRASP_TLS_CLIENT_CA")]
    pub tls_client_ca: Option<PathBuf>,
    /// File with the bearer token planning calls must send.
    #[arg(long, env = "MVGRASP_BEARER_TOKEN_FILE")]
    pub bearer_token_file: Option<PathBuf>,
    /// Plaintext address for the gRPC health service alone (probes).
    #[arg(long, env = "MVGRASP_HEALTH_LISTEN")]
    pub health_listen: Option<SocketAddr>,
}

impl Settings {
    /// Defaults, then the TOML file, then environment and flags.
    pub fn load(overrides: &Overrides) -> Result<Self> {
        let mut settings = match &overrides.config {
            Some(path) => {
                let text = std::fs::read_to_string(path)
                    .map_err(|e| Error::Startup(format!("config {}: {e}", path.display())))?;
                Self::from_toml(&text)
                    .map_err(|e| Error::Startup(format!("config {}: {e}", path.display())))?
            }
            None => Self::default(),
        };
        settings.apply(overrides);
        settings.validate()?;
        Ok(settings)
    }

    /// Settings from TOML text (unset keys keep their defaults; unknown keys are errors).
    pub fn from_toml(text: &str) -> Result<Self> {
        toml::from_str(text).map_err(|e| Error::Startup(e.to_string()))
    }

    fn apply(&mut self, o: &Overrides) {
        if let Some(v) = o.listen {
            self.listen = v;
        }
        if let Some(v) = o.metrics_listen {
            self.metrics_listen = Some(v);
        }
        if o.no_metrics {
            self.metrics_listen = None;
        }
        if let Some(v) = o.backend {
            self.model.backend = v;
        }
        if let Some(v) = &o.model {
            self.model.path.clone_from(v);
        }
        if let Some(v) = &o.onnxruntime {
            self.model.onnxruntime_library = Some(v.clone());
        }
        if let Some(v) = o.device {
            self.model.device = v;
        }
        if let Some(v) = o.intra_threads {
            self.model.intra_threads = v;
        }
        if let Some(v) = o.lone_call_threads {
            self.model.lone_call_threads = v;
        }
        if let Some(v) = o.spin_wait {
            self.model.spin_wait = v;
        }
        if let Some(v) = o.cuda_conv_search {
            self.model.cuda_conv_search = v;
        }
        if let Some(v) = o.sessions {
            self.model.sessions = v;
        }
        if let Some(v) = o.max_batch_views {
            self.batching.max_batch_views = v;
        }
        if let Some(v) = o.max_wait_ms {
            self.batching.max_wait_ms = v;
        }
        let security = &mut self.security;
        for (flag, setting) in [
            (&o.tls_cert, &mut security.tls_cert),
            (&o.tls_key, &mut security.tls_key),
            (&o.tls_client_ca, &mut security.tls_client_ca),
            (&o.bearer_token_file, &mut security.bearer_token_file),
        ] {
            if flag.is_some() {
                setting.clone_from(flag);
            }
        }
        if let Some(v) = o.health_listen {
            security.health_listen = Some(v);
        }
    }

    /// Checks every value, naming the key that is off.
    pub fn validate(&self) -> Result<()> {
        let bad = |key: &str, reason: String| Err(Error::Startup(format!("`{key}`: {reason}")));
        let b = &self.batching;
        if !(1..=4096).contains(&b.max_batch_views) {
            return bad(
                "batching.max_batch_views",
                format!("{} is not in 1..=4096", b.max_batch_views),
            );
        }
        if !(b.max_wait_ms.is_finite() && (0.0..=1000.0).contains(&b.max_wait_ms)) {
            return bad(
                "batching.max_wait_ms",
                format!("{} is not in 0..=1000", b.max_wait_ms),
            );
        }
        if b.max_queued_views < b.max_batch_views {
            return bad(
                "batching.max_queued_views",
                format!(
                    "{} is below max_batch_views {}",
                    b.max_queued_views, b.max_batch_views
                ),
            );
        }
        let l = &self.limits;
        if l.max_message_bytes < 1024 {
            return bad(
                "limits.max_message_bytes",
                format!("{} is under 1 KiB", l.max_message_bytes),
            );
        }
        if l.max_image_pixels == 0 || l.max_cloud_points == 0 || l.max_in_flight == 0 {
            return bad(
                "limits",
                "max_image_pixels, max_cloud_points and max_in_flight must be > 0".into(),
            );
        }
        for (key, threads) in [
            ("model.intra_threads", self.model.intra_threads),
            ("model.lone_call_threads", self.model.lone_call_threads),
            ("model.sessions", self.model.sessions),
        ] {
            if !(1..=64).contains(&threads) {
                return bad(key, format!("{threads} is not in 1..=64"));
            }
        }
        let q = self.defaults.min_quality;
        if !(q.is_finite() && (0.0..=1.0).contains(&q)) {
            return bad("defaults.min_quality", format!("{q} is not in [0, 1]"));
        }
        let w = self.decode.centre_weight;
        if !(w.is_finite() && (0.0..=10.0).contains(&w)) {
            return bad("decode.centre_weight", format!("{w} is not in [0, 10]"));
        }
        let slack = self.decode.wide_slack_m;
        if !(slack.is_finite() && (0.0..=0.1).contains(&slack)) {
            return bad("decode.wide_slack_m", format!("{slack} is not in [0, 0.1]"));
        }
        let middle = self.decode.deepen_to_middle_m;
        if !(middle.is_finite() && (0.0..=0.1).contains(&middle)) {
            return bad(
                "decode.deepen_to_middle_m",
                format!("{middle} is not in [0, 0.1]"),
            );
        }
        if !(1..=64).contains(&self.decode.peaks_per_view) {
            return bad(
                "decode.peaks_per_view",
                format!("{} is not in 1..=64", self.decode.peaks_per_view),
            );
        }
        let t = self.segment.tolerance_m;
        if !(t.is_finite() && (0.001..=0.1).contains(&t)) {
            return bad("segment.tolerance_m", format!("{t} is not in [0.001, 0.1]"));
        }
        if let Err(why) = self.views.parse() {
            return bad("views.axes", why);
        }
        if self.defaults.max_grasps == 0 {
            return bad("defaults.max_grasps", "must be > 0".into());
        }
        let tls = &self.security;
        if tls.tls_cert.is_some() != tls.tls_key.is_some() {
            return bad("security.tls_cert", "tls_cert and tls_key go together".into());
        }
        if tls.tls_client_ca.is_some() && tls.tls_cert.is_none() {
            return bad(
                "security.tls_client_ca",
                "mutual TLS needs tls_cert and tls_key".into(),
            );
        }
        if !(self.shutdown_grace_s.is_finite() && self.shutdown_grace_s >= 0.0) {
            return bad(
                "shutdown_grace_s",
                format!("{} is not >= 0", self.shutdown_grace_s),
            );
        }
        Ok(())
    }

    /// The planner's settings: its defaults with `[segment]`, `[decode]`
    /// and `[views]` applied; Err with the `[views]` problem `validate`
    /// reports.
    pub fn planner_config(&self) -> Result<mvgrasp_core::PlannerConfig, String> {
        let mut config = mvgrasp_core::PlannerConfig::default();
        config.cluster.tolerance_m = self.segment.tolerance_m;
        config.cluster.crease = self
            .segment
            .crease_split
            .then(mvgrasp_core::CreaseConfig::default);
        config.decode.centre_weight = self.decode.centre_weight;
        config.decode.peaks_per_view = self.decode.peaks_per_view;
        config.decode.wide_slack_m = self.decode.wide_slack_m;
        config.hand.deepen_to_middle_m = self.decode.deepen_to_middle_m;
        config.hand.pregrasp_boxes = self.decode.pregrasp_boxes;
        config.views = self.views.parse()?;
        Ok(config)
    }

    /// The number of requests that run CPU stages at once.
    pub fn cpu_workers(&self) -> usize {
        match self.limits.cpu_workers {
            0 => std::thread::available_parallelism().map_or(2, |n| n.get()),
            n => n,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layers_apply_in_order() {
        let toml = "listen = \"127.0.0.1:7000\"\n[batching]\nmax_batch_views = 8\nmax_wait_ms = 5.0\n";
        let mut s = Settings::from_toml(toml).unwrap();
        assert_eq!(s.listen.port(), 7000);
        assert_eq!(s.batching.max_batch_views, 8);
        assert_eq!(s.limits, Limits::default());
        s.apply(&Overrides {
            max_batch_views: Some(16),
            no_metrics: true,
            ..Default::default()
        });
        assert_eq!(s.batching.max_batch_views, 16);
        assert_eq!(s.batching.max_wait_ms, 5.0);
        assert_eq!(s.metrics_listen, None);
        s.validate().unwrap();
    }

    #[test]
    fn views_are_named_in_the_file_and_checked() {
        use mvgrasp_core::ViewAxis;
        let s = Settings::from_toml("").unwrap();
        assert_eq!(
            s.planner_config().unwrap().views,
            ViewAxis::ALL.to_vec(),
            "the paper's three by default"
        );
        let s = Settings::from_toml("[views]\naxes = [\"top\", \"top_front\", \"top_side\"]\n").unwrap();
        s.validate().unwrap();
        assert_eq!(
            s.planner_config().unwrap().views,
            [ViewAxis::Top, ViewAxis::TopFront, ViewAxis::TopSide]
        );
        for (axes, why) in [
            ("[\"top\", \"diagonal\"]", "unknown view \"diagonal\""),
            ("[\"side\", \"side\"]", "named twice"),
            ("[]", "at least one view"),
        ] {
            let s = Settings::from_toml(&format!("[views]\naxes = {axes}\n")).unwrap();
            let err = s.validate().unwrap_err().to_string();
            assert!(err.contains("views.axes") && err.contains(why), "{axes}: {err}");
            let err = s.planner_config().unwrap_err();
            assert!(err.contains(why), "no default views in place of {axes}: {err}");
        }
    }

    #[test]
    fn the_cuda_search_is_read_from_file_and_flags() {
        let mut s = Settings::from_toml("[model]\ncuda_conv_search = \"heuristic\"\n").unwrap();
        assert_eq!(s.model.cuda_conv_search, ConvSearch::Heuristic);
        s.apply(&Overrides {
            cuda_conv_search: Some(ConvSearch::Default),
            ..Default::default()
        });
        assert_eq!(s.model.cuda_conv_search, ConvSearch::Default);
        let err = Settings::from_toml("[model]\ncuda_conv_search = \"fastest\"\n").unwrap_err();
        assert!(err.to_string().contains("fastest"), "{err}");
    }

    #[test]
    fn the_documented_config_file_states_the_defaults() {
        let documented = Settings::from_toml(include_str!("../../deploy/server.toml")).unwrap();
        assert_eq!(documented, Settings::default());
    }

    #[test]
    fn bad_settings_name_the_key() {
        let err = Settings::from_toml("[batching]\nmax_batch_viewz = 8\n").unwrap_err();
        assert!(err.to_string().contains("max_batch_viewz"), "{err}");
        let mut s = Settings::default();
        s.batching.max_batch_views = 0;
        assert!(
            s.validate()
                .unwrap_err()
                .to_string()
                .contains("batching.max_batch_views")
        );
        let mut s = Settings::default();
        s.defaults.min_quality = f32::NAN;
        assert!(
            s.validate()
                .unwrap_err()
                .to_string()
                .contains("defaults.min_quality")
        );
        let mut s = Settings::default();
        s.segment.tolerance_m = 0.0;
        assert!(
            s.validate()
                .unwrap_err()
                .to_string()
                .contains("segment.tolerance_m")
        );
    }

    #[test]
    fn the_segment_and_decode_sections_reach_the_planner() {
        let defaults = Settings::default().planner_config().unwrap();
        assert_eq!(defaults.cluster, mvgrasp_core::ClusterConfig::default());
        assert_eq!(defaults.decode, mvgrasp_core::DecodeConfig::default());
        let s = Settings::from_toml(
            "[segment]\ntolerance_m = 0.02\ncrease_split = true\n[decode]\ncentre_weight = 0.5\npeaks_per_view = 8\nwide_slack_m = 0.03\ndeepen_to_middle_m = 0.04\npregrasp_boxes = false\n",
        )
        .unwrap();
        let config = s.planner_config().unwrap();
        assert_eq!(config.cluster.tolerance_m, 0.02);
        assert_eq!(config.cluster.crease, Some(mvgrasp_core::CreaseConfig::default()));
        assert_eq!(config.decode.centre_weight, 0.5);
        assert_eq!(config.decode.peaks_per_view, 8);
        assert_eq!(config.decode.wide_slack_m, 0.03);
        assert_eq!(config.hand.deepen_to_middle_m, 0.04);
        assert!(!config.hand.pregrasp_boxes);
        assert!(defaults.hand.pregrasp_boxes);
        assert_eq!(defaults.hand, mvgrasp_core::PlannerConfig::default().hand);
        for slack in [-0.01, 0.2, f64::NAN] {
            let mut s = Settings::default();
            s.decode.wide_slack_m = slack;
            assert!(
                s.validate()
                    .unwrap_err()
                    .to_string()
                    .contains("decode.wide_slack_m"),
                "{slack}"
            );
            let mut s = Settings::default();
            s.decode.deepen_to_middle_m = slack;
            assert!(
                s.validate()
                    .unwrap_err()
                    .to_string()
                    .contains("decode.deepen_to_middle_m"),
                "{slack}"
            );
        }
        let mut s = Settings::default();
        s.decode.centre_weight = f32::NAN;
        assert!(
            s.validate()
                .unwrap_err()
                .to_string()
                .contains("decode.centre_weight")
        );
        let mut s = Settings::default();
        s.decode.peaks_per_view = 0;
        assert!(
            s.validate()
                .unwrap_err()
                .to_string()
                .contains("decode.peaks_per_view")
        );
    }

    #[test]
    fn lone_call_threads_are_read_overridden_and_checked() {
        let mut s = Settings::from_toml("[model]\nlone_call_threads = 4\n").unwrap();
        assert_eq!(s.model.lone_call_threads, 4);
        s.apply(&Overrides {
            lone_call_threads: Some(1),
            ..Default::default()
        });
        assert_eq!(s.model.lone_call_threads, 1);
        s.validate().unwrap();
        s.model.lone_call_threads = 0;
        let err = s.validate().unwrap_err().to_string();
        assert!(err.contains("model.lone_call_threads"), "{err}");
    }

    #[test]
    fn sessions_are_read_overridden_and_checked() {
        assert_eq!(Settings::default().model.sessions, 2);
        let mut s = Settings::from_toml("[model]\nsessions = 3\n").unwrap();
        assert_eq!(s.model.sessions, 3);
        s.apply(&Overrides {
            sessions: Some(1),
            ..Default::default()
        });
        assert_eq!(s.model.sessions, 1);
        s.validate().unwrap();
        s.model.sessions = 0;
        let err = s.validate().unwrap_err().to_string();
        assert!(err.contains("model.sessions"), "{err}");
    }
}
