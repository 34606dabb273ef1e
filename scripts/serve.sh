#!/usr/bin/env bash
# Starts mvgrasp-server (release build) on 0.0.0.0:50051 with the CPU backend
# and the shipped model (or $MVGRASP_MODEL), metrics on :9464. Extra arguments go to the server
# (see `mvgrasp-server --help` and deploy/server.toml).
set -euo pipefail
cd "$(dirname "$0")/.."
ORT_DYLIB_PATH="$(scripts/fetch-onnxruntime.sh)"
export ORT_DYLIB_PATH
cargo build --release --quiet -p mvgrasp-server -p mvgrasp-client
model=${MVGRASP_MODEL:-models/mvgrasp-physics-labels.onnx}
if [[ -n "${MVGRASP_MODEL:-}" && ! -f "$model" ]]; then
    echo "error: MVGRASP_MODEL=$model: no such file" >&2
    exit 1
fi
if [[ -f "$model" ]]; then
    exec target/release/mvgrasp-server --config deploy/server.toml --model "$model" --device cpu "$@"
fi
echo "warning: $model is not shipped yet (issue 4); serving the analytic baseline instead" >&2
exec target/release/mvgrasp-server --config deploy/server.toml --backend baseline "$@"
