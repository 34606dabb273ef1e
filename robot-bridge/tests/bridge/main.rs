//! The bridge against the controller emulator, on loopback.

#![allow(clippy::expect_used)] // fixtures stop the test on bad set-up

use std::f64::consts::PI;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use robot_bridge::Error;
use robot_bridge::emulate::{Emulator, EmulatorPorts};
use robot_bridge::pick::{GraspTarget, PickConfig, Step, plan_pick, urscript};
use robot_bridge::rtde::RtdeClient;
use robot_bridge::script::send_script;
use robot_bridge::ur5e::{Joints, Ur5e};

const HOME: Joints = [0.0, -PI / 2.0, PI / 2.0, -PI / 2.0, -PI / 2.0, 0.0];
const TIMEOUT: Duration = Duration::from_secs(2);

fn emulator() -> Emulator {
    Emulator::start("127.0.0.1", EmulatorPorts::default(), HOME).expect("emulator")
}

/// Reads states until `done` holds or `limit` passes.
fn wait_for(
    client: &mut RtdeClient,
    limit: Duration,
    done: impl Fn(&robot_bridge::rtde::RobotState) -> bool,
) -> robot_bridge::rtde::RobotState {
    let start = Instant::now();
    loop {
        let state = client.next_state().expect("state");
        if done(&state) || start.elapsed() > limit {
            return state;
        }
    }
}

/// A top-down grasp in front of the robot, planned with fast moves so the
/// tests are short (the default configuration is conservative).
fn fast_pick_plan() -> (robot_bridge::pick::PickPlan, PickConfig) {
    let grasp = GraspTarget {
        world_from_grasp: Isometry3::from_parts(
            Translation3::new(0.1, -0.45, 0.05),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), PI),
        ),
        width_m: 0.05,
        quality: 0.9,
        object: None,
    };
    let config = PickConfig {
        joint_speed: 3.0,
        tool_speed: 0.5,
        ..PickConfig::default()
    };
    (
        plan_pick(&Ur5e::default(), &config, &[grasp], &[], &HOME).expect("plan"),
        config,
    )
}

#[test]
fn rtde_streams_the_state() {
    let emu = emulator();
    let mut client = RtdeClient::connect(emu.rtde_address, 125.0, TIMEOUT).expect("connect");
    assert_eq!(client.controller_version[0], 5);
    let a = client.next_state().expect("state");
    let b = client.next_state().expect("state");
    assert_eq!(a.actual_q, HOME);
    assert!(b.timestamp_s > a.timestamp_s);
    assert_eq!((a.robot_mode, a.safety_mode, a.runtime_state), (7, 1, 1));
    // The TCP pose (no tool set) is the flange from forward kinematics.
    let flange = Ur5e::default().forward(&HOME).translation.vector;
    assert!(
        (Vector3::new(a.actual_tcp_pose[0], a.actual_tcp_pose[1], a.actual_tcp_pose[2]) - flange).norm()
            < 1e-9
    );
}

#[test]
fn a_planned_pick_runs_to_its_last_waypoint() {
    let emu = emulator();
    let mut client = RtdeClient::connect(emu.rtde_address, 125.0, TIMEOUT).expect("connect");
    let (plan, config) = fast_pick_plan();
    let Some(Step::MoveJ { joints: last, .. }) = plan.steps.last() else {
        panic!("ends with a joint move")
    };
    send_script(emu.script_address, &urscript(&plan, &config), TIMEOUT).expect("send");
    let state = wait_for(&mut client, Duration::from_secs(20), |s| {
        s.runtime_state == 1 && (0..6).all(|i| (s.actual_q[i] - last[i]).abs() < 1e-6)
    });
    for i in 0..6 {
        assert!(
            (state.actual_q[i] - last[i]).abs() < 1e-6,
            "joint {i}: {:?} vs {last:?}",
            state.actual_q
        );
    }
}

