//! What an episode can hand out without changing: attempt views, alternatives, labelled frames, judged grasps.

use super::*;

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

/// `config` with the hand checked against the points seen alone: the
/// simulator's piles lean objects on one another, so where the approach
/// starts their boxes refuse most grasps (`HandConfig::pregrasp_boxes`:
/// a pile frame of the test below offers 1 grasp instead of 4), and the
/// tests of alternatives and judged grasps need several ranked per frame.
fn points_only(mut config: PlannerConfig) -> PlannerConfig {
    config.hand.pregrasp_boxes = false;
    config
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
    let crease_on = mvgrasp_sim::eval::config_with_crease("on").unwrap();
    let planner = Planner::new(points_only(crease_on), contract.clone()).unwrap();
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
    let meta = crate::meta_lines(&out.join("shard_pile_900000"));
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
    let planner = Planner::new(points_only(PlannerConfig::default()), net.contract().clone()).unwrap();
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
