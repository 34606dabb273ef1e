"""The written split of objects: what may be trained or tuned on, and what only reports.

- `train`: `pybullet_data/random_urdfs/000`-`799`. Only the train pools
  (this and the two below, with our procedural families and sample meshes)
  may feed `sim datagen`, training or tuning of any planner setting.
- `train-large`: the same meshes scaled to household sizes (longest side
  10-22 cm, fixed per mesh; heavier with their volume): on the train side,
  for what the URDF's sizes never show. Not a pool of its own meshes.
- `train-round`: rounded shapes generated here (`ROUND_COUNT`
  superellipsoids: balls, oblongs, rounded blocks, cylinders; longest
  side 6-20 cm): on the train side, for the rounded household shapes the
  angular `random_urdfs` never show.
- `test-a`: `random_urdfs/800`-`999`, at the URDF's scale.
- `test-b`: household shapes at realistic sizes (4-25 cm): robosuite's
  objects and pybullet_data's named meshes.

`check_split()` asserts the pools are disjoint and complete; every run
calls it, and so do the tests. Four random_urdfs meshes are plates thinner
than `THINNEST_PICKABLE_M` (`TOO_THIN`): they stay in their pools, but an
episode draws the next mesh of the pool in their place.
"""

from dataclasses import dataclass, field

import numpy as np

TRAIN_RANDOM = range(0, 800)
TEST_A_RANDOM = range(800, 1000)

# random_urdfs meshes whose thinnest side at the URDF's scale is under this:
# plates (295: 0.8 mm, 297: 1.5, 602: 1.5, 824: 0.5 mm) that two fingers
# cannot pick off a table and a depth camera cannot tell from it. The
# planner sees nothing there, so an episode holding one ended with "no
# grasp" and the plate left, whatever the planner.
THINNEST_PICKABLE_M = 0.002
TOO_THIN = frozenset(f"random_{i:03d}" for i in (295, 297, 602, 824))


@dataclass(frozen=True)
class ObjectSpec:
    """One object: where its mesh comes from and how big it is."""

    name: str
    source: str  # "random_urdf", "pybullet_mesh", "robosuite_mesh" or "robosuite_boxes"
    path: str  # relative to its asset folder
    scale: float = 1.0  # mesh units -> metres, before `max_extent_m`
    max_extent_m: float = 0.0  # if > 0, the longest side is scaled to this
    resize_m: float = 0.0  # if > 0, the object as loaded without it, scaled about its centre to this longest side
    extra: dict = field(default_factory=dict, compare=False, hash=False)


def random_urdf(index, resize_m=0.0):
    """`random_urdfs/NNN`, at the URDF's mesh scale (0.015), or resized."""
    n = f"{index:03d}"
    return ObjectSpec(f"random_{n}", "random_urdf", f"random_urdfs/{n}/{n}.obj", scale=0.015, resize_m=resize_m)


LARGE_M = (0.10, 0.22)


def large_size(index):
    """`train-large`'s longest side for mesh `index`: spread evenly over
    `LARGE_M` by the golden ratio, the same in every run."""
    return round(LARGE_M[0] + (LARGE_M[1] - LARGE_M[0]) * ((index * 0.6180339887) % 1.0), 4)


# Household shapes: longest side in metres (real objects of that kind).
HOUSEHOLD = (
    ObjectSpec("mug", "pybullet_mesh", "objects/mug.obj", max_extent_m=0.12),
    ObjectSpec("duck", "pybullet_mesh", "duck_vhacd.obj", max_extent_m=0.10),
    ObjectSpec("teddy", "pybullet_mesh", "teddy2_VHACD_CHs.obj", max_extent_m=0.16),
    ObjectSpec("bunny", "pybullet_mesh", "bunny.obj", max_extent_m=0.12),
    ObjectSpec("soccer_ball", "pybullet_mesh", "soccerball.obj", max_extent_m=0.09),
    ObjectSpec("lego_brick", "pybullet_mesh", "lego/lego.obj", max_extent_m=0.064),
    ObjectSpec("jenga_block", "pybullet_mesh", "jenga/jenga.obj", extra={"axis_scale": (0.15, 0.05, 0.03)}),
    ObjectSpec("bottle", "robosuite_mesh", "objects/meshes/bottle.stl", max_extent_m=0.22),
    ObjectSpec("can", "robosuite_mesh", "objects/meshes/can.stl", max_extent_m=0.12),
    ObjectSpec("cereal", "robosuite_mesh", "objects/meshes/cereal.stl", max_extent_m=0.18),
    ObjectSpec("milk", "robosuite_mesh", "objects/meshes/milk.stl", max_extent_m=0.20),
    ObjectSpec("bread", "robosuite_mesh", "objects/meshes/bread.stl", max_extent_m=0.12),
    ObjectSpec("lemon", "robosuite_mesh", "objects/meshes/lemon.stl", max_extent_m=0.08),
    ObjectSpec("round_nut", "robosuite_boxes", "objects/round-nut.xml", max_extent_m=0.10),
    ObjectSpec("square_nut", "robosuite_boxes", "objects/square-nut.xml", max_extent_m=0.10),
)

