//! Why episodes of `sim eval` end with "no grasp above tau": the episodes of
//! one scenario and setting (seen families, shipped model, in-process), and
//! at each such end the planner's view of the last frame: the objects still
//! visible (their family, matched by position to the scene's start: wrong
//! where objects moved, as in piles), the
//! objects detected and their extents, how many detections hold two or more
//! objects (merged) and how many objects are spread over two or more
//! detections (split; `sim::overlap`, as `segmentation_recall` counts them), how many candidates at tau the hand
//! check refused (by what the hand would have hit: the table, the grasp's
//! own object, a neighbour), and, planned again at tau 0, how many grasps
//! were kept and the best quality any reached. Each object left is listed
//! with the narrowest way across its visible points seen from above: over
//! the gripper's stroke (140 mm for the 2F-140), no parallel-jaw grasp
//! takes it from any side. (Whether those grasps would
//! have held: run the same setting at tau 0.) An episode can also end on a
//! frame whose grasps had all already failed (the loop does not try one
//! again until an object is taken): then the line says how many it was
//! offered.
//!
//!     cargo run --release -p mvgrasp-sim --example why_no_grasp [SCENARIO] [SETTING] [EPISODES] [SEED] [MODEL] [FAMILIES] [PNG_DIR]
//!
//! With `PNG_DIR`, each such last frame is drawn there as `SEED.png`: the
//! renderer's labels | the planner's detections.
//! Defaults: packed, all:0.1, 16 episodes from seed 900000 (the results/
//! scenes), the default model (`ModelSettings::default()`), the 8 seen families. Each attempt is
//! listed with its outcome, its approach's angle below the horizontal and
//! its quality; in isolated scenes, where the first grasp sat on the object. Needs ORT_DYLIB_PATH.
use mvgrasp_core::{PlanOptions, Planner, PlannerConfig, Workspace};
use mvgrasp_server::settings::ModelSettings;
use mvgrasp_sim::camera::Frame;
use mvgrasp_sim::eval::{End, EpisodeConfig, GraspSource, InProcess, PlannedGrasp, Setting, run_episode};
use mvgrasp_sim::objects::{Catalog, Family};
use mvgrasp_sim::scene::Scenario;

struct Diagnosing<'a> {
    inner: InProcess<'a>,
    last: String,
    seed: u64,
    png_dir: Option<&'a std::path::Path>,
    /// The table top's height in the world (m).
    table_z: f64,
    /// Each visible object: the centre of its points (x, y) and the
    /// narrowest way across them seen from above (m).
    left: Vec<([f64; 2], f64)>,
}

/// The narrowest width of points projected on the table, over directions
/// 1 degree apart, between the 1st and 99th percentile of each direction
/// (the camera's noise puts a few edge pixels on the table behind): a
/// parallel-jaw grasp closes roughly horizontally, so an object whose
/// visible part is wider than the stroke every way cannot be taken from any
/// side (the hidden part only widens it). Only points 5 mm or more over the
/// table count.
fn narrowest_across(points: &[nalgebra::Point3<f64>], table_z: f64) -> f64 {
    let above: Vec<_> = points.iter().filter(|p| p.z > table_z + 0.005).collect();
    if above.len() < 10 {
        return 0.0;
    }
    (0..180)
        .map(|deg| {
            let (s, c) = f64::from(deg).to_radians().sin_cos();
            let mut d: Vec<f64> = above.iter().map(|p| p.x * c + p.y * s).collect();
            d.sort_by(f64::total_cmp);
            let at = |q: f64| d[((d.len() - 1) as f64 * q).round() as usize];
            at(0.99) - at(0.01)
        })
        .fold(f64::INFINITY, f64::min)
}

