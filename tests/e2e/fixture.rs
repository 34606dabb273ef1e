//! Servers started in-process on ephemeral ports, and rendered frames as requests.

use std::{path::PathBuf, time::Duration};

use mvgrasp_client::{PlannerClient, pb};
use mvgrasp_core::{GraspMaps, GraspNet, ModelContract, MomentsNet, ViewBatch};
use mvgrasp_server::{BackendKind, RunningServer, Settings, backend::LoadedNet};
use nalgebra::Point3;

use crate::scene::{Camera, Scene, render};

/// The repository root.
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The ONNX Runtime library: `MVGRASP_ONNXRUNTIME`, else where
/// `scripts/fetch-onnxruntime.sh` puts it.
pub fn onnxruntime() -> PathBuf {
    let path = std::env::var_os("MVGRASP_ONNXRUNTIME")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo().join("target/onnxruntime/libonnxruntime.so.1.31.1"));
    assert!(
        path.exists(),
        "{} is missing: run scripts/fetch-onnxruntime.sh (scripts/test.sh does)",
        path.display()
    );
    path
}

/// `models/fixtures/tiny.onnx` (closed-form outputs; see make_fixtures.py).
pub fn tiny_model() -> PathBuf {
    repo().join("models/fixtures/tiny.onnx")
}

/// Settings for a test server: ephemeral ports, the given backend.
pub fn settings(backend: BackendKind) -> Settings {
    let mut s = Settings {
        listen: "127.0.0.1:0".parse().unwrap(),
        metrics_listen: Some("127.0.0.1:0".parse().unwrap()),
        ..Settings::default()
    };
    s.model.backend = backend;
    s.model.path = tiny_model();
    s.model.onnxruntime_library = Some(onnxruntime());
    s.shutdown_grace_s = 5.0;
    s
}

/// Starts a server and connects a client to it.
pub async fn start(settings: Settings) -> (RunningServer, PlannerClient) {
    let server = mvgrasp_server::start(settings).await.expect("server starts");
    let client = connect(&server).await;
    (server, client)
}

/// Starts a server around `net`.
pub async fn start_with(settings: Settings, net: LoadedNet) -> (RunningServer, PlannerClient) {
    let server = mvgrasp_server::start_with_net(settings, net)
        .await
        .expect("server starts");
    let client = connect(&server).await;
    (server, client)
}

pub async fn connect(server: &RunningServer) -> PlannerClient {
    PlannerClient::connect(&format!("http://{}", server.addr))
        .await
        .expect("client connects")
}

/// The baseline network, slowed down by `delay` per call.
pub struct SlowNet {
    pub inner: MomentsNet,
    pub delay: Duration,
}

impl GraspNet for SlowNet {
    fn contract(&self) -> &ModelContract {
        self.inner.contract()
    }
    fn infer(&mut self, batch: &ViewBatch) -> mvgrasp_core::Result<GraspMaps> {
        std::thread::sleep(self.delay);
        self.inner.infer(batch)
    }
}

pub fn slow_net(delay: Duration) -> LoadedNet {
    LoadedNet {
        net: Box::new(SlowNet {
            inner: MomentsNet::default(),
            delay,
        }),
        more: Vec::new(),
        lone: None,
        backend: "test-slow",
    }
}

/// A rendered uint16 frame of `scene` as a request (workspace around the table).
pub fn request(scene: &Scene, camera: &Camera) -> pb::PlanGraspsRequest {
    let k = camera.intrinsics;
    let z = scene.table_z;
    mvgrasp_client::request::depth_request(
        camera.width,
        camera.height,
        &render(scene, camera).depth_mm,
        pb::CameraIntrinsics {
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
        },
        &camera.world_from_camera,
        Some((Point3::new(-0.6, -0.4, z - 0.05), Point3::new(0.6, 0.4, z + 0.4))),
    )
}

/// The metrics page of a server's `/metrics` listener.
pub async fn scrape(addr: std::net::SocketAddr) -> String {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut stream = tokio::net::TcpStream::connect(addr).await.unwrap();
    stream
        .write_all(b"GET /metrics HTTP/1.1\r\nHost: test\r\n\r\n")
        .await
        .unwrap();
    let mut body = String::new();
    stream.read_to_string(&mut body).await.unwrap();
    assert!(body.starts_with("HTTP/1.1 200"), "{body}");
    body
}

/// The value of the first sample line starting with `prefix`.
pub fn sample(metrics: &str, prefix: &str) -> f64 {
    metrics
        .lines()
        .find(|l| l.starts_with(prefix))
        .and_then(|l| l.rsplit(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no sample {prefix}"))
}
