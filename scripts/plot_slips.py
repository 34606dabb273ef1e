#!/usr/bin/env python3
"""Where `sim eval` runs' grasps slip during the lift, drawn for people:
the share of physics trials that slipped by the torque of the object's
weight about the closing line, and by family and the pose the object lay
in (upright or toppled), one bar per run.

    python3 scripts/plot_slips.py OUT.png NAME=RUN[,RUN...] [NAME=RUN...]

Each NAME pools the runs after it (folders or eval.json files, e.g. one
model on two seeds). Needs matplotlib; reads runs made since 2026-11-25
(whose attempts record the torque and the object's tilt).
"""

import os
import sys
from collections import Counter

sys.path.insert(0, os.path.dirname(__file__))
import compare_eval  # noqa: E402

# Upper edges (N m), as `sim eval`'s `eval::TORQUE_BINS_NM`.
TORQUE_BINS = (0.05, 0.1, 0.2, 0.4, float("inf"))
TORQUE = 10


def bin_names():
    names, lower = [], 0.0
    for upper in TORQUE_BINS:
        names.append(f"{lower:g}-{upper:g}" if upper != float("inf") else f">= {lower:g}")
        lower = upper
    return names


def torque_bin(t):
    return bin_names()[next(i for i, upper in enumerate(TORQUE_BINS) if t < upper)]


def slips_by_torque(run):
    """{torque bin: (slipped, physics trials)}."""
    slipped, trials = Counter(), Counter()
    for episode in run.get("episodes", []):
        for a in episode["attempts"]:
            if len(a) <= TORQUE or a[TORQUE] is None:
                continue
            key = torque_bin(a[TORQUE])
            trials[key] += 1
            slipped[key] += a[0] == "slip during lift"
    return {key: (slipped[key], trials[key]) for key in trials}


def pooled(paths, count):
    total = {}
    for path in paths:
        for key, (s, n) in count(compare_eval.load(path)).items():
            a, b = total.get(key, (0, 0))
            total[key] = (a + s, b + n)
    return total


def main(argv):
    if len(argv) < 2 or argv[0] in ("-h", "--help"):
        print(__doc__)
        return 2
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = argv[0]
    groups = [(arg.split("=", 1)[0], arg.split("=", 1)[1].split(",")) for arg in argv[1:]]
    torque = [pooled(paths, slips_by_torque) for _, paths in groups]
    poses = [pooled(paths, compare_eval.slips_by_pose) for _, paths in groups]
    bins = [b for b in bin_names() if any(b in t for t in torque)]
    families = sorted({f for p in poses for f, pose in p if pose in ("upright", "toppled")})
    keys = [(f, pose) for f in families for pose in ("upright", "toppled") if any((f, pose) in p for p in poses)]

    fig, (left, right) = plt.subplots(1, 2, figsize=(15, 4.8), gridspec_kw={"width_ratios": [1, 3]})
    width = 0.8 / len(groups)

    def bars(ax, keys, tables):
        for g, ((name, _), table) in enumerate(zip(groups, tables)):
            rates = [100 * table[k][0] / table[k][1] if table.get(k, (0, 0))[1] else 0 for k in keys]
            xs = [i + (g - (len(groups) - 1) / 2) * width for i in range(len(keys))]
            ax.bar(xs, rates, width, label=name)
            for x, k, r in zip(xs, keys, rates):
                s, n = table.get(k, (0, 0))
                ax.text(x, r + 0.5, f"{s}/{n}", ha="center", va="bottom", fontsize=6, rotation=90)
        ax.set_ylim(0, 1.18 * max(ax.get_ylim()[1], 1.0))
        ax.set_ylabel("slipped during lift (% of physics trials)")
        ax.grid(axis="y", alpha=0.3)

    bars(left, bins, torque)
    left.set_xticks(range(len(bins)), bins)
    left.set_xlabel("torque of the weight about the closing line (N m)")
    left.set_title("by torque")
    left.legend(fontsize=8)
    bars(right, keys, poses)
    right.set_xticks(range(len(keys)), [f"{f}\n{pose}" for f, pose in keys], fontsize=7)
    right.set_title("by family and pose (upright: tipped < 30 degrees; toppled: 30-150)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
