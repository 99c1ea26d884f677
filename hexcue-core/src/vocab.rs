//! The words every layer shares, at the bottom of the crate so that any module may use them
//! without reaching up: the algorithms, the cueing channels, how a solve ended and why the
//! S-MPC switched, as types with their words (the words are what summaries and recordings
//! store, unchanged), and the error of a parameter value that cannot be (each profile section
//! validates itself where it is defined, next to what it tunes).

/// `1 thing` or `n things`, for counts in messages ("on 1 trace", "on 3 traces").
pub fn plural(n: u64, thing: &str) -> String {
    if n == 1 {
        format!("1 {thing}")
    } else {
        format!("{n} {thing}s")
    }
}

/// A profile value that cannot describe a real simulator.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("`{key}`: {reason}")]
pub struct ProfileError {
    /// Dotted path of the offending key, e.g. `geometry.leg_min_m`.
    pub key: String,
    /// What is wrong with the value and what was expected.
    pub reason: String,
}

/// `Ok` for a finite, strictly positive value, else an error naming the key.
pub(crate) fn positive(key: &str, v: f64) -> Result<(), ProfileError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(ProfileError {
            key: key.to_string(),
            reason: format!("{v}: expected a finite value greater than 0"),
        })
    }
}

/// The algorithms hexcue can run, in the order the console shows them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AlgorithmId {
    /// The switchable MPC (docs/design.md §5).
    Smpc,
    /// The MPC without terminal conditions (docs/design.md §4).
    Mpc,
    /// The classical washout filter (docs/design.md §3).
    Cwf,
}

impl AlgorithmId {
    /// Every algorithm, in the console's column order.
    pub const ALL: &'static [AlgorithmId] =
        &[AlgorithmId::Smpc, AlgorithmId::Mpc, AlgorithmId::Cwf];

    /// Short name used on the command line, in topics (`/cwf/...`) and summaries.
    pub fn key(self) -> &'static str {
        match self {
            AlgorithmId::Smpc => "smpc",
            AlgorithmId::Mpc => "mpc",
            AlgorithmId::Cwf => "cwf",
        }
    }

    /// Name shown to people.
    pub fn label(self) -> &'static str {
        match self {
            AlgorithmId::Smpc => "S-MPC",
            AlgorithmId::Mpc => "MPC",
            AlgorithmId::Cwf => "CWF",
        }
    }

    /// The algorithm a name means: its key or its label, case, blanks, `-` and `_` aside
    /// (`S-MPC`, `s_mpc` and `smpc` are the S-MPC). The one place names are normalised.
    pub fn from_key(name: &str) -> Option<Self> {
        let wanted: String = name
            .chars()
            .filter(|c| !matches!(c, '-' | '_' | ' '))
            .collect::<String>()
            .to_ascii_lowercase();
        Self::ALL.iter().copied().find(|a| a.key() == wanted)
    }
}

/// `--drive smpc`: the values are the keys; the S-MPC also answers to `s-mpc` and `s_mpc`
/// (with `ignore_case`, `S-MPC`), as [`AlgorithmId::from_key`] reads them.
#[cfg(feature = "clap")]
impl clap::ValueEnum for AlgorithmId {
    fn value_variants<'a>() -> &'a [Self] {
        Self::ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        let value = clap::builder::PossibleValue::new(self.key());
        Some(match self {
            AlgorithmId::Smpc => value.aliases(["s-mpc", "s_mpc"]),
            AlgorithmId::Mpc | AlgorithmId::Cwf => value,
        })
    }
}

impl std::fmt::Display for AlgorithmId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.key())
    }
}

/// A cueing channel the metrics judge: the perceived specific force along x, y, z and the
/// perceived angular velocity about them (head frame), in the order of [`Channel::ALL`].
/// In JSON, its key (`fx` … `wz`).
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Channel {
    /// Perceived specific force along x, forward (m/s²).
    Fx,
    /// Perceived specific force along y, right (m/s²).
    Fy,
    /// Perceived specific force along z, down (m/s²).
    Fz,
    /// Perceived angular velocity about x, roll (rad/s).
    Wx,
    /// Perceived angular velocity about y, pitch (rad/s).
    Wy,
    /// Perceived angular velocity about z, yaw (rad/s).
    Wz,
}

