//! A strike from rest played back: the engine's own run of a strike on the
//! object at rest, recorded once per time scale off the audio thread at
//! unit speed, and replayed by a new note at its speed
//! (docs/numerics.md, "A strike from rest played back").
//!
//! Without gravity, the object at rest and the hammer put on its surface,
//! the whole strike is linear in the hammer's speed: every phase is linear,
//! and the instants of its switches (zeros of the gap, a linear function of
//! the state) do not move with the speed. So the samples, the state at the
//! end of the strike and everything a caller may ask on the way are the
//! unit run's times the speed. [`StoredStrike::record`] checks that the
//! engine's own runs at the slowest and the fastest speed a caller plays
//! are that product to rounding before it keeps a recording; a voice then
//! writes the product instead of stepping, searching and switching
//! ([`EngineState::strike_stored`]), and takes the stored end state where
//! the recording ends. Anything that changes the voice before then first
//! runs the strike for real up to where the replay is
//! ([`EngineState::settle`]).

use super::{EngineState, ExactStats, Motion, Phase, RestRun, ScaleProps, FREE};
use crate::compile::CompiledScene;
use crate::scene::Switching;
use std::sync::Arc;

/// The longest recording kept \[samples\]: a strike whose last stored
/// switch comes later (a very low note of a soft hammer) is not recorded.
pub const MAX_STORED_SAMPLES: usize = 2048;

/// How far the engine's runs at other speeds may stray from the unit run
/// times the speed (relative to that run's largest output, and to the
/// largest entry of its end state) for a recording to be kept: rounding
/// alone moves them by about 1e-15; a switch the search placed elsewhere at
/// another speed moves them by its root resolution or more.
pub const LINEAR_TOL: f64 = 1e-11;

/// What a caller can read of a replaying voice at the start of one of its
/// samples (unit speed), and the sample's output.
#[derive(Debug, Clone, Copy, Default)]
struct Frame {
    out: [f64; 2],
    /// The motion the trace records for the sample (after the decision).
    motion: Motion,
    /// In contact for the coming sample ([`EngineState::in_contact`]).
    contact: bool,
    /// [`EngineState::energy_proxy`].
    proxy: f64,
    /// [`EngineState::penetration`].
    pen: f64,
    /// Hammer height and reference-time velocity (in flight).
    x_h: f64,
    v_h: f64,
}

/// A strike from rest at one time scale, as the engine runs it at unit
/// speed (1 m/s) up to the sample after which it has left its stored
/// switches with the hammer in flight: per sample what a caller may read
/// and the output, then the state to continue from. \[worker\]
#[derive(Debug)]
pub struct StoredStrike {
    /// The time scale, step, output band and kernel it was run with.
    s: f64,
    step: f64,
    band_hz: f64,
    portable: bool,
    dims: (usize, usize),
    frames: Vec<Frame>,
    /// The free state, the hammer and the search's run state after the
    /// last frame.
    end: Vec<f64>,
    end_x_h: f64,
    end_v_h: f64,
    rest_run: Option<RestRun>,
    herm_until: Option<u64>,
    spec_len: usize,
    contacts: u64,
    stats: ExactStats,
    /// The largest relative difference of the runs at the other speeds.
    linear_err: f64,
}

/// A voice replaying a [`StoredStrike`] at `amp` times its speed, `k`
/// samples in.
#[derive(Debug, Clone)]
pub(super) struct Replay {
    data: Arc<StoredStrike>,
    k: usize,
    amp: f64,
}

