//! `sim`: the synthetic data engine's command line.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Parser, Subcommand};
use mvgrasp_core::rng::SplitMix64;
use mvgrasp_core::{ModelContract, PlannerConfig};
use mvgrasp_server::{BackendKind, settings::ModelSettings};
use mvgrasp_sim::eval::{EpisodeConfig, Setting, crease_setting, square_turn_setting};
use mvgrasp_sim::{
    camera::{Camera, NoiseModel, render},
    dataset::{DatagenConfig, generate},
    files::write_frame,
    mesh::load_meshes,
    objects::{Catalog, Family},
    scene::{Scenario, Scene},
    targets::{Opening, TargetConfig},
};
use nalgebra::Vector3;

mod eval_command;
use eval_command::{EvalRun, LabelFrames, Planning, eval_command};

/// Synthetic scenes and a simulated depth camera for mvgrasp.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// How often analytic labels and rapier3d physics agree, on top-down
    /// grasps of isolated scenes (8 yaws x 3 depths each).
    PhysicsAgreement {
        /// Isolated scenes.
        #[arg(long, default_value_t = 20)]
        scenes: u64,
        /// First seed.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Shape families (comma-separated; default all).
        #[arg(long, value_delimiter = ',')]
        families: Vec<String>,
    },
    /// Render and label scenes into a dataset of views and target maps
    /// (numpy-readable shards + manifest.json; see `dataset.rs`).
    Datagen {
        /// Scenes to generate.
        #[arg(long)]
        scenes: u64,
        /// First scene seed (scenes use seed, seed + 1, ...).
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
        /// Scenarios drawn in turn (comma-separated).
        #[arg(long, value_delimiter = ',', default_value = "isolated,packed")]
        scenarios: Vec<String>,
        #[command(flatten)]
        objects: Objects,
        /// View side in pixels.
        #[arg(long, default_value_t = 96)]
        input_size_px: usize,
        /// View pixel size (mm).
        #[arg(long, default_value_t = 2.5)]
        pixel_size_mm: f32,
        /// Scenes per shard.
        #[arg(long, default_value_t = 64)]
        scenes_per_shard: u64,
        /// A perfect sensor.
        #[arg(long)]
        no_noise: bool,
        /// Candidate grasp centres every this many pixels along rows and
        /// columns (1: every pixel of the silhouette).
        #[arg(long, default_value_t = TargetConfig::default().stride_px)]
        stride_px: usize,
        /// Candidate image angles per centre, spread over 180 degrees.
        #[arg(long, default_value_t = TargetConfig::default().angles)]
        angles: usize,
        /// How wide candidates open before the margin: `chord`, the
        /// silhouette along the closing line through the pixel (the labels
        /// so far), or `pads`, twice its farthest reach from the pixel over
        /// the strip the pads sweep (`targets::Opening`).
        #[arg(long, default_value = "chord")]
        candidate_opening: Opening,
        /// Label each object as if it stood alone (where it is): the
        /// labels its own view can tell, without its neighbours.
        #[arg(long)]
        without_neighbours: bool,
        /// Draw the sensor noise and the label annealing again from this
        /// salt, for the same scenes and cameras (0: each scene's own draw).
        /// Two runs differing only here measure label repeatability.
        #[arg(long, default_value_t = 0)]
        label_salt: u64,
        /// Worker threads (default: one per core).
        #[arg(long)]
        threads: Option<usize>,
        /// Data version recorded in the manifest (default: sim-6, the labels
        /// of `grasp.rs` as they are now; older versions are in
        /// docs/experiments/).
        #[arg(long)]
        data_version: Option<String>,
    },
    /// Clear-the-table in physics with the planner in the loop: success and
    /// removal rates per scenario and planner setting, failure causes, and
    /// planning times (see the `eval` module). Writes OUT/eval.md and OUT/eval.json.
    Eval {
        /// The ONNX model (the service's default).
        #[arg(long, default_value_os_t = ModelSettings::default().path)]
        model: PathBuf,
        /// onnx (the model through ONNX Runtime) or baseline (the analytic
        /// moments network, no model file).
        #[arg(long, value_enum, default_value_t = BackendKind::Onnx)]
        backend: BackendKind,
        /// libonnxruntime.so (else ORT_DYLIB_PATH, then the loader's path).
        #[arg(long, env = "MVGRASP_ONNXRUNTIME")]
        onnxruntime: Option<PathBuf>,
        /// Scenarios (comma-separated).
        #[arg(long, value_delimiter = ',', default_value = "isolated,packed,pile,clutter")]
        scenarios: Vec<String>,
        /// Episodes per scenario (seeds seed, seed + 1, ...).
        #[arg(long, default_value_t = 10)]
        episodes: u64,
        /// First seed. Training data used seeds from 1000 on; keep clear of them.
        #[arg(long, default_value_t = 900_000)]
        seed: u64,
        /// Planner settings POLICY:TAU (entropy, all, top-down, random).
        #[arg(
            long,
            value_delimiter = ',',
            default_value = "entropy:0.8,all:0.8,top-down:0.8,random:0.8,entropy:0.9"
        )]
        settings: Vec<String>,
        #[command(flatten)]
        objects: Objects,
        /// Output folder.
        #[arg(long, default_value = "results")]
        out: PathBuf,
        /// Plan with the server at this endpoint (e.g. http://127.0.0.1:50051)
        /// instead of in this process: the service itself is measured.
        #[arg(long, conflicts_with_all = ["backend", "onnxruntime"])]
        server: Option<String>,
        /// Exit with an error if any scenario's success rate under the first
        /// setting is below this (the CI floor).
        #[arg(long)]
        min_success: Option<f64>,
        /// Worker threads (default: one per core).
        #[arg(long)]
        threads: Option<usize>,
        /// Added to every predicted opening by the in-process planner (mm;
        /// default: the planner's own, `DecodeConfig::opening_margin_m`).
        #[arg(long)]
        opening_margin_mm: Option<f64>,
        /// The in-process planner turns a grasp about its approach up to this
        /// far to square it to the surfaces its pads meet (degrees, 0: never;
        /// default: the planner's own, `HandConfig::square_turn_deg`).
        #[arg(long)]
        square_turn_deg: Option<f64>,
        /// Episodes per scenario drawn into OUT/snapshots (first setting).
        #[arg(long, default_value_t = 2)]
        snapshots: usize,
        /// The in-process planner's crease split: `off` (the planner's
        /// default), `on` (`CreaseConfig`'s defaults) or `split-only` (no
        /// re-joining of parts that hang on another).
        #[arg(long, default_value = "off")]
        crease_split: String,
        /// Also label the first setting's episode frames (each scene as the
        /// earlier attempts left it) as `sim datagen` labels its scenes, into
        /// a dataset at this folder: models can then be judged on the
        /// disturbed frames a run meets (`evaluate_onnx --min-step 1`).
        #[arg(long)]
        label_frames: Option<PathBuf>,
        /// With --label-frames: label every N-th frame of an episode.
        #[arg(long, default_value_t = 1, requires = "label_frames")]
        label_every: usize,
        /// Models (comma-separated ONNX files) whose best grasp is also tried
        /// on every frame of the first setting's episodes, from the same
        /// state, which is then restored: paired physics for models on the
        /// same frames (in-process planning only).
        #[arg(long, value_delimiter = ',', conflicts_with = "server")]
        judge: Vec<PathBuf>,
        /// Write the first setting's attempts into this folder, each with the
        /// view its grasp came from as the network read it, its peak pixel
        /// and how it ended (`attempts_SCENARIO_SEED.npy` / `.json`): physics
        /// outcomes to learn from (`train --physics`; in-process planning only).
        #[arg(long, conflicts_with = "server")]
        attempt_views: Option<PathBuf>,
        /// With --attempt-views: on every frame, also try up to this many of
        /// the grasps the planner ranked below the one the episode tried,
        /// each from the same state and then forgotten, and write them too
        /// (rows with `alternative` set to their rank).
        #[arg(long, default_value_t = 0, requires = "attempt_views")]
        attempt_alternatives: usize,
    },
    /// Render one scene: depth.png + camera.json (what `mvgrasp plan` reads),
    /// labels.png and preview.png.
    RenderSample {
        /// isolated, packed, pile or clutter.
        #[arg(long, default_value = "packed")]
        scenario: String,
        /// Scene and camera seed.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        objects: Objects,
        /// Look straight down instead of from 30-60 degrees elevation.
        #[arg(long)]
        top_down: bool,
        /// A perfect sensor (no noise, no dropouts).
        #[arg(long)]
        no_noise: bool,
    },
}

