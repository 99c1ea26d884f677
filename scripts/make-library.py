#!/usr/bin/env python3
"""The flight library (issue #23): short JSBSim flights of the manoeuvres simulator engineers
judge motion cueing on, written as hexcue traces with their sidecars and signal pictures.

    python3 -m venv target/venv
    target/venv/bin/pip install jsbsim==1.3.3 numpy matplotlib
    target/venv/bin/python scripts/make-library.py [--seed 23] [--out recordings/traces/library] [--only NAME,...]

Everything a flight does comes from its seed (turbulence, runway roughness, gust shapes):
the same seed, JSBSim version and script give the same files. The aircraft are the jsbsim
package's own c172p, 737 and f16, copied into target/jsbsim-root with three edits that leave
their dynamics untouched: the 737's network <input port=...> elements are removed (they open
sockets), an external rolling moment `external_reactions/wake` is declared (zero unless a flight
sets it: the wake encounter) and the 737's yaw damper is gated by `fcs/yaw-damper-enable`
(1 except in the Dutch roll, where the damper is off so that the mode shows).

Conventions (exactly those of the shipped traces, docs/formats.md): t,fx,fy,fz,p,q,r,phi,theta,psi
at 100 Hz; f = accelerations/a-pilot-{x,y,z}-ft_sec2 x 0.3048 (specific force at the eyepoint,
body axes x forward, y right, z down; level flight gives (0,0,-9.81)); p,q,r in rad/s; attitude
in rad, psi unwrapped. JSBSim computes a-pilot from the previous frame's accelerations (its
Auxiliary model runs before the Accelerations model in a frame), so the a-pilot read after
frame k+1 belongs to the state after frame k: each row is re-aligned by one integration step,
and every flight checks that against the specific force rebuilt from that frame's total forces,
mass and angular accelerations (`crosscheck_*` in the sidecar).
"""

import argparse
import json
import math
import os
import platform
import re
import shutil
import sys

import jsbsim
import numpy as np

FT = 0.3048
KT = 1.68781  # ft/s per knot
G_FPS2 = 32.174
DT = 1.0 / 200.0  # JSBSim's integration step; every 2nd is written (100 Hz)
COLUMNS = ["t", "fx", "fy", "fz", "p", "q", "r", "phi", "theta", "psi"]
UNITS = {"t": "s", "fx": "m/s^2", "fy": "m/s^2", "fz": "m/s^2", "p": "rad/s", "q": "rad/s",
         "r": "rad/s", "phi": "rad", "theta": "rad", "psi": "rad"}
CONVENTIONS = (
    "Body axes x forward, y right, z down. f = specific force (non-gravitational acceleration) at "
    "the pilot eyepoint = JSBSim accelerations/a-pilot-{x,y,z}-ft_sec2 * 0.3048, re-aligned by one "
    "integration step; level 1 g flight gives (0,0,-9.81). p,q,r = velocities/{p,q,r}-rad_sec. "
    "phi,theta,psi = attitude/*-rad, psi unwrapped (continuous).")
EYEPOINT_IN = {"c172p": (37.0, 0.0, 48.0), "737": (80.0, -30.0, 70.0), "f16": (-336.2, 0.0, 29.5)}


def clip(x, lo=-1.0, hi=1.0):
    return max(lo, min(hi, x))


def wrap(a):
    return math.atan2(math.sin(a), math.cos(a))


def smooth_step(x):
    """0 before 0, 1 after 1, a smooth ramp between (a pilot's input has no corner)."""
    x = clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def pulse(t, start, length, ramp=0.3):
    return smooth_step((t - start) / ramp) - smooth_step((t - start - length) / ramp)


# --- the aircraft, copied and edited (dynamics untouched) --------------------------------------

def make_root(root):
    src = os.path.dirname(jsbsim.__file__)
    if os.path.exists(root):
        shutil.rmtree(root)
    for d in ["engine", "systems"]:
        shutil.copytree(os.path.join(src, d), os.path.join(root, d))
    wake = ("\n <external_reactions>\n  <moment name=\"wake\" frame=\"BODY\">\n"
            "   <direction><x>1</x><y>0</y><z>0</z></direction>\n  </moment>\n"
            " </external_reactions>\n")
    for ac in ["c172p", "737", "f16"]:
        shutil.copytree(os.path.join(src, "aircraft", ac), os.path.join(root, "aircraft", ac))
        path = os.path.join(root, "aircraft", ac, ac + ".xml")
        x = open(path).read()
        # Data logs the models declare would be written into the working directory.
        x = re.sub(r"<output\s[^>]*>.*?</output>", "", x, flags=re.S)
        if ac == "737":
            x = re.sub(r"<input port=\"\d+\"\s*/>", "", x)
            x = re.sub(r"<input port=\"\d+\"[^>]*>.*?</input>", "", x, flags=re.S)
            x = x.replace("<input>fcs/yaw-damper</input>",
                          "<input>fcs/yaw-damper</input>\n                <gain>fcs/yaw-damper-enable</gain>", 1)
        if "<external_reactions>" in x:
            moment = wake.split("<external_reactions>", 1)[1].split("</external_reactions>")[0]
            x = x.replace("<external_reactions>", "<external_reactions>" + moment, 1)
        else:
            x = x.replace("<propulsion>", wake + "\n <propulsion>", 1)
        open(path, "w").write(x)


# --- one flight ------------------------------------------------------------------------------

