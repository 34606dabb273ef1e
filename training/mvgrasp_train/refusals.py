"""Why the labeller refused the candidates of a dataset's views.

    python3 -m mvgrasp_train.refusals --data DATASET [--few 20] [--hold-out-families bowl]

`sim datagen` counts, per view, each candidate grasp that was not positive
by why `label_grasp` refused it (meta.jsonl's `refused`: "object: pad",
"no pose", "over stroke", ...; sim/src/targets.rs). This prints, as shares
of the candidates, the positives and every reason: over all views, per view
direction, per family and direction (with how many views have only 1 to
`--few` positives, and none), and for the views with 1 to `--few` positives
against the rest. Every view of the dataset counts (no split), without the
families of `--hold-out-families`. Shards written before the counts existed
(2026-11-25) are refused with a message.
"""

import argparse
import collections
import sys

from . import dataset


def shares(meta, indices):
    """Candidates of views `indices`, and the share of them positive and
    refused for each reason, largest first: (candidates, [(reason, share)])
    with "positive" first."""
    refused = collections.Counter()
    candidates = positives = 0
    for i in indices:
        m = meta[i]
        refused.update(m["refused"])
        candidates += m["candidates"]
        positives += m["positives"]
    n = max(candidates, 1)
    ranked = sorted(refused.items(), key=lambda kv: (-kv[1], kv[0]))
    return candidates, [("positive", positives / n)] + [(k, v / n) for k, v in ranked]


def line(title, meta, indices):
    candidates, parts = shares(meta, indices)
    return (f"{title}: {len(indices)} views, {candidates} candidates: "
            + ", ".join(f"{k} {100 * s:.1f}%" for k, s in parts))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", required=True)
    p.add_argument("--few", type=int, default=20, help="views with 1 to this many positives are 'few'")
    p.add_argument("--hold-out-families", default="bowl", help="left out (comma-separated)")
    args = p.parse_args(argv)
    ds = dataset.load(args.data, mmap=True)
    if any("refused" not in m for m in ds.meta):
        raise SystemExit(f"{args.data}: views without refusal counts (made before sim datagen wrote them)")
    out = {f for f in args.hold_out_families.split(",") if f}
    views = [i for i, m in enumerate(ds.meta) if m["family"] not in out]

    def few(i):
        return 0 < ds.meta[i]["positives"] <= args.few

    print(line("all", ds.meta, views))
    axes = ("top", "front", "side")
    for axis in axes:
        print(line(axis, ds.meta, [i for i in views if ds.meta[i]["view"] == axis]))
    for family in sorted({ds.meta[i]["family"] for i in views}):
        for axis in axes:
            sel = [i for i in views if ds.meta[i]["family"] == family and ds.meta[i]["view"] == axis]
            if sel:
                none = sum(ds.meta[i]["positives"] == 0 for i in sel)
                print(line(f"{family} {axis} ({sum(map(few, sel))} few, {none} none)", ds.meta, sel))
    print(line(f"views with 1-{args.few} positives", ds.meta, [i for i in views if few(i)]))
    print(line(f"views with more than {args.few}", ds.meta,
               [i for i in views if ds.meta[i]["positives"] > args.few]))


if __name__ == "__main__":
    sys.exit(main())
