//! `hexcue eval` through the binary (docs/tuning.md, "One candidate: `hexcue eval`"): the
//! same input gives the same figures, which are `play --headless`'s; `--set` goes through the
//! profile loader; the base's figures may come from an earlier run; shards split the flights.

mod common;

use std::path::{Path, PathBuf};

use common::{hexcue, read_json, repo, stderr};
use serde_json::Value;
use sha2::{Digest, Sha256};

fn trace(name: &str) -> String {
    format!("recordings/traces/{name}.csv")
}

/// Runs `hexcue eval ARGS --out OUT` and returns its JSON; panics with its stderr on failure.
fn eval(args: &[&str], out: &Path) -> Value {
    let mut all: Vec<String> = vec!["eval".into()];
    all.extend(args.iter().map(|a| a.to_string()));
    all.extend(["--out".into(), out.display().to_string()]);
    let o = hexcue(&all);
    assert!(o.status.success(), "hexcue {all:?}: {}", stderr(&o));
    read_json(out)
}

/// A result without its wall time, the one figure that may differ between two runs.
fn without_wall_time(mut v: Value) -> Value {
    v.as_object_mut().unwrap().remove("wall_s");
    v
}

fn failure(args: &[&str]) -> String {
    let mut all = vec!["eval"];
    all.extend(args);
    let o = hexcue(&all);
    assert!(!o.status.success(), "hexcue {all:?} succeeded");
    stderr(&o)
}