impl GraspSource for Diagnosing<'_> {
    fn grasps(
        &mut self,
        frame: &Frame,
        workspace: Workspace,
        options: &PlanOptions,
    ) -> mvgrasp_sim::Result<Vec<PlannedGrasp>> {
        let ranked = self.inner.grasps(frame, workspace, options)?;
        if !ranked.is_empty() {
            // Kept for an episode that ends on this frame anyway: the loop
            // takes none of these grasps when each has already failed since
            // an object was last taken.
            self.last = format!(
                "offered {} grasp(s), every one already failed since an object was last taken",
                ranked.len()
            );
        } else {
            let bytes = frame.depth_le_bytes();
            let input = frame.scene_input(&bytes, workspace);
            let at_tau = PlanOptions {
                max_grasps: 1000,
                ..options.clone()
            };
            let all = PlanOptions {
                min_quality: 0.0,
                ..at_tau.clone()
            };
            let plan = |options: &PlanOptions, net: &mut dyn mvgrasp_core::GraspNet| {
                self.inner
                    .planner
                    .plan(&input, options, net)
                    .map_err(|e| mvgrasp_sim::Error::Scene(format!("planner: {e}")))
            };
            let p = plan(&at_tau, self.inner.net)?;
            let q = plan(&all, self.inner.net)?;
            let labels: std::collections::HashSet<u16> =
                frame.labels.iter().copied().filter(|&l| l >= 2).collect();
            self.left = labels
                .iter()
                .map(|&l| {
                    let pts = frame.labelled_points(l);
                    let n = pts.len().max(1) as f64;
                    let centre = [
                        pts.iter().map(|p| p.x).sum::<f64>() / n,
                        pts.iter().map(|p| p.y).sum::<f64>() / n,
                    ];
                    (centre, narrowest_across(&pts, self.table_z))
                })
                .collect();
            let best_q = q.grasps.iter().map(|g| g.quality).fold(0.0f32, f32::max);
            let seg = self
                .inner
                .planner
                .segment(&input)
                .map_err(|e| mvgrasp_sim::Error::Scene(format!("planner: {e}")))?;
            let overlap = mvgrasp_sim::overlap::Overlap::new(frame, &seg);
            let (merged, split) = (
                overlap.merged(),
                overlap.of_label.keys().filter(|&&l| overlap.is_split(l)).count(),
            );
            if let Some(dir) = self.png_dir {
                mvgrasp_sim::files::write_detections(
                    &dir.join(format!("{}.png", self.seed)),
                    frame,
                    &[&seg],
                )?;
            }

            let sizes: Vec<String> = q
                .objects
                .iter()
                .map(|o| {
                    let (a, b) = (o.frame.extent_min_m, o.frame.extent_max_m);
                    format!(
                        "{:.0}x{:.0}x{:.0}mm",
                        (b[0] - a[0]) * 1e3,
                        (b[1] - a[1]) * 1e3,
                        (b[2] - a[2]) * 1e3
                    )
                })
                .collect();
            self.last = format!(
                "visible {} detected {} (merged {merged}, objects split {split}) [{}] refused@tau {} (table {} own {} neighbour {}) kept@0 {} refused@0 {} (table {} own {} neighbour {}) best q {:.3}",
                labels.len(),
                p.objects.len(),
                sizes.join(" "),
                p.refused_for_collision,
                p.refusals.table,
                p.refusals.own_object,
                p.refusals.neighbour,
                q.grasps.len(),
                q.refused_for_collision,
                q.refusals.table,
                q.refusals.own_object,
                q.refusals.neighbour,
                best_q
            );
        }
        Ok(ranked)
    }
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, default: &str| args.get(i).cloned().unwrap_or_else(|| default.to_owned());
    let scenario = Scenario::parse(&arg(1, "packed")).ok_or_else(|| anyhow::anyhow!("unknown scenario"))?;
    let setting = Setting::parse(&arg(2, "all:0.1"))?;
    let episodes: u64 = arg(3, "16").parse()?;
    let seed0: u64 = arg(4, "900000").parse()?;
    let mut model = ModelSettings::default();
    if let Some(path) = args.get(5) {
        model.path = path.into();
    }
    let mut loaded = mvgrasp_server::backend::load(&model, 64)?;
    let planner = Planner::new(PlannerConfig::default(), loaded.net.contract().clone())?;
    let families: Vec<Family> = arg(
        6,
        "box,cylinder,ellipsoid,superquadric,bottle,mug,l_shape,t_shape",
    )
    .split(',')
    .map(|f| Family::parse(f).ok_or_else(|| anyhow::anyhow!("unknown family {f}")))
    .collect::<anyhow::Result<_>>()?;
    let png_dir = args.get(7).map(std::path::PathBuf::from);
    if let Some(dir) = &png_dir {
        std::fs::create_dir_all(dir)?;
    }
    let config = EpisodeConfig {
        catalog: Catalog::of(&families),
        ..EpisodeConfig::default()
    };
    for seed in seed0..seed0 + episodes {
        // The scene as the episode starts (the table does not move).
        let (scene, _) = mvgrasp_sim::eval::episode_scene(scenario, seed, &config.catalog)?;
        let mut source = Diagnosing {
            inner: InProcess {
                planner: &planner,
                net: loaded.net.as_mut(),
            },
            last: String::new(),
            seed,
            png_dir: png_dir.as_deref(),
            table_z: f64::from(scene.table_z),
            left: Vec::new(),
        };
        let e = run_episode(scenario, seed, &setting, &mut source, &config)?;
        // Each attempt: its outcome, and how steep its approach was (degrees
        // below the horizontal: 90 is straight down).
        let fails: Vec<String> = e
            .attempts
            .iter()
            .map(|a| {
                let approach = a.world_from_grasp.rotation * nalgebra::Vector3::z();
                format!(
                    "{} {:.0}deg q{:.2}",
                    a.failure.map_or("ok", |f| f.name()),
                    (-approach.z).clamp(-1.0, 1.0).asin().to_degrees(),
                    a.quality
                )
            })
            .collect();
        // Isolated scenes: where the first grasp sat on the object, in the
        // object's frame (origin and z axis as the family builds it: a
        // cylinder's base centre and axis), and its closing direction.
        if let (Scenario::Isolated, Some(a), Some(o)) = (scenario, e.attempts.first(), scene.objects.first())
        {
            let t = o.world_from_object.translation;
            let q = o.world_from_object.rotation;
            let axis = q * parry3d::math::Vector::Z;
            let g = a.world_from_grasp.translation.vector;
            let close = a.world_from_grasp.rotation * nalgebra::Vector3::x();
            let off =
                nalgebra::Vector3::new(g.x - f64::from(t.x), g.y - f64::from(t.y), g.z - f64::from(t.z));
            let ax = nalgebra::Vector3::new(f64::from(axis.x), f64::from(axis.y), f64::from(axis.z));
            let aabb = o.model.aabb;
            println!(
                "   first attempt: {:.0} mm along the object's z axis from its origin, {:.0} mm off it; closing {:.0} deg from that axis; axis . up {:.2}; object extents {:.0?} mm; opening {:.0} mm; {}",
                off.dot(&ax) * 1e3,
                (off - ax * off.dot(&ax)).norm() * 1e3,
                close.dot(&ax).abs().acos().to_degrees(),
                ax.z,
                ((aabb.maxs - aabb.mins) * 1000.0).to_array(),
                a.width_m * 1e3,
                a.failure.map_or("ok", |f| f.name())
            );
        }
        let names: Vec<String> = source
            .left
            .iter()
            .filter_map(|(c, across)| {
                scene
                    .objects
                    .iter()
                    .min_by(|a, b| {
                        let d = |o: &mvgrasp_sim::scene::PlacedObject| {
                            let t = o.world_from_object.translation;
                            (f64::from(t.x) - c[0]).powi(2) + (f64::from(t.y) - c[1]).powi(2)
                        };
                        d(a).total_cmp(&d(b))
                    })
                    .map(|o| format!("{} {:.0}mm", o.model.name, across * 1e3))
            })
            .collect();
        println!(
            "{seed} [{}] objects {} removed {} end {} | {} | {}",
            names.join(","),
            e.objects,
            e.removed,
            e.end.name(),
            if e.end == End::NoGraspAboveTau {
                source.last.as_str()
            } else {
                ""
            },
            fails.join(",")
        );
    }
    Ok(())
}
