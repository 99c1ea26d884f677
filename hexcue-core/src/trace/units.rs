//! Unit and sign checks on a flight's samples (docs/formats.md, "Units and signs"): numbers
//! that pass the range checks but mean something else. Gathered one sample at a time, so that
//! a trace streamed from its file and a live simulator's first seconds are checked without
//! being held.

use nalgebra::Vector3;

use crate::trace::AircraftSample;
use crate::G_MPS2;

/// Thresholds of the checks.
mod limits {
    /// Trace time at the start that stands for "at rest or trimmed" (s).
    pub const START_S: f64 = 1.0;
    /// |f| within this factor of 1 g in the other unit counts as that unit.
    pub const UNIT_TOLERANCE: f64 = 0.2;
    /// Median fz above this (m/s², half a g, positive = up) at the start and over the whole
    /// trace is a z-up convention.
    pub const Z_UP_MPS2: f64 = 4.9;
    /// Rate magnitude (rad/s, 115°/s) beyond which a light aircraft does not stay long...
    pub const FAST_RATE_RADPS: f64 = 2.0;
    /// ...for this long in total (s) and this share of the trace.
    pub const FAST_FOR_S: f64 = 2.0;
    pub const FAST_SHARE: f64 = 0.1;
    /// The attitude check needs this much attitude motion (RMS Euler rate, rad/s: 0.06°/s,
    /// 25× the noise that six decimals at 100 Hz leave in a finite difference)...
    pub const MIN_ATTITUDE_RMS_RADPS: f64 = 0.001;
    /// ...and rates that explain it this well (correlation of the Euler rates from p, q, r
    /// with the attitude's derivative) to decide.
    pub const MIN_CORRELATION: f64 = 0.9;
    /// Fitted ratio (attitude's derivative / Euler rates from p, q, r) inside this band means
    /// p, q, r are 57.3× too large (°/s); its inverse band means the attitude is in degrees.
    pub const DEG_BAND: (f64, f64) = (1.0 / 80.0, 1.0 / 40.0);
    /// A decided fit whose ratio is inside this band says the units agree.
    pub const SAME_BAND: (f64, f64) = (0.8, 1.25);
    /// Pitch beyond which the Euler kinematics are too ill-conditioned to use (|cos θ| <).
    pub const MIN_COS_THETA: f64 = 0.3;
    /// A step of the attitude faster than this (rad/s) is a wrap the other convention makes,
    /// or a glitch: left out of the fit rather than let one pair decide it.
    pub const MAX_ATTITUDE_STEP_RADPS: f64 = 20.0;
    /// Euler angles cannot leave these ranges (roll ±π, pitch ±π/2), with a margin for
    /// rounding; beyond them the attitude is in degrees.
    pub const MAX_ROLL_RAD: f64 = std::f64::consts::PI + 0.01;
    pub const MAX_PITCH_RAD: f64 = std::f64::consts::FRAC_PI_2 + 0.01;
}

const FT_PER_M: f64 = 1.0 / 0.3048;

pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Values kept for a median in bounded memory: every value up to [`UnitStats::KEPT`], then
/// every second, fourth, ... (the stride doubles whenever the store is full), so the median
/// is exact for traces up to that length and a uniform subsample's beyond it.
#[derive(Clone, Debug, Default)]
pub(crate) struct Thinned {
    pub(crate) values: Vec<f64>,
    pub(crate) stride: usize,
    seen: usize,
}

impl Thinned {
    pub(crate) fn push(&mut self, v: f64) {
        self.stride = self.stride.max(1);
        if self.seen.is_multiple_of(self.stride) {
            if self.values.len() >= UnitStats::KEPT {
                let mut i = 0;
                self.values.retain(|_| {
                    i += 1;
                    i % 2 == 1
                });
                self.stride *= 2;
            }
            if self.seen.is_multiple_of(self.stride) {
                self.values.push(v);
            }
        }
        self.seen += 1;
    }
}

/// Running sums of the least-squares fit b ≈ s·a of the attitude's derivative b to the
/// Euler rates a that p, q, r give, under one reading of the attitude's unit.
#[derive(Clone, Copy, Debug, Default)]
struct Fit {
    sab: f64,
    saa: f64,
    sbb: f64,
    pairs: usize,
}

/// What a [`Fit`] says.
#[derive(Clone, Copy, Debug, PartialEq)]
enum FitOutcome {
    /// The attitude moves too little, or the rates do not explain it well enough.
    Undecided { rms_radps: f64, correlation: f64 },
    /// The ratio s of the attitude's derivative to the Euler rates from p, q, r.
    Ratio(f64),
}

