//! Records and tables of a run: JSON per episode, attempt views, label, provenance and collision tables, the Markdown summary.

use super::*;

/// One episode as a record of `eval.json`'s `episodes`: its scenario,
/// setting and seed, objects at the start, removed and fallen off, how it
/// ended, and each attempt in order as `[outcome, quality, width_mm,
/// down_deg, plan_ms, label, family, view, [u, v], centroid_lever_mm,
/// torque_nm, repairs, tilt_deg]`: "ok", a failure's name, or for a collision on
/// approach what was hit ([`CollisionSite::name`]); the approach's angle
/// below the horizontal (90: straight down); for a physics trial the
/// grasp's analytic label ([`GraspLabel::name`]) and its object's family,
/// else null; the view the grasp came from and its peak pixel there; the
/// lever the planner could see ([`Attempt::centroid_lever_m`]); for a
/// physics trial the weight's torque about the closing line, else null; the
/// names of the planner's repairs to it ([`Repairs::names`]); for a grasp
/// that matched an object, how far the object was tipped from upright
/// ([`Attempt::tilt_deg`]), else null.
pub fn episode_record(e: &Episode, setting: &str) -> serde_json::Value {
    let round = |v: f64, places: i32| (v * 10f64.powi(places)).round() / 10f64.powi(places);
    let attempts: Vec<serde_json::Value> = e
        .attempts
        .iter()
        .map(|a| {
            let outcome = a.outcome_name();
            let approach = a.world_from_grasp.rotation * Vector3::z();
            let down_deg = (-approach.z).clamp(-1.0, 1.0).asin().to_degrees();
            let (label, family) = a.label.map_or((None, None), |(l, f)| (Some(l), Some(f.name())));
            serde_json::json!([
                outcome,
                round(f64::from(a.quality), 3),
                round(a.width_m * 1e3, 1),
                round(down_deg, 1),
                round(a.plan_ms, 2),
                label,
                family,
                a.view.name(),
                a.pixel,
                round(a.centroid_lever_m * 1e3, 1),
                a.torque_nm.map(|t| round(f64::from(t), 3)),
                a.repairs.names(),
                a.tilt_deg.map(|t| round(f64::from(t), 1)),
            ])
        })
        .collect();
    serde_json::json!({
        "scenario": e.scenario.name(),
        "setting": setting,
        "seed": e.seed,
        "objects": e.objects,
        "removed": e.removed,
        "fell_off": e.fell_off,
        "end": e.end.name(),
        "attempts": attempts,
    })
}

/// Writes `rows` of one episode ([`ViewKeeping::rows`]) into `dir`, for
/// learning from physics outcomes (`sim eval --attempt-views`):
/// `attempts_SCENARIO_SEED.npy`, float32 `[n, size_px, size_px]`, each view
/// as the network read it, and `attempts_SCENARIO_SEED.json`, one record
/// per row: the frame's `step` (attempts before it), the grasp's `rank`
/// among those the planner offered there (0 best), `alternative` (false for
/// the episode's own attempt, true for one ranked below it), `view`, `pixel` `[u, v]` (the quality peak the grasp came from),
/// predicted `quality`, `width_mm`, `outcome` ("ok" or why not:
/// [`Attempt::outcome_name`]), analytic `label` and `family` (physics
/// trials only), the planner's `repairs` and the object's `tilt_deg`.
/// Returns the rows written.
pub fn write_attempt_views(
    dir: &Path,
    (scenario, seed): (Scenario, u64),
    rows: &[AttemptRow],
    size_px: usize,
) -> Result<usize> {
    let mut data = Vec::with_capacity(rows.len() * size_px * size_px);
    let mut records = Vec::with_capacity(rows.len());
    for row in rows {
        if row.view.len() != size_px * size_px {
            return Err(Error::Invalid {
                field: "attempt views",
                reason: format!("a view of {} pixels, not {size_px} x {size_px}", row.view.len()),
            });
        }
        data.extend_from_slice(row.view);
        let a = &row.attempt;
        let (label, family) = a.label.map_or((None, None), |(l, f)| (Some(l), Some(f.name())));
        records.push(serde_json::json!({
            "step": row.step,
            "rank": row.rank,
            "alternative": row.alternative,
            "view": a.view.name(),
            "pixel": a.pixel,
            "quality": a.quality,
            "width_mm": (a.width_m * 1e4).round() / 10.0,
            "outcome": a.outcome_name(),
            "label": label,
            "family": family,
            "repairs": a.repairs.names(),
            "tilt_deg": a.tilt_deg,
        }));
    }
    std::fs::create_dir_all(dir).map_err(|e| crate::dataset::file_error(dir, e))?;
    let stem = format!("attempts_{}_{}", scenario.name(), seed);
    crate::dataset::write_npy(
        &dir.join(format!("{stem}.npy")),
        &[records.len(), size_px, size_px],
        &data,
    )?;
    let path = dir.join(format!("{stem}.json"));
    let text = serde_json::to_string(&records).map_err(|e| Error::Scene(format!("{stem}: {e}")))?;
    std::fs::write(&path, text).map_err(|e| crate::dataset::file_error(&path, e))?;
    Ok(records.len())
}

