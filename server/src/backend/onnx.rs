//! The ONNX Runtime backend: one session, run by the batching worker.

use std::{
    path::{Path, PathBuf},
    sync::OnceLock,
};

use mvgrasp_core::{Error as CoreError, GraspMaps, GraspNet, ModelContract, ViewBatch};
use ort::{
    environment::Environment,
    session::{Session, builder::GraphOptimizationLevel},
    value::TensorRef,
};

use crate::{
    error::{Error, Result},
    settings::{ConvSearch, Device, ModelSettings},
};

/// ONNX Runtime can be loaded once per process; the first library wins.
static ENVIRONMENT: OnceLock<Result<(PathBuf, Environment), String>> = OnceLock::new();

/// The library to load: the setting, else `ORT_DYLIB_PATH`, else the loader's search path.
pub fn onnxruntime_library(settings: &ModelSettings) -> PathBuf {
    settings
        .onnxruntime_library
        .clone()
        .or_else(|| std::env::var_os("ORT_DYLIB_PATH").map(PathBuf::from))
        .unwrap_or_else(|| PathBuf::from("libonnxruntime.so.1.31.1"))
}

fn environment(library: &Path) -> Result<&'static Environment> {
    let loaded = ENVIRONMENT.get_or_init(|| {
        let builder = ort::init_from(library).map_err(|e| format!("loading {}: {e}", library.display()))?;
        let env = builder
            .with_name("mvgrasp")
            .build()
            .map_err(|e| format!("ONNX Runtime environment: {e}"))?;
        Ok((library.to_owned(), env))
    });
    match loaded {
        Ok((path, env)) if path == library => Ok(env),
        Ok((path, _)) => Err(Error::Startup(format!(
            "ONNX Runtime is already loaded from {} in this process; cannot also load {}",
            path.display(),
            library.display()
        ))),
        Err(e) => Err(Error::Startup(e.clone())),
    }
}

/// A grasp network in an ONNX file, run by ONNX Runtime.
pub struct OnnxNet {
    session: Session,
    contract: ModelContract,
    provider: &'static str,
    /// Under CUDA, every batch is padded to this many views (0: no padding).
    fixed_batch: usize,
}

impl std::fmt::Debug for OnnxNet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnnxNet")
            .field("model_version", &self.contract.model_version)
            .field("provider", &self.provider)
            .finish()
    }
}

impl OnnxNet {
    /// Loads the model named by `settings`, reading its contract from the metadata.
    ///
    /// Under the CUDA provider every batch runs padded to `batch_views` views
    /// (a larger single request runs at its own size), and that size is run
    /// once here. Measured on an H100 (BENCHMARKS.md): a network call of up
    /// to 64 views takes under 2 ms, but each change of the input's batch
    /// size cost about as much as cuDNN's algorithm search for a new shape
    /// (185-270 ms exhaustive, about 40 ms heuristic, 9-16 ms default).
    /// With 16 clients and unpadded (or power-of-two) batch sizes that
    /// dominated: 39-65 calls/s. One fixed shape never changes.
    pub fn load(settings: &ModelSettings, batch_views: usize) -> Result<Self> {
        let env = environment(&onnxruntime_library(settings))?;
        let startup = |what: &str, e: &dyn std::fmt::Display| Error::Startup(format!("{what}: {e}"));
        let mut builder = Session::builder(env)
            .map_err(|e| startup("session builder", &e))?
            .with_intra_threads(settings.intra_threads)
            .map_err(|e| startup("intra threads", &e))?
            .with_inter_threads(1)
            .map_err(|e| startup("inter threads", &e))?
            // Every rewrite, the NCHWc layout and the int8 file's QDQ fusion
            // included: ONNX Runtime's own default, named so that a default
            // that moves does not move the server (the fastest level for
            // both shipped files: docs/experiments/2026-12-08-what-is-left-on-two-cores.md).
            .with_optimization_level(GraphOptimizationLevel::All)
            .map_err(|e| startup("graph optimisation level", &e))?
            .with_config_entry(
                "session.intra_op.allow_spinning",
                if settings.spin_wait { "1" } else { "0" },
            )
            .map_err(|e| startup("spin setting", &e))?;
        let mut provider = "onnxruntime-cpu";
        if settings.device == Device::Cuda {
            (builder, provider) = with_cuda(builder, settings.cuda_conv_search);
        }
        let path = &settings.path;
        let session = builder
            .commit_from_file(path)
            .map_err(|e| startup(&format!("loading model {}", path.display()), &e))?;
        let metadata = session
            .metadata()
            .map_err(|e| startup("reading model metadata", &e))?;
        let contract = ModelContract::from_metadata(|key| metadata.custom(key))
            .map_err(|e| Error::Startup(format!("{}: {e}", path.display())))?;
        drop(metadata);
        if session.inputs().len() != 1 || session.outputs().len() != 1 {
            return Err(Error::Startup(format!(
                "{}: the model has {} inputs and {} outputs; the contract needs 1 and 1",
                path.display(),
                session.inputs().len(),
                session.outputs().len()
            )));
        }
        let mut net = Self {
            session,
            contract,
            provider,
            fixed_batch: if provider == "onnxruntime-cuda" {
                batch_views.max(1)
            } else {
                0
            },
        };
        if net.fixed_batch > 0 {
            net.warm_up()?;
        }
        Ok(net)
    }

