#!/usr/bin/env bash
# The yardstick on the five shipped flights (docs/bound.md, "Measured"): `hexcue bound` on
# each full flight with the release build, one Markdown row per flight (lower, achieved and
# its gap, each algorithm's total error with its cueable part, the share of the CWF's cueable
# error the MPC and the S-MPC remove, the gap's parts and the bound's wall time), and the
# checks the tests make on 20 s slices only: no algorithm below `lower`, in total or on any
# channel, and no leg violation in the achieved motion. Exits non-zero if a check fails.
#
#   bash scripts/bound-table.sh [OUT_DIR]      (default target/bound-table)
#
# Wall times depend on the machine's load: run it on a quiet machine for docs/bound.md.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/bound-table}
mkdir -p "$out"
cargo build --release --quiet
echo "| flight | lower | achieved (gap) | CWF (cueable) | MPC (cueable) | S-MPC (cueable) | MPC / S-MPC remove of the CWF's cueable | grid / exact head unlimited / limiter | bound wall time |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
fail=0
for f in takeoff horizontal-stall landing steep-turn turbulence-cruise; do
    json="$out/$f.json"
    target/release/hexcue bound --trace "recordings/traces/$f.csv" --json "$json" --force \
        > "$out/$f.txt"
    jq -r --arg f "$f" '
      def r3: . * 1000 | round / 1000 | tostring;
      def pc: . * 100 | round | tostring + " %";
      .bound.lower.total as $l
      | .bound.achieved.total as $a
      | .algorithms as $g
      | ($g.cwf.total - $l) as $cc
      | "| \($f) | \($l | r3) | \($a | r3) (+\(($a / $l - 1) | pc)) | \($g.cwf.total | r3) (\($cc | r3)) | \($g.mpc.total | r3) (\(($g.mpc.total - $l) | r3)) | \($g.smpc.total | r3) (\(($g.smpc.total - $l) | r3)) | \((($cc - $g.mpc.total + $l) / $cc) | pc) / \((($cc - $g.smpc.total + $l) / $cc) | pc) | \(.details.gap.relaxed_on_grid | r3) / \(.details.gap.unlimited | r3) / \(.details.gap.replayed | r3) | \(.bound_time_s | round) s |"
    ' "$json"
    jq -e '
      .bound.lower.total as $l
      | (.algorithms | to_entries | all(.value.total >= $l))
        and (.algorithms | to_entries
             | all(.value.error as $e | ($e | keys | all(. as $c | $e[$c] >= ($l0[$c] // 0)))))
        and (.bound.achieved.leg_violations == 0)
    ' --argjson l0 "$(jq '.bound.lower.channel' "$json")" "$json" > /dev/null \
        || { echo "check failed on $f: see $json" >&2; fail=1; }
done
exit $fail
