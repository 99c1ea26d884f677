#!/usr/bin/env python3
"""A live session into a fake controller on a pseudo-terminal, for a look by hand: hexcue live
--headless (the debug build, CWF driving) with 5 s of the steep turn replayed in JSBSim's socket
format, its JSON output to a listener and its actuator frame to os.openpty(); prints the bytes
the controller got and the summary's step times. The checked version is tests/actuators.rs.

Usage: python3 scripts/actuator-session.py profiles/hobby-linear.toml 250000
"""
import os, socket, subprocess, threading, time, json, sys, tempfile
repo=os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
summary = os.path.join(tempfile.mkdtemp(), 'summary.json')
m, s = os.openpty(); path = os.ttyname(s)
os.set_inheritable(m, False)
got = bytearray(); stop = False
def rd():
    while not stop:
        try:
            b = os.read(m, 4096)
            if b: got.extend(b)
        except OSError: time.sleep(0.005)
threading.Thread(target=rd, daemon=True).start()
js = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); js.bind(('127.0.0.1', 0)); jport = js.getsockname()[1]
inp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); inp.bind(('127.0.0.1', 0)); iport = inp.getsockname()[1]; inp.close()
prof = sys.argv[1]; baud = sys.argv[2]
p = subprocess.Popen([repo+'/target/debug/hexcue','live','--headless','--input',f'jsbsim://127.0.0.1:{iport}','--output',f'udp://127.0.0.1:{jport}','--output',f'serial://{path}?baud={baud}','--profile',prof,'--algorithms','cwf','--drive','cwf','--duration','8','--summary',summary,'--force'], cwd=repo, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
time.sleep(0.5)
rows = [l.split(',') for l in open(repo+'/recordings/traces/steep-turn.csv').read().splitlines()[1:]]
tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
ft = lambda v: float(v)/0.3048
t0 = time.time()
for k, r in enumerate(rows[2000:2500]):
    time.sleep(max(0, t0 + k*0.01 - time.time()))
    tx.sendto((','.join([r[0], str(ft(r[1])), str(ft(r[2])), str(ft(r[3]))] + r[4:10]) + '\n').encode(), ('127.0.0.1', iport))
out, err = p.communicate()
time.sleep(0.3); stop = True
l = json.load(open(summary))['live']
print(prof, 'rc', p.returncode, 'serial bytes', len(got), 'commands', l['commands_out'], 'step_ms', l['step_ms'], 'deadline_misses', l['deadline_misses'], 'limited', l['actuators_limited_steps'])
