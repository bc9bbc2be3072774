//! Following a strike on the object at rest (exact switching, a scene with
//! a stored strike, [`crate::compile::rest`]): while its switches come
//! where the compiler found them, a voice takes the stored states instead
//! of changes of basis, and the stored instants without a search for the
//! switches the engine's certifying run confirmed
//! ([`certify_rest_strike`]). docs/numerics.md, "A strike on an object at
//! rest".

use super::kernel::BlockProps;
use super::{EngineState, RestRun, FREE};
use crate::compile::rest::{RestStrike, REST_ENERGY_MATCH, REST_MATCH};
use crate::compile::CompiledScene;
use crate::scene::Switching;

/// A stored switch's state and derivative, per unit momentum, and a later
/// release's hammer momentum and its derivative.
#[derive(Clone, Copy)]
pub(super) struct StoredSwitch<'a> {
    pub(super) s: &'a [f64],
    pub(super) s_d: &'a [f64],
    pub(super) hammer_eta: Option<(f64, f64)>,
}

/// How many of `scene`'s stored switches of a strike from rest
/// ([`RestStrike`]: the first release, then the later switches in order)
/// this engine's certified search locates where they are stored: a
/// downward strike from rest (unit momentum, the hammer put on the
/// surface) run sample by sample at the scene's rate, each switch located
/// by the search (the stored instant a hint) and matched against the store
/// as a voice matches it, up to the first switch that is not where the
/// store has it. Runs once per scene and records the count
/// ([`RestStrike::certified`]); later calls return it. A voice takes those
/// switches at their stored instants without a search. [`EngineState::new`]
/// calls it; the instrument calls it for every scene it compiles. 0 without
/// a stored strike or exact switching. Allocates (a voice state).
/// docs/numerics.md section 6.9. \[any-thread\]
pub fn certify_rest_strike(scene: &CompiledScene) -> usize {
    let Some(r) = scene.rest.as_ref() else {
        return 0;
    };
    *r.certified.get_or_init(|| {
        if scene.switching != Switching::Exact || !(scene.sm > 0.0) {
            return 0;
        }
        let mut st = EngineState::new_uncertified(scene);
        st.rest_trust = false;
        st.strike(scene, 0.0, -1.0 / scene.sm);
        let last = r.later.last().map_or(r.t_r, |sw| sw.t);
        let samples = (last / scene.h).ceil() as u64 + 2;
        for _ in 0..samples {
            st.tick(scene);
            // the run ends past its last stored switch, or at a miss
            if st.rest_run.is_none() {
                break;
            }
        }
        let x = st.exact_stats;
        (x.rest_releases + x.rest_later) as usize
    })
}

/// A strike from rest's next stored switch ([`stored_switch`]).
struct NextStored<'a> {
    /// Its instant since the run's first entry \[s, reference time\].
    t: f64,
    sw: StoredSwitch<'a>,
    /// The Taylor step's scale ([`crate::compile::rest::RestSwitch::rho`]).
    rho: f64,
    is_entry: bool,
    /// An entry's stored energy and its derivative.
    energy: Option<(f64, f64)>,
}

/// The stored switch `run.next` of `r`: the first release, then the later
/// switches (stored for a downward strike only). `None` past the last.
fn stored_switch<'a>(r: &'a RestStrike, run: &RestRun) -> Option<NextStored<'a>> {
    if run.next == 0 {
        let sw = StoredSwitch {
            s: &r.f,
            s_d: &r.f_d,
            hammer_eta: None,
        };
        return Some(NextStored {
            t: r.t_r,
            sw,
            rho: r.rho,
            is_entry: false,
            energy: None,
        });
    }
    let later = r.later.get(run.next - 1).filter(|_| run.eta < 0.0)?;
    Some(NextStored {
        t: later.t,
        sw: StoredSwitch {
            s: &later.s,
            s_d: &later.s_d,
            hammer_eta: later.hammer_eta,
        },
        rho: later.rho,
        is_entry: (run.next - 1).is_multiple_of(2),
        energy: later.energy,
    })
}

/// Whether a switch (`entering`) `d` after the stored instant of `next`
/// is that switch: the kind agrees, `|d| rho <= REST_MATCH`, and for an
/// entry the amplitude that gives the stored state the energy the flight
/// has (`flight()`, the entry conserves it) is the run's to
/// `REST_ENERGY_MATCH`. The amplitude, or `None` (a miss: the product).
fn rest_matches(
    run: &RestRun,
    next: &NextStored,
    entering: bool,
    d: f64,
    flight: impl FnOnce() -> f64,
) -> Option<f64> {
    if next.is_entry != entering || !((d * next.rho).abs() <= REST_MATCH) {
        return None;
    }
    let Some((e, e_d)) = next.energy else {
        return Some(run.lambda);
    };
    let stored = run.eta * run.eta * (e + d * e_d);
    let lambda = (flight() / stored).sqrt();
    ((lambda - run.lambda).abs() <= REST_ENERGY_MATCH).then_some(lambda)
}

