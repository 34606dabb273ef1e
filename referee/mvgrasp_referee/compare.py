"""Two referee runs of the same episodes, side by side:
`python -m mvgrasp_referee.compare BASE/referee.json NEW/referee.json`.

Episodes are paired by (scenario, pool, camera, episode); the difference in
objects cleared gets a 95% interval from a paired bootstrap over episodes
(seeded, so the same files give the same interval).
"""

import argparse
import json
import random
from collections import defaultdict

from .report import cleared


def _key(e):
    return (e["scenario"], e["pool"], e["camera"], e["episode"])


def _attempts(e):
    tried = [a for a in e["attempts"] if a.get("outcome") not in (None, "no-grasp", "unreachable")]
    return len(tried), sum(a["outcome"] == "success" for a in tried)


def paired(base, new):
    """[(key, base episode, new episode)] for the episodes both runs hold."""
    b = {_key(e): e for e in base["episodes"]}
    n = {_key(e): e for e in new["episodes"]}
    missing = set(b) ^ set(n)
    if missing:
        raise SystemExit(f"compare: {len(missing)} episodes are in one run only, e.g. {sorted(missing)[0]}")
    return [(k, b[k], n[k]) for k in sorted(b)]


def bootstrap(diffs, rounds=2000, seed=7):
    """95% interval of the sum of `diffs` under resampling of the episodes."""
    if not diffs:
        return 0, 0
    rng = random.Random(seed)
    sums = sorted(sum(rng.choice(diffs) for _ in diffs) for _ in range(rounds))
    return sums[int(0.025 * rounds)], sums[int(0.975 * rounds) - 1]


def table(base, new):
    """Markdown rows: per scenario and in all, objects cleared, the paired
    difference with its interval, episodes better / worse, success per attempt."""
    groups = defaultdict(list)
    for k, b, n in paired(base, new):
        groups[k[0]].append((b, n))
        groups["all"].append((b, n))
    lines = ["| scenario | objects | cleared base | cleared new | difference (95%) | better / worse "
             "| success per attempt base | new |",
             "|---|---:|---:|---:|---|---|---:|---:|"]
    for name in [s for s in groups if s != "all"] + ["all"]:  # scenarios as the runs hold them
        pairs = groups[name]
        diffs = [cleared(n) - cleared(b) for b, n in pairs]
        lo, hi = bootstrap(diffs)
        rate = []
        for side in (0, 1):
            tried, held = map(sum, zip(*(_attempts(p[side]) for p in pairs)))
            rate.append(f"{held / tried:.3f} ({held}/{tried})" if tried else "-")
        lines.append(
            f"| {name} | {sum(b['initial'] for b, _ in pairs)} | {sum(cleared(b) for b, _ in pairs)} "
            f"| {sum(cleared(n) for _, n in pairs)} | {sum(diffs):+d} ({lo:+d} to {hi:+d}) "
            f"| {sum(d > 0 for d in diffs)} / {sum(d < 0 for d in diffs)} | {rate[0]} | {rate[1]} |")
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(prog="referee-compare", description=__doc__.splitlines()[0])
    p.add_argument("base")
    p.add_argument("new")
    args = p.parse_args(argv)
    with open(args.base) as f:
        base = json.load(f)
    with open(args.new) as f:
        new = json.load(f)
    print(table(base, new))


if __name__ == "__main__":
    main()
