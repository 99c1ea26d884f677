#!/usr/bin/env bash
# hexcue live against a real FlightGear (issue #20; not in CI: it needs FlightGear and takes
# minutes). FlightGear 2020.3 from Debian: apt-get install flightgear xvfb xauth mesa-utils dbus
#
#   scripts/flightgear-live.sh [SECONDS]      (from the repository's root; default 40)
#
# Starts FlightGear under Xvfb (a small window, scenery, models, aircraft and clouds not drawn,
# so that software GL reaches 45-85 frames/s) in a C172 in the air with the aileron held at
# +0.5, sending the shipped protocol (integrations/flightgear/hexcue.xml) to hexcue and
# logging the same properties as text (scripts/flightgear-log.xml). Once FlightGear sends,
# runs `hexcue live --headless` for SECONDS, then compares FlightGear's log with hexcue's
# recording (scripts/flightgear-compare.py): exit 0 when hexcue's roll rate is FlightGear's
# within 5 %. Leaves everything in $WORK (printed).
set -euo pipefail
SECS=${1:-40}
HEXCUE=${HEXCUE:-target/release/hexcue}
PORT=${PORT:-5139}
DISP=${DISP:-:57}
WORK=$(mktemp -d /tmp/hexcue-fg.XXXXXX)
echo "work: $WORK"
mkdir -p "$WORK/data/Protocol" "$WORK/home"
cp integrations/flightgear/hexcue.xml "$WORK/data/Protocol/hexcue.xml"
cp scripts/flightgear-log.xml "$WORK/data/Protocol/hexcue-log.xml"
python3 -m venv "$WORK/venv"
"$WORK/venv/bin/pip" install --quiet mcap zstandard

Xvfb "$DISP" -screen 0 640x480x24 >"$WORK/xvfb.log" 2>&1 &
XVFB=$!
FG=
cleanup() {
    [ -n "$FG" ] && kill "$FG" 2>/dev/null || true
    kill "$XVFB" 2>/dev/null || true
}
trap cleanup EXIT
sleep 1
# Without a session bus fgfs aborts at start: dbus-run-session.
DISPLAY="$DISP" FG_HOME="$WORK/home" dbus-run-session -- /usr/games/fgfs \
    --data="$WORK/data" --aircraft=c172p --in-air --altitude=5000 --vc=100 \
    --timeofday=noon --geometry=320x240 --disable-sound --disable-ai-traffic \
    --disable-real-weather-fetch \
    --prop:/sim/rendering/draw-mask/terrain=false --prop:/sim/rendering/draw-mask/models=false \
    --prop:/sim/rendering/draw-mask/aircraft=false --prop:/sim/rendering/draw-mask/clouds=false \
    --prop:/controls/flight/aileron=0.5 \
    --generic=socket,out,100,127.0.0.1,"$PORT",udp,hexcue \
    --generic=file,out,100,"$WORK/fg-log.csv",hexcue-log \
    >"$WORK/fg.log" 2>&1 &
FG=$!
echo "waiting for FlightGear's first frame (20 s unloaded, minutes on a busy machine)"
until [ -s "$WORK/fg-log.csv" ]; do
    kill -0 "$FG" 2>/dev/null || { echo "fgfs ended: $WORK/fg.log"; exit 1; }
    sleep 1
done
FROM=$(wc -l <"$WORK/fg-log.csv")
"$HEXCUE" live --headless --duration "$SECS" --input "flightgear://127.0.0.1:$PORT" \
    --algorithms cwf --drive cwf --record "$WORK/fg.mcap" --summary "$WORK/fg.json" \
    >"$WORK/table.txt" 2>"$WORK/live.log" || true
TO=$(wc -l <"$WORK/fg-log.csv")
# FlightGear's rows while hexcue ran (both outputs are written in the same frames).
sed -n "$((FROM + 1)),${TO}p" "$WORK/fg-log.csv" >"$WORK/fg-window.csv"
cat "$WORK/live.log"
grep "^live:" "$WORK/table.txt" || true
awk -F, -v n="$((TO - FROM))" -v s="$SECS" 'END { printf "FlightGear frames while hexcue ran: %d (%.1f a second)\n", n, n / s }' "$WORK/fg-window.csv"
"$WORK/venv/bin/python" scripts/flightgear-compare.py "$WORK/fg-window.csv" "$WORK/fg.mcap"
