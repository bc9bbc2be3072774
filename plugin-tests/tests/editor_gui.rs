//! The editor as a user sees it: the standalone application (nice-plug's
//! standalone wrapper, dummy audio backend) in a headless X server (Xvfb,
//! Mesa's software OpenGL), built with the allocation checker
//! (`--features standalone,rt-checks`, test-release profile: any allocation
//! in `process` aborts, and the live view records inside `process` while
//! the window is open). Screenshots with `xwd`, clicks with `xdotool`.
//!
//! Asserts: the window appears at the editor's default size and is not
//! blank; the user scene folder lists a valid and an invalid scene (the
//! invalid one with its error, in red); with nothing moving the window is
//! not redrawn (the application takes almost no CPU); clicking an audition
//! pad makes the live view change; clicking the valid user scene loads it
//! (the window's top bar changes) and it plays; editing its file offers a
//! reload in the top bar; a reload the compiler refuses shows its error
//! there in red, one that takes seconds "compiling…" until it plays; the
//! process never aborted. The screenshots are
//! written to `target/plugin-tests/editor/`; README's picture
//! (docs/editor.png) is `editor-struck.png`.
//!
//! Needs: Xvfb, xdotool, xwd and xdpyinfo (x11-apps, x11-utils), ImageMagick's
//! `convert` (Debian: xvfb xdotool x11-apps x11-utils imagemagick
//! libgl1-mesa-dri; `.ci/run` installs them). The binary comes from
//! `MODAL_CONTACT_STANDALONE` (`cargo xtask test` builds it) or is built here.

use modal_testkit::bundles::{STANDALONE_BIN, STANDALONE_BUILD_ARGS};
use plugin_tests::workspace_root;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The editor's default size (src/plugin/params/persisted.rs, `EDITOR_SIZE`).
const SIZE: (u32, u32) = modal_contact::plugin::params::EDITOR_SIZE;

fn standalone() -> PathBuf {
    if let Ok(p) = std::env::var("MODAL_CONTACT_STANDALONE") {
        return PathBuf::from(p);
    }
    let root = workspace_root();
    let ok = Command::new("cargo")
        .current_dir(&root)
        .args(STANDALONE_BUILD_ARGS)
        .status()
        .expect("cargo build");
    assert!(ok.success(), "building the standalone failed");
    root.join("target/test-release").join(STANDALONE_BIN)
}

fn tool(name: &str) -> Command {
    // ImageMagick's own convert (another program of that name may come first
    // in PATH)
    let path = match name {
        "convert" if Path::new("/usr/bin/convert").exists() => "/usr/bin/convert",
        n => n,
    };
    Command::new(path)
}

/// Kill on drop.
struct Killed(Child);
impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// An RGB image.
struct Shot {
    w: usize,
    h: usize,
    rgb: Vec<u8>,
}

