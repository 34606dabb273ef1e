"""The robot-bridge's own kinematics and pick planning, over its line
protocol (`robot-bridge plan-jsonl`; robot-bridge/src/jsonl.rs).

The bridge is configured as this cell is calibrated: its base where the
simulated arm stands, the TCP at the simulated 2F-140's fingertips, the
bin as its basket and the drop pose above it.
"""

import json
import math
import os
import subprocess
import tempfile

import numpy as np

from . import cell as cellmod


def quat_xyzw(rotation):
    """A rotation matrix as a quaternion (x, y, z, w)."""
    import mujoco  # noqa: PLC0415

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.asarray(rotation, float).ravel())
    return [q[1], q[2], q[3], q[0]]


def matrix_xyzw(quaternion):
    """A quaternion (x, y, z, w) as a rotation matrix (`quat_xyzw`'s inverse)."""
    import mujoco  # noqa: PLC0415

    x, y, z, w = quaternion
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, np.array([w, x, y, z], float))
    return m.reshape(3, 3)


def config_toml(tcp_in_flange, fingertip_travel=(), bin_fill_m=cellmod.BIN_FILL_M, approach_clearance_m=None,
                failed_radius_m=None, release_height_m=None, release_spread_m=None):
    """The bridge's settings for this cell (robot-bridge/bridge.toml's keys);
    `fingertip_travel` as `gripper.fingertip_travel` gives it (empty: a rigid
    TCP); the basket reaches `bin_fill_m` high; the fingers open
    `approach_clearance_m` wider than a grasp; a grasp within
    `failed_radius_m` of a pick that came up empty is tried last; the hand
    goes down towards `release_height_m` over the bin's floor before letting
    go, stopping on contact (0: lets go at the drop pose); it lets go over
    four spots `release_spread_m` off the drop pose in turn (0: over the
    drop pose) (None: the bridge's defaults)."""
    position, yaw = cellmod.WORLD_FROM_BASE
    base_q = [0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)]
    # Fingers close along the flange's y: the TCP's x (closing) is the flange's y.
    tcp_q = [0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)]
    (bx, by, bz), (hx, hy, hz) = cellmod.bin_box(bin_fill_m)
    fmt = ", ".join
    pick_keys = "" if approach_clearance_m is None else f"approach_clearance_m = {approach_clearance_m:.4f}\n"
    if failed_radius_m is not None:
        pick_keys += f"failed_radius_m = {failed_radius_m:.4f}\n"
    if release_height_m is not None:
        pick_keys += f"release_height_m = {release_height_m:.4f}\n"
    if release_spread_m is not None:
        pick_keys += f"release_spread_m = {release_spread_m:.4f}\n"
    return f"""[robot]
world_from_base = {{ position = [{fmt(f"{v:.6f}" for v in position)}], orientation = [{fmt(f"{v:.9f}" for v in base_q)}] }}
flange_from_tcp = {{ position = [{fmt(f"{v:.6f}" for v in tcp_in_flange)}], orientation = [{fmt(f"{v:.9f}" for v in tcp_q)}] }}
fingertip_travel = [{fmt(f"[{w}, {d}]" for w, d in fingertip_travel)}]

[pick]
world_from_drop = {{ position = [{bx:.4f}, {by:.4f}, {cellmod.DROP_HEIGHT_M:.4f}], orientation = [1.0, 0.0, 0.0, 0.0] }}
basket = {{ centre = [{bx:.4f}, {by:.4f}, {bz:.4f}], half_extents_m = [{hx:.4f}, {hy:.4f}, {hz:.4f}] }}
{pick_keys}"""


class Bridge:
    """A running `robot-bridge plan-jsonl` process."""

    def __init__(self, binary, tcp_in_flange, fingertip_travel=(), bin_fill_m=cellmod.BIN_FILL_M,
                 approach_clearance_m=None, failed_radius_m=None, release_height_m=None, release_spread_m=None):
        if not os.path.exists(binary):
            raise FileNotFoundError(f"{binary}: build it with `cargo build --release -p mvgrasp-robot-bridge`")
        self._config = tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False)
        self._config.write(config_toml(tcp_in_flange, fingertip_travel, bin_fill_m, approach_clearance_m,
                                       failed_radius_m, release_height_m, release_spread_m))
        self._config.close()
        self.process = subprocess.Popen([binary, "plan-jsonl", "--config", self._config.name],
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)

    def ask(self, request):
        self.process.stdin.write(json.dumps(request) + "\n")
        self.process.stdin.flush()
        line = self.process.stdout.readline()
        if not line:
            raise RuntimeError("robot-bridge plan-jsonl exited")
        return json.loads(line)

    def fk(self, q):
        """base_from_flange (4x4) by the bridge's kinematics."""
        answer = self.ask({"fk": [float(v) for v in q]})
        if not answer["ok"]:
            raise RuntimeError(answer["error"])
        t = np.eye(4)
        t[:3, :3] = matrix_xyzw(answer["orientation"])
        t[:3, 3] = answer["position"]
        return t

    def arm_reach(self):
        """Where the bridge's arm reaches, as the planner's ArmReach takes it (a dict)."""
        answer = self.ask({"arm_reach": None})
        if not answer["ok"]:
            raise RuntimeError(answer["error"])
        return answer["arm_reach"]

    def robot_body(self, q):
        """The arm at joints `q` as capsules (dicts a, b, radius_m; world),
        as the bridge tells the planner where it stands (`robot_body`)."""
        answer = self.ask({"robot_body": [float(v) for v in q]})
        if not answer["ok"]:
            raise RuntimeError(answer["error"])
        return answer["robot_body"]

    def plan(self, grasps, scene, current, released=0):
        """The bridge's pick for ranked `grasps` (dicts with position,
        orientation xyzw, width_m, quality, object) among the obstacles of
        `scene` (planner.bridge_scene), or its refusals; `released` objects
        were let go over the bin before (where over it this one goes)."""
        answer = self.ask({"plan": {"grasps": grasps, "scene": scene, "current": [float(v) for v in current],
                                    "released": int(released)}})
        if not answer["ok"]:
            raise RuntimeError(answer["error"])
        return answer

    def order(self, grasps, failed):
        """The order to try ranked `grasps` in once the picks at the `failed`
        grasps (dicts with position, orientation xyzw) came up empty: the
        bridge's own (`order` in robot-bridge/src/jsonl.rs)."""
        if not failed:
            return list(range(len(grasps)))
        pose = lambda g: {"position": list(g["position"]), "orientation": list(g["orientation"])}  # noqa: E731
        answer = self.ask({"order": {"grasps": [pose(g) for g in grasps], "failed": [pose(g) for g in failed]}})
        if not answer["ok"]:
            raise RuntimeError(answer["error"])
        return answer["order"]

    def close(self):
        if self.process.poll() is None:
            self.process.stdin.close()
            self.process.wait(timeout=10)
        self.process.stdout.close()
        os.unlink(self._config.name)
