"""Plots training curves of one or more runs into a PNG.

    python3 -m mvgrasp_train.plot OUT.png RUN_DIR[,STAGE2_DIR...][=LABEL] ...

Runs joined by commas are stages of one training (`train --init`), drawn
one after the other with a dotted line where a stage starts.

Left: train and held-out loss per epoch; right: held-out grasp accuracy
(overall solid, per view dotted). Needs matplotlib.

`draw_views` draws views with their target and predicted quality
(`evaluate_onnx --misses`).
"""

import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(runs):
    """The epochs of comma-separated stages, numbered on; and where each later stage starts."""
    log, starts = [], []
    for k, run in enumerate(runs.split(",")):
        with open(os.path.join(run, "log.jsonl")) as f:
            stage = [json.loads(line) for line in f if line.strip()]
        if k:
            starts.append(len(log) + 0.5)
        for e in stage:
            e["epoch"] = len(log) + 1
            log.append(e)
    return log, starts


def draw_views(out, ds, indices, pred, title):
    """One row per view `indices[k]` of `ds`: the view, its target quality
    and `pred[k]`'s quality; the positives as cyan dots, the predicted
    grasp (argmax quality) as a red cross."""
    from . import metric
    u, v, _, _, q = metric.decode(pred)
    rows = max(len(indices), 1)
    fig, axes = plt.subplots(rows, 3, figsize=(7.5, 2.5 * rows), squeeze=False)
    for r, i in enumerate(indices):
        m, target = ds.meta[i], ds.maps[i][0]
        panels = [(ds.views[i][0], "gray", None, f"{m['family']} {m['view']} {m.get('scenario', '')}"),
                  (target, "viridis", 0.8, f"target quality (max {target.max():.2f})"),
                  (pred[r][0], "viridis", 0.8, f"predicted (max {q[r]:.2f})")]
        truth = ds.grasps_of(i)
        for ax, (image, cmap, vmax, name) in zip(axes[r], panels):
            ax.imshow(image, cmap=cmap, vmin=0, vmax=vmax)
            ax.plot(truth[:, 0], truth[:, 1], "c.", ms=1.5)
            ax.plot([u[r]], [v[r]], "r+", ms=10)
            ax.set_title(name, fontsize=7)
            ax.axis("off")
    fig.suptitle(title, fontsize=8)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.25 / (2.5 * rows)))
    fig.savefig(out, dpi=80)
    plt.close(fig)


def main(argv):
    if len(argv) < 2 or argv[0].startswith("-"):
        print(__doc__)
        return 0 if argv and argv[0] in ("-h", "--help") else 2
    out, runs = argv[0], argv[1:]
    fig, (ax_loss, ax_acc) = plt.subplots(1, 2, figsize=(11, 4))
    for k, spec in enumerate(runs):
        path, _, label = spec.partition("=")
        label = label or os.path.basename(path.split(",")[0].rstrip("/"))
        log, starts = read(path)
        colour = f"C{k}"
        for x in starts:
            ax_acc.axvline(x, color=colour, linestyle=":", linewidth=0.8)
        epochs = [e["epoch"] for e in log]
        ax_loss.plot(epochs, [e["train_loss"] for e in log], "-", color=colour, label=f"{label} train")
        evaluated = [e for e in log if "eval_accuracy" in e]  # runs may evaluate every N epochs
        at = [e["epoch"] for e in evaluated]
        ax_loss.plot(at, [e["eval_loss"] for e in evaluated], "--", color=colour, label=f"{label} held-out")
        ax_acc.plot(at, [100 * e["eval_accuracy"] for e in evaluated], "-o", color=colour, label=label)
        for view, style in zip(("top", "front", "side"), (":", (0, (1, 3)), (0, (3, 3)))):
            values = [100 * e["eval_per_view"].get(view, float("nan")) for e in evaluated]
            ax_acc.plot(at, values, linestyle=style, color=colour, alpha=0.6, label=f"{label} {view}")
    ax_loss.set(xlabel="epoch", ylabel="MSE (4 maps)", title="loss", yscale="log")
    ax_acc.axhline(93, color="grey", lw=0.8)
    ax_acc.text(1, 93.5, "paper: 93%", color="grey", fontsize=8)
    ax_acc.set(xlabel="epoch", ylabel="% correct (IoU > 25%, angle < 30 deg)",
               title="held-out-object grasp accuracy", ylim=(0, 100))
    ax_loss.legend(fontsize=7)
    ax_acc.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
