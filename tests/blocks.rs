//! The block engine (`process_block`, what the plugin runs) against
//! per-sample `tick`: the output must be bit-identical whatever the block
//! sizes, including across located switches, offset-rod decisions, the
//! dense fallback and the epoch boundaries where the curvature bound is
//! refreshed. (The plugin-level test `host_abuse.rs` checks the same through
//! a real host; this one pins it on the engine, scene by scene.)

use modal_contact::compile::{compile_with, CompiledScene};
use modal_contact::engine::EngineState;
use modal_contact::scene::{Scene, Switching};
use modal_testkit::rng::TestRng;
use modal_testkit::scenes::{c_for, preset, wall_strike};

/// A source of block sizes.
type Sizes<'a> = Box<dyn FnMut() -> usize + 'a>;

fn by_ticks(sc: &CompiledScene, n: usize) -> (Vec<f64>, Vec<f64>, u64, f64) {
    let mut st = EngineState::new(sc);
    let (mut l, mut r) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for _ in 0..n {
        let o = st.tick(sc);
        l.push(o[0]);
        r.push(o[1]);
    }
    (l, r, st.contacts_started, st.penetration(sc))
}

fn by_blocks(
    sc: &CompiledScene,
    n: usize,
    sizes: &mut dyn FnMut() -> usize,
) -> (Vec<f64>, Vec<f64>, f64) {
    let mut st = EngineState::new(sc);
    let (mut l, mut r) = (vec![0.0; n], vec![0.0; n]);
    let mut i = 0;
    while i < n {
        let m = sizes().min(n - i);
        st.process_block(sc, &mut l[i..i + m], &mut r[i..i + m]);
        i += m;
    }
    (l, r, st.penetration(sc))
}

fn check(name: &str, scene: &Scene, switching: Switching, n: usize) {
    let sc = compile_with(scene, 44100.0, Some(switching)).unwrap();
    let (l0, r0, contacts, p0) = by_ticks(&sc, n);
    let mut rng = TestRng(12345);
    let mut random = move || rng.below(300);
    let mut splits: Vec<(&str, Sizes)> = vec![
        ("1", Box::new(|| 1)),
        ("7", Box::new(|| 7)),
        ("64", Box::new(|| 64)),
        ("100", Box::new(|| 100)),
        ("4096", Box::new(|| 4096)),
        ("random 0..300", Box::new(&mut random)),
    ];
    for (what, f) in splits.iter_mut() {
        let (l, r, p) = by_blocks(&sc, n, &mut **f);
        assert_eq!(
            p.to_bits(),
            p0.to_bits(),
            "{name} ({switching:?}): final state differs for blocks of {what}"
        );
        let same = l
            .iter()
            .zip(&l0)
            .chain(r.iter().zip(&r0))
            .all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(
            same,
            "{name} ({switching:?}): blocks of {what} differ from ticks"
        );
    }
    let peak = l0.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    println!("{name} ({switching:?}): {n} samples, {contacts} contacts, peak {peak:.3e}: identical for every split");
    assert!(
        peak.is_finite() && contacts > 0,
        "{name}: the check must see contacts"
    );
    assert!(
        peak > 0.0 || scene.pickup.is_empty(),
        "{name}: the check must see sound"
    );
}

#[test]
fn blocks_equal_ticks_bit_for_bit() {
    for sw in [Switching::Exact, Switching::OffsetRod] {
        // many bounces, gravity, a resting phase
        check("paper-bounce", &preset("paper-bounce"), sw, 50_000);
        // lumped string, eigen blocks
        check("paper-string", &preset("paper-string"), sw, 20_000);
        check("bell", &preset("bell"), sw, 20_000);
        // critically damped hammer on a wall: dense-fallback contact phase
        let wall = wall_strike(0.01, 1e6, c_for(0.01, 1e6, 1.0), 1e-3, -1.0);
        check("critical wall (dense)", &wall, sw, 5_000);
    }
}
