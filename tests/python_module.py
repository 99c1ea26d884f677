"""The Python module `hexcue` against the CLI (tests/python.rs runs this in its venv).

Arguments: the trace CSV, the CLI's `--summary` JSON, the CSV `hexcue export` wrote of the
recorded S-MPC commands, the JSON of the Rust engine's S-MPC commands at full precision, the
profile all three ran with (the default without the MPC's wall-clock limit), the trace's
first 20 s as a file of its own, the summary of `play --headless --preview` of the MPC
on that file, and what `play --headless` wrote on stderr for each file of the bad-input
corpus (tests/corpus/traces).
Prints one line per check; any failure raises (exit status 1).
"""

import json
import sys

import numpy as np

import hexcue


def same(ours, theirs, path="summary"):
    """The JSON's value (null for NaN) within 1e-12, key by key; wall times aside."""
    if isinstance(theirs, dict):
        assert isinstance(ours, dict) and set(ours) == set(theirs), (path, set(ours) ^ set(theirs))
        for key, value in theirs.items():
            if key != "step_time_us":
                same(ours[key], value, f"{path}.{key}")
    elif isinstance(theirs, list):
        assert isinstance(ours, list) and len(ours) == len(theirs), path
        for i, (a, b) in enumerate(zip(ours, theirs)):
            same(a, b, f"{path}[{i}]")
    elif theirs is None:
        assert ours is None or ours != ours, (path, ours)  # null: None or NaN
    elif isinstance(theirs, (int, float)) and not isinstance(theirs, bool):
        assert abs(ours - theirs) <= 1e-12, (path, ours, theirs)
    else:
        assert ours == theirs, (path, ours, theirs)


(trace_csv, summary_json, recorded_csv, engine_json, profile_toml, slice_csv,
 preview_json, corpus_json) = sys.argv[1:9]

# hexcue's own trace format (docs/formats.md): t, fx, fy, fz (m/s²), p, q, r (rad/s), ...
data = np.loadtxt(trace_csv, delimiter=",", skiprows=1)
f, w = data[:, 1:4], data[:, 4:7]
profile = hexcue.Profile.load(profile_toml)
assert profile.name == hexcue.Profile.default().name
assert profile.rate_hz == 100.0 and np.allclose(np.diff(data[:, 0]), 0.01), "a 100 Hz trace"

# (1) The S-MPC stepped one sample at a time gives the Rust engine's commands.
smpc = profile.algorithm("smpc")
steps = [smpc.step(f[k], w[k]) for k in range(len(f))]
stepped = {key: np.array([s[key] for s in steps]) for key in ("pose", "velocity", "acceleration")}
modes = {s["state"]["mode"] for s in steps}
switches = steps[-1]["state"]["switch_count"]
with open(engine_json) as fh:
    engine = json.load(fh)
worst = 0.0
for key in ("pose", "velocity", "acceleration"):
    rust = np.array(engine[key])
    assert rust.shape == stepped[key].shape, (key, rust.shape, stepped[key].shape)
    worst = max(worst, float(np.max(np.abs(rust - stepped[key]))))
assert worst <= 1e-9, f"stepped S-MPC differs from the Rust engine by {worst}"
print(f"step: {len(steps)} S-MPC steps, commands within {worst:.1e} of the Rust engine; "
      f"modes {sorted(modes)}, {switches} switches")

# ... and the recording `play --headless --record` wrote, to the recording's resolution
# (docs/recordings.md: pose 6 decimals, velocity and acceleration 3).
recorded = np.loadtxt(recorded_csv, delimiter=",", skiprows=1)
assert recorded.shape == (len(f), 19), recorded.shape
for key, cols, quantum in (("pose", slice(1, 7), 1e-6), ("velocity", slice(7, 13), 1e-3),
                           ("acceleration", slice(13, 19), 1e-3)):
    err = float(np.max(np.abs(recorded[:, cols] - stepped[key])))
    assert err <= quantum / 2 + 1e-12, f"{key}: {err} from the recording"
print("step: the recorded commands agree to the recording's resolution")

# The stepping object's own summary is the engine's without the trace's future: with the
# default profile's causal reference, the same score as the CLI's.
with open(summary_json) as fh:
    cli = json.load(fh)
