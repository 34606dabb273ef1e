//! Clear-the-table in simulation (DESIGN.md, method step 8; issue 6): the
//! planner in the loop, every grasp tried in rapier3d.
//!
//! An episode: a scene and one camera, both fixed by the seed; the camera is
//! the first of up to [`CAMERA_DRAWS`] random ones whose field of view holds
//! every object's bounding box (else the draw that cuts fewest), as a
//! camera is mounted to see the workspace. (Before 2026-11-24 it was the
//! first draw: on the tuning seeds 15 of 277 clutter objects were never in
//! view and 60 were cut by the image border.) Until the
//! table is clear, three attempts in a row fail, no grasp clears tau, or
//! `2 n + 3` attempts are spent (n objects): render a noisy frame, plan,
//! take the best grasp, and try it:
//!
//! 1. the grasp is matched to a scene object (its detection's centroid
//!    inside that object's box, 1 cm margin); none: *object missed*;
//! 2. the hand is checked for collisions along the approach: at the grasp
//!    and 2.5, 5, 7.5 and 10 cm back along the approach, pre-shaped to the
//!    planned width plus 2 cm (analytic, [`crate::grasp::label_grasp`]);
//!    any hit: *collision on approach*;
//! 3. the rapier3d trial ([`crate::physics::run_trial`]) closes, lifts
//!    15 cm, shakes, carries the object over the obstacles to a basket
//!    beside the table and lets go. In the basket: a success, and the
//!    object leaves the scene. The pads never got a grip: *width too small*
//!    when the object is wider than the stroke where the pads are, else
//!    *object missed*. Lost on the way up, during the carry, or landed
//!    outside the basket: *slip during lift*.
//!
//! After every physics trial the scene is what the trial left: pushed
//! neighbours stay pushed and a dropped object lies where it fell; then
//! everything settles ([`crate::pile::settle`]: what leaned on the taken
//! object falls), and objects that left the table are gone (counted as
//! `fell_off`, not removed). An attempt stopped by the approach check
//! leaves the scene as it was (a real arm's planner would not move there),
//! and so does one that matched no object. Until an object is next taken,
//! the executor takes the best of the planner's ranked grasps that is not
//! one it already tried and failed ([`same_grasp`]), as a robot would,
//! rather than failing the same grasp three times over; a grasp that
//! slipped but moved its object plans elsewhere anyway. (Before 2026-11-24
//! it took the best grasp every time; until 4015fe6 it forgot the
//! failed grasps after every physics trial, so one that slipped without
//! moving anything was tried again.)

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use mvgrasp_client::request::{depth_request, pose_from_message};
use mvgrasp_client::{PlannerClient, pb};
use mvgrasp_core::rng::SplitMix64;
use mvgrasp_core::{
    ClusterConfig, CreaseConfig, FieldOfView, Grasp, GraspNet, ModelContract, Plan, PlanOptions, Planner,
    PlannerConfig, Reattach, Repairs, ViewAxis, ViewPolicy, Workspace,
};
use nalgebra::{Isometry3, Point3, Translation3, Vector3};
use parry3d::math::Pose;

use crate::camera::{Camera, Frame, NoiseModel, render};
use crate::error::{Error, Result};
use crate::grasp::{GraspLabel, GripperModel, HandPart, Obstacle, label_grasp, pose_of, weight_torque_nm};
use crate::objects::{Catalog, Family};
use crate::physics::{Basket, TrialConfig, TrialOutcome, run_trial};
use crate::pile::{SettleConfig, settle};
use crate::scene::{Scenario, Scene};

/// Consecutive failed attempts that end an episode (the paper's rule).
pub const MAX_CONSECUTIVE_FAILURES: usize = 3;

/// Opening beyond the planned width while the hand approaches (m).
const APPROACH_MARGIN_M: f64 = 0.02;

/// Grasps asked of the planner per frame, best first: after the best
/// fails, the executor takes the next (see [`same_grasp`]).
pub const RANKED_GRASPS: usize = 8;

/// Two grasps count as the same within this distance (m) and turn (deg);
/// turned half round about the approach a parallel-jaw grasp is the same.
pub const SAME_GRASP_M: f64 = 0.01;
/// See [`SAME_GRASP_M`].
pub const SAME_GRASP_DEG: f64 = 15.0;

/// Whether `a` and `b` are the same grasp (within [`SAME_GRASP_M`] and
/// [`SAME_GRASP_DEG`], the jaws' half-turn symmetry included).
pub fn same_grasp(a: &Isometry3<f64>, b: &Isometry3<f64>) -> bool {
    let flip = nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI);
    let turn = |b: &nalgebra::UnitQuaternion<f64>| a.rotation.angle_to(b).to_degrees();
    (a.translation.vector - b.translation.vector).norm() < SAME_GRASP_M
        && turn(&b.rotation).min(turn(&(b.rotation * flip))) < SAME_GRASP_DEG
}

/// Approach distances checked for collisions (m back from the grasp).
const APPROACH_CHECKS_M: [f64; 5] = [0.0, 0.025, 0.05, 0.075, 0.10];

/// One planner setting under test.
#[derive(Debug, Clone, PartialEq)]
pub struct Setting {
    /// Which views the network sees.
    pub policy: ViewPolicy,
    /// Grasps under this quality are not tried.
    pub tau: f32,
}

impl Setting {
    /// `entropy:0.8`, `all:0.9`, `top-down:0.8`, `random:0.8`.
    pub fn parse(text: &str) -> Result<Self> {
        let bad = |reason: String| Error::Invalid {
            field: "setting",
            reason,
        };
        let (policy, tau) = text
            .split_once(':')
            .ok_or_else(|| bad(format!("{text:?} is not POLICY:TAU")))?;
        let tau: f32 = tau
            .parse()
            .map_err(|e| bad(format!("{text:?}: tau {tau:?}: {e}")))?;
        if !(0.0..=1.0).contains(&tau) {
            return Err(bad(format!("{text:?}: tau {tau} is outside [0, 1]")));
        }
        let policy = match policy {
            "entropy" => ViewPolicy::Entropy,
            "all" => ViewPolicy::All,
            "top-down" => ViewPolicy::TopDown,
            "random" => ViewPolicy::Random { seed: 0 },
            other => {
                return Err(bad(format!(
                    "{other:?} is not a view policy (entropy, all, top-down, random)"
                )));
            }
        };
        Ok(Self { policy, tau })
    }

    /// The name [`Self::parse`] reads.
    pub fn name(&self) -> String {
        let policy = match self.policy {
            ViewPolicy::Entropy => "entropy",
            ViewPolicy::All => "all",
            ViewPolicy::TopDown => "top-down",
            ViewPolicy::Random { .. } => "random",
        };
        format!("{policy}:{}", self.tau)
    }
}

/// The planner's squaring limit (`sim eval --square-turn-deg`, degrees):
/// how far a grasp may be turned about its approach to square it to the
/// surfaces its pads meet ([`mvgrasp_core::decode::HandConfig::square_turn_deg`]);
/// 0 turns squaring off. Refused outside 0-90 degrees (a quarter turn
/// already swaps the faces the pads meet) or when not a number.
pub fn square_turn_setting(deg: f64) -> Result<f64> {
    if (0.0..=90.0).contains(&deg) {
        Ok(deg)
    } else {
        Err(Error::Invalid {
            field: "square-turn-deg",
            reason: format!("{deg} is not within 0-90 degrees"),
        })
    }
}