impl Fit {
    /// One pair of consecutive samples, the attitude read as radians times `to_rad`.
    fn push(&mut self, w0: &AircraftSample, w1: &AircraftSample, to_rad: f64) {
        let wrap = |d: f64| d - std::f64::consts::TAU * (d / std::f64::consts::TAU).round();
        let dt = w1.t_s - w0.t_s;
        let att = (w0.attitude_rad + w1.attitude_rad) * (to_rad / 2.0);
        let rate = (w0.angular_velocity_radps + w1.angular_velocity_radps) / 2.0;
        let (sp, cp) = att.x.sin_cos();
        let (st, ct) = att.y.sin_cos();
        if ct.abs() < limits::MIN_COS_THETA || dt <= 0.0 {
            return;
        }
        let (p, q, r) = (rate.x, rate.y, rate.z);
        let a = Vector3::new(
            p + (q * sp + r * cp) * st / ct,
            q * cp - r * sp,
            (q * sp + r * cp) / ct,
        );
        // Roll and heading wrap (±π or 0…2π, in either unit once converted); pitch does not.
        let d = (w1.attitude_rad - w0.attitude_rad) * to_rad;
        let b = Vector3::new(wrap(d.x), d.y, wrap(d.z)) / dt;
        if !(a.iter().chain(b.iter()).all(|v| v.is_finite()))
            || b.amax() > limits::MAX_ATTITUDE_STEP_RADPS
        {
            return;
        }
        self.sab += a.dot(&b);
        self.saa += a.norm_squared();
        self.sbb += b.norm_squared();
        self.pairs += 1;
    }

    fn outcome(&self) -> FitOutcome {
        let (sab, saa, sbb, n) = (self.sab, self.saa, self.sbb, self.pairs);
        let rms_radps = if n > 0 {
            (sbb / (3 * n) as f64).sqrt()
        } else {
            0.0
        };
        let correlation = if saa > 0.0 && sbb > 0.0 {
            sab / (saa * sbb).sqrt()
        } else {
            0.0
        };
        if n >= 10
            && rms_radps >= limits::MIN_ATTITUDE_RMS_RADPS
            && correlation >= limits::MIN_CORRELATION
        {
            FitOutcome::Ratio(sab / saa)
        } else {
            FitOutcome::Undecided {
                rms_radps,
                correlation,
            }
        }
    }
}

/// The statistics the checks decide on: the first second's medians, medians over the whole
/// (of a uniform subsample when long), the attitude's derivative against the body rates with
/// the attitude read as radians and as degrees (running sums), the largest roll and pitch,
/// and the time spent at fast rates.
#[derive(Clone, Debug, Default)]
pub struct UnitStats {
    t0: Option<f64>,
    last_t: f64,
    rows: usize,
    start_norm: Vec<f64>,
    start_fz: Vec<f64>,
    all_norm: Thinned,
    all_fz: Thinned,
    prev: Option<AircraftSample>,
    as_radians: Fit,
    as_degrees: Fit,
    max_roll: f64,
    max_pitch: f64,
    max_rate_radps: f64,
    fast: usize,
}

/// Names of the columns a [`UnitStats`] verdict cites, in the order fx, fy, fz, p, q, r, phi,
/// theta, psi; and what "the whole" is called (`the trace`, `the first 10 s of input`).
pub struct UnitNames<'a> {
    /// The columns' headers as the user wrote them.
    pub columns: [String; 9],
    /// What the statistics cover, in a sentence: `the trace`, `the first 10 s of input`.
    pub whole: &'a str,
    /// Whether the samples have an attitude to check the rates against.
    pub has_attitude: bool,
}

/// What the checks conclude.
#[derive(Clone, Debug, PartialEq)]
pub enum UnitJudgement {
    /// The numbers agree with hexcue's units.
    Believable,
    /// A clear unit or sign mistake: the columns, the evidence and the likely cause.
    Mistake(String),
    /// The data cannot tell: too little motion, or no attitude to compare the rates with.
    /// Says what could not be checked and why.
    Unchecked(String),
}

impl UnitStats {
    /// Values kept per median (2 × 256 KiB at most).
    pub(crate) const KEPT: usize = 1 << 15;

    /// No sample yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Samples pushed.
    pub fn len(&self) -> usize {
        self.rows
    }

    /// Whether no sample was pushed.
    pub fn is_empty(&self) -> bool {
        self.rows == 0
    }

    /// Time from the first sample to the last (s).
    pub fn duration_s(&self) -> f64 {
        self.t0.map_or(0.0, |t0| self.last_t - t0)
    }

