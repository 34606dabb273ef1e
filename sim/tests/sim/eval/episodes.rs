//! Episodes (`sim::eval::run_episode`): the camera, the books, the rules that end them, grasps not tried twice.

use super::*;

/// An episode's camera holds every object whole when one of its draws
/// does; the count says which objects it would cut.
#[test]
fn episode_cameras_hold_every_object() {
    let catalog = mvgrasp_sim::objects::Catalog::of(&Family::ALL);
    let (mut held, mut redrawn) = (0, 0);
    for seed in 900_000..900_006 {
        let (scene, camera) = episode_scene(Scenario::Clutter, seed, &catalog).unwrap();
        // The first draw, as the episode's camera was before 2026-11-24.
        let mut rng = mvgrasp_core::rng::SplitMix64::new(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xE7A1);
        let first = Camera::random(&mut rng, Vector3::new(0.0, 0.0, f64::from(scene.table_z)), false);
        let outside = objects_outside_view(&scene, &camera);
        assert!(outside <= objects_outside_view(&scene, &first));
        held += usize::from(outside == 0);
        redrawn += usize::from(camera.world_from_camera != first.world_from_camera);
        // Every object the camera holds projects inside the image: its
        // rendered pixels never touch the border.
        let frame = mvgrasp_sim::camera::render(&scene, &camera, None);
        let (w, h) = (camera.width as usize, camera.height as usize);
        let touching = (0..scene.objects.len())
            .filter(|&i| {
                frame.labels.iter().enumerate().any(|(p, &l)| {
                    usize::from(l) == i + 2 && (p % w == 0 || p % w == w - 1 || p / w == 0 || p / w == h - 1)
                })
            })
            .count();
        assert!(
            touching <= outside,
            "seed {seed}: {touching} objects at the border, {outside} outside"
        );
    }
    // 15-20 objects over 0.8 x 0.64 m: the first draw often cuts some.
    assert!(redrawn > 0 && held >= 5, "redrawn {redrawn}, held {held} of 6");
    // Moved 3 m away, an object is outside any camera's view.
    let (mut scene, camera) = episode_scene(Scenario::Isolated, 900_000, &catalog).unwrap();
    assert_eq!(objects_outside_view(&scene, &camera), 0);
    let o = &mut scene.objects[0];
    o.world_from_object.translation.x += 3.0;
    o.world_aabb = o.model.aabb_at(&o.world_from_object);
    assert_eq!(objects_outside_view(&scene, &camera), 1);
}

/// `eval.json`'s per-episode record: the books and every attempt.
#[test]
fn an_episode_record_keeps_the_books_and_each_attempt() {
    // Straight down (grasp z = world -z), then level (grasp z = world x).
    let down = Isometry3::from_parts(
        nalgebra::Translation3::new(0.1, 0.2, 0.05),
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
    );
    let level = Isometry3::from_parts(
        nalgebra::Translation3::identity(),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2),
    );
    let e = Episode {
        scenario: Scenario::Pile,
        seed: 900_003,
        objects: 5,
        removed: 1,
        fell_off: 1,
        attempts: vec![
            Attempt {
                plan_ms: 12.345,
                world_from_grasp: down,
                width_m: 0.0614,
                quality: 0.71234,
                failure: None,
                collision: None,
                label: Some(("positive", Family::Box)),
                view: ViewAxis::Top,
                pixel: [36, 40],
                repairs: Repairs {
                    squared: true,
                    deepened: true,
                    ..Repairs::default()
                },
                centroid_lever_m: 0.01234,
                torque_nm: Some(0.04567),
                tilt_deg: Some(91.26),
            },
            Attempt {
                plan_ms: 9.0,
                world_from_grasp: level,
                width_m: 0.08,
                quality: 0.5,
                failure: Some(Failure::CollisionOnApproach),
                collision: Some(CollisionSite {
                    obstacle: Obstacle::Neighbour(0),
                    part: HandPart::Palm,
                    on_the_way_in: true,
                }),
                label: None,
                view: ViewAxis::Front,
                pixel: [10, 71],
                repairs: Repairs::default(),
                centroid_lever_m: 0.0,
                torque_nm: None,
                tilt_deg: None,
            },
            Attempt {
                plan_ms: 8.0,
                world_from_grasp: down,
                width_m: 0.1,
                quality: 0.4,
                failure: Some(Failure::SlipDuringLift),
                collision: None,
                label: Some(("not antipodal", Family::Mug)),
                view: ViewAxis::Side,
                pixel: [0, 0],
                repairs: Repairs::default(),
                centroid_lever_m: 0.05,
                torque_nm: Some(0.3),
                tilt_deg: None,
            },
        ],
        end: End::NoGraspAboveTau,
        last_plan_ms: Some(7.0),
    };
    let r = episode_record(&e, "all:0.1");
    assert_eq!(r["scenario"], "pile");
    assert_eq!(r["setting"], "all:0.1");
    assert_eq!(r["seed"], 900_003);
    assert_eq!(
        (
            r["objects"].as_u64(),
            r["removed"].as_u64(),
            r["fell_off"].as_u64()
        ),
        (Some(5), Some(1), Some(1))
    );
    assert_eq!(r["end"], "no grasp above tau");
    let a = r["attempts"].as_array().unwrap();
    assert_eq!(a.len(), 3);
    assert_eq!(
        a[0],
        serde_json::json!([
            "ok",
            0.712,
            61.4,
            90.0,
            12.35,
            "positive",
            "box",
            "top",
            [36, 40],
            12.3,
            0.046,
            ["squared", "deepened"],
            91.3
        ])
    );
    // No physics trial: no label, family or torque.
    assert!(
        a[1][5].is_null() && a[1][6].is_null() && a[1][10].is_null(),
        "{}",
        a[1]
    );
    assert_eq!(
        (&a[1][7], &a[1][8]),
        (&"front".into(), &serde_json::json!([10, 71]))
    );
    assert_eq!(a[1][11], serde_json::json!([]));
    assert!(a[1][12].is_null(), "{}", a[1]);
    assert_eq!(
        a[1][0],
        format!(
            "collision on approach: {}",
            e.attempts[1].collision.unwrap().name()
        )
    );
    assert_eq!(a[1][3], 0.0);
    assert_eq!(a[2][0], Failure::SlipDuringLift.name());
    assert_eq!((&a[2][5], &a[2][6]), (&"not antipodal".into(), &"mug".into()));
    assert_eq!(
        (&a[2][7], &a[2][9], &a[2][10]),
        (&"side".into(), &50.0.into(), &0.3.into())
    );
}

