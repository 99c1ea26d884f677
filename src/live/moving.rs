//! A lane moved between the stepping thread and the comparison lanes' thread, so that the
//! drive switches live to any of the session's algorithms (issue 36, docs/live.md,
//! *Switching the drive*).
//!
//! The stepping thread steps only the lanes its command hears; the others step on the
//! comparison lanes' thread ([`super::lanes`]). A switch to a comparison lane asks that
//! thread for it: once it has stepped the lane through the step at which it was asked, it
//! takes the lane out of its engine, in the state it has reached, with the metrics gathered
//! of it, and sends it over. The stepping thread puts it in its engine at its next step, and
//! only then starts the blend, from the new lane's command as it is. Once the blend is over
//! the old lane is not heard any more: it goes back the same way, and the comparison lanes'
//! thread puts it in its engine when it reaches the step it left at.
//!
//! On the stepping thread this costs no lock and no allocation: the channels are bounded
//! (their room is allocated when they are made), sent to with `try_send` and read with
//! `try_recv`, and a lane moves by value ([`hexcue_core::engine::LaneState`] and the
//! summary's [`LaneAccumulator`] are moved, not copied or boxed). The engine and the summary
//! keep room for every lane ([`hexcue_core::engine::Engine::put_lane`],
//! [`SummaryBuilder::put_lane`]).

use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TryRecvError, TrySendError};

use hexcue_core::bumpless::DriveSwitch;
use hexcue_core::engine::{Engine, LaneState, Retune, MAX_LANES};
use hexcue_core::mca::AlgorithmId;
use hexcue_core::summary::{LaneAccumulator, SummaryBuilder};

/// Requests the channel holds: more switches than an operator makes between two steps of a
/// thread that drains it every step.
const REQUESTS: usize = 16;

/// A lane on its way, with what goes with it.
pub struct Moving {
    pub lane: LaneState,
    /// Its metrics so far, for the session's summary.
    pub summary: Option<LaneAccumulator>,
    /// The lane resets its thread had made when it left: one made since on the other side
    /// resets it on arrival.
    pub resets: u64,
}

impl Moving {
    fn id(&self) -> AlgorithmId {
        self.lane.id()
    }

    /// Into `engine` and `summary`, reset if the receiving side has reset its lanes since
    /// the lane left (`resets` there now). A lane `engine` refuses (it runs it already,
    /// which the hand-over never does) keeps only its metrics.
    fn arrive(mut self, engine: &mut Engine, summary: &mut SummaryBuilder, resets: u64) {
        if self.resets != resets {
            self.lane.reset();
        }
        if let Some(acc) = self.summary {
            summary.put_lane(acc);
        }
        let _ = engine.put_lane(self.lane);
    }
}

/// Takes lane `id` out of `engine` and its metrics out of `summary`, to be sent.
fn depart(
    engine: &mut Engine,
    summary: &mut SummaryBuilder,
    id: AlgorithmId,
    resets: u64,
) -> Option<Moving> {
    Some(Moving {
        lane: engine.take_lane(id)?,
        summary: summary.take_lane(id),
        resets,
    })
}

/// The stepping thread's end: asks for lanes, receives them, and sends back those its
/// command no longer hears.
pub struct SteppingEnd {
    requests: SyncSender<(usize, AlgorithmId)>,
    arrivals: Receiver<Moving>,
    departures: SyncSender<Moving>,
    /// Lanes asked for and not yet arrived.
    incoming: [bool; 3],
    /// The drive asked for, whose lane has not arrived: the blend to it starts when it does.
    wanted: Option<AlgorithmId>,
    /// Retunes of lanes on their way here, applied when they arrive. Built off this thread;
    /// only their hand-over happens here.
    held: Vec<Retune>,
}

/// The comparison lanes' thread's end: serves the requests and takes lanes back.
pub struct LanesEnd {
    requests: Receiver<(usize, AlgorithmId)>,
    arrivals: SyncSender<Moving>,
    departures: Receiver<Moving>,
    /// Requests (the step at which it was asked, the lane) not yet served.
    asked: Vec<(usize, AlgorithmId)>,
    /// Lanes sent back, waiting for this thread to reach the step they left at.
    arriving: Vec<Moving>,
}

