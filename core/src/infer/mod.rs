//! Inference as a trait: a batch of views in, per-pixel grasp maps out.
//!
//! The server implements [`GraspNet`] with ONNX Runtime; tests and the
//! simulator can use [`MomentsNet`] (an analytic baseline) or any fake.

mod contract;
mod moments;

pub use contract::{Channel, ModelContract, NORMALISATION_CUBE_V1, keys};
pub use moments::MomentsNet;

use crate::error::{Error, Result};

/// Views stacked for the network: `len x 1 x size x size`, row-major (NCHW).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ViewBatch {
    /// View side in pixels.
    pub size_px: usize,
    /// Number of views.
    pub len: usize,
    /// `len * size_px * size_px` normalised depth values.
    pub data: Vec<f32>,
}

impl ViewBatch {
    /// An empty batch of `size_px` views.
    pub fn new(size_px: usize) -> Self {
        Self {
            size_px,
            len: 0,
            data: Vec::new(),
        }
    }

    /// Appends one view image (`size_px * size_px` values).
    pub fn push(&mut self, image: &[f32]) {
        debug_assert_eq!(image.len(), self.size_px * self.size_px);
        self.data.extend_from_slice(image);
        self.len += 1;
    }

    /// The `i`-th view.
    pub fn view(&self, i: usize) -> &[f32] {
        let n = self.size_px * self.size_px;
        &self.data[i * n..(i + 1) * n]
    }
}

/// Network output: `len x 4 x size x size` (NCHW), channels in the contract's order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GraspMaps {
    /// Map side in pixels.
    pub size_px: usize,
    /// Number of views.
    pub len: usize,
    /// The values.
    pub data: Vec<f32>,
}

impl GraspMaps {
    /// Checks the maps fit `batch`, naming what is off.
    pub fn check_matches(&self, batch: &ViewBatch) -> Result<()> {
        let expected = batch.len * 4 * batch.size_px * batch.size_px;
        if self.size_px != batch.size_px || self.len != batch.len || self.data.len() != expected {
            return Err(Error::Backend(format!(
                "maps are {} x 4 x {} px with {} values; the batch needs {} x 4 x {} px ({expected} values)",
                self.len,
                self.size_px,
                self.data.len(),
                batch.len,
                batch.size_px
            )));
        }
        Ok(())
    }

    /// Channel `channel_index` of view `view`.
    pub fn channel(&self, view: usize, channel_index: usize) -> &[f32] {
        let n = self.size_px * self.size_px;
        let start = (view * 4 + channel_index) * n;
        &self.data[start..start + n]
    }
}

/// A grasp network: per-pixel quality, cos 2phi, sin 2phi and width for a batch of views.
pub trait GraspNet {
    /// What the network expects and returns.
    fn contract(&self) -> &ModelContract;

    /// Runs the network on `batch`; the result must match [`GraspMaps::check_matches`].
    fn infer(&mut self, batch: &ViewBatch) -> Result<GraspMaps>;
}
