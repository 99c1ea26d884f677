//! The `[mpc]` profile section: prediction grid, weights and solver settings.

use serde::{Deserialize, Serialize};

use crate::vocab::{positive, ProfileError};

/// What the MPC assumes the aircraft will do over its horizon.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ReferenceMode {
    /// The current sample held: what a live simulator knows.
    #[default]
    Hold,
    /// The trace's true future (`CueInput::preview`), for offline studies.
    Preview,
    /// The current sample decaying over the horizon toward what the platform can sustain
    /// (`reference::decaying_mean`): what a live simulator knows, without predicting each
    /// sample of an oscillation as a sustained input.
    Decay,
}

fn default_true() -> bool {
    true
}

fn default_false_cue_margin() -> f64 {
    1.0
}

fn default_tilt_share() -> f64 {
    1.0
}

// The followed rotation's defaults are the washout filter's shipped tuning (`[cwf]`).
fn default_follow_tilt_lp_wn_radps() -> f64 {
    1.25
}

fn default_follow_tilt_rate_limit_dps() -> f64 {
    3.0
}

fn default_follow_tilt_acceleration_limit_dps2() -> f64 {
    10.0
}

fn default_follow_rotation_scale() -> f64 {
    0.6
}

fn default_follow_rotation_hp_wn_radps() -> f64 {
    1.0
}

fn default_reference_decay_s() -> [f64; 6] {
    [0.3; 6]
}

