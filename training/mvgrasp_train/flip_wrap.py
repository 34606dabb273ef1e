"""Wraps an exported grasp network so that one call averages four flips.

    python3 -m mvgrasp_train.flip_wrap IN.onnx OUT.onnx [--flips four|mirror]

The wrapped graph stacks each view with its left-right, up-down and double
flip into one batch of 4B, runs the original network once on it, flips each
part's maps back, negates sin 2phi for the two single flips (a mirror takes
phi to -phi; the double flip is a half turn and keeps it) and averages the
four. It is `evaluate_onnx.flip_average` inside the file, so the service,
`sim eval` and `evaluate_onnx` use it with no option of their own: the same
`views` -> `maps` interface and contract, at four times the network's work.
The metadata gains `mvgrasp.test_time_flips` = 4 and the model version a
`+flips` suffix. `--flips mirror` averages the view and its left-right
mirror only (2 passes, `test_time_flips` = 2, suffix `+mirror`): the
flips that keep the table below a front or side view, for networks
trained with `train --symmetries gravity`. Only onnx is needed (no PyTorch); the output is checked
against the same passes run separately (`check`).
"""

import argparse
import json
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from .evaluate_onnx import FLIP_SETS, flip_average

FLIPS_KEY = "mvgrasp.test_time_flips"
VERSION_KEY = "mvgrasp.model_version"
OUTPUTS_KEY = "mvgrasp.outputs"  # the channel order, e.g. quality,cos2phi,sin2phi,width
TOLERANCE = 1e-5
_END = np.iinfo(np.int64).min  # a Slice end past the start of the axis, walking backwards


def metadata(model):
    """The file's metadata as a dict."""
    return {p.key: p.value for p in model.metadata_props}


def write_metadata(model, props):
    """Appends `props` to the file's metadata."""
    for key, value in props.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value


def channel_order(props, needed):
    """The output channels `mvgrasp.outputs` names, in order; ValueError
    unless it names four, `needed` among them."""
    channels = [c.strip() for c in props.get(OUTPUTS_KEY, "").split(",")]
    if len(channels) != 4 or needed not in channels:
        raise ValueError(f"{OUTPUTS_KEY} {props.get(OUTPUTS_KEY)!r} does not name four channels with {needed}")
    return channels


def embed(graph, prefix, views, maps):
    """The graph's nodes and initializers to place inside a larger graph:
    every internal name prefixed, so that the host's own names never clash,
    the input read from `views` and the output written to `maps`."""
    inner = {graph.input[0].name: views, graph.output[0].name: maps}

    def rename(name):
        return inner.get(name, prefix + name) if name else name

    nodes = []
    for node in graph.node:
        copy = onnx.NodeProto()
        copy.CopyFrom(node)
        copy.name = prefix + node.name if node.name else ""
        copy.input[:] = [rename(n) for n in node.input]
        copy.output[:] = [rename(n) for n in node.output]
        nodes.append(copy)
    initializers = []
    for tensor in graph.initializer:
        copy = onnx.TensorProto()
        copy.CopyFrom(tensor)
        copy.name = rename(tensor.name)
        initializers.append(copy)
    return nodes, initializers