cli_score = cli["algorithms"]["smpc"]["score"]
assert abs(smpc.score() - cli_score) <= 1e-12, (smpc.score(), cli_score)
same({**smpc.summary(), "trace": cli["trace"]}, cli)
print("step: the stepping object's summary is the CLI's to 1e-12")
assert smpc.steps == len(f)
smpc.reset()
assert smpc.steps == 0
# The active set's warm start is history, not state: a reset keeps it, which may change the
# last bits (hexcue-core's engine tests say the same of a restored snapshot).
again = np.array([smpc.step(f[k], w[k])["pose"] for k in range(300)])
assert np.allclose(again, stepped["pose"][:300], rtol=0, atol=1e-9), "reset starts over"
assert np.abs(stepped["pose"][:300]).max() > 1e-3, "the first 3 s move the platform"

# (2) run() gives the summary and score of `play --headless --summary`.
result = hexcue.run(f, w, profile=profile, algorithms=["smpc"], name="landing")
score = result.score("smpc")
assert abs(score - cli_score) <= 1e-12, f"run() score {score!r} vs the CLI's {cli_score!r}"


same(result.summary, cli)
run_pose = result.algorithms["smpc"]["pose"]
assert run_pose.shape == (len(f), 6)
assert float(np.max(np.abs(run_pose - stepped["pose"]))) <= 1e-9
assert result.algorithms["smpc"]["mode"] == [s["state"]["mode"] for s in steps]
print(f"run: score {score!r}, the CLI's {cli_score!r}; the whole summary the same to 1e-12")

# read_trace reads the file as `play --trace` does: the same numbers as NumPy reads from the
# CSV, on the grid from 0, with the sidecar; run() of the trace is the CLI's run.
trace = hexcue.read_trace(trace_csv, profile=profile)
assert (trace.name, len(trace), trace.rate_hz) == ("landing", len(f), 100.0), trace
assert np.array_equal(trace.specific_force_mps2, f)
assert np.array_equal(trace.angular_velocity_radps, w)
assert np.array_equal(trace.attitude_rad, data[:, 7:10])
assert np.array_equal(trace.t_s, np.arange(len(f)) / 100.0)
assert trace.notices == [], trace.notices
with open(trace_csv[:-len(".csv")] + ".json") as fh:
    sidecar = json.load(fh)
for key in ("name", "aircraft", "scenario", "source", "sample_rate_hz", "duration_s"):
    assert trace.info[key] == sidecar.get(key), (key, trace.info[key], sidecar.get(key))
assert [(e["t"], e["event"]) for e in trace.info["events"]] == \
    [(e["t"], e["event"]) for e in sidecar["events"]], trace.info["events"]
from_file = hexcue.run(trace, profile=profile, algorithms=["smpc"])
same(from_file.summary, cli)
assert from_file.score("smpc") == score
try:
    hexcue.run(trace, w, profile=profile)
except ValueError as e:
    assert "hexcue.Trace" in str(e), str(e)
else:
    raise AssertionError("a trace was run with another angular velocity")
print(f"read_trace: {trace!r}, {len(trace.info['events'])} events; run() of it is the CLI's")

# The vestibular model of the aircraft's signal is the run's reference.
perceived = hexcue.perceive(f, w, profile=profile)
for key in ("specific_force_mps2", "angular_velocity_radps"):
    assert np.array_equal(perceived[key], result.reference[key]), key
print("perceive: the run's reference, exactly")