/// The crease split from its text form (`sim eval --crease-split`): `on`
/// (`CreaseConfig`'s defaults), `off` (the planner's default), `split-only` (the defaults without step 6, parts
/// hanging on another joining it), or
/// `SMOOTH_PX:BASELINE_PX:VALLEY_MM:RATIO:MIN_PART` (the fields of
/// [`CreaseConfig`], the valley in millimetres; step 6 with its defaults),
/// followed by `:AREA_CM2:SHARE:OUTLINE:STEP_MM` for step 6 ([`Reattach`]'s
/// fields; an area of 0 turns it off).
pub fn crease_setting(text: &str) -> Result<Option<CreaseConfig>> {
    let bad = |reason: String| Error::Invalid {
        field: "crease-split",
        reason,
    };
    match text {
        "on" => return Ok(Some(CreaseConfig::default())),
        "off" => return Ok(None),
        "split-only" => {
            return Ok(Some(CreaseConfig {
                reattach: None,
                ..CreaseConfig::default()
            }));
        }
        _ => {}
    }
    let usage = || {
        bad(format!(
            "{text:?} is not on, off, split-only, SMOOTH_PX:BASELINE_PX:VALLEY_MM:RATIO:MIN_PART \
             or that followed by :AREA_CM2:SHARE:OUTLINE:STEP_MM"
        ))
    };
    let fields: Vec<&str> = text.split(':').collect();
    let (split, attach) = fields.split_at(fields.len().min(5));
    let [smooth, baseline, valley_mm, ratio, min_part] = split[..] else {
        return Err(usage());
    };
    let number = |name: &str, v: &str| -> Result<f64> {
        v.parse::<f64>()
            .ok()
            .filter(|x| x.is_finite() && *x >= 0.0)
            .ok_or_else(|| bad(format!("{text:?}: {name} {v:?} is not a number >= 0")))
    };
    let whole = |name: &str, v: &str| -> Result<usize> {
        v.parse::<usize>()
            .map_err(|e| bad(format!("{text:?}: {name} {v:?}: {e}")))
    };
    let config = CreaseConfig {
        smooth_radius_px: whole("smoothing radius", smooth)?,
        baseline_px: whole("baseline", baseline)?,
        min_valley_m: (number("valley depth", valley_mm)? / 1000.0) as f32,
        min_valley_ratio: number("ratio", ratio)? as f32,
        min_part_points: whole("smallest part", min_part)?,
        reattach: match attach {
            [] => Some(Reattach::default()),
            [area_cm2, share, outline, step_mm] => Some(Reattach {
                max_area_m2: (number("area", area_cm2)? / 1e4) as f32,
                max_share: number("share", share)? as f32,
                min_outline_share: number("outline share", outline)? as f32,
                max_step_m: (number("step", step_mm)? / 1000.0) as f32,
            })
            .filter(|r| r.max_area_m2 > 0.0),
            _ => return Err(usage()),
        },
    };
    if config.baseline_px == 0 {
        return Err(bad(format!("{text:?}: the baseline must be at least 1 px")));
    }
    Ok(Some(config))
}

/// The text form of a crease split, as [`crease_setting`] reads it back
/// (recorded in a dataset's manifest: the segmentation made its views).
pub fn crease_text(crease: Option<&CreaseConfig>) -> String {
    let Some(c) = crease else {
        return "off".into();
    };
    let split = format!(
        "{}:{}:{}:{}:{}",
        c.smooth_radius_px,
        c.baseline_px,
        c.min_valley_m * 1000.0,
        c.min_valley_ratio,
        c.min_part_points
    );
    match &c.reattach {
        None => format!("{split}:0:0:0:0"),
        Some(r) => format!(
            "{split}:{}:{}:{}:{}",
            r.max_area_m2 * 1e4,
            r.max_share,
            r.min_outline_share,
            r.max_step_m * 1000.0
        ),
    }
}

/// Why an attempt failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Failure {
    /// The hand hits the table or an object on its way in.
    CollisionOnApproach,
    /// Gripped, then lost during the lift or the shake.
    SlipDuringLift,
    /// The object is wider than the stroke where the pads are.
    WidthTooSmall,
    /// The grasp is not on one object, or the pads close on nothing.
    ObjectMissed,
}

impl Failure {
    /// Every failure, in report order.
    pub const ALL: [Failure; 4] = [
        Failure::CollisionOnApproach,
        Failure::SlipDuringLift,
        Failure::WidthTooSmall,
        Failure::ObjectMissed,
    ];

    /// Report name.
    pub fn name(self) -> &'static str {
        match self {
            Self::CollisionOnApproach => "collision on approach",
            Self::SlipDuringLift => "slip during lift",
            Self::WidthTooSmall => "width too small",
            Self::ObjectMissed => "object missed",
        }
    }
}

/// How an episode ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum End {
    /// Every object removed.
    Cleared,
    /// Three failed attempts in a row.
    ConsecutiveFailures,
    /// No grasp reached tau (or no object was found), or every one that did
    /// was already refused in the unchanged scene.
    NoGraspAboveTau,
    /// `2 n + 3` attempts spent.
    AttemptLimit,
}

impl End {
    /// Report name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Cleared => "cleared",
            Self::ConsecutiveFailures => "3 failures in a row",
            Self::NoGraspAboveTau => "no grasp above tau",
            Self::AttemptLimit => "attempt limit",
        }
    }
}

/// One attempt.
#[derive(Debug, Clone, PartialEq)]
pub struct Attempt {
    /// Planning time, frame to ranked grasps (ms).
    pub plan_ms: f64,
    /// The grasp tried.
    pub world_from_grasp: Isometry3<f64>,
    /// Its opening (m).
    pub width_m: f64,
    /// Quality the planner gave the grasp.
    pub quality: f32,
    /// `None`: a success.
    pub failure: Option<Failure>,
    /// For a collision on approach: what the hand hit, and where.
    pub collision: Option<CollisionSite>,
    /// For a physics trial: the analytic label of the grasp as tried
    /// ([`GraspLabel::name`]) and its object's family, to set the labels
    /// the network learns from against physics on the planner's own grasps
    /// ([`label_table`]).
    pub label: Option<(&'static str, Family)>,
    /// The view the planner found the grasp in.
    pub view: ViewAxis,
    /// The grasp's peak pixel `[u, v]` in that view.
    pub pixel: [u32; 2],
    /// What the planner's hand check changed about it after decoding.
    pub repairs: Repairs,
    /// The lever the planner could see: the horizontal distance (m) from
    /// the closing line to the centroid of the object as it segmented it
    /// ([`horizontal_lever_m`]).
    pub centroid_lever_m: f64,
    /// For a physics trial: the torque (N m) of the object's weight about
    /// the closing line, from its true mass and centre of mass
    /// ([`weight_torque_nm`]), at the grasp as planned.
    pub torque_nm: Option<f32>,
    /// For a grasp that matched an object: how far (degrees) the object
    /// was tipped from the way the scene generator stands it upright (its
    /// own `z` against the world's up; [`object_tilt_deg`]).
    pub tilt_deg: Option<f32>,
}

impl Attempt {
    /// How it ended: "ok" (carried to the basket), "collision on approach:
    /// SITE" ([`CollisionSite::name`]) or the failure's name.
    pub fn outcome_name(&self) -> String {
        match (self.failure, self.collision) {
            (None, _) => "ok".to_owned(),
            (Some(_), Some(site)) => format!("collision on approach: {}", site.name()),
            (Some(f), None) => f.name().to_owned(),
        }
    }
}

/// The angle (degrees, 0-180) between `object`'s own `z` and the world's
/// up: 0 as the scene generator stands it upright, about 90 toppled onto a
/// side, 180 upside down.
pub fn object_tilt_deg(object: &crate::scene::PlacedObject) -> f32 {
    let up = object.world_from_object.rotation * parry3d::math::Vector::Z;
    up.z.clamp(-1.0, 1.0).acos().to_degrees()
}

/// Poses of an object by its tilt ([`object_tilt_deg`]), as [`provenance_table`] groups them.
pub const POSES: [(&str, f32); 3] = [
    ("upright", 30.0),
    ("toppled", 150.0),
    ("upside down", f32::INFINITY),
];

/// The name of the pose (of [`POSES`]) an object tipped `tilt_deg` from upright is in.
pub fn pose_name(tilt_deg: f32) -> &'static str {
    POSES
        .iter()
        .find(|(_, below)| tilt_deg < *below)
        .map_or(POSES[POSES.len() - 1].0, |(name, _)| name)
}

/// The horizontal distance (m) from `point` to the closing line (grasp `x`
/// through the grasp origin): the lever the weight of a mass at `point`
/// has about that line, whose torque the pads must hold by friction alone.
pub fn horizontal_lever_m(world_from_grasp: &Isometry3<f64>, point: &Point3<f64>) -> f64 {
    let closing = world_from_grasp.rotation * Vector3::x();
    let offset = point - Point3::from(world_from_grasp.translation.vector);
    closing.cross(&offset).z.abs()
}

/// What a collision on approach hit, with which part of the hand, and
/// whether at the grasp pose or on the way in to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct CollisionSite {
    /// What was hit (a neighbour's index is not kept).
    pub obstacle: Obstacle,
    /// Which part hit it.
    pub part: HandPart,
    /// True when the hand was still 2.5-10 cm back along the approach.
    pub on_the_way_in: bool,
}

