"""Render the BUILT modal_contact.vst3 with pedalboard and check its output.

Run (what `cargo xtask test` does):
    MODAL_CONTACT_VST3=target/plugin-tests/release/modal_contact.vst3 \
    MODAL_CONTACT_REFERENCE=target/test-release/render-reference \
    target/venv/bin/python plugin-tests/vst3/test_vst3.py

The reference is the instrument library driven directly (no plugin) by the
`render-reference` binary of plugin-tests with the same notes.

pedalboard facts used here (established in the infrastructure prototype):
- mido `time` is ABSOLUTE seconds from the start of the render, not a delta;
- an event lands on sample int(time * sample_rate), independent of buffer_size;
- parameters are attributes named after the display name in snake_case
  plus the unit (`output_gain_db`, `hardness_x`, `scene`, ...); enum values
  are the display strings;
- time t lands on int(t * sr), so a time like 0.7 s (0.7 * 44100 =
  30869.999...) is ambiguous: events here sit a quarter sample after a sample.
"""

import os
import subprocess
import sys
import tempfile

import mido
import numpy as np
import pedalboard

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BUNDLE = os.environ.get(
    "MODAL_CONTACT_VST3",
    os.path.join(ROOT, "target", "plugin-tests", "release", "modal_contact.vst3"),
)
REFERENCE = os.environ.get(
    "MODAL_CONTACT_REFERENCE", os.path.join(ROOT, "target", "test-release", "render-reference")
)
SR = 44100
ROOT_NOTE = 57  # marimba bar (220 Hz), the default scene


_PLUGIN = None


def load():
    """The plugin, loaded once for all the tests: pedalboard reads every
    parameter's info at load, nice-plug's 2080 hidden MIDI controller
    parameters included, which takes tens of seconds. Each test sets back
    the parameters it changes, and every render starts from a reset
    (pedalboard's default)."""
    global _PLUGIN
    if _PLUGIN is None:
        _PLUGIN = pedalboard.load_plugin(BUNDLE)
        assert _PLUGIN.is_instrument
    return _PLUGIN


def render(plugin, msgs, duration=2.0, sr=SR, **kw):
    audio = plugin(msgs, duration=duration, sample_rate=sr, num_channels=2, **kw)
    assert audio.shape == (2, int(duration * sr)), audio.shape
    assert audio.dtype == np.float32
    return audio


def on(note, vel, t):
    return mido.Message("note_on", note=note, velocity=vel, time=t)


def off(note, t):
    return mido.Message("note_off", note=note, velocity=0, time=t)


def reference(msgs, duration, sr=SR, extra=()):
    """The instrument library's render of the same notes (f32, shape (2, n))."""
    n = int(duration * sr)
    args = [REFERENCE, "--rate", str(sr), "--samples", str(n), *extra]
    for m in msgs:
        at = int(m.time * sr)
        if m.type == "note_on" and m.velocity > 0:
            args.append(f"on:{at}:{m.note}:{m.velocity}")
        else:
            args.append(f"off:{at}:{m.note}")
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "ref.f32")
        subprocess.run([*args, "--out", out], check=True)
        return np.fromfile(out, dtype="<f4").reshape(2, n)


def first_nonzero(x):
    nz = np.flatnonzero(x)
    return int(nz[0]) if len(nz) else None


def at_sample(k, sr=SR):
    """A time that unambiguously lands on sample k."""
    return (k + 0.25) / sr


def phrase(sr=SR):
    """A chord, a repeated note on the ringing bar, releases, more notes."""
    s = lambda t: at_sample(int(t * sr), sr)  # noqa: E731
    return [
        on(57, 100, s(0.0123)),
        on(61, 80, s(0.0123)),
        on(64, 90, s(0.0123)),
        on(57, 120, s(0.3)),  # repeated: strikes the ringing bar again
        off(61, s(0.6)),
        off(57, s(0.7)),
        on(69, 60, s(0.8)),
        on(45, 127, s(0.9)),
    ]


PHRASE = phrase()


def test_note_timing_and_finite():
    p = load()
    for sr in (44100, 96000):
        for t in (0.1, 0.123456, at_sample(12345, sr)):
            a = render(p, [on(ROOT_NOTE, 100, t)], duration=1.0, sr=sr)
            assert np.all(np.isfinite(a))
            at = int(t * sr)
            assert np.all(a[:, :at] == 0.0), f"sound before {t} s at {sr} Hz"
            first = first_nonzero(a[0])
            assert first is not None and at < first <= at + 3, (sr, at, first)
            print(f"  {sr} Hz: note at sample {at}, first sound at {first}")


