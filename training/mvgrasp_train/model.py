"""The grasp network (PyTorch): the paper's final architecture and a cheaper variant.

DESIGN.md, method step 5. Encoder C(9x9x8,s3) C(5x5x16,s2) C(5x5x16,s2)
C(3x3x32) x3, decoder T(3x3x32) x3 T(5x5x16,s2) T(5x5x32,s2) T(9x9x32,s3),
BatchNorm + ReLU after each, "same" padding (explicit pads and output
padding, so the output is the input's size for sides that are multiples of
12), then 1x1 heads: quality (sigmoid), cos 2phi, sin 2phi, width.

Variant `narrow`: the same network with the last transposed convolution
giving 8 channels instead of 32. That layer runs at full resolution and is
about half the CPU time of the whole network (BENCHMARKS.md).

Variant `skip`: `narrow` plus two skip connections, the encoder's features
at 24 x 24 (after the first convolution) and at 12 x 12 (after the second)
added through 1x1 convolutions to the decoder's at the same resolutions
(after its fourth and fifth layers). The 6 x 6 x 32 bottleneck is all the
paper's network has to place the best pixel with; the skips hand the
decoder the finer encoder maps. The 1x1 convolutions start at zero, so a
fresh `skip` network computes what the `narrow` one with the same other
weights computes, and `train --init` can start it from a `narrow` run.

Variant `lite`: `narrow` with its last transposed convolution 3 x 3 of
stride 3 instead of 9 x 9: each of the 24 x 24 features paints its own
3 x 3 output pixels, without its neighbours'. A ninth of that layer's
arithmetic: 6.7 M multiply-adds per 72 px view against `narrow`'s 17.3 M.
`train --init` starts it from a `narrow` run with each output phase's
centre tap of the 9 x 9 kernel (`start_lite`), then distils (`--teacher`).

Variant `wide`: `narrow` with twice the channels in every layer (16 ... 64
... 16), about 4x its arithmetic, to ask whether the network's size is
what holds its accuracy (models/RECIPES.md: fine-tunes fit their training views
no better than held-out ones). `widen` loads a `narrow` run into it so
that it starts as that run's function: the old channels keep their
weights, the new ones take no part in the old ones or the heads until
training moves their zero weights.
"""

import torch
from torch import nn

ARCHITECTURES = ("paper", "narrow", "skip", "wide", "lite")

# `skip`: (block whose output is taken, block after whose output it is added); blocks 0-5 encode, 6-11 decode.
SKIPS = ((1, 9), (0, 10))


def layer_shapes(architecture):
    """The convolutions as (in, out, kernel, stride, padding) for the
    encoder and (in, out, kernel, stride, padding, output padding) for the
    decoder's transposed ones."""
    m = 2 if architecture == "wide" else 1
    last = 32 if architecture == "paper" else 8 * m
    a, b, c = 8 * m, 16 * m, 32 * m
    enc = [(1, a, 9, 3, 3), (a, b, 5, 2, 2), (b, b, 5, 2, 2), (b, c, 3, 1, 1), (c, c, 3, 1, 1), (c, c, 3, 1, 1)]
    dec = [(c, c, 3, 1, 1, 0), (c, c, 3, 1, 1, 0), (c, c, 3, 1, 1, 0), (c, b, 5, 2, 2, 1), (b, c, 5, 2, 2, 1),
           (c, last, 3, 3, 0, 0) if architecture == "lite" else (c, last, 9, 3, 3, 0)]
    return enc, dec


def _block(conv, channels):
    return nn.Sequential(conv, nn.BatchNorm2d(channels), nn.ReLU(inplace=True))