/// A Markdown table of how the analytic labels fared in physics on the
/// grasps `episodes` tried: per label kind ([`GraspLabel::name`]), grasps
/// that held (reached the basket) of those tried, over every family and
/// per family. Collisions on approach and grasps that matched no object
/// never reach physics and are not counted. Empty without physics trials.
pub fn label_table(episodes: &[&Episode]) -> String {
    // (label, family) -> (held, tried); family None: every family.
    let mut counts: BTreeMap<(&str, Option<Family>), (usize, usize)> = BTreeMap::new();
    let mut families: Vec<Family> = Vec::new();
    for a in episodes.iter().flat_map(|e| &e.attempts) {
        let Some((label, family)) = a.label else { continue };
        if !families.contains(&family) {
            families.push(family);
        }
        for key in [(label, None), (label, Some(family))] {
            let c = counts.entry(key).or_insert((0, 0));
            c.0 += usize::from(a.failure.is_none());
            c.1 += 1;
        }
    }
    if counts.is_empty() {
        return String::new();
    }
    families.sort_by_key(|f| Family::ALL.iter().position(|x| x == f));
    let mut out = format!(
        "The tried grasps' analytic labels against physics (held / tried; the labels the network learns from, \
         on the planner's own grasps):\n\n| label | every family | {} |\n|---|---:|{}\n",
        families.iter().map(|f| f.name()).collect::<Vec<_>>().join(" | "),
        "---:|".repeat(families.len())
    );
    let labels: Vec<&str> = counts
        .keys()
        .filter(|(_, f)| f.is_none())
        .map(|(l, _)| *l)
        .collect();
    for label in labels {
        let cell = |family: Option<Family>| {
            let (held, tried) = counts.get(&(label, family)).copied().unwrap_or((0, 0));
            share(held, tried)
        };
        let per_family: Vec<String> = families.iter().map(|&f| cell(Some(f))).collect();
        out.push_str(&format!(
            "| {label} | {} | {} |\n",
            cell(None),
            per_family.join(" | ")
        ));
    }
    out
}

/// `n` of `of` as a table cell: "0.75 (3/4)", or "-" when `of` is 0.
pub(super) fn share(n: usize, of: usize) -> String {
    if of == 0 {
        "-".to_owned()
    } else {
        format!("{:.2} ({n}/{of})", n as f64 / of as f64)
    }
}

/// Upper edges (N m) of the torque bins of [`provenance_table`].
pub const TORQUE_BINS_NM: [f64; 5] = [0.05, 0.1, 0.2, 0.4, f64::INFINITY];
/// Upper edges (mm) of the lever bins of [`provenance_table`].
pub const LEVER_BINS_MM: [f64; 4] = [10.0, 20.0, 40.0, f64::INFINITY];

