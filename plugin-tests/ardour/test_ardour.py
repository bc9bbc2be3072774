"""Render the BUILT modal_contact.vst3 inside the real DAW Ardour, headless.

Run:
    MODAL_CONTACT_VST3=target/plugin-tests/release/modal_contact.vst3 \
    MODAL_CONTACT_REFERENCE=target/test-release/render-reference \
    target/venv/bin/python plugin-tests/ardour/test_ardour.py

Needs Debian's Ardour 7 (`apt-get install --no-install-recommends ardour`):
`ardour7-lua` (the headless Lua session tool) and
`/usr/lib/ardour7/ardour-vst3-scanner`. MODAL_CONTACT_ARDOUR_LUA and
MODAL_CONTACT_ARDOUR_VST3_SCANNER override the two paths;
the temporary directory (sessions, Ardour's logs, exported WAVs) is kept
and printed when a test failed or MODAL_CONTACT_ARDOUR_KEEP=1.

What happens (everything in one temporary directory: HOME, XDG config and
cache for Ardour, the bundle's copy, the sessions):
1. The bundle is copied, its library back-dated by a minute and scanned with
   ardour-vst3-scanner. Plugin discovery in ardour7-lua reads only that scan
   cache (VST3_PATH says where the bundles are) and takes the cache as stale
   when the library is newer than the cache file.
2. Run 1, `render_session.lua` in "create" mode, on the "None (Dummy)"
   backend at 44.1 kHz: a new session, a MIDI track with the plugin as its
   instrument and before it a Lua DSP note generator (`note_generator.lua`
   with this file's NOTES; Ardour 7.3's Lua cannot create a MIDI region).
   Three takes, each exported from sample 0 with Session:simple_export() to
   32-bit float WAV (an export preset written here: no dither, no
   normalisation): "default" (the plugin's defaults), "gain" (Output gain
   set to -12 dB with set_processor_param), "bell" (then Scene set to Bell).
   The session is saved with those two changes.
3. Run 2, "load" mode, on a copy of the saved session: the parameters are
   read back and one more take, "reload", is exported.

Ardour's headless tool was seen to be flaky on this kind of machine whatever
the plugin (earlier measurements: about a third of its runs exiting non-zero,
mostly heap errors at teardown after a good export, sometimes "Port already
exists" before anything; about 3 % of exports holding a few corrupted samples
although the export reported success). None of that showed with this script
(26 runs of this test: 52 Ardour runs, 104 exports, all accepted at the first
attempt with exit 0), but the guard stays: each run is tried up to ATTEMPTS
times and accepted only when
every export reported success AND every take matches the plugin's own render
of the same notes (`render-reference`, the instrument library driven
directly, bit-identical to the plugin through a plugin host) within TOLERANCE
after aligning by the latency Ardour reports; the exit code after the script
printed "done" is only reported. A mismatch that repeats exactly in two
attempts is the plugin's, not Ardour's, and fails at once. The tests then
assert on the accepted renders.
"""

import base64
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
BUNDLE = os.environ.get(
    "MODAL_CONTACT_VST3",
    os.path.join(ROOT, "target", "plugin-tests", "release", "modal_contact.vst3"),
)
REFERENCE = os.environ.get(
    "MODAL_CONTACT_REFERENCE", os.path.join(ROOT, "target", "test-release", "render-reference")
)
ARDOUR_LUA = os.environ.get("MODAL_CONTACT_ARDOUR_LUA", "ardour7-lua")
SCANNER = os.environ.get(
    "MODAL_CONTACT_ARDOUR_VST3_SCANNER", "/usr/lib/ardour7/ardour-vst3-scanner"
)
ARDOUR_LIBS = "/usr/lib/ardour7"  # the scanner's own libraries (libpbd, ...)

SR = 44100
SAMPLES = 250_000  # each take, from sample 0 (5.67 s)
ATTEMPTS = 8  # per Ardour run
RUN_TIMEOUT = 180  # seconds, per Ardour run
# Largest |Ardour - reference| accepted, after alignment. Both sides are the
# plugin's float32 samples: Ardour passes them through a 0 dB fader and trim,
# no panner (test_track_gain_and_routing_are_unity) and a 0 dB master bus
# into a 32-bit float file. Measured: exactly 0.0 in every take of run 1; 5.96e-8
# (2.7e-7 of the peak) in the reloaded session, whose Output gain comes back
# from Ardour's saved value through the VST3 normalised value, 3.4e-7 dB off
# -12 dB: one float32 rounding of the gain factor (pedalboard setting -12 dB
# gives those same samples). 1e-6 is 17 times that and 1/200000 of the peaks:
# a gain off by 4e-5 dB, a sample moved or a corrupted sample exceed it by
# orders of magnitude.
TOLERANCE = 1e-6

