"""The planner under judgement: the running mvgrasp service, called over gRPC
with the Python stubs generated from proto/ (client/python/mvgrasp_client.py).
"""

import importlib.util
import os
import time

import numpy as np

from . import assets
from . import cell as cellmod
from .bridge import quat_xyzw

_T = cellmod.TASK_HALF_M
WORKSPACE = ((-_T, -_T, -0.05), (_T, _T, 0.45))
POLICIES = {"default": None, "entropy": 1, "all": 2, "top-down": 3, "random": 4}


def _client_module():
    path = os.path.join(assets.ROOT, "client", "python", "mvgrasp_client.py")
    spec = importlib.util.spec_from_file_location("mvgrasp_client", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class Planner:
    """A gRPC connection to the service, and the request options of a setting."""

    def __init__(self, address, policy="default", min_quality=None, max_grasps=10, timeout_s=30.0,
                 view_cascade=None, approach_cone=None, arm_reach=None, with_views=False, obstacle_margin_m=0.0,
                 robot_body=False):
        import grpc  # noqa: PLC0415

        if policy not in POLICIES:
            raise ValueError(f"unknown view policy {policy!r} (one of {', '.join(POLICIES)})")
        client = _client_module()
        self.pb, rpc = client.stubs()
        # With views the answer carries every rendered view and its maps (MBs).
        self.with_views = with_views
        self.channel = grpc.insecure_channel(address, options=[("grpc.max_receive_message_length", 256 << 20)])
        self.stub = rpc.GraspPlannerStub(self.channel)
        self.policy, self.min_quality, self.max_grasps = policy, min_quality, max_grasps
        self.timeout_s = timeout_s
        self._model_info = None
        self.view_cascade = view_cascade
        self.approach_cone = None
        if approach_cone is not None:
            values = [float(v) for v in str(approach_cone).split(",")]
            if len(values) != 4:
                raise ValueError(f"--approach-cone {approach_cone!r}: give AX,AY,AZ,HALF_DEG")
            self.approach_cone = values
        # What stands this far around the workspace (and above it) is asked
        # for as obstacle boxes and handed to the bridge (0: not asked), as
        # the robot-bridge's planner.obstacle_margin_m asks for it.
        self.obstacle_region = obstacle_region(obstacle_margin_m)
        # Whether each frame is sent with the arm where it stands (the
        # bridge's capsules), as the robot-bridge's planner.robot_body does.
        self.asks_robot_body = robot_body
        self._client = client
        # The robot-bridge's answer to {"arm_reach": null} as the request's ArmReach, or None.
        self.arm_reach = None if arm_reach is None else client.arm_reach(
            self.pb, arm_reach["shoulder"], arm_reach["wrist_back_m"], arm_reach["approach_m"],
            arm_reach["max_m"], arm_reach["min_axis_m"], axis=arm_reach["axis"])

    def _info(self):
        """The served model's GetModelInfo answer, asked once."""
        if self._model_info is None:
            self._model_info = self.stub.GetModelInfo(self.pb.GetModelInfoRequest(), timeout=self.timeout_s)
        return self._model_info

    def model_info(self):
        info = self._info()
        return {"model_version": info.model_version, "backend": info.backend}

    def contract(self):
        """What the network reads: its input size, pixel size and normalisation."""
        info = self._info()
        return {"input_size_px": info.input_size_px, "pixel_size_m": info.pixel_size_m,
                "normalisation": info.normalisation}

    def plan(self, depth, pose, seed=0, robot_body=None):
        """Ranked grasps, detected objects and the table plane for one frame,
        and the call's wall time in ms; no grasps and the planner's `error`
        for a frame it refuses as invalid. `robot_body`: the arm's capsules
        where it stands (the bridge's `robot_body` answer), left out."""
        import grpc  # noqa: PLC0415

        pb = self.pb
        fx, fy, cx, cy = pose.intrinsics
        t = pose.world_from_camera
        qx, qy, qz, qw = quat_xyzw(t[:3, :3])
        options = {"max_grasps": self.max_grasps, "random_seed": seed}
        if self.min_quality is not None:
            options["min_quality"] = self.min_quality
        if POLICIES[self.policy] is not None:
            options["view_policy"] = POLICIES[self.policy]
        if self.view_cascade is not None:
            options["view_cascade"] = self.view_cascade
        if self.approach_cone is not None:
            ax, ay, az, half_deg = self.approach_cone
            options["approach_cone"] = pb.ApproachCone(axis=pb.Vector3(x=ax, y=ay, z=az),
                                                       half_angle_rad=np.radians(half_deg))
        if self.arm_reach is not None:
            options["arm_reach"] = self.arm_reach
        if self.obstacle_region is not None:
            (a0, b0, c0), (a1, b1, c1) = self.obstacle_region
            options["obstacle_region"] = pb.Workspace(min=pb.Vector3(x=a0, y=b0, z=c0),
                                                      max=pb.Vector3(x=a1, y=b1, z=c1))
        if robot_body:
            options["robot_body"] = [self._client.capsule(pb, c["a"], c["b"], c["radius_m"]) for c in robot_body]
        (x0, y0, z0), (x1, y1, z1) = WORKSPACE
        request = pb.PlanGraspsRequest(
            depth=pb.DepthImage(width=pose.width, height=pose.height, encoding=pb.DEPTH_ENCODING_FLOAT32_M,
                                data=np.ascontiguousarray(depth, "<f4").tobytes(),
                                intrinsics=pb.CameraIntrinsics(fx=fx, fy=fy, cx=cx, cy=cy)),
            world_from_camera=pb.Pose(position=pb.Vector3(x=t[0, 3], y=t[1, 3], z=t[2, 3]),
                                      orientation=pb.Quaternion(x=qx, y=qy, z=qz, w=qw)),
            workspace=pb.Workspace(min=pb.Vector3(x=x0, y=y0, z=z0), max=pb.Vector3(x=x1, y=y1, z=z1)),
            include_debug_views=self.with_views,
            **options,
        )
        start = time.perf_counter()
        try:
            response = self.stub.PlanGrasps(request, timeout=self.timeout_s)
        except grpc.RpcError as e:
            # A frame the planner refuses (say, a random camera that sees
            # nothing of the workspace) offers no grasp, and says why; any
            # other error (the server gone) ends the run.
            if e.code() != grpc.StatusCode.INVALID_ARGUMENT:
                raise
            return {"grasps": [], "objects": [], "table": None, "obstacles": [], "server_ms": 0.0,
                    "call_ms": (time.perf_counter() - start) * 1000.0, "views": {},
                    "error": f"{e.code().name}: {e.details()}"}
        elapsed_ms = (time.perf_counter() - start) * 1000.0
        grasps = [{
            "position": [g.pose.position.x, g.pose.position.y, g.pose.position.z],
            "orientation": [g.pose.orientation.x, g.pose.orientation.y, g.pose.orientation.z, g.pose.orientation.w],
            "width_m": g.width_m, "quality": g.quality, "object": g.object_id,
            "view": pb.ViewAxis.Name(g.view).removeprefix("VIEW_AXIS_").lower(),
            "pixel": (g.pixel_u, g.pixel_v), "angle_rad": g.angle_rad,
        } for g in response.grasps]
        # The network's input of each view, by (object, view name); the first of equals.
        views = {}
        for v in response.debug_views:
            key = (v.object_id, pb.ViewAxis.Name(v.axis).removeprefix("VIEW_AXIS_").lower())
            if key not in views:
                views[key] = np.frombuffer(v.image, dtype="<f4").reshape(v.size_px, v.size_px)
        objects = [{
            "id": o.id,
            "position": [o.world_from_object.position.x, o.world_from_object.position.y,
                         o.world_from_object.position.z],
            "orientation": [o.world_from_object.orientation.x, o.world_from_object.orientation.y,
                            o.world_from_object.orientation.z, o.world_from_object.orientation.w],
            "extent_min_m": [o.extent_min_m.x, o.extent_min_m.y, o.extent_min_m.z],
            "extent_max_m": [o.extent_max_m.x, o.extent_max_m.y, o.extent_max_m.z],
            "refused": {cause: getattr(o.refused, cause) for cause in REFUSALS},
        } for o in response.objects]
        table = {"normal": [response.table.normal.x, response.table.normal.y, response.table.normal.z],
                 "offset_m": response.table.offset_m}
        obstacles = [{"min": [o.min.x, o.min.y, o.min.z], "max": [o.max.x, o.max.y, o.max.z],
                      "object_id": o.object_id if o.HasField("object_id") else None}
                     for o in response.obstacles]
        return {"grasps": grasps, "objects": objects, "table": table, "obstacles": obstacles,
                "server_ms": response.timings.total_ms,
                "call_ms": elapsed_ms, "views": views}

    def close(self):
        self.channel.close()


# What a detected object's candidate grasps were lost to (`ObjectRefusals`).
REFUSALS = ("table", "neighbour", "own_points", "outside_approach_cone", "out_of_reach", "too_wide", "no_pose")


def obstacle_region(margin_m):
    """The workspace grown by `margin_m` sideways and upwards (the robot-bridge's
    planner.obstacle_margin_m), or None at 0."""
    if not margin_m:
        return None
    (x0, y0, z0), (x1, y1, z1) = WORKSPACE
    return (x0 - margin_m, y0 - margin_m, z0), (x1 + margin_m, y1 + margin_m, z1 + margin_m)


def bridge_scene(plan, robot_body_left_out=False):
    """The planner's answer as the robot-bridge turns it into obstacles
    (`plan-jsonl`'s `scene`: detected objects, table plane, workspace, and
    the boxes seen outside the workspace when there are any);
    `robot_body_left_out`: the plan was asked with the arm's body, so a box
    against the arm is something lying there (the bridge keeps it cut)."""
    (x0, y0, z0), (x1, y1, z1) = WORKSPACE
    scene = {"detected": [{k: o[k] for k in ("id", "position", "orientation", "extent_min_m", "extent_max_m")}
                          for o in plan["objects"]],
             "table_plane": plan["table"],
             "workspace": {"min": [x0, y0, z0], "max": [x1, y1, z1]}}
    if plan.get("obstacles"):
        # A box that continues a detected object names its index in `detected`.
        index_of = {o["id"]: k for k, o in enumerate(plan["objects"])}
        scene["obstacles"] = [{"min": o["min"], "max": o["max"], "object": index_of.get(o.get("object_id"))}
                              for o in plan["obstacles"]]
        if robot_body_left_out:
            scene["robot_body_left_out"] = True
    return scene


class OraclePlanner:
    """Ground-truth grasps, to check the executor rather than a planner: for
    each object, top-down through its centre of mass (which it knows),
    closing across the object's narrowest section there (the pads' 28 mm
    wide slab through the centre of mass, turned in 10-degree steps; the
    footprint's minor axis if no section fits the hand), at the true width
    plus the planner's opening margin (`OPENING_MARGIN_M`, as the service
    reports widths), the fingertips 4 cm below the section's top but at least 12 mm above the
    table (half the height of an object lower than 24 mm)."""

    ground_truth = True
    PAD_HALF_WIDTH_M = 0.014
    MAX_WIDTH_M = 0.13
    OPENING_MARGIN_M = 0.02  # the service's decode.opening_margin_m

    def model_info(self):
        return {"model_version": "oracle (ground truth)", "backend": "referee"}

    def grasp_for(self, cell, i):
        import mujoco  # noqa: PLC0415

        p, q = cell.object_pose(i)
        r = np.zeros(9)
        mujoco.mju_quat2Mat(r, q)
        world = cell.bodies[i].surface @ r.reshape(3, 3).T + p
        com = cell.data.xipos[cell.object_body_ids[i]].copy()
        best = None
        for angle in np.radians(np.arange(0.0, 180.0, 10.0)):
            x = np.array([np.cos(angle), np.sin(angle), 0.0])
            y = np.array([-np.sin(angle), np.cos(angle), 0.0])
            slab = world[np.abs((world - com) @ y) < self.PAD_HALF_WIDTH_M]
            if len(slab) < 10:
                continue
            along = (slab - com) @ x
            width = float(np.ptp(along))
            if width <= self.MAX_WIDTH_M and (best is None or width < best[0]):
                best = (width, x, (along.max() + along.min()) / 2, float(slab[:, 2].max()))
        if best is None:
            xy = world[:, :2] - world[:, :2].mean(axis=0)
            minor = np.linalg.svd(xy, full_matrices=False)[2][1]
            x = np.array([minor[0], minor[1], 0.0])
            along = (world - com) @ x
            best = (float(np.ptp(along)), x, (along.max() + along.min()) / 2, float(world[:, 2].max()))
        width, x, middle, top = best
        centre = com + middle * x
        z = np.array([0.0, 0.0, -1.0])
        y = np.cross(z, x)
        return {"position": [float(centre[0]), float(centre[1]), max(top - 0.04, min(0.012, top / 2))],
                "orientation": quat_xyzw(np.stack([x, y, z], axis=1)),
                "width_m": width + self.OPENING_MARGIN_M, "quality": 1.0, "object": None, "view": "top"}

    def plan_truth(self, cell, remaining):
        return {"grasps": [self.grasp_for(cell, i) for i in remaining], "objects": [],
                "table": {"normal": [0.0, 0.0, 1.0], "offset_m": 0.0}, "server_ms": 0.0, "call_ms": 0.0}

    def close(self):
        pass
