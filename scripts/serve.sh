#!/usr/bin/env bash
# Starts mvgrasp-server (release build) on 0.0.0.0:50051 with the CPU backend
# and the shipped model (or $MVGRASP_MODEL), metrics on :9464. Extra arguments go to the server
# (see `mvgrasp-server --help` and deploy/server.toml).
set -euo pipefail
cd "$(dirname "$0")/.."
ORT_DYLIB_PATH="$(scripts/fetch-onnxruntime.sh)"
export ORT_DYLIB_PATH
cargo build --release --quiet -p mvgrasp-server -p mvgrasp-client
args=(--config deploy/server.toml --device cpu)   # the config names the default model (models/manifest.toml)
if [[ -n "${MVGRASP_MODEL:-}" ]]; then
    [[ -f "$MVGRASP_MODEL" ]] || { echo "error: MVGRASP_MODEL=$MVGRASP_MODEL: no such file" >&2; exit 1; }
    args+=(--model "$MVGRASP_MODEL")
fi
exec target/release/mvgrasp-server "${args[@]}" "$@"
