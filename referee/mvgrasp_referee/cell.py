"""The work cell in MuJoCo: a table, a UR5e at its edge with a Robotiq 2F-140,
a bin, and the objects of a scene.

World frame: z up, the table top at z = 0, the objects' area centred on the
origin. The arm and gripper are robosuite's MJCF models (`assets`), loaded
with plain MuJoCo and changed only where stated:
- the arm's torque motors become joint position servos (a UR controller
  tracks joint targets), with gravity compensation and a motor's armature;
- the arm's link offsets are set to Universal Robots' published DH values
  (robosuite rounds them to the millimetre: d1 0.163, d4 0.134, d5 0.1,
  d6 0.098 against 0.1625, 0.1333, 0.0997, 0.0996 m), so the robot-bridge's
  kinematics and the simulated arm are the same robot (checked by a test);
- the gripper's finger actuators get a force limit (`GRIP_TORQUE_NM`) that
  makes the squeeze the one stated in `GRIP_FORCE_N`, measured by a test;
- pads get rubber friction (`objects.FRICTION_PAD`);
- the two fingers move mirrored, as the one motor of the real 2F-140 drives
  them (the file gives each its own servo).
"""

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import mujoco
import numpy as np

from . import assets, objects

TIMESTEP_S = 0.002
TABLE_HALF_M = (0.7, 0.55, 0.025)
TABLE_CENTRE_M = (0.0, -0.25, -0.025)
# The robot-bridge's base frame (DH) in the world: at the table's near edge,
# its x axis pointing away from the objects (DH's arm reaches along -x at q1 = 0).
WORLD_FROM_BASE = (np.array([0.0, -0.62, 0.0]), -math.pi / 2)  # position, yaw
BIN_CENTRE_M = (0.45, -0.47)
BIN_INNER_HALF_M = 0.13
BIN_WALL_M = (0.01, 0.09)  # thickness, height
# The robot-bridge's basket reaches this high (m): what piles up in the bin
# stands above its walls (`bin_top_m` in referee.json measures it).
BIN_FILL_M = 0.25
DROP_HEIGHT_M = 0.35
AREA_HALF_M = 0.15  # objects are placed within this square around the origin
# The square the robot is asked to clear (m, around the origin): the planner's
# workspace and the objects the referee counts; the parked arm and the bin lie outside.
TASK_HALF_M = 0.3
# Out of the camera's way while the picture is taken: over the bin side, tool down.
PARK = (math.radians(-150), math.radians(-100), math.radians(110), math.radians(-100),
        math.radians(-90), 0.0)
ARM_KP = (3000.0, 3000.0, 2000.0, 500.0, 500.0, 300.0)
ARM_KV = (300.0, 300.0, 200.0, 50.0, 50.0, 30.0)
ARM_ARMATURE = 0.1
# Each knuckle's position servo: stiff, with its torque capped, so the
# fingers stall on an object at one squeeze (robosuite's kp 20 squeezes
# in proportion to how far from closed they stop). The squeeze this gives
# is measured by the self-checks (`GRIP_FORCE_N`).
GRIP_KP = 200.0
GRIP_KV = 2.0
GRIP_OPEN_RAD = -0.092
GRIP_TORQUE_NM = 6.0
GRIP_FORCE_N = (50.0, 100.0)  # the squeeze over the stroke, checked (datasheet: settable 10-125 N)
DH_OFFSETS = {  # MJCF body -> (axis index, published UR5e value)
    "shoulder_link": (2, 0.1625),
    "wrist_2_link": (1, 0.1333 - 0.138 + 0.131),  # the y offsets add up to d4
    "forearm_link": (2, 0.425),
    "wrist_1_link": (2, 0.3922),
    "wrist_3_link": (2, 0.0997),
    "right_hand": (1, 0.0996),
}
# Contacts of pads and objects: as stiff as the time step allows (MuJoCo's
# default lets a 60 N squeeze sink 4-5 mm into an object and creep on).
NOSLIP_ITERATIONS = 4
STIFF_SOLREF = (2 * TIMESTEP_S, 1.0)
STIFF_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
ARM_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
              "wrist_2_joint", "wrist_3_joint")


