//! Summaries and reports: tilt, the lever arm, provenance tables, grasp identity, the bootstrap, summary counts.

use super::*;

#[test]
fn tilt_is_the_angle_of_the_objects_own_up_from_the_worlds() {
    let config = EpisodeConfig::default();
    let (scene, _) = episode_scene(Scenario::Isolated, 900_000, &config.catalog).unwrap();
    let mut object = scene.objects[0].clone();
    for (turn, tilt, pose) in [
        (0.0, 0.0, "upright"),
        (0.4, 22.918_31, "upright"),
        (std::f32::consts::FRAC_PI_2, 90.0, "toppled"),
        (2.7, 154.6986, "upside down"),
        (std::f32::consts::PI, 180.0, "upside down"),
    ] {
        // Any turn about the world's up keeps the tilt.
        object.world_from_object.rotation =
            parry3d::math::Rotation::from_rotation_z(1.0) * parry3d::math::Rotation::from_rotation_x(turn);
        let got = object_tilt_deg(&object);
        assert!((got - tilt).abs() < 1e-3, "{turn}: {got}");
        assert_eq!(pose_name(got), pose, "{turn}: {got}");
    }
}

#[test]
fn the_lever_is_the_horizontal_distance_to_the_closing_line() {
    // Closing along world x through the origin: only the offset across
    // it, horizontally, counts (not along it, not up or down).
    let along_x = Isometry3::identity();
    assert!((horizontal_lever_m(&along_x, &Point3::new(0.3, 0.04, -0.2)) - 0.04).abs() < 1e-12);
    assert!((horizontal_lever_m(&along_x, &Point3::new(0.3, -0.04, 0.5)) - 0.04).abs() < 1e-12);
    // Turned 90 degrees about z and moved: closing along world y.
    let along_y = Isometry3::from_parts(
        nalgebra::Translation3::new(1.0, 2.0, 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2),
    );
    assert!((horizontal_lever_m(&along_y, &Point3::new(1.03, 2.5, 0.1)) - 0.03).abs() < 1e-12);
    // A vertical closing line: the weight has no torque about it.
    let vertical = Isometry3::from_parts(
        nalgebra::Translation3::identity(),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -std::f64::consts::FRAC_PI_2),
    );
    assert!(horizontal_lever_m(&vertical, &Point3::new(0.05, 0.05, 0.0)) < 1e-12);
}

