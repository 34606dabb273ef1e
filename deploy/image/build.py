#!/usr/bin/env python3
"""The planner's container image, without Docker Hub or a container runtime.

    python3 deploy/image/build.py build [--server BIN] [--onnxruntime LIB] [--out DIR]
    python3 deploy/image/build.py smoke --image DIR/mvgrasp-server.oci.tar --client BIN

`build` puts the server binary, the shared libraries it and ONNX Runtime
load (copied from this Debian machine's packages, listed with their versions
in /usr/share/doc/mvgrasp-image/packages.txt), ONNX Runtime's CPU library
from PyPI, the default model and deploy/server.toml on an empty base: no
shell, no package manager, user 10001. It writes an OCI image archive
(`skopeo copy oci-archive:... docker://...` or `podman load -i ...` take it).

`smoke` unpacks that archive's layers into a fresh folder and starts the
image's entrypoint inside it with chroot as user 10001 (containers cannot run
in this sandbox): the server must answer a health check, plan the sample
frame, stop cleanly on SIGTERM, and leave its file system as it found it.
Needs root (chroot).
"""

import argparse
import gzip
import hashlib
import io
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tarfile
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
UID = GID = 10001
WORKDIR = "/opt/mvgrasp"
ORT_IN_IMAGE = "/opt/onnxruntime/libonnxruntime.so.1.31.1"
LIBDIR = "/usr/lib/x86_64-linux-gnu"
LOADER = "/lib64/ld-linux-x86-64.so.2"


def shared_libraries(path):
    """{soname: resolved host path} that `path` needs (ldd), and the loader."""
    out = subprocess.run(["ldd", path], capture_output=True, text=True, check=True).stdout
    libs = {}
    for line in out.splitlines():
        m = re.match(r"\s*(\S+) => (\S+) \(", line)
        if m:
            libs[m.group(1)] = os.path.realpath(m.group(2))
    return libs


def debian_package(path):
    """`package version` owning `path` (merged /usr: dpkg may know it as /lib/...)."""
    for candidate in (path, path.replace("/usr/lib/", "/lib/", 1)):
        found = subprocess.run(["dpkg", "-S", candidate], capture_output=True, text=True)
        if found.returncode == 0:
            package = found.stdout.split(":")[0]
            version = subprocess.run(["dpkg-query", "-W", "-f=${Version}", package],
                                     capture_output=True, text=True).stdout
            return f"{package} {version}"
    return "unknown (not from a Debian package)"


def default_model():
    """The model path deploy/server.toml names (relative to WORKDIR)."""
    with open(os.path.join(ROOT, "deploy", "server.toml")) as f:
        m = re.search(r'^path\s*=\s*"([^"]+)"', f.read(), re.M)
    if not m:
        sys.exit("deploy/server.toml names no [model] path")
    return m.group(1)


def layer_tar(rootfs):
    """A deterministic gzip'd tar of `rootfs`: owner root, times 0, sorted."""
    raw = io.BytesIO()
    with tarfile.open(fileobj=raw, mode="w", format=tarfile.PAX_FORMAT) as tar:
        for top, dirs, files in os.walk(rootfs):
            dirs.sort()
            for name in sorted(dirs) + sorted(files):
                full = os.path.join(top, name)
                info = tar.gettarinfo(full, arcname=os.path.relpath(full, rootfs))
                info.uid = info.gid = 0
                info.uname = info.gname = ""
                info.mtime = 0
                if info.isfile():
                    with open(full, "rb") as f:
                        tar.addfile(info, f)
                else:
                    tar.addfile(info)
    diff = raw.getvalue()
    zipped = io.BytesIO()
    with gzip.GzipFile(fileobj=zipped, mode="wb", mtime=0, compresslevel=6) as gz:
        gz.write(diff)
    return diff, zipped.getvalue()


def blob(layout, data):
    digest = hashlib.sha256(data).hexdigest()
    with open(os.path.join(layout, "blobs", "sha256", digest), "wb") as f:
        f.write(data)
    return {"digest": f"sha256:{digest}", "size": len(data)}


