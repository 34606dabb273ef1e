//! Does a compliant pad's contact normal label grasps as physics holds
//! them? Top-down grasps on isolated objects at 12 yaws (every 15 degrees),
//! through the box centre and moved 1.5 and 3 cm along the jaws' width,
//! fingertips 2.5 cm under the top, opened to the stroke, are labelled with
//! the current label (each pad's normal where its first ray meets the
//! object) and with `pad_compliance_m` set (the mean normal of the rays
//! within that distance of the first contact). Every grasp either label
//! calls positive or not antipodal is tried in physics with `sim eval`'s
//! trial and carry.
//!
//! Prints, per family, the grasps by (current label, compliant label) and
//! the share held.
//!
//!     cargo run --release -p mvgrasp-sim --example contact_patch [SCENES] [SEED] [FAMILIES] [COMPLIANCE_MM]
//!
//! Defaults: 12 scenes per family from seed 720000, the eight seen
//! families, 3 mm.
use std::collections::BTreeMap;

use mvgrasp_sim::grasp::{GraspLabel, GripperModel, label_grasp, top_down_over};
use mvgrasp_sim::objects::{Catalog, Family};
use mvgrasp_sim::physics::{Basket, TrialConfig, run_trial};
use mvgrasp_sim::scene::{Scenario, Scene};

fn short(label: &GraspLabel) -> &'static str {
    match label {
        GraspLabel::Positive { .. } => "positive",
        GraspLabel::NotAntipodal { .. } => "not antipodal",
        _ => "other",
    }
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scenes: u64 = args.first().map_or(Ok(12), |s| s.parse())?;
    let seed: u64 = args.get(1).map_or(Ok(720_000), |s| s.parse())?;
    let families: Vec<Family> = match args.get(2) {
        None => "box,cylinder,ellipsoid,superquadric,bottle,mug,l_shape,t_shape"
            .split(',')
            .filter_map(Family::parse)
            .collect(),
        Some(list) => list
            .split(',')
            .map(|f| Family::parse(f).ok_or_else(|| anyhow::anyhow!("unknown family {f}")))
            .collect::<anyhow::Result<_>>()?,
    };
    let compliance_mm: f32 = args.get(3).map_or(Ok(3.0), |s| s.parse())?;
    let current = GripperModel::robotiq_2f_140();
    let compliant = GripperModel {
        pad_compliance_m: compliance_mm / 1000.0,
        ..current
    };
    let config = TrialConfig {
        carry: Some(Basket::default()),
        ..TrialConfig::default()
    };
    // (family, current, compliant) -> (tried, held)
    let mut table: BTreeMap<(&str, &str, &str), (usize, usize)> = BTreeMap::new();
    let width = f64::from(current.max_width_m - current.clearance_m);
    for &family in &families {
        let catalog = Catalog::of(&[family]);
        for s in seed..seed + scenes {
            let scene = Scene::generate_from(Scenario::Isolated, s, &catalog)?;
            let o = &scene.objects[0];
            for k in 0..12 {
                let yaw = k as f64 * std::f64::consts::PI / 12.0;
                for offset in [0.0, 0.015, 0.03] {
                    let grasp = top_down_over(o, yaw, 0.025, offset);
                    let (a, b) = (
                        short(&label_grasp(&scene, 0, &grasp, width, &current)),
                        short(&label_grasp(&scene, 0, &grasp, width, &compliant)),
                    );
                    if a == "other" && b == "other" {
                        continue;
                    }
                    let held = usize::from(
                        run_trial(&scene, 0, &grasp, width, &current, &config)
                            .outcome
                            .is_held(),
                    );
                    for fam in [family.name(), "every family"] {
                        let e = table.entry((fam, a, b)).or_default();
                        e.0 += 1;
                        e.1 += held;
                    }
                }
            }
        }
    }
    println!("family | current label | with {compliance_mm} mm of pad compliance | tried | held | share");
    for ((fam, a, b), (n, held)) in &table {
        println!(
            "{fam} | {a} | {b} | {n} | {held} | {:.2}",
            *held as f64 / (*n).max(1) as f64
        );
    }
    // Over every family: each label's positives, the share of them held,
    // and the share of all held grasps it calls positive.
    let every = |want: &dyn Fn(&str, &str) -> bool| {
        table
            .iter()
            .filter(|((f, a, b), _)| *f == "every family" && want(a, b))
            .fold((0, 0), |(n, h), (_, (tn, th))| (n + tn, h + th))
    };
    let (_, held_all) = every(&|_, _| true);
    for (name, pick) in [("current", 0), ("compliant", 1)] {
        let (n, held) = every(&|a, b| [a, b][pick] == "positive");
        println!(
            "{name}: {n} positives, {held} held ({:.3}); {:.3} of the {held_all} grasps that held",
            held as f64 / n.max(1) as f64,
            held as f64 / held_all.max(1) as f64
        );
    }
    Ok(())
}
