"""Objects: meshes at their sizes, convex parts for collision, mass and friction.

A mesh geom collides in MuJoCo as its convex hull, so every object collides
as a convex decomposition (CoACD), computed once per object and cached under
`target/referee-cache/`. The camera sees the original mesh.

Mass is the mesh volume times a density drawn per object (200-1200 kg/m^3).
A stated share of objects (`HEAVY_PART_SHARE`) carry an off-centre dense
part, a tool's head: half their mass in a small sphere near one end of the
longest axis, inside the object. The planner cannot see it.
"""

import dataclasses
import hashlib
import os
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from . import assets

CACHE = os.path.join(assets.ROOT, "target", "referee-cache", "parts")
COACD = {"threshold": 0.08, "max_convex_hull": 12, "preprocess_resolution": 30, "resolution": 1000,
         "mcts_iterations": 60, "mcts_max_depth": 2, "mcts_nodes": 10, "seed": 1}
DENSITY_KG_M3 = (200.0, 1200.0)
HEAVY_PART_SHARE = 0.25
HEAVY_PART_MASS_SHARE = 0.5
# Coulomb friction (MuJoCo takes the larger of two geoms' values): the
# gripper's rubber pads 0.9 against anything; objects 0.5 (plastic, card,
# painted wood on each other); the table and bin 0.5. Torsional 0.005 m
# and rolling 1e-4 m on the pads (a pad patch of a few mm).
FRICTION_PAD = (0.9, 0.005, 0.0001)
FRICTION_OBJECT = (0.5, 0.005, 0.0001)
FRICTION_TABLE = (0.5, 0.005, 0.0001)


@dataclass
class Body:
    """An object ready to be put in a scene."""

    name: str
    vertices: np.ndarray  # visual mesh, metres, object frame (origin at the mesh's centroid)
    faces: np.ndarray
    parts: list  # convex parts: each an (n, 3) vertex array in the object frame
    volume_m3: float
    mass_kg: float
    heavy_part: tuple | None  # (position in the object frame, mass) or None
    extents_m: np.ndarray
    surface: np.ndarray  # points sampled on the visual mesh (object frame), for the oracle


def _load_mesh(spec):
    import trimesh  # noqa: PLC0415

    if spec.source == "random_urdf":
        mesh = trimesh.load(os.path.join(assets.pybullet_data(), spec.path), force="mesh")
    elif spec.source == "pybullet_mesh":
        mesh = trimesh.load(os.path.join(assets.pybullet_data(), spec.path), force="mesh")
    elif spec.source == "robosuite_mesh":
        mesh = trimesh.load(os.path.join(assets.robosuite_assets(), spec.path), force="mesh")
    elif spec.source == "robosuite_boxes":
        return _boxes_mesh(os.path.join(assets.robosuite_assets(), spec.path))
    elif spec.source == "generated":
        mesh = superellipsoid(spec.extra)
        return mesh, [np.asarray(mesh.vertices, float)]
    else:
        raise ValueError(f"{spec.name}: unknown source {spec.source!r}")
    return mesh, None


def superellipsoid(shape, subdivisions=4):
    """A superellipsoid mesh (`pools.round_shape`'s `extra`): an icosphere's
    vertices pushed along their directions onto the surface
    `(|u/a|^(2/e_xy) + |v/b|^(2/e_xy))^(e_xy/e_z) + |w/c|^(2/e_z) = 1`;
    a cylinder's profile axis `w` turned onto x."""
    import trimesh  # noqa: PLC0415

    sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
    d = np.asarray(sphere.vertices, float)
    (a, b, c), e_z, e_xy = shape["half_m"], shape["e_z"], shape["e_xy"]
    across = (np.abs(d[:, 0] / a) ** (2 / e_xy) + np.abs(d[:, 1] / b) ** (2 / e_xy)) ** (e_xy / e_z)
    radius = (across + np.abs(d[:, 2] / c) ** (2 / e_z)) ** (-e_z / 2)
    v = d * radius[:, None]
    if shape["kind"] == "cylinder":
        v = v[:, [2, 0, 1]]
    return trimesh.Trimesh(vertices=v, faces=np.asarray(sphere.faces), process=False)


