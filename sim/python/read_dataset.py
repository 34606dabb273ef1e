#!/usr/bin/env python3
"""Reads a `sim datagen` dataset with numpy alone, and checks it.

    python3 sim/python/read_dataset.py DATASET_DIR [--check]

`load(path)` returns (views [N,1,L,L], maps [N,4,L,L], meta list of dicts,
manifest dict); `split_by_instance(meta, eval_share, seed)` gives the 80/20
train / evaluation split by object instance. With --check, every invariant
of the format is verified and the exit code says whether they hold.
"""

import json
import os
import sys
import zlib

import numpy as np


def load(path):
    with open(os.path.join(path, "manifest.json")) as f:
        manifest = json.load(f)
    views, maps, meta = [], [], []
    for shard in manifest["shards"]:
        folder = os.path.join(path, shard)
        views.append(np.load(os.path.join(folder, "views.npy")))
        maps.append(np.load(os.path.join(folder, "maps.npy")))
        with open(os.path.join(folder, "meta.jsonl")) as f:
            meta.extend(json.loads(line) for line in f if line.strip())
    return np.concatenate(views), np.concatenate(maps), meta, manifest


def split_by_instance(meta, eval_share=0.2, seed=0):
    """Indices (train, eval): every view of an object instance on one side."""
    def side(instance):
        return (zlib.crc32(f"{seed}:{instance}".encode()) % 1000) < eval_share * 1000
    train = [i for i, m in enumerate(meta) if not side(m["instance"])]
    held = [i for i, m in enumerate(meta) if side(m["instance"])]
    return train, held


def check(views, maps, meta, manifest):
    problems = []
    c = manifest["contract"]
    l, outputs = c["input_size_px"], c["outputs"]
    n = len(meta)
    if views.shape != (n, 1, l, l) or views.dtype != np.float32:
        problems.append(f"views {views.shape} {views.dtype}, expected ({n}, 1, {l}, {l}) float32")
    if maps.shape != (n, 4, l, l) or maps.dtype != np.float32:
        problems.append(f"maps {maps.shape} {maps.dtype}, expected ({n}, 4, {l}, {l}) float32")
    if n != manifest["views"]:
        problems.append(f"{n} views read, manifest says {manifest['views']}")
    if problems:
        return problems
    q, cos2, sin2, width = (maps[:, outputs.index(k)] for k in ("quality", "cos2phi", "sin2phi", "width"))
    if not np.all((q >= 0) & (q <= 1)):
        problems.append("quality outside [0, 1]")
    graspable = q > 0
    if not np.allclose(cos2[graspable] ** 2 + sin2[graspable] ** 2, 1, atol=1e-4):
        problems.append("cos2phi^2 + sin2phi^2 != 1 where quality > 0")
    metres = width[graspable] * c["width_scale_m"]
    if not np.all((metres > 0) & (metres <= manifest["gripper"]["max_width_m"] + 1e-6)):
        problems.append("widths outside (0, max_width_m] where quality > 0")
    if np.any(maps[:, :, ~np.any(graspable, axis=0)] != 0):
        problems.append("channels not 0 where no view has a grasp")
    positives = sum(1 for m in meta if m["positives"] > 0)
    if positives != manifest["views_with_positives"]:
        problems.append(f"{positives} views with positives, manifest says {manifest['views_with_positives']}")
    painted = int(np.count_nonzero(np.any(graspable, axis=(1, 2))))
    if painted != positives:
        problems.append(f"{painted} views have painted quality, {positives} have positives")
    train, held = split_by_instance(meta)
    instances = lambda idx: {meta[i]["instance"] for i in idx}  # noqa: E731
    if instances(train) & instances(held):
        problems.append("an object instance is on both sides of the split")
    return problems


def main():
    path = sys.argv[1]
    views, maps, meta, manifest = load(path)
    train, held = split_by_instance(meta)
    families = sorted({m["family"] for m in meta})
    print(f"{len(meta)} views ({manifest['views_with_positives']} with positives) of "
          f"{len({m['instance'] for m in meta})} object instances, families {', '.join(families)}; "
          f"split {len(train)} train / {len(held)} eval views; views {views.shape}, maps {maps.shape}")
    if "--check" in sys.argv:
        problems = check(views, maps, meta, manifest)
        for p in problems:
            print(f"FAIL {p}")
        print("dataset check: every invariant holds" if not problems else f"dataset check: {len(problems)} problems")
        return 1 if problems else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
