//! What the console's parts share: the interface's state ([`App`]), the events it reacts
//! to, and a live session's header. Below the interface's behaviour (`app`), its drawing
//! (`view`, `gauges`, `help`, `live`) and the terminal glue, which all import it and not each
//! other's items.

use std::sync::Arc;
use std::time::Duration;

use ratatui::crossterm::event::KeyEvent;

use crate::session::player::Snapshot;
use crate::session::SessionInfo;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::Profile;
use hexcue_core::safety::SafetyState;
use hexcue_core::vocab::Channel;

use super::theme::Theme;

/// At most this many redraws a second: over SSH every frame costs bandwidth.
pub const FRAME_INTERVAL: Duration = Duration::from_millis(33);
/// How long a notice stays in the footer.
pub const NOTICE_FOR: Duration = Duration::from_secs(6);

/// What the interface reacts to.
#[derive(Clone, Debug, PartialEq)]
pub enum UiEvent {
    Key(KeyEvent),
    Resize,
    /// SIGTERM, SIGHUP or SIGINT: quit as `q` does, recording finished.
    Signal(&'static str),
}

/// Where events come from: the terminal and signals, or a script in tests.
pub trait EventSource {
    /// The next event, or `None` after `timeout` without one.
    fn next(&mut self, timeout: Duration) -> anyhow::Result<Option<UiEvent>>;
}

/// The leg gauges' geometry and thresholds. The bars show each leg's usage as `plot` and the
/// summary do: the fraction of the stroke from neutral to the nearer end stop (0 at neutral,
/// 1 at the end stop); the marks go by the margin left.
#[derive(Clone, Debug, PartialEq)]
pub struct LegScale {
    pub stewart: hexcue_core::model::stewart::Stewart,
    /// Margin of each leg at the neutral pose (m).
    pub neutral_margin_m: [f64; 6],
    /// Below this the leg is marked `!` (m).
    pub warn_m: f64,
    /// Below this it is marked `!!`: at the limiter's own margin, or outside the stroke (m).
    pub crit_m: f64,
}

impl LegScale {
    pub fn of(profile: &Profile) -> Self {
        let stewart = profile.stewart();
        let neutral = stewart.margins(&stewart.neutral_lengths_m);
        let neutral_margin_m: [f64; 6] = std::array::from_fn(|i| neutral[i].max(1e-6));
        let least = neutral_margin_m
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        let limiter = profile.limiter.leg_margin_m.max(0.0);
        // Critical: the limiter is about to act (or has); warning: a fifth of the stroke left.
        let crit_m = (1.5 * limiter).max(0.005);
        LegScale {
            stewart: stewart.clone(),
            neutral_margin_m,
            warn_m: (0.2 * least).max(2.0 * crit_m),
            crit_m,
        }
    }
}

pub struct App {
    pub info: Arc<SessionInfo>,
    pub snapshot: Arc<Snapshot>,
    /// Index into [`Channel::ALL`].
    pub channel: usize,
    pub help: bool,
    /// The help's page, where it does not fit in one (`?` turns them).
    pub help_page: usize,
    /// Playback was running when the help opened: closing it plays again.
    pub(super) help_paused_playback: bool,
    /// The go-to-time prompt (`g`), with what has been typed.
    pub goto: Option<String>,
    /// Why the time typed at the prompt was not gone to (shown until the next key).
    pub goto_refused: Option<&'static str>,
    pub theme: Theme,
    pub legs: LegScale,
    /// Each DoF's excursion limit (m, rad; x, y, z, roll, pitch, yaw), for the pose panel.
    pub pose_limits: [f64; 6],
    /// The pose panel is shown (`x`): beside the leg gauges where there is room, in their
    /// place where there is not.
    pub pose: bool,
    /// The overlaid view (`v`): one chart per channel with every algorithm on it, instead of
    /// a column per algorithm.
    pub overlay: bool,
    /// Perception thresholds per channel (m/s², rad/s), for the overlaid view's band: those
    /// the summary's false cues and score use (`bound::thresholds`).
    pub thresholds: [f64; 6],
    /// A live session's header (`hexcue live`); `None` for playback and review.
    pub live: Option<LiveStatus>,
    /// The parameter panel (`p`) of a `play` console; `None` in review, which has no
    /// algorithm to tune (the live console holds its own).
    pub params: Option<super::params::ParamPanel>,
    pub(super) quit: Option<&'static str>,
}

impl App {
    pub fn new(info: Arc<SessionInfo>, profile: &Profile, theme: Theme) -> Self {
        App {
            info,
            snapshot: Arc::new(Snapshot::empty(Vec::new(), 0, profile.rate_hz)),
            channel: 0,
            help: false,
            help_page: 0,
            help_paused_playback: false,
            goto: None,
            goto_refused: None,
            theme,
            legs: LegScale::of(profile),
            pose_limits: profile.limits.si().excursion.into(),
            pose: false,
            overlay: false,
            thresholds: hexcue_core::bound::thresholds(profile),
            live: None,
            params: None,
            quit: None,
        }
    }

    pub fn should_quit(&self) -> bool {
        self.quit.is_some()
    }

    /// The signal that ended the session, if one did.
    pub fn quit_signal(&self) -> Option<&'static str> {
        self.quit.filter(|q| q.starts_with("SIG"))
    }

    pub fn channel_name(&self) -> &'static str {
        self.channel().key()
    }

    /// The channel shown.
    pub fn channel(&self) -> Channel {
        Channel::ALL[self.channel % Channel::ALL.len()]
    }
}

/// What the header shows of a live session, as of one step.
#[derive(Clone, Debug, PartialEq)]
pub struct LiveStatus {
    pub input: String,
    /// Where input is expected: protocol and address (`LiveSession::input_source`).
    pub input_source: String,
    pub outputs: Vec<String>,
    pub drive: AlgorithmId,
    pub state: SafetyState,
    pub time_in_state_s: f64,
    /// Age of the held sample (s); `None` before the first.
    pub input_age_s: Option<f64>,
    pub sim_paused: bool,
    pub samples_in: u64,
    pub commands_out: u64,
    pub deadline_misses: u64,
    pub malformed: u64,
    pub latency_p99_ms: f64,
    pub step_p99_ms: f64,
    /// Each lane's 99th percentile share of its step's deadline used (0.25: a quarter).
    pub deadline_share_p99: Vec<(AlgorithmId, f64)>,
    /// An e-stop or quit was asked for: the platform is on its way to park.
    pub stopping: bool,
    /// The first seconds of input suggest a unit or sign mistake (the summary says which).
    pub unit_warning: bool,
    /// The outputs at whose address nothing listens (ICMP port unreachable).
    pub unreachable: Vec<String>,
    /// What the platform says of itself (a Moog base), if it answers.
    pub platform: Option<crate::sinks::PlatformStatus>,
    /// Session time (s), for how long input has been awaited.
    pub t_s: f64,
    /// A short answer to a key (`r`), shown in the footer for a few seconds.
    pub notice: Option<String>,
}
