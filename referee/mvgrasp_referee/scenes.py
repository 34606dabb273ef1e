"""Scenes of the clear-the-table protocol, fixed by seed.

- `isolated`: one object in a random stable pose (dropped from a random
  orientation near the middle of the table and settled);
- `packed`: five objects standing close (upright as their mesh stands,
  turned at random, outlines 2 cm or more apart);
- `pile`: five objects dropped from random orientations into a 16 cm box,
  settled, then the box is taken away;
- `clutter`: heavy clutter, ten objects dropped from random orientations
  over a 22 cm box (each above whatever it would overlap), settled, then
  the box is taken away. Not in the default `--scenarios`.
"""

import itertools
import math

import mujoco
import numpy as np

from . import cell as cellmod
from . import objects as objmod
from . import pools

# objects, consecutive failures allowed
SCENARIOS = {"isolated": (1, 3), "packed": (5, 4), "pile": (5, 4), "clutter": (10, 4)}
SETTLE_S = 1.5
CLUTTER_HALF_M = 0.11  # the box the clutter is dropped into (inner half width)
CLUTTER_SETTLE_S = 3.0  # ten objects from up to about a metre
PACKED_HALF_M = 0.12  # packed objects' centres are drawn from this square (the robot's)
PACKED_GAP_M = 0.02  # least gap between two packed objects' outlines
PACKED_GROW_M = 0.02  # the square grows by this after each 100 draws without room


def random_quat(rng):
    u = rng.uniform(size=3)
    return np.array([math.sqrt(1 - u[0]) * math.sin(2 * math.pi * u[1]),
                     math.sqrt(1 - u[0]) * math.cos(2 * math.pi * u[1]),
                     math.sqrt(u[0]) * math.sin(2 * math.pi * u[2]),
                     math.sqrt(u[0]) * math.cos(2 * math.pi * u[2])])


def yaw_quat(yaw):
    return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


def choose_objects(pool_name, scenario, seed, episode):
    """The objects of one episode: a deterministic draw from the pool."""
    objects = pools.pool(pool_name)
    count = SCENARIOS[scenario][0]
    rng = np.random.default_rng([seed, episode, 7])
    if scenario == "isolated":
        drawn = [(seed * 7919 + episode) % len(objects)] if pool_name != "test-b" else [episode % len(objects)]
    else:
        drawn = [int(i) for i in rng.choice(len(objects), size=count, replace=len(objects) < count)]
    return [objects[i] for i in _pickable(objects, drawn)]


def _pickable(objects, drawn):
    """`drawn` with each mesh too thin to pick (`pools.TOO_THIN`) replaced by
    the next one of the pool that is neither too thin nor drawn already;
    every other index as drawn."""
    out = []
    for i in drawn:
        while objects[i].name in pools.TOO_THIN:
            i = (i + 1) % len(objects)
            while i in drawn or i in out:
                i = (i + 1) % len(objects)
        out.append(i)
    return out


def bounding_radius(body):
    """The radius of the sphere around `body`'s box, about its centre."""
    return 0.5 * float(np.linalg.norm(body.extents_m))


def _hull(points):
    """The convex hull of 2-D points, counter-clockwise, no repeated corner
    (Andrew's monotone chain)."""
    pts = sorted(set(map(tuple, np.round(points, 9))))

    def half(seq):
        chain = []
        for p in seq:
            while len(chain) >= 2 and ((chain[-1][0] - chain[-2][0]) * (p[1] - chain[-2][1])
                                       - (chain[-1][1] - chain[-2][1]) * (p[0] - chain[-2][0])) <= 0:
                chain.pop()
            chain.append(p)
        return chain[:-1]

    return np.array(half(pts) + half(pts[::-1]) if len(pts) > 2 else pts, float)


def _footprint(body, yaw):
    """The outline on the table of `body` standing as its mesh stands, turned
    by `yaw`: the convex hull of its collision parts seen from above."""
    c, s = math.cos(yaw), math.sin(yaw)
    xy = np.concatenate(body.parts)[:, :2] @ np.array([[c, s], [-s, c]])
    return _hull(xy)


def _apart(a, b, gap):
    """Whether convex outlines `a` and `b` are `gap` or more apart along an
    edge normal of either (a separating axis; the true distance is at least that)."""
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)
        normals = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        pa, pb = a @ normals.T, b @ normals.T
        if (np.maximum(pb.min(0) - pa.max(0), pa.min(0) - pb.max(0)) >= gap).any():
            return True
    return False


