//! Cueing-quality metrics (DESIGN §6), accumulated sample by sample so that memory does not
//! grow with the trace: per channel x = perceived reference, y = perceived on the simulator.

use serde::{Deserialize, Serialize};

/// Metrics of one channel over a run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ChannelMetrics {
    /// Mean absolute difference, mean |x − y|.
    pub aad: f64,
    /// AAD / (max x − min x).
    pub naad: f64,
    /// Average absolute scale Σ|y| / Σ|x| (1: no down-scaling).
    pub aas: f64,
    /// Relative absolute error Σ|x − y| / Σ|x| (the paper's "absolute scale" error).
    pub rae: f64,
    /// Pearson correlation of x and y.
    pub pc: f64,
    /// Delay of y behind x that maximises their cross-correlation (s; positive = y lags).
    pub ed_s: f64,
    /// The best lag is at the edge of the searched window (±`max_lag`): the true delay, if
    /// the cross-correlation has a peak at all, lies beyond it, and `ed_s` is only a bound.
    #[serde(default)]
    pub ed_at_bound: bool,
    /// Root mean square of x − y.
    pub rmse: f64,
    /// Time during which y and x have opposite signs while both exceed the threshold (s).
    pub false_cue_s: f64,
    /// Jolts at the pilot's head on this channel (`crate::jolts`); set by the summary, which
    /// sees the platform's motion and not only the perceived channels.
    #[serde(default)]
    pub jolts: crate::jolts::Jolts,
}

/// Streaming accumulator for one channel. The cross-correlation is kept for lags within
/// ±`max_lag` samples only.
#[derive(Clone, Debug)]
pub struct ChannelAccumulator {
    n: u64,
    threshold: f64,
    dt_s: f64,
    sum_x: f64,
    sum_y: f64,
    sum_xx: f64,
    sum_yy: f64,
    sum_xy: f64,
    sum_abs_x: f64,
    sum_abs_y: f64,
    sum_abs_err: f64,
    sum_sq_err: f64,
    min_x: f64,
    max_x: f64,
    false_cues: u64,
    /// The first `max_lag + 1` samples of x and y, and ring buffers of the last ones: with
    /// them the sums over each lag's overlap window are exact.
    first_x: Vec<f64>,
    first_y: Vec<f64>,
    hist_x: Vec<f64>,
    hist_y: Vec<f64>,
    /// `lag_xy[l]` = Σ x[k − l]·y[k] for l = 0..=max_lag (y lagging), `lead_xy[l]` =
    /// Σ x[k]·y[k − l] (y leading).
    lag_xy: Vec<f64>,
    lead_xy: Vec<f64>,
}

impl ChannelAccumulator {
    /// An empty accumulator: `threshold` is the channel's perception threshold (m/s² or rad/s),
    /// `dt_s` the step (s), `max_lag` the widest lag of the cross-correlation (steps).
    pub fn new(threshold: f64, dt_s: f64, max_lag: usize) -> Self {
        ChannelAccumulator {
            n: 0,
            threshold,
            dt_s,
            sum_x: 0.0,
            sum_y: 0.0,
            sum_xx: 0.0,
            sum_yy: 0.0,
            sum_xy: 0.0,
            sum_abs_x: 0.0,
            sum_abs_y: 0.0,
            sum_abs_err: 0.0,
            sum_sq_err: 0.0,
            min_x: f64::INFINITY,
            max_x: f64::NEG_INFINITY,
            false_cues: 0,
            first_x: Vec::with_capacity(max_lag + 1),
            first_y: Vec::with_capacity(max_lag + 1),
            hist_x: vec![0.0; max_lag + 1],
            hist_y: vec![0.0; max_lag + 1],
            lag_xy: vec![0.0; max_lag + 1],
            lead_xy: vec![0.0; max_lag + 1],
        }
    }

