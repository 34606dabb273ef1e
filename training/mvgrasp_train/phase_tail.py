"""Runs an exported grasp network's full-resolution tail at the last
decoder layer's resolution: the same function, less work on CPU.

    python3 -m mvgrasp_train.phase_tail IN.onnx OUT.onnx

Every shipped network ends in a layer that turns 24 x 24 features into
72 x 72 ones three pixels per feature (a 3x3 convolution and a
DepthToSpace, or a transposed convolution whose kernel is its stride),
then a ReLU, then the 1x1 heads at 72 x 72. The heads act on each pixel
alone, so they can run before the pixel shuffle instead of after it: the
last layer's output channels are put in phase-major order (`DCR`), the
heads become one grouped 1x1 convolution (one group per phase, the same
weights in each) at 24 x 24, and a single DepthToSpace of the four output
channels makes the 72 x 72 maps. Element-wise nodes between the layer and
the heads (ReLU, and int8 files' per-tensor QuantizeLinear /
DequantizeLinear pairs) commute with the shuffle and stay where they are;
a DepthToSpace of block size 1 (the 3x3 stride-1 layers' sub-pixel form)
is dropped. Float and int8 (QDQ) files alike; the contract, metadata and
output name are kept.

`check` runs both files through onnxruntime and returns the largest
difference of their maps; `main` refuses to write a file that differs by
more than `TOLERANCE`. Needs numpy, onnx and onnxruntime, not PyTorch.
"""

import argparse
import json
import sys

import numpy as np
import onnx
from onnx import helper, numpy_helper

from .flip_wrap import TOLERANCE, probe_views, session

# Nodes that act on each value alone, with one parameter for the whole tensor.
ELEMENTWISE = ("Relu", "QuantizeLinear", "DequantizeLinear")


def attributes(node):
    return {a.name: helper.get_attribute_value(a) for a in node.attribute}


def rewrite(model):
    """A copy of `model` with its tail at the low resolution (see the module's doc).

    Raises ValueError when the graph does not end as described.
    """
    model = onnx.ModelProto.FromString(model.SerializeToString())
    graph = model.graph
    _drop_unit_shuffles(graph)
    nodes = list(graph.node)
    producer = {out: n for n in nodes for out in n.output}
    consumers = {}
    for n in nodes:
        for name in n.input:
            consumers.setdefault(name, []).append(n)
    inits = {i.name: i for i in graph.initializer}

    def feeding(node):
        """The node whose output is `node`'s first input, which nothing else reads."""
        source = producer[node.input[0]]
        if len(consumers[source.output[0]]) != 1:
            raise ValueError(f"{source.name}'s output is read by more than {node.name}")
        return source

    heads = _heads(nodes, inits)
    # Back from the heads through element-wise nodes to the shuffle or the transposed convolution.
    node = feeding(heads)
    while node.op_type in ELEMENTWISE:
        _require_per_tensor(node, inits)
        node = feeding(node)
    if node.op_type == "DepthToSpace":
        a = attributes(node)
        if a.get("mode", b"DCR") not in (b"CRD", "CRD"):
            raise ValueError(f"{node.name}: a DepthToSpace of mode {a.get('mode')!r}, not CRD")
        block = a["blocksize"]
        for user in consumers.get(node.output[0], []):
            user.input[list(user.input).index(node.output[0])] = node.input[0]
        shuffle = node
        node = feeding(node)
        while node.op_type in ELEMENTWISE:
            _require_per_tensor(node, inits)
            node = feeding(node)
        if node.op_type != "Conv":
            raise ValueError(f"{shuffle.name} follows {node.op_type} {node.name}, not a convolution")
        channels = _phase_major(node, block, producer, inits)
        nodes.remove(shuffle)
    elif node.op_type == "ConvTranspose":
        block, channels = _as_pointwise(node, producer, inits)
    else:
        raise ValueError(f"the heads follow {node.op_type} {node.name}: no sub-pixel layer to move them before")

    weight = numpy_helper.to_array(inits[heads.input[1]])
    if weight.shape[1] != channels:
        raise ValueError(f"the heads take {weight.shape[1]} channels; the last layer gives {channels}")
    phases = block * block
    bias = numpy_helper.to_array(inits[heads.input[2]]) if len(heads.input) > 2 else np.zeros(weight.shape[0], np.float32)
    name = heads.name or "heads"
    graph.initializer.extend([numpy_helper.from_array(np.concatenate([weight] * phases), f"{name}.phase_weight"),
                              numpy_helper.from_array(np.concatenate([bias] * phases), f"{name}.phase_bias")])
    grouped = helper.make_node("Conv", [heads.input[0], f"{name}.phase_weight", f"{name}.phase_bias"],
                               [f"{name}.phases"], name=f"{name}/phases", group=phases, kernel_shape=[1, 1])
    shuffle = helper.make_node("DepthToSpace", [f"{name}.phases"], [heads.output[0]], name=f"{name}/shuffle",
                               blocksize=block, mode="DCR")
    at = nodes.index(heads)
    nodes[at:at + 1] = [grouped, shuffle]
    del graph.node[:]
    graph.node.extend(nodes)
    _drop_unused_initializers(graph)
    # Shapes recorded for the intermediate tensors (int8 files carry them) no longer hold.
    del graph.value_info[:]
    onnx.checker.check_model(model)
    return model


