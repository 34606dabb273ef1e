//! A planned pick as the URScript program the controller runs.

use nalgebra::Isometry3;

use super::{PickConfig, PickPlan, Step};
use crate::ur5e::Joints;

/// The arm's part of a pick as a URScript program (gripper steps become
/// comments: the gripper is driven over its own socket).
pub fn urscript(plan: &PickPlan, config: &PickConfig) -> String {
    let t = config.flange_from_tcp;
    let mut out = String::from("def mvgrasp_pick():\n");
    out.push_str(&format!("  set_tcp({})\n", pose_literal(&t)));
    for step in &plan.steps {
        match step {
            Step::MoveJ { name, joints } => out.push_str(&format!(
                "  # {name}\n  movej({}, a={:.3}, v={:.3})\n",
                joints_literal(joints),
                config.joint_accel,
                config.joint_speed
            )),
            Step::MoveL {
                name,
                base_from_tcp,
                until_contact: false,
                ..
            } => out.push_str(&format!(
                "  # {name}\n  movel({}, a={:.3}, v={:.3})\n",
                pose_literal(base_from_tcp),
                config.tool_accel,
                config.tool_speed
            )),
            // The line runs in a thread while the program watches the tool's
            // contact detection along the motion, and stops the arm there.
            Step::MoveL {
                name,
                base_from_tcp,
                until_contact: true,
                ..
            } => out.push_str(&format!(
                "  # {name}, until the tool meets something\n\
                 \x20 global mvgrasp_line_done = False\n\
                 \x20 thread mvgrasp_line():\n\
                 \x20   movel({}, a={:.3}, v={:.3})\n\
                 \x20   mvgrasp_line_done = True\n\
                 \x20 end\n\
                 \x20 mvgrasp_line_thread = run mvgrasp_line()\n\
                 \x20 while not mvgrasp_line_done and tool_contact(direction=get_target_tcp_speed()) == 0:\n\
                 \x20   sync()\n\
                 \x20 end\n\
                 \x20 kill mvgrasp_line_thread\n\
                 \x20 stopl({:.3})\n",
                pose_literal(base_from_tcp),
                config.tool_accel,
                config.tool_speed,
                config.tool_accel
            )),
            Step::Gripper { name, close, width_m } => {
                let action = if *close {
                    "close".to_owned()
                } else {
                    format!("open to {:.0} mm", width_m * 1000.0)
                };
                out.push_str(&format!(
                    "  # gripper: {name} ({action}), sent on the gripper socket\n"
                ));
            }
        }
    }
    out.push_str("end\n");
    out
}

fn joints_literal(q: &Joints) -> String {
    format!(
        "[{}]",
        q.iter().map(|v| format!("{v:.6}")).collect::<Vec<_>>().join(", ")
    )
}

/// URScript pose `p[x, y, z, rx, ry, rz]` (rotation vector).
fn pose_literal(pose: &Isometry3<f64>) -> String {
    let (p, r) = (pose.translation.vector, pose.rotation.scaled_axis());
    format!(
        "p[{:.6}, {:.6}, {:.6}, {:.6}, {:.6}, {:.6}]",
        p.x, p.y, p.z, r.x, r.y, r.z
    )
}
