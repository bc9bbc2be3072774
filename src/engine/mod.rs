//! The per-sample engine: steps a [`CompiledScene`] exactly, switching between
//! the free and the contact phase (docs/numerics.md, "Exact switching"; the
//! paper's offset rod is the other [`Switching`](crate::scene::Switching) method).
//!
//! A voice is an [`EngineState`]: one `PhaseState` per [`Phase`] (state in
//! that phase's block coordinates, spare buffer, one-sample propagators,
//! output rows), the hammer in flight, and the exact switching's scratch
//! (`exact`). The physical state is never rebuilt while stepping (only for
//! traces). A step costs one 2x2 multiply per block plus the rows the
//! decision and the outputs need (O(N)); a switch costs one change of basis
//! (O(N^2)). Nothing in [`EngineState::tick`] or
//! [`EngineState::process_block`] allocates: all buffers are sized in
//! [`EngineState::new`].
//!
//! Samples run in two paths: the fast path steps up to `EPOCH` samples in
//! the block kernel and certifies afterwards that none holds a switch (one
//! curvature bound per epoch, `curvature_bound_fast`; exact mode) or applies
//! the rod's sign test; a sample it cannot certify runs the slow path (the
//! certified event search of `exact`, or the rod's decision and a change of
//! basis).
//!
//! The SIMD kernels (`kernel`, `vmath`) are the crate's own (the
//! several-contact engine's block path runs the block kernel too): which
//! ones run is chosen by run-time detection, and the AVX2 ones can only be
//! reached with the token that detection makes (`vmath::SimdPath`).
//!
//! Time scaling (pitch): a voice may run the scene with its time axis scaled by
//! `s` (every frequency times `s`, every decay time over `s`, contact stiffness
//! times `s^2`, contact damping times `s`, gravity times `s^2`, hammer mass
//! kept; energies scale by `s^2` at equal displacement). Then the reference
//! system simply steps by `s h`, so the same decomposition serves every pitch;
//! only the 2x2 block propagators are recomputed (O(N), no allocation).
//! Velocities in the reference system are the physical ones divided by `s`.
//!
//! The engine's files, one concern each (this one holds the voice's state,
//! the public types, and making and resetting a voice; the others add
//! `impl EngineState` blocks or hold what those use):
//!
//! - `process`: the entry points that run samples (`tick*`,
//!   `process_block*`) and the slow path's sample;
//! - `fast_path`: the block kernel's runs and their certification;
//! - `exact`: exact switching's event search, one sample at a time;
//! - `switch`: the offset rod's decision, entering and leaving contact, the
//!   switch log;
//! - `rest`: following a strike on the object at rest through its stored
//!   switches;
//! - `replay`: a strike from rest played back from its recording;
//! - `drive`: a contact driven over a moving surface (the hammer kept
//!   relative to it, its velocity changed at each sample instant);
//! - `state`: what a caller reads and sets between blocks (coordinates,
//!   the hammer, pressure, a new strike);
//! - `observe`: the trace's observations; `energy`: the energy and its
//!   proxy;
//! - `scale`: time scale, pitch bend and output band;
//! - `rebind`: carrying a voice over to a recompiled scene;
//! - `knobs`: settings that choose between equivalent paths;
//! - `kernel`, `vmath`, `dot`: the SIMD kernels, batched exp/sin/cos, and
//!   the scalar dot products; `denormal`: subnormal numbers off while
//!   stepping.

pub mod denormal;
mod dot;
mod drive;
mod energy;
mod exact;
mod fast_path;
pub(crate) mod kernel;
mod knobs;
mod observe;
mod process;
mod rebind;
mod replay;
mod rest;
mod scale;
pub(crate) mod search;
mod state;
mod switch;
pub(crate) mod vmath;

pub use drive::SurfaceAt;
pub use exact::{ExactStats, MAX_SWITCHES_PER_SAMPLE, ROOT_ULPS};
use exact::{SearchScratch, TermSplit};
use kernel::{BlockAcc, BlockProps, BlockRows, QuadAcc, EPOCH};
use replay::Replay;
pub use replay::{StoredStrike, LINEAR_TOL, MAX_STORED_SAMPLES};
pub use rest::certify_rest_strike;
use vmath::SimdPath;

use crate::compile::{CompiledPhase, CompiledScene};