class GraspNet(nn.Module):
    def __init__(self, architecture="paper"):
        super().__init__()
        if architecture not in ARCHITECTURES:
            raise ValueError(f"unknown architecture {architecture!r}; one of {ARCHITECTURES}")
        self.architecture = architecture
        enc, dec = layer_shapes(architecture)
        last = dec[-1][1]
        blocks = [_block(nn.Conv2d(i, o, k, s, p, bias=False), o) for i, o, k, s, p in enc]
        blocks += [_block(nn.ConvTranspose2d(i, o, k, s, p, op, bias=False), o) for i, o, k, s, p, op in dec]
        self.body = nn.Sequential(*blocks)
        self.heads = nn.Conv2d(last, 4, 1)
        self.skip_pairs = SKIPS if architecture == "skip" else ()
        out_channels = [o for _, o, *_ in enc + dec]
        self.skips = nn.ModuleList(nn.Conv2d(out_channels[a], out_channels[b], 1) for a, b in self.skip_pairs)
        for conv in self.skips:
            nn.init.zeros_(conv.weight)
            nn.init.zeros_(conv.bias)

    def raw(self, views):
        """The heads' outputs before the sigmoid: quality as a logit, then cos 2phi, sin 2phi, width."""
        x, kept = views, {}
        for i, block in enumerate(self.body):
            x = block(x)
            kept[i] = x
            for (source, target), conv in zip(self.skip_pairs, self.skips):
                if target == i:
                    x = x + conv(kept[source])
        return self.heads(x)

    def forward(self, views):
        return squash(self.raw(views))


def squash(raw):
    """The network's output from `GraspNet.raw`: the sigmoid on the quality logit."""
    return torch.cat([torch.sigmoid(raw[:, :1]), raw[:, 1:]], dim=1)


def widen(model, state):
    """Loads `state`, a `narrow` network's weights, into the `wide` network
    `model` so that it computes what the narrow one does: each tensor goes
    into the leading corner of the wider one, and the weights from a new
    input channel to an old output channel (and to the heads) are zero. New
    channels keep their fresh weights; BatchNorm statistics their defaults."""
    if model.architecture != "wide":
        raise ValueError(f"widen loads into a `wide` network, not {model.architecture!r}")
    own = model.state_dict()
    if set(own) != set(state):
        raise ValueError(f"not the same layers: {sorted(set(own) ^ set(state))}")
    with torch.no_grad():
        for key, small in state.items():
            big = own[key]
            if small.dim() == 0:
                big.copy_(small)
                continue
            corner = tuple(slice(0, n) for n in small.shape)
            big[corner] = small
            if small.dim() < 2:
                continue
            # Old outputs must not see new inputs. Conv2d and the heads are
            # [out, in, ...]; ConvTranspose2d is [in, out, ...].
            module = model.get_submodule(key.rsplit(".", 1)[0])
            out_dim, in_dim = (1, 0) if isinstance(module, nn.ConvTranspose2d) else (0, 1)
            index = [slice(None)] * big.dim()
            index[out_dim] = slice(0, small.shape[out_dim])
            index[in_dim] = slice(small.shape[in_dim], None)
            big[tuple(index)] = 0.0
    model.load_state_dict(own)
    return model


def train_mode(model, freeze_batchnorm=False):
    """Puts `model` in training mode; with `freeze_batchnorm`, its BatchNorm
    layers stay in inference mode (running statistics fixed, scale and
    shift still learned), as for a network read back by import_onnx.py."""
    model.train()
    if freeze_batchnorm:
        for m in model.modules():
            if isinstance(m, nn.BatchNorm2d):
                m.eval()
    return model


def fold_batchnorm(model):
    """An equivalent inference-only copy with each BatchNorm folded into its convolution."""
    model = model.eval()
    folded = GraspNet(model.architecture).eval()
    folded.load_state_dict(model.state_dict())
    layers = []
    for block in folded.body:
        conv, bn = block[0], block[1]
        scale = bn.weight / torch.sqrt(bn.running_var + bn.eps)
        shift = bn.bias - bn.running_mean * scale
        if isinstance(conv, nn.ConvTranspose2d):
            new = nn.ConvTranspose2d(conv.in_channels, conv.out_channels, conv.kernel_size, conv.stride,
                                     conv.padding, conv.output_padding, bias=True)
            new.weight.data = conv.weight.data * scale.view(1, -1, 1, 1)
        else:
            new = nn.Conv2d(conv.in_channels, conv.out_channels, conv.kernel_size, conv.stride, conv.padding,
                            bias=True)
            new.weight.data = conv.weight.data * scale.view(-1, 1, 1, 1)
        new.bias.data = shift.detach().clone()
        layers.append(nn.Sequential(new, nn.ReLU(inplace=True)))
    folded.body = nn.Sequential(*layers)
    return folded.eval()


