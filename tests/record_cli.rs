//! `tumble record` to GIF, PNG frames and MP4 (when ffmpeg is installed), `tumble view`'s
//! errors without a display, and the real window under Xvfb when `xvfb-run` is installed.
//!
//! Tests that render print why they skip when there is no GPU adapter, and fail instead with
//! TUMBLE_REQUIRE_GPU=1.
#![cfg(all(feature = "viewer", feature = "cli"))]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use tumble::viewer::palette;

fn tumble() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_tumble"));
    // Quiet "XDG_RUNTIME_DIR is invalid" noise from the drivers.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        command.env("XDG_RUNTIME_DIR", scratch("xdg"));
    }
    command
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("tumble-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700)).unwrap();
    }
    dir
}

fn require_gpu() -> bool {
    std::env::var("TUMBLE_REQUIRE_GPU").is_ok_and(|v| v == "1")
}

/// Skips a test for want of a tool (`why`), printing why; fails instead under
/// `TUMBLE_REQUIRE_GPU=1`, where `.ci/run` has installed the tools with the driver.
fn skip_or_fail(why: &str) {
    assert!(!require_gpu(), "TUMBLE_REQUIRE_GPU=1 but {why}");
    eprintln!("skipping: {why}");
}

/// Runs a rendering command; None (skip) when it failed for want of a GPU adapter.
fn run_rendering(command: &mut Command) -> Option<Output> {
    let output = command.output().expect("tumble runs");
    let stderr = String::from_utf8_lossy(&output.stderr);
    if !output.status.success() && stderr.contains("no usable GPU adapter") {
        assert!(!require_gpu(), "TUMBLE_REQUIRE_GPU=1 but: {stderr}");
        eprintln!("skipping: {stderr}");
        return None;
    }
    assert!(
        output.status.success(),
        "tumble failed: {stderr}\n{}",
        String::from_utf8_lossy(&output.stdout)
    );
    Some(output)
}

/// Runs `command`, which must fail saying `words`.
fn fails_saying(command: &mut Command, words: &str) {
    let output = command.output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        !output.status.success() && stderr.contains(words),
        "{stderr}"
    );
}

fn no_partial_files(dir: &Path) {
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        assert!(
            !entry.file_name().to_string_lossy().ends_with(".partial"),
            "left behind: {}",
            entry.path().display()
        );
    }
}

/// Also through a symbolic link (on unix): the file it leads to is written, and the link stays.
#[test]
fn record_gif() {
    let dir = scratch("gif");
    let out = dir.join("mixed.gif");
    #[cfg(unix)]
    std::os::unix::fs::symlink(dir.join("target.gif"), &out).unwrap();
    let Some(_) = run_rendering(
        tumble()
            .args([
                "record",
                "mixed",
                "--seconds",
                "0.5",
                "--fps",
                "10",
                "--size",
                "96x64",
                "-o",
            ])
            .arg(&out),
    ) else {
        return;
    };
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::RGBA);
    let mut decoder = options
        .read_info(std::fs::File::open(&out).unwrap())
        .unwrap();
    assert_eq!((decoder.width(), decoder.height()), (96, 64));
    let mut frames = Vec::new();
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        assert_eq!(frame.delay, 10, "10 fps = 10 cs per frame");
        frames.push(frame.buffer.to_vec());
    }
    assert_eq!(frames.len(), 5);
    assert_ne!(
        frames[0], frames[4],
        "the bodies fall between the first and last frame"
    );
    #[cfg(unix)]
    assert!(
        std::fs::symlink_metadata(&out)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    no_partial_files(&dir);
}

