//! Jolts: abrupt onsets of what the pilot's body gets at the head (DESIGN §12, issue #33).
//!
//! The onset of a channel at step k is its change over the last window, o_k = s_k − s_{k−N}
//! with N steps = [`JOLT_WINDOW_S`]: for fx, fy, fz the platform's specific force at the head
//! (Δf, m/s²), what the seat and the body push with, not the otoliths' perceived signal; for
//! the rotations the angular velocity at the head (rad/s), whose change over the window is
//! the mean angular acceleration over it times the window. An onset is a jolt when it exceeds
//! the channel's onset threshold ([`onset_thresholds`]); consecutive steps above it, or runs
//! closer together than one window, are one jolt (a 50 ms pulse is one jolt, not its rise and
//! its fall). The aircraft's onsets are measured the same way, and an onset is *charged* to
//! the algorithm only by how far it lies outside the range of the aircraft's own onsets over
//! the last [`ALLOWANCE_WINDOWS`] windows (and 0): a touchdown passed through is the flight's
//! jolt, not the algorithm's; a jolt in the other direction, or bigger than the aircraft's, or
//! where the aircraft had none, is the algorithm's. docs/tuning.md argues the window, the
//! thresholds and this rule.
//!
//! Constant memory: two ring buffers of a few windows per run, allocated once.

use serde::{Deserialize, Serialize};

use crate::model::vestibular::VestibularParams;

/// The window over which an onset is measured (s).
pub const JOLT_WINDOW_S: f64 = 0.1;
/// How far back the aircraft's own onsets excuse the simulator's, in windows: a causal cue
/// follows the aircraft through filters and the limiter by a few steps, never ahead of it.
pub const ALLOWANCE_WINDOWS: usize = 2;

/// One channel's jolts over a run, as the summary reports them (`metrics[ch].jolts`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Jolts {
    /// Jolts at the head: onsets above the threshold, whoever caused them.
    pub count: u64,
    /// The largest onset at the head: m/s² of specific-force change (fx, fy, fz) or rad/s of
    /// angular-velocity change (wx, wy, wz) within [`JOLT_WINDOW_S`].
    pub worst: f64,
    /// Jolts beyond what the aircraft had at that time: the algorithm's own.
    #[serde(default)]
    pub charged: u64,
    /// The largest onset beyond the aircraft's (same units as `worst`).
    #[serde(default)]
    pub charged_worst: f64,
}

/// Steps in the onset window at a rate (at least one).
pub fn window_steps(rate_hz: f64) -> usize {
    ((JOLT_WINDOW_S * rate_hz).round() as usize).max(1)
}

/// The otoliths' response at `t_s` to a unit step of specific force from rest:
/// K(Γa s+1)/((ΓL s+1)(Γs s+1)) by partial fractions,
/// y(t) = K[1 − (ΓL−Γa)/(ΓL−Γs)·e^(−t/ΓL) − (Γs−Γa)/(Γs−ΓL)·e^(−t/Γs)].
pub fn otolith_step_response(v: &VestibularParams, t_s: f64) -> f64 {
    let (k, la, ll, ls) = (
        v.otolith_gain,
        v.otolith_lead_s,
        v.otolith_long_s,
        v.otolith_short_s,
    );
    k * (1.0
        - (ll - la) / (ll - ls) * (-t_s / ll).exp()
        - (ls - la) / (ls - ll) * (-t_s / ls).exp())
}

/// A canal's response at `t_s` to a unit step of angular velocity from rest:
/// T_L·T_a·s / ((T_L s+1)(T_a s+1)(T_S s+1)) = (1/T_S)·s / ((s+a)(s+b)(s+c)) with a, b, c the
/// inverse time constants, by partial fractions.
pub fn canal_step_response(v: &VestibularParams, axis: usize, t_s: f64) -> f64 {
    let p = [
        1.0 / v.canal_tl_s[axis],
        1.0 / v.canal_ta_s,
        1.0 / v.canal_ts_s,
    ];
    let mut y = 0.0;
    for i in 0..3 {
        let (a, b, c) = (p[i], p[(i + 1) % 3], p[(i + 2) % 3]);
        y += -a / ((b - a) * (c - a)) * (-a * t_s).exp();
    }
    y / v.canal_ts_s
}

/// Each channel's onset threshold (fx, fy, fz in m/s², wx, wy, wz in rad/s): the smallest
/// step, made at the start of a window, that the profile's own vestibular model perceives
/// above its perception threshold by the window's end. An onset that large is felt as it
/// happens, within the window, not only once the motion has built up: a jolt, not a cue.
pub fn onset_thresholds(v: &VestibularParams, window_s: f64) -> [f64; 6] {
    let oto = otolith_step_response(v, window_s);
    let canal = v.canal_threshold_radps();
    std::array::from_fn(|c| {
        if c < 3 {
            v.otolith_threshold_mps2[c] / oto
        } else {
            canal[c - 3] / canal_step_response(v, c - 3, window_s)
        }
    })
}