def _boxes_mesh(path):
    """A body made of box geoms (robosuite's nuts): one mesh, and each box as a part."""
    import trimesh  # noqa: PLC0415

    boxes = []
    for geom in ET.parse(path).getroot().iter("geom"):
        if geom.get("type") != "box" or geom.get("group", "0") != "0":
            continue
        size = np.array([float(v) for v in geom.get("size").split()])
        pos = np.array([float(v) for v in geom.get("pos", "0 0 0").split()])
        quat = np.array([float(v) for v in geom.get("quat", "1 0 0 0").split()])
        transform = trimesh.transformations.quaternion_matrix(quat)
        transform[:3, 3] = pos
        boxes.append(trimesh.creation.box(extents=2 * size, transform=transform))
    if not boxes:
        raise ValueError(f"{path}: no box geoms")
    return trimesh.util.concatenate(boxes), [b.vertices.copy() for b in boxes]


def _decompose(vertices, faces):
    import coacd  # noqa: PLC0415

    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(np.asarray(vertices, float), np.asarray(faces, np.int64)), **COACD)
    return [np.asarray(p[0], float) for p in parts]


def load(spec):
    """The mesh at its size, centred, and its convex parts (cached)."""
    if spec.resize_m > 0:
        vertices, faces, parts = load(dataclasses.replace(spec, resize_m=0.0))
        k = spec.resize_m / np.ptp(vertices, axis=0).max()
        return vertices * k, faces, [p * k for p in parts]
    key = hashlib.sha256(repr((spec.name, spec.source, spec.path, spec.scale, spec.max_extent_m,
                               sorted(spec.extra.items()), sorted(COACD.items()))).encode()).hexdigest()[:16]
    cached = os.path.join(CACHE, f"{spec.name}-{key}.npz")
    if os.path.exists(cached):
        z = np.load(cached)
        parts = [z[f"part{i}"] for i in range(int(z["count"]))]
        return z["vertices"], z["faces"], parts
    mesh, parts = _load_mesh(spec)
    v = np.asarray(mesh.vertices, float) * spec.scale
    if "axis_scale" in spec.extra:
        v = v / np.ptp(v, axis=0) * np.array(spec.extra["axis_scale"])
        if parts is not None:
            raise ValueError(f"{spec.name}: axis_scale with given parts")
    factor = 1.0
    if spec.max_extent_m > 0:
        factor = spec.max_extent_m / np.ptp(v, axis=0).max()
    v = v * factor
    centre = (v.min(axis=0) + v.max(axis=0)) / 2
    v = v - centre
    faces = np.asarray(mesh.faces, np.int64)
    if parts is None:
        parts = _decompose(v, faces)
    else:
        parts = [p * spec.scale * factor - centre for p in parts]
    save_atomic(cached, vertices=v, faces=faces, count=len(parts), **{f"part{i}": p for i, p in enumerate(parts)})
    return v, faces, parts


def save_atomic(path, **arrays):
    """`np.savez` to `path` through a temporary file of this writer's own.

    Workers that meet the same uncached object decompose it side by side;
    each writes its own temporary file and the last rename wins (same
    content), so no worker renames another's file from under it.
    """
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), prefix=os.path.basename(path) + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **arrays)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def _hull_volume(points):
    from scipy.spatial import ConvexHull  # noqa: PLC0415

    return ConvexHull(points).volume


def make_body(spec, rng):
    """A `Body` for `spec` with mass drawn from `rng` (a numpy Generator)."""
    import trimesh  # noqa: PLC0415

    vertices, faces, parts = load(spec)
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    volume = abs(mesh.volume) if mesh.is_watertight else sum(_hull_volume(p) for p in parts)
    density = rng.uniform(*DENSITY_KG_M3)
    mass = max(volume * density, 0.01)
    heavy = None
    if rng.uniform() < HEAVY_PART_SHARE:
        # Near one end of the longest axis, pulled a third of the way back to
        # the centre so the sphere stays inside the body.
        centred = vertices - vertices.mean(axis=0)
        axis = np.linalg.svd(centred, full_matrices=False)[2][0]
        end = vertices[np.argmax(vertices @ axis * rng.choice([-1.0, 1.0]))]
        heavy = (vertices.mean(axis=0) + 0.6 * (end - vertices.mean(axis=0)), HEAVY_PART_MASS_SHARE * mass)
    surface, _ = trimesh.sample.sample_surface(mesh, 4000, seed=1)
    return Body(spec.name, vertices, faces, parts, volume, mass, heavy, np.ptp(vertices, axis=0),
                np.asarray(surface, float))