#[test]
fn episodes_keep_their_books_and_end_by_the_rules() {
    let mut net = MomentsNet::default();
    let planner = Planner::new(PlannerConfig::default(), net.contract().clone()).unwrap();
    let config = EpisodeConfig::default();
    let setting = Setting::parse("entropy:0.3").unwrap();
    let mut attempts = 0;
    for (scenario, seed) in [
        (Scenario::Isolated, 900_000),
        (Scenario::Isolated, 900_001),
        (Scenario::Packed, 900_000),
        (Scenario::Pile, 900_000),
    ] {
        let mut run = || {
            let mut source = InProcess {
                planner: &planner,
                net: &mut net,
            };
            run_episode(scenario, seed, &setting, &mut source, &config).unwrap()
        };
        let e = run();
        // Same seed, same episode: scenes, cameras and noise are fixed by the seed.
        let again = run();
        let outcomes = |e: &Episode| {
            let tried: Vec<_> = e.attempts.iter().map(|a| (a.quality, a.failure)).collect();
            (e.removed, e.fell_off, e.end, tried)
        };
        assert_eq!(outcomes(&e), outcomes(&again));
        assert_eq!(e.removed, e.successes());
        assert!(e.removed + e.fell_off <= e.objects);
        assert!(e.attempts.len() <= 2 * e.objects + 3);
        let tail = e
            .attempts
            .iter()
            .rev()
            .take_while(|a| a.failure.is_some())
            .count();
        match e.end {
            End::Cleared => assert_eq!(e.removed + e.fell_off, e.objects),
            End::ConsecutiveFailures => assert_eq!(tail, 3),
            End::NoGraspAboveTau => assert!(e.last_plan_ms.is_some()),
            End::AttemptLimit => assert_eq!(e.attempts.len(), 2 * e.objects + 3),
        }
        assert!(e.attempts.iter().all(|a| a.quality >= 0.3 && a.plan_ms > 0.0));
        attempts += e.attempts.len();
    }
    assert!(attempts > 0, "the baseline tried no grasp at all");
}

/// Plans the same ranked list for every frame.
struct Scripted(Vec<PlannedGrasp>);

impl GraspSource for Scripted {
    fn grasps(
        &mut self,
        _: &Frame,
        _: mvgrasp_core::Workspace,
        options: &mvgrasp_core::PlanOptions,
    ) -> mvgrasp_sim::Result<Vec<PlannedGrasp>> {
        Ok(self.0.iter().take(options.max_grasps).cloned().collect())
    }
}