/// The `[mpc]` section of a profile: the prediction grid, the reference over the horizon,
/// the weights of the cost and the solver's limits (docs/design.md §4, docs/profiles.md).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MpcParams {
    /// Reference over the horizon: `hold`, `decay` or `preview`.
    pub reference: ReferenceMode,
    /// Time constants of the `decay` reference per channel (Δf x, y, z, p, q, r): how fast
    /// the current sample's unsustainable part is predicted to fade (s).
    #[serde(default = "default_reference_decay_s")]
    pub reference_decay_s: [f64; 6],
    /// Length of the first, fine prediction intervals (s).
    pub fine_step_s: f64,
    /// Number of fine intervals.
    pub fine_steps: usize,
    /// Length of the coarse intervals that follow them (s): move blocking by construction.
    pub coarse_step_s: f64,
    /// Number of coarse intervals (may be 0).
    pub coarse_steps: usize,
    /// Leg-length constraints at the first grid point, every n-th after it, and the last.
    pub leg_constraint_stride: usize,
    /// Weight on the perceived specific-force error f̂ − f̂_ref per axis, per (m/s²)².
    pub specific_force_weight: [f64; 3],
    /// Weight on the perceived angular-velocity error ω̂ − ω̂_ref per axis, per (rad/s)².
    pub angular_velocity_weight: [f64; 3],
    /// When given, the weight of the perceived error per channel (f̂x, f̂y, f̂z, ω̂x, ω̂y, ω̂z)
    /// per squared perception threshold, the score's unit: Q_c = w_c / τ_c², in place of
    /// `specific_force_weight` and `angular_velocity_weight`. The shipped surge weight, 1.5
    /// per (m/s²)², is 0.043 per threshold² (docs/mpc.md, "Pricing what the score prices").
    #[serde(default)]
    pub threshold_error_weight: Option<[f64; 6]>,
    /// Linear price of the perceived error beyond the perception threshold per channel, per
    /// threshold and per fine interval: the score's dead zone is linear above the threshold,
    /// the quadratic weights are not. A slack σ ≥ |ŷ − ŷ_ref| − τ at every grid point, priced
    /// at w·σ/τ. 0 (the default) leaves the channel without one.
    #[serde(default)]
    pub dead_zone_weight: [f64; 6],
    /// Price of the next command's onset at the head beyond what the jolt measure excuses,
    /// per channel (fx, fy, fz, wx, wy, wz), per squared onset threshold (`crate::jolts`):
    /// a slack σ ≥ 0 on lo − m·θ − σθ ≤ s(u₀) − s_{k−N} ≤ hi + m·θ + σθ, with [lo, hi] the
    /// aircraft's own recent onsets and m = `ONSET_BAND_SHARE`, priced w·σ². 0 (the default)
    /// leaves the channel without one (docs/mpc.md, "Jolts: the onset priced in the QP").
    #[serde(default)]
    pub onset_weight: [f64; 6],
    /// The trace's future over the horizon when the input has one (recorded and scripted
    /// flights), in place of `reference`; a live simulator, which has no future, falls back to
    /// `reference`. The summary says which ran (docs/mpc.md, "Preview").
    #[serde(default)]
    pub preview: bool,
    /// Where no future is known (a live simulator; a recorded flight without `preview`), the
    /// engine forecasts the aircraft from its recent motion (`crate::forecast`): the `decay`
    /// reference plus the trend of the last 0.2 s, extrapolated this long (s) and then fading.
    /// 0 (the default) leaves the MPC on `reference` (docs/mpc.md, "Forecast").
    #[serde(default)]
    pub forecast_s: f64,
    /// Weight of a false cue per channel (f̂x, f̂y, f̂z, ω̂x, ω̂y, ω̂z): the square of how far,
    /// in perception thresholds, the simulator's perceived motion at a grid point goes to the
    /// opposite side of a reference that is itself above the threshold. A soft constraint
    /// (a slack per channel and grid point); 0 leaves the channel without one.
    #[serde(default)]
    pub false_cue_weight: [f64; 6],
    /// Where the predicted reference fades below the threshold, keep guarding the direction in
    /// which it was last felt (from the present on), so that the platform is not planned to
    /// swing back perceptibly while the pilot still feels the aircraft's motion one way: the
    /// prediction fades faster than the aircraft's motion may, and a felt washback against a
    /// motion that goes on is a false cue (docs/mpc.md, "False cues").
    #[serde(default = "default_true")]
    pub false_cue_carry: bool,
    /// Where the false-cue price starts, as a fraction of the perception threshold: the
    /// perceived motion against the reference is priced from this much of the threshold on,
    /// so that the optimum keeps it below the threshold instead of just at it (where the
    /// prediction's error makes it cross). 1 prices only what is beyond the threshold.
    #[serde(default = "default_false_cue_margin")]
    pub false_cue_margin: f64,
    /// While the aircraft's perceived heave is heavier than the threshold, keep roll and pitch
    /// within the tilt whose loss of vertical gravity, g·(1 − cos), stays below the heave
    /// threshold: a larger tilt is felt as lightness, a false heave cue the linear model
    /// cannot see (docs/mpc.md, "False cues").
    #[serde(default = "default_true")]
    pub heave_tilt_guard: bool,
    /// Put the tilt's loss of vertical force at the head, g·(1 − cos φ cos θ), into the
    /// prediction of the perceived heave: linearised at each grid point about the angles the
    /// previous plan gave it (as the leg rows are), carried through the heave otolith over
    /// the horizon, and integrated exactly into the MPC's own state at every step. The heave
    /// error the cost prices is then a slack per grid point tied to that prediction by an
    /// equality row (docs/mpc.md, "Tilt's loss of vertical force").
    #[serde(default)]
    pub tilt_heave_loss: bool,
    /// Keep the platform's total roll and pitch rate (tilt plus rotational channel) within
    /// the canals' threshold of the aircraft's own rate over the horizon, on the side of zero:
    /// between min(0, ω_aircraft) − th and max(0, ω_aircraft) + th. Without it only the tilt
    /// channel's rate was bounded, and the plan tilted through the rotational channel at
    /// several times the threshold for surge and sway, a rotation the pilot feels and the
    /// aircraft never made (docs/mpc.md, "Never worse than the CWF").
    #[serde(default)]
    pub unfelt_tilt_guard: bool,
    /// Input weight S on the platform acceleration per axis, per (m/s²)².
    pub acceleration_weight: [f64; 3],
    /// Input weight S on the tilt-channel roll and pitch rates, per (rad/s)².
    pub tilt_rate_weight: [f64; 2],
    /// Input weight S on the rotational-channel roll, pitch and yaw rates, per (rad/s)².
    pub rotation_rate_weight: [f64; 3],
    /// Input-rate weight R on each change of acceleration between intervals.
    pub acceleration_change_weight: [f64; 3],
    /// Input-rate weight R on each change of tilt rate.
    pub tilt_rate_change_weight: [f64; 2],
    /// Input-rate weight R on each change of rotational rate.
    pub rotation_rate_change_weight: [f64; 3],
    /// Washout: weight on the platform position per axis, per m².
    pub washout_position_weight: [f64; 3],
    /// Washout: weight on the platform velocity per axis, per (m/s)².
    pub washout_velocity_weight: [f64; 3],
    /// Washout: weight on the tilt-coordination angles (roll, pitch), per rad².
    pub washout_tilt_weight: [f64; 2],
    /// Washout: weight on the rotational-channel angles (roll, pitch, yaw), per rad².
    pub washout_rotation_weight: [f64; 3],
    /// Natural frequency of the return to neutral after a failed solve (rad/s).
    pub fallback_washout_radps: f64,
    /// Time constant of the low-pass on the aircraft's Δf whose tilt is COTC's terminal
    /// condition: the sustained part of the cue (s).
    pub cotc_sustained_s: f64,
    /// The share of the aircraft's sustained surge and sway specific force (the low-passed Δf
    /// above) that the plan carries by tilt: the `decay` reference fades toward this share of
    /// it, and COTC's terminal tilt is this share's. The linear model cannot see what a tilt
    /// costs beyond its rotation: the loss of vertical gravity, g·(1 − cos), felt as
    /// lightness, and the time to tilt back when the force reverses, felt as surge the wrong
    /// way. 1 tilts for all of it; the CWF's `specific_force_scale` is the same budget
    /// (docs/mpc.md, "How much tilt").
    #[serde(default = "default_tilt_share")]
    pub tilt_share: f64,
    /// `tilt_share` where the MPC predicts with samples ahead (`preview`, or the forecast of
    /// `forecast_s`): COTC's terminal tilt (of the sustained force as the low-pass will have
    /// it at the horizon's end) and the followed tilt. Of `tilt_share`'s two reasons for less
    /// than all of the force, tilting back late when it ends goes with a known future; the
    /// lightness stays. Absent: `tilt_share` (docs/mpc.md, "Preview: COTC's terminal tilt
    /// from the future").
    #[serde(default)]
    pub preview_tilt_share: Option<f64>,
    /// The heave cue channel: the cost tracks the perception of Δf_z through two first-order
    /// high-passes with this time constant (s), predicted fading to nothing, instead of the
    /// whole perceived heave; the false-cue guard still protects the whole. A sustained load factor
    /// (a turn, a pull-up, the stall) is then not chased until the stroke runs out, and the
    /// platform's return after a cue is priced as the rebound it is felt as. 0 tracks the
    /// whole perceived heave (docs/mpc.md, "Heave: what the stroke allows").
    #[serde(default)]
    pub heave_cue_s: f64,
    /// Weight on the platform's roll and pitch away from the followed rotation (`follow.rs`:
    /// a washout filter's tilt coordination on `tilt_share` of the force plus its rotational
    /// channel), per rad². 0 (the default) leaves the plan to rotate as it likes.
    #[serde(default)]
    pub tilt_follow_weight: [f64; 2],
    /// The followed tilt coordination's 2nd-order low-pass (rad/s).
    #[serde(default = "default_follow_tilt_lp_wn_radps")]
    pub follow_tilt_lp_wn_radps: f64,
    /// The followed tilt's rate limit (°/s).
    #[serde(default = "default_follow_tilt_rate_limit_dps")]
    pub follow_tilt_rate_limit_dps: f64,
    /// The followed tilt's acceleration limit (°/s²).
    #[serde(default = "default_follow_tilt_acceleration_limit_dps2")]
    pub follow_tilt_acceleration_limit_dps2: f64,
    /// Gain on the aircraft's roll and pitch rates in the followed rotational channel.
    #[serde(default = "default_follow_rotation_scale")]
    pub follow_rotation_scale: f64,
    /// The followed rotational channel's 2nd-order high-pass (rad/s).
    #[serde(default = "default_follow_rotation_hp_wn_radps")]
    pub follow_rotation_hp_wn_radps: f64,
    /// Solver time limit per step (ms); beyond it the step is a `max_time` failure.
    pub time_limit_ms: f64,
    /// Solver iteration limit.
    pub max_iterations: u32,
    /// Solver feasibility and duality-gap tolerance.
    pub tolerance: f64,
}