/// Both ends, connected.
pub fn ends() -> (SteppingEnd, LanesEnd) {
    let (requests, requests_rx) = sync_channel(REQUESTS);
    let (arrivals_tx, arrivals) = sync_channel(MAX_LANES);
    let (departures, departures_rx) = sync_channel(MAX_LANES);
    (
        SteppingEnd {
            requests,
            arrivals,
            departures,
            incoming: [false; 3],
            wanted: None,
            held: Vec::new(),
        },
        LanesEnd {
            requests: requests_rx,
            arrivals: arrivals_tx,
            departures: departures_rx,
            asked: Vec::new(),
            arriving: Vec::new(),
        },
    )
}

fn slot(id: AlgorithmId) -> usize {
    AlgorithmId::ALL.iter().position(|a| *a == id).unwrap_or(0)
}

/// What [`SteppingEnd::receive`] saw arrive.
pub struct Arrived {
    pub id: AlgorithmId,
    /// Steps the lane missed on its way (0 unless the comparison lanes' thread was behind:
    /// it steps on from the current sample).
    pub missed_steps: usize,
    /// The drive switched to it: its blend starts now.
    pub drives: bool,
}

impl Arrived {
    /// The event of a drive's lane arriving, the blend from `from` over `blend_s` starting.
    pub fn text(&self, from: AlgorithmId, blend_s: f64) -> String {
        let late = if self.missed_steps > 0 {
            format!(
                " {} steps late, stepping on from the current sample",
                self.missed_steps
            )
        } else {
            String::new()
        };
        format!(
            "drive: {}'s lane came over from the comparison lanes' thread{late}; the command \
             blends from {}'s to {}'s within {blend_s:.2} s",
            self.id.key(),
            from.key(),
            self.id.key()
        )
    }
}

impl SteppingEnd {
    /// The drive switched to `to` at step `k` ([`crate::tuning::Applied::Drive`]): blending
    /// in already when `here`, else asked for.
    pub fn drive(&mut self, to: AlgorithmId, here: bool, k: usize) {
        if here {
            self.wanted = None;
            return;
        }
        self.wanted = Some(to);
        self.ask(to, k);
    }

    fn ask(&mut self, id: AlgorithmId, k: usize) {
        // Full or hung up: asked again at the next step ([`SteppingEnd::receive`]).
        if !self.incoming[slot(id)] && self.requests.try_send((k, id)).is_ok() {
            self.incoming[slot(id)] = true;
        }
    }

    /// A retune for a lane on its way here is held for its arrival; others are handed
    /// back, for the comparison lanes' thread.
    pub fn route(&mut self, retune: Box<Retune>) -> Option<Box<Retune>> {
        let ids = retune.algorithms();
        if !ids.is_empty() && ids.iter().all(|id| self.incoming[slot(*id)]) {
            self.held.push(*retune);
            None
        } else {
            Some(retune)
        }
    }

    /// Before the step `k`: every lane that has arrived goes into `engine` (its held
    /// retunes with it, blended in over `blend_s`), and the drive asked for starts its blend
    /// over `blend_s` when its lane is among them. `resets`: the lane resets made so far.
    /// Calls `arrived` for each (an event); allocates nothing when nothing arrived.
    pub fn receive(
        &mut self,
        engine: &mut Engine,
        summary: &mut SummaryBuilder,
        drives: &mut DriveSwitch,
        resets: u64,
        blend_s: f64,
        mut arrived: impl FnMut(Arrived),
    ) {
        let k = engine.position();
        loop {
            let m = match self.arrivals.try_recv() {
                Ok(m) => m,
                Err(TryRecvError::Empty | TryRecvError::Disconnected) => break,
            };
            let id = m.id();
            let missed_steps = k.saturating_sub(m.lane.position());
            self.incoming[slot(id)] = false;
            m.arrive(engine, summary, resets);
            let mut i = 0;
            while i < self.held.len() {
                if self.held[i].algorithms().contains(&id) {
                    engine.retune(self.held.remove(i), blend_s);
                } else {
                    i += 1;
                }
            }
            let switch = self.wanted == Some(id);
            if switch {
                drives.switch(id, blend_s);
                self.wanted = None;
            }
            arrived(Arrived {
                id,
                missed_steps,
                drives: switch,
            });
        }
        if let Some(w) = self.wanted {
            if !engine.has_lane(w) {
                self.ask(w, k);
            }
        }
    }