impl Channel {
    /// The six channels in the order of a 6-vector: fx, fy, fz, wx, wy, wz.
    pub const ALL: [Channel; 6] = [
        Channel::Fx,
        Channel::Fy,
        Channel::Fz,
        Channel::Wx,
        Channel::Wy,
        Channel::Wz,
    ];

    /// The key in summaries, recordings and on the command line.
    pub const fn key(self) -> &'static str {
        match self {
            Channel::Fx => "fx",
            Channel::Fy => "fy",
            Channel::Fz => "fz",
            Channel::Wx => "wx",
            Channel::Wy => "wy",
            Channel::Wz => "wz",
        }
    }

    /// What a report calls it: the motion a pilot names, and its symbol.
    pub fn label(self) -> &'static str {
        match self {
            Channel::Fx => "surge f̂x",
            Channel::Fy => "sway f̂y",
            Channel::Fz => "heave f̂z",
            Channel::Wx => "roll ω̂x",
            Channel::Wy => "pitch ω̂y",
            Channel::Wz => "yaw ω̂z",
        }
    }

    /// The channel a [`Channel::key`] names.
    pub fn from_key(key: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.key() == key)
    }

    /// A specific force (m/s²) rather than an angular velocity (rad/s).
    pub fn is_force(self) -> bool {
        matches!(self, Channel::Fx | Channel::Fy | Channel::Fz)
    }

    /// Its place in [`Channel::ALL`], and in a 6-vector (Δf x, y, z; ω x, y, z).
    pub fn index(self) -> usize {
        self as usize
    }

    /// An angular velocity (rad/s).
    pub fn is_rotational(self) -> bool {
        !self.is_force()
    }

    /// The SI unit the JSON keeps: m/s² or rad/s.
    pub fn si_unit(self) -> &'static str {
        if self.is_force() {
            "m/s²"
        } else {
            "rad/s"
        }
    }

    /// The unit people read it in: m/s² for forces, °/s for rates (summaries keep SI).
    pub fn unit(self) -> &'static str {
        if self.is_force() {
            "m/s²"
        } else {
            "°/s"
        }
    }

    /// Factor from SI (m/s², rad/s) to [`Channel::unit`].
    pub fn display_scale(self) -> f64 {
        if self.is_force() {
            1.0
        } else {
            180.0 / std::f64::consts::PI
        }
    }
}

impl std::fmt::Display for Channel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.key())
    }
}

/// A degree of freedom of the platform, in pose order: x, y, z (m), roll, pitch, yaw (rad).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Dof {
    /// Surge, along x (m).
    X,
    /// Sway, along y (m).
    Y,
    /// Heave, along z (m).
    Z,
    /// Roll, about x (rad).
    Roll,
    /// Pitch, about y (rad).
    Pitch,
    /// Yaw, about z (rad).
    Yaw,
}

impl Dof {
    /// The six DoFs in pose order, the order of a pose 6-vector.
    pub const ALL: [Dof; 6] = [Dof::X, Dof::Y, Dof::Z, Dof::Roll, Dof::Pitch, Dof::Yaw];

    /// The key in summaries (`max_dof_usage`) and tables.
    pub const fn key(self) -> &'static str {
        match self {
            Dof::X => "x",
            Dof::Y => "y",
            Dof::Z => "z",
            Dof::Roll => "roll",
            Dof::Pitch => "pitch",
            Dof::Yaw => "yaw",
        }
    }

    /// Its place in [`Dof::ALL`], and in a pose 6-vector.
    pub fn index(self) -> usize {
        self as usize
    }
}

impl std::fmt::Display for Dof {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.key())
    }
}

/// An axis of the aircraft's motion as the engine takes it in, before any algorithm: the
/// specific force along x, y, z (as the change from 1 g) and the body rates p, q, r; what
/// the profile's `[input]` limits clip.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum InputAxis {
    /// Specific force along x (m/s²).
    Fx,
    /// Specific force along y (m/s²).
    Fy,
    /// Specific force along z, from 1 g (m/s²).
    Fz,
    /// Roll rate (rad/s).
    P,
    /// Pitch rate (rad/s).
    Q,
    /// Yaw rate (rad/s).
    R,
}

