#!/bin/sh
# A live JSBSim session of a few minutes, with or without two busy loops beside it, and
# what hexcue's summary says of its deadlines (docs/live.md, *Real time*). Not in CI: it
# takes minutes and measures the machine as much as hexcue.
#
#   scripts/live-under-load.sh [SECONDS] [BUSY_LOOPS] [HEXCUE] [-- extra hexcue live options]
#
# SECONDS (default 180) of session; BUSY_LOOPS (default 2) shells spinning at normal
# priority, as a visual system, a build or a second simulator would beside hexcue; HEXCUE
# the binary (default target/release/hexcue). Needs PyPI's jsbsim (installed into
# target/venv if missing). The session e-stops at its end while JSBSim still sends, so the
# latency covers fresh input only (no input-loss window at the end). Writes its files to
# target/live-under-load/ and prints one result line. SIM_FIFO=N runs JSBSim itself under
# SCHED_FIFO priority N (chrt), as a simulator protected from the same load would run.
set -eu
cd "$(dirname "$0")/.."
SECONDS_RUN=${1:-180}
BUSY=${2:-2}
HEXCUE=${3:-target/release/hexcue}
shift $(( $# < 3 ? $# : 3 ))
[ "${1:-}" = "--" ] && shift
OUT=target/live-under-load
mkdir -p "$OUT"
PY=target/venv/bin/python
if ! "$PY" -c "import jsbsim" 2>/dev/null; then
    python3 -m venv target/venv && target/venv/bin/pip install --quiet jsbsim mcap
fi

free_port() { "$PY" -c 'import socket; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
IN_PORT=$(free_port)
OUT_PORT=$(free_port)
# The shipped directive, on a port of this run's own (5138 may be a test's).
sed "s/port=\"5138\"/port=\"$IN_PORT\"/" integrations/jsbsim/hexcue.xml > "$OUT/directive.xml"
TAG="load$BUSY${SIM_FIFO:+-simfifo}-$(date +%H%M%S)"

PIDS=""
cleanup() { for p in $PIDS; do kill "$p" 2>/dev/null || true; done; }
trap cleanup EXIT INT TERM
i=0
while [ "$i" -lt "$BUSY" ]; do
    sh -c 'while :; do :; done' &
    PIDS="$PIDS $!"
    i=$((i + 1))
done

echo "before: $(uptime)" > "$OUT/$TAG.machine.txt"
"$HEXCUE" live --headless --duration "$SECONDS_RUN" --input "jsbsim://127.0.0.1:$IN_PORT" \
    --output "udp://127.0.0.1:$OUT_PORT" --record "$OUT/$TAG.mcap" --summary "$OUT/$TAG.json" \
    --force "$@" > "$OUT/$TAG.table" 2> "$OUT/$TAG.stderr" &
HEX=$!
sleep 1
# JSBSim outlives the session by 8 s: the e-stop's washout (≤ 5 s) runs on fresh input.
${SIM_FIFO:+chrt -f "$SIM_FIFO"} "$PY" tests/jsbsim_flight.py "$PWD/$OUT/directive.xml" "$((SECONDS_RUN + 8))" repeat \
    > /dev/null 2> "$OUT/$TAG.jsbsim" &
FLIGHT=$!
PIDS="$PIDS $FLIGHT"
sleep $((SECONDS_RUN / 2))
{
    echo "midway: $(uptime)"
    echo "busiest processes midway (ps, %CPU over each one's life):"
    ps -eo pid,cls,rtprio,ni,pcpu,comm --sort=-pcpu | head -15
} >> "$OUT/$TAG.machine.txt"
wait "$HEX"
wait "$FLIGHT" || true
echo "after: $(uptime)" >> "$OUT/$TAG.machine.txt"
"$PY" - "$OUT/$TAG.json" "$BUSY" "$OUT/$TAG.jsbsim" "${SIM_FIFO:-}" <<'PYEOF'
import json, sys
s = json.load(open(sys.argv[1]))
l = s["live"]
rt = l.get("realtime", {})
fifo = f"SCHED_FIFO {rt['priority']}" if rt.get("sched_fifo") else ("normal priority" + (f" ({rt['sched_fifo_refused']})" if rt.get("sched_fifo_refused") else ""))
lock = "memory locked" if rt.get("memory_locked") else "memory not locked"
print(
    f"{sys.argv[2]} busy loops, {fifo}, {lock}: {l['deadline_misses']} deadline misses of "
    f"{l['commands_out']} steps, step median {l['step_ms']['median']:.2f} ms p99 {l['step_ms']['p99']:.2f} ms, "
    f"latency median {l['latency_ms']['median']:.2f} ms p99 {l['latency_ms']['p99']:.2f} ms, "
    + (f"new-sample latency median {l['new_sample_latency_ms']['median']:.2f} ms p99 {l['new_sample_latency_ms']['p99']:.2f} ms, "
       f"{l['stale_steps']} stale steps, " if "stale_steps" in l else "")
    + f"{l['samples_in']} samples in, {l.get('frames_dropped', 'n/a')} frames dropped; "
    + (f"JSBSim at SCHED_FIFO {sys.argv[4]}, " if sys.argv[4] else "")
    + open(sys.argv[3]).read().strip()
)
PYEOF
echo "files: $OUT/$TAG.{json,table,mcap,stderr,jsbsim,machine.txt}"