#[test]
fn provenance_counts_attempts_by_view_and_repair_and_trials_by_torque_and_lever() {
    let attempt = |view, failure, torque_nm: Option<f32>, lever_mm: f64| Attempt {
        plan_ms: 5.0,
        world_from_grasp: Isometry3::identity(),
        width_m: 0.05,
        quality: 0.5,
        failure,
        collision: None,
        label: torque_nm.map(|_| ("positive", Family::Box)),
        view,
        pixel: [0, 0],
        repairs: Repairs::default(),
        centroid_lever_m: lever_mm / 1e3,
        torque_nm,
        tilt_deg: torque_nm.map(|_| 5.0),
    };
    let slip = Some(Failure::SlipDuringLift);
    let episode = |attempts| Episode {
        scenario: Scenario::Packed,
        seed: 1,
        objects: 3,
        removed: 0,
        fell_off: 0,
        attempts,
        end: End::Cleared,
        last_plan_ms: None,
    };
    let episodes = [
        episode(vec![
            attempt(ViewAxis::Top, None, Some(0.01), 5.0),
            attempt(ViewAxis::Top, slip, Some(0.3), 25.0),
            attempt(ViewAxis::Top, Some(Failure::CollisionOnApproach), None, 3.0),
        ]),
        episode(vec![
            Attempt {
                repairs: Repairs {
                    squared: true,
                    deepened: true,
                    ..Repairs::default()
                },
                tilt_deg: Some(90.0),
                ..attempt(ViewAxis::Front, slip, Some(0.5), 45.0)
            },
            Attempt {
                repairs: Repairs {
                    deepened: true,
                    ..Repairs::default()
                },
                ..attempt(ViewAxis::Top, None, Some(0.07), 12.0)
            },
            attempt(ViewAxis::Front, Some(Failure::ObjectMissed), None, 0.0),
        ]),
    ];
    let table = provenance_table(&episodes.iter().collect::<Vec<_>>());
    for row in [
        "| top | 4 | 0.50 (2/4) | 1 | 1 | 0 |",
        "| front | 2 | 0.00 (0/2) | 0 | 1 | 1 |",
        "| side | 0 | - | 0 | 0 | 0 |",
        // A grasp counts under each of its repairs.
        "| none (as decoded) | 4 | 0.25 (1/4) | 1 | 1 | 1 |",
        "| refit | 0 | - | 0 | 0 | 0 |",
        "| squared | 1 | 0.00 (0/1) | 0 | 1 | 0 |",
        "| deepened | 2 | 0.50 (1/2) | 0 | 1 | 0 |",
        "| 0-0.05 | 1 | 1.00 (1/1) | 0.00 (0/1) |",
        "| 0.05-0.1 | 1 | 1.00 (1/1) | 0.00 (0/1) |",
        "| 0.1-0.2 | 0 | - | - |",
        "| 0.2-0.4 | 1 | 0.00 (0/1) | 1.00 (1/1) |",
        "| >= 0.4 | 1 | 0.00 (0/1) | 1.00 (1/1) |",
        // Lever bins count the four physics trials only.
        "| 0-10 | 1 | 1.00 (1/1) | 0.00 (0/1) |",
        "| 10-20 | 1 | 1.00 (1/1) | 0.00 (0/1) |",
        "| 20-40 | 1 | 0.00 (0/1) | 1.00 (1/1) |",
        "| >= 40 | 1 | 0.00 (0/1) | 1.00 (1/1) |",
        // Slips by family and pose: three upright trials, one toppled.
        "| family | upright | toppled | upside down |",
        "| box | 0.33 (1/3) | 1.00 (1/1) | - |",
    ] {
        assert!(table.contains(row), "{row}\n{table}");
    }
    // Without physics trials only the views; without attempts nothing.
    let untried = [episode(vec![attempt(
        ViewAxis::Side,
        Some(Failure::ObjectMissed),
        None,
        0.0,
    )])];
    let views_only = provenance_table(&untried.iter().collect::<Vec<_>>());
    assert!(
        views_only.contains("| side | 1 | 0.00 (0/1) | 0 | 0 | 1 |"),
        "{views_only}"
    );
    assert!(!views_only.contains("torque"), "{views_only}");
    assert_eq!(provenance_table(&[&episode(Vec::new())]), "");
}

#[test]
fn the_same_grasp_within_a_centimetre_and_15_degrees_either_way_round() {
    let a = Isometry3::translation(0.1, 0.2, 0.3);
    let turned = |deg: f64, axis: Vector3<f64>| {
        Isometry3::from_parts(
            a.translation,
            UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), deg.to_radians()),
        )
    };
    assert!(same_grasp(&a, &a));
    assert!(same_grasp(&a, &Isometry3::translation(0.109, 0.2, 0.3)));
    assert!(!same_grasp(&a, &Isometry3::translation(0.111, 0.2, 0.3)));
    assert!(same_grasp(&a, &turned(14.0, Vector3::x())));
    assert!(!same_grasp(&a, &turned(16.0, Vector3::x())));
    // Jaws turned half round about the approach: the same grasp.
    assert!(same_grasp(&a, &turned(180.0, Vector3::z())));
    assert!(same_grasp(&a, &turned(170.0, Vector3::z())));
    assert!(!same_grasp(&a, &turned(90.0, Vector3::z())));
}

#[test]
fn the_episode_bootstrap_brackets_the_rate_and_narrows_with_more_episodes() {
    assert!(episode_bootstrap(&[]).iter().all(|v| v.is_nan()));
    assert!(episode_bootstrap(&[(0, 0), (0, 0)]).iter().all(|v| v.is_nan()));
    // Every episode at 4 of 5: no spread at all.
    assert_eq!(episode_bootstrap(&[(4, 5); 16]), [0.8, 0.8]);
    // Episodes removing 2, 3, 4 or 5 of 5 in turn: the interval holds
    // the overall rate (0.7), and four times the episodes halve it
    // roughly (the bootstrap's 1 / sqrt(n)).
    let pairs = |n: usize| (0..n).map(|i| (2 + i % 4, 5)).collect::<Vec<_>>();
    let [lo16, hi16] = episode_bootstrap(&pairs(16));
    let [lo64, hi64] = episode_bootstrap(&pairs(64));
    assert!(lo16 < 0.7 && 0.7 < hi16, "{lo16} {hi16}");
    assert!(lo64 < 0.7 && 0.7 < hi64, "{lo64} {hi64}");
    let ratio = (hi16 - lo16) / (hi64 - lo64);
    assert!((1.6..2.5).contains(&ratio), "{ratio}");
    // Seeded: the same pairs, the same interval.
    assert_eq!(episode_bootstrap(&pairs(16)), [lo16, hi16]);
}

