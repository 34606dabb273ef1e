//! Training targets: each rendered view of each detected object, with
//! per-pixel quality, cos 2phi, sin 2phi and width maps from analytic grasp
//! labels.
//!
//! The views come from `mvgrasp-core` run on the rendered (noisy) frame, the
//! code that serves. Candidate grasps sit on a pixel grid over each
//! silhouette, at `angles` image angles, opened to the silhouette's extent
//! along the closing direction plus a margin ([`Opening`]). Each becomes a
//! 6-DoF grasp through `core::decode::grasp_at`, the function the planner
//! decodes with, and is labelled by [`crate::grasp::label_grasp`]; every
//! candidate that is not positive is counted by why it was refused
//! ([`LabelledView::refused`]). Positives are refined by
//! a short simulated annealing over angle and width. A positive's score is
//! scaled by its distance to the view centre (the paper's third term: 1 at
//! the centre, 0.75 at the edge).
//!
//! Painting: every positive writes a disc of `paint_radius_px` around its
//! pixel. Quality is its score, and the angle and width channels are its
//! own; where discs overlap, the higher quality wins. Pixels without a
//! positive are 0 in every channel, so quality 0 means "no grasp here".

use mvgrasp_core::decode::{ViewPlacement, grasp_at};
use mvgrasp_core::rng::SplitMix64;
use mvgrasp_core::view::{silhouette_extent_px, silhouette_reach_px};
use mvgrasp_core::{
    Channel, GraspMaps, GraspNet, ModelContract, PlanOptions, Planner, ViewAxis, ViewBatch, ViewPolicy,
};

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Point3};

use crate::camera::Frame;
use crate::error::{Error, Result};
use crate::grasp::{GraspLabel, GripperModel, label_grasp};
use crate::objects::Family;
use crate::scene::Scene;

/// How candidates are drawn and targets painted.
#[derive(Debug, Clone, PartialEq)]
pub struct TargetConfig {
    /// Candidate pixels every `stride_px` along rows and columns.
    pub stride_px: usize,
    /// Candidate image angles per pixel, spread over 180 degrees.
    pub angles: usize,
    /// How wide a candidate opens before the margin.
    pub opening: Opening,
    /// Opening beyond the silhouette's extent (m).
    pub width_margin_m: f64,
    /// Disc painted per positive (px).
    pub paint_radius_px: f32,
    /// Annealing steps per positive (0: none).
    pub anneal_steps: usize,
    /// Whether the labels count the other objects (false: each object is
    /// labelled as if it stood alone, where it is; the view shows only the
    /// object, so these are the labels its view can tell).
    pub neighbours: bool,
}

impl Default for TargetConfig {
    fn default() -> Self {
        Self {
            stride_px: 3,
            angles: 8,
            opening: Opening::Chord,
            width_margin_m: 0.01,
            paint_radius_px: 1.6,
            anneal_steps: 6,
            neighbours: true,
        }
    }
}

/// How wide a candidate grasp opens (before `width_margin_m` on each side).
/// The pads sit symmetrically about the candidate's pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Opening {
    /// The silhouette's extent along the closing line through the pixel
    /// (the labels so far): off the chord's middle one pad starts inside the
    /// object.
    Chord,
    /// Twice the farthest the silhouette reaches from the pixel either way,
    /// over the strip the pads sweep (the pad width across the closing
    /// line): the pads start outside the silhouette wherever they close.
    Pads,
}

impl Opening {
    /// Its command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Chord => "chord",
            Self::Pads => "pads",
        }
    }

    /// The opening (px) at image point `(x, y)` closing along the unit
    /// image direction `(c, s)`, for pads `pad_width_px` wide.
    pub fn width_px(
        self,
        image: &[f32],
        l: usize,
        x: f64,
        y: f64,
        (c, s): (f64, f64),
        pad_width_px: f64,
    ) -> f64 {
        match self {
            Self::Chord => silhouette_extent_px(image, l, x, y, c, s),
            Self::Pads => {
                let half = pad_width_px / 2.0;
                let rows = half.ceil() as i64;
                let far = (-rows..=rows)
                    .map(|k| (k as f64).clamp(-half, half))
                    .map(|o| {
                        let (ahead, behind) = silhouette_reach_px(image, l, x - o * s, y + o * c, c, s);
                        ahead.max(behind)
                    })
                    .fold(0.0, f64::max);
                2.0 * far + 1.0
            }
        }
    }
}

impl std::str::FromStr for Opening {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match s {
            "chord" => Ok(Self::Chord),
            "pads" => Ok(Self::Pads),
            other => Err(Error::Invalid {
                field: "candidate opening",
                reason: format!("`{other}`: expected chord or pads"),
            }),
        }
    }
}