/// A GIF above 50 fps is recorded, with a warning: players show frames under 2 cs at 10 cs.
#[test]
fn fast_gifs_are_warned_of() {
    let dir = scratch("fast-gif");
    let fast = [
        "record",
        "cube",
        "--fps",
        "100",
        "--seconds",
        "0.02",
        "--size",
        "32x32",
    ];
    let Some(output) = run_rendering(tumble().args(fast).arg("-o").arg(dir.join("f.gif"))) else {
        return;
    };
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("warning: --fps 100: most players show GIF frames"),
        "{stderr}"
    );
    // 100 frames a second of 50 steps: every other frame shows the step the one before did.
    assert!(
        stderr.contains("50 % of the frames repeat the one before; a --dt of at most 0.0100"),
        "{stderr}"
    );
    // The length is the video's (frames / fps), the time the last frame's.
    let stdout = String::from_utf8_lossy(&output.stdout);
    let summary = "wrote 2 frames (32x32, 0.02 s at 100 fps, the last frame at simulated time \
                   0.00 s after 0 steps)";
    assert!(stdout.contains(summary), "{stdout}");
}

/// Decoded RGBA frames of a GIF, with its size.
fn gif_frames(path: &Path) -> (u16, u16, Vec<Vec<u8>>) {
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::RGBA);
    let mut decoder = options
        .read_info(std::fs::File::open(path).unwrap())
        .unwrap();
    let (w, h) = (decoder.width(), decoder.height());
    let mut frames = Vec::new();
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        frames.push(frame.buffer.to_vec());
    }
    (w, h, frames)
}

/// `record --compare`: two panes, each with its label (bright text in its top left corner, where
/// a recording of one world has only background), showing different motion.
#[test]
fn record_compare_side_by_side() {
    let dir = scratch("compare");
    let out = dir.join("compare.gif");
    let Some(output) = run_rendering(
        tumble()
            .args([
                "record",
                "tower",
                "--compare",
                "--solver coursework --dt 0.01",
            ])
            .args(["--seconds", "1", "--fps", "5", "--size", "640x240", "-o"])
            .arg(&out),
    ) else {
        return;
    };
    assert!(String::from_utf8_lossy(&output.stdout).contains("wrote 5 frames"));
    let (w, h, frames) = gif_frames(&out);
    assert_eq!((w, h, frames.len()), (640, 240, 5));
    let pixel = |frame: &[u8], x: usize, y: usize| {
        let i = 4 * (y * w as usize + x);
        [frame[i], frame[i + 1], frame[i + 2]]
    };
    let last = &frames[4];
    // The statistics' grey text (the bodies are coloured).
    let grey_text = |p: [u8; 3]| {
        let (max, min) = (p.iter().max().unwrap(), p.iter().min().unwrap());
        *min > 130 && max - min < 30
    };
    // In every frame from the first (frame 0's were placed at another zoom, and the labels
    // faded in over the first ten frames).
    for (k, frame) in frames.iter().enumerate() {
        for x0 in [0, 320] {
            let text = (8..50)
                .flat_map(|y| (x0 + 10..x0 + 300).map(move |x| (x, y)))
                .filter(|&(x, y)| grey_text(pixel(frame, x, y)))
                .count();
            assert!(
                text > 30,
                "frame {k}: no label in the pane at x = {x0}: {text} bright pixels"
            );
        }
    }
    let half = |frame: &[u8], x0: usize| -> Vec<[u8; 3]> {
        (60..h as usize)
            .flat_map(|y| (x0..x0 + 320).map(move |x| (x, y)))
            .map(|(x, y)| pixel(frame, x, y))
            .collect()
    };
    assert_ne!(
        half(last, 0),
        half(last, 320),
        "dt 0.02 and 0.01 move differently"
    );
}

/// `--camera orbit` starts where the framed camera looks and turns from there.
#[test]
fn record_orbit() {
    let dir = scratch("orbit");
    let mut runs = Vec::new();
    for camera in [None, Some("orbit")] {
        let out = dir.join(format!("{}.gif", camera.unwrap_or("still")));
        let mut command = tumble();
        command.args([
            "record",
            "cube",
            "--seconds",
            "0.4",
            "--fps",
            "10",
            "--size",
            "96x64",
        ]);
        if let Some(camera) = camera {
            command.args(["--camera", camera]);
        }
        let Some(_) = run_rendering(command.arg("-o").arg(&out)) else {
            return;
        };
        runs.push(gif_frames(&out).2);
    }
    assert_eq!(
        runs[0][0], runs[1][0],
        "the orbit starts at the framed camera"
    );
    assert_ne!(runs[0][2], runs[1][2], "and then turns");
}