def build(args):
    out = os.path.abspath(args.out)
    rootfs = os.path.join(out, "rootfs")
    shutil.rmtree(out, ignore_errors=True)
    model = default_model()

    def put(source, target, mode=0o644):
        dest = rootfs + target
        os.makedirs(os.path.dirname(dest), exist_ok=True)
        shutil.copyfile(source, dest)
        os.chmod(dest, mode)

    put(args.server, "/usr/local/bin/mvgrasp-server", 0o755)
    put(args.onnxruntime, ORT_IN_IMAGE)
    put(os.path.join(ROOT, model), f"{WORKDIR}/{model}")
    put(os.path.realpath(os.path.join(ROOT, "deploy", "server.toml")), "/etc/mvgrasp/server.toml")
    libs = {**shared_libraries(args.server), **shared_libraries(args.onnxruntime)}
    provenance = []
    for soname, host in sorted(libs.items()):
        put(host, f"{LIBDIR}/{soname}", 0o755)
        provenance.append(f"{LIBDIR}/{soname}: {debian_package(host)}")
    loader = os.path.realpath(LOADER)
    put(loader, "/usr/lib64/ld-linux-x86-64.so.2", 0o755)
    provenance.append(f"/usr/lib64/ld-linux-x86-64.so.2: {debian_package(loader)}")
    os.symlink("usr/lib", os.path.join(rootfs, "lib"))
    os.symlink("usr/lib64", os.path.join(rootfs, "lib64"))
    os.makedirs(os.path.join(rootfs, "etc"), exist_ok=True)
    with open(os.path.join(rootfs, "etc", "passwd"), "w") as f:
        f.write(f"root:x:0:0:root:/root:/usr/sbin/nologin\nmvgrasp:x:{UID}:{GID}:mvgrasp:/nonexistent:/usr/sbin/nologin\n")
    with open(os.path.join(rootfs, "etc", "group"), "w") as f:
        f.write(f"root:x:0:\nmvgrasp:x:{GID}:\n")
    for d, mode in (("tmp", 0o1777), ("proc", 0o555), ("dev", 0o755)):
        os.makedirs(os.path.join(rootfs, d), exist_ok=True)
        os.chmod(os.path.join(rootfs, d), mode)
    doc = os.path.join(rootfs, "usr", "share", "doc", "mvgrasp-image")
    os.makedirs(doc)
    with open(os.path.join(doc, "packages.txt"), "w") as f:
        f.write("# Shared libraries in this image and the Debian packages they were copied from\n")
        f.write("\n".join(provenance) + "\n")
        f.write(f"{ORT_IN_IMAGE}: onnxruntime 1.31.1 wheel (PyPI)\n")

    diff, zipped = layer_tar(rootfs)
    layout = os.path.join(out, "oci")
    os.makedirs(os.path.join(layout, "blobs", "sha256"))
    layer = blob(layout, zipped)
    with open(os.path.join(ROOT, "Cargo.toml")) as f:
        version = re.search(r'^version\s*=\s*"([^"]+)"', f.read(), re.M).group(1)
    config = {
        "architecture": "amd64", "os": "linux",
        "config": {
            "User": f"{UID}:{GID}",
            "Entrypoint": ["/usr/local/bin/mvgrasp-server"],
            "Env": ["PATH=/usr/local/bin", f"ORT_DYLIB_PATH={ORT_IN_IMAGE}",
                    "MVGRASP_CONFIG=/etc/mvgrasp/server.toml", "MVGRASP_LOG=info"],
            "WorkingDir": WORKDIR,
            "ExposedPorts": {"50051/tcp": {}, "9464/tcp": {}},
            "StopSignal": "SIGTERM",
            "Labels": {"org.opencontainers.image.title": "mvgrasp-server",
                       "org.opencontainers.image.version": version,
                       "org.opencontainers.image.description": "mvgrasp grasp planner, CPU backend"},
        },
        "rootfs": {"type": "layers", "diff_ids": [f"sha256:{hashlib.sha256(diff).hexdigest()}"]},
    }
    config_blob = blob(layout, json.dumps(config, sort_keys=True).encode())
    manifest = {
        "schemaVersion": 2, "mediaType": "application/vnd.oci.image.manifest.v1+json",
        "config": {"mediaType": "application/vnd.oci.image.config.v1+json", **config_blob},
        "layers": [{"mediaType": "application/vnd.oci.image.layer.v1.tar+gzip", **layer}],
    }
    manifest_blob = blob(layout, json.dumps(manifest, sort_keys=True).encode())
    index = {"schemaVersion": 2, "manifests": [{
        "mediaType": "application/vnd.oci.image.manifest.v1+json", **manifest_blob,
        "annotations": {"org.opencontainers.image.ref.name": version}}]}
    with open(os.path.join(layout, "index.json"), "w") as f:
        json.dump(index, f)
    with open(os.path.join(layout, "oci-layout"), "w") as f:
        json.dump({"imageLayoutVersion": "1.0.0"}, f)
    archive = os.path.join(out, "mvgrasp-server.oci.tar")
    with tarfile.open(archive, "w") as tar:
        tar.add(layout, arcname=".")
    shutil.rmtree(rootfs)
    print(f"wrote {archive}: {os.path.getsize(archive) / 1e6:.1f} MB "
          f"(layer {len(zipped) / 1e6:.1f} MB, {len(diff) / 1e6:.1f} MB unpacked), "
          f"{len(libs) + 1} shared libraries from Debian packages")
    print("\n".join(f"  {p}" for p in provenance))


