//! The dashboard server (port 29999): one text command, one text answer.
//! Used only for recovery actions, and only when the bridge is configured to.

use std::io::{BufRead, BufReader, Write};
use std::net::ToSocketAddrs;
use std::time::Duration;

use crate::error::{Error, Result};

/// Sends one dashboard command (e.g. `safetystatus`, `unlock protective stop`)
/// and returns the controller's answer line.
pub fn dashboard_command(address: impl ToSocketAddrs, command: &str, timeout: Duration) -> Result<String> {
    let stream = crate::net::connect(address, timeout, "dashboard")?;
    let mut writer = stream.try_clone().map_err(|e| Error::Io(e.to_string()))?;
    let mut reader = BufReader::new(stream);
    let mut line = String::new();
    // The server greets first ("Connected: Universal Robots Dashboard Server").
    reader
        .read_line(&mut line)
        .map_err(|e| Error::Io(format!("dashboard greeting: {e}")))?;
    writer
        .write_all(format!("{command}\n").as_bytes())
        .map_err(|e| Error::Io(format!("dashboard send: {e}")))?;
    line.clear();
    match reader.read_line(&mut line) {
        Ok(0) => Err(Error::Io("dashboard closed the connection".to_owned())),
        Ok(_) => Ok(line.trim().to_owned()),
        Err(e) => Err(Error::Io(format!("dashboard reply to `{command}`: {e}"))),
    }
}

/// Recovery after a protective stop, for bridges configured to do it: waits
/// `wait` (the controller refuses an unlock within 5 s of the stop), sends
/// `unlock protective stop`, and returns the controller's `safetystatus`
/// afterwards. It moves nothing.
pub fn unlock_protective_stop(
    address: impl ToSocketAddrs + Copy,
    wait: Duration,
    timeout: Duration,
) -> Result<String> {
    std::thread::sleep(wait);
    let reply = dashboard_command(address, "unlock protective stop", timeout)?;
    if !reply.to_ascii_lowercase().contains("releasing") {
        return Err(Error::Controller(format!(
            "the dashboard refused the unlock: {reply}"
        )));
    }
    dashboard_command(address, "safetystatus", timeout)
}
