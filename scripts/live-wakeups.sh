#!/bin/sh
# How often the live stepping thread wakes up, and hexcue's own delay from a sample's
# arrival to its command (docs/performance.md, *Live: driven by its input*). Not in CI: it
# measures the machine as much as hexcue.
#
#   scripts/live-wakeups.sh [HEXCUE] [SECONDS] [-- extra hexcue live options]
#
# HEXCUE the binary (default target/release/hexcue); SECONDS (default 10) counted. A
# shipped trace is sent in JSBSim's socket format at 100 Hz (docs/replay-jsbsim.py, Python's
# standard library only); hexcue runs headless with the CWF alone (the stepping thread's own
# work, whatever the algorithms cost) unless told otherwise after `--`, and stops while the
# sender still sends, so the latency covers fresh input only. The stepping thread is the
# main thread in headless mode: its voluntary context switches (each a sleep that ended)
# are read from /proc/PID/task/PID/status 2 s into the session and SECONDS later.
set -eu
cd "$(dirname "$0")/.."
HEXCUE=${1:-target/release/hexcue}
SECS=${2:-10}
shift $(( $# < 2 ? $# : 2 ))
[ "${1:-}" = "--" ] && shift
[ $# -eq 0 ] && set -- --algorithms cwf --drive cwf
OUT=target/live-wakeups
mkdir -p "$OUT"
free_port() { python3 -c 'import socket; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
IN_PORT=$(free_port)
OUT_PORT=$(free_port)
TAG="$(basename "$HEXCUE")-$(date +%H%M%S)"
python3 docs/replay-jsbsim.py recordings/traces/steep-turn.csv "$IN_PORT" 5 $((SECS + 8)) &
SENDER=$!
trap 'kill $SENDER 2>/dev/null || true' EXIT INT TERM
"$HEXCUE" live --headless --duration $((SECS + 4)) --input "jsbsim://127.0.0.1:$IN_PORT" \
    --output "udp://127.0.0.1:$OUT_PORT" --summary "$OUT/$TAG.json" "$@" 2>"$OUT/$TAG.err" &
PID=$!
switches() { awk '/^voluntary_ctxt_switches/ {v=$2} /^nonvoluntary_ctxt_switches/ {n=$2} END {print v, n}' "/proc/$PID/task/$PID/status"; }
sleep 2
A=$(switches)
sleep "$SECS"
B=$(switches)
wait "$PID" || true
python3 - "$OUT/$TAG.json" "$SECS" "$A" "$B" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))["live"]
secs = float(sys.argv[2])
(v0, n0), (v1, n1) = (map(int, a.split()) for a in sys.argv[3:5])
lat, new, step = s["latency_ms"], s["new_sample_latency_ms"], s["step_ms"]
print(f"stepping thread: {(v1 - v0) / secs:.0f} wake-ups/s (voluntary), {(n1 - n0) / secs:.1f} preemptions/s; "
      f"latency p50 {lat['median']:.2f} ms p99 {lat['p99']:.2f} ms; "
      f"new-sample latency p50 {new['median']:.2f} ms p99 {new['p99']:.2f} ms; "
      f"step p50 {step['median']:.3f} ms p99 {step['p99']:.3f} ms; "
      f"deadline misses {s['deadline_misses']} of {s['commands_out']}; "
      f"samples in {s['samples_in']}; realtime {s['realtime'].get('sched_fifo')}")
PY
