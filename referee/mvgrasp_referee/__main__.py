"""`python -m mvgrasp_referee`: clear-the-table runs against a running planner
(scripts/referee.sh sets up the environment and calls this)."""

import argparse
import multiprocessing
import os
import shlex
import sys
import time

SUITES = {
    # scenario -> episodes per camera and pool ("*": any pool not named)
    "oracle": {"isolated": {"*": 40, "test-b": 45}},
    "quick": {"isolated": {"*": 3}, "packed": {"test-b": 1, "train": 1}, "pile": {"test-a": 1, "train": 1}},
    "tune": {"isolated": {"*": 40}, "packed": {"*": 6}, "pile": {"*": 6}, "clutter": {"*": 6}},
    "standard": {"isolated": {"*": 60}, "packed": {"*": 10}, "pile": {"*": 10}, "clutter": {"*": 10}},
    "full": {"isolated": {"*": 200, "test-b": 90}, "packed": {"*": 25}, "pile": {"*": 25}, "clutter": {"*": 25}},
}


def parse(argv):
    p = argparse.ArgumentParser(prog="referee", description="Clear-the-table in MuJoCo against a running "
                                "mvgrasp planner, judged in physics.")
    p.add_argument("--server", default="127.0.0.1:50051", help="the planner's gRPC address (HOST:PORT)")
    p.add_argument("--suite", choices=SUITES, default="quick")
    p.add_argument("--camera", default="topdown", help="topdown, angled, random or all (topdown,angled,random)")
    p.add_argument("--pools", default="test-a,test-b",
                   help="pools to run (train, train-large: its meshes at household sizes, or train-round: "
                        "generated rounded shapes, only for tuning; "
                        "test-a, test-b only to report a chosen candidate)")
    p.add_argument("--scenarios", default="isolated,packed,pile",
                   help="isolated, packed, pile (the default) and clutter (ten objects, asked by name)")
    p.add_argument("--policy", default="default", help="view policy asked of the planner "
                   "(default: the server's; entropy, all, top-down, random)")
    p.add_argument("--min-quality", type=float, default=None, help="tau asked of the planner (default: the server's)")
    p.add_argument("--max-grasps", type=int, default=10)
    p.add_argument("--approach-cone", default=None, metavar="AX,AY,AZ,HALF_DEG",
                   help="ask for approaches within this cone only, e.g. 0,0,-1,60 (from above within 60 degrees)")
    p.add_argument("--arm-reach", action="store_true",
                   help="ask only for grasps the arm reaches at the pre-grasp, as the robot-bridge tells it "
                        "from its calibration (the planner's arm_reach)")
    p.add_argument("--obstacle-margin-m", type=float, default=0.0, metavar="M",
                   help="ask the planner for what stands this far around the workspace (and above it) as "
                        "obstacle boxes, and hand them to the robot-bridge, as its planner.obstacle_margin_m "
                        "does (default 0: not asked, as before 2026-12-01)")
    p.add_argument("--robot-body", action="store_true",
                   help="send each frame with the arm where it stands (the robot-bridge's capsules at its "
                        "joints), so the planner leaves its points out of the objects and obstacle boxes, as "
                        "the bridge's planner.robot_body does (default: not sent, as before 2026-12-01)")
    p.add_argument("--no-view-cascade", action="store_true",
                   help="ask for the paper's single pass over the policy's views (the ablation)")
    p.add_argument("--bin-fill-m", type=float, default=None, metavar="M",
                   help="how high the robot-bridge keeps the arm out of the bin, walls and what piles up in "
                        "them (m; default 0.25, the walls are 0.09)")
    p.add_argument("--approach-clearance-m", type=float, default=None, metavar="M",
                   help="the robot-bridge opens the fingers this much wider than a grasp's width "
                        "(its pick.approach_clearance_m; default: the bridge's own)")
    p.add_argument("--failed-radius-m", type=float, default=None, metavar="M",
                   help="the robot-bridge tries a grasp within this of a pick that came up empty-handed last "
                        "(its pick.failed_radius_m; default: the bridge's own; 0: in the planner's rank, "
                        "as before 2026-11-30)")
    p.add_argument("--release-height-m", type=float, default=0.15, metavar="M",
                   help="the robot-bridge lowers what it holds into the bin before letting go, stopping on "
                        "contact, at the lowest this high over the bin's floor (its pick.release_height_m; "
                        "default 0.15, the bridge's; 0: let go at the drop pose, as before 2026-12-01)")
    p.add_argument("--release-spread-m", type=float, default=0.05, metavar="M",
                   help="the robot-bridge lets go over four spots this far off the bin's centre along x and y, "
                        "in turn, counting the objects it held to the release (its pick.release_spread_m; "
                        "default 0.05, the bridge's; 0: over the centre, as before 2026-12-01)")
    p.add_argument("--close-speed-m-s", type=float, default=None, metavar="V",
                   help="how fast the pads close and open (m/s of the gap; default 0.14, the robot-bridge's "
                        "speed register on the 2F-140; 0: the servo slams them, as before 2026-11-29)")
    p.add_argument("--rigid-tcp", action="store_true",
                   help="configure the robot-bridge without the 2F-140's fingertip travel (the ablation)")
    p.add_argument("--oracle", action="store_true",
                   help="ground-truth grasps instead of the planner (the executor's self-check)")
    p.add_argument("--seed", type=int, default=2026)
    p.add_argument("--resolution", default="640x480")
    p.add_argument("--noise", action="store_true", help="Kinect-like depth noise")
    p.add_argument("--workers", type=int, default=max(1, min(2, os.cpu_count() or 1)))
    p.add_argument("--snapshots", type=int, default=12, help="failure snapshots to write (PNG)")
    p.add_argument("--attempt-views", default=None, metavar="DIR",
                   help="write each tried grasp's view and outcome here, for training (attempt_views.py)")
    p.add_argument("--attempt-alternatives", type=int, default=0, metavar="K",
                   help="with --attempt-views: also try up to K grasps ranked below each attempt's own, "
                   "from the same state (put back after)")
    p.add_argument("--bridge", default=None, help="robot-bridge binary (default target/release/robot-bridge)")
    p.add_argument("--out", required=True)
    return p.parse_args(argv)