impl StoredStrike {
    /// Record the strike from rest of `scene` at `pre`'s time scale with
    /// the output band `band_hz` (as a voice with that band plays it after
    /// copying `pre`), and check it against the engine's runs at `speeds`
    /// (m/s). `None` where it cannot be replayed: a scene with gravity or
    /// without exact switching, a dense phase, no contact or a recording
    /// longer than [`MAX_STORED_SAMPLES`], or a run at one of `speeds`
    /// further than [`LINEAR_TOL`] from the unit run times its speed.
    /// Allocates. \[worker\]
    pub fn record(
        scene: &CompiledScene,
        pre: &ScaleProps,
        band_hz: f64,
        speeds: &[f64],
    ) -> Option<Self> {
        if scene.switching != Switching::Exact
            || scene.g != 0.0
            || scene.free.dense.is_some()
            || scene.contact.dense.is_some()
        {
            return None;
        }
        // the stored switches' last instant, in samples at this scale: a
        // recording ends after it (not worth running when that is too long)
        if let Some(r) = scene.rest.as_ref() {
            let last = r.later.last().map_or(r.t_r, |sw| sw.t);
            if last / (scene.h * pre.s) > MAX_STORED_SAMPLES as f64 {
                return None;
            }
        }
        let unit = Self::run(scene, pre, band_hz)?;
        let mut err = 0.0f64;
        for &v in speeds {
            err = err.max(unit.distance(scene, pre, v)?);
        }
        (err <= LINEAR_TOL).then_some(Self {
            linear_err: err,
            ..unit
        })
    }

    /// A voice state at `pre`'s scale with the band `band_hz`, struck from
    /// rest at `speed`.
    fn struck(
        scene: &CompiledScene,
        pre: &ScaleProps,
        band_hz: f64,
        speed: f64,
    ) -> Option<EngineState> {
        let mut st = EngineState::new(scene);
        st.set_output_band(scene, band_hz);
        st.set_time_scale_from(scene, pre).ok()?;
        st.reset(scene);
        st.strike(scene, 0.0, -speed);
        Some(st)
    }

    /// The engine's strike from rest at unit speed, recorded sample by
    /// sample.
    fn run(scene: &CompiledScene, pre: &ScaleProps, band_hz: f64) -> Option<Self> {
        let mut st = Self::struck(scene, pre, band_hz, 1.0)?;
        let mut frames = Vec::new();
        let (mut l, mut r, mut m) = ([0.0], [0.0], [Motion::default()]);
        loop {
            let ended = st.contacts_started > 0 && !st.in_contact() && st.rest_run.is_none();
            if ended {
                break;
            }
            if frames.len() == MAX_STORED_SAMPLES {
                return None;
            }
            let f = Frame {
                contact: st.in_contact(),
                proxy: st.energy_proxy(scene),
                pen: st.penetration(scene),
                x_h: st.x_h,
                v_h: st.v_h,
                ..Frame::default()
            };
            st.process_block_observed(scene, &mut l, &mut r, &mut m);
            if !(l[0].is_finite() && r[0].is_finite()) {
                return None;
            }
            frames.push(Frame {
                out: [l[0], r[0]],
                motion: m[0],
                ..f
            });
        }
        Some(Self {
            s: st.time_scale,
            step: st.step_s,
            band_hz: st.band_hz,
            portable: st.portable_kernels(),
            dims: (scene.free.dim, scene.contact.dim),
            frames,
            end: st.phases[FREE].s.clone(),
            end_x_h: st.x_h,
            end_v_h: st.v_h,
            rest_run: st.rest_run,
            herm_until: st.herm_until,
            spec_len: st.spec_len,
            contacts: st.contacts_started,
            stats: st.exact_stats,
            linear_err: 0.0,
        })
    }

    /// The largest difference of the engine's run at speed `v` (as many
    /// samples, in one block) from this run times `v`, relative to this
    /// run's largest output (and largest end-state entry) times `v`;
    /// `None` when that run is not where this one ended (its hammer in
    /// flight past the stored switches after as many contacts).
    fn distance(&self, scene: &CompiledScene, pre: &ScaleProps, v: f64) -> Option<f64> {
        let mut st = Self::struck(scene, pre, self.band_hz, v)?;
        let n = self.frames.len();
        let (mut l, mut r) = (vec![0.0; n], vec![0.0; n]);
        st.process_block(scene, &mut l, &mut r);
        if st.contacts_started != self.contacts || st.in_contact() || st.rest_run.is_some() {
            return None;
        }
        let peak = self
            .frames
            .iter()
            .flat_map(|f| f.out)
            .fold(0.0f64, |a, x| a.max(x.abs()));
        let top = self.end.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let mut out = 0.0f64;
        for (a, (bl, br)) in self.frames.iter().zip(l.iter().zip(&r)) {
            out = out.max((bl - v * a.out[0]).abs());
            out = out.max((br - v * a.out[1]).abs());
        }
        let state = self
            .end
            .iter()
            .zip(&st.phases[FREE].s)
            .fold(0.0f64, |m, (a, b)| m.max((b - v * a).abs()));
        let err = (out / (v * peak)).max(state / (v * top));
        // not a number: never kept
        Some(if err.is_nan() { f64::INFINITY } else { err })
    }