def unpack(archive, into):
    """The image's config, its layers applied in order under `into`."""
    with tarfile.open(archive) as tar:
        def read(name):
            return tar.extractfile(name).read()

        index = json.loads(read("./index.json"))
        manifest = json.loads(read("./blobs/sha256/" + index["manifests"][0]["digest"].split(":")[1]))
        config = json.loads(read("./blobs/sha256/" + manifest["config"]["digest"].split(":")[1]))
        for layer in manifest["layers"]:
            data = read("./blobs/sha256/" + layer["digest"].split(":")[1])
            if hashlib.sha256(data).hexdigest() != layer["digest"].split(":")[1]:
                sys.exit(f"layer {layer['digest']} does not match its digest")
            with tarfile.open(fileobj=io.BytesIO(data), mode="r:gz") as layer_tar_file:
                layer_tar_file.extractall(into, filter="tar")
    return config["config"]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def smoke(args):
    if os.geteuid() != 0:
        sys.exit("smoke needs root (chroot)")
    failures = []

    def check(name, ok, detail=""):
        print(f"{'ok  ' if ok else 'FAIL'} {name}{': ' + detail if detail and not ok else ''}")
        if not ok:
            failures.append(name)

    root = tempfile.mkdtemp(prefix="mvgrasp-image-")
    os.chmod(root, 0o755)  # it becomes /, which user 10001 must traverse
    server = None
    try:
        config = unpack(args.image, root)
        check("no shell in the image", not any(os.path.lexists(root + p) for p in ("/bin/sh", "/usr/bin/sh", "/bin/bash")))
        uid, gid = (int(x) for x in config["User"].split(":"))
        check("runs as a non-root user", uid != 0 and gid != 0, config["User"])
        env = dict(e.split("=", 1) for e in config["Env"])
        port, metrics = free_port(), free_port()
        command = config["Entrypoint"] + ["--listen", f"127.0.0.1:{port}", "--metrics-listen", f"127.0.0.1:{metrics}"]

        def enter():
            os.chroot(root)
            os.chdir(config["WorkingDir"])
            os.setgroups([])
            os.setgid(gid)
            os.setuid(uid)

        def tree():
            return {os.path.relpath(os.path.join(top, n), root): os.lstat(os.path.join(top, n)).st_mtime_ns
                    for top, dirs, files in os.walk(root) for n in dirs + files}

        before = tree()
        log = tempfile.TemporaryFile("w+")
        server = subprocess.Popen(command, env=env, preexec_fn=enter, stdout=log, stderr=subprocess.STDOUT)
        client = [args.client, "--server", f"http://127.0.0.1:{port}", "--timeout-ms", "30000"]
        deadline = time.monotonic() + 60
        health = None
        while time.monotonic() < deadline and server.poll() is None:
            health = subprocess.run(client + ["health"], capture_output=True, text=True)
            if health.returncode == 0:
                break
            time.sleep(0.5)
        log.seek(0)
        check("health check: SERVING", health is not None and health.returncode == 0 and "SERVING" in health.stdout,
              f"{health and health.stdout}{health and health.stderr} server log:\n{log.read()[-3000:]}")
        info = subprocess.run(client + ["info"], capture_output=True, text=True)
        check("the default model on ONNX Runtime CPU", info.returncode == 0 and "onnxruntime-cpu" in info.stdout,
              info.stdout + info.stderr)
        print(f"     {info.stdout.strip()[:160]}")
        plan = subprocess.run(
            client + ["plan", "--depth", os.path.join(ROOT, "samples/table6/depth.png"),
                      "--camera", os.path.join(ROOT, "samples/table6/camera.json"), "--json"],
            capture_output=True, text=True)
        answer = json.loads(plan.stdout) if plan.returncode == 0 else {}
        objects, grasps = len(answer.get("objects", [])), len(answer.get("grasps", []))
        check("plans the sample frame: 6 objects, grasps", objects == 6 and grasps > 0,
              f"{objects} objects, {grasps} grasps; {plan.stderr[-1000:]}")
        print(f"     sample frame: {objects} objects, {grasps} grasps")
        server.send_signal(signal.SIGTERM)
        code = server.wait(timeout=30)
        check("stops on SIGTERM with status 0", code == 0, f"exit {code}")
        server = None
        changed = sorted(p for p, t in tree().items() if before.get(p) != t)
        check("wrote nothing to its file system (runs on a read-only root)", not changed, str(changed[:10]))
    finally:
        if server is not None:
            server.kill()
            server.wait()
        shutil.rmtree(root, ignore_errors=True)
    print(f"image smoke test: {len(failures)} failed")
    return 1 if failures else 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    b = sub.add_parser("build", help="write the OCI image archive")
    b.add_argument("--server", default=os.path.join(ROOT, "target/release/mvgrasp-server"))
    b.add_argument("--onnxruntime", default=os.path.join(ROOT, "target/onnxruntime/libonnxruntime.so.1.31.1"))
    b.add_argument("--out", default=os.path.join(ROOT, "target/image"))
    s = sub.add_parser("smoke", help="start the image's server with chroot and call it")
    s.add_argument("--image", default=os.path.join(ROOT, "target/image/mvgrasp-server.oci.tar"))
    s.add_argument("--client", default=os.path.join(ROOT, "target/release/mvgrasp"))
    args = parser.parse_args()
    return build(args) if args.command == "build" else smoke(args)


if __name__ == "__main__":
    sys.exit(main())