class Flight:
    def __init__(self, root, name, aircraft, kind, scenario, seed):
        self.name, self.aircraft, self.kind, self.scenario, self.seed = name, aircraft, kind, scenario, seed
        self.rng = np.random.default_rng(seed)
        self.fdm = jsbsim.FGFDMExec(root)
        self.fdm.set_debug_level(0)
        if not self.fdm.load_model(aircraft):
            raise SystemExit(f"{name}: JSBSim could not load {aircraft}")
        self.fdm.set_dt(DT)
        self.events = []
        self.rows = []  # 200 Hz: state after each frame
        self.extra = {}
        self.t0 = None  # sim time at which recording starts
        self.roughness = None
        self.ground_ft = 0.0
        self.dist_ft = 0.0

    def __getitem__(self, k):
        return self.fdm[k]

    def __setitem__(self, k, v):
        self.fdm[k] = v

    def ic(self, **kw):
        for k, v in kw.items():
            self.fdm["ic/" + k.replace("__", "-")] = v

    def start(self, trim=None):
        if self.aircraft == "737":
            self.fdm["fcs/yaw-damper-enable"] = 1.0
        self.fdm.run_ic()
        self.fdm["propulsion/set-running"] = -1
        if self.aircraft == "c172p":
            self.fdm["fcs/mixture-cmd-norm"] = 1.0
        if trim is not None:
            try:
                self.fdm["simulation/do_simple_trim"] = trim
            except jsbsim.TrimFailureError:
                pass  # the controllers settle what the trim could not

    @property
    def t(self):
        """Trace time: 0 when recording starts (negative while settling)."""
        return self.fdm.get_sim_time() - (self.t0 if self.t0 is not None else 1e9)

    def rough_runway(self, rms_m, seed, wavelengths_m=(1.5, 40.0), elevation_ft=None):
        """A seeded terrain-elevation profile under the wheels (JSBSim's own ground bumpiness
        only acts inside FlightGear): a sum of sines over the wavelength band, scaled to rms_m."""
        rng = np.random.default_rng(seed)
        k = 2 * math.pi / np.geomspace(wavelengths_m[0], wavelengths_m[1], 60)  # rad/m
        amp = k ** -1.0  # rougher at long wavelengths, as a runway's spectrum
        phase = rng.uniform(0, 2 * math.pi, k.size)
        amp *= rms_m / math.sqrt(0.5 * np.sum(amp ** 2))
        self.roughness = (k, amp, phase)
        self.extra["runway_roughness"] = {"rms_m": rms_m, "wavelength_m": list(wavelengths_m), "seed": seed}
        self.ground_ft = self.fdm["position/terrain-elevation-asl-ft"] if elevation_ft is None else elevation_ft

    def turbulence(self, severity, w20_kt, seed):
        self.fdm["atmosphere/turb-type"] = 4
        self.fdm["atmosphere/turbulence/milspec/severity"] = severity
        self.fdm["atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps"] = w20_kt * KT
        self.fdm["atmosphere/randomseed"] = seed
        self.extra["turbulence"] = {"turb_type": 4, "severity": severity, "w20_fps": round(w20_kt * KT, 2),
                                    "randomseed": seed}

    def event(self, text):
        self.events.append({"t": round(self.t, 2), "event": text})

    def step(self):
        if self.roughness is not None:
            gs = math.hypot(self.fdm["velocities/v-north-fps"], self.fdm["velocities/v-east-fps"])
            self.dist_ft += gs * DT
            k, amp, phase = self.roughness
            h_m = float(np.sum(amp * np.sin(k * self.dist_ft * FT + phase)))
            self.fdm["position/terrain-elevation-asl-ft"] = self.ground_ft + h_m / FT
        if not self.fdm.run():
            raise SystemExit(f"{self.name}: JSBSim stopped at t={self.t:.2f}")
        if self.t0 is not None:
            f = self.fdm
            self.rows.append([
                f["accelerations/a-pilot-x-ft_sec2"], f["accelerations/a-pilot-y-ft_sec2"],
                f["accelerations/a-pilot-z-ft_sec2"],
                f["velocities/p-rad_sec"], f["velocities/q-rad_sec"], f["velocities/r-rad_sec"],
                f["attitude/phi-rad"], f["attitude/theta-rad"], f["attitude/psi-rad"],
                # for the cross-check: specific force at the CG and angular acceleration
                f["forces/fbx-total-lbs"], f["forces/fby-total-lbs"], f["forces/fbz-total-lbs"],
                f["inertia/mass-slugs"],
                f["accelerations/pdot-rad_sec2"], f["accelerations/qdot-rad_sec2"],
                f["accelerations/rdot-rad_sec2"],
                f["inertia/cg-x-in"], f["inertia/cg-y-in"], f["inertia/cg-z-in"],
            ])

    def record(self):
        self.t0 = self.fdm.get_sim_time()

    def run_until(self, t_end, control):
        while self.t < t_end + 0.02 - 1e-9:  # two frames more: the re-alignment needs them
            control(self.t)
            self.step()

    def settle(self, seconds, control):
        """Runs before the recording starts (trim transients, gear settling on the ground)."""
        end = self.fdm.get_sim_time() + seconds
        while self.fdm.get_sim_time() < end - 1e-9:
            control(-1.0)
            self.step()

    # ---- what a pilot does, as simple loops on the state --------------------------------------
    def agl(self):
        return self.fdm["position/h-agl-ft"]

    def kcas(self):
        return self.fdm["velocities/vc-kts"]

    def write(self, out_dir, duration_s):
        a = np.array(self.rows)
        need = int(round(duration_s / DT)) + 2
        if len(a) < need:
            raise SystemExit(f"{self.name}: {len(a)} frames recorded, {need} needed")
        ep = np.array(EYEPOINT_IN[self.aircraft])
        # Eyepoint relative to the CG in body axes (structural x aft, z up; body x fwd, z down), ft.
        r = np.stack([-(ep[0] - a[:, 16]), ep[1] - a[:, 17], -(ep[2] - a[:, 18])], axis=1) / 12.0
        w, wdot = a[:, 3:6], a[:, 13:16]
        f_cg = a[:, 9:12] / a[:, 12:13]
        rebuilt = f_cg + np.cross(wdot, r) + np.cross(w, np.cross(w, r))
        apilot = a[:, 0:3]
        n = need - 1
        diff_aligned = np.abs(apilot[1:n + 1] - rebuilt[0:n]).max() * FT
        diff_same = np.abs(apilot[0:n] - rebuilt[0:n]).max() * FT
        if not diff_aligned < diff_same:
            raise SystemExit(f"{self.name}: a-pilot alignment check failed ({diff_aligned} vs {diff_same})")
        # Touchdowns on stiff JSBSim gear give single-step peaks of 4-6 g; a crash gives more.
        limit_g = 10.0 if self.aircraft == "f16" else 7.0
        if np.abs(apilot[1:n + 1] * FT).max() > limit_g * 9.80665:
            raise SystemExit(f"{self.name}: specific force beyond {limit_g} g: the flight went wrong")
        idx = np.arange(0, n, 2)
        f = apilot[idx + 1] * FT
        rates = a[idx, 3:6]
        att = a[idx, 6:9].copy()
        att[:, 2] = np.unwrap(att[:, 2])
        t = idx * DT
        rows = np.column_stack([t, f, rates, att])
        rows = rows[: int(round(duration_s * 100))]
        with open(os.path.join(out_dir, self.name + ".csv"), "w") as fh:
            fh.write(",".join(COLUMNS) + "\n")
            for row in rows:
                fh.write(f"{row[0]:.2f}," + ",".join(f"{v:.6f}" for v in row[1:]) + "\n")
        sidecar = {
            "name": self.name,
            "aircraft": self.aircraft,
            "kind": self.kind,
            "scenario": self.scenario,
            "duration_s": round(len(rows) / 100.0, 2),
            "n_samples": len(rows),
            "sample_rate_hz": 100,
            "jsbsim_internal_rate_hz": 200,
            "resampling": "JSBSim run at 200 Hz; every 2nd integration step written (exact 10 ms grid, no interpolation, no filtering)",
            "jsbsim_version": jsbsim.__version__,
            "python_version": platform.python_version(),
            "numpy_version": np.__version__,
            "command": COMMAND,
            "aircraft_source": f"jsbsim package data aircraft/{self.aircraft}/{self.aircraft}.xml (edits: see scripts/make-library.py; dynamics untouched)",
            "generator": "scripts/make-library.py",
            "columns": COLUMNS,
            "units": UNITS,
            "conventions": CONVENTIONS,
            "eyepoint_in": {"x": ep[0], "y": ep[1], "z": ep[2],
                            "frame": "JSBSim structural (x aft, y right, z up), inches"},
            "seed": self.seed,
            "events": [e for e in self.events if 0 <= e["t"] <= duration_s],
            "crosscheck_max_abs_diff_specific_force_m_s2": float(diff_aligned),
            "crosscheck_without_realignment_m_s2": float(diff_same),
        }
        sidecar.update(self.extra)
        with open(os.path.join(out_dir, self.name + ".json"), "w") as fh:
            json.dump(sidecar, fh, indent=2)
            fh.write("\n")
        picture(os.path.join(out_dir, self.name + ".png"), rows, sidecar)
        return rows