impl TargetConfig {
    /// Refuses settings that would label nothing (a zero stride or no
    /// angles) and a pad compliance outside 0 to 20 mm.
    pub fn check(&self) -> Result<()> {
        if self.stride_px == 0 || self.angles == 0 {
            return Err(Error::Invalid {
                field: "targets",
                reason: format!(
                    "the candidate stride ({} px) and angles ({}) must both be at least 1",
                    self.stride_px, self.angles
                ),
            });
        }
        Ok(())
    }

    /// The gripper these labels judge grasps with: the Robotiq 2F-140.
    pub fn gripper(&self) -> GripperModel {
        GripperModel::robotiq_2f_140()
    }
}

/// One view with its targets.
#[derive(Debug, Clone)]
pub struct LabelledView {
    /// Index of the scene object it shows.
    pub object: usize,
    /// That object's family.
    pub family: Family,
    /// Which view.
    pub axis: ViewAxis,
    /// Network input (`size x size`, the contract's normalisation).
    pub image: Vec<f32>,
    /// Targets, `4 x size x size` in the contract's channel order.
    pub maps: Vec<f32>,
    /// Candidates labelled.
    pub candidates: usize,
    /// Positives among them.
    pub positives: usize,
    /// The other candidates, by why they were refused (their first
    /// labelling, before any annealing): [`GraspLabel::reason`]'s keys,
    /// plus "over stroke" (the silhouette plus margin is wider than the
    /// stroke) and "no pose" (no insertion keeps the pads above the table,
    /// or no surface under the pixel). They sum to `candidates - positives`.
    pub refused: BTreeMap<&'static str, usize>,
    /// The positives themselves (after annealing): the ground-truth grasps
    /// the paper's accuracy metric compares predictions with.
    pub grasps: Vec<PixelGrasp>,
}

/// A labelled positive grasp in view pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelGrasp {
    /// Column of the grasp centre.
    pub u: usize,
    /// Row of the grasp centre.
    pub v: usize,
    /// Image angle of the closing direction, in [-pi/2, pi/2).
    pub phi: f32,
    /// Opening (m).
    pub width_m: f32,
    /// Painted quality (score times the centre-distance factor).
    pub quality: f32,
    /// The 6-DoF grasp it was labelled as (world frame; grasp frame of
    /// `grasp.rs`), opened to `width_m`.
    pub world_from_grasp: Isometry3<f64>,
}

/// A network that predicts nothing: the pipeline's views, without inference.
struct NoNet(ModelContract);

impl GraspNet for NoNet {
    fn contract(&self) -> &ModelContract {
        &self.0
    }
    fn infer(&mut self, batch: &ViewBatch) -> mvgrasp_core::Result<GraspMaps> {
        Ok(GraspMaps {
            size_px: batch.size_px,
            len: batch.len,
            data: vec![0.0; batch.len * 4 * batch.size_px * batch.size_px],
        })
    }
}

