"""Reads and checks a `sim datagen` dataset with numpy alone.

The format is written by `sim/src/dataset.rs` (format_version 2):
`manifest.json`, and per shard `views.npy` [n,1,L,L], `maps.npy` [n,4,L,L],
`grasps.npy` [m,6] (shard view index, u, v, phi, opening m, quality) and
`meta.jsonl` (one line per view).
"""

import json
import os
import zlib
from dataclasses import dataclass

import numpy as np

FORMAT_VERSION = 2
CHANNELS = ("quality", "cos2phi", "sin2phi", "width")


@dataclass
class Dataset:
    views: np.ndarray  # [N, 1, L, L] float32
    maps: np.ndarray  # [N, 4, L, L] float32, channel order CHANNELS
    grasps: np.ndarray  # [M, 6] float32: global view index, u, v, phi, opening m, quality
    meta: list
    manifest: dict

    @property
    def contract(self):
        return self.manifest["contract"]

    def grasps_of(self, view):
        """The ground-truth positives of one view, [k, 5] (u, v, phi, opening m, quality)."""
        lo, hi = np.searchsorted(self.grasps[:, 0], [view, view + 1])
        return self.grasps[lo:hi, 1:]


def load(path, mmap=False):
    """Every shard of the dataset at `path`, maps reordered to CHANNELS.

    `path` may name several datasets, comma-separated (e.g. chunks of one
    `sim datagen` run made with disjoint seeds); they are concatenated in
    order and must share the contract, gripper and data version.
    """
    paths = [p for p in str(path).split(",") if p]
    if len(paths) > 1:
        return merge([load(p, mmap) for p in paths], paths)
    manifest = read_manifest(path)
    mode = "r" if mmap else None
    views, maps, grasps, meta = [], [], [], []
    offset = 0
    for shard in manifest["shards"]:
        folder = os.path.join(path, shard)
        v = np.load(os.path.join(folder, "views.npy"), mmap_mode=mode)
        views.append(v)
        maps.append(np.load(os.path.join(folder, "maps.npy"), mmap_mode=mode))
        g = np.load(os.path.join(folder, "grasps.npy")).reshape(-1, 6).copy()
        g[:, 0] += offset
        grasps.append(g)
        with open(os.path.join(folder, "meta.jsonl")) as f:
            meta.extend(json.loads(line) for line in f if line.strip())
        offset += len(v)
    order = [manifest["contract"]["outputs"].index(c) for c in CHANNELS]
    maps = np.concatenate(maps)
    if order != [0, 1, 2, 3]:
        maps = maps[:, order]
    grasps = np.concatenate(grasps) if grasps else np.zeros((0, 6), np.float32)
    return Dataset(np.concatenate(views), maps, grasps, meta, manifest)


def read_manifest(path):
    """The `manifest.json` of the dataset folder `path`; ValueError when its
    format version is not the one this reader knows."""
    with open(os.path.join(path, "manifest.json")) as f:
        manifest = json.load(f)
    if manifest.get("format_version") != FORMAT_VERSION:
        raise ValueError(f"{path}: format_version {manifest.get('format_version')}, "
                         f"this reader knows {FORMAT_VERSION} (regenerate with `sim datagen`)")
    return manifest


def merge(parts, names):
    """One Dataset of `parts` in order; refuses parts whose contract, gripper or data version differ."""
    first = parts[0].manifest
    for part, name in zip(parts[1:], names[1:]):
        for key in ("contract", "gripper", "data_version", "format_version"):
            if part.manifest.get(key) != first.get(key):
                raise ValueError(f"{name}: {key} {part.manifest.get(key)!r} differs from {names[0]}'s {first.get(key)!r}")
    offsets = np.cumsum([0] + [len(p.meta) for p in parts[:-1]])
    grasps = [p.grasps + np.array([o, 0, 0, 0, 0, 0], np.float32) for p, o in zip(parts, offsets)]
    manifest = dict(first)
    manifest.update(views=sum(p.manifest["views"] for p in parts),
                    views_with_positives=sum(p.manifest["views_with_positives"] for p in parts),
                    failed_scenes=[s for p in parts for s in p.manifest.get("failed_scenes", [])],
                    parts=[{"path": n, "views": p.manifest["views"]} for p, n in zip(parts, names)])
    return Dataset(np.concatenate([p.views for p in parts]), np.concatenate([p.maps for p in parts]),
                   np.concatenate(grasps), [m for p in parts for m in p.meta], manifest)


def split_by_instance(meta, eval_share=0.2, seed=0):
    """Indices (train, eval): every view of an object instance on one side."""
    def held(instance):
        return (zlib.crc32(f"{seed}:{instance}".encode()) % 1000) < eval_share * 1000
    train = [i for i, m in enumerate(meta) if not held(m["instance"])]
    evaluation = [i for i, m in enumerate(meta) if held(m["instance"])]
    return train, evaluation


