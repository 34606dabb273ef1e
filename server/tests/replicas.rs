//! Three server processes behind one client address list, 16 callers; one
//! replica killed mid-run (SIGKILL), a second stopped (SIGTERM) later: the
//! calls go on on those left, none is lost.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::{
    net::TcpListener,
    path::PathBuf,
    process::{Child, Command, Stdio},
    sync::{
        Arc,
        atomic::{AtomicBool, Ordering},
    },
    time::{Duration, Instant},
};

use mvgrasp_client::{PlannerClient, scene::SceneFiles};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A port nothing listens on now (the server binds it a moment later).
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A server process on the analytic backend (no model, no ONNX Runtime).
struct Replica {
    child: Child,
    address: String,
}

impl Replica {
    fn start() -> Self {
        let port = free_port();
        let child = Command::new(env!("CARGO_BIN_EXE_mvgrasp-server"))
            .args(["--backend", "baseline", "--no-metrics", "--listen"])
            .arg(format!("127.0.0.1:{port}"))
            .env("MVGRASP_LOG", "warn")
            .stdout(Stdio::null())
            .spawn()
            .expect("server starts");
        Self {
            child,
            address: format!("http://127.0.0.1:{port}"),
        }
    }
}

impl Drop for Replica {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

async fn until_serving(address: &str) {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        if let Ok(mut c) = PlannerClient::connect(address).await
            && c.health().await.is_ok()
        {
            return;
        }
        assert!(Instant::now() < deadline, "{address} did not come up");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

#[derive(Default)]
struct Tally {
    answered: usize,
    answered_after_kill: usize,
    errors: Vec<String>,
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn calls_survive_a_replica_killed_mid_run() {
    let mut replicas: Vec<Replica> = (0..3).map(|_| Replica::start()).collect();
    for r in &replicas {
        until_serving(&r.address).await;
    }
    let addresses: Vec<String> = replicas.iter().map(|r| r.address.clone()).collect();
    let list = addresses.join(",");
    let scene = SceneFiles::load_depth(
        &repo().join("samples/table6/depth.png"),
        &repo().join("samples/table6/camera.json"),
    )
    .unwrap();
    let request = scene.request();

    let killed = Arc::new(AtomicBool::new(false));
    let run_for = Duration::from_secs(9);
    let start = Instant::now();
    let mut callers = Vec::new();
    let mut clients = Vec::new();
    for _ in 0..16 {
        // One client per robot, each with its own connections and turn order.
        let client = PlannerClient::connect(&list)
            .await
            .unwrap()
            .with_timeout(Duration::from_secs(30));
        clients.push(client.clone());
        let (mut client, request, killed) = (client, request.clone(), Arc::clone(&killed));
        callers.push(tokio::spawn(async move {
            let mut tally = Tally::default();
            while start.elapsed() < run_for {
                match client.plan(request.clone()).await {
                    Ok(answer) => {
                        assert_eq!(answer.objects.len(), 6);
                        tally.answered += 1;
                        if killed.load(Ordering::SeqCst) {
                            tally.answered_after_kill += 1;
                        }
                    }
                    Err(e) => tally.errors.push(format!("{e:?}")),
                }
            }
            tally
        }));
    }
    tokio::time::sleep(Duration::from_secs(3)).await;
    // SIGKILL: no goodbye, calls in flight on it break.
    replicas[1].child.kill().unwrap();
    replicas[1].child.wait().unwrap();
    killed.store(true, Ordering::SeqCst);
    tokio::time::sleep(Duration::from_secs(2)).await;
    // SIGTERM: the replica drains and closes; calls racing its close retry.
    let stopped = Command::new("kill")
        .args(["-TERM", &replicas[2].child.id().to_string()])
        .status()
        .unwrap();
    assert!(stopped.success());
    replicas[2].child.wait().unwrap();

    let mut total = Tally::default();
    for caller in callers {
        let t = caller.await.unwrap();
        total.answered += t.answered;
        total.answered_after_kill += t.answered_after_kill;
        total.errors.extend(t.errors);
    }
    let mut answered = [0u64; 3];
    let mut unavailable = [0u64; 3];
    let mut retries = 0;
    for c in &clients {
        for (i, r) in c.replicas().iter().enumerate() {
            assert_eq!(r.endpoint.trim_end_matches('/'), addresses[i]);
            answered[i] += r.answered;
            unavailable[i] += r.unavailable;
        }
        retries += c.retries();
    }
    eprintln!(
        "{} calls answered ({} after the kill); per replica answered {answered:?}, unavailable {unavailable:?}; {retries} retried",
        total.answered, total.answered_after_kill
    );
    assert!(
        total.errors.is_empty(),
        "{} lost calls (replicas {addresses:?}): {:?}",
        total.errors.len(),
        total.errors
    );
    assert!(
        total.answered_after_kill >= 16,
        "{} answered after the kill",
        total.answered_after_kill
    );

    assert!(
        answered.iter().all(|&n| n > 0),
        "every replica served before the kill: {answered:?}"
    );
    assert!(
        unavailable[1] > 0,
        "calls met the killed replica and were retried"
    );
    assert_eq!(
        retries,
        unavailable.iter().sum::<u64>(),
        "each unavailable call retried once"
    );
    assert_eq!(answered.iter().sum::<u64>() as usize, total.answered);

    // A call the planner refuses is not retried elsewhere (two entries for
    // the replica left: a retry would find the second).
    let survivor = &addresses[0];
    let mut client = PlannerClient::connect(&format!("{survivor},{survivor}"))
        .await
        .unwrap();
    let mut bad = request.clone();
    bad.world_from_camera = None;
    let refused = client.plan(bad).await.unwrap_err();
    assert!(
        matches!(&refused, mvgrasp_client::Error::Rpc(s) if s.code() == tonic::Code::InvalidArgument),
        "{refused}"
    );
    assert_eq!(client.retries(), 0);
    assert_eq!(client.replicas().iter().map(|r| r.answered).sum::<u64>(), 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_frozen_planner_is_given_up_at_the_deadline() {
    let replica = Replica::start();
    until_serving(&replica.address).await;
    let mut client = PlannerClient::connect(&replica.address)
        .await
        .unwrap()
        .with_timeout(Duration::from_secs(1));
    let pid = replica.child.id().to_string();
    // SIGSTOP: the connection stays up, the process answers nothing.
    assert!(
        Command::new("kill")
            .args(["-STOP", &pid])
            .status()
            .unwrap()
            .success()
    );
    let scene = SceneFiles::load_depth(
        &repo().join("samples/table6/depth.png"),
        &repo().join("samples/table6/camera.json"),
    )
    .unwrap();
    let started = Instant::now();
    let err = client.plan(scene.request()).await.unwrap_err();
    let waited = started.elapsed();
    assert!(
        Command::new("kill")
            .args(["-CONT", &pid])
            .status()
            .unwrap()
            .success()
    );
    assert!(
        matches!(&err, mvgrasp_client::Error::Rpc(s) if s.code() == tonic::Code::DeadlineExceeded),
        "{err}"
    );
    assert!(
        waited >= Duration::from_secs(1) && waited < Duration::from_secs(10),
        "gave up after {waited:?}: the deadline is 1 s (the upper bound only catches a hang)"
    );
    // Thawed, it answers again on the same client.
    assert!(client.plan(scene.request()).await.is_ok());
}
