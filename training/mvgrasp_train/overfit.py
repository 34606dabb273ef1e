"""Can the network fit a few training views? A capacity and loss check.

    python3 -m mvgrasp_train.overfit --data DATASET [--views 256] [--epochs 100] \
        [--architecture paper] [--positive-weight 1] [--threads 1]

Trains a fresh network, without augmentation, on `--views` training views
that have positives (the 80/20 split's training side, bowls left out) and
prints the paper's accuracy on those same views every 25 epochs. A network
that cannot reach near 100% here cannot be limited by generalisation.
"""

import argparse
import json
import time

import numpy as np
import torch

from . import dataset, metric
from .model import ARCHITECTURES, GraspNet
from .train import weighted_mse


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", required=True)
    p.add_argument("--views", type=int, default=256)
    p.add_argument("--epochs", type=int, default=100)
    p.add_argument("--architecture", choices=ARCHITECTURES, default="paper")
    p.add_argument("--positive-weight", type=float, default=1.0)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    ds = dataset.load(args.data, mmap=True)
    train, _ = dataset.split_by_instance(ds.meta)
    train = [i for i in train if ds.meta[i]["family"] != "bowl" and len(ds.grasps_of(i)) > 0]
    rng = np.random.default_rng(args.seed)
    idx = sorted(rng.choice(train, min(args.views, len(train)), replace=False).tolist())
    x = torch.from_numpy(np.asarray(ds.views[idx]))
    y = torch.from_numpy(np.asarray(ds.maps[idx]))
    model = GraspNet(args.architecture)
    optimiser = torch.optim.Adam(model.parameters(), lr=1e-3)
    started = time.time()
    for epoch in range(1, args.epochs + 1):
        model.train()
        order = torch.randperm(len(idx))
        losses = []
        for s in range(0, len(idx), 32):
            batch = order[s:s + 32]
            optimiser.zero_grad()
            loss = weighted_mse(model(x[batch]), y[batch], args.positive_weight)
            loss.backward()
            optimiser.step()
            losses.append(float(loss.detach()))
        if epoch % 25 == 0 or epoch == args.epochs:
            model.eval()
            with torch.no_grad():
                pred = torch.cat([model(x[s:s + 64]) for s in range(0, len(idx), 64)]).numpy()
            result = metric.evaluate(pred, ds, idx)
            print(json.dumps({"epoch": epoch, "loss": float(np.mean(losses)), "accuracy": result["accuracy"],
                              "per_view": {a: v["accuracy"] for a, v in result["per_view"].items()},
                              "elapsed_s": round(time.time() - started)}), flush=True)


if __name__ == "__main__":
    main()
