"""Held-out grasp accuracy of ONNX models on one dataset, side by side.

    python3 -m mvgrasp_train.evaluate_onnx --data DATASET MODEL.onnx [MODEL.onnx ...] \
        [--hold-out-families bowl] [--scenarios isolated,packed] [--families mug] [--all-views | --training-views] \
        [--misses MISSES.png [--misses-count 6]] [--smoothing-sigma-px 1.0] [--flips [four|mirror]] [--object-threshold 0.1] \
        [--angle-limit-deg 30] [--min-step 1]

Runs each model through onnxruntime (CPU) on the held-out instances of
DATASET (the 80/20 split by instance of dataset.py) and prints the paper's
accuracy (metric.py) overall, per view direction, per scenario and per
family, for the seen families and, apart, for the families named by
--hold-out-families. `--misses` draws the first model's first missed views
(view, target quality, predicted quality; the chosen grasp and the
positives marked). `--smoothing-sigma-px` blurs the predicted quality
before the argmax as the planner does before its peak search (its default
is 1.0 px; `metric.smooth_quality`); the default, 0, is the paper's metric
on the network's raw output. `--flips` averages each view's maps with
those of its three flips, flipped back (`flip_average`): test-time
augmentation at four times the inference, which the planner does not do.
`--flips mirror` averages each view with its left-right mirror only (two
passes), the flips that keep the table below a front or side view, for
networks trained with `train --symmetries gravity`.
Use it to compare models trained on different data on the same views: a
model never saw the instances of another dataset made with other seeds, so
on a dataset generated with seeds no model trained on, `--all-views` counts
every view, not only the 20% held-out share. `--training-views` scores the
80% a model trained on instead (the split is the same for every dataset), to
see how far a network fits its own training views.

Each model after the first is paired with the first on the same views:
the views only it got right and those only the first got right, with an
exact two-sided sign test on those (`metric.paired_views`).

It also judges objects as the planner's `all` view policy acts on them
(`metric.object_picks`): the best grasp over each object's views, tried
when its quality clears `--object-threshold` (the planner's min_quality,
0.1). A model can gain views and lose objects: a quality that rises on a
view whose labels refuse every grasp beats the object's good view.

`--angle-limit-deg` replaces the paper's 30-degree angle tolerance, which
passes grasps far enough off a box's faces to slip. At 7.5 degrees the
objects line on 8-angle labels ranked ten models more like one physics
seed (Spearman +0.61 against +0.18); on 16-angle labels the limit changes
nothing, as every angle is within 5.6 degrees of a labelled one
(docs/experiments/2026-11-25-where-the-slips-are.md, "Where the slips are").

On frames that `sim eval --label-frames` labelled, each view's `step` is the
attempts made in its episode before it; `--min-step 1` keeps the frames
that earlier attempts disturbed (views without a step count as step 0).
"""

import argparse
import json
import sys

import numpy as np

from . import dataset, metric


FLIP_SETS = {
    # (up-down, left-right) per pass
    "four": ((False, False), (False, True), (True, False), (True, True)),
    "mirror": ((False, False), (False, True)),
}


def predict(path, views, batch=256, sigma_px=0.0, flips=None):
    import onnxruntime
    session = onnxruntime.InferenceSession(path, providers=["CPUExecutionProvider"])

    def run(v):
        return np.concatenate([session.run(["maps"], {"views": np.ascontiguousarray(v[i:i + batch])})[0]
                               for i in range(0, len(v), batch)])

    out = flip_average(run, views, flips) if flips else run(views)
    return metric.smooth_quality(out, sigma_px)


