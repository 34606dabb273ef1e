//! The emulator's RTDE server (protocol 2).

use std::io::Write;
use std::net::TcpStream;
use std::sync::atomic::Ordering;
use std::time::Duration;

use super::Shared;
use crate::rtde::{Reader, VarType, packet, read_packet, write_packet};

/// Outputs the emulator knows, with their types.
const OUTPUTS: [(&str, VarType); 6] = [
    ("timestamp", VarType::Double),
    ("actual_q", VarType::Vector6D),
    ("actual_TCP_pose", VarType::Vector6D),
    ("robot_mode", VarType::Int32),
    ("safety_mode", VarType::Int32),
    ("runtime_state", VarType::Uint32),
];

/// Serves one client until it leaves, the emulator stops or connections drop.
pub(super) fn serve(mut stream: TcpStream, shared: &Shared) {
    let _ = stream.set_read_timeout(Some(Duration::from_millis(50)));
    let mut recipe: Vec<&str> = Vec::new();
    let mut period = Duration::from_millis(2);
    while !shared.should_close_rtde() {
        let Ok((kind, payload)) = read_packet(&mut stream) else {
            // A timeout just loops (to notice a stop); EOF or garbage ends the session.
            if stream.peek(&mut [0u8]).map(|n| n == 0).unwrap_or(false) {
                return;
            }
            continue;
        };
        let mut r = Reader::new(&payload);
        let reply: Vec<u8> = match kind {
            packet::REQUEST_PROTOCOL_VERSION => vec![u8::from(matches!(r.u16(), Ok(1 | 2)))],
            packet::GET_URCONTROL_VERSION => [5u32, 15, 0, 0].iter().flat_map(|v| v.to_be_bytes()).collect(),
            packet::SETUP_OUTPUTS => {
                let frequency = r.f64().unwrap_or(0.0);
                period = Duration::from_secs_f64(1.0 / frequency.clamp(1.0, 500.0));
                let text = r.rest_str().unwrap_or_default();
                // Clients such as ur_rtde end the list with a comma: empty names are skipped.
                let names: Vec<&str> = text.split(',').filter(|n| !n.is_empty()).collect();
                let in_use = shared.faults.recipe_in_use.load(Ordering::Relaxed);
                let types: Vec<&str> = names
                    .iter()
                    .map(|name| match OUTPUTS.iter().find(|(n, _)| n == name) {
                        _ if in_use => "IN_USE",
                        Some((_, t)) => t.name(),
                        None => "NOT_FOUND",
                    })
                    .collect();
                recipe = names
                    .iter()
                    .filter_map(|name| OUTPUTS.iter().find(|(n, _)| n == name).map(|(n, _)| *n))
                    .collect();
                let mut reply = vec![1u8];
                reply.extend_from_slice(types.join(",").as_bytes());
                reply
            }
            packet::SETUP_INPUTS => {
                let text = r.rest_str().unwrap_or_default();
                let count = text.split(',').filter(|n| !n.is_empty()).count();
                let mut reply = vec![0u8];
                reply.extend_from_slice(vec!["NOT_FOUND"; count].join(",").as_bytes());
                reply
            }
            packet::START => {
                if write_packet(&mut stream, packet::START, &[1]).is_ok() {
                    stream_state(&mut stream, shared, &recipe, period);
                }
                return;
            }
            packet::PAUSE => vec![1],
            _ => continue,
        };
        if write_packet(&mut stream, kind, &reply).is_err() {
            return;
        }
    }
}

/// Sends one data package per period until the client goes or connections drop.
fn stream_state(stream: &mut TcpStream, shared: &Shared, recipe: &[&str], period: Duration) {
    while !shared.should_close_rtde() {
        let mut payload = vec![1u8];
        {
            let robot = shared.robot();
            for name in recipe {
                match *name {
                    "timestamp" => {
                        payload.extend_from_slice(&robot.started.elapsed().as_secs_f64().to_be_bytes())
                    }
                    "actual_q" => robot
                        .q
                        .iter()
                        .for_each(|v| payload.extend_from_slice(&v.to_be_bytes())),
                    "actual_TCP_pose" => robot
                        .tcp_pose()
                        .iter()
                        .for_each(|v| payload.extend_from_slice(&v.to_be_bytes())),
                    "robot_mode" => payload.extend_from_slice(&7i32.to_be_bytes()),
                    "safety_mode" => payload.extend_from_slice(&robot.safety_mode.to_be_bytes()),
                    "runtime_state" => payload.extend_from_slice(&robot.runtime_state().to_be_bytes()),
                    _ => {}
                }
            }
        }
        if write_packet(stream, packet::DATA_PACKAGE, &payload).is_err() || stream.flush().is_err() {
            return;
        }
        std::thread::sleep(period);
    }
}
