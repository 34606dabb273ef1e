//! The bridge from the committed sample frame: planning locally or remotely, the approach cone, the CLI.

use super::*;
use robot_bridge::execute::{Controller, PickOutcome, execute_pick};
use robot_bridge::gripper::Gripper;
use robot_bridge::planner::{Ask, load_scene, plan_locally, plan_remotely};

fn sample(file: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../samples/table6")
        .join(file)
}

/// `robot-bridge pick --dry-run` on the committed sample frame, with `args` after.
fn dry_run<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_robot-bridge"))
        .args(["pick", "--dry-run", "--depth"])
        .arg(sample("depth.png"))
        .arg("--camera")
        .arg(sample("camera.json"))
        .args(args)
        .output()
        .expect("runs the CLI")
}

/// With the cell's approach cone the planner offers only approaches
/// within it (here: from above within 20 degrees).
#[test]
fn the_planner_is_asked_for_the_cells_approaches_only() {
    let scene = load_scene(&sample("depth.png"), &sample("camera.json")).expect("sample scene");
    let cone =
        mvgrasp_core::ApproachCone::new(Vector3::new(0.0, 0.0, -1.0), 20f64.to_radians()).expect("cone");
    let ask = Ask {
        approach_cone: Some(cone),
        ..Ask::any(50)
    };
    let planned = plan_locally(&scene, &ask).expect("planned");
    assert!(!planned.grasps.is_empty());
    for g in &planned.grasps {
        let approach = g.world_from_grasp.rotation * Vector3::z();
        assert!(approach.z <= -(20f64.to_radians().cos()) + 1e-9, "{approach:?}");
    }
}

/// The committed sample frame -> in-process planner -> collision-checked
/// pick -> run on the emulator: the object is placed.
#[test]
fn the_sample_scene_is_picked_end_to_end() {
    let scene = load_scene(&sample("depth.png"), &sample("camera.json")).expect("sample scene");
    assert_eq!((scene.width, scene.height), (640, 480));
    let planned = plan_locally(&scene, &Ask::any(10)).expect("planned");
    assert_eq!(planned.objects.len(), 6);
    assert!(!planned.grasps.is_empty());
    // The documented defaults (base, drop pose, basket obstacle), faster for the test.
    let mut config = robot_bridge::config::BridgeConfig::default()
        .pick_config()
        .expect("config");
    assert_eq!(config.obstacles.len(), 1, "the basket");
    config.obstacles.push(planned.table.clone());
    config.joint_speed = 3.0;
    config.tool_speed = 0.5;
    let plan = plan_pick(
        &Ur5e::default(),
        &config,
        &planned.grasps,
        &planned.objects,
        &HOME,
    )
    .expect("plan");
    let emu = emulator();
    let mut gripper = Gripper::connect(emu.gripper_address, 0.14, TIMEOUT).expect("gripper");
    gripper.activate().expect("activate");
    let mut controller = Controller {
        rtde: RtdeClient::connect(emu.rtde_address, 125.0, TIMEOUT).expect("rtde"),
        script_address: emu.script_address,
        gripper,
        io_timeout: TIMEOUT,
        motion_timeout: Duration::from_secs(10),
    };
    let outcome = execute_pick(&mut controller, &plan, &config).expect("pick");
    assert!(matches!(outcome, PickOutcome::Placed { .. }), "{outcome:?}");
}

