"""A JSBSim flight in real time: the c172p from the jsbsim package's own data, at 3000 ft and
100 kt, streamed by the output directive given as the first argument for the seconds given
as the second.

    python tests/jsbsim_flight.py DIRECTIVE.xml SECONDS [repeat|reversals [AILERON]]

By default (tests/live.rs) an elevator then an aileron input, once. With `repeat`
(scripts/live-under-load.sh) an aileron doublet and an elevator pulse every 10 s, so that
every algorithm has cues to follow for as long as the flight lasts. With `reversals`
(tests/livetune_jsbsim.rs) roll reversals between 45° of bank left and right every 3 s from
t = 1 s (the bank held by a proportional-derivative aileron, as
scripts/live-transitions-jsbsim.py flies them, its deflection within AILERON, 0.3 of full
unless given), so that the platform is never still."""

import math
import sys
import time

import jsbsim

directive, seconds = sys.argv[1], float(sys.argv[2])
mode = sys.argv[3] if len(sys.argv) > 3 else "once"
if mode not in ("once", "repeat", "reversals"):
    sys.exit(f"jsbsim_flight.py: mode {mode!r}: expected repeat or reversals")
aileron = float(sys.argv[4]) if len(sys.argv) > 4 else 0.3
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
    if mode == "reversals":
        target = 0.0 if t < 1.0 else (1.0 if int((t - 1.0) // 3.0) % 2 == 0 else -1.0) * math.radians(45)
        phi, p = fdm["attitude/phi-rad"], fdm["velocities/p-rad_sec"]
        fdm["fcs/aileron-cmd-norm"] = max(-aileron, min(aileron, 2.0 * (target - phi) - 0.5 * p))
        fdm["fcs/elevator-cmd-norm"] = -0.05 * min(1.0, abs(phi) / 0.8)
    elif mode == "repeat":
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
