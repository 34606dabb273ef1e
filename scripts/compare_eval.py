#!/usr/bin/env python3
"""Side-by-side totals of `sim eval` runs on the same seeds: the A/B we run
on the tuning seeds before a model or planner change lands.

    python3 scripts/compare_eval.py RUN_A RUN_B ...     # folders or eval.json files

For each run, summed over the settings it ran: objects removed, attempts,
success per attempt and the failure causes, per scenario and in all; then
how often the tried grasps held, by their analytic label (the table
`eval.md` prints per family), and the share the labeller calls positive;
then each episode's first attempt, whose frame is the same for every run
on these seeds (a paired comparison; later frames depend on what earlier
attempts did): how many the labeller calls positive and how many held;
then, for runs since 2026-11-25 (whose attempts record the object's tilt),
the slips during lift by family and by the pose the object lay in; and
for runs made with `--judge`, the judged models on the same states: each
one's held grasps, and against the first judged model the states only it
held and only the first held, with a two-sided sign test on those; last, each run's episodes
paired with the first run's (same scenario, seed and setting): objects
removed per episode, run minus first, summed with a 95% bootstrap
interval over episodes and a sign test on the episodes that differ.
The first run is the reference; the others show their difference to it.

    python3 scripts/compare_eval.py --paired A1:B1 [A2:B2 ...]

pools the paired episodes of several seed sets (A runs of one model, B of
the other) into one such comparison, per scenario and in all: how a
default change is judged (docs/experiments/2026-11-26-default-since-11-26.md, "The default since
2026-11-26"). Standard library only (the sign test comes from the training
package's `mvgrasp_train/stats.py`, itself standard library).
"""

import json
import os
import random
import sys
from collections import Counter

# The sign test lives in the training package (a standard-library module there).
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "training"))
from mvgrasp_train.stats import sign_test  # noqa: E402

COUNTS = ("removed", "objects", "attempts")


def load(path):
    if os.path.isdir(path):
        path = os.path.join(path, "eval.json")
    with open(path) as f:
        return json.load(f)


def totals(run):
    """{scenario: Counter} of removed / objects / attempts and each failure
    cause, summed over settings; "all" sums the scenarios."""
    out = {}
    for s in run["summaries"]:
        c = out.setdefault(s["scenario"], Counter())
        for key in COUNTS:
            c[key] += s[key]
        for cause, n in s["failures"].items():
            c[cause] += n
    out["all"] = sum(out.values(), Counter())
    return out


def held_by_label(run):
    """{label: (held, tried)} over every attempt that reached the physics
    trial: those with a label (`eval.json` records none for a collision on
    approach or a grasp that matched no object), as `eval.md`'s label table
    (`eval::label_table`) counts them."""
    tried, held = Counter(), Counter()
    for episode in run.get("episodes", []):
        for attempt in episode["attempts"]:
            outcome, label = attempt[0], attempt[5]
            if label is None:
                continue
            tried[label] += 1
            held[label] += outcome == "ok"
    return {label: (held[label], tried[label]) for label in tried}


def first_attempts(run):
    """(episodes with an attempt, first attempts labelled positive, first
    attempts that held). An episode's first frame depends only on the seed,
    scenario and episode, not on the planner, so runs on the same seeds are
    compared here on the same frames."""
    firsts = [e["attempts"][0] for e in run.get("episodes", []) if e["attempts"]]
    return len(firsts), sum(a[5] == "positive" for a in firsts), sum(a[0] == "ok" for a in firsts)


# Tilt from upright (degrees) under which an object counts as upright, then
# as toppled; above, upside down. As `sim eval`'s `eval::POSES`.
POSES = (("upright", 30.0), ("toppled", 150.0), ("upside down", float("inf")))
# Index of the tilt in an attempt record (`eval::episode_record`).
TILT = 12


def pose_of(tilt_deg):
    return next(name for name, below in POSES if tilt_deg < below)


def slips_by_pose(run):
    """{(family, pose): (slipped during lift, physics trials)} over the
    attempts that reached the physics trial and record their object's tilt
    (runs before 2026-11-25 record none: empty)."""
    slipped, trials = Counter(), Counter()
    for episode in run.get("episodes", []):
        for attempt in episode["attempts"]:
            if len(attempt) <= TILT or attempt[5] is None or attempt[TILT] is None:
                continue
            key = (attempt[6], pose_of(attempt[TILT]))
            trials[key] += 1
            slipped[key] += attempt[0] == "slip during lift"
    return {key: (slipped[key], trials[key]) for key in trials}