ROOT_NOTE = 57  # marimba bar, 220 Hz
GAIN_DB = -12.0  # the plugin's default is -6 dB
SCENE_BELL = 0  # the Scene parameter's position of Bell (docs/plugin.md)
SCENE_MARIMBA = 2  # the default, Marimba bar
PRESET_ID = "3b0f6a52-8c1d-4e7a-a6f2-5d9e8b7c4a10"
FORMAT_ID = "6d1e3c7a-2b4f-4a51-9b8e-3f1a0c9d7e21"

# (note-on sample, key, velocity, note-off sample). The four velocity notes
# are released and silent (the voice stops) long before the next note. Some
# sit on cycle edges of Ardour's 1024-sample cycle: 47104 = 46 * 1024 is a
# cycle's first sample, 92159 a cycle's last. The last two are held for the
# pitch measurement (note 57 -> 220 Hz, 69 -> 440 Hz).
NOTES = [
    (4410, ROOT_NOTE, 20, 15435),
    (26000, ROOT_NOTE, 60, 37025),
    (47104, ROOT_NOTE, 100, 58129),
    (70001, ROOT_NOTE, 127, 81026),
    (92159, ROOT_NOTE, 100, 158150),
    (170000, 69, 100, 236150),
]
VELOCITY_NOTES = NOTES[:4]
PITCH_NOTES = [(NOTES[4], 220.0), (NOTES[5], 440.0)]

# The marimba rings on after its release (its scene has no damper): the
# takes turn Custom damper on, so that the Damper knob (0.5) damps released
# notes and each note has died away before the next (the onsets and levels
# below are measured on silence); the parameters carry over from take to
# take, and the saved session keeps it.
TAKES_CREATE = [
    ("default", {"Custom damper": 1}),
    ("gain", {"Output gain": GAIN_DB}),
    ("bell", {"Scene": SCENE_BELL}),
]
TAKES_LOAD = [("reload", {})]
# what render-reference is told for each take's plugin state
REF_ARGS = {
    "default": ("--damper-custom",),
    "gain": ("--damper-custom", "--gain-db", str(GAIN_DB)),
    "bell": ("--damper-custom", "--preset", "bell", "--gain-db", str(GAIN_DB)),
    "reload": ("--damper-custom", "--preset", "bell", "--gain-db", str(GAIN_DB)),
}


class ArdourError(Exception):
    pass


# ---------------------------------------------------------------- references


def events():
    ev = []
    for on, key, vel, off in NOTES:
        ev.append((on, 0x90, key, vel))
        ev.append((off, 0x80, key, 0))
    return sorted(ev)


_ref_cache = {}


def reference(extra=()):
    """The instrument library's render of NOTES (f32, shape (2, SAMPLES))."""
    key = tuple(extra)
    if key not in _ref_cache:
        args = [REFERENCE, "--rate", str(SR), "--samples", str(SAMPLES), *extra]
        for at, status, note, vel in events():
            args.append(f"on:{at}:{note}:{vel}" if status == 0x90 else f"off:{at}:{note}")
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "ref.f32")
            subprocess.run([*args, "--out", out], check=True)
            _ref_cache[key] = np.fromfile(out, dtype="<f4").reshape(2, SAMPLES)
    return _ref_cache[key]


# ---------------------------------------------------------------- WAV


def read_float_wav(path):
    """A 32-bit float WAV as (rate, float32 array (channels, n)); strict."""
    with open(path, "rb") as f:
        b = f.read()
    assert b[:4] == b"RIFF" and b[8:12] == b"WAVE", f"{path}: not a RIFF WAVE file"
    fmt = data = None
    i = 12
    while i + 8 <= len(b):
        cid, n = b[i : i + 4], int.from_bytes(b[i + 4 : i + 8], "little")
        body = b[i + 8 : i + 8 + n]
        if cid == b"fmt ":
            fmt = body
        elif cid == b"data":
            data = body
        i += 8 + n + (n & 1)
    assert fmt is not None and data is not None, f"{path}: no fmt or data chunk"
    tag, channels, rate = (
        int.from_bytes(fmt[0:2], "little"),
        int.from_bytes(fmt[2:4], "little"),
        int.from_bytes(fmt[4:8], "little"),
    )
    bits = int.from_bytes(fmt[14:16], "little")
    if tag == 0xFFFE:  # WAVE_FORMAT_EXTENSIBLE: the sub-format's first 2 bytes
        tag = int.from_bytes(fmt[24:26], "little")
    assert tag == 3 and bits == 32, f"{path}: not 32-bit float (format {tag}, {bits} bits)"
    x = np.frombuffer(data[: len(data) - len(data) % (4 * channels)], dtype="<f4")
    return rate, x.reshape(-1, channels).T.copy()


