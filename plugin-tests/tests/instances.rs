//! Several instances of the BUILT `.clap` in one process (docs/plugin.md,
//! "Parameter changes: the swap design", 6.): eight instances through
//! clack-host, each loaded, activated and processing on a thread of its
//! own with its own scene and parameter changes, their compile workers
//! running side by side. Each renders in the offline render mode (CLAP
//! `render` extension), where the plugin waits for a scene it asked for
//! before it renders, so its output does not depend on when its worker
//! finishes; each must then equal, bit for bit, the same script rendered
//! by a lone instance whose worker was given ample time at every change.
//! The instances are deactivated and destroyed in a scrambled order, while
//! the others still process.

use modal_contact::plugin::params::ids;
use modal_contact::presets;
use plugin_tests::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex};
use std::time::{Duration, Instant};

const RATE: f64 = 48_000.0;
const BLOCK: usize = 256;
/// Seconds rendered per script.
const SECONDS: f64 = 1.2;
/// Time the lone renders give the worker (not a timing assertion).
const SETTLE: Duration = Duration::from_millis(100);
/// One scene per instance.
const SCENES: [&str; 8] = [
    "marimba-bar",
    "glockenspiel-bar",
    "wood-block",
    "vibraphone-bar",
    "bell",
    "tubular-chime",
    "frame-drum",
    "marimba-two-mallets",
];

/// What the host does with one instance: a scene set before activation
/// (a parameter flush), then notes and parameter events at sample
/// positions.
struct Script {
    scene: usize,
    events: Vec<HostEvent>,
}

fn scene_index(name: &str) -> f64 {
    presets::index_of(name).unwrap_or_else(|| panic!("no scene {name}")) as f64
}

/// Instance `i`'s script: notes on its scene, then Decay and Hardness
/// changed while they ring (each a recompile on the worker), and a third
/// recompile: Decay again (even `i`) or another scene (odd `i`, a preset
/// change with its fade). Event positions differ between instances.
fn script(i: usize) -> Script {
    let s = |t: f64| (t * RATE) as usize;
    let key = 60 + (i % 5) as u8;
    let mut events = vec![
        on(s(0.010) + 7 * i, key, 0.8),
        on(s(0.120) + 3 * i, key + 4, 0.6),
        param(s(0.250) + 37 * i, ids::DECAY, 0.25 + 0.04 * i as f64),
        on(s(0.300), key + 7, 0.7),
        param(s(0.550) + 11 * i, ids::HARDNESS, 0.45 + 0.03 * i as f64),
        off(s(0.600), key),
        on(s(0.700) + 5 * i, key + 2, 0.9),
    ];
    events.push(if i.is_multiple_of(2) {
        param(s(0.850) + 13 * i, ids::DECAY, 0.6)
    } else {
        param(
            s(0.850) + 13 * i,
            ids::SCENE,
            scene_index(SCENES[(i + 3) % SCENES.len()]),
        )
    });
    events.push(on(s(0.900), key + 5, 0.5));
    Script {
        scene: presets::index_of(SCENES[i]).expect("scene"),
        events,
    }
}

/// Load an instance for `script`: offline render mode, its scene flushed.
fn load(variant: Variant, script: &Script) -> LoadedPlugin {
    let mut p = LoadedPlugin::load(&clap_bundle(variant));
    assert!(
        p.set_render_mode(true),
        "the plugin refused the offline mode"
    );
    p.flush_params(&[(param_id(ids::SCENE), script.scene as f64)]);
    p
}

fn total() -> usize {
    (SECONDS * RATE) as usize
}

