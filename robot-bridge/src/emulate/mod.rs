//! A UR controller emulator for tests and dry runs: an RTDE server (state
//! out), a script receiver that executes `movej` / `movel` by interpolating
//! the joints at the commanded speed, the dashboard server, a Robotiq
//! 2F-140 on the URCap socket (closing stops on an object of a set width),
//! and fault injection (protective stop, dropped connections, a dropped RTDE
//! link alone, a stalled gripper, an output
//! recipe already in use).
//!
//! Simplifications, stated: `movel` is interpolated in joint space between
//! its end points (the TCP path is not a straight line here); once the data
//! stream has started, the RTDE server no longer reads from the client; the
//! one thing a guarded `movel` (run in a thread watched by `tool_contact`)
//! can meet is a level surface under the tool (`set_contact_height`).

mod dashboard_server;
mod gripper_server;
mod rtde_server;
mod script_server;

use gripper_server::GripperSim;

use std::net::{SocketAddr, TcpListener};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use nalgebra::Isometry3;

use crate::ur5e::{Joints, Ur5e};

/// Faults to inject; flip them at any time.
#[derive(Debug, Default)]
pub struct Faults {
    /// Trip a protective stop: motion halts, safety mode 3, until unlocked.
    pub protective_stop: AtomicBool,
    /// Close every open connection (and refuse new ones) while set.
    pub drop_connections: AtomicBool,
    /// Answer every output variable with `IN_USE`.
    pub recipe_in_use: AtomicBool,
    /// Close the RTDE link (and refuse new ones) while set; the script,
    /// gripper and dashboard interfaces stay up.
    pub drop_rtde: AtomicBool,
    /// The gripper's motor stalls: a commanded motion never ends.
    pub gripper_stalled: AtomicBool,
}

/// A queued joint motion.
#[derive(Debug, Clone, Copy)]
struct Motion {
    target: Joints,
    /// Speed of the fastest joint (rad/s).
    speed: f64,
    /// A guarded move (`tool_contact`): it ends where the TCP meets the
    /// surface set by `Emulator::set_contact_height`.
    guarded: bool,
}

/// The emulated robot.
#[derive(Debug)]
struct Robot {
    arm: Ur5e,
    q: Joints,
    flange_from_tcp: Isometry3<f64>,
    safety_mode: i32,
    motions: std::collections::VecDeque<Motion>,
    /// A surface under the tool: a guarded move stops where the TCP's z
    /// (base frame) goes below this.
    contact_z: Option<f64>,
    /// The TCP's z (base frame) where each guarded move ended.
    guarded_ends: Vec<f64>,
    started: Instant,
}

impl Robot {
    fn tcp_pose(&self) -> [f64; 6] {
        let pose = self.arm.forward(&self.q) * self.flange_from_tcp;
        let (p, r) = (pose.translation.vector, pose.rotation.scaled_axis());
        [p.x, p.y, p.z, r.x, r.y, r.z]
    }

    fn runtime_state(&self) -> u32 {
        if self.motions.is_empty() { 1 } else { 2 }
    }
}

struct Shared {
    robot: Mutex<Robot>,
    gripper: Mutex<GripperSim>,
    faults: Faults,
    stop: AtomicBool,
}

impl Shared {
    fn robot(&self) -> MutexGuard<'_, Robot> {
        // A panicked worker must not take the emulator down with it.
        self.robot
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    fn gripper(&self) -> MutexGuard<'_, GripperSim> {
        self.gripper
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    fn should_close(&self) -> bool {
        self.stop.load(Ordering::Relaxed) || self.faults.drop_connections.load(Ordering::Relaxed)
    }

    fn should_close_rtde(&self) -> bool {
        self.should_close() || self.faults.drop_rtde.load(Ordering::Relaxed)
    }
}

/// The ports to listen on (0 = any free port).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EmulatorPorts {
    /// RTDE.
    pub rtde: u16,
    /// Secondary interface (scripts).
    pub script: u16,
    /// Dashboard server.
    pub dashboard: u16,
    /// Robotiq URCap socket.
    pub gripper: u16,
}

