"""Runs one pick of the robot-bridge's plan on the simulated arm and judges it.

Joint moves are interpolated in time (a smooth profile at `JOINT_SPEED`) and
sent as targets to the arm's joint servos each step; straight moves run
through the bridge's own 1 cm IK samples at `TOOL_SPEED`; a guarded one
(the descent into the bin before the release) stops at the first contact
of the hand or what it holds with the cell or what lay in the bin. The
gripper opens to the step's width, closes until the fingers stall, the
object is lifted (the bridge's 15 cm), shaken, carried over the bin,
lowered into it where the bridge asks, and released. After the release,
and after a failed attempt once the hand has opened, the arm is put back
at its park pose (not simulated: `park`); a released object is judged
where it comes to rest.

Outcomes: `success` (the object is in the bin, on its floor or on what
lies in it), `empty` (the fingers closed
on nothing), `slip-lift`, `slip-shake`, `dropped-carry`, `collision`
(the arm, not its pads, touched the table, the bin or another object on the
way in and the object was not lifted). A move that is not finished within
its time is `timeout`.
"""

import math

import mujoco
import numpy as np

from . import cell as cellmod
from . import gripper

JOINT_SPEED = 0.6  # rad/s, peak (the robot-bridge's default joint_speed)
TOOL_SPEED = 0.10  # m/s
SETTLE_S = 0.25
# How fast the pads close (m/s of the gap): the 2F-140 closes at 30-250 mm/s
# over its speed register 0-255, and the robot-bridge sends 128. Without the
# ramp (0) the position servo slams the pads shut in about 20 ms (5 m/s).
CLOSE_SPEED_M_S = 0.14
CLOSE_MAX_S = 1.5  # after the ramp
SHAKE = (0.25, 2, 2.0)  # wrist 3 amplitude (rad), cycles, Hz
HELD_LIFT_M = 0.05  # an object held after a lift is this much above where it was
REST_MAX_S = 2.0  # how long a released object may take to come to rest
LINEAR_STEP_M = 0.01  # the spacing of the bridge's linear samples