def flip_average(run, views, flips="four"):
    """The maps `run` gives for `views` averaged over each view and its three
    flips (left-right, up-down, both), every map flipped back; with `flips`
    "mirror", over each view and its left-right mirror only. A single flip
    mirrors the grasp angle, phi -> -phi, so its sin 2phi changes sign; the
    double flip (a half turn) keeps it. Costs a pass per flip."""
    total, passes = None, FLIP_SETS[flips]
    for flip_y, flip_x in passes:
        axes = tuple(a for a, f in ((2, flip_y), (3, flip_x)) if f)
        maps = np.array(run(np.ascontiguousarray(np.flip(views, axes))), np.float32)
        maps = np.flip(maps, axes).copy()
        if flip_y != flip_x:
            maps[:, 2] *= -1.0
        total = maps if total is None else total + maps
    return total / float(len(passes))


def scored_views(meta, all_views=False, training_views=False):
    """Indices of the views to score: the held-out split (by instance, as
    training splits), every view, or the training split."""
    if all_views and training_views:
        raise SystemExit("--all-views and --training-views exclude each other")
    if all_views:
        return list(range(len(meta)))
    trained, held = dataset.split_by_instance(meta)
    return trained if training_views else held


def view_filter(meta, scenarios=(), families=(), min_step=0):
    """Whether view i is kept: of one of `scenarios` and `families` (empty:
    any), and of an episode frame after at least `min_step` attempts (views
    without a `step`, `sim datagen`'s, count as step 0)."""
    def wanted(i):
        m = meta[i]
        return ((not scenarios or m.get("scenario") in scenarios) and (not families or m["family"] in families)
                and m.get("step", 0) >= min_step)
    return wanted


def rounded(x):
    """Two decimals, or "-" for a median of no views (None)."""
    return "-" if x is None else f"{x:.2f}"


