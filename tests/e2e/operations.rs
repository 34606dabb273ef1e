//! Operating the service: health, reflection, metrics, deadlines, callers
//! that leave, batching across calls, and graceful shutdown.

use std::time::Duration;

use futures_util::StreamExt;
use mvgrasp_client::{Error, PlannerClient, pb};
use mvgrasp_server::BackendKind;
use nalgebra::Vector3;
use tonic::Code;
use tonic_health::pb::health_check_response::ServingStatus;
use tonic_reflection::pb::v1::{
    ServerReflectionRequest, server_reflection_client::ServerReflectionClient,
    server_reflection_request::MessageRequest, server_reflection_response::MessageResponse,
};

use crate::{
    fixture::{connect, request, sample, scrape, settings, slow_net, start, start_with},
    scene::{Camera, grid_scene},
};

fn frame() -> pb::PlanGraspsRequest {
    request(
        &grid_scene(0.0, 6, 3, 0.13),
        &Camera::orbit(Vector3::zeros(), 0.85, 50.0, -90.0),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn health_reflection_and_metrics() {
    let (server, mut client) = start(settings(BackendKind::Onnx)).await;
    assert_eq!(client.health().await.unwrap(), ServingStatus::Serving);

    let channel = tonic::transport::Endpoint::from_shared(format!("http://{}", server.addr))
        .unwrap()
        .connect()
        .await
        .unwrap();
    let mut reflection = ServerReflectionClient::new(channel);
    let ask = ServerReflectionRequest {
        host: String::new(),
        message_request: Some(MessageRequest::ListServices(String::new())),
    };
    let mut answers = reflection
        .server_reflection_info(futures_util::stream::iter(vec![ask]))
        .await
        .unwrap()
        .into_inner();
    let Some(MessageResponse::ListServicesResponse(list)) =
        answers.next().await.unwrap().unwrap().message_response
    else {
        panic!("no service list");
    };
    let names: Vec<String> = list.service.into_iter().map(|s| s.name).collect();
    assert!(names.contains(&"mvgrasp.v1.GraspPlanner".to_owned()), "{names:?}");
    assert!(names.contains(&"grpc.health.v1.Health".to_owned()), "{names:?}");

    let mut inferred_views = 0;
    let mut refused = [0u32; 7];
    let mut out_of_reach = 0;
    for call in 0..3 {
        let mut request = frame();
        if call == 2 {
            // An arm 10 m away: every candidate out of its reach.
            request.arm_reach = Some(pb::ArmReach {
                shoulder: Some(pb::Vector3 {
                    x: 10.0,
                    y: 0.0,
                    z: 0.2,
                }),
                axis: None,
                wrist_back_m: 0.33,
                approach_m: 0.1,
                max_m: 0.93,
                min_axis_m: 0.13,
            });
        }
        let response = client.plan(request).await.unwrap();
        out_of_reach += response.out_of_reach;
        for r in response.objects.iter().filter_map(|o| o.refused.as_ref()) {
            for (sum, n) in refused.iter_mut().zip([
                r.table,
                r.neighbour,
                r.own_points,
                r.outside_approach_cone,
                r.out_of_reach,
                r.too_wide,
                r.no_pose,
            ]) {
                *sum += n;
            }
        }
        inferred_views += response
            .objects
            .iter()
            .flat_map(|o| &o.views)
            .filter(|v| v.inferred)
            .count();
    }
    let _ = client.plan(Default::default()).await.unwrap_err();
    let metrics = scrape(server.metrics_addr.unwrap()).await;
    assert_eq!(
        sample(
            &metrics,
            "mvgrasp_requests_total{code=\"Ok\",method=\"PlanGrasps\"}"
        ),
        3.0
    );
    assert_eq!(
        sample(
            &metrics,
            "mvgrasp_requests_total{code=\"InvalidArgument\",method=\"PlanGrasps\"}"
        ),
        1.0
    );
    assert_eq!(sample(&metrics, "mvgrasp_objects_per_request_sum"), 18.0);
    assert!(metrics.contains("mvgrasp_grasps_refused_for_collision_total "));
    assert!(metrics.contains("mvgrasp_grasps_out_of_view_total "));
    assert!(metrics.contains("mvgrasp_grasps_turned_square_total "));
    assert!(metrics.contains("mvgrasp_grasps_turned_away_total "));
    assert!(metrics.contains("mvgrasp_lone_network_calls_total "));
    // Every network call timed, on one session or the other.
    assert_eq!(
        sample(
            &metrics,
            "mvgrasp_network_duration_seconds_count{session=\"lone\"}"
        ) + sample(
            &metrics,
            "mvgrasp_network_duration_seconds_count{session=\"shared\"}"
        ),
        sample(&metrics, "mvgrasp_batch_views_count")
    );
    // One view per object, and the next ones of objects the view cascade sent on.
    assert!(inferred_views >= 18);
    assert_eq!(sample(&metrics, "mvgrasp_batch_views_sum"), inferred_views as f64);
    assert!(
        sample(
            &metrics,
            "mvgrasp_stage_duration_seconds_count{stage=\"cluster\"}"
        ) >= 3.0
    );
    assert!(metrics.contains("mvgrasp_model_info{backend=\"onnxruntime-cpu\""));
    assert_eq!(sample(&metrics, "mvgrasp_queued_views"), 0.0);
    // The answers' per-object refusals, summed by cause.
    for (cause, n) in [
        "table",
        "neighbour",
        "own_points",
        "outside_approach_cone",
        "out_of_reach",
        "too_wide",
        "no_pose",
    ]
    .iter()
    .zip(refused)
    {
        let name = format!("mvgrasp_grasp_candidates_refused_total{{cause=\"{cause}\"}}");
        assert_eq!(sample(&metrics, &name), f64::from(n), "{cause}");
    }
    assert!(refused.iter().sum::<u32>() > 0, "{refused:?}");
    assert!(
        out_of_reach > 0 && out_of_reach == refused[4],
        "{out_of_reach} {refused:?}"
    );
    assert_eq!(
        sample(&metrics, "mvgrasp_grasps_out_of_reach_total"),
        f64::from(out_of_reach)
    );
    // Limits are exported for the alerts; label values exist before their first event.
    assert_eq!(sample(&metrics, "mvgrasp_queued_views_limit"), 2048.0);
    assert!(sample(&metrics, "mvgrasp_in_flight_requests_limit") > 0.0);
    assert_eq!(
        sample(&metrics, "mvgrasp_dropped_views_total{reason=\"queue_full\"}"),
        0.0
    );
    assert_eq!(
        sample(
            &metrics,
            "mvgrasp_requests_total{code=\"Ok\",method=\"StreamGrasps\"}"
        ),
        0.0
    );
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn deadlines_and_callers_that_leave() {
    let mut s = settings(BackendKind::Baseline);
    s.batching.max_wait_ms = 0.0;
    let (server, client) = start_with(s, slow_net(Duration::from_millis(1500))).await;
    let metrics_addr = server.metrics_addr.unwrap();
    // A caller that gives up while queued behind another call: its views never reach the network.
    let mut first = client.clone();
    let busy = tokio::spawn(async move { first.plan(frame()).await });
    // Wait until the first call's views are in the network (generous for busy machines).
    for _ in 0..500 {
        let m = scrape(metrics_addr).await;
        if sample(&m, "mvgrasp_batch_views_count") >= 1.0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let mut second = client.clone();
    let gone = tokio::time::timeout(Duration::from_millis(700), second.plan(frame())).await;
    assert!(gone.is_err(), "the second call should still be queued");
    assert!(busy.await.unwrap().is_ok());
    tokio::time::sleep(Duration::from_millis(100)).await;
    let metrics = scrape(metrics_addr).await;
    assert_eq!(
        sample(&metrics, "mvgrasp_dropped_views_total{reason=\"caller_gone\"}"),
        6.0,
        "{metrics}"
    );
    // A deadline shorter than the network call.
    let mut hurried = client.clone().with_timeout(Duration::from_millis(400));
    match hurried.plan(frame()).await {
        Err(Error::Rpc(status)) => assert!(
            matches!(status.code(), Code::DeadlineExceeded | Code::Cancelled),
            "{status:?}"
        ),
        other => panic!("expected a deadline error, got {other:?}"),
    }
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn concurrent_calls_share_network_batches() {
    let mut s = settings(BackendKind::Baseline);
    // Generous: calls still in their CPU stages are waited for, up to this.
    s.batching.max_wait_ms = 300.0;
    s.batching.max_batch_views = 64;
    let (server, client) = start_with(s, slow_net(Duration::from_millis(30))).await;
    let calls: Vec<_> = (0..8)
        .map(|_| {
            let mut c = client.clone();
            // One network round per call (no view cascade): 8 requests to batch.
            tokio::spawn(async move {
                c.plan(pb::PlanGraspsRequest {
                    view_cascade: Some(false),
                    ..frame()
                })
                .await
            })
        })
        .collect();
    for call in calls {
        assert_eq!(call.await.unwrap().unwrap().objects.len(), 6);
    }
    let metrics = scrape(server.metrics_addr.unwrap()).await;
    let requests = sample(&metrics, "mvgrasp_batch_requests_sum");
    let batches = sample(&metrics, "mvgrasp_batch_requests_count");
    assert_eq!(requests, 8.0);
    assert!(batches < 8.0, "8 concurrent calls ran in {batches} network calls");
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_sessions_answer_concurrent_calls_as_one_does() {
    let mut s = settings(BackendKind::Onnx);
    s.model.sessions = 2;
    s.batching.max_batch_views = 8; // a call's 6 views fill a batch: both sessions get work
    let (server, client) = start(s).await;
    let mut lone = client.clone();
    let expected = lone.plan(frame()).await.unwrap();
    assert_eq!(expected.objects.len(), 6);
    let calls: Vec<_> = (0..8)
        .map(|_| {
            let mut c = client.clone();
            tokio::spawn(async move { c.plan(frame()).await })
        })
        .collect();
    for call in calls {
        let answer = call.await.unwrap().unwrap();
        assert_eq!(answer.grasps, expected.grasps);
        assert_eq!(answer.objects.len(), 6);
    }
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_drains_calls_in_flight() {
    let (server, client) = start_with(
        settings(BackendKind::Baseline),
        slow_net(Duration::from_millis(400)),
    )
    .await;
    let addr = server.addr;
    let mut caller = client.clone();
    let in_flight = tokio::spawn(async move { caller.plan(frame()).await });
    // Shut down once the server holds the call (on a busy machine the
    // request can take a while to arrive).
    let metrics = server.metrics_addr.unwrap();
    for _ in 0..500 {
        if sample(&scrape(metrics).await, "mvgrasp_in_flight_requests") >= 1.0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    server.shutdown().await.unwrap();
    let answer = in_flight.await.unwrap();
    assert!(answer.is_ok(), "the call in flight was cut: {answer:?}");
    assert!(PlannerClient::connect(&format!("http://{addr}")).await.is_err());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_client_connects_to_a_running_server() {
    let (server, _first) = start(settings(BackendKind::Onnx)).await;
    let mut second = connect(&server).await;
    let info = second.model_info().await.unwrap();
    assert_eq!(info.backend, "onnxruntime-cpu");
    assert_eq!(info.outputs, ["quality", "cos2phi", "sin2phi", "width"]);
    server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn calls_over_the_in_flight_limit_are_refused_at_once() {
    let mut s = settings(BackendKind::Onnx);
    s.limits.max_in_flight = 2;
    s.batching.max_wait_ms = 0.0;
    let (server, client) = start_with(s, slow_net(Duration::from_millis(400))).await;
    let calls: Vec<_> = (0..8)
        .map(|_| {
            let mut c = client.clone();
            tokio::spawn(async move { c.plan(frame()).await.map(|_| ()) })
        })
        .collect();
    let mut answered = 0;
    let mut refused = Vec::new();
    for call in calls {
        match call.await.unwrap() {
            Ok(()) => answered += 1,
            Err(Error::Rpc(status)) => {
                assert_eq!(status.code(), Code::ResourceExhausted, "{}", status.message());
                assert!(status.message().contains("limit is 2"), "{}", status.message());
                refused.push(status);
            }
            Err(other) => panic!("{other}"),
        }
    }
    assert!(answered >= 2, "{answered} answered");
    assert_eq!(answered + refused.len(), 8);
    assert!(!refused.is_empty());
    let metrics = scrape(server.metrics_addr.unwrap()).await;
    assert_eq!(
        sample(
            &metrics,
            "mvgrasp_requests_total{code=\"ResourceExhausted\",method=\"PlanGrasps\"}"
        ),
        refused.len() as f64
    );
    // Capacity comes back as calls end.
    assert!(client.clone().plan(frame()).await.is_ok());
    server.shutdown().await.unwrap();
}

/// The HTTP/2 settings the gRPC port announces: a depth frame (0.5-4 MB)
/// fits the flow-control windows whole, and arrives in frames of up to
/// 1 MiB instead of dozens of 16 KiB ones.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_grpc_port_takes_a_frame_in_large_http2_frames() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let (server, _client) = start(settings(BackendKind::Baseline)).await;
    let mut stream = tokio::net::TcpStream::connect(server.addr).await.unwrap();
    // The client preface and an empty SETTINGS frame.
    let mut hello = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n".to_vec();
    hello.extend_from_slice(&[0, 0, 0, 0x4, 0, 0, 0, 0, 0]);
    stream.write_all(&hello).await.unwrap();
    // The server's first frame is its SETTINGS: 9-byte header, then
    // 6-byte entries (16-bit id, 32-bit value).
    let mut header = [0u8; 9];
    stream.read_exact(&mut header).await.unwrap();
    assert_eq!(header[3], 0x4, "frame type: SETTINGS");
    let length = u32::from_be_bytes([0, header[0], header[1], header[2]]) as usize;
    let mut body = vec![0u8; length];
    stream.read_exact(&mut body).await.unwrap();
    let announced: std::collections::HashMap<u16, u32> = body
        .chunks_exact(6)
        .map(|e| {
            (
                u16::from_be_bytes([e[0], e[1]]),
                u32::from_be_bytes([e[2], e[3], e[4], e[5]]),
            )
        })
        .collect();
    assert_eq!(
        announced.get(&0x5),
        Some(&(1 << 20)),
        "MAX_FRAME_SIZE: {announced:?}"
    );
    assert_eq!(
        announced.get(&0x4),
        Some(&(8 << 20)),
        "INITIAL_WINDOW_SIZE: {announced:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bench_callers_take_turns_over_their_connections() {
    let (server, first) = start(settings(BackendKind::Baseline)).await;
    let second = connect(&server).await;
    let connections = [first, second];
    let config = mvgrasp_client::bench::BenchConfig {
        concurrency: 4,
        duration: None,
        count: Some(12),
        rate: None,
        warmup: 3,
    };
    let report = mvgrasp_client::bench::run(&connections, &frame(), &config, None)
        .await
        .unwrap();
    assert_eq!((report.ok, report.errors), (12, 0), "{:?}", report.first_error);
    // Every connection carried its share of the warm-up (3 over 2: 2 each)
    // and at least one call of each of its two callers (a caller takes its
    // first ticket at once).
    let answered: Vec<u64> = connections
        .iter()
        .map(|c| c.replicas().iter().map(|r| r.answered).sum())
        .collect();
    assert!(
        answered.iter().all(|&n| n >= 4),
        "calls per connection {answered:?}"
    );
    assert_eq!(answered.iter().sum::<u64>(), 12 + 4);

    // With no connection nothing is called.
    let none = mvgrasp_client::bench::run(&[], &frame(), &config, None)
        .await
        .unwrap();
    assert_eq!((none.ok, none.errors), (0, 0));
    server.shutdown().await.unwrap();
}
