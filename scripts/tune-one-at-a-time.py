#!/usr/bin/env python3
"""Which of a tune's keys makes a flight worse: each key that TUNED changes, moved alone from
BASE's value to TUNED's (every other key at the base), and TUNED with that key alone put back
to the base's value, on one or more flights, through `hexcue eval` (the score `tune` and `play
--headless` give, the solvers' wall-clock limit lifted). Prints, per flight, a Markdown table
of the score and of each channel's threshold-aware error term (docs/tuning.md, "The score").

    scripts/tune-one-at-a-time.py BASE.toml TUNED.toml TRACE.csv... [--algorithm mpc]
        [--hexcue target/release/hexcue]

docs/tuning.md ("Why the crosswind landing got worse") shows its output for the 737 crosswind
landing.
"""
import argparse
import json
import os
import subprocess
import tempfile

CHANNELS = ("fx", "fy", "fz", "wx", "wy", "wz")


def space(hexcue, algorithm, profile, folder, name):
    out = os.path.join(folder, name + "-space.json")
    subprocess.run([hexcue, "eval", "--space", "--algorithm", algorithm, "--profile", profile,
                    "--out", out, "--force"], check=True)
    with open(out) as f:
        return {k["name"]: k["base"] for k in json.load(f)["keys"]}


def evaluate(hexcue, algorithm, profile, sets, traces, out):
    cmd = [hexcue, "eval", "--algorithm", algorithm, "--profile", profile,
           "--traces", ",".join(traces), "--out", out, "--force"]
    for k, v in sets:
        cmd += ["--set", f"{k}={v!r}"]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    with open(out) as f:
        return {fl["name"]: fl for fl in json.load(f)["flights"]}


def main():
    p = argparse.ArgumentParser()
    p.add_argument("base")
    p.add_argument("tuned")
    p.add_argument("traces", nargs="+")
    p.add_argument("--algorithm", default="mpc")
    p.add_argument("--hexcue", default="target/release/hexcue")
    a = p.parse_args()
    folder = tempfile.mkdtemp(prefix="one-at-a-time-")
    base = space(a.hexcue, a.algorithm, a.base, folder, "base")
    tuned = space(a.hexcue, a.algorithm, a.tuned, folder, "tuned")
    moved = [k for k in base if tuned[k] != base[k]]
    all_tuned = [(k, tuned[k]) for k in moved]
    rows = [("base", evaluate(a.hexcue, a.algorithm, a.base, [], a.traces,
                              os.path.join(folder, "base.json"))),
            ("tuned (every key)", evaluate(a.hexcue, a.algorithm, a.base, all_tuned, a.traces,
                                           os.path.join(folder, "tuned.json")))]
    for i, k in enumerate(moved):
        rows.append((f"only `{k}` {base[k]:g} → {tuned[k]:g}",
                     evaluate(a.hexcue, a.algorithm, a.base, [(k, tuned[k])], a.traces,
                              os.path.join(folder, f"only-{i}.json"))))
        rows.append((f"tuned, `{k}` back to {base[k]:g}",
                     evaluate(a.hexcue, a.algorithm, a.base,
                              [(x, v) for x, v in all_tuned if x != k], a.traces,
                              os.path.join(folder, f"but-{i}.json"))))
    for t in a.traces:
        name = os.path.splitext(os.path.basename(t))[0]
        print(f"\n### {name} ({a.algorithm})\n")
        print("| profile | score | " + " | ".join(f"error {c}" for c in CHANNELS)
              + " | false cue | limiter % |")
        print("|---|---:|" + "---:|" * len(CHANNELS) + "---:|---:|")
        for label, r in rows:
            fl = r[name]
            terms = fl["score_terms"]
            print(f"| {label} | {fl['score']:.4f} | "
                  + " | ".join(f"{terms['error'][c]:.4f}" for c in CHANNELS)
                  + f" | {terms['false_cue']:.4f} | {100 * fl['limiter_fraction']:.2f} |")


if __name__ == "__main__":
    main()