ROUND_COUNT = 120
ROUND_M = (0.06, 0.20)
ROUND_KINDS = ("ball", "oblong", "rounded_block", "cylinder")


def round_shape(index):
    """`train-round`'s object `index`: a superellipsoid, the same in every
    run. Its kind cycles through `ROUND_KINDS` (a ball or egg, an oblong
    like a lemon or a loaf, a rounded block, a cylinder lying on its side);
    `extra` holds its semi-axes in its own frame (m; `half_m[2]` along the
    profile axis `e_z` shapes, world z, or x for a cylinder; the longest,
    spread over `ROUND_M` by the golden ratio) and the two exponents (`e_xy`
    the cross-section: 1 round, towards 0 square). Every exponent is at
    most 1, so every shape is convex (its own collision part)."""
    rng = np.random.default_rng([index, 47])
    kind = ROUND_KINDS[index % len(ROUND_KINDS)]
    a = (ROUND_M[0] + (ROUND_M[1] - ROUND_M[0]) * ((index * 0.6180339887) % 1.0)) / 2.0
    if kind == "ball":
        half, e_z, e_xy = (a, a * rng.uniform(0.8, 1.0), a * rng.uniform(0.75, 1.0)), 1.0, 1.0
    elif kind == "oblong":
        half, e_z, e_xy = (a, a * rng.uniform(0.4, 0.75), a * rng.uniform(0.35, 0.7)), 1.0, 1.0
    elif kind == "rounded_block":
        half = (a, a * rng.uniform(0.4, 1.0), a * rng.uniform(0.3, 0.9))
        e_z, e_xy = rng.uniform(0.2, 0.6), rng.uniform(0.2, 0.6)
    else:
        r = a * rng.uniform(0.3, 0.6)
        half, e_z, e_xy = (r, r, a), rng.uniform(0.1, 0.3), 1.0
    extra = {"kind": kind, "half_m": tuple(round(float(h), 5) for h in half),
             "e_z": round(float(e_z), 4), "e_xy": round(float(e_xy), 4)}
    return ObjectSpec(f"round_{index:03d}", "generated", f"superellipsoid/{index:03d}", extra=extra)


POOLS = {
    "train": tuple(random_urdf(i) for i in TRAIN_RANDOM),
    "train-large": tuple(random_urdf(i, large_size(i)) for i in TRAIN_RANDOM),
    "train-round": tuple(round_shape(i) for i in range(ROUND_COUNT)),
    "test-a": tuple(random_urdf(i) for i in TEST_A_RANDOM),
    "test-b": HOUSEHOLD,
}

TEST_POOLS = ("test-a", "test-b")
TRAIN_POOLS = ("train", "train-large", "train-round")  # what may be trained or tuned on
RESIZED = {"train-large": "train"}  # pools of another pool's meshes, resized


def pool(name):
    """The objects of a pool, in a fixed order."""
    if name not in POOLS:
        raise ValueError(f"unknown pool {name!r} (one of {', '.join(POOLS)})")
    return POOLS[name]


def check_split():
    """Raises if a mesh is in two pools or a random_urdf is in none."""
    seen = {}
    for name, objects in POOLS.items():
        if name in RESIZED:
            base = {o.path for o in POOLS[RESIZED[name]]}
            if any(o.path not in base or o.resize_m <= 0 for o in objects):
                raise AssertionError(f"{name} holds a mesh that is not {RESIZED[name]}'s, resized")
            continue
        for o in objects:
            if o.path in seen:
                raise AssertionError(f"{o.path} is in both {seen[o.path]} and {name}")
            seen[o.path] = name
    for i in range(1000):
        if random_urdf(i).path not in seen:
            raise AssertionError(f"random_urdfs/{i:03d} is in no pool")
    return True
