"""Exports a trained network to ONNX with the mvgrasp model contract.

    python3 -m mvgrasp_train.export --run RUN_DIR --data DATASET --out models/mvgrasp-9.onnx \
        --version mvgrasp-9 [--golden models/golden-mvgrasp-9]

BatchNorm is folded into the convolutions first (and the graph is checked to
hold none); then every transposed convolution is rewritten in its sub-pixel
form, a 3x3 convolution and a DepthToSpace (`model.subpixel`: the same
function, measured faster on CPU; `--no-subpixel` keeps ConvTranspose),
except one whose kernel is its stride (`lite`'s last), kept as it is.
Then the 1x1 heads are moved before the last layer's pixel shuffle
(`phase_tail`: the same maps, the full-resolution tail's work done at 24 x
24). The batch axis is dynamic, opset 17, and the metadata carries
the contract `mvgrasp-core` reads (core/src/infer/contract.rs): input size,
metres per pixel, width scale, normalisation, output order, model and data
versions. onnxruntime's output must equal PyTorch's within 1e-4, else the
export fails. With --golden, two held-out views and PyTorch's maps for them
are written as .npy: the Rust test `golden_vectors_match_through_ort` feeds
the input through `ort` and compares.
"""

import argparse
import json
import os
import sys

import numpy as np
import onnx
import onnxruntime
import torch

from . import dataset, phase_tail, runs
from .model import GraspNet, fold_batchnorm, subpixel

TOLERANCE = 1e-4
OUTPUTS = "quality,cos2phi,sin2phi,width"


def contract_metadata(contract, version, data_version):
    return {
        "mvgrasp.input_size_px": str(contract["input_size_px"]),
        "mvgrasp.pixel_size_m": f"{contract['pixel_size_m']:.7g}",
        "mvgrasp.width_scale_m": f"{contract['width_scale_m']:.7g}",
        "mvgrasp.normalisation": contract["normalisation"],
        "mvgrasp.outputs": OUTPUTS,
        "mvgrasp.model_version": version,
        "mvgrasp.data_version": data_version,
    }


def export(model, size, path, metadata, sub_pixel=True):
    folded = fold_batchnorm(model)
    if sub_pixel:
        folded = subpixel(folded)
    example = torch.zeros(2, 1, size, size)
    torch.onnx.export(folded, (example,), path, input_names=["views"], output_names=["maps"],
                      dynamic_axes={"views": {0: "batch"}, "maps": {0: "batch"}}, opset_version=17,
                      do_constant_folding=True, dynamo=False)
    graph = onnx.load(path)
    ops = {n.op_type for n in graph.graph.node}
    if "BatchNormalization" in ops:
        raise SystemExit(f"{path}: BatchNormalization left in the graph")
    overlapping = [n.name for n in graph.graph.node if n.op_type == "ConvTranspose"
                   and [a.ints for a in n.attribute if a.name == "kernel_shape"]
                   != [a.ints for a in n.attribute if a.name == "strides"]]
    if sub_pixel and overlapping:
        raise SystemExit(f"{path}: ConvTranspose {overlapping} left in the sub-pixel graph")
    del graph.metadata_props[:]
    for key, value in metadata.items():
        entry = graph.metadata_props.add()
        entry.key, entry.value = key, value
    graph.producer_name = "mvgrasp_train"
    if sub_pixel:
        graph = phase_tail.rewrite(graph)
    onnx.checker.check_model(graph)
    onnx.save(graph, path)
    return sorted({n.op_type for n in graph.graph.node})


def compare(model, path, views):
    """Largest |onnxruntime - PyTorch| over `views`, and PyTorch's output."""
    model.eval()
    with torch.no_grad():
        expected = model(torch.from_numpy(views)).numpy()
    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = 1
    session = onnxruntime.InferenceSession(path, options, providers=["CPUExecutionProvider"])
    got = session.run(["maps"], {"views": views})[0]
    return float(np.abs(got - expected).max()), expected


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run", required=True, help="training run folder (model.pt)")
    p.add_argument("--data", required=True, help="the dataset it was trained on (contract, held-out views)")
    p.add_argument("--out", required=True)
    p.add_argument("--version", required=True, help="model version written into the metadata")
    p.add_argument("--data-version", help="data version for the metadata (default: --data's); e.g. "
                   "sim-3+sim-2 for a model trained on one set and fine-tuned on another")
    p.add_argument("--golden", help="folder for golden input.npy / output.npy")
    p.add_argument("--no-subpixel", action="store_true", help="keep the transposed convolutions as they are")
    args = p.parse_args(argv)

    try:
        saved = runs.load(args.run)
    except ValueError as e:
        raise SystemExit(f"--run: {e}")
    model = GraspNet(saved["architecture"])
    model.load_state_dict(saved["state_dict"])
    model.eval()
    ds = dataset.load(args.data, mmap=True)
    size = ds.contract["input_size_px"]
    metadata = contract_metadata(ds.contract, args.version, args.data_version or ds.manifest["data_version"])
    ops = export(model, size, args.out, metadata, sub_pixel=not args.no_subpixel)
    _, held = dataset.split_by_instance(ds.meta)
    # Two held-out views that have positives, plus a batch of 16 for the check.
    with_grasps = [i for i in held if ds.meta[i]["positives"] > 0]
    pick = with_grasps[:2] + with_grasps[len(with_grasps) // 2:][:14]
    views = np.ascontiguousarray(ds.views[pick], dtype=np.float32)
    worst, expected = compare(model, args.out, views)
    report = {"onnx": args.out, "bytes": os.path.getsize(args.out), "ops": ops, "max_abs_diff": worst,
              "tolerance": TOLERANCE, "metadata": metadata}
    print(json.dumps(report, indent=1))
    if worst > TOLERANCE:
        sys.exit(f"onnxruntime differs from PyTorch by {worst} > {TOLERANCE}")
    if args.golden:
        os.makedirs(args.golden, exist_ok=True)
        np.save(os.path.join(args.golden, "input.npy"), views[:2])
        np.save(os.path.join(args.golden, "output.npy"), expected[:2])
        with open(os.path.join(args.golden, "README.md"), "w") as f:
            f.write(f"# Golden vectors of `{os.path.basename(args.out)}` ({args.version})\n\n"
                    "`input.npy`: two held-out views `[2, 1, L, L]`; `output.npy`: PyTorch's maps for them "
                    "`[2, 4, L, L]` (quality, cos2phi, sin2phi, width).\nWritten by `python3 -m "
                    "mvgrasp_train.export ... --golden`; checked through `ort` by the Rust test "
                    "`golden_vectors_match_through_ort` (tests/e2e/onnx.rs) within "
                    f"{TOLERANCE}.\n")


if __name__ == "__main__":
    main()