impl EmulatorPorts {
    /// The controller's standard ports: 30004, 30002, 29999, 63352.
    pub fn standard() -> Self {
        Self {
            rtde: 30004,
            script: 30002,
            dashboard: 29999,
            gripper: 63352,
        }
    }
}

/// A running emulator; stops when dropped.
pub struct Emulator {
    shared: Arc<Shared>,
    /// Where the RTDE server listens.
    pub rtde_address: SocketAddr,
    /// Where the script receiver listens.
    pub script_address: SocketAddr,
    /// Where the dashboard server listens.
    pub dashboard_address: SocketAddr,
    /// Where the gripper socket listens.
    pub gripper_address: SocketAddr,
    threads: Vec<JoinHandle<()>>,
}

/// Servo period of the emulated controller (500 Hz, as the e-series).
const TICK: Duration = Duration::from_millis(2);

impl Emulator {
    /// Starts on `host` with the given ports, the arm at `initial_q`.
    pub fn start(host: &str, ports: EmulatorPorts, initial_q: Joints) -> std::io::Result<Self> {
        let shared = Arc::new(Shared {
            robot: Mutex::new(Robot {
                arm: Ur5e::default(),
                q: initial_q,
                flange_from_tcp: Isometry3::identity(),
                safety_mode: 1,
                motions: Default::default(),
                contact_z: None,
                guarded_ends: Vec::new(),
                started: Instant::now(),
            }),
            gripper: Mutex::new(GripperSim::default()),
            faults: Faults::default(),
            stop: AtomicBool::new(false),
        });
        let rtde = TcpListener::bind((host, ports.rtde))?;
        let script = TcpListener::bind((host, ports.script))?;
        let dashboard = TcpListener::bind((host, ports.dashboard))?;
        let gripper = TcpListener::bind((host, ports.gripper))?;
        let (rtde_address, script_address) = (rtde.local_addr()?, script.local_addr()?);
        let (dashboard_address, gripper_address) = (dashboard.local_addr()?, gripper.local_addr()?);
        let threads = vec![
            spawn_servo(Arc::clone(&shared)),
            spawn_acceptor(rtde, Arc::clone(&shared), rtde_server::serve, Serving::Concurrent),
            spawn_acceptor(
                script,
                Arc::clone(&shared),
                script_server::serve,
                Serving::InOrder,
            ),
            spawn_acceptor(
                dashboard,
                Arc::clone(&shared),
                dashboard_server::serve,
                Serving::Concurrent,
            ),
            spawn_acceptor(
                gripper,
                Arc::clone(&shared),
                gripper_server::serve,
                Serving::Concurrent,
            ),
        ];
        Ok(Self {
            shared,
            rtde_address,
            script_address,
            dashboard_address,
            gripper_address,
            threads,
        })
    }

    /// Sets the width of the object the gripper will close on (`None`:
    /// nothing there; a held object then slips out, and the fingers go on
    /// closing).
    pub fn set_object_width(&self, width_m: Option<f64>) {
        self.shared.gripper().object_width_m = width_m;
    }

    /// A surface under the tool at `z_m` (the TCP's z in the base frame):
    /// a guarded move (the bridge's descent before the release, watched by
    /// `tool_contact`) stops where it reaches it; `None`: nothing there.
    pub fn set_contact_height(&self, z_m: Option<f64>) {
        self.shared.robot().contact_z = z_m;
    }

    /// The TCP's z (base frame) where each guarded move so far ended, on
    /// contact or at its target.
    pub fn guarded_move_ends(&self) -> Vec<f64> {
        self.shared.robot().guarded_ends.clone()
    }

    /// The fault switches.
    pub fn faults(&self) -> &Faults {
        &self.shared.faults
    }

    /// Current joints.
    pub fn joints(&self) -> Joints {
        self.shared.robot().q
    }

    /// Clears a protective stop (what the dashboard's `unlock protective stop` does).
    pub fn unlock_protective_stop(&self) {
        self.shared.faults.protective_stop.store(false, Ordering::Relaxed);
        self.shared.robot().safety_mode = 1;
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        for thread in self.threads.drain(..) {
            let _ = thread.join();
        }
    }
}

