//! `mvgrasp`: plan grasps on a running planner, benchmark it, ask what it runs.

use std::{path::PathBuf, time::Duration};

use anyhow::{Context, bail};
use clap::{Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use mvgrasp_client::{
    Credentials, PlannerClient, ReplicaStats,
    bench::{self, BenchConfig},
    pb,
    scene::SceneFiles,
    viz,
};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// Client of the mvgrasp grasp planner.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    /// The planner: one address, several separated by commas (calls go
    /// round robin, a call that meets an unavailable replica goes on to the
    /// others), or `dns:///host:port` for every address the name has.
    #[arg(
        long,
        global = true,
        env = "MVGRASP_SERVER",
        default_value = "http://127.0.0.1:50051"
    )]
    server: String,
    /// Deadline per call (ms).
    #[arg(long, global = true)]
    timeout_ms: Option<u64>,
    /// PEM CA that signed the planner's certificate: call over TLS.
    #[arg(long, global = true, env = "MVGRASP_TLS_CA")]
    tls_ca: Option<PathBuf>,
    /// PEM certificate of this client (mutual TLS; with --tls-key).
    #[arg(long, global = true, env = "MVGRASP_TLS_CERT", requires = "tls_key")]
    tls_cert: Option<PathBuf>,
    /// PEM private key of --tls-cert.
    #[arg(long, global = true, env = "MVGRASP_TLS_KEY", requires = "tls_cert")]
    tls_key: Option<PathBuf>,
    /// The name on the planner's certificate, if the address differs.
    #[arg(long, global = true, env = "MVGRASP_TLS_DOMAIN")]
    tls_domain: Option<String>,
    /// File with the bearer token the planner asks for.
    #[arg(long, global = true, env = "MVGRASP_TOKEN_FILE")]
    token_file: Option<PathBuf>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Policy {
    Entropy,
    All,
    TopDown,
    Random,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Frame {
    Camera,
    World,
}

#[derive(Debug, clap::Args)]
struct SceneArgs {
    /// A 16-bit depth PNG (millimetres).
    #[arg(long, conflicts_with = "cloud")]
    depth: Option<PathBuf>,
    /// A PLY or PCD cloud.
    #[arg(long)]
    cloud: Option<PathBuf>,
    /// The frame the cloud's points are in.
    #[arg(long, value_enum, default_value = "camera")]
    cloud_frame: Frame,
    /// Camera JSON: intrinsics, world_from_camera, workspace.
    #[arg(long)]
    camera: PathBuf,
    /// Most grasps (0: the server's default).
    #[arg(long, default_value_t = 0)]
    max_grasps: u32,
    /// Drop grasps under this quality (tau; default: the server's).
    #[arg(long)]
    min_quality: Option<f32>,
    /// Which views go through the network.
    #[arg(long, value_enum, default_value = "entropy")]
    policy: Policy,
    /// Seed of `--policy random`.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The paper's single pass over the policy's views: no object goes on
    /// to its next view when the chosen one gives no grasp (the ablation).
    #[arg(long)]
    no_view_cascade: bool,
    /// Only approaches within this cone: axis x y z (world) and half-angle
    /// in degrees, e.g. `0 0 -1 60` for "from above within 60 degrees".
    #[arg(long, num_args = 4, allow_negative_numbers = true, value_names = ["AX", "AY", "AZ", "HALF_DEG"])]
    approach_cone: Option<Vec<f64>>,
    /// Only grasps the arm reaches (the planner's `ArmReach`, base axis
    /// along world z): its shoulder x y z (world, m), the wrist centre's
    /// distance back from the grasp along the approach, the straight
    /// approach's length, the wrist's farthest reach from the shoulder and
    /// its nearest to the base axis (m). `robot-bridge plan-jsonl` tells a
    /// UR5e's (`{"arm_reach": null}`).
    #[arg(
        long,
        num_args = 7,
        allow_negative_numbers = true,
        value_names = ["SX", "SY", "SZ", "WRIST_BACK_M", "APPROACH_M", "MAX_M", "MIN_AXIS_M"]
    )]
    arm_reach: Option<Vec<f64>>,
    /// Report what stands on the table inside this world box but outside
    /// the workspace as obstacle boxes (not planned): min x y z, max x y z (m).
    #[arg(
        long,
        num_args = 6,
        allow_negative_numbers = true,
        value_names = ["X0", "Y0", "Z0", "X1", "Y1", "Z1"]
    )]
    obstacle_region: Option<Vec<f64>>,
}