    /// One more sample, in SI, in time order.
    pub fn push(&mut self, s: &AircraftSample) {
        let t0 = *self.t0.get_or_insert(s.t_s);
        let norm = s.specific_force_mps2.norm();
        if s.t_s - t0 <= limits::START_S && self.start_norm.len() < Self::KEPT {
            self.start_norm.push(norm);
            self.start_fz.push(s.specific_force_mps2.z);
        }
        self.all_norm.push(norm);
        self.all_fz.push(s.specific_force_mps2.z);
        let rate = s.angular_velocity_radps.amax();
        self.fast += usize::from(rate > limits::FAST_RATE_RADPS);
        self.max_rate_radps = self.max_rate_radps.max(rate);
        self.max_roll = self.max_roll.max(s.attitude_rad.x.abs());
        self.max_pitch = self.max_pitch.max(s.attitude_rad.y.abs());
        if let Some(prev) = self.prev {
            self.as_radians.push(&prev, s, 1.0);
            self.as_degrees.push(&prev, s, std::f64::consts::PI / 180.0);
        }
        self.prev = Some(*s);
        self.last_t = s.t_s;
        self.rows += 1;
    }

    /// The clear mistakes only (see [`UnitStats::judge`]): `None` when the numbers are
    /// believable or cannot be judged.
    pub fn verdict(&self, names: &UnitNames) -> Option<String> {
        match self.judge(names) {
            UnitJudgement::Mistake(m) => Some(m),
            _ => None,
        }
    }

    /// The unit and sign mistakes that pass the range checks: a z-up frame (fz ≈ +9.81 at
    /// rest), specific force in ft/s² or in g, attitude in degrees (roll or pitch outside the
    /// Euler ranges, or an attitude that follows the rates once read as degrees), body rates
    /// in °/s (the attitude changing 57.3× slower than they say; without attitude, sustained
    /// rates no light aircraft flies). When none is found but the rates could not be compared
    /// with anything, the judgement says so instead of passing them.
    pub fn judge(&self, names: &UnitNames) -> UnitJudgement {
        if self.rows < 2 {
            return UnitJudgement::Believable;
        }
        if let Some(m) = self.force_mistake(names) {
            return UnitJudgement::Mistake(m);
        }
        let c = &names.columns;
        let rate_columns = format!("`{}`, `{}`, `{}`", c[3], c[4], c[5]);
        let att_columns = format!("`{}`, `{}`, `{}`", c[6], c[7], c[8]);
        let deg_s = "rates in °/s? expected rad/s: multiply by π/180 (0.017453)";
        let deg = "attitude in degrees? expected radians: multiply by π/180 (0.017453)";
        let (lo, hi) = limits::DEG_BAND;
        let is_deg_ratio = |s: f64| (lo..=hi).contains(&s);
        let mut why_unchecked = format!("there is no attitude ({att_columns}) to compare with");
        if names.has_attitude {
            let as_degrees = self.as_degrees.outcome();
            let both = |m: String| {
                match as_degrees {
                FitOutcome::Ratio(s) if is_deg_ratio(s) => format!(
                    "{m}; and read as radians the attitude still changes {:.1}× slower than {rate_columns} say: rates in °/s too (multiply them by π/180 as well)",
                    1.0 / s
                ),
                _ => m,
            }
            };
            for (i, max, range, limit) in [
                (
                    6,
                    self.max_roll,
                    "±π, the Euler roll range",
                    limits::MAX_ROLL_RAD,
                ),
                (
                    7,
                    self.max_pitch,
                    "±π/2, the Euler pitch range",
                    limits::MAX_PITCH_RAD,
                ),
            ] {
                if max > limit {
                    return UnitJudgement::Mistake(both(format!(
                        "columns {att_columns}: |`{}`| reaches {max:.2}, beyond {range}; {deg}",
                        c[i]
                    )));
                }
            }
            let as_radians = self.as_radians.outcome();
            match as_radians {
                FitOutcome::Ratio(s) if is_deg_ratio(s) => {
                    return UnitJudgement::Mistake(format!(
                        "columns {rate_columns}: the attitude ({att_columns}) changes {:.1}× slower than these rates say over {}; {deg_s}",
                        1.0 / s,
                        names.whole
                    ));
                }
                FitOutcome::Ratio(s) if is_deg_ratio(1.0 / s) => {
                    return UnitJudgement::Mistake(format!(
                        "columns {att_columns}: the attitude changes {s:.1}× faster than the rates {rate_columns} say over {}; {deg}",
                        names.whole
                    ));
                }
                // The rates explain the attitude: whatever their size, they are in rad/s.
                FitOutcome::Ratio(s) if in_same_band(s) => return UnitJudgement::Believable,
                _ => {}
            }
            // Read as radians the attitude does not follow the rates; read as degrees it
            // does (roll and pitch stayed small enough to pass the ranges). The reverse, a
            // degree reading 57.3× slower, is what any small-angle flight in radians gives,
            // so it proves nothing.
            if let FitOutcome::Ratio(s) = as_degrees {
                if in_same_band(s) {
                    return UnitJudgement::Mistake(format!(
                        "columns {att_columns}: read as degrees the attitude follows the rates {rate_columns} over {}, read as radians it does not; {deg}",
                        names.whole
                    ));
                }
            }
            why_unchecked = match as_radians {
                FitOutcome::Ratio(s) => format!(
                    "the attitude ({att_columns}) changes {s:.2}× as fast as these rates say, neither the same (1) nor a degree mistake (57.3 either way)"
                ),
                FitOutcome::Undecided { rms_radps, .. }
                    if rms_radps < limits::MIN_ATTITUDE_RMS_RADPS =>
                {
                    format!(
                        "the attitude ({att_columns}) barely moves (RMS rate {:.3}°/s, below the {:.2}°/s needed)",
                        rms_radps.to_degrees(),
                        limits::MIN_ATTITUDE_RMS_RADPS.to_degrees()
                    )
                }
                FitOutcome::Undecided { correlation, .. } => format!(
                    "the attitude ({att_columns}) does not follow these rates (correlation {correlation:.2}, below the {} needed)",
                    limits::MIN_CORRELATION
                ),
            };
        }
        let dt = self.duration_s() / (self.rows - 1) as f64;
        let fast_s = self.fast as f64 * dt;
        let share = self.fast as f64 / self.rows as f64;
        if fast_s >= limits::FAST_FOR_S && share >= limits::FAST_SHARE {
            return UnitJudgement::Mistake(format!(
                "columns {rate_columns}: a rate beyond {} rad/s ({:.0}°/s) for {fast_s:.1} s ({:.0} % of {}); {deg_s}",
                limits::FAST_RATE_RADPS,
                limits::FAST_RATE_RADPS.to_degrees(),
                100.0 * share,
                names.whole
            ));
        }
        UnitJudgement::Unchecked(format!(
            "the units of columns {rate_columns} could not be checked: {why_unchecked}, and their largest value ({:.3}) is believable in rad/s and in °/s alike; they are used as rad/s: make sure they are",
            self.max_rate_radps
        ))
    }