fn read_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buffer).unwrap();
    buffer.truncate(info.buffer_size());
    (info.width, info.height, buffer)
}

/// The names of the files in `dir`, sorted.
fn sorted_names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn record_png_frames() {
    let dir = scratch("png");
    let out = dir.join("frames");
    let Some(output) = run_rendering(
        tumble()
            .args([
                "record",
                "two-chain",
                "--seconds",
                "0.3",
                "--fps",
                "10",
                "--size",
                "80x60",
                "--contacts",
                "-o",
            ])
            .arg(&out),
    ) else {
        return;
    };
    assert!(String::from_utf8_lossy(&output.stdout).contains("wrote 3 frames"));
    let names = sorted_names(&out);
    assert_eq!(
        names,
        ["frame_000000.png", "frame_000001.png", "frame_000002.png"]
    );
    let (w, h, first) = read_png(&out.join(&names[0]));
    assert_eq!((w, h), (80, 60));
    let (_, _, last) = read_png(&out.join(&names[2]));
    assert_ne!(first, last);
    // Into the folder, now there: recorded again (it was refused as "a folder"), its one frame
    // replacing the three; files named otherwise stay.
    let theirs = ["frame_intro.png", "frame_1.png", "frame_0000001.txt"];
    for name in theirs {
        std::fs::write(out.join(name), name).unwrap();
    }
    let again = tumble()
        .args(["record", "two-chain", "--seconds", "0.1", "--fps", "10"])
        .args(["--size", "80x60", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&again.stderr);
    assert!(again.status.success(), "{stderr}");
    let names = sorted_names(&out);
    assert_eq!(
        names,
        [
            "frame_000000.png",
            "frame_0000001.txt",
            "frame_1.png",
            "frame_intro.png"
        ]
    );
}

/// Recording frames into a folder replaces the frames an earlier one left there; not one the run
/// reads (a scene saved under such a name). Refused before any rendering, so no GPU is needed.
#[test]
fn frames_never_replace_an_input() {
    let dir = scratch("png-input");
    let mesh = include_str!(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/tetrahedron.mesh"
    ));
    std::fs::write(dir.join("t.mesh"), mesh).unwrap();
    let scene = dir.join("frame_000007.png");
    let text = "1\nt.mesh 1 0 0 3 0 1 0 0 0\n";
    std::fs::write(&scene, text).unwrap();
    fails_saying(
        tumble()
            .args(["record", "--seconds", "0.1", "--size", "80x60"])
            .arg(&scene)
            .arg("-o")
            .arg(&dir),
        &format!("it would replace {}, which this run reads", scene.display()),
    );
    assert_eq!(std::fs::read_to_string(&scene).unwrap(), text);
}

#[test]
fn record_mp4_when_ffmpeg_is_installed() {
    if !tumble::viewer::record::ffmpeg_on_path() {
        return skip_or_fail("ffmpeg is not on PATH");
    }
    let dir = scratch("mp4");
    let out = dir.join("cube.mp4");
    let Some(_) = run_rendering(
        tumble()
            .args([
                "record",
                "cube",
                "--seconds",
                "0.5",
                "--fps",
                "20",
                "--size",
                "128x72",
                "--camera",
                "20,15",
                "-o",
            ])
            .arg(&out),
    ) else {
        return;
    };
    let bytes = std::fs::read(&out).unwrap();
    assert!(
        bytes.len() > 1000 && &bytes[4..8] == b"ftyp",
        "not an MP4 file"
    );
    no_partial_files(&dir);
    if let Ok(probe) = Command::new("ffprobe")
        .args([
            "-v",
            "error",
            "-count_frames",
            "-select_streams",
            "v:0",
            "-show_entries",
            "stream=nb_read_frames,width,height",
            "-of",
            "csv=p=0",
        ])
        .arg(&out)
        .output()
    {
        let text = String::from_utf8_lossy(&probe.stdout);
        assert_eq!(text.trim(), "128,72,10", "ffprobe: {text}");
    }
}

