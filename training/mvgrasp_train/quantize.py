"""int8 copy of an exported grasp network (ONNX Runtime static quantization).

    python3 -m mvgrasp_train.quantize --onnx ../models/M.onnx --data D1,D2 --out M-int8.onnx \
        [--views 512] [--calibration percentile|minmax] [--format qdq|qoperator] [--per-channel] [--golden DIR]
    python3 -m mvgrasp_train.quantize --onnx ../models/M.onnx --data D1,D2 --out M-int8.onnx --measure

Calibrates activation ranges on `--views` training views of `--data` (the
80% split by object instance, so the held-out views stay unseen; each
range the 0.01-99.99th percentile by default, `--calibration minmax` the
whole range), quantizes weights and activations to int8 up to the output
heads (which stay float: their one tensor holds quality logits, angles
and widths), keeps the model contract (`mvgrasp.*` metadata, `-int8`
added to the model version) and prints how far the int8 maps land from
the float model's on held-out views: max and mean absolute difference per
output channel, and how often the best quality pixel stays put
(`--measure`: the same figures for an int8 file already made). Needs
numpy, onnx and onnxruntime, not PyTorch.
"""

import argparse
import json
import os
import tempfile

import numpy as np
import onnx
from onnx import numpy_helper
from onnxruntime import quantization

from . import dataset
from .flip_wrap import session


CALIBRATION = {"percentile": quantization.CalibrationMethod.Percentile,
               "minmax": quantization.CalibrationMethod.MinMax}
# The share of each activation's calibration values inside its range, in percent.
PERCENTILE = 99.99


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


def relu_before_shuffle(model):
    """A copy of `model` with each `DepthToSpace -> Relu` run as `Relu -> DepthToSpace`.

    The same function (a ReLU acts on each value alone, a shuffle only moves
    them), but the convolution before the shuffle now feeds a ReLU directly:
    the quantizer then gives its output the ReLU's range (non-negative, twice
    the steps of a range with the negatives), and the shuffle moves 8-bit
    values instead of float ones.
    """
    model = onnx.ModelProto.FromString(model.SerializeToString())
    nodes = list(model.graph.node)
    readers = {}
    for n in nodes:
        for name in n.input:
            readers.setdefault(name, []).append(n)
    outputs = {o.name for o in model.graph.output}
    for i, shuffle in enumerate(nodes[:-1]):
        relu = nodes[i + 1]
        if (shuffle.op_type != "DepthToSpace" or relu.op_type != "Relu" or relu.input[0] != shuffle.output[0]
                or len(readers[shuffle.output[0]]) != 1 or shuffle.output[0] in outputs):
            continue
        features, activated = shuffle.input[0], relu.output[0]
        relu.input[0], relu.output[0] = features, shuffle.output[0]
        shuffle.input[0], shuffle.output[0] = shuffle.output[0], activated
        nodes[i], nodes[i + 1] = relu, shuffle
    del model.graph.node[:]
    model.graph.node.extend(nodes)
    del model.graph.value_info[:]
    onnx.checker.check_model(model)
    return model


def equalize_heads_input(model, views, widest=100.0):
    """A copy of `model` whose last layer's channels reach one range on `views`.

    The 1x1 heads (float) read the last layer's ReLU output, which int8
    quantizes with one scale for all its channels: a channel whose values
    stay small gets a few steps of it. A ReLU commutes with a positive
    factor, so each channel's weights and bias are multiplied by the widest
    channel's range over its own (at most `widest`, for channels that
    hardly fire) and the heads' weights for it divided by the same: the same
    function in float, every channel spread over the int8 range. Returns
    `model` unchanged (a copy) when the heads do not read a ReLU of a Conv.
    """
    model = onnx.ModelProto.FromString(model.SerializeToString())
    graph = model.graph
    producer = {out: n for n in graph.node for out in n.output}
    heads = [n for n in graph.node if n.op_type == "Conv"][-1]
    relu = producer.get(heads.input[0])
    layer = producer.get(relu.input[0]) if relu is not None and relu.op_type == "Relu" else None
    inits = {t.name: t for t in graph.initializer}
    if layer is None or layer.op_type != "Conv" or len(layer.input) < 3 or heads.input[1] not in inits:
        return model
    probe = onnx.ModelProto.FromString(model.SerializeToString())
    probe.graph.output.append(onnx.helper.make_tensor_value_info(heads.input[0], onnx.TensorProto.FLOAT, None))
    features = session(probe.SerializeToString()).run([heads.input[0]], {"views": views})[0]
    ranges = features.max(axis=(0, 2, 3))
    factor = np.minimum(ranges.max() / np.maximum(ranges, 1e-12), widest).astype(np.float32)

    def scaled(name, array):
        inits[name].CopyFrom(numpy_helper.from_array(array.astype(np.float32), name))

    weight = numpy_helper.to_array(inits[layer.input[1]])
    scaled(layer.input[1], weight * factor[:, None, None, None])
    scaled(layer.input[2], numpy_helper.to_array(inits[layer.input[2]]) * factor)
    head_weight = numpy_helper.to_array(inits[heads.input[1]])
    groups = next((onnx.helper.get_attribute_value(a) for a in heads.attribute if a.name == "group"), 1)
    per_group = head_weight.shape[0] // groups
    inputs = factor.reshape(groups, 1, -1)  # each group of the heads reads its own block of channels
    scaled(heads.input[1], (head_weight.reshape(groups, per_group, -1, 1, 1) / inputs[..., None, None])
           .reshape(head_weight.shape))
    return model


