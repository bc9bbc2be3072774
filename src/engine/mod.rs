//! The per-sample engine: steps a [`CompiledScene`] exactly, switching between
//! the free and the contact phase (docs/numerics.md, "Exact switching"; the
//! paper's offset rod is the other [`Switching`] method).
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
//! The SIMD kernels (`kernel`, `vmath`) are private: which ones run is
//! chosen by run-time detection, and the AVX2 ones can only be reached with
//! the token that detection makes (`vmath::SimdPath`).
//!
//! Time scaling (pitch): a voice may run the scene with its time axis scaled by
//! `s` (every frequency times `s`, every decay time over `s`, contact stiffness
//! times `s^2`, contact damping times `s`, gravity times `s^2`, hammer mass
//! kept; energies scale by `s^2` at equal displacement). Then the reference
//! system simply steps by `s h`, so the same decomposition serves every pitch;
//! only the 2x2 block propagators are recomputed (O(N), no allocation).
//! Velocities in the reference system are the physical ones divided by `s`.

pub mod denormal;
mod exact;
mod kernel;
mod replay;
mod vmath;

pub use exact::{ExactStats, MAX_SWITCHES_PER_SAMPLE, ROOT_ULPS};
use exact::{SearchScratch, TermSplit};
use kernel::{
    rows_of, run_block_with, BlockAcc, BlockIo, BlockProps, BlockRows, Extras, ObsIo, QuadAcc,
    QuadIo, Rows, SlopeIo, EPOCH,
};
use replay::Replay;
pub use replay::{StoredStrike, LINEAR_TOL, MAX_STORED_SAMPLES};
use vmath::SimdPath;

use crate::compile::rest::{RestStrike, REST_ENERGY_MATCH, REST_MATCH};
use crate::compile::{CompiledPhase, CompiledScene};
use crate::physics::block::exp2;
use crate::scene::Switching;
use denormal::FlushDenormals;

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

/// Switches recorded per tick by default (offline tools that expect more,
/// e.g. chattering contacts far above Nyquist, ask for a larger log with
/// [`EngineState::set_event_log_capacity`]; switches beyond it are counted
/// in [`EngineState::events_dropped`]).
const EVENT_LOG: usize = 64;

/// `bound_epoch` value that matches no epoch (bound not computed).
const NO_EPOCH: u64 = u64::MAX;

/// Samples the fast path tries after a sample failed its check. A kernel
/// run first loads every block's state, propagator and rows (at 200 modes
/// about as long as stepping 10 samples), so short runs cost nearly as
/// much as long ones, while a failure costs the run and a re-run of the
/// samples before it; so restarting at 16 rather than 1 makes a strike on
/// a ringing object cheaper, the more so the fewer its modes (the strike
/// table of `cargo bench --bench worst_block` measures a strike). Speed
/// only: the kernel's per-sample
/// sums do not depend on a run's length, so the output is the same bit for
/// bit.
const SPEC_RESTART: usize = 16;

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

/// A stored switch's state and derivative, per unit momentum, and a later
/// release's hammer momentum and its derivative.
#[derive(Clone, Copy)]
struct StoredSwitch<'a> {
    s: &'a [f64],
    s_d: &'a [f64],
    hammer_eta: Option<(f64, f64)>,
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
    /// Constants added to the contact phase's outputs (its equilibrium).
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
    /// The scene's gravity (reference time; physically `g s^2`).
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

/// What an observed run writes per sample: the motion, and the energy when
/// asked.
struct ObsOut<'a> {
    m: &'a mut [Motion],
    e: Option<&'a mut [f64]>,
}

/// The trace's rows of phase `ph`: `x_c, v_c` and, in contact, `eta`
/// (zeros in flight, `zeros` at least the phase's dimension).
fn obs_rows<'a>(ph: &'a CompiledPhase, zeros: &'a [f64], in_contact: bool) -> Rows<'a> {
    Rows {
        ev: &ph.rows.x_c,
        l: &ph.rows.v_c,
        r: if in_contact {
            &ph.rows.eta
        } else {
            &zeros[..ph.dim]
        },
    }
}