# The controller's state through a switch and back: a flight made up here (2 s of the largest
# surge the input allows, 1 s of its opposite, half a second of sway) that COTC cannot follow.
n = 1500
t = np.arange(n) / profile.rate_hz
hard_f = np.tile([0.0, 0.0, -hexcue.G_MPS2], (n, 1))
hard_f[(t > 1) & (t < 3), 0] = 9.0
hard_f[(t > 3) & (t < 4), 0] = -9.0
hard_f[(t > 4) & (t < 4.5), 1] = 9.0
hard_w = np.zeros((n, 3))
smpc.reset()
states = [smpc.step(hard_f[k], hard_w[k])["state"] for k in range(n)]
hard = hexcue.run(hard_f, hard_w, profile=profile, algorithms=["smpc"])
assert hard.algorithms["smpc"]["mode"] == [s["mode"] for s in states]
switched = [k for k in range(1, n) if states[k]["switch_count"] > states[k - 1]["switch_count"]]
assert len(switched) == hard.summary["algorithms"]["smpc"]["switches"] >= 2, switched
first = states[switched[0]]
# The supervisor's reason as recordings store it: "COTC not solved (primal_infeasible)".
assert "cotc" in str(first["last_switch_reason"]).lower(), first
assert {s["mode"] for s in states[switched[0]:]} & {"blend", "free"}, first
reasons = [states[k]["last_switch_reason"] for k in switched]
print(f"state: {len(switched)} switches, at steps {switched}: {reasons}")

# (3) run(preview=True) is `play --headless --preview`: the MPC sees the flight's future.
part_data = np.loadtxt(slice_csv, delimiter=",", skiprows=1)
part = {"specific_force_mps2": np.ascontiguousarray(part_data[:, 1:4]),
        "angular_velocity_radps": np.ascontiguousarray(part_data[:, 4:7]),
        "name": "landing-20s"}
with open(preview_json) as fh:
    cli_preview = json.load(fh)
assert cli_preview["mpc_reference"] == "preview", cli_preview.get("mpc_reference")
ahead = hexcue.run(part["specific_force_mps2"], part["angular_velocity_radps"], profile=profile,
                   algorithms=["mpc"], name=part["name"], preview=True)
same(ahead.summary, cli_preview)
causal = hexcue.run(part["specific_force_mps2"], part["angular_velocity_radps"], profile=profile,
                    algorithms=["mpc"], name=part["name"])
assert causal.summary["mpc_reference"] == "decay", causal.summary["mpc_reference"]
assert causal.score("mpc") != ahead.score("mpc"), "the preview changes the MPC's run"
print(f"preview: score {ahead.score('mpc')!r} as `play --preview`, "
      f"{causal.score('mpc')!r} without")

# (4) A bad profile raises with hexcue's message naming the key.
with open(profile_toml) as fh:
    text = fh.read()
bad = text.replace("rate_hz = 100.0", "rate_hz = \"fast\"", 1)
assert bad != text, "the default profile's rate line moved"
try:
    hexcue.Profile.from_toml(bad, "bad.toml")
except hexcue.ProfileError as e:
    message = str(e)
    assert "bad.toml:" in message and "rate_hz" in message, message
    assert isinstance(e, ValueError)
    print(f"bad profile: {message}")
else:
    raise AssertionError("a profile with rate_hz = \"fast\" was accepted")
try:
    profile.algorithm("lqr")
except ValueError as e:
    assert "smpc, mpc, cwf" in str(e), str(e)
else:
    raise AssertionError("an unknown algorithm was built")
try:
    hexcue.run(f[:10], w[:9])
except ValueError as e:
    assert "rows" in str(e), str(e)
else:
    raise AssertionError("signals of different lengths were run")

# (5) read_trace says of each file of the bad-input corpus what `play --trace` says: the same
# refusal, word for word (a hexcue.TraceError, a ValueError; an OSError for a missing file),
# or the same notes on a file it accepts.
with open(corpus_json) as fh:
    corpus = json.load(fh)
refused = 0
for case in corpus:
    said = case["stderr"].splitlines()
    try:
        read = hexcue.read_trace(case["path"])
    except (hexcue.TraceError, OSError) as e:
        assert not case["ok"], (case["path"], str(e))
        assert isinstance(e, (ValueError, FileNotFoundError)), (case["path"], e)
        assert f"hexcue: error: {e}" in said, (case["path"], str(e), said)
        refused += 1
        example = str(e)
    else:
        assert case["ok"], (case["path"], read.notices, said)
        notes = [line for line in said if line.startswith(f"note: {read.name}: ")]
        assert notes == [f"note: {read.name}: {n}" for n in read.notices], (notes, read.notices)
assert refused >= 25, refused
print(f"read_trace: the CLI's words on {len(corpus)} files of the corpus, {refused} refused; "
      f"e.g. {example}")
print("ok")
