//! The emulator's script receiver: runs `set_tcp`, `movej`, `movel` (guarded
//! in the bridge's `mvgrasp_line` thread) and `stopj`.

use std::io::Read;
use std::net::TcpStream;
use std::time::Duration;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::{Motion, Shared};

/// Reads a program (until the sender closes or pauses) and queues its motions.
pub(super) fn serve(mut stream: TcpStream, shared: &Shared) {
    let _ = stream.set_read_timeout(Some(Duration::from_millis(200)));
    let mut text = Vec::new();
    let mut buffer = [0u8; 4096];
    while !shared.should_close() {
        match stream.read(&mut buffer) {
            Ok(0) => break,
            Ok(n) => text.extend_from_slice(&buffer[..n]),
            Err(_) if !text.is_empty() => break,
            Err(_) => {}
        }
    }
    let program = String::from_utf8_lossy(&text);
    let mut robot = shared.robot();
    if robot.safety_mode != 1 {
        return; // a stopped controller runs nothing
    }
    let mut last = robot.motions.back().map_or(robot.q, |m| m.target);
    // A `movel` in the bridge's guarded-line thread stops on tool contact.
    let mut guarded = false;
    for line in program.lines().map(str::trim) {
        if line.starts_with("thread mvgrasp_line(") {
            guarded = true;
        } else if line == "end" {
            guarded = false;
        }
        if line.starts_with("stopj(") {
            // A new program replaces the running one: this one stops the arm.
            robot.motions.clear();
        } else if line.starts_with("set_tcp(") {
            if let Some(p) = pose(line) {
                robot.flange_from_tcp = p;
            }
        } else if line.starts_with("movej(") {
            let values = numbers_in_brackets(line);
            if let (Ok(target), Some(speed)) = (<[f64; 6]>::try_from(values), named(line, "v=")) {
                robot.motions.push_back(Motion {
                    target,
                    speed: speed.max(1e-3),
                    guarded: false,
                });
                last = target;
            }
        } else if line.starts_with("movel(") {
            let (Some(base_from_tcp), Some(speed)) = (pose(line), named(line, "v=")) else {
                continue;
            };
            let flange = base_from_tcp * robot.flange_from_tcp.inverse();
            let Ok(target) = robot.arm.inverse_nearest(&flange, &last) else {
                continue;
            };
            // Joint speed that covers the TCP distance at the commanded tool speed.
            let from = robot.arm.forward(&last) * robot.flange_from_tcp;
            let distance = (from.translation.vector - base_from_tcp.translation.vector).norm();
            let largest = crate::ur5e::max_joint_move(&target, &last);
            let seconds = (distance / speed.max(1e-3)).max(1e-3);
            robot.motions.push_back(Motion {
                target,
                speed: (largest / seconds).max(1e-3),
                guarded,
            });
            last = target;
        }
    }
}

/// The numbers inside the first `[...]` of `line`.
fn numbers_in_brackets(line: &str) -> Vec<f64> {
    let (Some(a), Some(b)) = (line.find('['), line.find(']')) else {
        return Vec::new();
    };
    if b < a {
        return Vec::new();
    }
    line[a + 1..b]
        .split(',')
        .filter_map(|v| v.trim().parse().ok())
        .collect()
}

/// `p[x, y, z, rx, ry, rz]` on the line as a transform.
fn pose(line: &str) -> Option<Isometry3<f64>> {
    let v: [f64; 6] = numbers_in_brackets(line).try_into().ok()?;
    Some(Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        UnitQuaternion::from_scaled_axis(Vector3::new(v[3], v[4], v[5])),
    ))
}

/// The value after `key` (e.g. `v=0.5`).
fn named(line: &str, key: &str) -> Option<f64> {
    let start = line.find(key)? + key.len();
    let end = line[start..].find([',', ')']).map_or(line.len(), |e| start + e);
    line[start..end].trim().parse().ok()
}
