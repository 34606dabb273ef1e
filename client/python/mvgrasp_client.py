#!/usr/bin/env python3
"""A Python client of the mvgrasp planner, generated from proto/ with grpcio-tools.

    pip install -r client/python/requirements.txt
    python3 client/python/mvgrasp_client.py --server 127.0.0.1:50051 \\
        --depth samples/table6/depth.png --camera samples/table6/camera.json

The stubs are generated into client/python/generated/ on first use (not
committed: proto/ is the one source of truth). Depth PNGs are read with a
small decoder below, so the example needs grpcio and protobuf only.
"""

import argparse
import json
import math
import os
import struct
import subprocess
import sys
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
PROTO_ROOT = os.path.join(HERE, "..", "..", "proto")
GENERATED = os.path.join(HERE, "generated")


def stubs():
    """Imports (generating first if needed) the mvgrasp.v1 messages and stubs."""
    proto = os.path.join(PROTO_ROOT, "mvgrasp", "v1", "grasp_planner.proto")
    target = os.path.join(GENERATED, "mvgrasp", "v1", "grasp_planner_pb2.py")
    if not os.path.exists(target) or os.path.getmtime(target) < os.path.getmtime(proto):
        os.makedirs(GENERATED, exist_ok=True)
        subprocess.run(
            [
                sys.executable, "-m", "grpc_tools.protoc",
                f"-I{PROTO_ROOT}", f"--python_out={GENERATED}", f"--grpc_python_out={GENERATED}",
                proto,
            ],
            check=True,
        )
    if GENERATED not in sys.path:
        sys.path.insert(0, GENERATED)
    from mvgrasp.v1 import grasp_planner_pb2, grasp_planner_pb2_grpc  # noqa: PLC0415

    return grasp_planner_pb2, grasp_planner_pb2_grpc


def read_depth_png(path):
    """(width, height, little-endian uint16 bytes) of a 16-bit grey PNG."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG")
    at, idat, width = 8, b"", None
    while at < len(data):
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        body = data[at + 8:at + 8 + length]
        at += 12 + length
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if (depth, colour, interlace) != (16, 0, 0):
                raise ValueError(f"{path}: need a 16-bit grey, non-interlaced PNG")
        elif kind == b"IDAT":
            idat += body
        elif kind == b"IEND":
            break
    raw = zlib.decompress(idat)
    stride, bpp = width * 2, 2
    out, prev = bytearray(), bytearray(stride)
    for row in range(height):
        kind, line = raw[row * (stride + 1)], bytearray(raw[row * (stride + 1) + 1:(row + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b, c = prev[i], prev[i - bpp] if i >= bpp else 0
            if kind == 1:
                line[i] = (line[i] + a) & 0xFF
            elif kind == 2:
                line[i] = (line[i] + b) & 0xFF
            elif kind == 3:
                line[i] = (line[i] + (a + b) // 2) & 0xFF
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 0xFF
        out += line
        prev = line
    # PNG is big-endian; the API wants little-endian.
    out[0::2], out[1::2] = out[1::2], out[0::2]
    return width, height, bytes(out)


def plan_request(pb, depth_png, camera_json, **options):
    """A PlanGraspsRequest for a depth PNG (mm) and a camera JSON."""
    with open(camera_json) as f:
        camera = json.load(f)
    width, height, data = read_depth_png(depth_png)
    k = camera["intrinsics"]
    p, q = camera["world_from_camera"]["position"], camera["world_from_camera"]["orientation"]
    request = pb.PlanGraspsRequest(
        depth=pb.DepthImage(
            width=width, height=height, encoding=pb.DEPTH_ENCODING_UINT16_MM, data=data,
            intrinsics=pb.CameraIntrinsics(fx=k["fx"], fy=k["fy"], cx=k["cx"], cy=k["cy"]),
        ),
        world_from_camera=pb.Pose(
            position=pb.Vector3(x=p[0], y=p[1], z=p[2]),
            orientation=pb.Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]),
        ),
        **options,
    )
    if "workspace" in camera:
        lo, hi = camera["workspace"]["min"], camera["workspace"]["max"]
        request.workspace.min.CopyFrom(pb.Vector3(x=lo[0], y=lo[1], z=lo[2]))
        request.workspace.max.CopyFrom(pb.Vector3(x=hi[0], y=hi[1], z=hi[2]))
    return request


def approach_cone(pb, axis, half_angle_deg):
    """An ApproachCone: approaches within `half_angle_deg` of `axis` (world)."""
    return pb.ApproachCone(axis=pb.Vector3(x=axis[0], y=axis[1], z=axis[2]),
                           half_angle_rad=math.radians(half_angle_deg))


def arm_reach(pb, shoulder, wrist_back_m, approach_m, max_m, min_axis_m, axis=(0.0, 0.0, 1.0)):
    """An ArmReach: only grasps whose wrist (wrist_back_m behind the grasp
    along its approach, and approach_m further back) lies within max_m of
    `shoulder` (world) and keeps min_axis_m from the base `axis` through it.
    `robot-bridge plan-jsonl` tells a UR5e's (`{"arm_reach": null}`)."""
    return pb.ArmReach(shoulder=pb.Vector3(x=shoulder[0], y=shoulder[1], z=shoulder[2]),
                       axis=pb.Vector3(x=axis[0], y=axis[1], z=axis[2]),
                       wrist_back_m=wrist_back_m, approach_m=approach_m, max_m=max_m, min_axis_m=min_axis_m)


