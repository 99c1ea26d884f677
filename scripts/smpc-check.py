#!/usr/bin/env python3
"""Two variants of `scripts/smpc-variants.py` OUTDIR against each other, S-MPC only: mean score,
flights worse by more than 2 % + 0.01, largest limiter share, switches; the flights that moved.

    scripts/smpc-check.py DIR_A VARIANT_A DIR_B VARIANT_B   (e.g. /tmp/before base /tmp/after base)
"""
import json,glob,os,sys
da, a, db, b = sys.argv[1:5]
rows=[];worse=[]
for p in sorted(glob.glob(f'{da}/{a}--*.json')):
    fn=os.path.basename(p)[len(a)+2:-5]
    q=f'{db}/{b}--{fn}.json'
    if not os.path.exists(q): continue
    x=json.load(open(p))['algorithms']['smpc']; y=json.load(open(q))['algorithms']['smpc']
    rows.append((fn,x['score'],y['score'],x['limiter_fraction'],y['limiter_fraction'],x['switches'],y['switches']))
    if y['score']>x['score']*1.02+0.01: worse.append(fn)
n=len(rows)
print(f'{n} flights: mean S-MPC score {a} {sum(r[1] for r in rows)/n:.4f} -> {b} {sum(r[2] for r in rows)/n:.4f}; max limiter {max(r[4] for r in rows)*100:.2f} %; switches {sum(r[5] for r in rows)} -> {sum(r[6] for r in rows)}; worse than 2%+0.01: {worse}')
for r in rows:
    if abs(r[2]-r[1])>0.0005 or r[5]!=r[6]: print(f'  {r[0]:27s} score {r[1]:.3f} -> {r[2]:.3f}  limiter {100*r[3]:.2f} -> {100*r[4]:.2f} %  switches {r[5]} -> {r[6]}')