/// Markdown tables of where the tried grasps came from and how far from
/// their grip the weight acted: every attempt by the view its grasp came
/// from and by what the planner's hand check changed about it ([`Repairs`];
/// held, collisions on approach, slips during lift, other failures); then
/// the physics trials by the torque of the object's weight about the
/// closing line ([`TORQUE_BINS_NM`]) and by the lever the planner could see
/// ([`LEVER_BINS_MM`]), with the share that held and that slipped during
/// lift, and by family and the pose the object lay in ([`POSES`]: the share
/// that slipped). Empty without attempts.
pub fn provenance_table(episodes: &[&Episode]) -> String {
    let attempts: Vec<&Attempt> = episodes.iter().flat_map(|e| &e.attempts).collect();
    if attempts.is_empty() {
        return String::new();
    }
    let failed = |of: &[&Attempt], f: Option<Failure>| of.iter().filter(|a| a.failure == f).count();
    let row = |name: &str, of: &[&Attempt]| {
        let ok = failed(of, None);
        let collided = failed(of, Some(Failure::CollisionOnApproach));
        let slips = failed(of, Some(Failure::SlipDuringLift));
        format!(
            "| {name} | {} | {} | {collided} | {slips} | {} |\n",
            of.len(),
            share(ok, of.len()),
            of.len() - ok - collided - slips
        )
    };
    let header = "| attempts | held | collision on approach | slip during lift | other failures |\n\
                  |---|---:|---:|---:|---:|---:|\n";
    let mut out = format!("The attempts by the view their grasp came from:\n\n| view {header}");
    for view in ViewAxis::ALL {
        let of: Vec<&Attempt> = attempts.iter().copied().filter(|a| a.view == view).collect();
        out.push_str(&row(view.name(), &of));
    }
    out.push_str(&format!(
        "\nThe attempts by what the planner's hand check changed about their grasp (a grasp may count in \
         several rows):\n\n| repair {header}"
    ));
    let untouched: Vec<&Attempt> = attempts
        .iter()
        .copied()
        .filter(|a| a.repairs == Repairs::default())
        .collect();
    out.push_str(&row("none (as decoded)", &untouched));
    for name in Repairs::ALL_NAMES {
        let of: Vec<&Attempt> = attempts
            .iter()
            .copied()
            .filter(|a| a.repairs.names().contains(&name))
            .collect();
        out.push_str(&row(name, &of));
    }
    let trials: Vec<&Attempt> = attempts.into_iter().filter(|a| a.torque_nm.is_some()).collect();
    if trials.is_empty() {
        return out;
    }
    let mut binned = |title: &str, edges: &[f64], value: &dyn Fn(&Attempt) -> f64| {
        out.push_str(&format!(
            "\n| {title} | physics trials | held | slip during lift |\n|---|---:|---:|---:|\n"
        ));
        let mut lower = 0.0;
        for &upper in edges {
            let of: Vec<&Attempt> = trials
                .iter()
                .copied()
                .filter(|a| (lower..upper).contains(&value(a)))
                .collect();
            let bin = if upper.is_finite() {
                format!("{lower}-{upper}")
            } else {
                format!(">= {lower}")
            };
            out.push_str(&format!(
                "| {bin} | {} | {} | {} |\n",
                of.len(),
                share(failed(&of, None), of.len()),
                share(failed(&of, Some(Failure::SlipDuringLift)), of.len())
            ));
            lower = upper;
        }
    };
    binned(
        "torque of the weight about the closing line (N m)",
        &TORQUE_BINS_NM,
        &|a| a.torque_nm.map_or(f64::NAN, f64::from),
    );
    binned(
        "lever the planner saw: closing line to the segmented centroid (mm)",
        &LEVER_BINS_MM,
        &|a| a.centroid_lever_m * 1e3,
    );
    // Trials by family and by the pose the object lay in.
    let mut families: Vec<Family> = trials.iter().filter_map(|a| a.label.map(|(_, f)| f)).collect();
    families.sort_by_key(|f| Family::ALL.iter().position(|x| x == f));
    families.dedup();
    out.push_str(&format!(
        "\nThe physics trials by family and the pose the object lay in (slipped during lift / trials; \
         upright: tipped less than {} degrees from how the scene stood it, toppled: {0}-{} degrees, \
         upside down: more):\n\n| family | {} |\n|---|{}\n",
        POSES[0].1,
        POSES[1].1,
        POSES.map(|(name, _)| name).join(" | "),
        "---:|".repeat(POSES.len())
    ));
    for family in families {
        let cells: Vec<String> = POSES
            .iter()
            .map(|(pose, _)| {
                let of: Vec<&Attempt> = trials
                    .iter()
                    .copied()
                    .filter(|a| {
                        a.label.is_some_and(|(_, f)| f == family)
                            && a.tilt_deg.is_some_and(|t| pose_name(t) == *pose)
                    })
                    .collect();
                share(failed(&of, Some(Failure::SlipDuringLift)), of.len())
            })
            .collect();
        out.push_str(&format!("| {} | {} |\n", family.name(), cells.join(" | ")));
    }
    out
}

