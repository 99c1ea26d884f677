//! `hexcue bound` (docs/bound.md): the yardstick on the shipped flights. An algorithm that
//! beats the lower bound is a bug in the bound; the achieved motion must be one the platform
//! makes; the heave-only figure of the turbulent cruise must agree with the independent check.

mod common;

use clarabel::solver::SolverStatus;
use common::{hexcue, read_json, repo, shipped_traces, stderr};
use hexcue::formats::trace::load_trace;
use hexcue_core::bound::Setup;
use hexcue_core::profile::text::default_profile;
use hexcue_core::vocab::Channel;

/// The first `seconds` of a shipped flight as a trace file of its own in `dir`.
fn slice_of(name: &str, seconds: usize, dir: &std::path::Path) -> std::path::PathBuf {
    let src = std::fs::read_to_string(repo().join("recordings/traces").join(name)).unwrap();
    let slice: Vec<&str> = src.lines().take(1 + 100 * seconds).collect();
    let path = dir.join(name.replace(".csv", &format!("-{seconds}s.csv")));
    std::fs::write(&path, slice.join("\n") + "\n").unwrap();
    path
}

fn bound_json(trace: &std::path::Path, extra: &[&str]) -> serde_json::Value {
    bound_run(trace, extra).0
}

/// `hexcue bound --json`: the JSON and the printed table.
fn bound_run(trace: &std::path::Path, extra: &[&str]) -> (serde_json::Value, String) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bound.json");
    let mut args = vec![
        "bound".to_string(),
        "--trace".into(),
        trace.to_string_lossy().into_owned(),
        "--json".into(),
        out.to_string_lossy().into_owned(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    let run = hexcue(&args);
    assert!(run.status.success(), "{}", stderr(&run));
    (read_json(&out), common::stdout(&run))
}

/// Seconds of each shipped flight the tests bound: the programmes grow with the flight, and
/// the full flights run in `scripts/bound-table.sh` (docs/bound.md's table).
const SLICE_S: &str = "20";

/// One test per shipped flight, so that the harness runs two at once (each `hexcue bound`
/// has serial stretches: the algorithms' runs, the replays).
macro_rules! shipped_flight {
    ($($test:ident: $file:literal),* $(,)?) => {$(
        #[test]
        fn $test() {
            no_algorithm_beats_the_lower_bound_on(&repo().join("recordings/traces").join($file));
        }
    )*};
}

shipped_flight! {
    no_algorithm_beats_the_lower_bound_on_the_horizontal_stall: "horizontal-stall.csv",
    no_algorithm_beats_the_lower_bound_on_the_landing: "landing.csv",
    no_algorithm_beats_the_lower_bound_on_the_steep_turn: "steep-turn.csv",
    no_algorithm_beats_the_lower_bound_on_the_takeoff: "takeoff.csv",
    no_algorithm_beats_the_lower_bound_on_the_turbulence_cruise: "turbulence-cruise.csv",
}

#[test]
fn every_shipped_flight_has_its_bound_test() {
    let names: Vec<String> = shipped_traces()
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "horizontal-stall.csv",
            "landing.csv",
            "steep-turn.csv",
            "takeoff.csv",
            "turbulence-cruise.csv"
        ]
    );
}

