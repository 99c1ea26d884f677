#!/usr/bin/env python3
"""The best heave cue any algorithm could give on a trace, within the profile's heave stroke:
a lower bound on the threshold-aware heave error (the summary's `score_terms.error.fz`).

Issue #21 asks the MPCs for a turbulence heave error at most 0.7 × the CWF's. This script
answers whether any motion of the platform can reach it. It lets the platform's heave
acceleration a_z(t) be anything within the profile's heave excursion, velocity and
acceleration limits, *knowing the whole flight in advance* (no causal algorithm can), and
minimises the same error the score counts: the mean over the flight of the soft dead zone
0.1·min(u, 1) + max(u − 1, 0), u = |f̂z_ref − f̂z_platform| / threshold, with f̂z the otolith
model's output (docs/design.md §4) for Δf_z. That error is piecewise linear and convex in a_z, so the
optimum is a linear programme (scipy's HiGHS), solved on a 10 Hz grid (the error of "no cue" on
that grid equals the 100 Hz one to three decimals on the shipped traces).

It is a bound in the algorithms' favour: the whole stroke is given to heave (no leg is shared
with surge, sway or tilt, no limiter margin), tilt's own loss of vertical gravity is left out,
and the future is known. Whatever it prints, no algorithm on this profile can do better.

    python3 -m venv target/py && target/py/bin/pip install numpy scipy
    target/py/bin/python scripts/heave-bound.py recordings/traces/turbulence-cruise.csv

Prints the error without a heave cue and the bound, and with `--cwf-error E` the ratio to a
CWF error taken from a summary.
"""
import argparse
import sys
import tomllib

import numpy as np
from scipy import optimize, signal, sparse

G = 9.80665


def main():
    p = argparse.ArgumentParser()
    p.add_argument("trace")
    p.add_argument("--profile", default="profiles/full-flight.toml")
    p.add_argument("--rate-hz", type=float, default=10.0, help="decision grid (Hz)")
    p.add_argument("--cwf-error", type=float, help="the CWF's fz error, to print the ratio")
    a = p.parse_args()
    with open(a.profile, "rb") as f:
        prof = tomllib.load(f)
    ves, heave = prof["vestibular"], prof["limits"]["heave"]
    below = prof.get("score", {}).get("below_threshold_weight", 0.1)
    tau = ves["otolith_threshold_mps2"][2]
    k, ga, gl, gs = (ves[x] for x in ("otolith_gain", "otolith_lead_s", "otolith_long_s",
                                      "otolith_short_s"))

    d = np.genfromtxt(a.trace, delimiter=",", names=True)
    t = d["t"]
    step = max(1, int(round(1.0 / (a.rate_hz * (t[1] - t[0])))))
    f = (d["fz"] + G)[::step]  # Δf_z: z down, so level flight is fz = −g
    dt = (t[1] - t[0]) * step
    n = len(f)

    num, den, _ = signal.cont2discrete(([k * ga, k], np.polymul([gl, 1], [gs, 1])), dt, "zoh")
    imp = signal.lfilter(num.flatten(), den, np.r_[1.0, np.zeros(n - 1)])
    perceive = np.zeros((n, n))
    for j in range(n):
        perceive[j:, j] = imp[: n - j]
    ref = perceive @ f

    def error(perceived):
        u = np.abs(ref - perceived) / tau
        return float(np.mean(below * np.minimum(u, 1) + np.maximum(u - 1, 0)))

    # Variables: a_z (n), then e (n) ≥ the soft dead zone of each step's error. The dead zone
    # is max(below·u, u − (1 − below)), so two pairs of rows per step bound e from below.
    integ = np.tril(np.ones((n, n)), -1) * dt
    vel, pos = integ, integ @ integ
    eye, zero = np.eye(n), np.zeros((n, n))
    rows, rhs = [], []
    for sign in (1.0, -1.0):
        rows.append(np.hstack([-sign * below / tau * perceive, -eye]))
        rhs.append(-sign * below / tau * ref)
        rows.append(np.hstack([-sign / tau * perceive, -eye]))
        # e ≥ ±u − (1 − below): the constant sits on the right with a plus sign.
        rhs.append(-sign / tau * ref + (1 - below))
    for m, lim in ((pos, heave["excursion_m"]), (vel, heave["velocity_mps"])):
        rows += [np.hstack([m, zero]), np.hstack([-m, zero])]
        rhs += [np.full(n, lim), np.full(n, lim)]
    acc = heave["acceleration_mps2"]
    res = optimize.linprog(
        np.r_[np.zeros(n), np.ones(n)],
        A_ub=sparse.csr_matrix(np.vstack(rows)),
        b_ub=np.concatenate(rhs),
        bounds=[(-acc, acc)] * n + [(0, None)] * n,
        method="highs",
    )
    if res.status != 0:
        sys.exit(f"{a.trace}: the linear programme did not solve: {res.message}")
    bound = error(perceive @ res.x[:n])
    print(f"{a.trace}: heave error without a heave cue {error(np.zeros(n)):.3f}; "
          f"best possible within ±{heave['excursion_m']} m (whole flight known) {bound:.3f}")
    if a.cwf_error:
        print(f"  against the CWF's {a.cwf_error:.3f}: {bound / a.cwf_error:.2f} × "
              f"(the bar asks ≤ 0.70 ×, i.e. ≤ {0.7 * a.cwf_error:.3f})")


if __name__ == "__main__":
    main()
