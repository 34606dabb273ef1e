#!/usr/bin/env bash
# Generates a dataset on every core and trains the grasp network on the GPU.
#
# Written for the lent GPU machine (16 cores, one H100, PyTorch there), run
# from the repository root with a release `sim` binary built elsewhere:
#
#   SIM=.carry/sim DATA=/tmp/mvgrasp-data OUT=/tmp/out \
#     bash scripts/gpu-datagen-train.sh datagen 270      # chunks until ~270 s are spent
#   OUT=/tmp/out bash scripts/gpu-datagen-train.sh train 240 [ARCH...]
#
# `datagen SECONDS`: `sim datagen` in chunks of $SCENES_PER_CHUNK scenes
# (isolated, packed, pile and heavy clutter in turn, 72 px x 3.33 mm views,
# data version $DATA_VERSION, default sim-6: sim-4's labels (fingertips 3 cm
# past the surface, as the planner has inserted them since 7332953; sim-3
# was 1.5 cm) with a 20 degree friction cone and a 0.6 N m torque limit
# (sim-5: 0.15 N m)), each chunk with its own seed range, until the next
# chunk would pass SECONDS. Each chunk's scenes, views and wall time go to
# $OUT/datagen.tsv: that is the throughput figure of issue 3.
# $SCENARIOS (default isolated,packed,pile,clutter) and $DATAGEN_ARGS (more
# `sim datagen` options, e.g. "--stride-px 1 --angles 16": labels at every
# pixel and 16 angles, about 10x the labelling time; docs/experiments/2026-11-24-dense-labels.md, "Dense
# labels") change what each chunk holds.
# `train MINUTES ARCH...`: one training run per architecture (default:
# paper), all at once on the one GPU, cosine schedule over MINUTES, on every
# chunk in $DATA, holding out the bowl family, the error at positive pixels
# weighted $POSITIVE_WEIGHT times (default 10; 1 is the paper's plain MSE;
# docs/experiments/ has the measurement), plus $RANK_WEIGHT times the rank loss
# (default 0: off; 0.01 lifted view accuracy 3 points on this CPU but
# cleared fewer objects in physics, docs/experiments/), under $SYMMETRIES
# (default gravity: front and side views only mirrored left-right, so the
# table stays below; all: the 8 symmetries of the square for every view, as
# stage 1 of the model card was trained). ARCH: paper, narrow,
# skip. Runs land in $DATA/runs/ARCH. DEVICE (default cuda) = cpu runs the
# same steps on a CPU, small, to check the script before spending device time.
set -euo pipefail

SIM=${SIM:-target/release/sim}
DATA=${DATA:-/tmp/mvgrasp-data}
OUT=${OUT:-/tmp/out}
SCENES_PER_CHUNK=${SCENES_PER_CHUNK:-1200}
SEED0=${SEED0:-200000}
DATA_VERSION=${DATA_VERSION:-sim-6}
POSITIVE_WEIGHT=${POSITIVE_WEIGHT:-10}
RANK_WEIGHT=${RANK_WEIGHT:-0}
SYMMETRIES=${SYMMETRIES:-gravity}
DEVICE=${DEVICE:-cuda}
SCENARIOS=${SCENARIOS:-isolated,packed,pile,clutter}
DATAGEN_ARGS=${DATAGEN_ARGS:-}
mkdir -p "$DATA" "$OUT"

chunks() { find "$DATA" -maxdepth 2 -name manifest.json -printf '%h\n' | sort | paste -sd, -; }

case "${1:-}" in
datagen)
    budget=${2:?seconds}
    started=$(date +%s)
    [ -f "$OUT/datagen.tsv" ] || printf 'chunk\tscenes\tviews\tviews_with_positives\tseconds\tthreads\n' >"$OUT/datagen.tsv"
    i=$(find "$DATA" -maxdepth 1 -name 'chunk-*' | wc -l)
    last=0
    while :; do
        now=$(date +%s)
        if [ $((now - started + last)) -gt "$budget" ]; then break; fi
        dir=$(printf '%s/chunk-%03d' "$DATA" "$i")
        t0=$(date +%s.%N)
        "$SIM" datagen --scenes "$SCENES_PER_CHUNK" --seed $((SEED0 + i * SCENES_PER_CHUNK)) \
            --scenarios "$SCENARIOS" --input-size-px 72 --pixel-size-mm 3.3333333 \
            --data-version "$DATA_VERSION" $DATAGEN_ARGS --out "$dir" 2>"$dir.log" >/dev/null || { tail -5 "$dir.log"; exit 1; }
        t1=$(date +%s.%N)
        python3 - "$dir" "$i" "$SCENES_PER_CHUNK" "$t0" "$t1" "$(nproc)" >>"$OUT/datagen.tsv" <<'EOF'
import json, sys
d, i, scenes, t0, t1, threads = sys.argv[1:]
m = json.load(open(f"{d}/manifest.json"))
print(f"{i}\t{scenes}\t{m['views']}\t{m['views_with_positives']}\t{float(t1) - float(t0):.1f}\t{threads}")
EOF
        tail -1 "$OUT/datagen.tsv"
        last=$(python3 -c "print(int($t1 - $t0) + 1)")
        i=$((i + 1))
    done
    ;;
train)
    minutes=${2:?minutes}
    shift 2
    archs=("${@:-paper}")
    data=$(chunks)
    pids=()
    for arch in "${archs[@]}"; do
        (cd training && PYTHONUNBUFFERED=1 python3 -m mvgrasp_train.train --data "$data" --out "$DATA/runs/$arch" \
            --architecture "$arch" --device "$DEVICE" --batch 64 --lr 1e-3 --schedule cosine \
            --epochs 1000 --minutes "$minutes" --eval-every 4 --hold-out-families bowl \
            --positive-weight "$POSITIVE_WEIGHT" --rank-weight "$RANK_WEIGHT" --symmetries "$SYMMETRIES" \
            >"$OUT/train-$arch.log" 2>&1) &
        pids+=($!)
    done
    for pid in "${pids[@]}"; do wait "$pid"; done
    ;;
*)
    echo "usage: $0 datagen SECONDS | train MINUTES [ARCH...]" >&2
    exit 2
    ;;
esac
