//! Robotiq 2F-140 through the Robotiq URCap's socket (port 63352): ASCII
//! `SET VAR value` (answered `ack`) and `GET VAR` (answered `VAR value`).

use std::io::{BufRead, BufReader, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use crate::error::{Error, Result};

/// How a gripper motion ended (the `OBJ` register).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GripOutcome {
    /// Stopped on contact while closing: an object is held (`OBJ 2`).
    Holding,
    /// Stopped on contact while opening (`OBJ 1`).
    ContactWhileOpening,
    /// Reached the requested position: nothing in between (`OBJ 3`).
    AtPosition,
}

/// The value of `var` in the gripper's answer to `GET var` (`"OBJ 2"`).
pub fn parse_get_reply(reply: &str, var: &str) -> Result<u32> {
    let mut parts = reply.split_whitespace();
    match (parts.next(), parts.next().map(str::parse::<u32>), parts.next()) {
        (Some(name), Some(Ok(value)), None) if name == var => Ok(value),
        _ => Err(Error::Protocol(format!(
            "gripper answered `{reply}` to GET {var}"
        ))),
    }
}

/// The opening of a 2F-140 for a position register value (0 = open 140 mm,
/// 255 = closed), linear; calibrate per gripper for better than a few mm.
pub fn width_of_position(position: u8, max_width_m: f64) -> f64 {
    max_width_m * (1.0 - f64::from(position) / 255.0)
}

/// The position register value for an opening (clamped to the stroke).
pub fn position_of_width(width_m: f64, max_width_m: f64) -> u8 {
    (255.0 * (1.0 - (width_m / max_width_m).clamp(0.0, 1.0))).round() as u8
}

/// A connected gripper.
pub struct Gripper {
    reader: BufReader<TcpStream>,
    writer: TcpStream,
    /// Full stroke (m): 0.14 for the 2F-140.
    pub max_width_m: f64,
    timeout: Duration,
}

impl Gripper {
    /// Connects; every exchange times out after `timeout`.
    pub fn connect(address: impl ToSocketAddrs, max_width_m: f64, timeout: Duration) -> Result<Self> {
        let stream = crate::net::connect(address, timeout, "gripper")?;
        let writer = stream.try_clone().map_err(|e| Error::Io(e.to_string()))?;
        Ok(Self {
            reader: BufReader::new(stream),
            writer,
            max_width_m,
            timeout,
        })
    }

    fn exchange(&mut self, line: &str) -> Result<String> {
        self.writer
            .write_all(format!("{line}\n").as_bytes())
            .map_err(|e| Error::Io(format!("gripper send: {e}")))?;
        let mut reply = String::new();
        match self.reader.read_line(&mut reply) {
            Ok(0) => Err(Error::Io("gripper closed the connection".to_owned())),
            Ok(_) => Ok(reply.trim().to_owned()),
            Err(e) => Err(Error::Io(format!("gripper reply to `{line}`: {e}"))),
        }
    }

    fn set(&mut self, var: &str, value: u32) -> Result<()> {
        let reply = self.exchange(&format!("SET {var} {value}"))?;
        if reply == "ack" {
            Ok(())
        } else {
            Err(Error::Protocol(format!(
                "gripper answered `{reply}` to SET {var}"
            )))
        }
    }

    fn get(&mut self, var: &str) -> Result<u32> {
        let reply = self.exchange(&format!("GET {var}"))?;
        parse_get_reply(&reply, var)
    }

    /// Activates the gripper and waits until it reports active (`STA 3`).
    pub fn activate(&mut self) -> Result<()> {
        self.set("ACT", 1)?;
        let start = Instant::now();
        while self.get("STA")? != 3 {
            if start.elapsed() > self.timeout * 5 {
                return Err(Error::Controller("gripper did not finish activating".to_owned()));
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        Ok(())
    }

    /// Whether the fingers still hold what they stopped on when closing
    /// (`OBJ 2`; an object that slipped out lets them go on to the
    /// requested position, `OBJ 3`).
    pub fn holding(&mut self) -> Result<bool> {
        Ok(self.get("OBJ")? == 2)
    }

    /// Moves to `width_m` with speed and force in 0..=255, waits for the
    /// motion to end, and says how it ended with the measured opening.
    pub fn move_to(&mut self, width_m: f64, speed: u8, force: u8) -> Result<(GripOutcome, f64)> {
        if !width_m.is_finite() {
            return Err(Error::InvalidInput {
                field: "width_m",
                reason: format!("{width_m}"),
            });
        }
        self.set("POS", u32::from(position_of_width(width_m, self.max_width_m)))?;
        self.set("SPE", u32::from(speed))?;
        self.set("FOR", u32::from(force))?;
        self.set("GTO", 1)?;
        let start = Instant::now();
        loop {
            let outcome = match self.get("OBJ")? {
                0 => None,
                1 => Some(GripOutcome::ContactWhileOpening),
                2 => Some(GripOutcome::Holding),
                _ => Some(GripOutcome::AtPosition),
            };
            if let Some(outcome) = outcome {
                let position = self.get("POS")?.min(255) as u8;
                return Ok((outcome, width_of_position(position, self.max_width_m)));
            }
            if start.elapsed() > self.timeout * 5 {
                return Err(Error::Controller("gripper motion did not end in time".to_owned()));
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn position_and_width_round_trip() {
        assert_eq!(position_of_width(0.14, 0.14), 0);
        assert_eq!(position_of_width(0.0, 0.14), 255);
        assert_eq!(position_of_width(0.5, 0.14), 0, "clamped to the stroke");
        for p in [0u8, 17, 128, 255] {
            assert_eq!(position_of_width(width_of_position(p, 0.14), 0.14), p);
        }
    }
}