def yaw_quat(yaw):
    return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


@dataclass
class Cell:
    """A compiled cell and the ids the executor needs."""

    model: mujoco.MjModel
    data: mujoco.MjData
    bodies: list = field(default_factory=list)  # objects.Body in scene order
    object_body_ids: list = field(default_factory=list)
    arm_qpos: np.ndarray = None  # qpos addresses of the six arm joints
    arm_dof: np.ndarray = None
    arm_act: np.ndarray = None
    grip_act: np.ndarray = None
    pad_geoms: tuple = ()
    finger_geoms: tuple = ()  # per finger: the pad and the fingertip box
    robot_geoms: set = field(default_factory=set)
    bin_geoms: set = field(default_factory=set)
    table_geom: int = -1

    def object_qpos(self, i):
        j = self.model.body_jntadr[self.object_body_ids[i]]
        a = self.model.jnt_qposadr[j]
        return self.data.qpos[a:a + 7]

    def object_pose(self, i):
        b = self.object_body_ids[i]
        return self.data.xpos[b].copy(), self.data.xquat[b].copy()

    def set_arm(self, q):
        self.data.qpos[self.arm_qpos] = q
        self.data.qvel[self.arm_dof] = 0.0
        self.data.ctrl[self.arm_act] = q

    def arm_q(self):
        return self.data.qpos[self.arm_qpos].copy()


def _arm_spec():
    arm = mujoco.MjSpec.from_file(f"{assets.robosuite_assets()}/robots/ur5e/robot.xml")
    for a in list(arm.actuators):
        arm.delete(a)
    for name, (axis, value) in DH_OFFSETS.items():
        body = arm.body(name)
        pos = list(body.pos)
        pos[axis] = value
        body.pos = pos
    for i, name in enumerate(ARM_JOINTS):
        joint = arm.joint(name)
        joint.armature = ARM_ARMATURE
        joint.damping = [1.0, 0.0, 0.0]
        act = arm.add_actuator()
        act.name = f"servo_{i}"
        act.target = name
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.set_to_position(kp=ARM_KP[i], kv=ARM_KV[i])
        act.ctrlrange = [-2 * math.pi, 2 * math.pi]
        act.ctrllimited = True
    for body in arm.bodies:
        body.gravcomp = 1.0
    return arm


# The file's tendon couplings turn each fingertip by 5/3 of its knuckle
# (coefficients 1.5 and 3.5), so the pads tilt by 67 degrees as they close
# and cross at mid-stroke. The real 2F-140 is a four-bar: the fingertip
# keeps its orientation (until it touches) and the inner knuckle turns with
# the outer one. These couplings say exactly that.
PARALLEL_COUPLINGS = {
    "finger2_12_cpl": (("finger_joint", 1.0), ("left_inner_finger_joint", -1.0)),
    "finger2_23_cpl": (("left_inner_finger_joint", 1.0), ("left_inner_knuckle_joint", 1.0)),
    "finger1_12_cpl": (("right_outer_knuckle_joint", 1.0), ("right_inner_finger_joint", 1.0)),
    "finger1_23_cpl": (("right_inner_finger_joint", 1.0), ("right_inner_knuckle_joint", 1.0)),
}


