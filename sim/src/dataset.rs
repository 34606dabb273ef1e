//! The dataset writer behind `sim datagen`: scenes rendered and labelled in
//! parallel, written as shards that numpy reads alone.
//!
//! Layout of `OUT/`:
//! - `manifest.json`: format version, the model contract the views were
//!   rendered for, the gripper, the generator settings, counts, and the
//!   scenes that failed (skipped, with their error).
//! - `shard_NNNNN/views.npy`: float32 `[n, 1, L, L]`, the network inputs.
//! - `shard_NNNNN/maps.npy`: float32 `[n, 4, L, L]`, targets in the
//!   contract's channel order (`manifest.contract.outputs`).
//! - `shard_NNNNN/grasps.npy`: float32 `[m, 6]`, every labelled positive:
//!   view index within the shard, u, v (pixel), phi (rad, [-pi/2, pi/2]),
//!   opening (m), painted quality. The ground truth of the accuracy metric.
//! - `shard_NNNNN/meta.jsonl`: one line per view: scene seed and scenario,
//!   object index, `instance` (unique per object instance, the key of the
//!   train / evaluation split), family, view axis, candidates, positives,
//!   and `refused`: the other candidates counted by why the labeller
//!   refused them (`targets::LabelledView::refused`; shards written before
//!   it existed lack it). Views of mid-episode frames (`sim eval
//!   --label-frames`, [`FrameLabeller`]) also carry `step`, the attempts
//!   made in the episode before that frame, and their `instance` names the
//!   frame (`scenario-seed.step:object`: `sim eval` runs every scenario from
//!   the same seeds).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use indicatif::{ProgressBar, ProgressStyle};
use mvgrasp_core::rng::SplitMix64;
use mvgrasp_core::{ModelContract, Planner, PlannerConfig};
use nalgebra::Vector3;
use rayon::prelude::*;

use crate::camera::{Camera, Frame, NoiseModel, render};
use crate::error::{Error, Result};
use crate::eval::crease_text;
use crate::grasp::GripperModel;
use crate::objects::Catalog;
use crate::scene::{Scenario, Scene};
use crate::targets::{LabelledView, TargetConfig, label_frame};

/// Version of the files this writer produces.
pub const FORMAT_VERSION: u32 = 2;

/// The data version of labels made now (sim-6: `grasp.rs` as it is; older
/// versions are in docs/experiments/).
pub const DATA_VERSION: &str = "sim-6";

/// What to generate.
#[derive(Debug, Clone)]
pub struct DatagenConfig {
    /// Scenes to render (seeds `seed .. seed + scenes`).
    pub scenes: u64,
    /// First scene seed.
    pub seed: u64,
    /// Scenarios, drawn in turn.
    pub scenarios: Vec<Scenario>,
    /// What objects are drawn from (families and meshes).
    pub catalog: Catalog,
    /// Scenes per shard.
    pub scenes_per_shard: u64,
    /// Candidate and painting settings.
    pub targets: TargetConfig,
    /// Camera noise (`None`: a perfect sensor).
    pub noise: Option<NoiseModel>,
    /// Data version written to the manifest (the model's `data_version`).
    pub data_version: String,
    /// 0: each scene's own draw. Otherwise the sensor noise and the
    /// annealing are drawn again from this salt, for the same scenes and
    /// cameras: two runs that differ only here measure how repeatable the
    /// labels are (`training/mvgrasp_train/repeatability.py`).
    pub label_salt: u64,
}

/// What a run produced.
#[derive(Debug, Clone, Default)]
pub struct DatagenReport {
    /// Labelled views written.
    pub views: usize,
    /// Views with at least one positive.
    pub views_with_positives: usize,
    /// Scenes that failed (seed, error), skipped.
    pub failed: Vec<(u64, String)>,
    /// Shards written.
    pub shards: usize,
}

pub(crate) fn file_error(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::File {
        path: path.display().to_string(),
        reason: e.to_string(),
    }
}

/// Writes a little-endian float32 `.npy` file of `shape`.
pub fn write_npy(path: &Path, shape: &[usize], data: &[f32]) -> Result<()> {
    let dims: Vec<String> = shape.iter().map(ToString::to_string).collect();
    let shape_text = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape_text}, }}");
    // Magic (6) + version (2) + length (2) + header + '\n' is a multiple of 64.
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut bytes = Vec::with_capacity(10 + header.len() + 4 * data.len());
    bytes.extend_from_slice(b"\x93NUMPY\x01\x00");
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for v in data {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(path, bytes).map_err(|e| file_error(path, e))
}