/// What scenes draw objects from: `--families`, `--meshes`, `--mesh-scale`.
#[derive(Debug, clap::Args)]
struct Objects {
    /// Shape families (comma-separated; default: all, or none when
    /// `--meshes` is given; give both to mix).
    #[arg(long, value_delimiter = ',')]
    families: Vec<String>,
    /// OBJ or STL files to add as objects (comma-separated; z up, metres
    /// unless `--mesh-scale`); decomposed into convex parts (`mesh.rs`).
    #[arg(long, value_delimiter = ',')]
    meshes: Vec<PathBuf>,
    /// Factor from mesh file units to metres (0.001 for millimetres).
    #[arg(long, default_value_t = 1.0)]
    mesh_scale: f32,
}

impl Objects {
    fn catalog(&self) -> anyhow::Result<Catalog> {
        let families = if self.families.is_empty() && !self.meshes.is_empty() {
            Vec::new()
        } else {
            families_of(&self.families)?
        };
        let meshes = load_meshes(&self.meshes, self.mesh_scale).context("--meshes")?;
        Ok(Catalog { families, meshes })
    }
}

fn families_of(names: &[String]) -> anyhow::Result<Vec<Family>> {
    if names.is_empty() {
        return Ok(Family::ALL.to_vec());
    }
    names
        .iter()
        .map(|f| Family::parse(f).with_context(|| format!("--families: unknown family {f:?}")))
        .collect()
}