impl CollisionSite {
    fn new(obstacle: Obstacle, part: HandPart, back_m: f64) -> Self {
        Self {
            obstacle: match obstacle {
                Obstacle::Neighbour(_) => Obstacle::Neighbour(0),
                other => other,
            },
            part,
            on_the_way_in: back_m > 0.0,
        }
    }

    /// Report name, e.g. "a neighbour (palm), on the way in".
    pub fn name(&self) -> String {
        let what = match self.obstacle {
            Obstacle::Table => "the table",
            Obstacle::Target => "the object",
            Obstacle::Neighbour(_) => "a neighbour",
        };
        let when = if self.on_the_way_in {
            "on the way in"
        } else {
            "at the grasp"
        };
        format!("{what} ({}), {when}", self.part.name())
    }
}

/// One episode.
#[derive(Debug, Clone, PartialEq)]
pub struct Episode {
    /// Its scenario.
    pub scenario: Scenario,
    /// Its seed (scene and camera).
    pub seed: u64,
    /// Objects on the table at the start.
    pub objects: usize,
    /// Objects removed.
    pub removed: usize,
    /// Objects that fell off the table while a pile settled (not removed).
    pub fell_off: usize,
    /// Every attempt, in order.
    pub attempts: Vec<Attempt>,
    /// How it ended.
    pub end: End,
    /// Planning time of the call that ended it with no grasp (ms), if any.
    pub last_plan_ms: Option<f64>,
}

impl Episode {
    /// Successful attempts.
    pub fn successes(&self) -> usize {
        self.attempts.iter().filter(|a| a.failure.is_none()).count()
    }
}

/// What an episode runs with (shared by every setting of a run).
#[derive(Debug, Clone)]
pub struct EpisodeConfig {
    /// The gripper in the analytic checks and in physics.
    pub gripper: GripperModel,
    /// The physics trial.
    pub trial: TrialConfig,
    /// Sensor noise; `None`: a perfect sensor.
    pub noise: Option<NoiseModel>,
    /// What scenes draw their objects from.
    pub catalog: Catalog,
}

impl Default for EpisodeConfig {
    fn default() -> Self {
        Self {
            gripper: GripperModel::robotiq_2f_140(),
            trial: TrialConfig {
                carry: Some(Basket::default()),
                ..TrialConfig::default()
            },
            noise: Some(NoiseModel::default()),
            catalog: Catalog::of(&Family::ALL),
        }
    }
}

/// The scene and camera of episode `seed` (the same for every setting).
pub fn episode_scene(scenario: Scenario, seed: u64, catalog: &Catalog) -> Result<(Scene, Camera)> {
    let scene = Scene::generate_from(scenario, seed, catalog)?;
    let mut rng = SplitMix64::new(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xE7A1);
    let target = Vector3::new(0.0, 0.0, f64::from(scene.table_z));
    let mut best: Option<(usize, Camera)> = None;
    for _ in 0..CAMERA_DRAWS {
        let camera = Camera::random(&mut rng, target, false);
        let outside = objects_outside_view(&scene, &camera);
        if best.as_ref().is_none_or(|(fewest, _)| outside < *fewest) {
            best = Some((outside, camera));
        }
        if outside == 0 {
            break;
        }
    }
    let (_, camera) = best.ok_or_else(|| Error::Scene("no camera drawn".into()))?;
    Ok((scene, camera))
}

/// The generator of an episode's sensor noise: [`run_episode`] draws each
/// frame's noise from it in turn.
pub fn episode_noise_rng(seed: u64) -> SplitMix64 {
    SplitMix64::new(seed ^ 0x0153_EAB0)
}

/// An episode's scene and the first frame [`run_episode`] sees of it
/// (with the default noise model, as `sim eval` renders).
pub fn episode_first_frame(scenario: Scenario, seed: u64, catalog: &Catalog) -> Result<(Scene, Frame)> {
    let (scene, camera) = episode_scene(scenario, seed, catalog)?;
    let frame = render(
        &scene,
        &camera,
        Some((&NoiseModel::default(), &mut episode_noise_rng(seed))),
    );
    Ok((scene, frame))
}

/// A default planner with the crease split of `crease` ([`crease_setting`]'s
/// text form), for comparing segmentations.
pub fn planner_with_crease(crease: &str, contract: &ModelContract) -> Result<Planner> {
    let config = PlannerConfig {
        cluster: ClusterConfig {
            crease: crease_setting(crease)?,
            ..ClusterConfig::default()
        },
        ..PlannerConfig::default()
    };
    Planner::new(config, contract.clone()).map_err(|e| Error::Invalid {
        field: "contract",
        reason: e.to_string(),
    })
}

/// Cameras drawn for an episode, at most, looking for one whose field of
/// view holds every object ([`episode_scene`]).
pub const CAMERA_DRAWS: usize = 32;

/// Objects of `scene` whose bounding box `camera` does not hold whole: a
/// corner behind it or projecting outside the image.
pub fn objects_outside_view(scene: &Scene, camera: &Camera) -> usize {
    let view = FieldOfView {
        world_from_camera: camera.world_from_camera,
        intrinsics: camera.intrinsics,
        width: camera.width,
        height: camera.height,
    };
    scene
        .objects
        .iter()
        .filter(|o| {
            o.world_aabb
                .vertices()
                .iter()
                .any(|c| !view.contains(&Point3::new(f64::from(c.x), f64::from(c.y), f64::from(c.z))))
        })
        .count()
}

/// A grasp of a plan, with where its object was seen.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedGrasp {
    /// The grasp pose in the world.
    pub world_from_grasp: Isometry3<f64>,
    /// Opening (m).
    pub width_m: f64,
    /// Predicted quality.
    pub quality: f32,
    /// Centroid of the detected object it grasps (world).
    pub object_centroid: Point3<f64>,
    /// The view it was found in.
    pub view: ViewAxis,
    /// Its peak pixel `[u, v]` in that view.
    pub pixel: [u32; 2],
    /// What the planner's hand check changed about it after decoding (none
    /// from a server that does not say).
    pub repairs: Repairs,
}

/// Whatever plans: the pipeline in this process, or a running server.
pub trait GraspSource {
    /// The grasps for `frame` under `options`, best first, at most
    /// `options.max_grasps`; empty when none reaches `options.min_quality`.
    fn grasps(
        &mut self,
        frame: &Frame,
        workspace: Workspace,
        options: &PlanOptions,
    ) -> Result<Vec<PlannedGrasp>>;
}

/// The planner and a network in this process.
pub struct InProcess<'a> {
    /// The pipeline.
    pub planner: &'a Planner,
    /// The network.
    pub net: &'a mut dyn GraspNet,
}

impl InProcess<'_> {
    fn plan(&mut self, frame: &Frame, workspace: Workspace, options: &PlanOptions) -> Result<Plan> {
        let bytes = frame.depth_le_bytes();
        let input = frame.scene_input(&bytes, workspace);
        self.planner
            .plan(&input, options, self.net)
            .map_err(|e| Error::Scene(format!("planner: {e}")))
    }

    /// [`GraspSource::grasps`], each grasp with the view it came from as the
    /// network read it (`size x size`, the contract's normalisation).
    pub fn grasps_with_views(
        &mut self,
        frame: &Frame,
        workspace: Workspace,
        options: &PlanOptions,
    ) -> Result<Vec<(PlannedGrasp, Vec<f32>)>> {
        let keeping = PlanOptions {
            keep_views: true,
            ..options.clone()
        };
        let plan = self.plan(frame, workspace, &keeping)?;
        plan.grasps
            .iter()
            .filter_map(|g| {
                let planned = planned_grasp(&plan, g)?;
                let view = plan
                    .debug_views
                    .iter()
                    .find(|d| d.object_id == g.object_id && d.view.axis == g.view);
                Some(match view {
                    Some(d) => Ok((planned, d.view.image.clone())),
                    None => Err(Error::Scene(format!(
                        "planner: grasp on object {} names a {} view it did not keep",
                        g.object_id,
                        g.view.name()
                    ))),
                })
            })
            .collect()
    }
}