/// The kernels this CPU runs when not asked for the portable ones, by name
/// (`"avx2+fma (runtime-detected)"` or `"generic (baseline target)"`).
pub fn fastest_kernels() -> &'static str {
    SimdPath::detect().name()
}

/// Whether this CPU has faster kernels than the portable ones.
pub fn has_faster_kernels() -> bool {
    SimdPath::detect() != SimdPath::Generic
}

/// What the trace records per sample (docs/design.md, "The render command and the trace CSV"), physical units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Hammer contact-face height \[m\].
    pub x_hammer: f64,
    /// Hammer velocity \[m/s\].
    pub v_hammer: f64,
    /// Object displacement at the contact point \[m\].
    pub x_contact: f64,
    /// Object velocity at the contact point \[m/s\].
    pub v_contact: f64,
    /// In contact for the step that follows (offset rod) / at this instant (exact).
    pub in_contact: bool,
    /// Total energy \[J\]: object + hammer (kinetic and gravity) + contact spring.
    pub energy: f64,
}

/// A phase switch during the last [`EngineState::tick`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SwitchEvent {
    /// Seconds (physical) after the tick's start instant `t_n` (0 for the
    /// offset rod, whose switches happen at sample instants).
    pub after_s: f64,
    /// `true` when contact started, `false` when it ended.
    pub entered: bool,
}

/// What the trace records per sample but the energy (see [`Observation`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Motion {
    /// Hammer contact-face height \[m\].
    pub x_hammer: f64,
    /// Hammer velocity \[m/s\].
    pub v_hammer: f64,
    /// Object displacement at the contact point \[m\].
    pub x_contact: f64,
    /// Object velocity at the contact point \[m/s\].
    pub v_contact: f64,
    /// In contact (see [`Observation::in_contact`]).
    pub in_contact: bool,
}

impl Motion {
    /// The observation with `energy` \[J\].
    pub fn with_energy(self, energy: f64) -> Observation {
        Observation {
            x_hammer: self.x_hammer,
            v_hammer: self.v_hammer,
            x_contact: self.x_contact,
            v_contact: self.v_contact,
            in_contact: self.in_contact,
            energy,
        }
    }
}

/// Switches recorded per tick by default (offline tools that expect more,
/// e.g. chattering contacts far above Nyquist, ask for a larger log with
/// [`EngineState::set_event_log_capacity`]; switches beyond it are counted
/// in [`EngineState::events_dropped`]).
const EVENT_LOG: usize = 64;

/// `bound_epoch` value that matches no epoch (bound not computed).
const NO_EPOCH: u64 = u64::MAX;

/// Why a time scale could not be applied.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeScaleError {
    /// The scale is not finite and positive.
    Invalid,
    /// A dense-fallback phase only has its propagator for the base rate.
    DenseFallback,
    /// A pitch bend on a scene with gravity would change the hammer's
    /// potential energy ([`EngineState::bend_time_scale`]).
    Gravity,
}

/// Which phase a voice is in: the hammer in flight, or in contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// The struck object alone; the hammer flies on its parabola.
    Free,
    /// Object, contact spring-damper and hammer together.
    Contact,
}

impl Phase {
    /// Index into [`EngineState`]'s per-phase states.
    #[inline]
    pub fn index(self) -> usize {
        self as usize
    }
}

/// Index of the free phase's `PhaseState`.
const FREE: usize = Phase::Free as usize;

/// Index of the contact phase's `PhaseState`.
const CONTACT: usize = Phase::Contact as usize;

/// A strike from rest that has so far switched where the compiler found it
/// would ([`crate::compile::rest`]).
#[derive(Debug, Clone, Copy)]
struct RestRun {
    /// The clock at the strike's first entry.
    clock0: u64,
    /// The time into that sample where it began \[s, reference time\].
    t0: f64,
    /// The hammer's momentum at the entry (energy coordinates).
    eta: f64,
    /// The next stored switch: 0 the first release, `j` the later switch
    /// `j - 1`.
    next: usize,
    /// The state's amplitude relative to the stored trajectory's, as the
    /// last entry measured it from the energies (1 up to rounding).
    lambda: f64,
}