# ---------------------------------------------------------------- comparison


def xcorr_lag(a, b, max_lag=4096):
    """The lag d (|d| <= max_lag) maximising sum a[n + d] * b[n]."""
    n = a.size + b.size
    size = 1 << (n - 1).bit_length()
    c = np.fft.irfft(np.fft.rfft(a, size) * np.conj(np.fft.rfft(b, size)), size)
    lags = np.concatenate([np.arange(0, max_lag + 1), np.arange(-max_lag, 0)])
    vals = np.concatenate([c[: max_lag + 1], c[size - max_lag :]])
    return int(lags[int(np.argmax(vals))])


def compare(wav, ref, latency):
    """wav[:, n + latency] against ref[:, n]: max |diff| and its place, lag."""
    n = min(wav.shape[1] - latency, ref.shape[1])
    d = np.abs(wav[:, latency : latency + n].astype(np.float64) - ref[:, :n])
    worst = int(np.argmax(d.max(axis=0)))
    return {
        "max_diff": float(d.max()),
        "at": worst,
        "n_diff": int(np.count_nonzero(d)),
        "peak": float(np.max(np.abs(wav))),
        "ref_peak": float(np.max(np.abs(ref))),
        "lag": xcorr_lag(wav.sum(axis=0).astype(np.float64), ref.sum(axis=0).astype(np.float64)),
    }


# ---------------------------------------------------------------- Ardour


class Workspace:
    """The temporary directory: Ardour's HOME/config/cache, the bundle copy."""

    def __init__(self):
        self.dir = tempfile.mkdtemp(prefix="modal-contact-ardour-")
        home = os.path.join(self.dir, "home")
        self.config = os.path.join(home, ".config")
        self.cache = os.path.join(home, ".cache")
        self.plugins = os.path.join(self.dir, "vst3")
        os.makedirs(self.plugins)
        self.bundle = os.path.join(self.plugins, os.path.basename(BUNDLE.rstrip("/")))
        self.env = dict(os.environ)
        self.env.update(
            HOME=home,
            XDG_CONFIG_HOME=self.config,
            XDG_CACHE_HOME=self.cache,
            XDG_DATA_HOME=os.path.join(home, ".local", "share"),
            VST3_PATH=self.plugins,
        )
        self.env.pop("DISPLAY", None)
        ardour_config = os.path.join(self.config, "ardour7")
        self.scripts = os.path.join(ardour_config, "scripts")
        self.export_presets = os.path.join(ardour_config, "export")
        os.makedirs(self.scripts)
        os.makedirs(self.export_presets)

    def install_plugin(self):
        assert os.path.isdir(BUNDLE), f"no VST3 bundle at {BUNDLE}"
        need = "(apt-get install --no-install-recommends ardour)"
        assert shutil.which(ARDOUR_LUA), f"no {ARDOUR_LUA} {need}"
        assert os.access(SCANNER, os.X_OK), f"no {SCANNER} {need}"
        shutil.copytree(BUNDLE, self.bundle, symlinks=True)
        libdir = os.path.join(self.bundle, "Contents", "x86_64-linux")
        libs = [os.path.join(libdir, f) for f in os.listdir(libdir) if f.endswith(".so")]
        assert len(libs) == 1, libs
        old = time.time() - 60  # older than the scan cache written next
        os.utime(libs[0], (old, old))
        env = dict(self.env)
        env["LD_LIBRARY_PATH"] = ARDOUR_LIBS + (
            ":" + env["LD_LIBRARY_PATH"] if env.get("LD_LIBRARY_PATH") else ""
        )
        r = subprocess.run(
            [SCANNER, "-f", "-v", self.bundle],
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
        )
        log = r.stdout + r.stderr
        caches = []
        for d, _, files in os.walk(self.cache):
            caches += [os.path.join(d, f) for f in files if f.endswith(".v3i")]
        return r.returncode, log, caches

    def write_config(self):
        with open(os.path.join(HERE, "note_generator.lua")) as f:
            text = f.read()
        rows = "\n".join(f"\t{{ {at}, 0x{st:02X}, {k}, {v} }}," for at, st, k, v in events())
        assert "--@EVENTS@--" in text
        with open(os.path.join(self.scripts, "mc_test_notes.lua"), "w") as f:
            f.write(text.replace("--@EVENTS@--", rows))
        with open(os.path.join(self.export_presets, "mc-float.format"), "w") as f:
            f.write(EXPORT_FORMAT)
        with open(os.path.join(self.export_presets, "mc-float.preset"), "w") as f:
            f.write(EXPORT_PRESET)

    def run(self, mode, session_dir, name, out_dir, takes, log_path):
        env = dict(self.env)
        env.update(
            MC_MODE=mode,
            MC_SESSION_DIR=session_dir,
            MC_SESSION_NAME=name,
            MC_RATE=str(SR),
            MC_OUT_DIR=out_dir,
            MC_PRESET=PRESET_ID,
            MC_SAMPLES=str(SAMPLES),
            MC_TAKES="|".join(
                t + (":" + ",".join(f"{k}={v:g}" for k, v in p.items()) if p else "")
                for t, p in takes
            ),
        )
        script = os.path.join(HERE, "render_session.lua")
        # line-buffered, so what was printed survives a crash at teardown
        cmd = ["stdbuf", "-oL", "-eL", ARDOUR_LUA, script]
        t0 = time.monotonic()
        try:
            with open(log_path, "w") as log:
                r = subprocess.run(
                    cmd,
                    env=env,
                    stdin=subprocess.DEVNULL,
                    stdout=log,
                    stderr=subprocess.STDOUT,
                    timeout=RUN_TIMEOUT,
                )
            rc = r.returncode
        except subprocess.TimeoutExpired:
            rc = "timeout"
        with open(log_path, errors="replace") as f:
            text = f.read()
        return rc, time.monotonic() - t0, text, parse_report(text)


