"""Replays a hexcue trace to `hexcue live` in JSBSim's socket format, in real time, for the
measured runs of docs/live.md (the same sender as tests/live.rs's replay):
python3 docs/replay-jsbsim.py TRACE.csv PORT [START_S] [SECONDS]."""
import socket, sys, time
path, port = sys.argv[1], int(sys.argv[2])
start_s = float(sys.argv[3]) if len(sys.argv) > 3 else 0.0
seconds = float(sys.argv[4]) if len(sys.argv) > 4 else 1e9
rows = [[float(v) for v in line.split(",")] for line in open(path).read().splitlines()[1:] if line.strip()]
rows = [r for r in rows if start_s <= r[0] < start_s + seconds]
ft = lambda v: v / 0.3048
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
to = ("127.0.0.1", port)
s.sendto(b"<LABELS> ,Time,a-pilot-x-ft sec2,a-pilot-y-ft sec2,a-pilot-z-ft sec2,p-rad sec,q-rad sec,r-rad sec,phi-rad,theta-rad,psi-rad\n", to)
t0 = time.monotonic()
for k, r in enumerate(rows):
    time.sleep(max(0.0, t0 + k * 0.01 - time.monotonic()))
    line = f"{r[0]:12.6f},{ft(r[1]):12.6f},{ft(r[2]):12.6f},{ft(r[3]):12.6f}," + ",".join(f"{v:12.8f}" for v in r[4:10]) + "\n"
    s.sendto(line.encode(), to)
print(f"sent {len(rows)} samples in {time.monotonic() - t0:.2f} s", file=sys.stderr)