#[test]
fn record_errors_are_clear() {
    let dir = scratch("errors");
    let output = tumble()
        .args(["record", "mixed", "-o"])
        .arg(dir.join("x.avi"))
        .output()
        .unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("use .mp4, .gif, or a directory"));

    let output = tumble()
        .args(["record", "mixed", "-o"])
        .arg(dir.join("x.mp4"))
        .env("PATH", "")
        .output()
        .unwrap();
    assert!(!output.status.success());
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("ffmpeg is not on PATH"),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );

    let output = tumble()
        .args(["record", "mixed", "--camera", "1,2,3,4", "-o"])
        .arg(dir.join("x.gif"))
        .output()
        .unwrap();
    assert!(!output.status.success());

    // A frame rate ffmpeg cannot read (it failed with its own parse error).
    let slow = ["record", "mixed", "--fps", "1e-300", "-o"];
    let words = "--fps 1e-300: an MP4 takes at least 0.01 frames a second";
    fails_saying(tumble().args(slow).arg(dir.join("slow.mp4")), words);

    // A step too short to finish (5e-324 never advanced the time, past Ctrl-C).
    for (dt, seconds, words) in [
        (
            "5e-324",
            "0.2",
            "recording 0.2 s takes inf steps of 5e-324 s, more than 1e8",
        ),
        (
            "1e-12",
            "0.2",
            "recording 0.2 s takes 2.0e11 steps of 1e-12 s",
        ),
        // Neither three hundred digits nor a --dt not given.
        (
            "0.02",
            "1e300",
            "recording 1e300 s takes 5.0e301 steps of 0.02 s",
        ),
    ] {
        let record = ["record", "cube", "--seconds", seconds, "--dt", dt, "-o"];
        fails_saying(tumble().args(record).arg(dir.join("d.gif")), words);
    }
    // Refused without the warning that nothing would move first, the compared world's too.
    for still in [["--dt", "0"], ["--compare", "--dt 0"]] {
        let output = tumble()
            .args(["record", "cube"])
            .args(still)
            .arg("-o")
            .arg(dir.join("d.gif"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{stderr}");
        assert!(
            stderr.contains("the time step must be positive to record, got 0")
                && !stderr.contains("warning"),
            "{still:?}: {stderr}"
        );
    }
    // More frames than a recording makes, refused before it begins.
    let long = ["record", "cube", "--seconds", "2e6", "-o"];
    let words = "recording 2e6 s at 30 fps makes 6.0e7 frames, more than 1e7";
    fails_saying(tumble().args(long).arg(dir.join("long.gif")), words);
}

/// The compared world's constraint budget is warned of as the first world's is.
#[test]
fn record_warns_of_the_compared_worlds_budget() {
    let dir = scratch("compare-budget");
    let Some(output) = run_rendering(
        tumble()
            .args([
                "record",
                "chain-1000",
                "--accurate",
                "--compare",
                "coursework",
            ])
            .args(["--seconds", "0.02", "--size", "64x64", "-o"])
            .arg(dir.join("c.gif")),
    ) else {
        return;
    };
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("warning: --compare: --max-iterations 10000 allows 6 constraint visits"),
        "{stderr}"
    );
}