def _drop_unit_shuffles(graph):
    """Removes DepthToSpace nodes of block size 1, which copy their input."""
    rename, kept = {}, []
    for n in graph.node:
        if n.op_type == "DepthToSpace" and attributes(n)["blocksize"] == 1:
            rename[n.output[0]] = n.input[0]
        else:
            kept.append(n)
    for n in kept:
        for k, name in enumerate(n.input):
            while name in rename:
                name = rename[name]
            n.input[k] = name
    for out in graph.output:
        if out.name in rename:
            raise ValueError(f"the graph's output {out.name} is a DepthToSpace of block size 1")
    del graph.node[:]
    graph.node.extend(kept)


def _heads(nodes, inits):
    """The last convolution: 1x1, one group, its weights a plain initializer."""
    convs = [n for n in nodes if n.op_type == "Conv"]
    if not convs:
        raise ValueError("no convolution in the graph")
    heads = convs[-1]
    plain = heads.input[1] in inits
    if not plain or list(inits[heads.input[1]].dims[2:]) != [1, 1] or attributes(heads).get("group", 1) != 1:
        raise ValueError(f"the last convolution {heads.name!r} is not 1x1 heads with plain weights")
    return heads


def _require_per_tensor(node, inits):
    for name in node.input[1:]:
        if name in inits and numpy_helper.to_array(inits[name]).size > 1:
            raise ValueError(f"{node.name}: per-channel parameters do not commute with the pixel shuffle")


def _tensor(name, producer, inits):
    """(initializer, DequantizeLinear or None) behind input `name`."""
    if name in inits:
        return inits[name], None
    node = producer.get(name)
    if node is not None and node.op_type == "DequantizeLinear" and node.input[0] in inits:
        return inits[node.input[0]], node
    raise ValueError(f"{name}: neither an initializer nor a dequantized one")


def _set(init, array):
    init.CopyFrom(numpy_helper.from_array(array.astype(numpy_helper.to_array(init).dtype), init.name))


def _reorder(name, order, producer, inits):
    """Reorders the first axis of the tensor behind `name` (and its per-channel scale and zero point)."""
    init, dq = _tensor(name, producer, inits)
    _set(init, numpy_helper.to_array(init)[order])
    if dq is not None:
        if attributes(dq).get("axis", 1) != 0 and numpy_helper.to_array(inits[dq.input[1]]).size > 1:
            raise ValueError(f"{dq.name}: per-channel on axis {attributes(dq).get('axis')}, not the output axis")
        for param in dq.input[1:]:
            values = numpy_helper.to_array(inits[param])
            if values.size > 1:
                _set(inits[param], values[order])