/// What a fast-path kernel run sums for the trace beside the audio.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Observe {
    /// Nothing (the instrument).
    No,
    /// The rows `x_c, v_c, eta` (in flight `v_c` alone: `x_c` is the
    /// negated event row).
    Motion,
    /// Those and the energy's block-diagonal form.
    MotionEnergy,
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

    /// Flush subnormal numbers to zero while stepping (default: on; see
    /// [`denormal`]). Off only to measure what it saves. \[any-thread\]
    pub fn set_flush_denormals(&mut self, on: bool) {
        self.flush_denormals = on;
    }

    /// Run the portable kernels (`true`) or the fastest ones this CPU has
    /// (`false`, the default). The two round differently (fused
    /// multiply-adds), each deterministically; benchmarks and equivalence
    /// tests compare them. \[any-thread\]
    pub fn set_portable_kernels(&mut self, portable: bool) {
        self.simd = if portable {
            SimdPath::Generic
        } else {
            SimdPath::detect()
        };
    }

    /// Whether the portable kernels run (see
    /// [`set_portable_kernels`](Self::set_portable_kernels)).
    pub fn portable_kernels(&self) -> bool {
        self.simd == SimdPath::Generic
    }

    /// Free-phase coordinates of the struck object (for tests and tools that
    /// set an initial vibration). Structure of arrays: block `k` is
    /// `(s[k], s[nb + k])`; for a modal object block `k` is mode `k`, i.e.
    /// `s[k] = omega_k q_k` and `s[n + k] = q_k'` (reference time).
    /// A replaying voice ([`strike_stored`](Self::strike_stored)) stops
    /// replaying and is at the instant of its strike: settle it
    /// ([`settle`](Self::settle)) first to change it where it is.
    pub fn free_state_mut(&mut self) -> &mut [f64] {
        self.replay = None;
        self.rest_run = None;
        self.discontinuity();
        &mut self.phases[FREE].s
    }

    /// Put the hammer in contact at the contact phase's static equilibrium
    /// (with gravity: resting on the object under its weight; without: just
    /// touching), the object following it, and return the contact-phase
    /// coordinates relative to that equilibrium (all zero now) for the caller
    /// to add a vibration. Structure of arrays like
    /// [`free_state_mut`](Self::free_state_mut); energy coordinates are
    /// `y = V (s + s_star)`, so the penetration cannot reach 0 while
    /// `|V s| < sqrt(k) p_static` in a passive phase. For benchmarks and
    /// tests of the steady contact phase. \[any-thread\]
    pub fn rest_in_contact(&mut self) -> &mut [f64] {
        self.replay = None;
        self.phases[CONTACT].s.iter_mut().for_each(|x| *x = 0.0);
        self.rest_run = None;
        self.rod_m = 0.0;
        self.phase = Phase::Contact;
        self.discontinuity();
        &mut self.phases[CONTACT].s
    }

    /// The current phase's state in its block coordinates (read only; the
    /// layout of [`free_state_mut`](Self::free_state_mut)). For tests and
    /// diagnostics; a replaying voice's is the one its strike left until
    /// it is settled ([`settle`](Self::settle)). \[any-thread\]
    pub fn phase_state(&self) -> &[f64] {
        &self.phases[self.phase.index()].s
    }

    /// Hammer height \[m\] and physical velocity \[m/s\] while in flight.
    pub fn hammer_in_flight(&self) -> Option<(f64, f64)> {
        let (x_h, v_h) = self.replay_hammer().unwrap_or((self.x_h, self.v_h));
        (!self.in_contact()).then_some((x_h, v_h * self.time_scale))
    }

    /// Whether the hammer is clear of the object for as long as both fly
    /// free: in flight, not falling back (no gravity, not moving down) and
    /// higher than the object's contact point can reach from its present
    /// state. Every block of the free phase is a contraction, so block
    /// `k`'s share of the contact point's displacement stays within `e_k
    /// |s_k|` (`CompiledPhase::ev_block`) and the point below their sum,
    /// while the hammer only rises. Also when that motion is damped more (a
    /// pressed voice: the object's state times a factor below 1), so a
    /// voice that is clear is pressed exactly by scaling its samples
    /// (docs/plugin.md, "Pressure and the mod wheel"). False for a dense
    /// free phase (no blocks to bound). The margin `1e-9` covers the sum's
    /// rounding and each step's `1 + 1e-12` of the blocks' contraction over
    /// far more steps than the 64 a decision stands for. O(N). \[audio-thread\]
    pub fn hammer_clear(&self, scene: &CompiledScene) -> bool {
        let ph = &scene.free;
        let nb = ph.dim / 2;
        // a replaying voice is never clear: its last stored switch is to come
        if self.replay.is_some()
            || self.in_contact()
            || self.g != 0.0
            || !(self.v_h >= 0.0)
            || ph.ev_block.len() != nb
        {
            return false;
        }
        let s = &self.phases[FREE].s;
        let reach: f64 = (0..nb)
            .map(|k| ph.ev_block[k] * (s[k] * s[k] + s[nb + k] * s[nb + k]).sqrt())
            .sum();
        self.x_h > reach * (1.0 + 1e-9)
    }

    /// [`energy_rt`](Self::energy_rt) of this state with the object's
    /// free state times `factor` (a pressed voice between two updates of
    /// its state, [`scale_free_state`](Self::scale_free_state)): the
    /// object's energy times `factor^2`, the hammer's as it is. In contact
    /// (never pressed) `energy_rt`. \[audio-thread after `reserve_observation`\]
    pub fn energy_rt_scaled(&mut self, scene: &CompiledScene, factor: f64) -> f64 {
        self.settle(scene);
        let e = self.energy_rt(scene);
        if factor == 1.0 || self.in_contact() {
            return e;
        }
        let s = self.time_scale;
        let hammer =
            s * s * (0.5 * scene.m_h * self.v_h * self.v_h + scene.m_h * scene.g * self.x_h);
        (e - hammer) * factor * factor + hammer
    }

    /// Multiply the free phase's state by `factor` (in `(0, 1]`): added
    /// mass-proportional damping over the samples it stands for (the
    /// instrument's pressure, docs/plugin.md, "Pressure and the mod
    /// wheel"). With `z(t) = e^(-a t) x(t)` every mode keeps its damped
    /// frequency and decays `a` faster; the free state has no affine part,
    /// so its energy is multiplied by `factor^2`. Refused (false, nothing
    /// changed) in contact, while replaying a stored strike, or for a
    /// factor outside `(0, 1]`. O(N). \[audio-thread\]
    pub fn scale_free_state(&mut self, factor: f64) -> bool {
        if self.replay.is_some() || self.in_contact() || !(factor > 0.0 && factor <= 1.0) {
            return false;
        }
        self.phases[FREE].s.iter_mut().for_each(|x| *x *= factor);
        self.rest_run = None;
        self.discontinuity();
        true
    }

    /// Whether the hammer is in contact (for the coming step; a replaying
    /// voice's as its stored strike has it).
    pub fn in_contact(&self) -> bool {
        self.replay_in_contact()
            .unwrap_or(self.phase == Phase::Contact)
    }

    /// Current time scale.
    pub fn time_scale(&self) -> f64 {
        self.time_scale
    }

    /// Run the scene with its time axis scaled by `s` (pitch ratio). O(N), no
    /// allocation (plus O(N M) for M modes left out by the output band, see
    /// [`EngineState::set_output_band`]). \[audio-thread\]
    pub fn set_time_scale(&mut self, scene: &CompiledScene, s: f64) -> Result<(), TimeScaleError> {
        scale_allowed(scene, s)?;
        self.settle(scene);
        self.set_time_scale_inner(scene, s);
        Ok(())
    }

    /// Change the time scale to `s` as a pitch bend does, without adding or
    /// removing energy: the object's state is scaled by `s_old / s` (its
    /// energy in reference units by `(s_old / s)^2`, so the physical energy
    /// `s^2 E_ref` is unchanged: a higher pitch at the same energy is a
    /// smaller displacement) and the hammer in flight keeps its physical
    /// velocity. Nothing happens in contact (the spring, the hammer and the
    /// object are coupled there): returns `Ok(false)` and the caller tries
    /// again after the release. In a scene with gravity the hammer's
    /// potential energy would change with the time axis: refused like
    /// the dense fallback ([`TimeScaleError::Gravity`]). O(N),
    /// allocation-free. \[audio-thread\]
    pub fn bend_time_scale(
        &mut self,
        scene: &CompiledScene,
        s: f64,
    ) -> Result<bool, TimeScaleError> {
        if !(s.is_finite() && s > 0.0) {
            return Err(TimeScaleError::Invalid);
        }
        if scene.free.dense.is_some() || scene.contact.dense.is_some() {
            return Err(TimeScaleError::DenseFallback);
        }
        if scene.g != 0.0 {
            return Err(TimeScaleError::Gravity);
        }
        // (a replaying voice in contact waits like any other, unsettled)
        if self.in_contact() {
            return Ok(false);
        }
        self.settle(scene);
        if self.in_contact() {
            return Ok(false);
        }
        if s == self.time_scale {
            return Ok(true);
        }
        let r = self.time_scale / s;
        for x in self.phases[FREE].s.iter_mut() {
            *x *= r;
        }
        self.set_time_scale_inner(scene, s);
        Ok(true)
    }

    /// [`set_time_scale`](Self::set_time_scale) at `pre`'s scale, its
    /// propagators copied from `pre` instead of computed, and its contact
    /// output rows too where `pre` holds them for this state's output band
    /// (bit for bit the same: `pre` was made by the same functions for
    /// `scene`). A `pre` made for another scene's step or block counts is
    /// not used: the propagators are then computed; rows made for another
    /// band are not used: the band is then applied, O(N M) for M modes
    /// left out. Otherwise O(N) copies, no transcendental function; no
    /// allocation. \[audio-thread\]
    pub fn set_time_scale_from(
        &mut self,
        scene: &CompiledScene,
        pre: &ScaleProps,
    ) -> Result<(), TimeScaleError> {
        scale_allowed(scene, pre.s)?;
        self.settle(scene);
        self.derive_for(scene, pre.s, false, Some(pre));
        Ok(())
    }

    fn set_time_scale_inner(&mut self, scene: &CompiledScene, s: f64) {
        self.derive_for(scene, s, false, None);
    }

    /// Everything [`set_time_scale_inner`](Self::set_time_scale_inner)
    /// derives from the scene at time scale `s`; `free_kept`: the free
    /// phase's propagators are already those of `scene` at `s` (the same
    /// free phase, the same scale), so only the contact phase's are
    /// computed (one exponential and one sine/cosine per block fewer).
    /// `pre`: the propagators at `s`, made ahead ([`ScaleProps`]), copied
    /// where they fit the scene.
    fn derive_for(
        &mut self,
        scene: &CompiledScene,
        s: f64,
        free_kept: bool,
        pre: Option<&ScaleProps>,
    ) {
        let free_kept = free_kept && s == self.time_scale && scene.h * s == self.step_s;
        let pre = pre.filter(|p| p.fits(scene, s));
        // physical velocity is preserved across a change of scale
        let v_phys = self.v_h * self.time_scale;
        self.time_scale = s;
        self.step_s = scene.h * s;
        // a contact's duration is counted in steps of one length
        self.rest_run = None;
        self.v_h = v_phys / s;
        if !free_kept {
            match pre {
                Some(p) => self.phases[FREE].props.copy_from(&p.free),
                None => fill_props(&mut self.phases[FREE].props, &scene.free, self.step_s),
            }
            self.phases[FREE].split.update(&scene.free, self.step_s);
        }
        match pre {
            Some(p) => self.phases[CONTACT].props.copy_from(&p.contact),
            None => fill_props(&mut self.phases[CONTACT].props, &scene.contact, self.step_s),
        }
        self.phases[CONTACT]
            .split
            .update(&scene.contact, self.step_s);
        self.part_ok = false;
        // Outputs in physical units: displacement rows as they are, velocity
        // rows times s (reference velocities are physical / s).
        for ch in 0..2 {
            mix_rows(&mut self.phases[FREE].out[ch], &scene.free, ch, s);
        }
        self.apply_band(scene, pre);
        self.g = scene.g;
        self.discontinuity();
    }

    /// Leave the struck object's modes whose frequency (at the current time
    /// scale, physical Hz) is above `band_hz` out of the outputs, in both
    /// phases, so a note pitched up never aliases its top modes back into
    /// the audio band. The dynamics are untouched (those modes still take
    /// part in the contact): only the pickup rows change, and they change
    /// consistently, because the contact rows are the free rows carried
    /// through `s_f = W_fc s_c + s_f*`: the output stays a continuous
    /// function of the physical state across every switch. `INFINITY` (the
    /// default) hears every mode; NaN or <= 0 is treated as `INFINITY`.
    /// A dense-fallback free phase has no modes to leave out (no effect).
    /// Allocation-free, O(N) plus O(N M) for M modes left out. \[audio-thread\]
    pub fn set_output_band(&mut self, scene: &CompiledScene, band_hz: f64) {
        self.settle(scene);
        self.band_hz = band_or_all(band_hz);
        // re-mix the rows (and apply the band) at the current scale
        self.set_time_scale_inner(scene, self.time_scale);
    }

    /// Modes currently left out of the outputs by the output band.
    pub fn band_muted_modes(&self) -> usize {
        self.band_muted
    }

    /// Mix the contact output rows at the current scale and leave the modes
    /// above the band out of them and of the free rows just mixed by
    /// `derive_for`: the free rows' entries zeroed, their contributions
    /// subtracted from the contact rows and offsets, O(N M) for M modes
    /// left out; or, where `pre` holds those contact rows for this band
    /// (made ahead by the same functions, so the same bits), O(N) copies
    /// of them instead.
    fn apply_band(&mut self, scene: &CompiledScene, pre: Option<&ScaleProps>) {
        let ahead = pre
            .and_then(|p| p.band.as_ref())
            .filter(|b| b.band_hz == self.band_hz);
        let [free, contact] = &mut self.phases;
        let free_rows = free.out.each_mut().map(|r| &mut r[..]);
        self.band_muted = match ahead {
            Some(b) => {
                for (dst, src) in contact.out.iter_mut().zip(&b.contact) {
                    dst.copy_from_slice(src);
                }
                self.out_c_offset = b.offset;
                band_out(scene, self.band_hz, self.time_scale, free_rows, None)
            }
            None => {
                for ch in 0..2 {
                    mix_rows(&mut contact.out[ch], &scene.contact, ch, self.time_scale);
                }
                self.out_c_offset = [scene.offsets.disp_l, scene.offsets.disp_r];
                let carry = (
                    contact.out.each_mut().map(|r| &mut r[..]),
                    &mut self.out_c_offset,
                );
                band_out(scene, self.band_hz, self.time_scale, free_rows, Some(carry))
            }
        };
    }

    /// Launch the hammer again from `height_m` with `velocity_m_per_s`
    /// (physical, positive up) while the object keeps its motion: a repeated
    /// strike hits a moving surface. If the old hammer is still in contact it is
    /// lifted off first (its spring is cut: that can only remove energy).
    /// Put on the surface (`height_m` 0), the coming sample decides at its
    /// start whether the contact begins there, without a search
    /// (docs/numerics.md section 6.9). O(N^2) when in contact, else O(N).
    /// \[audio-thread\]
    pub fn strike(&mut self, scene: &CompiledScene, height_m: f64, velocity_m_per_s: f64) {
        self.settle(scene);
        if self.in_contact() {
            // between samples: at the start of the coming one
            self.t_in_step = 0.0;
            self.leave_contact(scene);
        }
        // the surface's height as the event function sums it (its row is
        // `-x_c`, and a negated sum is the sum of the negated terms): a
        // hammer put on the surface then has `phi = 0` exactly
        let [ev_s, _, _] = self.event_sums(scene, 0.0, false);
        let height = height_m.max(0.0);
        self.x_h = -ev_s + height;
        self.v_h = velocity_m_per_s / self.time_scale;
        // a strike from rest still under way is not followed any further
        self.rest_run = None;
        self.discontinuity();
        // on the surface: whether the contact begins at this instant is
        // decided by the coming sample, from `phi' (0)`
        self.struck_on_surface = self.strike_entry && height == 0.0;
    }

    /// One sample: decide the phase at the current instant, return the output
    /// `[left, right]` of the current state, and advance one step. Same
    /// result as one sample of [`process_block`](Self::process_block).
    /// Allocation-free, O(N) (O(N^2) on a switch). \[audio-thread\]
    #[inline]
    pub fn tick(&mut self, scene: &CompiledScene) -> [f64; 2] {
        let (mut l, mut r) = ([0.0], [0.0]);
        self.process_block(scene, &mut l, &mut r);
        [l[0], r[0]]
    }

    /// Like [`tick`](Self::tick) but also returns the trace observation taken
    /// after the switching decision (docs/design.md, "The render command and
    /// the trace CSV"). O(N) plus the energy's cost ([`energy`](Self::energy)):
    /// offline only.
    pub fn tick_observed(&mut self, scene: &CompiledScene) -> ([f64; 2], Observation) {
        self.tick_with(scene, |st| st.observe(scene))
    }

    /// Like [`tick`](Self::tick), calling `look` on the state at the instant
    /// the trace records (after the switching decision, before the step):
    /// a caller that needs only part of the observation (e.g.
    /// [`motion`](Self::motion), and the energy now and then) pays only for
    /// that. Same samples as [`tick`](Self::tick). \[offline\]
    pub fn tick_with<R>(
        &mut self,
        scene: &CompiledScene,
        look: impl FnOnce(&mut Self) -> R,
    ) -> ([f64; 2], R) {
        self.settle(scene);
        let _flush = FlushDenormals::new(self.flush_denormals);
        self.n_events = 0;
        self.t_in_step = 0.0;
        let rod = scene.switching == Switching::OffsetRod;
        if rod {
            self.decide(scene);
        }
        let seen = look(self);
        let (mut l, mut r) = ([0.0], [0.0]);
        let (done, _) = self.run_fast(scene, &mut l, &mut r, rod, None);
        let out = if done == 1 {
            [l[0], r[0]]
        } else {
            self.slow_sample(scene, rod)
        };
        (out, seen)
    }

    /// Fill `left`/`right` with consecutive samples (f64): the block form of
    /// [`tick`](Self::tick), and what the instrument runs. The result does
    /// not depend on how a run is split into blocks (bit for bit).
    ///
    /// Samples in which no switch can happen (certified in exact mode by the
    /// curvature bound, decided by the sign test with the offset rod) run in
    /// the block kernel, up to `EPOCH` at a time; a sample that may hold a
    /// switch, and every sample of a dense-fallback phase, takes the slow
    /// path (event location, change of basis). Subnormal numbers are
    /// flushed to zero meanwhile ([`denormal`]), so a fading voice does not
    /// get slower. Allocation-free, no system call, O(N) per sample plus
    /// O(N^2) per switch. \[audio-thread\]
    pub fn process_block(&mut self, scene: &CompiledScene, left: &mut [f64], right: &mut [f64]) {
        let n = left.len().min(right.len());
        let mut i = self.replay_block(&mut left[..n], &mut right[..n]);
        if i == n {
            return;
        }
        let _flush = FlushDenormals::new(self.flush_denormals);
        kernel::clean_upper_state(self.simd);
        while i < n {
            let (done, slow) = self.run_fast(scene, &mut left[i..n], &mut right[i..n], false, None);
            i += done;
            if slow && i < n {
                let o = self.slow_sample(scene, false);
                left[i] = o[0];
                right[i] = o[1];
                i += 1;
            }
        }
    }

    /// [`process_block`](Self::process_block) that also writes each
    /// sample's [`Motion`] into `motion` (as [`tick_with`](Self::tick_with)
    /// would see it, after the switching decision): fast samples get it from
    /// the contact point's rows, summed in the block path's own kernel pass
    /// (about 1.3-1.6x the block path's cost at 100-1000 modes, instead of a
    /// tick per sample). Same
    /// samples as `process_block` bit for bit; the motion equals
    /// [`motion`](Self::motion)'s up to the order of the sums (rounding).
    /// Allocates its scratch on the first call unless
    /// [`reserve_observation`](Self::reserve_observation) did.
    /// \[offline\] \[audio-thread after `reserve_observation`\]
    pub fn process_block_observed(
        &mut self,
        scene: &CompiledScene,
        left: &mut [f64],
        right: &mut [f64],
        motion: &mut [Motion],
    ) {
        self.observed(scene, left, right, motion, None);
    }

    /// [`process_block_observed`](Self::process_block_observed) that also
    /// writes each sample's [`energy`](Self::energy) into `energy`. In a
    /// phase whose energy coordinates do not mix blocks
    /// ([`CompiledPhase::energy_quad`]: a modal object in flight, its
    /// uncoupled modes) the energy comes from the same kernel pass as the
    /// motion, O(N) per sample; elsewhere (a coupled contact phase, a
    /// string, gravity's equilibrium offset) each sample takes
    /// [`energy`](Self::energy), O(dim^2). Same samples as `process_block`
    /// bit for bit; motion and energy equal [`motion`](Self::motion)'s and
    /// [`energy`](Self::energy)'s up to the order of the sums. Allocates its
    /// scratch on the first call. \[offline\]
    pub fn process_block_traced(
        &mut self,
        scene: &CompiledScene,
        left: &mut [f64],
        right: &mut [f64],
        motion: &mut [Motion],
        energy: &mut [f64],
    ) {
        self.observed(scene, left, right, motion, Some(energy));
    }

    /// Allocate the scratch of [`process_block_observed`](Self::process_block_observed)
    /// and [`process_block_traced`](Self::process_block_traced) now, so that
    /// their calls allocate nothing (the instrument's live view observes
    /// voices on the audio thread). Idempotent. \[main-thread / worker\]
    pub fn reserve_observation(&mut self) {
        let dim = self.phases[FREE].s.len().max(self.phases[CONTACT].s.len());
        if self.obs.as_ref().is_none_or(|o| o.zeros.len() < dim) {
            self.obs = Some(Box::new(ObsScratch {
                zeros: vec![0.0; dim],
                rows: Box::default(),
                oacc: Box::new([[[0.0; 4]; 3]; EPOCH]),
                qacc: Box::new([[0.0; 4]; EPOCH]),
                qout: Box::new([0.0; EPOCH]),
                e_next: None,
                y: vec![0.0; dim],
            }));
        }
    }

    fn observed(
        &mut self,
        scene: &CompiledScene,
        left: &mut [f64],
        right: &mut [f64],
        motion: &mut [Motion],
        mut energy: Option<&mut [f64]>,
    ) {
        if energy.is_some() {
            // the energy is not stored with a strike from rest
            self.settle(scene);
        }
        self.reserve_observation();
        let mut n = left.len().min(right.len()).min(motion.len());
        if let Some(e) = energy.as_deref() {
            n = n.min(e.len());
        }
        let mut i = self.replay_observed(&mut left[..n], &mut right[..n], &mut motion[..n]);
        let _flush = FlushDenormals::new(self.flush_denormals);
        kernel::clean_upper_state(self.simd);
        while i < n {
            let (done, slow) = self.run_fast(
                scene,
                &mut left[i..n],
                &mut right[i..n],
                false,
                Some(ObsOut {
                    m: &mut motion[i..n],
                    e: energy.as_deref_mut().map(|e| &mut e[i..n]),
                }),
            );
            i += done;
            if slow && i < n {
                let want = energy.is_some();
                let (o, (m, e)) = self.tick_with(scene, |st| {
                    (st.motion(scene), want.then(|| st.energy_observed(scene)))
                });
                left[i] = o[0];
                right[i] = o[1];
                motion[i] = m;
                if let (Some(es), Some(e)) = (energy.as_deref_mut(), e) {
                    es[i] = e;
                }
                i += 1;
            }
        }
    }

    /// Whether the current phase's energy can come from the kernel pass
    /// (see [`process_block_traced`](Self::process_block_traced)).
    fn quad_energy_ok(&self, scene: &CompiledScene) -> bool {
        let ph = scene.phase(self.phase);
        ph.energy_quad.is_some()
            && ph.gens.is_some()
            && ph.dense.is_none()
            && (!self.in_contact() || scene.s_star.iter().all(|&x| x == 0.0))
    }

    /// The motion of the `k` samples the fast path is about to commit
    /// (before [`commit_kernel`](Self::commit_kernel)): state 0 is the
    /// current one, states `1..k` come from the rows `x_c, v_c, eta` (and
    /// the energy's form) the fast path's kernel pass summed beside its own
    /// (`Observe`); the hammer in flight follows the same parabola as
    /// the fast path, in contact its height is `x_c - p_eff - rod` with
    /// `p_eff` the event row the engine's own pass computed.
    fn observe_run(&mut self, scene: &CompiledScene, k: usize, out: ObsOut) {
        let ObsOut { m, e } = out;
        // energy of state 0: the last run's, or the state's own
        let e0 = match (&e, self.obs.as_ref().and_then(|o| o.e_next)) {
            (None, _) => None,
            (Some(_), Some((c, v))) if c == self.clock => Some(v),
            (Some(_), _) => Some(self.energy_observed(scene)),
        };
        let quad = if e.is_some() && self.quad_energy_ok(scene) {
            scene.phase(self.phase).energy_quad.as_ref()
        } else {
            None
        };
        let in_contact = self.in_contact();
        let ph = scene.phase(self.phase);
        let obs = self
            .obs
            .as_mut()
            .expect("allocated by process_block_observed");
        let ps = &self.phases[self.phase.index()];
        let r0 = rows_of(self.simd, &ps.s, &obs_rows(ph, &obs.zeros, in_contact));
        // states 1..k: the rows (and the energy's form) the engine's own
        // kernel pass summed beside its rows (`run_kernel_rows`)
        let (sc, dt, g) = (self.time_scale, self.step_s, self.g);
        let (mut x_h, mut v_h) = (self.x_h, self.v_h);
        for (j, mj) in m.iter_mut().enumerate().take(k) {
            let [xc, vc, eta] = if j == 0 {
                r0
            } else if in_contact {
                [obs.rows.ev[j - 1], obs.rows.l[j - 1], obs.rows.r[j - 1]]
            } else {
                // `x_c = -ev` bit for bit (the same products and sums,
                // negated), `0 - ev` so that a zero stays +0
                [0.0 - self.brows.ev[j - 1], obs.rows.ev[j - 1], 0.0]
            };
            *mj = if in_contact {
                let ev = if j == 0 {
                    self.cache[0]
                } else {
                    self.brows.ev[j - 1]
                };
                let x_c = xc + scene.offsets.x_c;
                Motion {
                    x_hammer: x_c - (ev + scene.offsets.pi / scene.sk) - self.rod_m,
                    v_hammer: (eta + scene.offsets.eta) / scene.sm * sc,
                    x_contact: x_c,
                    v_contact: (vc + scene.offsets.v_c) * sc,
                    in_contact: true,
                }
            } else {
                let here = Motion {
                    x_hammer: x_h,
                    v_hammer: v_h * sc,
                    x_contact: xc,
                    v_contact: vc * sc,
                    in_contact: false,
                };
                x_h += v_h * dt - 0.5 * g * dt * dt;
                v_h -= g * dt;
                here
            };
        }
        if let (Some(es), Some(e0)) = (e, e0) {
            // the affine terms of `energy`, from the motion just written
            let q = &obs.qout;
            let e_at = |j: usize, mj: &Motion| {
                let stored = 0.5 * q[j - 1];
                let x_h = mj.x_hammer;
                let v_h = mj.v_hammer / sc;
                let affine = if in_contact {
                    scene.m_h * scene.g * x_h
                } else {
                    0.5 * scene.m_h * v_h * v_h + scene.m_h * scene.g * x_h
                };
                sc * sc * (stored + affine)
            };
            es[0] = e0;
            if quad.is_some() {
                for j in 1..k {
                    es[j] = e_at(j, &m[j]);
                }
                // the state after the run: hammer in flight after k steps
                let (x_k, v_k) = if in_contact { (0.0, 0.0) } else { (x_h, v_h) };
                let last = Motion {
                    x_hammer: x_k,
                    v_hammer: v_k * sc,
                    ..m[k - 1]
                };
                obs.e_next = (!in_contact).then(|| (self.clock + k as u64, e_at(k, &last)));
            } else {
                obs.e_next = None;
            }
        }
    }

    /// The fast path: run up to `left.len()` samples (within the current
    /// epoch and the speculation length) through the block kernel, then
    /// check them in order; commit every sample before the first one that
    /// may hold a switch. Returns the samples done and whether the next one
    /// needs the slow path. `decided`: the offset-rod decision for the first
    /// sample was already taken (traces). \[audio-thread\]
    fn run_fast(
        &mut self,
        scene: &CompiledScene,
        left: &mut [f64],
        right: &mut [f64],
        decided: bool,
        obs: Option<ObsOut>,
    ) -> (usize, bool) {
        let phase = self.phase;
        let in_contact = phase == Phase::Contact;
        let ph = exact::current_phase(self, scene);
        if ph.dense.is_some() || ph.gens.is_none() {
            return (0, true);
        }
        let exact = scene.switching == Switching::Exact;
        let epoch_left = EPOCH - (self.clock % EPOCH as u64) as usize;
        let mut k_max = left
            .len()
            .min(right.len())
            .min(epoch_left)
            .min(self.spec_len);
        if obs.as_ref().is_some_and(|o| o.e.is_some()) && !self.quad_energy_ok(scene) {
            // energy from the state itself, one sample at a time
            k_max = k_max.min(1);
        }
        if k_max == 0 {
            return (0, false);
        }
        if exact {
            // A strike from rest knows the sample its next switch falls in
            // (a hint for where the run stops, never a decision): the run
            // ends before it, and that sample goes to the slow path as a
            // failed test would send it, without the run past it that the
            // failed test would throw away. Same samples bit for bit.
            match self.rest_due_in(scene) {
                Some(0) => {
                    self.spec_len = SPEC_RESTART;
                    self.herm_until = Some(self.clock / EPOCH as u64 + 1);
                    return (0, true);
                }
                Some(k) => k_max = k_max.min(k),
                None => {}
            }
        }
        if !self.cache_ok {
            self.refresh_cache(scene);
        }
        let epoch = self.clock / EPOCH as u64;
        let dt = self.step_s;
        if exact && (self.bound_epoch != epoch || self.bound_dt != dt) {
            self.bound = self.fast_margin(scene, dt);
            self.bound_epoch = epoch;
            self.bound_dt = dt;
        }
        // In the epoch of a sample that failed its test and the next one,
        // the samples are also tried with the Hermite certificate
        // (docs/numerics.md section 6.2): the kernel then sums the slope
        // row too. Keyed to the voice's clock (runs never cross an epoch),
        // so the output does not depend on how blocks are split.
        let hermite = exact && self.fast_hermite && self.herm_until.is_some_and(|u| epoch <= u);
        if hermite && (self.herm_epoch != epoch || self.herm_dt != dt) {
            (self.herm_rem, self.herm_mag) = self.hermite_margin(scene, dt);
            self.herm_epoch = epoch;
            self.herm_dt = dt;
        }
        let nb = ph.dim / 2;
        let herm_units = (2 * nb + 16) as f64 * f64::EPSILON;
        if exact {
            // The first sample's test below needs `phi0 - margin > 0` (or
            // the Hermite certificate, whose lower bound is at most
            // `phi0`), and `phi0` is known now. Where it fails (the
            // samples before a slow release, the sample a strike starts
            // in) every sample of the run would be thrown away: the same
            // decision, without the O(N k) run.
            let phi0 = self.cache[0]
                + if in_contact {
                    scene.offsets.pi / scene.sk
                } else {
                    self.x_h
                };
            let herm_ok = hermite && phi0 - self.herm_rem - herm_units * self.herm_mag > 0.0;
            if !(phi0 - self.bound > 0.0) && !herm_ok {
                self.spec_len = SPEC_RESTART;
                self.herm_until = Some(epoch + 1);
                return (0, true);
            }
        }
        // The slope at the run's first state, `phi'`: an O(N) sequential
        // sum, needed only where the first sample's chord test fails (later
        // samples take the kernel's slope row), so it is summed there.
        let mut d_j: Option<f64> = None;
        let observe = match &obs {
            None => Observe::No,
            Some(o) if o.e.is_some() && self.quad_energy_ok(scene) => Observe::MotionEnergy,
            Some(_) => Observe::Motion,
        };
        self.run_kernel_rows(scene, k_max, hermite, observe);
        // Check the samples in order (hammer in flight: its exact parabola).
        let g = self.g;
        let margin = self.bound;
        let (off, out_off) = if in_contact {
            (scene.offsets.pi / scene.sk, self.out_c_offset)
        } else {
            (0.0, [0.0; 2])
        };
        let (mut x_h, mut v_h) = (self.x_h, self.v_h);
        let mut rows_j = self.cache;
        let mut k_ok = k_max;
        for j in 0..k_max {
            let phi0 = rows_j[0] + if in_contact { off } else { x_h };
            let (x_h1, v_h1) = if in_contact {
                (x_h, v_h)
            } else {
                (x_h + v_h * dt - 0.5 * g * dt * dt, v_h - g * dt)
            };
            let next_rows = [self.brows.ev[j], self.brows.l[j], self.brows.r[j]];
            let ok = if exact {
                let phi1 = next_rows[0] + if in_contact { off } else { x_h1 };
                let chord = phi1 > 0.0 && phi0.min(phi1) - margin > 0.0;
                let d1 = if hermite {
                    self.slope.out[j] + if in_contact { 0.0 } else { v_h1 }
                } else {
                    0.0
                };
                let ok = chord
                    || hermite && {
                        let d0 = *d_j.get_or_insert_with(|| {
                            dot(&ph.ev_d, &self.phases[phase.index()].s)
                                + if in_contact { 0.0 } else { self.v_h }
                        });
                        let low = phi0
                            .min(phi1)
                            .min(phi0 + d0 * dt / 3.0)
                            .min(phi1 - d1 * dt / 3.0);
                        let hammer = if in_contact {
                            off.abs()
                        } else {
                            x_h.abs() + x_h1.abs() + dt * (v_h.abs() + v_h1.abs())
                        };
                        let allow = herm_units * (self.herm_mag + hammer);
                        low - self.herm_rem - allow > 0.0
                    };
                d_j = Some(d1);
                ok
            } else if j == 0 && decided {
                true
            } else if in_contact {
                phi0 > 0.0 // leave at the first sample with p_eff <= 0
            } else {
                !(phi0 < 0.0) // enter at the first sample with p > 0
            };
            if !ok {
                k_ok = j;
                break;
            }
            left[j] = rows_j[1] + out_off[0];
            right[j] = rows_j[2] + out_off[1];
            rows_j = next_rows;
            x_h = x_h1;
            v_h = v_h1;
        }
        if k_ok < k_max {
            self.exact_stats.kernel_discarded += (k_max - k_ok) as u64;
            self.spec_len = SPEC_RESTART;
            self.herm_until = Some((self.clock + k_ok as u64) / EPOCH as u64 + 1);
            if k_ok == 0 {
                return (0, true);
            }
            // Re-run only the certified samples (bit-identical: the kernel's
            // per-sample sums do not depend on the number of samples).
            self.run_kernel(scene, k_ok);
        } else {
            self.spec_len = (2 * self.spec_len).min(EPOCH);
        }
        if let Some(ObsOut { m, e }) = obs {
            self.observe_run(
                scene,
                k_ok,
                ObsOut {
                    m: &mut m[..k_ok],
                    e: e.map(|e| &mut e[..k_ok]),
                },
            );
        }
        self.commit_kernel(k_ok);
        if !in_contact {
            self.x_h = x_h;
            self.v_h = v_h;
        }
        self.clock += k_ok as u64;
        // The events of the last sample: none in a fast sample, unless the
        // offset rod's decision for it was already taken (and logged) by
        // `tick_observed`.
        if !(decided && k_ok == 1) {
            self.n_events = 0;
        }
        (k_ok, k_ok < k_max)
    }

    /// One sample on the slow path: a possible switch (located exactly, or
    /// the offset rod's decision) or a dense-fallback phase. `decided`: the
    /// offset-rod decision for this instant was already taken. \[audio-thread\]
    fn slow_sample(&mut self, scene: &CompiledScene, decided: bool) -> [f64; 2] {
        if !decided {
            self.n_events = 0;
            self.t_in_step = 0.0;
        }
        let out = if scene.switching == Switching::Exact {
            let out = self.output(scene);
            self.advance_exact(scene);
            self.discontinuity();
            out
        } else {
            if !decided {
                self.decide(scene);
            }
            let out = self.output(scene);
            self.step_plain(scene);
            out
        };
        self.clock += 1;
        out
    }

    /// One step of the current phase, no switching (offset rod after its
    /// decision): the block kernel, or the dense propagator.
    fn step_plain(&mut self, scene: &CompiledScene) {
        let phase = self.phase;
        let in_contact = phase == Phase::Contact;
        let ph = exact::current_phase(self, scene);
        if ph.dense.is_some() || ph.gens.is_none() {
            let s = &mut self.phases[phase.index()].s;
            step_phase(ph, s, &mut self.scratch);
            self.cache_ok = false;
        } else {
            self.run_kernel(scene, 1);
            self.commit_kernel(1);
        }
        if !in_contact {
            // Hammer in flight: exact parabola (never diagonalised), in
            // reference time (step s h, the scene's gravity).
            let dt = self.step_s;
            self.x_h += self.v_h * dt - 0.5 * self.g * dt * dt;
            self.v_h -= self.g * dt;
        }
    }

    /// Run the block kernel `k` samples from the current block phase's
    /// state into the spare buffer (the state itself is left untouched) and
    /// leave the rows of every stepped state in `brows`.
    fn run_kernel(&mut self, scene: &CompiledScene, k: usize) {
        self.run_kernel_rows(scene, k, false, Observe::No);
    }

    /// The kernel run of [`run_kernel`](Self::run_kernel), with the slope
    /// row when `slope`, and with what `observe` asks summed into the
    /// observation scratch (the trace's rows `x_c, v_c, eta`, and the
    /// energy's form): one pass over the state for the audio and the trace.
    fn run_kernel_rows(&mut self, scene: &CompiledScene, k: usize, slope: bool, observe: Observe) {
        let ph = scene.phase(self.phase);
        let in_contact = self.in_contact();
        let ps = &mut self.phases[self.phase.index()];
        let (s, next, props, out) = (&ps.s, &mut ps.next, &ps.props, &ps.out);
        let io = BlockIo {
            p: props,
            s,
            next,
            rows: Rows {
                ev: &ph.ev,
                l: &out[0],
                r: &out[1],
            },
            acc: &mut self.acc,
            out: &mut self.brows,
        };
        let mut extras = Extras::default();
        if slope {
            let SlopeScratch { acc, out: dout } = &mut *self.slope;
            extras.slope = Some(SlopeIo {
                row: &ph.ev_d,
                acc,
                out: dout,
            });
        }
        if observe != Observe::No {
            let obs = self
                .obs
                .as_deref_mut()
                .expect("allocated by reserve_observation");
            // in flight the event row is `-x_c` (the compiler's), so the
            // kernel's own event sums give `x_c` and only `v_c` is added
            extras.obs = Some(ObsIo {
                rows: if in_contact {
                    obs_rows(ph, &obs.zeros, true)
                } else {
                    Rows {
                        ev: &ph.rows.v_c,
                        l: &ph.rows.v_c,
                        r: &ph.rows.v_c,
                    }
                },
                all: in_contact,
                acc: &mut obs.oacc,
                out: &mut obs.rows,
            });
            if observe == Observe::MotionEnergy {
                extras.quad = ph.energy_quad.as_ref().map(|quad| QuadIo {
                    quad,
                    acc: &mut obs.qacc,
                    out: &mut obs.qout,
                });
            }
        }
        run_block_with(self.simd, io, extras, k);
    }

    /// The Hermite certificate's remainder for steps of `dt` from the
    /// current state, valid for every later state of the phase (each block
    /// is a contraction), and the magnitude its rounding allowance scales
    /// with: `(sum_k min(c4_k dt^4 / 384, 2 e_k + 8/27 dt c1_k) |s_k| (1 +
    /// 1e-12), sum_k (e_k + dt c1_k) |s_k|)`. docs/numerics.md section 6.2.
    fn hermite_margin(&self, scene: &CompiledScene, dt: f64) -> (f64, f64) {
        let (ph, s) = (scene.phase(self.phase), &self.phases[self.phase.index()].s);
        let nb = ph.dim / 2;
        if ph.ev_d4_block.len() != nb {
            return (f64::INFINITY, f64::INFINITY);
        }
        let (dt4, tail) = (dt * dt * dt * dt / 384.0, 8.0 / 27.0 * dt);
        let (rem, mag) = kernel::hermite_sums(
            self.simd,
            &s[..2 * nb],
            [&ph.ev_d_block, &ph.ev_d4_block, &ph.ev_block],
            [dt4, tail, dt],
        );
        (rem * (1.0 + 1e-12), mag)
    }

    /// Adopt the state of the last [`run_kernel`](Self::run_kernel) call,
    /// which ran `k >= 1` samples, and its rows as the cached rows.
    fn commit_kernel(&mut self, k: usize) {
        let ps = &mut self.phases[self.phase.index()];
        std::mem::swap(&mut ps.s, &mut ps.next);
        let j = k - 1;
        self.cache = [self.brows.ev[j], self.brows.l[j], self.brows.r[j]];
        self.cache_ok = true;
    }

    /// Interpolation margin for fast steps of `dt` from the current state:
    /// a bound on `|phi(t) - L(t)|` within any later step of the phase,
    /// `L` the chord between the step's end values, so that both end values
    /// above the margin certify no crossing inside. Per block the smaller
    /// of its curvature's share `c_k |s_k| dt^2 / 8` and `2 e_k |s_k|` (the
    /// block's share of `phi` and of the chord both stay within
    /// `e_k |s_k|`); no larger than the curvature bounds `|ev_dd| |s|` and
    /// `sqrt(sum c_k * sum c_k |s_k|^2)` times `dt^2 / 8` (see
    /// `CompiledPhase::ev_dd_block`, `ev_block`; docs/numerics.md section
    /// 6.2); plus gravity's exact `g dt^2 / 8` in flight. Valid for every
    /// later state of the phase. O(N).
    fn fast_margin(&self, scene: &CompiledScene, dt: f64) -> f64 {
        let (ph, s) = (scene.phase(self.phase), &self.phases[self.phase.index()].s);
        let h = dt * dt / 8.0;
        let (e, w, blocks) = kernel::margin_sums(self.simd, s, &ph.ev_dd_block, &ph.ev_block, h);
        let global2 = ph.ev_dd_norm * ph.ev_dd_norm * e;
        let weighted2 = ph.ev_dd_block_sum * w;
        let g = if self.in_contact() { 0.0 } else { self.g };
        // 1 + 1e-12: the blocks are contractions up to rounding of exp2,
        // and the sums round
        (g * h + blocks.min(global2.min(weighted2).sqrt() * h)) * (1.0 + 1e-12)
    }

    fn refresh_cache(&mut self, scene: &CompiledScene) {
        let ph = scene.phase(self.phase);
        let ps = &self.phases[self.phase.index()];
        let (s, out) = (&ps.s, &ps.out);
        let rows = Rows {
            ev: &ph.ev,
            l: &out[0],
            r: &out[1],
        };
        self.cache = rows_of(self.simd, s, &rows);
        self.cache_ok = true;
    }

    /// The event function now: flight `x_h - x_c`, contact `p_eff`
    /// (from the cached rows: the same numbers the fast path decides on).
    fn phi_now(&mut self, scene: &CompiledScene) -> f64 {
        if !self.cache_ok {
            self.refresh_cache(scene);
        }
        if self.in_contact() {
            self.cache[0] + scene.offsets.pi / scene.sk
        } else {
            self.cache[0] + self.x_h
        }
    }

    /// Effective penetration now (`p_eff`, with the rod) \[m\].
    pub fn penetration(&self, scene: &CompiledScene) -> f64 {
        if let Some(p) = self.replay_penetration() {
            return p;
        }
        if self.in_contact() {
            (dot(&scene.contact.rows.pi, &self.phases[CONTACT].s) + scene.offsets.pi) / scene.sk
        } else {
            dot(&scene.free.rows.x_c, &self.phases[FREE].s) - self.x_h
        }
    }

    /// Offset rod: the decision at a sample instant, on the same numbers
    /// the fast path uses ([`phi_now`](Self::phi_now)).
    fn decide(&mut self, scene: &CompiledScene) {
        let phi = self.phi_now(scene);
        if self.in_contact() {
            // Leave at the first sample with p_eff <= 0 (paper 2.2); cutting the
            // spring there can only lose its energy 0.5 k p_eff^2.
            if !(phi > 0.0) {
                self.leave_contact(scene);
            }
        } else if phi < 0.0 {
            // p = x_c - x_h = -phi > 0
            self.enter_contact(scene, -phi);
        }
    }

    /// Offset rod: the spring starts unstretched (p_eff = 0), so entering
    /// contact adds no energy. O(N^2): one change of basis; O(N) when the
    /// object is at rest (its coordinates are all zero).
    fn enter_contact(&mut self, scene: &CompiledScene, p: f64) {
        let at_rest = self.phases[FREE].s.iter().all(|&x| x == 0.0);
        let stored = if at_rest {
            None
        } else {
            self.rest_next(scene, true)
        };
        self.rod_m = p;
        let eta = scene.sm * self.v_h;
        let dc = scene.contact.dim;
        let [free, contact] = &mut self.phases;
        if let Some((sw, d, scale)) = stored {
            // a later contact of a strike from rest, where the compiler
            // found it: the state it stored
            for i in 0..dc {
                contact.s[i] = scale * (sw.s[i] + d * sw.s_d[i]) - scene.s_star[i];
            }
        } else {
            for i in 0..dc {
                contact.s[i] = scene.col_eta[i] * eta - scene.s_star[i];
            }
            if !at_rest {
                kernel::change_of_basis_add(
                    self.simd,
                    scene.w_cf_h.as_ref().filter(|_| self.structured),
                    scene.w_cf.as_slice(),
                    dc,
                    &free.s,
                    &mut contact.s,
                    &mut self.dense_tmp,
                );
            }
        }
        if at_rest {
            // a strike from rest begins: follow it
            self.rest_run =
                (self.rest_enabled && scene.rest.is_some() && scene.switching == Switching::Exact)
                    .then_some(RestRun {
                        clock0: self.clock,
                        t0: self.t_in_step,
                        eta,
                        next: 0,
                        lambda: 1.0,
                    });
        }
        self.phase = Phase::Contact;
        self.contacts_started += 1;
        self.discontinuity();
        self.log_event(true);
    }

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
    fn rest_next<'a>(
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

    /// Cut the spring (can only remove its energy). O(N^2): one change of
    /// basis; O(N) at the end of a strike on the object at rest, whose free
    /// state the compiler stored (docs/numerics.md, "A strike on an object
    /// at rest").
    fn leave_contact(&mut self, scene: &CompiledScene) {
        let rows = &scene.contact.rows;
        let [pi, x_c, eta] = dot3([&rows.pi, &rows.x_c, &rows.eta], &self.phases[CONTACT].s);
        // exactly `penetration`'s
        let p_eff = (pi + scene.offsets.pi) / scene.sk;
        let x_c = x_c + scene.offsets.x_c;
        let mut eta = eta + scene.offsets.eta;
        let df = scene.free.dim;
        let rest = self.rest_next(scene, false);
        let [free, contact] = &mut self.phases;
        if let Some((sw, d, scale)) = rest {
            for i in 0..df {
                free.s[i] = scene.s_f_star[i] + scale * (sw.s[i] + d * sw.s_d[i]);
            }
            if let Some((e, e_d)) = sw.hammer_eta {
                // the hammer leaves on the stored trajectory too
                eta = scale * (e + d * e_d);
            }
        } else {
            free.s[..df].copy_from_slice(&scene.s_f_star);
            kernel::change_of_basis_add(
                self.simd,
                scene.w_fc_h.as_ref().filter(|_| self.structured),
                scene.w_fc.as_slice(),
                df,
                &contact.s,
                &mut free.s,
                &mut self.dense_tmp,
            );
        }
        self.x_h = x_c - p_eff - self.rod_m;
        self.v_h = eta / scene.sm;
        self.rod_m = 0.0;
        self.phase = Phase::Free;
        self.discontinuity();
        self.log_event(false);
    }

    /// Let a strike from rest's stored switch instants end the fast path's
    /// runs before the samples that hold them (`true`, the default) or not:
    /// only for tests that check it changes no sample. \[any-thread\]
    #[doc(hidden)]
    pub fn set_rest_schedule(&mut self, on: bool) {
        self.rest_schedule = on;
    }

    /// Take strikes from rest through the stored release (`true`, the
    /// default) or always through the dense change of basis (`false`): only
    /// for tests and benchmarks that compare the two. \[any-thread\]
    #[doc(hidden)]
    pub fn set_rest_strike(&mut self, on: bool) {
        self.rest_enabled = on;
        if !on {
            self.rest_run = None;
        }
    }

    /// Take a strike from rest's stored switches that the engine's
    /// certifying run confirmed at their stored instants without a search
    /// (`true`, the default) or locate each with the search, the stored
    /// instant a hint (`false`): only for tests and benchmarks that compare
    /// the two. \[any-thread\]
    #[doc(hidden)]
    pub fn set_rest_trust(&mut self, on: bool) {
        self.rest_trust = on;
    }

    /// Switch through the hierarchical changes of basis where the scene has
    /// them (`true`, the default) or always through the dense matrices
    /// (`false`): only for tests and benchmarks that compare the two.
    /// \[any-thread\]
    #[doc(hidden)]
    pub fn set_structured_switch(&mut self, on: bool) {
        self.structured = on;
    }

    /// Let the fast path try the Hermite certificate after a failed sample
    /// (`true`, the default) or leave every such sample to the slow path
    /// (`false`): only for tests and benchmarks that compare the two.
    /// \[any-thread\]
    #[doc(hidden)]
    pub fn set_fast_hermite(&mut self, on: bool) {
        self.fast_hermite = on;
    }

    /// Begin the contact of a strike that puts the hammer on the surface
    /// moving into it at the strike's instant (`true`, the default) or
    /// leave that to the search (`false`): only for tests that compare the
    /// two. \[any-thread\]
    #[doc(hidden)]
    pub fn set_strike_entry(&mut self, on: bool) {
        self.strike_entry = on;
    }

    /// Clear the rest of a sample after a located switch with the Hermite
    /// certificate (`true`, the default) or always with the search
    /// (`false`): only for tests and benchmarks that compare the two.
    /// \[any-thread\]
    #[doc(hidden)]
    pub fn set_hermite_after_switch(&mut self, on: bool) {
        self.hermite_after_switch = on;
    }

    fn log_event(&mut self, entered: bool) {
        if self.n_events < self.events.len() {
            self.events[self.n_events] = SwitchEvent {
                after_s: self.t_in_step / self.time_scale,
                entered,
            };
            self.n_events += 1;
        } else {
            self.events_dropped += 1;
        }
    }

    /// Enter contact (offset rod at the current penetration) and leave it
    /// again: two changes of basis, O(N^2). Only for benchmarks of the switch
    /// cost. \[any-thread\]
    #[doc(hidden)]
    pub fn bench_switch_pair(&mut self, scene: &CompiledScene) {
        let p = self.penetration(scene);
        self.enter_contact(scene, p.max(0.0));
        self.leave_contact(scene);
    }

    /// Phase switches that happened during the last `tick` (offline
    /// diagnostics: contact start/end times). \[any-thread\]
    pub fn switch_events(&self) -> &[SwitchEvent] {
        &self.events[..self.n_events]
    }

    /// Record up to `n` switches per tick (default 64). Allocates: not on
    /// the audio thread. \[main-thread\]
    pub fn set_event_log_capacity(&mut self, n: usize) {
        self.events = vec![SwitchEvent::default(); n];
        self.n_events = 0;
    }

    #[inline]
    fn output(&mut self, scene: &CompiledScene) -> [f64; 2] {
        if !self.cache_ok {
            self.refresh_cache(scene);
        }
        if self.in_contact() {
            [
                self.cache[1] + self.out_c_offset[0],
                self.cache[2] + self.out_c_offset[1],
            ]
        } else {
            [self.cache[1], self.cache[2]]
        }
    }

    /// Cheap O(N) energy proxy in reference units: `0.5 |s|^2` of the current
    /// phase plus the hammer's kinetic energy. Exact for modal objects in
    /// flight (orthonormal blocks); within a factor kappa(V)^2 otherwise.
    /// Used to stop voices that have decayed and to pick the quietest
    /// voice to steal (for each note-on of a chord that steals: the sum
    /// runs in four lanes, `x[i]` into lane `i % 4`, which the compiler
    /// vectorises; a single chain of additions waited for each one).
    /// \[audio-thread\]
    pub fn energy_proxy(&self, scene: &CompiledScene) -> f64 {
        if let Some(e) = self.replay_proxy() {
            return e;
        }
        let s = &self.phases[self.phase.index()].s;
        let (quads, tail) = s.as_chunks::<4>();
        let mut acc = [0.0; 4];
        for q in quads {
            for l in 0..4 {
                acc[l] += q[l] * q[l];
            }
        }
        let tail: f64 = tail.iter().map(|x| x * x).sum();
        let state = 0.5 * (((acc[0] + acc[1]) + (acc[2] + acc[3])) + tail);
        match self.phase {
            Phase::Contact => state,
            Phase::Free => state + 0.5 * scene.m_h * self.v_h * self.v_h,
        }
    }

    /// Whether this state can be carried from `old` to `new`: the same
    /// layout (dimensions of both phases, and of this state), and no dense
    /// phase away from `s = 1` (a dense propagator cannot scale time).
    fn can_rebind(&self, old: &CompiledScene, new: &CompiledScene) -> bool {
        old.free.dim == new.free.dim
            && old.contact.dim == new.contact.dim
            && self.phases[FREE].s.len() == new.free.dim
            && self.phases[CONTACT].s.len() == new.contact.dim
            && !((new.free.dense.is_some() || new.contact.dense.is_some())
                && self.time_scale != 1.0)
    }

    /// Carry the running state over to a recompiled scene `new` (same object,
    /// other parameters), so a parameter change neither resets nor clicks.
    ///
    /// The state is taken to energy coordinates with `old` and back to phase
    /// coordinates with `new`; the energy coordinates themselves are kept, so
    /// the stored energy `0.5 |y|^2` is unchanged by the swap. In contact this
    /// keeps the spring coordinate `pi = sqrt(k) p_eff`: with a new stiffness
    /// `k'` the rod is re-chosen so that `0.5 k' p_eff'^2 = 0.5 k p_eff^2`
    /// (docs/numerics.md, "The stability cases": parameters changed during
    /// contact), and the hammer keeps its momentum coordinate.
    /// Returns `false` (state untouched) when the layouts differ (another
    /// object or another mode count): the caller then resets the voice.
    /// O(N^2), allocation-free. \[audio-thread\]
    pub fn rebind(&mut self, old: &CompiledScene, new: &CompiledScene) -> bool {
        self.settle(old);
        if !self.can_rebind(old, new) {
            return false;
        }
        let (ph_old, ph_new, s, star_old, star_new) = if self.in_contact() {
            (
                &old.contact,
                &new.contact,
                &mut self.phases[CONTACT].s,
                &old.s_star[..],
                &new.s_star[..],
            )
        } else {
            (
                &old.free,
                &new.free,
                &mut self.phases[FREE].s,
                &[][..],
                &[][..],
            )
        };
        let dim = ph_old.dim;
        // y = V_old (s + s*_old)
        for i in 0..dim {
            let mut acc = 0.0;
            for j in 0..dim {
                acc += ph_old.v[(i, j)] * (s[j] + star_old.get(j).copied().unwrap_or(0.0));
            }
            self.scratch[i] = acc;
        }
        // s = V_new^{-1} y - s*_new
        for i in 0..dim {
            let mut acc = 0.0;
            for j in 0..dim {
                acc += ph_new.vinv[(i, j)] * self.scratch[j];
            }
            s[i] = acc - star_new.get(i).copied().unwrap_or(0.0);
        }
        if self.in_contact() {
            // keep the true penetration p = p_eff + rod: x_h is unchanged
            // only if the spring length is; choose the rod so p_eff' = pi/sk'.
            let pi = dot(&new.contact.rows.pi, &self.phases[CONTACT].s) + new.offsets.pi;
            let p_true = self.rod_m + old_p_eff(old, pi);
            self.rod_m = p_true - pi / new.sk;
        }
        let scale = self.time_scale;
        // re-derive propagators and output rows for the new scene
        self.set_time_scale_inner(new, scale);
        true
    }

    /// [`rebind`](Self::rebind) for a state out of contact whose new scene
    /// steps the free phase in the same coordinates as the old one (the
    /// same `V` and free propagators: the same object, only the contact
    /// differs, as for the brightness levels of
    /// [`crate::instrument::Scenes`], which the worker compares): the state
    /// stays as it is, bit for bit, the free phase's propagators too, and
    /// the contact phase's propagators and the rows are derived again for
    /// `new`. O(N) instead of O(N^2). Returns `false` (state untouched) in contact, when the
    /// layouts differ, or for a dense phase away from `s = 1`.
    /// \[audio-thread\]
    pub fn rebind_same_free(&mut self, old: &CompiledScene, new: &CompiledScene) -> bool {
        self.settle(old);
        if self.in_contact() || !self.can_rebind(old, new) {
            return false;
        }
        debug_assert!(
            old.free.v == new.free.v && old.free.gens == new.free.gens && old.h == new.h,
            "rebind_same_free: the free phases differ"
        );
        let scale = self.time_scale;
        self.derive_for(new, scale, true, None);
        true
    }

    /// Physical observation of the current state: [`motion`](Self::motion)
    /// and [`energy`](Self::energy). \[offline\]
    pub fn observe(&self, scene: &CompiledScene) -> Observation {
        self.motion(scene).with_energy(self.energy(scene))
    }

    /// The trace's columns but the energy: O(N) (dot products with the
    /// compiled rows). \[offline\]
    pub fn motion(&self, scene: &CompiledScene) -> Motion {
        let s = self.time_scale;
        if self.in_contact() {
            let ph = &scene.contact;
            let st = &self.phases[CONTACT].s;
            let x_c = dot(&ph.rows.x_c, st) + scene.offsets.x_c;
            let v_c = dot(&ph.rows.v_c, st) + scene.offsets.v_c;
            let eta = dot(&ph.rows.eta, st) + scene.offsets.eta;
            Motion {
                x_hammer: self.contact_hammer_height(scene, x_c),
                v_hammer: eta / scene.sm * s,
                x_contact: x_c,
                v_contact: v_c * s,
                in_contact: true,
            }
        } else {
            let ph = &scene.free;
            let st = &self.phases[FREE].s;
            Motion {
                x_hammer: self.x_h,
                v_hammer: self.v_h * s,
                x_contact: dot(&ph.rows.x_c, st),
                v_contact: dot(&ph.rows.v_c, st) * s,
                in_contact: false,
            }
        }
    }

    /// Hammer height in contact: the contact point less the effective
    /// penetration and the rod.
    fn contact_hammer_height(&self, scene: &CompiledScene, x_c: f64) -> f64 {
        x_c - self.penetration(scene) - self.rod_m
    }

    /// Total energy \[J\]: object + hammer (kinetic and gravity) + contact
    /// spring, from the state in energy coordinates `y = V (s + s*)` as
    /// `0.5 |y|^2` plus the affine terms. O(nonzeros of V): O(N) where `V`
    /// is sparse (a modal object in flight), O(dim^2) for a dense `V` (a
    /// coupled contact phase, a string). \[offline\]
    pub fn energy(&self, scene: &CompiledScene) -> f64 {
        let mut y = Vec::new();
        self.energy_using(scene, &mut y)
    }

    /// [`energy`](Self::energy) without allocating once
    /// [`reserve_observation`](Self::reserve_observation) ran (a dense `V`
    /// takes its product vector from the observation scratch): the
    /// instrument's live view reads it on the audio thread. Same value bit
    /// for bit. \[audio-thread after `reserve_observation`\]
    pub fn energy_rt(&mut self, scene: &CompiledScene) -> f64 {
        self.settle(scene);
        let mut y = self
            .obs
            .as_mut()
            .map(|o| std::mem::take(&mut o.y))
            .unwrap_or_default();
        let e = self.energy_using(scene, &mut y);
        if let Some(o) = self.obs.as_mut() {
            o.y = y;
        }
        e
    }

    /// [`energy`](Self::energy) for the traced block path: in a coupled
    /// contact phase whose change of basis back to the free phase has a
    /// hierarchical form (a large modal object), through the free
    /// coordinates: `s_f = W_fc (s + s*)` in O(N r log N), the object's
    /// energy from the free phase's sparse `V` in O(N), plus the spring's
    /// `pi^2 / 2` and the hammer's `eta^2 / 2` from their rows. The same
    /// energy as the dense `0.5 |V (s + s*)|^2` to within the hierarchical
    /// form's tolerance (docs/numerics.md, "Structured changes of basis");
    /// elsewhere exactly [`energy_rt`](Self::energy_rt). \[offline\]
    fn energy_observed(&mut self, scene: &CompiledScene) -> f64 {
        let structured = scene.w_fc_h.as_ref().filter(|_| self.structured);
        let (Some(h), true, true) = (structured, self.in_contact(), scene.free.v_sparse.is_some())
        else {
            return self.energy_rt(scene);
        };
        self.reserve_observation();
        let obs = self.obs.as_mut().expect("reserved");
        let df = scene.free.dim;
        if obs.y.len() < df {
            obs.y.resize(df, 0.0);
        }
        let st = &self.phases[CONTACT].s;
        let s_f = &mut obs.y[..df];
        s_f.copy_from_slice(&scene.s_f_star);
        let [a, b, c] = &mut self.dense_tmp;
        kernel::hodlr_mat_vec_add(self.simd, h, st, s_f, [a, b, c]);
        let e_obj = half_norm_sq_energy_coords(&scene.free, s_f, &[], &mut Vec::new());
        let rows = &scene.contact.rows;
        let pi = dot(&rows.pi, st) + scene.offsets.pi;
        let eta = dot(&rows.eta, st) + scene.offsets.eta;
        let x_c = dot(&rows.x_c, st) + scene.offsets.x_c;
        let x_h = self.contact_hammer_height(scene, x_c);
        let s = self.time_scale;
        s * s * (e_obj + 0.5 * (pi * pi + eta * eta) + scene.m_h * scene.g * x_h)
    }

    /// See [`energy`](Self::energy); `y` is grown to the phase's dimension
    /// when `V` is dense (no allocation when it is already that long).
    fn energy_using(&self, scene: &CompiledScene, y: &mut Vec<f64>) -> f64 {
        let s = self.time_scale;
        if self.in_contact() {
            let ph = &scene.contact;
            let st = &self.phases[CONTACT].s;
            let e_ref = half_norm_sq_energy_coords(ph, st, &scene.s_star, y);
            let x_c = dot(&ph.rows.x_c, st) + scene.offsets.x_c;
            let x_h = self.contact_hammer_height(scene, x_c);
            s * s * (e_ref + scene.m_h * scene.g * x_h)
        } else {
            let e_obj = half_norm_sq_energy_coords(&scene.free, &self.phases[FREE].s, &[], y);
            let v = self.v_h;
            s * s * (e_obj + 0.5 * scene.m_h * v * v + scene.m_h * scene.g * self.x_h)
        }
    }
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