def quantize(src, dst, calibration, fmt="qdq", per_channel=True, method="percentile", equalize=True):
    """Writes the int8 model of `src` to `dst` (the heads in float), its metadata kept and its version marked.

    `method`: "percentile" (each activation's 0.01-99.99th percentile over the
    calibration views) or "minmax" (its whole range); `equalize`: the last
    layer's channels brought to one range first (`equalize_heads_input`).
    """
    with tempfile.TemporaryDirectory() as tmp:
        reordered = os.path.join(tmp, "reordered.onnx")
        model = relu_before_shuffle(onnx.load(src))
        onnx.save(equalize_heads_input(model, calibration) if equalize else model, reordered)
        prepared = os.path.join(tmp, "prepared.onnx")
        quantization.quant_pre_process(reordered, prepared, skip_symbolic_shape=True)
        quantization.quantize_static(
            prepared,
            dst,
            Views(calibration),
            quant_format=quantization.QuantFormat.QDQ if fmt == "qdq" else quantization.QuantFormat.QOperator,
            per_channel=per_channel,
            activation_type=quantization.QuantType.QUInt8,
            weight_type=quantization.QuantType.QInt8,
            calibrate_method=CALIBRATION[method],
            nodes_to_exclude=head_and_after(onnx.load(prepared)),
            extra_options={"CalibPercentile": PERCENTILE} if method == "percentile" else {},
        )
    source = onnx.load(src)
    model = onnx.load(dst)
    del model.metadata_props[:]
    for entry in source.metadata_props:
        value = entry.value + "-int8" if entry.key == "mvgrasp.model_version" else entry.value
        model.metadata_props.add(key=entry.key, value=value)
    onnx.save(model, dst)


def _maps(path, views):
    run = session(path)
    return run.run(None, {"views": views})[0], run.get_modelmeta().custom_metadata_map


def _both(float_path, int8_path, views):
    """Both files' maps for `views` (each file run once) and the names of their channels."""
    a, meta = _maps(float_path, views)
    b, _ = _maps(int8_path, views)
    return a, b, meta["mvgrasp.outputs"].split(",")


def _differences(a, b, names):
    gap = np.abs(a - b)
    return {name: {"max": float(gap[:, k].max()), "mean": float(gap[:, k].mean())} for k, name in enumerate(names)}


def _best_pixel(a, b, names):
    q = names.index("quality")
    n, side = a.shape[0], a.shape[-1]
    fa, fb = a[:, q].reshape(n, -1), b[:, q].reshape(n, -1)
    pa, pb = fa.argmax(1), fb.argmax(1)
    moved = np.hypot(pa // side - pb // side, pa % side - pb % side)
    lost = fa.max(1) - fa[np.arange(n), pb]
    return {"within_2px": float((moved <= 2).mean()), "quality_lost_mean": float(lost.mean()),
            "quality_lost_p95": float(np.quantile(lost, 0.95))}


def differences(float_path, int8_path, views):
    """Per output channel, the max and mean |int8 - float| over `views`."""
    return _differences(*_both(float_path, int8_path, views))


def best_pixel(float_path, int8_path, views):
    """Where each file puts a view's best quality pixel, the planner's first pick.

    `within_2px`: the share of `views` whose int8 best pixel lies within 2
    pixels of the float file's; `quality_lost_mean` / `_p95`: the float
    file's quality at the int8 file's best pixel, below its own best.
    """
    return _best_pixel(*_both(float_path, int8_path, views))


def measure(float_path, int8_path, views):
    """`differences` and `best_pixel` from one run of each file over `views`."""
    maps = _both(float_path, int8_path, views)
    return {"difference_on_held_out": _differences(*maps), "best_pixel": _best_pixel(*maps)}


def write_golden(path, views, folder):
    """`views` and `path`'s maps for them (onnxruntime, one thread) as `folder`/input.npy, output.npy."""
    maps, meta = _maps(path, views)
    os.makedirs(folder, exist_ok=True)
    np.save(os.path.join(folder, "input.npy"), views)
    np.save(os.path.join(folder, "output.npy"), maps)
    version = meta["mvgrasp.model_version"]
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
    p.add_argument("--calibration", choices=sorted(CALIBRATION), default="percentile",
                   help=f"activation ranges: the {PERCENTILE}th percentile (default) or the whole range")
    p.add_argument("--equalize", action=argparse.BooleanOptionalAction, default=True,
                   help="bring the last layer's channels to one range before quantizing (the same float function)")
    p.add_argument("--format", choices=("qdq", "qoperator"), default="qdq")
    p.add_argument("--per-channel", action=argparse.BooleanOptionalAction, default=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--golden", metavar="DIR",
                   help="also write two held-out views and the int8 file's maps for them (onnxruntime's)")
    p.add_argument("--measure", action="store_true",
                   help="write nothing: measure the int8 file already at --out against --onnx")
    args = p.parse_args(argv)
    ds = dataset.load(args.data)
    train_idx, eval_idx = dataset.split_by_instance(ds.meta)
    held_out = sample_views(ds, eval_idx, args.check_views, args.seed + 1)
    if args.measure:
        print(json.dumps({"measured": args.out, "held_out_views": len(held_out),
                          **measure(args.onnx, args.out, held_out)}))
        return
    quantize(args.onnx, args.out, sample_views(ds, train_idx, args.views, args.seed), args.format, args.per_channel,
             args.calibration, args.equalize)
    if args.golden:
        write_golden(args.out, held_out[:2], args.golden)
    print(json.dumps({"out": args.out, "format": args.format, "per_channel": args.per_channel,
                      "calibration": args.calibration, "equalize": args.equalize,
                      "calibration_views": min(args.views, len(train_idx)),
                      **measure(args.onnx, args.out, held_out)}))


if __name__ == "__main__":
    main()