/// One labelled view as a shard stores it: the scene seed and scenario it
/// came from, and for a mid-episode frame the episode's step.
pub struct ShardView {
    /// Scene (episode) seed.
    pub seed: u64,
    /// Its scenario.
    pub scenario: Scenario,
    /// Attempts made before this frame (`None`: a `sim datagen` scene).
    pub step: Option<usize>,
    /// The view and its labels.
    pub view: LabelledView,
}

fn write_shard(dir: &Path, contract: &ModelContract, views: &[ShardView]) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| file_error(dir, e))?;
    let l = contract.input_size_px;
    let n = views.len();
    let images: Vec<f32> = views.iter().flat_map(|r| r.view.image.iter().copied()).collect();
    let maps: Vec<f32> = views.iter().flat_map(|r| r.view.maps.iter().copied()).collect();
    write_npy(&dir.join("views.npy"), &[n, 1, l, l], &images)?;
    write_npy(&dir.join("maps.npy"), &[n, 4, l, l], &maps)?;
    let grasps: Vec<f32> = views
        .iter()
        .enumerate()
        .flat_map(|(i, r)| {
            r.view
                .grasps
                .iter()
                .flat_map(move |g| [i as f32, g.u as f32, g.v as f32, g.phi, g.width_m, g.quality])
        })
        .collect();
    write_npy(&dir.join("grasps.npy"), &[grasps.len() / 6, 6], &grasps)?;
    let path = dir.join("meta.jsonl");
    let mut meta = std::io::BufWriter::new(std::fs::File::create(&path).map_err(|e| file_error(&path, e))?);
    for ShardView {
        seed,
        scenario,
        step,
        view: v,
    } in views
    {
        let instance = match step {
            None => format!("{seed}:{}", v.object),
            // `sim eval` runs every scenario from the same seeds.
            Some(step) => format!("{}-{seed}.{step}:{}", scenario.name(), v.object),
        };
        let mut line = serde_json::json!({
            "scene_seed": seed, "scenario": scenario.name(), "object": v.object,
            "instance": instance, "family": v.family.name(),
            "view": v.axis.name(), "candidates": v.candidates, "positives": v.positives,
            "refused": v.refused,
        });
        if let Some(step) = step {
            line["step"] = serde_json::json!(step);
        }
        writeln!(meta, "{line}").map_err(|e| file_error(&path, e))?;
    }
    meta.flush().map_err(|e| file_error(&path, e))
}

/// Renders and labels one scene.
fn scene_views(
    seed: u64,
    scenario: Scenario,
    config: &DatagenConfig,
    planner: &Planner,
    gripper: &GripperModel,
) -> Result<Vec<LabelledView>> {
    let (scene, frame, mut rng) = scene_frame(seed, scenario, config)?;
    label_frame(&scene, &frame, planner, gripper, &config.targets, &mut rng)
}

