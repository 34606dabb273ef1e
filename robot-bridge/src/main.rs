//! `robot-bridge`: the UR5e bridge's command line.

use anyhow::{Context, bail};
use clap::{Parser, Subcommand};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use robot_bridge::config::BridgeConfig;
use robot_bridge::emulate::{Emulator, EmulatorPorts};
use robot_bridge::pick::{GraspTarget, PickConfig, Step, plan_pick, urscript};
use robot_bridge::ur5e::{HOME, Ur5e};

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
    /// Plan grasps on a depth frame + camera file (with the mvgrasp service
    /// given by `--planner`, else in-process with the analytic baseline),
    /// choose a feasible pick and run it on the controller, printing each
    /// step; `--dry-run` prints the URScript only.
    Pick {
        /// 16-bit depth PNG (millimetres).
        #[arg(long)]
        depth: std::path::PathBuf,
        /// Camera JSON (intrinsics, world_from_camera, workspace).
        #[arg(long)]
        camera: std::path::PathBuf,
        /// Settings file (calibration, limits, planner, recovery; see robot-bridge/bridge.toml).
        #[arg(long, env = "ROBOT_BRIDGE_CONFIG")]
        config: Option<std::path::PathBuf>,
        /// Controller host (standard ports 30004, 30002, 29999, 63352).
        #[arg(long)]
        robot: Option<String>,
        /// Robot base position in the world (m).
        #[arg(long, num_args = 3, allow_negative_numbers = true)]
        base_position: Option<Vec<f64>>,
        /// TCP position over the basket, world (m).
        #[arg(long, num_args = 3, allow_negative_numbers = true)]
        basket: Option<Vec<f64>>,
        /// The mvgrasp planner service, e.g. http://127.0.0.1:50051 (unset: in-process baseline).
        #[arg(long, env = "MVGRASP_SERVER")]
        planner: Option<String>,
        /// Print the URScript instead of moving the robot.
        #[arg(long)]
        dry_run: bool,
        /// Picks that came up empty-handed on this scene (closed on nothing,
        /// or held nothing over the basket), one JSON pose a line
        /// (`{"position": [x, y, z], "orientation": [x, y, z, w]}`, world):
        /// grasps repeating one are tried last (`[pick] failed_radius_m`),
        /// and a pick that comes up empty-handed is added. Delete it when
        /// the scene changes.
        #[arg(long, env = "ROBOT_BRIDGE_FAILED_PICKS")]
        failed_picks: Option<std::path::PathBuf>,
        /// The objects let go over the basket since it was emptied, a file
        /// holding one number (missing: 0): chooses where over the basket
        /// this one goes (`[pick] release_spread_m`), and counts up when
        /// the pick holds its object to the release. Delete it when the
        /// basket is emptied.
        #[arg(long, env = "ROBOT_BRIDGE_BASKET_COUNT")]
        basket_count: Option<std::path::PathBuf>,
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
    /// Kinematics and pick planning as a line protocol on stdin/stdout (one
    /// JSON request per line; see `robot_bridge::jsonl`), with the
    /// calibration, drop pose and basket of `--config`. Used by the physics
    /// referee to run the bridge's own picks on a simulated arm.
    PlanJsonl {
        /// Settings file (see robot-bridge/bridge.toml).
        #[arg(long, env = "ROBOT_BRIDGE_CONFIG")]
        config: Option<std::path::PathBuf>,
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
        Command::Pick {
            depth,
            camera,
            config,
            robot,
            base_position,
            basket,
            planner,
            dry_run,
            failed_picks,
            basket_count,
        } => {
            let mut settings = match &config {
                Some(path) => BridgeConfig::load(path)?,
                None => BridgeConfig::default(),
            };
            if let Some(host) = robot {
                settings.robot.host = host;
            }
            if let Some(p) = base_position {
                settings.robot.world_from_base.position = [p[0], p[1], p[2]];
            }
            if let Some(p) = basket {
                // The basket moves with its drop pose.
                let drop = settings.pick.world_from_drop.position;
                let b = &mut settings.pick.basket.centre;
                *b = [
                    b[0] + p[0] - drop[0],
                    b[1] + p[1] - drop[1],
                    b[2] + p[2] - drop[2],
                ];
                settings.pick.world_from_drop.position = [p[0], p[1], p[2]];
            }
            if planner.is_some() {
                settings.planner.endpoint = planner;
            }
            settings.validate()?;
            let files = PickFiles {
                failed_picks: failed_picks.as_deref(),
                basket_count: basket_count.as_deref(),
            };
            pick(&arm, &depth, &camera, &settings, dry_run, &files)?;
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
        Command::PlanJsonl { config } => {
            let settings = match &config {
                Some(path) => BridgeConfig::load(path)?,
                None => BridgeConfig::default(),
            };
            settings.validate()?;
            let config = settings.pick_config()?;
            let stdin = std::io::stdin();
            robot_bridge::jsonl::serve(&arm, &config, stdin.lock(), std::io::stdout().lock())?;
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

/// What `pick` keeps between picks of one scene (`--failed-picks`) and of
/// one basket (`--basket-count`).
struct PickFiles<'a> {
    failed_picks: Option<&'a std::path::Path>,
    basket_count: Option<&'a std::path::Path>,
}

/// The text of a file `pick` keeps between picks; None where it does not exist yet.
fn read_if_present(path: &std::path::Path) -> anyhow::Result<Option<String>> {
    match std::fs::read_to_string(path) {
        Ok(text) => Ok(Some(text)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(anyhow::anyhow!(e).context(format!("reading {}", path.display()))),
    }
}

/// The number in a `--basket-count` file (missing: 0).
fn read_basket_count(path: &std::path::Path) -> anyhow::Result<usize> {
    let Some(text) = read_if_present(path)? else {
        return Ok(0);
    };
    text.trim().parse().with_context(|| {
        format!(
            "{}: one whole number expected (objects let go over the basket), not {:?}",
            path.display(),
            text.trim()
        )
    })
}

fn pick(
    arm: &Ur5e,
    depth: &std::path::Path,
    camera: &std::path::Path,
    settings: &BridgeConfig,
    dry_run: bool,
    files: &PickFiles,
) -> anyhow::Result<()> {
    use std::time::Duration;

    use robot_bridge::execute::{Controller, execute_pick};
    use robot_bridge::gripper::Gripper;
    use robot_bridge::planner::{load_scene, plan_locally, plan_remotely};
    use robot_bridge::rtde::RtdeClient;

    let scene = load_scene(depth, camera)?;
    let robot = settings.robot.host.as_str();
    let timeout = Duration::from_secs_f64(settings.robot.io_timeout_s);
    let mut rtde = if dry_run {
        None
    } else {
        Some(RtdeClient::connect_with_retry(
            (robot, 30004),
            125.0,
            timeout,
            3,
            timeout / 4,
        )?)
    };
    // Where the arm stands as the frame is planned: its body is left out of
    // what the planner sees, and the pick starts from it.
    let current = match rtde.as_mut() {
        Some(client) => client.next_state()?.actual_q,
        None => HOME,
    };
    let ask = settings.ask(arm, &current)?;
    let planned = match &settings.planner.endpoint {
        Some(endpoint) => plan_remotely(
            endpoint,
            &settings.planner_credentials()?,
            &scene,
            &ask,
            Duration::from_secs_f64(settings.planner.timeout_s),
        )?,
        None => plan_locally(&scene, &ask)?,
    };
    println!(
        "planner {}: {} objects, {} grasps",
        planned.planner,
        planned.objects.len(),
        planned.grasps.len()
    );
    let mut config = settings.pick_config()?;
    if let Some(path) = files.basket_count {
        config.released = read_basket_count(path)?;
    }
    config.obstacles.push(planned.table.clone());
    let seen = config.add_seen_obstacles(arm, &planned.outside, &current, settings.planner.robot_body);
    println!(
        "{} boxes outside the workspace kept clear of, {} taken for the cell",
        planned.outside.len() - seen.left_out.len(),
        seen.left_out.len()
    );
    for (name, why) in &seen.left_out {
        println!("  {name}: {why}");
    }
    for (name, why) in &seen.cut {
        println!("  {name}: {why}, kept cut back clear of it");
    }
    let failed = match files.failed_picks.map(read_if_present).transpose()?.flatten() {
        Some(text) => robot_bridge::pick::parse_failed_picks(&text)?,
        None => Vec::new(),
    };
    let poses: Vec<_> = planned.grasps.iter().map(|g| g.world_from_grasp).collect();
    let order = config.order_after_failures(&poses, &failed);
    let ordered: Vec<_> = order.iter().map(|&k| planned.grasps[k]).collect();
    let plan = plan_pick(arm, &config, &ordered, &planned.objects, &current).context("no feasible pick")?;
    let grasp = &ordered[plan.grasp_index];
    let p = grasp.world_from_grasp.translation.vector;
    println!(
        "picking grasp {} (quality {:.2}, width {:.0} mm) at ({:.3}, {:.3}, {:.3}) m:",
        order[plan.grasp_index] + 1,
        grasp.quality,
        grasp.width_m * 1000.0,
        p.x,
        p.y,
        p.z
    );
    for step in &plan.steps {
        match step {
            Step::MoveJ { name, joints } => println!("  movej  {name:<16} {}", format_joints(joints)),
            Step::MoveL { name, joints, .. } => println!("  movel  {name:<16} {}", format_joints(joints)),
            Step::Gripper { name, close, width_m } => {
                println!(
                    "  grip   {name:<16} {}",
                    if *close {
                        "close".to_owned()
                    } else {
                        format!("open {:.0} mm", width_m * 1000.0)
                    }
                )
            }
        }
    }
    let Some(rtde) = rtde else {
        print!("{}", urscript(&plan, &config));
        return Ok(());
    };
    let mut gripper = Gripper::connect((robot, 63352), 0.14, timeout)?;
    gripper.activate()?;
    let script_address = std::net::ToSocketAddrs::to_socket_addrs(&(robot, 30002))?
        .next()
        .context("the robot address resolves to nothing")?;
    let mut controller = Controller {
        rtde,
        script_address,
        gripper,
        io_timeout: timeout,
        motion_timeout: Duration::from_secs_f64(settings.robot.motion_timeout_s),
    };
    match execute_pick(&mut controller, &plan, &config) {
        Ok(outcome) => {
            println!("outcome: {outcome:?}");
            if let (robot_bridge::execute::PickOutcome::Placed { .. }, Some(path)) =
                (&outcome, files.basket_count)
            {
                std::fs::write(path, format!("{}\n", config.released + 1))
                    .with_context(|| format!("writing {}", path.display()))?;
            }
            if let (true, Some(path)) = (outcome.empty_handed(), files.failed_picks) {
                use std::io::Write;
                let line = robot_bridge::pick::failed_pick_line(&grasp.world_from_grasp);
                std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(path)
                    .and_then(|mut f| writeln!(f, "{line}"))
                    .with_context(|| format!("writing {}", path.display()))?;
                println!("added to {}: the next pick tries elsewhere first", path.display());
            }
            Ok(())
        }
        Err(stop @ robot_bridge::Error::ProtectiveStop { .. })
            if settings.recovery.unlock_protective_stop =>
        {
            println!("{stop}; unlocking it through the dashboard (recovery.unlock_protective_stop)");
            let status = robot_bridge::dashboard::unlock_protective_stop(
                (robot, 29999),
                Duration::from_secs_f64(settings.recovery.unlock_after_s),
                timeout,
            )?;
            println!("dashboard: {status}; the pick is over, the robot stays where it stopped");
            Err(stop.into())
        }
        Err(e) => Err(e.into()),
    }
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
