//! Issue 38, item 5: the README's OMCT paragraph is generated from what `hexcue omct --out
//! docs/omct` wrote (`docs/omct/omct.json`); this test recomputes every number of it from
//! that file and fails when the paragraph drifts from it.

mod common;

use common::repo;

/// The gains of `test` for `alg` at frequencies within `lo..=hi` rad/s.
fn gains(omct: &serde_json::Value, test: &str, alg: &str, lo: f64, hi: f64) -> Vec<f64> {
    let t = omct["tests"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["test"] == test)
        .unwrap_or_else(|| panic!("no {test} in omct.json"));
    t["results"][alg]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| {
            let f = r["frequency_radps"].as_f64().unwrap();
            lo - 1e-9 <= f && f <= hi + 1e-9
        })
        .map(|r| r["gain"].as_f64().unwrap())
        .collect()
}

fn min(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
}

#[test]
fn the_readmes_omct_numbers_are_those_of_omct_json() {
    let text = std::fs::read_to_string(repo().join("docs/omct/omct.json")).unwrap();
    let omct: serde_json::Value = serde_json::from_str(&text).unwrap();
    let omct = &omct;
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    // The README's lines are wrapped: compare with single spaces.
    let readme = readme.split_whitespace().collect::<Vec<_>>().join(" ");
    const MPCS: [&str; 2] = ["smpc", "mpc"];
    const ALL: f64 = f64::INFINITY;
    let of = |tests: &[&str], algs: &[&str], lo: f64, hi: f64| -> Vec<f64> {
        tests
            .iter()
            .flat_map(|t| algs.iter().flat_map(move |a| gains(omct, t, a, lo, hi)))
            .collect()
    };
    let surge = of(&["surge"], &MPCS, 0.1, 1.0);
    let cwf_surge = of(&["surge"], &["cwf"], 0.0, ALL);
    let direct: Vec<&str> = omct["tests"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|t| t["cross_coupling"] == false)
        .map(|t| t["test"].as_str().unwrap())
        .collect();
    let rates = ["roll-rate", "pitch-rate"];
    let mpc_rates = of(&rates, &MPCS, 1.0, 4.0);
    let cwf_rates = of(&rates, &["cwf"], 1.0, 4.0);
    // The MPCs' rate gains as a share of the CWF's at the same test and frequency.
    let share = rates
        .iter()
        .flat_map(|t| {
            let cwf = gains(omct, t, "cwf", 1.0, 4.0);
            MPCS.iter().flat_map(move |a| {
                let cwf = cwf.clone();
                gains(omct, t, a, 1.0, 4.0)
                    .into_iter()
                    .zip(cwf)
                    .map(|(m, c)| m / c)
            })
        })
        .fold(f64::INFINITY, f64::min);
    let yaw = of(&["yaw-rate"], &MPCS, 1.0, 4.0);
    let expected = [
        format!(
            "gain of {:.2}–{:.2} from 0.1 to 1 rad/s",
            min(&surge),
            max(&surge)
        ),
        format!(
            "the CWF gives {:.2} at 0.1 rad/s and dips to {:.2}",
            gains(omct, "surge", "cwf", 0.1, 0.1)[0],
            min(&cwf_surge)
        ),
        format!(
            "largest gain on any direct test is {:.2}",
            max(&of(&direct, &MPCS, 0.0, ALL))
        ),
        format!(
            "gains are {:.2}–{:.2}, against the CWF's {:.2}–{:.2} (at least {:.2} of it)",
            min(&mpc_rates),
            max(&mpc_rates),
            min(&cwf_rates),
            max(&cwf_rates),
            // "At least": rounded down.
            (share * 100.0).floor() / 100.0
        ),
        format!("yaw rate is {:.2}–{:.2}", min(&yaw), max(&yaw)),
        format!(
            "its gain is at most {:.2}, against the CWF's {:.2}",
            max(&of(&["heave"], &MPCS, 0.0, ALL)),
            max(&of(&["heave"], &["cwf"], 0.0, ALL))
        ),
    ];
    for want in expected {
        assert!(
            readme.contains(&want),
            "the README does not say {want:?} (docs/omct/omct.json)"
        );
    }
}

/// The README's workspace figures (the share of the S-MPC's steps the limiter changed and
/// its peak leg usage on the stall, the take-off and the landing) are those of `hexcue play
/// --headless --trace recordings/traces/NAME.csv` (the S-MPC alone: its figures do not
/// depend on the other lanes).
#[test]
fn the_readmes_limiter_shares_are_what_play_gives() {
    let dir = tempfile::tempdir().unwrap();
    let mut shares = Vec::new();
    let mut peaks = Vec::new();
    for name in ["horizontal-stall", "takeoff", "landing"] {
        let trace = repo().join(format!("recordings/traces/{name}.csv"));
        let summary = dir.path().join(format!("{name}.json"));
        let out = common::hexcue(&[
            "play".as_ref(),
            "--headless".as_ref(),
            "--algorithms".as_ref(),
            "smpc".as_ref(),
            "--trace".as_ref(),
            trace.as_os_str(),
            "--summary".as_ref(),
            summary.as_os_str(),
        ]);
        assert!(out.status.success(), "{name}: {}", common::stderr(&out));
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
        let smpc = &json["algorithms"]["smpc"];
        shares.push(100.0 * smpc["limiter_fraction"].as_f64().unwrap());
        peaks.push(100.0 * smpc["max_leg_usage"].as_f64().unwrap());
    }
    let want = format!(
        "The limiter acted on {:.2} % of the S-MPC's steps on the stall, {:.2} % on the \
         take-off and {:.2} % on the landing (peak leg usage {:.1} %, {:.1} %, {:.1} %)",
        shares[0], shares[1], shares[2], peaks[0], peaks[1], peaks[2]
    );
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    let readme = readme.split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(readme.contains(&want), "the README does not say {want:?}");
}