    /// Specific force in ft/s² or g, or a z-up frame.
    fn force_mistake(&self, names: &UnitNames) -> Option<String> {
        let whole = names.whole;
        let c = &names.columns;
        let norm_start = median(self.start_norm.clone());
        let norm_all = median(self.all_norm.values.clone());
        let near = |v: f64, unit: f64| (v - unit).abs() <= limits::UNIT_TOLERANCE * unit;
        let f_columns = format!("`{}`, `{}`, `{}`", c[0], c[1], c[2]);
        if near(norm_start, G_MPS2 * FT_PER_M) && near(norm_all, G_MPS2 * FT_PER_M) {
            return Some(format!(
                "columns {f_columns}: |f| is {norm_start:.2} at the start (median of the first second) and {norm_all:.2} over {whole}, which is 1 g in ft/s² (32.17); expected m/s² (9.81): multiply by 0.3048 (JSBSim's `accelerations/a-pilot-*-ft_sec2` headers are converted when kept as JSBSim writes them)"
            ));
        }
        if near(norm_start, 1.0) && near(norm_all, 1.0) {
            return Some(format!(
                "columns {f_columns}: |f| is {norm_start:.2} at the start and {norm_all:.2} over {whole}, which is 1 g as a load factor; expected m/s² (9.81): multiply by 9.80665"
            ));
        }
        let fz_start = median(self.start_fz.clone());
        let fz_all = median(self.all_fz.values.clone());
        if fz_start > limits::Z_UP_MPS2 && fz_all > 0.0 {
            return Some(format!(
                "column `{}`: fz is {fz_start:+.2} m/s² at the start (median of the first second) and {fz_all:+.2} over {whole}: a z-up convention? hexcue's head frame has z down, so rest and level flight give fz = −9.81; negate fz (a z-up frame usually flips y, q and r as well)",
                c[2]
            ));
        }
        None
    }
}