def _gripper_spec():
    path = f"{assets.robosuite_assets()}/grippers/robotiq_gripper_140.xml"
    root = ET.parse(path).getroot()
    for tendon in root.iter("fixed"):
        couplings = PARALLEL_COUPLINGS[tendon.get("name")]
        joints = tendon.findall("joint")
        if [j.get("joint") for j in joints] != [c[0] for c in couplings]:
            raise ValueError(f"{path}: tendon {tendon.get('name')} is not the expected coupling")
        for joint, (_, coef) in zip(joints, couplings):
            joint.set("coef", str(coef))
        # A coupling holds at zero length; the file's range 0-1 would let it slack.
        tendon.attrib.pop("range", None)
        tendon.attrib.pop("limited", None)
    # The file's pads open to 126.5 mm at the knuckles' open stop (0 rad);
    # the datasheet's stroke is 140 mm. The open stop moves to GRIP_OPEN_RAD.
    for joint in root.iter("joint"):
        if joint.get("name") == "finger_joint":
            joint.set("range", f"{GRIP_OPEN_RAD} 0.7")
        elif joint.get("name") == "right_outer_knuckle_joint":
            joint.set("range", f"-0.725 {-GRIP_OPEN_RAD}")
    for actuator in root.iter("position"):
        lo, hi = (GRIP_OPEN_RAD, 0.7) if actuator.get("joint") == "finger_joint" else (-0.7, -GRIP_OPEN_RAD)
        actuator.set("ctrlrange", f"{lo} {hi}")
    grip = mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode"))
    grip.meshdir = os.path.dirname(path)
    for a in grip.actuators:
        a.set_to_position(kp=GRIP_KP, kv=GRIP_KV)
        a.forcerange = [-GRIP_TORQUE_NM, GRIP_TORQUE_NM]
        a.forcelimited = True
    # One motor drives both fingers of the 2F-140 through one linkage: they
    # move together, mirrored. The file gives each finger its own servo, so
    # two stalled servos let a grasped object and both fingers float
    # sideways together (docs/experiments/2026-11-29-coupled-fingers.md).
    # As MuJoCo Menagerie's 2F-85 does, a joint equality mirrors them.
    mirror = grip.add_equality()
    mirror.type = mujoco.mjtEq.mjEQ_JOINT
    mirror.name = "fingers_mirrored"
    mirror.name1, mirror.name2 = "right_outer_knuckle_joint", "finger_joint"
    mirror.data[:5] = [0.0, -1.0, 0.0, 0.0, 0.0]  # right = -left
    for eq in grip.equalities:
        eq.solref = [2 * TIMESTEP_S, 1.0]
    # The file does not say `angle="radian"` (robosuite merges it into a
    # model that does): read as degrees, its 0-0.7 knuckle range would be 0-0.7 deg.
    grip.compiler.degree = False
    for body in grip.bodies:
        body.gravcomp = 1.0
    for geom in grip.geoms:
        if "fingerpad" in geom.name or "fingertip_collision" in geom.name:
            geom.friction = list(objects.FRICTION_PAD)
            geom.condim = 4
            geom.solref, geom.solimp = list(STIFF_SOLREF), list(STIFF_SOLIMP)
    return grip


ROBOT_CONTYPE, ROBOT_CONAFFINITY = 2, 1


def _under(body, root):
    while body is not None and body.name != "world":
        if body.name == root.name:
            return True
        body = body.parent
    return False


def _add_box(body, name, size, pos, rgba, friction=objects.FRICTION_TABLE):
    g = body.add_geom()
    g.name = name
    g.type = mujoco.mjtGeom.mjGEOM_BOX
    g.size = list(size)
    g.pos = list(pos)
    g.rgba = list(rgba)
    g.friction = list(friction)
    g.solref, g.solimp = list(STIFF_SOLREF), list(STIFF_SOLIMP)
    return g