def jobs(args):
    from . import camera, pools, scenes  # noqa: PLC0415

    cameras = list(camera.CAMERAS) if args.camera == "all" else args.camera.split(",")
    for c in cameras:
        if c not in camera.CAMERAS:
            raise SystemExit(f"referee: unknown camera {c!r} (topdown, angled, random or all)")
    pool_names = args.pools.split(",")
    for name in pool_names:
        pools.pool(name)
    out = []
    for scenario in args.scenarios.split(","):
        if scenario not in scenes.SCENARIOS:
            raise SystemExit(f"referee: unknown scenario {scenario!r}")
        for cam in cameras:
            for pool in pool_names:
                per_pool = SUITES[args.suite].get(scenario, {})
                count = per_pool.get(pool, per_pool.get("*", 0))
                out += [(scenario, pool, cam, e) for e in range(count)]
    return out


_worker = {}


def _init(args):
    from . import bridge, cell, gripper, planner  # noqa: PLC0415

    probe = cell.build([], [])
    travel = [] if args.rigid_tcp else gripper.fingertip_travel(probe)
    _worker["bridge"] = bridge.Bridge(args.bridge, gripper.tcp_in_flange(probe), travel, args.bin_fill_m,
                                        args.approach_clearance_m, args.failed_radius_m, args.release_height_m,
                                        args.release_spread_m)
    _worker["planner"] = planner.OraclePlanner() if args.oracle else planner.Planner(
        args.server, args.policy, args.min_quality, args.max_grasps,
        view_cascade=False if args.no_view_cascade else None, approach_cone=args.approach_cone,
        arm_reach=_worker["bridge"].arm_reach() if args.arm_reach else None,
        with_views=args.attempt_views is not None, obstacle_margin_m=args.obstacle_margin_m,
        robot_body=args.robot_body)
    _worker["args"] = args
    _worker["renderers"] = {}
    if args.attempt_views:
        _worker["contract"] = _worker["planner"].contract()


def _run(job):
    from . import attempt_views, protocol, report  # noqa: PLC0415

    scenario, pool, cam, episode = job
    args = _worker["args"]

    def take(cell, pose, depth, entry, record):
        folder = os.path.join(args.out, "failures")
        if os.path.isdir(folder) and len(os.listdir(folder)) >= args.snapshots:
            return None
        return report.snapshot(args.out, cell, pose, depth, entry, record, _worker["renderers"])

    start = time.perf_counter()
    recorder = attempt_views.Recorder() if args.attempt_views else None
    record = protocol.run_episode(_worker["planner"], _worker["bridge"], scenario, pool, cam, args.seed, episode,
                                  args.resolution, args.noise, take if args.snapshots > 0 else None,
                                  recorder, args.attempt_alternatives, args.close_speed_m_s)
    if recorder is not None:
        record["attempt_views"] = recorder.write(args.attempt_views, scenario, cam, args.seed, episode,
                                                 _worker["contract"]["input_size_px"])
    record["wall_s"] = round(time.perf_counter() - start, 2)
    return record


