"""Packs training data small enough to travel to a lent GPU machine.

The dense-label datasets and `--attempt-views` folders of a recipe are
gigabytes (the `qc` recipe's: 2.5 GB of datasets and 0.7 GB of attempts),
the GPU machine takes a 64 MiB working tree, and it has too little time to
regenerate dense labels. A pack keeps what training reads:

- a dataset's views and maps in float16 (views at most 2.4e-4 off: 0.06
  mm of depth on the 24 cm cube, against millimetres of simulated sensor
  noise; openings rounded down, at most 4.9e-4 of 0.2 m: 0.1 mm),
  each shard's `meta.jsonl` and the manifest, xz-compressed; not its
  `grasps.npy` (the positives the metric reads, about half the bytes).
  `unpack` writes a dataset in `sim datagen`'s format again, with one grasp
  per painted pixel derived from the maps (the best angle and opening
  there) and `positives` / `candidates` counted to match, so the on-device
  evaluation is a stand-in: accuracy against the painted best grasp of
  each pixel, not against every labelled grasp. Measure a run brought back
  on the real datasets here (`evaluate_onnx`).
- an `--attempt-views` folder's rows that `train --physics` reads, the
  episodes' own attempts only with `--own-only` (what `--physics-own-only`
  learns), views in float16.

    python3 -m mvgrasp_train.pack pack --data D/a,D/b --physics AV/x,AV/y --own-only --out .gpu/pack
    python3 -m mvgrasp_train.pack unpack .gpu/pack --out /tmp/data     # on the GPU machine

`unpack` writes `OUT/NAME` for each folder packed (named by its last path
part, which must be unique) and prints a line `KIND PATH` for each, KIND
`dataset` or `attempts`. Numpy and the standard library only.
"""

import argparse
import concurrent.futures
import glob
import io
import json
import lzma
import os
import shutil
import sys

import numpy as np

from . import dataset, physics

FORMAT = "mvgrasp-pack-1"


def _write_array(path, array):
    buffer = io.BytesIO()
    np.save(buffer, array)
    with open(path, "wb") as f:
        f.write(lzma.compress(buffer.getvalue(), preset=6))


def _read_array(path):
    with open(path, "rb") as f:
        return np.load(io.BytesIO(lzma.decompress(f.read())))


def to_half(maps, quality_channel, width_channel):
    """`maps` in float16, no painted quality rounded to 0 (a pixel keeps
    its angle and width only where quality > 0) and no width rounded up
    (past the gripper's opening)."""
    half = maps.astype(np.float16)
    q = half[:, quality_channel]
    q[(maps[:, quality_channel] > 0) & (q == 0)] = np.float16(6e-8)
    w = half[:, width_channel]
    up = w.astype(np.float32) > maps[:, width_channel]
    w[up] = np.nextafter(w[up], np.float16(0))
    return half