#[test]
fn a_protective_stop_halts_motion_and_is_reported() {
    let emu = emulator();
    let mut client = RtdeClient::connect(emu.rtde_address, 125.0, TIMEOUT).expect("connect");
    let mut target = HOME;
    target[0] += 1.0;
    send_script(
        emu.script_address,
        &format!(
            "movej([{}], a=1.0, v=0.5)\n",
            target.map(|v| v.to_string()).join(", ")
        ),
        TIMEOUT,
    )
    .expect("send");
    wait_for(&mut client, TIMEOUT, |s| {
        s.runtime_state == 2 && s.actual_q[0] > HOME[0] + 0.05
    });
    emu.faults().protective_stop.store(true, Ordering::Relaxed);
    let stopped = wait_for(&mut client, TIMEOUT, |s| s.stopped_by_safety());
    assert!(stopped.stopped_by_safety());
    let later = wait_for(&mut client, Duration::from_millis(200), |_| false);
    assert_eq!(later.actual_q, stopped.actual_q, "no motion after the stop");
    assert!(
        later.actual_q[0] < target[0] - 0.1,
        "it stopped short of the target"
    );
    // A program sent during the stop does not run.
    send_script(
        emu.script_address,
        "movej([0, 0, 0, 0, 0, 0], a=1.0, v=3.0)\n",
        TIMEOUT,
    )
    .expect("send");
    let still = wait_for(&mut client, Duration::from_millis(300), |_| false);
    assert_eq!(still.actual_q, stopped.actual_q);
    emu.unlock_protective_stop();
    let unlocked = wait_for(&mut client, TIMEOUT, |s| !s.stopped_by_safety());
    assert_eq!(unlocked.safety_mode, 1);
}

#[test]
fn reconnects_with_backoff_once_the_link_is_back() {
    let emu = emulator();
    emu.faults().drop_connections.store(true, Ordering::Relaxed);
    std::thread::scope(|s| {
        s.spawn(|| {
            std::thread::sleep(Duration::from_millis(250));
            emu.faults().drop_connections.store(false, Ordering::Relaxed);
        });
        let start = Instant::now();
        let mut client = RtdeClient::connect_with_retry(
            emu.rtde_address,
            125.0,
            Duration::from_millis(300),
            8,
            Duration::from_millis(50),
        )
        .expect("reconnected");
        assert!(
            start.elapsed() >= Duration::from_millis(200),
            "it had to wait for the link"
        );
        client.next_state().expect("state");
    });
    // A controller refusal is not retried.
    emu.faults().recipe_in_use.store(true, Ordering::Relaxed);
    let start = Instant::now();
    let err = RtdeClient::connect_with_retry(emu.rtde_address, 125.0, TIMEOUT, 5, Duration::from_millis(500))
        .err()
        .expect("refused");
    assert!(matches!(err, Error::Controller(_)), "{err}");
    assert!(
        start.elapsed() < Duration::from_millis(500),
        "no retry on a refusal"
    );
}

#[test]
fn recipe_in_use_and_dropped_connections_are_clear_errors() {
    let emu = emulator();
    emu.faults().recipe_in_use.store(true, Ordering::Relaxed);
    let err = RtdeClient::connect(emu.rtde_address, 125.0, TIMEOUT)
        .err()
        .expect("refused");
    assert!(
        matches!(&err, Error::Controller(m) if m.contains("IN_USE") && m.contains("timestamp")),
        "{err}"
    );
    emu.faults().recipe_in_use.store(false, Ordering::Relaxed);
    let mut client = RtdeClient::connect(emu.rtde_address, 125.0, TIMEOUT).expect("connect");
    client.next_state().expect("state");
    emu.faults().drop_connections.store(true, Ordering::Relaxed);
    let start = Instant::now();
    let err = loop {
        match client.next_state() {
            Ok(_) if start.elapsed() < Duration::from_secs(3) => continue,
            Ok(_) => panic!("the stream never dropped"),
            Err(e) => break e,
        }
    };
    assert!(matches!(err, Error::Io(_)), "{err}");
}

mod executor {
    use super::*;
    use robot_bridge::execute::{Controller, PickOutcome, execute_pick};
    use robot_bridge::gripper::Gripper;

    fn controller(emu: &Emulator) -> Controller {
        let mut gripper = Gripper::connect(emu.gripper_address, 0.14, TIMEOUT).expect("gripper");
        gripper.activate().expect("activate");
        Controller {
            rtde: RtdeClient::connect(emu.rtde_address, 125.0, TIMEOUT).expect("rtde"),
            script_address: emu.script_address,
            gripper,
            io_timeout: TIMEOUT,
            motion_timeout: Duration::from_secs(10),
        }
    }

