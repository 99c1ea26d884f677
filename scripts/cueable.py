#!/usr/bin/env python3
"""Cueable error (docs/bound.md): each algorithm's threshold-aware error above the bound's
per-channel figure (the channel's own optimum where `hexcue bound --channels` computed it,
else its error at the joint optimum), summed over the channels, and the share of the CWF's
that each removes. Reads a `hexcue bound --json` file and `play --headless --summary` files
of the same flight (a `:suffix` after a summary names its algorithms apart, e.g.
`prev.json:-preview`); computing the bound once serves every variant.

usage: scripts/cueable.py BOUND.json SUMMARY.json[:suffix]..."""
import json, sys
b = json.load(open(sys.argv[1]))
lower = dict(b['details']['joint_error']); lower.update(b['bound']['lower']['channel'])
chs = ['fx','fy','fz','wx','wy','wz']
res = {}
for arg in sys.argv[2:]:
    path, _, suf = arg.partition(':')
    d = json.load(open(path))
    for a, s in d['algorithms'].items():
        e = s['score_terms']['error']
        res[a + suf] = (sum(max(e[c] - lower[c], 0) for c in chs), {c: max(e[c] - lower[c], 0) for c in chs}, e)
cwf = res['cwf'][0]
print(f"{b['trace']}: lower per channel " + ' '.join(f"{c} {lower[c]:.3f}" for c in chs))
for k, (c, per, e) in res.items():
    print(f"  {k:14s} cueable {c:.3f}  removes {100*(1-c/cwf):5.1f} % of the CWF's  (" + ' '.join(f"{ch} {per[ch]:.3f}" for ch in chs) + f")  fz error {e['fz']:.3f}")
