//! `sim eval`: runs the episodes in parallel (one network per worker),
//! writes the report, and applies the CI floor.

use std::ops::Range;
use std::path::PathBuf;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use mvgrasp_core::{GraspNet, ModelContract, Planner, PlannerConfig};
use mvgrasp_server::settings::ModelSettings;
use mvgrasp_sim::camera::render;
use mvgrasp_sim::dataset::{DATA_VERSION, DatagenConfig, FrameLabeller};
use mvgrasp_sim::eval::{
    Episode, EpisodeConfig, Failure, GraspSource, InProcess, JudgeTally, Remote, Setting, Summary,
    ViewKeeping, collision_list, episode_record, episode_scene, grasp_outcome, judge_table, label_table,
    markdown_table, plan_options, provenance_table, run_episode, run_episode_with, write_attempt_views,
};
use mvgrasp_sim::files::{DrawnGrasp, write_grasp_snapshot};
use mvgrasp_sim::scene::{Scenario, Scene};
use mvgrasp_sim::targets::TargetConfig;
use rayon::prelude::*;

/// Where grasps come from.
pub enum Planning<'a> {
    /// This process, with the model `sim eval` names.
    InProcess(&'a ModelSettings),
    /// A running server at this endpoint.
    Server(String),
}

fn load_net(model: &ModelSettings) -> anyhow::Result<Box<dyn GraspNet + Send>> {
    let batch_views = mvgrasp_server::settings::BatchSettings::default().max_batch_views;
    Ok(mvgrasp_server::backend::load(model, batch_views)
        .with_context(|| format!("loading {}", model.path.display()))?
        .net)
}

enum Worker {
    Net(Box<dyn GraspNet + Send>),
    Remote(Box<Remote>),
}

/// `git rev-parse --short HEAD`, with `-dirty` when tracked files differ
/// from it, other than `results/` (where reports go) and Markdown (docs
/// cannot change an outcome).
fn git_revision() -> String {
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
    };
    let Some(head) = git(&["rev-parse", "--short", "HEAD"]) else {
        return "unknown".to_owned();
    };
    match git(&[
        "status",
        "--porcelain",
        "--untracked-files=no",
        "--",
        ":/",
        ":(top,exclude)results",
        ":(top,exclude,glob)**/*.md",
    ]) {
        Some(changes) if changes.is_empty() => head,
        _ => format!("{head}-dirty"),
    }
}

/// One `sim eval` run.
pub struct EvalRun<'a> {
    /// Where grasps come from.
    pub planning: Planning<'a>,
    /// The in-process planner's configuration.
    pub planner: PlannerConfig,
    /// Scenarios.
    pub scenarios: Vec<Scenario>,
    /// Seeds, per scenario.
    pub seeds: Range<u64>,
    /// Planner settings compared.
    pub settings: Vec<Setting>,
    /// Gripper, physics, noise, families.
    pub config: EpisodeConfig,
    /// Report folder.
    pub out: PathBuf,
    /// The CI floor on the first setting's success rate.
    pub min_success: Option<f64>,
    /// Episodes per scenario drawn into `out/snapshots`.
    pub snapshots: usize,
    /// Label the first setting's frames into a dataset (`None`: don't).
    pub label_frames: Option<LabelFrames>,
    /// Models whose best grasp is tried on every frame of the first
    /// setting's episodes, from the same state (`--judge`; in process only).
    pub judge: Vec<PathBuf>,
    /// Write the first setting's attempts with the views their grasps came
    /// from into this folder (`--attempt-views`; in process only).
    pub attempt_views: Option<PathBuf>,
    /// With `attempt_views`: per frame, up to this many grasps ranked below
    /// the tried one, tried from the same state and written too
    /// (`--attempt-alternatives`; 0: none).
    pub attempt_alternatives: usize,
}