#[test]
fn a_refused_grasp_is_not_tried_again_in_an_unchanged_scene() {
    // Two grasps over empty table, 5 cm apart: neither matches an
    // object, so the scene never moves.
    let at = |x: f64| PlannedGrasp {
        world_from_grasp: Isometry3::translation(x, -0.45, 0.1),
        width_m: 0.05,
        quality: 0.9,
        object_centroid: Point3::new(x, -0.45, 0.1),
        view: ViewAxis::Front,
        pixel: [3, 4],
        repairs: Repairs::default(),
    };
    let mut source = Scripted(vec![at(0.5), at(0.55)]);
    let setting = Setting::parse("all:0.1").unwrap();
    let e = run_episode(
        Scenario::Isolated,
        900_000,
        &setting,
        &mut source,
        &EpisodeConfig::default(),
    )
    .unwrap();
    let tried: Vec<f64> = e
        .attempts
        .iter()
        .map(|a| a.world_from_grasp.translation.x)
        .collect();
    assert_eq!(tried, vec![0.5, 0.55]);
    assert!(
        e.attempts
            .iter()
            .all(|a| a.failure == Some(Failure::ObjectMissed))
    );
    // Where each came from is kept; no object matched, so no trial,
    // torque or tilt.
    assert!(
        e.attempts.iter().all(|a| a.view == ViewAxis::Front
            && a.pixel == [3, 4]
            && a.torque_nm.is_none()
            && a.tilt_deg.is_none()),
        "{:?}",
        e.attempts
    );
    assert_eq!(e.end, End::NoGraspAboveTau);
}

#[test]
fn a_grasp_that_failed_in_physics_is_not_tried_again_until_an_object_is_taken() {
    // Two top-down grasps 30 cm over the isolated object, 5 cm apart,
    // matched to it by their centroid: each passes the approach check,
    // closes on air in the physics trial and leaves the scene as it was.
    let config = EpisodeConfig::default();
    let (scene, _) = episode_scene(Scenario::Isolated, 900_000, &config.catalog).unwrap();
    let aabb = scene.objects[0].world_aabb;
    let centre = (aabb.mins + aabb.maxs) * 0.5;
    let centroid = Point3::new(f64::from(centre.x), f64::from(centre.y), f64::from(centre.z));
    let down = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let over = |dx: f64| PlannedGrasp {
        world_from_grasp: Isometry3::from_parts((centroid.coords + Vector3::new(dx, 0.0, 0.3)).into(), down),
        width_m: 0.05,
        quality: 0.9,
        object_centroid: centroid,
        view: ViewAxis::Top,
        pixel: [36, 36],
        repairs: Repairs::default(),
    };
    let mut source = Scripted(vec![over(0.0), over(0.05)]);
    let setting = Setting::parse("all:0.1").unwrap();
    let e = run_episode(Scenario::Isolated, 900_000, &setting, &mut source, &config).unwrap();
    let tried: Vec<f64> = e
        .attempts
        .iter()
        .map(|a| a.world_from_grasp.translation.x - centroid.x)
        .collect();
    assert_eq!(tried.len(), 2, "{tried:?}");
    assert!(
        tried[0].abs() < 1e-9 && (tried[1] - 0.05).abs() < 1e-9,
        "{tried:?}"
    );
    // Both ran the trial (a label, no approach collision) and failed.
    assert!(
        e.attempts
            .iter()
            .all(|a| a.failure.is_some() && a.collision.is_none() && a.label.is_some()),
        "{:?}",
        e.attempts
    );
    assert_eq!(e.end, End::NoGraspAboveTau);
    assert_eq!(e.removed, 0);
    // Each trial records the weight's torque at the grasp as planned, in
    // the scene as it stood: the first in the episode's scene, the second
    // in the scene the first trial left (settled; it barely moved).
    let torque = |dx: f64| weight_torque_nm(&scene.objects[0], &pose_of(&over(dx).world_from_grasp));
    assert_eq!(e.attempts[0].torque_nm, Some(torque(0.0)));
    let second = e.attempts[1].torque_nm.expect("a trial ran");
    assert_eq!(e.attempts[0].tilt_deg, Some(object_tilt_deg(&scene.objects[0])));
    assert!((second - torque(0.05)).abs() < 0.01, "{second} {}", torque(0.05));
    // The closing line (world x) runs through the centroid the planner
    // saw, so the lever it saw is zero.
    assert!(
        e.attempts.iter().all(|a| a.centroid_lever_m < 1e-9),
        "{:?}",
        e.attempts
    );
}
