//! The parallel-jaw gripper model used to place and check grasps.

use crate::error::{Error, Result};

/// A parallel-jaw gripper.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gripper {
    /// Largest opening between the pads (m).
    pub max_width_m: f64,
    /// Pad extent across the closing direction (m).
    pub finger_width_m: f64,
    /// Pad extent along the approach direction, back from the fingertip (m).
    pub finger_depth_m: f64,
}

impl Gripper {
    /// Robotiq 2F-140: 0-140 mm stroke, pads about 27 mm wide and 40 mm deep.
    pub fn robotiq_2f_140() -> Self {
        Self {
            max_width_m: 0.14,
            finger_width_m: 0.027,
            finger_depth_m: 0.04,
        }
    }

    /// Robotiq 2F-85: 0-85 mm stroke, pads about 22 mm wide and 37 mm deep.
    pub fn robotiq_2f_85() -> Self {
        Self {
            max_width_m: 0.085,
            finger_width_m: 0.022,
            finger_depth_m: 0.037,
        }
    }

    /// Every size finite, positive and at most 0.5 m.
    pub fn validate(&self) -> Result<()> {
        for (name, value) in [
            ("gripper.max_width_m", self.max_width_m),
            ("gripper.finger_width_m", self.finger_width_m),
            ("gripper.finger_depth_m", self.finger_depth_m),
        ] {
            if !(value.is_finite() && value > 0.0 && value <= 0.5) {
                return Err(Error::invalid(
                    name,
                    format!("must be in (0, 0.5] m, got {value}"),
                ));
            }
        }
        Ok(())
    }
}

impl Default for Gripper {
    fn default() -> Self {
        Self::robotiq_2f_140()
    }
}