    /// One step: x the perceived reference, y the perceived simulator motion (same unit).
    pub fn push(&mut self, x: f64, y: f64) {
        let cap = self.hist_x.len();
        if self.first_x.len() < cap {
            self.first_x.push(x);
            self.first_y.push(y);
        }
        let slot = (self.n as usize) % cap;
        self.hist_x[slot] = x;
        self.hist_y[slot] = y;
        let available = (self.n as usize).min(cap - 1);
        for l in 0..=available {
            let past = (slot + cap - l) % cap;
            self.lag_xy[l] += self.hist_x[past] * y;
            self.lead_xy[l] += x * self.hist_y[past];
        }
        self.n += 1;
        self.sum_x += x;
        self.sum_y += y;
        self.sum_xx += x * x;
        self.sum_yy += y * y;
        self.sum_xy += x * y;
        self.sum_abs_x += x.abs();
        self.sum_abs_y += y.abs();
        let e = x - y;
        self.sum_abs_err += e.abs();
        self.sum_sq_err += e * e;
        self.min_x = self.min_x.min(x);
        self.max_x = self.max_x.max(x);
        if x.abs() > self.threshold && y.abs() > self.threshold && x.signum() != y.signum() {
            self.false_cues += 1;
        }
    }

    /// Steps pushed so far.
    pub fn count(&self) -> u64 {
        self.n
    }

    /// The metrics of the steps pushed so far (all zero before the first).
    pub fn finish(&self) -> ChannelMetrics {
        if self.n == 0 {
            return ChannelMetrics::default();
        }
        let n = self.n as f64;
        let ratio = |num: f64, den: f64| if den > 0.0 { num / den } else { 0.0 };
        let aad = self.sum_abs_err / n;
        let (mx, my) = (self.sum_x / n, self.sum_y / n);
        let var_x = (self.sum_xx / n - mx * mx).max(0.0);
        let var_y = (self.sum_yy / n - my * my).max(0.0);
        let cov = self.sum_xy / n - mx * my;
        let pc = if var_x > 0.0 && var_y > 0.0 {
            (cov / (var_x * var_y).sqrt()).clamp(-1.0, 1.0)
        } else {
            0.0
        };
        // Pearson correlation over each lag's overlap window. For y lagging by l the pairs are
        // (x[k − l], y[k]): x without its last l samples, y without its first l.
        let nn = self.n as usize;
        let max_lag = (self.lag_xy.len() - 1).min(nn.saturating_sub(2));
        let cap = self.hist_x.len();
        let last = |buf: &[f64], l: usize| -> (f64, f64) {
            (0..l)
                .map(|j| buf[(nn - 1 - j) % cap])
                .fold((0.0, 0.0), |(s, q), v| (s + v, q + v * v))
        };
        let first = |buf: &[f64], l: usize| -> (f64, f64) {
            buf[..l]
                .iter()
                .fold((0.0, 0.0), |(s, q), v| (s + v, q + v * v))
        };
        let pearson = |sxy: f64, m: f64, (sx, sxx): (f64, f64), (sy, syy): (f64, f64)| {
            let cov = sxy / m - (sx / m) * (sy / m);
            let vx = sxx / m - (sx / m).powi(2);
            let vy = syy / m - (sy / m).powi(2);
            if vx > 0.0 && vy > 0.0 {
                cov / (vx * vy).sqrt()
            } else {
                f64::NEG_INFINITY
            }
        };
        let mut best = (f64::NEG_INFINITY, 0i64);
        for l in 0..=max_lag {
            let m = (nn - l) as f64;
            let (lx, lxx) = last(&self.hist_x, l);
            let (ly, lyy) = last(&self.hist_y, l);
            let (fx, fxx) = first(&self.first_x, l);
            let (fy, fyy) = first(&self.first_y, l);
            let lagging = pearson(
                self.lag_xy[l],
                m,
                (self.sum_x - lx, self.sum_xx - lxx),
                (self.sum_y - fy, self.sum_yy - fyy),
            );
            let leading = pearson(
                self.lead_xy[l],
                m,
                (self.sum_x - fx, self.sum_xx - fxx),
                (self.sum_y - ly, self.sum_yy - lyy),
            );
            // Ties go to the smaller delay.
            if lagging > best.0 + 1e-12 {
                best = (lagging, l as i64);
            }
            if leading > best.0 + 1e-12 {
                best = (leading, -(l as i64));
            }
        }
        ChannelMetrics {
            aad,
            naad: ratio(aad, self.max_x - self.min_x),
            aas: ratio(self.sum_abs_y, self.sum_abs_x),
            rae: ratio(self.sum_abs_err, self.sum_abs_x),
            pc,
            ed_s: best.1 as f64 * self.dt_s,
            ed_at_bound: max_lag > 0 && best.1.unsigned_abs() as usize == self.lag_xy.len() - 1,
            rmse: (self.sum_sq_err / n).sqrt(),
            false_cue_s: self.false_cues as f64 * self.dt_s,
            jolts: Default::default(),
        }
    }
}