def parse_report(text):
    rep = {"params": {}, "set": {}, "export": {}, "procs": [], "raw": []}
    for line in text.splitlines():
        if not line.startswith("MC "):
            continue
        f = line[3:].split("\t")
        rep["raw"].append(f)
        key = f[0]
        if key == "param":
            rep["params"].setdefault(f[1], {})[f[2]] = float(f[3])
        elif key == "set":
            rep["set"][(f[1], f[2])] = (float(f[3]), float(f[4]))
        elif key == "export":
            rep["export"][f[1]] = f[2]
        elif key == "proc":
            rep["procs"].append(f[2])
        elif key == "latency":
            rep["latency"] = {f[i]: int(f[i + 1]) for i in range(1, len(f) - 1, 2)}
        elif key in ("done", "closed"):
            rep[key] = True
        else:
            rep[key] = f[1:] if len(f) > 2 else (f[1] if len(f) > 1 else True)
    return rep


def tail(text, n=25):
    return "\n".join("      | " + line for line in text.splitlines()[-n:])


def attempt_run(ws, label, mode, takes, prepare):
    """Up to ATTEMPTS runs of render_session.lua; the first accepted one."""
    reasons = []
    signatures = {}
    for attempt in range(1, ATTEMPTS + 1):
        base = os.path.join(ws.dir, f"{label}-{attempt}")
        os.makedirs(base)
        session_dir, name = prepare(base)
        out_dir = os.path.join(base, "export")
        log_path = os.path.join(base, "ardour.log")
        rc, secs, text, rep = ws.run(mode, session_dir, name, out_dir, takes, log_path)
        why, renders = judge(rep, takes, out_dir)
        status = "accepted" if why is None else f"rejected: {why}"
        print(f"  {label} attempt {attempt}: exit {rc}, {secs:.1f} s, {status}")
        if why is None:
            return {
                "attempt": attempt,
                "rc": rc,
                "report": rep,
                "renders": renders,
                "session_dir": session_dir,
                "name": name,
                "reasons": reasons,
            }
        print(tail(text, 12))
        reasons.append(f"attempt {attempt}: exit {rc}: {why}")
        sig = renders.get("signature")
        if sig is not None:
            signatures[sig] = signatures.get(sig, 0) + 1
            if signatures[sig] == 2:
                # the same mismatch twice: deterministic, not Ardour's flakiness
                reasons.append("the same mismatch twice: the plugin's output, not Ardour")
                break
    raise ArdourError(f"{label}: no accepted run in {attempt} attempts:\n  " + "\n  ".join(reasons))