def _phase_major(conv, block, producer, inits):
    """Puts `conv`'s output channels c * b^2 + phase (CRD) in order phase * C + c (DCR); returns C."""
    init, _ = _tensor(conv.input[1], producer, inits)
    out = numpy_helper.to_array(init).shape[0]
    phases = block * block
    if out % phases:
        raise ValueError(f"{conv.name}: {out} output channels for {phases} phases")
    channels = out // phases
    order = np.array([c * phases + p for p in range(phases) for c in range(channels)])
    _reorder(conv.input[1], order, producer, inits)
    if len(conv.input) > 2:
        _reorder(conv.input[2], order, producer, inits)
    return channels


def _as_pointwise(conv, producer, inits):
    """Rewrites a transposed convolution whose kernel is its stride as a 1x1
    convolution to phase-major channels; returns (block, channels)."""
    a = attributes(conv)
    k, s = list(a["kernel_shape"]), list(a.get("strides", [1, 1]))
    if k != s or k[0] != k[1] or any(a.get("pads", [0, 0, 0, 0])) or a.get("group", 1) != 1 \
            or any(a.get("output_padding", [0, 0])) or any(d != 1 for d in a.get("dilations", [1, 1])):
        raise ValueError(f"{conv.name}: a transposed convolution that is not one block per input pixel")
    block = k[0]
    init, dq = _tensor(conv.input[1], producer, inits)
    w = numpy_helper.to_array(init)  # [in, out, b, b]
    cin, channels = w.shape[0], w.shape[1]
    phases = block * block
    # Output channel p * C + c, p = ky * b + kx, takes w[:, c, ky, kx].
    pointwise = w.transpose(2, 3, 1, 0).reshape(phases * channels, cin, 1, 1)
    _set(init, pointwise)
    if dq is not None:
        axis = attributes(dq).get("axis", 1)
        if axis != 1 and any(numpy_helper.to_array(inits[p]).size > 1 for p in dq.input[1:]):
            raise ValueError(f"{dq.name}: per-channel on axis {axis}, not the transposed convolution's output axis")
        _tile_per_channel(dq, phases, inits)
        for attr in dq.attribute:
            if attr.name == "axis":
                attr.i = 0
    if len(conv.input) > 2:
        b_init, b_dq = _tensor(conv.input[2], producer, inits)
        _set(b_init, np.tile(numpy_helper.to_array(b_init), phases))
        if b_dq is not None:
            _tile_per_channel(b_dq, phases, inits)
    conv.op_type = "Conv"
    del conv.attribute[:]
    conv.attribute.extend([helper.make_attribute("kernel_shape", [1, 1])])
    return block, channels


def _tile_per_channel(dq, phases, inits):
    """Repeats a DequantizeLinear's per-channel scale and zero point once per phase."""
    for name in dq.input[1:]:
        values = numpy_helper.to_array(inits[name])
        if values.size > 1:
            _set(inits[name], np.tile(values, phases))


def _drop_unused_initializers(graph):
    used = {name for n in graph.node for name in n.input}
    kept = [i for i in graph.initializer if i.name in used]
    del graph.initializer[:]
    graph.initializer.extend(kept)


def check(before, after, views):
    """Largest |maps(after) - maps(before)| over `views` (float32 [n, 1, L, L])."""
    a = session(before.SerializeToString()).run(["maps"], {"views": views})[0]
    b = session(after.SerializeToString()).run(["maps"], {"views": views})[0]
    if a.shape != b.shape:
        raise ValueError(f"maps of shape {b.shape}, not {a.shape}")
    return float(np.abs(a - b).max())


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("src")
    p.add_argument("dst")
    args = p.parse_args(argv)
    before = onnx.load(args.src)
    try:
        after = rewrite(before)
    except ValueError as e:
        sys.exit(f"{args.src}: {e}")
    worst = check(before, after, probe_views(before, 8))
    print(json.dumps({"src": args.src, "dst": args.dst, "max_abs_diff": worst, "tolerance": TOLERANCE,
                      "nodes": [len(before.graph.node), len(after.graph.node)]}))
    if worst > TOLERANCE:
        sys.exit(f"the rewritten maps differ by {worst} > {TOLERANCE}; nothing written")
    onnx.save(after, args.dst)


if __name__ == "__main__":
    main()
