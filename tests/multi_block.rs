//! The several-contact engine's block path (`src/multi/fast.rs`, docs/numerics.md
//! section 14): runs of samples in the block kernel, each certified to hold
//! no crossing, against the same engine with every sample taking the
//! search's way, and however a host splits its blocks.

use modal_contact::multi::{CompiledMulti, MultiModel, MultiObservation, MultiState};
use modal_contact::scene::Scene;
use modal_testkit::rng::TestRng;
use std::path::Path;

const RATE: f64 = 48_000.0;

/// A preset of several contacts, compiled as the render compiles it.
fn compiled(name: &str) -> CompiledMulti {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("presets/{name}.toml"));
    let scene = Scene::from_file(&path).unwrap();
    let model = MultiModel::from_scene(&scene, RATE).unwrap();
    let switching = scene.contact.switching.unwrap_or_default();
    CompiledMulti::with_switching(&model, RATE, switching).unwrap()
}

/// Every number of an observation, as bits.
fn bits(o: &MultiObservation) -> Vec<u64> {
    let mut v: Vec<u64> = [o.x_hammer, o.v_hammer, o.x_contact, o.v_contact]
        .iter()
        .flat_map(|a| a.iter().map(|x| x.to_bits()))
        .collect();
    v.push(u64::from(o.active));
    v.push(o.energy.to_bits());
    v
}

/// On the four several-contact presets and the piano string with a felt
/// law in eight pieces (more springs than the kernel sums: its later
/// pieces read the row of the piece below; half a second each, blocks of 1
/// to 200 samples at random), on the portable kernels and on this CPU's
/// fastest (each path's block kernel against its own per-sample step):
/// after every block, every contact's motion and
/// the energy are the per-sample search's bit for bit, and so are the
/// switches and the search's evaluations (the block path clears a sample
/// only where the search's first test would); the outputs too (a sample
/// the search takes sums its output as the kernel does); and the block
/// path took most samples.
#[test]
fn the_block_path_moves_as_the_search_does_bit_for_bit() {
    let mut rng = TestRng(0xb10c);
    let names = [
        "ball-between-plates",
        "marimba-two-mallets",
        "snare-pair",
        "wind-chimes",
    ];
    let mut cases: Vec<(&str, CompiledMulti)> = names.iter().map(|&n| (n, compiled(n))).collect();
    cases.push(("piano-string, felt in eight pieces", piano_with_felt_in(8)));
    for (name, portable, sc) in cases
        .iter()
        .flat_map(|(n, sc)| [(*n, true, sc), (*n, false, sc)])
    {
        let sc = sc.clone();
        let mut search = MultiState::new(&sc);
        search.set_block_path(false);
        search.set_portable_kernels(portable);
        let mut block = MultiState::new(&sc);
        block.set_portable_kernels(portable);
        let n = (0.5 * RATE) as usize;
        let (mut l, mut r) = (vec![0.0; 200], vec![0.0; 200]);
        let (mut done, mut peak, mut worst) = (0, 0.0f64, 0.0f64);
        while done < n {
            let len = (1 + rng.below(200)).min(n - done);
            block.process_block(&sc, &mut l[..len], &mut r[..len]);
            for i in 0..len {
                let [a, b] = search.tick(&sc);
                peak = peak.max(a.abs()).max(b.abs());
                worst = worst.max((a - l[i]).abs()).max((b - r[i]).abs());
            }
            done += len;
            assert_eq!(
                bits(&block.observe(&sc)),
                bits(&search.observe(&sc)),
                "{name}: motion after {done} samples"
            );
        }
        let (a, b) = (&search.stats, &block.stats);
        println!(
            "{name} ({}): {} switches, {} evaluations; block path {} of {n} samples ({} \
             discarded); outputs within {:.1e} of the peak",
            if portable { "portable" } else { "fastest" },
            b.switches,
            b.evaluations,
            b.kernel_samples,
            b.kernel_discarded,
            worst / peak
        );
        assert_eq!((a.switches, a.evaluations), (b.switches, b.evaluations));
        assert_eq!(a.contacts_started, b.contacts_started);
        assert_eq!(a.kernel_samples, 0);
        assert!(b.kernel_samples as f64 > 0.9 * n as f64, "{name}");
        assert!(peak > 0.0 && worst == 0.0, "{name}: {worst:e} of {peak:e}");
    }
}