def judge(rep, takes, out_dir):
    """None if the run is accepted, else why not; and the takes read."""
    renders = {}
    if not rep.get("done"):
        return "the script did not finish (no 'done')", renders
    lat = rep.get("latency", {}).get("plugin")
    if lat is None:
        return "no latency report", renders
    for take, _ in takes:
        if rep["export"].get(take) != "ok":
            return f"export of {take!r}: {rep['export'].get(take)}", renders
        path = os.path.join(out_dir, take + ".wav")
        if not os.path.exists(path):
            return f"no {path}", renders
        try:
            rate, x = read_float_wav(path)
        except (AssertionError, ValueError) as e:
            return f"{take}: unreadable WAV: {e}", renders
        if rate != SR or x.shape != (2, SAMPLES):
            return f"{take}: {rate} Hz, shape {x.shape}", renders
        c = compare(x, reference(REF_ARGS[take]), lat)
        renders[take] = (x, c)
        if not np.all(np.isfinite(x)):
            return f"{take}: non-finite samples", renders
        if c["lag"] != lat or c["max_diff"] > TOLERANCE:
            renders["signature"] = (take, c["lag"], c["max_diff"], c["at"])
            return (
                f"{take}: does not match the reference: cross-correlation lag {c['lag']} "
                f"(reported latency {lat}), max |diff| {c['max_diff']:.3e} at sample {c['at']}, "
                f"{c['n_diff']} samples differ",
                renders,
            )
    return None, renders


EXPORT_FORMAT = f"""<?xml version="1.0" encoding="UTF-8"?>
<ExportFormatSpecification name="modal_contact test float WAV" id="{FORMAT_ID}" with-cue="false" with-toc="false" with-mp4chaps="false" command="" analyse="false" soundcloud-upload="false">
  <Encoding id="F_WAV" type="T_Sndfile" extension="wav" name="WAV" has-sample-format="true" channel-limit="256"/>
  <SampleRate rate="1"/>
  <SRCQuality quality="SRC_SincBest"/>
  <EncodingOptions>
    <Option name="sample-format" value="SF_Float"/>
    <Option name="dithering" value="D_None"/>
    <Option name="tag-metadata" value="false"/>
    <Option name="tag-support" value="false"/>
    <Option name="broadcast-info" value="false"/>
  </EncodingOptions>
  <Processing>
    <Normalize enabled="false" loudness="no" dbfs="0" lufs="-23" dbtp="-1"/>
    <Silence>
      <Start>
        <Trim enabled="false"/>
        <Add enabled="false">
          <Duration format="Timecode" hours="0" minutes="0" seconds="0" frames="0"/>
        </Add>
      </Start>
      <End>
        <Trim enabled="false"/>
        <Add enabled="false">
          <Duration format="Timecode" hours="0" minutes="0" seconds="0" frames="0"/>
        </Add>
      </End>
    </Silence>
  </Processing>
</ExportFormatSpecification>
"""

# SampleRate rate="1" is "the session's rate": no resampling.
EXPORT_PRESET = f"""<?xml version="1.0" encoding="UTF-8"?>
<ExportPreset id="{PRESET_ID}" name="modal_contact test float WAV">
  <ExportFormat id="{FORMAT_ID}"/>
  <ExportFilename>
    <Folder relative="1" path="export"/>
    <Field name="label" enabled="0"/>
    <Field name="session" enabled="0"/>
    <Field name="snapshot" enabled="0"/>
    <Field name="timespan" enabled="1"/>
    <Field name="revision" enabled="0"/>
    <Field name="time" enabled="0" value="T_None"/>
    <Field name="date" enabled="0" value="D_None"/>
  </ExportFilename>
</ExportPreset>
"""


# ---------------------------------------------------------------- the runs

_state = {}


def runs():
    """Scan, run 1 (create, 3 takes, save), run 2 (load, 1 take): once."""
    if "error" in _state:
        raise ArdourError(f"(see the first test) {_state['error']}")
    if "run1" in _state:
        return _state
    try:
        ws = Workspace()
        _state["ws"] = ws
        print(f"  workspace {ws.dir}")
        rc, log, caches = ws.install_plugin()
        _state["scan"] = (rc, log, caches)
        ws.write_config()
        name = "mc"

        def fresh(base):
            return os.path.join(base, name), name

        run1 = attempt_run(ws, "create", "create", TAKES_CREATE, fresh)
        _state["run1"] = run1

        def copy_saved(base):
            # a pristine copy of the saved session for every attempt
            dst = os.path.join(base, name)
            skip = shutil.ignore_patterns("export")
            shutil.copytree(run1["session_dir"], dst, symlinks=True, ignore=skip)
            return dst, name

        _state["run2"] = attempt_run(ws, "load", "load", TAKES_LOAD, copy_saved)
    except Exception as e:  # noqa: BLE001
        _state["error"] = str(e) if isinstance(e, ArdourError) else f"{type(e).__name__}: {e}"
        raise
    return _state


# ---------------------------------------------------------------- tests


