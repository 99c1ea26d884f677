#!/usr/bin/env python3
"""The forecast (`[mpc] forecast_s`) against the causal `decay` reference, per flight and
algorithm, from the summaries `scripts/mpc-variants.py` wrote (docs/mpc.md, "Forecast",
issue #35): score, felt error per channel, false-cue time per channel, charged jolts,
limiter share, and every place where the forecast is worse than a tolerance: felt error
more than 5 % and 0.01 above, false cues 0.1 s longer on a channel, charged jolts 2 more on
the flight, limiter share 0.1 point higher.

usage: scripts/forecast-compare.py DIR BASE VARIANT [ALGS]
e.g.   scripts/forecast-compare.py target/fc/lib base fc smpc,mpc"""
import glob, json, os, sys
d, base, var = sys.argv[1:4]
algs = (sys.argv[4] if len(sys.argv) > 4 else 'smpc,mpc').split(',')
chs = ['fx', 'fy', 'fz', 'wx', 'wy', 'wz']
flights = sorted(os.path.basename(p)[len(base) + 2:-5] for p in glob.glob(f'{d}/{base}--*.json'))
def load(v, f):
    return json.load(open(f'{d}/{v}--{f}.json'))['algorithms']
def row(a):
    m = a['metrics']
    return dict(score=a['score'], felt=[a['score_terms']['felt'][c] for c in chs],
                false=[m[c]['false_cue_s'] for c in chs],
                jolts=sum(m[c]['jolts']['charged'] for c in chs),
                limiter=100 * a['limiter_fraction'])
worse, better, sums = [], {}, {}
print(f"{'flight':28s} alg   score {base}→{var}   felt {'/'.join(chs)} ({base}→{var})   false s   jolts   limiter %")
for f in flights:
    b_all, v_all = load(base, f), load(var, f)
    for al in algs:
        b, v = row(b_all[al]), row(v_all[al])
        s = sums.setdefault(al, [0, 0, 0, 0, 0])
        s[0] += b['score']; s[1] += v['score']; s[2] += b['jolts']; s[3] += v['jolts']; s[4] += 1
        better.setdefault(al, [0, 0])
        better[al][0 if v['score'] < b['score'] else 1] += 1
        felt = ' '.join(f"{x:.3f}→{y:.3f}" for x, y in zip(b['felt'], v['felt']) if x > 0.005 or y > 0.005)
        fls = sum(b['false']), sum(v['false'])
        print(f"{f:28s} {al:5s} {b['score']:6.3f}→{v['score']:6.3f}  {felt}  {fls[0]:.1f}→{fls[1]:.1f}  {b['jolts']}→{v['jolts']}  {b['limiter']:.2f}→{v['limiter']:.2f}")
        for c, x, y in zip(chs, b['felt'], v['felt']):
            if y > 1.05 * x and y - x > 0.01:
                worse.append(f"{f} {al} felt {c} {x:.3f}→{y:.3f}")
        for c, x, y in zip(chs, b['false'], v['false']):
            if y - x > 0.1 + 1e-9:
                worse.append(f"{f} {al} false cues {c} {x:.2f}→{y:.2f} s")
        if v['jolts'] - b['jolts'] >= 2:
            worse.append(f"{f} {al} charged jolts {b['jolts']}→{v['jolts']}")
        if v['limiter'] - b['limiter'] > 0.1:
            worse.append(f"{f} {al} limiter {b['limiter']:.2f}→{v['limiter']:.2f} %")
print()
for al, s in sums.items():
    print(f"{al}: mean score {s[0]/s[4]:.3f} → {s[1]/s[4]:.3f}; charged jolts {s[2]} → {s[3]}; "
          f"score lower on {better[al][0]} of {s[4]} flights")
print(f"\nworse than the tolerance ({len(worse)}):")
for w in worse:
    print('  ' + w)