/// The piano string with Chaigne and Askenfelt's felt (`F = 4.5e9 p^2.5`,
/// `pieces` pieces) in place of its spring: a hammer contact and a touch
/// per further piece, each crossing taken by the search.
fn piano_with_felt_in(pieces: usize) -> CompiledMulti {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("presets/piano-string.toml");
    let text = std::fs::read_to_string(path).unwrap().replace(
        "stiffness_n_per_m = 8.6e4",
        &format!(
            "law = {{ power = 2.5, force_n_at = [1e-3, 142.3], pieces = {pieces}, \
             from_m = 5e-5, up_to_m = 1e-3 }}"
        ),
    );
    let scene = Scene::from_toml_str(&text).unwrap();
    let model = MultiModel::from_scene(&scene, RATE).unwrap();
    CompiledMulti::with_switching(&model, RATE, Default::default()).unwrap()
}

/// The Hermite certificates (docs/numerics.md sections 6.2 and 14) clear a
/// contact's sample, or the rest of one after a switch, only where the
/// search finds no crossing: on the four several-contact presets and the
/// piano string with a felt law, struck again every 0.1 s at speeds from
/// 0.3 to 3 m/s, the engine with them and without them gives the same
/// switches, every contact's motion, the energy and the outputs bit for
/// bit, with fewer evaluations of the event functions.
#[test]
fn the_hermite_certificates_clear_only_samples_without_a_crossing() {
    let mut rng = TestRng(0x4e41);
    let names = [
        "ball-between-plates",
        "marimba-two-mallets",
        "snare-pair",
        "wind-chimes",
        "piano with felt",
    ];
    for name in names {
        let sc = if name == "piano with felt" {
            piano_with_felt_in(4)
        } else {
            compiled(name)
        };
        let mut with = MultiState::new(&sc);
        let mut without = MultiState::new(&sc);
        without.set_hermite(false);
        let n = (1.0 * RATE) as usize;
        let (mut l, mut r) = (vec![0.0; 64], vec![0.0; 64]);
        let (mut l2, mut r2) = (vec![0.0; 64], vec![0.0; 64]);
        let mut done = 0;
        while done < n {
            if done % 4800 < 64 && done > 0 {
                let speed = 0.3 + 2.7 * rng.unit();
                for c in 0..sc.contacts() {
                    let a = with.strike(&sc, c, 0.0, -speed);
                    let b = without.strike(&sc, c, 0.0, -speed);
                    assert_eq!(a.is_ok(), b.is_ok());
                }
            }
            with.process_block(&sc, &mut l, &mut r);
            without.process_block(&sc, &mut l2, &mut r2);
            done += 64;
            for i in 0..64 {
                assert_eq!(
                    (l[i].to_bits(), r[i].to_bits()),
                    (l2[i].to_bits(), r2[i].to_bits()),
                    "{name}: output at {}",
                    done - 64 + i
                );
            }
            assert_eq!(
                bits(&with.observe(&sc)),
                bits(&without.observe(&sc)),
                "{name}: motion after {done} samples"
            );
        }
        let (a, b) = (&with.stats, &without.stats);
        println!(
            "{name}: {} switches; {} evaluations with the certificates ({} cleared), {} without",
            a.switches, a.evaluations, a.hermite_cleared, b.evaluations
        );
        assert_eq!(a.switches, b.switches);
        assert_eq!(a.contacts_started, b.contacts_started);
        assert_eq!(b.hermite_cleared, 0);
        assert!(a.hermite_cleared > 0, "{name}");
        assert!(a.evaluations < b.evaluations, "{name}");
    }
}
