//! The ONNX Runtime backend: one session, run by the batching worker.

use std::{
    path::{Path, PathBuf},
    sync::OnceLock,
};

use mvgrasp_core::{Error as CoreError, GraspMaps, GraspNet, ModelContract, ViewBatch};
use ort::{environment::Environment, session::Session, value::TensorRef};

use crate::{
    error::{Error, Result},
    settings::{Device, ModelSettings},
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
    pub fn load(settings: &ModelSettings) -> Result<Self> {
        let env = environment(&onnxruntime_library(settings))?;
        let startup = |what: &str, e: &dyn std::fmt::Display| Error::Startup(format!("{what}: {e}"));
        let mut builder = Session::builder(env)
            .map_err(|e| startup("session builder", &e))?
            .with_intra_threads(settings.intra_threads)
            .map_err(|e| startup("intra threads", &e))?
            .with_inter_threads(1)
            .map_err(|e| startup("inter threads", &e))?
            .with_config_entry(
                "session.intra_op.allow_spinning",
                if settings.spin_wait { "1" } else { "0" },
            )
            .map_err(|e| startup("spin setting", &e))?;
        let mut provider = "onnxruntime-cpu";
        if settings.device == Device::Cuda {
            (builder, provider) = with_cuda(builder);
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
        Ok(Self {
            session,
            contract,
            provider,
        })
    }

    /// `onnxruntime-cpu` or `onnxruntime-cuda`.
    pub fn provider(&self) -> &'static str {
        self.provider
    }
}

#[cfg(feature = "cuda")]
fn with_cuda(
    builder: ort::session::builder::SessionBuilder,
) -> (ort::session::builder::SessionBuilder, &'static str) {
    use ort::ep::ExecutionProvider;
    let cuda = ort::ep::CUDA::default();
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
        let input = TensorRef::from_array_view(([batch.len, 1, l, l], batch.data.as_slice()))
            .map_err(|e| backend("input tensor", &e))?;
        let outputs = self
            .session
            .run(ort::inputs![input])
            .map_err(|e| backend("run", &e))?;
        let (shape, data) = outputs[0]
            .try_extract_tensor::<f32>()
            .map_err(|e| backend("output tensor", &e))?;
        let expected = [batch.len as i64, 4, l as i64, l as i64];
        if shape.as_ref() != expected {
            return Err(CoreError::Backend(format!(
                "output shape {:?}, expected {expected:?}",
                shape.as_ref()
            )));
        }
        Ok(GraspMaps {
            size_px: l,
            len: batch.len,
            data: data.to_vec(),
        })
    }
}