def test_plugin_scanned_and_loaded():
    s = runs()
    rc, log, caches = s["scan"]
    print(f"  scanner exit {rc}, cache files {[os.path.basename(c) for c in caches]}")
    assert rc == 0, log[-2000:]
    assert len(caches) == 1, caches
    with open(caches[0]) as f:
        cache = f.read()
    assert 'name="Modal Contact"' in cache and 'category="Instrument' in cache, cache
    assert 'n_outputs="2"' in cache and 'n_midi_inputs="1"' in cache, cache
    rep = s["run1"]["report"]
    uid, path = rep["plugin_info"]
    print(f"  Ardour lists the VST3: uid {uid}, {path}")
    assert path.startswith(s["ws"].bundle + os.sep), path
    # the generator feeds the instrument, which feeds the fader
    for run in ("run1", "run2"):
        procs = s[run]["report"]["procs"]
        print(f"  {run} processors: {procs}")
        i = procs.index("MC Test Notes")
        assert procs[i + 1] == "Modal Contact" and procs[i + 2] == "Amp", procs


def test_track_gain_and_routing_are_unity():
    s = runs()
    for run in ("run1", "run2"):
        rep = s[run]["report"]
        got = {
            k: rep[k]
            for k in (
                "fader",
                "trim",
                "pan_azimuth",
                "panner_bypassed",
                "master_fader",
                "master_trim",
                "track_outputs",
                "master_io",
                "routed",
                "rate",
            )
        }
        print(f"  {run}: {got}")
        assert float(rep["fader"]) == 1.0 and float(rep["trim"]) == 1.0, got
        assert float(rep["master_fader"]) == 1.0 and float(rep["master_trim"]) == 1.0, got
        assert float(rep["pan_azimuth"]) == 0.5, got
        assert rep["track_outputs"] == "2" and rep["master_io"] == ["2", "2"], got
        assert rep["routed"] == "1", got
        assert rep["rate"] == [str(SR), "buffer", "1024"], got
    # The saved session: the track's panner shell holds no panner (Ardour 7.3's
    # headless tool makes none), so its 2 outputs are the plugin's 2 channels
    # copied as they are; a stereo panner at the centre would be unity too.
    with open(os.path.join(s["run1"]["session_dir"], s["run1"]["name"] + ".ardour")) as f:
        xml = f.read()
    route = xml[xml.index('<Route version="'):]
    route = route[route.index(' name="synth"') :]
    route = route[: route.index("</Route>")]
    shell = re.search(r"<PannerShell [^>]*?(/>|>.*?</PannerShell>)", route, re.S).group(0)
    print(f"  saved track panner: {shell}")
    assert 'bypassed="0"' in shell
    panner = re.search(r'<Panner [^>]*type="([^"]*)"', shell)
    assert panner is None or panner.group(1) in ("Equal Power Stereo",), shell
    # the proof: every take equals the plugin's own output (test below)


def test_renders_equal_the_plugin_own_render():
    s = runs()
    for run in ("run1", "run2"):
        r = s[run]
        lat = r["report"]["latency"]
        print(f"  {run}: attempt {r['attempt']} (exit {r['rc']}); Ardour's latencies {lat}")
        for take, (x, c) in ((k, v) for k, v in r["renders"].items() if k != "signature"):
            print(
                f"    {take}: peak {c['peak']:.6f} (reference {c['ref_peak']:.6f}), "
                f"lag by cross-correlation {c['lag']} (reported {lat['plugin']}), "
                f"max |ardour - reference| {c['max_diff']:.3e} "
                f"({c['max_diff'] / c['ref_peak']:.2e} of the peak), {c['n_diff']} samples differ"
            )
            assert lat["plugin"] == 0 and lat["track"] == 0, lat  # the plugin reports none
            assert c["lag"] == lat["plugin"], c
            assert c["max_diff"] <= TOLERANCE, c
            # sounding: the presets play at -45 LUFS at velocity 100
            # (docs/levels.md), peaks of a few hundredths at 0 dB
            assert c["ref_peak"] > 0.005, c


def default_take():
    s = runs()
    x, _ = s["run1"]["renders"]["default"]
    return x[:, s["run1"]["report"]["latency"]["plugin"] :]


