"""The clear-the-table protocol: episodes of attempts, each judged in physics.

An attempt: the arm parks, the camera takes a depth frame, the planner is
called over gRPC, the robot-bridge picks the best-ranked grasp it can reach
(its IK, its collision model, its steps), and the simulated arm runs it.
Grasps the bridge refuses, and grasps whose pre-grasp move makes the arm
touch something in the simulator (the state is put back), are counted as
`unreachable` and the next grasp is tried. An episode ends when the table is
clear, after the scenario's consecutive failures, when the planner offers
no grasp or the arm can reach none of them, or after 2 x objects + 4 attempts.
"""

import mujoco
import numpy as np

from . import camera as cammod
from . import cell as cellmod
from . import executor, gripper, scenes
from .bridge import matrix_xyzw
from .planner import REFUSALS, bridge_scene

MAX_GRASPS_TRIED = 10


def grasp_on_object(grasp, objects):
    """How a planned grasp sits on its object as the planner saw it: the
    object's extent (its gravity-aligned frame: x the long horizontal axis,
    z up) and the angle between the closing line and that long axis seen
    from above (0: end to end, 90: across). Empty when the object is not
    among the detected ones."""
    obj = next((o for o in objects if o["id"] == grasp["object"]), None)
    if obj is None:
        return {}
    extent = np.subtract(obj["extent_max_m"], obj["extent_min_m"])
    closing = matrix_xyzw(grasp["orientation"])[:, 0]
    long_axis = matrix_xyzw(obj["orientation"])[:, 0]
    across = np.hypot(closing[0], closing[1])
    angle = 90.0
    if across > 1e-9:
        cosine = abs(closing[0] * long_axis[0] + closing[1] * long_axis[1]) / (across * np.hypot(*long_axis[:2]))
        angle = float(np.degrees(np.arccos(min(1.0, cosine))))
    return {"object_extent_m": [round(float(v), 4) for v in extent], "closing_to_long_deg": round(angle, 1)}


def snapshot(cell):
    d = cell.data
    return d.qpos.copy(), d.qvel.copy(), d.act.copy(), d.ctrl.copy(), d.time


def restore(cell, state):
    d = cell.data
    d.qpos[:], d.qvel[:], d.act[:], d.ctrl[:], d.time = state
    mujoco.mj_forward(cell.model, d)


def full_state(cell):
    """Everything the simulation's next step depends on (MuJoCo's
    integration state: with the solver's warm start, unlike `snapshot`)."""
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    state = np.empty(mujoco.mj_stateSize(cell.model, spec))
    mujoco.mj_getState(cell.model, cell.data, state, spec)
    return state


def set_full_state(cell, state):
    mujoco.mj_setState(cell.model, cell.data, state, mujoco.mjtState.mjSTATE_INTEGRATION)
    mujoco.mj_forward(cell.model, cell.data)


def _try_alternatives(cell, before, ask, grasps, start, count, remaining, table, record, close_speed_m_s):
    """Up to `count` reachable grasps from `grasps[start:]`, each run from the
    full state `before` and passed to `record(index, outcome, target)`; the
    state after the caller's own attempt is put back exactly at the end."""
    after = full_state(cell)
    tried = 0
    while tried < count and start < len(grasps):
        set_full_state(cell, before)
        answer = ask(start)
        if answer["grasp_index"] is None:
            break
        k = start + answer["grasp_index"]
        target = target_of(cell, grasps[k], remaining)
        outcome, _ = executor.execute(cell, answer["steps"], target, table, close_speed_m_s)
        start = k + 1
        if outcome != "unreachable-sim":
            record(k, outcome, target)
            tried += 1
    set_full_state(cell, after)


def target_of(cell, grasp, remaining):
    """The object nearest the grasp centre (the one it is meant for)."""
    p = np.array(grasp["position"])
    best, best_d = None, np.inf
    for i in remaining:
        body = cell.object_body_ids[i]
        geoms = [g for g in range(cell.model.ngeom) if cell.model.geom_bodyid[g] == body and cell.model.geom_group[g] == 1]
        d = np.linalg.norm(cell.data.geom_xpos[geoms[0]] - p) if geoms else np.inf
        pos = cell.object_pose(i)[0]
        d = min(d, np.linalg.norm(pos - p))
        if d < best_d:
            best, best_d = i, d
    return best


