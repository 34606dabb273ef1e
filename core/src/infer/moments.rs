//! An analytic baseline network: grasp across the silhouette's minor axis at
//! its centroid.
//!
//! It needs no model file, so tests, benchmarks and the simulator can run the
//! whole pipeline before (or beside) a trained network. It is not a learned
//! grasp predictor: it does not look at depth variation, and its quality map
//! is a Gaussian bump around the silhouette centroid, scaled by how solid the
//! silhouette is there.

use super::{Channel, GraspMaps, GraspNet, ModelContract, ViewBatch};
use crate::error::Result;
use crate::view::{silhouette_extent_px, silhouette_share};

/// The analytic baseline (see the module docs).
#[derive(Debug, Clone)]
pub struct MomentsNet {
    contract: ModelContract,
    /// Width of the quality bump (px).
    pub sigma_px: f32,
    /// Opening added on both sides of the measured extent (m).
    pub margin_m: f32,
}

impl Default for MomentsNet {
    fn default() -> Self {
        Self::new(ModelContract::baseline())
    }
}

impl MomentsNet {
    /// A baseline speaking `contract` (its size, pixel size, width scale and channel order).
    pub fn new(contract: ModelContract) -> Self {
        Self {
            contract,
            sigma_px: 3.0,
            margin_m: 0.01,
        }
    }

    fn one_view(&self, image: &[f32], out: &mut [f32]) {
        let l = self.contract.input_size_px;
        let n = l * l;
        let (mut m0, mut mu, mut mv) = (0.0f64, 0.0f64, 0.0f64);
        for (i, &value) in image.iter().enumerate() {
            if value > 0.0 {
                m0 += 1.0;
                mu += (i % l) as f64;
                mv += (i / l) as f64;
            }
        }
        if m0 < 3.0 {
            return; // all-zero maps: no grasp
        }
        let (cu, cv) = (mu / m0, mv / m0);
        let (mut c20, mut c02, mut c11) = (0.0, 0.0, 0.0);
        for (i, &value) in image.iter().enumerate() {
            if value > 0.0 {
                let (du, dv) = ((i % l) as f64 - cu, (i / l) as f64 - cv);
                c20 += du * du;
                c02 += dv * dv;
                c11 += du * dv;
            }
        }
        let major = 0.5 * (2.0 * c11).atan2(c20 - c02);
        let closing = major + std::f64::consts::FRAC_PI_2;
        let (du, dv) = (closing.cos(), closing.sin());
        // Extent along the closing direction through the centroid.
        let extent_px = silhouette_extent_px(image, l, cu + 0.5, cv + 0.5, du, dv);
        let extent_m = extent_px as f32 * self.contract.pixel_size_m;
        let width = (extent_m + 2.0 * self.margin_m) / self.contract.width_scale_m;
        let solid = silhouette_share(image, l, cu + 0.5, cv + 0.5, (1.5 * self.sigma_px) as isize);
        let peak = 0.95 * solid;
        let (cos2, sin2) = ((2.0 * closing).cos() as f32, (2.0 * closing).sin() as f32);
        let inv_two_sigma_sq = 1.0 / (2.0 * self.sigma_px * self.sigma_px);
        let index = |c: Channel| self.contract.channel_index(c) * n;
        let (q0, c0, s0, w0) = (
            index(Channel::Quality),
            index(Channel::Cos2Phi),
            index(Channel::Sin2Phi),
            index(Channel::Width),
        );
        for i in 0..n {
            let (du, dv) = ((i % l) as f32 - cu as f32, (i / l) as f32 - cv as f32);
            let q = peak * (-(du * du + dv * dv) * inv_two_sigma_sq).exp();
            out[q0 + i] = if q > 1e-6 { q } else { 0.0 }; // no denormal tails
            out[c0 + i] = cos2;
            out[s0 + i] = sin2;
            out[w0 + i] = width;
        }
    }
}

impl GraspNet for MomentsNet {
    fn contract(&self) -> &ModelContract {
        &self.contract
    }

    fn infer(&mut self, batch: &ViewBatch) -> Result<GraspMaps> {
        let l = self.contract.input_size_px;
        let mut maps = GraspMaps {
            size_px: l,
            len: batch.len,
            data: vec![0.0; batch.len * 4 * l * l],
        };
        if batch.size_px != l {
            return Err(crate::Error::Backend(format!(
                "batch views are {} px, the network takes {l} px",
                batch.size_px
            )));
        }
        for i in 0..batch.len {
            let out = &mut maps.data[i * 4 * l * l..(i + 1) * 4 * l * l];
            self.one_view(batch.view(i), out);
        }
        Ok(maps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closes_across_the_short_side_of_a_bar() {
        let mut net = MomentsNet::default();
        let l = net.contract().input_size_px;
        // A bar 40 px long along u, 8 px wide, centred at (48, 48).
        let mut image = vec![0.0f32; l * l];
        for v in 44..52 {
            for u in 28..68 {
                image[v * l + u] = 0.6;
            }
        }
        let mut batch = ViewBatch::new(l);
        batch.push(&image);
        let maps = net.infer(&batch).unwrap();
        maps.check_matches(&batch).unwrap();
        let q = maps.channel(0, 0);
        let best = (0..l * l).max_by(|&a, &b| q[a].total_cmp(&q[b])).unwrap();
        assert_eq!((best % l, best / l), (48, 48));
        // closing along v: phi = +-90 deg -> cos 2phi = -1
        assert!((maps.channel(0, 1)[best] + 1.0).abs() < 1e-5);
        let width_m = maps.channel(0, 3)[best] * 0.2;
        assert!((width_m - (8.0 * 0.0025 + 0.02)).abs() < 0.0026, "{width_m}");
    }
}
