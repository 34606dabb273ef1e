//! The pairs of touching parts that the crease split cuts one cluster into
//! (steps 1-5 of `core::segment::crease`, without step 6), each labelled by
//! the renderer as one object or two, with the measures step 6 (`Reattach`)
//! judges them by; on the scenes and cameras of `sim eval --seed SEED` (first
//! frame of each episode, seen families).
//!
//!     cargo run --release -p mvgrasp-sim --example crease_pairs [EPISODES] [SEED] [LIST]
//!
//! Prints, per scenario, how many pairs are one object and how many two, and
//! how many of each step 6's defaults would join; with `LIST` (any third
//! argument) also every pair: scenario, seed, same object, the two parts'
//! families (by the majority of their pixels), their points, the touching
//! pixel pairs, the smaller part's area (cm^2), its outline (px) and the mean
//! depth change across the border (mm).

use std::collections::{BTreeMap, HashMap};

use mvgrasp_core::{GraspNet, MomentsNet, Reattach};
use mvgrasp_sim::eval::{episode_first_frame, planner_with_crease};
use mvgrasp_sim::objects::{Catalog, Family};
use mvgrasp_sim::scene::Scenario;

/// One pair of touching parts.
struct Pair {
    same_object: bool,
    /// Each part's majority label (2 + object index; 1 the table).
    labels: [u16; 2],
    points: [usize; 2],
    /// Neighbouring pixel pairs across the border.
    border: usize,
    /// The smaller part's surface seen from the camera (m^2).
    small_area_m2: f32,
    /// The smaller part's pixels with a 4-neighbour outside it.
    small_outline: usize,
    /// Mean optical-axis depth change across the border (m).
    step_m: f32,
}

impl Pair {
    /// Whether `r` would join the smaller part to the larger one (judged on
    /// this pair alone; step 6 itself goes smallest part first).
    fn joins(&self, r: &Reattach) -> bool {
        let (small, large) = (
            self.points[0].min(self.points[1]),
            self.points[0].max(self.points[1]),
        );
        r.hangs_on(
            small,
            large,
            self.small_area_m2,
            self.border,
            self.small_outline,
            self.step_m * self.border as f32,
        )
    }
}

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let episodes: u64 = args.next().map(|a| a.parse()).transpose()?.unwrap_or(64);
    let first_seed: u64 = args.next().map(|a| a.parse()).transpose()?.unwrap_or(800_000);
    let list = args.next().is_some();
    let contract = MomentsNet::default().contract().clone();
    let (whole, split) = (
        planner_with_crease("off", &contract)?,
        planner_with_crease("split-only", &contract)?,
    );
    let families: Vec<Family> = Family::ALL.into_iter().filter(|f| *f != Family::Bowl).collect();
    let catalog = Catalog::of(&families);
    let reattach = Reattach::default();
    if list {
        println!(
            "scenario seed same family_a family_b points_a points_b border small_area_cm2 small_outline step_mm"
        );
    }
    let mut table: Vec<(Scenario, [usize; 4])> = Vec::new();
    for scenario in [
        Scenario::Isolated,
        Scenario::Packed,
        Scenario::Pile,
        Scenario::Clutter,
    ] {
        let mut counts = [0usize; 4];
        for seed in first_seed..first_seed + episodes {
            let (scene, frame) = episode_first_frame(scenario, seed, &catalog)?;
            let bytes = frame.depth_le_bytes();
            let input = frame.scene_input(&bytes, scene.workspace());
            let (clusters, parts) = (whole.segment(&input)?, split.segment(&input)?);
            let eye = frame.camera.world_from_camera;
            let axis = eye.rotation * nalgebra::Vector3::z();
            let depth = |p: [f32; 3]| {
                let d = nalgebra::Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))
                    - eye.translation.vector;
                d.dot(&axis) as f32
            };
            let family = |label: u16| match label {
                l if l >= 2 => format!("{:?}", scene.objects[usize::from(l - 2)].model.family),
                _ => "table".into(),
            };
            let focal_px = frame.camera.intrinsics.fx as f32;
            for pair in pairs(
                &frame.labels,
                frame.camera.width as usize,
                &clusters,
                &parts,
                &depth,
                focal_px,
            ) {
                let k = if pair.same_object { 0 } else { 2 };
                counts[k] += 1;
                counts[k + 1] += usize::from(pair.joins(&reattach));
                if list {
                    println!(
                        "{scenario:?} {seed} {} {} {} {} {} {} {:.1} {} {:.1}",
                        pair.same_object,
                        family(pair.labels[0]),
                        family(pair.labels[1]),
                        pair.points[0],
                        pair.points[1],
                        pair.border,
                        pair.small_area_m2 * 1e4,
                        pair.small_outline,
                        pair.step_m * 1000.0
                    );
                }
            }
        }
        table.push((scenario, counts));
    }
    println!("scenario | pairs of one object | joined by step 6 | pairs of two objects | joined by step 6");
    println!("---|---:|---:|---:|---:");
    for (scenario, c) in &table {
        println!("{scenario:?} | {} | {} | {} | {}", c[0], c[1], c[2], c[3]);
    }
    Ok(())
}