/// `g` of `plan` with where its object was seen; `None` for a grasp on no
/// object of the plan.
fn planned_grasp(plan: &Plan, g: &Grasp) -> Option<PlannedGrasp> {
    let object = plan.objects.iter().find(|o| o.id == g.object_id)?;
    Some(PlannedGrasp {
        world_from_grasp: g.world_from_grasp,
        width_m: g.width_m,
        quality: g.quality,
        object_centroid: Point3::from(object.frame.world_from_object.translation.vector),
        view: g.view,
        pixel: g.pixel,
        repairs: g.repairs,
    })
}

impl GraspSource for InProcess<'_> {
    fn grasps(
        &mut self,
        frame: &Frame,
        workspace: Workspace,
        options: &PlanOptions,
    ) -> Result<Vec<PlannedGrasp>> {
        let plan = self.plan(frame, workspace, options)?;
        Ok(plan
            .grasps
            .iter()
            .filter_map(|g| planned_grasp(&plan, g))
            .collect())
    }
}

/// An in-process source that keeps every grasp it offers with the view it
/// came from, frame by frame (`sim eval --attempt-views`): after an
/// episode, [`ViewKeeping::rows`] gives each attempt the view the network read,
/// so physics outcomes can be learned from.
pub struct ViewKeeping<'a> {
    /// The planner and network.
    pub inner: InProcess<'a>,
    /// Per call (frame): the grasps offered, best first, with their views.
    frames: Vec<Vec<(PlannedGrasp, Vec<f32>)>>,
}

/// One row of `sim eval --attempt-views`: an attempt with the view its
/// grasp came from.
#[derive(Debug, Clone, PartialEq)]
pub struct AttemptRow<'a> {
    /// The frame: attempts the episode had made before it.
    pub step: usize,
    /// The grasp's place in the planner's ranking on that frame (0 best).
    pub rank: usize,
    /// `false`: the episode's own attempt. `true`: a grasp ranked below
    /// it, tried from the same state and forgotten ([`alternative_attempts`]).
    pub alternative: bool,
    /// What it came to.
    pub attempt: Attempt,
    /// The view as the network read it.
    pub view: &'a [f32],
}

impl<'a> ViewKeeping<'a> {
    /// Keeps the views of `inner`'s grasps.
    pub fn new(inner: InProcess<'a>) -> Self {
        Self {
            inner,
            frames: Vec::new(),
        }
    }

    /// The rows `sim eval --attempt-views` writes for `episode` (planned by
    /// this source, from its first call on): each attempt with the view its
    /// grasp came from (none where the tried pose is none this source
    /// offered on that frame), followed, when
    /// `alternatives` > 0, by up to that many grasps the planner ranked
    /// below it on the same frame, tried from `scenes[step]` (the scene as
    /// that frame showed it) and forgotten ([`alternative_attempts`]).
    /// Fails when `alternatives` > 0 and a frame's scene is missing.
    pub fn rows(
        &self,
        episode: &Episode,
        scenes: &[Scene],
        alternatives: usize,
        config: &EpisodeConfig,
    ) -> Result<Vec<AttemptRow<'_>>> {
        if alternatives > 0 && scenes.len() < episode.attempts.len() {
            return Err(Error::Invalid {
                field: "attempt alternatives",
                reason: format!("{} scenes for {} attempts", scenes.len(), episode.attempts.len()),
            });
        }
        let mut rows = Vec::new();
        for (step, a) in episode.attempts.iter().enumerate() {
            let Some(offered) = self.frames.get(step) else {
                continue;
            };
            let Some(rank) = offered
                .iter()
                .position(|(g, _)| g.world_from_grasp == a.world_from_grasp)
            else {
                continue;
            };
            rows.push(AttemptRow {
                step,
                rank,
                alternative: false,
                attempt: a.clone(),
                view: &offered[rank].1,
            });
            if alternatives == 0 {
                continue;
            }
            let grasps: Vec<PlannedGrasp> = offered.iter().map(|(g, _)| g.clone()).collect();
            for (rank, attempt) in
                alternative_attempts(&scenes[step], &grasps, &a.world_from_grasp, alternatives, config)
            {
                rows.push(AttemptRow {
                    step,
                    rank,
                    alternative: true,
                    attempt,
                    view: &offered[rank].1,
                });
            }
        }
        Ok(rows)
    }
}

impl GraspSource for ViewKeeping<'_> {
    fn grasps(
        &mut self,
        frame: &Frame,
        workspace: Workspace,
        options: &PlanOptions,
    ) -> Result<Vec<PlannedGrasp>> {
        let offered = self.inner.grasps_with_views(frame, workspace, options)?;
        let grasps = offered.iter().map(|(g, _)| g.clone()).collect();
        self.frames.push(offered);
        Ok(grasps)
    }
}

/// A running server, over gRPC.
/// Each call blocks on its own single-threaded runtime, so call it from
/// plain threads, not from inside an async runtime.
pub struct Remote {
    runtime: tokio::runtime::Runtime,
    client: PlannerClient,
}

impl Remote {
    /// Connects to the server at `endpoint` (`http://host:port`).
    pub fn connect(endpoint: &str) -> Result<Self> {
        let failed = |e: &dyn std::fmt::Display| Error::Scene(format!("connecting to {endpoint}: {e}"));
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(|e| failed(&e))?;
        let client = runtime
            .block_on(PlannerClient::connect(endpoint))
            .map_err(|e| failed(&e))?;
        Ok(Self { runtime, client })
    }

    /// The served model's contract and provenance.
    pub fn model_info(&mut self) -> Result<pb::ModelInfo> {
        self.runtime
            .block_on(self.client.model_info())
            .map_err(|e| Error::Scene(format!("server: {e}")))
    }
}

impl GraspSource for Remote {
    fn grasps(
        &mut self,
        frame: &Frame,
        workspace: Workspace,
        options: &PlanOptions,
    ) -> Result<Vec<PlannedGrasp>> {
        let c = &frame.camera;
        let k = c.intrinsics;
        let mut request = depth_request(
            c.width,
            c.height,
            &frame.depth_mm,
            pb::CameraIntrinsics {
                fx: k.fx,
                fy: k.fy,
                cx: k.cx,
                cy: k.cy,
            },
            &c.world_from_camera,
            Some((workspace.min, workspace.max)),
        );
        request.gripper = Some(pb::Gripper {
            max_width_m: options.gripper.max_width_m,
            finger_width_m: options.gripper.finger_width_m,
            finger_depth_m: options.gripper.finger_depth_m,
        });
        request.max_grasps = u32::try_from(options.max_grasps).unwrap_or(u32::MAX);
        request.min_quality = Some(options.min_quality);
        request.view_cascade = Some(options.view_cascade);
        request.view_policy = match options.view_policy {
            ViewPolicy::Entropy => pb::ViewPolicy::Entropy,
            ViewPolicy::All => pb::ViewPolicy::All,
            ViewPolicy::TopDown => pb::ViewPolicy::TopDown,
            ViewPolicy::Random { seed } => {
                request.random_seed = seed;
                pb::ViewPolicy::Random
            }
        } as i32;
        let response = self
            .runtime
            .block_on(self.client.plan(request))
            .map_err(|e| Error::Scene(format!("server: {e}")))?;
        response
            .grasps
            .iter()
            .filter_map(|g| {
                let object = response.objects.iter().find(|o| o.id == g.object_id)?;
                let view = match view_axis(g.view()) {
                    Some(view) => view,
                    None => {
                        return Some(Err(Error::Scene(format!(
                            "server: grasp {:?} names no view",
                            g.pose
                        ))));
                    }
                };
                Some(Ok(PlannedGrasp {
                    world_from_grasp: pose_from_message(g.pose.as_ref()),
                    width_m: g.width_m,
                    quality: g.quality,
                    object_centroid: Point3::from(
                        pose_from_message(object.world_from_object.as_ref())
                            .translation
                            .vector,
                    ),
                    view,
                    pixel: [g.pixel_u, g.pixel_v],
                    repairs: g.repairs.map_or_else(Repairs::default, |r| Repairs {
                        refit: r.refit,
                        turned_away: r.turned_away,
                        squared: r.squared,
                        deepened: r.deepened,
                        out_of_view: r.out_of_view,
                    }),
                }))
            })
            .collect()
    }
}

/// The planner's view of a message's view axis; `None` for an unspecified one.
fn view_axis(axis: pb::ViewAxis) -> Option<ViewAxis> {
    match axis {
        pb::ViewAxis::Unspecified => None,
        pb::ViewAxis::Top => Some(ViewAxis::Top),
        pb::ViewAxis::Front => Some(ViewAxis::Front),
        pb::ViewAxis::Side => Some(ViewAxis::Side),
    }
}

