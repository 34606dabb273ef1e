"""What a referee run writes: `referee.json` (rows and every attempt),
`referee.md` (the table with 95% intervals) and PNG snapshots of failures."""

import json
import math
import os

import mujoco
import numpy as np

FAILURES = ("empty", "slip-lift", "slip-shake", "dropped-carry", "collision", "timeout")


def wilson(successes, trials, z=1.96):
    """95% Wilson score interval of a proportion."""
    if trials == 0:
        return (float("nan"), float("nan"))
    p = successes / trials
    centre = (p + z * z / (2 * trials)) / (1 + z * z / trials)
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / (1 + z * z / trials)
    return (max(0.0, centre - half), min(1.0, centre + half))


def cleared(episode):
    """Objects of an episode in the bin at its end: picked, or carried along
    with a picked one (records from before `carried` was counted have none)."""
    return episode["removed"] + episode.get("carried", 0)


def rows(episodes):
    """One row per scenario x camera x pool."""
    groups = {}
    for e in episodes:
        groups.setdefault((e["scenario"], e["camera"], e["pool"]), []).append(e)
    out = []
    for (scenario, camera, pool), eps in sorted(groups.items()):
        attempts = [a for e in eps for a in e["attempts"] if a["outcome"] not in ("no-grasp", "unreachable")]
        plans = [a["plan_ms"] for e in eps for a in e["attempts"]]
        successes = sum(a["outcome"] == "success" for a in attempts)
        row = {
            "scenario": scenario, "camera": camera, "pool": pool, "episodes": len(eps),
            "attempts": len(attempts), "successes": successes,
            "removed": sum(e["removed"] for e in eps), "carried": sum(e.get("carried", 0) for e in eps),
            "cleared": sum(cleared(e) for e in eps), "initial": sum(e["initial"] for e in eps),
            "no_grasp": sum(e["end"] == "no-grasp" for e in eps),
            "unreachable": sum(a["unreachable"] for e in eps for a in e["attempts"]),
            "episodes_ended_unreachable": sum(e["end"] == "unreachable" for e in eps),
            "lost": sum(e["lost"] for e in eps),
            "median_plan_ms": round(float(np.median(plans)), 2) if plans else None,
            "failures": {f: sum(a["outcome"] == f for a in attempts) for f in FAILURES},
        }
        row["success_ci95"] = [round(v, 4) for v in wilson(successes, len(attempts))]
        row["cleared_ci95"] = [round(v, 4) for v in wilson(row["cleared"], row["initial"])]
        out.append(row)
    return out


def check(table):
    """Raises if a row's counts do not add up (every attempt has one outcome,
    nothing is removed that was not there)."""
    for r in table:
        name = f"{r['scenario']}/{r['camera']}/{r['pool']}"
        if r["successes"] + sum(r["failures"].values()) != r["attempts"]:
            raise AssertionError(f"{name}: {r['attempts']} attempts but {r['successes']} successes and "
                                 f"{sum(r['failures'].values())} failures")
        if not 0 <= r["removed"] <= r["cleared"] <= r["initial"] or r["removed"] > r["successes"]:
            raise AssertionError(f"{name}: removed {r['removed']} (cleared {r['cleared']}) of {r['initial']} "
                                 f"with {r['successes']} successes")
    return True


def fmt_rate(k, n, ci):
    if n == 0:
        return "-"
    return f"{k / n:.2f} ({ci[0]:.2f}-{ci[1]:.2f})"


def _cell_settings(meta):
    """The cell's settings a run records, as a clause (runs before they were
    recorded have none)."""
    parts = []
    if meta.get("close_speed_m_s") is not None:
        speed = meta["close_speed_m_s"]
        moving = "closing and opening" if meta.get("pads_open_at_speed") else "closing"
        parts.append(f"pads {moving} at {speed} m/s" if speed > 0 else "pads slammed (no ramp)")
    if meta.get("approach_clearance_m") is not None:
        parts.append(f"fingers opened {meta['approach_clearance_m']} m wider than the grasp")
    if meta.get("bin_fill_m") is not None:
        parts.append(f"the bridge's basket {meta['bin_fill_m']} m high")
    if "failed_tried_last" in meta:
        radius = meta.get("failed_radius_m")
        within = "the bridge's radius" if radius is None else f"{radius} m"
        parts.append(f"grasps within {within} of an empty-handed pick tried last"
                     if meta["failed_tried_last"] else "grasps in the planner's rank after an empty-handed pick")
    if meta.get("lowered_before_release"):
        parts.append(f"held objects lowered into the bin (to {meta['release_height_m']} m over its floor, "
                     "stopping on contact) before the release")
    if meta.get("release_spread_m"):
        parts.append(f"let go over four spots {meta['release_spread_m']} m off the bin's centre in turn")
    return "; " + ", ".join(parts) if parts else ""


