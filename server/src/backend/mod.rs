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
    /// Further sessions of the same file (`model.sessions` less one), each
    /// run by its own batching worker.
    pub more: Vec<Box<dyn GraspNet + Send>>,
    /// The same network with more threads, for a call that has the server
    /// to itself (`model.lone_call_threads`; CPU only).
    pub lone: Option<Box<dyn GraspNet + Send>>,
    /// `onnxruntime-cpu`, `onnxruntime-cuda` or `baseline-moments`.
    pub backend: &'static str,
}

impl std::fmt::Debug for LoadedNet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LoadedNet")
            .field("model_version", &self.net.contract().model_version)
            .field("backend", &self.backend)
            .field("sessions", &(1 + self.more.len()))
            .field("lone", &self.lone.is_some())
            .finish()
    }
}

/// Loads the backend that `settings` names. `batch_views` is the most views
/// the batcher puts in one network call (the CUDA backend runs every call at
/// that size, see [`OnnxNet::load`]). On the CPU, with `lone_call_threads`
/// over `intra_threads`, a second session of the file runs with that many
/// threads.
pub fn load(settings: &ModelSettings, batch_views: usize) -> Result<LoadedNet> {
    match settings.backend {
        BackendKind::Onnx => {
            let net = OnnxNet::load(settings, batch_views)?;
            let backend = net.provider();
            let lone = if backend == "onnxruntime-cpu" && settings.lone_call_threads > settings.intra_threads
            {
                let wide = ModelSettings {
                    intra_threads: settings.lone_call_threads,
                    ..settings.clone()
                };
                Some(Box::new(OnnxNet::load(&wide, batch_views)?) as Box<dyn GraspNet + Send>)
            } else {
                None
            };
            let more = (1..settings.sessions)
                .map(|_| Ok(Box::new(OnnxNet::load(settings, batch_views)?) as Box<dyn GraspNet + Send>))
                .collect::<Result<_>>()?;
            Ok(LoadedNet {
                net: Box::new(net),
                more,
                lone,
                backend,
            })
        }
        BackendKind::Baseline => Ok(LoadedNet {
            net: Box::new(MomentsNet::default()),
            more: (1..settings.sessions)
                .map(|_| Box::new(MomentsNet::default()) as Box<dyn GraspNet + Send>)
                .collect(),
            lone: None,
            backend: "baseline-moments",
        }),
    }
}