    #[test]
    fn a_pick_with_an_object_is_placed() {
        let emu = emulator();
        emu.set_object_width(Some(0.05));
        let mut c = controller(&emu);
        let (plan, config) = fast_pick_plan();
        let outcome = execute_pick(&mut c, &plan, &config).expect("pick");
        let PickOutcome::Placed { held_width_m } = outcome else {
            panic!("{outcome:?}")
        };
        assert!((held_width_m - 0.05).abs() < 0.002, "{held_width_m}");
        let Some(Step::MoveJ { joints, .. }) = plan.steps.last() else {
            panic!("retreat")
        };
        let q = emu.joints();
        assert!(
            (0..6).all(|i| (q[i] - joints[i]).abs() < 1e-3),
            "{q:?} vs {joints:?}"
        );
    }

    #[test]
    fn an_empty_grasp_stops_at_the_object() {
        let emu = emulator();
        emu.set_object_width(None);
        let mut c = controller(&emu);
        let (plan, config) = fast_pick_plan();
        assert_eq!(
            execute_pick(&mut c, &plan, &config).expect("pick"),
            PickOutcome::NoObject
        );
        // Left at the grasp (the approach's end), not lifted.
        let Step::MoveL { joints, .. } = &plan.steps[2] else {
            panic!("approach")
        };
        let q = emu.joints();
        assert!(
            (0..6).all(|i| (q[i] - joints[i]).abs() < 1e-3),
            "{q:?} vs {joints:?}"
        );
        std::thread::sleep(Duration::from_millis(100));
        assert_eq!(emu.joints(), q, "and it stays there");
    }

    #[test]
    fn a_dropped_rtde_link_mid_pick_stops_the_arm() {
        let emu = emulator();
        let mut c = controller(&emu);
        let (plan, config) = fast_pick_plan();
        let err = std::thread::scope(|s| {
            s.spawn(|| {
                // Once the arm is on its way.
                let start = Instant::now();
                while emu.joints() == HOME && start.elapsed() < Duration::from_secs(5) {
                    std::thread::sleep(Duration::from_millis(2));
                }
                std::thread::sleep(Duration::from_millis(30));
                emu.faults().drop_rtde.store(true, Ordering::Relaxed);
            });
            execute_pick(&mut c, &plan, &config).expect_err("the link dropped")
        });
        assert!(
            matches!(&err, Error::Controller(m) if m.contains("RTDE link lost mid-motion") && m.contains("stopj sent")),
            "{err}"
        );
        // stopj decelerates: the arm comes to rest within a second, and stays.
        let start = Instant::now();
        let mut q = emu.joints();
        loop {
            std::thread::sleep(Duration::from_millis(50));
            let now = emu.joints();
            if now == q || start.elapsed() > Duration::from_secs(1) {
                break;
            }
            q = now;
        }
        std::thread::sleep(Duration::from_millis(200));
        assert_eq!(emu.joints(), q, "the arm stopped with the link");
        let first_motion = plan
            .steps
            .iter()
            .find_map(|s| match s {
                Step::MoveJ { joints, .. } | Step::MoveL { joints, .. } => Some(*joints),
                Step::Gripper { .. } => None,
            })
            .expect("a motion");
        assert!(
            q != HOME && (0..6).any(|i| (q[i] - first_motion[i]).abs() > 1e-3),
            "stopped on the way, not at the waypoint: {q:?}"
        );
    }

    #[test]
    fn no_motion_goes_out_over_a_link_that_is_down() {
        let emu = emulator();
        let mut c = controller(&emu);
        let (plan, config) = fast_pick_plan();
        // Down while the gripper opens, before the first motion.
        emu.faults().drop_rtde.store(true, Ordering::Relaxed);
        let err = execute_pick(&mut c, &plan, &config).expect_err("the link is down");
        assert!(
            matches!(&err, Error::Controller(m) | Error::Io(m) if m.contains("RTDE")),
            "{err}"
        );
        std::thread::sleep(Duration::from_millis(200));
        assert_eq!(emu.joints(), HOME, "nothing was sent");
    }