/// Bodies that blow up while recording are told of, as `run` tells of them (the recording said
/// nothing; they were drawn dark red): under 1e300 units/s² of gravity every body of the mixed
/// scene does, in the first world only.
#[test]
fn record_tells_of_bodies_that_blew_up() {
    let dir = scratch("blew-up");
    let Some(output) = run_rendering(
        tumble()
            .args(["record", "mixed", "--gravity", "0,-1e300,0"])
            .args(["--compare", "--gravity 0,-9.8,0"])
            .args(["--seconds", "0.1", "--size", "64x64", "-o"])
            .arg(dir.join("b.gif")),
    ) else {
        return;
    };
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("warning: 7 bodies of world A blew up"),
        "{stderr}"
    );
    assert!(!stderr.contains("of world B"), "{stderr}");
}

/// `view --screenshot` is checked as the other outputs are, before any window opens: not over
/// the scene it shows (it replaced it with a PNG), and a PNG by name.
#[test]
fn screenshots_are_pngs_and_replace_no_input() {
    let dir = scratch("shot-inputs");
    let scene = dir.join("s-scene.txt");
    let box_mesh = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/box.mesh");
    std::fs::copy(&box_mesh, dir.join("box.mesh")).unwrap();
    std::fs::write(&scene, "1\nbox.mesh 1 0 0 3 0 1 0 0 0\n").unwrap();
    let link = dir.join("shot.png");
    #[cfg(unix)]
    std::os::unix::fs::symlink(&scene, &link).unwrap();
    let before = std::fs::read(&scene).unwrap();
    let mut cases = vec![(dir.join("shot.jpg"), "a screenshot is a PNG; name it .png")];
    if cfg!(unix) {
        cases.push((link.clone(), "which this run reads"));
    }
    for (shot, words) in cases {
        let view = ["view", "--frames", "1", "--screenshot"];
        fails_saying(tumble().args(view).arg(&shot).arg(&scene), words);
    }
    assert_eq!(std::fs::read(&scene).unwrap(), before, "the scene changed");
}

#[test]
fn view_without_display_points_to_record_and_run() {
    // No display at all, and a stale WAYLAND_DISPLAY (winit would panic on it).
    for wayland in [None, Some("wayland-stale-tumble-test")] {
        let mut command = tumble();
        command
            .args(["view", "mixed"])
            .env_remove("DISPLAY")
            .env_remove("WAYLAND_DISPLAY");
        if let Some(w) = wayland {
            command.env("WAYLAND_DISPLAY", w);
        }
        let output = command.output().unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("tumble record") && stderr.contains("tumble run"),
            "{stderr}"
        );
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
    // A DISPLAY that names no X server: said so, not that none is set.
    let output = tumble()
        .args(["view", "mixed"])
        .env("DISPLAY", ":987")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("cannot open a window"), "{stderr}");
    assert!(!stderr.contains("neither DISPLAY"), "{stderr}");
    // `--camera orbit` is the recorder's: said before any window is looked for.
    let view = ["view", "mixed", "--camera", "orbit"];
    fails_saying(tumble().args(view), "turns the camera over a recording");
    // A pitch past the vertical is refused, also before any window is looked for.
    let view = ["view", "mixed", "--camera", "30,95"];
    fails_saying(
        tumble().args(view),
        "the pitch must lie in -90..=90 degrees",
    );
    // A window smaller than the least one opened is said to be raised (it was without a word).
    let output = tumble()
        .args(["view", "mixed", "--size", "100x300"])
        .env("DISPLAY", ":987")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    let raised = "warning: --size 100x300: the window opens at least 320x240, so at 320x300";
    assert!(stderr.contains(raised), "{stderr}");
}

fn on_path(program: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|d| d.join(program).is_file()))
}

/// The real app in a real (virtual) window: 30 frames of the mixed scene, then a screenshot of
/// the window with the panel.
#[test]
fn view_window_under_xvfb() {
    if !on_path("xvfb-run") {
        return skip_or_fail("xvfb-run is not installed");
    }
    let dir = scratch("view");
    let shot = dir.join("view.png");
    let mut command = Command::new("xvfb-run");
    command
        .args([
            "-a",
            "-s",
            "-screen 0 1024x700x24 -nolisten tcp",
            env!("CARGO_BIN_EXE_tumble"),
            "view",
            "mixed",
            "--size",
            "1024x700",
            "--frames",
            "30",
            "--screenshot",
        ])
        .arg(&shot)
        .env("XDG_RUNTIME_DIR", scratch("view-xdg"))
        .env_remove("WAYLAND_DISPLAY");
    let Some(output) = run_rendering(&mut command) else {
        return;
    };
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("frames:"), "{stderr}");
    check_screenshot(&shot);
}

