"""The paper's grasp accuracy, with numpy alone.

A view's prediction is the grasp at the pixel of highest predicted quality,
with the predicted angle and opening there. It is correct when some
ground-truth positive of that view (`grasps.npy`) has an angle within 30
degrees of it (angles are modulo 180: a parallel-jaw grasp is symmetric)
and a grasp rectangle overlapping it with IoU > 25%. A rectangle is the
opening (along the closing direction) by the finger pad width (across it),
both in pixels. Accuracy counts views that have at least one positive;
views without one are reported apart: how often the prediction there still
clears a quality threshold.

The 30 degrees are the paper's. `angle_limit_deg` makes it stricter: on
boxes, grasps 20 degrees or more off the faces pass at 30 yet slip half
the time in physics (docs/experiments/2026-11-25-where-the-slips-are.md, "Where the slips are").
"""

import numpy as np

from .stats import sign_test

ANGLE_LIMIT_DEG = 30.0
IOU_LIMIT = 0.25


def decode(maps):
    """Argmax-quality grasp per view: arrays (u, v, phi, opening_units, quality), [N] each.

    `maps` is [N, 4, L, L] in the order quality, cos2phi, sin2phi, width.
    """
    n, _, l, _ = maps.shape
    flat = maps[:, 0].reshape(n, -1)
    best = flat.argmax(axis=1)
    v, u = np.divmod(best, l)
    at = maps[np.arange(n), :, v, u]  # [N, 4]
    phi = 0.5 * np.arctan2(at[:, 2], at[:, 1])
    return u, v, phi, at[:, 3], at[:, 0]


def smooth_quality(maps, sigma_px):
    """`maps` with the quality channel blurred as the planner blurs it before
    its peak search (`core::decode::smooth`: a separable Gaussian of radius
    ceil(3 sigma), edges clamped, qualities under 1e-6 set to 0 first); the
    other channels are left as they are, read at the peak. `sigma_px <= 0`
    returns `maps` unchanged: the paper's metric reads the network's raw
    argmax."""
    if sigma_px <= 0:
        return maps
    r = int(np.ceil(3.0 * sigma_px))
    kernel = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma_px) ** 2)
    kernel /= kernel.sum()
    q = np.where(maps[:, 0] > 1e-6, maps[:, 0], 0.0).astype(np.float32)
    for axis in (2, 1):  # rows, then columns
        pad = [(0, 0)] * 3
        pad[axis] = (r, r)
        padded = np.pad(q, pad, mode="edge")
        n = q.shape[axis]
        q = sum(w * np.take(padded, np.arange(k, k + n), axis=axis) for k, w in enumerate(kernel))
    out = maps.copy()
    out[:, 0] = q
    return out


def angle_diff(a, b):
    """Difference of grasp angles modulo pi, in [0, pi/2]."""
    d = np.mod(np.asarray(a) - np.asarray(b), np.pi)
    return np.minimum(d, np.pi - d)


def rectangle(u, v, phi, length, height):
    """Corners (4 x 2, counter-clockwise in u, v) of a grasp rectangle centred on pixel (u, v)."""
    c, s = np.cos(phi), np.sin(phi)
    along, across = np.array([c, s]) * length / 2, np.array([-s, c]) * height / 2
    centre = np.array([u + 0.5, v + 0.5])
    return np.array([centre - along - across, centre + along - across,
                     centre + along + across, centre - along + across])


def _area(poly):
    if len(poly) < 3:
        return 0.0
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _clip(subject, clipper):
    """Sutherland-Hodgman: `subject` clipped by convex `clipper` (both counter-clockwise)."""
    out = list(subject)
    orient = np.sign(_signed_area(clipper)) or 1.0
    for i in range(len(clipper)):
        a, b = clipper[i], clipper[(i + 1) % len(clipper)]
        inside = lambda p: orient * ((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])) >= 0  # noqa: E731
        points, out = out, []
        for j in range(len(points)):
            p, q = points[j], points[(j + 1) % len(points)]
            if inside(q):
                if not inside(p):
                    out.append(_intersect(p, q, a, b))
                out.append(q)
            elif inside(p):
                out.append(_intersect(p, q, a, b))
        if not out:
            return np.zeros((0, 2))
    return np.array(out)