def obstacle_region(pb, lo, hi):
    """A world box whose contents outside the workspace the planner reports
    as obstacle boxes (`PlanGraspsResponse.obstacles`), not planned."""
    return pb.Workspace(min=pb.Vector3(x=lo[0], y=lo[1], z=lo[2]), max=pb.Vector3(x=hi[0], y=hi[1], z=hi[2]))


def capsule(pb, a, b, radius_m):
    """A Capsule of the robot's body (`PlanGraspsRequest.robot_body`): the
    segment a-b (world) swept by radius_m; the points within are left out.
    `robot-bridge plan-jsonl` tells a UR5e's at its joints
    (`{"robot_body": [q1..q6]}`)."""
    return pb.Capsule(a=pb.Vector3(x=a[0], y=a[1], z=a[2]), b=pb.Vector3(x=b[0], y=b[1], z=b[2]),
                      radius_m=radius_m)


# Calls spread round robin over every address the target names; a unary call
# that meets an unavailable replica (unreachable, gone mid-call, shutting
# down) is sent up to twice more, and round robin sends it to the next
# replicas: one replica killed and another stopping meet a call at most
# twice. PlanGrasps and GetModelInfo are idempotent.
SERVICE_CONFIG = json.dumps({
    "loadBalancingConfig": [{"round_robin": {}}],
    "methodConfig": [{
        "name": [{"service": "mvgrasp.v1.GraspPlanner", "method": m} for m in ("PlanGrasps", "GetModelInfo")],
        "retryPolicy": {
            "maxAttempts": 3, "initialBackoff": "0.01s", "maxBackoff": "0.1s", "backoffMultiplier": 2,
            "retryableStatusCodes": ["UNAVAILABLE"],
        },
    }],
})


def target(server):
    """The gRPC target for `server`: `host:port`, several separated by commas
    (each name resolved now to its IPv4 addresses), or `dns:///host:port`
    (gRPC resolves it, one replica per record, and re-resolves as it goes)."""
    parts = [p.strip() for p in server.split(",") if p.strip()]
    if not parts:
        raise ValueError("no planner address given")
    if len(parts) == 1:
        return parts[0]
    import socket  # noqa: PLC0415

    addresses = []
    for part in parts:
        host, _, port = part.rpartition(":")
        if not host or not port.isdigit():
            raise ValueError(f"{part}: give host:port")
        infos = socket.getaddrinfo(host, int(port), socket.AF_INET, socket.SOCK_STREAM)
        addresses += sorted({f"{info[4][0]}:{port}" for info in infos})
    return "ipv4:" + ",".join(addresses)


def channel(server, ca=None, cert=None, key=None, domain=None, token=None):
    """A channel to one planner or several replicas (see `target`).

    `ca` (PEM bytes of the CA that signed the planner's certificate) makes it
    TLS; `cert` and `key` add this client's certificate (mutual TLS);
    `domain` is the name on the planner's certificate when the address does
    not carry it; `token` is sent as `authorization: Bearer <token>`.
    """
    import grpc  # noqa: PLC0415

    name = target(server)
    options = [
        ("grpc.service_config", SERVICE_CONFIG), ("grpc.enable_retries", 1),
        ("grpc.max_receive_message_length", 256 << 20), ("grpc.max_send_message_length", -1),
        # A call is retried only while its request is still buffered (256 KiB
        # by default; a 640x480 depth frame is 600 KiB).
        ("grpc.per_rpc_retry_buffer_size", 64 << 20),
    ]
    if name.startswith("ipv4:"):
        # The default :authority would be the whole list, which HTTP/2 servers refuse.
        options.append(("grpc.default_authority", name[len("ipv4:"):].split(",")[0]))
    if domain:
        options.append(("grpc.ssl_target_name_override", domain))
    if ca is not None:
        credentials = grpc.ssl_channel_credentials(root_certificates=ca, private_key=key, certificate_chain=cert)
        chan = grpc.secure_channel(name, credentials, options=options)
    else:
        chan = grpc.insecure_channel(name, options=options)
    if token:
        chan = grpc.intercept_channel(chan, _bearer(token))
    return chan


