#!/usr/bin/env python3
"""Bar chart of the core stage benchmark (criterion medians) -> docs/stage_bench.png.

Run after `taskset -c 0 cargo bench -p mvgrasp-core --bench stages`; needs matplotlib.
"""
import json
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parent.parent
GROUP = ROOT / "target" / "criterion" / "640x480_6_objects"
STAGES = [
    ("1_sensor_random_points_for_table", "sensor: random sample"),
    ("2_table_ransac", "table RANSAC"),
    ("3_sensor_objects_above_table", "sensor: block mask + objects"),
    ("4_cluster", "clustering"),
    ("5_object_frames", "object frames"),
    ("6_render_views_and_entropy", "views + entropy"),
    ("7_decode_and_rank", "decode + rank"),
]


def median_us(name: str) -> float:
    estimates = json.loads((GROUP / name / "new" / "estimates.json").read_text())
    return estimates["median"]["point_estimate"] / 1e3


def main() -> int:
    out = ROOT / (sys.argv[1] if len(sys.argv) > 1 else "docs/stage_bench.png")
    values = [median_us(name) for name, _ in STAGES]
    total = median_us("all_but_network")
    fig, ax = plt.subplots(figsize=(8, 4.2))
    ax.barh([label for _, label in STAGES][::-1], values[::-1], color="#4a90d9")
    for y, v in enumerate(values[::-1]):
        ax.text(v + 10, y, f"{v:.0f} us", va="center", fontsize=9)
    ax.set_xlabel("median time per 640x480 frame with 6 objects, one core (us)")
    ax.set_title(f"mvgrasp-core stages: all but the network {total / 1e3:.2f} ms (target 2 ms)")
    ax.set_xlim(0, max(values) * 1.25)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
