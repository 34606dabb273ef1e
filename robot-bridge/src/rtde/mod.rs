//! RTDE (Real-Time Data Exchange, port 30004), protocol version 2: the
//! packet codec, the variable types, and a client that reads robot state.
//!
//! A packet is `u16 size (header included) | u8 type | payload`, big-endian.

mod client;

pub use client::{RobotState, RtdeClient, STATE_VARIABLES};

use std::io::{Read, Write};

use crate::error::{Error, Result};

/// Packet types used here.
pub mod packet {
    /// Request a protocol version (`u16`); answered with `u8` accepted.
    pub const REQUEST_PROTOCOL_VERSION: u8 = b'V';
    /// Controller version; answered with four `u32`.
    pub const GET_URCONTROL_VERSION: u8 = b'v';
    /// A text message.
    pub const TEXT_MESSAGE: u8 = b'M';
    /// One data package of a recipe.
    pub const DATA_PACKAGE: u8 = b'U';
    /// Output recipe: `f64` frequency, comma-separated names; answered with `u8` id and types.
    pub const SETUP_OUTPUTS: u8 = b'O';
    /// Input recipe: comma-separated names; answered with `u8` id and types.
    pub const SETUP_INPUTS: u8 = b'I';
    /// Start the data stream; answered with `u8` accepted.
    pub const START: u8 = b'S';
    /// Pause the data stream; answered with `u8` accepted.
    pub const PAUSE: u8 = b'P';
}

/// The RTDE variable types this crate reads and writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VarType {
    /// Six `f64`.
    Vector6D,
    /// `f64`.
    Double,
    /// `i32`.
    Int32,
    /// `u32`.
    Uint32,
}

impl VarType {
    /// The name RTDE uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::Vector6D => "VECTOR6D",
            Self::Double => "DOUBLE",
            Self::Int32 => "INT32",
            Self::Uint32 => "UINT32",
        }
    }

    /// Parses an RTDE type name.
    pub fn parse(name: &str) -> Option<Self> {
        [Self::Vector6D, Self::Double, Self::Int32, Self::Uint32]
            .into_iter()
            .find(|t| t.name() == name)
    }

    /// Encoded size in bytes.
    pub fn size(self) -> usize {
        match self {
            Self::Vector6D => 48,
            Self::Double => 8,
            Self::Int32 | Self::Uint32 => 4,
        }
    }
}

/// Largest packet accepted (bytes); RTDE's size field is a `u16`.
pub const MAX_PACKET: usize = u16::MAX as usize;

/// Writes one packet.
pub fn write_packet(stream: &mut impl Write, kind: u8, payload: &[u8]) -> Result<()> {
    let size = payload.len() + 3;
    if size > MAX_PACKET {
        return Err(Error::Protocol(format!(
            "RTDE packet of {size} bytes is too large"
        )));
    }
    let mut bytes = Vec::with_capacity(size);
    bytes.extend_from_slice(&(size as u16).to_be_bytes());
    bytes.push(kind);
    bytes.extend_from_slice(payload);
    stream
        .write_all(&bytes)
        .map_err(|e| Error::Io(format!("RTDE write: {e}")))
}

/// Reads one packet: its type and payload.
pub fn read_packet(stream: &mut impl Read) -> Result<(u8, Vec<u8>)> {
    let mut header = [0u8; 3];
    stream
        .read_exact(&mut header)
        .map_err(|e| Error::Io(format!("RTDE read: {e}")))?;
    let size = usize::from(u16::from_be_bytes([header[0], header[1]]));
    if size < 3 {
        return Err(Error::Protocol(format!(
            "RTDE packet size {size} is below the header size"
        )));
    }
    let mut payload = vec![0u8; size - 3];
    stream
        .read_exact(&mut payload)
        .map_err(|e| Error::Io(format!("RTDE read: {e}")))?;
    Ok((header[2], payload))
}

/// A cursor over a payload that fails with a protocol error when short.
pub struct Reader<'a> {
    bytes: &'a [u8],
}

impl<'a> Reader<'a> {
    /// Reads `bytes` from the start.
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes }
    }

    fn take<const N: usize>(&mut self) -> Result<[u8; N]> {
        if self.bytes.len() < N {
            return Err(Error::Protocol(format!(
                "RTDE payload ends early: {N} bytes needed, {} left",
                self.bytes.len()
            )));
        }
        let (head, rest) = self.bytes.split_at(N);
        self.bytes = rest;
        let mut out = [0u8; N];
        out.copy_from_slice(head);
        Ok(out)
    }

    /// A `u8`.
    pub fn u8(&mut self) -> Result<u8> {
        Ok(self.take::<1>()?[0])
    }

    /// A big-endian `u16`.
    pub fn u16(&mut self) -> Result<u16> {
        Ok(u16::from_be_bytes(self.take()?))
    }

    /// A big-endian `u32`.
    pub fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_be_bytes(self.take()?))
    }

    /// A big-endian `i32`.
    pub fn i32(&mut self) -> Result<i32> {
        Ok(i32::from_be_bytes(self.take()?))
    }

    /// A big-endian `f64`.
    pub fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_be_bytes(self.take()?))
    }

    /// The rest as UTF-8 text.
    pub fn rest_str(&mut self) -> Result<String> {
        let text = std::str::from_utf8(self.bytes).map_err(|e| Error::Protocol(format!("RTDE text: {e}")))?;
        self.bytes = &[];
        Ok(text.to_owned())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packet_round_trip_and_short_reads() {
        let mut wire = Vec::new();
        write_packet(&mut wire, packet::SETUP_OUTPUTS, b"abc").unwrap();
        assert_eq!(wire, [0, 6, b'O', b'a', b'b', b'c']);
        let (kind, payload) = read_packet(&mut wire.as_slice()).unwrap();
        assert_eq!((kind, payload.as_slice()), (b'O', b"abc".as_slice()));
        assert!(matches!(
            read_packet(&mut [0u8, 9, b'O', 1].as_slice()),
            Err(Error::Io(_))
        ));
        assert!(matches!(
            read_packet(&mut [0u8, 2, b'O'].as_slice()),
            Err(Error::Protocol(_))
        ));
        assert!(matches!(Reader::new(&[1, 2]).u32(), Err(Error::Protocol(_))));
    }
}
