//! Runs a planned pick on a controller, watching its state the whole time.
//!
//! Arm motions go out as URScript in chunks between gripper actions; after
//! each chunk the executor waits on RTDE until the joints reach the chunk's
//! last waypoint. A protective stop, a dropped connection, a timeout, a
//! gripper that stalls or closes on nothing ends the pick right there with a
//! clear outcome, and no further motion is sent: the robot is left stopped,
//! never moving on a guess. A lost RTDE link or a timeout mid-motion also
//! sends `stopj`, since the controller would run the program on.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use crate::error::{Error, Result};
use crate::gripper::{GripOutcome, Gripper};
use crate::pick::{PickConfig, PickPlan, Step, urscript};
use crate::rtde::RtdeClient;
use crate::script::send_script;
use crate::ur5e::Joints;

/// The connections a pick needs.
pub struct Controller {
    /// Robot state stream.
    pub rtde: RtdeClient,
    /// Secondary interface (scripts).
    pub script_address: SocketAddr,
    /// The gripper.
    pub gripper: Gripper,
    /// Timeout for one connection exchange.
    pub io_timeout: Duration,
    /// Timeout for one chunk of arm motion.
    pub motion_timeout: Duration,
}

/// How a pick ended when nothing failed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PickOutcome {
    /// The object was carried to the basket and released.
    Placed {
        /// Opening measured when the gripper stopped on the object (m).
        held_width_m: f64,
    },
    /// The gripper closed on nothing; the arm stopped at the grasp.
    NoObject,
    /// The gripper held the object when it closed and nothing when it was
    /// to let go over the basket (it slipped out on the lift or the carry);
    /// the arm stopped over the basket.
    Lost,
}

impl PickOutcome {
    /// Whether the pick came up empty-handed: a grasp at the same spot on
    /// an unchanged scene is worth trying last (`PickConfig::order_after_failures`).
    pub fn empty_handed(&self) -> bool {
        matches!(self, Self::NoObject | Self::Lost)
    }
}

/// Gripper speed and force registers used for picks (0..=255).
const GRIP_SPEED: u8 = 128;
/// See [`GRIP_SPEED`].
const GRIP_FORCE: u8 = 100;
/// Joint tolerance for "arrived" (rad).
const ARRIVED_RAD: f64 = 1e-3;

/// Executes `plan`; see the module docs for what stops it.
pub fn execute_pick(
    controller: &mut Controller,
    plan: &PickPlan,
    config: &PickConfig,
) -> Result<PickOutcome> {
    let state = controller.rtde.next_state()?;
    if state.stopped_by_safety() || state.robot_mode != 7 {
        return Err(Error::Controller(format!(
            "robot not ready (robot mode {}, safety mode {}): nothing sent",
            state.robot_mode, state.safety_mode
        )));
    }
    let mut chunk: Vec<Step> = Vec::new();
    let mut held_width_m = 0.0;
    let mut closed_on_object = false;
    for step in &plan.steps {
        match step {
            Step::MoveJ { .. } | Step::MoveL { .. } => chunk.push(step.clone()),
            Step::Gripper { name, close, width_m } => {
                run_chunk(controller, &mut chunk, plan.grasp_index, config)?;
                let stalled =
                    |e: Error| Error::Controller(format!("gripper ({name}): {e}; the arm is still"));
                // Before letting go: is the object still there?
                if closed_on_object && !*close && !controller.gripper.holding().map_err(stalled)? {
                    return Ok(PickOutcome::Lost);
                }
                let target = if *close { 0.0 } else { *width_m };
                let (outcome, measured) = controller
                    .gripper
                    .move_to(target, GRIP_SPEED, GRIP_FORCE)
                    .map_err(stalled)?;
                match (close, outcome) {
                    (true, GripOutcome::Holding) => {
                        held_width_m = measured;
                        closed_on_object = true;
                    }
                    (true, _) => return Ok(PickOutcome::NoObject),
                    (false, GripOutcome::ContactWhileOpening) => {
                        return Err(Error::Controller(format!(
                            "gripper blocked while opening ({name})"
                        )));
                    }
                    (false, _) => {}
                }
            }
        }
    }
    run_chunk(controller, &mut chunk, plan.grasp_index, config)?;
    Ok(PickOutcome::Placed { held_width_m })
}

/// Sends the queued arm steps and waits until the last one is reached.
fn run_chunk(
    controller: &mut Controller,
    chunk: &mut Vec<Step>,
    grasp_index: usize,
    config: &PickConfig,
) -> Result<()> {
    let Some(target) = chunk.last().map(final_joints) else {
        return Ok(());
    };
    // A guarded move ends where the tool meets something: done when the
    // program is, wherever the arm stopped.
    let guarded = matches!(
        chunk.last(),
        Some(Step::MoveL {
            until_contact: true,
            ..
        })
    );
    let program = urscript(
        &PickPlan {
            grasp_index,
            steps: std::mem::take(chunk),
        },
        config,
    );
    // A fresh state first: no motion goes out over a link that is down or
    // to a controller that stopped.
    let before = controller
        .rtde
        .next_state()
        .map_err(|e| Error::Controller(format!("RTDE link lost before a motion ({e}): nothing sent")))?;
    if before.stopped_by_safety() {
        return Err(Error::ProtectiveStop {
            safety_mode: before.safety_mode,
        });
    }
    send_script(controller.script_address, &program, controller.io_timeout)?;
    let start = Instant::now();
    let mut started = false;
    loop {
        let state = match controller.rtde.next_state() {
            Ok(state) => state,
            // The controller runs the program on without the link: stop it
            // over the script interface, and say whether that worked.
            Err(lost) => {
                return Err(stop_after(
                    controller,
                    &format!("RTDE link lost mid-motion ({lost})"),
                ));
            }
        };
        if state.stopped_by_safety() {
            return Err(Error::ProtectiveStop {
                safety_mode: state.safety_mode,
            });
        }
        started |= state.runtime_state == 2;
        let arrived = (0..6).all(|i| (state.actual_q[i] - target[i]).abs() < ARRIVED_RAD);
        if arrived && (started || state.runtime_state == 1) || guarded && started && state.runtime_state == 1
        {
            return Ok(());
        }
        if start.elapsed() > controller.motion_timeout {
            return Err(stop_after(
                controller,
                &format!(
                    "motion did not reach its waypoint within {:.1} s",
                    controller.motion_timeout.as_secs_f64()
                ),
            ));
        }
    }
}

/// Stops whatever program runs (`stopj`) after `what` went wrong; no further
/// motion is sent. The error says whether the stop reached the controller.
fn stop_after(controller: &Controller, what: &str) -> Error {
    match send_script(controller.script_address, "stopj(2.0)\n", controller.io_timeout) {
        Ok(()) => Error::Controller(format!("{what}: arm stopped (stopj sent)")),
        Err(e) => Error::Controller(format!(
            "{what}: stopj could not be sent either ({e}); stop the arm at the pendant"
        )),
    }
}

fn final_joints(step: &Step) -> Joints {
    match step {
        Step::MoveJ { joints, .. } | Step::MoveL { joints, .. } => *joints,
        Step::Gripper { .. } => [f64::NAN; 6],
    }
}