class Run:
    """One pick in progress: steps the physics and keeps what happened."""

    def __init__(self, cell, target, budget_s=40.0, close_speed_m_s=CLOSE_SPEED_M_S):
        self.cell, self.target = cell, target
        self.close_speed_m_s = close_speed_m_s
        self.m, self.d = cell.model, cell.data
        self.steps_left = int(budget_s / cellmod.TIMESTEP_S)
        self.collisions = []  # (phase, geom names) of the arm meeting something
        self.phase = "start"
        self.frames = []  # optional snapshots (phase, qpos)
        self.released_from_m = None  # the held object's lowest point (z) as the pads opened

    def step(self, n=1):
        for _ in range(n):
            mujoco.mj_step(self.m, self.d)
            self.steps_left -= 1
            if self.phase in ("pre-grasp", "approach") and self.d.ncon:
                self._watch_contacts()
        return self.steps_left > 0

    def _watch_contacts(self):
        c = self.cell
        finger = c.finger_geoms[0] | c.finger_geoms[1]
        for i in range(self.d.ncon):
            con = self.d.contact[i]
            g1, g2 = con.geom1, con.geom2
            robot = g1 in c.robot_geoms, g2 in c.robot_geoms
            if robot[0] == robot[1]:
                continue
            arm_geom, other = (g1, g2) if robot[0] else (g2, g1)
            target_geoms = self._target_geoms()
            if other in target_geoms and arm_geom in finger:
                continue  # the pads touching their own object
            if other in target_geoms and self.phase == "approach":
                continue  # the hand meeting its object as it goes in: judged by the outcome
            self.collisions.append((self.phase, self.m.geom(arm_geom).name, self._name(other)))

    def _name(self, geom):
        """A geom's name, else its body's (an object's convex pieces are unnamed)."""
        return self.m.geom(geom).name or self.m.body(self.m.geom_bodyid[geom]).name or "world"

    def _target_geoms(self):
        if self.target is None:
            return set()
        body = self.cell.object_body_ids[self.target]
        return {g for g in range(self.m.ngeom) if self.m.geom_bodyid[g] == body}

    def move_joints(self, q_to, speed=JOINT_SPEED):
        q_from = self.cell.arm_q()
        q_to = np.asarray(q_to, float)
        # A smoothstep profile peaks at 1.5 x its mean speed.
        duration = max(1.5 * float(np.max(np.abs(q_to - q_from))) / speed, 0.3)
        n = int(duration / cellmod.TIMESTEP_S)
        for k in range(1, n + 1):
            s = k / n
            s = s * s * (3 - 2 * s)
            self.d.ctrl[self.cell.arm_act] = q_from + s * (q_to - q_from)
            if not self.step():
                return False
        return self.step(int(SETTLE_S / cellmod.TIMESTEP_S / 2))

    def move_path(self, path, length_m, stop=None):
        """Through joint samples that are `length_m` of tool travel in all;
        a guarded move (`stop`, a test run after every physics step) holds
        the arm where it is once the test is true."""
        duration = max(length_m / TOOL_SPEED, 0.2)
        per = max(int(duration / len(path) / cellmod.TIMESTEP_S), 1)
        q_prev = self.cell.arm_q()
        for q in path:
            q = np.asarray(q, float)
            for k in range(1, per + 1):
                self.d.ctrl[self.cell.arm_act] = q_prev + k / per * (q - q_prev)
                if not self.step():
                    return False
                if stop is not None and stop():
                    self.d.ctrl[self.cell.arm_act] = self.cell.arm_q()
                    return self.step(int(SETTLE_S / cellmod.TIMESTEP_S / 2))
            q_prev = q
        return self.step(int(SETTLE_S / cellmod.TIMESTEP_S / 2))

    def hand_meets_something(self, held, resting):
        """Whether the fingers or the object `held` touch the cell (the bin,
        the table) or one of the objects `resting` (those in the bin when
        the attempt began): what the UR's tool contact detection stops a
        guarded move on, here at the first contact. An object carried
        along with the held one is not among them."""
        c = self.cell
        hand = c.finger_geoms[0] | c.finger_geoms[1]
        held_body = None if held is None else c.object_body_ids[held]
        resting_bodies = {c.object_body_ids[i] for i in resting}
        for i in range(self.d.ncon):
            con = self.d.contact[i]
            for a, b in ((con.geom1, con.geom2), (con.geom2, con.geom1)):
                if not (a in hand or self.m.geom_bodyid[a] == held_body) or b in c.robot_geoms:
                    continue
                body = self.m.geom_bodyid[b]
                if body == 0 or body in resting_bodies:
                    return True
        return False

    def open_to(self, width_m, table):
        """Moves the pads to `width_m` at `close_speed_m_s` (the 2F-140 moves
        both ways at the one speed the bridge sends: the command ramps along
        the gap table from the current gap), then lets them settle. Without
        the ramp a release slams the pads open at about 3 m/s and throws
        what they held."""
        width_m = min(width_m, 0.14)
        if self.close_speed_m_s > 0:
            gap = gripper.pad_gap(self.cell)
            steps = int(abs(width_m - gap) / self.close_speed_m_s / cellmod.TIMESTEP_S)
            for k in range(1, steps + 1):
                gripper.set_command(self.cell, gripper.command_for_width(table, gap + (width_m - gap) * k / steps))
                if not self.step():
                    return False
        gripper.set_command(self.cell, gripper.command_for_width(table, width_m))
        return self.step(int(0.6 / cellmod.TIMESTEP_S))

    def close(self, table):
        """Closes the pads at `close_speed_m_s` (the command ramps down the
        gap table from the current opening; the pads stop on an object
        while the command goes on, so the squeeze builds to its limit), then
        until the knuckle stops moving (or CLOSE_MAX_S)."""
        if self.close_speed_m_s > 0:
            gap = gripper.pad_gap(self.cell)
            steps = int(gap / self.close_speed_m_s / cellmod.TIMESTEP_S)
            for k in range(1, steps + 1):
                width = gap * (1 - k / steps)
                gripper.set_command(self.cell, gripper.command_for_width(table, width))
                if not self.step():
                    return False
        gripper.set_command(self.cell, gripper.CLOSED_RAD)
        still, last = 0, gripper.knuckle(self.cell)
        for _ in range(int(CLOSE_MAX_S / cellmod.TIMESTEP_S)):
            if not self.step():
                return False
            now = gripper.knuckle(self.cell)
            still = still + 1 if abs(now - last) < 2e-5 else 0
            last = now
            if still >= int(0.1 / cellmod.TIMESTEP_S):
                break
        return self.step(int(0.15 / cellmod.TIMESTEP_S))

    def shake(self):
        amplitude, cycles, hz = SHAKE
        q0 = self.cell.arm_q()
        n = int(cycles / hz / cellmod.TIMESTEP_S)
        for k in range(n):
            t = k * cellmod.TIMESTEP_S
            q = q0.copy()
            q[5] += amplitude * math.sin(2 * math.pi * hz * t)
            q[3] += 0.4 * amplitude * math.sin(2 * math.pi * hz * t)
            self.d.ctrl[self.cell.arm_act] = q
            if not self.step():
                return False
        self.d.ctrl[self.cell.arm_act] = q0
        return self.step(int(0.2 / cellmod.TIMESTEP_S))


def held_objects(cell):
    """Objects touching both fingers."""
    m, d = cell.model, cell.data
    touching = [set(), set()]
    for i in range(d.ncon):
        c = d.contact[i]
        for k, geoms in enumerate(cell.finger_geoms):
            for a, b in ((c.geom1, c.geom2), (c.geom2, c.geom1)):
                if a in geoms:
                    body = m.geom_bodyid[b]
                    if body in cell.object_body_ids:
                        touching[k].add(cell.object_body_ids.index(body))
    return touching[0] & touching[1]