/// What a voice keeps per phase, sized for that phase's compiled form.
#[derive(Debug, Clone)]
struct PhaseState {
    /// The state in the phase's block coordinates (structure of arrays).
    s: Vec<f64>,
    /// Double buffer: the fused step writes here, then the vectors swap.
    next: Vec<f64>,
    /// One-sample block propagators at the current time scale.
    props: BlockProps,
    /// Output rows `[left, right]` mixed at the current time scale and band.
    out: [Vec<f64>; 2],
    /// The exact event search's split of the phase's terms into slow and
    /// fast ones at the current step.
    split: TermSplit,
}

impl PhaseState {
    fn new(dim: usize) -> Self {
        Self {
            s: vec![0.0; dim],
            next: vec![0.0; dim],
            props: BlockProps::new(dim / 2),
            out: [vec![0.0; dim], vec![0.0; dim]],
            split: TermSplit::with_capacity(dim),
        }
    }
}

impl CompiledScene {
    /// The compiled form of `phase`.
    #[inline]
    pub fn phase(&self, phase: Phase) -> &CompiledPhase {
        match phase {
            Phase::Free => &self.free,
            Phase::Contact => &self.contact,
        }
    }
}

/// The current phase of `st` in `scene` (a plain shared borrow; split out so
/// the borrow checker sees it does not alias the state vectors).
fn current_phase<'a>(st: &EngineState, scene: &'a CompiledScene) -> &'a CompiledPhase {
    scene.phase(st.phase)
}
/// Mutable per-voice state. Sized for one compiled scene (or larger).
#[derive(Debug, Clone)]
pub struct EngineState {
    /// Per phase: state, spare buffer, propagators, output rows, search split.
    phases: [PhaseState; 2],
    /// The phase the voice is in.
    phase: Phase,
    scratch: Vec<f64>,
    /// Kernel variant for this CPU.
    simd: SimdPath,
    /// Run with subnormals flushed to zero (see [`denormal`]); on unless a
    /// benchmark turns it off to measure what it saves.
    flush_denormals: bool,
    /// Cached rows of the current state: `[ev . s, left, right]`, valid when
    /// `cache_ok` (the block kernel computes them for the next sample).
    cache: [f64; 3],
    cache_ok: bool,
    /// Scratch of the block kernel: per-sample lane sums and the rows of
    /// every stepped state (boxed: 9 KiB, allocated once).
    acc: Box<BlockAcc>,
    brows: Box<BlockRows>,
    /// Samples since the last reset: the voice's own clock. Epochs of
    /// `EPOCH` samples of this clock (not the host's blocks) decide when the
    /// curvature bound is refreshed, so the output does not depend on how the
    /// caller splits its blocks.
    clock: u64,
    /// Interpolation margin of fast steps of exact switching: a bound on
    /// how far `phi` strays from the chord between a step's end values, for
    /// steps of `bound_dt` (reference time), valid for the epoch
    /// `bound_epoch` of `clock` and the current phase (each block is a
    /// contraction, so a bound taken from an earlier state of the same
    /// phase holds for every later one; see `fast_margin`).
    bound: f64,
    bound_epoch: u64,
    /// The step `bound` was taken for.
    bound_dt: f64,
    /// The Hermite certificate's remainder and rounding magnitude
    /// ([`hermite_margin`](Self::hermite_margin)) for steps of `herm_dt`,
    /// taken in the epoch `herm_epoch` of the current phase.
    herm_rem: f64,
    herm_mag: f64,
    herm_epoch: u64,
    herm_dt: f64,
    /// The last epoch of the clock in which the fast path tries the
    /// Hermite certificate: the one after the last sample it handed to
    /// the slow path (`None`: none since the reset).
    herm_until: Option<u64>,
    /// Try the Hermite certificate in the fast path (default); off only to
    /// compare with the slow path's in tests and benchmarks.
    fast_hermite: bool,
    /// Clear the rest of a sample after a located switch with the Hermite
    /// certificate (default); off only to compare with the search.
    hermite_after_switch: bool,
    /// Scratch of the kernel's slope row (boxed, allocated once).
    slope: Box<SlopeScratch>,
    /// How many samples the fast path tries at once: reset to
    /// `SPEC_RESTART` when a sample fails its check, doubled after each
    /// full success (speed only, never results).
    spec_len: usize,
    /// Constants added to the contact phase's outputs (its equilibrium)
    /// at load 1 ([`out_c_offset`](Self::out_c_offset) scales them).
    out_c_offset: [f64; 2],
    /// Output band [Hz, physical]: modes of the struck object above it are
    /// left out of the outputs (not of the dynamics). Infinite = all heard.
    band_hz: f64,
    /// Modes left out of the outputs by the band at the current scale.
    band_muted: usize,
    /// Offset rod length \[m\] (valid in contact).
    rod_m: f64,
    /// Hammer height \[m\] and reference-time velocity (valid in flight).
    x_h: f64,
    v_h: f64,
    /// Time scale `s` (1 = the scene as written).
    time_scale: f64,
    /// `s h`.
    step_s: f64,
    /// The constant force on the hammer (its weight and a hand's press)
    /// as a multiple of the scene's own ([`set_load`](Self::set_load)):
    /// 1 as compiled. Every quantity the force sets is the scene's times
    /// this: the hammer's acceleration, the contact phase's equilibrium
    /// `s_star` and the rows' constants.
    load: f64,
    /// The hammer's acceleration: the scene's gravity times `load`
    /// (reference time; physically `g s^2`).
    g: f64,
    /// Number of contact starts since the last reset (diagnostic).
    pub contacts_started: u64,
    /// Of those, the contacts of strikes played back from their recording
    /// ([`strike_stored`](Self::strike_stored)): counted where the replay
    /// ends, no switch work of the voice's own (diagnostic).
    pub contacts_replayed: u64,
    /// Scratch vectors for dense partial steps (exact switching).
    dense_tmp: [Vec<f64>; 3],
    /// Block propagators of the last partial step `exp(G tau)` (exact
    /// switching), for `part_tau` in the phase `part_contact`; valid when
    /// `part_ok` (cleared when the propagators' scene may change).
    p_part: BlockProps,
    /// Scratch of the batched partial propagators: per block `m tau`,
    /// `w tau`, then `exp(m tau)`, `sin(w tau)`, `cos(w tau)`.
    part_args: [Vec<f64>; 5],
    part_tau: f64,
    part_contact: bool,
    part_ok: bool,
    /// What exact switching did since the last reset (diagnostic).
    pub exact_stats: ExactStats,
    /// Switches of the last tick (fixed capacity: no allocation).
    events: Vec<SwitchEvent>,
    n_events: usize,
    /// Switches not recorded because the log was full (diagnostic).
    pub events_dropped: u64,
    /// Scratch of the exact event search.
    search: SearchScratch,
    /// Reference time consumed in the current step (for event times).
    t_in_step: f64,
    /// A strike that began on the object at rest (exact switching, a
    /// scene with [`CompiledScene::rest`]) and has so far switched where
    /// the compiler found it would (docs/numerics.md, "A strike on an
    /// object at rest").
    rest_run: Option<RestRun>,
    /// A strike just put the hammer on the surface (`phi = 0` exactly) and
    /// nothing has changed the state since: the coming sample's contact
    /// begins at its start if `phi' < 0` there, without a search
    /// ([`strike`](Self::strike), docs/numerics.md section 6.9).
    struck_on_surface: bool,
    /// Take [`struck_on_surface`](Self::struck_on_surface) (default); off
    /// only to compare with the search in tests.
    strike_entry: bool,
    /// Use the stored release of a strike from rest (default); off only to
    /// compare with the dense product in tests and benchmarks.
    rest_enabled: bool,
    /// Take a strike from rest's certified stored switches at their stored
    /// instants without a search (default); off only to compare with the
    /// search, and for the certifying run itself.
    rest_trust: bool,
    /// Let a strike from rest's stored switch instants schedule the fast
    /// path's runs (default; scheduling only, the same samples bit for bit).
    rest_schedule: bool,
    /// Switch through the hierarchical changes of basis where the scene has
    /// them (default); off only to compare with the dense product in tests
    /// and benchmarks.
    structured: bool,
    /// Offline observation scratch ([`process_block_observed`](Self::process_block_observed)),
    /// allocated on its first call.
    obs: Option<Box<ObsScratch>>,
    /// A stored strike from rest being played back
    /// ([`strike_stored`](Self::strike_stored)): the state above is the
    /// one the strike left until the replay ends or is settled.
    replay: Option<Replay>,
    /// A driven scene ([`CompiledScene::drive`]): the clock of the last
    /// sample whose surface slope the hammer was given (`NO_EPOCH`: none
    /// since the reset), that sample's path position \[m\], its step along
    /// the path \[m\] and the surface's rate over it \[m/s, physical\], and
    /// the speed along the path for the coming samples \[m/s\].
    drive_clock: u64,
    drive_path: f64,
    drive_step: f64,
    drive_rate: f64,
    drive_speed: f64,
}

