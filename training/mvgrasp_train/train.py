"""Trains a grasp network on a `sim datagen` dataset.

    python3 -m mvgrasp_train.train --data DATASET --out RUN_DIR \
        [--architecture paper|narrow|skip|wide] [--epochs 8] [--minutes 60] [--batch 32] \
        [--device cuda] [--schedule cosine]

Splits 80/20 by object instance, trains with MSE on the four maps and Adam
(lr 1e-3; `--init RUN --lr 1e-4` continues a run as a second, lower-rate stage;
RUN may be a shipped ONNX file read back by import_onnx.py).
`--positive-weight W` weights the squared error at pixels whose target
quality is above 0 (the painted positives) W times (1: plain MSE, the
paper's loss); `--balance-positives A` weighs them A / n times more again in
a view with only n < A of them; `--empty-view-weight E` weighs the quality
error of views without positives E times; `--peak-weight P` adds P times
`peak_loss`, each view's highest predicted quality against its labels'
highest (0 without positives). `--rank-weight R` adds R times `rank_loss`: minus the log
of the softmax share of the quality logits on positive pixels, per view
with positives (the argmax of the quality map is the metric's grasp).
`--teacher T.onnx` adds `--teacher-weight` times the MSE between the
network's maps and T's on the same augmented batch (`Teacher`): with T a
flip-wrapped file (flip_wrap.py) of the network it starts from, one pass
learns what four flips averaged give (self-distillation).
`--physics DIR[,DIR]` (folders of `sim eval --attempt-views`, physics.py)
adds `--physics-weight` times the squared error between the network's
quality at each tried grasp's pixel, smoothed as the planner smooths it
(`--physics-sigma-px`), and the physics outcome (1 held, 0 slipped or
opened too narrow), on a batch of attempts under a random symmetry of
the square per step (`physics_loss`); with the grasps ranked below the tried
ones (`sim eval --attempt-alternatives`) unless `--physics-own-only`.
`--label-weight 0` drops the label
loss: with `--teacher` the model it starts from, the network then only
moves where physics says its picks fail or hold.
`--architecture skip`, `wide` or `lite` may start from a `narrow` run (`start_from`).
Augments each training view (augment.py), with all 8 symmetries of the
square or, with `--symmetries gravity`, only those that keep the table
below in front and side views (`augment.symmetry_mask`; the physics
attempts alike), and after every epoch
evaluates the paper's grasp accuracy on the held-out instances. On a GPU
(`--device cuda`) the training views sit in device memory and whole batches
are augmented there (augment_torch.py); on the CPU each view is augmented
with numpy (augment.py) unless `--augment torch`. `--schedule cosine` decays the rate to 2% of
`--lr` over the run: over `--epochs`, or over `--minutes` when that comes
first (then the schedule follows the clock). Writes
RUN_DIR/log.jsonl (one line per epoch), RUN_DIR/model.pt (the last epoch's
weights: no model is picked on the held-out set) and RUN_DIR/eval.json.
"""

import argparse
import json
import os
import sys
import time

import numpy as np
import torch

from . import augment, augment_torch, dataset, metric, physics, runs
from .model import ARCHITECTURES, GraspNet, squash, start_lite, train_mode, widen


def progress(done, total, started, extra=""):
    width = 30
    filled = int(width * done / max(total, 1))
    elapsed = time.time() - started
    eta = elapsed / max(done, 1) * (total - done)
    sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} "
                     f"{elapsed:5.0f}s eta {eta:4.0f}s {extra}")
    sys.stderr.flush()


def predict(model, views, batch=128, device="cpu"):
    model.eval()
    out = []
    with torch.no_grad():
        for i in range(0, len(views), batch):
            x = torch.from_numpy(np.ascontiguousarray(views[i:i + batch])).to(device)
            out.append(model(x).cpu().numpy())
    return np.concatenate(out) if out else np.zeros((0, 4) + views.shape[2:], np.float32)


def evaluate(model, ds, indices, batch=128, device="cpu"):
    """Held-out MSE and the paper's accuracy on views `indices`."""
    indices = np.asarray(indices)
    pred = predict(model, ds.views[indices], batch, device)
    loss = float(np.mean((pred - ds.maps[indices]) ** 2))
    result = metric.evaluate(pred, ds, indices)
    result["loss"] = loss
    return result


