#!/usr/bin/env bash
# The project's test command (README.md): installs what it needs, then runs
# the same checks CI runs. Safe to run on a fresh machine with Rust.
set -euo pipefail
cd "$(dirname "$0")/.."

# Disk is the scarce thing on CI machines: say what there is, first and last.
disk_report() {
    echo "== disk: $(df -h --output=avail . | tail -1 | tr -d ' ') free; target/ $(du -sh target 2>/dev/null | cut -f1 || echo 0)"
}
disk_report
trap disk_report EXIT

if ! cargo nextest --version >/dev/null 2>&1; then
    echo "== installing cargo-nextest"
    cargo install cargo-nextest --locked
fi
for component in rustfmt clippy; do
    if ! rustup component list --installed 2>/dev/null | grep -q "^$component"; then
        rustup component add "$component" || true
    fi
done

echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== docs: every relative Markdown link and every docs/experiments file named exists"
python3 scripts/check_links.py
echo "== cargo clippy"
cargo clippy --workspace --all-targets -- -D warnings
echo "== layering: the sim library without its service feature builds, and depends on no gRPC crate"
cargo clippy -p mvgrasp-sim --no-default-features --lib --tests -- -D warnings
if cargo tree -p mvgrasp-sim --no-default-features -e normal | grep -E "tonic|prost|mvgrasp-(server|client|proto)"; then
    echo "the sim library reaches the service crates above without its service feature" >&2
    exit 1
fi
echo "== cargo clippy, server with the CUDA backend compiled in (it runs only on a GPU machine)"
cargo clippy -p mvgrasp-server --features cuda -- -D warnings
echo "== cargo doc"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --quiet
echo "== doc tests"
cargo test --workspace --doc --quiet
echo "== ur_rtde (a third-party RTDE client) against the robot-bridge emulator"
cargo build --quiet -p mvgrasp-robot-bridge --bin robot-bridge
python3 robot-bridge/tests/ur_rtde_check.py target/debug/robot-bridge
echo "== ONNX Runtime (the CPU library from the onnxruntime wheel on PyPI)"
MVGRASP_ONNXRUNTIME="$(scripts/fetch-onnxruntime.sh)"
export MVGRASP_ONNXRUNTIME
echo "== Python client (grpcio, stubs generated from proto/) against the server"
pydeps=target/pydeps
if ! PYTHONPATH="$pydeps" python3 -c "import grpc, grpc_tools" >/dev/null 2>&1; then
    python3 -m pip install --quiet --disable-pip-version-check --target "$pydeps" -r client/python/requirements.txt
fi
cargo build --quiet -p mvgrasp-server --bin mvgrasp-server
PYTHONPATH="$pydeps" python3 client/python/test_client.py target/debug/mvgrasp-server "$MVGRASP_ONNXRUNTIME"
echo "== monitoring: alert rules (promtool), the Grafana dashboard's metrics on a live /metrics, a real Prometheus scraping a loaded server"
if ! command -v promtool >/dev/null 2>&1; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get install -y -q --no-install-recommends prometheus >/dev/null \
        || { apt-get update -q >/dev/null && apt-get install -y -q --no-install-recommends prometheus >/dev/null; }
fi
promtool check config deploy/prometheus/prometheus.yml
promtool test rules deploy/prometheus/rules_test.yml
cargo build --quiet -p mvgrasp-client --bin mvgrasp
python3 deploy/check_monitoring.py target/debug/mvgrasp-server target/debug/mvgrasp
echo "== container image (OCI archive from Debian's libraries, no base image pulled), smoke-tested with chroot: health, the sample frame, SIGTERM"
python3 deploy/image/build.py build --server target/debug/mvgrasp-server --out target/image-ci
if [[ $EUID -eq 0 ]]; then
    python3 deploy/image/build.py smoke --image target/image-ci/mvgrasp-server.oci.tar --client target/debug/mvgrasp
