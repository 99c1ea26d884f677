#!/usr/bin/env python3
"""The S-MPC's supervisor, before and after, from two folders of `hexcue play --headless
--summary` files (e.g. kept by `scripts/cueing-bars.py --keep DIR`): per flight, the switch
count, the threshold-aware error per channel (S-MPC / MPC / CWF), the limiter fraction, leg
violations and the S-MPC's step time median / p99.

    scripts/smpc-switches.py BEFORE_DIR AFTER_DIR
"""
import glob
import json
import os
import sys

CH = ["fx", "fy", "fz", "wx", "wy", "wz"]


def load(folder):
    out = {}
    for path in sorted(glob.glob(os.path.join(folder, "*.json"))):
        with open(path) as f:
            d = json.load(f)
        if "algorithms" in d:
            out[os.path.splitext(os.path.basename(path))[0]] = d["algorithms"]
    return out


def main():
    before, after = load(sys.argv[1]), load(sys.argv[2])
    print("| flight | switches before → after | S-MPC error before → after where it moved "
          "(MPC / CWF) | limiter % | leg violations | S-MPC step µs median / p99 before → after |")
    print("|---|---:|---|---|---|---|")
    tot = [0, 0]
    worse = []
    for name in sorted(after):
        b, a = before[name], after[name]
        sb, sa = b["smpc"], a["smpc"]
        tot[0] += sb["switches"]
        tot[1] += sa["switches"]
        cells = []
        for c in CH:
            eb, ea = sb["score_terms"]["error"][c], sa["score_terms"]["error"][c]
            em, ec = a["mpc"]["score_terms"]["error"][c], a["cwf"]["score_terms"]["error"][c]
            if abs(ea - eb) >= 0.0005:
                cells.append(f"{c} {eb:.3f} → {ea:.3f} ({em:.3f} / {ec:.3f})")
            if ea > eb + 0.0005:
                worse.append(f"{name} {c} {eb:.3f} → {ea:.3f}")
        tb, ta = sb["step_time_us"], sa["step_time_us"]
        print(f"| {name} | {sb['switches']} → {sa['switches']} | {'; '.join(cells) or '–'} | "
              f"{100 * sb['limiter_fraction']:.2f} → {100 * sa['limiter_fraction']:.2f} | "
              f"{sb['leg_violations']} → {sa['leg_violations']} | "
              f"{tb['median']:.0f} / {tb['p99']:.0f} → {ta['median']:.0f} / {ta['p99']:.0f} |")
    print(f"\nswitches over {len(after)} flights: {tot[0]} → {tot[1]}")
    print("S-MPC channel errors that rose by 0.0005 or more: " + ("; ".join(worse) or "none"))


if __name__ == "__main__":
    main()