    #[test]
    fn a_gripper_that_does_not_move_ends_the_pick_with_the_arm_still() {
        let emu = emulator();
        let mut c = controller(&emu);
        let (plan, config) = fast_pick_plan();
        emu.faults().gripper_stalled.store(true, Ordering::Relaxed);
        let err = execute_pick(&mut c, &plan, &config).expect_err("stalled");
        assert!(
            matches!(&err, Error::Controller(m) if m.contains("gripper") && m.contains("did not end in time")),
            "{err}"
        );
        let q = emu.joints();
        std::thread::sleep(Duration::from_millis(100));
        assert_eq!(emu.joints(), q, "nothing moves after the gripper failed");
        let Some(Step::MoveJ { joints: last, .. }) = plan.steps.last() else {
            panic!("retreat")
        };
        assert!(
            (0..6).any(|i| (q[i] - last[i]).abs() > 1e-3),
            "the pick did not go on"
        );
    }

    #[test]
    fn a_protective_stop_mid_pick_ends_it_stopped() {
        let emu = emulator();
        let mut c = controller(&emu);
        let (plan, config) = fast_pick_plan();
        std::thread::scope(|s| {
            s.spawn(|| {
                std::thread::sleep(Duration::from_millis(150));
                emu.faults().protective_stop.store(true, Ordering::Relaxed);
            });
            let err = execute_pick(&mut c, &plan, &config).expect_err("stopped");
            assert!(matches!(&err, Error::ProtectiveStop { safety_mode: 3 }), "{err}");
        });
        let q = emu.joints();
        std::thread::sleep(Duration::from_millis(100));
        assert_eq!(emu.joints(), q, "nothing moves after the stop");
        // Recovery through the dashboard, when configured to: unlocked, still in place.
        let status =
            robot_bridge::dashboard::unlock_protective_stop(emu.dashboard_address, Duration::ZERO, TIMEOUT)
                .expect("dashboard");
        assert_eq!(emu.joints(), q, "unlocking moves nothing");
        assert_eq!(status, "Safetystatus: NORMAL");
    }
}

mod from_files {
    use super::*;
    use robot_bridge::execute::{Controller, PickOutcome, execute_pick};
    use robot_bridge::gripper::Gripper;
    use robot_bridge::planner::{load_scene, plan_locally, plan_remotely};