else
    echo "image smoke test NOT RUN: chroot needs root"
fi
echo "== Kubernetes manifests (no cluster here): kubectl kustomize, kubernetes-validate --strict, how the objects fit together, checkov"
k8sdeps=target/pydeps-k8s
if ! PYTHONPATH="$k8sdeps" python3 -c "import kubernetes_validate, checkov, yaml" >/dev/null 2>&1; then
    python3 -m pip install --quiet --disable-pip-version-check --target "$k8sdeps" -r deploy/k8s/requirements-check.txt 2>&1 \
        | grep -v -e "dependency resolver" -e "which is incompatible" || true
fi
PYTHONPATH="$k8sdeps" python3 deploy/k8s/check.py
echo "== fuzzing, a short pass (20,000 inputs per target; scripts/fuzz.sh alone runs 1,000,000): requests through planning, the client's file readers, the bridge's protocols"
scripts/fuzz.sh 20000
echo "== physics referee (MuJoCo, robosuite's UR5e + 2F-140, objects from PyPI wheels): self-checks, then the quick suite against a server"
export MVGRASP_ROBOT_BRIDGE=target/debug/robot-bridge
scripts/referee.sh --self-check
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
target/debug/mvgrasp-server --config deploy/server.toml --listen "127.0.0.1:$port" --no-metrics \
    --onnxruntime "$MVGRASP_ONNXRUNTIME" &
referee_server=$!
timeout 120 bash -c "until (echo > /dev/tcp/127.0.0.1/$port) 2>/dev/null; do sleep 0.5; done"
rm -rf target/referee-ci
referee_status=0
scripts/referee.sh --server "127.0.0.1:$port" --suite quick --camera topdown,angled --out target/referee-ci \
    || referee_status=$?
kill "$referee_server"
wait "$referee_server" || true
[[ $referee_status -eq 0 ]] || exit "$referee_status"
echo "== sim datagen, read back by the Python dataset reader (numpy only)"
if ! PYTHONPATH="$pydeps" python3 -c "import numpy" >/dev/null 2>&1; then
    python3 -m pip install --quiet --disable-pip-version-check --target "$pydeps" numpy
fi
cargo build --quiet -p mvgrasp-sim --bin sim
rm -rf target/datagen-ci
# Every scenario but clutter, procedural families and two sample meshes (OBJ, binary STL).
target/debug/sim datagen --scenes 6 --scenes-per-shard 3 --scenarios isolated,packed,pile \
    --families box,cylinder,mug,bottle --meshes samples/meshes/u_channel.obj,samples/meshes/hex_nut.stl \
    --out target/datagen-ci
PYTHONPATH="$pydeps" python3 sim/python/read_dataset.py target/datagen-ci --check
echo "== training: dataset reader, augmentation, metric (numpy), flip wrapper and compose (onnx); torch tests skip, saying why"
traindeps=target/pydeps-train
if ! PYTHONPATH="$traindeps" python3 -c "import numpy, onnx, onnxruntime" >/dev/null 2>&1; then
    python3 -m pip install --quiet --disable-pip-version-check --target "$traindeps" -r training/requirements-ci.txt
fi
PYTHONPATH="$traindeps" python3 -m unittest discover -s training/tests -v
echo "== sim eval --attempt-views (physics outcomes to learn from), read back by the training package (numpy)"
rm -rf target/eval-ci target/attempts-ci
target/debug/sim eval --scenarios isolated,packed --episodes 1 --settings all:0.1 --snapshots 0 \
    --out target/eval-ci --attempt-views target/attempts-ci --attempt-alternatives 2
PYTHONPATH="$traindeps:training" python3 -m mvgrasp_train.physics target/attempts-ci
echo "== scripts: compare_eval (standard library)"
python3 -m unittest discover -s scripts/tests -v
echo "== cargo nextest"
cargo nextest run --workspace --no-fail-fast
