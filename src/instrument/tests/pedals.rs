//! Tests of the sustain and sostenuto pedals.

use super::*;

/// The sustain pedal: a note released while it is down rings exactly as a
/// note never released (bit for bit) until the pedal comes up, and from then
/// exactly as a note released at that instant.
#[test]
fn sustain_pedal_holds_released_notes_until_it_comes_up() {
    let n = 30_000;
    let (release, pedal_up) = (4_000, 16_000);
    let held = play(
        &[pedal(0, true, true), on(10, 60, 0.8), off(release, 60)],
        n,
    );
    let never_released = play(&[on(10, 60, 0.8)], n);
    assert_eq!(held, never_released, "released under the pedal: no damper");
    let up = play(
        &[
            pedal(0, true, true),
            on(10, 60, 0.8),
            off(release, 60),
            pedal(pedal_up, true, false),
        ],
        n,
    );
    let released_then = play(&[on(10, 60, 0.8), off(pedal_up, 60)], n);
    assert_eq!(up, released_then, "pedal up = note-off then");
    // and the damper really acts: the tail is quieter than the held note's
    assert!(rms(&up[n - 4000..]) < 0.5 * rms(&never_released[n - 4000..]));
    // a key still down when the pedal comes up keeps sounding undamped
    let still_down = play(
        &[
            pedal(0, true, true),
            on(10, 60, 0.8),
            pedal(pedal_up, true, false),
        ],
        n,
    );
    assert_eq!(still_down, never_released);
}

/// The sostenuto pedal holds only the notes down when it was pressed: a
/// note struck after it is damped at its note-off as usual; the held one
/// is damped when the pedal comes up.
#[test]
fn sostenuto_holds_only_the_notes_down_when_pressed() {
    let n = 30_000;
    let events = [
        on(10, 60, 0.8),
        pedal(100, false, true),
        on(200, 67, 0.8),
        off(4_000, 60),
        off(4_000, 67),
        pedal(16_000, false, false),
    ];
    let with = play(&events, n);
    let expect = play(
        &[
            on(10, 60, 0.8),
            on(200, 67, 0.8),
            off(4_000, 67),
            off(16_000, 60),
        ],
        n,
    );
    assert_eq!(with, expect);
    // pedal down before any note holds nothing
    let early = play(&[pedal(0, false, true), on(10, 60, 0.8), off(4_000, 60)], n);
    assert_eq!(early, play(&[on(10, 60, 0.8), off(4_000, 60)], n));
}

/// Both pedals: a note held by sostenuto stays undamped when the sustain
/// pedal comes up, and the other way round.
#[test]
fn each_pedal_keeps_what_the_other_holds() {
    let n = 24_000;
    let both = play(
        &[
            on(10, 60, 0.8),
            pedal(50, false, true),
            pedal(60, true, true),
            off(2_000, 60),
            pedal(8_000, true, false),
        ],
        n,
    );
    assert_eq!(
        both,
        play(&[on(10, 60, 0.8)], n),
        "sostenuto still holds it"
    );
    let other = play(
        &[
            on(10, 60, 0.8),
            pedal(50, false, true),
            pedal(60, true, true),
            off(2_000, 60),
            pedal(8_000, false, false),
            pedal(12_000, true, false),
        ],
        n,
    );
    assert_eq!(other, play(&[on(10, 60, 0.8), off(12_000, 60)], n));
}
