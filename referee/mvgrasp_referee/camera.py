"""The depth camera: poses, intrinsics, rendering, noise.

Poses look at the objects' area (the world origin, table top):
- `topdown`: 1.0-1.2 m above the table, straight down (any roll);
- `angled`: 45 degrees elevation, 0.85-1.0 m from the area, from the side
  facing the robot (+-30 degrees of azimuth);
- `random`: 30-90 degrees elevation, any azimuth, 0.8-1.2 m; a pose from
  which the parked arm hides part of the objects' area (or that lies
  inside the arm) is drawn again: a camera is mounted where it sees the
  table.

Rendering is MuJoCo's depth buffer (metres along the optical axis), headless
through OSMesa here (`MUJOCO_GL=osmesa`) or EGL on a GPU machine. The
request's frame is OpenCV's (x right, y down, z forward); MuJoCo's camera
looks along its -z with y up, so `world_from_camera = world_from_mujoco_camera
* diag(1, -1, -1)`.
"""

import math
from dataclasses import dataclass

import mujoco
import numpy as np

CAMERAS = ("topdown", "angled", "random")
RESOLUTIONS = {"640x480": (640, 480), "424x240": (424, 240), "320x240": (320, 240), "224x224": (224, 224)}
FOVY_DEG = 50.0
TARGET = np.array([0.0, 0.0, 0.0])


@dataclass
class CameraPose:
    """A camera for one frame."""

    kind: str
    world_from_camera: np.ndarray  # 4x4, OpenCV convention
    width: int
    height: int
    fovy_deg: float

    @property
    def intrinsics(self):
        """(fx, fy, cx, cy) in pixels, OpenCV convention (pixel centres at integers)."""
        f = (self.height / 2) / math.tan(math.radians(self.fovy_deg) / 2)
        return f, f, self.width / 2 - 0.5, self.height / 2 - 0.5

    def mujoco_pose(self):
        """world_from_camera in MuJoCo's convention (looks along -z, y up)."""
        t = self.world_from_camera.copy()
        t[:3, :3] = t[:3, :3] @ np.diag([1.0, -1.0, -1.0])
        return t


def look_at(eye, target, up_hint):
    """world_from_camera (OpenCV) at `eye` looking at `target`."""
    z = target - eye
    z = z / np.linalg.norm(z)
    x = np.cross(z, up_hint)
    if np.linalg.norm(x) < 1e-6:
        x = np.cross(z, np.array([1.0, 0.0, 0.0]))
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    t = np.eye(4)
    t[:3, 0], t[:3, 1], t[:3, 2], t[:3, 3] = x, y, z, eye
    return t


# Tries at a pose that sees the area before giving up.
MAX_DRAWS = 100


def sample_pose(kind, rng, resolution="640x480", keep=None):
    """A camera of `kind` drawn from `rng` (numpy Generator) and how many
    `random` poses were drawn again because `keep(pose)` said no (None:
    every pose is kept; the referee passes `sees_area`)."""
    for redrawn in range(MAX_DRAWS):
        pose = _draw_pose(kind, rng, resolution)
        if kind != "random" or keep is None or keep(pose):
            return pose, redrawn
    raise RuntimeError(f"no {kind} camera pose in {MAX_DRAWS} draws sees the objects' area")


def sees_area(cell, pose, area_half_m, lift_m=0.3):
    """Whether a camera at `pose` sees the objects' area past the arm: rays
    between its eye and the area's centre and corners meet no geom of the
    robot (`cell.robot_geoms`) on the way, cast both ways (the one from the
    area starts `lift_m` above the table, over the objects, and catches an
    eye inside the arm)."""
    model, data = cell.model, cell.data
    eye = pose.world_from_camera[:3, 3]
    robot = cell.robot_geoms
    geomid = np.zeros(1, np.int32)
    corners = [(0.0, 0.0)] + [(sx * area_half_m, sy * area_half_m) for sx in (-1, 1) for sy in (-1, 1)]
    for x, y in corners:
        for start, end in ((eye, np.array([x, y, 0.0])), (np.array([x, y, lift_m]), eye)):
            ray = end - start
            length = float(np.linalg.norm(ray))
            hit = mujoco.mj_ray(model, data, start, ray / length, None, 1, -1, geomid)
            if 0.0 <= hit < length and int(geomid[0]) in robot:
                return False
    return True


