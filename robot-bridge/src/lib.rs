//! # mvgrasp robot bridge
//!
//! Turns mvgrasp grasps into UR5e + Robotiq 2F-140 motions. This first part
//! is the arm's kinematics: forward kinematics from the UR5e DH table, the
//! closed-form inverse (up to 8 solutions) and the choice of the solution
//! nearest the current joints within the limits.
//!
//! ```
//! use robot_bridge::ur5e::Ur5e;
//!
//! let arm = Ur5e::default();
//! let q = [0.3, -1.2, 1.4, -1.6, -1.57, 0.7];
//! let pose = arm.forward(&q);
//! let back = arm.inverse_nearest(&pose, &q)?;
//! assert!((0..6).all(|i| (back[i] - q[i]).abs() < 1e-9));
//! # Ok::<(), robot_bridge::Error>(())
//! ```

pub mod collision;
pub mod config;
pub mod dashboard;
pub mod emulate;
mod error;
pub mod execute;
pub mod gripper;
pub mod jsonl;
mod net;
pub mod pick;
pub mod planner;
pub mod rtde;
pub mod script;
pub mod ur5e;

pub use error::{Error, Result};
