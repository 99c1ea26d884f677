#!/usr/bin/env bash
# Regenerates the pictures shown in README.md ("Pictures") and the OMCT report in docs/omct/.
#
#   bash docs/images/make.sh                       # everything (the OMCT of every algorithm)
#   OMCT_FREQUENCIES=6 bash docs/images/make.sh    # a quicker OMCT: 6 of the 12 frequencies
#
# Every figure uses hexcue's default algorithm list, i.e. every algorithm this build knows, so
# re-running it after a new algorithm lands adds that algorithm everywhere. Idempotent: it
# overwrites its outputs and leaves nothing else behind.
set -euo pipefail
cd "$(dirname "$0")/../.."

cargo build --release --quiet
hexcue() { cargo run --release --quiet -- "$@"; }

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Time histories: the horizontal stall of the S-MPC paper, every algorithm.
hexcue play --headless --trace recordings/traces/horizontal-stall.csv \
    --record "$tmp/horizontal-stall.mcap" > "$tmp/horizontal-stall.txt"
hexcue plot "$tmp/horizontal-stall.mcap" --channels fx,fy \
    -o docs/images/horizontal-stall-fx-fy.png --force
hexcue plot "$tmp/horizontal-stall.mcap" --channels legs \
    -o docs/images/horizontal-stall-legs.png --force
hexcue plot "$tmp/horizontal-stall.mcap" --channels x,pitch,leg1,leg4 \
    -o docs/images/horizontal-stall-pose-legs.png --force

# The S-MPC's supervisor, blend and fallback: a flight where it leaves COTC.
hexcue play --headless --trace recordings/traces/library/737-rejected-takeoff.csv \
    --record "$tmp/737-rejected-takeoff.mcap" > "$tmp/737-rejected-takeoff.txt"
hexcue plot "$tmp/737-rejected-takeoff.mcap" --channels fx,pitch \
    -o docs/images/737-rejected-takeoff-smpc.png --force

# The OMCT of every algorithm: docs/omct/omct.md, omct.json and one Bode plot per test.
# --force: these replace the shipped figures (hexcue never overwrites without it).
hexcue omct --frequencies "${OMCT_FREQUENCIES:-12}" --out docs/omct --force
