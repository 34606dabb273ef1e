//! An RTDE client that streams the robot state the bridge watches.

use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use super::{Reader, VarType, packet, read_packet, write_packet};
use crate::error::{Error, Result};
use crate::ur5e::Joints;

/// The output recipe the bridge asks for, in order.
pub const STATE_VARIABLES: [&str; 6] = [
    "timestamp",
    "actual_q",
    "actual_TCP_pose",
    "robot_mode",
    "safety_mode",
    "runtime_state",
];

/// The types RTDE gives [`STATE_VARIABLES`].
const STATE_TYPES: [VarType; 6] = [
    VarType::Double,
    VarType::Vector6D,
    VarType::Vector6D,
    VarType::Int32,
    VarType::Int32,
    VarType::Uint32,
];

/// One sample of the robot's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotState {
    /// Controller time (s).
    pub timestamp_s: f64,
    /// Joint positions (rad).
    pub actual_q: Joints,
    /// TCP pose in the base frame `[x, y, z, rx, ry, rz]` (m, rotation vector).
    pub actual_tcp_pose: [f64; 6],
    /// Robot mode (7 = running).
    pub robot_mode: i32,
    /// Safety mode (1 = normal, 3 = protective stop).
    pub safety_mode: i32,
    /// Program state (1 = stopped, 2 = playing).
    pub runtime_state: u32,
}

impl RobotState {
    /// True when a protective or emergency stop is active.
    pub fn stopped_by_safety(&self) -> bool {
        self.safety_mode != 1
    }
}

/// A connected RTDE session streaming [`STATE_VARIABLES`].
pub struct RtdeClient {
    stream: TcpStream,
    recipe_id: u8,
    /// The controller's version (major, minor, bugfix, build).
    pub controller_version: [u32; 4],
}

impl RtdeClient {
    /// Connects, negotiates protocol 2, sets up the state recipe at
    /// `frequency_hz` and starts the stream. Every read and write times out
    /// after `timeout`.
    pub fn connect(address: impl ToSocketAddrs, frequency_hz: f64, timeout: Duration) -> Result<Self> {
        let stream = crate::net::connect(address, timeout, "RTDE")?;
        let mut client = Self {
            stream,
            recipe_id: 0,
            controller_version: [0; 4],
        };

        let reply = client.request(packet::REQUEST_PROTOCOL_VERSION, &2u16.to_be_bytes())?;
        if Reader::new(&reply).u8()? != 1 {
            return Err(Error::Controller("RTDE protocol version 2 refused".to_owned()));
        }
        let reply = client.request(packet::GET_URCONTROL_VERSION, &[])?;
        let mut r = Reader::new(&reply);
        client.controller_version = [r.u32()?, r.u32()?, r.u32()?, r.u32()?];

        let mut setup = frequency_hz.to_be_bytes().to_vec();
        setup.extend_from_slice(STATE_VARIABLES.join(",").as_bytes());
        let reply = client.request(packet::SETUP_OUTPUTS, &setup)?;
        let mut r = Reader::new(&reply);
        client.recipe_id = r.u8()?;
        let types = r.rest_str()?;
        let types: Vec<&str> = types.split(',').collect();
        if types.len() != STATE_VARIABLES.len() {
            return Err(Error::Protocol(format!(
                "output setup answered {} types for {} variables",
                types.len(),
                STATE_VARIABLES.len()
            )));
        }
        for ((name, kind), expected) in STATE_VARIABLES.iter().zip(&types).zip(STATE_TYPES) {
            match VarType::parse(kind) {
                Some(t) if t == expected => {}
                Some(t) => {
                    return Err(Error::Protocol(format!(
                        "RTDE output `{name}` is {}, expected {}",
                        t.name(),
                        expected.name()
                    )));
                }
                // NOT_FOUND, or IN_USE (another client owns it).
                None => return Err(Error::Controller(format!("RTDE output `{name}`: {kind}"))),
            }
        }
        let reply = client.request(packet::START, &[])?;
        if Reader::new(&reply).u8()? != 1 {
            return Err(Error::Controller("RTDE start refused".to_owned()));
        }
        Ok(client)
    }

    /// [`Self::connect`], retried up to `attempts` times with a backoff that
    /// starts at `first_backoff` and doubles (capped at 5 s): for a
    /// controller that is restarting or dropped the link. The last error is
    /// returned if every attempt fails; a refusal by the controller
    /// (`Error::Controller`) is not retried.
    pub fn connect_with_retry(
        address: impl ToSocketAddrs + Copy,
        frequency_hz: f64,
        timeout: Duration,
        attempts: usize,
        first_backoff: Duration,
    ) -> Result<Self> {
        let mut backoff = first_backoff;
        let mut last = Error::Io("no connection attempt made".to_owned());
        for attempt in 0..attempts.max(1) {
            if attempt > 0 {
                std::thread::sleep(backoff);
                backoff = (backoff * 2).min(Duration::from_secs(5));
            }
            match Self::connect(address, frequency_hz, timeout) {
                Ok(client) => return Ok(client),
                Err(e @ Error::Controller(_)) => return Err(e),
                Err(e) => last = e,
            }
        }
        Err(last)
    }

    /// Sends a request and waits for the answer of the same type (text
    /// messages in between are skipped).
    fn request(&mut self, kind: u8, payload: &[u8]) -> Result<Vec<u8>> {
        write_packet(&mut self.stream, kind, payload)?;
        loop {
            let (got, reply) = read_packet(&mut self.stream)?;
            if got == kind {
                return Ok(reply);
            }
            if got != packet::TEXT_MESSAGE {
                return Err(Error::Protocol(format!(
                    "expected RTDE packet {:?}, got {:?}",
                    kind as char, got as char
                )));
            }
        }
    }

    /// The next state sample.
    pub fn next_state(&mut self) -> Result<RobotState> {
        loop {
            let (kind, payload) = read_packet(&mut self.stream)?;
            if let Some(state) = RobotState::from_packet(kind, &payload, self.recipe_id)? {
                return Ok(state);
            }
        }
    }
}

impl RobotState {
    /// The state in a packet of `kind`, if it is a data package of
    /// `recipe_id` (the layout checked against `STATE_TYPES` at set-up);
    /// `None` for other packets; an error for a package cut short.
    pub fn from_packet(kind: u8, payload: &[u8], recipe_id: u8) -> Result<Option<Self>> {
        if kind != packet::DATA_PACKAGE {
            return Ok(None); // text messages
        }
        let mut r = Reader::new(payload);
        if r.u8()? != recipe_id {
            return Ok(None);
        }
        let vector = |r: &mut Reader<'_>| -> Result<[f64; 6]> {
            Ok([r.f64()?, r.f64()?, r.f64()?, r.f64()?, r.f64()?, r.f64()?])
        };
        Ok(Some(Self {
            timestamp_s: r.f64()?,
            actual_q: vector(&mut r)?,
            actual_tcp_pose: vector(&mut r)?,
            robot_mode: r.i32()?,
            safety_mode: r.i32()?,
            runtime_state: r.u32()?,
        }))
    }
}
