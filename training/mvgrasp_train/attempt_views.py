"""The views of `--attempt-views` folders as a dataset without labels: the
views the planner fed the network, for `train --teacher T.onnx
--label-weight 0` to distil a network on them.

    python3 -m mvgrasp_train.attempt_views --like DATASET --out DIR AV_DIR [AV_DIR ...]

Every row of every folder (tried grasps, the alternatives ranked below them
and whatever their outcome) gives its view, as it was, to one view of the
new dataset (`sim datagen`'s format 2, one shard): maps zero, no labelled
grasps, meta naming the object (`instance` = folder name and target, so the
80/20 split keeps an object's views together). The contract, gripper and
data version come from `--like`, the dataset it will be trained beside
(`dataset.merge` refuses parts that differ); a folder whose contract
differs from it is refused.
"""

import argparse
import json
import os
import sys

import numpy as np

from . import dataset, physics


def write(folders, like, out):
    """Writes the dataset; returns its number of views. ValueError for a
    folder that is not one or whose views the `like` dataset's network
    could not read."""
    base = dataset.read_manifest(like)
    contract = base["contract"]
    size = int(contract["input_size_px"])
    views, meta = [], []
    for d in folders:
        problems = physics.contract_problems(physics.read_manifest(d)["contract"], contract)
        if problems:
            raise ValueError(f"{d}: {problems}")
        name = os.path.basename(os.path.normpath(d))
        for npy, v, rows in physics.episodes(d, size):
            stem = os.path.basename(npy)[:-4]
            for k, r in enumerate(rows):
                views.append(v[k])
                meta.append({"family": "attempt-views", "instance": f"{name}:{r.get('target', stem)}",
                             "positives": 0, "view": r["view"], "scenario": "attempt-views", "source": stem})
    if not views:
        raise ValueError("no attempt rows in " + ", ".join(folders))
    n = len(views)
    shard = os.path.join(out, "shard_00000")
    os.makedirs(shard, exist_ok=True)
    np.save(os.path.join(shard, "views.npy"), np.asarray(views, np.float32).reshape(n, 1, size, size))
    np.save(os.path.join(shard, "maps.npy"), np.zeros((n, 4, size, size), np.float32))
    np.save(os.path.join(shard, "grasps.npy"), np.zeros((0, 6), np.float32))
    with open(os.path.join(shard, "meta.jsonl"), "w") as f:
        f.writelines(json.dumps(m) + "\n" for m in meta)
    manifest = {key: base[key] for key in ("format_version", "contract", "gripper", "data_version") if key in base}
    manifest.update(shards=["shard_00000"], views=n, views_with_positives=0, failed_scenes=[],
                    generator={"attempt_views": [os.path.abspath(d) for d in folders]})
    with open(os.path.join(out, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=1)
    return n


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--like", required=True, help="the dataset it will be trained beside (contract, gripper, data version)")
    p.add_argument("--out", required=True)
    p.add_argument("folders", nargs="+", help="--attempt-views folders (sim eval or scripts/referee.sh)")
    args = p.parse_args(argv)
    try:
        n = write(args.folders, args.like, args.out)
    except ValueError as e:
        raise SystemExit(str(e))
    ds = dataset.load(args.out)
    problems = dataset.check(ds)
    if problems:
        raise SystemExit(f"{args.out}: {problems}")
    print(f"{n} views: {dataset.summary(ds)}", file=sys.stderr)


if __name__ == "__main__":
    main()