impl Shot {
    fn px(&self, x: usize, y: usize) -> [u8; 3] {
        let i = 3 * (y * self.w + x);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// Distinct colours in a region (a blank window has one or two).
    fn colours(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> usize {
        let mut c: Vec<[u8; 3]> = Vec::new();
        for y in y0..y1.min(self.h) {
            for x in x0..x1.min(self.w) {
                c.push(self.px(x, y));
            }
        }
        c.sort_unstable();
        c.dedup();
        c.len()
    }

    /// Pixels that differ in a region.
    fn diff(&self, o: &Shot, x0: usize, y0: usize, x1: usize, y1: usize) -> usize {
        let mut n = 0;
        for y in y0..y1.min(self.h) {
            for x in x0..x1.min(self.w) {
                n += usize::from(self.px(x, y) != o.px(x, y));
            }
        }
        n
    }
}

/// Screenshot window `wid` (also saved as PNG when `save` is given).
fn shot(display: &str, wid: &str, save: Option<&Path>) -> Shot {
    let xwd = Command::new("xwd")
        .env("DISPLAY", display)
        .args(["-silent", "-id", wid])
        .output()
        .expect("xwd (Debian: x11-apps)");
    assert!(xwd.status.success(), "xwd failed");
    let mut conv = tool("convert")
        .args(["xwd:-", "ppm:-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("convert (Debian: imagemagick)");
    {
        use std::io::Write;
        conv.stdin.take().unwrap().write_all(&xwd.stdout).unwrap();
    }
    let out = conv.wait_with_output().unwrap();
    assert!(out.status.success(), "convert failed");
    if let Some(p) = save {
        let mut c = tool("convert")
            .args(["ppm:-", &p.display().to_string()])
            .stdin(Stdio::piped())
            .spawn()
            .unwrap();
        use std::io::Write;
        c.stdin.take().unwrap().write_all(&out.stdout).unwrap();
        assert!(c.wait().unwrap().success());
    }
    parse_ppm(&out.stdout)
}

/// A binary PPM (P6, maxval 255).
fn parse_ppm(b: &[u8]) -> Shot {
    let mut fields = Vec::new();
    let mut i = 0;
    while fields.len() < 4 {
        while b[i].is_ascii_whitespace() {
            i += 1;
        }
        if b[i] == b'#' {
            while b[i] != b'\n' {
                i += 1;
            }
            continue;
        }
        let s = i;
        while !b[i].is_ascii_whitespace() {
            i += 1;
        }
        fields.push(String::from_utf8_lossy(&b[s..i]).into_owned());
    }
    assert_eq!(fields[0], "P6");
    assert_eq!(fields[3], "255");
    let (w, h): (usize, usize) = (fields[1].parse().unwrap(), fields[2].parse().unwrap());
    let rgb = b[i + 1..i + 1 + 3 * w * h].to_vec();
    Shot { w, h, rgb }
}

fn click(display: &str, wid: &str, x: u32, y: u32) {
    let ok = Command::new("xdotool")
        .env("DISPLAY", display)
        .args(["mousemove", "--window", wid, &x.to_string(), &y.to_string()])
        .args(["mousedown", "1"])
        .status()
        .expect("xdotool");
    assert!(ok.success());
    std::thread::sleep(Duration::from_millis(120));
    let ok = Command::new("xdotool")
        .env("DISPLAY", display)
        .args(["mouseup", "1"])
        .status()
        .unwrap();
    assert!(ok.success());
}

/// A free display number (no lock file).
fn free_display() -> String {
    (90..200)
        .find(|n| !Path::new(&format!("/tmp/.X{n}-lock")).exists())
        .map(|n| format!(":{n}"))
        .expect("a free X display number")
}

/// The application still runs (the allocation checker aborts it on any
/// allocation in `process`, e.g. in the live view's recording).
fn assert_alive(app: &mut Child, out: &Path) {
    if let Some(status) = app.try_wait().unwrap() {
        panic!(
            "the application died ({status}); its log:\n{}",
            std::fs::read_to_string(out.join("standalone.log")).unwrap_or_default()
        );
    }
}

const USER_SCENE: &str = include_str!("../../presets/wood-block.toml");

/// The invalid scene of the folder: the wood block with a negative decay
/// rate.
fn invalid_scene() -> String {
    let bad = USER_SCENE.replacen("decay_rate_per_s = ", "decay_rate_per_s = -", 1);
    let e = modal_contact::scene::Scene::from_toml_str(&bad)
        .expect_err("the invalid scene must not validate");
    assert!(e.path.ends_with("decay_rate_per_s"), "{e}");
    bad
}

/// A valid scene named `my-block` that takes seconds to compile: a modal
/// object of 600 modes, every one of them at the contact point.
fn slow_scene() -> String {
    let mut s = String::from(
        "version = 1\nname = \"my-block\"\nduration_s = 1.0\n\n[[object]]\nname = \"plate\"\n\
         kind = \"modal\"\npoints = [\"contact\", \"pickup\"]\n",
    );
    for k in 0..600 {
        let w = 1.0 / (1.0 + k as f64 * 0.01);
        s += &format!(
            "\n[[object.mode]]\nfreq_hz = {}\nt60_s = {}\nweights = [{w}, {}]\n",
            110.0 * (1.0 + k as f64).powf(1.3),
            2.0 / (1.0 + k as f64 * 0.02),
            if k % 2 == 0 { w } else { -w }
        );
    }
    s + "\n[hammer]\nmass_kg = 0.03\nheight_m = 0.001\nvelocity_m_per_s = -2.0\n\n\
         [contact]\nobject = \"plate\"\npoint = \"contact\"\nstiffness_n_per_m = 3e5\n\
         damping_n_s_per_m = 40.0\n\n[[pickup]]\nobject = \"plate\"\npoint = \"pickup\"\n\
         quantity = \"velocity\"\ngain = 0.5\n"
}

/// The share of one core the process `pid` takes over `span` (its threads'
/// user and system time from `/proc/<pid>/stat`).
fn cpu_share(pid: u32, span: Duration) -> f64 {
    let ticks = || -> u64 {
        let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
        // the fields after the command's closing parenthesis; utime and
        // stime are the 14th and 15th of the line
        let rest = &stat[stat.rfind(')').unwrap() + 2..];
        let f: Vec<&str> = rest.split_whitespace().collect();
        f[11].parse::<u64>().unwrap() + f[12].parse::<u64>().unwrap()
    };
    let hz: f64 = Command::new("getconf")
        .arg("CLK_TCK")
        .output()
        .ok()
        .and_then(|o| String::from_utf8_lossy(&o.stdout).trim().parse().ok())
        .unwrap_or(100.0);
    let a = ticks();
    std::thread::sleep(span);
    (ticks() - a) as f64 / hz / span.as_secs_f64()
}

/// Pixels in a region that are the editor's error red (240, 90, 80),
/// give or take the text's anti-aliasing.
fn red_pixels(s: &Shot, x0: usize, y0: usize, x1: usize, y1: usize) -> usize {
    let mut n = 0;
    for y in y0..y1.min(s.h) {
        for x in x0..x1.min(s.w) {
            let [r, g, b] = s.px(x, y).map(u16::from);
            n += usize::from(r >= 120 && r >= 2 * g && r >= 2 * b);
        }
    }
    n
}

#[test]
fn the_editor_shows_the_scene_plays_pads_and_loads_user_scenes() {
    let bin = standalone();
    let out = workspace_root().join("target/plugin-tests/editor");
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).unwrap();
    let (data, scenes) = user_scene_folder();

    let display = free_display();
    let xvfb = spawn_xvfb(&display);
    let t0 = Instant::now();
    wait_for_display(&display, t0);
    let mut app = spawn_standalone(&bin, &display, &data, &out);
    let wid = find_window(&display, &out);
    println!("window {wid} after {:.2} s", t0.elapsed().as_secs_f64());
    let ed = Editor {
        display: &display,
        wid: &wid,
        out: &out,
    };

    let first = first_frame(&ed);
    assert_eq!(
        (first.w as u32, first.h as u32),
        SIZE,
        "the window has the editor's size"
    );
    // let the folder listing arrive, then the reference picture
    std::thread::sleep(Duration::from_millis(1500));
    let before = shot(ed.display, ed.wid, Some(&ed.out.join("editor-idle.png")));
    let (w, h) = (before.w, before.h);
    println!("idle: {} colours", before.colours(0, 0, w, h));
    // the folder's entries (below the built-in list: one 23-pixel row per
    // preset shown, at most BUILT_IN_ROWS, the rest scrolled; at 7 presets
    // and without the "Import recording..." row the first entry sat at
    // y = 327; that button's row is 23 pixels too): the invalid file's
    // error in red below its name
    let shown = modal_contact::presets::COUNT.min(modal_contact::plugin::editor::BUILT_IN_ROWS);
    let user_row_y = 327 + 23 * (shown as u32 - 7) + 23;
    let listed_red = red_pixels(&before, 0, user_row_y as usize, 260, h);
    println!("folder list: {listed_red} red pixels (the invalid file's error)");
    assert!(
        listed_red > 100,
        "the invalid file's error is not shown ({listed_red} red pixels)"
    );

    editor_idles(&app.0);
    let view = (280, 60, w.min(700), h.min(500));
    let struck = pad_moves_the_view(&ed, &mut app.0, &before, view);
    let user_struck = user_scene_loads_and_plays(&ed, &mut app.0, &struck, w, user_row_y, view);
    let file = scenes.join("my-block.toml");
    let button_x = changed_file_offers_a_reload_that_fails(&ed, &mut app.0, &file, &user_struck, w);
    slow_compile_is_labelled(&ed, &mut app.0, &file, w, button_x);
    let _ = Command::new("kill")
        .args(["-TERM", &app.0.id().to_string()])
        .status();
    drop(xvfb);
}

/// The editor under test: the X display, its window's id, and the folder
/// of the screenshots and the application's log.
struct Editor<'a> {
    display: &'a str,
    wid: &'a str,
    out: &'a Path,
}

/// The user data directory with its scene folder (a valid scene and an
/// invalid one): `(data directory, scene folder)`.
fn user_scene_folder() -> (PathBuf, PathBuf) {
    // the user data directory: a short path, as the browser shows it in
    // README's picture
    let data = std::env::temp_dir().join("modal-contact-editor");
    let _ = std::fs::remove_dir_all(&data);
    let scenes = data.join("modalcontact/scenes");
    std::fs::create_dir_all(&scenes).unwrap();
    std::fs::write(
        scenes.join("my-block.toml"),
        USER_SCENE.replace("name = \"wood-block\"", "name = \"my-block\""),
    )
    .unwrap();
    std::fs::write(scenes.join("typo.toml"), invalid_scene()).unwrap();
    (data, scenes)
}

/// Xvfb on `display`, killed on drop.
fn spawn_xvfb(display: &str) -> Killed {
    Killed(
        Command::new("Xvfb")
            .args([display, "-screen", "0", "1280x1024x24", "-nolisten", "tcp"])
            .stderr(Stdio::null())
            .spawn()
            .expect("Xvfb (Debian: xvfb)"),
    )
}

/// Wait (at most 20 s from `t0`) until the X server on `display` answers.
fn wait_for_display(display: &str, t0: Instant) {
    while !Command::new("xdpyinfo")
        .env("DISPLAY", display)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
    {
        assert!(t0.elapsed() < Duration::from_secs(20), "Xvfb did not start");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The standalone `bin` on `display`, its user data in `data`, its log in
/// `out`; killed on drop.
fn spawn_standalone(bin: &Path, display: &str, data: &Path, out: &Path) -> Killed {
    let log = std::fs::File::create(out.join("standalone.log")).unwrap();
    Killed(
        Command::new(bin)
            .args([
                "--backend",
                "dummy",
                "--sample-rate",
                "48000",
                "--period-size",
                "256",
            ])
            .env("DISPLAY", display)
            .env("LIBGL_ALWAYS_SOFTWARE", "1")
            .env("XDG_DATA_HOME", data)
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .spawn()
            .expect("the standalone"),
    )
}

/// The id of the application's window on `display` (waiting up to 60 s),
/// or a failure with the application's log in `out`.
fn find_window(display: &str, out: &Path) -> String {
    let found = Command::new("timeout")
        .args([
            "60",
            "xdotool",
            "search",
            "--sync",
            "--name",
            "^Modal Contact$",
        ])
        .env("DISPLAY", display)
        .output()
        .expect("xdotool (Debian: xdotool)");
    let wid = String::from_utf8_lossy(&found.stdout)
        .lines()
        .next()
        .unwrap_or("")
        .trim()
        .to_string();
    assert!(
        !wid.is_empty(),
        "no window; the application's log:\n{}",
        std::fs::read_to_string(out.join("standalone.log")).unwrap_or_default()
    );
    wid
}

/// The first painted frame: more than a handful of colours (within 30 s).
fn first_frame(ed: &Editor) -> Shot {
    // the first painted frame: more than a handful of colours
    let t1 = Instant::now();
    loop {
        let s = shot(ed.display, ed.wid, None);
        if s.colours(0, 0, s.w, s.h) > 20 {
            break s;
        }
        assert!(
            t1.elapsed() < Duration::from_secs(30),
            "the window stays blank"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Nothing moves: the window is not redrawn, the application `app` idles
/// (the audio thread's dummy backend and the worker's poll remain;
/// redrawing at the display rate took about 40 % of a core here).
fn editor_idles(app: &Child) {
    let idle = cpu_share(app.id(), Duration::from_secs(3));
    println!(
        "idle: the application takes {:.1} % of one core",
        idle * 100.0
    );
    assert!(
        idle < 0.12,
        "the idle editor takes {:.1} % of one core: is it redrawn when nothing changed?",
        idle * 100.0
    );
}

/// An audition pad (the second, "root", in the bottom row between the side
/// panels), struck high: the live view `view` (x0, y0, x1, y1) must move
/// from `before`. Returns the struck picture.
fn pad_moves_the_view(
    ed: &Editor,
    app: &mut Child,
    before: &Shot,
    view: (usize, usize, usize, usize),
) -> Shot {
    click(ed.display, ed.wid, 390, SIZE.1 - 40);
    std::thread::sleep(Duration::from_millis(400));
    assert_alive(app, ed.out);
    let struck = shot(ed.display, ed.wid, Some(&ed.out.join("editor-struck.png")));
    let changed = struck.diff(before, view.0, view.1, view.2, view.3);
    println!("live view: {changed} pixels changed after the pad");
    assert!(
        changed > 2000,
        "the live view did not change after a pad ({changed} pixels)"
    );
    assert!(
        app.try_wait().unwrap().is_none(),
        "the application died (allocation in process?)"
    );
    struck
}

/// The user scene (the first entry of the folder list, at `user_row_y`):
/// the top bar (the window's width `w`) names it once the worker compiled
/// it; struck, the live view `view` moves again. Returns the struck
/// picture.
fn user_scene_loads_and_plays(
    ed: &Editor,
    app: &mut Child,
    struck: &Shot,
    w: usize,
    user_row_y: u32,
    view: (usize, usize, usize, usize),
) -> Shot {
    let listing = std::fs::read_to_string(ed.out.join("standalone.log")).unwrap_or_default();
    click(ed.display, ed.wid, 56, user_row_y);
    std::thread::sleep(Duration::from_millis(1500));
    let loaded = shot(
        ed.display,
        ed.wid,
        Some(&ed.out.join("editor-user-scene.png")),
    );
    let top = loaded.diff(struck, 0, 0, w, 50);
    println!("top bar: {top} pixels changed after loading the user scene");
    assert!(
        top > 100,
        "the top bar did not change after loading a user scene\n{listing}"
    );
    // strike it: the view moves again
    click(ed.display, ed.wid, 390, SIZE.1 - 40);
    std::thread::sleep(Duration::from_millis(400));
    let user_struck = shot(
        ed.display,
        ed.wid,
        Some(&ed.out.join("editor-user-struck.png")),
    );
    assert!(user_struck.diff(&loaded, view.0, view.1, view.2, view.3) > 2000);
    assert_alive(app, ed.out);
    user_struck
}

/// The scene's `file` changes on disk (into an invalid scene): the top bar
/// offers a reload (checked once a second), the scene is not swapped
/// silently; reloaded, the compile fails and the top bar says why in red
/// (the last good scene plays on); `w`: the window's width. Returns the
/// reload button's x.
fn changed_file_offers_a_reload_that_fails(
    ed: &Editor,
    app: &mut Child,
    file: &Path,
    user_struck: &Shot,
    w: usize,
) -> usize {
    std::fs::write(
        file,
        invalid_scene().replace("name = \"wood-block\"", "name = \"my-block\""),
    )
    .unwrap();
    std::thread::sleep(Duration::from_millis(2500));
    let offered = shot(
        ed.display,
        ed.wid,
        Some(&ed.out.join("editor-changed-on-disk.png")),
    );
    let top = offered.diff(user_struck, 0, 0, w, 30);
    println!("top bar: {top} pixels changed after the file changed on disk");
    assert!(
        top > 100,
        "no reload offered after the file changed on disk"
    );
    assert_alive(app, ed.out);

    // reload it: the compile fails, the top bar says why in red (the last
    // good scene plays on)
    let changed_x: Vec<usize> = (0..w)
        .filter(|&x| (0..30).any(|y| offered.px(x, y) != user_struck.px(x, y)))
        .collect();
    let button_x = (changed_x[0] + changed_x[changed_x.len() - 1]) / 2;
    click(ed.display, ed.wid, button_x as u32, 14);
    std::thread::sleep(Duration::from_millis(1500));
    let failed = shot(
        ed.display,
        ed.wid,
        Some(&ed.out.join("editor-reload-failed.png")),
    );
    let red = red_pixels(&failed, 0, 24, w, 44);
    println!("top bar: {red} red pixels after reloading the invalid file");
    assert!(
        red > 100,
        "the failed compile's error is not shown in the top bar ({red} red pixels)"
    );
    assert_alive(app, ed.out);
    button_x
}

/// A valid scene that takes seconds to compile, written to `file` and
/// reloaded with the button at `button_x`: while it compiles, the top bar
/// (the window's width `w`) says "compiling…" (and no longer the error);
/// once it plays, the label is gone.
fn slow_compile_is_labelled(ed: &Editor, app: &mut Child, file: &Path, w: usize, button_x: usize) {
    std::fs::write(file, slow_scene()).unwrap();
    std::thread::sleep(Duration::from_millis(2500));
    click(ed.display, ed.wid, button_x as u32, 14);
    std::thread::sleep(Duration::from_millis(400));
    let compiling = shot(
        ed.display,
        ed.wid,
        Some(&ed.out.join("editor-compiling.png")),
    );
    let red = red_pixels(&compiling, 0, 24, w, 44);
    assert_eq!(
        red, 0,
        "the error is still shown while the new scene compiles"
    );
    let t2 = Instant::now();
    let compiled = loop {
        std::thread::sleep(Duration::from_millis(500));
        let s = shot(ed.display, ed.wid, None);
        // the summary line names the new scene's 600 modes once it plays
        if s.diff(&compiling, 0, 24, w, 44) > 100 {
            break s;
        }
        assert!(
            t2.elapsed() < Duration::from_secs(120),
            "the 600-mode scene never finished compiling"
        );
    };
    println!(
        "600-mode scene compiled within {:.1} s of the reload",
        t2.elapsed().as_secs_f64()
    );
    let label = compiled.diff(&compiling, 0, 0, w, 24);
    println!("top bar: {label} pixels changed when the compile ended (the \"compiling…\" label)");
    assert!(
        label > 100,
        "no \"compiling…\" in the top bar while the scene compiled"
    );
    assert_alive(app, ed.out);
}