#[test]
fn missing_or_bad_files_name_the_problem() {
    let err = load_scene(&sample("nope.png"), &sample("camera.json")).expect_err("missing");
    assert!(err.to_string().contains("nope.png"), "{err}");
    let dir = std::env::temp_dir().join(format!("rb-bad-camera-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let bad = dir.join("camera.json");
    std::fs::write(
        &bad,
        r#"{"intrinsics": {"fx": 600, "fy": 600, "cx": 320},
            "world_from_camera": {"position": [0, 0, 1], "orientation": [1, 0, 0, 0]}}"#,
    )
    .expect("write");
    let err = load_scene(&sample("depth.png"), &bad).expect_err("bad camera");
    assert!(err.to_string().contains("intrinsics.cy"), "{err}");
}

/// The service (baseline backend) plans exactly what the in-process
/// planner plans: same pipeline, same network, over gRPC.
#[test]
fn the_service_plans_what_the_in_process_planner_plans() {
    let runtime = tokio::runtime::Runtime::new().expect("runtime");
    let mut settings = mvgrasp_server::Settings {
        listen: "127.0.0.1:0".parse().expect("address"),
        metrics_listen: None,
        ..Default::default()
    };
    settings.model.backend = mvgrasp_server::BackendKind::Baseline;
    let server = runtime.block_on(mvgrasp_server::start(settings)).expect("server");
    let scene = load_scene(&sample("depth.png"), &sample("camera.json")).expect("sample scene");
    // The documented defaults' ask, the arm's reach included.
    let ask = robot_bridge::config::BridgeConfig::default()
        .ask(&Ur5e::default(), &HOME)
        .expect("ask");
    assert!(ask.arm_reach.is_some() && !ask.robot_body.is_empty());
    let local = plan_locally(&scene, &ask).expect("local");
    let remote = plan_remotely(
        &format!("http://{}", server.addr),
        &Default::default(),
        &scene,
        &ask,
        TIMEOUT,
    )
    .expect("remote");
    assert!(remote.planner.contains("baseline-moments"), "{}", remote.planner);
    assert_eq!(remote.grasps.len(), local.grasps.len());
    assert!(!remote.grasps.is_empty());
    for (r, l) in remote.grasps.iter().zip(&local.grasps) {
        let d = r.world_from_grasp.inverse() * l.world_from_grasp;
        assert!(d.translation.vector.norm() < 1e-9 && d.rotation.angle() < 1e-9);
        assert_eq!((r.width_m, r.quality, r.object), (l.width_m, l.quality, l.object));
    }
    assert_eq!(remote.objects.len(), 6);
    for (r, l) in remote.objects.iter().zip(&local.objects) {
        assert!((r.half_extents_m - l.half_extents_m).norm() < 1e-9);
        assert!((r.world_from_box.translation.vector - l.world_from_box.translation.vector).norm() < 1e-9);
    }
    assert!(
        (remote.table.world_from_box.translation.vector - local.table.world_from_box.translation.vector)
            .norm()
            < 1e-9
    );
    runtime.block_on(server.shutdown()).expect("shutdown");
}

#[test]
fn a_planner_that_is_down_is_a_clear_error() {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("free port")
        .port();
    let scene = load_scene(&sample("depth.png"), &sample("camera.json")).expect("sample scene");
    let endpoint = format!("http://127.0.0.1:{port}");
    let err = plan_remotely(&endpoint, &Default::default(), &scene, &Ask::any(10), TIMEOUT)
        .expect_err("nothing listens there");
    assert!(
        matches!(err, Error::Io(_)) && err.to_string().contains(&endpoint),
        "{err}"
    );
}

#[test]
fn a_planner_that_asks_for_a_token_gets_the_configured_one() {
    let runtime = tokio::runtime::Runtime::new().expect("runtime");
    let dir = std::env::temp_dir().join(format!("rb-token-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    std::fs::write(dir.join("token"), "cell-4-token\n").expect("write");
    let mut settings = mvgrasp_server::Settings {
        listen: "127.0.0.1:0".parse().expect("address"),
        metrics_listen: None,
        ..Default::default()
    };
    settings.model.backend = mvgrasp_server::BackendKind::Baseline;
    settings.security.bearer_token_file = Some(dir.join("token"));
    let server = runtime.block_on(mvgrasp_server::start(settings)).expect("server");
    let endpoint = format!("http://{}", server.addr);
    let scene = load_scene(&sample("depth.png"), &sample("camera.json")).expect("sample scene");
    let err =
        plan_remotely(&endpoint, &Default::default(), &scene, &Ask::any(10), TIMEOUT).expect_err("no token");
    assert!(err.to_string().contains("Bearer"), "{err}");
    let config: robot_bridge::config::BridgeConfig = toml::from_str(&format!(
        "[planner]\nendpoint = \"{endpoint}\"\ntoken_file = \"{}\"\n",
        dir.join("token").display()
    ))
    .expect("config");
    let credentials = config.planner_credentials().expect("credentials");
    let planned =
        plan_remotely(&endpoint, &credentials, &scene, &Ask::any(10), TIMEOUT).expect("with the token");
    assert_eq!(planned.objects.len(), 6);
    runtime.block_on(server.shutdown()).expect("shutdown");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_planner_that_does_not_answer_is_a_clear_error_within_the_deadline() {
    // Accepts connections and never says a word.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let port = listener.local_addr().expect("address").port();
    std::thread::spawn(move || {
        let held: Vec<_> = listener.incoming().collect();
        drop(held);
    });
    let scene = load_scene(&sample("depth.png"), &sample("camera.json")).expect("sample scene");
    let endpoint = format!("http://127.0.0.1:{port}");
    let start = Instant::now();
    let err =
        plan_remotely(&endpoint, &Default::default(), &scene, &Ask::any(10), TIMEOUT).expect_err("no answer");
    let waited = start.elapsed();
    assert!(err.to_string().contains(&endpoint), "{err}");
    assert!(
        waited < TIMEOUT * 3,
        "gave up after {waited:?}, deadline {TIMEOUT:?}"
    );
}

#[test]
fn the_cli_reads_its_config_and_names_a_bad_key() {
    let dir = std::env::temp_dir().join(format!("rb-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let good = dir.join("bridge.toml");
    std::fs::write(&good, "[pick]\npregrasp_m = 0.12\n[robot]\ntool_speed = 0.05\n").expect("write");
    let out = dry_run(&[std::ffi::OsStr::new("--config"), good.as_os_str()]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        stdout.contains("movel(") && stdout.contains("v=0.050)"),
        "{stdout}"
    );
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[robot]\njoint_speed = 7.0\n").expect("write");
    let out = dry_run(&[std::ffi::OsStr::new("--config"), bad.as_os_str()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("robot.joint_speed"));
}

#[test]
fn the_cli_dry_run_prints_a_script() {
    let out = dry_run::<&str>(&[]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("6 objects") && stdout.contains("def mvgrasp_pick():"),
        "{stdout}"
    );
}

/// `pick --failed-picks FILE`: the grasp the dry run picks, written to the
/// file as a pick that came up empty, is not the one picked next (the file
/// itself is left alone by a dry run); a bad line is named.
#[test]
fn the_cli_tries_a_grasp_that_came_up_empty_last() {
    let dir = std::env::temp_dir().join(format!("rb-failed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let run = |failed: Option<&std::path::Path>| match failed {
        Some(path) => dry_run(&[std::ffi::OsStr::new("--failed-picks"), path.as_os_str()]),
        None => dry_run::<&str>(&[]),
    };
    let picked = |out: &std::process::Output| -> usize {
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{stdout}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let line = stdout
            .lines()
            .find(|l| l.starts_with("picking grasp "))
            .expect("picking line");
        line["picking grasp ".len()..]
            .split(' ')
            .next()
            .and_then(|n| n.parse().ok())
            .expect("rank")
    };
    let first = picked(&run(None));
    // The same grasps as the CLI's: the in-process planner, the default request.
    let scene = load_scene(&sample("depth.png"), &sample("camera.json")).expect("sample scene");
    let ask = robot_bridge::config::BridgeConfig::default()
        .ask(&Ur5e::default(), &HOME)
        .expect("ask");
    let planned = plan_locally(&scene, &ask).expect("planned");
    let file = dir.join("failed.jsonl");
    let line = robot_bridge::pick::failed_pick_line(&planned.grasps[first - 1].world_from_grasp);
    std::fs::write(&file, format!("{line}\n")).expect("write");
    let second = picked(&run(Some(&file)));
    assert_ne!(second, first);
    assert_eq!(std::fs::read_to_string(&file).expect("read"), format!("{line}\n"));
    // No file yet: nothing failed.
    assert_eq!(picked(&run(Some(&dir.join("none.jsonl")))), first);
    std::fs::write(&file, "{\"position\": [0, 0]}\n").expect("write");
    let out = run(Some(&file));
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("line 1"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `pick --basket-count FILE` with `release_spread_m`: the count chooses the
/// spot over the basket, four in turn (a missing file is 0); a dry run
/// leaves the file alone; a file that holds no number is named.
#[test]
fn the_cli_lets_go_over_the_spot_the_basket_count_chooses() {
    let dir = std::env::temp_dir().join(format!("rb-basket-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let config = dir.join("bridge.toml");
    std::fs::write(&config, "[pick]\nrelease_spread_m = 0.06\n").expect("write");
    let count = dir.join("count");
    let script = |n: Option<&str>| {
        match n {
            Some(text) => std::fs::write(&count, text).expect("write"),
            None => {
                let _ = std::fs::remove_file(&count);
            }
        }
        let out = dry_run(&[
            std::ffi::OsStr::new("--config"),
            config.as_os_str(),
            std::ffi::OsStr::new("--basket-count"),
            count.as_os_str(),
        ]);
        if let Some(text) = n {
            assert_eq!(std::fs::read_to_string(&count).expect("read"), text);
        }
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let over_the_basket = |n: Option<&str>| {
        let (ok, stdout, stderr) = script(n);
        assert!(ok, "{stdout}\n{stderr}");
        stdout
            .lines()
            .find(|l| l.trim_start().starts_with("movej  over the basket"))
            .expect("over the basket")
            .to_owned()
    };
    let spots: Vec<String> = ["0", "1", "2", "3"]
        .iter()
        .map(|n| over_the_basket(Some(n)))
        .collect();
    for (i, a) in spots.iter().enumerate() {
        for b in &spots[i + 1..] {
            assert_ne!(a, b, "four spots");
        }
    }
    assert_eq!(over_the_basket(None), spots[0]);
    assert_eq!(over_the_basket(Some("5\n")), spots[1]);
    let (ok, _, stderr) = script(Some("two"));
    assert!(!ok);
    assert!(stderr.contains("one whole number"), "{stderr}");
}