impl SceneArgs {
    fn load(&self) -> anyhow::Result<SceneFiles> {
        Ok(match (&self.depth, &self.cloud) {
            (Some(depth), None) => SceneFiles::load_depth(depth, &self.camera)?,
            (None, Some(cloud)) => {
                let frame = match self.cloud_frame {
                    Frame::Camera => pb::CloudFrame::Camera,
                    Frame::World => pb::CloudFrame::World,
                };
                SceneFiles::load_cloud(cloud, frame, &self.camera)?
            }
            _ => bail!("give --depth or --cloud"),
        })
    }

    fn request(&self, scene: &SceneFiles) -> pb::PlanGraspsRequest {
        let policy = match self.policy {
            Policy::Entropy => pb::ViewPolicy::Entropy,
            Policy::All => pb::ViewPolicy::All,
            Policy::TopDown => pb::ViewPolicy::TopDown,
            Policy::Random => pb::ViewPolicy::Random,
        };
        pb::PlanGraspsRequest {
            max_grasps: self.max_grasps,
            min_quality: self.min_quality,
            view_policy: policy as i32,
            random_seed: self.seed,
            view_cascade: self.no_view_cascade.then_some(false),
            approach_cone: self.approach_cone.as_ref().map(|c| pb::ApproachCone {
                axis: Some(pb::Vector3 {
                    x: c[0],
                    y: c[1],
                    z: c[2],
                }),
                half_angle_rad: c[3].to_radians(),
            }),
            arm_reach: self.arm_reach.as_ref().map(|r| pb::ArmReach {
                shoulder: Some(pb::Vector3 {
                    x: r[0],
                    y: r[1],
                    z: r[2],
                }),
                axis: None,
                wrist_back_m: r[3],
                approach_m: r[4],
                max_m: r[5],
                min_axis_m: r[6],
            }),
            obstacle_region: self.obstacle_region.as_ref().map(|b| pb::Workspace {
                min: Some(pb::Vector3 {
                    x: b[0],
                    y: b[1],
                    z: b[2],
                }),
                max: Some(pb::Vector3 {
                    x: b[3],
                    y: b[4],
                    z: b[5],
                }),
            }),
            ..scene.request()
        }
    }
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Plan grasps for one frame and print them ranked.
    Plan {
        #[command(flatten)]
        scene: SceneArgs,
        /// Print the whole response as JSON.
        #[arg(long)]
        json: bool,
        /// Draw the grasps over the depth image and the views into this PNG.
        #[arg(long)]
        viz: Option<PathBuf>,
    },
    /// Load the server with one frame: latency percentiles and throughput.
    Bench {
        #[command(flatten)]
        scene: SceneArgs,
        /// Concurrent callers.
        #[arg(long, default_value_t = 1)]
        concurrency: usize,
        /// Connections the callers take turns over (one per caller: each
        /// its own, as a fleet's robots; 1: all share one, as one process's
        /// stubs do).
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..))]
        connections: u16,
        /// Seconds to run (default 10 unless --count is given).
        #[arg(long)]
        duration_s: Option<f64>,
        /// Calls to make.
        #[arg(long)]
        count: Option<usize>,
        /// Total calls per second (default: as fast as answers come).
        #[arg(long)]
        rate: Option<f64>,
        /// Unmeasured calls first (shared out over the connections, at
        /// least one on each).
        #[arg(long, default_value_t = 5)]
        warmup: usize,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// The model and backend the server runs.
    Info,
    /// The planner's gRPC health status (exit code 1 unless SERVING).
    Health,
}

fn json_of_grasp(g: &pb::Grasp) -> serde_json::Value {
    let pose = g.pose.unwrap_or_default();
    let p = pose.position.unwrap_or_default();
    let q = pose.orientation.unwrap_or_default();
    serde_json::json!({
        "object_id": g.object_id, "quality": g.quality, "width_m": g.width_m,
        "view": pb::ViewAxis::try_from(g.view).map_or("unknown", |v| v.as_str_name()),
        "pixel": [g.pixel_u, g.pixel_v], "angle_rad": g.angle_rad,
        "position": [p.x, p.y, p.z], "orientation_xyzw": [q.x, q.y, q.z, q.w],
    })
}

