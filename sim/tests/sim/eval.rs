//! The clear-the-table loop (`sim::eval`): settings, episodes, grasp sources, reports, the bootstrap.

use mvgrasp_core::{
    CreaseConfig, GraspNet, MomentsNet, Planner, PlannerConfig, Reattach, Repairs, ViewAxis, ViewPolicy,
};
use mvgrasp_sim::camera::Camera;
use mvgrasp_sim::camera::Frame;
use mvgrasp_sim::eval::{
    Attempt, CollisionSite, End, Episode, EpisodeConfig, Failure, GraspSource, InProcess, PlannedGrasp,
    Setting, Summary, collision_list, crease_setting, crease_text, episode_bootstrap, episode_record,
    episode_scene, horizontal_lever_m, label_table, markdown_table, object_tilt_deg, objects_outside_view,
    pose_name, provenance_table, run_episode, same_grasp, square_turn_setting,
};
use mvgrasp_sim::grasp::{HandPart, Obstacle, pose_of, weight_torque_nm};
use mvgrasp_sim::objects::Family;
use mvgrasp_sim::scene::Scenario;
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

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
fn settings_parse_and_bad_ones_say_why() {
    let s = Setting::parse("top-down:0.9").unwrap();
    assert_eq!((s.policy, s.tau), (ViewPolicy::TopDown, 0.9));
    assert_eq!(Setting::parse(&s.name()).unwrap(), s);
    for (bad, why) in [
        ("entropy", "POLICY:TAU"),
        ("entropy:x", "tau"),
        ("entropy:1.5", "outside"),
        ("sideways:0.8", "not a view policy"),
    ] {
        let err = Setting::parse(bad).unwrap_err().to_string();
        assert!(err.contains(why), "{bad}: {err}");
    }
}

#[test]
fn square_turn_settings_within_a_quarter_turn_only() {
    for ok in [0.0, 15.0, 35.0, 90.0] {
        assert_eq!(square_turn_setting(ok).unwrap(), ok);
    }
    for bad in [-1.0, 90.5, f64::NAN, f64::INFINITY] {
        let e = square_turn_setting(bad).unwrap_err().to_string();
        assert!(e.contains("square-turn-deg") && e.contains("0-90"), "{bad}: {e}");
    }
}