/// The change of six signals over the last `n` steps, 0 until `n` steps have been seen.
#[derive(Clone, Debug)]
pub struct OnsetWindow {
    history: Vec<[f64; 6]>,
    seen: usize,
}

impl OnsetWindow {
    /// A window of `n` steps (at least one).
    pub fn new(n: usize) -> Self {
        OnsetWindow {
            history: vec![[0.0; 6]; n.max(1) + 1],
            seen: 0,
        }
    }

    /// The onset at this step.
    pub fn push(&mut self, s: &[f64; 6]) -> [f64; 6] {
        let cap = self.history.len();
        let slot = self.seen % cap;
        self.history[slot] = *s;
        self.seen += 1;
        if self.seen < cap {
            return [0.0; 6];
        }
        // The slot after this one holds the sample n steps back.
        let past = self.history[(slot + 1) % cap];
        std::array::from_fn(|c| s[c] - past[c])
    }
}

/// Events of one channel: runs above a threshold, merged when closer than `gap` steps.
#[derive(Clone, Copy, Debug, Default)]
struct EventCounter {
    count: u64,
    worst: f64,
    /// Steps since the last step above the threshold; `None` before the first.
    since_above: Option<usize>,
}

impl EventCounter {
    fn push(&mut self, value: f64, threshold: f64, gap: usize) {
        self.worst = self.worst.max(value);
        if value > threshold {
            if self.since_above.is_none_or(|s| s >= gap) {
                self.count += 1;
            }
            self.since_above = Some(0);
        } else if let Some(s) = self.since_above.as_mut() {
            *s += 1;
        }
    }
}

/// The aircraft's onsets: its own jolts, and the range each channel's onsets spanned over the
/// allowance (with 0), which the simulator's onsets are charged beyond.
#[derive(Clone, Debug)]
pub struct AircraftOnsets {
    window: OnsetWindow,
    recent: Vec<[f64; 6]>,
    seen: usize,
    thresholds: [f64; 6],
    gap: usize,
    events: [EventCounter; 6],
}

impl AircraftOnsets {
    /// The aircraft's onsets, judged against the six onset thresholds (m/s² for fx, fy, fz; rad/s
    /// for wx, wy, wz) over a window of `window_steps` steps ([`window_steps`]).
    pub fn new(thresholds: [f64; 6], window_steps: usize) -> Self {
        let n = window_steps.max(1);
        AircraftOnsets {
            window: OnsetWindow::new(n),
            recent: vec![[0.0; 6]; ALLOWANCE_WINDOWS * n + 1],
            seen: 0,
            thresholds,
            gap: n,
            events: [EventCounter::default(); 6],
        }
    }

    /// One step of the aircraft (Δf at the head, m/s², and body rates, rad/s); returns each
    /// channel's allowance (lowest, highest onset recently, 0 included).
    pub fn push(&mut self, signal: &[f64; 6]) -> [(f64, f64); 6] {
        let onset = self.window.push(signal);
        let cap = self.recent.len();
        self.recent[self.seen % cap] = onset;
        self.seen += 1;
        for (c, e) in self.events.iter_mut().enumerate() {
            e.push(onset[c].abs(), self.thresholds[c], self.gap);
        }
        let filled = self.seen.min(cap);
        std::array::from_fn(|c| {
            self.recent[..filled]
                .iter()
                .fold((0.0_f64, 0.0_f64), |(lo, hi), o| {
                    (lo.min(o[c]), hi.max(o[c]))
                })
        })
    }

    /// The aircraft's own jolts per channel (`charged` as `count`: nothing excuses them).
    pub fn jolts(&self) -> [Jolts; 6] {
        self.events.map(|e| Jolts {
            count: e.count,
            worst: e.worst,
            charged: e.count,
            charged_worst: e.worst,
        })
    }
}

/// One algorithm's jolts at the head, all of them and those beyond the aircraft's, and the
/// supra-threshold part of its charged onsets for the score.
#[derive(Clone, Debug)]
pub struct JoltAccumulator {
    window: OnsetWindow,
    thresholds: [f64; 6],
    gap: usize,
    all: [EventCounter; 6],
    charged: [EventCounter; 6],
    /// Σ_k max(e_k/θ − 1, 0) of the charged onsets e, per channel.
    excess_sum: [f64; 6],
}