impl MpcParams {
    /// Interval lengths of the prediction grid (s).
    pub fn grid(&self) -> Vec<f64> {
        std::iter::repeat_n(self.fine_step_s, self.fine_steps)
            .chain(std::iter::repeat_n(self.coarse_step_s, self.coarse_steps))
            .collect()
    }

    /// The reference the MPC predicts with, given whether the input offers a future: the
    /// preview where `preview` or `forecast_s` asks for it and there is one (the flight's
    /// own, or the engine's forecast: `crate::forecast`), else `reference`.
    pub fn reference_with(&self, future_known: bool) -> ReferenceMode {
        if (self.preview || self.forecast_s > 0.0) && future_known {
            ReferenceMode::Preview
        } else {
            self.reference
        }
    }

    /// The share of the sustained surge and sway force carried by tilt: `preview_tilt_share`
    /// where the MPC predicts with samples ahead (`reference_with`), `tilt_share` otherwise.
    pub fn tilt_share_with(&self, future_known: bool) -> f64 {
        match self.reference_with(future_known) {
            ReferenceMode::Preview => self.preview_tilt_share.unwrap_or(self.tilt_share),
            _ => self.tilt_share,
        }
    }

    /// The reference's name as summaries give it (`hold`, `decay`, `preview`).
    pub fn reference_word(mode: ReferenceMode) -> &'static str {
        match mode {
            ReferenceMode::Hold => "hold",
            ReferenceMode::Preview => "preview",
            ReferenceMode::Decay => "decay",
        }
    }

    /// The weights Q of the perceived error, per (m/s²)² for f̂ and per (rad/s)² for ω̂, given
    /// the perception thresholds (m/s², rad/s) in the order f̂x..ω̂z.
    pub fn output_weights(&self, thresholds: &[f64; 6]) -> ([f64; 3], [f64; 3]) {
        match &self.threshold_error_weight {
            Some(w) => {
                let q = |c: usize| w[c] / (thresholds[c] * thresholds[c]);
                ([q(0), q(1), q(2)], [q(3), q(4), q(5)])
            }
            None => (self.specific_force_weight, self.angular_velocity_weight),
        }
    }

    /// The length of the prediction horizon: the sum of the grid's interval lengths (s).
    pub fn horizon_s(&self) -> f64 {
        self.grid().iter().sum()
    }

    /// Validates the parameters of an MPC without terminal conditions.
    pub fn validate(&self) -> Result<(), ProfileError> {
        self.validate_as(false)
    }

    /// Validates the parameters of an MPC with (`true`, COTC) or without terminal conditions.
    pub fn validate_as(&self, terminal_conditions: bool) -> Result<(), ProfileError> {
        let err = |key: &str, reason: String| {
            Err(ProfileError {
                key: format!("mpc.{key}"),
                reason,
            })
        };
        if !(0.0..=1.0).contains(&self.forecast_s) {
            return err(
                "forecast_s",
                format!(
                    "{} s: expected from 0 (off) to 1 s (a short forecast)",
                    self.forecast_s
                ),
            );
        }
        positive("mpc.fine_step_s", self.fine_step_s)?;
        if self.fine_step_s > 1.0 {
            return err(
                "fine_step_s",
                format!("{} s: expected at most 1 s", self.fine_step_s),
            );
        }
        if self.fine_steps == 0 {
            return err("fine_steps", "expected at least one fine interval".into());
        }
        if self.coarse_steps > 0 {
            positive("mpc.coarse_step_s", self.coarse_step_s)?;
            if self.coarse_step_s > 2.0 {
                return err(
                    "coarse_step_s",
                    format!("{} s: expected at most 2 s", self.coarse_step_s),
                );
            }
        }
        if self.fine_steps + self.coarse_steps > 100 {
            return err(
                "fine_steps",
                "more than 100 intervals in all: the QP would not run in real time".into(),
            );
        }
        let horizon = self.horizon_s();
        if horizon < 1.5 - 1e-9 {
            return err(
                "coarse_steps",
                format!(
                    "horizon {horizon:.2} s: the MPC must see at least 1.5 s to plan the washout"
                ),
            );
        }
        if self.leg_constraint_stride == 0 {
            return err(
                "leg_constraint_stride",
                "expected 1 (every grid point) or more".into(),
            );
        }
        let non_negative = |key: &str, vals: &[f64]| -> Result<(), ProfileError> {
            for (i, v) in vals.iter().enumerate() {
                if !(v.is_finite() && *v >= 0.0) {
                    return Err(ProfileError {
                        key: format!("mpc.{key}[{i}]"),
                        reason: format!("{v}: expected a finite weight of 0 or more"),
                    });
                }
            }
            Ok(())
        };
        let strictly_positive = |key: &str, vals: &[f64]| -> Result<(), ProfileError> {
            for (i, v) in vals.iter().enumerate() {
                positive(&format!("mpc.{key}[{i}]"), *v)?;
            }
            Ok(())
        };
        non_negative("specific_force_weight", &self.specific_force_weight)?;
        non_negative("angular_velocity_weight", &self.angular_velocity_weight)?;
        non_negative("false_cue_weight", &self.false_cue_weight)?;
        if let Some(w) = &self.threshold_error_weight {
            non_negative("threshold_error_weight", w)?;
        }
        non_negative("dead_zone_weight", &self.dead_zone_weight)?;
        non_negative("onset_weight", &self.onset_weight)?;
        non_negative("acceleration_weight", &self.acceleration_weight)?;
        non_negative("tilt_rate_weight", &self.tilt_rate_weight)?;
        non_negative("rotation_rate_weight", &self.rotation_rate_weight)?;
        // R > 0 keeps the QP strictly convex in the inputs whatever S is.
        strictly_positive(
            "acceleration_change_weight",
            &self.acceleration_change_weight,
        )?;
        strictly_positive("tilt_rate_change_weight", &self.tilt_rate_change_weight)?;
        strictly_positive(
            "rotation_rate_change_weight",
            &self.rotation_rate_change_weight,
        )?;
        // Without terminal conditions the washout is the only way back to neutral, so every
        // position must be weighted. COTC's terminal equalities bring the platform to rest at
        // neutral themselves: it may leave the position unweighted (its terminal Riccati
        // weight is then the cost-to-go of everything else, and stability comes from the
        // equalities). The rotational angles have no terminal condition in either.
        if terminal_conditions {
            non_negative("washout_position_weight", &self.washout_position_weight)?;
        } else {
            strictly_positive("washout_position_weight", &self.washout_position_weight)?;
        }
        non_negative("washout_velocity_weight", &self.washout_velocity_weight)?;
        non_negative("washout_tilt_weight", &self.washout_tilt_weight)?;
        strictly_positive("washout_rotation_weight", &self.washout_rotation_weight)?;
        positive("mpc.fallback_washout_radps", self.fallback_washout_radps)?;
        positive("mpc.time_limit_ms", self.time_limit_ms)?;
        positive("mpc.cotc_sustained_s", self.cotc_sustained_s)?;
        if !(self.tilt_share > 0.0 && self.tilt_share <= 1.0) {
            return err(
                "tilt_share",
                format!(
                    "expected a share of the sustained specific force in (0, 1], got {}",
                    self.tilt_share
                ),
            );
        }
        if let Some(share) = self.preview_tilt_share {
            if !(share > 0.0 && share <= 1.0) {
                return err(
                    "preview_tilt_share",
                    format!(
                        "expected a share of the sustained specific force in (0, 1], got {share}"
                    ),
                );
            }
        }
        non_negative("tilt_follow_weight", &self.tilt_follow_weight)?;
        positive("mpc.follow_tilt_lp_wn_radps", self.follow_tilt_lp_wn_radps)?;
        positive(
            "mpc.follow_tilt_rate_limit_dps",
            self.follow_tilt_rate_limit_dps,
        )?;
        positive(
            "mpc.follow_tilt_acceleration_limit_dps2",
            self.follow_tilt_acceleration_limit_dps2,
        )?;
        positive(
            "mpc.follow_rotation_hp_wn_radps",
            self.follow_rotation_hp_wn_radps,
        )?;
        if !(self.follow_rotation_scale.is_finite()
            && (0.0..=2.0).contains(&self.follow_rotation_scale))
        {
            return err(
                "follow_rotation_scale",
                format!(
                    "expected a gain from 0 to 2, got {}",
                    self.follow_rotation_scale
                ),
            );
        }
        if !(self.heave_cue_s.is_finite() && self.heave_cue_s >= 0.0) {
            return err(
                "heave_cue_s",
                format!(
                    "expected a time constant in s, 0 for none, got {}",
                    self.heave_cue_s
                ),
            );
        }
        if !(0.0..=1.0).contains(&self.false_cue_margin) {
            return err(
                "false_cue_margin",
                format!(
                    "expected a fraction of the threshold in [0, 1], got {}",
                    self.false_cue_margin
                ),
            );
        }
        for (i, v) in self.reference_decay_s.iter().enumerate() {
            positive(&format!("mpc.reference_decay_s[{i}]"), *v)?;
        }
        if self.max_iterations == 0 {
            return err("max_iterations", "expected at least 1".into());
        }
        positive("mpc.tolerance", self.tolerance)?;
        if self.tolerance > 1e-2 {
            return err(
                "tolerance",
                format!("{}: expected at most 1e-2", self.tolerance),
            );
        }
        Ok(())
    }
}

