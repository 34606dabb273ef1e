"""How repeatable the labels are: two `sim datagen` runs of the same scenes.

`sim datagen --label-salt S` draws the sensor noise and the label annealing
again for the same scenes and cameras; `--without-neighbours` labels each
object as if it stood alone (the same views). Labelling a run twice gives
two label sets for the same objects; this module pairs their views and
asks how well one set predicts the other with the accuracy metric:

* **oracle**: each A view's best positive (highest quality), judged against
  B's positives of the same view. A network that reproduced label set A
  exactly would score this against B; the network is judged against one
  draw, so this is a ceiling that a perfect network does not pass on average.
* **any positive**: the mean over A's positives, judged the same way.
* how often one draw finds positives in a view where the other finds none.

Views are paired by (instance, view axis) when that key is unique in both
runs (two detections of one object are left out). With noise, the object's
frame can turn between runs (its axes come from noisy points), so B's view
is matched onto A's by the square symmetry that fits best, and B's grasps
are moved with it. Pairs whose silhouettes still differ (IoU below
`min_iou`, 0.5: a wrong match, as noise alone leaves a median of 0.91) are
counted and left out.

    python3 -m mvgrasp_train.repeatability --a RUN_A --b RUN_B [--model M.onnx] [--json OUT]
"""

import argparse
import json
import sys

import numpy as np

from . import dataset, metric

# Generator settings that must agree between the two runs: the same scenes and
# cameras; they may differ in `label_salt` (another draw) and `neighbours`.
SAME_GENERATOR = ("scenes", "first_seed", "scenarios", "families", "noise", "stride_px", "angles",
                  "anneal_steps")
VARIED = ("label_salt", "neighbours")


def check_pair(a, b):
    """Refuses runs that are not the same scenes labelled twice."""
    for key in ("contract", "gripper", "data_version", "format_version"):
        if a.manifest.get(key) != b.manifest.get(key):
            raise ValueError(f"the runs differ in {key}")
    ga, gb = a.manifest.get("generator", {}), b.manifest.get("generator", {})
    for key in SAME_GENERATOR:
        if ga.get(key) != gb.get(key):
            raise ValueError(f"the runs differ in generator.{key}: {ga.get(key)} vs {gb.get(key)}")
    defaults = {"label_salt": 0, "neighbours": True}
    if all(ga.get(k, defaults[k]) == gb.get(k, defaults[k]) for k in VARIED):
        raise ValueError("the runs have the same label_salt and neighbours: the same labels")


def pair_views(a, b, families=None):
    """[(index in a, index in b)] for (instance, view) keys unique in both; and how many were not."""
    def keys(ds):
        seen = {}
        for i, m in enumerate(ds.meta):
            if families is None or m["family"] in families:
                seen.setdefault((m["instance"], m["view"]), []).append(i)
        return seen
    ka, kb = keys(a), keys(b)
    pairs = [(ia[0], kb[k][0]) for k, ia in ka.items() if len(ia) == 1 and len(kb.get(k, [])) == 1]
    return sorted(pairs), len(set(ka) | set(kb)) - len(pairs)


def symmetry_of_image(image, k):
    """The k-th square symmetry of a [L, L] image, in `augment.symmetry`'s order."""
    if k & 1:
        image = image[:, ::-1]
    if k & 2:
        image = image[::-1, :]
    if k & 4:
        image = image.T
    return image


def move_grasps(grasps, k, l):
    """Grasp rows (u, v, phi, ...) under the k-th symmetry of an L x L view, as `augment.symmetry` moves maps."""
    g = np.array(grasps, dtype=np.float64, copy=True)
    if k & 1:
        g[:, 0], g[:, 2] = l - 1 - g[:, 0], -g[:, 2]
    if k & 2:
        g[:, 1], g[:, 2] = l - 1 - g[:, 1], -g[:, 2]
    if k & 4:
        g[:, [0, 1]] = g[:, [1, 0]]
        g[:, 2] = np.pi / 2 - g[:, 2]
    g[:, 2] = np.mod(g[:, 2] + np.pi / 2, np.pi) - np.pi / 2
    return g


def silhouette_iou(x, y):
    x, y = x > 0, y > 0
    union = (x | y).sum()
    return float((x & y).sum() / union) if union else 1.0


def align(view_a, view_b):
    """(k, IoU): the symmetry of B's view that best matches A's, and the silhouettes' IoU after it."""
    scores = []
    for k in range(8):
        turned = symmetry_of_image(view_b, k)
        # Best IoU, then the closest depths, then the plainest symmetry.
        scores.append((silhouette_iou(view_a, turned), -np.abs(view_a - turned).mean(), -k))
    iou, _, minus_k = max(scores)
    return -minus_k, iou