fn json_of_response(r: &pb::PlanGraspsResponse) -> serde_json::Value {
    let t = r.timings.unwrap_or_default();
    serde_json::json!({
        "request_id": r.request_id,
        "model_version": r.model_version,
        "grasps": r.grasps.iter().map(json_of_grasp).collect::<Vec<_>>(),
        "ranked_after_turned_away": r.ranked_after_turned_away,
        "ranked_last_out_of_view": r.ranked_last_out_of_view,
        "outside_approach_cone": r.outside_approach_cone,
        "out_of_reach": r.out_of_reach,
        "objects": r.objects.iter().map(|o| {
            let c = o.world_from_object.unwrap_or_default().position.unwrap_or_default();
            serde_json::json!({
                "id": o.id, "centroid": [c.x, c.y, c.z], "point_count": o.point_count,
                "refused": refusal_counts(o).into_iter().collect::<serde_json::Map<_, _>>(),
                "views": o.views.iter().map(|v| serde_json::json!({
                    "axis": pb::ViewAxis::try_from(v.axis).map_or("unknown", |a| a.as_str_name()),
                    "entropy": v.entropy, "inferred": v.inferred,
                })).collect::<Vec<_>>(),
            })
        }).collect::<Vec<_>>(),
        "obstacles": r.obstacles.iter().map(|o| {
            let (lo, hi) = (o.min.unwrap_or_default(), o.max.unwrap_or_default());
            serde_json::json!({
                "min": [lo.x, lo.y, lo.z], "max": [hi.x, hi.y, hi.z], "point_count": o.point_count,
                "object_id": o.object_id,
            })
        }).collect::<Vec<_>>(),
        "obstacles_dropped": r.obstacles_dropped,
        "timings_ms": {
            "sensor": t.sensor_ms, "table": t.table_ms, "objects": t.objects_ms, "cluster": t.cluster_ms,
            "frames": t.frames_ms, "views": t.views_ms, "select": t.select_ms,
            "inference": t.inference_ms, "decode": t.decode_ms, "total": t.total_ms,
        },
    })
}

/// An object's candidate grasps lost, by cause (the answer's `refused`):
/// each cause's name, how `plan` words it, and the count.
fn refusals(o: &pb::DetectedObject) -> [(&'static str, &'static str, u32); 7] {
    let r = o.refused.unwrap_or_default();
    [
        ("table", "hit the table", r.table),
        ("neighbour", "hit a neighbour", r.neighbour),
        ("own_points", "hit the object's own points", r.own_points),
        (
            "outside_approach_cone",
            "outside the approach cone",
            r.outside_approach_cone,
        ),
        ("out_of_reach", "out of the arm's reach", r.out_of_reach),
        ("too_wide", "wider than the gripper opens", r.too_wide),
        ("no_pose", "no pose at the peak", r.no_pose),
    ]
}

/// An object's refusals by cause, as JSON fields.
fn refusal_counts(o: &pb::DetectedObject) -> Vec<(String, serde_json::Value)> {
    refusals(o)
        .into_iter()
        .map(|(cause, _, n)| (cause.to_owned(), n.into()))
        .collect()
}

/// Why an object got no grasp, from its refusals: e.g. "3 hit the table,
/// 2 out of the arm's reach".
fn no_grasp_reason(o: &pb::DetectedObject) -> String {
    let parts: Vec<String> = refusals(o)
        .iter()
        .filter(|(_, _, n)| *n > 0)
        .map(|(_, why, n)| format!("{n} {why}"))
        .collect();
    if parts.is_empty() {
        "none refused: no peak cleared min_quality in its views, or the answer was full".to_owned()
    } else {
        format!("candidates refused: {}", parts.join(", "))
    }
}

/// What the grasps at the end of the list are, in the order they come.
fn ranked_last_note(turned_away: u32, out_of_view: u32) -> String {
    let mut parts = Vec::new();
    if turned_away > 0 {
        parts.push(format!("{turned_away} turned away from a neighbour"));
    }
    if out_of_view > 0 {
        parts.push(format!("{out_of_view} reaching past the image border"));
    }
    if parts.is_empty() {
        String::new()
    } else {
        format!("; ranked last: {}", parts.join(", then "))
    }
}

