"""Physics outcomes of the planner's own grasps, to learn from.

    sim eval --model M --settings all:0.1 ... --attempt-views DIR

writes, per episode of the first setting, `attempts_SCENARIO_SEED.npy`
(float32 `[n, L, L]`: the view each attempt's grasp came from, exactly as
the network read it) and `attempts_SCENARIO_SEED.json` (per row the quality
peak `pixel` `[u, v]` the grasp came from and the `outcome`: "ok" when
physics carried the object to the basket), plus `manifest.json` with the
model contract. `train --physics DIR` then pulls the network's quality at
those pixels (as the planner smooths it) towards the outcome: 1 held, 0
failed.

The MuJoCo referee writes the same (`scripts/referee.sh --pools train
--attempt-views DIR`), its outcomes named as in its report ("empty",
"dropped-carry", "slip-shake", ...): pass those as `failures`
(`train --physics-failures`).

Only the failures the network can be blamed for count as 0 by default: a
slip during lift, an opening too small, and a pad or the palm meeting the
grasped object itself on the approach. A collision with a neighbour or
the table depends on what the object-centred view does not show, and an
object missed on the segmentation; those rows are left out. Numpy only.

    python3 -m mvgrasp_train.physics DIR [DIR ...]

checks folders (every row readable, as many rows as the manifest says)
and prints what they hold.
"""

import argparse
import glob
import json
import os
import sys
from dataclasses import dataclass, field

import numpy as np

HELD = "ok"
# Outcome prefixes: a collision's outcome names what was hit, with which part, where.
NETWORK_FAILURES = ("slip during lift", "width too small", "collision on approach: the object")
# Format 2 adds each row's `rank` on its frame and rows for grasps ranked below the
# tried one (`alternative` true).
FORMATS = ("mvgrasp-attempt-views-1", "mvgrasp-attempt-views-2")


@dataclass
class Attempts:
    """Attempts with their views: `views` `[n, L, L]`, `pixels` `[n, 2]`
    (u, v), `held` `[n]` (1.0 or 0.0), and each row's record."""
    views: np.ndarray
    pixels: np.ndarray
    held: np.ndarray
    records: list = field(default_factory=list)
    contract: dict = field(default_factory=dict)

    def __len__(self):
        return len(self.held)


def read_manifest(d):
    """The `manifest.json` of the `--attempt-views` folder `d`; ValueError
    when there is none or its format is not one this reader knows."""
    path = os.path.join(d, "manifest.json")
    if not os.path.exists(path):
        raise ValueError(f"{d}: no manifest.json (not a sim eval --attempt-views folder)")
    with open(path) as f:
        manifest = json.load(f)
    if manifest.get("format") not in FORMATS:
        raise ValueError(f"{d}: format {manifest.get('format')!r}, not one of {FORMATS} "
                         "(not a sim eval --attempt-views folder)")
    return manifest


def episodes(d, size):
    """Each episode file of the folder `d` in name order: (path of its
    .npy, its views `[n, size, size]`, its n rows). ValueError when the
    views and rows disagree."""
    for npy in sorted(glob.glob(os.path.join(d, "attempts_*.npy"))):
        v = np.load(npy)
        with open(npy[:-4] + ".json") as f:
            rows = json.load(f)
        if v.shape != (len(rows), size, size):
            raise ValueError(f"{npy}: views {v.shape} for {len(rows)} rows of {size} px")
        yield npy, v, rows


def load(dirs, failures=NETWORK_FAILURES, alternatives=True):
    """The attempts of one or more `--attempt-views` folders (a list or a
    comma-separated string) that held or whose outcome starts with one of
    `failures`; with `alternatives` False, the episodes' own attempts only
    (not the grasps ranked below them, `sim eval --attempt-alternatives`).
    Raises ValueError for a folder that is not one, rows that disagree with
    their views, pixels outside the view, or folders with different
    contracts."""
    if isinstance(dirs, str):
        dirs = [d for d in dirs.split(",") if d]
    views, pixels, held, records, contract = [], [], [], [], None
    for d in dirs:
        theirs = read_manifest(d)["contract"]
        if contract is None:
            contract = theirs
        elif theirs != contract:
            raise ValueError(f"{d}: contract {theirs} differs from {contract}")
        size = int(theirs["input_size_px"])
        for npy, v, rows in episodes(d, size):
            for k, r in enumerate(rows):
                u, vv = r["pixel"]
                if not (0 <= u < size and 0 <= vv < size):
                    raise ValueError(f"{npy}: row {k} pixel {r['pixel']} outside the {size} px view")
                if r["outcome"] != HELD and not any(r["outcome"].startswith(f) for f in failures):
                    continue
                if not alternatives and r.get("alternative"):
                    continue
                views.append(v[k])
                pixels.append((u, vv))
                held.append(1.0 if r["outcome"] == HELD else 0.0)
                records.append({**r, "file": os.path.basename(npy)})
    if contract is None:
        raise ValueError("no --attempt-views folder given")
    size = int(contract["input_size_px"])
    return Attempts(
        views=np.asarray(views, dtype=np.float32).reshape(-1, size, size),
        pixels=np.asarray(pixels, dtype=np.int64).reshape(-1, 2),
        held=np.asarray(held, dtype=np.float32),
        records=records,
        contract=contract,
    )