/// The paper's simulated results (success, removal) per scenario, for the report.
pub fn paper_numbers(scenario: Scenario) -> &'static str {
    match scenario {
        Scenario::Isolated => "0.926 success",
        Scenario::Packed => "0.84 / 0.88 (tau 0.8)",
        Scenario::Pile => "0.75 / 0.89 (tau 0.8)",
        Scenario::Clutter => "removal >= 0.90 (real robot: 9 of 10 runs cleared)",
    }
}

/// A Markdown list of where the collisions on approach of `summaries`
/// happened, most frequent first (empty when there were none).
pub fn collision_list(summaries: &[Summary]) -> String {
    let mut out = String::new();
    for s in summaries.iter().filter(|s| !s.collisions.is_empty()) {
        let mut sites: Vec<(&CollisionSite, &usize)> = s.collisions.iter().collect();
        sites.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
        let sites: Vec<String> = sites.iter().map(|(k, n)| format!("{} {n}", k.name())).collect();
        out.push_str(&format!(
            "- {}, {}: {}\n",
            s.scenario.name(),
            s.setting,
            sites.join("; ")
        ));
    }
    if out.is_empty() {
        out
    } else {
        format!(
            "Collisions on approach, by what the hand hit (pads or palm; \"closing\": a pad met a neighbour \
             before the object) and where (at the grasp pose, or 2.5-10 cm back on the way in):\n\n{out}"
        )
    }
}

/// The Markdown table of `summaries`.
pub fn markdown_table(summaries: &[Summary]) -> String {
    let mut out = String::from(
        "| scenario | setting | episodes | success | removal | attempts | cleared | no grasp > tau | collision on approach | slip during lift | width too small | object missed | plan p50 / p90 (ms) | paper | 95% intervals: success; removal |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|\n",
    );
    let interval = |ci: [f64; 2]| {
        if ci.iter().all(|v| v.is_finite()) {
            format!("{:.2}-{:.2}", ci[0], ci[1])
        } else {
            "-".to_owned()
        }
    };
    for s in summaries {
        out.push_str(&format!(
            "| {} | {} | {} | {:.2} ({}/{}) | {:.2} ({}/{}) | {} | {} | {} | {} | {} | {} | {} | {:.0} / {:.0} | {} | {}; {} |\n",
            s.scenario.name(),
            s.setting,
            s.episodes,
            s.success_rate(),
            s.successes,
            s.attempts,
            s.removal_rate(),
            s.removed,
            s.objects,
            s.attempts,
            s.cleared,
            s.ended_without_grasp,
            s.failures[0],
            s.failures[1],
            s.failures[2],
            s.failures[3],
            s.plan_ms[0],
            s.plan_ms[1],
            paper_numbers(s.scenario),
            interval(s.success_ci95),
            interval(s.removal_ci95),
        ));
    }
    out
}