def subpixel_taps(k, s):
    """Where each tap of a k x k transposed convolution of stride s goes in
    its sub-pixel form: ((phase ry, phase rx, tap ty, tap tx), (ky, kx))
    for every kernel tap (ky, kx), each exactly once (see `subpixel`)."""
    return [((ry, rx, ty, tx), (s * (2 - ty) + ry, s * (2 - tx) + rx))
            for ry in range(s) for rx in range(s) for ty in range(3) for tx in range(3)
            if s * (2 - ty) + ry < k and s * (2 - tx) + rx < k]


def subpixel(folded):
    """An equivalent copy of a BN-folded network with every transposed
    convolution as a 3x3 convolution to s*s times the channels followed by
    a pixel shuffle (ONNX DepthToSpace): the same function, cheaper on CPU.

    For ConvTranspose2d(k, stride s, padding s, output padding op) with
    k + op = 3 s (all of this network's), output pixel s q + r is
    sum over m in {-1, 0, 1} of x[q - m] w[s (m + 1) + r]: three taps per
    output phase r, taps past the kernel being zero. The 3x3 convolution's
    output channel c s^2 + ry s + rx holds phase (ry, rx) of channel c,
    which is the order PixelShuffle (DepthToSpace, mode CRD) expects.
    A transposed convolution with k = s and no padding (`lite`'s last) is
    kept: ONNX Runtime runs it in 85% of the time of its sub-pixel form, a
    1x1 convolution and a DepthToSpace
    (docs/experiments/2026-11-29-lite-network.md).
    """
    layers = []
    for block in folded.body:
        conv = block[0]
        if isinstance(conv, nn.ConvTranspose2d):
            (k, _), (s, _), (p, _), (op, _) = conv.kernel_size, conv.stride, conv.padding, conv.output_padding
            cin, cout = conv.in_channels, conv.out_channels
            w = conv.weight.data  # [cin, cout, k, k]
            if k == s and p == 0 and op == 0:
                layers.append(block)  # its own s x s block per input pixel: measured faster as it is
                continue
            if p == s and k + op == 3 * s:
                new_w = torch.zeros(cout, s, s, cin, 3, 3)
                for (ry, rx, ty, tx), (ky, kx) in subpixel_taps(k, s):
                    new_w[:, ry, rx, :, ty, tx] = w[:, :, ky, kx].t()
                new = nn.Conv2d(cin, cout * s * s, 3, 1, 1, bias=True)
                new.weight.data = new_w.reshape(cout * s * s, cin, 3, 3)
            else:
                raise ValueError(f"no sub-pixel form for ConvTranspose2d(k={k}, s={s}, p={p}, op={op})")
            new.bias.data = conv.bias.data.repeat_interleave(s * s)
            layers.append(nn.Sequential(new, nn.PixelShuffle(s), nn.ReLU(inplace=True)))
        else:
            layers.append(block)
    out = GraspNet(folded.architecture).eval()
    out.body = nn.Sequential(*layers)
    out.heads = folded.heads
    out.skips = folded.skips
    return out.eval()


def start_lite(model, state):
    """Loads `state`, a `narrow` network's weights, into the `lite` network
    `model`: every layer as it is but the last transposed convolution,
    whose 3 x 3 kernel takes the 9 x 9 one's centre taps (output phase r of
    pixel q from x[q], w[s + r]: what the narrow layer adds from the
    feature right under the pixel, without its two neighbours')."""
    if model.architecture != "lite":
        raise ValueError(f"start_lite loads into a `lite` network, not {model.architecture!r}")
    key = f"body.{len(model.body) - 1}.0.weight"
    own = model.state_dict()
    if set(own) != set(state):
        raise ValueError(f"not the same layers: {sorted(set(own) ^ set(state))}")
    with torch.no_grad():
        for name, value in state.items():
            if name == key:
                s = model.body[-1][0].stride[0]
                own[name].copy_(value[:, :, s:2 * s, s:2 * s])
            else:
                own[name].copy_(value)
    model.load_state_dict(own)
    return model
