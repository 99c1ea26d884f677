#!/usr/bin/env python3
"""Compares what a real FlightGear reported with what hexcue recorded from it.

Usage: flightgear-compare.py FG_LOG.csv RECORDING.mcap

FG_LOG.csv is FlightGear's own log of the same properties (scripts/flightgear-log.xml, an
ASCII generic-protocol output written in the same frames as the datagrams sent to hexcue):
time, freeze, x/y/z-accel-fps_sec, p/q/r-body, roll/pitch/heading-deg. RECORDING.mcap is
`hexcue live --record`; its /aircraft topic is the held sample each step, in SI.

Prints, per quantity, FlightGear's peak (converted to SI) and hexcue's, and their ratio.
Needs the `mcap` and `zstandard` Python packages (scripts/flightgear-live.sh installs them
into a venv).
"""
import csv
import json
import math
import sys

from mcap.reader import make_reader

FT = 0.3048
DEG = math.pi / 180.0


def flightgear(path):
    rows = []
    with open(path) as f:
        for row in csv.reader(f):
            if len(row) != 11:
                continue
            v = [float(x) for x in row]
            if v[1] != 0:  # frozen
                continue
            rows.append(
                {
                    "fx": v[2] * FT, "fy": v[3] * FT, "fz": v[4] * FT,
                    "p": v[5], "q": v[6], "r": v[7],
                    "phi": v[8] * DEG, "theta": v[9] * DEG,
                }
            )
    return rows


def hexcue(path):
    rows = []
    with open(path, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(topics=["/aircraft"]):
            m = json.loads(message.data)
            f_, w, a = m["specific_force"], m["angular_velocity"], m["attitude"]
            rows.append(
                {
                    "fx": f_[0], "fy": f_[1], "fz": f_[2],
                    "p": w[0], "q": w[1], "r": w[2],
                    "phi": a[0], "theta": a[1],
                }
            )
    # Before the first sample hexcue holds the aircraft at rest: leave those steps out.
    first = next(
        (i for i, r in enumerate(rows) if any(r[k] != 0 for k in ("p", "q", "r", "phi"))),
        len(rows),
    )
    return rows[first:]


def main():
    fg, hx = flightgear(sys.argv[1]), hexcue(sys.argv[2])
    print(f"FlightGear rows (not frozen): {len(fg)}; hexcue steps with input: {len(hx)}")
    if not fg or not hx:
        sys.exit("nothing to compare")
    print(f"{'':6} {'FlightGear peak':>16} {'hexcue peak':>12} {'ratio':>7}  (SI: m/s², rad/s, rad)")
    worst = 0.0
    for key in ("fx", "fy", "fz", "p", "q", "r", "phi", "theta"):
        a = max((r[key] for r in fg), key=abs)
        b = max((r[key] for r in hx), key=abs)
        ratio = b / a if a != 0 else float("nan")
        if key == "p":
            worst = abs(ratio - 1.0)
        print(f"{key:6} {a:16.5f} {b:12.5f} {ratio:7.3f}")
    print(f"roll rate p: hexcue / FlightGear = 1 {'+' if worst >= 0 else ''}{worst:.3f}")
    sys.exit(0 if worst <= 0.05 else 1)


if __name__ == "__main__":
    main()
