"""Augmentation that suits orthographic depth views, with numpy alone.

Every transform keeps views and targets consistent:

* the 8 symmetries of the square (flips and transposes). A view's pixels
  are metric and its depth axis is untouched, so a mirrored view is the
  view of the mirrored object; the angle channels follow: mirroring u sends
  phi to -phi (sin 2phi flips sign), a transpose sends phi to pi/2 - phi
  (cos 2phi flips sign). In a front or side view image v points down
  (gravity, towards the table: `core::view::orthographic`), and the labels
  refuse grasps whose hand would meet the table there. Only the identity
  and the mirror of u keep the table below; `symmetry_mask(view, "gravity")`
  limits those views to them (top views look along gravity and keep all 8).
* a small scale change about the centre (nearest-neighbour on the targets),
  with the opening channel scaled by the same factor;
* depth noise and dropout / clipping on the view only: Gaussian noise on
  the surface, random pixels emptied, a band of the nearest depths clipped.
"""

import numpy as np


def flip_u(view, maps):
    maps = maps[..., ::-1].copy()
    maps[2] *= -1
    return view[..., ::-1].copy(), maps


def flip_v(view, maps):
    maps = maps[..., ::-1, :].copy()
    maps[2] *= -1
    return view[..., ::-1, :].copy(), maps


def transpose(view, maps):
    maps = np.swapaxes(maps, -1, -2).copy()
    maps[1] *= -1
    return np.swapaxes(view, -1, -2).copy(), maps


def symmetry(view, maps, k):
    """The k-th (0..7) symmetry of the square applied to one view [1,L,L] and its maps [4,L,L]."""
    if k & 1:
        view, maps = flip_u(view, maps)
    if k & 2:
        view, maps = flip_v(view, maps)
    if k & 4:
        view, maps = transpose(view, maps)
    return view, maps


SYMMETRY_MODES = ("all", "gravity")
ALL_SYMMETRIES = 7  # bits 1, 2, 4: mirror u, mirror v, transpose
KEEP_DOWN = 1  # mirror u only: image v stays the direction of gravity


def symmetry_mask(view, mode):
    """The bits of the symmetry index a view may use: all for a `top` view
    or in mode "all"; in mode "gravity", the mirror of u alone for the
    views whose image v is gravity (front, side). ValueError for another
    mode, or in mode "gravity" for a view that is none of the three."""
    if mode not in SYMMETRY_MODES:
        raise ValueError(f"symmetries {mode!r}, not one of {SYMMETRY_MODES}")
    if mode == "all" or view == "top":
        return ALL_SYMMETRIES
    if view in ("front", "side"):
        return KEEP_DOWN
    raise ValueError(f"view {view!r} is not top, front or side: its direction of gravity is unknown")


def rescale(view, maps, factor):
    """Zooms about the centre by `factor` (>1 enlarges), opening channel scaled alike."""
    l = view.shape[-1]
    centre = (l - 1) / 2
    src = np.clip(np.rint((np.arange(l) - centre) / factor + centre).astype(int), 0, l - 1)
    inside = np.abs((np.arange(l) - centre) / factor) <= centre + 0.5
    mask = inside[:, None] & inside[None, :]
    view = np.where(mask, view[..., src[:, None], src[None, :]], 0).astype(np.float32)
    maps = np.where(mask, maps[..., src[:, None], src[None, :]], 0).astype(np.float32)
    maps[3] *= factor
    return view, maps


def corrupt(view, rng, noise=0.01, dropout=0.02, clip_share=0.3):
    """Sensor-like damage on a view's surface pixels (empty pixels stay 0)."""
    view = view.copy()
    surface = view > 0
    view[surface] += rng.normal(0, noise, size=int(surface.sum())).astype(np.float32)
    view[surface & (rng.random(view.shape) < dropout)] = 0
    if rng.random() < clip_share and surface.any():
        top = view[surface].max()
        view = np.minimum(view, top - rng.uniform(0, 0.02)).astype(np.float32)
    np.clip(view, 0, 1, out=view)
    view[~surface] = 0
    return view


def augment(view, maps, rng, scale=0.05, mask=ALL_SYMMETRIES):
    """One random augmentation of a view [1,L,L] and its maps [4,L,L]; the
    symmetry drawn is ANDed with `mask` (`symmetry_mask`), so the random
    draws are the same whatever the mask."""
    view, maps = symmetry(view, maps, int(rng.integers(8)) & mask)
    if scale > 0:
        view, maps = rescale(view, maps, float(rng.uniform(1 - scale, 1 + scale)))
    return corrupt(view, rng), maps
