"""Two grasp networks in one file: where to grasp from one, how good from the other.

    python3 -m mvgrasp_train.compose --where WHERE.onnx --level LEVEL.onnx OUT.onnx

The composed graph runs both networks on the same views. Its maps are
WHERE's (quality, angle and opening), with each view's quality map scaled
so that its peak equals LEVEL's peak on that view:

    quality_out = quality_where * max(quality_level) / max(quality_where)

Within a view the order of the pixels is WHERE's, so the paper's metric
(the argmax of each view) is WHERE's exactly; across views and objects the
planner ranks by LEVEL's peaks, and tau is read on LEVEL's scale. The
question it answers: does a physics-trained network win in physics by
where it grasps inside a view, or by which view and object it trusts? A
label-trained WHERE scores more of the paper's metric; a physics-trained
LEVEL clears more objects.

Both files must carry the same contract (input size, pixel size, width
scale, normalisation, output order). The metadata is WHERE's, with the
version `WHERE+level(LEVEL)` and `mvgrasp.level_model` naming LEVEL's
version. Only onnx is needed; the output is checked against the two files
run apart (`check`). It costs both networks' time.
"""

import argparse
import sys

import numpy as np
import onnx
from onnx import helper, numpy_helper

from .flip_wrap import (OUTPUTS_KEY, TOLERANCE, VERSION_KEY, channel_order, embed, metadata, probe_views, save_checked,
                        session, write_metadata)

LEVEL_KEY = "mvgrasp.level_model"
CONTRACT_KEYS = ("mvgrasp.input_size_px", "mvgrasp.pixel_size_m", "mvgrasp.width_scale_m", "mvgrasp.normalisation",
                 OUTPUTS_KEY)
EPS = 1e-6  # a view WHERE scores 0 everywhere keeps 0, not a division by zero


def _opset(model):
    return max(o.version for o in model.opset_import if o.domain in ("", "ai.onnx"))


def compose(where, level):
    """A new ModelProto: WHERE's maps with each view's quality scaled to
    LEVEL's peak. Raises ValueError when the two contracts differ or a file
    is not a `views` -> `maps` network."""
    for name, model in (("where", where), ("level", level)):
        if len(model.graph.input) != 1 or len(model.graph.output) != 1:
            raise ValueError(f"{name}: expected one input (views) and one output (maps)")
    pw, pl = metadata(where), metadata(level)
    for key in CONTRACT_KEYS:
        if pw.get(key) != pl.get(key):
            raise ValueError(f"the contracts differ in {key}: where {pw.get(key)!r}, level {pl.get(key)!r}")
    q = channel_order(pw, "quality").index("quality")
    opset = _opset(where)
    if opset != _opset(level):
        raise ValueError(f"the opsets differ: where {opset}, level {_opset(level)}")
    views, maps = where.graph.input[0].name, where.graph.output[0].name
    split = {}
    nodes, initializers = [], []
    for name, model in (("where", where), ("level", level)):
        n, i = embed(model.graph, name + "/", views, f"{name}/maps")
        nodes += n
        initializers += i
        channels = [f"compose/{name}_{k}" for k in range(4)]
        nodes.append(helper.make_node("Split", [f"{name}/maps", "compose/split"], channels, axis=1,
                                      name=f"compose/split_{name}"))
        split[name] = channels
    initializers.append(numpy_helper.from_array(np.ones(4, np.int64), "compose/split"))
    initializers.append(numpy_helper.from_array(np.float32(EPS), "compose/eps"))
    if opset >= 18:  # ReduceMax takes its axes as an input from opset 18 on
        initializers.append(numpy_helper.from_array(np.array([1, 2, 3], np.int64), "compose/peak_axes"))

    def peak(x, out):
        if opset >= 18:
            return helper.make_node("ReduceMax", [x, "compose/peak_axes"], [out], keepdims=1, name=out)
        return helper.make_node("ReduceMax", [x], [out], axes=[1, 2, 3], keepdims=1, name=out)

    outs = list(split["where"])
    outs[q] = "compose/quality"
    nodes += [
        peak(split["where"][q], "compose/where_peak"),
        peak(split["level"][q], "compose/level_peak"),
        helper.make_node("Add", ["compose/where_peak", "compose/eps"], ["compose/where_peak_eps"],
                         name="compose/where_peak_eps"),
        helper.make_node("Div", ["compose/level_peak", "compose/where_peak_eps"], ["compose/scale"],
                         name="compose/scale"),
        helper.make_node("Mul", [split["where"][q], "compose/scale"], ["compose/quality"], name="compose/quality"),
        helper.make_node("Concat", outs, [maps], axis=1, name="compose/maps"),
    ]
    graph = helper.make_graph(nodes, where.graph.name + "+level", list(where.graph.input),
                              list(where.graph.output), initializers)
    out = helper.make_model(graph, opset_imports=list(where.opset_import), producer_name="mvgrasp_train",
                            ir_version=max(where.ir_version, level.ir_version))
    props = dict(pw)
    level_version = pl.get(VERSION_KEY, "unversioned")
    props[LEVEL_KEY] = level_version
    props[VERSION_KEY] = f"{pw.get(VERSION_KEY, 'unversioned')}+level({level_version})"
    write_metadata(out, props)
    onnx.checker.check_model(out)
    return out


def expected(where_maps, level_maps, quality=0):
    """What the composed file must give, from the two files' maps (numpy)."""
    out = np.array(where_maps, np.float32)
    qw = out[:, quality]
    scale = level_maps[:, quality].max(axis=(1, 2)) / (qw.max(axis=(1, 2)) + np.float32(EPS))
    out[:, quality] = qw * scale[:, None, None]
    return out


def check(where, level, composed, views):
    """Largest |composed(views) - expected(where(views), level(views))|."""
    q = channel_order(metadata(where), "quality").index("quality")
    run = [session(m.SerializeToString()).run(["maps"], {"views": views})[0] for m in (where, level, composed)]
    return float(np.abs(run[2] - expected(run[0], run[1], q)).max())


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--where", required=True, help="the network whose maps (and argmax) are kept")
    p.add_argument("--level", required=True, help="the network whose peak quality sets each view's scale")
    p.add_argument("out")
    args = p.parse_args(argv)
    where, level = onnx.load(args.where), onnx.load(args.level)
    try:
        composed = compose(where, level)
    except ValueError as e:
        sys.exit(f"compose: {e}")
    worst = check(where, level, composed, probe_views(where))
    save_checked(composed, args.out, worst, "the composed model differs from the two files run apart")


if __name__ == "__main__":
    main()