/// Not blank: the 3D view (left) shows many colours besides the background, and the panel
/// (right) has text.
fn check_screenshot(path: &Path) {
    let (w, h, rgba) = read_png(path);
    assert!(w >= 320 && h >= 200, "{w}x{h}");
    let distinct = |x0: u32, x1: u32| {
        let mut set = std::collections::HashSet::new();
        for y in 0..h {
            for x in x0..x1 {
                let i = 4 * (y * w + x) as usize;
                set.insert([rgba[i], rgba[i + 1], rgba[i + 2]]);
            }
        }
        set.len()
    };
    let left = distinct(0, w / 3);
    let right = distinct(w - w / 5, w);
    assert!(left > 50, "3D view nearly blank: {left} colours");
    assert!(right > 10, "panel nearly blank: {right} colours");
}

/// The real window comparing two settings: `tumble view tower --compare accurate` for 200
/// frames (CI runs the same command), whose screenshot shows bodies in both panes.
#[test]
fn view_compare_under_xvfb() {
    if !on_path("xvfb-run") {
        return skip_or_fail("xvfb-run is not installed");
    }
    let dir = scratch("view-compare");
    let shot = dir.join("compare.png");
    let mut command = Command::new("xvfb-run");
    command
        .args([
            "-a",
            "-s",
            "-screen 0 1280x800x24 -nolisten tcp",
            env!("CARGO_BIN_EXE_tumble"),
            "view",
            "tower",
            "--compare",
            "accurate",
            "--frames",
            "200",
            "--screenshot",
        ])
        .arg(&shot)
        .env("XDG_RUNTIME_DIR", scratch("view-compare-xdg"))
        .env_remove("WAYLAND_DISPLAY");
    let Some(output) = run_rendering(&mut command) else {
        return;
    };
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("world A (coursework)"), "{stderr}");
    assert!(stderr.contains("world B (accurate)"), "{stderr}");
    check_compare_screenshot(&shot);
}

/// The pixels of tower's bodies in a lit picture: bright, saturated, and of the chromaticity
/// of one of the bodies' palette colours (not of the ground grid's red and blue axes).
fn body_pixel(p: [u8; 3]) -> bool {
    let c = p.map(|v| v as f64);
    let (max, min) = (c[0].max(c[1]).max(c[2]), c[0].min(c[1]).min(c[2]));
    if max < 90.0 || max - min < 0.3 * max {
        return false;
    }
    let chroma = |c: [f64; 3]| {
        let s = c[0] + c[1] + c[2];
        [c[0] / s, c[1] / s, c[2] / s]
    };
    let distance = |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).abs()).sum::<f64>();
    let here = chroma(c);
    let to = |srgb: [f32; 3]| distance(here, chroma(srgb.map(|v| v as f64)));
    let axes = [palette::GRID_X_AXIS_SRGB, palette::GRID_Z_AXIS_SRGB];
    let nearest_axis = axes.iter().map(|&a| to(a)).fold(f64::INFINITY, f64::min);
    (0..9).any(|i| {
        let d = to(palette::body_srgb(i, false));
        d < 0.06 && d < nearest_axis
    })
}

