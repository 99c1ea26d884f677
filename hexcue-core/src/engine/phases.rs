//! A profile's two phases (air and `[ground]`): which algorithms they tune differently, and
//! those algorithms built and warmed up ahead, so that a change of phase on a live session's
//! stepping thread builds nothing.

use nalgebra::Vector3;

use super::Spares;
use crate::mca::{AlgorithmId, BuildError, CueInput, CueSample, MotionCueing, PlatformCommand};
use crate::profile::Profile;

/// Whether the two profiles tune algorithm `id` alike (`[mpc]` tunes the MPC and the S-MPC,
/// `[smpc]` the S-MPC).
pub(super) fn tunes_alike(a: &Profile, b: &Profile, id: AlgorithmId) -> bool {
    match id {
        AlgorithmId::Cwf => a.cwf == b.cwf,
        AlgorithmId::Mpc => a.mpc == b.mpc,
        AlgorithmId::Smpc => a.mpc == b.mpc && a.smpc == b.smpc,
    }
}

/// Algorithm `id` built ahead for both phases ([`Spares`]); none when `air` and `ground`
/// tune it alike.
pub(super) fn phase_spares(
    air: &Profile,
    ground: &Profile,
    id: AlgorithmId,
) -> Result<Spares, BuildError> {
    if tunes_alike(air, ground, id) {
        return Ok(Default::default());
    }
    let built = |p: &Profile| p.algorithm(id).map(|a| Some(warmed(a, p.dt_s())));
    Ok([[built(air)?, built(air)?], [built(ground)?, built(ground)?]])
}

/// Steps taken by a spare before it is put aside ([`warmed`]).
const WARM_UP_STEPS: usize = 50;

/// `algorithm` stepped [`WARM_UP_STEPS`] on a gentle manoeuvre, then reset to rest: an
/// algorithm sizes some of its buffers in its first steps (the MPC's prediction of the tilt it
/// follows, its solver's), which must not happen on a live session's stepping thread when the
/// spare is taken. A reset restores every running state, so the warm-up leaves no trace in
/// the commands.
fn warmed(mut algorithm: Box<dyn MotionCueing>, dt_s: f64) -> Box<dyn MotionCueing> {
    let mut applied = PlatformCommand::default();
    for k in 0..WARM_UP_STEPS {
        let t_s = k as f64 * dt_s;
        let sample = CueSample {
            delta_f_mps2: Vector3::new(1.5 * (2.0 * t_s).sin(), 0.5, -0.5),
            angular_velocity_radps: Vector3::new(0.05, 0.02 * t_s.cos(), 0.03),
        };
        applied = algorithm.step(&CueInput {
            k,
            t_s,
            dt_s,
            sample,
            preview: &[],
            applied: &applied,
            deadline: None,
        });
    }
    algorithm.reset();
    algorithm
}

/// A retune's algorithm for a profile with `[ground]`: its new tuning for each phase.
pub(super) struct PhaseSet {
    pub(super) id: AlgorithmId,
    /// The one algorithm when the two phases tune it alike.
    pub(super) single: Option<Box<dyn MotionCueing>>,
    pub(super) spares: Spares,
}

impl PhaseSet {
    pub(super) fn build(
        air: &Profile,
        ground: &Profile,
        id: AlgorithmId,
    ) -> Result<Self, BuildError> {
        let alike = tunes_alike(air, ground, id);
        Ok(PhaseSet {
            id,
            single: if alike {
                Some(air.algorithm(id)?)
            } else {
                None
            },
            spares: phase_spares(air, ground, id)?,
        })
    }

    /// The algorithm to run in phase `on_ground`, out of the set.
    pub(super) fn take_for(&mut self, on_ground: bool) -> Option<Box<dyn MotionCueing>> {
        self.single.take().or_else(|| {
            self.spares[on_ground as usize]
                .iter_mut()
                .find_map(Option::take)
        })
    }
}

/// Algorithms rebuilt for a new tuning, ready for [`super::Engine::retune`]: built apart from the
/// engine so that a live session builds them off its stepping thread (an MPC's set-up takes
/// longer than a step).
pub struct Retune {
    pub(super) profile: Profile,
    pub(super) algorithms: Vec<Box<dyn MotionCueing>>,
    /// With `[ground]`: the new ground profile and each changed algorithm for both phases.
    pub(super) phased: Option<PhasedRetune>,
}

pub(super) struct PhasedRetune {
    pub(super) ground: Profile,
    pub(super) sets: Vec<PhaseSet>,
}

impl Retune {
    /// The algorithms among `ids` whose section differs between `old` and `new`, built as
    /// `new` tunes them (`[mpc]` rebuilds the MPC and the S-MPC, `[smpc]` the S-MPC). With
    /// a `[ground]` table, those whose tuning differs in either phase, built for both
    /// phases, so that the engine changes phase afterwards without building anything.
    pub fn build(old: &Profile, new: &Profile, ids: &[AlgorithmId]) -> Result<Self, BuildError> {
        if new.ground.is_some() {
            let on_ground = |p: &Profile| {
                p.on_ground().map_err(|e| BuildError::Setup {
                    algorithm: ids.first().copied().unwrap_or(AlgorithmId::Cwf),
                    reason: e.to_string(),
                })
            };
            let (old_ground, new_ground) = (on_ground(old)?, on_ground(new)?);
            let sets = ids
                .iter()
                .filter(|id| {
                    !tunes_alike(old, new, **id) || !tunes_alike(&old_ground, &new_ground, **id)
                })
                .map(|id| PhaseSet::build(new, &new_ground, *id))
                .collect::<Result<Vec<_>, _>>()?;
            return Ok(Retune {
                profile: new.clone(),
                algorithms: Vec::new(),
                phased: Some(PhasedRetune {
                    ground: new_ground,
                    sets,
                }),
            });
        }
        let algorithms = ids
            .iter()
            .filter(|id| !tunes_alike(old, new, **id))
            .map(|id| new.algorithm(*id))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Retune {
            profile: new.clone(),
            algorithms,
            phased: None,
        })
    }

    /// The algorithms it changes.
    pub fn algorithms(&self) -> Vec<AlgorithmId> {
        let sets = self.phased.iter().flat_map(|p| p.sets.iter().map(|s| s.id));
        self.algorithms.iter().map(|a| a.id()).chain(sets).collect()
    }
}