#[test]
fn two_runs_give_the_same_figures_and_play_headless_gives_the_same_score() {
    let dir = tempfile::tempdir().unwrap();
    // A profile whose MPC never meets its wall-clock limit, so that `play`, which keeps it,
    // computes what `eval`, which lifts it, does.
    let text = std::fs::read_to_string(repo().join("profiles/full-flight.toml")).unwrap();
    assert!(text.contains("time_limit_ms = 20.0"));
    let profile = dir.path().join("patient.toml");
    std::fs::write(
        &profile,
        text.replace("time_limit_ms = 20.0", "time_limit_ms = 60000.0"),
    )
    .unwrap();
    let profile = profile.display().to_string();
    for (algorithm, shard) in [("cwf", "3/5"), ("mpc", "3/5")] {
        // Shard 3 of 5 of the shipped traces (sorted by name) is the take-off alone.
        let args = [
            "--algorithm",
            algorithm,
            "--profile",
            &profile,
            "--traces",
            "recordings/traces",
            "--shard",
            shard,
        ];
        let a = eval(&args, &dir.path().join(format!("{algorithm}-a.json")));
        let b = eval(&args, &dir.path().join(format!("{algorithm}-b.json")));
        assert_eq!(a["flights"].as_array().unwrap().len(), 1);
        assert_eq!(a["flights"][0]["name"], "takeoff");
        assert!(a["wall_s"].as_f64().unwrap() > 0.0);
        assert_eq!(without_wall_time(a.clone()), without_wall_time(b));

        let summary = dir.path().join(format!("{algorithm}-play.json"));
        let o = hexcue(&[
            "play",
            "--headless",
            "--algorithms",
            algorithm,
            "--profile",
            &profile,
            "--trace",
            &trace("takeoff"),
            "--summary",
            &summary.display().to_string(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let played = &read_json(&summary)["algorithms"][algorithm];
        let flight = &a["flights"][0];
        assert_eq!(
            flight["score"].as_f64(),
            played["score"].as_f64(),
            "{algorithm}"
        );
        assert_eq!(flight["score_terms"], played["score_terms"], "{algorithm}");
        for key in [
            "limiter_steps",
            "max_leg_usage",
            "leg_violations",
            "max_dof_usage",
        ] {
            assert_eq!(flight[key], played[key], "{algorithm} {key}");
        }
        // Evaluated without --set, the candidate is the base.
        assert_eq!(a["profile_sha256"], a["base_profile_sha256"]);
        assert_eq!(flight["base"]["score"], flight["score"]);
        assert_eq!(a["objective"], a["mean_score"]);
    }
}

#[test]
fn a_set_value_is_scored_written_and_judged_against_the_base() {
    let dir = tempfile::tempdir().unwrap();
    let flights = format!("{},{}", trace("takeoff"), trace("horizontal-stall"));
    let base = eval(
        &["--algorithm", "cwf", "--traces", &flights],
        &dir.path().join("base.json"),
    );
    let saved = dir.path().join("candidate.toml");
    let saved_arg = saved.display().to_string();
    let set = [
        "--set",
        "cwf.tilt_lp_zeta=0.9",
        "--set",
        "cwf.specific_force_scale[0,1]=0.7",
    ];
    let mut args = vec!["--algorithm", "cwf", "--traces", &flights];
    args.extend(set);
    let fresh = eval(
        &[
            &args[..],
            &["--save-profile", &saved_arg, "--note", "a test"],
        ]
        .concat(),
        &dir.path().join("fresh.json"),
    );
    let base_json = dir.path().join("base.json").display().to_string();
    let reused = eval(
        &[&args[..], &["--base-result", &base_json]].concat(),
        &dir.path().join("reused.json"),
    );
    // The base's figures from the earlier run are the ones the base run here gives.
    assert_eq!(without_wall_time(fresh.clone()), without_wall_time(reused));
    assert_ne!(fresh["profile_sha256"], base["profile_sha256"]);
    assert_eq!(fresh["base_profile_sha256"], base["profile_sha256"]);
    assert_eq!(fresh["keys"]["cwf.tilt_lp_zeta"], 0.9);
    assert_eq!(fresh["keys"]["cwf.specific_force_scale[1]"], 0.7);
    for (f, b) in fresh["flights"]
        .as_array()
        .unwrap()
        .iter()
        .zip(base["flights"].as_array().unwrap())
    {
        assert_eq!(f["base"]["score"], b["score"]);
        assert_ne!(f["score"], b["score"]);
    }

    // The profile written is the one scored: its text below the header has the result's
    // hash, and read as a profile it scores the same.
    let text = std::fs::read_to_string(&saved).unwrap();
    let (header, body) = text.split_once('\n').unwrap();
    assert!(
        header.starts_with("# tuned: `hexcue eval --algorithm cwf --set cwf.tilt_lp_zeta=0.9")
            && header.contains("a test: CWF mean score"),
        "{header}"
    );
    let digest: String = Sha256::digest(body.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(fresh["profile_sha256"], Value::String(digest));
    let shipped = std::fs::read_to_string(repo().join("profiles/full-flight.toml")).unwrap();
    assert_eq!(
        body.lines().count(),
        shipped.lines().count(),
        "comments kept"
    );
    let again = eval(
        &[
            "--algorithm",
            "cwf",
            "--profile",
            &saved_arg,
            "--traces",
            &flights,
        ],
        &dir.path().join("again.json"),
    );
    assert_eq!(again["flights"][0]["score"], fresh["flights"][0]["score"]);
    assert_eq!(again["flights"][1]["score"], fresh["flights"][1]["score"]);

    // The verdict is tune's gate, checked here from the figures: accepted exactly when every
    // flight is within 2 % of the base, legs in stroke, the limiter within the base's share
    // + 1 %, and the mean below the base's.
    let holds = fresh["flights"].as_array().unwrap().iter().all(|f| {
        let b = &f["base"];
        f["leg_violations"] == 0
            && f["limiter_fraction"].as_f64().unwrap()
                <= b["limiter_fraction"].as_f64().unwrap() + 0.001
            && f["score"].as_f64().unwrap() <= 1.02 * b["score"].as_f64().unwrap()
    }) && fresh["mean_score"].as_f64() < fresh["base_mean_score"].as_f64();
    assert_eq!(
        fresh["verdict"]["accepted"].as_bool(),
        Some(holds),
        "{fresh}"
    );
    assert_eq!(fresh["verdict"]["reason"].is_null(), holds);

    // Shards: each flight scored alone is the same as among the others.
    for (i, f) in fresh["flights"].as_array().unwrap().iter().enumerate() {
        let shard = format!("{i}/2");
        let one = eval(
            &[&args[..], &["--shard", &shard, "--base-result", &base_json]].concat(),
            &dir.path().join(format!("shard-{i}.json")),
        );
        assert_eq!(one["flights"][0], *f, "shard {shard}");
    }
}

#[test]
fn with_validation_flights_the_verdict_is_tunes_gate_on_them() {
    let dir = tempfile::tempdir().unwrap();
    // Heave at full scale: within 2 % on the training take-off, 11 % worse on the validation
    // landing; surge at 0.3: twice as bad on the take-off; surge at full scale: better on both.
    for (set, refused_by) in [
        ("cwf.specific_force_scale[2]=1.0", Some("landing: score")),
        (
            "cwf.specific_force_scale[0]=0.3",
            Some("training takeoff: score"),
        ),
        ("cwf.specific_force_scale[0]=1.0", None),
    ] {
        let r = eval(
            &[
                "--algorithm",
                "cwf",
                "--traces",
                &trace("takeoff"),
                "--validate",
                &trace("landing"),
                "--set",
                set,
            ],
            &dir.path().join("r.json"),
        );
        let _ = std::fs::remove_file(dir.path().join("r.json"));
        assert_eq!(r["validation"]["flights"][0]["name"], "landing");
        let within =
            |f: &Value| f["score"].as_f64().unwrap() <= 1.02 * f["base"]["score"].as_f64().unwrap();
        let (train, val) = (&r["flights"][0], &r["validation"]["flights"][0]);
        // The gate recomputed from the figures: training and validation flights within 2 %,
        // legs in stroke, the limiter within the base's share + 0.1 % in training (tune's
        // feasibility) and + 1 % in validation, and a validation mean below the base's.
        let limiter = |f: &Value, margin: f64| {
            f["leg_violations"] == 0
                && f["limiter_fraction"].as_f64().unwrap()
                    <= f["base"]["limiter_fraction"].as_f64().unwrap() + margin
        };
        let holds = within(train)
            && limiter(train, 0.001)
            && within(val)
            && limiter(val, 0.01)
            && r["validation"]["mean_score"].as_f64() < r["validation"]["base_mean_score"].as_f64();
        assert_eq!(
            r["verdict"]["accepted"].as_bool(),
            Some(holds),
            "{set}: {r}"
        );
        match refused_by {
            Some(why) => {
                let reason = r["verdict"]["reason"].as_str().unwrap();
                assert!(reason.starts_with(why), "{set}: {reason}");
            }
            None => assert!(holds && r["verdict"]["reason"].is_null(), "{set}: {r}"),
        }
    }
}

#[test]
fn bad_input_is_refused_naming_the_key_or_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.json").display().to_string();
    let t = trace("takeoff");
    let base = ["--algorithm", "cwf", "--traces", &t, "--out", &out];
    let with = |extra: &[&str]| failure(&[&base[..], extra].concat());
    let e = with(&["--set", "cwf.tilt_lp_zeta=abc"]);
    assert!(
        e.contains("cwf.tilt_lp_zeta=abc") && e.contains("not a TOML value"),
        "{e}"
    );
    let e = with(&["--set", "score.leg_usage_start=1.5"]);
    assert!(e.contains("score.leg_usage_start"), "{e}");
    let e = with(&["--set", "cwf.no_such_gain=1"]);
    assert!(e.contains("no_such_gain"), "{e}");
    let e = with(&["--set", "cwf.specific_force_scale[5]=1"]);
    assert!(e.contains("no element 5"), "{e}");
    // A value of the wrong shape is the user's --set, not a line of the candidate's text,
    // which they never see.
    let e = with(&[
        "--set",
        "cwf.tilt_lp_zeta=0.8",
        "--set",
        "cwf.specific_force_scale=[1,2]",
    ]);
    assert!(
        e.contains("--set `cwf.specific_force_scale=[1,2]`: `cwf.specific_force_scale`")
            && e.contains("expected an array of length 3")
            && !e.contains("tilt_lp_zeta")
            && !e.contains("with --set:"),
        "{e}"
    );
    let e = with(&["--shard", "2/2"]);
    assert!(e.contains("--shard `2/2`"), "{e}");
    let e = failure(&["--algorithm", "lqr", "--traces", &t, "--out", &out]);
    assert!(e.contains("unknown algorithm `lqr`"), "{e}");
    let e = failure(&[
        "--algorithm",
        "cwf",
        "--traces",
        "no/such.csv",
        "--out",
        &out,
    ]);
    assert!(e.contains("no/such.csv"), "{e}");
    assert!(
        !PathBuf::from(&out).exists(),
        "nothing written on a failure"
    );

    // A base result that is a candidate's, not the base's, is refused with why.
    let candidate = dir.path().join("candidate.json");
    eval(
        &[
            "--algorithm",
            "cwf",
            "--traces",
            &t,
            "--set",
            "cwf.tilt_lp_zeta=0.9",
        ],
        &candidate,
    );
    let e = with(&[
        "--set",
        "cwf.tilt_lp_zeta=0.8",
        "--base-result",
        &candidate.display().to_string(),
    ]);
    assert!(
        e.contains("--base-result")
            && e.contains("but of a candidate (--set cwf.tilt_lp_zeta=0.9)"),
        "{e}"
    );
}

#[test]
fn the_space_is_tunes_table_with_the_profiles_values() {
    for (algorithm, n) in [("cwf", 15), ("mpc", 22), ("smpc", 8)] {
        let o = hexcue(&["eval", "--space", "--algorithm", algorithm]);
        assert!(o.status.success(), "{}", stderr(&o));
        let space: Value = serde_json::from_slice(&o.stdout).unwrap();
        let keys = space["keys"].as_array().unwrap();
        assert_eq!(keys.len(), n, "{algorithm}");
        for k in keys {
            let (lo, hi) = (k["lower"].as_f64().unwrap(), k["upper"].as_f64().unwrap());
            assert!(lo < hi, "{k}");
        }
    }
    let o = hexcue(&["eval", "--space", "--algorithm", "cwf"]);
    let space: Value = serde_json::from_slice(&o.stdout).unwrap();
    let zeta = space["keys"]
        .as_array()
        .unwrap()
        .iter()
        .find(|k| k["name"] == "cwf.tilt_lp_zeta")
        .unwrap();
    assert_eq!(zeta["lower"], 0.5);
    assert_eq!(zeta["upper"], 1.0);
    assert_eq!(zeta["log"], false);
    assert_eq!(space["default_step"], 0.2);
    // The compact profile does not state the MPC's false-cue keys: tune leaves them out.
    let o = hexcue(&[
        "eval",
        "--space",
        "--algorithm",
        "mpc",
        "--profile",
        "profiles/compact.toml",
    ]);
    let space: Value = serde_json::from_slice(&o.stdout).unwrap();
    let absent = space["not_stated"].as_array().unwrap();
    assert!(absent
        .iter()
        .any(|k| k.as_str().unwrap().starts_with("mpc.false_cue_weight")));
}
