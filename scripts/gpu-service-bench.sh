#!/usr/bin/env bash
# The service on a GPU machine: the CUDA backend (and the CPU one beside it)
# under `mvgrasp bench`, samples/table6, the server's default request (view
# cascade on) and default model, from 1 to 256 concurrent clients.
#
# Needs: a server built with `cargo build --release -p mvgrasp-server -p mvgrasp-client
# --features mvgrasp-server/cuda`, and ONNX Runtime 1.31.1's GPU build, i.e. the
# `onnxruntime/capi/libonnxruntime*.so*` files of the `onnxruntime-gpu==1.31.1` wheel
# unpacked into $ORT_GPU_DIR, with CUDA 13 / cuDNN 9 libraries on the loader path
# (the script adds every lib folder of the `nvidia` Python packages, if present).
#
#   ORT_GPU_DIR=/tmp/ortgpu OUT=/tmp/out SERVER=target/release/mvgrasp-server \
#     CLIENT=target/release/mvgrasp [RUNS=FILE] [BENCH_ARGS="..."] [CONNECTIONS=each|N] \
#     bash scripts/gpu-service-bench.sh [SECONDS]
#
# CONNECTIONS: the connections the clients take turns over, `each` (one per
# client, as a fleet's robots) or a count (default 1: all share one).
#
# Each setting: a fresh server (its CUDA warm-up line goes to stdout), then
# `mvgrasp bench --json` per client count (appended to $OUT/bench.jsonl,
# labelled), then the server's per-stage time sums from /metrics
# ($OUT/stages-LABEL.txt).
set -uo pipefail
seconds=${1:-8}
ORT_GPU_DIR=${ORT_GPU_DIR:?the folder holding libonnxruntime.so.1.31.1 of the GPU wheel}
OUT=${OUT:-target/bench}
S=${SERVER:-target/release/mvgrasp-server}
C=${CLIENT:-target/release/mvgrasp}
MODEL=${MODEL:-$(sed -n 's/^path = "\([^"]*\)".*/\1/p' deploy/server.toml | head -1)}
mkdir -p "$OUT"
NV=$(python3 -c "import nvidia; print(list(nvidia.__path__)[0])" 2>/dev/null || true)
LIBS=$([ -n "$NV" ] && find "$NV" -name 'lib*.so*' -printf '%h\n' | sort -u | paste -sd: || true)
export LD_LIBRARY_PATH="$ORT_GPU_DIR${LIBS:+:$LIBS}${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
ORT=$ORT_GPU_DIR/libonnxruntime.so.1.31.1
# BENCH_ARGS: more `mvgrasp bench` request flags, e.g. "--approach-cone 0 0 -1 60" (the robot-bridge's)
read -r -a extra <<<"${BENCH_ARGS:-}"
connections_for() { # clients -> connections
    if [[ "${CONNECTIONS:-1}" == each ]]; then echo "$1"; else echo "${CONNECTIONS:-1}"; fi
}
SCENE=(--depth samples/table6/depth.png --camera samples/table6/camera.json "${extra[@]}")
echo "model $MODEL; $(nproc) cores; $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null)"
port=50600
cpu_s() { # a process's user + system CPU seconds so far
    awk -v hz="$(getconf CLK_TCK)" '{ print ($14 + $15) / hz }' "/proc/$1/stat"
}
run() { # label device max_batch_views conv_search sessions clients...
    local label=$1 dev=$2 mb=$3 search=$4 sessions=$5
    shift 5
    port=$((port + 2))
    RUST_LOG=info NO_COLOR=1 "$S" --config deploy/server.toml --listen 127.0.0.1:$port \
        --metrics-listen 127.0.0.1:$((port + 1)) --model "$MODEL" --onnxruntime "$ORT" --device "$dev" \
        --intra-threads 2 --max-batch-views "$mb" --max-wait-ms 2 --cuda-conv-search "$search" --sessions "$sessions" \
        >"$OUT/server-$label.log" 2>&1 &
    local pid=$!
    for _ in $(seq 900); do
        "$C" --server http://127.0.0.1:$port health >/dev/null 2>&1 && break
        kill -0 "$pid" 2>/dev/null || { echo "$label: the server exited"; tail -5 "$OUT/server-$label.log"; return; }
        sleep 0.1
    done
    sed 's/\x1b\[[0-9;]*m//g' "$OUT/server-$label.log" | grep -oE "(CUDA|WARN|ERROR).*" | head -3
    for clients in "$@"; do
        local report before client connections
        connections=$(connections_for "$clients")
        before=$(cpu_s "$pid")
        # The client's CPU seconds (bash's `time`: user + system) beside the server's.
        client=$( { TIMEFORMAT='%U %S'; time "$C" --server http://127.0.0.1:$port bench "${SCENE[@]}" --warmup 20 \
            --json --concurrency "$clients" --connections "$connections" --duration-s "$seconds" >"$OUT/report.json"; } 2>&1 | awk '{ print $1 + $2 }')
        report=$(cat "$OUT/report.json")
        echo "{\"label\": \"$label\", \"clients\": $clients, \"connections\": $connections, \"server_cpu_s\": $(awk -v a="$(cpu_s "$pid")" -v b="$before" 'BEGIN { print a - b }'), \"client_cpu_s\": $client, \"report\": $report}" | tee -a "$OUT/bench.jsonl"
    done
    rm -f "$OUT/report.json"
    python3 -c "import urllib.request as u; print(u.urlopen('http://127.0.0.1:$((port + 1))/metrics').read().decode())" \
        | grep -E "^mvgrasp_stage_duration_seconds_(sum|count)" >"$OUT/stages-$label.txt"
    kill "$pid"; wait "$pid" 2>/dev/null
}
dmon=
command -v nvidia-smi >/dev/null && { nvidia-smi dmon -s u -d 1 >"$OUT/dmon.txt" 2>&1 & dmon=$!; }
# label device max_batch_views conv_search sessions clients...; RUNS=FILE: one such line each
if [[ -n "${RUNS:-}" ]]; then
    while read -r line; do
        [[ -z "$line" || "$line" == \#* ]] || run $line
    done <"$RUNS"
else
    run cuda-b64-s1 cuda 64 exhaustive 1 1 16 64 256
    run cuda-b64-s2 cuda 64 exhaustive 2 1 16 64 256
    run cuda-b64-s4 cuda 64 exhaustive 4 16 64 256
    run cuda-b32-s2 cuda 32 exhaustive 2 16 64 256
    run cuda-b32-s4 cuda 32 exhaustive 4 16 64 256
    run cpu cpu 32 exhaustive 1 1 16 64
fi
[ -n "$dmon" ] && kill "$dmon"
