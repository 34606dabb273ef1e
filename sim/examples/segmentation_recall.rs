//! How well the planner's segmentation separates a scene's objects, per
//! scenario, with the crease split off and on, on the scenes and cameras of
//! `sim eval --seed 800000` (the tuning seeds; first frame of each episode).
//!
//!     cargo run --release -p mvgrasp-sim --example segmentation_recall [EPISODES] [PNG_DIR|-] [CREASE] [SEED]
//!
//! `CREASE` is the split compared with none, as `sim eval --crease-split`
//! takes it (`on`, the default, or `split-only`); `SEED` the first episode's seed (default 800000).
//!
//! Scored on pixels, against the renderer's labels, over the pixels the
//! planner kept as object points:
//! - an object is *visible* with at least 200 such pixels;
//! - *found*: one detection covers it with IoU >= 0.5;
//! - a detection is *merged* when two or more objects each hold at least 20%
//!   of its pixels;
//! - an object is *split* when two or more detections each hold at least 20%
//!   of its pixels;
//! - a detection *matches none* when it is no object's IoU >= 0.5 match (a
//!   fragment, a merge, or something that is not an object).
//!
//! With `PNG_DIR`, each scene is drawn as labels | split off | split on.

use std::path::PathBuf;

use mvgrasp_core::{GraspNet, MomentsNet, Segmentation};
use mvgrasp_sim::camera::Frame;
use mvgrasp_sim::eval::{episode_first_frame, planner_with_crease};
use mvgrasp_sim::files::write_detections;
use mvgrasp_sim::objects::{Catalog, Family};
use mvgrasp_sim::overlap::Overlap;
use mvgrasp_sim::scene::Scenario;

/// Counts over a set of frames.
#[derive(Default)]
struct Score {
    visible: usize,
    detections: usize,
    found: usize,
    merged: usize,
    split: usize,
    unmatched: usize,
}

fn score(frame: &Frame, seg: &Segmentation, score: &mut Score) {
    let overlap = Overlap::new(frame, seg);
    score.detections += seg.clusters.len();
    let mut matched = vec![false; seg.clusters.len()];
    for (&label, &n) in &overlap.of_label {
        if n < 200 {
            continue;
        }
        score.visible += 1;
        if let Some(&(d, _)) = overlap
            .shares(label)
            .iter()
            .find(|&&(d, k)| k as f64 / (n + overlap.of_detection[d] - k) as f64 >= 0.5)
        {
            score.found += 1;
            matched[d] = true;
        }
        if overlap.is_split(label) {
            score.split += 1;
        }
    }
    score.unmatched += matched.iter().filter(|&&m| !m).count();
    score.merged += overlap.merged();
}

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let episodes: u64 = args.next().map(|a| a.parse()).transpose()?.unwrap_or(16);
    let png_dir = args.next().filter(|a| a != "-").map(PathBuf::from);
    if let Some(dir) = &png_dir {
        std::fs::create_dir_all(dir)?;
    }
    let contract = MomentsNet::default().contract().clone();
    let crease = args.next().unwrap_or_else(|| "on".into());
    let planners = [
        planner_with_crease("off", &contract)?,
        planner_with_crease(&crease, &contract)?,
    ];
    let first_seed: u64 = args.next().map(|a| a.parse()).transpose()?.unwrap_or(800_000);
    // The seen families of results/seen-families (every family but the bowl).
    let families: Vec<Family> = Family::ALL.into_iter().filter(|f| *f != Family::Bowl).collect();
    let catalog = Catalog::of(&families);
    println!(
        "scenario | crease split | visible | detections | found (IoU >= 0.5) | merged detections | split objects | detections matching none"
    );
    println!("---|---|---|---|---|---|---|---");
    for scenario in [
        Scenario::Isolated,
        Scenario::Packed,
        Scenario::Pile,
        Scenario::Clutter,
    ] {
        let mut scores = [Score::default(), Score::default()];
        for seed in first_seed..first_seed + episodes {
            let (scene, frame) = episode_first_frame(scenario, seed, &catalog)?;
            let bytes = frame.depth_le_bytes();
            let input = frame.scene_input(&bytes, scene.workspace());
            let segs = [planners[0].segment(&input)?, planners[1].segment(&input)?];
            for (seg, s) in segs.iter().zip(&mut scores) {
                score(&frame, seg, s);
            }
            if let Some(dir) = &png_dir {
                let name = format!("{scenario:?}-{seed}.png").to_lowercase();
                write_detections(&dir.join(name), &frame, &[&segs[0], &segs[1]])?;
            }
        }
        for (s, on) in scores.iter().zip(["off", "on"]) {
            println!(
                "{scenario:?} | {on} | {} | {} | {} | {} | {} | {}",
                s.visible, s.detections, s.found, s.merged, s.split, s.unmatched
            );
        }
    }
    Ok(())
}
