#!/usr/bin/env bash
# Two or more model files side by side through the service, in one run: the
# release server with deploy/server.toml, the sample frame (640x480, 6
# objects), one client and 16 clients, the files alternated ROUNDS times (the
# machine is noisy), each server started fresh. Prints a Markdown table and
# keeps every report in target/bench/models.jsonl.
# Usage: scripts/bench-models.sh MODEL.onnx MODEL.onnx [...]   (ROUNDS=2 SECONDS_PER_RUN=10 in the environment)
set -euo pipefail
cd "$(dirname "$0")/.."
[[ $# -ge 2 ]] || { echo "usage: $0 MODEL.onnx MODEL.onnx [...]" >&2; exit 2; }
rounds=${ROUNDS:-2}
seconds=${SECONDS_PER_RUN:-10}
ort="$(scripts/fetch-onnxruntime.sh)"
cargo build --release --quiet -p mvgrasp-server -p mvgrasp-client
mkdir -p target/bench
out=target/bench/models.jsonl
: > "$out"
scene=(--depth samples/table6/depth.png --camera samples/table6/camera.json)
for round in $(seq "$rounds"); do
    for model in "$@"; do
        port=$((50100 + RANDOM % 800))
        target/release/mvgrasp-server --config deploy/server.toml --listen "127.0.0.1:$port" --no-metrics \
            --model "$model" --onnxruntime "$ort" > target/bench/models-server.log 2>&1 &
        pid=$!
        for _ in $(seq 100); do
            target/release/mvgrasp --server "http://127.0.0.1:$port" health >/dev/null 2>&1 && break
            sleep 0.1
        done
        for clients in 1 16; do
            report=$(target/release/mvgrasp --server "http://127.0.0.1:$port" bench "${scene[@]}" \
                --duration-s "$seconds" --warmup 20 --json --concurrency "$clients")
            echo "{\"round\": $round, \"model\": \"$model\", \"clients\": $clients, \"report\": $report}" >> "$out"
        done
        kill -TERM "$pid"; wait "$pid" || true
    done
done
python3 - "$out" <<'EOF'
import json, sys
rows = [json.loads(line) for line in open(sys.argv[1])]
print("| model | one client p50 ms, per round | server p50 ms | 16 clients calls/s, per round | 16 clients p99 ms | grasps per answer |")
print("|---|---|---|---|---|---|")
for model in dict.fromkeys(r["model"] for r in rows):
    one = [r["report"] for r in rows if r["model"] == model and r["clients"] == 1]
    many = [r["report"] for r in rows if r["model"] == model and r["clients"] == 16]
    fmt = lambda xs: " / ".join(f"{x:.2f}" for x in xs)
    print(f"| `{model}` | {fmt(r['p50_ms'] for r in one)} "
          f"| {fmt(r['server_p50_ms'] for r in one)} "
          f"| {' / '.join(str(round(r['throughput_per_s'])) for r in many)} "
          f"| {fmt(r['p99_ms'] for r in many)} | {fmt(r['mean_grasps'] for r in one)} |")
EOF