/// `--label-frames DIR --label-every N`: the first setting's episode frames,
/// labelled as `sim datagen` labels its scenes, into a dataset at `out`.
pub struct LabelFrames {
    /// Dataset folder.
    pub out: PathBuf,
    /// Every how many frames of an episode (1: all; 0 is refused).
    pub every: usize,
}

pub fn eval_command(run: &EvalRun) -> anyhow::Result<()> {
    let EvalRun {
        planning,
        planner: planner_config,
        scenarios,
        seeds,
        settings,
        config,
        out,
        min_success,
        snapshots,
        label_frames,
        judge,
        attempt_views,
        attempt_alternatives,
    } = run;
    anyhow::ensure!(!settings.is_empty(), "--settings: at least one");
    // The contract (and the model's name) from the model, or the server.
    let (contract, model_name) = match planning {
        Planning::InProcess(model) => (
            load_net(model)?.contract().clone(),
            model.path.display().to_string(),
        ),
        Planning::Server(endpoint) => {
            let info = Remote::connect(endpoint)?.model_info()?;
            let contract = ModelContract {
                input_size_px: info.input_size_px as usize,
                pixel_size_m: info.pixel_size_m as f32,
                model_version: info.model_version.clone(),
                data_version: info.data_version.clone(),
                ..ModelContract::baseline()
            };
            (contract, format!("the server at {endpoint} ({})", info.backend))
        }
    };
    let planner = Planner::new(planner_config.clone(), contract.clone())?;
    // Judged models: loaded like the planning model, and they must read the
    // views the planner renders for it.
    let judge_settings: Vec<ModelSettings> = match planning {
        _ if judge.is_empty() => Vec::new(),
        Planning::Server(_) => anyhow::bail!("--judge needs the in-process planner (not --server)"),
        Planning::InProcess(model) => judge
            .iter()
            .map(|path| ModelSettings {
                path: path.clone(),
                ..(*model).clone()
            })
            .collect(),
    };
    // Each judged model plans with a planner of its own contract.
    let mut judge_planners = Vec::new();
    for settings in &judge_settings {
        let theirs = load_net(settings)?.contract().clone();
        anyhow::ensure!(
            theirs.input_size_px == contract.input_size_px && theirs.pixel_size_m == contract.pixel_size_m,
            "--judge {}: views of {} px x {} mm, the planner renders {} px x {} mm",
            settings.path.display(),
            theirs.input_size_px,
            theirs.pixel_size_m * 1000.0,
            contract.input_size_px,
            contract.pixel_size_m * 1000.0
        );
        judge_planners.push(Planner::new(planner_config.clone(), theirs)?);
    }
    if attempt_views.is_some() && matches!(planning, Planning::Server(_)) {
        anyhow::bail!("--attempt-views needs the in-process planner (not --server)");
    }
    let command: Vec<String> = std::env::args().collect();
    let labeller = match label_frames {
        None => None,
        Some(LabelFrames { out: dir, every }) => Some(
            FrameLabeller::new(
                dir,
                contract.clone(),
                DatagenConfig {
                    scenes: seeds.end - seeds.start,
                    seed: seeds.start,
                    scenarios: scenarios.clone(),
                    catalog: config.catalog.clone(),
                    scenes_per_shard: 1,
                    data_version: DATA_VERSION.to_owned(),
                    targets: TargetConfig::default(),
                    noise: config.noise,
                    label_salt: 0,
                },
                *every,
                serde_json::json!({
                    "model": model_name, "model_version": contract.model_version,
                    "setting": settings[0].name(), "command": command,
                }),
            )
            .with_context(|| format!("--label-frames {}", dir.display()))?,
        ),
    };
    let mut jobs: Vec<(Scenario, usize, u64)> = Vec::new();
    for &scenario in scenarios {
        for k in 0..settings.len() {
            jobs.extend(seeds.clone().map(|seed| (scenario, k, seed)));
        }
    }
    let bar = ProgressBar::new(jobs.len() as u64).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} episodes {elapsed} eta {eta} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let started = std::time::Instant::now();
    // Per episode: its setting, the episode, the judged models' tallies and
    // each judged frame's outcomes (step, one name per model).
    // And the attempts written with their views (--attempt-views).
    type Judged = (Vec<JudgeTally>, Vec<(usize, Vec<&'static str>)>, usize);
    let results: Vec<anyhow::Result<(usize, Episode, Judged)>> = jobs
        .par_iter()
        .map_init(
            || -> anyhow::Result<(Worker, Vec<Box<dyn GraspNet + Send>>)> {
                let worker = match planning {
                    Planning::InProcess(model) => Worker::Net(load_net(model)?),
                    Planning::Server(endpoint) => Worker::Remote(Box::new(Remote::connect(endpoint)?)),
                };
                let judges = judge_settings
                    .iter()
                    .map(load_net)
                    .collect::<anyhow::Result<Vec<_>>>()?;
                Ok((worker, judges))
            },
            |state, &(scenario, k, seed)| {
                let (worker, judges) = match state {
                    Ok((worker, judges)) => (worker, judges),
                    Err(e) => anyhow::bail!("{e:#}"),
                };
                let mut in_process;
                let mut keeping = None;
                let source: &mut dyn GraspSource = match worker {
                    Worker::Net(net) => {
                        let inner = InProcess {
                            planner: &planner,
                            net: net.as_mut(),
                        };
                        if k == 0 && attempt_views.is_some() {
                            keeping.insert(ViewKeeping::new(inner))
                        } else {
                            in_process = inner;
                            &mut in_process
                        }
                    }
                    Worker::Remote(remote) => remote.as_mut(),
                };
                let context = || format!("{} seed {seed} {}", scenario.name(), settings[k].name());
                // The episode's attempts with their views (--attempt-views),
                // and the alternatives on the frames' scenes: rows written.
                let write_kept = |keeping: &Option<ViewKeeping>, episode: &Episode, scenes: &[Scene]| match (
                    keeping,
                    attempt_views,
                ) {
                    (Some(keeping), Some(dir)) => write_attempt_views(
                        dir,
                        (episode.scenario, episode.seed),
                        &keeping.rows(episode, scenes, *attempt_alternatives, config)?,
                        contract.input_size_px,
                    ),
                    _ => Ok(0),
                };
                // The scene at every frame, for the alternatives.
                let keep_scenes = k == 0 && attempt_views.is_some() && *attempt_alternatives > 0;
                let mut scenes: Vec<Scene> = Vec::new();
                let mut tallies = vec![JudgeTally::default(); judges.len()];
                let mut judged_frames = Vec::new();
                if k != 0 || (labeller.is_none() && judges.is_empty() && !keep_scenes) {
                    let episode =
                        run_episode(scenario, seed, &settings[k], source, config).with_context(context)?;
                    let written = write_kept(&keeping, &episode, &[]).with_context(context)?;
                    bar.inc(1);
                    return Ok((k, episode, (tallies, judged_frames, written)));
                }
                let options = plan_options(&settings[k], seed, &config.gripper);
                let mut views = Vec::new();
                // Where the objects stood at the last judged frame: a frame
                // after an attempt that never reached physics shows the same
                // state, and is judged once.
                let mut last_judged: Option<Vec<[f32; 3]>> = None;
                let episode = run_episode_with(
                    scenario,
                    seed,
                    &settings[k],
                    source,
                    config,
                    &mut |step, scene, frame| {
                        if keep_scenes {
                            scenes.push(scene.clone());
                        }
                        if let Some(labeller) = &labeller
                            && labeller.wants(step)
                        {
                            views.extend(labeller.label(&planner, (scenario, seed, step), scene, frame));
                        }
                        // Each judged model's best grasp on this very frame, tried
                        // from this state and then forgotten.
                        let state: Vec<[f32; 3]> = scene
                            .objects
                            .iter()
                            .map(|o| o.world_from_object.translation.into())
                            .collect();
                        if judges.is_empty() || last_judged.as_ref() == Some(&state) {
                            return;
                        }
                        last_judged = Some(state);
                        let mut names = Vec::with_capacity(judges.len());
                        for ((net, tally), planner) in
                            judges.iter_mut().zip(tallies.iter_mut()).zip(&judge_planners)
                        {
                            let mut judged = InProcess {
                                planner,
                                net: net.as_mut(),
                            };
                            let planned = judged.grasps(frame, scene.workspace(), &options).ok();
                            let outcome = planned.map(|g| g.first().map(|g| grasp_outcome(scene, g, config)));
                            tally.add(outcome);
                            names.push(JudgeTally::outcome_name(outcome));
                        }
                        judged_frames.push((step, names));
                    },
                )
                .with_context(context)?;
                if let Some(labeller) = &labeller {
                    labeller
                        .write_episode(scenario, seed, &views)
                        .with_context(context)?;
                }
                let written = write_kept(&keeping, &episode, &scenes).with_context(context)?;
                bar.inc(1);
                Ok((k, episode, (tallies, judged_frames, written)))
            },
        )
        .collect();
    bar.finish_and_clear();
    let results = results.into_iter().collect::<anyhow::Result<Vec<_>>>()?;
    // The judged models' tallies per scenario, then over all of them.
    let mut judged_rows: Vec<(String, String, JudgeTally)> = Vec::new();
    for (j, path) in judge.iter().enumerate() {
        let mut all = JudgeTally::default();
        for &scenario in scenarios {
            let mut tally = JudgeTally::default();
            for (_, _, (tallies, _, _)) in results
                .iter()
                .filter(|(k, e, _)| *k == 0 && e.scenario == scenario)
            {
                tally.merge(&tallies[j]);
            }
            all.merge(&tally);
            judged_rows.push((scenario.name().to_owned(), path.display().to_string(), tally));
        }
        judged_rows.push(("all".to_owned(), path.display().to_string(), all));
    }
    judged_rows.sort_by_key(|(scenario, _, _)| {
        scenarios
            .iter()
            .position(|s| s.name() == scenario)
            .unwrap_or(scenarios.len())
    });
    // Each judged frame's outcomes, for paired tests between the models.
    let judged_frames: Vec<serde_json::Value> = results
        .iter()
        .filter(|(k, _, _)| *k == 0)
        .flat_map(|(_, e, (_, frames, _))| {
            frames.iter().map(move |(step, outcomes)| {
                serde_json::json!({"scenario": e.scenario.name(), "seed": e.seed, "step": step, "outcomes": outcomes})
            })
        })
        .collect();
    let attempt_rows: usize = results.iter().map(|(_, _, (_, _, written))| written).sum();
    let results: Vec<(usize, Episode)> = results.into_iter().map(|(k, e, _)| (k, e)).collect();
    // For eval.json: scenario, setting, seed order.
    let mut episodes_in_order: Vec<&(usize, Episode)> = results.iter().collect();
    episodes_in_order.sort_by_key(|(k, e)| (scenarios.iter().position(|s| *s == e.scenario), *k, e.seed));
    let mut summaries = Vec::new();
    for &scenario in scenarios {
        for (k, setting) in settings.iter().enumerate() {
            let episodes: Vec<Episode> = results
                .iter()
                .filter(|(j, e)| *j == k && e.scenario == scenario)
                .map(|(_, e)| e.clone())
                .collect();
            summaries.push(Summary::of(scenario, setting, &episodes));
        }
    }
    // Snapshots: the first episodes of each scenario under the first setting,
    // every attempt drawn over the episode's first (noiseless) frame.
    let snapshot_dir = out.join("snapshots");
    let mut snapshot_files = Vec::new();
    for &scenario in scenarios {
        let mut first: Vec<&Episode> = results
            .iter()
            .filter(|(k, e)| *k == 0 && e.scenario == scenario)
            .map(|(_, e)| e)
            .collect();
        first.sort_by_key(|e| e.seed);
        for e in first.into_iter().take(*snapshots) {
            let (scene, camera) = episode_scene(scenario, e.seed, &config.catalog)?;
            let frame = render(&scene, &camera, None);
            let drawn: Vec<DrawnGrasp> = e
                .attempts
                .iter()
                .map(|a| (a.world_from_grasp, a.width_m, a.failure.is_none()))
                .collect();
            std::fs::create_dir_all(&snapshot_dir)
                .with_context(|| format!("creating {}", snapshot_dir.display()))?;
            let name = format!("{}-{}.png", scenario.name(), e.seed);
            write_grasp_snapshot(&snapshot_dir.join(&name), &frame, &drawn)?;
            snapshot_files.push(name);
        }
    }
    let table = markdown_table(&summaries);
    let collisions = collision_list(&summaries);
    let labels = label_table(&episodes_in_order.iter().map(|(_, e)| e).collect::<Vec<_>>());
    // Where the tried grasps came from, per setting (every scenario).
    let provenance: String = settings
        .iter()
        .enumerate()
        .map(|(k, setting)| {
            let of: Vec<&Episode> = episodes_in_order
                .iter()
                .filter(|(j, _)| *j == k)
                .map(|(_, e)| e)
                .collect();
            let table = provenance_table(&of);
            if table.is_empty() {
                String::new()
            } else {
                format!(
                    "\n### Where the tried grasps came from: {}\n\n{table}",
                    setting.name()
                )
            }
        })
        .collect();
    let judged = judge_table(&judged_rows);
    let provenance = if judged.is_empty() {
        provenance
    } else {
        format!(
            "{provenance}\n### Other models' best grasps on the same frames ({}, `--judge`)\n\n\
             Every frame of the first setting's episodes, before this run's own attempt: each judged \
             model plans on the frame, and its best grasp is tried in physics from that state, which \
             is then restored. Paired: every model sees the same frames.\n\n{judged}",
            settings[0].name()
        )
    };
    let objects_line = format!(" Objects drawn from: {}.", config.catalog.names().join(", "));
    let report = format!(
        "# Clear-the-table in simulation\n\n- revision: `{}`\n- model: `{}` ({}, data {}), {} px views of {} mm\n- command: `{}`\n- seeds {}..{} per scenario, the same scenes and cameras for every setting; {:.0} s on {} threads\n\n{table}\n\
         Success = successful attempts / attempts; removal = objects removed / objects at the start; \
         their 95% intervals resample whole episodes (a percentile bootstrap, 2,000 draws, seeded). \
         A success is an object carried to the basket beside the table and let go into it; after every \
         physics trial the scene keeps what the trial did to it (pushed neighbours, dropped objects) and \
         settles; objects knocked off the table are not removed. `pile`: 4-6 objects dropped \
         into a box, settled in rapier3d, the box lifted away. `clutter` is 15-20 objects \
         spread over the table.{}\n{}{}{}{}",
        git_revision(),
        model_name,
        contract.model_version,
        contract.data_version,
        contract.input_size_px,
        contract.pixel_size_m * 1000.0,
        command.join(" "),
        seeds.start,
        seeds.end,
        started.elapsed().as_secs_f64(),
        rayon::current_num_threads(),
        objects_line,
        if collisions.is_empty() {
            String::new()
        } else {
            format!("\n{collisions}")
        },
        if labels.is_empty() {
            String::new()
        } else {
            format!("\n{labels}")
        },
        provenance,
        if snapshot_files.is_empty() {
            String::new()
        } else {
            format!(
                "\nSnapshots (first setting; every attempt over the first frame, green worked, red failed): {}\n",
                snapshot_files
                    .iter()
                    .map(|f| format!("[{f}](snapshots/{f})"))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        },
    );
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    std::fs::write(out.join("eval.md"), &report).with_context(|| format!("writing {}", out.display()))?;
    let json = serde_json::json!({
        "revision": git_revision(),
        "command": command,
        "model_version": contract.model_version,
        "summaries": summaries.iter().map(|s| serde_json::json!({
            "scenario": s.scenario.name(), "setting": s.setting, "episodes": s.episodes,
            "objects": s.objects, "removed": s.removed, "fell_off": s.fell_off, "attempts": s.attempts, "successes": s.successes,
            "success_rate": s.success_rate(), "removal_rate": s.removal_rate(),
            "failures": Failure::ALL.iter().zip(s.failures).map(|(f, n)| (f.name(), n)).collect::<std::collections::BTreeMap<_, _>>(),
            "collisions_on_approach": s.collisions.iter().map(|(site, n)| (site.name(), *n)).collect::<std::collections::BTreeMap<_, _>>(),
            "ended_without_grasp": s.ended_without_grasp, "cleared": s.cleared,
            "plan_ms_p50": s.plan_ms[0], "plan_ms_p90": s.plan_ms[1],
            "success_ci95": s.success_ci95, "removal_ci95": s.removal_ci95,
        })).collect::<Vec<_>>(),
        "judged_models": judge.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
        "judged_frames": judged_frames,
        "judged": judged_rows.iter().map(|(scenario, model, t)| serde_json::json!({
            "scenario": scenario, "model": model, "frames": t.frames, "no_grasp": t.no_grasp,
            "planning_errors": t.errors, "tried": t.tried(), "held": t.held,
            "failures": Failure::ALL.iter().zip(t.failures).map(|(f, n)| (f.name(), n)).collect::<std::collections::BTreeMap<_, _>>(),
        })).collect::<Vec<_>>(),
        "episodes": episodes_in_order.iter().map(|(k, e)| episode_record(e, &settings[*k].name())).collect::<Vec<_>>(),
    });
    std::fs::write(out.join("eval.json"), serde_json::to_string_pretty(&json)?)
        .with_context(|| format!("writing {}", out.display()))?;
    println!("{report}");
    println!("wrote {}/eval.md and eval.json", out.display());
    if let Some(dir) = attempt_views {
        let manifest = serde_json::json!({
            "format": "mvgrasp-attempt-views-2",
            "alternatives": attempt_alternatives,
            "model": model_name, "model_version": contract.model_version,
            "contract": {
                "input_size_px": contract.input_size_px, "pixel_size_m": contract.pixel_size_m,
                "normalisation": contract.normalisation,
            },
            "setting": settings[0].name(), "scenarios": scenarios.iter().map(|s| s.name()).collect::<Vec<_>>(),
            "seeds": [seeds.start, seeds.end], "attempts": attempt_rows,
            "revision": git_revision(), "command": command,
        });
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        std::fs::write(
            dir.join("manifest.json"),
            serde_json::to_string_pretty(&manifest)?,
        )
        .with_context(|| format!("writing {}/manifest.json", dir.display()))?;
        println!(
            "attempts with their views ({}): {attempt_rows} -> {}",
            settings[0].name(),
            dir.display()
        );
    }
    if let (Some(labeller), Some(LabelFrames { out: dir, .. })) = (labeller, label_frames) {
        let report = labeller.finish()?;
        println!(
            "labelled frames ({}): {} views, {} with positives, {} episodes; {} frames failed -> {}",
            settings[0].name(),
            report.views,
            report.views_with_positives,
            report.shards,
            report.failed.len(),
            dir.display()
        );
    }
    if let Some(floor) = *min_success {
        for s in summaries.iter().filter(|s| s.setting == settings[0].name()) {
            let rate = if s.attempts == 0 { 0.0 } else { s.success_rate() };
            anyhow::ensure!(
                rate >= floor,
                "{} under {}: success rate {rate:.2} is below the floor {floor}",
                s.scenario.name(),
                s.setting
            );
        }
    }
    Ok(())
}
