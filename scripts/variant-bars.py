"""Issue #35's bars per variant from `play --headless` summaries: the S-MPC's and the MPC's
share of the CWF's cueable error on the five shipped flights (BOUNDS, environment: the
directory of `bound-FLIGHT.json`), the turbulent cruise's heave error against the CWF's, and
the RAE order S-MPC <= MPC < CWF on surge and sway on every flight of CWFDIR (each failure
listed as S-MPC / MPC / CWF). Summaries named as scripts/smpc-variants.py writes them.

usage: scripts/variant-bars.py CWFDIR:CWFVAR LABEL=SDIR:SVAR:MDIR:MVAR...
e.g.   BOUNDS=/work/bounds scripts/variant-bars.py /tmp/sv:base base=/tmp/sv:base:/tmp/sv:base"""
import json, os, sys, glob
chs = ['fx', 'fy', 'fz', 'wx', 'wy', 'wz']
five = ['horizontal-stall', 'landing', 'steep-turn', 'takeoff', 'turbulence-cruise']
cd, cv = sys.argv[1].split(':')
flights = sorted(os.path.basename(p)[len(cv) + 2:-5] for p in glob.glob(f'{cd}/{cv}--*.json'))
bounds = os.environ['BOUNDS']
def low(f):
    b = json.load(open(f'{bounds}/bound-{f}.json')); l = dict(b['details']['joint_error']); l.update(b['bound']['lower']['channel']); return l
def alg(d, v, f, a): return json.load(open(f'{d}/{v}--{f}.json'))['algorithms'][a]
for spec in sys.argv[2:]:
    label, r = spec.split('='); sd, sv, md, mv = r.split(':')
    sh = []
    for f in five:
        l = low(f); c = alg(cd, cv, f, 'cwf'); s = alg(sd, sv, f, 'smpc'); m = alg(md, mv, f, 'mpc')
        cue = lambda x: sum(max(x['score_terms']['error'][ch] - l[ch], 0) for ch in chs)
        sh.append(f"{f[:10]} S {100*(1-cue(s)/cue(c)):.1f} M {100*(1-cue(m)/cue(c)):.1f}")
    f = 'turbulence-cruise'; c = alg(cd, cv, f, 'cwf'); s = alg(sd, sv, f, 'smpc'); m = alg(md, mv, f, 'mpc')
    hz = f"cruise heave S {s['score_terms']['error']['fz']:.3f} ({s['score_terms']['error']['fz']/c['score_terms']['error']['fz']:.2f}x) M {m['score_terms']['error']['fz']:.3f} ({m['score_terms']['error']['fz']/c['score_terms']['error']['fz']:.2f}x) CWF {c['score_terms']['error']['fz']:.3f}"
    fails = []
    for f in flights:
        c = alg(cd, cv, f, 'cwf'); s = alg(sd, sv, f, 'smpc'); m = alg(md, mv, f, 'mpc')
        for ch in ['fx', 'fy']:
            rs, rm, rc = s['metrics'][ch]['rae'], m['metrics'][ch]['rae'], c['metrics'][ch]['rae']
            if not (rs <= rm and rm < rc):
                fails.append(f"{f} {ch} {rs:.3f}/{rm:.3f}/{rc:.3f}")
    print(f"{label}: " + '; '.join(sh)); print('   ' + hz)
    print(f"   order fails ({len(fails)}, five: {sum(1 for x in fails if x.split()[0] in five)}): " + '; '.join(fails))
