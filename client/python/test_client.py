#!/usr/bin/env python3
"""A real cross-language call: the Python client against a running mvgrasp-server.

Usage: python3 client/python/test_client.py SERVER_BINARY ONNXRUNTIME_LIBRARY
Starts the server (tiny fixture model, ONNX Runtime CPU) on a free port, plans
on samples/table6 from Python, checks the response contract and a bad request,
then stops the server with SIGTERM. Then three replicas (analytic backend)
behind one comma-separated address, 16 callers, one replica killed mid-run
and a second stopped later: no call may be lost. Then mutual TLS and a
bearer token (certificates made with openssl). Needs grpcio + grpcio-tools
on sys.path.
"""

import math
import os
import signal
import socket
import subprocess
import sys
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..", "..")
sys.path.insert(0, HERE)

import grpc  # noqa: E402

import mvgrasp_client  # noqa: E402

results = {"passed": 0, "failed": 0}


def check(name, ok, detail=""):
    results["passed" if ok else "failed"] += 1
    print(f"{'ok  ' if ok else 'FAIL'} {name}{': ' + detail if detail and not ok else ''}")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def check_replicas(server_bin, pb, rpc):
    """16 callers over 3 replicas; replica 1 is killed (SIGKILL) mid-run, replica 2 stopped (SIGTERM) later."""
    ports = [free_port() for _ in range(3)]
    replicas = [subprocess.Popen([server_bin, "--backend", "baseline", "--no-metrics", "--listen", f"127.0.0.1:{p}"],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for p in ports]
    try:
        for p in ports:
            with grpc.insecure_channel(f"127.0.0.1:{p}") as c:
                grpc.channel_ready_future(c).result(timeout=60)
        request = mvgrasp_client.plan_request(
            pb, os.path.join(ROOT, "samples/table6/depth.png"), os.path.join(ROOT, "samples/table6/camera.json"))
        addresses = ",".join(f"127.0.0.1:{p}" for p in ports)
        stop_at = time.monotonic() + 9
        killed = threading.Event()
        tally = {"answered": 0, "after_kill": 0, "errors": []}
        lock = threading.Lock()

        def caller():
            # One channel per robot: its own connections and round robin.
            with mvgrasp_client.channel(addresses) as chan:
                planner = rpc.GraspPlannerStub(chan)
                while time.monotonic() < stop_at:
                    try:
                        answer = planner.PlanGrasps(request, timeout=30)
                        with lock:
                            tally["answered"] += 1
                            tally["after_kill"] += killed.is_set() and len(answer.objects) == 6
                    except grpc.RpcError as e:
                        with lock:
                            tally["errors"].append(f"{e.code()} {e.details()}")

        threads = [threading.Thread(target=caller) for _ in range(16)]
        for t in threads:
            t.start()
        time.sleep(3)
        replicas[1].kill()
        replicas[1].wait()
        killed.set()
        time.sleep(2)
        replicas[2].send_signal(signal.SIGTERM)  # drains and closes; calls racing it go on
        replicas[2].wait(timeout=30)
        for t in threads:
            t.join()
        print(f"     replicas: {tally['answered']} answered, {tally['after_kill']} after the kill, "
              f"{len(tally['errors'])} lost")
        check("no call lost when a replica dies", not tally["errors"], str(tally["errors"][:5]))
        check("calls go on on those left", tally["after_kill"] >= 16, str(tally["after_kill"]))
    finally:
        for r in replicas:
            r.kill()
            r.wait()


def make_certificates(folder):
    """A CA, a server certificate for 127.0.0.1 and a client certificate (openssl)."""
    def run(*args):
        subprocess.run(["openssl", *args], check=True, capture_output=True, cwd=folder)

    ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes"]
    run("req", "-x509", *ec, "-keyout", "ca.key", "-out", "ca.crt", "-days", "2", "-subj", "/CN=fleet-ca")
    for name, ext in (("server", "subjectAltName=DNS:localhost,IP:127.0.0.1\nextendedKeyUsage=serverAuth"),
                      ("robot", "subjectAltName=DNS:robot-1\nextendedKeyUsage=clientAuth")):
        with open(os.path.join(folder, f"{name}.ext"), "w") as f:
            f.write(ext)
        run("req", *ec, "-keyout", f"{name}.key", "-out", f"{name}.csr", "-subj", f"/CN={name}")
        run("x509", "-req", "-in", f"{name}.csr", "-CA", "ca.crt", "-CAkey", "ca.key", "-CAcreateserial",
            "-out", f"{name}.crt", "-days", "2", "-extfile", f"{name}.ext")

    def read(name):
        with open(os.path.join(folder, name), "rb") as f:
            return f.read()

    return read


def check_security(server_bin, pb, rpc):
    """Mutual TLS and a bearer token: only the fleet's robot with the token plans."""
    import tempfile  # noqa: PLC0415

    folder = tempfile.mkdtemp(prefix="mvgrasp-tls-")
    read = make_certificates(folder)
    with open(os.path.join(folder, "token"), "w") as f:
        f.write("fleet-7f3a9c\n")
    port = free_port()
    server = subprocess.Popen(
        [server_bin, "--backend", "baseline", "--no-metrics", "--listen", f"127.0.0.1:{port}",
         "--tls-cert", os.path.join(folder, "server.crt"), "--tls-key", os.path.join(folder, "server.key"),
         "--tls-client-ca", os.path.join(folder, "ca.crt"), "--bearer-token-file", os.path.join(folder, "token")],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    request = mvgrasp_client.plan_request(
        pb, os.path.join(ROOT, "samples/table6/depth.png"), os.path.join(ROOT, "samples/table6/camera.json"))
    address = f"127.0.0.1:{port}"
    robot = {"ca": read("ca.crt"), "cert": read("robot.crt"), "key": read("robot.key")}

    def plan(**credentials):
        with mvgrasp_client.channel(address, **credentials) as chan:
            try:
                return len(rpc.GraspPlannerStub(chan).PlanGrasps(request, timeout=30, wait_for_ready=False).objects)
            except grpc.RpcError as e:
                return e.code()

    try:
        deadline = time.monotonic() + 60
        while plan(**robot, token="fleet-7f3a9c") != 6 and time.monotonic() < deadline:
            time.sleep(0.3)
        check("TLS: the robot with its certificate and the token plans", plan(**robot, token="fleet-7f3a9c") == 6)
        answer = plan(**robot)
        check("no token: UNAUTHENTICATED", answer == grpc.StatusCode.UNAUTHENTICATED, str(answer))
        answer = plan(**robot, token="fleet-0000")
        check("wrong token: UNAUTHENTICATED", answer == grpc.StatusCode.UNAUTHENTICATED, str(answer))
        answer = plan(ca=read("ca.crt"), token="fleet-7f3a9c")
        check("no client certificate: refused", answer == grpc.StatusCode.UNAVAILABLE, str(answer))
        answer = plan(token="fleet-7f3a9c")
        check("plaintext to the TLS port: refused", answer == grpc.StatusCode.UNAVAILABLE, str(answer))
    finally:
        server.kill()
        server.wait()


def main():
    server_bin, ort_lib = sys.argv[1], sys.argv[2]
    port = free_port()
    server = subprocess.Popen(
        [server_bin, "--listen", f"127.0.0.1:{port}", "--no-metrics",
         "--model", os.path.join(ROOT, "models/fixtures/tiny.onnx"), "--onnxruntime", ort_lib],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )
    try:
        pb, rpc = mvgrasp_client.stubs()
        channel = grpc.insecure_channel(f"127.0.0.1:{port}")
        grpc.channel_ready_future(channel).result(timeout=30)
        planner = rpc.GraspPlannerStub(channel)

        info = planner.GetModelInfo(pb.GetModelInfoRequest(), timeout=10)
        check("model info", info.model_version == "fixture-tiny-1" and info.backend == "onnxruntime-cpu",
              str(info))

        request = mvgrasp_client.plan_request(
            pb, os.path.join(ROOT, "samples/table6/depth.png"), os.path.join(ROOT, "samples/table6/camera.json"),
            max_grasps=20, request_id="python-1")
        response = planner.PlanGrasps(request, timeout=30)
        check("six objects", len(response.objects) == 6, f"{len(response.objects)} objects")
        check("grasps returned", len(response.grasps) > 0)
        qualities = [g.quality for g in response.grasps]
        # Grasps turned away from a neighbour, then grasps reaching past the
        # image border, come last, each group sorted among itself.
        last = len(qualities) - response.ranked_last_out_of_view
        turned = last - response.ranked_after_turned_away
        check("sorted by quality",
              all(part == sorted(part, reverse=True)
                  for part in (qualities[:turned], qualities[turned:last], qualities[last:])),
              str(qualities))
        norms = [math.sqrt(sum(v * v for v in (g.pose.orientation.x, g.pose.orientation.y,
                                                 g.pose.orientation.z, g.pose.orientation.w)))
                 for g in response.grasps]
        check("unit quaternions", all(abs(n - 1) < 1e-9 for n in norms), str(norms))
        check("widths within the 2F-140", all(0 < g.width_m <= 0.14 for g in response.grasps))
        check("request id echoed", response.request_id == "python-1")

        # Only approaches from above within 30 degrees; the rest are counted.
        coned = mvgrasp_client.plan_request(
            pb, os.path.join(ROOT, "samples/table6/depth.png"), os.path.join(ROOT, "samples/table6/camera.json"),
            max_grasps=20, approach_cone=mvgrasp_client.approach_cone(pb, (0, 0, -1), 30))
        coned_response = planner.PlanGrasps(coned, timeout=30)
        check("approaches within the cone",
              all(mvgrasp_client.approach(g.pose.orientation)[2] <= -math.cos(math.radians(30)) + 1e-9
                  for g in coned_response.grasps),
              str([mvgrasp_client.approach(g.pose.orientation) for g in coned_response.grasps]))

        # The right half of the table as the workspace, the whole table as
        # the obstacle region: what stands on the left half comes back as
        # boxes, none reaching into the workspace past its 1 cm margin.
        halved = mvgrasp_client.plan_request(
            pb, os.path.join(ROOT, "samples/table6/depth.png"), os.path.join(ROOT, "samples/table6/camera.json"),
            obstacle_region=mvgrasp_client.obstacle_region(pb, (-0.6, -0.4, -0.05), (0.6, 0.4, 0.4)))
        halved.workspace.min.x = 0.0
        halved_response = planner.PlanGrasps(halved, timeout=30)
        boxes = [(o.min.x, o.max.x, o.max.z) for o in halved_response.obstacles]
        check("objects outside the workspace come back as obstacle boxes",
              0 < len(halved_response.objects) < 6 and boxes and all(hi_x <= 0.0101 and top > 0.01
                                                                      for _, hi_x, top in boxes),
              f"{len(halved_response.objects)} objects, boxes {boxes}")

        # The same told that the left half is the robot's body (capsules
        # along y filling x < 0 up to 0.4 m): nothing there is an obstacle
        # any more, and the same objects are planned.
        halved.robot_body.extend(mvgrasp_client.capsule(pb, (-0.25, -0.45, z), (-0.25, 0.45, z), 0.26)
                                 for z in (0.0, 0.1, 0.2, 0.3, 0.4))
        bodied = planner.PlanGrasps(halved, timeout=30)
        check("the robot's body is no obstacle",
              not bodied.obstacles and len(bodied.objects) == len(halved_response.objects),
              f"{len(bodied.obstacles)} boxes, {len(bodied.objects)} objects")

        def reached(shoulder, max_m, min_axis_m):
            request = mvgrasp_client.plan_request(
                pb, os.path.join(ROOT, "samples/table6/depth.png"), os.path.join(ROOT, "samples/table6/camera.json"),
                max_grasps=20, arm_reach=mvgrasp_client.arm_reach(pb, shoulder, 0.33, 0.1, max_m, min_axis_m))
            return planner.PlanGrasps(request, timeout=30)

        everywhere = reached((0.0, 0.0, 0.16), 5.0, 0.0)
        plain = planner.PlanGrasps(mvgrasp_client.plan_request(
            pb, os.path.join(ROOT, "samples/table6/depth.png"), os.path.join(ROOT, "samples/table6/camera.json"),
            max_grasps=20), timeout=30)
        check("an arm that reaches every grasp changes nothing",
              list(everywhere.grasps) == list(plain.grasps) and everywhere.out_of_reach == 0,
              f"{len(everywhere.grasps)} grasps against {len(plain.grasps)}, {everywhere.out_of_reach} out of reach")
        nowhere = reached((5.0, 5.0, 0.16), 0.5, 0.13)
        check("an arm that reaches none: no grasp, each object's candidates counted out of reach",
              not nowhere.grasps and nowhere.out_of_reach > 0
              and all(o.refused.out_of_reach > 0 for o in nowhere.objects),
              f"{len(nowhere.grasps)} grasps, {nowhere.out_of_reach} out of reach, "
              f"{[o.refused.out_of_reach for o in nowhere.objects]}")

        bad = mvgrasp_client.plan_request(
            pb, os.path.join(ROOT, "samples/table6/depth.png"), os.path.join(ROOT, "samples/table6/camera.json"))
        bad.depth.intrinsics.fx = 0
        try:
            planner.PlanGrasps(bad, timeout=10)
            check("bad intrinsics refused", False, "no error")
        except grpc.RpcError as e:
            check("bad intrinsics refused",
                  e.code() == grpc.StatusCode.INVALID_ARGUMENT and "depth.intrinsics.fx" in e.details(),
                  f"{e.code()} {e.details()}")

        frames = [mvgrasp_client.plan_request(
            pb, os.path.join(ROOT, "samples/table6/depth.png"), os.path.join(ROOT, "samples/table6/camera.json"),
            request_id=f"frame-{i}") for i in range(3)]
        ids = [r.request_id for r in planner.StreamGrasps(iter(frames), timeout=30)]
        check("stream in order", ids == ["frame-0", "frame-1", "frame-2"], str(ids))
        channel.close()
    finally:
        server.send_signal(signal.SIGTERM)
        try:
            code = server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
            code = None
        check("server stops on SIGTERM", code == 0, f"exit {code}; log:\n{server.stdout.read()}")
    check_replicas(server_bin, pb, rpc)
    check_security(server_bin, pb, rpc)
    print(f"python_client: {results['passed']} passed, {results['failed']} failed")
    return 1 if results["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