def _packed(bodies, rng):
    """Upright objects, each turned at random and put where its outline stays
    `PACKED_GAP_M` from every one placed before; after every 100 draws that
    found no room the square drawn from grows by `PACKED_GROW_M` a side, so
    an object that does not fit lands outside the robot's square (and is
    not counted) rather than inside another."""
    out, placed = [], []
    for b in bodies:
        yaw = rng.uniform(0, 2 * math.pi)
        shape = _footprint(b, yaw)
        for k in itertools.count():
            half = PACKED_HALF_M + PACKED_GROW_M * (k // 100)
            xy = rng.uniform(-half, half, 2)
            if all(_apart(shape + xy, other, PACKED_GAP_M) for other in placed):
                break
        placed.append(shape + xy)
        bottom = min(float(p[:, 2].min()) for p in b.parts)
        out.append(((xy[0], xy[1], -bottom + 0.005), yaw_quat(yaw)))
    return out


def placements(scenario, bodies, rng):
    if scenario == "isolated":
        b = bodies[0]
        xy = rng.uniform(-0.05, 0.05, 2)
        return [((xy[0], xy[1], 0.5 * float(np.max(b.extents_m)) + 0.02), random_quat(rng))]
    if scenario == "packed":
        return _packed(bodies, rng)
    if scenario == "pile":
        out, z = [], 0.0
        for b in bodies:
            z += float(np.max(b.extents_m)) + 0.01
            xy = rng.uniform(-0.04, 0.04, 2)
            out.append(((xy[0], xy[1], z), random_quat(rng)))
        return out
    if scenario == "clutter":
        # Bounding spheres never overlap at the start: each object goes above
        # every placed one whose footprint its own would meet.
        out, placed = [], []
        for b in bodies:
            r = bounding_radius(b)
            xy = rng.uniform(-CLUTTER_HALF_M + 0.03, CLUTTER_HALF_M - 0.03, 2)
            z = max([pz + pr for pxy, pz, pr in placed if np.linalg.norm(xy - pxy) < r + pr], default=0.0) + r + 0.01
            placed.append((xy, z, r))
            out.append(((xy[0], xy[1], z), random_quat(rng)))
        return out
    raise ValueError(f"unknown scenario {scenario!r} (one of {', '.join(SCENARIOS)})")


def _walls(half, h):
    """Four walls of a box `2 half` wide inside, `2 h` high, around the origin."""
    return [(f"pile_wall{k}", size, centre) for k, (size, centre) in enumerate([
        ((0.005, half, h), (half + 0.005, 0, h)), ((0.005, half, h), (-half - 0.005, 0, h)),
        ((half, 0.005, h), (0, half + 0.005, h)), ((half, 0.005, h), (0, -half - 0.005, h))])]


def make(scenario, pool_name, seed, episode):
    """A settled cell for one episode."""
    specs = choose_objects(pool_name, scenario, seed, episode)
    rng = np.random.default_rng([seed, episode, 11])
    bodies = [objmod.make_body(s, rng) for s in specs]
    where = placements(scenario, bodies, rng)
    fixtures = {"pile": _walls(0.08, 0.3), "clutter": _walls(CLUTTER_HALF_M, 0.4)}.get(scenario, [])
    cell = cellmod.build(bodies, where, fixtures=fixtures)
    settle(cell, CLUTTER_SETTLE_S if scenario == "clutter" else SETTLE_S)
    if fixtures:
        # Take the box away: rebuild without it, objects where they came to rest.
        rest = [cell.object_pose(i) for i in range(len(bodies))]
        cell = cellmod.build(bodies, rest)
        settle(cell)
    return cell, specs


def settle(cell, seconds=SETTLE_S):
    for _ in range(int(seconds / cellmod.TIMESTEP_S)):
        mujoco.mj_step(cell.model, cell.data)
    # Start the episode at rest.
    cell.data.qvel[:] = 0.0


def on_table(cell, i):
    """Still on the table and in the square the robot is asked to clear
    (the planner's workspace)."""
    p = cell.object_pose(i)[0]
    half = cellmod.TASK_HALF_M
    return p[2] > -0.02 and abs(p[0]) < half and abs(p[1]) < half
