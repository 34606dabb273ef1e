#!/usr/bin/env bash
# The service on a GPU machine: the CUDA backend (and the CPU one beside it)
# under `mvgrasp bench`, samples/table6, one client and 16 clients.
#
# Needs: a server built with `cargo build --release -p mvgrasp-server -p mvgrasp-client
# --features mvgrasp-server/cuda`, and ONNX Runtime 1.31.1's GPU build, i.e. the
# `onnxruntime/capi/libonnxruntime*.so*` files of the `onnxruntime-gpu==1.31.1` wheel
# unpacked into $ORT_GPU_DIR, with CUDA 13 / cuDNN 9 libraries on the loader path
# (the script adds every lib folder of the `nvidia` Python packages, if present).
#
#   ORT_GPU_DIR=/tmp/ortgpu OUT=/tmp/out SERVER=target/release/mvgrasp-server \
#     CLIENT=target/release/mvgrasp bash scripts/gpu-service-bench.sh [SECONDS]
#
# Each setting: a fresh server (its CUDA warm-up line goes to stdout), then
# `mvgrasp bench --json` (appended to $OUT/bench.jsonl, labelled).
set -uo pipefail
seconds=${1:-6}
ORT_GPU_DIR=${ORT_GPU_DIR:?the folder holding libonnxruntime.so.1.31.1 of the GPU wheel}
OUT=${OUT:-target/bench}
S=${SERVER:-target/release/mvgrasp-server}
C=${CLIENT:-target/release/mvgrasp}
mkdir -p "$OUT"
NV=$(python3 -c "import nvidia; print(list(nvidia.__path__)[0])" 2>/dev/null || true)
LIBS=$([ -n "$NV" ] && find "$NV" -name 'lib*.so*' -printf '%h\n' | sort -u | paste -sd: || true)
export LD_LIBRARY_PATH="$ORT_GPU_DIR${LIBS:+:$LIBS}${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
ORT=$ORT_GPU_DIR/libonnxruntime.so.1.31.1
SCENE=(--depth samples/table6/depth.png --camera samples/table6/camera.json)
port=50600
run() { # label device max_batch_views conv_search
    local label=$1 dev=$2 mb=$3 search=$4
    port=$((port + 1))
    RUST_LOG=info NO_COLOR=1 "$S" --listen 127.0.0.1:$port --no-metrics --model models/mvgrasp.onnx \
        --onnxruntime "$ORT" --device "$dev" --intra-threads 2 --max-batch-views "$mb" --max-wait-ms 2 \
        --cuda-conv-search "$search" >"$OUT/server-$label.log" 2>&1 &
    local pid=$!
    for _ in $(seq 900); do "$C" --server http://127.0.0.1:$port health >/dev/null 2>&1 && break; sleep 0.1; done
    sed 's/\x1b\[[0-9;]*m//g' "$OUT/server-$label.log" | grep -oE "(CUDA|WARN).*" | head -3
    for clients in 1 16; do
        local report
        report=$("$C" --server http://127.0.0.1:$port bench "${SCENE[@]}" --warmup 20 --json \
            --concurrency $clients --duration-s "$seconds")
        echo "{\"label\": \"$label\", \"clients\": $clients, \"report\": $report}" | tee -a "$OUT/bench.jsonl"
    done
    kill "$pid"; wait "$pid" 2>/dev/null
}
run cuda-exhaustive-b64 cuda 64 exhaustive
run cuda-exhaustive-b16 cuda 16 exhaustive
run cuda-default-b64 cuda 64 default
run cpu-b64 cpu 64 exhaustive