def _signed_area(poly):
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * (np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _intersect(p, q, a, b):
    d1, d2 = q - p, b - a
    denom = d1[0] * d2[1] - d1[1] * d2[0]
    if denom == 0:
        return q
    t = ((a[0] - p[0]) * d2[1] - (a[1] - p[1]) * d2[0]) / denom
    return p + t * d1


def iou(r1, r2):
    """Intersection over union of two convex polygons."""
    inter = _area(_clip(r1, r2))
    union = _area(r1) + _area(r2) - inter
    return inter / union if union > 0 else 0.0


def grasp_correct(pred, truth, pixel_m, pad_m, angle_limit_deg=ANGLE_LIMIT_DEG):
    """Whether `pred` = (u, v, phi, opening_m) matches a row of `truth` [k, >=4] (u, v, phi, opening_m),
    its angle within `angle_limit_deg` of that row's."""
    if len(truth) == 0:
        return False
    u, v, phi, opening = pred
    height = pad_m / pixel_m
    length = max(opening / pixel_m, 1.0)
    close = angle_diff(truth[:, 2], phi) < np.deg2rad(angle_limit_deg)
    reach = (length + truth[:, 3] / pixel_m) / 2 + height
    close &= np.hypot(truth[:, 0] - u, truth[:, 1] - v) < reach
    if not close.any():
        return False
    mine = rectangle(u, v, phi, length, height)
    for t in truth[close]:
        other = rectangle(t[0], t[1], t[2], max(t[3] / pixel_m, 1.0), height)
        if iou(mine, other) > IOU_LIMIT:
            return True
    return False


def hits(pred_maps, ds, indices, angle_limit_deg=ANGLE_LIMIT_DEG):
    """Per view `indices[k]`: whether the best predicted grasp of
    `pred_maps[k]` matches one of its positives (None: it has none;
    `grasp_correct` with `angle_limit_deg`); and the best predicted
    qualities."""
    c = ds.contract
    pixel_m, width_scale = c["pixel_size_m"], c["width_scale_m"]
    pad_m = ds.manifest["gripper"]["pad_width_m"]
    u, v, phi, width, quality = decode(pred_maps)
    out = []
    for k, i in enumerate(indices):
        truth = ds.grasps_of(i)
        out.append(grasp_correct((u[k], v[k], phi[k], width[k] * width_scale), truth, pixel_m, pad_m,
                                 angle_limit_deg) if len(truth) else None)
    return out, quality


def paired_views(first_ok, ok):
    """Two models' `hits` on the same views: (views only the second got
    right, views only the first got right, the sign test's p on those).
    Views without positives (None) are left out."""
    pairs = [(f, o) for f, o in zip(first_ok, ok, strict=True) if f is not None]
    only_it = sum(o and not f for f, o in pairs)
    only_first = sum(f and not o for f, o in pairs)
    return only_it, only_first, sign_test(only_it, only_first)


def miss_kinds(pred_maps, ds, indices, near_px=2.0, ok=None):
    """Why the views with positives are missed: the best pixel more than
    `near_px` from every positive (`missed_far`: which pixel wins), or
    within it with the angle or opening off (`missed_heads`); and the median
    number of positives of the views hit and of those missed (models/RECIPES.md:
    the misses are mostly views whose labels pass few grasps). `ok`: the
    judgements of `hits`, where the caller has them already."""
    if ok is None:
        ok, _ = hits(pred_maps, ds, indices)
    u, v, *_ = decode(pred_maps)
    far, heads, counts = 0, 0, {True: [], False: []}
    for k, i in enumerate(indices):
        if ok[k] is None:
            continue
        truth = ds.grasps_of(i)
        counts[ok[k]].append(len(truth))
        if not ok[k]:
            if np.hypot(truth[:, 0] - u[k], truth[:, 1] - v[k]).min() > near_px:
                far += 1
            else:
                heads += 1

    return {"views_with_positives": len(counts[True]) + len(counts[False]), "missed_far": far,
            "missed_heads": heads, "median_positives_hit": median_of(counts[True]),
            "median_positives_missed": median_of(counts[False])}


def evaluate(pred_maps, ds, indices, threshold=0.5, by=(), object_threshold=0.1, angle_limit_deg=ANGLE_LIMIT_DEG,
             judged=None):
    """Accuracy of `pred_maps` [len(indices), 4, L, L] on views `indices` of `ds`.

    Returns a dict: accuracy over views with positives, per view axis, and the
    share of views without positives whose best predicted quality clears
    `threshold` (false alarms), and the median best quality of views without
    and with positives (`median_peak_*`); why the misses were missed (`misses`:
    `miss_kinds` of the same judgements); the objects' picks under the
    planner's `all` view policy at quality `object_threshold` (`objects`:
    `object_picks`), and the same over each scene's views (`scenes`: the
    first pick of a clear-the-table run); for each meta key in `by`
    (scenario, family, ...), `per_KEY` = `accuracy_by` of the same judgements.
    A prediction matches a positive within `angle_limit_deg` (the paper's 30).
    `judged`: `hits` of the same maps and views, where the caller has them
    already (evaluate_onnx also pairs models on them).
    """
    ok, quality = judged if judged is not None else hits(pred_maps, ds, indices, angle_limit_deg)
    per_axis, empty, alarms = {}, 0, 0
    instances = [ds.meta[i].get("instance", f"view {i}") for i in indices]
    # A scene is a seed of a scenario, or an episode's frame (`step`: sim eval
    # --label-frames, which runs every scenario from the same seeds).
    scenes = [(ds.meta[i].get("scenario"), ds.meta[i].get("scene_seed", f"view {i}"), ds.meta[i].get("step"))
              for i in indices]
    for k, i in enumerate(indices):
        if ok[k] is None:
            empty += 1
            alarms += int(quality[k] >= threshold)
            continue
        axis = ds.meta[i]["view"]
        h, t = per_axis.get(axis, (0, 0))
        per_axis[axis] = (h + int(ok[k]), t + 1)
    total_hits = sum(h for h, _ in per_axis.values())
    total = sum(t for _, t in per_axis.values())
    return {
        "accuracy": total_hits / total if total else float("nan"),
        "views_with_positives": total,
        "per_view": {a: {"accuracy": h / t, "views": t} for a, (h, t) in sorted(per_axis.items())},
        "views_without_positives": empty,
        "false_alarm_rate": alarms / empty if empty else float("nan"),
        "false_alarm_threshold": threshold,
        "median_peak_without_positives": median_of([q for q, h in zip(quality, ok) if h is None]),
        "median_peak_with_positives": median_of([q for q, h in zip(quality, ok) if h is not None]),
        "misses": miss_kinds(pred_maps, ds, indices, ok=ok),
        "objects": object_picks(ok, quality, instances, object_threshold),
        "scenes": object_picks(ok, quality, scenes, object_threshold),
        **{f"per_{key}": accuracy_by(ok, [ds.meta[i].get(key, "?") for i in indices]) for key in by},
    }


def object_picks(ok, quality, instances, threshold=0.1):
    """The planner's `all` view policy, judged per object: each object
    (`instances[k]`, meta `instance`) acts on the best predicted grasp over
    all its views, and only if its quality clears `threshold` (the planner's
    `min_quality`). `ok` and `quality` are `hits`' judgements and best
    qualities for the same views.

    Returns `objects_with_positives` (some view of it has a positive) and
    `objects_without_positives`; `accuracy`: of the former, the share whose
    best grasp across views is a positive, at any quality (a view without
    positives winning is a miss); `picked`: the same share, counting only
    grasps at or above `threshold` (what a clear-the-table run can pick);
    `attempts`: the objects of either kind whose best grasp clears
    `threshold`, and `attempt_precision`: the share of those that are
    positives; `false_alarm_rate`: the share of objects without any positive
    whose best grasp clears `threshold`; `wrong_view`: objects with positives
    whose winning view has none, and `another_view_right`: objects missed
    while another of their views was right (what a perfect view choice
    would win). Views' accuracy (`evaluate`) judges each view alone; this
    weighs quality across views too, which a model that inflates the
    quality of views without positives loses.
    """
    best, has_positive = {}, {}
    for k, name in enumerate(instances):
        # Ties go to the earlier view, as the planner's order does.
        if name not in best or quality[k] > quality[best[name]]:
            best[name] = k
        has_positive[name] = has_positive.get(name, False) or ok[k] is not None
    with_pos = [n for n in best if has_positive[n]]
    without = [n for n in best if not has_positive[n]]
    correct = {n: bool(ok[best[n]]) for n in best}
    another_right = {n for k, n in enumerate(instances) if ok[k] and not correct[n]}
    tried = [n for n in best if quality[best[n]] >= threshold]

    def share(num, den):
        return num / den if den else float("nan")

    return {
        "threshold": threshold,
        "objects_with_positives": len(with_pos),
        "objects_without_positives": len(without),
        "accuracy": share(sum(correct[n] for n in with_pos), len(with_pos)),
        "picked": share(sum(correct[n] and quality[best[n]] >= threshold for n in with_pos), len(with_pos)),
        "attempts": len(tried),
        "attempt_precision": share(sum(correct[n] for n in tried), len(tried)),
        "false_alarm_rate": share(sum(quality[best[n]] >= threshold for n in without), len(without)),
        "wrong_view": sum(ok[best[n]] is None for n in with_pos),
        "another_view_right": len(another_right),
    }


def median_of(values):
    """The median as a float; None for no values."""
    return float(np.median(values)) if len(values) else None


def accuracy_by(ok, names):
    """{name: {"accuracy", "views"}} of the judgements `ok` (True / False;
    None, a view without positives, counts nowhere) grouped by the parallel
    list `names`; a name with no judged view gets nan and 0."""
    out = {}
    for name in sorted(set(names)):
        judged = [h for h, n in zip(ok, names) if n == name and h is not None]
        out[name] = {"accuracy": sum(judged) / len(judged) if judged else float("nan"), "views": len(judged)}
    return out


def misses(pred_maps, ds, indices, ok=None):
    """Positions k (into `indices`) of the views with positives whose best
    predicted grasp matches none of them. `ok`: `hits`' judgements of these
    views, where the caller has them already (at its own angle limit);
    without it they are judged here at the paper's."""
    if ok is None:
        ok, _ = hits(pred_maps, ds, indices)
    return [k for k, h in enumerate(ok) if h is False]
