#!/usr/bin/env python3
"""Issue 34's check against a real JSBSim: every way back to neutral without a jolt.

A real JSBSim (PyPI `jsbsim`, its own c172p, as tests/jsbsim_flight.py flies it: 3000 ft,
100 kt, here at full throttle) flies roll reversals between ±45° of bank every 3 s in real
time, streaming
integrations/jsbsim/hexcue.xml (its port rewritten) into

    hexcue live --headless --input jsbsim://127.0.0.1:P --output udp://127.0.0.1:Q \
        [--output serial://PTY?baud=250000] --summary S.json

and every JSON datagram of the udp output is logged (t, seq, pose, velocity, acceleration,
state). Three sessions, each stopped mid-reversal, the platform moving:

  (a) input lost: JSBSim stops stepping (its socket output just ends); once the platform is
      parked and at rest, SIGINT ends the session;
  (b) SIGINT: hexcue gets SIGINT while JSBSim keeps flying until hexcue has exited;
  (c) as (b) with profiles/hobby-linear.toml and --output serial://<pty> read by
      os.openpty(): the bytes are the start frame, position frames that match the template
      and equal the JSON datagrams' actuator values and round((leg - min) / (max - min) *
      (2^bits - 1)) of the same step's legs, then the stop frame, nothing after it. The shipped
      profile's start and stop are empty, so a copy gets two 8-byte frames (those of
      tests/actuators.rs) to be checked.

For each, over the transition (from the first datagram whose state is not `running` to the
last): the worst commanded acceleration per DoF from the second difference of successive
poses (the first spans the last two commands before it, so a step in velocity at the
hand-over counts) and from the datagram's own `acceleration` field, m/s² for x, y, z and
°/s² for roll, pitch, yaw; the worst jerk (third difference); the time from the transition's
first datagram to rest on neutral (|pose| <= 1 mm and 0.05°, |velocity| <= 1e-4 m/s and
0.01 °/s, and so to the end); and the checks: within 2 m/s² and 30 °/s², at rest within the
profile's return_time_s, the session ending parked with status 0.

Usage (with the venv made by tests/live.rs's jsbsim_python(), or any Python with jsbsim):
    python3 -m venv target/jsbsim-venv && target/jsbsim-venv/bin/pip install jsbsim
    target/jsbsim-venv/bin/python scripts/live-transitions-jsbsim.py [HEXCUE] \
        [--drive smpc|mpc|cwf] [--stop-s 10.6] [--only a,b,c] [--log-dir DIR]
HEXCUE defaults to target/release/hexcue. Exits 1 when a check fails, 2 when the session
could not be run at all, 3 when no check failed but a session was not stopped while running
(JSBSim descheduled past the input timeout before the stop; run again, not under nice). Nothing waits a fixed time where it matters: every wait is on a
condition (a datagram, a state, the process's exit) with a generous bound.
"""

import argparse
import json
import math
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import tomllib

import jsbsim

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
AXIS_MPS2 = 2.0  # issue 34's bounds during a transition
ANGLE_DPS2 = 30.0
REST_M = 1e-3
REST_DEG = 0.05
REST_V_MPS = 1e-4
REST_V_DPS = 0.01
DOFS = ["surge", "sway", "heave", "roll", "pitch", "yaw"]
DEG = 180.0 / math.pi


def fail(msg):
    print(f"live-transitions-jsbsim: {msg}", file=sys.stderr)
    sys.exit(2)


def wait_until(cond, bound_s, what):
    """Polls `cond` until it holds, at most bound_s; fails naming `what` otherwise."""
    end = time.monotonic() + bound_s
    while not cond():
        if time.monotonic() > end:
            fail(f"timed out after {bound_s} s waiting for {what}")
        time.sleep(0.01)


class Listener:
    """Collects the JSON datagrams of a udp:// output, with their arrival times."""

    def __init__(self):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.port = self.sock.getsockname()[1]
        self.commands = []
        self.lock = threading.Lock()
        self.stopping = False
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self):
        while True:
            try:
                data, _ = self.sock.recvfrom(65536)
            except socket.timeout:
                if self.stopping:
                    return
                continue
            c = json.loads(data)
            with self.lock:
                self.commands.append(c)

    def snapshot(self):
        with self.lock:
            return list(self.commands)

    def last(self):
        with self.lock:
            return self.commands[-1] if self.commands else None

    def stop(self):
        self.stopping = True
        self.thread.join()
        self.sock.close()