impl EngineState {
    /// The stored switch of a strike from rest that is due now, if the
    /// strike has so far switched where the compiler found it would and
    /// this switch (an entry when `entering`, else a release) comes where
    /// the compiler found the next one: the state after it and its
    /// derivative per unit momentum, the offset `T - t` of this instant
    /// from the stored one, and the factor to write them with (the
    /// momentum the strike began with, times the amplitude the last entry
    /// measured). A switch elsewhere, or an entry whose state in flight is
    /// off the stored trajectory ([`REST_ENERGY_MATCH`]), ends the run (a
    /// miss); past the last stored switch the run ends without one.
    pub(super) fn rest_next<'a>(
        &mut self,
        scene: &'a CompiledScene,
        entering: bool,
    ) -> Option<(StoredSwitch<'a>, f64, f64)> {
        let run = self.rest_run.take()?;
        let r = scene.rest.as_ref()?;
        let next = stored_switch(r, &run)?;
        let t = (self.clock - run.clock0) as f64 * self.step_s + (self.t_in_step - run.t0);
        let d = t - next.t;
        let flight = || self.flight_energy(scene);
        let Some(lambda) = rest_matches(&run, &next, entering, d, flight) else {
            self.exact_stats.rest_misses += 1;
            return None;
        };
        let sw = next.sw;
        if run.next == 0 {
            self.exact_stats.rest_releases += 1;
        } else {
            self.exact_stats.rest_later += 1;
        }
        if run.next < r.later.len() {
            self.rest_run = Some(RestRun {
                next: run.next + 1,
                lambda,
                ..run
            });
        }
        Some((sw, d, lambda * run.eta))
    }

    /// A strike from rest's next stored switch where the engine's
    /// certifying run confirmed it ([`RestStrike::certified`]) and it falls
    /// inside the rest of this sample after `t`: how far after `t` it is,
    /// for the caller to advance and switch there as it does at a root,
    /// without a search. An entry is taken only where the flight's energy
    /// there matches the stored trajectory's (as
    /// [`rest_next`](Self::rest_next) checks it; the partial propagators
    /// it needs are those the advance then uses), so that a state off the
    /// trajectory leaves everything to the search. `None`: the search
    /// decides (no such switch, the run ended, [`set_rest_trust`] off).
    /// docs/numerics.md section 6.9. O(N). \[audio-thread\]
    ///
    /// [`set_rest_trust`]: Self::set_rest_trust
    pub(super) fn rest_trusted_switch(&mut self, scene: &CompiledScene, t: f64) -> Option<f64> {
        let run = self.rest_run.filter(|_| self.rest_trust)?;
        let r = scene.rest.as_ref()?;
        if run.next >= r.certified.get().copied().unwrap_or(0) {
            return None;
        }
        let next = stored_switch(r, &run)?;
        let k = (self.clock - run.clock0) as f64;
        let tau = run.t0 + next.t - k * self.step_s;
        if !(tau > t && tau < self.step_s) || next.is_entry == self.in_contact() {
            return None;
        }
        let w = tau - t;
        if next.is_entry {
            // the flight's energy at tau, the state not yet moved
            self.ensure_partial(scene, w);
            let d = k * self.step_s + (tau - run.t0) - next.t;
            let flight = || self.flight_energy_stepped(scene, Some((&self.p_part, w)));
            rest_matches(&run, &next, true, d, flight)?;
        }
        Some(w)
    }

    /// How many samples from now the one holding a strike from rest's next
    /// stored switch starts (0: this one), if such a strike is being
    /// followed. O(1). \[audio-thread\]
    pub(super) fn rest_due_in(&self, scene: &CompiledScene) -> Option<usize> {
        let run = self.rest_run.as_ref().filter(|_| self.rest_schedule)?;
        let rest = scene.rest.as_ref()?;
        let r = match run.next {
            0 => rest.t_r,
            j => rest.later.get(j - 1).filter(|_| run.eta < 0.0)?.t,
        };
        let at = run.clock0 as f64 + ((run.t0 + r) / self.step_s).floor();
        let now = self.clock as f64;
        (at >= now).then(|| (at - now).min(usize::MAX as f64 / 2.0) as usize)
    }

    /// The energy in flight in reference units (`0.5 |V_f s_f|^2 + 0.5
    /// eta^2`; no gravity), in O(N) through the free phase's block-diagonal
    /// energy form (NaN without one: the compiler stores no later entry
    /// then).
    fn flight_energy(&self, scene: &CompiledScene) -> f64 {
        self.flight_energy_stepped(scene, None)
    }

    /// [`flight_energy`](Self::flight_energy) of the state the propagators
    /// `by` (made for `w`, in flight) would step it to, without stepping
    /// it; `None`: of the state as it is.
    fn flight_energy_stepped(&self, scene: &CompiledScene, by: Option<(&BlockProps, f64)>) -> f64 {
        let Some(q) = scene.free.energy_quad.as_ref() else {
            return f64::NAN;
        };
        let s = &self.phases[FREE].s;
        let nb = q.aa.len();
        let mut acc = 0.0;
        for k in 0..nb {
            let (mut a, mut b) = (s[k], s[nb + k]);
            if let Some((p, _)) = by {
                let [p00, p01, p10, p11] = p.get(k);
                (a, b) = (p00 * a + p01 * b, p10 * a + p11 * b);
            }
            acc += q.aa[k] * a * a + q.ab[k] * a * b + q.bb[k] * b * b;
        }
        let v_h = by.map_or(self.v_h, |(_, w)| self.v_h - self.g * w);
        let eta = scene.sm * v_h;
        0.5 * (acc + eta * eta)
    }
}
