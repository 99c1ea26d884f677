"""Writes a long synthetic trace (hexcue CSV, 100 Hz) for the memory measurement in
docs/performance.md: python3 docs/make-long-trace.py ROWS FILE."""
import math, sys
n = int(sys.argv[1]); out = open(sys.argv[2], "w")
out.write("t,fx,fy,fz,p,q,r,phi,theta,psi\n")
for k in range(n):
    t = k / 100.0
    fx = 1.5 * math.sin(0.3 * t); fy = 0.8 * math.sin(0.7 * t + 1.0); fz = -9.80665 + 0.5 * math.sin(1.1 * t)
    p = 0.05 * math.sin(0.9 * t); q = 0.03 * math.sin(0.4 * t); r = 0.02 * math.sin(0.2 * t)
    out.write(f"{t:.2f},{fx:.6f},{fy:.6f},{fz:.6f},{p:.6f},{q:.6f},{r:.6f},{0.1*math.sin(0.05*t):.6f},{0.05*math.sin(0.03*t):.6f},{(0.01*t)%6.283185:.6f}\n")
