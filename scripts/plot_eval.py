#!/usr/bin/env python3
"""Bar chart of a `sim eval` report against the paper's simulated numbers.

    python3 scripts/plot_eval.py results/eval.json results/eval.png [--title TEXT]

Success and removal rate per scenario (bars per planner setting), with the
paper's figures as black ticks where it reports them, and each bar's 95%
interval over episodes where the report has one. Needs matplotlib.
"""

import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

# The paper's simulated results (Kasaei & Kasaei 2023): success, removal.
PAPER = {"isolated": (0.926, None), "packed": (0.84, 0.88), "pile": (0.75, 0.89), "clutter": (None, 0.90)}


def main():
    src, out = sys.argv[1], sys.argv[2]
    title = sys.argv[sys.argv.index("--title") + 1] if "--title" in sys.argv else "sim eval"
    with open(src) as f:
        report = json.load(f)
    rows = report["summaries"]
    scenarios = list(dict.fromkeys(r["scenario"] for r in rows))
    settings = list(dict.fromkeys(r["setting"] for r in rows))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    width = 0.8 / len(settings)
    for ax, metric, k in ((axes[0], "success_rate", 0), (axes[1], "removal_rate", 1)):
        for j, setting in enumerate(settings):
            xs, ys, lo, hi = [], [], [], []
            for i, sc in enumerate(scenarios):
                row = next((r for r in rows if r["scenario"] == sc and r["setting"] == setting), None)
                if row and row["attempts"]:
                    xs.append(i + (j - (len(settings) - 1) / 2) * width)
                    ys.append(row[metric])
                    # 95% interval over episodes (reports since 9513968).
                    ci = row.get(metric.replace("_rate", "_ci95")) or [None, None]
                    lo.append(row[metric] - ci[0] if ci[0] is not None else 0.0)
                    hi.append(ci[1] - row[metric] if ci[1] is not None else 0.0)
            ax.bar(xs, ys, width, label=setting, yerr=[lo, hi], capsize=2, error_kw={"linewidth": 0.8})
        for i, sc in enumerate(scenarios):
            paper = PAPER.get(sc, (None, None))[k]
            if paper is not None:
                ax.hlines(paper, i - 0.45, i + 0.45, colors="black", linewidth=2)
                ax.text(i + 0.46, paper, f"paper {paper:.2f}", fontsize=7, va="center")
        ax.set_xticks(range(len(scenarios)), scenarios)
        ax.set_ylim(0, 1.05)
        ax.set_title(metric.replace("_", " "))
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{title} ({report.get('model_version', '?')}, rev {report.get('revision', '?')})")
    fig.tight_layout()
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main()