def markdown(meta, table):
    lines = [
        "# Referee run",
        "",
        f"Planner `{meta['model_version']}` ({meta['backend']}), request: view policy `{meta['policy']}`, "
        f"min_quality {meta['min_quality']}, max_grasps {meta['max_grasps']}"
        f"{'' if meta.get('view_cascade', True) else ', no view cascade'}"
        f"{', approach cone ' + meta['approach_cone'] if meta.get('approach_cone') else ''}{', arm reach from the bridge' if meta.get('arm_reach') else ''}{', obstacles within ' + str(meta['obstacle_margin_m']) + ' m of the workspace' if meta.get('obstacle_margin_m') else ''}. Suite `{meta['suite']}`, "
        f"seed {meta['seed']}, {meta['resolution']} depth{' with noise' if meta['noise'] else ''}"
        f"{_cell_settings(meta)}. Command: `{meta['command']}`.",
        "",
        "Success = attempts whose object reached the bin / attempts (95% Wilson interval); cleared = objects "
        "in the bin / objects at the start (carried: of those, objects that went in with a picked one). "
        "Unreachable grasps are counted apart (not attempts): the robot-bridge refused them (IK, its collision "
        "model) or the simulated arm touched something on the way to the pre-grasp; the next grasp was tried.",
        "",
        "| scenario | camera | pool | episodes | attempts | success | cleared | carried | no grasp | unreachable | "
        "empty | slip lift | slip shake | dropped | collision | median plan ms |",
        "|---|---|---|---:|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in table:
        f = r["failures"]
        lines.append(
            f"| {r['scenario']} | {r['camera']} | {r['pool']} | {r['episodes']} | {r['attempts']} | "
            f"{fmt_rate(r['successes'], r['attempts'], r['success_ci95'])} | "
            f"{fmt_rate(r['cleared'], r['initial'], r['cleared_ci95'])} | {r['carried']} | {r['no_grasp']} | "
            f"{r['unreachable']} | "
            f"{f['empty']} | {f['slip-lift']} | {f['slip-shake']} | {f['dropped-carry']} | {f['collision']} | "
            f"{r['median_plan_ms']} |")
    lines += ["", f"Wall time {meta['wall_s']:.0f} s on {meta['workers']} worker(s).", ""]
    return "\n".join(lines)


def write(out_dir, meta, episodes):
    table = rows(episodes)
    check(table)
    with open(os.path.join(out_dir, "referee.json"), "w") as f:
        json.dump({"meta": meta, "rows": table, "episodes": episodes}, f, indent=1)
    with open(os.path.join(out_dir, "referee.md"), "w") as f:
        f.write(markdown(meta, table))
    return table


def _depth_with_grasp(depth, pose, entry):
    """The depth image as grey, the grasp's fingers and centre drawn over it (RGB array)."""
    valid = depth > 0
    img = np.zeros(depth.shape + (3,), np.uint8)
    if valid.any():
        lo, hi = np.percentile(depth[valid], [2, 98])
        g = np.clip((hi - depth) / max(hi - lo, 1e-6), 0, 1) * 200 + 40
        img[valid] = g[valid, None].astype(np.uint8)
    grasp = entry.get("grasp")
    if not grasp:
        return img
    x, y, z, w = grasp["orientation"]
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    centre = np.array(grasp["position"])
    half = entry.get("width_m", 0.05) / 2
    camera_from_world = np.linalg.inv(pose.world_from_camera)
    fx, fy, cx, cy = pose.intrinsics

    def pixel(p):
        c = camera_from_world[:3, :3] @ p + camera_from_world[:3, 3]
        return (fx * c[0] / c[2] + cx, fy * c[1] / c[2] + cy) if c[2] > 1e-3 else None

    def line(a, b, colour):
        pa, pb = pixel(a), pixel(b)
        if pa is None or pb is None:
            return
        for t in np.linspace(0, 1, 200):
            u, v = int(round(pa[0] + t * (pb[0] - pa[0]))), int(round(pa[1] + t * (pb[1] - pa[1])))
            if 0 <= v < img.shape[0] and 0 <= u < img.shape[1]:
                img[max(v - 1, 0):v + 2, max(u - 1, 0):u + 2] = colour

    closing, along, approach = r[:, 0], r[:, 1], r[:, 2]
    for side in (-1, 1):
        tip = centre + side * half * closing
        line(tip - 0.014 * along, tip + 0.014 * along, (255, 60, 60))
        line(tip, tip - 0.04 * approach, (255, 60, 60))
    line(centre - half * closing, centre + half * closing, (60, 220, 60))
    return img


def snapshot(out_dir, cell, pose, depth, entry, record, renderer_cache):
    """`failures/<scenario>-<camera>-<pool>-e<episode>-a<attempt>.png`: the
    depth frame with the grasp, beside a rendered picture of the hand at the
    object as the attempt ended."""
    from PIL import Image  # noqa: PLC0415

    folder = os.path.join(out_dir, "failures")
    os.makedirs(folder, exist_ok=True)
    left = _depth_with_grasp(depth, pose, entry)
    del renderer_cache
    renderer = mujoco.Renderer(cell.model, 480, 640)
    cam = mujoco.MjvCamera()
    target = np.array(entry.get("grasp", {}).get("position", [0.0, 0.0, 0.05]))
    hand = cell.data.xpos[cell.model.body("grip/right_gripper").id]
    # From the side facing the robot, framing the grasp and where the hand is now.
    cam.lookat[:] = (target + hand) / 2
    cam.distance = 0.6 + 0.8 * float(np.linalg.norm(hand - target))
    cam.azimuth, cam.elevation = -60.0, -30.0
    option = mujoco.MjvOption()
    option.sitegroup[:] = 0
    renderer.update_scene(cell.data, cam, scene_option=option)
    right = renderer.render()
    renderer.close()
    left_img = Image.fromarray(left).resize((640, 480))
    canvas = Image.new("RGB", (1280, 480))
    canvas.paste(left_img, (0, 0))
    canvas.paste(Image.fromarray(right), (640, 0))
    name = f"{record['scenario']}-{record['camera']}-{record['pool']}-e{record['episode']}-a{entry['attempt']}.png"
    canvas.save(os.path.join(folder, name))
    return name