/// Labels every view of every detected object in `frame` of `scene`.
pub fn label_frame(
    scene: &Scene,
    frame: &Frame,
    planner: &Planner,
    gripper: &GripperModel,
    config: &TargetConfig,
    rng: &mut SplitMix64,
) -> Result<Vec<LabelledView>> {
    config.check()?;
    let bytes = frame.depth_le_bytes();
    let input = frame.scene_input(&bytes, scene.workspace());
    let options = PlanOptions {
        view_policy: ViewPolicy::TopDown,
        keep_views: true,
        max_grasps: 1,
        min_quality: 1.0,
        // Only the views are wanted here (the stand-in network infers nothing).
        view_cascade: false,
        ..PlanOptions::default()
    };
    let contract = planner.contract().clone();
    let plan = planner
        .plan(&input, &options, &mut NoNet(contract.clone()))
        .map_err(|e| Error::Scene(format!("pipeline: {e}")))?;
    let core_gripper = gripper.planner_gripper();
    let decode = &planner.config().decode;
    let l = contract.input_size_px;
    let pixel_m = f64::from(contract.pixel_size_m);
    let (iq, ic, is, iw) = (
        contract.channel_index(Channel::Quality),
        contract.channel_index(Channel::Cos2Phi),
        contract.channel_index(Channel::Sin2Phi),
        contract.channel_index(Channel::Width),
    );
    let mut out = Vec::new();
    for dv in &plan.debug_views {
        let Some(detected) = plan.objects.iter().find(|o| o.id == dv.object_id) else {
            continue;
        };
        // The scene object this detection is: the one whose box holds its centroid.
        let centroid = Point3::from(detected.frame.world_from_object.translation.vector);
        let Some(object) = scene.object_at(&centroid, 0.01) else {
            continue;
        };
        let alone;
        let (label_scene, label_object) = if config.neighbours {
            (scene, object)
        } else {
            alone = scene.only(object);
            (&alone, 0)
        };
        let view = &dv.view;
        let placement = ViewPlacement {
            view,
            world_from_object: &detected.frame.world_from_object,
            object_id: dv.object_id,
        };
        let mut maps = vec![0.0f32; 4 * l * l];
        let mut candidates = 0;
        let mut grasps = Vec::new();
        let pad_width_px = f64::from(gripper.pad_width_m) / pixel_m;
        let mut refused = BTreeMap::new();
        let judge =
            |phi: f64, width: f64, u: usize, v: usize| -> Result<(f32, Isometry3<f64>), &'static str> {
                if !(width > 0.0 && width <= core_gripper.max_width_m) {
                    return Err("over stroke");
                }
                let pose = grasp_at(&placement, u, v, phi, width, &core_gripper, &plan.table, decode)
                    .ok_or("no pose")?;
                match label_grasp(label_scene, label_object, &pose, width, gripper) {
                    GraspLabel::Positive { score, .. } => Ok((score, pose)),
                    label => Err(label.reason()),
                }
            };
        for v in (config.stride_px / 2..l).step_by(config.stride_px) {
            for u in (config.stride_px / 2..l).step_by(config.stride_px) {
                if view.image[v * l + u] <= 0.0 {
                    continue;
                }
                for k in 0..config.angles {
                    let phi =
                        -std::f64::consts::FRAC_PI_2 + k as f64 * std::f64::consts::PI / config.angles as f64;
                    let (x, y) = (u as f64 + 0.5, v as f64 + 0.5);
                    let across =
                        config
                            .opening
                            .width_px(&view.image, l, x, y, (phi.cos(), phi.sin()), pad_width_px)
                            * pixel_m;
                    let width = across + 2.0 * config.width_margin_m;
                    candidates += 1;
                    let (mut best, mut best_pose) = match judge(phi, width, u, v) {
                        Ok(judged) => judged,
                        Err(why) => {
                            *refused.entry(why).or_insert(0) += 1;
                            continue;
                        }
                    };
                    // Simulated annealing over angle and width from this positive.
                    let (mut best_phi, mut best_width) = (phi, width);
                    let (mut cur_phi, mut cur_width, mut cur) = (phi, width, best);
                    for step in 0..config.anneal_steps {
                        let temperature =
                            0.05 * (1.0 - step as f64 / config.anneal_steps.max(1) as f64) + 1e-3;
                        let try_phi = cur_phi + 0.12 * rng.gaussian();
                        let try_width = (cur_width + 0.005 * rng.gaussian()).max(0.005);
                        let Ok((score, pose)) = judge(try_phi, try_width, u, v) else {
                            continue;
                        };
                        if score >= cur || rng.next_f64() < (f64::from(score - cur) / temperature).exp() {
                            (cur_phi, cur_width, cur) = (try_phi, try_width, score);
                            if cur > best {
                                (best_phi, best_width, best, best_pose) = (cur_phi, cur_width, cur, pose);
                            }
                        }
                    }
                    let centre = (l as f64 - 1.0) / 2.0;
                    let d = ((u as f64 - centre).powi(2) + (v as f64 - centre).powi(2)).sqrt() / centre;
                    let quality = best * (1.0 - 0.25 * d.min(1.0)) as f32;
                    // A parallel-jaw grasp is the same at phi and phi + pi: fold to [-pi/2, pi/2].
                    let phi = 0.5 * (2.0 * best_phi).sin().atan2((2.0 * best_phi).cos());
                    let (c2, s2) = ((2.0 * phi).cos() as f32, (2.0 * phi).sin() as f32);
                    let w = (best_width / f64::from(contract.width_scale_m)) as f32;
                    grasps.push(PixelGrasp {
                        u,
                        v,
                        phi: phi as f32,
                        width_m: best_width as f32,
                        quality,
                        world_from_grasp: best_pose,
                    });
                    let r = config.paint_radius_px;
                    let reach = r.ceil() as i64;
                    for dy in -reach..=reach {
                        for dx in -reach..=reach {
                            let (x, y) = (u as i64 + dx, v as i64 + dy);
                            if x < 0
                                || y < 0
                                || x >= l as i64
                                || y >= l as i64
                                || ((dx * dx + dy * dy) as f32) > r * r
                            {
                                continue;
                            }
                            let i = y as usize * l + x as usize;
                            if quality > maps[iq * l * l + i] {
                                maps[iq * l * l + i] = quality;
                                maps[ic * l * l + i] = c2;
                                maps[is * l * l + i] = s2;
                                maps[iw * l * l + i] = w;
                            }
                        }
                    }
                }
            }
        }
        out.push(LabelledView {
            object,
            family: scene.objects[object].model.family,
            axis: view.axis,
            image: view.image.clone(),
            maps,
            candidates,
            positives: grasps.len(),
            refused,
            grasps,
        });
    }
    Ok(out)
}
