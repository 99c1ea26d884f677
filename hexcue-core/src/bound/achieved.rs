//! The achieved motion (docs/bound.md, "achieved"): the joint programme over all six DoFs on
//! a coarser grid, its legs and head re-linearised about the previous answer in sequences of
//! passes, each answer replayed through the lanes' own pipeline; the best kept and polished.

use super::*;

/// Grid of the achieved programme (samples per decision step).
pub const ACHIEVED_GRID: usize = 5;

/// A motion the platform can make near the relaxed optimum: the joint programme over all six
/// DoFs (the legs couple them) on a grid `ACHIEVED_GRID` samples apart, with the legs
/// linearised about neutral and then about the previous answer's poses, one sequence of
/// passes per entry of `ACHIEVED_SEQUENCES`. Every answer is replayed at the full rate;
/// returns them all (label, replay, programme).
///
/// The first pass depends on the inset alone (no head rows, braking rows or trust region yet),
/// so it is solved once per inset and shared by the sequences of that inset, and returned
/// once.
pub fn achieved_with_legs(
    profile: &Profile,
    trace: &Trace,
    setup: &Setup,
) -> Vec<(String, Replayed, Solution)> {
    achieved_with_sequences(profile, trace, setup, &ACHIEVED_SEQUENCES)
}

/// `achieved_with_legs` with other sequences (`LIGHTENED_SEQUENCE` among them, say), and the
/// polish of the best of their answers.
pub fn achieved_with_sequences(
    profile: &Profile,
    trace: &Trace,
    setup: &Setup,
    sequences: &[Sequence],
) -> Vec<(String, Replayed, Solution)> {
    let mut out = run_sequences(profile, trace, setup, sequences);
    out.extend(polish(profile, trace, setup, &out));
    out
}

/// The sequences' answers alone, without the polish (`achieved_with_sequences`).
pub(super) fn run_sequences(
    profile: &Profile,
    trace: &Trace,
    setup: &Setup,
    sequences: &[Sequence],
) -> Vec<(String, Replayed, Solution)> {
    let mut starts: Vec<(f64, Start)> = Vec::new();
    for seq in sequences {
        if !starts.contains(&(seq.inset_m, seq.start)) {
            starts.push((seq.inset_m, seq.start));
        }
    }
    let coarse = setup.coarse(profile, ACHIEVED_GRID);
    let firsts: Vec<Solution> = starts
        .par_iter()
        .map(|&(inset_m, start)| first_pass(profile, &coarse, inset_m, start))
        .collect();
    sequences
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, seq)| {
            let key = (seq.inset_m, seq.start);
            let at = starts.iter().position(|&s| s == key);
            let first = at.map(|a| firsts[a].clone());
            let owner = sequences.iter().position(|s| (s.inset_m, s.start) == key) == Some(i);
            legs_sequence(profile, trace, setup, seq, first, owner)
        })
        .collect()
}

/// The best candidate so far (by its replay) re-solved about itself: the legs, the head
/// (the tilt's lightening with it) and the limiter's braking path linearised about its
/// answer, in the trust region, for as long as each pass replays better than the best
/// before it (at most `POLISH_PASSES`). Its first pass is the candidate itself, not
/// returned again.
pub(super) fn polish(
    profile: &Profile,
    trace: &Trace,
    setup: &Setup,
    candidates: &[(String, Replayed, Solution)],
) -> Vec<(String, Replayed, Solution)> {
    let solved =
        |s: &Solution| matches!(s.status, SolverStatus::Solved | SolverStatus::AlmostSolved);
    let Some((label, best, sol)) = candidates
        .iter()
        .filter(|(_, r, s)| solved(s) && !r.commands.is_empty())
        .min_by(|a, b| a.1.total.total_cmp(&b.1.total))
    else {
        return Vec::new();
    };
    let seq = Sequence {
        inset_m: LEG_INSETS_M[0],
        relinearise_head: true,
        lookahead: Lookahead::Path,
        passes: 1,
        trust_from: 2,
        trust_fraction: TRUST_FRACTION,
        start: Start::Linear,
        extra_passes: POLISH_PASSES,
    };
    let mut out = legs_sequence_from(
        profile,
        trace,
        setup,
        &seq,
        Some(sol.clone()),
        false,
        best.total,
    );
    for (name, _, _) in &mut out {
        *name = format!("{label}, polished: {name}");
    }
    out
}