/// Scratch of the kernel's slope row (`EngineState::run_kernel_rows`).
#[derive(Debug, Clone)]
struct SlopeScratch {
    acc: QuadAcc,
    out: [f64; EPOCH],
}

/// Scratch of [`EngineState::process_block_observed`] and
/// [`EngineState::process_block_traced`]: the contact point's rows and the
/// energy's form, summed in the fast path's own kernel pass.
#[derive(Debug, Clone)]
struct ObsScratch {
    zeros: Vec<f64>,
    /// The observation rows of every stepped state of the last kernel run.
    rows: Box<BlockRows>,
    oacc: Box<BlockAcc>,
    qacc: Box<QuadAcc>,
    qout: Box<[f64; EPOCH]>,
    /// The energy of the state at this clock, left by the last observed
    /// run (its last stepped state), so consecutive runs take every energy
    /// from the same kernel sums.
    e_next: Option<(u64, f64)>,
    /// The product vector of [`EngineState::energy_rt`].
    y: Vec<f64>,
}

/// A scene's one-sample block propagators at one time scale, both phases,
/// and its contact output rows with the output band applied where it
/// leaves modes out: what [`EngineState::set_time_scale`] computes (one
/// `exp` and one `sin_cos` per block, one row of `W_fc` per mode left
/// out), made ahead off the audio thread so a note-on at a common scale
/// copies them instead ([`EngineState::set_time_scale_from`]).
/// The instrument keeps one per MIDI key of the played scene
/// (docs/design.md, "The instrument"). \[worker\]
#[derive(Clone, Debug)]
pub struct ScaleProps {
    s: f64,
    /// The strike from rest at this scale, recorded for
    /// [`EngineState::strike_stored`] ([`ScaleProps::store_strike`]).
    strike: Option<std::sync::Arc<StoredStrike>>,
    /// The step they were made for (`scene.h * s`).
    step: f64,
    free: BlockProps,
    contact: BlockProps,
    /// The contact output rows with the output band applied, where it
    /// leaves modes out at this scale (else `None`: the band then costs
    /// O(N) at a note-on, nothing to make ahead).
    band: Option<BandRows>,
}