impl InputAxis {
    /// The six axes in the order of the engine's input sample: fx, fy, fz, p, q, r.
    pub const ALL: [InputAxis; 6] = [
        InputAxis::Fx,
        InputAxis::Fy,
        InputAxis::Fz,
        InputAxis::P,
        InputAxis::Q,
        InputAxis::R,
    ];

    /// The key in summaries (`input_clipped`) and messages.
    pub const fn key(self) -> &'static str {
        match self {
            InputAxis::Fx => "fx",
            InputAxis::Fy => "fy",
            InputAxis::Fz => "fz",
            InputAxis::P => "p",
            InputAxis::Q => "q",
            InputAxis::R => "r",
        }
    }

    /// Its place in [`InputAxis::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }
}

impl std::fmt::Display for InputAxis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.key())
    }
}

/// How one QP solve ended, as reports and recordings name it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SolveStatus {
    /// No solve yet (a report before the first step): the empty word.
    #[default]
    NotYet,
    /// The QP was posed and not solved, for a reason the solver did not name.
    Unsolved,
    /// Solved by the active set.
    Solved,
    /// Clarabel solved what the active set could not (docs/recordings.md).
    SolvedClarabel,
    /// No motion satisfies the constraints.
    PrimalInfeasible,
    /// The dual is infeasible: the objective is unbounded below.
    DualInfeasible,
    /// Solved to Clarabel's reduced tolerance.
    AlmostSolved,
    /// Primal infeasible to Clarabel's reduced tolerance.
    AlmostPrimalInfeasible,
    /// Dual infeasible to Clarabel's reduced tolerance.
    AlmostDualInfeasible,
    /// The iteration cap was reached.
    MaxIterations,
    /// The time limit was reached.
    MaxTime,
    /// The solver broke down numerically.
    NumericalError,
    /// Clarabel stopped making progress.
    InsufficientProgress,
    /// A callback stopped Clarabel (hexcue sets none).
    CallbackTerminated,
    /// The QP's data could not be brought up to date with this step.
    UpdateError,
    /// The QP could not be set up.
    SetupError,
    /// The running state was not finite; no QP was posed.
    NonFiniteState,
    /// Not solved this step by design: the other controller is in charge and solved.
    Standby,
    /// A word this version does not know, read from a file.
    Unknown,
}

impl SolveStatus {
    /// Every status, in the order of the enum.
    pub const ALL: [SolveStatus; 19] = [
        SolveStatus::NotYet,
        SolveStatus::Unsolved,
        SolveStatus::Solved,
        SolveStatus::SolvedClarabel,
        SolveStatus::PrimalInfeasible,
        SolveStatus::DualInfeasible,
        SolveStatus::AlmostSolved,
        SolveStatus::AlmostPrimalInfeasible,
        SolveStatus::AlmostDualInfeasible,
        SolveStatus::MaxIterations,
        SolveStatus::MaxTime,
        SolveStatus::NumericalError,
        SolveStatus::InsufficientProgress,
        SolveStatus::CallbackTerminated,
        SolveStatus::UpdateError,
        SolveStatus::SetupError,
        SolveStatus::NonFiniteState,
        SolveStatus::Standby,
        SolveStatus::Unknown,
    ];