/// The plan options of `setting` for episode `seed`.
pub fn plan_options(setting: &Setting, seed: u64, gripper: &GripperModel) -> PlanOptions {
    PlanOptions {
        gripper: gripper.planner_gripper(),
        max_grasps: RANKED_GRASPS,
        min_quality: setting.tau,
        view_policy: match setting.policy {
            ViewPolicy::Random { .. } => ViewPolicy::Random { seed },
            other => other,
        },
        keep_views: false,
        view_cascade: true,
        approach_cone: None,
    }
}

/// Runs one episode of `scenario` / `seed` with `setting`, planning with `source`.
pub fn run_episode(
    scenario: Scenario,
    seed: u64,
    setting: &Setting,
    source: &mut dyn GraspSource,
    config: &EpisodeConfig,
) -> Result<Episode> {
    run_episode_with(scenario, seed, setting, source, config, &mut |_, _, _| {})
}

/// [`run_episode`], showing `on_frame` every frame before the planner gets
/// it: the attempts made so far, the scene as they left it, and the frame
/// (`sim eval --label-frames` labels them). It cannot change the episode.
pub fn run_episode_with(
    scenario: Scenario,
    seed: u64,
    setting: &Setting,
    source: &mut dyn GraspSource,
    config: &EpisodeConfig,
    on_frame: &mut dyn FnMut(usize, &Scene, &Frame),
) -> Result<Episode> {
    let (mut scene, camera) = episode_scene(scenario, seed, &config.catalog)?;
    let options = plan_options(setting, seed, &config.gripper);
    let mut noise_rng = episode_noise_rng(seed);
    let mut episode = Episode {
        scenario,
        seed,
        objects: scene.objects.len(),
        removed: 0,
        fell_off: 0,
        attempts: Vec::new(),
        end: End::Cleared,
        last_plan_ms: None,
    };
    let limit = 2 * episode.objects + 3;
    // Grasps tried and failed since an object was last taken (the approach
    // check refused them, they matched no object, or the trial failed): the
    // executor takes the best grasp that is none of them.
    let mut refused: Vec<Isometry3<f64>> = Vec::new();
    loop {
        if scene.objects.is_empty() {
            episode.end = End::Cleared;
            break;
        }
        let failures_in_a_row = episode
            .attempts
            .iter()
            .rev()
            .take_while(|a| a.failure.is_some())
            .count();
        if failures_in_a_row >= MAX_CONSECUTIVE_FAILURES {
            episode.end = End::ConsecutiveFailures;
            break;
        }
        if episode.attempts.len() >= limit {
            episode.end = End::AttemptLimit;
            break;
        }
        let frame = render(
            &scene,
            &camera,
            config.noise.as_ref().map(|n| (n, &mut noise_rng)),
        );
        on_frame(episode.attempts.len(), &scene, &frame);
        let started = Instant::now();
        let grasps = source.grasps(&frame, scene.workspace(), &options)?;
        let plan_ms = started.elapsed().as_secs_f64() * 1e3;
        let best = grasps
            .into_iter()
            .find(|g| !refused.iter().any(|r| same_grasp(r, &g.world_from_grasp)));
        let Some(grasp) = best else {
            episode.end = End::NoGraspAboveTau;
            episode.last_plan_ms = Some(plan_ms);
            break;
        };
        let (attempt, after) = attempt_on(&scene, &grasp, plan_ms, config);
        // The scene as the trial left it (a pushed neighbour stays pushed, a
        // dropped object lies where it fell), the target gone if it reached
        // the basket; then what still moves or leaned on the target comes to
        // rest. Off the table is gone.
        if let Some((target, poses)) = after {
            for (o, pose) in scene.objects.iter_mut().zip(poses) {
                o.world_from_object = pose;
                o.world_aabb = o.model.aabb_at(&pose);
            }
            if attempt.failure.is_none() {
                scene.objects.remove(target);
                episode.removed += 1;
            }
            episode.fell_off += settle(&mut scene, &SettleConfig::default());
        }
        if attempt.failure.is_some() {
            refused.push(grasp.world_from_grasp);
        } else {
            refused.clear();
        }
        episode.attempts.push(attempt);
    }
    Ok(episode)
}

/// What grasp `grasp` would come to in `scene` as it stands, without
/// changing it: `None` when the object is carried to the basket, else why
/// not (the grasp on no object, the approach check, or the physics trial),
/// exactly as an episode's attempt would end. `sim eval --judge` tries
/// other models' best grasps on an episode's frames with it.
pub fn grasp_outcome(scene: &Scene, grasp: &PlannedGrasp, config: &EpisodeConfig) -> Option<Failure> {
    attempt_on(scene, grasp, 0.0, config).0.failure
}

/// The attempt `grasp` (planned in `plan_ms`) makes on `scene` as it
/// stands, as an episode records it, and for a physics trial the target
/// and every object's pose as the trial left them. `scene` is not changed.
fn attempt_on(
    scene: &Scene,
    grasp: &PlannedGrasp,
    plan_ms: f64,
    config: &EpisodeConfig,
) -> (Attempt, Option<(usize, Vec<Pose>)>) {
    let mut attempt = Attempt {
        plan_ms,
        world_from_grasp: grasp.world_from_grasp,
        width_m: grasp.width_m,
        quality: grasp.quality,
        failure: Some(Failure::ObjectMissed),
        collision: None,
        label: None,
        view: grasp.view,
        pixel: grasp.pixel,
        repairs: grasp.repairs,
        centroid_lever_m: horizontal_lever_m(&grasp.world_from_grasp, &grasp.object_centroid),
        torque_nm: None,
        tilt_deg: None,
    };
    let Some(target) = scene.object_at(&grasp.object_centroid, 0.01) else {
        return (attempt, None);
    };
    let object = &scene.objects[target];
    attempt.tilt_deg = Some(object_tilt_deg(object));
    match try_grasp(scene, target, grasp, config) {
        (Tried::Collided(site), _) => {
            attempt.failure = Some(Failure::CollisionOnApproach);
            attempt.collision = Some(site);
            (attempt, None)
        }
        (Tried::Trial(failure, name), poses) => {
            attempt.failure = failure;
            attempt.label = Some((name, object.model.family));
            attempt.torque_nm = Some(weight_torque_nm(object, &pose_of(&grasp.world_from_grasp)));
            (attempt, poses.map(|p| (target, p)))
        }
    }
}

/// Up to `count` of the grasps `offered` on a frame that the planner ranked
/// below the one the episode tried there (`tried`; those above it had
/// failed already on the unchanged scene), best first, each tried from
/// `scene` as it stood and then forgotten: what the episode would have
/// recorded had the planner ranked it first (`sim eval
/// --attempt-alternatives`). Each comes with its place in `offered`; none
/// when `tried` is not among them.
pub fn alternative_attempts(
    scene: &Scene,
    offered: &[PlannedGrasp],
    tried: &Isometry3<f64>,
    count: usize,
    config: &EpisodeConfig,
) -> Vec<(usize, Attempt)> {
    let Some(at) = offered.iter().position(|g| g.world_from_grasp == *tried) else {
        return Vec::new();
    };
    offered
        .iter()
        .enumerate()
        .skip(at + 1)
        .filter(|(_, g)| !same_grasp(tried, &g.world_from_grasp))
        .take(count)
        .map(|(rank, g)| (rank, attempt_on(scene, g, 0.0, config).0))
        .collect()
}

/// One model's best grasps tried on frames it did not choose
/// (`sim eval --judge`): frames seen, frames without a grasp above tau,
/// frames whose planning failed, and the grasps tried by outcome.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct JudgeTally {
    /// Frames judged.
    pub frames: usize,
    /// Frames where it offered no grasp at tau.
    pub no_grasp: usize,
    /// Frames its planning failed on.
    pub errors: usize,
    /// Grasps held (carried to the basket).
    pub held: usize,
    /// Grasps failed, per [`Failure::ALL`].
    pub failures: [usize; 4],
}

impl JudgeTally {
    /// Counts one frame: `None` for a planning error, `Some(None)` for no
    /// grasp, `Some(Some(outcome))` for a grasp tried.
    pub fn add(&mut self, frame: Option<Option<Option<Failure>>>) {
        self.frames += 1;
        match frame {
            None => self.errors += 1,
            Some(None) => self.no_grasp += 1,
            Some(Some(None)) => self.held += 1,
            Some(Some(Some(f))) => {
                if let Some(k) = Failure::ALL.iter().position(|&g| g == f) {
                    self.failures[k] += 1;
                }
            }
        }
    }