#[test]
fn summaries_count_rates_and_causes() {
    let attempt = |failure| Attempt {
        plan_ms: 10.0,
        world_from_grasp: Isometry3::identity(),
        width_m: 0.05,
        quality: 0.9,
        failure,
        collision: None,
        label: None,
        view: ViewAxis::Top,
        pixel: [36, 36],
        repairs: Repairs::default(),
        centroid_lever_m: 0.0,
        torque_nm: None,
        tilt_deg: None,
    };
    let tried = |failure, label, family| Attempt {
        label: Some((label, family)),
        ..attempt(failure)
    };
    let collided = |obstacle, part, on_the_way_in| Attempt {
        collision: Some(CollisionSite {
            obstacle,
            part,
            on_the_way_in,
        }),
        ..attempt(Some(Failure::CollisionOnApproach))
    };
    let episodes = vec![
        Episode {
            scenario: Scenario::Packed,
            seed: 1,
            objects: 4,
            removed: 3,
            fell_off: 0,
            attempts: vec![
                tried(None, "positive", Family::Cylinder),
                tried(Some(Failure::SlipDuringLift), "not antipodal", Family::Box),
                tried(None, "positive", Family::Box),
                tried(None, "not antipodal", Family::Cylinder),
            ],
            end: End::NoGraspAboveTau,
            last_plan_ms: Some(30.0),
        },
        Episode {
            scenario: Scenario::Packed,
            seed: 2,
            objects: 5,
            removed: 0,
            fell_off: 1,
            attempts: vec![
                Attempt {
                    plan_ms: 30.0,
                    ..collided(Obstacle::Neighbour(0), HandPart::Palm, true)
                },
                collided(Obstacle::Table, HandPart::LeftPad, false),
                collided(Obstacle::Neighbour(0), HandPart::Palm, true),
            ],
            end: End::ConsecutiveFailures,
            last_plan_ms: None,
        },
    ];
    let s = Summary::of(
        Scenario::Packed,
        &Setting::parse("entropy:0.8").unwrap(),
        &episodes,
    );
    assert_eq!((s.attempts, s.successes, s.removed, s.objects), (7, 3, 3, 9));
    assert_eq!(s.fell_off, 1);
    assert!((s.success_rate() - 3.0 / 7.0).abs() < 1e-12);
    assert!((s.removal_rate() - 3.0 / 9.0).abs() < 1e-12);
    assert_eq!(s.failures, [3, 1, 0, 0]);
    let sites: Vec<(String, usize)> = s.collisions.iter().map(|(k, n)| (k.name(), *n)).collect();
    assert_eq!(
        sites,
        [
            ("the table (left pad), at the grasp".to_owned(), 1),
            ("a neighbour (palm), on the way in".to_owned(), 2)
        ]
    );
    let list = collision_list(std::slice::from_ref(&s));
    assert!(
        list.contains(
            "- packed, entropy:0.8: a neighbour (palm), on the way in 2; the table (left pad), at the grasp 1"
        ),
        "{list}"
    );
    assert_eq!((s.ended_without_grasp, s.cleared), (1, 0));
    // Nine planning times (seven of 10 ms, two of 30 ms): p50 10, p90 30.
    assert_eq!(s.plan_ms, [10.0, 30.0]);
    // Resampling the two episodes: both the first (removal 6/8), both
    // the second (0/10) or one of each (3/9), each both ways round.
    assert_eq!(s.removal_ci95, [0.0, 0.75]);
    assert_eq!(s.success_ci95, [0.0, 0.75]);
    let table = markdown_table(&[s]);
    assert!(
        table.contains("| packed | entropy:0.8 | 2 | 0.43 (3/7) | 0.33 (3/9) |"),
        "{table}"
    );
    assert!(table.contains("| 0.00-0.75; 0.00-0.75 |\n"), "{table}");
    // The labels against physics: only the four physics trials count,
    // families in catalogue order.
    let labels = label_table(&episodes.iter().collect::<Vec<_>>());
    for row in [
        "| label | every family | box | cylinder |",
        "| not antipodal | 0.50 (1/2) | 0.00 (0/1) | 1.00 (1/1) |",
        "| positive | 1.00 (2/2) | 1.00 (1/1) | 1.00 (1/1) |",
    ] {
        assert!(labels.contains(row), "{row}\n{labels}");
    }
    assert_eq!(label_table(&[&episodes[1]]), "");
}