def weighted_mse(pred, target, positive_weight=1.0, balance_px=0.0, empty_view_weight=1.0):
    """Mean squared error over every pixel and channel, the error at pixels
    with a positive target quality counted `positive_weight` times; with
    `balance_px` A > 0, in a view with n < A positive pixels those count
    A / n times more again, so that every view's positives weigh at least
    as much as A pixels' worth (views whose labels pass a few grasps on a
    large surface are most of the misses: models/RECIPES.md). With
    `empty_view_weight` E, the quality error of a view without any positive
    pixel counts E times: the planner's `all` policy acts on the best
    grasp across an object's views, so a quality that rises on a view the
    labels refuse beats the object's good view (`metric.object_picks`)."""
    error = (pred - target) ** 2
    if positive_weight == 1.0 and not balance_px and empty_view_weight == 1.0:
        return torch.mean(error)
    positive = (target[:, :1] > 0).to(error.dtype)
    weight = positive_weight
    if balance_px:
        count = positive.sum(dim=(1, 2, 3), keepdim=True).clamp(min=1.0)
        weight = positive_weight * torch.clamp(balance_px / count, min=1.0)
    weight = 1.0 + (weight - 1.0) * positive
    if empty_view_weight != 1.0:
        empty = (positive.sum(dim=(1, 2, 3), keepdim=True) == 0).to(error.dtype)
        quality = torch.zeros(1, error.shape[1], 1, 1, dtype=error.dtype, device=error.device)
        quality[:, 0] = 1.0
        weight = weight * (1.0 + (empty_view_weight - 1.0) * empty * quality)
    return torch.mean(weight * error)


def peak_loss(quality, target_quality):
    """Mean over views of the squared difference between the view's highest
    predicted quality and its highest target quality (0 for a view without
    positives). The planner's `all` policy compares those peaks across an
    object's views and acts on the highest (`metric.object_picks`); the MSE
    over every pixel hardly sees one pixel's peak on a view the labels
    refuse."""
    top = quality.flatten(1).max(dim=1).values
    return torch.mean((top - target_quality.flatten(1).max(dim=1).values) ** 2)


def rank_loss(scores, target_quality):
    """How far the view's best pixel is from a positive: per view with at
    least one positive pixel (target quality > 0), minus the log of the
    share of the softmax over all its pixels' `scores` (the quality logits,
    or the qualities over a temperature) that falls on positive pixels; the
    mean over those views (0 when there are none).

    The paper's accuracy takes the argmax of the quality map, and only the
    few percent of pixels painted positive can win it; this term scores
    that directly, where the MSE mostly learns "quality 0 almost
    everywhere" (docs/experiments/2026-11-24-missing-accuracy-rank-loss-skips.md, "Where the missing accuracy is").
    """
    logits = scores.flatten(1)
    positive = target_quality.flatten(1) > 0
    has = positive.any(dim=1)
    if not bool(has.any()):
        return logits.sum() * 0.0
    logits, positive = logits[has], positive[has]
    everything = torch.logsumexp(logits, dim=1)
    on_positives = torch.logsumexp(logits.masked_fill(~positive, float("-inf")), dim=1)
    return torch.mean(everything - on_positives)


class Teacher:
    """An ONNX model run through onnxruntime (CPU) on each training batch;
    its maps are a second target. Its contract must be the dataset's."""

    KEYS = ("mvgrasp.input_size_px", "mvgrasp.pixel_size_m", "mvgrasp.width_scale_m", "mvgrasp.normalisation",
            "mvgrasp.outputs")

    def __init__(self, path, contract, threads=1):
        import onnxruntime

        from .export import contract_metadata

        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = max(threads, 1)
        self.session = onnxruntime.InferenceSession(path, options, providers=["CPUExecutionProvider"])
        meta = self.session.get_modelmeta().custom_metadata_map
        want = {k: v for k, v in contract_metadata(contract, "", "").items() if k in self.KEYS}
        wrong = {k: (meta.get(k), v) for k, v in want.items() if meta.get(k) != v}
        if wrong:
            raise SystemExit(f"--teacher {path}: contract differs from the data's (file, data): {wrong}")
        self.version = meta.get("mvgrasp.model_version", "?")

    def maps(self, views):
        x = np.ascontiguousarray(views.detach().cpu().numpy(), dtype=np.float32)
        return torch.from_numpy(self.session.run(["maps"], {"views": x})[0]).to(views.device)