    /// Runs the fixed batch size once, so that cuDNN's algorithm search
    /// happens before the first request, then a few more times to log its cost.
    fn warm_up(&mut self) -> Result<()> {
        const TIMED_RUNS: usize = 5;
        let l = self.contract.input_size_px;
        let len = self.fixed_batch;
        let batch = ViewBatch {
            size_px: l,
            len,
            data: vec![0.0; len * l * l],
        };
        let mut ms = Vec::with_capacity(TIMED_RUNS + 1);
        for _ in 0..=TIMED_RUNS {
            let t0 = std::time::Instant::now();
            self.infer(&batch)
                .map_err(|e| Error::Startup(format!("warming up a batch of {len} views: {e}")))?;
            ms.push(t0.elapsed().as_secs_f64() * 1e3);
        }
        let first = ms.remove(0);
        ms.sort_by(f64::total_cmp);
        tracing::info!(
            views = len,
            first_ms = first,
            median_ms = ms[ms.len() / 2],
            "CUDA warm-up"
        );
        Ok(())
    }

    /// Pads every batch to at least `views` views (0: never), dropping the
    /// padding's maps. `load` sets this under CUDA; public so that tests can
    /// check the padding on the CPU provider.
    pub fn pad_batches_to(&mut self, views: usize) {
        self.fixed_batch = views;
    }

    /// `onnxruntime-cpu` or `onnxruntime-cuda`.
    pub fn provider(&self) -> &'static str {
        self.provider
    }
}

#[cfg(feature = "cuda")]
fn with_cuda(
    builder: ort::session::builder::SessionBuilder,
    search: ConvSearch,
) -> (ort::session::builder::SessionBuilder, &'static str) {
    use ort::ep::{ExecutionProvider, cuda::ConvAlgorithmSearch};
    let cuda = ort::ep::CUDA::default().with_conv_algorithm_search(match search {
        ConvSearch::Exhaustive => ConvAlgorithmSearch::Exhaustive,
        ConvSearch::Heuristic => ConvAlgorithmSearch::Heuristic,
        ConvSearch::Default => ConvAlgorithmSearch::Default,
    });
    match ort::ep::CUDA::is_available() {
        Ok(true) => {}
        Ok(false) => {
            tracing::warn!("this ONNX Runtime has no CUDA execution provider; running on the CPU");
            return (builder, "onnxruntime-cpu");
        }
        Err(e) => {
            tracing::warn!(error = %e, "cannot query ONNX Runtime's providers; running on the CPU");
            return (builder, "onnxruntime-cpu");
        }
    }
    match builder.with_execution_providers([cuda.build().error_on_failure()]) {
        Ok(b) => (b, "onnxruntime-cuda"),
        Err(e) => {
            tracing::warn!(error = %e, "the CUDA execution provider failed to register; running on the CPU");
            (e.recover(), "onnxruntime-cpu")
        }
    }
}

#[cfg(not(feature = "cuda"))]
fn with_cuda(
    builder: ort::session::builder::SessionBuilder,
    _search: ConvSearch,
) -> (ort::session::builder::SessionBuilder, &'static str) {
    tracing::warn!("device = cuda, but this server was built without the `cuda` feature; running on the CPU");
    (builder, "onnxruntime-cpu")
}

impl GraspNet for OnnxNet {
    fn contract(&self) -> &ModelContract {
        &self.contract
    }

    fn infer(&mut self, batch: &ViewBatch) -> mvgrasp_core::Result<GraspMaps> {
        let l = batch.size_px;
        let backend = |what: &str, e: &dyn std::fmt::Display| CoreError::Backend(format!("{what}: {e}"));
        let run_len = batch.len.max(self.fixed_batch);
        let padded;
        let data = if run_len > batch.len {
            let mut v = Vec::with_capacity(run_len * l * l);
            v.extend_from_slice(&batch.data);
            v.resize(run_len * l * l, 0.0);
            padded = v;
            padded.as_slice()
        } else {
            batch.data.as_slice()
        };
        let input = TensorRef::from_array_view(([run_len, 1, l, l], data))
            .map_err(|e| backend("input tensor", &e))?;
        let outputs = self
            .session
            .run(ort::inputs![input])
            .map_err(|e| backend("run", &e))?;
        let (shape, data) = outputs[0]
            .try_extract_tensor::<f32>()
            .map_err(|e| backend("output tensor", &e))?;
        let expected = [run_len as i64, 4, l as i64, l as i64];
        if shape.as_ref() != expected {
            return Err(CoreError::Backend(format!(
                "output shape {:?}, expected {expected:?}",
                shape.as_ref()
            )));
        }
        Ok(GraspMaps {
            size_px: l,
            len: batch.len,
            data: data[..batch.len * 4 * l * l].to_vec(),
        })
    }
}