    /// The name of one judged frame's outcome, as [`Self::add`] takes it:
    /// "planning error", "no grasp", "held" or the failure's name.
    pub fn outcome_name(frame: Option<Option<Option<Failure>>>) -> &'static str {
        match frame {
            None => "planning error",
            Some(None) => "no grasp",
            Some(Some(None)) => "held",
            Some(Some(Some(f))) => f.name(),
        }
    }

    /// Adds another tally's counts.
    pub fn merge(&mut self, other: &JudgeTally) {
        self.frames += other.frames;
        self.no_grasp += other.no_grasp;
        self.errors += other.errors;
        self.held += other.held;
        for (a, b) in self.failures.iter_mut().zip(other.failures) {
            *a += b;
        }
    }

    /// Grasps tried.
    pub fn tried(&self) -> usize {
        self.held + self.failures.iter().sum::<usize>()
    }
}

/// The `--judge` table: per scenario (or "all"; in `rows`' order) and model, the
/// frames, grasps tried and held, held per frame and per grasp tried, and
/// the failures by cause. Empty without rows.
pub fn judge_table(rows: &[(String, String, JudgeTally)]) -> String {
    if rows.is_empty() {
        return String::new();
    }
    let mut out = String::from(
        "| scenario | model | frames | no grasp > tau | tried | held | held / frames | held / tried | failures |\n|---|---|---:|---:|---:|---:|---:|---:|---|\n",
    );
    for (scenario, model, t) in rows {
        let failures: Vec<String> = Failure::ALL
            .iter()
            .zip(t.failures)
            .filter(|(_, n)| *n > 0)
            .map(|(f, n)| format!("{} {n}", f.name()))
            .collect();
        let errors = if t.errors > 0 {
            format!(" ({} planning errors)", t.errors)
        } else {
            String::new()
        };
        out.push_str(&format!(
            "| {scenario} | {model} | {}{errors} | {} | {} | {} | {} | {} | {} |\n",
            t.frames,
            t.no_grasp,
            t.tried(),
            t.held,
            share(t.held, t.frames),
            share(t.held, t.tried()),
            if failures.is_empty() {
                "-".to_owned()
            } else {
                failures.join(", ")
            }
        ));
    }
    out
}

