"""Average the weights of training runs into one run (a "model soup").

    python3 -m mvgrasp_train.soup --runs RUN_A,RUN_B[,...] --out RUN_DIR

The runs must share an architecture, and should share a starting point
(fine-tunes of one `--init`): the mean of unrelated networks' weights is not
a network. Floating-point tensors are averaged; integer buffers (BatchNorm's
step counts) are taken from the first run. RUN_DIR/model.pt is what `export
--run RUN_DIR` reads; RUN_DIR/config.json names the runs. Measured once
(docs/experiments/2026-11-27-fifth-physics-round.md, "A fifth physics round"): the mean of qc and qe, two
fine-tunes of p2 with the physics term at 0.3 and none, scored views
between the two.
"""

import argparse
import json
import os
import sys

from . import runs


def average(state_dicts):
    """The element-wise mean of floating-point tensors of `state_dicts`
    (same keys and shapes), other tensors from the first."""
    first = state_dicts[0]
    for other in state_dicts[1:]:
        if other.keys() != first.keys():
            raise ValueError("the runs' networks differ in their tensors")
        for k, v in first.items():
            if other[k].shape != v.shape:
                raise ValueError(f"{k}: shape {tuple(other[k].shape)} against {tuple(v.shape)}")
    return {k: (sum(sd[k] for sd in state_dicts) / len(state_dicts)) if v.is_floating_point() else v.clone()
            for k, v in first.items()}


def soup(run_dirs, out):
    saved = [runs.load(r) for r in run_dirs]
    kinds = {s["architecture"] for s in saved}
    if len(kinds) != 1:
        raise ValueError(f"the runs' architectures differ: {sorted(kinds)}")
    state = average([s["state_dict"] for s in saved])
    runs.save(out, saved[0]["architecture"], state, saved[0]["frozen_batchnorm"])
    with open(os.path.join(out, "config.json"), "w") as f:
        json.dump({"soup_of": [os.path.abspath(r) for r in run_dirs], "architecture": saved[0]["architecture"]}, f,
                  indent=1)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", required=True, help="comma-separated run folders (model.pt each)")
    p.add_argument("--out", required=True, help="run folder to write")
    args = p.parse_args(argv)
    run_dirs = [r for r in args.runs.split(",") if r]
    if len(run_dirs) < 2:
        p.error("--runs needs two runs or more")
    try:
        soup(run_dirs, args.out)
    except (OSError, ValueError) as e:
        print(f"soup: {e}", file=sys.stderr)
        return 1
    print(f"wrote {os.path.join(args.out, runs.MODEL)}: the mean of {len(run_dirs)} runs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