def compare(a, b, pairs, min_iou=0.5):
    """Label agreement of runs `a` and `b` over `pairs` (see the module doc)."""
    c = a.contract
    l, pixel_m = c["input_size_px"], c["pixel_size_m"]
    pad_m = a.manifest["gripper"]["pad_width_m"]
    counts = {"pairs": len(pairs), "turned": 0, "misaligned": 0, "both": 0, "only_a": 0, "only_b": 0,
              "neither": 0}
    oracle, any_positive, kept, groups = [], [], [], []
    for ia, ib in pairs:
        k, iou = align(a.views[ia, 0], b.views[ib, 0])
        if iou < min_iou:
            counts["misaligned"] += 1
            continue
        counts["turned"] += int(k != 0)
        ta, tb = a.grasps_of(ia), b.grasps_of(ib)
        has_a, has_b = len(ta) > 0, len(tb) > 0
        counts[{(True, True): "both", (True, False): "only_a", (False, True): "only_b",
                (False, False): "neither"}[(has_a, has_b)]] += 1
        kept.append((ia, ib, k))
        if not (has_a and has_b):
            continue
        tb = move_grasps(tb, k, l)
        hits = [metric.grasp_correct((g[0], g[1], g[2], g[3]), tb, pixel_m, pad_m) for g in ta]
        oracle.append(hits[int(np.argmax(ta[:, 4]))])
        any_positive.append(float(np.mean(hits)))
        groups.append((a.meta[ia].get("scenario", "?"), a.meta[ia].get("view", "?")))
    with_a = counts["both"] + counts["only_a"]
    return {
        **counts,
        "oracle_accuracy": float(np.mean(oracle)) if oracle else float("nan"),
        "any_positive_accuracy": float(np.mean(any_positive)) if any_positive else float("nan"),
        "b_empty_where_a_has_positives": counts["only_a"] / with_a if with_a else float("nan"),
        "oracle_per_scenario": metric.accuracy_by(oracle, [g[0] for g in groups]),
        "oracle_per_view": metric.accuracy_by(oracle, [g[1] for g in groups]),
        "min_iou": min_iou,
        "kept": kept,
    }


def model_accuracy(model, a, b, kept):
    """The network's accuracy on each run's own views and labels, over the kept pairs with positives in both."""
    from . import evaluate_onnx
    both = [(ia, ib) for ia, ib, _ in kept if len(a.grasps_of(ia)) and len(b.grasps_of(ib))]
    out = {}
    for name, ds, idx in (("a", a, [p[0] for p in both]), ("b", b, [p[1] for p in both])):
        pred = evaluate_onnx.predict(model, np.asarray(ds.views[idx]))
        out[name] = metric.evaluate(pred, ds, idx)["accuracy"]
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--a", required=True, help="one sim datagen run")
    p.add_argument("--b", required=True, help="the same scenes with another --label-salt, or --without-neighbours")
    p.add_argument("--hold-out-families", default="bowl",
                   help="families left out, comma-separated (default bowl, as in training)")
    p.add_argument("--min-iou", type=float, default=0.5,
                   help="silhouette IoU below which a pair is left out (noise alone leaves a median of 0.91)")
    p.add_argument("--model", help="also score this ONNX model on both runs (needs onnxruntime)")
    p.add_argument("--json", help="write the result here")
    args = p.parse_args(argv)
    a, b = dataset.load(args.a, mmap=True), dataset.load(args.b, mmap=True)
    check_pair(a, b)
    left_out = {f for f in args.hold_out_families.split(",") if f}
    families = {m["family"] for m in a.meta} - left_out
    pairs, unpaired = pair_views(a, b, families)
    result = compare(a, b, pairs, args.min_iou)
    result["unpaired"] = unpaired
    if args.model:
        result["model"] = {"path": args.model, **model_accuracy(args.model, a, b, result["kept"])}
    del result["kept"]
    print(f"{result['pairs']} paired views ({unpaired} keys not unique in both), "
          f"{result['misaligned']} left out (silhouette IoU < {args.min_iou}), {result['turned']} turned")
    print(f"positives in both {result['both']}, only A {result['only_a']}, only B {result['only_b']}, "
          f"neither {result['neither']}")
    print(f"oracle (A's best positive judged against B): {100 * result['oracle_accuracy']:.1f}%")
    print(f"any A positive judged against B:             {100 * result['any_positive_accuracy']:.1f}%")
    for group in ("scenario", "view"):
        print(f"oracle per {group}: " + ", ".join(f"{name} {100 * r['accuracy']:.1f}% of {r['views']}"
                                                for name, r in result[f"oracle_per_{group}"].items()))
    if args.model:
        print(f"{args.model} on A: {100 * result['model']['a']:.1f}%, on B: {100 * result['model']['b']:.1f}%")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
