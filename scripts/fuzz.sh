#!/usr/bin/env bash
# Fuzzes every target of fuzz/ (libFuzzer through cargo-fuzz) on the stable
# toolchain: `scripts/fuzz.sh [RUNS]` (default 1,000,000 per target, the
# targets in FUZZ_TARGETS or all; CI runs
# a short pass). Seeds are in fuzz/seeds/<target>, inputs that once crashed
# in fuzz/regressions/<target> (each also a unit test); the corpus grows in
# fuzz/corpus/<target> (not committed); a crash lands in fuzz/artifacts/ and
# fails the script. Sanitizer: none (the code under test is safe Rust; what
# is looked for is panics, hangs, unbounded memory).
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-1000000}
if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "== installing cargo-fuzz"
    cargo install cargo-fuzz --locked
fi
export RUSTC_BOOTSTRAP=1
for target in ${FUZZ_TARGETS:-plan_request client_files bridge_protocols}; do
    mkdir -p "fuzz/corpus/$target"
    echo "== fuzz $target: $runs runs"
    start=$(date +%s)
    log="fuzz/$target.log"
    set +e
    mkdir -p "fuzz/regressions/$target"
    cargo fuzz run --sanitizer none "$target" "fuzz/corpus/$target" "fuzz/seeds/$target" "fuzz/regressions/$target" -- \
        -runs="$runs" -max_len=4096 -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 >"$log" 2>&1
    status=$?
    set -e
    grep -E "^(#[0-9]+ +(INITED|DONE)|stat::number_of_executed_units|stat::peak_rss_mb|SUMMARY|==[0-9]+== ERROR)|panicked" "$log" || tail -20 "$log"
    echo "   $target: exit $status after $(( $(date +%s) - start )) s (log: $log)"
    [[ $status -eq 0 ]] || exit "$status"
done
