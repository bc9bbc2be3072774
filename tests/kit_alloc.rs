//! The instrument playing kits allocates nothing on the audio thread: a
//! counting allocator armed around every `Instrument::process` and
//! `Instrument::install` of a random abuse of the kit presets (swaps
//! between them and a preset of one contact, either switching method,
//! random play parameters and dampers, random notes and pressure). Built without the `rt-checks` feature (whose allocation
//! checker is that build's global allocator; the plugin's checked build
//! plays the kits in `plugin-tests/tests/rt_alloc.rs`).
#![cfg(not(feature = "rt-checks"))]

use modal_contact::instrument::{
    lookahead_samples, prepare, Event, Instrument, PlayParams, SceneParams, TimedEvent, VariantSet,
};
use modal_contact::presets;
use modal_contact::scene::Switching;
use modal_testkit::rng::TestRng;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

struct Counting;

static ARMED: AtomicBool = AtomicBool::new(false);
static ALLOCS: AtomicUsize = AtomicUsize::new(0);
static LAST: AtomicUsize = AtomicUsize::new(0);
/// `KIT_ALLOC_TRACE=1`: print where an armed allocation comes from.
static TRACE: AtomicBool = AtomicBool::new(false);

// SAFETY: every method passes its arguments unchanged to the system
// allocator and returns its result, so the memory handed out is `System`'s
// and meets the `GlobalAlloc` contract exactly as `System` does. The counting
// around the calls only updates atomics; a traced allocation disarms the
// counter before capturing its backtrace, whose own allocations therefore
// go straight to `System`.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if ARMED.load(Ordering::Relaxed) {
            ALLOCS.fetch_add(1, Ordering::Relaxed);
            LAST.store(layout.size(), Ordering::Relaxed);
            if TRACE.load(Ordering::Relaxed) {
                ARMED.store(false, Ordering::Relaxed);
                let bt = std::backtrace::Backtrace::force_capture().to_string();
                use std::io::Write;
                let _ = std::io::stderr().write_all(bt.as_bytes());
            }
        }
        // SAFETY: our caller upholds `alloc`'s contract for `layout`, the
        // same contract `System.alloc` asks for.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from this allocator with `layout`, so from
        // `System` (every block of ours is `System`'s), as `dealloc` requires.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if ARMED.load(Ordering::Relaxed) {
            ALLOCS.fetch_add(1, Ordering::Relaxed);
            LAST.store(new_size, Ordering::Relaxed);
            if TRACE.load(Ordering::Relaxed) {
                ARMED.store(false, Ordering::Relaxed);
                let bt = std::backtrace::Backtrace::force_capture().to_string();
                use std::io::Write;
                let _ = std::io::stderr().write_all(bt.as_bytes());
            }
        }
        // SAFETY: `ptr` came from this allocator, so from `System`, with
        // `layout`, and our caller upholds `realloc`'s contract for
        // `new_size`: what `System.realloc` asks for.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The counter is global: the tests take turns (another test's set-up
/// would count as this one's allocations).
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn armed<R>(what: &str, f: impl FnOnce() -> R) -> R {
    let before = ALLOCS.load(Ordering::Relaxed);
    ARMED.store(true, Ordering::Relaxed);
    let r = f();
    ARMED.store(false, Ordering::Relaxed);
    let n = ALLOCS.load(Ordering::Relaxed) - before;
    assert_eq!(
        n,
        0,
        "{what}: {n} allocations (the last {} bytes)",
        LAST.load(Ordering::Relaxed)
    );
    r
}

