"""A JSBSim flight in real time: the c172p from the jsbsim package's own data, at 3000 ft and
100 kt, streamed by the output directive given as the first argument for the seconds given
as the second.

    python tests/jsbsim_flight.py DIRECTIVE.xml SECONDS [repeat]

By default (tests/live.rs) an elevator then an aileron input, once. With `repeat`
(scripts/live-under-load.sh) an aileron doublet and an elevator pulse every 10 s, so that
every algorithm has cues to follow for as long as the flight lasts."""

import sys
import time

import jsbsim

directive, seconds = sys.argv[1], float(sys.argv[2])
repeat = len(sys.argv) > 3 and sys.argv[3] == "repeat"
fdm = jsbsim.FGFDMExec(None)  # the package's own aircraft, engines and systems
fdm.set_debug_level(0)
fdm.set_output_directive(directive)
fdm.load_model("c172p")
fdm["ic/h-sl-ft"] = 3000
fdm["ic/vc-kts"] = 100
fdm["ic/gamma-deg"] = 0
fdm.run_ic()
fdm["propulsion/set-running"] = -1
fdm["fcs/throttle-cmd-norm"] = 0.8
dt = fdm.get_delta_t()
start = time.monotonic()
frames = 0
late = 0
while fdm.get_sim_time() < seconds:
    t = fdm.get_sim_time()
    if repeat:
        phase = t % 10.0
        fdm["fcs/aileron-cmd-norm"] = 0.4 if 2.0 < phase < 3.0 else (-0.4 if 3.0 < phase < 4.0 else 0.0)
        fdm["fcs/elevator-cmd-norm"] = -0.2 if 6.0 < phase < 7.0 else 0.0
    else:
        fdm["fcs/elevator-cmd-norm"] = -0.3 if 1.0 < t < 2.0 else 0.0
        fdm["fcs/aileron-cmd-norm"] = 0.3 if 2.0 < t < 3.0 else 0.0
    fdm.run()
    frames += 1
    # Real time: JSBSim itself runs as fast as it can.
    wait = start + frames * dt - time.monotonic()
    if wait > 0:
        time.sleep(wait)
    elif wait < -dt:
        late += 1
print(
    f"jsbsim: {frames} frames of {dt:.5f} s in {time.monotonic() - start:.1f} s, "
    f"{late} more than a frame late",
    file=sys.stderr,
)