#[test]
fn crease_settings_parse_and_bad_ones_say_why() {
    assert_eq!(crease_setting("on").unwrap(), Some(CreaseConfig::default()));
    assert_eq!(crease_setting("off").unwrap(), None);
    let c = crease_setting("3:8:4.5:0.25:120").unwrap().unwrap();
    assert_eq!(
        (c.smooth_radius_px, c.baseline_px, c.min_part_points),
        (3, 8, 120)
    );
    assert!((c.min_valley_m - 0.0045).abs() < 1e-7 && (c.min_valley_ratio - 0.25).abs() < 1e-7);
    assert_eq!(
        c.reattach,
        Some(Reattach::default()),
        "five fields keep step 6's defaults"
    );
    let split_only = crease_setting("split-only").unwrap().unwrap();
    assert_eq!(
        split_only,
        CreaseConfig {
            reattach: None,
            ..CreaseConfig::default()
        }
    );
    let r = crease_setting("2:6:5:0.4:200:15:0.25:0.2:12")
        .unwrap()
        .unwrap()
        .reattach
        .unwrap();
    assert!((r.max_area_m2 - 0.0015).abs() < 1e-7 && (r.max_step_m - 0.012).abs() < 1e-7);
    assert!((r.max_share - 0.25).abs() < 1e-7 && (r.min_outline_share - 0.2).abs() < 1e-7);
    let off = crease_setting("2:6:5:0.4:200:0:0.3:0.15:20").unwrap().unwrap();
    assert_eq!(off.reattach, None, "an area of 0 turns step 6 off");
    for text in [
        "on",
        "off",
        "split-only",
        "3:8:4.5:0.25:120",
        "2:6:5:0.4:200:15:0.25:0.2:12",
    ] {
        let config = crease_setting(text).unwrap();
        let back = crease_setting(&crease_text(config.as_ref())).unwrap();
        assert_eq!(back, config, "{text} -> {}", crease_text(config.as_ref()));
    }
    for (bad, why) in [
        ("maybe", "SMOOTH_PX:BASELINE_PX"),
        ("2:6:5:0.4", "SMOOTH_PX:BASELINE_PX"),
        ("2:6:5:0.4:200:20", "AREA_CM2:SHARE:OUTLINE:STEP_MM"),
        ("2:6:5:0.4:200:20:0.3:0.15:x", "step"),
        ("2:0:5:0.4:200", "at least 1 px"),
        ("2:6:-5:0.4:200", "valley depth"),
        ("2:6:5:nan:200", "ratio"),
        ("2.5:6:5:0.4:200", "smoothing radius"),
    ] {
        let err = crease_setting(bad).unwrap_err().to_string();
        assert!(err.contains(why), "{bad}: {err}");
    }
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

/// `run_episode_with` planning in process with `planner` and `net`.
fn hooked_episode(
    planner: &Planner,
    net: &mut dyn GraspNet,
    (scenario, seed, setting): (Scenario, u64, &Setting),
    config: &EpisodeConfig,
    hook: &mut dyn FnMut(usize, &mvgrasp_sim::scene::Scene, &Frame),
) -> Episode {
    let mut source = InProcess { planner, net };
    mvgrasp_sim::eval::run_episode_with(scenario, seed, setting, &mut source, config, hook).unwrap()
}

/// `sim eval --attempt-views`: keeping the views changes nothing about
/// the episode, every attempt gets the view its grasp came from (the
/// network reads the attempt's smoothed quality at its pixel there), and the
/// files hold one row per attempt.
#[test]
fn each_attempt_keeps_the_view_its_grasp_came_from() {
    use mvgrasp_core::{Channel, ViewBatch};
    use mvgrasp_sim::eval::{ViewKeeping, write_attempt_views};

    let mut net = MomentsNet::default();
    let contract = net.contract().clone();
    let l = contract.input_size_px;
    let planner = Planner::new(PlannerConfig::default(), contract.clone()).unwrap();
    let config = EpisodeConfig::default();
    let setting = Setting::parse("all:0.1").unwrap();
    let (scenario, seed) = (Scenario::Pile, 900_000);
    let plain = hooked_episode(
        &planner,
        &mut net,
        (scenario, seed, &setting),
        &config,
        &mut |_, _, _| {},
    );
    let mut keeping = ViewKeeping::new(InProcess {
        planner: &planner,
        net: &mut net,
    });
    let kept = run_episode(scenario, seed, &setting, &mut keeping, &config).unwrap();
    let outcomes = |e: &Episode| {
        let tried: Vec<_> = e
            .attempts
            .iter()
            .map(|a| (a.quality, a.failure, a.pixel, a.world_from_grasp))
            .collect();
        (e.removed, e.fell_off, e.end, tried)
    };
    assert_eq!(outcomes(&kept), outcomes(&plain));
    assert!(kept.attempts.len() >= 3, "{} attempts", kept.attempts.len());
    let rows = keeping.rows(&kept, &[], 0, &config).unwrap();
    assert_eq!(rows.len(), kept.attempts.len(), "every attempt has its view");
    assert!(
        rows.iter()
            .enumerate()
            .all(|(k, r)| r.step == k && !r.alternative)
    );
    let views: Vec<Vec<f32>> = rows.iter().map(|r| r.view.to_vec()).collect();
    let mut again = MomentsNet::default();
    let q = contract.channel_index(Channel::Quality);
    for (a, view) in kept.attempts.iter().zip(&views) {
        assert_eq!(view.len(), l * l);
        let maps = again
            .infer(&ViewBatch {
                size_px: l,
                len: 1,
                data: view.clone(),
            })
            .unwrap();
        // The planner peaks on the smoothed quality map.
        let quality = mvgrasp_core::decode::smooth(
            &maps.data[q * l * l..(q + 1) * l * l],
            l,
            l,
            planner.config().decode.smoothing_sigma_px,
        );
        let [u, v] = a.pixel.map(|p| p as usize);
        let at = quality[v * l + u];
        assert!(
            (at - a.quality).abs() < 1e-5,
            "quality {} at the pixel, {} planned",
            at,
            a.quality
        );
    }
    assert!(
        keeping.rows(&kept, &[], 1, &config).is_err(),
        "alternatives need the frames' scenes"
    );
    let out = std::env::temp_dir().join(format!("mvgrasp-attempt-views-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let mut short = rows[1].clone();
    short.view = &short.view[1..];
    let err = write_attempt_views(&out, (scenario, seed), &[short], l).unwrap_err();
    assert!(err.to_string().contains(&format!("not {l} x {l}")), "{err}");
    let rows = write_attempt_views(&out, (scenario, seed), &rows[1..], l).unwrap();
    assert_eq!(rows, kept.attempts.len() - 1);
    let stem = out.join(format!("attempts_pile_{seed}"));
    let records: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(stem.with_extension("json")).unwrap()).unwrap();
    assert_eq!(records.len(), rows);
    for (r, (step, a)) in records.iter().zip(kept.attempts.iter().enumerate().skip(1)) {
        assert_eq!(r["step"], step);
        assert_eq!(r["alternative"], false);
        assert_eq!(r["pixel"], serde_json::json!(a.pixel));
        assert_eq!(r["outcome"], a.outcome_name());
        assert_eq!(r["view"], a.view.name());
    }
    let npy = std::fs::read(stem.with_extension("npy")).unwrap();
    let header = String::from_utf8_lossy(&npy[10..npy.len().min(128)]).into_owned();
    assert!(header.contains(&format!("({rows}, {l}, {l})")), "{header}");
    assert_eq!(
        npy.len() % 64,
        (4 * rows * l * l) % 64,
        "header padded to 64 bytes"
    );
    let first = &npy[npy.len() - 4 * rows * l * l..][..4 * l * l];
    let back: Vec<f32> = first
        .chunks(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    assert_eq!(back, views[1]);
    std::fs::remove_dir_all(&out).unwrap();
}

/// The planner's grasps, with the one of rank `rank` moved first on the
/// first frame only.
struct RankedFirst<'a> {
    inner: InProcess<'a>,
    rank: usize,
    calls: usize,
}

impl GraspSource for RankedFirst<'_> {
    fn grasps(
        &mut self,
        frame: &Frame,
        workspace: mvgrasp_core::Workspace,
        options: &mvgrasp_core::PlanOptions,
    ) -> mvgrasp_sim::Result<Vec<PlannedGrasp>> {
        let mut grasps = self.inner.grasps(frame, workspace, options)?;
        if self.calls == 0 {
            let moved = grasps.remove(self.rank);
            grasps.insert(0, moved);
        }
        self.calls += 1;
        Ok(grasps)
    }
}

/// `sim eval --attempt-alternatives`: the grasps ranked below each tried
/// one are tried from the frame's scene without changing the episode,
/// and each comes to what the episode records when the planner ranks it
/// first.
#[test]
fn alternatives_end_as_the_episode_would_with_them_first() {
    use mvgrasp_sim::eval::ViewKeeping;

    let mut net = MomentsNet::default();
    let contract = net.contract().clone();
    let l = contract.input_size_px;
    // This pile comes apart into several objects (several grasps ranked
    // below each tried one) with the crease split on.
    let planner = mvgrasp_sim::eval::planner_with_crease("on", &contract).unwrap();
    let config = EpisodeConfig::default();
    let setting = Setting::parse("all:0.1").unwrap();
    let (scenario, seed) = (Scenario::Pile, 900_000);
    let plain = run_episode(
        scenario,
        seed,
        &setting,
        &mut InProcess {
            planner: &planner,
            net: &mut net,
        },
        &config,
    )
    .unwrap();
    let mut keeping = ViewKeeping::new(InProcess {
        planner: &planner,
        net: &mut net,
    });
    let mut scenes = Vec::new();
    let kept = mvgrasp_sim::eval::run_episode_with(
        scenario,
        seed,
        &setting,
        &mut keeping,
        &config,
        &mut |_, scene, _| scenes.push(scene.clone()),
    )
    .unwrap();
    let outcome = |a: &Attempt| {
        (
            a.failure,
            a.collision,
            a.label,
            a.quality,
            a.pixel,
            a.world_from_grasp,
        )
    };
    assert_eq!(
        kept.attempts.iter().map(outcome).collect::<Vec<_>>(),
        plain.attempts.iter().map(outcome).collect::<Vec<_>>()
    );
    let rows = keeping.rows(&kept, &scenes, 2, &config).unwrap();
    let own: Vec<_> = rows.iter().filter(|r| !r.alternative).collect();
    assert_eq!(own.len(), kept.attempts.len());
    let alternatives: Vec<_> = rows.iter().filter(|r| r.alternative).collect();
    assert!(alternatives.len() >= 4, "{} alternatives", alternatives.len());
    for r in &alternatives {
        let tried = own.iter().find(|o| o.step == r.step).unwrap();
        assert!(!same_grasp(
            &tried.attempt.world_from_grasp,
            &r.attempt.world_from_grasp
        ));
        assert!(r.rank > tried.rank, "ranked below the tried grasp");
        assert_eq!(r.view.len(), l * l);
    }
    assert!(
        (0..kept.attempts.len())
            .all(|step| rows.iter().filter(|r| r.step == step && r.alternative).count() <= 2),
        "at most 2 per frame"
    );
    assert!(rows.windows(2).all(|w| w[0].step <= w[1].step), "in frame order");
    // The first frame's alternatives, ranked first: the episode's first
    // attempt ends exactly as the alternative did.
    let first: Vec<_> = alternatives.iter().filter(|r| r.step == 0).collect();
    assert!(!first.is_empty());
    let mut net = MomentsNet::default();
    for r in first {
        let rank = r.rank;
        let forced = run_episode(
            scenario,
            seed,
            &setting,
            &mut RankedFirst {
                inner: InProcess {
                    planner: &planner,
                    net: &mut net,
                },
                rank,
                calls: 0,
            },
            &config,
        )
        .unwrap();
        assert_eq!(outcome(&forced.attempts[0]), outcome(&r.attempt), "rank {rank}");
    }
}

/// `sim eval --label-frames`: every frame the planner gets is shown to
/// the hook in step order without changing the episode, and a
/// `FrameLabeller` writes them as a dataset whose views name their
/// frame.
#[test]
fn episode_frames_are_labelled_as_datagen_labels_scenes() {
    use mvgrasp_sim::dataset::{DatagenConfig, FrameLabeller};

    let mut net = MomentsNet::default();
    let contract = net.contract().clone();
    let planner = Planner::new(PlannerConfig::default(), contract.clone()).unwrap();
    let config = EpisodeConfig::default();
    let setting = Setting::parse("all:0.1").unwrap();
    let (scenario, seed) = (Scenario::Pile, 900_000);
    let out = std::env::temp_dir().join(format!("mvgrasp-frames-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let datagen = DatagenConfig {
        scenes: 1,
        seed,
        scenarios: vec![scenario],
        catalog: config.catalog.clone(),
        scenes_per_shard: 1,
        targets: mvgrasp_sim::targets::TargetConfig::default(),
        noise: config.noise,
        data_version: "test".into(),
        label_salt: 0,
    };
    assert!(FrameLabeller::new(&out, contract.clone(), datagen.clone(), 0, serde_json::json!({})).is_err());
    let labeller = FrameLabeller::new(
        &out,
        contract,
        datagen,
        2,
        serde_json::json!({"setting": setting.name()}),
    )
    .unwrap();
    let (mut steps, mut views, mut objects) = (Vec::new(), Vec::new(), Vec::new());
    let labelled = hooked_episode(
        &planner,
        &mut net,
        (scenario, seed, &setting),
        &config,
        &mut |step, scene, frame| {
            steps.push(step);
            objects.push(scene.objects.len());
            if labeller.wants(step) {
                views.extend(labeller.label(&planner, (scenario, seed, step), scene, frame));
            }
        },
    );
    let plain = {
        let mut source = InProcess {
            planner: &planner,
            net: &mut net,
        };
        run_episode(scenario, seed, &setting, &mut source, &config).unwrap()
    };
    let outcomes = |e: &Episode| {
        let tried: Vec<_> = e
            .attempts
            .iter()
            .map(|a| (a.quality, a.failure, a.pixel))
            .collect();
        (e.removed, e.fell_off, e.end, tried)
    };
    assert_eq!(outcomes(&labelled), outcomes(&plain));
    assert!(
        labelled.attempts.len() >= 3,
        "{} attempts",
        labelled.attempts.len()
    );
    // One frame before each attempt, and one more if the episode ended on
    // a frame without a grasp to try.
    let frames = labelled.attempts.len() + usize::from(labelled.end == End::NoGraspAboveTau);
    assert_eq!(steps, (0..frames).collect::<Vec<_>>());
    // Objects only leave: the frames after a removal show fewer.
    assert!(objects.windows(2).all(|w| w[1] <= w[0]), "{objects:?}");
    assert!(objects.last() < objects.first(), "{objects:?}");
    // Every second frame labelled: steps 0, 2, ...
    let mut labelled_steps: Vec<usize> = views.iter().filter_map(|v| v.step).collect();
    labelled_steps.dedup();
    assert_eq!(labelled_steps, (0..frames).step_by(2).collect::<Vec<_>>());
    assert!(views.iter().any(|v| v.view.positives > 0));
    labeller.write_episode(scenario, seed, &views).unwrap();
    let report = labeller.finish().unwrap();
    assert_eq!((report.views, report.shards), (views.len(), 1));
    assert!(report.failed.is_empty(), "{:?}", report.failed);
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["views"], views.len());
    assert_eq!(manifest["frames_from"]["every"], 2);
    assert_eq!(manifest["frames_from"]["setting"], "all:0.1");
    assert_eq!(manifest["shards"][0], "shard_pile_900000");
    let meta = super::meta_lines(&out.join("shard_pile_900000"));
    assert_eq!(meta.len(), views.len());
    for (line, v) in meta.iter().zip(&views) {
        let step = v.step.unwrap();
        assert_eq!(line["step"], step);
        assert_eq!(line["instance"], format!("pile-{seed}.{step}:{}", v.view.object));
    }
    let _ = std::fs::remove_dir_all(&out);
}

/// `sim eval --judge`: a grasp tried from a frame's state by
/// `grasp_outcome` ends as the episode's own attempt on that frame did,
/// and leaves the scene as it was; the tallies count and table it.
#[test]
fn a_judged_grasp_ends_as_the_episode_s_attempt_did() {
    use mvgrasp_sim::eval::{JudgeTally, grasp_outcome, judge_table, plan_options};

    let mut net = MomentsNet::default();
    let planner = Planner::new(PlannerConfig::default(), net.contract().clone()).unwrap();
    let config = EpisodeConfig::default();
    let setting = Setting::parse("all:0.1").unwrap();
    let (mut compared, mut failures) = (0, 0);
    for (scenario, seed) in [(Scenario::Packed, 900_001), (Scenario::Packed, 900_002)] {
        let options = plan_options(&setting, seed, &config.gripper);
        let mut judged = Vec::new();
        let mut twin = MomentsNet::default();
        let episode = hooked_episode(
            &planner,
            &mut net,
            (scenario, seed, &setting),
            &config,
            &mut |_, scene, frame| {
                let before: Vec<_> = scene.objects.iter().map(|o| o.world_from_object).collect();
                let mut judge = InProcess {
                    planner: &planner,
                    net: &mut twin,
                };
                let best = judge.grasps(frame, scene.workspace(), &options).unwrap();
                judged.push(
                    best.first()
                        .map(|g| (g.world_from_grasp, grasp_outcome(scene, g, &config))),
                );
                let after: Vec<_> = scene.objects.iter().map(|o| o.world_from_object).collect();
                assert_eq!(before, after, "judging moved the scene");
            },
        );
        // Where the episode tried the judge's grasp (no earlier failure
        // made it take another), both end the same way.
        for (attempt, judged) in episode.attempts.iter().zip(&judged) {
            let Some((pose, outcome)) = judged else { continue };
            if same_grasp(pose, &attempt.world_from_grasp) {
                assert_eq!(*outcome, attempt.failure, "{} {seed}", scenario.name());
                compared += 1;
                failures += usize::from(outcome.is_some());
            }
        }
    }
    assert!(
        compared >= 4 && failures >= 2,
        "{compared} compared, {failures} failed"
    );

    let mut tally = JudgeTally::default();
    tally.add(Some(Some(None)));
    tally.add(Some(Some(Some(Failure::SlipDuringLift))));
    tally.add(Some(None));
    tally.add(None);
    assert_eq!(
        (
            tally.frames,
            tally.tried(),
            tally.held,
            tally.no_grasp,
            tally.errors
        ),
        (4, 2, 1, 1, 1)
    );
    let mut all = JudgeTally::default();
    all.merge(&tally);
    all.merge(&tally);
    assert_eq!((all.frames, all.held, all.failures[1]), (8, 2, 2));
    let table = judge_table(&[("pile".into(), "m.onnx".into(), tally)]);
    assert!(table.contains("| pile | m.onnx | 4 (1 planning errors) | 1 | 2 | 1 | 0.25 (1/4) | 0.50 (1/2) | slip during lift 1 |"), "{table}");
    assert!(judge_table(&[]).is_empty());
    let names: Vec<&str> = [
        None,
        Some(None),
        Some(Some(None)),
        Some(Some(Some(Failure::ObjectMissed))),
    ]
    .into_iter()
    .map(JudgeTally::outcome_name)
    .collect();
    assert_eq!(names, ["planning error", "no grasp", "held", "object missed"]);
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
