//! URScript over the secondary interface (port 30002).

use std::io::Write;
use std::net::ToSocketAddrs;
use std::time::Duration;

use crate::error::{Error, Result};

/// Sends a URScript program; the controller runs it on receipt.
pub fn send_script(address: impl ToSocketAddrs, program: &str, timeout: Duration) -> Result<()> {
    let mut stream = crate::net::connect(address, timeout, "script")?;
    let mut text = program.to_owned();
    if !text.ends_with('\n') {
        text.push('\n');
    }
    stream
        .write_all(text.as_bytes())
        .map_err(|e| Error::Io(format!("script send: {e}")))
}