/// Effective penetration in `old` for the spring coordinate `pi` (which the
/// rebind keeps): `p_eff = pi / sqrt(k_old)`.
fn old_p_eff(old: &CompiledScene, pi: f64) -> f64 {
    pi / old.sk
}

/// `0.5 |y|^2` for `y = V (s + s_star)` (physical energy coordinates).
/// Each `y_i` is summed over `j` in ascending order, so the sparse and the
/// dense products give the same value bit for bit. A sparse `V` costs its
/// nonzeros; a dense one is applied by columns (contiguous in memory).
fn half_norm_sq_energy_coords(
    ph: &CompiledPhase,
    s: &[f64],
    s_star: &[f64],
    y: &mut Vec<f64>,
) -> f64 {
    let sj = |j: usize| s[j] + s_star.get(j).copied().unwrap_or(0.0);
    if let Some(sp) = &ph.v_sparse {
        let mut e = 0.0;
        for i in 0..ph.dim {
            let y = sp.row_dot(i, sj);
            e += y * y;
        }
        return 0.5 * e;
    }
    if y.len() < ph.dim {
        y.resize(ph.dim, 0.0);
    }
    let y = &mut y[..ph.dim];
    y.iter_mut().for_each(|v| *v = 0.0);
    // nalgebra stores by columns: column j is one contiguous slice
    for (j, col) in ph.v.as_slice().chunks_exact(ph.dim.max(1)).enumerate() {
        let x = sj(j);
        for (yi, v) in y.iter_mut().zip(col) {
            *yi += v * x;
        }
    }
    0.5 * y.iter().map(|v| v * v).sum::<f64>()
}