    /// The word reports and recordings store, in snake case.
    pub fn as_str(self) -> &'static str {
        match self {
            SolveStatus::NotYet => "",
            SolveStatus::Unsolved => "unsolved",
            SolveStatus::Solved => "solved",
            SolveStatus::SolvedClarabel => "solved_clarabel",
            SolveStatus::PrimalInfeasible => "primal_infeasible",
            SolveStatus::DualInfeasible => "dual_infeasible",
            SolveStatus::AlmostSolved => "almost_solved",
            SolveStatus::AlmostPrimalInfeasible => "almost_primal_infeasible",
            SolveStatus::AlmostDualInfeasible => "almost_dual_infeasible",
            SolveStatus::MaxIterations => "max_iterations",
            SolveStatus::MaxTime => "max_time",
            SolveStatus::NumericalError => "numerical_error",
            SolveStatus::InsufficientProgress => "insufficient_progress",
            SolveStatus::CallbackTerminated => "callback_terminated",
            SolveStatus::UpdateError => "update_error",
            SolveStatus::SetupError => "setup_error",
            SolveStatus::NonFiniteState => "non_finite_state",
            SolveStatus::Standby => "standby",
            SolveStatus::Unknown => "unknown",
        }
    }

    /// The status a word names; [`SolveStatus::Unknown`] for one this version does not know.
    pub fn from_word(word: &str) -> Self {
        Self::ALL
            .into_iter()
            .find(|s| s.as_str() == word)
            .unwrap_or(SolveStatus::Unknown)
    }

    /// The QP was solved, by the active set or by Clarabel after it.
    pub fn is_solved(self) -> bool {
        matches!(self, SolveStatus::Solved | SolveStatus::SolvedClarabel)
    }

    /// A few characters for an 80-column screen.
    pub fn short(self) -> &'static str {
        match self {
            SolveStatus::Solved => "ok",
            SolveStatus::SolvedClarabel => "ok(c)",
            SolveStatus::AlmostSolved => "~ok",
            SolveStatus::PrimalInfeasible => "infeas",
            SolveStatus::DualInfeasible => "d-infeas",
            SolveStatus::MaxTime => "timeout",
            SolveStatus::MaxIterations => "max-it",
            SolveStatus::InsufficientProgress => "stalled",
            other => other.as_str(),
        }
    }
}

impl std::fmt::Display for SolveStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl serde::Serialize for SolveStatus {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

/// Which QP a [`crate::mca::SolverReport`] is about: the MPC's own, or one of the S-MPC's
/// two. Its [`QpName::word`] is what recordings store (`mpc`, `cotc`, `free`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum QpName {
    /// The MPC without terminal conditions (the `mpc` algorithm).
    #[default]
    Mpc,
    /// The MPC with terminal conditions (the S-MPC's COTC, or a COTC on its own).
    Cotc,
    /// The S-MPC's MPC without terminal conditions.
    Free,
    /// A name this version does not know, read from a file.
    Unknown,
}

impl QpName {
    /// Every name, [`QpName::Unknown`] last.
    pub const ALL: [QpName; 4] = [QpName::Mpc, QpName::Cotc, QpName::Free, QpName::Unknown];

    /// The word reports and recordings store.
    pub fn word(self) -> &'static str {
        match self {
            QpName::Mpc => "mpc",
            QpName::Cotc => "cotc",
            QpName::Free => "free",
            QpName::Unknown => "unknown",
        }
    }

    /// The name a word names; [`QpName::Unknown`] for one this version does not know.
    pub fn from_word(word: &str) -> Self {
        Self::ALL
            .into_iter()
            .find(|n| n.word() == word)
            .unwrap_or(QpName::Unknown)
    }
}

impl std::fmt::Display for QpName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.word())
    }
}

impl serde::Serialize for QpName {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.word())
    }
}

/// Why the S-MPC's supervisor changed controller. Its [`Display`](std::fmt::Display) is the
/// text recordings and summaries store; [`SwitchReason::parse`] reads that text back.
#[derive(Clone, Debug, PartialEq)]
pub enum SwitchReason {
    /// COTC's QP was not solved: the free MPC takes over.
    CotcNotSolved(SolveStatus),
    /// The errors stayed within ε for the dwell time and COTC is solved: back to COTC.
    Settled {
        /// The error bound ε (m/s²).
        epsilon_mps2: f64,
        /// How long the errors stayed within it (s).
        dwell_s: f64,
    },
    /// The supervisor had left COTC on a failure both MPCs shared, and COTC is solved again:
    /// back at once, without the ε dwell, since the departure was not COTC's.
    SharedFailureOver,
    /// A reason this version does not know, read from a file, kept as written.
    Other(String),
}