def pack_dataset(src, dst):
    manifest = dataset.read_manifest(src)
    outputs = manifest["contract"]["outputs"]
    os.makedirs(dst)
    for shard in manifest["shards"]:
        os.makedirs(os.path.join(dst, shard))
        views = np.load(os.path.join(src, shard, "views.npy"))
        maps = np.load(os.path.join(src, shard, "maps.npy"))
        _write_array(os.path.join(dst, shard, "views.npy.xz"), views.astype(np.float16))
        _write_array(os.path.join(dst, shard, "maps.npy.xz"), to_half(maps, outputs.index("quality"), outputs.index("width")))
        shutil.copyfile(os.path.join(src, shard, "meta.jsonl"), os.path.join(dst, shard, "meta.jsonl"))
    manifest["packed"] = {"format": FORMAT, "kind": "dataset", "from": os.path.abspath(src)}
    with open(os.path.join(dst, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=1)


def painted_grasps(maps, channels, width_scale_m):
    """One grasp row per pixel with quality > 0 (view, u, v, phi, opening
    m, quality), ordered by view: the maps' best grasp of each pixel."""
    q, c, s, w = (maps[:, channels.index(k)] for k in dataset.CHANNELS)
    view, v, u = np.nonzero(q > 0)
    phi = 0.5 * np.arctan2(s[view, v, u], c[view, v, u])
    return np.stack([view, u, v, phi, w[view, v, u] * width_scale_m, q[view, v, u]], axis=1).astype(np.float32)


def unpack_dataset(src, dst):
    manifest = dataset.read_manifest(src)
    channels = manifest["contract"]["outputs"]
    quality = channels.index("quality")
    cos, sin = channels.index("cos2phi"), channels.index("sin2phi")
    os.makedirs(dst)
    for shard in manifest["shards"]:
        os.makedirs(os.path.join(dst, shard))
        views = _read_array(os.path.join(src, shard, "views.npy.xz")).astype(np.float32)
        maps = _read_array(os.path.join(src, shard, "maps.npy.xz")).astype(np.float32)
        painted = maps[:, quality] > 0
        norm = np.sqrt(maps[:, cos] ** 2 + maps[:, sin] ** 2)
        for k in (cos, sin):  # unit length again after rounding
            maps[:, k] = np.where(painted, maps[:, k] / np.where(painted, norm, 1), 0)
        grasps = painted_grasps(maps, channels, manifest["contract"]["width_scale_m"])
        counts = np.bincount(grasps[:, 0].astype(np.int64), minlength=len(views))
        with open(os.path.join(src, shard, "meta.jsonl")) as f:
            meta = [json.loads(line) for line in f if line.strip()]
        if len(meta) != len(views):
            raise ValueError(f"{src}/{shard}: {len(meta)} meta lines for {len(views)} views")
        for m, n in zip(meta, counts):
            m["positives"] = int(n)
            if "refused" in m:
                m["candidates"] = int(n) + sum(m["refused"].values())
        np.save(os.path.join(dst, shard, "views.npy"), views)
        np.save(os.path.join(dst, shard, "maps.npy"), maps)
        np.save(os.path.join(dst, shard, "grasps.npy"), grasps)
        with open(os.path.join(dst, shard, "meta.jsonl"), "w") as f:
            f.writelines(json.dumps(m) + "\n" for m in meta)
    manifest["packed"]["grasps"] = "one per painted pixel, derived from the maps (pack.py)"
    with open(os.path.join(dst, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=1)


def pack_attempts(src, dst, own_only):
    manifest = physics.read_manifest(src)
    os.makedirs(dst)
    kept = 0
    for npy in sorted(glob.glob(os.path.join(src, "attempts_*.npy"))):
        views = np.load(npy)
        with open(npy[:-4] + ".json") as f:
            rows = json.load(f)
        keep = [k for k, r in enumerate(rows) if not (own_only and r.get("alternative"))]
        name = os.path.basename(npy)[:-4]
        _write_array(os.path.join(dst, name + ".npy.xz"), views[keep].astype(np.float16))
        with open(os.path.join(dst, name + ".json"), "w") as f:
            json.dump([rows[k] for k in keep], f)
        kept += len(keep)
    manifest["attempts"] = kept
    manifest["packed"] = {"format": FORMAT, "kind": "attempts", "from": os.path.abspath(src), "own_only": own_only}
    with open(os.path.join(dst, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=1)


def unpack_attempts(src, dst):
    os.makedirs(dst)
    for xz in sorted(glob.glob(os.path.join(src, "attempts_*.npy.xz"))):
        name = os.path.basename(xz)[:-len(".npy.xz")]
        np.save(os.path.join(dst, name + ".npy"), _read_array(xz).astype(np.float32))
        shutil.copyfile(os.path.join(src, name + ".json"), os.path.join(dst, name + ".json"))
    shutil.copyfile(os.path.join(src, "manifest.json"), os.path.join(dst, "manifest.json"))


def pack(data, attempts, own_only, out):
    data, attempts = [d.rstrip("/") for d in data], [d.rstrip("/") for d in attempts]
    names = [os.path.basename(d) for d in data + attempts]
    if len(set(names)) != len(names):
        raise ValueError(f"folder names repeat: {names}")
    if os.path.exists(out):
        raise ValueError(f"{out} exists")
    os.makedirs(out)
    for d in data:
        pack_dataset(d, os.path.join(out, os.path.basename(d)))
    for d in attempts:
        pack_attempts(d, os.path.join(out, os.path.basename(d)), own_only)


UNPACKERS = {"dataset": unpack_dataset, "attempts": unpack_attempts}


def unpack(src, out):
    """Unpacks every folder of the pack `src` into `out`, each in its own
    process (xz and the float16 conversion use one core); returns (kind,
    path) pairs, kind "dataset" or "attempts"."""
    jobs = []
    for name in sorted(os.listdir(src)):
        path = os.path.join(src, name, "manifest.json")
        if not os.path.isfile(path):
            continue
        with open(path) as f:
            kind = json.load(f).get("packed", {}).get("kind")
        if kind not in UNPACKERS:
            raise ValueError(f"{src}/{name}: not a packed folder")
        jobs.append((kind, os.path.join(src, name), os.path.join(out, name)))
    if not jobs:
        raise ValueError(f"{src}: no packed folder in it")
    with concurrent.futures.ProcessPoolExecutor() as pool:
        for done in [pool.submit(UNPACKERS[kind], folder, target) for kind, folder, target in jobs]:
            done.result()
    return [(kind, target) for kind, _, target in jobs]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    a = sub.add_parser("pack")
    a.add_argument("--data", default="", help="sim datagen folders, comma-separated")
    a.add_argument("--physics", default="", help="sim eval --attempt-views folders, comma-separated")
    a.add_argument("--own-only", action="store_true", help="only the episodes' own attempts")
    a.add_argument("--out", required=True)
    b = sub.add_parser("unpack")
    b.add_argument("pack")
    b.add_argument("--out", required=True)
    args = p.parse_args(argv)
    split = lambda s: [x for x in s.split(",") if x]  # noqa: E731
    try:
        if args.command == "pack":
            pack(split(args.data), split(args.physics), args.own_only, args.out)
            print(f"{args.out}: {sum(os.path.getsize(f) for f in glob.glob(args.out + '/**', recursive=True) if os.path.isfile(f)) / 1e6:.1f} MB")
        else:
            for kind, path in unpack(args.pack, args.out):
                print(kind, path)
    except ValueError as e:
        raise SystemExit(str(e))


if __name__ == "__main__":
    sys.exit(main())