/// Streaming quantiles of step times on logarithmic buckets (0.5 % wide) from 0.1 µs to
/// 100 s: fixed memory whatever the run's length.
#[derive(Clone, Debug)]
pub struct TimeHistogram {
    buckets: Vec<u64>,
    count: u64,
    max_us: f64,
}

const HIST_MIN_US: f64 = 0.1;
const HIST_GROWTH: f64 = 1.005;
const HIST_BUCKETS: usize = 4200;

impl Default for TimeHistogram {
    fn default() -> Self {
        TimeHistogram {
            buckets: vec![0; HIST_BUCKETS],
            count: 0,
            max_us: 0.0,
        }
    }
}

/// Median, 99th percentile and maximum of step times (µs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StepTimes {
    /// Median step time (µs).
    pub median: f64,
    /// 99th percentile of the step times (µs).
    pub p99: f64,
    /// Longest step time (µs).
    pub max: f64,
}

impl TimeHistogram {
    /// Counts one step time `us` (µs; a non-finite or negative one counts as 0).
    pub fn push(&mut self, us: f64) {
        let us = if us.is_finite() { us.max(0.0) } else { 0.0 };
        let i = if us <= HIST_MIN_US {
            0
        } else {
            ((us / HIST_MIN_US).ln() / HIST_GROWTH.ln()) as usize
        };
        self.buckets[i.min(HIST_BUCKETS - 1)] += 1;
        self.count += 1;
        self.max_us = self.max_us.max(us);
    }

    /// Upper edge of the bucket holding the q-quantile, capped by the maximum seen.
    pub fn quantile(&self, q: f64) -> f64 {
        if self.count == 0 {
            return 0.0;
        }
        let rank = ((q * self.count as f64).ceil() as u64).clamp(1, self.count);
        let mut seen = 0;
        for (i, c) in self.buckets.iter().enumerate() {
            seen += c;
            if seen >= rank {
                return (HIST_MIN_US * HIST_GROWTH.powi(i as i32 + 1)).min(self.max_us);
            }
        }
        self.max_us
    }