def _add_object(spec, index, body_data, position, quat):
    """A free body with the visual mesh (group 1, no contacts) and its convex parts (group 3)."""
    name = f"obj{index}"
    mesh = spec.add_mesh()
    mesh.name = f"{name}_visual"
    mesh.uservert = body_data.vertices.astype(np.float32).ravel().tolist()
    mesh.userface = body_data.faces.astype(np.int32).ravel().tolist()
    mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
    body = spec.worldbody.add_body()
    body.name = name
    body.pos = list(position)
    body.quat = list(quat)
    body.add_freejoint()
    vis = body.add_geom()
    vis.type = mujoco.mjtGeom.mjGEOM_MESH
    vis.meshname = mesh.name
    vis.contype = vis.conaffinity = 0
    vis.group = 1
    vis.mass = 0.0
    vis.density = 0.0
    vis.rgba = [0.85, 0.55, 0.2, 1.0]
    parts_volume = 0.0
    part_meshes = []
    for k, part in enumerate(body_data.parts):
        m = spec.add_mesh()
        m.name = f"{name}_part{k}"
        m.uservert = part.astype(np.float32).ravel().tolist()
        part_meshes.append(m.name)
        from scipy.spatial import ConvexHull  # noqa: PLC0415

        try:
            parts_volume += ConvexHull(part).volume
        except Exception:  # noqa: BLE001 - a flat part has no volume
            pass
    light_mass = body_data.mass_kg - (body_data.heavy_part[1] if body_data.heavy_part else 0.0)
    density = light_mass / max(parts_volume, 1e-9)
    for mesh_name in part_meshes:
        g = body.add_geom()
        g.type = mujoco.mjtGeom.mjGEOM_MESH
        g.meshname = mesh_name
        g.group = 3
        g.density = density
        g.friction = list(objects.FRICTION_OBJECT)
        g.condim = 4
        g.solref, g.solimp = list(STIFF_SOLREF), list(STIFF_SOLIMP)
        g.rgba = [0.3, 0.7, 0.3, 0.5]
    if body_data.heavy_part is not None:
        at, mass = body_data.heavy_part
        g = body.add_geom()
        g.type = mujoco.mjtGeom.mjGEOM_SPHERE
        g.size = [0.008, 0, 0]
        g.pos = list(at)
        g.mass = mass
        g.contype = g.conaffinity = 0
        g.group = 4
    return name


def build(bodies, placements, fixtures=()):
    """Compiles a cell with `bodies` (objects.Body) at `placements` ((position, quat wxyz) each).

    `fixtures` are static boxes (name, half sizes, centre) for the self-checks."""
    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    spec.option.timestep = TIMESTEP_S
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 10.0
    spec.option.noslip_iterations = NOSLIP_ITERATIONS
    spec.visual.global_.offwidth = 1280
    spec.visual.global_.offheight = 960
    spec.visual.map.znear = 0.01
    spec.stat.extent = 2.0
    light = spec.worldbody.add_light()
    light.pos = [0, 0, 2.5]
    light.dir = [0, 0, -1]
    world = spec.worldbody
    _add_box(world, "table", TABLE_HALF_M, TABLE_CENTRE_M, [0.55, 0.45, 0.35, 1])
    bx, by = BIN_CENTRE_M
    half, (thick, height) = BIN_INNER_HALF_M, BIN_WALL_M
    bin_names = []
    for k, (dx, dy, sx, sy) in enumerate([(half + thick, 0, thick, half + 2 * thick),
                                          (-half - thick, 0, thick, half + 2 * thick),
                                          (0, half + thick, half, thick), (0, -half - thick, half, thick)]):
        _add_box(world, f"bin_wall{k}", (sx, sy, height / 2), (bx + dx, by + dy, height / 2), [0.2, 0.3, 0.6, 1])
        bin_names.append(f"bin_wall{k}")
    for name, half_sizes, centre in fixtures:
        _add_box(world, name, half_sizes, centre, [0.8, 0.2, 0.2, 1], objects.FRICTION_OBJECT)
    position, yaw = WORLD_FROM_BASE
    mount = world.add_frame()
    mount.pos = list(position)
    mount.quat = list(yaw_quat(yaw + math.pi))  # MJCF base = DH base turned half a turn
    mount.attach_body(_arm_spec().body("base"), "arm/", "")
    hand = spec.body("arm/right_hand")
    hand.add_frame().attach_body(_gripper_spec().body("right_gripper"), "grip/", "")
    names = [_add_object(spec, i, b, *placements[i]) for i, b in enumerate(bodies)]
    # The depth camera; its pose is set per frame (camera.DepthCamera).
    cam = world.add_camera()
    cam.name = "depth"
    cam.pos = [0.0, 0.0, 1.1]
    # The robot does not collide with itself (its linkage parts overlap in the
    # model); it collides with everything else.
    robot_root = spec.body("arm/base")
    for geom in spec.geoms:
        if not (geom.contype or geom.conaffinity):
            continue  # visual only
        if _under(geom.parent, robot_root):
            geom.contype, geom.conaffinity = ROBOT_CONTYPE, ROBOT_CONAFFINITY
        else:
            geom.contype, geom.conaffinity = 1, 3
    model = spec.compile()
    data = mujoco.MjData(model)
    cell = Cell(model, data, bodies=list(bodies))
    cell.object_body_ids = [model.body(n).id for n in names]
    cell.arm_qpos = np.array([model.jnt_qposadr[model.joint(f"arm/{j}").id] for j in ARM_JOINTS])
    cell.arm_dof = np.array([model.jnt_dofadr[model.joint(f"arm/{j}").id] for j in ARM_JOINTS])
    cell.arm_act = np.array([model.actuator(f"arm/servo_{i}").id for i in range(6)])
    cell.grip_act = np.array([model.actuator("grip/finger_1").id, model.actuator("grip/finger_2").id])
    cell.pad_geoms = (model.geom("grip/left_fingerpad_collision").id, model.geom("grip/right_fingerpad_collision").id)
    cell.finger_geoms = tuple({model.geom(f"grip/{side}_{part}").id for part in ("fingerpad_collision", "fingertip_collision")}
                              for side in ("left", "right"))
    robot_root = model.body("arm/base").id
    cell.robot_geoms = {g for g in range(model.ngeom)
                        if model.body_rootid[model.geom_bodyid[g]] == model.body_rootid[robot_root]
                        and model.geom_bodyid[g] != 0}
    cell.bin_geoms = {model.geom(n).id for n in bin_names}
    cell.table_geom = model.geom("table").id
    cell.set_arm(np.array(PARK))
    mujoco.mj_forward(model, data)
    return cell