def test_onsets_at_the_generated_samples():
    x = default_take()
    ref = reference(REF_ARGS["default"])
    first_on = NOTES[0][0]
    assert np.all(x[:, : first_on + 1] == 0.0), "sound before the first note"
    for on, key, vel, _ in NOTES:
        before = x[:, on - 63 : on + 1]  # the previous note has stopped by now
        after = np.flatnonzero(np.any(x[:, on + 1 : on + 64] != 0.0, axis=0))
        first = on + 1 + int(after[0]) if len(after) else None
        ref_first = on + 1 + int(np.flatnonzero(np.any(ref[:, on + 1 : on + 64] != 0.0, axis=0))[0])
        print(f"  note {key} vel {vel} at sample {on}: sound from {first} (reference {ref_first})")
        assert np.all(before == 0.0), f"sound just before the note at {on}"
        assert first is not None and on < first <= on + 3, (on, first)
        assert first == ref_first, (first, ref_first)


def pitch(x, lo, hi):
    """The strongest frequency in [lo, hi] Hz (Hann, zero-padded FFT, parabolic)."""
    m = x.astype(np.float64) * np.hanning(x.size)
    size = 1 << 21
    spec = np.abs(np.fft.rfft(m, size))
    freqs = np.fft.rfftfreq(size, 1 / SR)
    band = np.flatnonzero((freqs >= lo) & (freqs <= hi))
    k = band[int(np.argmax(spec[band]))]
    a, b, c = np.log(spec[k - 1 : k + 2])
    return (k + 0.5 * (a - c) / (a - 2 * b + c)) * SR / size, spec, freqs