def run_episode(planner, bridge, scenario, pool, camera_kind, seed, episode, resolution="640x480", noise=False,
                snapshots=None, recorder=None, alternatives=0, close_speed_m_s=executor.CLOSE_SPEED_M_S):
    """One episode, the pads moving at `close_speed_m_s`; returns its
    record (attempts and counts). With a
    `recorder` (attempt_views.Recorder), each tried grasp's view and outcome
    are recorded, and after each attempt up to `alternatives` grasps ranked
    below it are tried from the same state, recorded, and the state put
    back (the episode goes on from its own attempt)."""
    cell, specs = scenes.make(scenario, pool, seed, episode)

    def name_of(index):
        return specs[index].name if index is not None else None

    rng = np.random.default_rng([seed, episode, 13])
    pose, redrawn = cammod.sample_pose(camera_kind, rng, resolution,
                                       lambda p: cammod.sees_area(cell, p, cellmod.AREA_HALF_M))
    cam = cammod.DepthCamera(cell.model, pose.width, pose.height)
    table = gripper.gap_table(cell)
    allowed_failures = scenes.SCENARIOS[scenario][1]
    initial = [i for i in range(len(specs)) if scenes.on_table(cell, i)]
    record = {"scenario": scenario, "pool": pool, "camera": camera_kind, "seed": seed, "episode": episode,
              "objects": [s.name for s in specs], "initial": len(initial), "attempts": [], "end": None,
              "camera_pose": pose.world_from_camera.round(4).tolist(), "camera_redrawn": redrawn}
    removed, failures = set(), 0
    # Grasps that left the hand empty (the gripper tells): the bridge tries
    # grasps that repeat one of them last (`order`), as `pick --failed-picks` does.
    empty_handed = []
    # Picks that held their object to the release, wherever it landed: as
    # `pick --basket-count` counts them, where over the bin the next goes.
    released = 0
    try:
        for attempt in range(2 * len(specs) + 4):
            remaining = [i for i in initial if i not in removed and scenes.on_table(cell, i)]
            if not remaining:
                record["end"] = "clear"
                break
            if failures >= allowed_failures:
                record["end"] = "failures"
                break
            depth = cam.depth(cell.model, cell.data, pose)
            if noise:
                depth = cammod.add_noise(depth, rng)
            body = None
            if getattr(planner, "ground_truth", False):
                plan = planner.plan_truth(cell, remaining)
            else:
                body = bridge.robot_body(cell.arm_q()) if getattr(planner, "asks_robot_body", False) else None
                plan = planner.plan(depth, pose, seed=seed * 1000 + attempt, robot_body=body)
            entry = {"attempt": attempt, "plan_ms": round(plan["call_ms"], 2), "server_ms": round(plan["server_ms"], 2),
                     "detected": len(plan["objects"]), "grasps": len(plan["grasps"]), "unreachable": 0,
                     "refused": []}
            if not plan["grasps"]:
                entry["outcome"] = "no-grasp"
                if "error" in plan:
                    entry["planner_error"] = plan["error"]
                # Why, summed over the detected objects (the planner's own count).
                entry["refused_by_planner"] = {
                    cause: sum(o.get("refused", {}).get(cause, 0) for o in plan["objects"])
                    for cause in REFUSALS}
                record["attempts"].append(entry)
                record["end"] = "no-grasp"
                break
            obstacles = bridge_scene(plan, body is not None)
            grasps = plan["grasps"][:MAX_GRASPS_TRIED]
            rank = bridge.order(grasps, empty_handed)  # the planner's rank of each, in the order tried
            grasps = [grasps[k] for k in rank]
            index_of = {o["id"]: k for k, o in enumerate(plan["objects"])}

            def ask(start):
                asked = [{"position": g["position"], "orientation": g["orientation"], "width_m": g["width_m"],
                          "quality": g["quality"], "object": index_of.get(g["object"])} for g in grasps[start:]]
                return bridge.plan(asked, obstacles, cell.arm_q(), released)

            outcome, details = None, {}
            start = 0
            while start < len(grasps):
                answer = ask(start)
                if "obstacles" in obstacles:
                    # The boxes seen outside the workspace, and those the bridge took for the cell.
                    entry["obstacles_seen"] = len(obstacles["obstacles"])
                    entry["obstacles_left_out"] = sorted({o["why"] for o in answer.get("obstacles_left_out", [])})
                    entry["obstacles_kept"] = entry["obstacles_seen"] - len(answer.get("obstacles_left_out", []))
                    entry["obstacles_cut"] = len(answer.get("obstacles_cut", []))
                if answer["grasp_index"] is None:
                    entry["unreachable"] += len(grasps) - start
                    entry["refused"] += [r["reason"] for r in answer["refused"]][:3]
                    break
                chosen = start + answer["grasp_index"]
                entry["unreachable"] += answer["grasp_index"]
                entry["refused"] += [r["reason"] for r in answer["refused"]][:3]
                grasp = grasps[chosen]
                target = target_of(cell, grasp, remaining)
                state = snapshot(cell)
                before = full_state(cell) if alternatives > 0 else None
                outcome, details = executor.execute(cell, answer["steps"], target, table, close_speed_m_s)
                if outcome == "unreachable-sim":
                    entry["unreachable"] += 1
                    entry["refused"].append("simulated arm touched " + "; ".join(details["collisions"][:2]))
                    restore(cell, state)
                    start = chosen + 1
                    outcome = None
                    continue
                entry.update({"grasp_rank": rank[chosen], "quality": round(grasp["quality"], 4),
                              "width_m": round(grasp["width_m"], 4), "view": grasp["view"],
                              "grasp": {"position": [round(v, 4) for v in grasp["position"]],
                                        "orientation": [round(v, 5) for v in grasp["orientation"]]},
                              "target": name_of(target), **details})
                entry.update(grasp_on_object(grasp, plan["objects"]))
                if recorder is not None:
                    recorder.add(plan, grasp, rank[chosen], outcome, attempt, False, name_of(target))
                    if alternatives > 0:
                        _try_alternatives(cell, before, ask, grasps, chosen + 1, alternatives, remaining, table,
                                          lambda k, o, t: recorder.add(plan, grasps[k], rank[k], o, attempt, True,
                                                                       name_of(t)), close_speed_m_s)
                break
            if outcome is None:
                entry["outcome"] = "unreachable"
                record["attempts"].append(entry)
                record["end"] = "unreachable"
                break
            entry["outcome"] = outcome
            record["attempts"].append(entry)
            if snapshots is not None and outcome != "success":
                entry["snapshot"] = snapshots(cell, pose, depth, entry, record)
            if outcome != "success":
                executor.park(cell)
            if details.get("empty_handed"):
                empty_handed.append(grasp)
            if "released_from_m" in details:
                released += 1
            if outcome == "success":
                removed.add(details["picked"])
                failures = 0
            else:
                failures += 1
        else:
            record["end"] = "attempts"
    finally:
        cam.close()
    record["removed"] = len(removed.intersection(initial))
    record["bin_top_m"] = round(cellmod.bin_top(cell), 3)
    record["carried"], record["lost"] = left_the_table(cell, initial, removed)
    return record


def left_the_table(cell, initial, removed):
    """Of the objects at the start that no attempt picked (not in
    `removed`) and that are off the table at the end: how many lie in the
    bin (carried along with a picked one) and how many elsewhere (lost)."""
    gone = [i for i in initial if i not in removed and not scenes.on_table(cell, i)]
    carried = sum(1 for i in gone if cellmod.in_bin(cell.object_pose(i)[0]))
    return carried, len(gone) - carried