/// `script` rendered by an instance alone in the process, its worker
/// given [`SETTLE`] after the activation and after every block with a
/// parameter event: each scene it asked for is ready at the next block,
/// as if the worker took no time (an offline render must not need this).
fn lone(variant: Variant, script: &Script) -> [Vec<f32>; 2] {
    let mut p = load(variant, script);
    let mut s = p.activate(RATE, 1, BLOCK);
    let settle_after: Vec<usize> = script
        .events
        .iter()
        .filter(|e| matches!(e, HostEvent::Param { .. }))
        .map(|e| e.at() / BLOCK)
        .collect();
    std::thread::sleep(SETTLE);
    let mut out = [Vec::with_capacity(total()), Vec::with_capacity(total())];
    for k in 0..total().div_ceil(BLOCK) {
        let len = BLOCK.min(total() - k * BLOCK);
        let part = s.render(k * BLOCK, len, BLOCK, &script.events);
        out[0].extend_from_slice(&part[0]);
        out[1].extend_from_slice(&part[1]);
        if settle_after.contains(&k) {
            std::thread::sleep(SETTLE);
        }
    }
    s.deactivate();
    out
}

/// A step of the scrambled teardown.
#[derive(Clone, Copy, PartialEq)]
enum Step {
    Deactivate(usize),
    Destroy(usize),
}

/// Deactivations in the order 5 2 7 0 3 6 1 4, destructions in the order
/// 2 5 7 0 3 6 1 4, interleaved: the first destruction comes while six
/// instances are still active and processing.
const TEARDOWN: [Step; 16] = {
    use Step::*;
    [
        Deactivate(5),
        Deactivate(2),
        Destroy(2),
        Deactivate(7),
        Destroy(5),
        Deactivate(0),
        Destroy(7),
        Deactivate(3),
        Destroy(0),
        Deactivate(6),
        Destroy(3),
        Deactivate(1),
        Destroy(6),
        Deactivate(4),
        Destroy(1),
        Destroy(4),
    ]
};

/// Where the threads are: how many are ready to render, which teardown
/// step is next, whether one failed (the others then stop waiting).
#[derive(Default)]
struct State {
    ready: usize,
    step: usize,
    failed: bool,
}

#[derive(Default)]
struct Stage {
    state: Mutex<State>,
    moved: Condvar,
}

impl Stage {
    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Wait until `done` holds, calling `idle` (if any) every millisecond
    /// meanwhile; false if another thread failed.
    fn wait(&self, done: impl Fn(&State) -> bool, mut idle: Option<&mut dyn FnMut()>) -> bool {
        let mut g = self.lock();
        loop {
            if g.failed {
                return false;
            }
            if done(&g) {
                return true;
            }
            match idle.as_mut() {
                Some(f) => {
                    drop(g);
                    f();
                    g = self.lock();
                    g = self
                        .moved
                        .wait_timeout(g, Duration::from_millis(1))
                        .unwrap_or_else(|e| e.into_inner())
                        .0;
                }
                None => g = self.moved.wait(g).unwrap_or_else(|e| e.into_inner()),
            }
        }
    }

    fn update(&self, f: impl FnOnce(&mut State)) {
        f(&mut self.lock());
        self.moved.notify_all();
    }
}

/// What one instance's thread saw.
struct Run {
    out: [Vec<f32>; 2],
    /// Blocks it processed after its script while waiting for its turn
    /// to be deactivated.
    extra_blocks: usize,
    /// Instances still active when this one was destroyed.
    active_at_destroy: usize,
}

