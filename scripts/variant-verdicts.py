#!/usr/bin/env python3
"""Verdicts of variants against the CWF from `play --headless` summaries (docs/mpc.md, "After
the chain's cure: the variants again"): per flight and variant, score, limiter share, the
channels where the MPC loses to the CWF by `hexcue compare`'s rule (src/compare/verdict.rs,
`judge`: false cues beyond the CWF's + 1 % of the flight, else more charged jolts, else felt
error beyond the CWF's × 1.05 + 0.01; without `--bound`'s forced channels), and the share of
the CWF's cueable error removed where BOUNDS (environment) holds `bound-FLIGHT.json`. Then per
variant: mean score, largest limiter share, flights scoring worse than the first variant's
by more than 2 % + 0.01, and channels felt worse that were not with the first variant.
Summaries are named as scripts/smpc-variants.py and mpc-variants.py write them
(DIR/VARIANT--FLIGHT.json); the CWF's are read from CWFDIR/CWFVAR--*.json.

usage: scripts/variant-verdicts.py CWFDIR:CWFVAR LABEL=DIR:VARIANT:ALG...
e.g.   BOUNDS=/work/bounds scripts/variant-verdicts.py /tmp/sv:base S=/tmp/sv:base:smpc \
           S07=/tmp/sv:ct07:smpc M=/tmp/sv:base:mpc"""
import json, os, sys, glob
chs = ['fx', 'fy', 'fz', 'wx', 'wy', 'wz']
bounds = os.environ.get('BOUNDS', '')
cwfdir, cwfvar = sys.argv[1].split(':')
specs = []
for a in sys.argv[2:]:
    label, rest = a.split('=', 1)
    d, v, alg = rest.split(':')
    specs.append((label, d, v, alg))
flights = sorted(os.path.basename(p)[len(cwfvar) + 2:-5] for p in glob.glob(f'{cwfdir}/{cwfvar}--*.json'))
def load(d, v, f):
    p = f'{d}/{v}--{f}.json'
    return json.load(open(p)) if os.path.exists(p) else None
def lower(f):
    p = f'{bounds}/bound-{f}.json'
    if not os.path.exists(p): return None
    b = json.load(open(p)); low = dict(b['details']['joint_error']); low.update(b['bound']['lower']['channel']); return low
def judge(a, b, margin):
    if a['false_cue_s'] > b['false_cue_s'] + margin: return 'false'
    if b['false_cue_s'] > a['false_cue_s'] + margin: return None
    ja, jb = a['jolts']['charged'], b['jolts']['charged']
    if ja > jb: return 'jolt'
    if jb > ja: return None
    if a['felt'] > b['felt'] * 1.05 + 0.01: return 'felt'
    return None
res = {}
print(f"{'flight':28s} " + ' '.join(f'{l:>22s}' for l, *_ in specs))
print(f"{'':28s} " + ' '.join(f"{'score lim% worse':>22s}" for _ in specs))
for f in flights:
    cw = load(cwfdir, cwfvar, f)
    c = cw['algorithms']['cwf']; margin = 0.01 * cw['steps'] / cw['rate_hz']
    low = lower(f)
    cue = lambda s: sum(max(s['score_terms']['error'][ch] - low[ch], 0) for ch in chs)
    cells = []
    for label, d, v, alg in specs:
        s = load(d, v, f)
        if s is None: cells.append(f"{'-':>22s}"); continue
        s = s['algorithms'][alg]
        worse = []
        for ch in chs:
            am = dict(s['metrics'][ch]); am['felt'] = s['score_terms']['felt'][ch]
            bm = dict(c['metrics'][ch]); bm['felt'] = c['score_terms']['felt'][ch]
            w = judge(am, bm, margin)
            if w: worse.append(f'{ch}:{w}')
        share = 100 * (1 - cue(s) / cue(c)) if low else None
        res.setdefault(label, []).append((f, s['score'], s['limiter_fraction'], worse, share, s['metrics']['fx']['rae'], s['metrics']['fy']['rae'], s['score_terms']['error']['fz']))
        cells.append(f"{s['score']:7.3f} {100*s['limiter_fraction']:5.2f} {len(worse):2d}" + (f" {share:4.0f}%" if low else '      '))
    print(f'{f:28s} ' + ' '.join(f'{x:>22s}' for x in cells))
ref = res[specs[0][0]]
print('\nlabel         mean score  max lim%  worse-channels  flights >2%+0.01 vs ref  new worse channels vs ref  shares')
for label, *_ in specs:
    r = res.get(label, [])
    if not r: continue
    rd = {x[0]: x for x in ref}
    up = [f"{x[0]} {rd[x[0]][1]:.2f}->{x[1]:.2f}" for x in r if x[0] in rd and x[1] > rd[x[0]][1] * 1.02 + 0.01]
    # A channel lost for another reason (a jolt before, felt error now) is not new.
    chans = lambda w: {c.split(':')[0] for c in w}
    new = [f"{x[0]} {','.join(c for c in x[3] if c.split(':')[0] in chans(x[3]) - chans(rd[x[0]][3]))}"
           for x in r if x[0] in rd and chans(x[3]) - chans(rd[x[0]][3])]
    gone = [f"{x[0]} {','.join(sorted(chans(rd[x[0]][3]) - chans(x[3])))}"
            for x in r if x[0] in rd and chans(rd[x[0]][3]) - chans(x[3])]
    mx = max(r, key=lambda x: x[2])
    print(f"{label:12s} {sum(x[1] for x in r)/len(r):8.3f} (n={len(r)})  {100*mx[2]:5.2f} ({mx[0]})  {sum(len(x[3]) for x in r):3d}  {len(up)}: {'; '.join(up)}")
    print(f"{'':12s} new worse: {'; '.join(new) or 'none'}")
    print(f"{'':12s} no longer worse: {'; '.join(gone) or 'none'}")
    print(f"{'':12s} cueable shares: " + ' '.join(f"{x[0][:12]} {x[4]:.1f}" for x in r if x[4] is not None))
    print(f"{'':12s} all worse: " + '; '.join(f"{x[0]} {','.join(x[3])}" for x in r if x[3]))