def judged_pairs(run):
    """For a run with `--judge`: per judged model (its name, held, states
    judged, states only it held, states only the first model held, and the
    sign test's p on those two), over every judged state."""
    models = run.get("judged_models", [])
    frames = run.get("judged_frames", [])
    if not models or not frames:
        return []
    held = [[f["outcomes"][m] == "held" for f in frames] for m in range(len(models))]
    rows = []
    for m, name in enumerate(models):
        only_it = sum(x and not y for x, y in zip(held[m], held[0]))
        only_first = sum(y and not x for x, y in zip(held[m], held[0]))
        rows.append((name, sum(held[m]), len(frames), only_it, only_first, sign_test(only_it, only_first)))
    return rows


# Bootstrap draws and the generator's seed for the paired interval: fixed, so
# a report is the same each time it is made.
BOOTSTRAP_DRAWS = 4000
BOOTSTRAP_SEED = 1


def paired_episodes(run_a, run_b):
    """{(scenario, seed, setting): (removed by A, removed by B, objects)}
    over the episodes both runs hold. Raises ValueError where a pair's
    object counts differ: the runs did not see the same scenes."""
    def by_key(run):
        return {(e["scenario"], e["seed"], e["setting"]): e for e in run.get("episodes", [])
                if "seed" in e and "setting" in e}
    a, b = by_key(run_a), by_key(run_b)
    pairs = {}
    for key in sorted(set(a) & set(b)):
        if a[key]["objects"] != b[key]["objects"]:
            raise ValueError(f"episode {key}: {a[key]['objects']} objects against {b[key]['objects']}: "
                             "not the same scene (different seeds or simulator revisions?)")
        pairs[key] = (a[key]["removed"], b[key]["removed"], a[key]["objects"])
    return pairs


def paired_summary(diffs, draws=BOOTSTRAP_DRAWS, seed=BOOTSTRAP_SEED):
    """For per-episode differences (B minus A): (episodes, total difference,
    2.5% and 97.5% points of the total over `draws` bootstrap resamples of
    the episodes, episodes better, episodes worse, sign test p)."""
    diffs = list(diffs)
    better, worse = sum(d > 0 for d in diffs), sum(d < 0 for d in diffs)
    if not diffs:
        return 0, 0, 0, 0, 0, 0, 1.0
    rng = random.Random(seed)
    totals_ = sorted(sum(rng.choice(diffs) for _ in diffs) for _ in range(draws))
    lo, hi = totals_[int(0.025 * draws)], totals_[int(0.975 * draws) - 1]
    return len(diffs), sum(diffs), lo, hi, better, worse, sign_test(better, worse)


def paired_lines(pairs):
    """Report lines per scenario and in all for {key: (removed A, removed B,
    objects)} (keys start with the scenario)."""
    lines = []
    scenarios = sorted({key[0] for key in pairs}) + ["all"]
    for scenario in scenarios:
        chosen = [v for k, v in pairs.items() if scenario in ("all", k[0])]
        n, total, lo, hi, better, worse, p = paired_summary(b - a for a, b, _ in chosen)
        objects = sum(o for _, _, o in chosen)
        removed_a, removed_b = sum(a for a, _, _ in chosen), sum(b for _, b, _ in chosen)
        lines.append(f"  {scenario:10s} {n:4d} episodes, {objects:5d} objects: removed {removed_a} "
                     f"({removed_a / objects:.3f}) against {removed_b} ({removed_b / objects:.3f}), "
                     f"{total:+d} (95% bootstrap {lo:+d} to {hi:+d}); episodes better {better} / "
                     f"worse {worse}, sign test p = {p:.3g}")
    return lines


def report_paired(pair_paths):
    """The pooled paired comparison of `--paired A:B ...`."""
    pooled, lines = {}, []
    for i, (a_path, b_path) in enumerate(pair_paths):
        pairs = paired_episodes(load(a_path), load(b_path))
        if not pairs:
            raise ValueError(f"{a_path} and {b_path} share no episode (same seeds and settings?)")
        lines.append(f"{a_path} : {b_path}")
        lines += paired_lines(pairs)
        pooled.update({(k[0], i) + k[1:]: v for k, v in pairs.items()})
    if len(pair_paths) > 1:
        lines.append(f"pooled over {len(pair_paths)} pairs of runs")
        lines += paired_lines(pooled)
    return "\n".join(lines)