def wrap(model, flips="four"):
    """A new ModelProto: `model` run on a view and its three flips (`flips`
    "four") or its left-right mirror ("mirror"), maps flipped back and
    averaged. `model` must map `[B, 1, L, L]` to `[B, 4, L, L]` (one input,
    one output) and not be wrapped already."""
    graph = model.graph
    if len(graph.input) != 1 or len(graph.output) != 1:
        raise ValueError("expected one input (views) and one output (maps)")
    if flips not in FLIP_SETS:
        raise ValueError(f"flips {flips!r}, not one of {sorted(FLIP_SETS)}")
    props = metadata(model)
    if FLIPS_KEY in props:
        raise ValueError(f"already averages {props[FLIPS_KEY]} flips")
    channels = channel_order(props, "sin2phi")
    passes = FLIP_SETS[flips]
    views, maps = graph.input[0].name, graph.output[0].name
    inner_in, inner_out = "flip/stacked", "flip/net_maps"
    nodes, initializers = embed(graph, "net/", inner_in, inner_out)

    def const(name, values, dtype=np.int64):
        initializers.append(numpy_helper.from_array(np.asarray(values, dtype=dtype), name))
        return name

    start, end, step = const("flip/start", [-1]), const("flip/end", [_END]), const("flip/step", [-1])
    ax = {}  # the axes some pass flips, each made once (an unused one would be dead weight in the file)

    def flip(x, axis, out):
        if axis not in ax:
            ax[axis] = const(f"flip/axis{axis}", [axis])
        return helper.make_node("Slice", [x, start, end, ax[axis], step], [out], name=out)

    def flipped(x, rows_axis, flip_y, flip_x, out, head):
        """Appends to `head` the nodes that flip `x` (rows on `rows_axis`,
        columns on the next) as a pass says; returns the result's name."""
        if flip_x:
            head.append(flip(x, rows_axis + 1, out + "_x" if flip_y else out))
            x = out + "_x" if flip_y else out
        if flip_y:
            head.append(flip(x, rows_axis, out))
            x = out
        return x

    # Pass k's views: up-down is the rows (axis 2), left-right the columns (3).
    head, inputs = [], []
    for k, (flip_y, flip_x) in enumerate(passes):
        inputs.append(flipped(views, 2, flip_y, flip_x, f"flip/in{k}", head))
    head.append(helper.make_node("Concat", inputs, [inner_in], axis=0, name=inner_in))
    # [nB, 4, L, L] -> [n, B, 4, L, L]: part k holds every view under pass k.
    size = [d.dim_value for d in graph.input[0].type.tensor_type.shape.dim[2:]]
    if len(size) != 2 or min(size) <= 0:
        raise ValueError("expected views of a fixed size [B, 1, L, L]")
    n = len(passes)
    shape = const("flip/parts_shape", [n, -1, 4] + size)
    sign = np.ones((n, 1, 4, 1, 1), np.float32)
    for k, (flip_y, flip_x) in enumerate(passes):
        if flip_y != flip_x:  # a single flip mirrors the angle
            sign[k, 0, channels.index("sin2phi")] = -1.0
    const("flip/sign", sign, np.float32)
    split = const("flip/split", [1] * n)
    parts = [f"flip/p{k}" for k in range(n)]
    tail = [
        helper.make_node("Reshape", [inner_out, shape], ["flip/parts"], name="flip/parts"),
        helper.make_node("Split", ["flip/parts", split], parts, axis=0, name="flip/split"),
    ]
    back = [flipped(part, 3, flip_y, flip_x, part + "_back", tail) for part, (flip_y, flip_x) in zip(parts, passes)]
    tail += [
        helper.make_node("Concat", back, ["flip/back"], axis=0, name="flip/back"),
        helper.make_node("Mul", ["flip/back", "flip/sign"], ["flip/signed"], name="flip/signed"),
        helper.make_node("ReduceMean", ["flip/signed"], [maps], axes=[0], keepdims=0, name="flip/mean"),
    ]
    new_graph = helper.make_graph(head + nodes + tail, graph.name + "+flips", list(graph.input),
                                  list(graph.output), initializers)
    out = helper.make_model(new_graph, opset_imports=list(model.opset_import), producer_name="mvgrasp_train",
                            ir_version=model.ir_version)
    props[FLIPS_KEY] = str(n)
    props[VERSION_KEY] = props.get(VERSION_KEY, "unversioned") + ("+flips" if flips == "four" else "+mirror")
    write_metadata(out, props)
    onnx.checker.check_model(out)
    if out.graph.input[0].type.tensor_type.elem_type != TensorProto.FLOAT:
        raise ValueError("expected float views")
    return out


def session(model_bytes):
    import onnxruntime

    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = 1
    return onnxruntime.InferenceSession(model_bytes, options, providers=["CPUExecutionProvider"])


def check(base, wrapped, views, flips="four"):
    """Largest |wrapped(views) - the passes of base averaged| (numpy,
    `evaluate_onnx.flip_average` with the same `flips`)."""
    plain, flipped = session(base.SerializeToString()), session(wrapped.SerializeToString())
    expected = flip_average(lambda v: plain.run(["maps"], {"views": v})[0], views, flips)
    got = flipped.run(["maps"], {"views": views})[0]
    return float(np.abs(got - expected).max())


def probe_views(model, n=5):
    """`n` seeded random views of `model`'s input size, to check a file made from it."""
    size = model.graph.input[0].type.tensor_type.shape.dim[2].dim_value
    return np.random.default_rng(0).uniform(0.0, 1.0, (n, 1, size, size)).astype(np.float32)


def save_checked(model, path, worst, what):
    """Writes `model` to `path`, prints its check as JSON, and exits with
    an error when `worst` (its largest difference from what it was made
    from) is over TOLERANCE; `what` names the two sides in that error."""
    onnx.save(model, path)
    print(json.dumps({"onnx": path, "max_abs_diff": worst, "tolerance": TOLERANCE,
                      "model_version": metadata(model)[VERSION_KEY]}))
    if worst > TOLERANCE:
        sys.exit(f"{what} by {worst} > {TOLERANCE}")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model")
    p.add_argument("out")
    p.add_argument("--flips", choices=sorted(FLIP_SETS), default="four",
                   help="four: the view and its three flips; mirror: the view and its left-right mirror "
                        "(the flips that keep the table below a front or side view)")
    args = p.parse_args(argv)
    base = onnx.load(args.model)
    wrapped = wrap(base, args.flips)
    worst = check(base, wrapped, probe_views(base), args.flips)
    save_checked(wrapped, args.out, worst, f"the wrapped model differs from its {args.flips} passes averaged")


if __name__ == "__main__":
    main()
