#!/usr/bin/env python3
"""Issue #23's acceptance check of a tuned profile against its base, on flights the tune never
fitted on: runs `hexcue play --headless` with each profile on each flight (the solvers'
wall-clock limit lifted, as `hexcue tune` and `hexcue compare` do, so that the result does not
depend on the machine's load) and checks, per algorithm:

- on every flight, the tuned score at most the base's × 1.02;
- on every flight, the limiter acting on at most the base's share of the steps + 1 % of them;
- no leg outside its stroke;
- for the CWF, the mean score over the flights at least 5 % below the base's.

    scripts/tune-acceptance.py BASE.toml TUNED.toml TRACE.csv...

Prints one Markdown table per algorithm and a verdict line for each; exits 1 when a check
fails, so that `scripts/tune-comparison.sh` can say so.
"""
import argparse
import concurrent.futures
import os
import sys
import tempfile

from hexcue_play import play_summary, unlimited_profile

ALGORITHMS = ("cwf", "mpc", "smpc")
SCORE_TOLERANCE = 0.02
LIMITER_TOLERANCE = 0.01
CWF_MEAN_GAIN = 0.05


def main():
    p = argparse.ArgumentParser()
    p.add_argument("base")
    p.add_argument("tuned")
    p.add_argument("traces", nargs="+")
    p.add_argument("--hexcue", default="target/release/hexcue")
    p.add_argument("--jobs", type=int, default=2)
    a = p.parse_args()
    folder = tempfile.mkdtemp(prefix="tune-acceptance-")
    profiles = {k: unlimited_profile(v, folder, k)
                for k, v in (("base", a.base), ("tuned", a.tuned))}
    jobs = [(k, t) for t in a.traces for k in profiles]
    with concurrent.futures.ThreadPoolExecutor(a.jobs) as ex:
        done = ex.map(lambda j: play_summary(a.hexcue, profiles[j[0]], j[1], os.path.join(
            folder, f"{j[0]}-{os.path.splitext(os.path.basename(j[1]))[0]}.json"))["algorithms"],
            jobs)
        results = {(k, t): r for (k, t), r in zip(jobs, done)}

    failed = False
    for alg in ALGORITHMS:
        print(f"\n### {alg}\n")
        print("| flight | base score | tuned score | tuned / base | limiter % base → tuned "
              "| leg violations | |")
        print("|---|---:|---:|---:|---|---:|---|")
        problems, base_sum, tuned_sum = [], 0.0, 0.0
        for t in a.traces:
            name = os.path.splitext(os.path.basename(t))[0]
            b, u = results[("base", t)][alg], results[("tuned", t)][alg]
            base_sum += b["score"]
            tuned_sum += u["score"]
            bad = []
            if u["score"] > b["score"] * (1 + SCORE_TOLERANCE) + 1e-9:
                bad.append("score")
            if u["limiter_fraction"] > b["limiter_fraction"] + LIMITER_TOLERANCE + 1e-12:
                bad.append("limiter")
            if u["leg_violations"] > 0:
                bad.append("legs")
            problems += [f"{name}: {x}" for x in bad]
            print(f"| {name} | {b['score']:.4f} | {u['score']:.4f} | "
                  f"{u['score'] / b['score']:.3f} | {100 * b['limiter_fraction']:.2f} → "
                  f"{100 * u['limiter_fraction']:.2f} | {u['leg_violations']} | "
                  f"{'FAILS: ' + ', '.join(bad) if bad else 'ok'} |")
        n = len(a.traces)
        mean_b, mean_u = base_sum / n, tuned_sum / n
        print(f"| **mean** | {mean_b:.4f} | {mean_u:.4f} | {mean_u / mean_b:.3f} | | | |")
        if alg == "cwf" and mean_u > mean_b * (1 - CWF_MEAN_GAIN):
            problems.append(f"mean {mean_u:.4f} is not 5 % below the base's {mean_b:.4f}")
        verdict = "accepted" if not problems else "NOT accepted: " + "; ".join(problems)
        print(f"\n{alg}: {verdict}")
        failed |= bool(problems)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