def test_velocity_order():
    p = load()
    levels = []
    for vel in (20, 60, 100, 127):
        a = render(p, [on(ROOT_NOTE, vel, 0.0)], duration=1.0)
        levels.append(float(np.sqrt(np.mean(a[0] ** 2))))
    print(f"  rms for velocity 20/60/100/127: {levels}")
    assert all(b > 1.2 * a for a, b in zip(levels, levels[1:])), levels


def test_equals_the_instrument_library():
    p = load()
    for sr in (44100, 96000):
        a = render(p, phrase(sr), duration=2.0, sr=sr)
        ref = reference(phrase(sr), 2.0, sr)
        err = float(np.max(np.abs(a - ref)))
        print(f"  {sr} Hz: peak {float(np.max(np.abs(a))):.4f}, max |vst3 - library| = {err:.3e}")
        assert np.all(np.isfinite(a))
        # sounding: the presets play at -45 LUFS at velocity 100 (docs/levels.md)
        assert float(np.max(np.abs(a))) > 0.005
        assert err <= 1e-6, err


def test_buffer_size_does_not_change_output():
    p = load()
    ref = render(p, PHRASE, duration=1.0)
    for bs in (64, 333, 8192):
        assert np.array_equal(render(p, PHRASE, duration=1.0, buffer_size=bs), ref), bs


def test_gain_parameter():
    p = load()
    base = render(p, [on(ROOT_NOTE, 100, 0.01)], duration=0.5)
    p.output_gain_db = 0.0  # dB; the default is -6 dB
    try:
        louder = render(p, [on(ROOT_NOTE, 100, 0.01)], duration=0.5)
    finally:
        p.output_gain_db = -6.0
    ratio = float(np.max(np.abs(louder)) / np.max(np.abs(base)))
    print(f"  -6 dB -> 0 dB: peak ratio {ratio:.4f}")
    assert abs(ratio - 10 ** (6 / 20)) < 1e-3, ratio
    # and it matches the library at that gain
    p.output_gain_db = 0.0
    try:
        a = render(p, PHRASE, duration=1.0)
    finally:
        p.output_gain_db = -6.0
    err = float(np.max(np.abs(a - reference(PHRASE, 1.0, extra=("--gain-db", "0")))))
    assert err <= 1e-6, err


def test_lookahead_is_a_reported_latency():
    """Lookahead 10 ms at 48 kHz: the VST3 reports 480 samples of latency
    (pedalboard reads it through IAudioProcessor::getLatencySamples) and its
    output is the plain render 480 samples later, bit for bit (pedalboard
    does not compensate an instrument's latency)."""
    p = load()
    sr = 48000
    plain = render(p, phrase(sr), duration=2.0, sr=sr)
    assert p.reported_latency_samples == 0, p.reported_latency_samples
    p.lookahead_ms = 10
    try:
        late = render(p, phrase(sr), duration=2.0, sr=sr)
        latency = p.reported_latency_samples
    finally:
        p.lookahead_ms = 0
    n = plain.shape[1] - 480
    err = float(np.max(np.abs(late[:, 480:] - plain[:, :n])))
    print(f"  lookahead 10 ms: reported latency {latency} samples; max |late(t + 480) - plain(t)| = {err:.3e}")
    assert latency == 480, latency
    assert np.all(late[:, :480] == 0.0)
    assert err == 0.0, err


def test_scene_parameter():
    p = load()
    names = p.parameters["scene"].valid_values
    print(f"  scenes: {names}")
    assert "Bell" in names and "Marimba bar" in names, names
    p.scene = "Bell"
    try:
        msgs = [on(69, 100, 0.05)]
        a = render(p, msgs, duration=1.0)
        ref = reference(msgs, 1.0, extra=("--preset", "bell"))
        err = float(np.max(np.abs(a - ref)))
        print(f"  bell: max |vst3 - library| = {err:.3e}")
        assert err <= 1e-6, err
    finally:
        p.scene = "Marimba bar"


def main():
    global BUNDLE
    if len(sys.argv) > 1:
        BUNDLE = sys.argv[1]
    tests = [v for k, v in sorted(globals().items()) if k.startswith("test_")]
    failed = 0
    for t in tests:
        try:
            print(f"{t.__name__}:")
            t()
            print(f"ok   {t.__name__}")
        except Exception as e:  # noqa: BLE001
            failed += 1
            print(f"FAIL {t.__name__}: {e!r}")
    print(f"{len(tests) - failed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