    fn sample(file: &str) -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../samples/table6")
            .join(file)
    }

    /// With the cell's approach cone the planner offers only approaches
    /// within it (here: from above within 20 degrees).
    #[test]
    fn the_planner_is_asked_for_the_cells_approaches_only() {
        let scene = load_scene(&sample("depth.png"), &sample("camera.json")).expect("sample scene");
        let cone =
            mvgrasp_core::ApproachCone::new(Vector3::new(0.0, 0.0, -1.0), 20f64.to_radians()).expect("cone");
        let planned = plan_locally(&scene, 50, Some(cone)).expect("planned");
        assert!(!planned.grasps.is_empty());
        for g in &planned.grasps {
            let approach = g.world_from_grasp.rotation * Vector3::z();
            assert!(approach.z <= -(20f64.to_radians().cos()) + 1e-9, "{approach:?}");
        }
    }

    /// The committed sample frame -> in-process planner -> collision-checked
    /// pick -> run on the emulator: the object is placed.
    #[test]
    fn the_sample_scene_is_picked_end_to_end() {
        let scene = load_scene(&sample("depth.png"), &sample("camera.json")).expect("sample scene");
        assert_eq!((scene.width, scene.height), (640, 480));
        let planned = plan_locally(&scene, 10, None).expect("planned");
        assert_eq!(planned.objects.len(), 6);
        assert!(!planned.grasps.is_empty());
        // The documented defaults (base, drop pose, basket obstacle), faster for the test.
        let mut config = robot_bridge::config::BridgeConfig::default()
            .pick_config()
            .expect("config");
        assert_eq!(config.obstacles.len(), 1, "the basket");
        config.obstacles.push(planned.table.clone());
        config.joint_speed = 3.0;
        config.tool_speed = 0.5;
        let plan = plan_pick(
            &Ur5e::default(),
            &config,
            &planned.grasps,
            &planned.objects,
            &HOME,
        )
        .expect("plan");
        let emu = emulator();
        let mut gripper = Gripper::connect(emu.gripper_address, 0.14, TIMEOUT).expect("gripper");
        gripper.activate().expect("activate");
        let mut controller = Controller {
            rtde: RtdeClient::connect(emu.rtde_address, 125.0, TIMEOUT).expect("rtde"),
            script_address: emu.script_address,
            gripper,
            io_timeout: TIMEOUT,
            motion_timeout: Duration::from_secs(10),
        };
        let outcome = execute_pick(&mut controller, &plan, &config).expect("pick");
        assert!(matches!(outcome, PickOutcome::Placed { .. }), "{outcome:?}");
    }

    #[test]
    fn missing_or_bad_files_name_the_problem() {
        let err = load_scene(&sample("nope.png"), &sample("camera.json")).expect_err("missing");
        assert!(err.to_string().contains("nope.png"), "{err}");
        let dir = std::env::temp_dir().join(format!("rb-bad-camera-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let bad = dir.join("camera.json");
        std::fs::write(
            &bad,
            r#"{"intrinsics": {"fx": 600, "fy": 600, "cx": 320},
                "world_from_camera": {"position": [0, 0, 1], "orientation": [1, 0, 0, 0]}}"#,
        )
        .expect("write");
        let err = load_scene(&sample("depth.png"), &bad).expect_err("bad camera");
        assert!(err.to_string().contains("intrinsics.cy"), "{err}");
    }

    /// The service (baseline backend) plans exactly what the in-process
    /// planner plans: same pipeline, same network, over gRPC.
    #[test]
    fn the_service_plans_what_the_in_process_planner_plans() {
        let runtime = tokio::runtime::Runtime::new().expect("runtime");
        let mut settings = mvgrasp_server::Settings {
            listen: "127.0.0.1:0".parse().expect("address"),
            metrics_listen: None,
            ..Default::default()
        };
        settings.model.backend = mvgrasp_server::BackendKind::Baseline;
        let server = runtime.block_on(mvgrasp_server::start(settings)).expect("server");
        let scene = load_scene(&sample("depth.png"), &sample("camera.json")).expect("sample scene");
        let local = plan_locally(&scene, 10, None).expect("local");
        let remote = plan_remotely(
            &format!("http://{}", server.addr),
            &Default::default(),
            &scene,
            10,
            None,
            TIMEOUT,
        )
        .expect("remote");
        assert!(remote.planner.contains("baseline-moments"), "{}", remote.planner);
        assert_eq!(remote.grasps.len(), local.grasps.len());
        assert!(!remote.grasps.is_empty());
        for (r, l) in remote.grasps.iter().zip(&local.grasps) {
            let d = r.world_from_grasp.inverse() * l.world_from_grasp;
            assert!(d.translation.vector.norm() < 1e-9 && d.rotation.angle() < 1e-9);
            assert_eq!((r.width_m, r.quality, r.object), (l.width_m, l.quality, l.object));
        }
        assert_eq!(remote.objects.len(), 6);
        for (r, l) in remote.objects.iter().zip(&local.objects) {
            assert!((r.half_extents_m - l.half_extents_m).norm() < 1e-9);
            assert!(
                (r.world_from_box.translation.vector - l.world_from_box.translation.vector).norm() < 1e-9
            );
        }
        assert!(
            (remote.table.world_from_box.translation.vector - local.table.world_from_box.translation.vector)
                .norm()
                < 1e-9
        );
        runtime.block_on(server.shutdown()).expect("shutdown");
    }

    #[test]
    fn a_planner_that_is_down_is_a_clear_error() {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("free port")
            .port();
        let scene = load_scene(&sample("depth.png"), &sample("camera.json")).expect("sample scene");
        let endpoint = format!("http://127.0.0.1:{port}");
        let err = plan_remotely(&endpoint, &Default::default(), &scene, 10, None, TIMEOUT)
            .expect_err("nothing listens there");
        assert!(
            matches!(err, Error::Io(_)) && err.to_string().contains(&endpoint),
            "{err}"
        );
    }

    #[test]
    fn a_planner_that_asks_for_a_token_gets_the_configured_one() {
        let runtime = tokio::runtime::Runtime::new().expect("runtime");
        let dir = std::env::temp_dir().join(format!("rb-token-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        std::fs::write(dir.join("token"), "cell-4-token\n").expect("write");
        let mut settings = mvgrasp_server::Settings {
            listen: "127.0.0.1:0".parse().expect("address"),
            metrics_listen: None,
            ..Default::default()
        };
        settings.model.backend = mvgrasp_server::BackendKind::Baseline;
        settings.security.bearer_token_file = Some(dir.join("token"));
        let server = runtime.block_on(mvgrasp_server::start(settings)).expect("server");
        let endpoint = format!("http://{}", server.addr);
        let scene = load_scene(&sample("depth.png"), &sample("camera.json")).expect("sample scene");
        let err =
            plan_remotely(&endpoint, &Default::default(), &scene, 10, None, TIMEOUT).expect_err("no token");
        assert!(err.to_string().contains("Bearer"), "{err}");
        let config: robot_bridge::config::BridgeConfig = toml::from_str(&format!(
            "[planner]\nendpoint = \"{endpoint}\"\ntoken_file = \"{}\"\n",
            dir.join("token").display()
        ))
        .expect("config");
        let credentials = config.planner_credentials().expect("credentials");
        let planned =
            plan_remotely(&endpoint, &credentials, &scene, 10, None, TIMEOUT).expect("with the token");
        assert_eq!(planned.objects.len(), 6);
        runtime.block_on(server.shutdown()).expect("shutdown");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_planner_that_does_not_answer_is_a_clear_error_within_the_deadline() {
        // Accepts connections and never says a word.
        let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
        let port = listener.local_addr().expect("address").port();
        std::thread::spawn(move || {
            let held: Vec<_> = listener.incoming().collect();
            drop(held);
        });
        let scene = load_scene(&sample("depth.png"), &sample("camera.json")).expect("sample scene");
        let endpoint = format!("http://127.0.0.1:{port}");
        let start = Instant::now();
        let err =
            plan_remotely(&endpoint, &Default::default(), &scene, 10, None, TIMEOUT).expect_err("no answer");
        let waited = start.elapsed();
        assert!(err.to_string().contains(&endpoint), "{err}");
        assert!(
            waited < TIMEOUT * 3,
            "gave up after {waited:?}, deadline {TIMEOUT:?}"
        );
    }

    #[test]
    fn the_cli_reads_its_config_and_names_a_bad_key() {
        let dir = std::env::temp_dir().join(format!("rb-config-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let good = dir.join("bridge.toml");
        std::fs::write(&good, "[pick]\npregrasp_m = 0.12\n[robot]\ntool_speed = 0.05\n").expect("write");
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_robot-bridge"))
            .args(["pick", "--dry-run", "--depth"])
            .arg(sample("depth.png"))
            .arg("--camera")
            .arg(sample("camera.json"))
            .arg("--config")
            .arg(&good)
            .output()
            .expect("runs");
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        assert!(
            stdout.contains("movel(") && stdout.contains("v=0.050)"),
            "{stdout}"
        );
        let bad = dir.join("bad.toml");
        std::fs::write(&bad, "[robot]\njoint_speed = 7.0\n").expect("write");
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_robot-bridge"))
            .args(["pick", "--dry-run", "--depth"])
            .arg(sample("depth.png"))
            .arg("--camera")
            .arg(sample("camera.json"))
            .arg("--config")
            .arg(&bad)
            .output()
            .expect("runs");
        assert!(!out.status.success());
        assert!(String::from_utf8_lossy(&out.stderr).contains("robot.joint_speed"));
    }

    #[test]
    fn the_cli_dry_run_prints_a_script() {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_robot-bridge"))
            .args(["pick", "--dry-run", "--depth"])
            .arg(sample("depth.png"))
            .arg("--camera")
            .arg(sample("camera.json"))
            .output()
            .expect("run the CLI");
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{stdout}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            stdout.contains("6 objects") && stdout.contains("def mvgrasp_pick():"),
            "{stdout}"
        );
    }
}