/// Instance `i`'s thread: load, activate, wait for all eight, render the
/// script, then keep processing until its deactivation step, then wait
/// for its destruction step.
fn instance_thread(variant: Variant, i: usize, stage: &Stage, active: &AtomicUsize) -> Run {
    let script = script(i);
    let deactivate_at = TEARDOWN
        .iter()
        .position(|s| *s == Step::Deactivate(i))
        .expect("deactivation step");
    let destroy_at = TEARDOWN
        .iter()
        .position(|s| *s == Step::Destroy(i))
        .expect("destruction step");
    let mut p = load(variant, &script);
    let mut s = p.activate(RATE, 1, BLOCK);
    stage.update(|st| st.ready += 1);
    assert!(
        stage.wait(|st| st.ready == SCENES.len(), None),
        "another instance failed"
    );
    let out = s.render(0, total(), BLOCK, &script.events);
    let mut extra_blocks = 0;
    let mut pos = total();
    let mut more = || {
        let b = s.process(BLOCK, pos, &[]);
        assert!(
            b[0].iter().chain(b[1]).all(|x| x.is_finite()),
            "instance {i}: a non-finite sample after its script"
        );
        pos += BLOCK;
        extra_blocks += 1;
    };
    assert!(
        stage.wait(|st| st.step == deactivate_at, Some(&mut more)),
        "another instance failed"
    );
    s.deactivate();
    active.fetch_sub(1, Ordering::SeqCst);
    stage.update(|st| st.step += 1);
    assert!(
        stage.wait(|st| st.step == destroy_at, None),
        "another instance failed"
    );
    let active_at_destroy = active.load(Ordering::SeqCst);
    drop(p);
    stage.update(|st| st.step += 1);
    Run {
        out,
        extra_blocks,
        active_at_destroy,
    }
}

fn check_instances(variant: Variant) {
    let started = Instant::now();
    let scripts: Vec<Script> = (0..SCENES.len()).map(script).collect();
    let alone: Vec<[Vec<f32>; 2]> = scripts.iter().map(|s| lone(variant, s)).collect();
    let lone_s = started.elapsed().as_secs_f64();
    let stage = Stage::default();
    let active = AtomicUsize::new(SCENES.len());
    let runs: Vec<Run> = std::thread::scope(|sc| {
        let handles: Vec<_> = (0..SCENES.len())
            .map(|i| {
                let (stage, active) = (&stage, &active);
                sc.spawn(move || {
                    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                        instance_thread(variant, i, stage, active)
                    }));
                    if r.is_err() {
                        stage.update(|st| st.failed = true);
                    }
                    r
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| match h.join().expect("thread") {
                Ok(run) => run,
                Err(e) => std::panic::resume_unwind(e),
            })
            .collect()
    });
    let together_s = started.elapsed().as_secs_f64() - lone_s;
    let mut bad = Vec::new();
    for (i, (run, lone)) in runs.iter().zip(&alone).enumerate() {
        let differs = (0..2).find_map(|c| {
            run.out[c]
                .iter()
                .zip(&lone[c])
                .position(|(a, b)| a.to_bits() != b.to_bits())
                .map(|k| (c, k))
        });
        println!(
            "{}: instance {i} ({}): peak {:.3}, {} blocks after its script, destroyed with {} active; {}",
            variant.name(),
            SCENES[i],
            peak(&run.out[0]).max(peak(&run.out[1])),
            run.extra_blocks,
            run.active_at_destroy,
            match differs {
                None => "equal to the lone render, bit for bit".to_string(),
                Some((c, k)) => format!(
                    "differs from the lone render from sample {k} of channel {c} \
                     ({} vs {})",
                    run.out[c][k], lone[c][k]
                ),
            }
        );
        assert!(
            peak(&lone[0]) > 0.01,
            "instance {i}: the lone render is silent"
        );
        if differs.is_some() {
            bad.push(i);
        }
    }
    println!(
        "{}: eight lone renders {lone_s:.1} s, eight together {together_s:.1} s",
        variant.name()
    );
    assert!(
        bad.is_empty(),
        "instances {bad:?} differ from their lone renders"
    );
    // the instances played their own scenes, not one another's
    for i in 0..runs.len() {
        for j in i + 1..runs.len() {
            assert!(
                runs[i].out[0] != runs[j].out[0],
                "instances {i} and {j} rendered the same"
            );
        }
    }
}

/// The release build, then the rt-checks build (the offline waits and
/// the teardown allocate nothing in `process`); one after the other, so
/// that the lone renders are alone.
#[test]
fn eight_instances_on_their_own_threads_equal_lone_instances() {
    check_instances(Variant::Release);
    check_instances(Variant::RtChecks);
}