/// What [`try_grasp`] came to.
enum Tried {
    /// The approach check stopped it.
    Collided(CollisionSite),
    /// The physics trial ran: its failure, if any, and the grasp's label
    /// ([`GraspLabel::name`]).
    Trial(Option<Failure>, &'static str),
}

/// The approach check, then the physics trial, of `grasp` on object
/// `target`: what it came to, and where the trial left every object
/// (`None` when the approach check stopped it before any physics).
fn try_grasp(
    scene: &Scene,
    target: usize,
    grasp: &PlannedGrasp,
    config: &EpisodeConfig,
) -> (Tried, Option<Vec<Pose>>) {
    let pose = grasp.world_from_grasp;
    let approach = pose.rotation * Vector3::z();
    let mut final_label = None;
    for back in APPROACH_CHECKS_M {
        let at = Translation3::from(-approach * back) * pose;
        // Pre-shaped on the way in: the planned width plus 2 cm, within the stroke.
        let width = if back == 0.0 {
            grasp.width_m
        } else {
            (grasp.width_m + APPROACH_MARGIN_M).min(f64::from(config.gripper.max_width_m))
        };
        let label = label_grasp(scene, target, &at, width, &config.gripper);
        if let GraspLabel::Collision { obstacle, part } = label
            && (back > 0.0 || part != HandPart::Closing)
        {
            return (Tried::Collided(CollisionSite::new(obstacle, part, back)), None);
        }
        if back == 0.0 {
            final_label = Some(label);
        }
    }
    let trial = run_trial(
        scene,
        target,
        &pose,
        grasp.width_m,
        &config.gripper,
        &config.trial,
    );
    let failure = match trial.outcome {
        TrialOutcome::Held { .. } => None,
        TrialOutcome::Dropped { .. } => Some(Failure::SlipDuringLift),
        TrialOutcome::NoGrip => match final_label {
            Some(GraspLabel::TooWide) => Some(Failure::WidthTooSmall),
            _ => Some(Failure::ObjectMissed),
        },
    };
    let name = final_label.as_ref().map_or("none", GraspLabel::name);
    (Tried::Trial(failure, name), Some(trial.poses))
}

/// One episode as a record of `eval.json`'s `episodes`: its scenario,
/// setting and seed, objects at the start, removed and fallen off, how it
/// ended, and each attempt in order as `[outcome, quality, width_mm,
/// down_deg, plan_ms, label, family, view, [u, v], centroid_lever_mm,
/// torque_nm, repairs, tilt_deg]`: "ok", a failure's name, or for a collision on
/// approach what was hit ([`CollisionSite::name`]); the approach's angle
/// below the horizontal (90: straight down); for a physics trial the
/// grasp's analytic label ([`GraspLabel::name`]) and its object's family,
/// else null; the view the grasp came from and its peak pixel there; the
/// lever the planner could see ([`Attempt::centroid_lever_m`]); for a
/// physics trial the weight's torque about the closing line, else null; the
/// names of the planner's repairs to it ([`Repairs::names`]); for a grasp
/// that matched an object, how far the object was tipped from upright
/// ([`Attempt::tilt_deg`]), else null.
pub fn episode_record(e: &Episode, setting: &str) -> serde_json::Value {
    let round = |v: f64, places: i32| (v * 10f64.powi(places)).round() / 10f64.powi(places);
    let attempts: Vec<serde_json::Value> = e
        .attempts
        .iter()
        .map(|a| {
            let outcome = a.outcome_name();
            let approach = a.world_from_grasp.rotation * Vector3::z();
            let down_deg = (-approach.z).clamp(-1.0, 1.0).asin().to_degrees();
            let (label, family) = a.label.map_or((None, None), |(l, f)| (Some(l), Some(f.name())));
            serde_json::json!([
                outcome,
                round(f64::from(a.quality), 3),
                round(a.width_m * 1e3, 1),
                round(down_deg, 1),
                round(a.plan_ms, 2),
                label,
                family,
                a.view.name(),
                a.pixel,
                round(a.centroid_lever_m * 1e3, 1),
                a.torque_nm.map(|t| round(f64::from(t), 3)),
                a.repairs.names(),
                a.tilt_deg.map(|t| round(f64::from(t), 1)),
            ])
        })
        .collect();
    serde_json::json!({
        "scenario": e.scenario.name(),
        "setting": setting,
        "seed": e.seed,
        "objects": e.objects,
        "removed": e.removed,
        "fell_off": e.fell_off,
        "end": e.end.name(),
        "attempts": attempts,
    })
}

/// Writes `rows` of one episode ([`ViewKeeping::rows`]) into `dir`, for
/// learning from physics outcomes (`sim eval --attempt-views`):
/// `attempts_SCENARIO_SEED.npy`, float32 `[n, size_px, size_px]`, each view
/// as the network read it, and `attempts_SCENARIO_SEED.json`, one record
/// per row: the frame's `step` (attempts before it), the grasp's `rank`
/// among those the planner offered there (0 best), `alternative` (false for
/// the episode's own attempt, true for one ranked below it), `view`, `pixel` `[u, v]` (the quality peak the grasp came from),
/// predicted `quality`, `width_mm`, `outcome` ("ok" or why not:
/// [`Attempt::outcome_name`]), analytic `label` and `family` (physics
/// trials only), the planner's `repairs` and the object's `tilt_deg`.
/// Returns the rows written.
pub fn write_attempt_views(
    dir: &Path,
    (scenario, seed): (Scenario, u64),
    rows: &[AttemptRow],
    size_px: usize,
) -> Result<usize> {
    let mut data = Vec::with_capacity(rows.len() * size_px * size_px);
    let mut records = Vec::with_capacity(rows.len());
    for row in rows {
        if row.view.len() != size_px * size_px {
            return Err(Error::Invalid {
                field: "attempt views",
                reason: format!("a view of {} pixels, not {size_px} x {size_px}", row.view.len()),
            });
        }
        data.extend_from_slice(row.view);
        let a = &row.attempt;
        let (label, family) = a.label.map_or((None, None), |(l, f)| (Some(l), Some(f.name())));
        records.push(serde_json::json!({
            "step": row.step,
            "rank": row.rank,
            "alternative": row.alternative,
            "view": a.view.name(),
            "pixel": a.pixel,
            "quality": a.quality,
            "width_mm": (a.width_m * 1e4).round() / 10.0,
            "outcome": a.outcome_name(),
            "label": label,
            "family": family,
            "repairs": a.repairs.names(),
            "tilt_deg": a.tilt_deg,
        }));
    }
    std::fs::create_dir_all(dir).map_err(|e| crate::dataset::file_error(dir, e))?;
    let stem = format!("attempts_{}_{}", scenario.name(), seed);
    crate::dataset::write_npy(
        &dir.join(format!("{stem}.npy")),
        &[records.len(), size_px, size_px],
        &data,
    )?;
    let path = dir.join(format!("{stem}.json"));
    let text = serde_json::to_string(&records).map_err(|e| Error::Scene(format!("{stem}: {e}")))?;
    std::fs::write(&path, text).map_err(|e| crate::dataset::file_error(&path, e))?;
    Ok(records.len())
}

/// A Markdown table of how the analytic labels fared in physics on the
/// grasps `episodes` tried: per label kind ([`GraspLabel::name`]), grasps
/// that held (reached the basket) of those tried, over every family and
/// per family. Collisions on approach and grasps that matched no object
/// never reach physics and are not counted. Empty without physics trials.
pub fn label_table(episodes: &[&Episode]) -> String {
    // (label, family) -> (held, tried); family None: every family.
    let mut counts: BTreeMap<(&str, Option<Family>), (usize, usize)> = BTreeMap::new();
    let mut families: Vec<Family> = Vec::new();
    for a in episodes.iter().flat_map(|e| &e.attempts) {
        let Some((label, family)) = a.label else { continue };
        if !families.contains(&family) {
            families.push(family);
        }
        for key in [(label, None), (label, Some(family))] {
            let c = counts.entry(key).or_insert((0, 0));
            c.0 += usize::from(a.failure.is_none());
            c.1 += 1;
        }
    }
    if counts.is_empty() {
        return String::new();
    }
    families.sort_by_key(|f| Family::ALL.iter().position(|x| x == f));
    let mut out = format!(
        "The tried grasps' analytic labels against physics (held / tried; the labels the network learns from, \
         on the planner's own grasps):\n\n| label | every family | {} |\n|---|---:|{}\n",
        families.iter().map(|f| f.name()).collect::<Vec<_>>().join(" | "),
        "---:|".repeat(families.len())
    );
    let labels: Vec<&str> = counts
        .keys()
        .filter(|(_, f)| f.is_none())
        .map(|(l, _)| *l)
        .collect();
    for label in labels {
        let cell = |family: Option<Family>| {
            let (held, tried) = counts.get(&(label, family)).copied().unwrap_or((0, 0));
            share(held, tried)
        };
        let per_family: Vec<String> = families.iter().map(|&f| cell(Some(f))).collect();
        out.push_str(&format!(
            "| {label} | {} | {} |\n",
            cell(None),
            per_family.join(" | ")
        ));
    }
    out
}

/// `n` of `of` as a table cell: "0.75 (3/4)", or "-" when `of` is 0.
fn share(n: usize, of: usize) -> String {
    if of == 0 {
        "-".to_owned()
    } else {
        format!("{:.2} ({n}/{of})", n as f64 / of as f64)
    }
}

/// Upper edges (N m) of the torque bins of [`provenance_table`].
pub const TORQUE_BINS_NM: [f64; 5] = [0.05, 0.1, 0.2, 0.4, f64::INFINITY];
/// Upper edges (mm) of the lever bins of [`provenance_table`].
pub const LEVER_BINS_MM: [f64; 4] = [10.0, 20.0, 40.0, f64::INFINITY];

/// Markdown tables of where the tried grasps came from and how far from
/// their grip the weight acted: every attempt by the view its grasp came
/// from and by what the planner's hand check changed about it ([`Repairs`];
/// held, collisions on approach, slips during lift, other failures); then
/// the physics trials by the torque of the object's weight about the
/// closing line ([`TORQUE_BINS_NM`]) and by the lever the planner could see
/// ([`LEVER_BINS_MM`]), with the share that held and that slipped during
/// lift, and by family and the pose the object lay in ([`POSES`]: the share
/// that slipped). Empty without attempts.
pub fn provenance_table(episodes: &[&Episode]) -> String {
    let attempts: Vec<&Attempt> = episodes.iter().flat_map(|e| &e.attempts).collect();
    if attempts.is_empty() {
        return String::new();
    }
    let failed = |of: &[&Attempt], f: Option<Failure>| of.iter().filter(|a| a.failure == f).count();
    let row = |name: &str, of: &[&Attempt]| {
        let ok = failed(of, None);
        let collided = failed(of, Some(Failure::CollisionOnApproach));
        let slips = failed(of, Some(Failure::SlipDuringLift));
        format!(
            "| {name} | {} | {} | {collided} | {slips} | {} |\n",
            of.len(),
            share(ok, of.len()),
            of.len() - ok - collided - slips
        )
    };
    let header = "| attempts | held | collision on approach | slip during lift | other failures |\n\
                  |---|---:|---:|---:|---:|---:|\n";
    let mut out = format!("The attempts by the view their grasp came from:\n\n| view {header}");
    for view in ViewAxis::ALL {
        let of: Vec<&Attempt> = attempts.iter().copied().filter(|a| a.view == view).collect();
        out.push_str(&row(view.name(), &of));
    }
    out.push_str(&format!(
        "\nThe attempts by what the planner's hand check changed about their grasp (a grasp may count in \
         several rows):\n\n| repair {header}"
    ));
    let untouched: Vec<&Attempt> = attempts
        .iter()
        .copied()
        .filter(|a| a.repairs == Repairs::default())
        .collect();
    out.push_str(&row("none (as decoded)", &untouched));
    for name in Repairs::ALL_NAMES {
        let of: Vec<&Attempt> = attempts
            .iter()
            .copied()
            .filter(|a| a.repairs.names().contains(&name))
            .collect();
        out.push_str(&row(name, &of));
    }
    let trials: Vec<&Attempt> = attempts.into_iter().filter(|a| a.torque_nm.is_some()).collect();
    if trials.is_empty() {
        return out;
    }
    let mut binned = |title: &str, edges: &[f64], value: &dyn Fn(&Attempt) -> f64| {
        out.push_str(&format!(
            "\n| {title} | physics trials | held | slip during lift |\n|---|---:|---:|---:|\n"
        ));
        let mut lower = 0.0;
        for &upper in edges {
            let of: Vec<&Attempt> = trials
                .iter()
                .copied()
                .filter(|a| (lower..upper).contains(&value(a)))
                .collect();
            let bin = if upper.is_finite() {
                format!("{lower}-{upper}")
            } else {
                format!(">= {lower}")
            };
            out.push_str(&format!(
                "| {bin} | {} | {} | {} |\n",
                of.len(),
                share(failed(&of, None), of.len()),
                share(failed(&of, Some(Failure::SlipDuringLift)), of.len())
            ));
            lower = upper;
        }
    };
    binned(
        "torque of the weight about the closing line (N m)",
        &TORQUE_BINS_NM,
        &|a| a.torque_nm.map_or(f64::NAN, f64::from),
    );
    binned(
        "lever the planner saw: closing line to the segmented centroid (mm)",
        &LEVER_BINS_MM,
        &|a| a.centroid_lever_m * 1e3,
    );
    // Trials by family and by the pose the object lay in.
    let mut families: Vec<Family> = trials.iter().filter_map(|a| a.label.map(|(_, f)| f)).collect();
    families.sort_by_key(|f| Family::ALL.iter().position(|x| x == f));
    families.dedup();
    out.push_str(&format!(
        "\nThe physics trials by family and the pose the object lay in (slipped during lift / trials; \
         upright: tipped less than {} degrees from how the scene stood it, toppled: {0}-{} degrees, \
         upside down: more):\n\n| family | {} |\n|---|{}\n",
        POSES[0].1,
        POSES[1].1,
        POSES.map(|(name, _)| name).join(" | "),
        "---:|".repeat(POSES.len())
    ));
    for family in families {
        let cells: Vec<String> = POSES
            .iter()
            .map(|(pose, _)| {
                let of: Vec<&Attempt> = trials
                    .iter()
                    .copied()
                    .filter(|a| {
                        a.label.is_some_and(|(_, f)| f == family)
                            && a.tilt_deg.is_some_and(|t| pose_name(t) == *pose)
                    })
                    .collect();
                share(failed(&of, Some(Failure::SlipDuringLift)), of.len())
            })
            .collect();
        out.push_str(&format!("| {} | {} |\n", family.name(), cells.join(" | ")));
    }
    out
}

/// Episodes of one scenario under one setting, summed.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// The scenario.
    pub scenario: Scenario,
    /// The setting's name.
    pub setting: String,
    /// Episodes.
    pub episodes: usize,
    /// Objects on the tables at the start.
    pub objects: usize,
    /// Objects removed.
    pub removed: usize,
    /// Objects that fell off the table while piles settled.
    pub fell_off: usize,
    /// Attempts.
    pub attempts: usize,
    /// Successful attempts.
    pub successes: usize,
    /// Failed attempts by cause, in [`Failure::ALL`] order.
    pub failures: [usize; 4],
    /// Collisions on approach by where they happened.
    pub collisions: BTreeMap<CollisionSite, usize>,
    /// Episodes that ended with no grasp above tau.
    pub ended_without_grasp: usize,
    /// Episodes that cleared the table.
    pub cleared: usize,
    /// Planning time percentiles (ms): 50th, 90th.
    pub plan_ms: [f64; 2],
    /// 95% interval of the success rate, resampling whole episodes
    /// ([`episode_bootstrap`]; NaN without attempts).
    pub success_ci95: [f64; 2],
    /// 95% interval of the removal rate, resampling whole episodes.
    pub removal_ci95: [f64; 2],
}