/// The one-sample block propagators `exp(G_k dt)` (libm's exp and sin_cos:
/// these are applied every sample, so they take the most accurate
/// functions; equal to `exp2` bit for bit).
fn fill_props(p: &mut BlockProps, ph: &CompiledPhase, dt: f64) {
    if let Some(gens) = &ph.gens {
        for (k, g) in gens.iter().enumerate() {
            p.set(k, &ph.osc.get(k).map_or_else(|| exp2(g, dt), |o| o.exp(dt)));
        }
    }
}

/// Whether `scene` may run at time scale `s`: finite and positive, and 1
/// for a scene with a dense phase (whose propagator is made at the
/// compile's step only).
fn scale_allowed(scene: &CompiledScene, s: f64) -> Result<(), TimeScaleError> {
    if !(s.is_finite() && s > 0.0) {
        return Err(TimeScaleError::Invalid);
    }
    if s != 1.0 && (scene.free.dense.is_some() || scene.contact.dense.is_some()) {
        return Err(TimeScaleError::DenseFallback);
    }
    Ok(())
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

impl ScaleProps {
    /// The propagators of `scene` at time scale `s`, and its contact
    /// output rows with the output band `band_hz` applied (the same
    /// functions, so the same bits, as `set_time_scale`'s on a state whose
    /// band is `band_hz`). \[worker\]
    pub fn new(scene: &CompiledScene, s: f64, band_hz: f64) -> Self {
        let step = scene.h * s;
        let of = |ph: &CompiledPhase| {
            let mut p = BlockProps::new(ph.gens.as_ref().map_or(0, Vec::len));
            fill_props(&mut p, ph, step);
            p
        };
        let rows = |ph: &CompiledPhase| {
            [0, 1].map(|ch| {
                let mut r = vec![0.0; ph.dim];
                mix_rows(&mut r, ph, ch, s);
                r
            })
        };
        let (mut free, mut contact) = (rows(&scene.free), rows(&scene.contact));
        let mut offset = [scene.offsets.disp_l, scene.offsets.disp_r];
        let band_hz = band_or_all(band_hz);
        let muted = band_out(
            scene,
            band_hz,
            s,
            free.each_mut().map(|r| &mut r[..]),
            Some((contact.each_mut().map(|r| &mut r[..]), &mut offset)),
        );
        Self {
            s,
            strike: None,
            step,
            free: of(&scene.free),
            contact: of(&scene.contact),
            band: (muted > 0).then_some(BandRows {
                band_hz,
                contact,
                offset,
            }),
        }
    }

    /// The time scale they are for.
    pub fn scale(&self) -> f64 {
        self.s
    }

    /// Made for `scene` at `s`: the same step and the same block counts
    /// (a check, not a proof: the caller pairs them with their scene).
    fn fits(&self, scene: &CompiledScene, s: f64) -> bool {
        let nb = |ph: &CompiledPhase| ph.gens.as_ref().map_or(0, Vec::len);
        self.s == s
            && self.step == scene.h * s
            && self.free.len() == nb(&scene.free)
            && self.contact.len() == nb(&scene.contact)
    }
}

/// An output band as [`EngineState::set_output_band`] takes it: NaN or
/// <= 0 hears every mode (`INFINITY`).
fn band_or_all(band_hz: f64) -> f64 {
    if band_hz > 0.0 {
        band_hz
    } else {
        f64::INFINITY
    }
}

/// Zero the entries of the free output rows `free` (mixed at time scale
/// `s`) of the modes whose frequency is above `band_hz` (physical Hz);
/// with `carry`, subtract each zeroed entry's contribution from the
/// contact rows and offsets (the contact rows are the free rows carried
/// through `s_f = W_fc s_c + s_f*`). Returns how many modes are left out.
/// O(N), plus O(N) per mode left out with `carry`. \[audio-thread\]
/// \[worker\]
fn band_out(
    scene: &CompiledScene,
    band_hz: f64,
    s: f64,
    mut free: [&mut [f64]; 2],
    mut carry: Option<([&mut [f64]; 2], &mut [f64; 2])>,
) -> usize {
    let Some(gens) = scene.free.gens.as_ref() else {
        return 0;
    };
    if !band_hz.is_finite() {
        return 0;
    }
    let nb = gens.len();
    // omega_phys = omega_ref * s; muted when omega_ref * s > 2 pi band
    let limit = 2.0 * std::f64::consts::PI * band_hz / s;
    let (df, dc) = (scene.w_fc.nrows(), scene.contact.dim);
    let mut muted = 0;
    for (k, g) in gens.iter().enumerate() {
        let half_tr = 0.5 * (g[0] + g[3]);
        let det = g[0] * g[3] - g[1] * g[2];
        let w2 = det - half_tr * half_tr;
        if !(w2 > limit * limit) {
            continue;
        }
        muted += 1;
        for i in [k, nb + k] {
            let r = [free[0][i], free[1][i]];
            for (f, r) in free.iter_mut().zip(r) {
                if r != 0.0 {
                    f[i] = 0.0;
                }
            }
            let Some(([out_l, out_r], offset)) = carry.as_mut() else {
                continue;
            };
            // row i of W_fc, strided through its column-major storage,
            // read once for both channels; each entry takes the same
            // subtractions in the same order as one channel at a time
            let row = scene.w_fc.as_slice()[i..].iter().step_by(df);
            let (out_l, out_r) = (&mut out_l[..dc], &mut out_r[..dc]);
            match (r[0] != 0.0, r[1] != 0.0) {
                (true, true) => {
                    for ((a, b), w) in out_l.iter_mut().zip(out_r.iter_mut()).zip(row) {
                        *a -= r[0] * w;
                        *b -= r[1] * w;
                    }
                }
                (true, false) => out_l.iter_mut().zip(row).for_each(|(a, w)| *a -= r[0] * w),
                (false, true) => out_r.iter_mut().zip(row).for_each(|(b, w)| *b -= r[1] * w),
                (false, false) => {}
            }
            for ch in 0..2 {
                if r[ch] != 0.0 {
                    offset[ch] -= r[ch] * scene.s_f_star[i];
                }
            }
        }
    }
    muted
}

fn mix_rows(dst: &mut [f64], ph: &CompiledPhase, ch: usize, s: f64) {
    let (d, v) = if ch == 0 {
        (&ph.rows.disp_l, &ph.rows.vel_l)
    } else {
        (&ph.rows.disp_r, &ph.rows.vel_r)
    };
    for ((o, a), b) in dst.iter_mut().zip(d).zip(v) {
        *o = a + b * s;
    }
}

#[inline]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `[dot(rows[0], s), dot(rows[1], s), dot(rows[2], s)]` bit for bit (each
/// the same sequential sum from the same start) in one pass: each sum is a
/// chain of dependent additions, and three independent chains overlap
/// where three passes would wait for each in turn. O(N).
pub(crate) fn dot3(rows: [&[f64]; 3], s: &[f64]) -> [f64; 3] {
    let n = s.len().min(rows[0].len());
    if rows.iter().any(|r| r.len().min(s.len()) != n) {
        return rows.map(|r| dot(r, s));
    }
    let zero: f64 = std::iter::empty::<f64>().sum();
    let mut acc = [zero; 3];
    let (r0, r1, r2) = (&rows[0][..n], &rows[1][..n], &rows[2][..n]);
    for (k, &x) in s[..n].iter().enumerate() {
        acc[0] += r0[k] * x;
        acc[1] += r1[k] * x;
        acc[2] += r2[k] * x;
    }
    acc
}

/// One step of a dense-fallback phase: `s = exp(A h) s`.
#[inline]
fn step_phase(ph: &CompiledPhase, s: &mut [f64], scratch: &mut [f64]) {
    let (_, phi) = ph.dense.as_ref().expect("dense phase");
    let n = ph.dim;
    for i in 0..n {
        let row = &phi[i * n..(i + 1) * n];
        scratch[i] = dot(row, s);
    }
    s[..n].copy_from_slice(&scratch[..n]);
}
