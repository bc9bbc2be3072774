//! No output sample is subnormal in f32 (a CLAP validator's fuzzer found
//! samples between 1e-38 and 3e-44 in decaying tails): the f64 state is
//! flushed, but a tiny f64 output still becomes a subnormal f32 unless the
//! conversion flushes too.
//!
//! The scene makes such a tail on purpose: one mode that the pickup does not
//! hear rings for a long time (the voice keeps sounding), while the one it
//! hears dies in milliseconds, so the output passes through every magnitude
//! down to zero, the f32 subnormal range (1.4e-45 .. 1.2e-38) included.

use modal_contact::instrument::{prepare_scene, Event, Instrument, InstrumentParams, TimedEvent};
use modal_testkit::scenes::{Contact, Hammer, Modal, Pickup, SceneBuilder};

fn tail_scene() -> modal_contact::scene::Scene {
    SceneBuilder::new("tail")
        .duration(3.0)
        .object(
            Modal::new("o", &["c", "p"])
                .mode(180.0, 30.0, &[1.0, 0.0])
                .mode(2500.0, 0.02, &[0.8, 0.9]),
        )
        .hammer(Hammer::new(0.01).height(1e-3).velocity(-1.0))
        .contact(Contact::new("o", 1e6).point("c").damping(5.0))
        .pickup(Pickup::new("o", "p"))
        .build()
}

#[test]
fn no_output_sample_is_subnormal_in_f32() {
    for rate in [44100.0, 48000.0, 96000.0] {
        let p = InstrumentParams::default();
        let prepared = prepare_scene(&tail_scene(), &p.scene, rate, 0).unwrap();
        let mut inst = Instrument::new(prepared, p.play);
        let n = (2.0 * rate) as usize;
        let (mut l, mut r) = (vec![0.0f32; n], vec![0.0f32; n]);
        let on = TimedEvent {
            offset: 0,
            event: Event::NoteOn {
                key: 60,
                velocity_norm: 0.8,
            },
        };
        inst.process(&[on], &mut l, &mut r);
        let sub = l
            .iter()
            .chain(&r)
            .filter(|x| **x != 0.0 && x.abs() < f32::MIN_POSITIVE)
            .count();
        // the tail really went through the range: some samples are tiny
        // but normal, later ones exactly zero
        let tiny = l
            .iter()
            .filter(|x| x.abs() > 0.0 && x.abs() < 1e-30)
            .count();
        let zeros = l.iter().filter(|x| **x == 0.0).count();
        println!("{rate} Hz: {sub} subnormal, {tiny} normal below 1e-30, {zeros} zero samples");
        assert_eq!(sub, 0, "{rate} Hz: {sub} subnormal f32 samples");
        assert!(
            tiny > 0 && zeros > 0,
            "{rate} Hz: the tail did not reach the range"
        );
        assert_eq!(inst.active_voices(), 1, "the unheard mode keeps the voice");
    }
}
