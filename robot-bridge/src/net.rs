//! The one way the bridge opens a TCP connection: resolve, connect with a
//! timeout, and put the same timeout on every read and write.

use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use crate::error::{Error, Result};

/// Connects to `address` for `what` (named in errors, e.g. "RTDE").
pub(crate) fn connect(address: impl ToSocketAddrs, timeout: Duration, what: &str) -> Result<TcpStream> {
    let address = address
        .to_socket_addrs()
        .map_err(|e| Error::Io(format!("{what} address: {e}")))?
        .next()
        .ok_or_else(|| Error::Io(format!("{what} address resolves to nothing")))?;
    let stream = TcpStream::connect_timeout(&address, timeout)
        .map_err(|e| Error::Io(format!("{what} connect {address}: {e}")))?;
    stream
        .set_read_timeout(Some(timeout))
        .map_err(|e| Error::Io(format!("{what}: {e}")))?;
    stream
        .set_write_timeout(Some(timeout))
        .map_err(|e| Error::Io(format!("{what}: {e}")))?;
    stream
        .set_nodelay(true)
        .map_err(|e| Error::Io(format!("{what}: {e}")))?;
    Ok(stream)
}