fn no_algorithm_beats_the_lower_bound_on(trace: &std::path::Path) {
    let (j, text) = bound_run(trace, &["--duration", SLICE_S]);
    if trace.ends_with("landing.csv") {
        the_readmes_bound_figures_are(&text);
    }
    assert_eq!(j["steps"].as_u64(), Some(2000), "{}", trace.display());
    let name = trace.display();
    let bound = &j["bound"];
    let lower_total = bound["lower"]["total"].as_f64().unwrap();
    let algorithms = j["algorithms"].as_object().unwrap();
    assert_eq!(algorithms.len(), 3, "{name}: {j}");
    for (alg, e) in algorithms {
        let total = e["total"].as_f64().unwrap();
        assert!(
            lower_total <= total,
            "{name}: {alg} total {total} < lower {lower_total}"
        );
        for c in Channel::ALL.map(Channel::key) {
            let lower = bound["lower"]["channel"][c].as_f64().unwrap();
            let err = e["error"][c].as_f64().unwrap();
            assert!(lower <= err, "{name}: {alg} {c} {err} < lower {lower}");
        }
    }
    // The achieved motion: made by the platform (no leg outside its stroke) and, being a
    // motion, no better than the bound. Within 15 % of it is issue #33's aim, not met on
    // every flight (docs/bound.md, "The gap").
    let achieved = &bound["achieved"];
    assert_eq!(achieved["leg_violations"].as_u64(), Some(0), "{name}");
    let total = achieved["total"].as_f64().unwrap();
    assert!(
        total >= lower_total - 1e-6,
        "{name}: achieved {total} < lower {lower_total}"
    );
    // The joint optimum bounds every channel's own optimum from above.
    for c in Channel::ALL.map(Channel::key) {
        let own = bound["lower"]["channel"][c].as_f64().unwrap();
        let joint = j["details"]["joint_error"][c].as_f64().unwrap();
        assert!(
            own <= joint + 1e-6,
            "{name}: {c} alone {own} > joint {joint}"
        );
    }
    // The valid relaxation (exact kinematics) bounds every motion, the achieved one
    // included, channel by channel and in total; it contains the linearised one.
    let valid = &bound["lower"]["valid"];
    let valid_total = valid["total"].as_f64().unwrap();
    assert!(valid_total <= lower_total + 1e-6, "{name}: {valid}");
    let mut motions: Vec<(&str, &serde_json::Value)> = algorithms
        .iter()
        .map(|(a, e)| (a.as_str(), &e["error"]))
        .collect();
    motions.push(("achieved", &achieved["error"]));
    for (who, error) in motions {
        let mut sum = 0.0;
        for c in Channel::ALL.map(Channel::key) {
            let v = valid["channel"][c].as_f64().unwrap();
            let err = error[c].as_f64().unwrap();
            sum += err;
            assert!(v <= err + 1e-9, "{name}: {who} {c} {err} < valid {v}");
        }
        assert!(
            valid_total <= sum + 1e-9,
            "{name}: {who} {sum} < valid {valid_total}"
        );
    }
    assert!(bound["dominance"]["possible"].is_boolean(), "{name}");
    assert!(bound["dominance"]["binding"].is_array(), "{name}");
}

#[test]
fn the_turbulent_cruise_heave_bound_agrees_with_the_independent_check() {
    // scripts/heave-bound.py (10 Hz, HiGHS) gives 1.698 and an independent 100 Hz programme
    // with exact kinematics 1.704 (issue #33): the heave channel alone must be 1.70 ± 3 %.
    // The programme `hexcue bound --channels fz` solves for it (heave alone on its own DoFs,
    // `Setup::channel_dofs`), on the whole flight; the command itself would add the achieved
    // motion's sequences over all six DoFs, which the figure does not depend on
    // (`--channels` below checks the command's side on a slice).
    let profile = default_profile();
    let trace = load_trace(
        &repo().join("recordings/traces/turbulence-cruise.csv"),
        profile.rate_hz,
    )
    .unwrap()
    .trace;
    let setup = Setup::new(&profile, &trace).unwrap();
    let heave = setup
        .programme(&[2], &setup.channel_dofs(2), &[2], None)
        .solve();
    assert_eq!(heave.status, SolverStatus::Solved);
    let fz = heave.error[2];
    assert!((fz - 1.70).abs() <= 0.03 * 1.70, "heave bound {fz}");
    // The same programme as the command's: on a slice, `--channels fz` gives that channel's
    // own optimum as the core computes it, solves no other channel alone, and is below the
    // CWF.
    let path = repo().join("recordings/traces/turbulence-cruise.csv");
    let j = bound_json(
        &path,
        &[
            "--channels",
            "fz",
            "--algorithms",
            "cwf",
            "--duration",
            "10",
        ],
    );
    let cli = j["bound"]["lower"]["channel"]["fz"].as_f64().unwrap();
    let mut slice = trace.clone();
    slice.samples.truncate(1000);
    let setup = Setup::new(&profile, &slice).unwrap();
    let core = setup
        .programme(&[2], &setup.channel_dofs(2), &[2], None)
        .solve()
        .error[2];
    assert!((cli - core).abs() <= 1e-6 * (1.0 + core), "{cli} vs {core}");
    assert!(j["bound"]["lower"]["channel"]["fx"].is_null(), "{j}");
    let cwf = j["algorithms"]["cwf"]["error"]["fz"].as_f64().unwrap();
    assert!(cli < cwf, "{cli} vs the CWF's {cwf}");
}

