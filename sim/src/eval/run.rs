//! The episode loop: plan, pick a grasp not yet failed, check the approach, try it in physics, settle.

use super::*;

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
        arm_reach: None,
        obstacle_region: None,
        robot_body: Vec::new(),
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