/// Scene `seed` of `scenario` as `sim datagen` renders it: the scene, the
/// frame, and the generator the labelling then draws from (its annealing).
pub fn scene_frame(
    seed: u64,
    scenario: Scenario,
    config: &DatagenConfig,
) -> Result<(Scene, Frame, SplitMix64)> {
    let scene = Scene::generate_from(scenario, seed, &config.catalog)?;
    let mut rng = SplitMix64::new(seed.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ 0xDA7A);
    let top_down = rng.next_f64() < 0.15;
    let camera = Camera::random(
        &mut rng,
        Vector3::new(0.0, 0.0, f64::from(scene.table_z)),
        top_down,
    );
    if config.label_salt != 0 {
        rng = SplitMix64::new(rng.next_u64() ^ config.label_salt.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    }
    let frame = render(&scene, &camera, config.noise.as_ref().map(|n| (n, &mut rng)));
    Ok((scene, frame, rng))
}

/// Generates the dataset into `out` for networks that speak `contract`.
pub fn generate(
    out: &Path,
    contract: &ModelContract,
    config: &DatagenConfig,
    progress: bool,
) -> Result<DatagenReport> {
    if config.scenarios.is_empty() || config.catalog.is_empty() || config.scenes_per_shard == 0 {
        return Err(Error::Invalid {
            field: "datagen",
            reason: "scenarios, families and scenes per shard must not be empty / zero".into(),
        });
    }
    config.targets.check()?;
    std::fs::create_dir_all(out).map_err(|e| file_error(out, e))?;
    let planner = Planner::new(PlannerConfig::default(), contract.clone()).map_err(|e| Error::Invalid {
        field: "contract",
        reason: e.to_string(),
    })?;
    let gripper = config.targets.gripper();
    let bar = if progress {
        ProgressBar::new(config.scenes)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} scenes ({per_sec}, eta {eta})",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let shards = config.scenes.div_ceil(config.scenes_per_shard);
    let report = Mutex::new(DatagenReport::default());
    let outcome: Vec<Result<()>> = (0..shards)
        .into_par_iter()
        .map(|shard| {
            let first = shard * config.scenes_per_shard;
            let last = (first + config.scenes_per_shard).min(config.scenes);
            let mut views = Vec::new();
            let mut failed = Vec::new();
            for k in first..last {
                let seed = config.seed + k;
                let scenario = config.scenarios[(k % config.scenarios.len() as u64) as usize];
                match scene_views(seed, scenario, config, &planner, &gripper) {
                    Ok(v) => views.extend(v.into_iter().map(|view| ShardView {
                        seed,
                        scenario,
                        step: None,
                        view,
                    })),
                    Err(e) => failed.push((seed, e.to_string())),
                }
                bar.inc(1);
            }
            if !views.is_empty() {
                write_shard(&out.join(format!("shard_{shard:05}")), contract, &views)?;
            }
            let mut r = report
                .lock()
                .map_err(|_| Error::Scene("a worker panicked".into()))?;
            r.views += views.len();
            r.views_with_positives += views.iter().filter(|r| r.view.positives > 0).count();
            r.failed.extend(failed);
            r.shards += usize::from(!views.is_empty());
            Ok(())
        })
        .collect();
    bar.finish_and_clear();
    outcome.into_iter().collect::<Result<Vec<()>>>()?;
    let mut report = report
        .into_inner()
        .map_err(|_| Error::Scene("a worker panicked".into()))?;
    report.failed.sort();
    write_manifest(out, contract, config, &gripper, &report, None)?;
    Ok(report)
}

fn write_manifest(
    out: &Path,
    contract: &ModelContract,
    config: &DatagenConfig,
    gripper: &GripperModel,
    report: &DatagenReport,
    frames_from: Option<serde_json::Value>,
) -> Result<()> {
    let mut shard_dirs: Vec<PathBuf> = std::fs::read_dir(out)
        .map_err(|e| file_error(out, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("shard_"))
        })
        .collect();
    shard_dirs.sort();
    let mut manifest = serde_json::json!({
        "format_version": FORMAT_VERSION,
        "data_version": config.data_version,
        "contract": {
            "input_size_px": contract.input_size_px, "pixel_size_m": contract.pixel_size_m,
            "width_scale_m": contract.width_scale_m, "normalisation": contract.normalisation,
            "outputs": contract.outputs.iter().map(|c| c.name()).collect::<Vec<_>>(),
        },
        "gripper": {
            "max_width_m": gripper.max_width_m, "pad_width_m": gripper.pad_width_m,
            "pad_depth_m": gripper.pad_depth_m, "friction": gripper.friction,
            "max_torque_nm": gripper.max_torque_nm,
        },
        "generator": {
            "scenes": config.scenes, "first_seed": config.seed,
            "scenarios": config.scenarios.iter().map(|s| s.name()).collect::<Vec<_>>(),
            "families": config.catalog.names(),
            "noise": config.noise.is_some(), "stride_px": config.targets.stride_px,
            "angles": config.targets.angles, "anneal_steps": config.targets.anneal_steps,
            "candidate_opening": config.targets.opening.name(),
            "label_salt": config.label_salt, "neighbours": config.targets.neighbours,
            "crease_split": crease_text(PlannerConfig::default().cluster.crease.as_ref()),
        },
        "views": report.views,
        "views_with_positives": report.views_with_positives,
        "failed_scenes": report.failed.iter().map(|(seed, e)| serde_json::json!({"seed": seed, "error": e})).collect::<Vec<_>>(),
        "shards": shard_dirs.iter().filter_map(|p| p.file_name().and_then(|n| n.to_str()).map(str::to_owned)).collect::<Vec<_>>(),
    });
    if let Some(frames_from) = frames_from {
        manifest["frames_from"] = frames_from;
    }
    let path = out.join("manifest.json");
    let text = serde_json::to_string_pretty(&manifest).map_err(|e| file_error(&path, e))?;
    std::fs::write(&path, text).map_err(|e| file_error(&path, e))
}