def physics_loss(model, attempts, picked, kernel, symmetry, device="cpu"):
    """Mean squared error between the network's quality at the pixels of
    attempts `picked` (after `physics.symmetry` number `symmetry`, one for
    all or one per attempt), smoothed by the 1-D `kernel` in both directions
    with clamped edges as the planner does, and their outcomes (1 held, 0 failed)."""
    ks = np.broadcast_to(np.asarray(symmetry, dtype=np.int64), (len(picked),))
    views, pixels = physics.symmetry_each(attempts.views[picked], attempts.pixels[picked], ks)
    x = torch.from_numpy(views).unsqueeze(1).to(device)
    quality = torch.sigmoid(model.raw(x)[:, :1])
    r = (len(kernel) - 1) // 2
    k = torch.as_tensor(kernel, device=device)
    quality = torch.nn.functional.pad(quality, (r, r, r, r), mode="replicate")
    quality = torch.nn.functional.conv2d(quality, k.view(1, 1, 1, -1))
    quality = torch.nn.functional.conv2d(quality, k.view(1, 1, -1, 1))
    at = quality[torch.arange(len(picked), device=device), 0,
                 torch.as_tensor(pixels[:, 1], device=device), torch.as_tensor(pixels[:, 0], device=device)]
    held = torch.as_tensor(attempts.held[picked], device=device)
    return torch.mean((at - held) ** 2)