def picture(path, rows, sidecar):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    t = rows[:, 0]
    for i, lab in enumerate(["fx", "fy", "fz"]):
        axes[0].plot(t, rows[:, 1 + i], lw=0.7, label=lab)
    axes[0].set_ylabel("specific force (m/s²)")
    for i, lab in enumerate(["p", "q", "r"]):
        axes[1].plot(t, np.degrees(rows[:, 4 + i]), lw=0.7, label=lab)
    axes[1].set_ylabel("body rates (°/s)")
    for i, lab in enumerate(["phi", "theta", "psi"]):
        axes[2].plot(t, np.degrees(rows[:, 7 + i]), lw=0.7, label=lab)
    axes[2].set_ylabel("attitude (°)")
    axes[2].set_xlabel("t (s)")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=7)
        for e in sidecar["events"]:
            ax.axvline(e["t"], color="k", lw=0.5, ls=":")
    for e in sidecar["events"]:
        axes[0].annotate(e["event"][:40], (e["t"], 1.0), xycoords=("data", "axes fraction"),
                         fontsize=6, rotation=90, va="top", ha="right")
    fig.suptitle(f"{sidecar['name']} ({sidecar['aircraft']})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


COMMAND = "python scripts/make-library.py"

GAINS = {
    # aileron per rad of bank error and per rad/s of roll rate; elevator per rad of pitch error
    # and per rad/s of pitch rate; rudder per rad of sideslip (positive rudder yaws nose-left).
    "c172p": dict(kphi=1.5, kp=0.4, kth=3.0, kq=0.8, kbeta=2.0, kthr=0.05),
    "737": dict(kphi=2.0, kp=1.0, kth=4.0, kq=2.0, kbeta=3.0, kthr=0.03),
    # The F-16's flight control system takes roll-rate and load-factor commands.
    "f16": dict(kphi=0.6, kp=0.05, kth=1.0, kq=0.3, kbeta=0.0, kthr=0.02),
}


class Pilot:
    def __init__(self, f):
        self.f = f
        self.g = GAINS[f.aircraft]
        self.thr = f["fcs/throttle-cmd-norm"]

    def fly(self, phi_t, theta_t, ail=0.0, elev=0.0, rud=0.0, coordinate=True):
        f, g = self.f, self.g
        a = g["kphi"] * (phi_t - f["attitude/phi-rad"]) - g["kp"] * f["velocities/p-rad_sec"]
        e = -(g["kth"] * (theta_t - f["attitude/theta-rad"]) - g["kq"] * f["velocities/q-rad_sec"])
        r = -g["kbeta"] * f["aero/beta-rad"] if coordinate else 0.0
        f["fcs/aileron-cmd-norm"] = clip(a + ail)
        f["fcs/elevator-cmd-norm"] = clip(e + elev)
        f["fcs/rudder-cmd-norm"] = clip(r + rud)

    def throttle(self, value):
        self.thr = clip(value, 0.0, 1.0)
        for i in range(2 if self.f.aircraft == "737" else 1):
            self.f[f"fcs/throttle-cmd-norm[{i}]"] = self.thr

    def hold_speed(self, kcas):
        """Proportional on the speed error around the trimmed throttle, plus a slow integral."""
        if not hasattr(self, "thr0"):
            self.thr0, self.thr_i = self.thr, 0.0
        err = kcas - self.f.kcas()
        self.thr_i += 0.002 * err * DT
        self.throttle(self.thr0 + self.g["kthr"] * err + self.thr_i)

    def theta_for_climb(self, theta0, h_t, k=0.002, kv=0.004):
        """Pitch attitude that holds altitude h_t: proportional on altitude and climb rate."""
        f = self.f
        return theta0 + clip(k * (h_t - f["position/h-sl-ft"]) - kv * f["velocities/h-dot-fps"], -0.15, 0.15)

    def brakes(self, v):
        self.f["fcs/left-brake-cmd-norm"] = v
        self.f["fcs/right-brake-cmd-norm"] = v
        self.f["fcs/center-brake-cmd-norm"] = v

    def steer(self, psi_t, k=3.0, kr=1.0):
        """Rudder and nose wheel on the runway heading."""
        f = self.f
        err = wrap(psi_t - f["attitude/psi-rad"])
        cmd = clip(-(k * err - kr * f["velocities/r-rad_sec"]))
        f["fcs/rudder-cmd-norm"] = cmd
        # Positive rudder yaws the nose left; a positive nose-wheel command steers right.
        f["fcs/steer-cmd-norm"] = -cmd
        return cmd


def airborne(f, h_ft, kcas, psi_deg=90.0, gamma_deg=0.0, trim=1):
    f.ic(h__sl__ft=h_ft, vc__kts=kcas, psi__true__deg=psi_deg, gamma__deg=gamma_deg,
         lat__geod__deg=37.6, long__gc__deg=-122.4)
    f.start(trim=trim)
    p = Pilot(f)
    return p


def on_runway(f, elevation_ft=433.0, psi_deg=90.0):
    f.ic(lat__geod__deg=37.6, long__gc__deg=-122.4, psi__true__deg=psi_deg, terrain__elevation__ft=elevation_ft,
         h__agl__ft=f_gear_height(f.aircraft), vc__kts=0.0, theta__deg=0.0)
    f.start()
    p = Pilot(f)
    p.throttle(0.0)
    return p


def f_gear_height(ac):
    return {"c172p": 4.5, "737": 8.0, "f16": 7.0}[ac]


# --- the flights ----------------------------------------------------------------------------

def takeoff(f, p, vr, v2_theta, duration, fail_at=None, reject_at=None, ab=False, flaps=None):
    """Ground roll on the centre line, rotation at vr, climb at v2_theta; optionally an engine
    failure (737: engine 1) or a rejected take-off at the given KCAS."""
    psi0 = f["attitude/psi-rad"]
    st = {"phase": "hold", "failed": False}
    if flaps is not None:
        f["fcs/flap-cmd-norm"] = flaps

    def c(t):
        if st["phase"] == "hold":
            p.brakes(1.0)
            p.throttle(1.0 if t >= 0 else 0.0)
            p.steer(psi0)
            f["fcs/elevator-cmd-norm"] = 0.0
            if ab:
                f["fcs/throttle-cmd-norm"] = 1.0 if t >= 0 else 0.0
            if t >= 2.0:
                st["phase"] = "roll"
                p.brakes(0.0)
                f.event("brakes released, take-off thrust" + (" (full afterburner)" if ab else ""))
            return
        v = f.kcas()
        if reject_at is not None and st["phase"] == "roll" and v >= reject_at:
            st["phase"] = "reject"
            f.event(f"take-off rejected at {v:.0f} KCAS: thrust idle, maximum braking, spoilers")
        if st["phase"] == "reject":
            p.throttle(0.0)
            p.brakes(1.0)
            f["fcs/spoiler-cmd-norm"] = 1.0
            f["fcs/speedbrake-cmd-norm"] = 1.0
            f["fcs/elevator-cmd-norm"] = 0.3
            p.steer(psi0)
            if v < 3 and "stopped" not in st:
                st["stopped"] = True
                f.event("stopped")
            return
        if fail_at is not None and not st["failed"] and v >= fail_at:
            st["failed"] = True
            f["propulsion/engine[0]/set-running"] = 0
            f.event(f"left engine fails at {v:.0f} KCAS (after V1): the take-off continues")
        rud_bias = 0.0
        if st["failed"]:
            f["fcs/throttle-cmd-norm[0]"] = 0.0
        if st["phase"] == "roll":
            p.steer(psi0, k=4.0 if st["failed"] else 3.0)
            f["fcs/elevator-cmd-norm"] = 0.0
            if v >= vr:
                st["phase"] = "rotate"
                st["t_rot"] = t
                f.event(f"rotate at {v:.0f} KCAS")
        elif st["phase"] in ("rotate", "climb"):
            if st["phase"] == "rotate" and f["gear/unit[1]/WOW"] == 0 and f["gear/unit[2]/WOW"] == 0:
                st["phase"] = "climb"
                f.event(f"lift-off at {f.kcas():.0f} KCAS")
            theta_t = min(v2_theta, 0.05 + 0.05 * (t - st["t_rot"]))  # about 2.3 deg/s rotation
            if st["failed"]:
                # Rudder against the yaw of the live engine, wings nearly level (5 deg into it).
                err = wrap(psi0 - f["attitude/psi-rad"])
                rud_bias = clip(-(2.0 * err - 1.5 * f["velocities/r-rad_sec"]))
                p.fly(math.radians(3.0) if st["phase"] == "climb" else 0.0, theta_t, rud=rud_bias, coordinate=False)
                f["fcs/steer-cmd-norm"] = -rud_bias
            else:
                p.fly(0.0, theta_t, coordinate=st["phase"] == "climb")
                if st["phase"] == "rotate":
                    p.steer(psi0)
            if st["phase"] == "climb" and f.agl() > 35 and "gear" not in st:
                st["gear"] = True
                f["gear/gear-cmd-norm"] = 0.0
                f.event("positive climb, gear up")
    f.record()
    f.run_until(duration, c)


def cruise_turbulence(f, p, h, theta0, duration):
    psi0 = f["attitude/psi-rad"]

    def c(t):
        phi_t = clip(1.0 * wrap(psi0 - f["attitude/psi-rad"]), -0.2, 0.2)
        p.fly(phi_t, p.theta_for_climb(theta0, h))
        p.hold_speed(f.v_target)
    f.record()
    f.event("turbulence active throughout (Tustin/Dryden), autopilot holds altitude, heading, speed")
    f.run_until(duration, c)


SCENARIOS = {}


def scenario(name, aircraft, kind, duration, text):
    def wrap(fn):
        SCENARIOS[name] = (fn, aircraft, kind, duration, text)
        return fn
    return wrap


@scenario("737-takeoff", "737", "ground", 50.0,
          "Boeing 737 normal take-off, flaps 5: 2 s at take-off thrust on the brakes, brake release, ground roll on the centre line (rudder and nose wheel), rotation at 140 KCAS to 15 deg, lift-off, gear up. Runway roughness RMS 4 mm.")
def _(f, seed, d):
    p = on_runway(f)
    f.rough_runway(0.004, seed + 1)
    p.brakes(1.0)
    f.settle(3.0, lambda t: None)
    takeoff(f, p, vr=140, v2_theta=math.radians(15), duration=d, flaps=0.25)


@scenario("737-rejected-takeoff", "737", "ground", 40.0,
          "Boeing 737 rejected take-off: take-off thrust, ground roll, abort at 120 KCAS (before V1): thrust to idle, maximum braking, ground spoilers, to a stop on the centre line. Sustained deceleration of about 0.4 g. Runway roughness RMS 4 mm.")
def _(f, seed, d):
    p = on_runway(f)
    f.rough_runway(0.004, seed + 1)
    p.brakes(1.0)
    f.settle(3.0, lambda t: None)
    takeoff(f, p, vr=999, v2_theta=0.2, duration=d, reject_at=120, flaps=0.25)


@scenario("737-engine-failure-v1", "737", "ground", 55.0,
          "Boeing 737 engine failure after V1: take-off thrust, at 135 KCAS the left engine fails; the take-off continues with rudder against the asymmetric thrust, rotation at 145 KCAS, climb at 12 deg with the wings 3 deg into the live engine. Runway roughness RMS 4 mm.")
def _(f, seed, d):
    p = on_runway(f)
    f.rough_runway(0.004, seed + 1)
    p.brakes(1.0)
    f.settle(3.0, lambda t: None)
    takeoff(f, p, vr=145, v2_theta=math.radians(12), duration=d, fail_at=135, flaps=0.25)


@scenario("f16-afterburner-takeoff", "f16", "ground", 35.0,
          "F-16 maximum-afterburner take-off: on the brakes, brake release at full afterburner (about 0.7 g of sustained forward acceleration, beyond what tilt coordination can give), rotation at 150 KCAS to 12 deg, gear up, accelerating climb.")
def _(f, seed, d):
    p = on_runway(f)
    f.rough_runway(0.003, seed + 1)
    p.brakes(1.0)
    f.settle(3.0, lambda t: None)
    takeoff(f, p, vr=150, v2_theta=math.radians(12), duration=d, ab=True)


def turb_flight(name, ac, h, kcas, severity, w20, text):
    @scenario(name, ac, "turbulence", 60.0, text)
    def _(f, seed, d):
        p = airborne(f, h, kcas)
        f.v_target = kcas
        theta0 = f["attitude/theta-rad"]
        f.turbulence(severity, w20, seed + 2)
        f.settle(2.0, lambda t: p.fly(0.0, theta0))
        cruise_turbulence(f, p, h, theta0, d)


turb_flight("737-turbulence-light", "737", 3000, 220, 3, 15,
            "Boeing 737 at 3000 ft, 220 KCAS in light turbulence: Tustin-discretised Dryden model (turb-type 4), MIL-F-8785C severity 3, W20 = 15 kt, seeded; an autopilot holds altitude, heading and speed.")
turb_flight("c172p-turbulence-moderate", "c172p", 2500, 100, 4, 30,
            "Cessna 172 at 2500 ft, 100 KCAS in moderate turbulence: Tustin-discretised Dryden model (turb-type 4), MIL-F-8785C severity 4, W20 = 30 kt, seeded; a light-handed autopilot holds altitude, heading and speed.")
turb_flight("737-turbulence-severe", "737", 3000, 250, 6, 45,
            "Boeing 737 at 3000 ft, 250 KCAS in severe turbulence: Tustin-discretised Dryden model (turb-type 4), MIL-F-8785C severity 6, W20 = 45 kt, seeded; an autopilot holds altitude, heading and speed.")


# --- approaches and landings ----------------------------------------------------------------

APPROACH = {
    # approach speed (KCAS), flaps, flare height (ft above touchdown), flare pitch (rad), gear height (ft)
    "c172p": dict(v=65, flaps=0.33, flare=12, theta_flare=0.10, gear=4.5),
    "737": dict(v=140, flaps=0.75, flare=35, theta_flare=0.08, gear=8.0),
}


def approach(f, duration, h0_agl=300.0, gs_deg=3.0, crosswind_kt=0.0, hard=False, go_around_agl=None,
             shear=None, roughness_mm=3.0):
    """A stabilised approach from h0_agl on a gs_deg glide path to the runway (heading 090),
    flare, touchdown, roll-out; or a go-around; or a microburst and its escape."""
    a = APPROACH[f.aircraft]
    elev = 433.0
    f["fcs/flap-cmd-norm"] = a["flaps"]
    f["gear/gear-cmd-norm"] = 1.0
    f.ic(lat__geod__deg=37.6, long__gc__deg=-122.4, psi__true__deg=90.0, terrain__elevation__ft=elev,
         h__agl__ft=h0_agl, vc__kts=a["v"], gamma__deg=-gs_deg)
    f.start(trim=1)
    p = Pilot(f)
    if crosswind_kt:
        # From the north, across the 090 runway: the air moves south. Set after the trim,
        # which would otherwise trim it away; the settling below lets the crab establish.
        f["atmosphere/wind-north-fps"] = -crosswind_kt * KT
        f.extra["wind"] = {"from_deg": 360, "speed_kt": crosswind_kt}
    f.rough_runway(roughness_mm / 1000.0, f.seed + 1, elevation_ft=elev)
    theta0 = f["attitude/theta-rad"]
    psi_rwy = math.radians(90.0)
    vs0 = f["velocities/h-dot-fps"]
    st = {"phase": "approach", "y": 0.0, "vs": vs0}

    def lateral():
        st["y"] += f["velocities/v-north-fps"] * DT  # left of the centre line is north
        return clip(0.002 * st["y"] + 0.06 * f["velocities/v-north-fps"], -0.35, 0.35)

    def c(t):
        agl = f.agl() - a["gear"]
        phase = st["phase"]
        if shear is not None:
            shear(t, st)
        if phase == "approach":
            st["h_plan"] += vs0 * DT
            theta_t = theta0 + clip(0.01 * (st["h_plan"] - f.agl()) - 0.02 * (f["velocities/h-dot-fps"] - vs0), -0.12, 0.15)
            p.fly(lateral(), theta_t)
            p.hold_speed(a["v"])
            if go_around_agl is not None and agl < go_around_agl:
                st["phase"] = "go-around"
                f.event(f"go-around at {agl + 0:.0f} ft: take-off/go-around thrust, pitch 15 deg, flaps 15")
                f["fcs/flap-cmd-norm"] = 0.5
            elif st.get("escape"):
                st["phase"] = "escape"
            elif agl < a["flare"] * (0.25 if hard else 1.0):
                st["phase"] = "flare"
                st["t_flare"] = t
                f.event(f"flare at {agl:.0f} ft, thrust idle" + (" (late: hard landing)" if hard else ""))
                if crosswind_kt:
                    f.event("de-crab: rudder aligns the nose with the runway, wing down into the wind")
        if phase == "flare":
            p.throttle(0.0)
            theta_t = theta0 + (a["theta_flare"] - theta0) * smooth_step((t - st["t_flare"]) / 2.0)
            rud = 0.0
            if crosswind_kt:
                rud = clip(-(3.0 * wrap(psi_rwy - f["attitude/psi-rad"]) - 1.0 * f["velocities/r-rad_sec"]))
            p.fly(lateral(), theta_t if not hard else theta0 + 0.02, rud=rud, coordinate=not crosswind_kt)
            st["vs"] = f["velocities/h-dot-fps"]
            if f["gear/unit[1]/WOW"] or f["gear/unit[2]/WOW"]:
                st["phase"] = "rollout"
                st["t_td"] = t
                f.event(f"main gear touchdown, sink rate {-st['vs']:.1f} ft/s, {f.kcas():.0f} KCAS")
        if phase == "rollout":
            p.throttle(0.0)
            theta_t = 0.0 if t - st["t_td"] > 2.0 else f["attitude/theta-rad"]
            p.fly(0.0, theta_t, coordinate=False)
            p.steer(psi_rwy)
            if f.aircraft == "737":
                f["fcs/spoiler-cmd-norm"] = 1.0
                f["fcs/speedbrake-cmd-norm"] = 1.0
            # Brakes off before the stop: JSBSim's gear friction at rest under braking gives
            # forces no aircraft has (a steady 0.5 g forward while standing still).
            slow = f["velocities/vg-fps"] < 30 * KT
            if t - st["t_td"] > 3.0 and not slow:
                if "brakes" not in st:
                    st["brakes"] = True
                    f.event("brakes applied")
                p.brakes(0.4)
            elif slow:
                if "slow" not in st and "brakes" in st:
                    st["slow"] = True
                    f.event("brakes released at 30 kt, taxi speed")
                p.brakes(0.0)
        if phase in ("go-around", "escape"):
            p.throttle(1.0)
            st.setdefault("t_up", (t, f["attitude/theta-rad"]))
            theta_t = min(math.radians(15), st["t_up"][1] + 0.04 * (t - st["t_up"][0]))
            p.fly(lateral(), theta_t)
            if f["velocities/h-dot-fps"] > 5 and "gear_up" not in st and phase == "go-around":
                st["gear_up"] = True
                f["gear/gear-cmd-norm"] = 0.0
                f.event("positive climb, gear up")
    # The flaps run out after the trim: settle on the glide path before recording.
    st["h_plan"] = f.agl()

    def settle(t):
        st["h_plan"] += vs0 * DT
        p.fly(lateral(), theta0 + clip(0.01 * (st["h_plan"] - f.agl()) - 0.02 * (f["velocities/h-dot-fps"] - vs0), -0.12, 0.15))
        p.hold_speed(a["v"])
    f.settle(8.0, settle)
    f.record()
    f.run_until(duration, c)


@scenario("c172p-crosswind-landing", "c172p", "approach", 55.0,
          "Cessna 172 approach and landing in a 12 kt direct crosswind from the left (runway 090, wind 360/12): flaps 10, 65 KCAS on a 3 deg path from 250 ft, crabbed into the wind on the centre line; at the flare the pilot de-crabs with rudder and lowers the upwind wing; touchdown, roll-out with brakes. Runway roughness RMS 3 mm.")
def _(f, seed, d):
    approach(f, d, h0_agl=250.0, crosswind_kt=12.0)


@scenario("737-crosswind-landing", "737", "approach", 50.0,
          "Boeing 737 approach and landing in a 20 kt direct crosswind from the left (runway 090, wind 360/20): flaps 30, 140 KCAS on a 3 deg path from 400 ft, crabbed on the centre line; de-crab in the flare with rudder, wing down into the wind; touchdown, spoilers, brakes. Runway roughness RMS 3 mm.")
def _(f, seed, d):
    approach(f, d, h0_agl=400.0, crosswind_kt=20.0)


@scenario("737-hard-landing", "737", "approach", 40.0,
          "Boeing 737 hard landing: a steep 4 deg approach at 140 KCAS, flaps 30, from about 300 ft and a late, insufficient flare with thrust to idle, touching down at a high sink rate; spoilers, brakes and roll-out. Runway roughness RMS 3 mm.")
def _(f, seed, d):
    approach(f, d, h0_agl=380.0, gs_deg=4.0, hard=True)


@scenario("737-go-around", "737", "approach", 45.0,
          "Boeing 737 go-around: stabilised approach at 140 KCAS, flaps 30, from 500 ft; at 150 ft take-off/go-around thrust, pitch to 15 deg, flaps 15, gear up on a positive climb.")
def _(f, seed, d):
    approach(f, d, h0_agl=500.0, go_around_agl=150.0)


@scenario("737-windshear-approach", "737", "approach", 45.0,
          "Boeing 737 microburst windshear on a 3 deg approach at 140 KCAS from about 1200 ft: a 25 kt headwind builds over 5 s (airspeed gain), then a 15 ft/s downdraft and a 30 kt tailwind (airspeed loss, sink); at the warning the pilot flies the escape: take-off/go-around thrust, pitch 15 deg, wings level.")
def _(f, seed, d):
    def shear(t, st):
        head = 25.0 * smooth_step((t - 8.0) / 5.0) - 55.0 * smooth_step((t - 14.0) / 8.0)
        down = 15.0 * (smooth_step((t - 13.0) / 4.0) - smooth_step((t - 26.0) / 6.0))
        f["atmosphere/wind-east-fps"] = -head * KT  # a headwind on 090 moves the air west
        f["atmosphere/wind-down-fps"] = down
        if t >= 8.0 and "shear" not in st:
            st["shear"] = True
            f.event("microburst: headwind builds (25 kt over 5 s)")
        if t >= 14.0 and "down" not in st:
            st["down"] = True
            f.event("downdraft 15 ft/s and shift to a 30 kt tailwind")
        if t >= 17.0 and not st.get("escape"):
            st["escape"] = True
            f.event("windshear warning: escape manoeuvre (TOGA thrust, pitch 15 deg)")
    f.extra["windshear"] = {"headwind_kt": 25, "tailwind_kt": 30, "downdraft_fps": 15}
    approach(f, d, h0_agl=1300.0, shear=shear)


# --- ground ---------------------------------------------------------------------------------

@scenario("c172p-rough-taxi", "c172p", "ground", 50.0,
          "Cessna 172 taxiing over rough ground (a grass strip: seeded terrain profile RMS 25 mm, wavelengths 0.8-20 m) at about 12 kt, with a 90 deg turn to the right at t = 20 s and back at t = 36 s; throttle and brakes hold the speed.")
def _(f, seed, d):
    p = on_runway(f)
    f.rough_runway(0.025, seed + 1, wavelengths_m=(0.8, 20.0))
    p.brakes(1.0)
    f.settle(3.0, lambda t: None)
    st = {}

    def c(t):
        psi_t = math.radians(90.0 + 90.0 * (smooth_step((t - 20.0) / 4.0) - smooth_step((t - 36.0) / 4.0)))
        p.brakes(0.0 if t > 1.0 else 1.0)
        v = f["velocities/vg-fps"] / KT
        err = 12.0 - v
        p.throttle(clip(0.25 + 0.05 * err, 0.0, 0.6))
        if err < -3:
            p.brakes(0.3)
        p.steer(psi_t, k=2.0, kr=0.5)
        f["fcs/elevator-cmd-norm"] = -0.2  # stick back on rough ground
        if t >= 1.0 and "go" not in st:
            st["go"] = True
            f.event("brakes off, taxi at 12 kt over rough ground")
        for tt, txt in [(20.0, "turn 90 deg right"), (36.0, "turn back left")]:
            if t >= tt and tt not in st:
                st[tt] = True
                f.event(txt)
    f.record()
    f.run_until(d, c)


# --- airborne manoeuvres -----------------------------------------------------------------------

def manoeuvre(f, d, h, kcas, control, kind_note=None):
    p = airborne(f, h, kcas)
    theta0 = f["attitude/theta-rad"]
    f.v_target = kcas
    f.settle(2.0, lambda t: p.fly(0.0, theta0))
    f.record()
    f.run_until(d, lambda t: control(t, p, theta0, h))


@scenario("737-wake-encounter", "737", "manoeuvre", 35.0,
          "Boeing 737 at 3000 ft, 180 KCAS, flaps 5, crossing the wake of a heavy aircraft: the vortex pair's rolling moment (an external rolling moment: a 1.2 s pulse to the left, then 0.8 s to the right, peak 0.8 rad/s^2 of roll acceleration) rolls the aircraft suddenly; the pilot reacts after 0.6 s and levels the wings.")
def _(f, seed, d):
    f["fcs/flap-cmd-norm"] = 0.25
    st = {}

    def c(t, p, theta0, h):
        m = f["inertia/ixx-slugs_ft2"] * 0.8
        shape = -pulse(t, 8.0, 1.2, 0.3) + 0.6 * pulse(t, 9.5, 0.8, 0.2)
        f["external_reactions/wake/magnitude-lbsft"] = m * shape
        if t >= 8.0 and "w" not in st:
            st["w"] = True
            f.event("wake vortex: sudden rolling moment to the left")
        if 8.0 <= t < 8.6:
            p.fly(f["attitude/phi-rad"], p.theta_for_climb(theta0, h), coordinate=False)  # startle: hands still
            f["fcs/aileron-cmd-norm"] = 0.0
        else:
            if t >= 8.6 and "r" not in st:
                st["r"] = True
                f.event("pilot reacts: wings level")
            p.fly(0.0, p.theta_for_climb(theta0, h))
        p.hold_speed(180)
    manoeuvre(f, d, 3000, 180, c)


@scenario("737-steep-turns", "737", "manoeuvre", 70.0,
          "Boeing 737 steep turns at 250 KCAS, 5000 ft: 45 deg bank to the left for 25 s, reversal through wings level into 45 deg to the right for 20 s, roll-out; altitude held with back pressure (1.4 g), thrust added.")
def _(f, seed, d):
    st = {}

    def c(t, p, theta0, h):
        phi_t = math.radians(-45 * (smooth_step((t - 3) / 3) - smooth_step((t - 30) / 3))
                             + 45 * (smooth_step((t - 33) / 3) - smooth_step((t - 55) / 3)))
        p.fly(phi_t, p.theta_for_climb(theta0, h, k=0.004, kv=0.02) + 0.03 * abs(math.sin(phi_t)))
        p.hold_speed(250)
        for tt, txt in [(3.0, "roll into 45 deg left bank"), (30.0, "reverse: roll through to 45 deg right"),
                        (55.0, "roll out wings level")]:
            if t >= tt and tt not in st:
                st[tt] = True
                f.event(txt)
    manoeuvre(f, d, 5000, 250, c)


@scenario("f16-roll-doublet", "f16", "manoeuvre", 30.0,
          "F-16 at 10000 ft, 350 KCAS: lateral-stick doublets (roll-rate commands) of 30 % for 0.6 s each way at t = 5 s, then 60 % at t = 15 s; pitch attitude held; wings levelled after each.")
def _(f, seed, d):
    st = {}

    def c(t, p, theta0, h):
        dbl = 0.3 * (pulse(t, 5, 0.6, 0.1) - pulse(t, 5.6, 0.6, 0.1)) + 0.6 * (pulse(t, 15, 0.6, 0.1) - pulse(t, 15.6, 0.6, 0.1))
        active = 4.9 < t < 6.5 or 14.9 < t < 16.5
        p.fly(f["attitude/phi-rad"] if active else 0.0, theta0)
        if active:
            f["fcs/aileron-cmd-norm"] = dbl
        p.hold_speed(350)
        for tt, txt in [(5.0, "roll doublet, 30 % stick"), (15.0, "roll doublet, 60 % stick")]:
            if t >= tt and tt not in st:
                st[tt] = True
                f.event(txt)
    manoeuvre(f, d, 10000, 350, c)


@scenario("f16-pitch-doublet", "f16", "manoeuvre", 30.0,
          "F-16 at 10000 ft, 350 KCAS: longitudinal-stick doublets (load-factor commands) of 20 % for 1 s each way at t = 5 s, then 40 % at t = 15 s; wings level held.")
def _(f, seed, d):
    st = {}

    def c(t, p, theta0, h):
        dbl = -0.2 * (pulse(t, 5, 1, 0.1) - pulse(t, 6, 1, 0.1)) - 0.4 * (pulse(t, 15, 1, 0.1) - pulse(t, 16, 1, 0.1))
        active = 4.9 < t < 7.5 or 14.9 < t < 17.5
        p.fly(0.0, p.theta_for_climb(theta0, h))
        if active:
            f["fcs/elevator-cmd-norm"] = dbl
        p.hold_speed(350)
        for tt, txt in [(5.0, "pitch doublet, 20 % stick (pull first)"), (15.0, "pitch doublet, 40 % stick")]:
            if t >= tt and tt not in st:
                st[tt] = True
                f.event(txt)
    manoeuvre(f, d, 10000, 350, c)


@scenario("737-dutch-roll", "737", "manoeuvre", 45.0,
          "Boeing 737 at 10000 ft, 250 KCAS, yaw damper off: a rudder doublet (30 % for 1 s each way) at t = 5 s excites the Dutch roll, which the pilot leaves to oscillate (controls fixed) for 25 s, then damps with the ailerons and rudder.")
def _(f, seed, d):
    st = {}
    f["fcs/yaw-damper-enable"] = 0.0

    def c(t, p, theta0, h):
        f["fcs/yaw-damper-enable"] = 0.0
        dbl = 0.3 * (pulse(t, 5, 1, 0.1) - pulse(t, 6, 1, 0.1))
        if t < 32:
            p.fly(0.0 if t < 5 else f["attitude/phi-rad"], p.theta_for_climb(theta0, h), coordinate=False)
            f["fcs/aileron-cmd-norm"] = 0.0 if t >= 5 else f["fcs/aileron-cmd-norm"]
            f["fcs/rudder-cmd-norm"] = dbl
        else:
            p.fly(0.0, p.theta_for_climb(theta0, h), rud=-3.0 * f["velocities/r-rad_sec"])
        p.hold_speed(250)
        for tt, txt in [(5.0, "rudder doublet, yaw damper off: Dutch roll"), (32.0, "pilot damps the oscillation")]:
            if t >= tt and tt not in st:
                st[tt] = True
                f.event(txt)
    manoeuvre(f, d, 10000, 250, c)


@scenario("f16-windup-turn", "f16", "manoeuvre", 40.0,
          "F-16 wind-up turn at 15000 ft from 450 KCAS at military power: bank and load factor built up together over 20 s to about 70 deg and 3 g (the full-flight profile's input range is +-30 m/s^2), speed bleeding off, then roll-out and unload.")
def _(f, seed, d):
    st = {}

    def c(t, p, theta0, h):
        k = smooth_step((t - 3) / 20.0) - smooth_step((t - 30) / 3.0)
        phi_t = math.radians(70.0) * k
        p.fly(phi_t, p.theta_for_climb(theta0, h))
        if 3 < t < 33:
            f["fcs/elevator-cmd-norm"] = -0.3 * k
        p.throttle(0.75)
        for tt, txt in [(3.0, "wind-up: bank and pull building"), (23.0, "70 deg bank, about 3 g"),
                        (30.0, "roll out and unload")]:
            if t >= tt and tt not in st:
                st[tt] = True
                f.event(txt)
    manoeuvre(f, d, 15000, 450, c)


# --- upsets -------------------------------------------------------------------------------------

def upset_flight(f, d, h, kcas, upset, recover, events):
    st = {}

    def c(t, p, theta0, h):
        if t < events[1][0]:
            upset(t, p, theta0)
        else:
            recover(t, p, theta0, st)
        for tt, txt in events:
            if t >= tt and tt not in st:
                st[tt] = True
                f.event(txt)
    manoeuvre(f, d, h, kcas, c)


@scenario("737-upset-nose-high", "737", "upset", 45.0,
          "Boeing 737 nose-high upset at 10000 ft from 250 KCAS: the nose rises to 30 deg at climb thrust and the speed decays; recovery (UPRT): push to unload, thrust reduced, bank 45 deg to bring the nose down, wings level as the nose passes the horizon, recover to level flight.")
def _(f, seed, d):
    def upset(t, p, theta0):
        p.fly(0.0, theta0 + math.radians(28) * smooth_step((t - 3) / 6.0))
        p.throttle(0.9)

    def recover(t, p, theta0, st):
        p.throttle(0.3)
        if not st.get("level") and f["attitude/theta-rad"] < math.radians(3):
            st["level"] = True
            f.event("nose through the horizon: wings level, recover")
        if st.get("level"):
            p.fly(0.0, theta0)
            p.hold_speed(230)
        else:
            p.fly(math.radians(45), -0.1, elev=0.2)
    upset_flight(f, d, 10000, 250, upset, recover,
                 [(3.0, "nose-high upset: nose rising to 30 deg"), (14.0, "recovery: push, thrust reduced, bank 45 deg")])


@scenario("737-upset-nose-low", "737", "upset", 40.0,
          "Boeing 737 nose-low upset at 12000 ft from 250 KCAS: the aircraft rolls to 60 deg and the nose falls to -20 deg, speed rising; recovery (UPRT): thrust idle, speed brakes, roll wings level first, then pull out at about 2.5 g to level flight.")
def _(f, seed, d):
    def upset(t, p, theta0):
        k = smooth_step((t - 3) / 6.0)
        p.fly(math.radians(60) * k, theta0 - math.radians(22) * k)

    def recover(t, p, theta0, st):
        p.throttle(0.0)
        f["fcs/speedbrake-cmd-norm"] = 1.0
        if not st.get("rolled") and abs(f["attitude/phi-rad"]) < math.radians(10):
            st["rolled"] = True
            f.event("wings level: pull out")
        if st.get("rolled"):
            st.setdefault("t_pull", (t, f["attitude/theta-rad"]))
            p.fly(0.0, min(theta0 + 0.05, st["t_pull"][1] + 0.08 * (t - st["t_pull"][0])))
        else:
            p.fly(0.0, f["attitude/theta-rad"], elev=0.0)
    upset_flight(f, d, 12000, 250, upset, recover,
                 [(3.0, "nose-low upset: rolling to 60 deg, nose to -20 deg"),
                  (12.0, "recovery: thrust idle, speed brakes, roll wings level")])


@scenario("c172p-spiral-dive", "c172p", "upset", 45.0,
          "Cessna 172 spiral dive at 4500 ft from 100 KCAS: the bank creeps to 70 deg and the nose drops to -30 deg with cruise power, speed and load factor rising; recovery: power idle, wings level, gentle pull-out to level flight.")
def _(f, seed, d):
    def upset(t, p, theta0):
        k = smooth_step((t - 3) / 14.0)
        p.fly(math.radians(70) * k, theta0 - math.radians(30) * smooth_step((t - 8) / 9.0))

    def recover(t, p, theta0, st):
        p.throttle(0.0)
        if not st.get("rolled") and abs(f["attitude/phi-rad"]) < math.radians(10):
            st["rolled"] = True
            f.event("wings level: pull out")
        if st.get("rolled"):
            st.setdefault("t_pull", (t, f["attitude/theta-rad"]))
            p.fly(0.0, min(theta0 + 0.05, st["t_pull"][1] + 0.07 * (t - st["t_pull"][0])))
            if f["attitude/theta-rad"] > theta0:
                p.throttle(0.7)
        else:
            p.fly(0.0, f["attitude/theta-rad"])
    upset_flight(f, d, 4500, 100, upset, recover,
                 [(3.0, "spiral dive developing: bank to 70 deg, nose to -30 deg"),
                  (20.0, "recovery: power idle, roll wings level")])


@scenario("737-stall-wing-drop", "737", "upset", 50.0,
          "Boeing 737 clean stall at 10000 ft from 170 KCAS: thrust idle, the pilot holds altitude as the speed decays, then raises the nose until the stall; at the stall the right wing drops (provoked by rudder and aileron for 1.3 s); recovery: push to unload, wings level, thrust, pull out alpha-limited.")
def _(f, seed, d):
    st = {}

    def c(t, p, theta0, h):
        ph = st.get("phase", "decel")
        if ph == "decel":
            p.throttle(0.0)
            if "idle" not in st:
                st["idle"] = True
                f.event("thrust idle, hold altitude while the speed decays, then pull to the stall")
            p.fly(0.0, max(p.theta_for_climb(theta0, h, k=0.006, kv=0.03), theta0 + 0.012 * max(0.0, t - 12.0)))
            if f["aero/alpha-deg"] > 15.0 or t > 35.0:
                st["phase"], st["t_s"] = "drop", t
                f.event(f"stall (alpha {f['aero/alpha-deg']:.1f} deg, {f.kcas():.0f} KCAS): right wing drops")
        elif ph == "drop":
            p.fly(math.radians(50), f["attitude/theta-rad"], rud=-0.8, coordinate=False)
            f["fcs/elevator-cmd-norm"] = -0.6
            if t - st["t_s"] > 1.3:
                st["phase"] = "recover"
                f.event("recovery: push, wings level, thrust")
        else:
            p.throttle(1.0)
            alpha = f["aero/alpha-deg"]
            theta_t = theta0 - 0.05 if alpha > 8 else theta0 + 0.05
            p.fly(0.0, theta_t)
    manoeuvre(f, d, 10000, 170, c)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=23)
    ap.add_argument("--out", default="recordings/traces/library")
    ap.add_argument("--only", default="")
    ap.add_argument("--root", default="target/jsbsim-root")
    a = ap.parse_args()
    global COMMAND
    COMMAND = "python scripts/make-library.py --seed %d" % a.seed
    make_root(a.root)
    os.makedirs(a.out, exist_ok=True)
    names = [n for n in a.only.split(",") if n] or list(SCENARIOS)
    for i, name in enumerate(names):
        fn, ac, kind, duration, text = SCENARIOS[name]
        seed = a.seed * 1000 + 10 * list(SCENARIOS).index(name)
        f = Flight(a.root, name, ac, kind, text, seed)
        fn(f, seed, duration)
        rows = f.write(a.out, duration)
        print(f"{name}: {len(rows)} rows, |f| max {np.abs(rows[:, 1:4]).max():.2f} m/s^2, "
              f"events {[(e['t'], e['event'][:30]) for e in f.events]}", file=sys.stderr)


if __name__ == "__main__":
    main()