/// The achieved programme's first pass at an inset: the legs linearised about neutral, the
/// head linear, with the tilt's lightening in heave when the sequence starts `Lightened`.
pub(super) fn first_pass(
    profile: &Profile,
    coarse: &Setup,
    inset_m: f64,
    start: Start,
) -> Solution {
    let g = &profile.geometry;
    let margin = profile.limiter.leg_margin_m + inset_m;
    let poses = vec![Vector6::zeros(); coarse.reference[0].len()];
    let rows = leg_rows(profile, &poses, None, &coarse.limits);
    let all: Vec<usize> = (0..6).collect();
    let mut prog = coarse.programme(&all, &all, &all, None);
    // A hair inside the boxes, so that rounding never makes the limiter act.
    prog.box_scale = 1.0 - 1e-6;
    prog.legs = Some((&rows, g.leg_min_m + margin, g.leg_max_m - margin));
    prog.lightening = start == Start::Lightened;
    prog.solve()
}

/// How a sequence of the achieved programme keeps its motion where the workspace limiter's
/// braking look-ahead accepts it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lookahead {
    /// Legs at the planned poses only.
    None,
    /// The legs also in the stroke at the point where braking every DoF would stop
    /// (`LegRows::stop_gain`).
    StopPoint,
    /// Rows for the limiter's own braking path wherever a pass came near the legs' margin on
    /// it (`acceptance::PathRows`).
    Path,
}

/// One sequence of passes of the achieved programme.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sequence {
    /// Leg rows this far inside the limiter's margin (m).
    pub inset_m: f64,
    /// Whether passes after the first re-linearise the head's inputs about the previous
    /// answer too (the sequential programme of docs/bound.md).
    pub relinearise_head: bool,
    /// What keeps the motion inside the limiter's look-ahead.
    pub lookahead: Lookahead,
    /// Passes (the first about neutral).
    pub passes: usize,
    /// From this pass on (0: never) each pass keeps its poses within a trust region about the
    /// previous answer's, `TRUST_FRACTION` of each DoF's excursion: the legs and the head it
    /// linearised there are then accurate to second order in that radius, so that the plan's
    /// own poses stay in the stroke (docs/bound.md, "`achieved`").
    pub trust_from: usize,
    /// The trust region's radius per DoF as a share of its excursion (`TRUST_FRACTION`).
    pub trust_fraction: f64,
    /// What the first pass minimises: the linear head's error, or with the tilt's lightening
    /// in heave (`Start::Lightened`).
    pub start: Start,
    /// Passes after `passes`, each in the trust region when `trust_from` > 0, for as long as
    /// each replays better than the sequence's best so far (0: none).
    pub extra_passes: usize,
}

/// The model of a sequence's first pass, before any re-linearisation about an answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Start {
    /// The relaxation's linear head model.
    Linear,
    /// The linear head with the tilt's lightening g(1 − cos θ cos φ) in heave as the cones of
    /// `Lightening` (docs/bound.md, "The tilt's lightening"): a first pass that already pays
    /// for the lightness of the tilt it takes, so that the passes re-linearised about it start
    /// from a motion that tilts less where tilting lightens the head more than it cues.
    Lightened,
}

/// Radius of the achieved programme's trust region per DoF, as a share of its excursion
/// (`Sequence::trust_from`): 3 % is 51 mm of surge on the full-flight platform, where a leg of
/// 1.5 m is off its tangent by under a millimetre, inside every inset.
pub const TRUST_FRACTION: f64 = 0.03;

