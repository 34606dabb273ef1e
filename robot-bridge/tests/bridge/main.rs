//! The bridge against the controller emulator, on loopback: the RTDE link and
//! its recovery here; executing picks and planning from files in their own files.

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

use robot_bridge::ur5e::HOME;
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
    fast_pick(PickConfig::default())
}

/// `fast_pick_plan` from `settings` (its speeds replaced).
fn fast_pick(settings: PickConfig) -> (robot_bridge::pick::PickPlan, PickConfig) {
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
        ..settings
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

mod executor;
mod from_files;
