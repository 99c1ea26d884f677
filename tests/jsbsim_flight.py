"""A short JSBSim flight in real time for tests/live.rs: the c172p from the jsbsim package's
own data, at 3000 ft and 100 kt, an elevator then an aileron input, streamed by the output
directive given as the first argument for the seconds given as the second."""

import sys
import time

import jsbsim

directive, seconds = sys.argv[1], float(sys.argv[2])
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
while fdm.get_sim_time() < seconds:
    t = fdm.get_sim_time()
    fdm["fcs/elevator-cmd-norm"] = -0.3 if 1.0 < t < 2.0 else 0.0
    fdm["fcs/aileron-cmd-norm"] = 0.3 if 2.0 < t < 3.0 else 0.0
    fdm.run()
    frames += 1
    # Real time: JSBSim itself runs as fast as it can.
    wait = start + frames * dt - time.monotonic()
    if wait > 0:
        time.sleep(wait)
print(f"jsbsim: {frames} frames of {dt:.5f} s", file=sys.stderr)