/// The touching pairs of `parts` that lie in one cluster of `clusters`.
fn pairs(
    labels: &[u16],
    width: usize,
    clusters: &mvgrasp_core::Segmentation,
    parts: &mvgrasp_core::Segmentation,
    depth: &dyn Fn([f32; 3]) -> f32,
    focal_px: f32,
) -> Vec<Pair> {
    let n = parts.points.len();
    let owner = |seg: &mvgrasp_core::Segmentation| {
        let mut of = vec![usize::MAX; n];
        for (d, c) in seg.clusters.iter().enumerate() {
            for &i in c {
                of[i as usize] = d;
            }
        }
        of
    };
    let (part_of, cluster_of) = (owner(parts), owner(clusters));
    let point_at: HashMap<usize, usize> = parts
        .pixels
        .iter()
        .enumerate()
        .map(|(i, &p)| (p as usize, i))
        .collect();
    // Each part's majority label, area and outline.
    let mut label_counts: Vec<HashMap<u16, usize>> = vec![HashMap::new(); parts.clusters.len()];
    let mut area = vec![0f32; parts.clusters.len()];
    let mut outline = vec![0usize; parts.clusters.len()];
    let mut touch: BTreeMap<(usize, usize), (usize, f32)> = BTreeMap::new();
    for (i, &pixel) in parts.pixels.iter().enumerate() {
        let (p, d) = (pixel as usize, part_of[i]);
        if d == usize::MAX {
            continue;
        }
        *label_counts[d].entry(labels[p]).or_default() += 1;
        area[d] += (depth(parts.points[i]) / focal_px).powi(2);
        let (u, v) = (p % width, p / width);
        let around = [
            (u > 0).then(|| p - 1),
            (u + 1 < width).then_some(p + 1),
            (v > 0).then(|| p - width),
            Some(p + width),
        ];
        let mut edge = false;
        for (k, q) in around.into_iter().enumerate() {
            let j = q.and_then(|q| point_at.get(&q).copied());
            let other = j.map(|j| part_of[j]);
            if other != Some(d) {
                edge = true;
            }
            // Each pixel pair once: towards +u and +v, inside one cluster.
            if let (Some(j), Some(o), 1 | 3) = (j, other, k)
                && o != d
                && o != usize::MAX
                && cluster_of[i] == cluster_of[j]
            {
                let entry = touch.entry((d.min(o), d.max(o))).or_default();
                entry.0 += 1;
                entry.1 += (depth(parts.points[i]) - depth(parts.points[j])).abs();
            }
        }
        outline[d] += usize::from(edge);
    }
    let major: Vec<u16> = label_counts
        .iter()
        .map(|c| c.iter().max_by_key(|&(l, k)| (*k, *l)).map_or(0, |(&l, _)| l))
        .collect();
    touch
        .into_iter()
        .map(|((a, b), (border, step_sum))| {
            let small = if parts.clusters[a].len() <= parts.clusters[b].len() {
                a
            } else {
                b
            };
            Pair {
                same_object: major[a] == major[b],
                labels: [major[a], major[b]],
                points: [parts.clusters[a].len(), parts.clusters[b].len()],
                border,
                small_area_m2: area[small],
                small_outline: outline[small],
                step_m: step_sum / border as f32,
            }
        })
        .collect()
}