    /// Samples replayed before the voice continues from the end state.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Never: a recording holds at least the strike's first sample.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Bytes it holds (its frames and its end state).
    pub fn heap_bytes(&self) -> usize {
        self.frames.len() * std::mem::size_of::<Frame>() + self.end.len() * 8
    }

    /// The largest relative difference the check at other speeds found.
    pub fn linear_err(&self) -> f64 {
        self.linear_err
    }
}

impl EngineState {
    /// [`strike`](Self::strike) a voice at rest (just reset, its scale and
    /// band those `pre` was made for) from the surface at
    /// `speed_m_per_s` (physical, positive down), and play it from `pre`'s
    /// stored strike ([`ScaleProps::stored_strike`]) where it has one:
    /// the next samples are the recording's times the speed, without a
    /// step, a search or a switch, then the voice goes on from the stored
    /// end state. Returns whether it replays; else it is an ordinary
    /// strike. O(N) like `strike` (the recording is shared, not copied).
    /// \[audio-thread\]
    pub fn strike_stored(
        &mut self,
        scene: &CompiledScene,
        speed_m_per_s: f64,
        pre: &ScaleProps,
    ) -> bool {
        let fresh = self.clock == 0
            && self.phase == Phase::Free
            && self.replay.is_none()
            && self.phases[FREE].s.iter().all(|&x| x == 0.0);
        self.strike(scene, 0.0, -speed_m_per_s);
        let Some(data) = pre.strike.as_ref() else {
            return false;
        };
        let fits = fresh
            && pre.fits(scene, self.time_scale)
            && data.s == self.time_scale
            && data.step == self.step_s
            && data.band_hz == self.band_hz
            && data.portable == self.portable_kernels()
            && data.dims == (scene.free.dim, scene.contact.dim)
            && data.end.len() == self.phases[FREE].s.len()
            && self.flush_denormals
            && self.rest_enabled
            && self.rest_trust
            && self.rest_schedule
            && self.structured
            && self.strike_entry
            && self.fast_hermite
            && self.hermite_after_switch
            && self.struck_on_surface
            && speed_m_per_s.is_finite()
            && speed_m_per_s > 0.0;
        if !fits {
            return false;
        }
        self.replay = Some(Replay {
            data: Arc::clone(data),
            k: 0,
            amp: speed_m_per_s,
        });
        self.exact_stats.replayed += 1;
        true
    }

    /// Whether the voice is replaying a stored strike.
    pub fn replaying(&self) -> bool {
        self.replay.is_some()
    }

    /// Run a replaying voice's strike for real up to where its replay is
    /// (the state is still the one the strike left: the replay has not
    /// touched it), so that it can be changed: what everything that
    /// changes a voice does first. Today's cost of the strike so far;
    /// nothing without a replay. \[audio-thread\]
    pub fn settle(&mut self, scene: &CompiledScene) {
        let Some(rp) = self.replay.take() else {
            return;
        };
        self.exact_stats.replayed = self.exact_stats.replayed.saturating_sub(1);
        self.exact_stats.settled += 1;
        let (mut l, mut r) = ([0.0; 64], [0.0; 64]);
        let mut left = rp.k;
        while left > 0 {
            let n = left.min(64);
            self.process_block(scene, &mut l[..n], &mut r[..n]);
            left -= n;
        }
    }

    /// The frame of a replaying voice at its current sample.
    fn frame(&self) -> Option<(&Frame, f64)> {
        self.replay
            .as_ref()
            .map(|rp| (&rp.data.frames[rp.k], rp.amp))
    }

