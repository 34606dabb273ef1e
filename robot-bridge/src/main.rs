//! `robot-bridge`: the UR5e bridge's command line.

use std::f64::consts::FRAC_PI_2;

use anyhow::{Context, bail};
use clap::{Parser, Subcommand};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use robot_bridge::emulate::{Emulator, EmulatorPorts};
use robot_bridge::pick::{GraspTarget, PickConfig, plan_pick, urscript};
use robot_bridge::ur5e::Ur5e;

/// UR's usual home: upper arm up, forearm level, tool pointing down.
const HOME: [f64; 6] = [0.0, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, 0.0];

#[derive(Parser)]
#[command(
    name = "robot-bridge",
    version,
    about = "Turns mvgrasp grasps into UR5e motions"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Joint solutions for a flange pose in the robot base frame.
    Ik {
        /// Position x y z (m).
        #[arg(long, num_args = 3, allow_negative_numbers = true, value_names = ["X", "Y", "Z"])]
        position: Vec<f64>,
        /// Orientation quaternion x y z w.
        #[arg(long, num_args = 4, allow_negative_numbers = true, value_names = ["QX", "QY", "QZ", "QW"])]
        orientation: Vec<f64>,
        /// Current joints (rad), to pick the nearest solution.
        #[arg(long, num_args = 6, allow_negative_numbers = true, default_values_t = HOME)]
        current: Vec<f64>,
    },
    /// Dry run: the pick motion for one grasp (world = robot base here), as URScript on stdout.
    Script {
        /// Grasp centre x y z (m), mvgrasp grasp frame.
        #[arg(long, num_args = 3, allow_negative_numbers = true, value_names = ["X", "Y", "Z"])]
        position: Vec<f64>,
        /// Grasp orientation quaternion x y z w (+z = approach, +x = closing).
        #[arg(long, num_args = 4, allow_negative_numbers = true, value_names = ["QX", "QY", "QZ", "QW"])]
        orientation: Vec<f64>,
        /// Opening (m).
        #[arg(long, default_value_t = 0.05)]
        width: f64,
        /// Current joints (rad).
        #[arg(long, num_args = 6, allow_negative_numbers = true, default_values_t = HOME)]
        current: Vec<f64>,
    },
    /// Run the controller emulator (RTDE + script receiver) until interrupted.
    Emulate {
        /// Address to listen on (loopback by default).
        #[arg(long, default_value = "127.0.0.1")]
        host: String,
        /// RTDE port.
        #[arg(long, default_value_t = 30004)]
        rtde_port: u16,
        /// Script (secondary interface) port.
        #[arg(long, default_value_t = 30002)]
        script_port: u16,
        /// Dashboard port.
        #[arg(long, default_value_t = 29999)]
        dashboard_port: u16,
        /// Robotiq URCap socket port.
        #[arg(long, default_value_t = 63352)]
        gripper_port: u16,
    },
    /// Flange pose for joint angles (rad).
    Fk {
        /// Six joint angles (rad).
        #[arg(num_args = 6, allow_negative_numbers = true)]
        joints: Vec<f64>,
    },
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let arm = Ur5e::default();
    match cli.command {
        Command::Ik {
            position,
            orientation,
            current,
        } => {
            let q = Quaternion::new(orientation[3], orientation[0], orientation[1], orientation[2]);
            if q.norm().is_nan() || (q.norm() - 1.0).abs() > 1e-3 {
                bail!("--orientation must be a unit quaternion (norm {:.6})", q.norm());
            }
            let pose = Isometry3::from_parts(
                Translation3::new(position[0], position[1], position[2]),
                UnitQuaternion::new_normalize(q),
            );
            let current: [f64; 6] = current
                .try_into()
                .map_err(|_| anyhow::anyhow!("--current needs 6 values"))?;
            let solutions = arm.inverse(&pose, current[5]);
            println!("{} solution(s) (rad):", solutions.len());
            for s in &solutions {
                println!("  {}", format_joints(s));
            }
            let nearest = arm
                .inverse_nearest(&pose, &current)
                .context("no solution within the joint limits")?;
            println!("nearest to current within limits: {}", format_joints(&nearest));
        }
        Command::Script {
            position,
            orientation,
            width,
            current,
        } => {
            let grasp = GraspTarget {
                world_from_grasp: pose_from_args(&position, &orientation)?,
                width_m: width,
                quality: 1.0,
                object: None,
            };
            let current: [f64; 6] = current
                .try_into()
                .map_err(|_| anyhow::anyhow!("--current needs 6 values"))?;
            let config = PickConfig::default();
            let plan = plan_pick(&arm, &config, &[grasp], &[], &current).context("no feasible pick")?;
            print!("{}", urscript(&plan, &config));
        }
        Command::Emulate {
            host,
            rtde_port,
            script_port,
            dashboard_port,
            gripper_port,
        } => {
            let ports = EmulatorPorts {
                rtde: rtde_port,
                script: script_port,
                dashboard: dashboard_port,
                gripper: gripper_port,
            };
            let emulator = Emulator::start(&host, ports, HOME).context("cannot start the emulator")?;
            println!(
                "emulating a UR5e: RTDE on {}, scripts on {}, dashboard on {}, gripper on {}",
                emulator.rtde_address,
                emulator.script_address,
                emulator.dashboard_address,
                emulator.gripper_address
            );
            loop {
                std::thread::sleep(std::time::Duration::from_secs(3600));
            }
        }
        Command::Fk { joints } => {
            let q: [f64; 6] = joints
                .try_into()
                .map_err(|_| anyhow::anyhow!("6 joint angles needed"))?;
            let pose = arm.forward(&q);
            let (p, r) = (pose.translation.vector, pose.rotation);
            println!("position (m): {:.6} {:.6} {:.6}", p.x, p.y, p.z);
            println!(
                "orientation (x y z w): {:.6} {:.6} {:.6} {:.6}",
                r.i, r.j, r.k, r.w
            );
        }
    }
    Ok(())
}

fn pose_from_args(position: &[f64], orientation: &[f64]) -> anyhow::Result<Isometry3<f64>> {
    let q = Quaternion::new(orientation[3], orientation[0], orientation[1], orientation[2]);
    if q.norm().is_nan() || (q.norm() - 1.0).abs() > 1e-3 {
        bail!("--orientation must be a unit quaternion (norm {:.6})", q.norm());
    }
    if position.iter().any(|v| !v.is_finite()) {
        bail!("--position must be finite");
    }
    Ok(Isometry3::from_parts(
        Translation3::new(position[0], position[1], position[2]),
        UnitQuaternion::new_normalize(q),
    ))
}

fn format_joints(q: &[f64; 6]) -> String {
    q.iter().map(|v| format!("{v:+.6}")).collect::<Vec<_>>().join(" ")
}
