"""Reads an exported network back into PyTorch, to fine-tune it.

    python3 -m mvgrasp_train.import_onnx --onnx ../models/mvgrasp-8.onnx --architecture narrow --out RUN_DIR

The export folds each BatchNorm into its convolution and rewrites every
transposed convolution in its sub-pixel form (export.py, model.subpixel).
This undoes both: each transposed kernel tap is read back from the one
sub-pixel tap it went to, and each BatchNorm becomes the identity with the
folded bias as its shift (weight 1, running mean 0, running variance
1 - eps). The result computes what the file computes; it is checked
against onnxruntime within 1e-4 before RUN_DIR/model.pt is written, marked
`frozen_batchnorm`: `train --init RUN_DIR` then keeps the BatchNorm layers
in inference mode (their running statistics are not a batch's, so training
mode would change the function), their scale and shift still learned.
"""

import argparse
import json
import os
import sys

import numpy as np
import onnx
import torch
from onnx import numpy_helper
from torch import nn

from . import runs
from .export import TOLERANCE, compare
from .model import ARCHITECTURES, GraspNet, subpixel_taps


def convolutions(path):
    """(weight, bias) of every Conv node of the graph, in graph order."""
    graph = onnx.load(path).graph
    init = {t.name: numpy_helper.to_array(t).copy() for t in graph.initializer}
    out = []
    for node in graph.node:
        if node.op_type == "Conv":
            if len(node.input) < 3 or node.input[1] not in init or node.input[2] not in init:
                raise SystemExit(f"{path}: Conv {node.name} without constant weight and bias")
            out.append((init[node.input[1]], init[node.input[2]]))
    return out


def from_onnx(path, architecture):
    """A GraspNet computing what the exported file at `path` computes."""
    model = GraspNet(architecture).eval()
    convs = convolutions(path)
    blocks = list(model.body)
    if len(convs) != len(blocks) + 1:
        raise SystemExit(f"{path}: {len(convs)} convolutions, the {architecture} network has {len(blocks) + 1}")
    with torch.no_grad():
        for block, (w, b) in zip(blocks, convs):
            conv, bn = block[0], block[1]
            if isinstance(conv, nn.ConvTranspose2d):
                (k, _), (s, _) = conv.kernel_size, conv.stride
                cin, cout = conv.in_channels, conv.out_channels
                if w.shape != (cout * s * s, cin, 3, 3):
                    raise SystemExit(f"{path}: sub-pixel weight {w.shape}, expected {(cout * s * s, cin, 3, 3)}")
                sub = torch.from_numpy(w).reshape(cout, s, s, cin, 3, 3)
                weight = torch.zeros(cin, cout, k, k)
                # The inverse of model.subpixel's tap mapping.
                for (ry, rx, ty, tx), (ky, kx) in subpixel_taps(k, s):
                    weight[:, :, ky, kx] = sub[:, ry, rx, :, ty, tx].t()
                bias = torch.from_numpy(b).reshape(cout, s * s)[:, 0]
            else:
                if w.shape != tuple(conv.weight.shape):
                    raise SystemExit(f"{path}: weight {w.shape}, expected {tuple(conv.weight.shape)}")
                weight, bias = torch.from_numpy(w), torch.from_numpy(b)
            conv.weight.copy_(weight)
            bn.weight.fill_(1.0)
            bn.bias.copy_(bias)
            bn.running_mean.zero_()
            bn.running_var.fill_(1.0 - bn.eps)
        w, b = convs[-1]
        model.heads.weight.copy_(torch.from_numpy(w))
        model.heads.bias.copy_(torch.from_numpy(b))
    return model


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--onnx", required=True)
    p.add_argument("--architecture", choices=[a for a in ARCHITECTURES if a not in ("skip", "lite")], required=True,
                   help="the file's network (a `skip` or `lite` file cannot be read back yet)")
    p.add_argument("--out", required=True, help="run folder for model.pt")
    args = p.parse_args(argv)
    model = from_onnx(args.onnx, args.architecture)
    size = int({e.key: e.value for e in onnx.load(args.onnx).metadata_props}["mvgrasp.input_size_px"])
    # Depth-like views: a table at 0 and a few raised blobs, plus noise.
    rng = np.random.default_rng(0)
    views = np.zeros((8, 1, size, size), np.float32)
    yy, xx = np.mgrid[0:size, 0:size]
    for v in views:
        for _ in range(3):
            cy, cx, r = rng.uniform(0.2 * size, 0.8 * size, 2).tolist() + [rng.uniform(4, size / 4)]
            v[0] += (((yy - cy) ** 2 + (xx - cx) ** 2) < r * r) * rng.uniform(0.1, 0.6)
        v[0] += rng.normal(0, 0.01, (size, size))
    worst, _ = compare(model, args.onnx, views)
    print(json.dumps({"onnx": args.onnx, "architecture": args.architecture, "max_abs_diff": worst}))
    if worst > TOLERANCE:
        sys.exit(f"the imported network differs from the file by {worst} > {TOLERANCE}")
    runs.save(args.out, args.architecture, model.state_dict(), True, imported_from=os.path.abspath(args.onnx))


if __name__ == "__main__":
    main()