    /// A replaying voice's next samples into `left`/`right` (up to the
    /// recording's end, where it takes the stored end state); returns how
    /// many. \[audio-thread\]
    pub(super) fn replay_block(&mut self, left: &mut [f64], right: &mut [f64]) -> usize {
        let Some(rp) = self.replay.as_mut() else {
            return 0;
        };
        let n = left.len().min(right.len()).min(rp.data.frames.len() - rp.k);
        for (j, f) in rp.data.frames[rp.k..rp.k + n].iter().enumerate() {
            left[j] = rp.amp * f.out[0];
            right[j] = rp.amp * f.out[1];
        }
        rp.k += n;
        if rp.k == rp.data.frames.len() {
            self.finish_replay();
        }
        n
    }

    /// [`replay_block`](Self::replay_block) with the motion of each
    /// sample. \[audio-thread\]
    pub(super) fn replay_observed(
        &mut self,
        left: &mut [f64],
        right: &mut [f64],
        motion: &mut [Motion],
    ) -> usize {
        if let Some(rp) = self.replay.as_ref() {
            let n = motion.len().min(rp.data.frames.len() - rp.k);
            for (m, f) in motion.iter_mut().zip(&rp.data.frames[rp.k..rp.k + n]) {
                *m = Motion {
                    x_hammer: rp.amp * f.motion.x_hammer,
                    v_hammer: rp.amp * f.motion.v_hammer,
                    x_contact: rp.amp * f.motion.x_contact,
                    v_contact: rp.amp * f.motion.v_contact,
                    in_contact: f.motion.in_contact,
                };
            }
            let n = n.min(left.len()).min(right.len());
            return self.replay_block(&mut left[..n], &mut right[..n]);
        }
        0
    }

    /// The replay is over: the voice goes on from the stored end state
    /// times the speed, as the strike would have left it.
    fn finish_replay(&mut self) {
        let Some(rp) = self.replay.take() else {
            return;
        };
        let d = &*rp.data;
        for (x, e) in self.phases[FREE].s.iter_mut().zip(&d.end) {
            *x = rp.amp * e;
        }
        self.phase = Phase::Free;
        self.x_h = rp.amp * d.end_x_h;
        self.v_h = rp.amp * d.end_v_h;
        self.clock = d.frames.len() as u64;
        self.rest_run = d.rest_run.map(|run| RestRun {
            eta: rp.amp * run.eta,
            ..run
        });
        self.herm_until = d.herm_until;
        self.spec_len = d.spec_len;
        self.contacts_started += d.contacts;
        self.contacts_replayed += d.contacts;
        self.exact_stats.add(&d.stats);
        self.discontinuity();
    }

    /// [`in_contact`](Self::in_contact) of a replaying voice.
    pub(super) fn replay_in_contact(&self) -> Option<bool> {
        self.frame().map(|(f, _)| f.contact)
    }

    /// [`energy_proxy`](Self::energy_proxy) of a replaying voice.
    pub(super) fn replay_proxy(&self) -> Option<f64> {
        self.frame().map(|(f, a)| a * a * f.proxy)
    }

    /// [`penetration`](Self::penetration) of a replaying voice.
    pub(super) fn replay_penetration(&self) -> Option<f64> {
        self.frame().map(|(f, a)| a * f.pen)
    }

    /// The hammer's height and reference-time velocity of a replaying
    /// voice.
    pub(super) fn replay_hammer(&self) -> Option<(f64, f64)> {
        self.frame().map(|(f, a)| (a * f.x_h, a * f.v_h))
    }
}

impl ScaleProps {
    /// Record the strike from rest at these propagators' scale
    /// ([`StoredStrike::record`]) and keep it for
    /// [`EngineState::strike_stored`]. Whether one was kept. \[worker\]
    pub fn store_strike(&mut self, scene: &CompiledScene, band_hz: f64, speeds: &[f64]) -> bool {
        self.strike = StoredStrike::record(scene, self, band_hz, speeds).map(Arc::new);
        self.strike.is_some()
    }

    /// Drop the stored strike (notes then strike as the engine runs them:
    /// a comparison for tests and benchmarks).
    #[doc(hidden)]
    pub fn forget_strike(&mut self) {
        self.strike = None;
    }

    /// The stored strike from rest at this scale, if one was recorded.
    pub fn stored_strike(&self) -> Option<&StoredStrike> {
        self.strike.as_deref()
    }
}