/// Both panes of a compare screenshot (the 3D view, left of the panel, split in two) show
/// bodies. The view ends where the top row stops being the 3D view's background.
fn check_compare_screenshot(path: &Path) {
    let (w, h, rgba) = read_png(path);
    let pixel = |x: u32, y: u32| {
        let i = 4 * (y * w + x) as usize;
        [rgba[i], rgba[i + 1], rgba[i + 2]]
    };
    let background = palette::srgb_bytes(palette::BACKGROUND_SRGB);
    let view_width = (0..w)
        .rev()
        .find(|&x| pixel(x, 2) == background)
        .expect("the 3D view's background in the top row")
        + 1;
    assert!(view_width > w / 2, "view {view_width} of {w} pixels wide");
    // Below the panes' labels; inside a body (its 3x3 neighbourhood too), which thin lines
    // such as the grid's axes never are.
    let inside = |x: u32, y: u32| (0..9).all(|k| body_pixel(pixel(x + k % 3 - 1, y + k / 3 - 1)));
    let count = |x0: u32, x1: u32| {
        (80..h - 1)
            .flat_map(|y| (x0.max(1)..x1 - 1).map(move |x| (x, y)))
            .filter(|&(x, y)| inside(x, y))
            .count()
    };
    let (left, right) = (count(0, view_width / 2), count(view_width / 2, view_width));
    eprintln!("body pixels: {left} in the left pane, {right} in the right one");
    assert!(
        left > 300 && right > 300,
        "bodies in both panes: {left} and {right} pixels"
    );
}

/// `.ci/run` checks the screenshot of its own `tumble view --compare` run through this test:
/// TUMBLE_CHECK_COMPARE_SCREENSHOT=path cargo test --release --test record_cli check_compare_screenshot_file
#[test]
fn check_compare_screenshot_file() {
    match std::env::var_os("TUMBLE_CHECK_COMPARE_SCREENSHOT") {
        Some(path) => check_compare_screenshot(Path::new(&path)),
        None => eprintln!("TUMBLE_CHECK_COMPARE_SCREENSHOT not set: nothing to check"),
    }
}

/// `.ci/run` checks the screenshot of its own `tumble view` run through this test:
/// TUMBLE_CHECK_SCREENSHOT=path cargo test --release --test record_cli check_screenshot_file
#[test]
fn check_screenshot_file() {
    match std::env::var_os("TUMBLE_CHECK_SCREENSHOT") {
        Some(path) => check_screenshot(Path::new(&path)),
        None => eprintln!("TUMBLE_CHECK_SCREENSHOT not set: nothing to check"),
    }
}

/// Ctrl-C during a recording: the frames rendered so far end up in a valid file under the final
/// name, no partial file is left, and the exit status says SIGINT (130).
#[cfg(unix)]
#[test]
fn record_survives_ctrl_c() {
    let dir = scratch("sigint");
    let out = dir.join("long.gif");
    let mut child = tumble()
        .args([
            "record",
            "mixed",
            "--seconds",
            "600",
            "--size",
            "64x48",
            "-o",
        ])
        .arg(&out)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until some frames went out (the partial file grows), or the process gave up.
    let partial = dir.join(".long.gif.partial");
    let start = std::time::Instant::now();
    while std::fs::metadata(&partial).map_or(0, |m| m.len()) < 2000
        && start.elapsed().as_secs() < 30
    {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    if child.try_wait().unwrap().is_none() {
        // Twice at once, as `timeout -s INT` sends it: the copy does not stop it at once.
        for _ in 0..2 {
            unsafe {
                libc::kill(child.id() as libc::pid_t, libc::SIGINT);
            }
        }
    }
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    if stderr.contains("no usable GPU adapter") {
        assert!(!require_gpu(), "TUMBLE_REQUIRE_GPU=1 but: {stderr}");
        eprintln!("skipping: {stderr}");
        return;
    }
    assert_eq!(output.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted"), "{stderr}");
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::RGBA);
    let mut decoder = options
        .read_info(std::fs::File::open(&out).unwrap())
        .unwrap();
    let mut frames = 0;
    while decoder.read_next_frame().unwrap().is_some() {
        frames += 1;
    }
    assert!(frames >= 1);
    no_partial_files(&dir);
}