/// Declares `CotcOverrides` with one optional field per overridable `[mpc]` key (same name,
/// same type), and its `apply` and `overrides` from the same list, so that a key cannot be
/// parsed without being applied or be applied without naming `[smpc.cotc]` in its errors.
macro_rules! cotc_overrides {
    ($(#[$sdoc:meta])* { $($(#[$doc:meta])* $name:ident: $ty:ty,)* }) => {
        $(#[$sdoc])*
        #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct CotcOverrides {
            $(
                $(#[$doc])*
                #[serde(default, skip_serializing_if = "Option::is_none")]
                pub $name: Option<$ty>,
            )*
        }

        impl CotcOverrides {
            /// COTC's parameters: `[mpc]` with these overrides applied.
            pub fn apply(&self, mpc: &MpcParams) -> MpcParams {
                let mut m = mpc.clone();
                $(
                    if let Some(v) = self.$name {
                        m.$name = v;
                    }
                )*
                m
            }

            /// Whether `[smpc.cotc]` sets the `[mpc]` key `name`.
            fn overrides(&self, name: &str) -> bool {
                match name {
                    $(stringify!($name) => self.$name.is_some(),)*
                    _ => false,
                }
            }
        }
    };
}

cotc_overrides! {
    /// Where COTC's tuning departs from `[mpc]` (the profile's `[smpc.cotc]` table): its own
    /// prediction grid after the fine intervals, its own translational washout and, where the
    /// S-MPC is tuned apart from the free MPC, its own cost weights. Absent keys keep the `[mpc]`
    /// values.
    ///
    /// Why COTC is tuned apart: its terminal conditions already bring the platform to rest at
    /// neutral by the end of the horizon, so the washout terms that stand in for them in the free
    /// MPC only take cue away; and a plan that must be undone within the horizon is gentler, and
    /// gives more cue, when the horizon is longer (docs/mpc.md, "COTC's own tuning").
    {
        /// Length of COTC's coarse intervals (s).
        coarse_step_s: f64,
        /// Number of COTC's coarse intervals.
        coarse_steps: usize,
        /// COTC's washout weight on the platform position per axis, per m².
        washout_position_weight: [f64; 3],
        /// COTC's washout weight on the platform velocity per axis, per (m/s)².
        washout_velocity_weight: [f64; 3],
        /// COTC's share of the sustained surge and sway carried by tilt: its terminal tilt.
        tilt_share: f64,
        /// COTC's weight on the perceived specific-force error per axis, per (m/s²)².
        specific_force_weight: [f64; 3],
        /// COTC's weight on the perceived angular-velocity error per axis, per (rad/s)².
        angular_velocity_weight: [f64; 3],
        /// COTC's linear price of the error beyond the threshold per channel.
        dead_zone_weight: [f64; 6],
        /// COTC's weight on its roll and pitch away from the followed rotation, per rad².
        tilt_follow_weight: [f64; 2],
        /// COTC's input weight on the platform acceleration per axis, per (m/s²)².
        acceleration_weight: [f64; 3],
        /// COTC's input-rate weight on each change of acceleration between intervals.
        acceleration_change_weight: [f64; 3],
        /// COTC's washout weight on the tilt-coordination angles (roll, pitch), per rad².
        washout_tilt_weight: [f64; 2],
        /// COTC's washout weight on the rotational-channel angles (roll, pitch, yaw), per rad².
        washout_rotation_weight: [f64; 3],
        /// COTC's time constant of the sustained cue its terminal tilt carries (s).
        cotc_sustained_s: f64,
        /// COTC's onset price per channel, per squared onset threshold.
        onset_weight: [f64; 6],
        /// COTC's false-cue weight per channel.
        false_cue_weight: [f64; 6],
        /// COTC's time constants of the `decay` reference per channel (s).
        reference_decay_s: [f64; 6],
        /// Whether COTC's heave prediction carries the tilt's loss of vertical force.
        tilt_heave_loss: bool,
        /// COTC's heave cue channel's time constant (s; 0 tracks the whole heave).
        heave_cue_s: f64,
        /// COTC's input weight on the rotational-channel rates, per (rad/s)².
        rotation_rate_weight: [f64; 3],
        /// COTC's input-rate weight on each change of tilt rate.
        tilt_rate_change_weight: [f64; 2],
        /// COTC's input-rate weight on each change of rotational rate.
        rotation_rate_change_weight: [f64; 3],
    }
}

impl CotcOverrides {
    /// Validates COTC's parameters; an error names the key under `smpc.cotc` when it is one
    /// of the overrides, under `mpc` otherwise.
    pub fn validate(&self, mpc: &MpcParams) -> Result<(), ProfileError> {
        self.apply(mpc).validate_as(true).map_err(|mut e| {
            let field = e.key.trim_start_matches("mpc.");
            let name = field.split('[').next().unwrap_or(field);
            if self.overrides(name) {
                e.key = format!("smpc.cotc.{field}");
            }
            e.reason = format!(
                "{} (in COTC's tuning, [mpc] with [smpc.cotc] applied)",
                e.reason
            );
            e
        })
    }
}

#[cfg(test)]
mod tests {
    use crate::testing::full_flight;

    #[test]
    fn invalid_values_name_their_key() {
        let base = full_flight();
        type Spoil = fn(&mut super::MpcParams);
        let cases: [(&str, Spoil); 5] = [
            ("mpc.coarse_steps", |m| m.coarse_steps = 1),
            ("mpc.specific_force_weight[1]", |m| {
                m.specific_force_weight[1] = -1.0
            }),
            ("mpc.washout_position_weight[2]", |m| {
                m.washout_position_weight[2] = 0.0
            }),
            ("mpc.tolerance", |m| m.tolerance = f64::NAN),
            ("mpc.leg_constraint_stride", |m| m.leg_constraint_stride = 0),
        ];
        for (key, spoil) in cases {
            let mut p = base.clone();
            spoil(&mut p.mpc);
            let err = p.validate().unwrap_err();
            assert_eq!(err.key, key, "{err}");
        }
        let mut p = base.clone();
        p.mpc.fine_step_s = 0.005;
        p.mpc.fine_steps = 100;
        assert!(
            p.validate().is_err(),
            "a fine step shorter than a sample is refused"
        );
    }

    #[test]
    fn cotc_overrides_apply_over_mpc_and_errors_name_their_table() {
        let p = full_flight();
        let cotc = p.cotc_params();
        // The shipped COTC: a longer horizon, no surge / sway washout, [mpc] otherwise.
        assert!(cotc.horizon_s() > p.mpc.horizon_s());
        assert_eq!(cotc.washout_position_weight[0], 0.0);
        assert_eq!(cotc.specific_force_weight, p.mpc.specific_force_weight);
        assert_eq!(cotc.fine_steps, p.mpc.fine_steps);
        // No overrides: COTC is [mpc].
        assert_eq!(super::CotcOverrides::default().apply(&p.mpc), p.mpc);

        // An unweighted position is refused for the free MPC, not for COTC.
        let mut bad = p.clone();
        bad.mpc.washout_position_weight[0] = 0.0;
        assert_eq!(
            bad.validate().unwrap_err().key,
            "mpc.washout_position_weight[0]"
        );
        // An invalid override names [smpc.cotc]…
        let mut bad = p.clone();
        bad.smpc.cotc.coarse_steps = Some(0);
        bad.smpc.cotc.coarse_step_s = Some(0.3);
        let err = bad.validate().unwrap_err();
        assert_eq!(err.key, "smpc.cotc.coarse_steps", "{err}");
        assert!(err.reason.contains("COTC"), "{err}");
        let mut bad = p.clone();
        bad.smpc.cotc.washout_velocity_weight = Some([0.0, f64::NAN, 0.0]);
        assert_eq!(
            bad.validate().unwrap_err().key,
            "smpc.cotc.washout_velocity_weight[1]"
        );
        // The tilt's share of the sustained force is a share: (0, 1], in [mpc] and COTC's.
        let mut bad = p.clone();
        bad.mpc.tilt_share = 0.0;
        assert_eq!(bad.validate().unwrap_err().key, "mpc.tilt_share");
        let mut bad = p.clone();
        bad.mpc.preview_tilt_share = Some(1.2);
        let err = bad.validate().unwrap_err();
        assert_eq!(err.key, "mpc.preview_tilt_share", "{err}");
        assert!(err.reason.contains("1.2"), "{err}");
        // With the future known the preview's share, without it `tilt_share`.
        let mut own = p.mpc.clone();
        own.preview = true;
        own.preview_tilt_share = Some(0.9);
        assert_eq!(own.tilt_share_with(true), 0.9);
        assert_eq!(own.tilt_share_with(false), own.tilt_share);
        own.preview_tilt_share = None;
        assert_eq!(own.tilt_share_with(true), own.tilt_share);
        let mut bad = p.clone();
        bad.smpc.cotc.tilt_share = Some(1.5);
        assert_eq!(bad.validate().unwrap_err().key, "smpc.cotc.tilt_share");
        let mut own = p.clone();
        own.smpc.cotc.tilt_share = Some(1.0);
        assert_eq!(own.cotc_params().tilt_share, 1.0);
        assert_eq!(own.mpc.tilt_share, p.mpc.tilt_share);
        // The heave cue's time constant: 0 (none) or a positive time, named when wrong.
        for v in [-0.5, f64::NAN, f64::INFINITY] {
            let mut bad = p.clone();
            bad.mpc.heave_cue_s = v;
            assert_eq!(bad.validate().unwrap_err().key, "mpc.heave_cue_s", "{v}");
        }
        // Following the washout's rotation: weights of 0 or more, a positive filter and
        // limits, a gain from 0 to 2; each named when wrong.
        let mut bad = p.clone();
        bad.mpc.tilt_follow_weight = [10.0, -1.0];
        assert_eq!(bad.validate().unwrap_err().key, "mpc.tilt_follow_weight[1]");
        let mut bad = p.clone();
        bad.mpc.follow_tilt_rate_limit_dps = 0.0;
        assert_eq!(
            bad.validate().unwrap_err().key,
            "mpc.follow_tilt_rate_limit_dps"
        );
        let mut bad = p.clone();
        bad.mpc.follow_rotation_scale = f64::NAN;
        assert_eq!(bad.validate().unwrap_err().key, "mpc.follow_rotation_scale");
    }

    /// The cost keys COTC may tune apart (#35): each given in `[smpc.cotc]` reaches COTC only,
    /// is read from the profile's text, and a bad value is named under `smpc.cotc`.
    #[test]
    fn cotc_cost_overrides_reach_cotc_alone_and_are_named_when_wrong() {
        let p = full_flight();
        let text = crate::profile::text::DEFAULT_PROFILE_TOML.replacen(
            "[smpc.cotc]\n",
            "[smpc.cotc]\nspecific_force_weight = [2.0, 3.0, 0.7]\n\
             angular_velocity_weight = [11.0, 12.0, 13.0]\n\
             dead_zone_weight = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]\n\
             washout_rotation_weight = [0.5, 0.6, 0.7]\n\
             cotc_sustained_s = 2.5\n",
            1,
        );
        let own = crate::profile::text::parse_profile(&text, "t").unwrap();
        let plain =
            crate::profile::text::parse_profile(crate::profile::text::DEFAULT_PROFILE_TOML, "t")
                .unwrap();
        let cotc = own.cotc_params();
        assert_eq!(cotc.specific_force_weight, [2.0, 3.0, 0.7]);
        assert_eq!(cotc.angular_velocity_weight, [11.0, 12.0, 13.0]);
        assert_eq!(cotc.dead_zone_weight, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]);
        assert_eq!(cotc.washout_rotation_weight, [0.5, 0.6, 0.7]);
        assert_eq!(cotc.cotc_sustained_s, 2.5);
        // The free MPC keeps [mpc]'s.
        assert_eq!(own.mpc, plain.mpc);
        // Keys [smpc.cotc] does not set stay [mpc]'s in COTC too.
        assert_eq!(cotc.onset_weight, plain.mpc.onset_weight);
        assert_eq!(cotc.tilt_follow_weight, plain.mpc.tilt_follow_weight);
        assert_eq!(cotc.tilt_share, plain.cotc_params().tilt_share);

        let mut bad = p.clone();
        bad.smpc.cotc.dead_zone_weight = Some([0.0, 0.0, -1.0, 0.0, 0.0, 0.0]);
        assert_eq!(
            bad.validate().unwrap_err().key,
            "smpc.cotc.dead_zone_weight[2]"
        );
        let mut bad = p.clone();
        bad.smpc.cotc.specific_force_weight = Some([1.0, f64::NAN, 1.0]);
        assert_eq!(
            bad.validate().unwrap_err().key,
            "smpc.cotc.specific_force_weight[1]"
        );
        // The same bad value in [mpc] is named there.
        let mut bad = p.clone();
        bad.mpc.specific_force_weight[1] = f64::NAN;
        assert_eq!(
            bad.validate().unwrap_err().key,
            "mpc.specific_force_weight[1]"
        );
    }

    #[test]
    fn a_profile_without_the_heave_cue_key_loads_and_tracks_the_whole_heave() {
        let toml = crate::profile::text::DEFAULT_PROFILE_TOML;
        let line = toml
            .lines()
            .find(|l| l.starts_with("heave_cue_s"))
            .expect("the default profile sets heave_cue_s");
        let without = toml.replace(line, "");
        let p = crate::profile::text::parse_profile(&without, "t").unwrap();
        assert_eq!(p.mpc.heave_cue_s, 0.0);
    }

    #[test]
    fn a_profile_without_the_follow_keys_loads_and_rotates_freely() {
        let toml = crate::profile::text::DEFAULT_PROFILE_TOML;
        let without: String = toml
            .lines()
            .filter(|l| !(l.starts_with("tilt_follow_weight") || l.starts_with("follow_")))
            .map(|l| format!("{l}\n"))
            .collect();
        let p = crate::profile::text::parse_profile(&without, "t").unwrap();
        assert_eq!(p.mpc.tilt_follow_weight, [0.0; 2]);
        // The rest default to the washout filter's shipped tuning.
        let shipped = crate::profile::text::parse_profile(toml, "t").unwrap();
        assert_eq!(p.mpc.follow_tilt_lp_wn_radps, shipped.cwf.tilt_lp_wn_radps);
        assert_eq!(
            p.mpc.follow_tilt_rate_limit_dps,
            shipped.cwf.tilt_rate_limit_dps
        );
        assert_eq!(
            p.mpc.follow_rotation_scale,
            shipped.cwf.angular_velocity_scale[1]
        );
    }

    #[test]
    fn cotc_table_is_optional_and_refuses_unknown_keys() {
        let toml = crate::profile::text::DEFAULT_PROFILE_TOML;
        let start = toml
            .find("[smpc.cotc]")
            .expect("the default profile tunes COTC");
        let without = &toml[..start];
        let p = crate::profile::text::parse_profile(without, "t").unwrap();
        assert_eq!(p.cotc_params(), p.mpc);
        let spoiled = toml.replace("[smpc.cotc]\n", "[smpc.cotc]\nhorizon_s = 3.0\n");
        let err = crate::profile::text::parse_profile(&spoiled, "t").unwrap_err();
        let text = err.to_string();
        assert!(text.contains("horizon_s"), "{text}");
    }

    #[test]
    fn unknown_keys_are_refused_and_reference_parses() {
        let toml = crate::profile::text::DEFAULT_PROFILE_TOML;
        let line = "reference = \"decay\"";
        assert!(
            toml.contains(line),
            "the default profile's reference line moved"
        );
        let spoiled = toml.replace(line, "reference = \"decay\"\nhorizon = 3");
        assert!(crate::profile::text::parse_profile(&spoiled, "t").is_err());
        let preview = toml.replace(line, "reference = \"preview\"");
        let p = crate::profile::text::parse_profile(&preview, "t").unwrap();
        assert_eq!(p.mpc.reference, super::ReferenceMode::Preview);
    }

    #[test]
    fn both_shipped_profiles_load() {
        for path in ["profiles/full-flight.toml", "profiles/compact.toml"] {
            let full = format!("{}/{path}", concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
            let text = std::fs::read_to_string(&full).unwrap();
            let p = crate::profile::text::parse_profile(&text, path).unwrap();
            assert!(p.mpc.horizon_s() >= 1.5);
        }
    }
}