fn print_table(r: &pb::PlanGraspsResponse) {
    println!(
        "{} objects, {} grasps (model {}){}",
        r.objects.len(),
        r.grasps.len(),
        r.model_version,
        ranked_last_note(r.ranked_after_turned_away, r.ranked_last_out_of_view)
    );
    println!("rank  object  view   quality  width_mm        x        y        z   approach");
    for (rank, g) in r.grasps.iter().enumerate() {
        let pose = g.pose.unwrap_or_default();
        let p = pose.position.unwrap_or_default();
        let q = pose.orientation.unwrap_or_default();
        let rotation = UnitQuaternion::from_quaternion(Quaternion::new(q.w, q.x, q.y, q.z));
        let a = rotation * Vector3::z();
        let view = pb::ViewAxis::try_from(g.view).map_or("?", |v| match v {
            pb::ViewAxis::Top => "top",
            pb::ViewAxis::Front => "front",
            pb::ViewAxis::Side => "side",
            pb::ViewAxis::TopFront => "top_front",
            pb::ViewAxis::TopSide => "top_side",
            pb::ViewAxis::Unspecified => "?",
        });
        println!(
            "{:>4}  {:>6}  {:<5}  {:>7.3}  {:>8.1}  {:>7.3}  {:>7.3}  {:>7.3}   ({:+.2}, {:+.2}, {:+.2})",
            rank + 1,
            g.object_id,
            view,
            g.quality,
            g.width_m * 1e3,
            p.x,
            p.y,
            p.z,
            a.x,
            a.y,
            a.z
        );
    }
    for o in &r.objects {
        if !r.grasps.iter().any(|g| g.object_id == o.id) {
            println!("object {}: no grasp ({})", o.id, no_grasp_reason(o));
        }
    }
    for o in &r.obstacles {
        let (lo, hi) = (o.min.unwrap_or_default(), o.max.unwrap_or_default());
        let whose = o
            .object_id
            .map_or(String::new(), |id| format!(", the rest of object {id}"));
        println!(
            "obstacle outside the workspace: x {:.3}..{:.3}, y {:.3}..{:.3}, z {:.3}..{:.3} m ({} points{whose})",
            lo.x, hi.x, lo.y, hi.y, lo.z, hi.z, o.point_count
        );
    }
    if r.obstacles_dropped > 0 {
        println!(
            "{} more obstacle boxes past the server's cap",
            r.obstacles_dropped
        );
    }
    if let Some(t) = r.timings {
        println!(
            "server: {:.2} ms (inference incl. batching {:.2} ms, other stages {:.2} ms)",
            t.total_ms,
            t.inference_ms,
            t.sensor_ms
                + t.table_ms
                + t.objects_ms
                + t.cluster_ms
                + t.frames_ms
                + t.views_ms
                + t.select_ms
                + t.decode_ms
        );
    }
}