/// Resamples drawn by [`episode_bootstrap`].
pub const BOOTSTRAP_RESAMPLES: usize = 2000;

/// The 2.5th and 97.5th percentiles of `sum(numerator) / sum(denominator)`
/// over [`BOOTSTRAP_RESAMPLES`] resamples, with replacement, of the
/// episodes' `(numerator, denominator)` pairs: a percentile bootstrap over
/// episodes, since the attempts and objects of one episode are not
/// independent of each other. Seeded, so a report is reproducible;
/// resamples with a zero denominator are left out; NaN when none is left.
pub fn episode_bootstrap(pairs: &[(usize, usize)]) -> [f64; 2] {
    let mut rng = SplitMix64::new(0xB007_57A9);
    let mut rates = Vec::with_capacity(BOOTSTRAP_RESAMPLES);
    if !pairs.is_empty() {
        for _ in 0..BOOTSTRAP_RESAMPLES {
            let (mut num, mut den) = (0usize, 0usize);
            for _ in 0..pairs.len() {
                let (n, d) = pairs[rng.below(pairs.len())];
                num += n;
                den += d;
            }
            if den > 0 {
                rates.push(num as f64 / den as f64);
            }
        }
    }
    if rates.is_empty() {
        return [f64::NAN; 2];
    }
    rates.sort_by(f64::total_cmp);
    let at = |p: f64| rates[((rates.len() - 1) as f64 * p).round() as usize];
    [at(0.025), at(0.975)]
}

impl Summary {
    /// Sums `episodes` (all of one scenario and setting).
    pub fn of(scenario: Scenario, setting: &Setting, episodes: &[Episode]) -> Self {
        let mut failures = [0; 4];
        let mut collisions = BTreeMap::new();
        let mut times: Vec<f64> = Vec::new();
        for e in episodes {
            for a in &e.attempts {
                times.push(a.plan_ms);
                if let Some(site) = a.collision {
                    *collisions.entry(site).or_insert(0) += 1;
                }
                if let Some(f) = a.failure {
                    failures[Failure::ALL.iter().position(|&x| x == f).unwrap_or(0)] += 1;
                }
            }
            times.extend(e.last_plan_ms);
        }
        times.sort_by(f64::total_cmp);
        let pct = |p: f64| {
            if times.is_empty() {
                f64::NAN
            } else {
                times[((times.len() - 1) as f64 * p).round() as usize]
            }
        };
        Self {
            scenario,
            setting: setting.name(),
            episodes: episodes.len(),
            objects: episodes.iter().map(|e| e.objects).sum(),
            removed: episodes.iter().map(|e| e.removed).sum(),
            fell_off: episodes.iter().map(|e| e.fell_off).sum(),
            attempts: episodes.iter().map(|e| e.attempts.len()).sum(),
            successes: episodes.iter().map(Episode::successes).sum(),
            failures,
            collisions,
            ended_without_grasp: episodes.iter().filter(|e| e.end == End::NoGraspAboveTau).count(),
            cleared: episodes.iter().filter(|e| e.end == End::Cleared).count(),
            plan_ms: [pct(0.5), pct(0.9)],
            success_ci95: episode_bootstrap(
                &episodes
                    .iter()
                    .map(|e| (e.successes(), e.attempts.len()))
                    .collect::<Vec<_>>(),
            ),
            removal_ci95: episode_bootstrap(
                &episodes
                    .iter()
                    .map(|e| (e.removed, e.objects))
                    .collect::<Vec<_>>(),
            ),
        }
    }

    /// Successful attempts over attempts (NaN without attempts).
    pub fn success_rate(&self) -> f64 {
        self.successes as f64 / self.attempts as f64
    }

    /// Objects removed over objects at the start.
    pub fn removal_rate(&self) -> f64 {
        self.removed as f64 / self.objects as f64
    }
}

/// The paper's simulated results (success, removal) per scenario, for the report.
pub fn paper_numbers(scenario: Scenario) -> &'static str {
    match scenario {
        Scenario::Isolated => "0.926 success",
        Scenario::Packed => "0.84 / 0.88 (tau 0.8)",
        Scenario::Pile => "0.75 / 0.89 (tau 0.8)",
        Scenario::Clutter => "removal >= 0.90 (real robot: 9 of 10 runs cleared)",
    }
}

/// A Markdown list of where the collisions on approach of `summaries`
/// happened, most frequent first (empty when there were none).
pub fn collision_list(summaries: &[Summary]) -> String {
    let mut out = String::new();
    for s in summaries.iter().filter(|s| !s.collisions.is_empty()) {
        let mut sites: Vec<(&CollisionSite, &usize)> = s.collisions.iter().collect();
        sites.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
        let sites: Vec<String> = sites.iter().map(|(k, n)| format!("{} {n}", k.name())).collect();
        out.push_str(&format!(
            "- {}, {}: {}\n",
            s.scenario.name(),
            s.setting,
            sites.join("; ")
        ));
    }
    if out.is_empty() {
        out
    } else {
        format!(
            "Collisions on approach, by what the hand hit (pads or palm; \"closing\": a pad met a neighbour \
             before the object) and where (at the grasp pose, or 2.5-10 cm back on the way in):\n\n{out}"
        )
    }
}

/// The Markdown table of `summaries`.
pub fn markdown_table(summaries: &[Summary]) -> String {
    let mut out = String::from(
        "| scenario | setting | episodes | success | removal | attempts | cleared | no grasp > tau | collision on approach | slip during lift | width too small | object missed | plan p50 / p90 (ms) | paper | 95% intervals: success; removal |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|\n",
    );
    let interval = |ci: [f64; 2]| {
        if ci.iter().all(|v| v.is_finite()) {
            format!("{:.2}-{:.2}", ci[0], ci[1])
        } else {
            "-".to_owned()
        }
    };
    for s in summaries {
        out.push_str(&format!(
            "| {} | {} | {} | {:.2} ({}/{}) | {:.2} ({}/{}) | {} | {} | {} | {} | {} | {} | {} | {:.0} / {:.0} | {} | {}; {} |\n",
            s.scenario.name(),
            s.setting,
            s.episodes,
            s.success_rate(),
            s.successes,
            s.attempts,
            s.removal_rate(),
            s.removed,
            s.objects,
            s.attempts,
            s.cleared,
            s.ended_without_grasp,
            s.failures[0],
            s.failures[1],
            s.failures[2],
            s.failures[3],
            s.plan_ms[0],
            s.plan_ms[1],
            paper_numbers(s.scenario),
            interval(s.success_ci95),
            interval(s.removal_ci95),
        ));
    }
    out
}
