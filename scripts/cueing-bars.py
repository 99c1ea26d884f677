#!/usr/bin/env python3
"""Issue #21's bars, measured: runs `hexcue play --headless` on each trace with a profile
(the solvers' wall-clock limit lifted, as `hexcue compare` does) and prints, per trace, the
threshold-aware error of each algorithm on the six channels and every bar that fails.

    scripts/cueing-bars.py [--profile P.toml] [--hexcue target/release/hexcue] TRACE.csv...

Bars (docs/mpc.md, "Never worse than the CWF"): per MPC and channel, error ≤ CWF × 1.05 +
0.005 and false-cue time ≤ CWF + 1 % of the flight; roll and pitch PC ≥ 0; S-MPC ≤ MPC < CWF
on surge and sway RAE; the limiter below 1 % of the steps; on a trace whose name contains
"turbulence", heave error ≤ 0.7 × the CWF's.
"""
import argparse
import concurrent.futures
import os
import tempfile

from hexcue_play import play_summary, unlimited_profile

CH = ["fx", "fy", "fz", "wx", "wy", "wz"]


def run(hexcue, profile, trace, outdir):
    name = os.path.splitext(os.path.basename(trace))[0]
    return name, play_summary(hexcue, profile, trace, os.path.join(outdir, name + ".json"))


def bars(name, d):
    a = d["algorithms"]
    flight = d["steps"] / d["rate_hz"]
    fails = []
    cwf = a["cwf"]
    for k in ("smpc", "mpc"):
        if k not in a:
            continue
        m = a[k]
        for c in CH:
            e, ec = m["score_terms"]["error"][c], cwf["score_terms"]["error"][c]
            if e > ec * 1.05 + 0.005:
                fails.append(f"{k} {c} error {e:.3f} > {ec:.3f}")
            fc, fcc = m["metrics"][c]["false_cue_s"], cwf["metrics"][c]["false_cue_s"]
            if fc > fcc + 0.01 * flight + 1e-9:
                fails.append(f"{k} {c} false {fc:.2f} s > {fcc:.2f} s")
        for c in ("wx", "wy"):
            if m["metrics"][c]["pc"] < 0:
                fails.append(f"{k} {c} PC {m['metrics'][c]['pc']:.2f}")
        if m["limiter_fraction"] >= 0.01:
            fails.append(f"{k} limiter {100 * m['limiter_fraction']:.1f} %")
        if "turbulence" in name:
            e, ec = m["score_terms"]["error"]["fz"], cwf["score_terms"]["error"]["fz"]
            if e > 0.7 * ec:
                fails.append(f"{k} fz error {e:.3f} > 0.7 × {ec:.3f}")
    if "smpc" in a and "mpc" in a:
        for c in ("fx", "fy"):
            s, m, w = (a[k]["metrics"][c]["rae"] for k in ("smpc", "mpc", "cwf"))
            if not (s <= m * 1.005 and m < w):
                fails.append(f"order {c} RAE {s:.3f} / {m:.3f} / {w:.3f}")
    return fails


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--profile", default="profiles/full-flight.toml")
    p.add_argument("--hexcue", default="target/release/hexcue")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--keep", help="folder to keep the summaries in")
    p.add_argument("traces", nargs="+")
    args = p.parse_args()
    outdir = args.keep or tempfile.mkdtemp(prefix="cueing-bars-")
    os.makedirs(outdir, exist_ok=True)
    profile = unlimited_profile(args.profile, outdir, "profile")
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as ex:
        results = list(ex.map(lambda t: run(args.hexcue, profile, t, outdir), args.traces))
    total = 0
    print("| trace | " + " | ".join(CH) + " | false s (S/M/C, worst channel) | fails |")
    print("|---|" + "---|" * len(CH) + "---|---|")
    for name, d in results:
        a = d["algorithms"]
        cells = []
        for c in CH:
            ec = a["cwf"]["score_terms"]["error"][c]
            parts = []
            for k in ("smpc", "mpc"):
                if k in a:
                    e = a[k]["score_terms"]["error"][c]
                    star = "*" if e > ec * 1.05 + 0.005 else ""
                    parts.append(f"{star}{e:.3f}")
            parts.append(f"{ec:.3f}")
            cells.append(" / ".join(parts))
        fc = " / ".join(
            f"{max(a[k]['metrics'][c]['false_cue_s'] for c in CH):.1f}"
            for k in ("smpc", "mpc", "cwf") if k in a)
        f = bars(name, d)
        total += len(f)
        print(f"| {name} | " + " | ".join(cells) + f" | {fc} | {'; '.join(f) or 'none'} |")
    print(f"\n{total} failed bars over {len(results)} traces (summaries in {outdir})")


if __name__ == "__main__":
    main()