fn scenarios_of(names: &[String]) -> anyhow::Result<Vec<Scenario>> {
    names
        .iter()
        .map(|s| Scenario::parse(s).with_context(|| format!("--scenarios: unknown scenario {s:?}")))
        .collect()
}

/// `--threads`: rayon's worker count (default: one per core).
fn use_threads(threads: Option<usize>) -> anyhow::Result<()> {
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global()?;
    }
    Ok(())
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::Eval {
            model,
            backend,
            onnxruntime,
            scenarios,
            episodes,
            seed,
            settings,
            objects,
            out,
            min_success,
            threads,
            snapshots,
            server,
            opening_margin_mm,
            square_turn_deg,
            crease_split,
            label_frames,
            label_every,
            judge,
            attempt_views,
            attempt_alternatives,
        } => {
            use_threads(threads)?;
            let scenarios = scenarios_of(&scenarios)?;
            let settings = settings
                .iter()
                .map(|s| Setting::parse(s))
                .collect::<Result<Vec<_>, _>>()?;
            let model = ModelSettings {
                backend,
                path: model,
                onnxruntime_library: onnxruntime,
                ..ModelSettings::default()
            };
            let config = EpisodeConfig {
                catalog: objects.catalog()?,
                ..EpisodeConfig::default()
            };
            let planning = match server {
                Some(endpoint) => Planning::Server(endpoint),
                None => Planning::InProcess(&model),
            };
            let mut planner = PlannerConfig::default();
            if let Some(mm) = opening_margin_mm {
                planner.decode.opening_margin_m = mm / 1000.0;
            }
            if let Some(deg) = square_turn_deg {
                planner.hand.square_turn_deg = square_turn_setting(deg)?;
            }
            planner.cluster.crease = crease_setting(&crease_split)?;
            eval_command(&EvalRun {
                planning,
                planner,
                scenarios,
                seeds: seed..seed + episodes,
                settings,
                config,
                out,
                min_success,
                snapshots,
                label_frames: label_frames.map(|out| LabelFrames {
                    out,
                    every: label_every,
                }),
                judge,
                attempt_views,
                attempt_alternatives,
            })?;
        }
        Command::PhysicsAgreement {
            scenes,
            seed,
            families,
        } => {
            let started = std::time::Instant::now();
            let a = mvgrasp_sim::physics::agreement(
                seed..seed + scenes,
                &families_of(&families)?,
                &mvgrasp_sim::grasp::GripperModel::robotiq_2f_140(),
                &mvgrasp_sim::physics::TrialConfig::default(),
            )?;
            println!(
                "{} grasps on {scenes} isolated scenes: agreement {:.1}% (both positive {}, both negative {}, analytic positive but dropped {}, analytic negative but held {}); {:.1} s",
                a.total(),
                a.rate() * 100.0,
                a.both_positive,
                a.both_negative,
                a.analytic_only,
                a.physics_only,
                started.elapsed().as_secs_f64()
            );
        }
        Command::Datagen {
            scenes,
            seed,
            out,
            scenarios,
            objects,
            input_size_px,
            pixel_size_mm,
            scenes_per_shard,
            no_noise,
            stride_px,
            angles,
            candidate_opening,
            without_neighbours,
            label_salt,
            threads,
            data_version,
        } => {
            use_threads(threads)?;
            let scenarios = scenarios_of(&scenarios)?;
            let targets = TargetConfig {
                stride_px,
                angles,
                opening: candidate_opening,
                neighbours: !without_neighbours,
                ..TargetConfig::default()
            };
            let data_version = data_version.unwrap_or_else(|| mvgrasp_sim::dataset::DATA_VERSION.to_owned());
            let contract = ModelContract {
                input_size_px,
                pixel_size_m: pixel_size_mm / 1000.0,
                data_version: data_version.clone(),
                ..ModelContract::baseline()
            };
            let config = DatagenConfig {
                scenes,
                seed,
                scenarios,
                catalog: objects.catalog()?,
                scenes_per_shard,
                targets,
                noise: (!no_noise).then(NoiseModel::default),
                data_version,
                label_salt,
            };
            let started = std::time::Instant::now();
            let report = generate(&out, &contract, &config, true)?;
            println!(
                "{} views ({} with positives) from {} scenes in {} shards, {} scenes failed, {:.1} s; wrote {}",
                report.views,
                report.views_with_positives,
                scenes,
                report.shards,
                report.failed.len(),
                started.elapsed().as_secs_f64(),
                out.join("manifest.json").display()
            );
        }
        Command::RenderSample {
            scenario,
            seed,
            out,
            objects,
            top_down,
            no_noise,
        } => {
            let scenario = Scenario::parse(&scenario)
                .with_context(|| format!("--scenario {scenario:?}: isolated, packed, pile or clutter"))?;
            let scene = Scene::generate_from(scenario, seed, &objects.catalog()?)?;
            let mut rng = SplitMix64::new(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xCA3E);
            let target = Vector3::new(0.0, 0.0, f64::from(scene.table_z));
            let camera = Camera::random(&mut rng, target, top_down);
            let noise = NoiseModel::default();
            let frame = render(&scene, &camera, (!no_noise).then_some((&noise, &mut rng)));
            write_frame(&out, &scene, &frame)?;
            println!(
                "{} seed {seed}: {} objects ({}), table at {:.3} m; wrote {}/{{depth.png, labels.png, camera.json, preview.png}}",
                scenario.name(),
                scene.objects.len(),
                scene
                    .objects
                    .iter()
                    .map(|o| o.model.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
                scene.table_z,
                out.display()
            );
        }
    }
    Ok(())
}