impl JoltAccumulator {
    /// An empty accumulator for six onset thresholds (m/s², rad/s) over a window of
    /// `window_steps` steps ([`window_steps`]).
    pub fn new(thresholds: [f64; 6], window_steps: usize) -> Self {
        JoltAccumulator {
            window: OnsetWindow::new(window_steps),
            thresholds,
            gap: window_steps.max(1),
            all: [EventCounter::default(); 6],
            charged: [EventCounter::default(); 6],
            excess_sum: [0.0; 6],
        }
    }

    /// One step: the simulator's head signal (Δf m/s², angular velocity rad/s) and the
    /// aircraft's allowance at this step ([`AircraftOnsets::push`]).
    pub fn push(&mut self, signal: &[f64; 6], allowance: &[(f64, f64); 6]) {
        let onset = self.window.push(signal);
        for c in 0..6 {
            let (lo, hi) = allowance[c];
            let o = onset[c];
            let charged = (o - hi).max(lo - o).max(0.0);
            let th = self.thresholds[c];
            self.all[c].push(o.abs(), th, self.gap);
            self.charged[c].push(charged, th, self.gap);
            self.excess_sum[c] += (charged / th - 1.0).max(0.0);
        }
    }

    /// Each channel's jolts so far, in the order fx, fy, fz, wx, wy, wz.
    pub fn jolts(&self) -> [Jolts; 6] {
        std::array::from_fn(|c| Jolts {
            count: self.all[c].count,
            worst: self.all[c].worst,
            charged: self.charged[c].count,
            charged_worst: self.charged[c].worst,
        })
    }

