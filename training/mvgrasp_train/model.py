"""The grasp network (PyTorch): the paper's final architecture and a cheaper variant.

DESIGN.md, method step 5. Encoder C(9x9x8,s3) C(5x5x16,s2) C(5x5x16,s2)
C(3x3x32) x3, decoder T(3x3x32) x3 T(5x5x16,s2) T(5x5x32,s2) T(9x9x32,s3),
BatchNorm + ReLU after each, "same" padding (explicit pads and output
padding, so the output is the input's size for sides that are multiples of
12), then 1x1 heads: quality (sigmoid), cos 2phi, sin 2phi, width.

Variant `narrow`: the same network with the last transposed convolution
giving 8 channels instead of 32. That layer runs at full resolution and is
about half the CPU time of the whole network (BENCHMARKS.md).
"""

import torch
from torch import nn

ARCHITECTURES = ("paper", "narrow")


def _block(conv, channels):
    return nn.Sequential(conv, nn.BatchNorm2d(channels), nn.ReLU(inplace=True))


class GraspNet(nn.Module):
    def __init__(self, architecture="paper"):
        super().__init__()
        if architecture not in ARCHITECTURES:
            raise ValueError(f"unknown architecture {architecture!r}; one of {ARCHITECTURES}")
        self.architecture = architecture
        last = 32 if architecture == "paper" else 8
        enc = [(1, 8, 9, 3, 3), (8, 16, 5, 2, 2), (16, 16, 5, 2, 2), (16, 32, 3, 1, 1), (32, 32, 3, 1, 1),
               (32, 32, 3, 1, 1)]
        dec = [(32, 32, 3, 1, 1, 0), (32, 32, 3, 1, 1, 0), (32, 32, 3, 1, 1, 0), (32, 16, 5, 2, 2, 1),
               (16, 32, 5, 2, 2, 1), (32, last, 9, 3, 3, 0)]
        layers = [_block(nn.Conv2d(i, o, k, s, p, bias=False), o) for i, o, k, s, p in enc]
        layers += [_block(nn.ConvTranspose2d(i, o, k, s, p, op, bias=False), o) for i, o, k, s, p, op in dec]
        self.body = nn.Sequential(*layers)
        self.heads = nn.Conv2d(last, 4, 1)

    def forward(self, views):
        x = self.heads(self.body(views))
        return torch.cat([torch.sigmoid(x[:, :1]), x[:, 1:]], dim=1)


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