/// A note's contact output rows and offsets at one scale with the modes
/// above `band_hz` left out ([`EngineState::set_output_band`]): the
/// O(N M) part of the band, made ahead.
#[derive(Clone, Debug)]
struct BandRows {
    band_hz: f64,
    contact: [Vec<f64>; 2],
    offset: [f64; 2],
}

impl EngineState {
    /// Allocate state for `scene` and reset it to the scene's initial state.
    /// The first state made for a scene also certifies its stored strike
    /// from rest ([`certify_rest_strike`]). [main-thread / worker]
    pub fn new(scene: &CompiledScene) -> Self {
        certify_rest_strike(scene);
        Self::new_uncertified(scene)
    }

    /// [`new`](Self::new) without certifying the scene (what the
    /// certification itself runs on).
    fn new_uncertified(scene: &CompiledScene) -> Self {
        let df = scene.free.dim;
        let dc = scene.contact.dim;
        let mut st = EngineState {
            phases: [PhaseState::new(df), PhaseState::new(dc)],
            phase: Phase::Free,
            scratch: vec![0.0; df.max(dc)],
            simd: SimdPath::detect(),
            flush_denormals: true,
            cache: [0.0; 3],
            cache_ok: false,
            acc: Box::new([[[0.0; 4]; 3]; EPOCH]),
            brows: Box::default(),
            clock: 0,
            bound: 0.0,
            bound_epoch: NO_EPOCH,
            bound_dt: 0.0,
            spec_len: EPOCH,
            herm_rem: 0.0,
            herm_mag: 0.0,
            herm_epoch: NO_EPOCH,
            herm_dt: 0.0,
            herm_until: None,
            fast_hermite: true,
            hermite_after_switch: true,
            slope: Box::new(SlopeScratch {
                acc: [[0.0; 4]; EPOCH],
                out: [0.0; EPOCH],
            }),
            out_c_offset: [0.0; 2],
            band_hz: f64::INFINITY,
            band_muted: 0,
            rod_m: 0.0,
            x_h: 0.0,
            v_h: 0.0,
            time_scale: 1.0,
            step_s: scene.h,
            load: 1.0,
            g: scene.g,
            contacts_started: 0,
            contacts_replayed: 0,
            dense_tmp: [
                vec![0.0; df.max(dc)],
                vec![0.0; df.max(dc)],
                vec![0.0; df.max(dc)],
            ],
            exact_stats: ExactStats::default(),
            p_part: BlockProps::new(df.max(dc) / 2),
            part_args: std::array::from_fn(|_| vec![0.0; df.max(dc) / 2]),
            part_tau: 0.0,
            part_contact: false,
            part_ok: false,
            events: vec![SwitchEvent::default(); EVENT_LOG],
            n_events: 0,
            events_dropped: 0,
            search: SearchScratch::new(df.max(dc)),
            t_in_step: 0.0,
            rest_run: None,
            struck_on_surface: false,
            strike_entry: true,
            rest_enabled: true,
            rest_trust: true,
            rest_schedule: true,
            structured: true,
            obs: None,
            replay: None,
            drive_clock: NO_EPOCH,
            drive_path: 0.0,
            drive_step: 0.0,
            drive_rate: 0.0,
            drive_speed: 0.0,
        };
        st.set_time_scale(scene, 1.0)
            .expect("time scale 1 is always valid");
        st.reset(scene);
        st
    }

