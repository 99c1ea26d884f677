"""JSBSim's c172p from the runway in real time, streamed by an output directive: full
throttle, the elevator pulled above 55 kt, for the seconds given. It prints each change of
JSBSim's own weight on wheels (`gear/wow`) with its time, to set beside a live session's
ground-phase events (docs/live.md, "Air and ground"). Crude on purpose: the early rotation
makes the aircraft bounce, which gives several changes to compare.

    python scripts/jsbsim-takeoff.py integrations/jsbsim/hexcue.xml 40
"""
import sys
import time

import jsbsim

directive, seconds = sys.argv[1], float(sys.argv[2])
fdm = jsbsim.FGFDMExec(None)  # the package's own aircraft, engines and systems
fdm.set_debug_level(0)
fdm.set_output_directive(directive)
fdm.load_model("c172p")
fdm["ic/h-agl-ft"] = 0.0
fdm["ic/vc-kts"] = 0
fdm["ic/psi-true-deg"] = 0
fdm.run_ic()
fdm["propulsion/set-running"] = -1
fdm["fcs/throttle-cmd-norm"] = 1.0
fdm["fcs/mixture-cmd-norm"] = 1.0
dt = fdm.get_delta_t()
start = time.monotonic()
frames = 0
wow = None
while fdm.get_sim_time() < seconds:
    fdm["fcs/elevator-cmd-norm"] = -0.35 if fdm["velocities/vc-kts"] > 55 else 0.0
    fdm.run()
    frames += 1
    now = fdm["gear/wow"] > 0.5
    if now != wow:
        print(f"jsbsim: wow {int(now)} at {fdm.get_sim_time():.2f} s, "
              f"h-agl {fdm['position/h-agl-ft']:.1f} ft", file=sys.stderr)
        wow = now
    # Real time: JSBSim itself runs as fast as it can.
    wait = start + frames * dt - time.monotonic()
    if wait > 0:
        time.sleep(wait)
print(f"jsbsim: end, h-agl {fdm['position/h-agl-ft']:.0f} ft", file=sys.stderr)
