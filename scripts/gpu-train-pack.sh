#!/usr/bin/env bash
# Trains several runs at once on the lent GPU machine from a carried pack
# (`python3 -m mvgrasp_train.pack pack ...`; training/README.md), and puts
# the runs, their logs and nvidia-smi's view in $OUT/runs.tar.
#
#   PACK=.gpu/pack RUNS=.gpu/runs.txt MINUTES=6 OUT=/tmp/out bash scripts/gpu-train-pack.sh
#
# RUNS holds one run per line: a name, then `train` options. In them $DATA
# stands for the pack's datasets and $PHYSICS for its attempt folders
# (comma-separated, as --data and --physics take them), $INIT for the folder
# $PACK/init (a run folder carried with the pack, for --init). Every run
# gets --device cuda, --minutes $MINUTES and --out; the rest is the line's.
# Lines starting with # are skipped. DEVICE=cpu MINUTES=0.2 runs the same
# steps on a small pack here, to check the script before spending device
# time.
#
# Budget (H200, 2026-11-27, five runs of the qc recipe at batch 32 on the
# 2,400-scene pack): unpacked in 8 s; the GPU 99% busy, 11 s an epoch per
# run (23-25 epochs in 6.5 minutes); each run's final evaluation of every
# held-out view then took about 150 s on the CPU. MINUTES=6.5 ran past a
# 590 s call, so keep MINUTES + 4 under the call's limit. $OUT/runs.tar is
# rewritten every 20 s, so a call stopped at its limit still brings back
# every run saved by then (model.pt is written before that evaluation).
set -euo pipefail

PACK=${PACK:?PACK: a folder written by mvgrasp_train.pack}
RUNS=${RUNS:?RUNS: a file of runs, one per line}
MINUTES=${MINUTES:?MINUTES: minutes of training per run}
OUT=${OUT:-/tmp/out}
WORK=${WORK:-/tmp/mvgrasp-pack}
DEVICE=${DEVICE:-cuda}
THREADS=${THREADS:-2}
PACK=$(cd "$PACK" && pwd)
RUNS=$(cd "$(dirname "$RUNS")" && pwd)/$(basename "$RUNS")
mkdir -p "$OUT" "$WORK/runs"
started=$(date +%s)
(cd training && python3 -m mvgrasp_train.pack unpack "$PACK" --out "$WORK/data") >"$WORK/unpacked.txt"
joined() { awk -v kind="$1" '$1 == kind { print $2 }' "$WORK/unpacked.txt" | paste -sd, -; }
DATA=$(joined dataset)
PHYSICS=$(joined attempts)
INIT=$PACK/init
echo "unpacked in $(($(date +%s) - started)) s: data $DATA physics $PHYSICS" | tee "$WORK/runs/timing.txt"
pids=()
while read -r name options; do
    case "$name" in '' | '#'*) continue ;; esac
    expanded=${options//\$DATA/$DATA}
    expanded=${expanded//\$PHYSICS/$PHYSICS}
    expanded=${expanded//\$INIT/$INIT}
    mkdir -p "$WORK/runs/$name"
    echo "$name: $expanded" >>"$WORK/runs/timing.txt"
    # shellcheck disable=SC2086 # the options split into words on purpose
    (cd training && status=0 && PYTHONUNBUFFERED=1 python3 -m mvgrasp_train.train $expanded --device "$DEVICE" \
        --threads "$THREADS" --minutes "$MINUTES" --out "$WORK/runs/$name" >"$WORK/runs/$name/train.log" 2>&1 ||
        status=$?
        echo "$name exit $status at $(($(date +%s) - started)) s" >>"$WORK/runs/timing.txt") &
    pids+=($!)
done <"$RUNS"
(sleep 60 && nvidia-smi >"$WORK/runs/nvidia-smi.txt" 2>&1 || true) >/dev/null 2>&1 &
snapshot() { tar -C "$WORK" -cf "$OUT/.runs.tar" runs && mv "$OUT/.runs.tar" "$OUT/runs.tar"; }
(while sleep 20; do snapshot || true; done) >/dev/null 2>&1 &
snapshots=$!
for pid in "${pids[@]}"; do wait "$pid" || true; done
kill "$snapshots"
snapshot
cat "$WORK/runs/timing.txt"