    /// Objects at rest, hammer at the scene's initial height and velocity.
    /// Does not allocate. \[audio-thread\]
    pub fn reset(&mut self, scene: &CompiledScene) {
        self.phases[FREE].s.iter_mut().for_each(|x| *x = 0.0);
        self.phases[CONTACT].s.iter_mut().for_each(|x| *x = 0.0);
        self.phase = Phase::Free;
        self.replay = None;
        self.rod_m = 0.0;
        self.x_h = scene.hammer_x0;
        self.v_h = scene.hammer_v0 / self.time_scale;
        self.contacts_started = 0;
        self.contacts_replayed = 0;
        self.exact_stats = ExactStats::default();
        self.events_dropped = 0;
        self.clock = 0;
        self.rest_run = None;
        self.herm_until = None;
        self.load = 1.0;
        self.g = scene.g;
        self.drive_clock = NO_EPOCH;
        self.drive_rate = 0.0;
        self.drive_step = 0.0;
        if let Some(d) = &scene.drive {
            self.drive_path = d.start_m;
            self.drive_speed = d.speed_m_per_s;
        }
        self.discontinuity();
    }

    /// The state jumped (reset, switch, strike, new propagators): the cached
    /// rows and the curvature bound no longer describe it.
    #[inline]
    fn discontinuity(&mut self) {
        self.struck_on_surface = false;
        self.cache_ok = false;
        self.bound_epoch = NO_EPOCH;
        self.herm_epoch = NO_EPOCH;
        // and the energy an observed run kept for the next run's first sample
        if let Some(o) = self.obs.as_mut() {
            o.e_next = None;
        }
    }

    /// The rows' constants under the current load: the scene's times
    /// [`load`](Self::set_load) (they are the rows of the force's
    /// equilibrium, linear in the force; the scene's own bit for bit at
    /// load 1).
    #[inline]
    fn out_c_offset(&self) -> [f64; 2] {
        self.out_c_offset.map(|x| x * self.load)
    }

    /// See [`offsets`](Self::offsets): the contact phase's output constants
    /// under the current load.
    #[inline]
    fn offsets(&self, scene: &CompiledScene) -> crate::compile::RowOffsets {
        let (o, l) = (&scene.offsets, self.load);
        crate::compile::RowOffsets {
            x_c: o.x_c * l,
            v_c: o.v_c * l,
            disp_l: o.disp_l * l,
            disp_r: o.disp_r * l,
            pi: o.pi * l,
            eta: o.eta * l,
        }
    }
}