    /// After a step: every lane of `engine` the command no longer hears (its blend out is
    /// over) goes back to the comparison lanes' thread; kept one more step if it cannot go
    /// (the channel full, or no thread there).
    pub fn release(
        &mut self,
        engine: &mut Engine,
        summary: &mut SummaryBuilder,
        drives: &DriveSwitch,
        resets: u64,
    ) {
        for id in AlgorithmId::ALL {
            if !engine.has_lane(*id) || drives.hears(*id) || self.wanted == Some(*id) {
                continue;
            }
            let Some(m) = depart(engine, summary, *id, resets) else {
                continue;
            };
            if let Err(TrySendError::Full(m) | TrySendError::Disconnected(m)) =
                self.departures.try_send(m)
            {
                if let Some(acc) = m.summary {
                    summary.put_lane(acc);
                }
                let _ = engine.put_lane(m.lane);
            }
        }
    }

    /// After the session: the lanes still on their way here join `engine` and `summary`,
    /// so that every lane's metrics reach the summary.
    pub fn drain(&mut self, engine: &mut Engine, summary: &mut SummaryBuilder, resets: u64) {
        while let Ok(m) = self.arrivals.try_recv() {
            self.incoming[slot(m.id())] = false;
            m.arrive(engine, summary, resets);
        }
    }
}

impl LanesEnd {
    /// Before each step of the comparison lanes' `engine`: the lanes sent back that left at
    /// this step (or before: never, the stepping thread being ahead) go into it.
    pub fn take_back(&mut self, engine: &mut Engine, summary: &mut SummaryBuilder, resets: u64) {
        self.arriving.extend(self.departures.try_iter());
        let k = engine.position();
        let mut i = 0;
        while i < self.arriving.len() {
            if self.arriving[i].lane.position() <= k {
                self.arriving.remove(i).arrive(engine, summary, resets);
            } else {
                i += 1;
            }
        }
    }

    /// After each step: every lane asked for at a step this engine has now stepped leaves
    /// for the stepping thread, in the state it has reached.
    pub fn serve(&mut self, engine: &mut Engine, summary: &mut SummaryBuilder, resets: u64) {
        self.asked.extend(self.requests.try_iter());
        // Read after the requests: a lane sent back before it was asked for again is seen.
        self.arriving.extend(self.departures.try_iter());
        let k = engine.position();
        let arriving: Vec<AlgorithmId> = self.arriving.iter().map(|m| m.id()).collect();
        self.asked.retain(|(at, id)| {
            if engine.has_lane(*id) {
                if *at >= k {
                    return true;
                }
                if let Some(m) = depart(engine, summary, *id, resets) {
                    if let Err(e) = self.arrivals.send(m) {
                        // The stepping thread has hung up: the lane stays for the summary.
                        e.0.arrive(engine, summary, resets);
                    }
                }
                return false;
            }
            // On its way back here: served once it has arrived. Anywhere else (the stepping
            // thread has it, after a request already served), nothing to do.
            arriving.contains(id)
        });
    }