def check(ds):
    """Every invariant of the format; returns a list of problems (empty: all hold)."""
    problems = []
    c, manifest, meta = ds.contract, ds.manifest, ds.meta
    views, maps, grasps = ds.views, ds.maps, ds.grasps
    l, n = c["input_size_px"], len(meta)
    if views.shape != (n, 1, l, l) or views.dtype != np.float32:
        problems.append(f"views {views.shape} {views.dtype}, expected ({n}, 1, {l}, {l}) float32")
    if maps.shape != (n, 4, l, l) or maps.dtype != np.float32:
        problems.append(f"maps {maps.shape} {maps.dtype}, expected ({n}, 4, {l}, {l}) float32")
    if n != manifest["views"]:
        problems.append(f"{n} views read, manifest says {manifest['views']}")
    if problems:
        return problems
    q, cos2, sin2, width = maps[:, 0], maps[:, 1], maps[:, 2], maps[:, 3]
    if not np.all((q >= 0) & (q <= 1)):
        problems.append("quality outside [0, 1]")
    graspable = q > 0
    if not np.allclose(cos2[graspable] ** 2 + sin2[graspable] ** 2, 1, atol=1e-4):
        problems.append("cos2phi^2 + sin2phi^2 != 1 where quality > 0")
    max_width = manifest["gripper"]["max_width_m"] + 1e-6
    metres = width[graspable] * c["width_scale_m"]
    if not np.all((metres > 0) & (metres <= max_width)):
        problems.append("widths outside (0, max_width_m] where quality > 0")
    if np.any(maps[:, 1:][np.broadcast_to(~graspable[:, None], maps[:, 1:].shape)] != 0):
        problems.append("channels not 0 where quality is 0")
    positives = sum(1 for m in meta if m["positives"] > 0)
    if positives != manifest["views_with_positives"]:
        problems.append(f"{positives} views with positives, manifest says {manifest['views_with_positives']}")
    # Refusal counts (written since 2026-11-25): every candidate is a positive or refused.
    if any("refused" in m and sum(m["refused"].values()) + m["positives"] != m["candidates"] for m in meta):
        problems.append("refused + positives differ from candidates in meta.jsonl")
    painted = int(np.count_nonzero(np.any(graspable, axis=(1, 2))))
    if painted != positives:
        problems.append(f"{painted} views have painted quality, {positives} have positives")
    counts = np.bincount(grasps[:, 0].astype(np.int64), minlength=n) if len(grasps) else np.zeros(n, int)
    if len(counts) != n or any(counts[i] != m["positives"] for i, m in enumerate(meta)):
        problems.append("grasps.npy rows per view differ from meta positives")
    elif len(grasps):
        if np.any(np.diff(grasps[:, 0]) < 0):
            problems.append("grasps.npy is not ordered by view")
        vi, u, v = (grasps[:, k].astype(np.int64) for k in range(3))
        if np.any(q[vi, v, u] + 1e-6 < grasps[:, 5]):
            problems.append("a grasp's pixel is painted lower than its quality")
        if np.any(np.abs(grasps[:, 3]) > np.pi / 2 + 1e-5):
            problems.append("grasp angles outside [-pi/2, pi/2]")
        if np.any((grasps[:, 4] <= 0) | (grasps[:, 4] > max_width)):
            problems.append("grasp openings outside (0, max_width_m]")
    train, held = split_by_instance(meta)
    instances = lambda idx: {meta[i]["instance"] for i in idx}  # noqa: E731
    if instances(train) & instances(held):
        problems.append("an object instance is on both sides of the split")
    return problems


def summary(ds):
    train, held = split_by_instance(ds.meta)
    families = sorted({m["family"] for m in ds.meta})
    return (f"{len(ds.meta)} views ({ds.manifest['views_with_positives']} with positives, "
            f"{len(ds.grasps)} labelled grasps) of {len({m['instance'] for m in ds.meta})} object "
            f"instances, families {', '.join(families)}; split {len(train)} train / {len(held)} eval "
            f"views; views {ds.views.shape}, maps {ds.maps.shape}")


def sample_objects(meta, indices, n, rng):
    """Whole objects of `indices` in `rng`'s order (every view of an
    instance, or none) until there are at least `n` views; sorted. The
    per-epoch evaluation scores objects' picks across their views
    (`metric.object_picks`), which a sample of single views would cut."""
    by_instance = {}
    for i in indices:
        by_instance.setdefault(meta[i].get("instance", i), []).append(i)
    groups = list(by_instance.values())
    picked = []
    for k in rng.permutation(len(groups)):
        if len(picked) >= n:
            break
        picked.extend(groups[k])
    return np.sort(np.asarray(picked, dtype=np.int64))