def check_contract(attempts, contract):
    """Problems (a list of strings) between the attempts' contract and a
    dataset's: the network must read the same views."""
    return contract_problems(attempts.contract, contract)


def contract_problems(theirs, contract):
    """Problems (a list of strings) between an `--attempt-views` folder's
    contract `theirs` and a dataset's `contract`."""
    keys = ("input_size_px", "pixel_size_m", "normalisation")
    return [f"{k}: attempts {theirs.get(k)!r}, data {contract.get(k)!r}"
            for k in keys
            if not (np.isclose(theirs.get(k), contract.get(k)) if k == "pixel_size_m"
                    else theirs.get(k) == contract.get(k))]


def symmetry(views, pixels, k):
    """One of the 8 symmetries of the square (`k` in 0..8: bit 1 mirrors
    u, bit 2 mirrors v, bit 4 swaps them, in that order) applied to views
    `[n, L, L]` (indexed [v, u]) and their pixels `[n, 2]` alike. The
    quality at a pixel does not depend on the angle, so nothing else
    changes."""
    size = views.shape[-1]
    pixels = pixels.copy()
    if k & 1:
        views = views[:, :, ::-1]
        pixels[:, 0] = size - 1 - pixels[:, 0]
    if k & 2:
        views = views[:, ::-1, :]
        pixels[:, 1] = size - 1 - pixels[:, 1]
    if k & 4:
        views = views.transpose(0, 2, 1)
        pixels = pixels[:, ::-1]
    return np.ascontiguousarray(views), np.ascontiguousarray(pixels)


def symmetry_each(views, pixels, ks):
    """`symmetry` with its own index `ks[i]` per row (rows grouped by index)."""
    views, pixels = views.copy(), pixels.copy()
    for k in np.unique(ks):
        rows = np.flatnonzero(ks == k)
        views[rows], pixels[rows] = symmetry(views[rows], pixels[rows], int(k))
    return views, pixels


def gaussian_kernel(sigma_px):
    """The planner's quality smoothing (`DecodeConfig::smoothing_sigma_px`)
    as a normalised 1-D kernel of radius ceil(3 sigma), as
    `core::decode::smooth`; sigma <= 0 (no smoothing) gives `[1]`."""
    if sigma_px <= 0:
        return np.ones(1, dtype=np.float32)
    radius = int(np.ceil(3 * sigma_px))
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    k = np.exp(-0.5 * (x / sigma_px) ** 2)
    return (k / k.sum()).astype(np.float32)


def summary(attempts):
    """One line: rows, held share, rows per outcome."""
    outcomes = {}
    for r in attempts.records:
        kind = r["outcome"].split(" (")[0]  # a collision by what was hit, not with which part or where
        outcomes[kind] = outcomes.get(kind, 0) + 1
    held = float(attempts.held.mean()) if len(attempts) else float("nan")
    ranked = sum(bool(r.get("alternative")) for r in attempts.records)
    return f"{len(attempts)} attempts ({ranked} of them alternatives), {100 * held:.1f}% held; " + ", ".join(
        f"{k} {v}" for k, v in sorted(outcomes.items()))


def main(argv=None):
    p = argparse.ArgumentParser(description="Check sim eval --attempt-views folders and say what they hold.")
    p.add_argument("dirs", nargs="+")
    args = p.parse_args(argv)
    for d in args.dirs:
        try:
            every = load(d, failures=("",))
            used = load(d)
        except ValueError as e:
            raise SystemExit(str(e))
        with open(os.path.join(d, "manifest.json")) as f:
            want = json.load(f).get("attempts")
        if want != len(every):
            raise SystemExit(f"{d}: {len(every)} rows, the manifest says {want}")
        print(f"{d}: {summary(every)}; learned from (held, or failed as {NETWORK_FAILURES}): {len(used)}")


if __name__ == "__main__":
    sys.exit(main())
