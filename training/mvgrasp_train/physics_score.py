"""How well models' quality at the planner's tried grasps predicts physics.

    python3 -m mvgrasp_train.physics_score --attempts DIR[,DIR] MODEL.onnx [MODEL.onnx ...] \
        [--own-only] [--sigma-px 1] [--json OUT.json]

Reads `sim eval --attempt-views` folders (`physics.load`: held 1, failed 0
for the failures the network can be blamed for) and runs each model
through onnxruntime (CPU) on the attempts' views. A model's score for an
attempt is its quality at the attempt's pixel, smoothed as the planner
smooths it before its peak search (`metric.smooth_quality`, sigma 1 px by
default), exactly what `train --physics` pulls towards the outcome. Per
model it prints:

- AUC: the chance that a held attempt scores above a failed one (ties
  count half). 0.5 is a coin; it says how well the quality ranks grasps.
- Brier score: the mean squared error between score and outcome (what
  `train --physics` minimises); it also punishes a quality that ranks
  well but does not read as a chance of success.
- calibration: per quality bin, the attempts, their mean quality and the
  share that held.

The attempts are other grasps than a new model would pick: this scores a
model on grasps it did not choose (the tried pixel, not its own peak), so
it compares models on the same grasps. Run it on folders from seeds no
model trained on. Needs numpy and onnxruntime.
"""

import argparse
import json
import sys

import numpy as np

from . import metric, physics

# What the attempts' contract and the model's metadata must agree on.
CONTRACT_KEYS = {"input_size_px": int, "pixel_size_m": float, "normalisation": str}
DEFAULT_EDGES = (0.0, 0.2, 0.4, 0.6, 0.8, 0.9, 1.0)


def model_contract(meta):
    """The attempts-comparable contract from an ONNX file's metadata map,
    and the index of its quality channel. Raises ValueError when a key is
    missing or the outputs name no quality."""
    contract = {}
    for key, kind in CONTRACT_KEYS.items():
        value = meta.get(f"mvgrasp.{key}")
        if value is None:
            raise ValueError(f"metadata has no mvgrasp.{key}")
        contract[key] = kind(value)
    outputs = meta.get("mvgrasp.outputs", "").split(",")
    if "quality" not in outputs:
        raise ValueError(f"mvgrasp.outputs {meta.get('mvgrasp.outputs')!r} names no quality channel")
    return contract, outputs.index("quality")


def quality_at(path, attempts, sigma_px=1.0, batch=256):
    """The model's quality at each attempt's pixel, smoothed as the planner
    smooths it. Raises ValueError when the model reads other views than
    the attempts'."""
    import onnxruntime

    session = onnxruntime.InferenceSession(path, providers=["CPUExecutionProvider"])
    contract, channel = model_contract(session.get_modelmeta().custom_metadata_map)
    problems = physics.check_contract(attempts, contract)
    if problems:
        raise ValueError(f"{path}: " + "; ".join(problems))
    scores = np.empty(len(attempts), np.float32)
    for start in range(0, len(attempts), batch):
        views = np.ascontiguousarray(attempts.views[start:start + batch, None])
        maps = session.run(["maps"], {"views": views})[0]
        quality = metric.smooth_quality(maps[:, [channel]], sigma_px)[:, 0]
        u, v = attempts.pixels[start:start + batch].T
        scores[start:start + len(views)] = quality[np.arange(len(views)), v, u]
    return scores


def auc(scores, held):
    """Area under the ROC curve of `scores` for `held` (1 / 0): the chance a
    held row scores above a failed one, ties counting half
    (Mann-Whitney U over average ranks). NaN without both kinds."""
    scores = np.asarray(scores, np.float64)
    held = np.asarray(held) > 0.5
    n_held, n_failed = int(held.sum()), int((~held).sum())
    if n_held == 0 or n_failed == 0:
        return float("nan")
    order = np.argsort(scores, kind="stable")
    ranks = np.empty(len(scores), np.float64)
    sorted_scores = scores[order]
    start = 0
    while start < len(scores):
        end = start
        while end + 1 < len(scores) and sorted_scores[end + 1] == sorted_scores[start]:
            end += 1
        ranks[order[start:end + 1]] = 0.5 * (start + end) + 1.0  # 1-based average rank of the tie
        start = end + 1
    u = ranks[held].sum() - n_held * (n_held + 1) / 2.0
    return float(u / (n_held * n_failed))


def brier(scores, held):
    """Mean squared error between `scores` and `held`."""
    return float(np.mean((np.asarray(scores, np.float64) - np.asarray(held, np.float64)) ** 2))


def calibration(scores, held, edges=DEFAULT_EDGES):
    """Per bin `[edges[k], edges[k+1])` (the last one closed): attempts,
    mean score, share held (NaN for an empty bin)."""
    scores, held = np.asarray(scores, np.float64), np.asarray(held, np.float64)
    rows = []
    for k, (lo, hi) in enumerate(zip(edges[:-1], edges[1:])):
        last = k == len(edges) - 2
        inside = (scores >= lo) & ((scores <= hi) if last else (scores < hi))
        n = int(inside.sum())
        rows.append({"from": lo, "to": hi, "attempts": n,
                     "mean_quality": float(scores[inside].mean()) if n else float("nan"),
                     "held": float(held[inside].mean()) if n else float("nan")})
    return rows


def score(path, attempts, sigma_px=1.0):
    """One model's AUC, Brier score and calibration on `attempts`."""
    q = quality_at(path, attempts, sigma_px)
    return {"model": path, "attempts": len(attempts), "auc": auc(q, attempts.held),
            "brier": brier(q, attempts.held), "mean_quality": float(q.mean()) if len(q) else float("nan"),
            "calibration": calibration(q, attempts.held)}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--attempts", required=True, metavar="DIR[,DIR]", help="sim eval --attempt-views folders")
    p.add_argument("models", nargs="+", metavar="MODEL.onnx")
    p.add_argument("--own-only", action="store_true",
                   help="the episodes' own attempts only, not the alternatives ranked below them")
    p.add_argument("--sigma-px", type=float, default=1.0,
                   help="the planner's quality smoothing (DecodeConfig::smoothing_sigma_px)")
    p.add_argument("--json", metavar="OUT", help="also write the scores as JSON")
    args = p.parse_args(argv)
    try:
        attempts = physics.load(args.attempts, alternatives=not args.own_only)
        results = [score(m, attempts, args.sigma_px) for m in args.models]
    except ValueError as e:
        raise SystemExit(str(e))
    print(f"{args.attempts}: {physics.summary(attempts)}")
    print("| model | AUC | Brier | mean quality | " + " | ".join(
        f"{c['from']:.1f}-{c['to']:.1f}: n, q, held" for c in results[0]["calibration"]) + " |")
    print("|---|---:|---:|---:|" + "---:|" * len(results[0]["calibration"]))
    for r in results:
        bins = " | ".join(f"{c['attempts']}, {c['mean_quality']:.2f}, {c['held']:.2f}" if c["attempts"] else "0"
                          for c in r["calibration"])
        print(f"| {r['model']} | {r['auc']:.3f} | {r['brier']:.4f} | {r['mean_quality']:.3f} | {bins} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"attempts": args.attempts, "own_only": args.own_only, "sigma_px": args.sigma_px,
                       "scores": results}, f, indent=1)


if __name__ == "__main__":
    sys.exit(main())