#[test]
fn kits_allocate_nothing_on_the_audio_thread() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    const RATE: f64 = 48_000.0;
    TRACE.store(
        std::env::var_os("KIT_ALLOC_TRACE").is_some(),
        Ordering::Relaxed,
    );
    let mut rng = TestRng(0xa11c);
    let kits: Vec<usize> = (0..presets::COUNT)
        .filter(|&i| presets::is_kit(i))
        .collect();
    let bar = presets::index_of("marimba-bar").unwrap();
    let mut sp = SceneParams {
        preset: kits[0],
        ..SceneParams::default()
    };
    let mut inst = Instrument::new(prepare(&sp, RATE, 0).unwrap(), PlayParams::default());
    let (mut l, mut r) = (vec![0.0f32; 4096], vec![0.0f32; 4096]);
    let mut revision = 1;
    let mut notes = 0;
    for round in 0..120 {
        if round % 3 == 1 {
            sp.preset = if rng.below(5) == 0 {
                bar
            } else {
                kits[rng.below(kits.len())]
            };
            sp.stiffness_factor = [0.3, 1.0, 3.0][rng.below(3)];
            sp.decay_scale = [0.5, 1.0, 2.0][rng.below(3)];
            sp.switching = [Switching::Exact, Switching::OffsetRod][rng.below(2)];
            // a damper: released kit voices carried to its compile
            sp.damper_custom = rng.below(2) == 0;
            sp.damper_norm = [0.0, 0.5, 1.0][rng.below(3)];
            // the levels of a host's polyphonic modulation: more compiles
            // a kit voice is carried between
            sp.strike_pos_norm = [None, Some(0.3)][rng.below(2)];
            sp.variants = VariantSet {
                position: rng.below(2) == 0,
                damper: rng.below(2) == 0,
            };
            if let Ok(p) = prepare(&sp, RATE, revision) {
                revision += 1;
                if inst.can_install() {
                    armed("install", || inst.install(p).ok());
                }
            }
            for slot in inst.retired_slots_mut() {
                slot.take();
            }
        }
        if round % 7 == 3 {
            let play = PlayParams {
                polyphony: 1 + rng.below(64),
                pitch_tracking: rng.below(4) != 0,
                drop_height_m: [0.0, 0.02, 0.3][rng.below(3)],
                lookahead_s: [0.0, 0.005][rng.below(2)],
                ..PlayParams::default()
            };
            armed("set_play", || {
                inst.set_play(play);
                inst.set_lookahead(lookahead_samples(play.lookahead_s, RATE));
            });
        }
        let n = 1 + rng.below(4096);
        let mut events = Vec::new();
        for _ in 0..rng.below(24) {
            let offset = rng.below(n);
            let key = 36 + rng.below(60) as u8;
            let event = match rng.below(8) {
                0 | 1 => Event::NoteOn {
                    key,
                    velocity_norm: rng.unit(),
                },
                2 => Event::NoteOff { key },
                3 => Event::ChannelPressure { value: rng.unit() },
                4 => Event::NotePosition {
                    key: Some(key),
                    offset: rng.uniform(-0.3, 0.3),
                },
                5 => Event::NoteDamper {
                    key: Some(key),
                    offset: rng.uniform(-0.6, 0.6),
                },
                6 => Event::NoteBrightness {
                    key: Some(key),
                    value: rng.unit(),
                },
                _ => Event::PitchBend {
                    value: rng.uniform(-1.0, 1.0),
                },
            };
            notes += 1;
            events.push(TimedEvent { offset, event });
        }
        events.sort_by_key(|e| e.offset);
        armed("process", || {
            inst.process(&events, &mut l[..n], &mut r[..n])
        });
    }
    println!("{notes} events, {} swaps, {:?}", revision - 1, inst.stats);
    assert!(inst.stats.swaps > 20);
}

/// A copy of a prepared scene (`Prepared: Clone`, as the benches and a
/// host of the library make one per instrument) plays as the original
/// does: no allocation. A derived clone of a voice's scratch would keep
/// only its length, not its room, and the first note at another pitch
/// would grow it on the audio thread.
#[test]
fn a_cloned_prepared_scene_plays_without_allocating() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    const RATE: f64 = 48_000.0;
    let kit = (0..presets::COUNT).find(|&i| presets::is_kit(i)).unwrap();
    for preset in ["marimba-bar", "steel-plate", presets::PRESETS[kit].name] {
        let sp = SceneParams {
            preset: presets::index_of(preset).unwrap(),
            ..SceneParams::default()
        };
        let original = prepare(&sp, RATE, 0).unwrap();
        let mut inst = Instrument::new(original.clone(), PlayParams::default());
        let (mut l, mut r) = (vec![0.0f32; 256], vec![0.0f32; 256]);
        for round in 0..8u8 {
            let events: Vec<TimedEvent> = (0..16u8)
                .map(|k| TimedEvent {
                    offset: 4 * k as usize,
                    event: Event::NoteOn {
                        key: 30 + 4 * k + round,
                        velocity_norm: 0.8,
                    },
                })
                .collect();
            armed(preset, || inst.process(&events, &mut l, &mut r));
        }
        assert_eq!(inst.stats.notes, 128, "{preset}");
    }
}