def _draw_pose(kind, rng, resolution):
    if kind not in CAMERAS:
        raise ValueError(f"unknown camera {kind!r} (one of {', '.join(CAMERAS)})")
    width, height = RESOLUTIONS[resolution]
    if kind == "topdown":
        eye = TARGET + np.array([0.0, 0.0, rng.uniform(1.0, 1.2)])
        roll = rng.uniform(-math.pi, math.pi)
        up = np.array([math.cos(roll), math.sin(roll), 0.0])
        return CameraPose(kind, look_at(eye, TARGET, up), width, height, FOVY_DEG)
    if kind == "angled":
        elevation = math.radians(45.0)
        azimuth = math.radians(90.0 + rng.uniform(-30.0, 30.0))  # from +y, facing the robot
        distance = rng.uniform(0.85, 1.0)
    else:
        elevation = math.radians(rng.uniform(30.0, 90.0))
        azimuth = rng.uniform(-math.pi, math.pi)
        distance = rng.uniform(0.8, 1.2)
    direction = np.array([math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
                          math.sin(elevation)])
    eye = TARGET + distance * direction
    # Image "up" towards world up (the usual mounting), roll left as is.
    return CameraPose(kind, look_at(eye, TARGET, np.array([0.0, 0.0, -1.0])), width, height, FOVY_DEG)


class DepthCamera:
    """Renders depth images of a cell through its camera `depth` (cell.build adds it)."""

    def __init__(self, model, width, height):
        self.renderer = mujoco.Renderer(model, height, width)
        self.renderer.enable_depth_rendering()
        self.width, self.height = width, height
        self.camera_id = model.camera("depth").id
        self.option = mujoco.MjvOption()
        # Groups 0-2: the robot, table, bin and the objects' visual meshes (not their convex parts).
        self.option.geomgroup[:] = [1, 1, 1, 0, 0, 0]

    def depth(self, model, data, pose):
        """float32 metres along the optical axis; 0 where nothing is seen."""
        if (pose.width, pose.height) != (self.width, self.height):
            raise ValueError(f"camera {pose.width}x{pose.height} on a {self.width}x{self.height} renderer")
        t = pose.mujoco_pose()
        q = np.zeros(4)
        mujoco.mju_mat2Quat(q, t[:3, :3].ravel())
        model.cam_pos[self.camera_id] = t[:3, 3]
        model.cam_quat[self.camera_id] = q
        model.cam_fovy[self.camera_id] = pose.fovy_deg
        mujoco.mj_kinematics(model, data)
        mujoco.mj_camlight(model, data)
        self.renderer.update_scene(data, camera=self.camera_id, scene_option=self.option)
        depth = self.renderer.render().astype(np.float32)
        depth[~np.isfinite(depth)] = 0.0
        depth[depth > 5.0] = 0.0
        return depth

    def close(self):
        self.renderer.close()


def add_noise(depth, rng):
    """Kinect-like noise: axial sigma 1.2 mm + 1.9 mm x (z - 0.4 m)^2, a
    missing reading at 1% of pixels and along 30% of depth edges > 2 cm,
    then 1 mm quantisation."""
    z = depth.copy()
    valid = z > 0
    sigma = 0.0012 + 0.0019 * (z - 0.4) ** 2
    z[valid] += rng.normal(0.0, 1.0, valid.sum()) * sigma[valid]
    z[rng.uniform(size=z.shape) < 0.01] = 0.0
    edges = np.zeros_like(valid)
    edges[:, 1:] |= np.abs(np.diff(depth, axis=1)) > 0.02
    edges[1:, :] |= np.abs(np.diff(depth, axis=0)) > 0.02
    z[edges & (rng.uniform(size=z.shape) < 0.3)] = 0.0
    return np.round(z * 1000.0) / 1000.0


def back_project(depth, pose):
    """World points (n, 3) and their pixel (v, u) indices of every valid pixel."""
    fx, fy, cx, cy = pose.intrinsics
    v, u = np.nonzero(depth > 0)
    z = depth[v, u].astype(float)
    cam = np.stack([(u - cx) / fx * z, (v - cy) / fy * z, z], axis=1)
    t = pose.world_from_camera
    return cam @ t[:3, :3].T + t[:3, 3], v, u