def world_from_dh_base():
    """The robot-bridge's `world_from_base` (4x4)."""
    position, yaw = WORLD_FROM_BASE
    t = np.eye(4)
    t[:3, :3] = np.array([[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]])
    t[:3, 3] = position
    return t


def bin_box(fill_m=BIN_FILL_M):
    """The bin and what may pile up in it, `fill_m` high, as the
    robot-bridge's basket obstacle: (centre, half extents)."""
    bx, by = BIN_CENTRE_M
    half = BIN_INNER_HALF_M + 2 * BIN_WALL_M[0]
    return (bx, by, fill_m / 2), (half, half, fill_m / 2)


def height_span(cell, index):
    """The lowest and highest points (z, m) of object `index`: each geom's
    bounding box turned into the world, so a little wide."""
    m, d = cell.model, cell.data
    low, high = math.inf, -math.inf
    for g in np.flatnonzero(m.geom_bodyid == cell.object_body_ids[index]):
        centre, half = m.geom_aabb[g, :3], m.geom_aabb[g, 3:]
        rot = d.geom_xmat[g].reshape(3, 3)
        z, reach = d.geom_xpos[g][2] + rot[2] @ centre, np.abs(rot[2]) @ half
        low, high = min(low, float(z - reach)), max(high, float(z + reach))
    return low, high


def bin_top(cell):
    """The highest point (z, m) of the objects lying in the bin (0 when none),
    a little high (`height_span`)."""
    return max([0.0] + [height_span(cell, i)[1] for i in range(len(cell.object_body_ids))
                        if in_bin(cell.object_pose(i)[0])])


def in_bin(position):
    """Within the bin's walls, resting on its floor (the table's top) or on
    what is already in it, below where the bridge lets go (an object on top
    of a tall one standing in the bin is in it)."""
    bx, by = BIN_CENTRE_M
    return (abs(position[0] - bx) < BIN_INNER_HALF_M + 0.01 and abs(position[1] - by) < BIN_INNER_HALF_M + 0.01
            and -0.02 < position[2] < DROP_HEIGHT_M)