def start_from(model, saved, name):
    """Loads a saved run's weights into `model`: a run of the same
    architecture, or a `narrow` run into a `skip` network (its skip
    convolutions stay at zero, so it starts as the narrow network's function)
    or a `wide` one (`model.widen`, the same)."""
    if saved["architecture"] == model.architecture:
        model.load_state_dict(saved["state_dict"])
        return
    if (saved["architecture"], model.architecture) == ("narrow", "wide"):
        widen(model, saved["state_dict"])
        return
    if (saved["architecture"], model.architecture) == ("narrow", "lite"):
        start_lite(model, saved["state_dict"])
        return
    if (saved["architecture"], model.architecture) != ("narrow", "skip"):
        raise SystemExit(f"--init {name} is {saved['architecture']}, not {model.architecture}")
    missing, unexpected = model.load_state_dict(saved["state_dict"], strict=False)
    if unexpected or any(not k.startswith("skips.") for k in missing):
        raise SystemExit(f"--init {name}: unexpected {unexpected}, missing {missing}")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--architecture", choices=ARCHITECTURES, default="paper")
    p.add_argument("--epochs", type=int, default=8)
    p.add_argument("--minutes", type=float, default=0, help="stop after the epoch that passes this (0: no limit)")
    p.add_argument("--batch", type=int, default=32)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    p.add_argument("--eval-views", type=int, default=1500, help="held-out views evaluated per epoch (all at the end)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--positive-weight", type=float, default=1.0,
                   help="weight of the squared error at positive pixels (1: plain MSE)")
    p.add_argument("--balance-positives", type=float, default=0.0, metavar="A",
                   help="in a view with n < A positive pixels, weigh those A / n times more again (0: off)")
    p.add_argument("--empty-view-weight", type=float, default=1.0, metavar="E",
                   help="weigh the quality error of views without positive pixels E times (1: off)")
    p.add_argument("--peak-weight", type=float, default=0.0, metavar="P",
                   help="weight of peak_loss (each view's highest quality against its labels' highest) (0: none)")
    p.add_argument("--rank-weight", type=float, default=0.0,
                   help="weight of rank_loss (the argmax on a positive pixel) added to the MSE (0: none)")
    p.add_argument("--rank-temperature", type=float, default=0.0,
                   help="rank_loss on the sigmoid qualities divided by this (0: on the quality logits, unbounded)")
    p.add_argument("--teacher", metavar="T.onnx",
                   help="also learn this ONNX model's maps on each augmented batch (e.g. a flip_wrap file)")
    p.add_argument("--teacher-weight", type=float, default=1.0, help="weight of the MSE to --teacher's maps")
    p.add_argument("--physics", metavar="DIR[,DIR]",
                   help="also learn physics outcomes of tried grasps (sim eval --attempt-views folders)")
    p.add_argument("--physics-weight", type=float, default=1.0, help="weight of physics_loss")
    p.add_argument("--physics-failures", metavar="PREFIX[,PREFIX]", default=",".join(physics.NETWORK_FAILURES),
                   help="outcomes (name prefixes) learned as failures; other failures are left out "
                        "(default: the network's own, physics.NETWORK_FAILURES)")
    p.add_argument("--physics-own-only", action="store_true",
                   help="only the episodes' own attempts, not the alternatives ranked below them")
    p.add_argument("--physics-sigma-px", type=float, default=1.0,
                   help="the planner's quality smoothing (DecodeConfig::smoothing_sigma_px)")
    p.add_argument("--label-weight", type=float, default=1.0,
                   help="weight of the label loss (0: none; with --teacher and --physics, see above)")
    p.add_argument("--symmetries", choices=augment.SYMMETRY_MODES, default="all",
                   help="gravity: front and side views only mirrored left-right, so the table stays below "
                        "(top views keep all 8); all: the 8 symmetries of the square for every view")
    p.add_argument("--device", default="cpu")
    p.add_argument("--augment", choices=("auto", "numpy", "torch"), default="auto",
                   help="numpy: per view on the CPU; torch: whole batches on --device, data held there (auto: torch off the CPU)")
    p.add_argument("--schedule", choices=("constant", "cosine"), default="constant")
    p.add_argument("--eval-every", type=int, default=1, help="evaluate the held-out sample every N epochs")
    p.add_argument("--init", help="start from this run's model.pt (e.g. a second stage at a lower --lr)")
    p.add_argument("--freeze-batchnorm", action="store_true",
                   help="keep BatchNorm in inference mode (running statistics fixed; scale and shift still "
                        "learned); implied by an --init run that is frozen (import_onnx.py)")
    p.add_argument("--hold-out-families", default="",
                   help="comma-separated shape families never trained on (evaluated apart)")
    args = p.parse_args(argv)

    if args.threads:
        torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    os.makedirs(args.out, exist_ok=True)
    ds = dataset.load(args.data)
    problems = dataset.check(ds)
    if problems:
        raise SystemExit(f"{args.data}: {problems}")
    train_idx, eval_idx = dataset.split_by_instance(ds.meta)
    unseen = {f for f in args.hold_out_families.split(",") if f}
    unknown = unseen - {m["family"] for m in ds.meta}
    if unknown:
        raise SystemExit(f"--hold-out-families: {sorted(unknown)} not in the dataset")
    family_idx = [i for i, m in enumerate(ds.meta) if m["family"] in unseen]
    train_idx = [i for i in train_idx if ds.meta[i]["family"] not in unseen]
    eval_idx = [i for i in eval_idx if ds.meta[i]["family"] not in unseen]
    print(dataset.summary(ds), file=sys.stderr)
    print(f"training on {len(train_idx)} views; held-out instances {len(eval_idx)} views; "
          f"unseen families {sorted(unseen)} {len(family_idx)} views", file=sys.stderr)
    eval_sample = dataset.sample_objects(ds.meta, eval_idx, args.eval_views, rng)

    device = torch.device(args.device)
    model = GraspNet(args.architecture)
    if args.init:
        try:
            saved = runs.load(args.init)
        except ValueError as e:
            raise SystemExit(f"--init: {e}")
        start_from(model, saved, args.init)
        args.freeze_batchnorm = args.freeze_batchnorm or saved["frozen_batchnorm"]
    model = model.to(device)
    teacher = Teacher(args.teacher, ds.contract, args.threads) if args.teacher else None
    attempts = None
    if args.physics:
        try:
            failures = tuple(f.strip() for f in args.physics_failures.split(",") if f.strip())
            attempts = physics.load(args.physics, failures=failures, alternatives=not args.physics_own_only)
        except ValueError as e:
            raise SystemExit(f"--physics: {e}")
        problems = physics.check_contract(attempts, ds.contract)
        if problems or not len(attempts):
            raise SystemExit(f"--physics {args.physics}: {problems or 'no attempts that held or failed'}")
        print(f"physics: {physics.summary(attempts)}", file=sys.stderr)
        kernel = physics.gaussian_kernel(args.physics_sigma_px)
        try:
            attempt_masks = np.array([augment.symmetry_mask(r.get("view"), args.symmetries)
                                      for r in attempts.records], dtype=np.int64)
        except ValueError as e:
            raise SystemExit(f"--physics {args.physics}: {e}")
    if args.label_weight == 0 and teacher is None and attempts is None:
        raise SystemExit("--label-weight 0 needs --teacher or --physics: nothing to learn")
    optimiser = torch.optim.Adam(model.parameters(), lr=args.lr)
    config = {k: v for k, v in vars(args).items()}
    config.update(physics_attempts=len(attempts) if attempts is not None else 0, train_views=len(train_idx), eval_views_total=len(eval_idx), unseen_family_views=len(family_idx), torch=torch.__version__,
                  threads=torch.get_num_threads(), data_version=ds.manifest["data_version"],
                  contract=ds.contract, gripper=ds.manifest["gripper"])
    with open(os.path.join(args.out, "config.json"), "w") as f:
        json.dump(config, f, indent=1)
    on_device = args.augment == "torch" or (args.augment == "auto" and device.type != "cpu")
    try:
        masks = np.array([augment.symmetry_mask(m.get("view"), args.symmetries) for m in ds.meta], dtype=np.int64)
    except ValueError as e:
        raise SystemExit(f"{args.data}: {e}")
    if on_device:
        train_views = torch.from_numpy(ds.views[train_idx]).to(device)
        train_maps = torch.from_numpy(ds.maps[train_idx]).to(device)
        train_masks = torch.from_numpy(masks[train_idx]).to(device)
        generator = torch.Generator(device=device)
        generator.manual_seed(args.seed)
    log = open(os.path.join(args.out, "log.jsonl"), "w")
    started = time.time()
    steps = len(train_idx) // args.batch

    def progress_share(epoch, step):
        share = ((epoch - 1) * steps + step) / max(args.epochs * steps, 1)
        if args.minutes:
            share = max(share, (time.time() - started) / (args.minutes * 60))
        return min(share, 1.0)

    for epoch in range(1, args.epochs + 1):
        train_mode(model, args.freeze_batchnorm)
        order = rng.permutation(len(train_idx) if on_device else train_idx)
        losses, t0 = [], time.time()
        for step in range(steps):
            batch = order[step * args.batch:(step + 1) * args.batch]
            if on_device:
                picked = torch.from_numpy(batch).to(device)
                x, y = augment_torch.augment(train_views[picked], train_maps[picked], generator,
                                             mask=train_masks[picked])
            else:
                pairs = [augment.augment(ds.views[i], ds.maps[i], rng, mask=masks[i]) for i in batch]
                x = torch.from_numpy(np.stack([a for a, _ in pairs])).to(device)
                y = torch.from_numpy(np.stack([b for _, b in pairs])).to(device)
            if args.schedule == "cosine":
                share = progress_share(epoch, step)
                for group in optimiser.param_groups:
                    group["lr"] = args.lr * (0.02 + 0.98 * 0.5 * (1 + np.cos(np.pi * share)))
            optimiser.zero_grad()
            raw = model.raw(x)
            loss = args.label_weight * weighted_mse(squash(raw), y, args.positive_weight, args.balance_positives,
                                                    args.empty_view_weight)
            if args.peak_weight:
                loss = loss + args.peak_weight * peak_loss(torch.sigmoid(raw[:, 0]), y[:, 0])
            if teacher is not None:
                loss = loss + args.teacher_weight * torch.mean((squash(raw) - teacher.maps(x)) ** 2)
            if args.rank_weight:
                scores = raw[:, 0] if not args.rank_temperature else torch.sigmoid(raw[:, 0]) / args.rank_temperature
                loss = loss + args.rank_weight * rank_loss(scores, y[:, 0])
            if attempts is not None:
                picked = rng.integers(0, len(attempts), size=args.batch)
                ks = int(rng.integers(0, 8)) & attempt_masks[picked]
                loss = loss + args.physics_weight * physics_loss(model, attempts, picked, kernel, ks, device)
            loss.backward()
            optimiser.step()
            losses.append(loss.detach())
            if step % 50 == 0 or step == steps - 1:
                recent = float(torch.stack(losses[-50:]).mean())
                progress(step + 1, steps, t0, f"epoch {epoch} loss {recent:.5f}")
        sys.stderr.write("\n")
        done = args.minutes and time.time() - started > args.minutes * 60
        entry = {"epoch": epoch, "train_loss": float(torch.stack(losses).mean()),
                 "lr": optimiser.param_groups[0]["lr"], "epoch_s": time.time() - t0}
        if epoch % args.eval_every == 0 or done or epoch == args.epochs:
            result = evaluate(model, ds, eval_sample, device=device)
            entry.update(eval_loss=result["loss"], eval_accuracy=result["accuracy"],
                         eval_object_accuracy=result["objects"]["accuracy"],
                         eval_per_view={k: v["accuracy"] for k, v in result["per_view"].items()})
        entry["elapsed_s"] = time.time() - started
        log.write(json.dumps(entry) + "\n")
        log.flush()
        print(json.dumps(entry), file=sys.stderr)
        if done:
            print(f"time budget of {args.minutes} min reached after epoch {epoch}", file=sys.stderr)
            break
    runs.save(args.out, args.architecture, model.state_dict(), args.freeze_batchnorm, epochs=epoch,
              train_s=time.time() - started)
    final = evaluate(model, ds, eval_idx, device=device)
    if family_idx:
        final["unseen_families"] = {"families": sorted(unseen), **evaluate(model, ds, family_idx, device=device)}
    final.update(epochs=epoch, train_s=time.time() - started)
    with open(os.path.join(args.out, "eval.json"), "w") as f:
        json.dump(final, f, indent=1)
    print(json.dumps(final), file=sys.stderr)


if __name__ == "__main__":
    main()