/// A connection to `server`, each call with the deadline of `--timeout-ms` if given.
async fn connect(
    server: &str,
    timeout_ms: Option<u64>,
    credentials: &Credentials,
) -> anyhow::Result<PlannerClient> {
    let client = PlannerClient::connect_with(server, credentials).await?;
    Ok(match timeout_ms {
        Some(ms) => client.with_timeout(Duration::from_millis(ms)),
        None => client,
    })
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    let credentials = Credentials::from_files(
        cli.tls_ca.as_deref(),
        cli.tls_cert.as_deref().zip(cli.tls_key.as_deref()),
        cli.tls_domain.clone(),
        cli.token_file.as_deref(),
    )?;
    let mut client = connect(&cli.server, cli.timeout_ms, &credentials).await?;
    match cli.command {
        Command::Plan { scene, json, viz } => {
            let files = scene.load()?;
            let mut request = scene.request(&files);
            request.include_debug_views = viz.is_some();
            let response = client.plan(request).await?;
            if json {
                println!("{}", serde_json::to_string_pretty(&json_of_response(&response))?);
            } else {
                print_table(&response);
            }
            if let Some(path) = viz {
                viz::draw(&files, &response)?.save(&path)?;
                eprintln!("wrote {}", path.display());
            }
        }
        Command::Bench {
            scene,
            concurrency,
            connections,
            duration_s,
            count,
            rate,
            warmup,
            json,
        } => {
            let files = scene.load()?;
            let request = scene.request(&files);
            let duration = match (duration_s, count) {
                (None, None) => Some(Duration::from_secs(10)),
                (d, _) => d.map(Duration::from_secs_f64),
            };
            let bar = if let Some(n) = count {
                ProgressBar::new(n as u64)
            } else {
                ProgressBar::new_spinner()
            };
            bar.set_style(
                ProgressStyle::with_template(
                    "{spinner} [{elapsed_precise}] {bar:30} {pos} calls ({per_sec})",
                )
                .context("progress style")?,
            );
            let config = BenchConfig {
                concurrency,
                duration,
                count,
                rate,
                warmup,
            };
            let mut pool = vec![client];
            for _ in 1..connections {
                pool.push(connect(&cli.server, cli.timeout_ms, &credentials).await?);
            }
            let report = bench::run(&pool, &request, &config, Some(bar.clone())).await?;
            bar.finish_and_clear();
            if json {
                println!(
                    "{}",
                    serde_json::json!({
                        "concurrency": report.concurrency, "ok": report.ok, "errors": report.errors,
                        "elapsed_s": report.elapsed_s, "throughput_per_s": report.throughput_per_s,
                        "p50_ms": report.p50_ms, "p90_ms": report.p90_ms, "p99_ms": report.p99_ms,
                        "max_ms": report.max_ms, "server_p50_ms": report.server_p50_ms,
                        "mean_grasps": report.mean_grasps, "first_error": report.first_error,
                        "errors_by_code": report.errors_by_code, "error_p50_ms": report.error_p50_ms,
                        "error_p99_ms": report.error_p99_ms, "error_max_ms": report.error_max_ms,
                    })
                );
            } else {
                println!(
                    "concurrency {}: {} ok, {} errors in {:.1} s -> {:.1} calls/s; latency p50 {:.2} ms, p90 {:.2} ms, p99 {:.2} ms, max {:.2} ms; server p50 {:.2} ms; {:.1} grasps/answer",
                    report.concurrency,
                    report.ok,
                    report.errors,
                    report.elapsed_s,
                    report.throughput_per_s,
                    report.p50_ms,
                    report.p90_ms,
                    report.p99_ms,
                    report.max_ms,
                    report.server_p50_ms,
                    report.mean_grasps
                );
            }
            if let Some(e) = report.first_error {
                eprintln!(
                    "first error: {e}; errors by code {:?}, time to the error p50 {:.2} ms, p99 {:.2} ms",
                    report.errors_by_code, report.error_p50_ms, report.error_p99_ms
                );
            }
            // Each connection keeps its own tally of the replicas: summed.
            let mut replicas: Vec<ReplicaStats> = Vec::new();
            for o in pool.iter().flat_map(PlannerClient::replicas) {
                match replicas.iter_mut().find(|r| r.endpoint == o.endpoint) {
                    Some(r) => {
                        r.answered += o.answered;
                        r.unavailable += o.unavailable;
                        r.down |= o.down;
                    }
                    None => replicas.push(o),
                }
            }
            if replicas.len() > 1 {
                for r in replicas {
                    eprintln!(
                        "replica {}: {} answered, {} unavailable{}",
                        r.endpoint,
                        r.answered,
                        r.unavailable,
                        if r.down { " (sitting out)" } else { "" }
                    );
                }
                let retries: u64 = pool.iter().map(PlannerClient::retries).sum();
                eprintln!("{retries} calls retried on another replica");
            }
        }
        Command::Info => {
            let info = client.model_info().await?;
            println!(
                "model {} (data {}), backend {}, input {} px of {} mm, width scale {} m, outputs [{}], normalisation {}, max batch {} views, server {}",
                info.model_version,
                info.data_version,
                info.backend,
                info.input_size_px,
                info.pixel_size_m * 1e3,
                info.width_scale_m,
                info.outputs.join(", "),
                info.normalisation,
                info.max_batch_views,
                info.server_version
            );
        }
        Command::Health => {
            let status = client.health().await?;
            println!("{}", status.as_str_name());
            if status != tonic_health::pb::health_check_response::ServingStatus::Serving {
                std::process::exit(1);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An object without a grasp says why: its refusals by cause, or that
    /// none was refused.
    #[test]
    fn an_object_without_a_grasp_says_why() {
        let object = |refused: pb::ObjectRefusals| pb::DetectedObject {
            refused: Some(refused),
            ..Default::default()
        };
        let refused = object(pb::ObjectRefusals {
            table: 1,
            out_of_reach: 3,
            too_wide: 2,
            ..Default::default()
        });
        assert_eq!(
            no_grasp_reason(&refused),
            "candidates refused: 1 hit the table, 3 out of the arm's reach, 2 wider than the gripper opens"
        );
        let counts = refusal_counts(&refused);
        assert_eq!(counts.len(), 7);
        assert!(counts.contains(&("too_wide".to_owned(), 2.into())));
        assert!(counts.contains(&("out_of_reach".to_owned(), 3.into())));
        assert!(no_grasp_reason(&object(Default::default())).starts_with("none refused"));
    }
}
