#!/usr/bin/env python3
"""Calls/s and p99 against clients for scripts/gpu-service-bench.sh's runs
-> docs/service_gpu.png.

Reads results/service-gpu/bench-*.jsonl (one file per day; rows of several
runs carry "run"); one line per sweep named in SHOWN; needs matplotlib.
"""
import json
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parent.parent
# The sweeps shown (of every run's settings, those that tell the story apart).
SHOWN = ["2026-11-28: cuda-b64", "2026-11-28: cuda-b16", "2026-11-30 run 1: cuda-b64", "2026-11-30 run 1: cuda-b16",
         "2026-11-30 run 2: cuda-b64-s1", "2026-11-30 run 2: cuda-b64-s2", "2026-11-30 run 2: cuda-b32-s2",
         "2026-11-30 run 4: cone-b32-s2"]
series = {name: [] for name in SHOWN}
for path in sorted((ROOT / "results" / "service-gpu").glob("bench-*.jsonl")):
    day = path.stem.removeprefix("bench-")
    for line in path.read_text().splitlines():
        row = json.loads(line)
        name = f"{day} run {row['run']}: {row['label']}" if "run" in row else f"{day}: {row['label']}"
        if name in series:
            series[name].append((row["clients"], row["report"]))

fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
for k, (name, points) in enumerate(series.items()):
    points.sort(key=lambda p: p[0])
    clients = [c for c, _ in points]
    style = "--" if name.startswith("2026-11-28") else "-"
    colour = plt.cm.tab10(k)
    left.plot(clients, [r["throughput_per_s"] for _, r in points], style, color=colour, marker="o", label=name)
    right.plot(clients, [r["p99_ms"] for _, r in points], style, color=colour, marker="o", label=name)
left.axhline(5000, color="red", linestyle=":", linewidth=1, label="issue 51 target: 5,000 calls/s")
right.axhline(50, color="red", linestyle=":", linewidth=1, label="target p99: 50 ms")
for ax, title in ((left, "calls/s"), (right, "p99 ms (log)")):
    ax.set_xscale("log", base=2)
    ax.set_xlabel("concurrent clients")
    ax.set_title(title)
    ax.grid(alpha=0.3)
right.set_yscale("log")
left.legend(fontsize=7, loc="upper left")
fig.suptitle("The service on an H200 (CUDA; sample frame; default request, cone: the bridge's; dashed: c580df3)", fontsize=10)
fig.tight_layout()
out = ROOT / "docs" / "service_gpu.png"
fig.savefig(out, dpi=110)
print(f"wrote {out}")