def report(pred, ds, indices, object_threshold=0.1, angle_limit_deg=metric.ANGLE_LIMIT_DEG, judged=None):
    return metric.evaluate(pred, ds, indices, by=("scenario", "family"), object_threshold=object_threshold,
                           angle_limit_deg=angle_limit_deg, judged=judged)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("models", nargs="+")
    p.add_argument("--data", required=True)
    p.add_argument("--hold-out-families", default="bowl")
    p.add_argument("--scenarios", default="", help="only views of these scenarios (comma-separated)")
    p.add_argument("--all-views", action="store_true",
                   help="every view, not the held-out split (for data made with seeds no model trained on)")
    p.add_argument("--training-views", action="store_true",
                   help="the training split instead of the held-out one: how well a model fits what it trained on")
    p.add_argument("--families", default="", help="only views of these families (comma-separated)")
    p.add_argument("--misses", help="draw the first model's first missed views of seen families here (PNG; "
                                    "needs matplotlib)")
    p.add_argument("--misses-count", type=int, default=6)
    p.add_argument("--smoothing-sigma-px", type=float, default=0.0,
                   help="blur the predicted quality before the argmax, as the planner does (its default: 1.0)")
    p.add_argument("--object-threshold", type=float, default=0.1,
                   help="the quality an object's best grasp must reach to be tried (the planner's min_quality)")
    p.add_argument("--angle-limit-deg", type=float, default=metric.ANGLE_LIMIT_DEG,
                   help="a prediction matches a positive within this angle (the paper's: 30)")
    p.add_argument("--min-step", type=int, default=0,
                   help="only views of episode frames after this many attempts (sim eval --label-frames)")
    p.add_argument("--flips", nargs="?", const="four", choices=sorted(FLIP_SETS),
                   help="average each view's maps with its three flips' (four, 4 passes) or its left-right "
                        "mirror's (mirror, 2 passes); the planner does one pass")
    args = p.parse_args(argv)
    ds = dataset.load(args.data, mmap=True)
    held = scored_views(ds.meta, args.all_views, args.training_views)
    wanted = view_filter(ds.meta, {s for s in args.scenarios.split(",") if s},
                         {f for f in args.families.split(",") if f}, args.min_step)
    held = [i for i in held if wanted(i)]
    unseen = {f for f in args.hold_out_families.split(",") if f}
    # Every view of an unseen family counts, not only its held-out share: no model trained on them.
    families = [i for i, m in enumerate(ds.meta) if m["family"] in unseen and wanted(i)]
    seen = [i for i in held if ds.meta[i]["family"] not in unseen]
    results = {}
    for n, path in enumerate(args.models):
        pred = predict(path, ds.views[seen], sigma_px=args.smoothing_sigma_px, flips=args.flips)
        judged = metric.hits(pred, ds, seen, args.angle_limit_deg)
        results[path] = {"seen_families": report(pred, ds, seen, args.object_threshold, args.angle_limit_deg, judged)}
        ok = judged[0]
        if n == 0:
            first_ok = ok
        else:
            only_it, only_first, p_value = metric.paired_views(first_ok, ok)
            results[path]["seen_families"]["paired_against_first"] = {
                "first": args.models[0], "only_this_right": only_it, "only_first_right": only_first,
                "sign_test_p": p_value}
        if args.misses and n == 0:
            from . import plot
            picked = metric.misses(pred, ds, seen, ok=ok)[:args.misses_count]
            plot.draw_views(args.misses, ds, [seen[k] for k in picked], pred[picked],
                            f"{path}: first {len(picked)} missed views")
        if families:
            results[path]["unseen_families"] = report(
                predict(path, ds.views[families], sigma_px=args.smoothing_sigma_px, flips=args.flips), ds, families,
                args.object_threshold, args.angle_limit_deg)
    print(json.dumps(results, indent=1))
    print(f"{'model':<40} {'seen':>7} {'top':>6} {'front':>6} {'side':>6} {'unseen':>7}", file=sys.stderr)
    for path, r in results.items():
        s = r["seen_families"]
        v = s["per_view"]
        u = r.get("unseen_families", {}).get("accuracy", float("nan"))
        print(f"{path:<40} {100 * s['accuracy']:6.1f}% "
              + " ".join(f"{100 * v.get(a, {}).get('accuracy', float('nan')):5.1f}%" for a in ("top", "front", "side"))
              + f" {100 * u:6.1f}%", file=sys.stderr)
    for path, r in results.items():
        q = r["seen_families"].get("paired_against_first")
        if q:
            print(f"{path}: views (seen families) only it got right / only {q['first']} got right: "
                  f"{q['only_this_right']} / {q['only_first_right']}, sign test p = {q['sign_test_p']:.2g}",
                  file=sys.stderr)
    for path, r in results.items():
        o = r["seen_families"]["objects"]
        print(f"{path}: objects (the `all` policy, best grasp over each object's views): "
              f"{100 * o['accuracy']:.1f}% of {o['objects_with_positives']} right, {100 * o['picked']:.1f}% right "
              f"at quality >= {o['threshold']}; {o['attempts']} attempts, {100 * o['attempt_precision']:.1f}% right; "
              f"{100 * o['false_alarm_rate']:.1f}% of {o['objects_without_positives']} objects without positives "
              f"tried; {o['wrong_view']} won by a view without positives, {o['another_view_right']} missed with "
              f"another view right; median peak of views without positives "
              f"{rounded(r['seen_families']['median_peak_without_positives'])} "
              f"(with: {rounded(r['seen_families']['median_peak_with_positives'])})", file=sys.stderr)
        c = r["seen_families"]["scenes"]
        print(f"{path}: scenes' first picks (the best grasp over every view of a scene): {100 * c['accuracy']:.1f}% "
              f"of {c['objects_with_positives']} right", file=sys.stderr)
    for path, r in results.items():
        m = r["seen_families"]["misses"]
        n = max(m["views_with_positives"], 1)
        print(f"{path}: missed {100 * m['missed_far'] / n:.1f}% with the best pixel > 2 px from every positive, "
              f"{100 * m['missed_heads'] / n:.1f}% on one with the angle or opening off; median positives per "
              f"view hit {m['median_positives_hit']}, missed {m['median_positives_missed']}", file=sys.stderr)


if __name__ == "__main__":
    main()
