#!/usr/bin/env python3
"""Reads a `sim datagen` dataset with numpy alone, and checks it.

    python3 sim/python/read_dataset.py DATASET_DIR [--check]

The reader itself is `training/mvgrasp_train/dataset.py` (`load`,
`split_by_instance`, `check`); this is its command line. With --check, every
invariant of the format is verified and the exit code says whether they hold.
"""

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "training"))

from mvgrasp_train.dataset import check, load, summary  # noqa: E402


def main():
    ds = load(sys.argv[1])
    print(summary(ds))
    if "--check" in sys.argv:
        problems = check(ds)
        for p in problems:
            print(f"FAIL {p}")
        print("dataset check: every invariant holds" if not problems else f"dataset check: {len(problems)} problems")
        return 1 if problems else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
