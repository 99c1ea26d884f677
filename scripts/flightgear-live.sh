#!/bin/sh
# hexcue live against a real FlightGear (docs/live.md, *Against a real FlightGear*). Not in
# CI: it needs FlightGear and a few minutes.
#
#   scripts/flightgear-live.sh [SECONDS] [HEXCUE]
#
# Starts FlightGear (c172p in the air at 3000 ft, 100 kt) under Xvfb in software GL with the
# scenery not drawn, sending integrations/flightgear/hexcue.xml to hexcue and, in the same
# frames, its own body rates (scripts/flightgear/hexcue-rates.xml) to a logger of this
# script's; once it flies, runs
# `hexcue live --headless` for SECONDS (default 40) while ±0.5 aileron doublets go to
# FlightGear over UDP (scripts/flightgear/hexcue-aileron.xml); then compares the roll rate
# hexcue recorded (`/aircraft` of its MCAP) with FlightGear's own (scripts/flightgear_live.py).
# Exit status 0 when they agree within 1 ± 5 %.
#
# Needs (Debian 12): apt-get install -y flightgear xvfb xauth mesa-utils dbus
# and PyPI's mcap and numpy (installed into target/venv if missing).
set -eu
cd "$(dirname "$0")/.."
RUN_S=${1:-40}
HEXCUE=${2:-target/release/hexcue}
for tool in fgfs Xvfb dbus-run-session; do
    if ! command -v "$tool" >/dev/null && [ ! -x "/usr/games/$tool" ]; then
        echo "$tool not found: apt-get install -y flightgear xvfb xauth mesa-utils dbus" >&2
        exit 2
    fi
done
FGFS=$(command -v fgfs || echo /usr/games/fgfs)
PY=target/venv/bin/python
if ! "$PY" -c "import mcap, numpy" 2>/dev/null; then
    python3 -m venv target/venv && target/venv/bin/pip install --quiet mcap numpy
fi
WORK=$PWD/target/flightgear-live/$(date +%Y%m%d-%H%M%S)
# FlightGear's home (its navigation-data cache: ~2 min to build on the first run) is kept
# between runs.
FG_HOME_DIR=$PWD/target/flightgear-live/home
mkdir -p "$WORK/data/Protocol" "$FG_HOME_DIR"
# FlightGear looks for Protocol/NAME.xml in every --data directory before its own root
# (FGGlobals::findDataPath): the shipped protocol file as it is, no copy into FG_ROOT.
cp integrations/flightgear/hexcue.xml scripts/flightgear/hexcue-rates.xml \
    scripts/flightgear/hexcue-aileron.xml "$WORK/data/Protocol/"

free_port() { "$PY" -c 'import socket; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
IN_PORT=$(free_port)
AIL_PORT=$(free_port)
OUT_PORT=$(free_port)
LOG_PORT=$(free_port)
DISPLAY_N=90
while [ -e "/tmp/.X$DISPLAY_N-lock" ]; do DISPLAY_N=$((DISPLAY_N + 1)); done

PIDS=""
cleanup() { for p in $PIDS; do kill "$p" 2>/dev/null || true; done; }
trap cleanup EXIT INT TERM

"$PY" scripts/flightgear_live.py log "$LOG_PORT" "$WORK/fg-rates.csv" &
PIDS="$! $PIDS"
Xvfb ":$DISPLAY_N" -screen 0 640x480x24 -nolisten tcp > "$WORK/xvfb.log" 2>&1 &
PIDS="$! $PIDS"
sleep 2
START=$(date +%s)
DISPLAY=":$DISPLAY_N" FG_HOME="$FG_HOME_DIR" dbus-run-session -- "$FGFS" \
    --data="$WORK/data" --aircraft=c172p --in-air --altitude=3000 --vc=100 --heading=270 \
    --timeofday=noon --geometry=320x240 --disable-sound --disable-ai-traffic \
    --disable-real-weather-fetch --disable-terrasync --disable-random-objects \
    --prop:/sim/rendering/draw-mask/terrain=false --prop:/sim/rendering/draw-mask/models=false \
    --prop:/sim/rendering/draw-mask/aircraft=false --prop:/sim/rendering/draw-mask/clouds=false \
    --prop:/controls/engines/engine/throttle=0.8 \
    --generic="socket,out,100,127.0.0.1,$IN_PORT,udp,hexcue" \
    --generic="socket,out,100,127.0.0.1,$LOG_PORT,udp,hexcue-rates" \
    --generic="socket,in,20,127.0.0.1,$AIL_PORT,udp,hexcue-aileron" \
    > "$WORK/fgfs.log" 2>&1 &
FG=$!
PIDS="$FG $PIDS"
echo "FlightGear starting (display :$DISPLAY_N, log $WORK/fgfs.log)" >&2
# Flying once its own log passes 5 s of simulated time (the first frames come ~20 s after
# launch in software GL, after the navigation-data cache is built).
until [ -s "$WORK/fg-rates.csv" ] && awk -F, 'END { exit !($1 > 5) }' "$WORK/fg-rates.csv"; do
    if ! kill -0 "$FG" 2>/dev/null; then
        echo "FlightGear exited; see $WORK/fgfs.log" >&2
        exit 1
    fi
    if [ $(($(date +%s) - START)) -gt 900 ]; then
        echo "FlightGear did not fly within 900 s; see $WORK/fgfs.log" >&2
        exit 1
    fi
    sleep 1
done
echo "FlightGear flying after $(($(date +%s) - START)) s; hexcue live for $RUN_S s" >&2

"$PY" scripts/flightgear_live.py aileron "$AIL_PORT" "$((RUN_S + 1))" &
AIL=$!
PIDS="$AIL $PIDS"
"$HEXCUE" live --headless --duration "$RUN_S" --input "flightgear://127.0.0.1:$IN_PORT" \
    --output "udp://127.0.0.1:$OUT_PORT" --record "$WORK/fg.mcap" --summary "$WORK/fg.json" \
    2> "$WORK/hexcue.stderr" > "$WORK/hexcue.stdout"
wait "$AIL" || true
kill "$FG" 2>/dev/null || true
wait "$FG" 2>/dev/null || true
"$PY" - "$WORK/fg.json" <<'PYEOF'
import json, sys
l = json.load(open(sys.argv[1]))["live"]
print(f"hexcue: {l['samples_in']} samples in, {l['commands_out']} commands out, "
      f"{l['deadline_misses']} deadline misses, latency p99 {l['latency_ms']['p99']:.2f} ms, "
      f"{l['malformed']} malformed, unit warning: {l.get('unit_warning')}")
PYEOF
grep -E "frame rate|fps" "$WORK/fgfs.log" | tail -1 || true
status=0
"$PY" scripts/flightgear_live.py compare "$WORK/fg.mcap" "$WORK/fg-rates.csv" || status=$?
echo "files: $WORK" >&2
exit $status
