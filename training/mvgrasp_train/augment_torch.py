"""The augmentation of augment.py on whole batches of torch tensors (GPU training).

Same transforms, same order, same conventions: the 8 symmetries of the
square with the angle channels following, a scale change about the centre
(nearest neighbour, opening channel scaled alike), then depth noise,
dropout and clipping on the view's surface pixels. For the same symmetry
index and scale factor the result equals augment.py's to the bit
(test_torch_parts.py checks it); the random draws differ, since they come
from torch's generator, one per sample.

Per-sample numpy augmentation costs about 0.3 ms a view in Python, which
starves a GPU; this runs a batch of 256 views in a handful of kernels.
"""

import torch


def symmetry(views, maps, k):
    """Applies symmetry k[b] (0..7, as augment.symmetry) to views [B,1,L,L] and maps [B,4,L,L]."""
    sign = torch.ones_like(maps[:, :, :1, :1])
    for bit, flip_dims, channel in ((1, (-1,), 2), (2, (-2,), 2)):
        on = (k & bit).bool().view(-1, 1, 1, 1)
        views = torch.where(on, views.flip(flip_dims), views)
        maps = torch.where(on, maps.flip(flip_dims), maps)
        sign[:, channel] = torch.where(on[:, 0], -sign[:, channel], sign[:, channel])
    on = (k & 4).bool().view(-1, 1, 1, 1)
    views = torch.where(on, views.transpose(-1, -2), views)
    maps = torch.where(on, maps.transpose(-1, -2), maps)
    sign[:, 1] = torch.where(on[:, 0], -sign[:, 1], sign[:, 1])
    return views, maps * sign


def rescale(views, maps, factor):
    """Zooms sample b about the centre by factor[b] (float64 [B]), as augment.rescale."""
    b, _, l, _ = views.shape
    centre = (l - 1) / 2
    offsets = torch.arange(l, device=views.device, dtype=torch.float64) - centre
    scaled = offsets[None, :] / factor[:, None]  # [B, L]
    src = torch.clamp(torch.round(scaled + centre), 0, l - 1).long()
    inside = scaled.abs() <= centre + 0.5
    mask = (inside[:, :, None] & inside[:, None, :]).view(b, 1, l * l)
    index = (src[:, :, None] * l + src[:, None, :]).view(b, 1, l * l)

    def resample(x):
        c = x.shape[1]
        picked = torch.gather(x.reshape(b, c, l * l), 2, index.expand(b, c, l * l))
        return torch.where(mask, picked, torch.zeros_like(picked)).view(b, c, l, l)

    views, maps = resample(views), resample(maps)
    maps[:, 3] *= factor.to(maps.dtype)[:, None, None]
    return views, maps


def corrupt(views, generator, noise=0.01, dropout=0.02, clip_share=0.3):
    """Sensor-like damage on the surface pixels of each view (empty pixels stay 0), as augment.corrupt."""
    b = views.shape[0]
    surface = views > 0
    noisy = views + noise * torch.randn(views.shape, generator=generator, device=views.device)
    drop = torch.rand(views.shape, generator=generator, device=views.device) < dropout
    noisy = torch.where(surface & drop, torch.zeros_like(noisy), noisy)
    top = torch.where(surface, noisy, torch.full_like(noisy, -torch.inf)).amax(dim=(1, 2, 3))
    clip = (torch.rand(b, generator=generator, device=views.device) < clip_share) & surface.flatten(1).any(1)
    ceiling = top - 0.02 * torch.rand(b, generator=generator, device=views.device)
    ceiling = torch.where(clip, ceiling, torch.full_like(ceiling, torch.inf)).view(b, 1, 1, 1)
    noisy = torch.minimum(noisy, ceiling).clamp(0, 1)
    return torch.where(surface, noisy, torch.zeros_like(noisy))


def augment(views, maps, generator, scale=0.05, mask=None):
    """One random augmentation of each view [B,1,L,L] and its maps [B,4,L,L];
    sample b's symmetry is ANDed with mask[b] (int64 [B], augment.symmetry_mask;
    None: all 8), the draws the same whatever the mask."""
    b, device = views.shape[0], views.device
    k = torch.randint(0, 8, (b,), generator=generator, device=device)
    if mask is not None:
        k = k & mask
    views, maps = symmetry(views, maps, k)
    if scale > 0:
        u = torch.rand(b, generator=generator, device=device, dtype=torch.float64)
        views, maps = rescale(views, maps, 1 - scale + 2 * scale * u)
    return corrupt(views, generator), maps
