#!/usr/bin/env python3
"""Variants of the shipped profile's [mpc] section, each run with `hexcue play --headless` on
the flights given, and a table of score, limiter share and felt error per channel
(docs/mpc.md, issue #35). A variant is NAME=LINE[;LINE...]: each LINE (`key = value`)
replaces that key in [mpc] or is added to it. The solvers' wall-clock limit is lifted, as in
`compare`. Environment: ALGS (default smpc,mpc,cwf), FLAGS (more play options, e.g.
--preview). Summaries already in OUTDIR are reused.

usage: scripts/mpc-variants.py BIN OUTDIR VARIANT... -- FLIGHT.csv...
e.g.   scripts/mpc-variants.py target/release/hexcue /tmp/v base= \
           "dz=dead_zone_weight = [0.05, 0.05, 0.05, 0.05, 0.05, 0.05]" -- recordings/traces/*.csv"""
import json, os, subprocess, sys
bin_, out = sys.argv[1], sys.argv[2]
args = sys.argv[3:]
sep = args.index('--')
variants, flights = args[:sep], args[sep + 1:]
base = open(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'profiles', 'full-flight.toml')).read()
algs = os.environ.get('ALGS', 'smpc,mpc,cwf')
extra_flags = os.environ.get('FLAGS', '').split()
os.makedirs(out, exist_ok=True)
rows = {}
for v in variants:
    name, _, extra = v.partition('=')
    lines = [l for l in extra.split(';') if l.strip()]
    import re
    head, sep_, tail = base.partition('[mpc]\n')
    for l in lines:
        k = l.split('=')[0].strip()
        pat = re.compile('^' + re.escape(k) + r' *=.*$', re.M)
        if pat.search(tail.split('\n[')[0]):
            tail = pat.sub(l, tail, count=1)
        else:
            tail = l + '\n' + tail
    prof = head + sep_ + tail
    prof = prof.replace('time_limit_ms = 20.0', 'time_limit_ms = 10000.0')
    pp = f'{out}/{name}.toml'
    open(pp, 'w').write(prof)
    for f in flights:
        fn = os.path.basename(f)[:-4]
        sp = f'{out}/{name}--{fn}.json'
        if not os.path.exists(sp):
            r = subprocess.run([bin_, 'play', '--headless', '--trace', f, '--profile', pp, '--algorithms', algs,
                                '--summary', sp, '--force'] + extra_flags, capture_output=True, text=True)
            if r.returncode != 0:
                print(name, fn, 'FAILED', r.stderr[-500:]); continue
        d = json.load(open(sp))
        for a, s in d['algorithms'].items():
            rows[(name, fn, a)] = s
        print(f"{name:10s} {fn:28s} ref={d.get('mpc_reference')}", flush=True)
chs = ['fx', 'fy', 'fz', 'wx', 'wy', 'wz']
print('\nvariant    flight                       alg   score  limiter%  felt ' + ' '.join(f'{c:>6s}' for c in chs) + '  false')
for (name, fn, a), s in sorted(rows.items(), key=lambda kv: (kv[0][1], kv[0][2], variants.index(next(v for v in variants if v.partition('=')[0]==kv[0][0])))):
    felt = s['score_terms']['felt']
    print(f"{name:10s} {fn:28s} {a:5s} {s['score']:6.3f} {100*s['limiter_fraction']:7.2f}      " + ' '.join(f"{felt[c]:6.3f}" for c in chs) + f"  {s['score_terms']['false_cue']:.3f}")
print('\nmeans per variant and algorithm (score, limiter %, max limiter %)')
for v in variants:
    name = v.partition('=')[0]
    for a in algs.split(','):
        ss = [s for (n, f, al), s in rows.items() if n == name and al == a]
        if ss:
            print(f"{name:10s} {a:5s} mean score {sum(s['score'] for s in ss)/len(ss):.3f}  mean limiter {100*sum(s['limiter_fraction'] for s in ss)/len(ss):.2f} %  max {100*max(s['limiter_fraction'] for s in ss):.2f} %  n={len(ss)}")