/// The sequences of the achieved programme (docs/bound.md, "`achieved`").
///
/// A fourth, the legs alone at 5 mm (four plain passes), was the best candidate on none of
/// the five shipped flights nor the F-16's wind-up turn (docs/bound.md, "What a run
/// costs"), and was dropped: three programmes a flight.
pub const ACHIEVED_SEQUENCES: [Sequence; 3] = [
    Sequence {
        inset_m: LEG_INSETS_M[1],
        relinearise_head: true,
        lookahead: Lookahead::None,
        passes: LEG_ITERATIONS + 2,
        trust_from: LEG_ITERATIONS + 1,
        trust_fraction: TRUST_FRACTION,
        start: Start::Linear,
        extra_passes: 0,
    },
    Sequence {
        inset_m: LEG_INSETS_M[0],
        relinearise_head: true,
        lookahead: Lookahead::StopPoint,
        passes: LEG_ITERATIONS,
        trust_from: 0,
        trust_fraction: TRUST_FRACTION,
        start: Start::Linear,
        extra_passes: 0,
    },
    Sequence {
        inset_m: LEG_INSETS_M[0],
        relinearise_head: true,
        lookahead: Lookahead::Path,
        passes: 6,
        trust_from: 5,
        trust_fraction: TRUST_FRACTION,
        start: Start::Linear,
        extra_passes: 0,
    },
];

/// A sequence from the lightened relaxation (`Start::Lightened`): four plain passes, then
/// passes in the trust region while the replay improves. Not among `ACHIEVED_SEQUENCES`: on
/// the take-off, whose gap is the tilt's lightness, its best replay is 0.0643 against the
/// others' 0.0577 (docs/bound.md, "The achieved motion from the lightened relaxation");
/// `examples/gap_where.rs` runs it with `GAP_WHERE_LIGHTENING`.
pub const LIGHTENED_SEQUENCE: Sequence = Sequence {
    inset_m: LEG_INSETS_M[1],
    relinearise_head: true,
    lookahead: Lookahead::None,
    passes: LEG_ITERATIONS,
    trust_from: LEG_ITERATIONS + 1,
    trust_fraction: TRUST_FRACTION,
    start: Start::Lightened,
    extra_passes: POLISH_PASSES,
};

/// Most passes of the polish (`polish`) and of a sequence's `extra_passes`: each is kept
/// only while it replays better than the best before it.
pub const POLISH_PASSES: usize = 3;

/// `bound` polishes the best candidate only when it replays more than this share above
/// `lower.total`: a polish pass costs a whole programme and can gain at most the gap.
pub const POLISH_ABOVE: f64 = 0.05;

pub(crate) fn legs_sequence(
    profile: &Profile,
    trace: &Trace,
    setup: &Setup,
    seq: &Sequence,
    first: Option<Solution>,
    emit_first: bool,
) -> Vec<(String, Replayed, Solution)> {
    legs_sequence_from(profile, trace, setup, seq, first, emit_first, f64::INFINITY)
}