class PtyReader:
    """A fake controller: reads every byte hexcue writes to a pseudo-terminal."""

    def __init__(self):
        self.master, self.slave = os.openpty()
        os.set_inheritable(self.master, False)
        # Raw, so that the line discipline neither echoes nor translates CR/LF (hexcue sets
        # the port's mode too, but the bytes must be read as they were written).
        import tty

        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.bytes = bytearray()
        self.stopping = False
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self):
        import select

        while not self.stopping:
            r, _, _ = select.select([self.master], [], [], 0.05)
            if r:
                try:
                    self.bytes.extend(os.read(self.master, 65536))
                except OSError:
                    time.sleep(0.01)

    def stop(self):
        self.stopping = True
        self.thread.join()
        os.close(self.master)
        os.close(self.slave)


def directive_for(port, dir_):
    """The shipped directive with its port set to `port`."""
    text = open(os.path.join(REPO, "integrations/jsbsim/hexcue.xml")).read()
    text, n = re.subn(r'port="\d+"', f'port="{port}"', text)
    if n != 1:
        fail("integrations/jsbsim/hexcue.xml: expected one port=\"N\" attribute")
    path = os.path.join(dir_, "hexcue-directive.xml")
    open(path, "w").write(text)
    return path


class Flight:
    """The c172p in real time, rolling between +45° and -45° of bank every 3 s from t = 1 s."""

    def __init__(self, directive):
        self.fdm = jsbsim.FGFDMExec(None)
        self.fdm.set_debug_level(0)
        self.fdm.set_output_directive(directive)
        self.fdm.load_model("c172p")
        self.fdm["ic/h-sl-ft"] = 3000
        self.fdm["ic/vc-kts"] = 100
        self.fdm["ic/gamma-deg"] = 0
        self.fdm.run_ic()
        self.fdm["propulsion/set-running"] = -1
        self.fdm["fcs/throttle-cmd-norm"] = 1.0
        self.dt = self.fdm.get_delta_t()
        self.start = None
        self.frames = 0
        self.late = 0

    def step(self):
        if self.start is None:
            self.start = time.monotonic()
        t = self.fdm.get_sim_time()
        target = 0.0 if t < 1.0 else (45.0 if int((t - 1.0) // 3.0) % 2 == 0 else -45.0) / DEG
        phi = self.fdm["attitude/phi-rad"]
        p = self.fdm["velocities/p-rad_sec"]
        self.fdm["fcs/aileron-cmd-norm"] = max(-1.0, min(1.0, 2.0 * (target - phi) - 0.5 * p))
        self.fdm["fcs/elevator-cmd-norm"] = -0.05 * min(1.0, abs(phi) / 0.8)
        self.fdm.run()
        self.frames += 1
        # Real time: JSBSim itself runs as fast as it can.
        wait = self.start + self.frames * self.dt - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        elif wait < -self.dt:
            self.late += 1

    def time(self):
        return self.fdm.get_sim_time()

    def attitude(self):
        return (self.fdm["attitude/phi-rad"] * DEG, self.fdm["velocities/p-rad_sec"] * DEG)


def free_udp_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def profile_with_frames(profile, dir_):
    """The profile, with start and stop frames when it has none, so that both can be checked."""
    text = open(profile).read()
    act = tomllib.loads(text)["actuators"]
    if act.get("start", "") == "" or act.get("stop", "") == "":
        text = re.sub(r'^start = ""', 'start = "<249><249><0><6><0><1><10><13>"', text, flags=re.M)
        text = re.sub(r'^stop = ""', 'stop = "<249><249><0><6><0><0><10><13>"', text, flags=re.M)
        path = os.path.join(dir_, os.path.basename(profile))
        open(path, "w").write(text)
        return path
    return profile


def run_session(args, scenario, log_dir):
    """Runs one session; returns (commands, exit status, stderr, summary, serial bytes, profile)."""
    dir_ = tempfile.mkdtemp(prefix=f"hexcue-{scenario}-")
    in_port = free_udp_port()
    directive = directive_for(in_port, dir_)
    listener = Listener()
    summary_path = os.path.join(dir_, "summary.json")
    cmd = [
        args.hexcue, "live", "--headless",
        "--input", f"jsbsim://127.0.0.1:{in_port}",
        "--output", f"udp://127.0.0.1:{listener.port}",
        "--summary", summary_path, "--force",
        "--drive", args.drive,
    ]
    if args.drive == "cwf":
        cmd += ["--algorithms", "cwf"]
    pty = None
    profile = args.profile
    if scenario == "c":
        profile = profile_with_frames(os.path.join(REPO, "profiles/hobby-linear.toml"), dir_)
        pty = PtyReader()
        cmd += ["--output", f"serial://{pty.path}?baud=250000"]
    if profile:
        cmd += ["--profile", profile]
    print(f"({scenario}) {' '.join(cmd)}", flush=True)
    err_path = os.path.join(dir_, "stderr.txt")
    proc = subprocess.Popen(cmd, cwd=REPO, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=open(err_path, "w"))
    # A command leaves every step from the start: the first one says the session runs.
    wait_until(lambda: listener.last() is not None or proc.poll() is not None, 20,
               "hexcue's first JSON datagram")
    if proc.poll() is not None:
        fail(f"hexcue exited with {proc.returncode}: {open(err_path).read()}")
    flight = Flight(directive)
    while flight.time() < args.stop_s:
        flight.step()
    phi, p = flight.attitude()
    at_stop = listener.last()
    print(f"({scenario}) stop at JSBSim t {flight.time():.2f} s: bank {phi:.1f}°, roll rate "
          f"{p:.1f} °/s; hexcue t {at_stop['t']:.2f} s, state {at_stop['state']}", flush=True)
    if scenario == "a":
        # The input just ends. Wait for the platform parked and at rest, then end the session.
        def parked_at_rest():
            c = listener.snapshot()
            return len(c) > 50 and all(x["state"] == "parked" and at_rest(x) for x in c[-50:]) \
                and any(x["state"] == "washout" for x in c)
        wait_until(parked_at_rest, 20, "parked at rest on neutral after the input's loss")
        proc.send_signal(signal.SIGINT)
    else:
        proc.send_signal(signal.SIGINT)
        # JSBSim goes on flying until hexcue has exited.
        end = time.monotonic() + 20
        while proc.poll() is None:
            if time.monotonic() > end:
                proc.kill()
                fail("hexcue did not exit within 20 s of SIGINT")
            flight.step()
    try:
        status = proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        fail("hexcue did not exit within 20 s of SIGINT")
    # Every datagram sent has arrived once the listener has been quiet a while.
    listener.stop()
    serial = None
    if pty:
        # hexcue has exited: the last byte it wrote is in the pty's buffer or already read.
        n = -1
        while n != len(pty.bytes):
            n = len(pty.bytes)
            time.sleep(0.1)
        pty.stop()
        serial = bytes(pty.bytes)
    stderr = open(err_path).read()
    summary = json.load(open(summary_path)) if os.path.exists(summary_path) else None
    print(f"({scenario}) JSBSim: {flight.frames} frames of {flight.dt:.5f} s, {flight.late} "
          f"more than a frame late", flush=True)
    commands = sorted(listener.commands, key=lambda c: c["seq"])
    if log_dir:
        os.makedirs(log_dir, exist_ok=True)
        with open(os.path.join(log_dir, f"{scenario}.jsonl"), "w") as f:
            for c in commands:
                f.write(json.dumps({k: c.get(k) for k in
                                    ["t", "seq", "pose", "velocity", "acceleration", "legs",
                                     "actuators", "state"] if k in c}) + "\n")
        open(os.path.join(log_dir, f"{scenario}.stderr.txt"), "w").write(stderr)
        if serial is not None:
            open(os.path.join(log_dir, f"{scenario}.serial.bin"), "wb").write(serial)
    # The stop tested is the one asked for only if the platform was running when it came:
    # a simulator descheduled for more than input_timeout_s on a loaded machine loses the
    # input before it, and the session then checks other transitions.
    stopped_running = at_stop["state"] == "running"
    return commands, status, stderr, summary, serial, profile, stopped_running


def at_rest(c):
    pose, vel = c["pose"], c["velocity"]
    return (all(abs(v) <= REST_M for v in pose[:3])
            and all(abs(v) * DEG <= REST_DEG for v in pose[3:])
            and all(abs(v) <= REST_V_MPS for v in vel[:3])
            and all(abs(v) * DEG <= REST_V_DPS for v in vel[3:]))


def scale(i):
    """Display units: m for the axes, degrees for the angles."""
    return 1.0 if i < 3 else DEG


def second_differences(poses, lo, hi, dt):
    """Worst |(p[k+1] - 2p[k] + p[k-1])/dt²| per DoF for k in [lo, hi), display units."""
    worst = [0.0] * 6
    for k in range(max(lo, 1), min(hi, len(poses) - 1)):
        for i in range(6):
            a = (poses[k + 1][i] - 2 * poses[k][i] + poses[k - 1][i]) / dt**2 * scale(i)
            worst[i] = max(worst[i], abs(a))
    return worst


def row(name, v, ua, ub):
    print(f"  {name:<38} {v[0]:7.3f} {v[1]:7.3f} {v[2]:7.3f} {ua:<6} "
          f"{v[3]:7.2f} {v[4]:7.2f} {v[5]:7.2f} {ub}")


def analyse(scenario, commands, status, summary, return_time_s):
    """Prints the figures of every way back to neutral; returns the list of failed checks.

    A transition starts at the first datagram whose state is `washout` or `estop` after one
    that is neither, and ends at the next `parked` (or the log's end). Its accelerations are
    counted from the second difference centred on the last command before it (the hand-over),
    so a step in velocity between the algorithm and the path counts. A fade-in (`engaging`)
    is reported too, for information: the driving algorithm's command, faded in, not a path.
    """
    failed = []
    seqs = [c["seq"] for c in commands]
    gaps = sum(1 for a, b in zip(seqs, seqs[1:]) if b != a + 1)
    if seqs and (seqs[0] != 0 or gaps):
        failed.append(f"datagrams lost: first seq {seqs[0]}, {gaps} gaps")
    n = len(commands)
    dt = (commands[-1]["t"] - commands[0]["t"]) / (n - 1)
    poses = [c["pose"] for c in commands]
    states = [c["state"] for c in commands]
    if "running" not in states:
        return failed + ["the platform never ran"]
    segments = []
    prev = None
    for k, s in enumerate(states):
        if s != prev:
            segments.append([s, k, k])
            prev = s
        segments[-1][2] = k + 1
    print(f"\n({scenario}) {n} datagrams, dt {dt*1000:.2f} ms, hexcue exit status {status}; "
          f"states: " + " → ".join(f"{s} {commands[a]['t']:.2f} s" for s, a, _ in segments))
    returning = ("washout", "estop")
    for s, a, b in segments:
        if s != "engaging":
            continue
        fade = second_differences(poses, a, b, dt)
        print(f"  fade-in from {commands[a]['t']:.2f} s (the algorithm's command, faded in; "
              f"not checked):")
        row("worst |a|, poses' 2nd difference", fade, "m/s²", "°/s²")
    starts = [k for k in range(1, n) if states[k] in returning and states[k - 1] not in returning]
    if not starts:
        return failed + ["no way back to neutral: the session never left running"]
    for start in starts:
        end = next((k for k in range(start, n) if states[k] == "parked"), n)
        # The hand-over: the acceleration the platform had on the last command before.
        handover = second_differences(poses, start - 2, start - 1, dt)
        acc2 = second_differences(poses, start - 1, end, dt)
        jerk = [0.0] * 6
        for k in range(max(start - 1, 1), min(end, n - 2)):
            for i in range(6):
                j = (poses[k + 2][i] - 3 * poses[k + 1][i] + 3 * poses[k][i]
                     - poses[k - 1][i]) / dt**3 * scale(i)
                jerk[i] = max(jerk[i], abs(j))
        accf = [max(abs(c["acceleration"][i]) * scale(i) for c in commands[start:end])
                for i in range(6)]
        before = second_differences(poses, start - 100, start - 1, dt)
        rest = end
        while rest > start and at_rest(commands[rest - 1]):
            rest -= 1
        t0 = commands[start]["t"]
        p0 = [poses[start - 1][i] * scale(i) for i in range(6)]
        v0 = [commands[start - 1]["velocity"][i] * scale(i) for i in range(6)]
        print(f"  {states[start]} at {t0:.2f} s (after {states[start - 1]}), parked at "
              f"{commands[end]['t'] if end < n else float('nan'):.2f} s")
        print(f"  {'':<38} {'surge':>7} {'sway':>7} {'heave':>7} {'':<6} "
              f"{'roll':>7} {'pitch':>7} {'yaw':>7}")
        row("pose at the start", p0, "m", "°")
        row("velocity at the start", v0, "m/s", "°/s")
        row("|a| at the hand-over (last command)", handover, "m/s²", "°/s²")
        row("worst |a|, poses' 2nd difference", acc2, "m/s²", "°/s²")
        row("worst |a|, `acceleration` field", accf, "m/s²", "°/s²")
        row("worst |jerk|, 3rd difference", jerk, "m/s³", "°/s³")
        row(f"(before: the last second's worst |a|)", before, "m/s²", "°/s²")
        mine = []
        if rest < end or (end == n and rest < n):
            to_rest = commands[rest]["t"] - t0
            print(f"  at rest on neutral {to_rest:.2f} s after the transition's start "
                  f"(return_time_s {return_time_s})")
            if to_rest > return_time_s + 1e-9:
                mine.append(f"at {t0:.2f} s: at rest on neutral after {to_rest:.2f} s > "
                            f"{return_time_s} s")
        else:
            mine.append(f"at {t0:.2f} s: never at rest on neutral")
        grown = []
        for i in range(6):
            bound = AXIS_MPS2 if i < 3 else ANGLE_DPS2
            for what, v in (("poses' second difference", acc2[i]),
                            ("acceleration field", accf[i])):
                if v > bound:
                    mine.append(f"at {t0:.2f} s: {DOFS[i]} |a| {v:.3f} > {bound} ({what})")
            # Beyond the bound, did the path grow the acceleration it inherited?
            if acc2[i] > max(bound, handover[i]) * 1.01:
                grown.append(DOFS[i])
        print(f"  issue 34's check (≤ {AXIS_MPS2} m/s², ≤ {ANGLE_DPS2} °/s², at rest within "
              f"{return_time_s} s): {'PASS' if not mine else 'FAIL'}; a DoF whose |a| rose "
              f"above both the bound and its hand-over value: {', '.join(grown) or 'none'}")
        failed += mine
    if states[-1] != "parked":
        failed.append(f"the last datagram's state is {states[-1]}, not parked")
    if status != 0:
        failed.append(f"hexcue exited with status {status}")
    if summary:
        brakes = summary.get("live", {}).get("transitions", {}).get("hard_brakes")
        print(f"  summary: live.transitions.hard_brakes {json.dumps(brakes)}")
    return failed


def template_regex(act):
    """The position frame as a byte regex with a group per <AxisNa>, and the axes' order."""
    bits, enc = act["bits"], act["encoding"]
    width = {"binary": b"(.{%d})" % ((bits + 7) // 8),
             "decimal": rb"(\d+)",
             "hex": b"([0-9A-F]{%d})" % ((bits + 3) // 4)}[enc]
    out, axes, pos = b"", [], 0
    tpl = act["template"]
    for m in re.finditer(r"<Axis([1-6])a>|<(\d{1,3})>", tpl):
        out += re.escape(tpl[pos:m.start()].encode())
        if m.group(1):
            out += width
            axes.append(int(m.group(1)))
        else:
            out += re.escape(bytes([int(m.group(2))]))
        pos = m.end()
    out += re.escape(tpl[pos:].encode())
    return re.compile(out, re.S), axes


def literal_frame(tpl):
    out, pos = b"", 0
    for m in re.finditer(r"<(\d{1,3})>", tpl):
        out += tpl[pos:m.start()].encode() + bytes([int(m.group(1))])
        pos = m.end()
    return out + tpl[pos:].encode()


def check_serial(serial, commands, profile):
    """The serial stream against the template, the JSON actuators and the legs."""
    failed = []
    prof = tomllib.loads(open(profile).read())
    act, geo = prof["actuators"], prof["geometry"]
    if act["kind"] != "linear":
        return [f"{profile}: only a linear [actuators] is checked here"]
    start, stop = literal_frame(act["start"]), literal_frame(act["stop"])
    regex, axes = template_regex(act)
    full = (1 << act["bits"]) - 1
    decode = {"binary": lambda b: int.from_bytes(b, "big"), "decimal": int,
              "hex": lambda b: int(b, 16)}[act["encoding"]]
    print(f"\n(c) serial: {len(serial)} bytes; start frame {start.hex()} , stop frame {stop.hex()}")
    if not serial.startswith(start):
        failed.append(f"the first bytes are {serial[:len(start)].hex()}, not the start frame")
    if not serial.endswith(stop):
        failed.append(f"the last bytes are {serial[-len(stop):].hex()}, not the stop frame")
    body = serial[len(start):len(serial) - len(stop)]
    frames, pos = [], 0
    while pos < len(body):
        m = regex.match(body, pos)
        if not m:
            failed.append(f"bytes {pos + len(start)}..: {body[pos:pos + 40].hex()} match no "
                          f"frame of the template")
            break
        frames.append([decode(m.group(g + 1)) for g in range(len(axes))])
        pos = m.end()
    # A frame goes every step from engaging on: the JSON datagrams from the first engaging.
    first = next(k for k, c in enumerate(commands) if c["state"] == "engaging")
    sent = commands[first:]
    print(f"(c) {len(frames)} position frames; {len(sent)} JSON datagrams from the first "
          f"engaging on")
    if len(frames) != len(sent):
        failed.append(f"{len(frames)} position frames for {len(sent)} steps from engaging on")
    lo, hi = geo["leg_min_m"], geo["leg_max_m"]
    json_mismatch = legs_off = 0
    for f, c in zip(frames, sent):
        by_axis = [0] * 6
        for g, a in enumerate(axes):
            by_axis[a - 1] = f[g]
        if by_axis != c["actuators"]:
            json_mismatch += 1
        for n in range(6):
            leg = c["legs"][act["order"][n] - 1]
            p = round((leg - lo) / (hi - lo) * full)
            if act["invert"][n]:
                p = full - p
            p = min(full, max(0, p + act["offset"][n]))
            # The legs in the JSON are printed to a finite precision: one count of 2^24 is
            # 15 nm of a 250 mm stroke.
            if abs(p - by_axis[n]) > 1:
                legs_off += 1
    print(f"(c) frames whose positions differ from the datagram's `actuators`: {json_mismatch}; "
          f"positions more than 1 count from round((leg - min)/(max - min)·(2^bits - 1)): "
          f"{legs_off}")
    if json_mismatch:
        failed.append(f"{json_mismatch} frames differ from the JSON actuators")
    if legs_off:
        failed.append(f"{legs_off} positions differ from the legs' by more than a count")
    print(f"(c) serial check (start first, every frame to the template and the legs, stop "
          f"last): {'PASS' if not failed else 'FAIL'}")
    return failed


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("hexcue", nargs="?", default=os.path.join(REPO, "target/release/hexcue"))
    ap.add_argument("--drive", default="smpc", choices=["smpc", "mpc", "cwf"],
                    help="the driving algorithm (cwf: run it alone)")
    ap.add_argument("--profile", help="the profile of (a) and (b) (default: hexcue's embedded "
                    "full-flight)")
    ap.add_argument("--stop-s", type=float, default=10.6,
                    help="JSBSim's time of the stop (s); by default mid-way through the reversal that starts at 10 s, the aircraft near wings level rolling at about 55 °/s")
    ap.add_argument("--only", default="a,b,c", help="the scenarios to run, e.g. a,b")
    ap.add_argument("--log-dir", help="keep every datagram (JSON lines), stderr and the serial "
                    "bytes here")
    args = ap.parse_args()
    if not os.access(args.hexcue, os.X_OK):
        fail(f"{args.hexcue}: not an executable (build it, or give the binary's path)")
    failures = {}
    inconclusive = []
    for scenario in args.only.split(","):
        commands, status, stderr, summary, serial, profile, stopped_running = run_session(
            args, scenario, args.log_dir)
        prof = profile or os.path.join(REPO, "profiles/full-flight.toml")
        return_time_s = tomllib.loads(open(prof).read()).get("safety", {}).get(
            "return_time_s", 4.5)
        failed = analyse(scenario, commands, status, summary, return_time_s)
        if serial is not None:
            failed += check_serial(serial, commands, profile)
        for line in stderr.splitlines():
            if any(w in line for w in ("hard brake", "error", "input lost", "warning")):
                print(f"  stderr: {line}")
        failures[scenario] = failed
        if not stopped_running:
            inconclusive.append(scenario)
    print()
    for scenario, failed in failures.items():
        verdict = 'PASS' if not failed else 'FAIL: ' + '; '.join(failed)
        if scenario in inconclusive:
            verdict += (" (INCONCLUSIVE: the platform was not running when the stop came; the "
                        "input was lost before it, JSBSim late on a loaded machine: run again)")
        print(f"({scenario}) {verdict}")
    sys.exit(1 if any(failures.values()) else 3 if inconclusive else 0)


if __name__ == "__main__":
    main()