#[test]
fn bound_refuses_an_unknown_channel_naming_it() {
    let trace = repo().join("recordings/traces/takeoff.csv");
    let out = hexcue(&[
        "bound",
        "--trace",
        trace.to_str().unwrap(),
        "--channels",
        "fx,heave",
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("heave"), "{}", stderr(&out));
}

#[test]
fn play_headless_bound_adds_the_bound_object_and_the_cueable_table() {
    // The landing's first 10 s: the summary's shape and the table do not need the whole
    // flight (the bound's figures are checked on the shipped flights above).
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("s.json");
    let trace = slice_of("landing.csv", 10, dir.path());
    let out = hexcue(&[
        "play",
        "--headless",
        "--bound",
        "--algorithms",
        "cwf",
        "--trace",
        trace.to_str().unwrap(),
        "--summary",
        summary.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        common::stdout(&out).contains("cueable"),
        "{}",
        common::stdout(&out)
    );
    let j = read_json(&summary);
    let b = j["bound"].as_object().unwrap();
    let keys: Vec<&str> = b.keys().map(|k| k.as_str()).collect();
    assert_eq!(keys, ["achieved", "dominance", "lower"]);
    let lower = &j["bound"]["lower"];
    assert_eq!(lower["channel"].as_object().unwrap().len(), 6);
    let mut achieved: Vec<&str> = j["bound"]["achieved"]
        .as_object()
        .unwrap()
        .keys()
        .map(|k| k.as_str())
        .collect();
    achieved.sort();
    assert_eq!(
        achieved,
        ["error", "leg_violations", "limiter_fraction", "total"]
    );
    let cwf = j["algorithms"]["cwf"]["score_terms"]["error"]["fx"]
        .as_f64()
        .unwrap();
    assert!(lower["channel"]["fx"].as_f64().unwrap() <= cwf);
}

/// The README's bound figures (the landing's first 20 s) are what `hexcue bound` prints.
fn the_readmes_bound_figures_are(text: &str) {
    // "total  lower  achieved  S-MPC (cueable) …": the totals row.
    let totals: Vec<String> = text
        .lines()
        .find(|l| l.starts_with("total"))
        .unwrap_or_else(|| panic!("no totals row in\n{text}"))
        .split_whitespace()
        .skip(1)
        .filter(|w| !w.starts_with('('))
        .map(str::to_string)
        .collect();
    let valid = text
        .lines()
        .find_map(|l| {
            l.strip_prefix("valid lower bound of the exact kinematics (docs/bound.md): total ")
        })
        .and_then(|rest| rest.split(';').next())
        .unwrap_or_else(|| panic!("no valid bound line in\n{text}"));
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    let line = readme
        .lines()
        .find(|l| l.starts_with("# On the landing's first 20 s:"))
        .expect("the README's bound line");
    let expected = format!(
        "# On the landing's first 20 s: lower {} (valid bound {valid}), achieved {}, S-MPC {}, MPC {}, CWF {}.",
        totals[0], totals[1], totals[2], totals[3], totals[4]
    );
    assert_eq!(line, expected, "README against `hexcue bound`:\n{text}");
}

#[test]
fn compare_bound_reports_the_cueable_error_and_the_dominance() {
    // A 10 s slice of the landing in a folder of its own.
    let dir = tempfile::tempdir().unwrap();
    slice_of("landing.csv", 10, dir.path());
    let report = dir.path().join("report.md");
    let out = hexcue(&[
        "compare",
        "--bound",
        "--traces",
        dir.path().to_str().unwrap(),
        "--out",
        report.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let md = std::fs::read_to_string(&report).unwrap();
    assert!(md.contains("hexcue compare --bound"), "{md}");
    assert!(
        md.contains(
            "| channel | lower | achieved | S-MPC (cueable) | MPC (cueable) | CWF (cueable) |"
        ),
        "{md}"
    );
    assert!(
        md.contains("Share of the CWF's cueable error removed: S-MPC "),
        "{md}"
    );
    assert!(
        md.contains("A motion nowhere worse than the CWF and better in total: "),
        "{md}"
    );
    // Each algorithm's cueable total is its total less the bound's, and never negative.
    let total_row = md
        .lines()
        .find(|l| l.starts_with("| total |"))
        .expect("the bound's totals row");
    let cells: Vec<&str> = total_row.split('|').map(str::trim).collect();
    let lower: f64 = cells[2].parse().unwrap();
    for cell in &cells[4..7] {
        let (total, cueable) = cell.split_once(" (").unwrap();
        let (total, cueable): (f64, f64) = (
            total.parse().unwrap(),
            cueable.trim_end_matches(')').parse().unwrap(),
        );
        assert!((total - lower - cueable).abs() < 0.0015, "{total_row}");
        assert!(cueable >= 0.0, "{total_row}");
    }
}

#[test]
fn tune_refuses_an_unknown_objective_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = hexcue(&[
        "tune",
        "--algorithm",
        "cwf",
        "--traces",
        repo()
            .join("recordings/traces/landing.csv")
            .to_str()
            .unwrap(),
        "--objective",
        "felt",
        "--out",
        dir.path().join("t.toml").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--objective"), "{}", stderr(&out));
    assert!(stderr(&out).contains("felt"), "{}", stderr(&out));
}
