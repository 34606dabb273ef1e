//! The emulator's dashboard server: a greeting, then one answer per command.

use std::net::TcpStream;
use std::sync::atomic::Ordering;

use super::Shared;

/// Serves one client line by line.
pub(super) fn serve(stream: TcpStream, shared: &Shared) {
    super::serve_lines(
        stream,
        shared,
        Some("Connected: Universal Robots Dashboard Server"),
        |command| match command {
            "robotmode" => "Robotmode: RUNNING".to_owned(),
            "safetystatus" | "safetymode" => {
                let stopped = shared.robot().safety_mode == 3;
                format!(
                    "Safetystatus: {}",
                    if stopped { "PROTECTIVE_STOP" } else { "NORMAL" }
                )
            }
            "unlock protective stop" => {
                shared.faults.protective_stop.store(false, Ordering::Relaxed);
                shared.robot().safety_mode = 1;
                "Protective stop releasing".to_owned()
            }
            "close safety popup" => "closing safety popup".to_owned(),
            "stop" => {
                shared.robot().motions.clear();
                "Stopped".to_owned()
            }
            other => format!("could not understand: '{other}'"),
        },
    );
}