    /// Per channel, Σ over the steps of the charged onset's excess over its threshold, in
    /// thresholds (the score's jolt term divides it by the steps and scales it).
    pub fn excess_sum(&self) -> [f64; 6] {
        self.excess_sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::vestibular::Vestibular;
    use nalgebra::Vector3;

    const RATE_HZ: f64 = 100.0;

    fn thresholds() -> [f64; 6] {
        onset_thresholds(&VestibularParams::default(), JOLT_WINDOW_S)
    }

    /// Runs a simulator signal against an aircraft signal; returns the simulator's jolts.
    fn run(sim: &[[f64; 6]], aircraft: &[[f64; 6]]) -> ([Jolts; 6], [f64; 6]) {
        let n = window_steps(RATE_HZ);
        let mut ac = AircraftOnsets::new(thresholds(), n);
        let mut acc = JoltAccumulator::new(thresholds(), n);
        for (s, a) in sim.iter().zip(aircraft) {
            let allowance = ac.push(a);
            acc.push(s, &allowance);
        }
        (acc.jolts(), acc.excess_sum())
    }

    /// 20 s of nothing with a 50 ms pulse of `size` on channel `c` at 10 s.
    fn quiet_with_pulse(c: usize, size: f64) -> Vec<[f64; 6]> {
        (0..2000)
            .map(|k| {
                let mut s = [0.0; 6];
                if (1000..1005).contains(&k) {
                    s[c] = size;
                }
                s
            })
            .collect()
    }

    #[test]
    fn the_step_responses_match_the_discretised_model() {
        // An independent derivation: the exact (ZOH) integrated model stepped at 1 kHz.
        let v = VestibularParams::default();
        let dt = 0.001;
        let mut oto = Vestibular::new(&v, dt);
        let mut canal = Vestibular::new(&v, dt);
        let (mut f_model, mut w_model) = (0.0, 0.0);
        for _ in 0..100 {
            f_model = oto
                .step(&Vector3::new(1.0, 0.0, 0.0), &Vector3::zeros())
                .channel(0);
            w_model = canal
                .step(&Vector3::zeros(), &Vector3::new(0.0, 0.0, 1.0))
                .channel(5);
        }
        // The model's output after 100 held steps lies between the responses at 99 and 100 ms.
        let between = |y: f64, f: &dyn Fn(f64) -> f64| {
            let (a, b) = (f(0.099), f(0.100));
            y >= a.min(b) - 1e-9 && y <= a.max(b) + 1e-9
        };
        assert!(
            between(f_model, &|t| otolith_step_response(&v, t)),
            "{f_model} vs {}",
            otolith_step_response(&v, 0.1)
        );
        assert!(
            between(w_model, &|t| canal_step_response(&v, 2, t)),
            "{w_model} vs {}",
            canal_step_response(&v, 2, 0.1)
        );
        // Both start from rest, and the otoliths settle at K, the canals back at 0.
        assert!(otolith_step_response(&v, 0.0).abs() < 1e-12);
        assert!(canal_step_response(&v, 0, 0.0).abs() < 1e-12);
        assert!((otolith_step_response(&v, 200.0) - v.otolith_gain).abs() < 1e-9);
        assert!(canal_step_response(&v, 0, 500.0).abs() < 1e-6);
    }

    #[test]
    fn the_thresholds_are_steps_felt_within_the_window() {
        let th = thresholds();
        // By hand: K[1 + 1.6852·e^(−0.1/5.33) − 2.6852·e^(−0.1/0.66)] = 0.1385 at 0.1 s, so
        // 0.17 / 0.1385 and 0.28 / 0.1385; the roll canal gives 0.625, so 3 °/s / 0.625.
        assert!((th[0] - 1.227).abs() < 0.005, "{th:?}");
        assert!((th[1] - th[0]).abs() < 1e-12);
        assert!((th[2] - 2.021).abs() < 0.005, "{th:?}");
        assert!((th[3].to_degrees() - 4.80).abs() < 0.02, "{th:?}");
    }

    #[test]
    fn a_50_ms_pulse_of_3_mps2_in_a_quiet_trace_is_one_jolt() {
        for c in [0, 2] {
            let sim = quiet_with_pulse(c, 3.0);
            let still = vec![[0.0; 6]; sim.len()];
            let (j, excess) = run(&sim, &still);
            assert_eq!(j[c].count, 1, "channel {c}: {:?}", j[c]);
            assert_eq!(j[c].charged, 1, "channel {c}: {:?}", j[c]);
            assert!((j[c].worst - 3.0).abs() < 1e-12 && (j[c].charged_worst - 3.0).abs() < 1e-12);
            assert!(excess[c] > 0.0);
            for other in (0..6).filter(|&o| o != c) {
                assert_eq!(j[other].count, 0);
            }
        }
    }

    #[test]
    fn a_longer_pulse_is_felt_at_its_start_and_its_end() {
        let sim: Vec<[f64; 6]> = (0..2000)
            .map(|k| {
                [
                    if (1000..1050).contains(&k) { 3.0 } else { 0.0 },
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                ]
            })
            .collect();
        let (j, _) = run(&sim, &vec![[0.0; 6]; 2000]);
        assert_eq!(j[0].count, 2, "{:?}", j[0]);
    }

    #[test]
    fn a_smooth_sinusoid_below_the_onset_threshold_is_no_jolt() {
        // 1.5 m/s² at 1 rad/s: it changes by at most 0.15 m/s² in 0.1 s, well felt as motion
        // but never as a jolt; and a 0.5 rad/s roll-rate sinusoid at 0.5 rad/s likewise.
        let sim: Vec<[f64; 6]> = (0..6000)
            .map(|k| {
                let t = k as f64 / RATE_HZ;
                [
                    1.5 * t.sin(),
                    0.0,
                    1.5 * t.cos() - 1.5,
                    0.5 * (0.5 * t).sin(),
                    0.0,
                    0.0,
                ]
            })
            .collect();
        let (j, excess) = run(&sim, &vec![[0.0; 6]; 6000]);
        for c in 0..6 {
            assert_eq!(j[c].count, 0, "channel {c}: {:?}", j[c]);
            assert_eq!(excess[c], 0.0);
        }
        assert!(j[0].worst > 0.1 && j[0].worst < 0.16, "{:?}", j[0]);
    }

    #[test]
    fn the_aircrafts_own_onset_is_not_charged() {
        // A touchdown in the flight: the cue passes it at 0.6 and a step later.
        let aircraft = quiet_with_pulse(2, 5.0);
        let sim: Vec<[f64; 6]> = (0..aircraft.len())
            .map(|k| {
                let mut s = [0.0; 6];
                if k > 0 {
                    s[2] = 0.6 * aircraft[k - 1][2];
                }
                s
            })
            .collect();
        let (j, excess) = run(&sim, &aircraft);
        assert_eq!(j[2].count, 1, "felt at the head: {:?}", j[2]);
        assert_eq!(j[2].charged, 0, "but the flight's: {:?}", j[2]);
        assert_eq!(excess[2], 0.0);
        // The same jolt the other way, or with no jolt in the flight, is the algorithm's.
        let backwards: Vec<[f64; 6]> = sim.iter().map(|s| s.map(|v| -v)).collect();
        assert_eq!(run(&backwards, &aircraft).0[2].charged, 1);
        assert_eq!(run(&sim, &vec![[0.0; 6]; sim.len()]).0[2].charged, 1);
        // And a cue that jolts twice as hard as the aircraft is charged the difference.
        let harder: Vec<[f64; 6]> = sim.iter().map(|s| s.map(|v| v / 0.6 * 1.6)).collect();
        let (j, _) = run(&harder, &aircraft);
        assert_eq!(j[2].charged, 1);
        assert!((j[2].charged_worst - 3.0).abs() < 1e-9, "{:?}", j[2]);
    }
}
