//! Executing planned picks on the emulated controller and gripper: outcomes, stops, recovery.

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

/// An emulator whose gripper closes on an object `object_width_m` wide
/// (`None`: nothing there), and a controller connected to it.
fn emulated(object_width_m: Option<f64>) -> (Emulator, Controller) {
    let emu = emulator();
    emu.set_object_width(object_width_m);
    let c = controller(&emu);
    (emu, c)
}

/// The arm at `joints` (within 1e-3 rad each).
fn at(q: &Joints, joints: &Joints) -> bool {
    (0..6).all(|i| (q[i] - joints[i]).abs() < 1e-3)
}

#[test]
fn a_pick_with_an_object_is_placed() {
    let (emu, mut c) = emulated(Some(0.05));
    let (plan, config) = fast_pick_plan();
    let outcome = execute_pick(&mut c, &plan, &config).expect("pick");
    let PickOutcome::Placed { held_width_m } = outcome else {
        panic!("{outcome:?}")
    };
    assert!((held_width_m - 0.05).abs() < 0.002, "{held_width_m}");
    let (q, retreat) = (emu.joints(), final_joints(&plan));
    assert!(at(&q, &retreat), "{q:?} vs {retreat:?}");
}

/// The descent before the release is a guarded move: with a surface under
/// the tool it ends there (the chunk is done when the program is), the
/// object is let go and the pick goes on; with none it runs to its end.
#[test]
fn the_descent_into_the_basket_stops_on_contact() {
    let (plan, config) = fast_pick(PickConfig {
        release_lowest_z_m: Some(0.1),
        ..PickConfig::default()
    });
    assert!(plan.steps.iter().any(|s| matches!(
        s,
        Step::MoveL {
            until_contact: true,
            ..
        }
    )));
    for surface in [Some(0.25), None] {
        let (emu, mut c) = emulated(Some(0.05));
        emu.set_contact_height(surface);
        let outcome = execute_pick(&mut c, &plan, &config).expect("pick");
        assert!(matches!(outcome, PickOutcome::Placed { .. }), "{outcome:?}");
        assert!(at(&emu.joints(), &final_joints(&plan)), "retreated");
        // The one guarded move (the descent), where the emulator ended it.
        let ends = emu.guarded_move_ends();
        assert_eq!(ends.len(), 1, "{ends:?}");
        match surface {
            Some(z) => assert!((ends[0] - z).abs() < 0.01, "stopped at {} on {z}", ends[0]),
            None => assert!((ends[0] - 0.1).abs() < 0.005, "went down to {}", ends[0]),
        }
    }
}

/// The joints a plan ends at.
fn final_joints(plan: &robot_bridge::pick::PickPlan) -> Joints {
    match plan.steps.last() {
        Some(Step::MoveJ { joints, .. }) => *joints,
        other => panic!("{other:?}"),
    }
}

#[test]
fn an_empty_grasp_stops_at_the_object() {
    let (emu, mut c) = emulated(None);
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
    assert!(at(&q, joints), "{q:?} vs {joints:?}");
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(emu.joints(), q, "and it stays there");
}

#[test]
fn an_object_lost_on_the_way_is_not_let_go_of_over_the_basket() {
    let (emu, mut c) = emulated(Some(0.05));
    let (plan, config) = fast_pick_plan();
    let Step::MoveL { joints: at_grasp, .. } = plan.steps[2].clone() else {
        panic!("approach")
    };
    let outcome = std::thread::scope(|s| {
        s.spawn(|| {
            // Once the arm leaves the grasp with the object, it slips out.
            let start = Instant::now();
            while !at(&emu.joints(), &at_grasp) && start.elapsed() < Duration::from_secs(5) {
                std::thread::sleep(Duration::from_millis(1));
            }
            while at(&emu.joints(), &at_grasp) && start.elapsed() < Duration::from_secs(10) {
                std::thread::sleep(Duration::from_millis(1));
            }
            emu.set_object_width(None);
        });
        execute_pick(&mut c, &plan, &config).expect("pick")
    });
    assert_eq!(outcome, PickOutcome::Lost);
    assert!(outcome.empty_handed() && PickOutcome::NoObject.empty_handed());
    assert!(!PickOutcome::Placed { held_width_m: 0.05 }.empty_handed());
    // Stopped over the basket, before the release.
    let release = plan
        .steps
        .iter()
        .position(|s| matches!(s, Step::Gripper { name: "release", .. }))
        .expect("release");
    let Step::MoveJ { joints: over, .. } = &plan.steps[release - 1] else {
        panic!("over the basket: {:?}", plan.steps[release - 1])
    };
    let q = emu.joints();
    assert!(at(&q, over), "{q:?} vs {over:?}");
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
