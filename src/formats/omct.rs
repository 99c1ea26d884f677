//! The OMCT report: `omct.md` (a table per test, for people) and `omct.json` (for tools).

use serde::Serialize;
use serde_json::{json, Value};

use hexcue_core::mca::AlgorithmId;
use hexcue_core::omct::{frequency_label, OmctCurve, OmctTest};

/// Everything one `hexcue omct` run measured.
#[derive(Clone, Debug)]
pub struct OmctReport {
    pub profile: String,
    pub algorithms: Vec<AlgorithmId>,
    pub tests: Vec<OmctTest>,
    pub frequencies_radps: Vec<f64>,
    pub curves: Vec<OmctCurve>,
}

impl OmctReport {
    fn curve(&self, test: OmctTest, algorithm: AlgorithmId) -> Option<&OmctCurve> {
        self.curves
            .iter()
            .find(|c| c.test == test && c.algorithm == algorithm)
    }

    /// `omct.json`: per test, its units and each algorithm's points (NaN written as null).
    pub fn to_json(&self) -> Value {
        let tests: Vec<Value> = self
            .tests
            .iter()
            .map(|&test| {
                let (i, o) = test.channels();
                let results: serde_json::Map<String, Value> = self
                    .algorithms
                    .iter()
                    .filter_map(|&a| {
                        self.curve(test, a)
                            .map(|c| (a.key().to_string(), to_value(&c.points)))
                    })
                    .collect();
                json!({
                    "test": test.key(),
                    "description": test.description(),
                    "cross_coupling": test.is_cross_coupling(),
                    "input_unit": i.si_unit(),
                    "output_unit": o.si_unit(),
                    "results": results,
                })
            })
            .collect();
        json!({
            "tool": "hexcue",
            "tool_version": env!("CARGO_PKG_VERSION"),
            "profile": self.profile,
            "algorithms": self.algorithms.iter().map(|a| a.key()).collect::<Vec<_>>(),
            "frequencies_radps": self.frequencies_radps,
            "tests": tests,
        })
    }

    /// `omct.md`: a table per test; rotational amplitudes in °/s, as a pilot reads them.
    pub fn to_markdown(&self) -> String {
        let mut s = String::new();
        s.push_str(&format!(
            "# Objective Motion Cueing Test: profile `{}`\n\n",
            self.profile
        ));
        s.push_str(
            "ICAO 9625 OMCT, measured by `hexcue omct`: each aircraft channel is driven by \
             A·sin(ωt) from rest, the platform's response at the pilot's head (after the \
             workspace limiter) is fitted after the transient, and gain = response amplitude / A, \
             phase = the response's phase against the input (negative: a lag), wrapped into \
             (−180°, 180°] here, in omct.json and in the Bode plots (whose phase line breaks \
             where it crosses ±180°): a lead of 5° is +5°, never −355°. Frequencies are the \
             standard's (0.1 to 15.85 rad/s, five a decade). A starts at 0.1 g or 5 °/s and is halved until the limiter stays idle; `*` marks a point at \
             which the limiter still acted at the smallest amplitude tried.\n\n",
        );
        for &test in &self.tests {
            let (i, o) = test.channels();
            let gain_unit = if i.si_unit() == o.si_unit() {
                String::new()
            } else {
                format!(", gain in ({})/({})", o.si_unit(), i.si_unit())
            };
            let amp_unit = i.unit();
            s.push_str(&format!(
                "## {}: {}{}\n\n",
                test.key(),
                test.description(),
                gain_unit
            ));
            let algs: Vec<(AlgorithmId, &OmctCurve)> = self
                .algorithms
                .iter()
                .filter_map(|&a| self.curve(test, a).map(|c| (a, c)))
                .collect();
            s.push_str("| ω (rad/s) |");
            for (a, _) in &algs {
                let l = a.label();
                s.push_str(&format!(" {l} gain | {l} phase (°) | {l} A ({amp_unit}) |"));
            }
            s.push_str("\n|---:|");
            for _ in &algs {
                s.push_str("---:|---:|---:|");
            }
            s.push('\n');
            for (k, w) in self.frequencies_radps.iter().enumerate() {
                s.push_str(&format!("| {} |", frequency_label(*w)));
                for (_, c) in &algs {
                    match c.points.get(k) {
                        Some(p) => {
                            let a = if i.is_rotational() {
                                p.amplitude.to_degrees()
                            } else {
                                p.amplitude
                            };
                            let star = if p.limiter_steps > 0 { " *" } else { "" };
                            s.push_str(&format!(
                                " {} | {} | {}{star} |",
                                num(p.gain, 4),
                                num(p.phase_deg, 1),
                                num(a, 3)
                            ));
                        }
                        None => s.push_str(" – | – | – |"),
                    }
                }
                s.push('\n');
            }
            s.push('\n');
        }
        s
    }
}

/// A number with `digits` significant-ish decimals; `–` for one that was not measured.
fn num(v: f64, decimals: usize) -> String {
    if !v.is_finite() {
        "–".to_string()
    } else if v != 0.0 && v.abs() < 10f64.powi(-(decimals as i32)) {
        format!("{v:.2e}")
    } else {
        format!("{v:.decimals$}")
    }
}

fn to_value<T: Serialize>(v: &T) -> Value {
    serde_json::to_value(v).unwrap_or(Value::Null)
}

#[cfg(test)]
mod tests {
    use super::*;
    use hexcue_core::omct::OmctPoint;

    #[test]
    fn report_tables_and_json() {
        let p = |w: f64| OmctPoint {
            frequency_radps: w,
            amplitude: 0.0872665,
            gain: 0.5,
            phase_deg: 30.0,
            limiter_steps: usize::from(w > 1.0),
            residual: 0.0,
        };
        let r = OmctReport {
            profile: "full-flight".into(),
            algorithms: vec![AlgorithmId::Cwf],
            tests: vec![OmctTest::PitchRate],
            frequencies_radps: vec![0.1, 2.0],
            curves: vec![OmctCurve {
                test: OmctTest::PitchRate,
                algorithm: AlgorithmId::Cwf,
                input_unit: "rad/s",
                output_unit: "rad/s",
                points: vec![p(0.1), p(2.0)],
            }],
        };
        let md = r.to_markdown();
        assert!(md.contains("## pitch-rate"), "{md}");
        assert!(md.contains("| 0.1 | 0.5000 | 30.0 | 5.000 |"), "{md}");
        assert!(md.contains("| 2 | 0.5000 | 30.0 | 5.000 * |"), "{md}");
        let j = r.to_json();
        assert_eq!(j["tests"][0]["test"], "pitch-rate");
        assert_eq!(j["tests"][0]["results"]["cwf"][1]["gain"], 0.5);
        assert_eq!(num(f64::NAN, 2), "–");
        assert_eq!(num(1e-5, 4), "1.00e-5");
    }
}