def per_attempt(c):
    return c["removed"] / c["attempts"] if c["attempts"] else float("nan")


def report(paths):
    return report_runs([load(p) for p in paths], [os.path.basename(os.path.normpath(p)) for p in paths])


def report_runs(runs, names):
    tables = [totals(r) for r in runs]
    seeds = {r["command"][r["command"].index("--seed") + 1] if "--seed" in r["command"] else "?" for r in runs}
    lines = [f"seeds: {', '.join(sorted(seeds))}" + ("  (runs on different seeds: not comparable)" if len(seeds) > 1 else "")]
    scenarios = [s for s in tables[0] if s != "all"] + ["all"]
    causes = sorted({k for t in tables for c in t.values() for k in c if k not in COUNTS})
    for scenario in scenarios:
        lines.append(f"\n{scenario}")
        ref = tables[0].get(scenario, Counter())
        for name, table in zip(names, tables):
            c = table.get(scenario, Counter())
            row = f"  {name:24s} removed {c['removed']:5d} of {c['objects']:5d}  attempts {c['attempts']:5d}  per attempt {per_attempt(c):.3f}"
            if c is not ref:
                row += f"  (removed {c['removed'] - ref['removed']:+d})"
            row += "  " + ", ".join(f"{cause} {c[cause]}" for cause in causes)
            lines.append(row)
    lines.append("\ntried grasps held, by label (held / tried)")
    for name, run in zip(names, runs):
        held = held_by_label(run)
        cells = ", ".join(f"{label} {h}/{n} ({h / n:.3f})" for label, (h, n) in sorted(held.items()))
        tried = sum(n for _, n in held.values())
        positive = held.get("positive", (0, 0))[1]
        share = f"; labelled positive {positive}/{tried} ({positive / tried:.3f})" if tried else ""
        lines.append(f"  {name:24s} {cells}{share}")
    lines.append("\nfirst attempts, on the same frames for every run (labelled positive / held, of episodes)")
    for name, run in zip(names, runs):
        n, positive, held = first_attempts(run)
        if n:
            lines.append(f"  {name:24s} {n} episodes: labelled positive {positive} ({positive / n:.3f}), "
                         f"held {held} ({held / n:.3f})")
    poses = [slips_by_pose(run) for run in runs]
    keys = sorted({key for p in poses for key in p})
    if keys:
        lines.append("\nslips during lift by family and pose (slipped / physics trials; "
                     "upright: tipped < 30 degrees, toppled: < 150, else upside down)")
        for name, p in zip(names, poses):
            cells = ", ".join(f"{family} {pose} {p[(family, pose)][0]}/{p[(family, pose)][1]}"
                              for family, pose in keys if (family, pose) in p)
            lines.append(f"  {name:24s} {cells if cells else '(no tilt recorded)'}")
    for name, run in zip(names, runs):
        rows = judged_pairs(run)
        if rows:
            lines.append(f"\n{name}: judged models on the same states (held; against the first: "
                         "states only it held / only the first held, sign test)")
            for model, held, n, only_it, only_first, p in rows:
                versus = "" if model == rows[0][0] else f"  {only_it} / {only_first}, p = {p:.3g}"
                lines.append(f"  {model:36s} held {held}/{n} ({held / n:.3f}){versus}")
    for name, run in zip(names[1:], runs[1:]):
        pairs = paired_episodes(runs[0], run)
        if pairs:
            lines.append(f"\npaired episodes, {name} against {names[0]} (objects removed per episode, "
                         f"{name} minus {names[0]})")
            lines += paired_lines(pairs)
    return "\n".join(lines)


def main(argv):
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__)
        return 0 if argv else 2
    try:
        if argv[0] == "--paired":
            pairs = [arg.split(":") for arg in argv[1:]]
            if not pairs or any(len(p) != 2 for p in pairs):
                print("--paired takes RUN_A:RUN_B arguments", file=sys.stderr)
                return 2
            print(report_paired(pairs))
        else:
            print(report(argv))
    except (OSError, ValueError, KeyError) as e:
        print(f"compare_eval: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