fn in_same_band(s: f64) -> bool {
    (limits::SAME_BAND.0..=limits::SAME_BAND.1).contains(&s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(has_attitude: bool) -> UnitNames<'static> {
        UnitNames {
            columns: ["fx", "fy", "fz", "p", "q", "r", "phi", "theta", "psi"].map(String::from),
            whole: "the trace",
            has_attitude,
        }
    }

    /// A quiet flight at 100 Hz: a gentle pitch and heading change (0.2°/s RMS), the attitude
    /// integrated from the rates.
    fn quiet(rate_scale: f64, attitude_scale: f64, seconds: f64) -> UnitStats {
        let mut stats = UnitStats::new();
        let (mut theta, mut psi) = (0.02f64, 6.2f64);
        for k in 0..=(seconds * 100.0) as usize {
            let t = k as f64 / 100.0;
            let q = 0.004 * (0.3 * t).sin();
            let r = 0.003 * (0.2 * t).cos();
            let (phi, wrapped) = (0.0, psi.rem_euclid(std::f64::consts::TAU));
            stats.push(&AircraftSample {
                t_s: t,
                specific_force_mps2: Vector3::new(0.3, 0.0, -9.8),
                angular_velocity_radps: Vector3::new(0.0, q, r) * rate_scale,
                attitude_rad: Vector3::new(phi, theta, wrapped) * attitude_scale,
            });
            theta += q * 0.01;
            psi += r / theta.cos() * 0.01;
        }
        stats
    }

    #[test]
    fn a_quiet_flight_is_judged_by_the_attitude_however_little_it_moves() {
        assert_eq!(
            quiet(1.0, 1.0, 60.0).judge(&names(true)),
            UnitJudgement::Believable
        );
        let deg_s = quiet(57.29578, 1.0, 60.0).judge(&names(true));
        match &deg_s {
            UnitJudgement::Mistake(m) => assert!(m.contains("°/s") && m.contains("`p`")),
            other => panic!("{other:?}"),
        }
        // Pitch under 1.6° and the heading wrapping at 360: only the fit read as degrees
        // sees it.
        let deg = quiet(1.0, 57.29578, 60.0).judge(&names(true));
        match &deg {
            UnitJudgement::Mistake(m) => assert!(m.contains("degrees") && m.contains("`phi`")),
            other => panic!("{other:?}"),
        }
        // Both in degrees with small angles reads like both in radians: only the
        // magnitudes could tell, and here they do not, so it is not passed as checked.
        let both = quiet(57.29578, 57.29578, 60.0).judge(&names(true));
        assert_ne!(both, UnitJudgement::Believable);
    }

    #[test]
    fn what_cannot_be_judged_is_said_not_passed() {
        // At rest: no motion to compare.
        let mut rest = UnitStats::new();
        for k in 0..500 {
            rest.push(&AircraftSample {
                t_s: k as f64 / 100.0,
                specific_force_mps2: Vector3::new(0.0, 0.0, -9.81),
                angular_velocity_radps: Vector3::zeros(),
                attitude_rad: Vector3::new(0.0, 0.03, 1.0),
            });
        }
        match rest.judge(&names(true)) {
            UnitJudgement::Unchecked(m) => {
                assert!(
                    m.contains("barely moves") && m.contains("`p`, `q`, `r`"),
                    "{m}"
                )
            }
            other => panic!("{other:?}"),
        }
        // No attitude columns: nothing to compare with.
        match quiet(1.0, 1.0, 20.0).judge(&names(false)) {
            UnitJudgement::Unchecked(m) => assert!(m.contains("no attitude"), "{m}"),
            other => panic!("{other:?}"),
        }
        // The live path asks only for mistakes.
        assert_eq!(rest.verdict(&names(true)), None);
    }

    #[test]
    fn medians_hold_bounded_memory() {
        // Past the kept values the medians are a uniform subsample's: exact before it.
        let mut t = Thinned::default();
        for i in 0..UnitStats::KEPT {
            t.push(i as f64);
        }
        assert_eq!(t.values.len(), UnitStats::KEPT);
        assert_eq!(median(t.values.clone()), (UnitStats::KEPT / 2) as f64);
        for i in UnitStats::KEPT..10 * UnitStats::KEPT {
            t.push(i as f64);
        }
        assert!(t.values.len() <= UnitStats::KEPT, "{}", t.values.len());
        assert!(t.values.windows(2).all(|w| w[1] - w[0] == t.stride as f64));
        let m = median(t.values.clone());
        assert!((m / (5 * UnitStats::KEPT) as f64 - 1.0).abs() < 0.01, "{m}");
    }
}
