//! Do the positives of `sim datagen --candidate-opening pads` hold in
//! physics as the chord's do? Isolated scenes rendered as `sim datagen`
//! renders them (the eight seen families, 72 px views of 3.33 mm, stride 3,
//! 8 angles), every view labelled both ways from the same draw, and up to
//! PER_VIEW positives of each view, drawn at random, tried in `sim eval`'s
//! trial (close, lift, shake, carry to the basket; no approach). The pads'
//! positives split into those at a pixel where the chord also has a
//! positive (at any angle) and the new ones.
//!
//!     cargo run --release -p mvgrasp-sim --example opening_physics [SCENES] [SEED] [PER_VIEW]
//!
//! Defaults: 64 scenes from seed 720000, 4 positives per view. Prints, per
//! opening and view direction, the positives labelled, tried and held.
use std::collections::{BTreeMap, HashSet};

use mvgrasp_core::rng::SplitMix64;
use mvgrasp_core::{ModelContract, Planner, PlannerConfig};
use mvgrasp_sim::camera::NoiseModel;
use mvgrasp_sim::dataset::{DatagenConfig, scene_frame};
use mvgrasp_sim::grasp::GripperModel;
use mvgrasp_sim::objects::{Catalog, Family};
use mvgrasp_sim::physics::{Basket, TrialConfig, run_trial};
use mvgrasp_sim::scene::Scenario;
use mvgrasp_sim::targets::{LabelledView, Opening, TargetConfig, label_frame};
use rayon::prelude::*;

/// (opening, view, kind) -> (labelled, tried, held); kind: "all", or for
/// the pads "same pixel" / "new pixel".
type Tally = BTreeMap<(&'static str, String, &'static str), (usize, usize, usize)>;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scenes: u64 = args.first().map_or(Ok(64), |s| s.parse())?;
    let seed: u64 = args.get(1).map_or(Ok(720_000), |s| s.parse())?;
    let per_view: usize = args.get(2).map_or(Ok(4), |s| s.parse())?;
    let seen: Vec<Family> = Family::ALL.into_iter().filter(|&f| f != Family::Bowl).collect();
    let contract = ModelContract {
        input_size_px: 72,
        pixel_size_m: 0.010 / 3.0,
        ..ModelContract::baseline()
    };
    let planner = Planner::new(PlannerConfig::default(), contract).map_err(|e| anyhow::anyhow!("{e}"))?;
    let gripper = GripperModel::robotiq_2f_140();
    let trial = TrialConfig {
        carry: Some(Basket::default()),
        ..TrialConfig::default()
    };
    let config = |opening| DatagenConfig {
        scenes,
        seed,
        scenarios: vec![Scenario::Isolated],
        catalog: Catalog::of(&seen),
        scenes_per_shard: 64,
        targets: TargetConfig {
            opening,
            ..TargetConfig::default()
        },
        noise: Some(NoiseModel::default()),
        data_version: "opening_physics".into(),
        label_salt: 0,
    };
    let (chord_config, pads_config) = (config(Opening::Chord), config(Opening::Pads));
    let tallies: Vec<anyhow::Result<Tally>> = (seed..seed + scenes)
        .into_par_iter()
        .map(|s| {
            let (scene, frame, rng) = scene_frame(s, Scenario::Isolated, &chord_config)?;
            let label = |config: &DatagenConfig| -> anyhow::Result<Vec<LabelledView>> {
                let mut rng = rng.clone();
                Ok(label_frame(
                    &scene,
                    &frame,
                    &planner,
                    &gripper,
                    &config.targets,
                    &mut rng,
                )?)
            };
            let (chord, pads) = (label(&chord_config)?, label(&pads_config)?);
            let mut pick = SplitMix64::new(s ^ 0x0FE1);
            let mut tally = Tally::new();
            for (c, p) in chord.iter().zip(&pads) {
                let axis = c.axis.name().to_string();
                let chord_pixels: HashSet<(usize, usize)> = c.grasps.iter().map(|g| (g.u, g.v)).collect();
                for (name, view) in [("chord", c), ("pads", p)] {
                    let mut order: Vec<usize> = (0..view.grasps.len()).collect();
                    for i in (1..order.len()).rev() {
                        order.swap(i, (pick.next_u64() % (i as u64 + 1)) as usize);
                    }
                    for (rank, &i) in order.iter().enumerate() {
                        let g = &view.grasps[i];
                        let kind = match name {
                            "chord" => "all",
                            _ if chord_pixels.contains(&(g.u, g.v)) => "same pixel",
                            _ => "new pixel",
                        };
                        let entry = tally.entry((name, axis.clone(), kind)).or_default();
                        entry.0 += 1;
                        if rank < per_view {
                            let outcome = run_trial(
                                &scene,
                                view.object,
                                &g.world_from_grasp,
                                f64::from(g.width_m),
                                &gripper,
                                &trial,
                            )
                            .outcome;
                            entry.1 += 1;
                            entry.2 += usize::from(outcome.is_held());
                        }
                    }
                }
            }
            Ok(tally)
        })
        .collect();
    let mut total = Tally::new();
    for tally in tallies {
        for (key, (n, tried, held)) in tally? {
            let entry = total.entry(key).or_default();
            entry.0 += n;
            entry.1 += tried;
            entry.2 += held;
        }
    }
    println!("opening | view | positives | labelled | tried | held | share held");
    for ((opening, view, kind), (n, tried, held)) in &total {
        println!(
            "{opening} | {view} | {kind} | {n} | {tried} | {held} | {:.2}",
            *held as f64 / (*tried).max(1) as f64
        );
    }
    Ok(())
}