def _bearer(token):
    """A client interceptor adding `authorization: Bearer <token>` to every call."""
    import grpc  # noqa: PLC0415

    header = ("authorization", f"Bearer {token}")

    class Details(grpc.ClientCallDetails):
        def __init__(self, d):
            self.method, self.timeout, self.credentials = d.method, d.timeout, d.credentials
            self.wait_for_ready, self.compression = d.wait_for_ready, d.compression
            self.metadata = list(d.metadata or []) + [header]

    class Bearer(grpc.UnaryUnaryClientInterceptor, grpc.StreamStreamClientInterceptor):
        def intercept_unary_unary(self, continuation, details, request):
            return continuation(Details(details), request)

        def intercept_stream_stream(self, continuation, details, requests):
            return continuation(Details(details), requests)

    return Bearer()


def approach(q):
    """The grasp frame's +z (approach) in the world, from its quaternion."""
    x, y, z, w = q.x, q.y, q.z, q.w
    return (2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--server", default="127.0.0.1:50051",
                        help="host:port, several separated by commas (round robin, up to two retries on other "
                             "replicas), or dns:///host:port")
    parser.add_argument("--depth", required=True)
    parser.add_argument("--camera", required=True)
    parser.add_argument("--max-grasps", type=int, default=0)
    parser.add_argument("--timeout-s", type=float, default=10.0)
    parser.add_argument("--approach-cone", type=float, nargs=4, metavar=("AX", "AY", "AZ", "HALF_DEG"),
                        help="only approaches within this cone, e.g. 0 0 -1 60 (from above within 60 degrees)")
    parser.add_argument("--obstacle-region", type=float, nargs=6, metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"),
                        help="report what stands inside this world box but outside the workspace as obstacles")
    parser.add_argument("--no-view-cascade", action="store_true",
                        help="the paper's single pass over the policy's views")
    parser.add_argument("--tls-ca", help="PEM CA that signed the planner's certificate: call over TLS")
    parser.add_argument("--tls-cert", help="PEM certificate of this client (mutual TLS)")
    parser.add_argument("--tls-key", help="PEM key of --tls-cert")
    parser.add_argument("--tls-domain", help="the name on the planner's certificate, if the address differs")
    parser.add_argument("--token-file", help="file with the bearer token the planner asks for")
    args = parser.parse_args()

    def read(path):
        if path is None:
            return None
        with open(path, "rb") as f:
            return f.read()

    pb, rpc = stubs()
    token = read(args.token_file).decode().strip() if args.token_file else None
    with channel(args.server, ca=read(args.tls_ca), cert=read(args.tls_cert), key=read(args.tls_key),
                 domain=args.tls_domain, token=token) as chan:
        planner = rpc.GraspPlannerStub(chan)
        info = planner.GetModelInfo(pb.GetModelInfoRequest(), timeout=args.timeout_s)
        print(f"model {info.model_version} on {info.backend}, views {info.input_size_px} px")
        options = {"max_grasps": args.max_grasps}
        if args.approach_cone:
            options["approach_cone"] = approach_cone(pb, args.approach_cone[:3], args.approach_cone[3])
        if args.obstacle_region:
            options["obstacle_region"] = obstacle_region(pb, args.obstacle_region[:3], args.obstacle_region[3:])
        if args.no_view_cascade:
            options["view_cascade"] = False
        request = plan_request(pb, args.depth, args.camera, **options)
        response = planner.PlanGrasps(request, timeout=args.timeout_s)
    print(f"{len(response.objects)} objects, {len(response.grasps)} grasps "
          f"({response.outside_approach_cone} outside the approach cone), "
          f"{response.timings.total_ms:.1f} ms in the server")
    for rank, g in enumerate(response.grasps, 1):
        p, a = g.pose.position, approach(g.pose.orientation)
        print(f"{rank:>3} object {g.object_id} q {g.quality:.3f} width {g.width_m * 1e3:.1f} mm "
              f"at ({p.x:.3f}, {p.y:.3f}, {p.z:.3f}) approach ({a[0]:+.2f}, {a[1]:+.2f}, {a[2]:+.2f})")
    for o in response.obstacles:
        print(f"obstacle x {o.min.x:.3f}..{o.max.x:.3f} y {o.min.y:.3f}..{o.max.y:.3f} "
              f"z {o.min.z:.3f}..{o.max.z:.3f} ({o.point_count} points)")
    return 0 if math.isfinite(response.timings.total_ms) else 1


if __name__ == "__main__":
    sys.exit(main())
