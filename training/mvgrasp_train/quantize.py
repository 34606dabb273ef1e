"""int8 copy of an exported grasp network (ONNX Runtime static quantization).

    python3 -m mvgrasp_train.quantize --onnx ../models/M.onnx --data D1,D2 --out M-int8.onnx \
        [--views 512] [--format qdq|qoperator] [--per-channel] [--golden DIR]

Calibrates activation ranges on `--views` training views of `--data` (the
80% split by object instance, so the held-out views stay unseen), quantizes
weights and activations to int8 up to the output heads (which stay
float: their one tensor holds quality logits, angles and widths), keeps the model contract (`mvgrasp.*`
metadata, `-int8` added to the model version) and prints how far the int8
maps land from the float model's on held-out views: max and mean absolute
difference per output channel. Needs numpy, onnx and onnxruntime, not
PyTorch.
"""

import argparse
import json
import os
import tempfile

import numpy as np
import onnx
import onnxruntime
from onnxruntime import quantization

from . import dataset


class Views(quantization.CalibrationDataReader):
    """The calibration views, a batch of 16 at a time."""

    def __init__(self, views, batch=16):
        self._batches = iter([views[i:i + batch] for i in range(0, len(views), batch)])

    def get_next(self):
        batch = next(self._batches, None)
        return None if batch is None else {"views": batch}


def sample_views(ds, indices, count, seed):
    """`count` of the views at `indices` (float32 [n, 1, s, s]), drawn without repeats."""
    rng = np.random.default_rng(seed)
    chosen = np.sort(rng.choice(np.asarray(indices), size=min(count, len(indices)), replace=False))
    return np.ascontiguousarray(ds.views[chosen], dtype=np.float32)


def head_and_after(model):
    """Names of the last convolution (the 1x1 heads) and of every node after it.

    Its output holds the quality logits and the angle and width channels in
    one tensor; one int8 scale for all of them would leave the width a few
    centimetres per step, so the heads stay in float.
    """
    last = max(i for i, n in enumerate(model.graph.node) if n.op_type == "Conv")
    return [n.name for n in model.graph.node[last:] if n.op_type != "Constant"]


def quantize(src, dst, calibration, fmt="qdq", per_channel=True):
    """Writes the int8 model of `src` to `dst` (the heads in float), its metadata kept and its version marked."""
    with tempfile.TemporaryDirectory() as tmp:
        prepared = os.path.join(tmp, "prepared.onnx")
        quantization.quant_pre_process(src, prepared, skip_symbolic_shape=True)
        quantization.quantize_static(
            prepared,
            dst,
            Views(calibration),
            quant_format=quantization.QuantFormat.QDQ if fmt == "qdq" else quantization.QuantFormat.QOperator,
            per_channel=per_channel,
            activation_type=quantization.QuantType.QUInt8,
            weight_type=quantization.QuantType.QInt8,
            calibrate_method=quantization.CalibrationMethod.MinMax,
            nodes_to_exclude=head_and_after(onnx.load(prepared)),
        )
    source = onnx.load(src)
    model = onnx.load(dst)
    del model.metadata_props[:]
    for entry in source.metadata_props:
        value = entry.value + "-int8" if entry.key == "mvgrasp.model_version" else entry.value
        model.metadata_props.add(key=entry.key, value=value)
    onnx.save(model, dst)


def differences(float_path, int8_path, views):
    """Per output channel, the max and mean |int8 - float| over `views`."""
    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = 1
    run = {p: onnxruntime.InferenceSession(p, options, providers=["CPUExecutionProvider"])
           for p in (float_path, int8_path)}
    a = run[float_path].run(None, {"views": views})[0]
    b = run[int8_path].run(None, {"views": views})[0]
    names = run[float_path].get_modelmeta().custom_metadata_map["mvgrasp.outputs"].split(",")
    gap = np.abs(a - b)
    return {name: {"max": float(gap[:, k].max()), "mean": float(gap[:, k].mean())} for k, name in enumerate(names)}


def write_golden(path, views, folder):
    """`views` and `path`'s maps for them (onnxruntime, one thread) as `folder`/input.npy, output.npy."""
    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = 1
    session = onnxruntime.InferenceSession(path, options, providers=["CPUExecutionProvider"])
    os.makedirs(folder, exist_ok=True)
    np.save(os.path.join(folder, "input.npy"), views)
    np.save(os.path.join(folder, "output.npy"), session.run(None, {"views": views})[0])
    version = session.get_modelmeta().custom_metadata_map["mvgrasp.model_version"]
    with open(os.path.join(folder, "README.md"), "w") as f:
        f.write(f"# Golden vectors of `{os.path.basename(path)}` ({version})\n\n"
                "`input.npy`: two held-out views `[2, 1, L, L]`; `output.npy`: onnxruntime's maps for them "
                "`[2, 4, L, L]` (quality, cos2phi, sin2phi, width), from the int8 file itself (its distance "
                "from the float file is the quantizer's report, in models/MODEL_CARD.md).\nWritten by "
                "`python3 -m mvgrasp_train.quantize ... --golden`; checked through `ort` by the Rust test "
                "`golden_vectors_match_through_ort` (tests/e2e/onnx.rs).\n")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--onnx", required=True, help="the float model (an export of mvgrasp_train.export)")
    p.add_argument("--data", required=True, help="dataset folders to calibrate on (comma-separated)")
    p.add_argument("--out", required=True)
    p.add_argument("--views", type=int, default=512, help="calibration views (training split)")
    p.add_argument("--check-views", type=int, default=512, help="held-out views the difference is measured on")
    p.add_argument("--format", choices=("qdq", "qoperator"), default="qdq")
    p.add_argument("--per-channel", action=argparse.BooleanOptionalAction, default=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--golden", metavar="DIR",
                   help="also write two held-out views and the int8 file's maps for them (onnxruntime's)")
    args = p.parse_args(argv)
    ds = dataset.load(args.data)
    train_idx, eval_idx = dataset.split_by_instance(ds.meta)
    quantize(args.onnx, args.out, sample_views(ds, train_idx, args.views, args.seed), args.format, args.per_channel)
    held_out = sample_views(ds, eval_idx, args.check_views, args.seed + 1)
    if args.golden:
        write_golden(args.out, held_out[:2], args.golden)
    print(json.dumps({"out": args.out, "format": args.format, "per_channel": args.per_channel,
                      "calibration_views": min(args.views, len(train_idx)),
                      "difference_on_held_out": differences(args.onnx, args.out, held_out)}))


if __name__ == "__main__":
    main()
