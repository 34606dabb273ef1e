//! The emulator's Robotiq URCap socket (`SET`/`GET`, one line each).

use std::net::TcpStream;

use super::Shared;

/// The emulated gripper's registers and the object between its fingers.
#[derive(Debug, Clone)]
pub(super) struct GripperSim {
    pub(super) activated: bool,
    /// Current position, 0 (open) ..= 255 (closed), continuous.
    pub(super) position: f64,
    pub(super) request: u8,
    pub(super) speed: u8,
    pub(super) force: u8,
    pub(super) moving: bool,
    pub(super) obj: u32,
    /// Width of the object between the fingers (m), if any.
    pub(super) object_width_m: Option<f64>,
}

impl Default for GripperSim {
    fn default() -> Self {
        Self {
            activated: false,
            position: 0.0,
            request: 0,
            speed: 255,
            force: 150,
            moving: false,
            obj: 3,
            object_width_m: Some(0.05),
        }
    }
}

/// 2F-140 stroke (m).
const STROKE_M: f64 = 0.14;

impl GripperSim {
    /// One servo tick of `dt` seconds: 20-150 mm/s by the speed register;
    /// closing stops on the object, if there is one.
    pub(super) fn tick(&mut self, dt: f64) {
        if self.obj == 2 && self.object_width_m.is_none() {
            // The held object slipped out: the fingers go on to the request.
            self.moving = true;
            self.obj = 0;
        }
        if !self.moving {
            return;
        }
        let mm_per_s = 20.0 + 130.0 * f64::from(self.speed) / 255.0;
        let step = mm_per_s / 1000.0 / STROKE_M * 255.0 * dt;
        let target = f64::from(self.request);
        let closing = target > self.position;
        let contact = self
            .object_width_m
            .map(|w| 255.0 * (1.0 - (w / STROKE_M).clamp(0.0, 1.0)));
        let next = if closing {
            (self.position + step).min(target)
        } else {
            (self.position - step).max(target)
        };
        match contact {
            Some(c) if closing && next >= c && self.position <= c => {
                self.position = c;
                self.moving = false;
                self.obj = 2;
            }
            _ => {
                self.position = next;
                if (next - target).abs() < 1e-9 {
                    self.moving = false;
                    self.obj = 3;
                }
            }
        }
    }
}

/// Serves one client line by line.
pub(super) fn serve(stream: TcpStream, shared: &Shared) {
    super::serve_lines(stream, shared, None, |line| answer(line, &mut shared.gripper()));
}

/// The answer to one request line.
fn answer(line: &str, g: &mut GripperSim) -> String {
    let words: Vec<&str> = line.split_whitespace().collect();
    match words.as_slice() {
        ["SET", var, value] => match (*var, value.parse::<u32>()) {
            ("ACT", Ok(v)) => {
                g.activated = v == 1;
                "ack".to_owned()
            }
            ("POS", Ok(v)) => {
                g.request = v.min(255) as u8;
                "ack".to_owned()
            }
            ("SPE", Ok(v)) => {
                g.speed = v.min(255) as u8;
                "ack".to_owned()
            }
            ("FOR", Ok(v)) => {
                g.force = v.min(255) as u8;
                "ack".to_owned()
            }
            ("GTO", Ok(1)) if g.activated => {
                g.moving = true;
                g.obj = 0;
                "ack".to_owned()
            }
            ("GTO", Ok(_)) => "ack".to_owned(),
            _ => "?".to_owned(),
        },
        ["GET", "STA"] => format!("STA {}", if g.activated { 3 } else { 0 }),
        ["GET", "POS"] => format!("POS {}", g.position.round() as u32),
        ["GET", "PRE"] => format!("PRE {}", g.request),
        ["GET", "OBJ"] => format!("OBJ {}", g.obj),
        ["GET", "ACT"] => format!("ACT {}", u32::from(g.activated)),
        ["GET", "FLT"] => "FLT 0".to_owned(),
        _ => "?".to_owned(),
    }
}
