//! URScript over the secondary interface (port 30002).

use std::io::Write;
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use crate::error::{Error, Result};

/// Sends a URScript program; the controller runs it on receipt.
pub fn send_script(address: impl ToSocketAddrs, program: &str, timeout: Duration) -> Result<()> {
    let address = address
        .to_socket_addrs()
        .map_err(|e| Error::Io(format!("script address: {e}")))?
        .next()
        .ok_or_else(|| Error::Io("script address resolves to nothing".to_owned()))?;
    let mut stream = TcpStream::connect_timeout(&address, timeout)
        .map_err(|e| Error::Io(format!("script connect {address}: {e}")))?;
    stream
        .set_write_timeout(Some(timeout))
        .map_err(|e| Error::Io(e.to_string()))?;
    let mut text = program.to_owned();
    if !text.ends_with('\n') {
        text.push('\n');
    }
    stream
        .write_all(text.as_bytes())
        .map_err(|e| Error::Io(format!("script send: {e}")))
}
