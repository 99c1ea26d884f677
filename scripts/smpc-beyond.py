#!/usr/bin/env python3
"""The bar S-MPC <= MPC < CWF on surge and sway RAE on the flights beyond the platform (#35), from a
`scripts/smpc-variants.py` OUTDIR: per flight RAE and felt error (`score_terms.felt`) of the three,
and the aircraft's mean |perceived| sway and surge (m/s^2, = aad / rae), so that an RAE over almost
no signal is told apart from a felt difference. VARIANT (default base) gives the S-MPC's column;
the MPC's and CWF's come from base.

    scripts/smpc-beyond.py OUTDIR [VARIANT]
"""
import json, sys
d = sys.argv[1]; pre = sys.argv[2] if len(sys.argv) > 2 else "base"
fl=['f16-afterburner-takeoff','f16-pitch-doublet','f16-roll-doublet','f16-windup-turn','737-upset-nose-high','737-upset-nose-low','737-rejected-takeoff','737-dutch-roll','737-windshear-approach','c172p-spiral-dive','horizontal-stall']
print('| flight | surge RAE S-MPC / MPC / CWF | surge felt S-MPC / MPC / CWF | sway RAE S-MPC / MPC / CWF | sway felt S-MPC / MPC / CWF | mean |x| sway / surge (m/s²) | bar surge, sway | switches |')
print('|---|---|---|---|---|---|---|---|')
for f in fl:
    a=json.load(open(f'{d}/{pre}--{f}.json'))['algorithms']
    b=json.load(open(f'{d}/base--{f}.json'))['algorithms']
    s=a['smpc'];m=b['mpc'];c=b['cwf']
    row=[f]
    bars=[]
    for ch in ['fx','fy']:
        r=[x['metrics'][ch]['rae'] for x in (s,m,c)]
        fe=[x['score_terms']['felt'][ch] for x in (s,m,c)]
        row.append(' / '.join(f'{v:.3f}' for v in r)); row.append(' / '.join(f'{v:.3f}' for v in fe))
        bars.append(('ok' if r[0]<=r[1] else 'S>M')+('' if r[1]<r[2] else ',M≥C'))
    # ratio aad/rae ~ mean |x|
    sx=[ (s['metrics'][ch]['aad']/s['metrics'][ch]['rae'] if s['metrics'][ch]['rae'] else 0) for ch in ['fy','fx']]
    row.append(f'{sx[0]:.3f} / {sx[1]:.3f}')
    row.append(', '.join(bars)); row.append(str(s['switches']))
    print('| '+' | '.join(row)+' |')
