"""The 2F-140 as the executor drives it: opening to a width, closing until the
fingers stall, and what the pads measure (gap, squeeze).

The gripper closes through its two knuckle position servos (torque-capped,
`cell.GRIP_TORQUE_NM`), the linkage following through its couplings, until
the fingers stop moving: on an object, or at the end of the stroke.
"""

import mujoco
import numpy as np

from . import cell as cellmod

PAD_HALF_LENGTH_M = 0.033  # the pad box's half size along the finger
CLOSED_RAD = 0.7


def flange_frame(cell):
    m, d = cell.model, cell.data
    b = m.body("arm/right_hand").id
    return d.xpos[b].copy(), d.xmat[b].reshape(3, 3).copy()


def pads_in_flange(cell):
    """Both pad centres in the flange frame (after mj_kinematics or a step)."""
    p, r = flange_frame(cell)
    return [r.T @ (cell.data.geom_xpos[g] - p) for g in cell.pad_geoms]


def pad_gap(cell):
    """Distance between the pads' inner faces (m; negative when they overlap)."""
    a, b = pads_in_flange(cell)
    thickness = cell.model.geom_size[cell.pad_geoms[0]][2]
    return abs(a[1] - b[1]) - 2 * thickness


def _set_knuckles(cell, angle):
    """Places the linkage at knuckle angle `angle` (kinematics only)."""
    m, d = cell.model, cell.data
    for name, sign in (("finger_joint", 1), ("left_inner_finger_joint", 1), ("left_inner_knuckle_joint", -1),
                       ("right_outer_knuckle_joint", -1), ("right_inner_finger_joint", 1),
                       ("right_inner_knuckle_joint", -1)):
        d.qpos[m.jnt_qposadr[m.joint(f"grip/{name}").id]] = sign * angle


def gap_table(cell, samples=40):
    """(knuckle angles, pad gaps) over the stroke, from the linkage's kinematics."""
    saved = cell.data.qpos.copy()
    angles = np.linspace(cellmod.GRIP_OPEN_RAD, CLOSED_RAD, samples)
    gaps = []
    for a in angles:
        _set_knuckles(cell, a)
        mujoco.mj_kinematics(cell.model, cell.data)
        gaps.append(pad_gap(cell))
    cell.data.qpos[:] = saved
    mujoco.mj_kinematics(cell.model, cell.data)
    return angles, np.array(gaps)


def tcp_in_flange(cell, width_m=0.06):
    """The fingertips' midpoint in the flange frame at an opening of `width_m`."""
    angles, gaps = gap_table(cell)
    angle = float(np.interp(width_m, gaps[::-1], angles[::-1]))
    saved = cell.data.qpos.copy()
    _set_knuckles(cell, angle)
    mujoco.mj_kinematics(cell.model, cell.data)
    a, b = pads_in_flange(cell)
    cell.data.qpos[:] = saved
    mujoco.mj_kinematics(cell.model, cell.data)
    mid = (a + b) / 2
    mid[2] += PAD_HALF_LENGTH_M
    return mid


def fingertip_travel(cell, reference_m=0.06, step_m=0.01):
    """Where the fingertips are along the approach, relative to the TCP at an
    opening of `reference_m`, at openings 0 to 14 cm (the robot-bridge's
    `robot.fingertip_travel`): the linkage pulls them back as it opens."""
    ref = tcp_in_flange(cell, reference_m)[2]
    widths = np.arange(0.0, 0.14 + 1e-9, step_m)
    return [[round(float(w), 3), round(float(tcp_in_flange(cell, w)[2] - ref), 5)] for w in widths]


def command_for_width(table, width_m):
    angles, gaps = table
    return float(np.interp(width_m, gaps[::-1], angles[::-1]))


def set_command(cell, angle):
    cell.data.ctrl[cell.grip_act] = [angle, -angle]


def knuckle(cell):
    m = cell.model
    return float(cell.data.qpos[m.jnt_qposadr[m.joint("grip/finger_joint").id]])


def pad_forces(cell):
    """Total normal force (N) on each pad from anything that is not the robot."""
    m, d = cell.model, cell.data
    forces = [0.0, 0.0]
    f6 = np.zeros(6)
    for i in range(d.ncon):
        c = d.contact[i]
        for k, pads in enumerate(cell.finger_geoms):
            if c.geom1 in pads or c.geom2 in pads:
                mujoco.mj_contactForce(m, d, i, f6)
                forces[k] += abs(f6[0])
    return forces


def knuckles(cell):
    """Both knuckle angles, the right one's sign turned: equal when the
    fingers mirror each other."""
    m = cell.model
    right = cell.data.qpos[m.jnt_qposadr[m.joint("grip/right_outer_knuckle_joint").id]]
    return knuckle(cell), -float(right)


def close_on_box(width_m, settle_s=1.5, offset_m=0.0):
    """Closes on a fixed box `width_m` wide, tool down, its centre `offset_m`
    off the hand's along the closing axis, and returns the cell once the
    fingers stall."""
    arm_q = np.array([0.0, -1.2, 1.6, -1.97, -1.5708, 0.0])
    probe = cellmod.build([], [])
    probe.set_arm(arm_q)
    mujoco.mj_forward(probe.model, probe.data)
    p, r = flange_frame(probe)
    tcp = p + r @ tcp_in_flange(probe, width_m)
    half = [width_m / 2 if abs(r[i, 1]) > 0.9 else 0.02 for i in range(3)]
    c = cellmod.build([], [], fixtures=[("probe", half, tcp - r[:, 2] * 0.015 + r[:, 1] * offset_m)])
    c.set_arm(arm_q)
    set_command(c, command_for_width(gap_table(c), width_m + 0.02))
    for _ in range(250):
        mujoco.mj_step(c.model, c.data)
    set_command(c, CLOSED_RAD)
    for _ in range(int(settle_s / cellmod.TIMESTEP_S)):
        mujoco.mj_step(c.model, c.data)
    return c


def squeeze_probe(width_m, settle_s=1.5):
    """Closes on a fixed box `width_m` wide, tool down, and returns the
    (left, right) pad forces (N) and the pad gap (m) once the fingers stall."""
    c = close_on_box(width_m, settle_s)
    return pad_forces(c), pad_gap(c)
