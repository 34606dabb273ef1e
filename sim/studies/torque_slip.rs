//! Which analytic positives hold in physics? Top-down grasps on isolated
//! objects at 4 yaws, through the box centre and moved 2, 4 and 6 cm
//! sideways along the jaws' width (so the weight turns the object about the
//! closing line), fingertips 2.5 cm under the top, opened to the stroke.
//! Every grasp the sim-4 label (friction cone 26.6 degrees, no torque term)
//! calls positive is tried in physics with `sim eval`'s trial and carry.
//!
//! Prints the share held per bin of the narrowest cone that still labels the
//! grasp positive (its worst contact angle, rounded up to 5, 10, 15, 20 or
//! 26.6 degrees) and of the weight's torque about the closing line; then how
//! many of the sim-4 positives the current label (`GripperModel::robotiq_2f_140`)
//! keeps and how many of those held. `--each` lists every grasp.
//!
//!     cargo run --release -p mvgrasp-sim --example torque_slip [SCENES] [SEED] [FAMILIES] [--each]
//!
//! Defaults: 30 scenes per family from seed 700000 (the calibration; 710000
//! is the check), families box, cylinder, bottle, superquadric, ellipsoid.
use std::collections::BTreeMap;

use mvgrasp_sim::grasp::{GripperModel, label_grasp, top_down_over, weight_torque_nm};
use mvgrasp_sim::objects::{Catalog, Family};
use mvgrasp_sim::physics::{Basket, TrialConfig, run_trial};
use mvgrasp_sim::scene::{Scenario, Scene};

/// Cones (deg) tried, narrowest first.
const CONES_DEG: [f32; 5] = [5.0, 10.0, 15.0, 20.0, 26.6];
/// Torque bins (N m): upper edges.
const TORQUES_NM: [f32; 5] = [0.03, 0.06, 0.1, 0.15, f32::INFINITY];

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let each = args.iter().any(|a| a == "--each");
    let plain: Vec<&String> = args.iter().filter(|a| !a.starts_with("--")).collect();
    let scenes: u64 = plain.first().map_or(Ok(30), |s| s.parse())?;
    let seed: u64 = plain.get(1).map_or(Ok(700_000), |s| s.parse())?;
    let families: Vec<Family> = match plain.get(2) {
        None => vec![
            Family::Box,
            Family::Cylinder,
            Family::Bottle,
            Family::Superquadric,
            Family::Ellipsoid,
        ],
        Some(list) => list
            .split(',')
            .map(|f| Family::parse(f).ok_or_else(|| anyhow::anyhow!("unknown family {f}")))
            .collect::<anyhow::Result<_>>()?,
    };
    let current = GripperModel::robotiq_2f_140();
    let sim4 = GripperModel {
        friction: 0.5,
        max_torque_nm: f32::INFINITY,
        ..current
    };
    let config = TrialConfig {
        carry: Some(Basket::default()),
        ..TrialConfig::default()
    };
    // (cone bin, torque bin) -> (tried, held); and the current label's (kept, held).
    let mut bins: BTreeMap<(usize, usize), (usize, usize)> = BTreeMap::new();
    let (mut tried, mut held_all, mut kept, mut kept_held) = (0, 0, 0, 0);
    for &family in &families {
        let catalog = Catalog::of(&[family]);
        for s in seed..seed + scenes {
            let scene = Scene::generate_from(Scenario::Isolated, s, &catalog)?;
            let o = &scene.objects[0];
            for k in 0..4 {
                let yaw = k as f64 * std::f64::consts::PI / 4.0;
                for offset in [0.0, 0.02, 0.04, 0.06] {
                    let grasp = top_down_over(o, yaw, 0.025, offset);
                    let width = f64::from(current.max_width_m - current.clearance_m);
                    if !label_grasp(&scene, 0, &grasp, width, &sim4).is_positive() {
                        continue;
                    }
                    let cone = CONES_DEG
                        .iter()
                        .position(|deg| {
                            let narrow = GripperModel {
                                friction: deg.to_radians().tan(),
                                ..sim4
                            };
                            label_grasp(&scene, 0, &grasp, width, &narrow).is_positive()
                        })
                        .unwrap_or(CONES_DEG.len() - 1);
                    let torque = weight_torque_nm(o, &mvgrasp_sim::grasp::pose_of(&grasp));
                    let t = TORQUES_NM
                        .iter()
                        .position(|&e| torque < e)
                        .unwrap_or(TORQUES_NM.len() - 1);
                    let outcome = run_trial(&scene, 0, &grasp, width, &current, &config).outcome;
                    let held = usize::from(outcome.is_held());
                    let bin = bins.entry((cone, t)).or_default();
                    bin.0 += 1;
                    bin.1 += held;
                    tried += 1;
                    held_all += held;
                    if label_grasp(&scene, 0, &grasp, width, &current).is_positive() {
                        kept += 1;
                        kept_held += held;
                    }
                    if each {
                        println!(
                            "{} seed {s} yaw {:.0} offset {:.0} mm: mass {:.3} kg, torque {torque:.3} N m, cone {} deg, {outcome:?}",
                            family.name(),
                            yaw.to_degrees(),
                            offset * 1000.0,
                            o.model.mass_kg,
                            CONES_DEG[cone],
                        );
                    }
                }
            }
        }
    }
    println!("cone (deg) | torque below (N m) | positives | held | share");
    for ((c, t), (n, held)) in &bins {
        println!(
            "{:>10} | {:>18} | {n:>9} | {held:>4} | {:.2}",
            CONES_DEG[*c],
            TORQUES_NM[*t],
            *held as f64 / (*n).max(1) as f64
        );
    }
    let share = |a: usize, b: usize| a as f64 / b.max(1) as f64;
    println!(
        "sim-4 positives: {tried}, held {held_all} ({:.2}); the current label keeps {kept}, held {kept_held} ({:.2}), {:.2} of all that held",
        share(held_all, tried),
        share(kept_held, kept),
        share(kept_held, held_all)
    );
    Ok(())
}