    /// After the session: the lanes on their way back join `engine` and `summary`.
    pub fn drain(&mut self, engine: &mut Engine, summary: &mut SummaryBuilder, resets: u64) {
        self.arriving.extend(self.departures.try_iter());
        for m in self.arriving.drain(..) {
            m.arrive(engine, summary, resets);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use hexcue_core::testing::{full_flight, manoeuvre};

    /// The hand-over's protocol on its own, with no thread: both ends stepped by hand over
    /// the same trace. The comparison side is two steps behind when it serves the request
    /// (a lagging thread), the stepping side has reset its lanes and retuned the lane while
    /// it travelled: the lane arrives two steps late and says so, is reset, takes the held
    /// retune, and then steps exactly as a lane reset and retuned at that step where it
    /// stood; the drive switches to it. The lane sent back joins the comparison engine at
    /// the step it left, not before, with its metrics.
    #[test]
    fn a_late_lane_is_reset_and_retuned_on_arrival_and_one_sent_back_waits_for_its_step() {
        let profile = full_flight();
        let trace = Arc::new(manoeuvre());
        let mut stepping = Engine::new(&profile, trace.clone(), &[AlgorithmId::Cwf]).unwrap();
        let mut lanes = Engine::new(&profile, trace.clone(), &[AlgorithmId::Mpc]).unwrap();
        let mut stood = Engine::new(&profile, trace.clone(), &[AlgorithmId::Mpc]).unwrap();
        let mut summaries = [0, 1].map(|_| SummaryBuilder::new(&profile, &trace.name));
        let (mut here, mut there) = ends();
        let mut drives = DriveSwitch::new(AlgorithmId::Cwf);
        let mut moving = false;
        for _ in 0..300 {
            summaries[0].push(&stepping.step().unwrap());
            summaries[1].push(&lanes.step().unwrap());
            stood.step().unwrap();
        }
        here.drive(AlgorithmId::Mpc, false, 300);
        let mut tuned = profile.clone();
        tuned.mpc.specific_force_weight[0] *= 2.0;
        let retune = Retune::build(&profile, &tuned, &[AlgorithmId::Mpc]).unwrap();
        assert!(here.route(Box::new(retune)).is_none(), "held for the lane");
        // The stepping side runs on and resets its lanes (a fade-in again) at step 302.
        for k in 300..303 {
            if k == 302 {
                stepping.reset_lanes();
            }
            summaries[0].push(&stepping.step().unwrap());
            stood.step().unwrap();
        }
        // The comparison side, behind, steps 300 and serves the request.
        summaries[1].push(&lanes.step().unwrap());
        let [ours, theirs] = &mut summaries;
        there.serve(&mut lanes, theirs, 0);
        assert!(!lanes.has_lane(AlgorithmId::Mpc));
        let mut arrived = Vec::new();
        here.receive(&mut stepping, ours, &mut drives, 1, 3.0, |a| {
            arrived.push(a.text(AlgorithmId::Cwf, 3.0))
        });
        assert_eq!(arrived.len(), 1);
        assert!(
            arrived[0].starts_with(
                "drive: mpc's lane came over from the comparison lanes' thread 2 steps late"
            ),
            "{}",
            arrived[0]
        );
        assert_eq!(drives.drive(), AlgorithmId::Mpc);
        assert!(stepping.has_lane(AlgorithmId::Mpc));
        assert_eq!(
            stepping.profile().mpc,
            tuned.mpc,
            "the held retune was applied"
        );
        // Where it stood at step 303 (in the surge pulse): reset, then retuned.
        stood.reset_lanes();
        stood.retune(
            Retune::build(&profile, &tuned, &[AlgorithmId::Mpc]).unwrap(),
            3.0,
        );
        for k in 303..400 {
            let (a, b) = (stepping.step().unwrap(), stood.step().unwrap());
            ours.push(&a);
            let (a, b) = (a.lane(AlgorithmId::Mpc).unwrap(), &b.lanes[0]);
            let close = (a.command.pose - b.command.pose).amax();
            assert!(close <= 1e-7, "step {k}: {:?} {:?}", a.command, b.command);
            moving |= a.command.pose.amax() > 1e-3;
        }
        assert!(moving, "the MPC never moved: nothing was compared");
        // The CWF is no longer heard once the drive is the MPC alone: it goes back, and the
        // comparison side, at step 301, takes it in only at step 400, where it left.
        let alone = DriveSwitch::new(AlgorithmId::Mpc);
        here.release(&mut stepping, ours, &alone, 1);
        assert!(!stepping.has_lane(AlgorithmId::Cwf));
        assert!(
            ours.take_lane(AlgorithmId::Cwf).is_none(),
            "its metrics went"
        );
        while lanes.position() < 400 {
            there.take_back(&mut lanes, theirs, 1);
            assert!(!lanes.has_lane(AlgorithmId::Cwf), "{}", lanes.position());
            theirs.push(&lanes.step().unwrap());
        }
        there.take_back(&mut lanes, theirs, 1);
        assert!(lanes.has_lane(AlgorithmId::Cwf));
        let frame = lanes.step().unwrap();
        assert_eq!(frame.lanes.len(), 1);
        theirs.push(&frame);
        let cwf = theirs
            .take_lane(AlgorithmId::Cwf)
            .expect("its metrics came with it");
        assert_eq!(cwf.id(), AlgorithmId::Cwf);
    }
}