def main(argv=None):
    args = parse(sys.argv[1:] if argv is None else argv)
    from . import assets, pools, report  # noqa: PLC0415

    pools.check_split()
    if args.attempt_views is not None:
        if args.oracle:
            raise SystemExit("referee: --attempt-views records the planner's grasps, not the oracle's")
        if any(name not in pools.TRAIN_POOLS for name in args.pools.split(",")):
            raise SystemExit("referee: --attempt-views records training data: --pools train or train-large only")
    if args.bridge is None:
        args.bridge = os.path.join(assets.ROOT, "target", "release", "robot-bridge")
    from . import cell  # noqa: PLC0415

    if args.bin_fill_m is None:
        args.bin_fill_m = cell.BIN_FILL_M
    if not cell.BIN_WALL_M[1] <= args.bin_fill_m < cell.DROP_HEIGHT_M:
        raise SystemExit(f"referee: --bin-fill-m {args.bin_fill_m}: from the bin's walls ({cell.BIN_WALL_M[1]} m) "
                         f"to under the drop height ({cell.DROP_HEIGHT_M} m)")
    if args.close_speed_m_s is None:
        from . import executor  # noqa: PLC0415

        args.close_speed_m_s = executor.CLOSE_SPEED_M_S
    if not 0.0 <= args.close_speed_m_s <= 5.0:
        raise SystemExit(f"referee: --close-speed-m-s {args.close_speed_m_s}: from 0 (no ramp) to 5 m/s")
    if args.approach_clearance_m is not None and not 0.0 <= args.approach_clearance_m <= 0.1:
        raise SystemExit(f"referee: --approach-clearance-m {args.approach_clearance_m}: from 0 to 0.1 m")
    if args.failed_radius_m is not None and not 0.0 <= args.failed_radius_m <= 0.1:
        raise SystemExit(f"referee: --failed-radius-m {args.failed_radius_m}: from 0 to 0.1 m")
    if not (args.release_height_m == 0.0 or cell.BIN_WALL_M[1] <= args.release_height_m < cell.DROP_HEIGHT_M):
        raise SystemExit(f"referee: --release-height-m {args.release_height_m}: 0 (off), or from the bin's walls "
                         f"({cell.BIN_WALL_M[1]} m) to under the drop height ({cell.DROP_HEIGHT_M} m)")
    if not 0.0 <= args.release_spread_m < cell.BIN_INNER_HALF_M:
        raise SystemExit(f"referee: --release-spread-m {args.release_spread_m}: 0 (off), or under the bin's "
                         f"inner half width ({cell.BIN_INNER_HALF_M} m)")
    os.makedirs(args.out, exist_ok=True)
    work = jobs(args)
    assets.robosuite_assets()
    assets.pybullet_data()
    _init(args)
    info = _worker["planner"].model_info()
    print(f"referee: {len(work)} episodes, suite {args.suite}, planner {info['model_version']} "
          f"on {info['backend']}, {args.workers} worker(s)", file=sys.stderr)
    start = time.perf_counter()
    episodes = []
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(args.workers, initializer=_init, initargs=(args,)) as pool:
        for k, record in enumerate(pool.imap(_run, work), 1):
            episodes.append(record)
            done = sum(a["outcome"] == "success" for e in episodes for a in e["attempts"])
            tried = sum(a["outcome"] not in ("no-grasp", "unreachable") for e in episodes for a in e["attempts"])
            bar = "#" * int(30 * k / len(work))
            print(f"\r[{bar:<30}] {k}/{len(work)} episodes, {done}/{tried} attempts held, "
                  f"{time.perf_counter() - start:.0f} s", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    meta = {**info, "suite": args.suite, "policy": args.policy, "min_quality": args.min_quality,
            "max_grasps": args.max_grasps, "view_cascade": not args.no_view_cascade,
            "approach_cone": args.approach_cone, "arm_reach": args.arm_reach,
            "obstacle_margin_m": args.obstacle_margin_m, "robot_body": args.robot_body, "seed": args.seed,
            "resolution": args.resolution, "noise": args.noise,
            "oracle": args.oracle, "bin_fill_m": args.bin_fill_m,
            "approach_clearance_m": args.approach_clearance_m, "failed_radius_m": args.failed_radius_m,
            "failed_tried_last": args.failed_radius_m != 0.0, "release_height_m": args.release_height_m,
            "lowered_before_release": args.release_height_m != 0.0, "release_spread_m": args.release_spread_m,
            "close_speed_m_s": args.close_speed_m_s,
            "pads_open_at_speed": True, "workers": args.workers,
            "wall_s": time.perf_counter() - start,
            "command": "scripts/referee.sh " + " ".join(shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv))}
    table = report.write(args.out, meta, episodes)
    if args.attempt_views:
        from . import attempt_views  # noqa: PLC0415

        attempt_views.write_manifest(args.attempt_views, info, _worker["contract"],
                                     sum(e.get("attempt_views", 0) for e in episodes),
                                     {"pools": args.pools, "seed": args.seed, "alternatives": args.attempt_alternatives,
                                      "command": meta["command"]})
    print(report.markdown(meta, table))
    _worker["bridge"].close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