/// The servo loop: moves the joints toward the queued targets, and halts on a protective stop.
fn spawn_servo(shared: Arc<Shared>) -> JoinHandle<()> {
    std::thread::spawn(move || {
        let dt = TICK.as_secs_f64();
        while !shared.stop.load(Ordering::Relaxed) {
            {
                let mut robot = shared.robot();
                if shared.faults.protective_stop.load(Ordering::Relaxed) {
                    robot.safety_mode = 3;
                }
                if !shared.faults.gripper_stalled.load(Ordering::Relaxed) {
                    shared.gripper().tick(dt);
                }
                if robot.safety_mode != 1 {
                    robot.motions.clear();
                } else if let Some(motion) = robot.motions.front().copied() {
                    let touching =
                        motion.guarded && robot.contact_z.is_some_and(|z| robot.tcp_pose()[2] <= z);
                    if touching {
                        // The program's tool contact check stops the line here.
                        robot.motions.pop_front();
                        let z = robot.tcp_pose()[2];
                        robot.guarded_ends.push(z);
                        continue;
                    }
                    let remaining: Vec<f64> = (0..6).map(|i| motion.target[i] - robot.q[i]).collect();
                    let largest = remaining.iter().fold(0.0f64, |m, r| m.max(r.abs()));
                    let step = motion.speed * dt;
                    if largest <= step {
                        robot.q = motion.target;
                        robot.motions.pop_front();
                        if motion.guarded {
                            let z = robot.tcp_pose()[2];
                            robot.guarded_ends.push(z);
                        }
                    } else {
                        for (q, r) in robot.q.iter_mut().zip(&remaining) {
                            *q += r * step / largest;
                        }
                    }
                }
            }
            std::thread::sleep(TICK);
        }
    })
}

/// Serves a line protocol: an optional greeting, then one answer per line,
/// until the client leaves, the emulator stops or connections drop.
fn serve_lines(
    stream: std::net::TcpStream,
    shared: &Shared,
    greeting: Option<&str>,
    mut answer: impl FnMut(&str) -> String,
) {
    use std::io::{BufRead, BufReader, Write};
    let _ = stream.set_read_timeout(Some(Duration::from_millis(50)));
    let Ok(mut writer) = stream.try_clone() else {
        return;
    };
    if let Some(greeting) = greeting
        && writer.write_all(format!("{greeting}\n").as_bytes()).is_err()
    {
        return;
    }
    let mut reader = BufReader::new(stream);
    let mut line = String::new();
    while !shared.should_close() {
        line.clear();
        match reader.read_line(&mut line) {
            Ok(0) => return,
            Ok(_) => {}
            Err(_) => continue, // a timeout: look at the stop flags again
        }
        if writer
            .write_all(format!("{}\n", answer(line.trim())).as_bytes())
            .is_err()
        {
            return;
        }
    }
}

/// How an acceptor serves its connections.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Serving {
    /// One thread per connection, side by side.
    Concurrent,
    /// One after the other, in the order they arrived (the controller runs
    /// script programs in the order it receives them).
    InOrder,
}

/// Accepts connections until the emulator stops.
fn spawn_acceptor(
    listener: TcpListener,
    shared: Arc<Shared>,
    serve: fn(std::net::TcpStream, &Shared),
    serving: Serving,
) -> JoinHandle<()> {
    std::thread::spawn(move || {
        let _ = listener.set_nonblocking(true);
        let mut workers = Vec::new();
        while !shared.stop.load(Ordering::Relaxed) {
            match listener.accept() {
                Ok((stream, _)) if !shared.faults.drop_connections.load(Ordering::Relaxed) => {
                    let _ = stream.set_nonblocking(false);
                    if serving == Serving::InOrder {
                        serve(stream, &shared);
                        continue;
                    }
                    let shared = Arc::clone(&shared);
                    workers.push(std::thread::spawn(move || serve(stream, &shared)));
                }
                Ok(_) => {} // dropped on the floor: the connection closes
                Err(_) => std::thread::sleep(Duration::from_millis(5)),
            }
        }
        for worker in workers {
            let _ = worker.join();
        }
    })
}
