//! The emulator's dashboard server: a greeting, then one answer per command.

use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::sync::atomic::Ordering;
use std::time::Duration;

use super::Shared;

/// Serves one client line by line.
pub(super) fn serve(stream: TcpStream, shared: &Shared) {
    let _ = stream.set_read_timeout(Some(Duration::from_millis(50)));
    let Ok(mut writer) = stream.try_clone() else {
        return;
    };
    if writer
        .write_all(b"Connected: Universal Robots Dashboard Server\n")
        .is_err()
    {
        return;
    }
    let mut reader = BufReader::new(stream);
    let mut line = String::new();
    while !shared.should_close() {
        line.clear();
        match reader.read_line(&mut line) {
            Ok(0) => return,
            Ok(_) => {}
            Err(_) => continue,
        }
        let command = line.trim();
        let reply = match command {
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
        };
        if writer.write_all(format!("{reply}\n").as_bytes()).is_err() {
            return;
        }
    }
}