/// Labels the frames of `sim eval`'s episodes as `sim datagen` labels its
/// scenes (`sim eval --label-frames`): each scene as the earlier attempts
/// left it (pushed, dropped, one object fewer), the frame with the noise
/// the planner saw. Every `every`-th frame of an episode is labelled; one
/// shard per episode; the manifest says which model and setting made the
/// episodes (`frames_from`). Labelling draws from its own generator, so
/// the episodes are the same with it or without it.
pub struct FrameLabeller {
    out: PathBuf,
    contract: ModelContract,
    config: DatagenConfig,
    gripper: GripperModel,
    every: usize,
    frames_from: serde_json::Value,
    report: Mutex<DatagenReport>,
}

impl FrameLabeller {
    /// A labeller writing into `out` (created) views for `contract`, with
    /// `config`'s targets, noise note and data version (its `scenes`,
    /// `seed`, `scenarios` and `catalog` describe the episodes).
    pub fn new(
        out: &Path,
        contract: ModelContract,
        config: DatagenConfig,
        every: usize,
        frames_from: serde_json::Value,
    ) -> Result<Self> {
        if every == 0 {
            return Err(Error::Invalid {
                field: "label every",
                reason: "must be at least 1 (1: every frame)".into(),
            });
        }
        config.targets.check()?;
        std::fs::create_dir_all(out).map_err(|e| file_error(out, e))?;
        Ok(Self {
            out: out.to_path_buf(),
            contract,
            gripper: config.targets.gripper(),
            config,
            every,
            frames_from,
            report: Mutex::new(DatagenReport::default()),
        })
    }

    /// Whether the frame after `step` attempts is labelled.
    pub fn wants(&self, step: usize) -> bool {
        step.is_multiple_of(self.every)
    }

    /// The labelled views of one frame; a frame the labeller fails on is
    /// counted in the manifest's `failed_scenes` and gives none.
    pub fn label(
        &self,
        planner: &Planner,
        (scenario, seed, step): (Scenario, u64, usize),
        scene: &Scene,
        frame: &Frame,
    ) -> Vec<ShardView> {
        let mut rng = SplitMix64::new(
            seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (step as u64 + 1).wrapping_mul(0xD1B5_4A32_D192_ED03),
        );
        match label_frame(
            scene,
            frame,
            planner,
            &self.gripper,
            &self.config.targets,
            &mut rng,
        ) {
            Ok(views) => views
                .into_iter()
                .map(|view| ShardView {
                    seed,
                    scenario,
                    step: Some(step),
                    view,
                })
                .collect(),
            Err(e) => {
                if let Ok(mut r) = self.report.lock() {
                    r.failed
                        .push((seed, format!("{} step {step}: {e}", scenario.name())));
                }
                Vec::new()
            }
        }
    }

    /// Writes one episode's views as the shard `shard_SCENARIO_SEED`.
    pub fn write_episode(&self, scenario: Scenario, seed: u64, views: &[ShardView]) -> Result<()> {
        if views.is_empty() {
            return Ok(());
        }
        write_shard(
            &self.out.join(format!("shard_{}_{seed}", scenario.name())),
            &self.contract,
            views,
        )?;
        let mut r = self
            .report
            .lock()
            .map_err(|_| Error::Scene("a worker panicked".into()))?;
        r.views += views.len();
        r.views_with_positives += views.iter().filter(|v| v.view.positives > 0).count();
        r.shards += 1;
        Ok(())
    }

    /// Writes the manifest once every episode is in; what was written.
    pub fn finish(self) -> Result<DatagenReport> {
        let mut report = self
            .report
            .into_inner()
            .map_err(|_| Error::Scene("a worker panicked".into()))?;
        report.failed.sort();
        let mut from = self.frames_from;
        from["every"] = serde_json::json!(self.every);
        write_manifest(
            &self.out,
            &self.contract,
            &self.config,
            &self.gripper,
            &report,
            Some(from),
        )?;
        Ok(report)
    }
}