impl SwitchReason {
    /// The reason a stored text names; [`SwitchReason::Other`] for text that is not exactly
    /// what this version's `Display` writes.
    pub fn parse(text: &str) -> Self {
        let parsed = if text == SHARED_FAILURE_OVER {
            Some(SwitchReason::SharedFailureOver)
        } else if let Some(word) = text
            .strip_prefix("COTC not solved (")
            .and_then(|r| r.strip_suffix(')'))
        {
            let status = SolveStatus::from_word(word);
            (status != SolveStatus::Unknown).then_some(SwitchReason::CotcNotSolved(status))
        } else if let Some(rest) = text.strip_prefix("errors within ε = ") {
            let mut words = rest.split(' ');
            let epsilon = words.next().and_then(|w| w.parse().ok());
            let dwell = words.nth(2).and_then(|w| w.parse().ok());
            epsilon
                .zip(dwell)
                .map(|(epsilon_mps2, dwell_s)| SwitchReason::Settled {
                    epsilon_mps2,
                    dwell_s,
                })
        } else {
            None
        };
        // Only a reason that prints back to the same text is understood.
        parsed
            .filter(|r| r.to_string() == text)
            .unwrap_or_else(|| SwitchReason::Other(text.to_string()))
    }
}

impl std::fmt::Display for SwitchReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SwitchReason::CotcNotSolved(status) => write!(f, "COTC not solved ({status})"),
            SwitchReason::Settled {
                epsilon_mps2,
                dwell_s,
            } => write!(
                f,
                "errors within ε = {epsilon_mps2:.2} m/s² for {dwell_s:.1} s and COTC solved"
            ),
            SwitchReason::SharedFailureOver => f.write_str(SHARED_FAILURE_OVER),
            SwitchReason::Other(text) => f.write_str(text),
        }
    }
}

/// [`SwitchReason::SharedFailureOver`]'s text.
const SHARED_FAILURE_OVER: &str = "shared failure over, COTC solved again";

/// The reason as its text: what recordings and summaries store. Formatted only here, at the
/// edge; the step carries the enum.
impl serde::Serialize for SwitchReason {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_read_back() {
        for s in SolveStatus::ALL {
            assert_eq!(SolveStatus::from_word(s.as_str()), s);
        }
        for c in Channel::ALL {
            assert_eq!(Channel::from_key(c.key()), Some(c));
        }
        for text in [
            "COTC not solved (primal_infeasible)",
            "errors within ε = 0.30 m/s² for 1.5 s and COTC solved",
            "COTC infeasible",
        ] {
            assert_eq!(SwitchReason::parse(text).to_string(), text);
        }
        assert_eq!(
            SwitchReason::parse("COTC not solved (max_time)"),
            SwitchReason::CotcNotSolved(SolveStatus::MaxTime)
        );
        assert!(matches!(
            SwitchReason::parse("errors within ε = 0.30 m/s² for 1.5 s and COTC solved"),
            SwitchReason::Settled { dwell_s, .. } if dwell_s == 1.5
        ));
        assert_eq!(
            SwitchReason::parse("shared failure over, COTC solved again"),
            SwitchReason::SharedFailureOver
        );
        for n in QpName::ALL {
            assert_eq!(QpName::from_word(n.word()), n);
        }
    }

    use proptest::prelude::*;

    /// Reasons as the supervisor makes them: a status, or ε and the dwell at the precision
    /// the text carries (hundredths of m/s², tenths of a second).
    fn any_reason() -> impl Strategy<Value = SwitchReason> {
        prop_oneof![
            (0..SolveStatus::ALL.len() - 1)
                .prop_map(|i| SwitchReason::CotcNotSolved(SolveStatus::ALL[i])),
            (0u32..100_000, 0u32..100_000).prop_map(|(e, d)| SwitchReason::Settled {
                epsilon_mps2: f64::from(e) / 100.0,
                dwell_s: f64::from(d) / 10.0,
            }),
            Just(SwitchReason::SharedFailureOver),
        ]
    }

    proptest! {
        #[test]
        fn a_switch_reason_reads_back_from_its_text(r in any_reason()) {
            prop_assert_eq!(SwitchReason::parse(&r.to_string()), r);
        }

        #[test]
        fn any_text_reads_back_to_itself(text in "\\PC{0,60}") {
            prop_assert_eq!(SwitchReason::parse(&text).to_string(), text);
        }

        #[test]
        fn statuses_and_qp_names_read_back_from_their_words(i in 0..SolveStatus::ALL.len(), j in 0..QpName::ALL.len()) {
            let s = SolveStatus::ALL[i];
            prop_assert_eq!(SolveStatus::from_word(&s.to_string()), s);
            let n = QpName::ALL[j];
            prop_assert_eq!(QpName::from_word(&n.to_string()), n);
        }
    }
}
