#!/usr/bin/env python3
"""Variants of the shipped profile for the S-MPC (issue #35), each run with `hexcue play
--headless` on the flights given, and per flight the S-MPC's threshold-aware error per channel,
its cueable part (error above the bound's per-channel figure, as scripts/cueable.py) and the
share of the CWF's cueable error it removes, with surge and sway RAE, limiter share, false-cue
time and jolt term beside the MPC's and the CWF's (run once, from the `base` variant).

A variant is NAME=LINE[;LINE...]: `cotc.KEY = V` sets KEY in [smpc.cotc], `smpc.KEY = V` in
[smpc], `KEY = V` in [mpc] (replacing the key where the section has it, else adding it). The
solvers' wall-clock limit is lifted, as in `compare`. BOUNDS (environment) is a directory of
`hexcue bound --json` files named `bound-FLIGHT.json`; flights without one get no cueable
figure (their error total still ranks the variants: the bound does not depend on them).
FLAGS (environment): more `play` options for every run, e.g. `--preview` (the CWF ignores it).
Summaries already in OUTDIR are reused.

usage: scripts/smpc-variants.py BIN OUTDIR VARIANT... -- FLIGHT.csv...
e.g.   BOUNDS=/tmp/bounds scripts/smpc-variants.py target/release/hexcue /tmp/sv base= \\
           "hz=cotc.specific_force_weight = [1.5, 1.5, 0.5]" -- recordings/traces/*.csv"""
import json, os, re, subprocess, sys

bin_, out = sys.argv[1], sys.argv[2]
args = sys.argv[3:]
sep = args.index('--')
variants, flights = args[:sep], args[sep + 1:]
here = os.path.dirname(os.path.abspath(__file__))
base = open(os.path.join(here, '..', 'profiles', 'full-flight.toml')).read()
bounds = os.environ.get('BOUNDS')
jobs = int(os.environ.get('JOBS', '1'))
extra_flags = os.environ.get('FLAGS', '').split()
chs = ['fx', 'fy', 'fz', 'wx', 'wy', 'wz']
os.makedirs(out, exist_ok=True)


def set_key(text, section, line):
    """`line` (`key = value`) into `section` of the TOML text."""
    key = line.split('=')[0].strip()
    head = f'[{section}]\n'
    i = text.index(head) + len(head)
    j = text.find('\n[', i)
    j = len(text) if j < 0 else j + 1
    body = text[i:j]
    pat = re.compile('^' + re.escape(key) + r' *=.*$', re.M)
    body = pat.sub(line, body, count=1) if pat.search(body) else line + '\n' + body
    return text[:i] + body + text[j:]


def profile_of(lines):
    prof = base
    for l in lines:
        l = l.strip()
        if l.startswith('cotc.'):
            prof = set_key(prof, 'smpc.cotc', l[5:])
        elif l.startswith('smpc.'):
            prof = set_key(prof, 'smpc', l[5:])
        else:
            prof = set_key(prof, 'mpc', l)
    return prof.replace('time_limit_ms = 20.0', 'time_limit_ms = 10000.0')


runs = []
for v in variants:
    name, _, extra = v.partition('=')
    pp = f'{out}/{name}.toml'
    open(pp, 'w').write(profile_of([l for l in extra.split(';') if l.strip()]))
    algs = 'smpc,mpc,cwf' if name == 'base' else 'smpc'
    for f in flights:
        fn = os.path.basename(f)[:-4]
        sp = f'{out}/{name}--{fn}.json'
        if not os.path.exists(sp):
            runs.append((name, fn, [bin_, 'play', '--headless', '--trace', f, '--profile', pp,
                                    '--algorithms', algs, '--summary', sp, '--force'] + extra_flags))
procs = []
for name, fn, cmd in runs:
    while len(procs) >= jobs:
        p, n = procs.pop(0)
        if p.wait() != 0:
            print(n, 'FAILED', p.stderr.read()[-500:])
    procs.append((subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True),
                  f'{name} {fn}'))
for p, n in procs:
    if p.wait() != 0:
        print(n, 'FAILED', p.stderr.read()[-500:])


def lower_of(fn):
    path = f'{bounds}/bound-{fn}.json' if bounds else None
    if not path or not os.path.exists(path):
        return None
    b = json.load(open(path))
    low = dict(b['details']['joint_error'])
    low.update(b['bound']['lower']['channel'])
    return low


def load(name, fn):
    p = f'{out}/{name}--{fn}.json'
    return json.load(open(p))['algorithms'] if os.path.exists(p) else None


shares = {}
print('variant     flight                      alg    error  cueable  removes  ' +
      ' '.join(f'{c:>13s}' for c in chs) + '   fxRAE  fyRAE  limit%  false  jolt  switches')
for f in flights:
    fn = os.path.basename(f)[:-4]
    b = load('base', fn)
    if b is None or 'cwf' not in b:
        continue
    low = lower_of(fn)
    cue = lambda e: sum(max(e[c] - low[c], 0) for c in chs) if low else float('nan')
    cwf_cue = cue(b['cwf']['score_terms']['error'])
    rows = [('base', 'cwf', b['cwf']), ('base', 'mpc', b['mpc'])]
    for v in variants:
        name = v.partition('=')[0]
        a = load(name, fn)
        if a:
            rows.append((name, 'smpc', a['smpc']))
    for name, alg, s in rows:
        e = s['score_terms']['error']
        c = cue(e)
        rem = 100 * (1 - c / cwf_cue) if low else float('nan')
        if alg == 'smpc':
            shares.setdefault(name, []).append((fn, rem, sum(e.values())))
        per = ' '.join(f'{e[ch]:6.3f}({max(e[ch] - low[ch], 0):5.3f})' if low else f'{e[ch]:6.3f}       '
                       for ch in chs)
        m = s['metrics']
        fc = sum(m[ch]['false_cue_s'] for ch in chs)
        print(f"{name:11s} {fn:27s} {alg:5s} {sum(e.values()):7.3f} {c:7.3f} {rem:6.1f} %  {per}  "
              f"{m['fx']['rae']:6.3f} {m['fy']['rae']:6.3f} {100 * s['limiter_fraction']:6.2f} {fc:6.2f} "
              f"{s['score_terms']['jolt']:5.3f} {s.get('switches', 0)}")
print('\nper variant: S-MPC error summed over the flights, and the smallest share of the CWF\'s '
      'cueable error removed (flights with a bound)')
for v in variants:
    name = v.partition('=')[0]
    r = shares.get(name, [])
    with_bound = [x for x in r if x[1] == x[1]]
    worst = min(with_bound, key=lambda x: x[1]) if with_bound else ('-', float('nan'))
    print(f"{name:11s} error sum {sum(x[2] for x in r):8.3f} over {len(r)} flights;  "
          f"worst share {worst[1]:5.1f} % ({worst[0]})  "
          + ' '.join(f'{x[0][:10]} {x[1]:.0f}' for x in with_bound))
