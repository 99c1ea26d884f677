//! The flight library (`recordings/traces/library`, made by `scripts/make-library.py`; issue
//! #23), embedded so that `hexcue compare` runs it by default from any directory, as it ran
//! the five shipped traces before.

use super::trace::{embedded_traces, TraceError};
use hexcue_core::trace::Trace;

/// Where the library's files are in the repository.
pub const LIBRARY_FOLDER: &str = "recordings/traces/library";

macro_rules! flight {
    ($name:literal) => {
        (
            $name,
            include_str!(concat!("../../recordings/traces/library/", $name, ".csv")),
            include_str!(concat!("../../recordings/traces/library/", $name, ".json")),
        )
    };
}

/// Every flight of the library: (name, CSV, sidecar JSON), in name order.
pub const LIBRARY_TRACES: [(&str, &str, &str); 23] = [
    flight!("737-crosswind-landing"),
    flight!("737-dutch-roll"),
    flight!("737-engine-failure-v1"),
    flight!("737-go-around"),
    flight!("737-hard-landing"),
    flight!("737-rejected-takeoff"),
    flight!("737-stall-wing-drop"),
    flight!("737-steep-turns"),
    flight!("737-takeoff"),
    flight!("737-turbulence-light"),
    flight!("737-turbulence-severe"),
    flight!("737-upset-nose-high"),
    flight!("737-upset-nose-low"),
    flight!("737-wake-encounter"),
    flight!("737-windshear-approach"),
    flight!("c172p-crosswind-landing"),
    flight!("c172p-rough-taxi"),
    flight!("c172p-spiral-dive"),
    flight!("c172p-turbulence-moderate"),
    flight!("f16-afterburner-takeoff"),
    flight!("f16-pitch-doublet"),
    flight!("f16-roll-doublet"),
    flight!("f16-windup-turn"),
];

/// The library's flights (embedded), in name order, at `target_rate_hz`, with their sidecars.
pub fn library_traces(target_rate_hz: f64) -> Result<Vec<Trace>, TraceError> {
    embedded_traces(&LIBRARY_TRACES, LIBRARY_FOLDER, target_rate_hz)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    #[test]
    fn the_embedded_library_is_the_folder() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/recordings/traces/library");
        let mut on_disk: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter_map(|e| {
                e.file_name()
                    .to_str()?
                    .strip_suffix(".csv")
                    .map(String::from)
            })
            .collect();
        on_disk.sort();
        let embedded: Vec<&str> = LIBRARY_TRACES.iter().map(|(n, _, _)| *n).collect();
        assert_eq!(
            on_disk, embedded,
            "run scripts/make-library.py, then list its flights here"
        );
        for (name, csv, _) in LIBRARY_TRACES {
            let file = std::fs::read_to_string(format!("{dir}/{name}.csv")).unwrap();
            assert!(
                file == csv,
                "{name}: the embedded copy differs from the file"
            );
        }
    }

    #[test]
    fn every_flight_loads_with_its_sidecar_and_the_library_spans_what_issue_23_asks() {
        let traces = library_traces(100.0).unwrap();
        assert!(traces.len() >= 20, "{}", traces.len());
        let mut aircraft = BTreeSet::new();
        let mut kinds = BTreeSet::new();
        for ((name, _, json), t) in LIBRARY_TRACES.iter().zip(&traces) {
            assert_eq!(t.rate_hz, 100.0, "{name}");
            assert!(t.notices.is_empty(), "{name}: {:?}", t.notices);
            let d = t.duration_s();
            assert!((29.0..=90.0).contains(&d), "{name}: {d} s");
            let info = t
                .info
                .as_ref()
                .unwrap_or_else(|| panic!("{name}: no sidecar"));
            assert!(!info.events.is_empty(), "{name}: no events");
            aircraft.insert(info.aircraft.clone().unwrap());
            let v: serde_json::Value = serde_json::from_str(json).unwrap();
            for key in [
                "kind",
                "seed",
                "jsbsim_version",
                "command",
                "units",
                "conventions",
            ] {
                assert!(v.get(key).is_some(), "{name}: no `{key}`");
            }
            kinds.insert(v["kind"].as_str().unwrap().to_string());
            // The script checks a-pilot, re-aligned by one step, against the specific force
            // rebuilt from that step's forces: within 0.15 m/s² on the most violent flights
            // (Dutch roll, roll doublet), and at least 3 times closer than without it.
            let check = v["crosscheck_max_abs_diff_specific_force_m_s2"]
                .as_f64()
                .unwrap();
            let unaligned = v["crosscheck_without_realignment_m_s2"].as_f64().unwrap();
            assert!(
                check < 0.2 && 3.0 * check < unaligned,
                "{name}: {check}, {unaligned}"
            );
        }
        let aircraft: Vec<&str> = aircraft.iter().map(String::as_str).collect();
        assert_eq!(aircraft, ["737", "c172p", "f16"]);
        let kinds: Vec<&str> = kinds.iter().map(String::as_str).collect();
        assert_eq!(
            kinds,
            ["approach", "ground", "manoeuvre", "turbulence", "upset"]
        );
    }
}
