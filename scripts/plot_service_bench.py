#!/usr/bin/env python3
"""Bar charts of scripts/bench-service.sh's results -> docs/service_bench.png.

Reads target/bench/service.jsonl; needs matplotlib.
"""
import json
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parent.parent
runs = [json.loads(line) for line in (ROOT / "target" / "bench" / "service.jsonl").read_text().splitlines()]
# One bar per setting: the run of median throughput among its repeats.
rows = []
for label in dict.fromkeys(r["label"] for r in runs):
    mine = sorted((r for r in runs if r["label"] == label), key=lambda r: r["report"]["throughput_per_s"])
    rows.append(mine[len(mine) // 2])
labels = [f"{r['label']}\n({sum(1 for x in runs if x['label'] == r['label'])} runs, median)" for r in rows]
fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
p50 = [r["report"]["p50_ms"] for r in rows]
p99 = [r["report"]["p99_ms"] for r in rows]
x = range(len(rows))
left.bar([i - 0.2 for i in x], p50, 0.4, label="p50")
left.bar([i + 0.2 for i in x], p99, 0.4, label="p99")
left.axhline(15, color="red", linestyle="--", linewidth=1, label="target p50 (1 client): 15 ms")
left.set_yscale("log")
left.set_xticks(list(x), labels)
left.set_ylabel("end-to-end latency (ms, log)")
left.legend(fontsize=8)
right.bar(list(x), [r["report"]["throughput_per_s"] for r in rows], color="tab:green")
right.set_xticks(list(x), labels)
right.set_ylabel("calls / s")
for i, r in enumerate(rows):
    right.text(i, r["report"]["throughput_per_s"], f"{r['report']['throughput_per_s']:.1f}", ha="center", va="bottom")
model_file = ROOT / "target" / "bench" / "model.txt"
model = model_file.read_text().strip() if model_file.exists() else "model not recorded"
fig.suptitle(f"mvgrasp-server, samples/table6 (640x480, 6 objects), {model}, CPU, 2 cores")
fig.tight_layout()
out = ROOT / "docs" / "service_bench.png"
fig.savefig(out, dpi=110)
print(f"wrote {out}")