/// Pressure on held strokes of the driven presets under a constant force
/// (the ball's weight, the hand on the guiro's stick) moves that force
/// at every pressure message (`EngineState::set_load`), in contact and
/// in flight: no allocation.
#[test]
fn pressing_a_driven_stroke_allocates_nothing() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    const RATE: f64 = 48_000.0;
    let driven = modal_testkit::scenes::driven_presets();
    assert!(driven.len() >= 5, "{driven:?}");
    for preset in driven {
        let sp = SceneParams {
            preset: presets::index_of(preset).unwrap(),
            ..SceneParams::default()
        };
        let mut inst = Instrument::new(prepare(&sp, RATE, 0).unwrap(), PlayParams::default());
        let (mut l, mut r) = (vec![0.0f32; 256], vec![0.0f32; 256]);
        let keys = [60u8, 64, 67];
        let on: Vec<TimedEvent> = keys
            .iter()
            .map(|&key| TimedEvent {
                offset: 0,
                event: Event::NoteOn {
                    key,
                    velocity_norm: 0.8,
                },
            })
            .collect();
        armed(preset, || inst.process(&on, &mut l, &mut r));
        let mut rng = TestRng(7);
        for _ in 0..40 {
            let events: Vec<TimedEvent> = (0..8)
                .map(|j| TimedEvent {
                    offset: 32 * j,
                    event: if rng.below(3) == 0 {
                        Event::ChannelPressure { value: rng.unit() }
                    } else {
                        Event::NotePressure {
                            key: Some(keys[rng.below(3)]),
                            value: rng.unit(),
                        }
                    },
                })
                .collect();
            armed(preset, || inst.process(&events, &mut l, &mut r));
        }
        assert!(inst.active_voices() > 0, "{preset}: the strokes go on");
    }
}

/// A law of eight pieces (more springs than the block kernel sums: every
/// sample through the search) plays through the instrument without
/// allocating: marimba-bar's yarn as `F = K p^2` in eight pieces, chords
/// struck again on ringing voices at every velocity, with exact switching
/// and with the offset rod; the output audible and finite.
#[test]
fn a_law_of_eight_pieces_plays_without_allocating() {
    use modal_contact::instrument::prepare_scene;
    use modal_testkit::scenes::{law_k_through_spring, power_law_travel, with_power_law};
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    const RATE: f64 = 48_000.0;
    let bar = presets::index_of("marimba-bar").unwrap();
    let spring = presets::scene(bar).unwrap();
    let k = law_k_through_spring(&spring);
    let travel = |v| power_law_travel(spring.hammer.mass_kg, k, 2.0, v);
    let scene = with_power_law(&spring, (2.0, k), 8, (travel(0.12), travel(3.0)));
    assert_eq!(scene.all_contacts(), 8);
    let mut rng = TestRng(0x8a1);
    for switching in [Switching::Exact, Switching::OffsetRod] {
        let sp = SceneParams {
            preset: bar,
            switching,
            ..SceneParams::default()
        };
        let mut inst = Instrument::new(
            prepare_scene(&scene, &sp, RATE, 0).unwrap(),
            PlayParams::default(),
        );
        let (mut l, mut r) = (vec![0.0f32; 1024], vec![0.0f32; 1024]);
        let mut peak = 0.0f32;
        for round in 0..48 {
            let events: Vec<TimedEvent> = (0..if round % 4 == 0 { 6 } else { 0 })
                .map(|i| TimedEvent {
                    offset: 37 * i,
                    event: Event::NoteOn {
                        key: 48 + rng.below(24) as u8,
                        velocity_norm: rng.unit().max(0.05),
                    },
                })
                .collect();
            armed("process", || inst.process(&events, &mut l, &mut r));
            assert!(l.iter().chain(&r).all(|x| x.is_finite()));
            peak = l.iter().chain(&r).fold(peak, |m, x| m.max(x.abs()));
        }
        println!("{switching:?}: peak {peak:.3}, {:?}", inst.stats);
        assert!(peak > 1e-3, "{switching:?}: silent ({peak})");
    }
}
