#!/usr/bin/env bash
# The service benchmark of BENCHMARKS.md: samples/table6 (640x480, 6 objects),
# entropy policy, CPU backend, through gRPC on this machine:
#   1. one client, calls back to back: end-to-end latency;
#   2. 16 concurrent clients with batching, then the same without batching
#      (max_batch_views = 1: every call's views run alone), in this one run.
# The model is the default (deploy/server.toml's [model] path) or $MODEL.
# Results: target/bench/service.jsonl and a Markdown table on stdout.
# The two 16-client settings alternate REPEATS times (the machine is noisy).
# Usage: scripts/bench-service.sh [SECONDS per setting, default 20] [REPEATS, default 3]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-20}
repeats=${2:-3}
ort="$(scripts/fetch-onnxruntime.sh)"
mkdir -p target/bench
# The default model, as deploy/server.toml names it (models/manifest.toml), or $MODEL.
model=${MODEL:-$(sed -n 's/^path = "\([^"]*\)".*/\1/p' deploy/server.toml | head -1)}
[[ -f "$model" ]] || { echo "error: $model: no such model file" >&2; exit 1; }
cargo build --release --quiet -p mvgrasp-server -p mvgrasp-client
out=target/bench/service.jsonl
echo "$model" > target/bench/model.txt  # the plot's title
: > "$out"
scene=(--depth samples/table6/depth.png --camera samples/table6/camera.json)

measure() { # label, client args, then -- server args
    local label=$1; shift
    local client_args=()
    while [[ $1 != -- ]]; do client_args+=("$1"); shift; done
    shift
    local port=$((50100 + RANDOM % 800))
    /usr/bin/time -v -o "target/bench/$label.time" target/release/mvgrasp-server --listen "127.0.0.1:$port" \
        --no-metrics --model "$model" --onnxruntime "$ort" "$@" > "target/bench/$label.log" 2>&1 &
    local pid=$!
    for _ in $(seq 100); do
        target/release/mvgrasp --server "http://127.0.0.1:$port" health >/dev/null 2>&1 && break
        sleep 0.1
    done
    local report
    report=$(target/release/mvgrasp --server "http://127.0.0.1:$port" bench "${scene[@]}" \
        --duration-s "$seconds" --warmup 10 --json "${client_args[@]}")
    pkill -TERM -P "$pid"; wait "$pid" || true  # the server, so that time(1) reports
    local rss_kb
    rss_kb=$(awk -F': ' '/Maximum resident/ {print $2}' "target/bench/$label.time")
    echo "{\"label\": \"$label\", \"server_max_rss_kb\": $rss_kb, \"report\": $report}" | tee -a "$out"
}

measure single --concurrency 1 -- --intra-threads 2
for _ in $(seq "$repeats"); do
    measure batched-16 --concurrency 16 -- --intra-threads 2 --max-batch-views 64 --max-wait-ms 2
    measure unbatched-16 --concurrency 16 -- --intra-threads 2 --max-batch-views 1 --max-wait-ms 0
done

python3 - "$out" "$model" <<'PY'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
print(f"\nmodel: {sys.argv[2]}\n")
import statistics
for label in sorted({r["label"] for r in rows}):
    t = [r["report"]["throughput_per_s"] for r in rows if r["label"] == label]
    print(f"{label}: median {statistics.median(t):.1f} calls/s over {len(t)} runs ({', '.join(f'{v:.1f}' for v in t)})")
print()
print("| setting | clients | calls/s | p50 ms | p90 ms | p99 ms | server p50 ms | errors | server max RSS MiB |")
print("|---|---|---|---|---|---|---|---|---|")
for r in rows:
    b = r["report"]
    print(f"| {r['label']} | {b['concurrency']} | {b['throughput_per_s']:.1f} | {b['p50_ms']:.2f} | {b['p90_ms']:.2f} | "
          f"{b['p99_ms']:.2f} | {b['server_p50_ms']:.2f} | {b['errors']} | {r['server_max_rss_kb'] / 1024:.0f} |")
PY