/// `legs_sequence` whose extra passes must replay better than `baseline` too (the replayed
/// total of a `first` that is not emitted).
fn legs_sequence_from(
    profile: &Profile,
    trace: &Trace,
    setup: &Setup,
    seq: &Sequence,
    mut first: Option<Solution>,
    emit_first: bool,
    baseline: f64,
) -> Vec<(String, Replayed, Solution)> {
    let g = &profile.geometry;
    let inset_m = seq.inset_m;
    let margin = profile.limiter.leg_margin_m + inset_m;
    let (lo, hi) = (g.leg_min_m + margin, g.leg_max_m - margin);
    let all: Vec<usize> = (0..6).collect();
    let coarse = setup.coarse(profile, ACHIEVED_GRID);
    let stewart = profile.stewart();
    let limiter = WorkspaceLimiter::new(
        stewart.clone(),
        profile.limits.si(),
        profile.limiter.leg_margin_m,
        setup.dt_s,
    );
    let mut path_rows = acceptance::PathRows::new();
    let mut node_rows: Vec<NodeRow> = Vec::new();
    let mut poses: Vec<Vector6<f64>> = vec![Vector6::zeros(); coarse.reference[0].len()];
    let mut velocities: Option<Vec<Vector6<f64>>> = None;
    let mut head: Option<Vec<HeadRows>> = None;
    let mut out = Vec::new();
    let label = |i: usize, trusted: bool| {
        let look = match seq.lookahead {
            Lookahead::StopPoint if i > 1 => " (braking)",
            Lookahead::Path if i > 1 => " (braking path)",
            _ => "",
        };
        let trusted = if trusted { " in a trust region" } else { "" };
        let from = match seq.start {
            Start::Lightened => ", from the lightened relaxation",
            Start::Linear => "",
        };
        format!(
            "legs{look}{} linearised {i}× at {:.0} mm inset{trusted}{from}",
            if seq.relinearise_head && i > 1 {
                " and head"
            } else {
                ""
            },
            inset_m * 1000.0
        )
    };
    let path_margin = profile.limiter.leg_margin_m + PATH_INSET_M;
    let path_stroke = (g.leg_min_m + path_margin, g.leg_max_m - path_margin);
    // The best replayed total so far, which an extra pass must beat to go on.
    let mut best = baseline;
    for iteration in 1..=seq.passes + seq.extra_passes {
        // The first pass is the shared one when given (`achieved_with_legs`).
        let shared = iteration == 1 && first.is_some();
        let radius: Vector6<f64> = coarse.limits.excursion * seq.trust_fraction;
        let solve_pass = |trusted: bool| {
            let rows = leg_rows(
                profile,
                &poses,
                if seq.lookahead == Lookahead::StopPoint {
                    velocities.as_deref()
                } else {
                    None
                },
                &coarse.limits,
            );
            let mut prog = coarse.programme(&all, &all, &all, None);
            // A hair inside the boxes, so that rounding never makes the limiter act.
            prog.box_scale = 1.0 - 1e-6;
            prog.legs = Some((&rows, lo, hi));
            prog.head = head.as_deref();
            prog.node_rows = Some(&node_rows);
            // Only the first pass has the linear head, with which the lightening goes.
            prog.lightening = iteration == 1 && seq.start == Start::Lightened;
            if trusted {
                prog.trust = Some((&poses, radius));
            }
            prog.solve()
        };
        let solved =
            |s: &Solution| matches!(s.status, SolverStatus::Solved | SolverStatus::AlmostSolved);
        let mut trusted = seq.trust_from > 0 && iteration >= seq.trust_from;
        let sol = match first.take().filter(|_| iteration == 1) {
            Some(sol) => sol,
            None => {
                let sol = solve_pass(trusted);
                // A pass that ends unsolved is tried once more the other way: a plain pass
                // (the legs linearised about an answer that moved far) in the trust region
                // about that answer; a pass in the trust region (the answer breaks the legs
                // re-linearised about it by more than the radius can repair, as on the
                // steep turn) without it. The failed attempt is reported as unsolved.
                if !solved(&sol) && iteration > 1 && seq.trust_from > 0 {
                    out.push((label(iteration, trusted), replay(profile, trace, &[]), sol));
                    trusted = !trusted;
                    solve_pass(trusted)
                } else {
                    sol
                }
            }
        };
        if !solved(&sol) {
            if !shared || emit_first {
                out.push((label(iteration, trusted), replay(profile, trace, &[]), sol));
            }
            break;
        }
        let emit = !shared || emit_first;
        let r = emit.then(|| {
            let steps = expand(&sol, ACHIEVED_GRID, trace.len(), setup.dt_s);
            replay(profile, trace, &clamp_commands(&steps, &setup.limits))
        });
        poses = sol.pose.clone();
        velocities = Some(sol.velocity.clone());
        if seq.lookahead == Lookahead::Path {
            (node_rows, _) = path_rows.update(
                &limiter,
                &stewart,
                profile.limiter.leg_margin_m,
                PATH_INSET_M,
                path_stroke,
                &sol,
                ACHIEVED_GRID,
                trace.len(),
                setup.dt_s,
            );
        }
        if seq.relinearise_head {
            head = Some(head_rows(&sol, &setup.eye_m));
        }
        if let Some(r) = r {
            let total = r.total;
            out.push((label(iteration, trusted), r, sol));
            if iteration > seq.passes && total >= best {
                break;
            }
            best = best.min(total);
        }
    }
    out
}

/// The head's inputs linearised about every grid step of an answer.
fn head_rows(sol: &Solution, eye_m: &Vector3<f64>) -> Vec<HeadRows> {
    (0..sol.pose.len())
        .map(|k| HeadRows::about(&sol.pose[k], &sol.velocity[k], &sol.acceleration[k], eye_m))
        .collect()
}