    /// Median, 99th percentile and maximum of the times counted (µs), each within 0.5 % of the
    /// exact value (log-spaced buckets).
    pub fn summary(&self) -> StepTimes {
        StepTimes {
            median: self.quantile(0.5),
            p99: self.quantile(0.99),
            max: self.max_us,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(xs: &[f64], ys: &[f64]) -> ChannelMetrics {
        let mut acc = ChannelAccumulator::new(0.1, 0.01, 100);
        for (x, y) in xs.iter().zip(ys) {
            acc.push(*x, *y);
        }
        acc.finish()
    }

    #[test]
    fn identical_signals_are_perfect() {
        let x: Vec<f64> = (0..1000).map(|k| (k as f64 * 0.01).sin()).collect();
        let m = run(&x, &x);
        assert!(m.aad.abs() < 1e-15 && m.rae.abs() < 1e-15 && m.rmse.abs() < 1e-15);
        assert!((m.aas - 1.0).abs() < 1e-12 && (m.pc - 1.0).abs() < 1e-12);
        assert_eq!(m.ed_s, 0.0);
        assert_eq!(m.false_cue_s, 0.0);
    }

    #[test]
    fn scaled_signal_has_known_errors() {
        // y = x/2: AAD = mean|x|/2, RAE = 0.5, AAS = 0.5, PC = 1.
        let x: Vec<f64> = (0..1000).map(|k| (k as f64 * 0.05).sin() + 0.5).collect();
        let y: Vec<f64> = x.iter().map(|v| v / 2.0).collect();
        let m = run(&x, &y);
        let mean_abs = x.iter().map(|v| v.abs()).sum::<f64>() / x.len() as f64;
        assert!((m.aad - mean_abs / 2.0).abs() < 1e-12);
        assert!((m.rae - 0.5).abs() < 1e-12 && (m.aas - 0.5).abs() < 1e-12);
        assert!((m.pc - 1.0).abs() < 1e-9);
        let range = x.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - x.iter().cloned().fold(f64::INFINITY, f64::min);
        assert!((m.naad - m.aad / range).abs() < 1e-12);
        let rmse = (x.iter().map(|v| (v / 2.0).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
        assert!((m.rmse - rmse).abs() < 1e-12);
    }

    #[test]
    fn a_delay_beyond_the_window_is_marked_as_a_bound() {
        let x: Vec<f64> = (0..3000)
            .map(|k| {
                let t = k as f64 * 0.01;
                (1.3 * t).sin() + 0.5 * (3.7 * t).sin() + 0.3 * (0.4 * t).cos()
            })
            .collect();
        let delayed = |n: usize| -> Vec<f64> {
            (0..3000)
                .map(|k| if k >= n { x[k - n] } else { 0.0 })
                .collect()
        };
        let inside = run(&x, &delayed(25));
        assert!(!inside.ed_at_bound && (inside.ed_s - 0.25).abs() < 1e-12);
        // 1.5 s of delay, 1 s searched: the answer is the edge, and says so.
        let beyond = run(&x, &delayed(150));
        assert!(beyond.ed_at_bound, "{beyond:?}");
        assert_eq!(beyond.ed_s.abs(), 1.0);
    }

    #[test]
    fn delay_is_found_and_signed() {
        // A band-limited random-ish signal delayed by 25 samples (0.25 s).
        let x: Vec<f64> = (0..3000)
            .map(|k| {
                let t = k as f64 * 0.01;
                (1.3 * t).sin() + 0.5 * (3.7 * t).sin() + 0.3 * (0.4 * t).cos()
            })
            .collect();
        let lagged: Vec<f64> = (0..3000)
            .map(|k| if k >= 25 { x[k - 25] } else { 0.0 })
            .collect();
        assert!((run(&x, &lagged).ed_s - 0.25).abs() < 1e-12);
        let leading: Vec<f64> = (0..3000)
            .map(|k| if k + 10 < 3000 { x[k + 10] } else { 0.0 })
            .collect();
        assert!((run(&x, &leading).ed_s + 0.10).abs() < 1e-12);
    }

    #[test]
    fn opposite_signs_above_threshold_are_false_cues() {
        let x = vec![1.0; 50];
        let mut y = vec![0.5; 50];
        for v in y.iter_mut().take(20) {
            *v = -0.5;
        }
        assert!((run(&x, &y).false_cue_s - 0.2).abs() < 1e-12);
        // Below the threshold a sign error is not felt.
        let y = vec![-0.05; 50];
        assert_eq!(run(&x, &y).false_cue_s, 0.0);
    }

    #[test]
    fn histogram_quantiles_are_within_half_a_percent() {
        let mut h = TimeHistogram::default();
        for i in 1..=1000 {
            h.push(i as f64);
        }
        let s = h.summary();
        assert!((s.median - 500.0).abs() / 500.0 < 0.006, "{s:?}");
        assert!((s.p99 - 990.0).abs() / 990.0 < 0.006, "{s:?}");
        assert_eq!(s.max, 1000.0);
    }
}
