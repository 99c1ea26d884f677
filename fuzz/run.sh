#!/usr/bin/env bash
# Runs each fuzz target for a fixed time: fuzz/run.sh [SECONDS per target, default 60].
#
# Needs cargo-fuzz (`cargo install cargo-fuzz`) and a C++ compiler (libFuzzer is built from
# source by libfuzzer-sys). cargo-fuzz passes unstable rustc flags: a nightly toolchain is
# used when there is one, otherwise the stable one with RUSTC_BOOTSTRAP=1 (which lets stable
# rustc accept them). Not part of `cargo test` or CI.
#
# Environment: TARGETS="trace profile recording" to choose, SANITIZER=none|address
# (default none: the code under test is safe Rust, and none runs several times faster),
# JOBS (default 1) parallel fuzzing jobs per target.
#
# Each target starts from the committed seeds in fuzz/seeds/TARGET and grows a working
# corpus in fuzz/corpus/TARGET (ignored by git); a crash is saved in fuzz/artifacts/TARGET
# and makes this script exit non-zero. The last status line of each run (executions,
# coverage, corpus) is kept in fuzz/logs/TARGET.log.
set -euo pipefail
cd "$(dirname "$0")"

SECONDS_PER_TARGET="${1:-60}"
TARGETS="${TARGETS:-trace profile recording}"
SANITIZER="${SANITIZER:-none}"
JOBS="${JOBS:-1}"

if ! command -v cargo-fuzz >/dev/null 2>&1; then
    echo "cargo-fuzz is not installed: cargo install cargo-fuzz" >&2
    exit 2
fi
if rustup run nightly rustc --version >/dev/null 2>&1; then
    TOOLCHAIN=(+nightly)
else
    TOOLCHAIN=()
    export RUSTC_BOOTSTRAP=1
    echo "no nightly toolchain: using stable with RUSTC_BOOTSTRAP=1" >&2
fi

# Inputs larger than any seed are rarely useful; recordings need room for a small file.
max_len() {
    case "$1" in
        recording) echo 65536 ;;
        *) echo 16384 ;;
    esac
}

# libFuzzer forks and writes to fuzz-N.log once -jobs is given at all: only for JOBS > 1.
PARALLEL=()
if [ "$JOBS" -gt 1 ]; then
    PARALLEL=(-jobs="$JOBS" -workers="$JOBS")
fi

mkdir -p logs
status=0
for target in $TARGETS; do
    mkdir -p "corpus/$target" "artifacts/$target"
    echo "== $target: ${SECONDS_PER_TARGET} s" >&2
    set +e
    cargo "${TOOLCHAIN[@]}" fuzz run --sanitizer "$SANITIZER" --debug-assertions \
        "$target" "corpus/$target" "seeds/$target" -- \
        -max_total_time="$SECONDS_PER_TARGET" -max_len="$(max_len "$target")" \
        -timeout=10 -rss_limit_mb=4096 "${PARALLEL[@]}" -print_final_stats=1 \
        >"logs/$target.log" 2>&1
    rc=$?
    set -e
    grep -E '^#[0-9]+' "logs/$target.log" | tail -1 >&2 || true
    grep -E '^stat::number_of_executed_units|^Done [0-9]+ runs' "logs/$target.log" >&2 || true
    if [ $rc -ne 0 ]; then
        echo "$target: the fuzzer stopped with status $rc (see fuzz/logs/$target.log and fuzz/artifacts/$target)" >&2
        status=1
    fi
done
exit $status
