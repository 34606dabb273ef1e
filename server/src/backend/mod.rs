//! Inference backends: ONNX Runtime (the product) or the analytic baseline.

mod onnx;

pub use onnx::{OnnxNet, onnxruntime_library};

use mvgrasp_core::{GraspNet, MomentsNet};

use crate::{
    error::Result,
    settings::{BackendKind, ModelSettings},
};

/// A loaded network and the name of what runs it.
pub struct LoadedNet {
    /// The network.
    pub net: Box<dyn GraspNet + Send>,
    /// `onnxruntime-cpu`, `onnxruntime-cuda` or `baseline-moments`.
    pub backend: &'static str,
}

impl std::fmt::Debug for LoadedNet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LoadedNet")
            .field("model_version", &self.net.contract().model_version)
            .field("backend", &self.backend)
            .finish()
    }
}

/// Loads the backend that `settings` names. `batch_views` is the most views
/// the batcher puts in one network call (the CUDA backend runs every call at
/// that size, see [`OnnxNet::load`]).
pub fn load(settings: &ModelSettings, batch_views: usize) -> Result<LoadedNet> {
    match settings.backend {
        BackendKind::Onnx => {
            let net = OnnxNet::load(settings, batch_views)?;
            let backend = net.provider();
            Ok(LoadedNet {
                net: Box::new(net),
                backend,
            })
        }
        BackendKind::Baseline => Ok(LoadedNet {
            net: Box::new(MomentsNet::default()),
            backend: "baseline-moments",
        }),
    }
}