def execute(cell, plan_steps, target, gap_table, close_speed_m_s=CLOSE_SPEED_M_S):
    """Runs the bridge's steps for a grasp of object `target` (index or None),
    the pads moving at `close_speed_m_s`, and returns (outcome, details)."""
    run = Run(cell, target, close_speed_m_s=close_speed_m_s)
    start_z = {i: cell.object_pose(i)[0][2] for i in range(len(cell.bodies))}
    lay_in_bin = [i for i in range(len(cell.bodies)) if cellmod.in_bin(cell.object_pose(i)[0])]
    closed = False
    lifted = False
    picked = None
    for step in plan_steps:
        name = step["name"]
        kind = step["kind"]
        if kind == "gripper" and not step["close"]:
            if name == "release":
                run.phase = "release"
                held = held_objects(cell)
                if picked is None or picked not in held:
                    return "dropped-carry", _details(run, picked, empty_handed=True)
                run.released_from_m = cellmod.height_span(cell, picked)[0]
                run.open_to(0.14, gap_table)
                run.step(int(0.8 / cellmod.TIMESTEP_S))
                break
            run.phase = "open"
            if not run.open_to(step["width_m"], gap_table):
                return "timeout", _details(run, picked)
        elif kind == "gripper" and step["close"]:
            run.phase = "close"
            if not run.close(gap_table):
                return "timeout", _details(run, picked)
            closed = True
            if gripper.pad_gap(cell) < 0.002:
                return ("collision" if run.collisions else "empty"), _details(run, picked, empty_handed=True)
        elif kind == "movej":
            if not closed:
                run.phase = "pre-grasp"
            else:
                run.phase = "carry"
            if not run.move_joints(step["joints"]):
                return "timeout", _details(run, picked)
            if run.phase == "pre-grasp" and run.collisions:
                return "unreachable-sim", _details(run, picked)
        elif kind == "movel" and step.get("until_contact"):
            run.phase = "lower"
            if not run.move_path(step["path"], LINEAR_STEP_M * len(step["path"]),
                                 stop=lambda: run.hand_meets_something(picked, lay_in_bin)):
                return "timeout", _details(run, picked)
        elif kind == "movel":
            run.phase = "approach" if not closed else "lift"
            if not run.move_path(step["path"], 0.15 if closed else 0.10):
                return "timeout", _details(run, picked)
            if run.phase == "lift":
                lifted = True
                held = held_objects(cell)
                raised = [i for i in held if cell.object_pose(i)[0][2] > start_z[i] + HELD_LIFT_M]
                if not raised:
                    cause = "collision" if run.collisions else ("empty" if not held else "slip-lift")
                    return cause, _details(run, picked, empty_handed=True)
                picked = target if target in raised else raised[0]
                run.phase = "shake"
                run.shake()
                if picked not in held_objects(cell):
                    return "slip-shake", _details(run, picked, empty_handed=True)
    if not lifted:
        return "timeout", _details(run, picked)
    park(cell)
    if picked is not None and cellmod.in_bin(come_to_rest(cell, picked)):
        return "success", _details(run, picked)
    return "dropped-carry", _details(run, picked)


def come_to_rest(cell, index, max_s=REST_MAX_S):
    """Lets the scene run until object `index` has moved less than 1 mm in
    0.1 s (or `max_s`), and returns its position: an object let go over the
    bin is judged where it lands, not while it falls."""
    window = int(0.1 / cellmod.TIMESTEP_S)
    last = now = cell.object_pose(index)[0].copy()
    for _ in range(int(max_s / 0.1)):
        for _ in range(window):
            mujoco.mj_step(cell.model, cell.data)
        now = cell.object_pose(index)[0].copy()
        if np.linalg.norm(now - last) < 0.001:
            break
        last = now
    return now


def park(cell):
    """Opens the hand, puts the arm back at its park pose (not simulated) and
    lets the scene settle for 0.3 s."""
    gripper.set_command(cell, cellmod.GRIP_OPEN_RAD)
    for _ in range(int(0.4 / cellmod.TIMESTEP_S)):
        mujoco.mj_step(cell.model, cell.data)
    cell.set_arm(np.array(cellmod.PARK))
    mujoco.mj_forward(cell.model, cell.data)
    for _ in range(int(0.3 / cellmod.TIMESTEP_S)):
        mujoco.mj_step(cell.model, cell.data)


def _details(run, picked, empty_handed=False):
    """What an attempt leaves besides its outcome; `empty_handed`: the hand
    would hold nothing over the bin (closed on nothing, or the object was
    left or lost on the way), which the robot-bridge's gripper reports too
    (`NoObject`, `Lost`): not said of a release that lands outside the bin."""
    details = {"picked": picked, "collisions": sorted({f"{p}: {a} ~ {b}" for p, a, b in run.collisions})[:6],
               "sim_s": round(run.d.time, 3)}
    if run.released_from_m is not None:
        details["released_from_m"] = round(run.released_from_m, 4)  # the object's lowest point as the pads opened
    if empty_handed:
        details["empty_handed"] = True
    return details