def test_pitch():
    x = default_take()
    for (on, key, _, off), expect in PITCH_NOTES:
        seg = x[0, on + SR // 10 : off]  # skip the strike's first 100 ms
        f, spec, freqs = pitch(seg, 0.5 * expect, 1.5 * expect)
        # and it is the strongest component of the whole note
        audible = np.flatnonzero((freqs > 20) & (freqs < 10000))
        strongest = freqs[audible[int(np.argmax(spec[audible]))]]
        print(
            f"  note {key}: {f:.4f} Hz (expected {expect:.2f}, {100 * (f / expect - 1):+.4f} %), "
            f"strongest component {strongest:.1f} Hz, {seg.size} samples"
        )
        assert abs(f / expect - 1) < 1e-3, f
        assert abs(strongest / f - 1) < 0.01, strongest


def test_velocity_levels():
    x = default_take()
    ref = reference(REF_ARGS["default"])
    levels = []
    for on, _, vel, off in VELOCITY_NOTES:
        peak = float(np.max(np.abs(x[:, on:off])))
        ref_peak = float(np.max(np.abs(ref[:, on:off])))
        v = 0.05 + 2.95 * (vel / 127) ** 2  # impact speed, docs/plugin.md
        levels.append((vel, peak, ref_peak, v))
    for vel, peak, ref_peak, v in levels:
        print(
            f"  velocity {vel:3d}: peak {peak:.6f} (reference {ref_peak:.6f}, "
            f"ratio {peak / ref_peak:.7f}), peak / impact speed {peak / v:.6f}"
        )
    peaks = [p for _, p, _, _ in levels]
    assert all(b > 1.2 * a for a, b in zip(peaks, peaks[1:])), peaks
    for vel, peak, ref_peak, v in levels:
        assert abs(peak / ref_peak - 1) < 1e-5, (vel, peak, ref_peak)
    # the contact is linear: the strike's amplitude is proportional to the
    # documented impact speed v = 0.05 + 2.95 (vel/127)^2 m/s
    per_v = [p / v for _, p, _, v in levels]
    assert max(per_v) / min(per_v) - 1 < 1e-3, per_v


def test_output_gain_parameter():
    s = runs()
    r1 = s["run1"]
    default, _ = r1["renders"]["default"]
    gain, _ = r1["renders"]["gain"]
    before, after = r1["report"]["set"][("gain", "Output gain")]
    print(f"  set_processor_param Output gain {before:g} dB, read back {after:g} dB")
    assert abs(after - GAIN_DB) < 1e-4, after
    assert abs(r1["report"]["params"]["initial"]["Output gain"] - (-6.0)) < 1e-4
    d, g = default.astype(np.float64), gain.astype(np.float64)
    ratio = float(np.sum(d * g) / np.sum(d * d))
    peak_ratio = float(np.max(np.abs(g)) / np.max(np.abs(d)))
    expect = 10 ** ((GAIN_DB - -6.0) / 20)
    resid = float(np.max(np.abs(g - ratio * d)))
    print(
        f"  -12 dB / default -6 dB: least-squares ratio {ratio:.6f}, peak ratio {peak_ratio:.6f} "
        f"(expected {expect:.6f}), max residual {resid:.2e}"
    )
    assert abs(ratio - expect) < 1e-5, ratio
    assert abs(peak_ratio - expect) < 1e-5, peak_ratio
    assert resid < 1e-6, resid


def test_scene_parameter():
    s = runs()
    r1 = s["run1"]
    marimba, _ = r1["renders"]["gain"]
    bell, c = r1["renders"]["bell"]
    before, after = r1["report"]["set"][("bell", "Scene")]
    initial = r1["report"]["params"]["initial"]["Scene"]
    print(f"  Scene: initial {initial:g}, set {before:g}, read back {after:g}")
    assert initial == SCENE_MARIMBA, initial
    assert after == SCENE_BELL, after
    change = float(np.max(np.abs(bell - marimba)))
    print(
        f"  bell vs marimba (both -12 dB): max difference {change:.4f}; "
        f"bell equals the library's bell to {c['max_diff']:.1e}"
    )
    # the presets play at -45 LUFS (docs/levels.md): peaks of a few hundredths
    assert change > 0.005, change


def test_session_reload_restores_parameters():
    s = runs()
    saved = s["run1"]["report"]
    loaded = s["run2"]["report"]
    assert saved.get("saved") == "0", saved.get("saved")
    initial = saved["params"]["initial"]
    restored = loaded["params"]["initial"]
    gain, scene = restored["Output gain"], restored["Scene"]
    print(f"  after reload: Output gain {gain:g} dB, Scene {scene:g}")
    assert set(restored) == set(initial), (set(restored) ^ set(initial))
    expect = dict(initial, **{"Output gain": GAIN_DB, "Scene": SCENE_BELL, "Custom damper": 1.0})
    for k, v in expect.items():
        assert abs(restored[k] - v) <= 1e-6 * max(1.0, abs(v)), (k, restored[k], v)
    # the reloaded session sounds like the saved one and like the library
    bell, _ = s["run1"]["renders"]["bell"]
    again, c = s["run2"]["renders"]["reload"]
    same = float(np.max(np.abs(again - bell)))
    a, b = again.astype(np.float64), bell.astype(np.float64)
    ratio = float(np.sum(a * b) / np.sum(b * b))
    print(
        f"  reload take vs the saved session's bell take: max |diff| {same:.3e}, "
        f"gain ratio {ratio:.9f} ({20 * np.log10(ratio):+.2e} dB); "
        f"vs the library {c['max_diff']:.3e}"
    )
    assert same <= TOLERANCE, same
    # the plugin's own state in the saved session (reported only: its format
    # is nice-plug's): the VST3 chunk holds the parameters as set
    with open(os.path.join(s["run1"]["session_dir"], s["run1"]["name"] + ".ardour")) as f:
        chunk = re.search(r"<chunk>([^<]*)</chunk>", f.read())
    if chunk:
        state = base64.b64decode(chunk.group(1))
        found = re.findall(rb'"(gain|scene)":\{"[a-z0-9]+":("?[^"}]*"?)\}', state)
        print(f"  the plugin's saved VST3 state: {[(k.decode(), v.decode()) for k, v in found]}")
    # what the plugin logged while Ardour loaded the session: restoring it
    # sends every parameter (2095 with the VST3 wrapper's hidden MIDI CC
    # ones) in one process call; the wrapper's event queues must hold them
    # without growing on the audio thread
    log = os.path.join(s["ws"].dir, f"load-{s['run2']['attempt']}", "ardour.log")
    with open(log, errors="replace") as f:
        warnings = sorted({ln.strip() for ln in f if "WARN" in ln and "Reasonable Synth" not in ln})
    print(f"  plugin warnings in the load run's log: {warnings or 'none'}")
    grew = [w for w in warnings if "buffer filled up" in w]
    assert not grew, grew


def main():
    global BUNDLE
    if len(sys.argv) > 1:
        BUNDLE = sys.argv[1]
    t0 = time.monotonic()
    tests = [v for k, v in globals().items() if k.startswith("test_")]
    failed = 0
    for t in tests:
        try:
            print(f"{t.__name__}:")
            t()
            print(f"ok   {t.__name__}")
        except Exception as e:  # noqa: BLE001
            failed += 1
            print(f"FAIL {t.__name__}: {e!r}")
    ws = _state.get("ws")
    for run in ("run1", "run2"):
        if run in _state:
            r = _state[run]
            earlier = r["reasons"] or "none"
            print(f"{run}: accepted at attempt {r['attempt']} (exit {r['rc']}); earlier: {earlier}")
    if ws is not None:
        if failed or os.environ.get("MODAL_CONTACT_ARDOUR_KEEP"):
            print(f"kept {ws.dir} (sessions, Ardour's logs, the exported takes)")
        else:
            shutil.rmtree(ws.dir, ignore_errors=True)
    print(f"total {time.monotonic() - t0:.1f} s")
    print(f"{len(tests) - failed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
