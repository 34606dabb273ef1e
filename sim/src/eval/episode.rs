//! What an episode is and records: failures, ends, attempts, collision sites, the episode, its configuration, scene and first frame.

use super::*;

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
    pub(super) fn new(obstacle: Obstacle, part: HandPart, back_m: f64) -> Self {
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

/// The default planner's settings with the crease split of `crease`
/// ([`crease_setting`]'s text form).
pub fn config_with_crease(crease: &str) -> Result<PlannerConfig> {
    Ok(PlannerConfig {
        cluster: ClusterConfig {
            crease: crease_setting(crease)?,
            ..ClusterConfig::default()
        },
        ..PlannerConfig::default()
    })
}

/// A default planner with the crease split of `crease` ([`crease_setting`]'s
/// text form), for comparing segmentations.
pub fn planner_with_crease(crease: &str, contract: &ModelContract) -> Result<Planner> {
    Planner::new(config_with_crease(crease)?, contract.clone()).map_err(|e| Error::Invalid {
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
