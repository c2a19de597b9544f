//! `tumble view` and `tumble record`. The arguments exist in every build; without the `viewer`
//! feature the commands explain how to get it.

use super::{SceneArgs, SettingsArgs};
use clap::{Args, Parser};
use std::path::PathBuf;
#[cfg(feature = "viewer")]
use tumble::{Settings, io::counted};

/// The settings of a compared world: `--compare` takes a preset (`accurate`, `coursework`), the
/// settings flags of `tumble run`, or a preset followed by flags.
#[derive(Debug, Parser)]
#[command(no_binary_name = true)]
struct CompareFlags {
    #[command(flatten)]
    settings: SettingsArgs,
}

/// Parses a `--compare` spec (also typed into the viewer's panel) into settings, printing the
/// warnings they earn.
#[cfg(feature = "viewer")]
pub fn parse_compare(spec: &str) -> Result<Settings, String> {
    let (settings, notes) = compare_checked(spec)?;
    for note in notes {
        eprintln!("warning: --compare: {note}");
    }
    Ok(settings)
}

/// [`parse_compare`] without printing: the settings and their warnings.
#[cfg(feature = "viewer")]
fn compare_checked(spec: &str) -> Result<(Settings, Vec<String>), String> {
    let mut words: Vec<&str> = spec.split_whitespace().collect();
    let preset = match words.first() {
        Some(&"accurate") => Some(true),
        Some(&"coursework") => Some(false),
        _ => None,
    };
    if preset.is_some() {
        words.remove(0);
    } else if words.is_empty() {
        return Err("expected a preset (accurate, coursework) or settings flags".into());
    }
    let mut flags = CompareFlags::try_parse_from(&words).map_err(|e| {
        let text = e.to_string();
        let first = text.lines().next().unwrap_or(&text);
        let first = first.trim_start_matches("error: ");
        // A word that is neither a preset nor a flag ("--compare bogus").
        match preset {
            None if !spec.trim_start().starts_with('-') => {
                format!("{first}: expected a preset (accurate, coursework) or settings flags")
            }
            _ => first.to_string(),
        }
    })?;
    if let Some(accurate) = preset {
        flags.settings.accurate |= accurate;
    }
    flags.settings.checked().map_err(|e| e.to_string())
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}': expected WIDTHxHEIGHT, e.g. 1280x720"))?;
    let w: u32 = w.trim().parse().map_err(|e| format!("'{s}': width: {e}"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|e| format!("'{s}': height: {e}"))?;
    if !(1..=16384).contains(&w) || !(1..=16384).contains(&h) {
        return Err(format!("'{s}': width and height must lie in 1..=16384"));
    }
    Ok((w, h))
}

/// A second world beside the first (`tumble view` and `tumble record`).
#[derive(Debug, Args)]
pub struct CompareArgs {
    /// Compare with other settings: a second world of the scene stepped in lockstep and drawn
    /// beside the first, each labelled. A preset (`accurate`, `coursework`) and/or settings
    /// flags, e.g. `--compare accurate` or `--compare "--solver coursework --dt 0.01"`.
    #[arg(long, value_name = "PRESET_OR_FLAGS", allow_hyphen_values = true)]
    pub compare: Option<String>,
    /// With --compare: draw the second world as a translucent ghost over the first instead of
    /// beside it.
    #[arg(long, requires = "compare")]
    pub ghost: bool,
}

#[derive(Debug, Args)]
pub struct ViewArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Window size in pixels (at least 320x240; a window system may open a larger window than
    /// asked, and the first line printed gives the size it opened).
    #[arg(long, value_name = "WxH", default_value = "1280x800", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Quit after this many frames (smoke tests, frame-time measurements).
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = super::whole_number::<u64>)]
    pub frames: Option<u64>,
    /// Write a PNG of the whole window after the last of --frames.
    #[arg(long, value_name = "FILE.png", requires = "frames")]
    pub screenshot: Option<PathBuf>,
    /// Start paused.
    #[arg(long)]
    pub paused: bool,
    /// Render as fast as possible instead of waiting for the display's refresh.
    #[arg(long)]
    pub no_vsync: bool,
    /// Start with shadows off (a panel toggle).
    #[arg(long)]
    pub no_shadows: bool,
    /// Start with fixed bodies hidden, to see into a pile's bin (a panel toggle).
    #[arg(long)]
    pub no_fixed: bool,
    /// Camera: YAW,PITCH[,DISTANCE[,X,Y,Z]] in degrees (pitch from -90 to 90, steeper than 88.8
    /// taken as 88.8) and scene units (default: framed scene).
    #[arg(long, value_name = "SPEC", allow_hyphen_values = true)]
    pub camera: Option<String>,
    #[command(flatten)]
    pub comparison: CompareArgs,
    #[command(flatten)]
    pub settings: SettingsArgs,
}

#[derive(Debug, Args)]
pub struct RecordArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Output: FILE.mp4 (needs ffmpeg on PATH), FILE.gif, or a directory for numbered PNGs.
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// Simulated seconds to record.
    #[arg(
        long,
        value_name = "T",
        default_value_t = 5.0,
        allow_negative_numbers = true
    )]
    pub seconds: f64,
    /// Frames per second of simulated time (the simulation steps at its own fixed dt).
    #[arg(
        long,
        value_name = "F",
        default_value_t = 30.0,
        allow_negative_numbers = true
    )]
    pub fps: f64,
    /// Frame size [default: 1280x720, 640x360 for .gif].
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Camera: YAW,PITCH[,DISTANCE[,X,Y,Z]] in degrees (pitch from -90 to 90, steeper than 88.8
    /// taken as 88.8) and scene units (default: the scene framed from yaw 35, pitch 25), or
    /// `orbit`: the framed scene turning once around its vertical axis over the recording.
    #[arg(long, value_name = "SPEC", allow_hyphen_values = true)]
    pub camera: Option<String>,
    #[command(flatten)]
    pub comparison: CompareArgs,

    /// Draw contact points and normals.
    #[arg(long)]
    pub contacts: bool,
    /// No ground: its plane and grid, and the shadows cast on it.
    #[arg(long)]
    pub no_grid: bool,
    /// No constraint segments.
    #[arg(long)]
    pub no_constraints: bool,
    /// No shadows.
    #[arg(long)]
    pub no_shadows: bool,
    /// No fixed bodies (a pile's walls), to see into the bin.
    #[arg(long)]
    pub no_fixed: bool,
    #[command(flatten)]
    pub settings: SettingsArgs,
}

#[cfg(not(feature = "viewer"))]
const NO_VIEWER: &str = "this tumble was built without the viewer (cargo feature `viewer` is off): rebuild with default features, or use `tumble run SCENE` to simulate headless";

#[cfg(not(feature = "viewer"))]
pub fn view(_args: &ViewArgs) -> anyhow::Result<()> {
    anyhow::bail!(NO_VIEWER)
}

#[cfg(not(feature = "viewer"))]
pub fn record(_args: &RecordArgs) -> anyhow::Result<()> {
    anyhow::bail!(NO_VIEWER)
}

/// The layout of compared worlds the flags ask for.
#[cfg(feature = "viewer")]
fn layout(ghost: bool) -> tumble::viewer::Layout {
    if ghost {
        tumble::viewer::Layout::Ghost
    } else {
        tumble::viewer::Layout::SideBySide
    }
}

/// The compared world's constraint budget, as the first world's is warned of when the scene
/// loads ([`super::short_budget`]): `--compare coursework` on chain-10000 visited one
/// constraint a step in silence.
#[cfg(feature = "viewer")]
fn warn_of_compared_budget(compare: Option<&Settings>, world: &tumble::World) {
    let note = compare.and_then(|s| super::short_budget(s, world.constraints.len()));
    if let Some(note) = note {
        eprintln!("warning: --compare: {note}");
    }
}

/// The settings of `--compare` and their warnings, not printed: `view` leaves them to the app
/// (which parses the spec again: printed here too, each came twice), `record` to after its own
/// checks (printed first, `--dt 0`'s warning came before the refusal of it).
#[cfg(feature = "viewer")]
fn compare_settings(spec: Option<&str>) -> anyhow::Result<Option<(Settings, Vec<String>)>> {
    spec.map(|spec| compare_checked(spec).map_err(|e| anyhow::anyhow!("--compare '{spec}': {e}")))
        .transpose()
}

#[cfg(feature = "viewer")]
pub fn view(args: &ViewArgs) -> anyhow::Result<()> {
    let compare = compare_settings(args.comparison.compare.as_deref())?.map(|(s, _)| s);
    // Checked before the window opens (the view applies it once the scene is framed).
    if let Some(spec) = &args.camera {
        anyhow::ensure!(
            spec.trim() != "orbit",
            "--camera orbit turns the camera over a recording (`tumble record`); the window's camera turns with the mouse"
        );
        tumble::viewer::OrbitCamera::default()
            .apply_spec(spec)
            .map_err(anyhow::Error::msg)?;
    }
    let (min_width, min_height) = tumble::viewer::MIN_WINDOW_SIZE;
    let (width, height) = args.size;
    if width < min_width || height < min_height {
        eprintln!(
            "warning: --size {width}x{height}: the window opens at least {min_width}x{min_height}, so at {}x{}",
            width.max(min_width),
            height.max(min_height)
        );
    }
    let world = args.scene.load(args.settings.settings()?)?;
    warn_of_compared_budget(compare.as_ref(), &world);
    // Checked as the other outputs are: `--screenshot scene.txt` replaced the scene with a PNG.
    if let Some(shot) = &args.screenshot {
        let png = shot
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"));
        anyhow::ensure!(
            png,
            "--screenshot {}: a screenshot is a PNG; name it .png",
            shot.display()
        );
        tumble::io::check_output(shot, &world.inputs)?;
    }
    let options = tumble::viewer::ViewOptions {
        scene: args.scene.scene.clone(),
        width: args.size.0,
        height: args.size.1,
        frames: args.frames,
        screenshot: args.screenshot.clone(),
        vsync: !args.no_vsync,
        paused: args.paused,
        camera: args.camera.clone(),
        interrupted: super::interrupt::interrupted,
        constraints: super::constraints_choice(args.scene.constraints.as_deref()),
        compare: args.comparison.compare.clone(),
        layout: layout(args.comparison.ghost),
        shadows: !args.no_shadows,
        fixed_bodies: !args.no_fixed,
        parse_settings: parse_compare,
    };
    super::interrupt::install(false);
    tumble::viewer::run_viewer(world, options)
}

/// Tells of the bodies of each world (`frozen`, the first world's then the compared one's)
/// that blew up while recording: `run` names each as it blows up, a recording said nothing (its
/// frozen bodies are drawn dark red).
#[cfg(feature = "viewer")]
fn warn_of_frozen_bodies(frozen: &[usize]) {
    for (k, &bodies) in frozen.iter().enumerate().filter(|(_, n)| **n > 0) {
        let world = match frozen.len() {
            1 => String::new(),
            _ => format!(" of world {}", tumble::viewer::compare::lane_name(k)),
        };
        eprintln!(
            "warning: {}{world} blew up (a non-finite value or an absurd speed) and {} frozen \
             at the last good pose, drawn dark red; `tumble run` with the same flags names them",
            tumble::io::counted(bodies as u64, "body", "bodies"),
            if bodies == 1 { "was" } else { "were" },
        );
    }
}

/// Warnings on frames a recording will show otherwise than a user may expect.
#[cfg(feature = "viewer")]
fn warn_of_frames(kind: tumble::viewer::OutputKind, fps: f64, (dt, compared): (f64, Option<f64>)) {
    // The coarsest world's step: the first world's, or the compared one's.
    let (name, coarsest) = match compared {
        Some(compared) if compared > dt => ("--compare's --dt", compared),
        _ => ("--dt", dt),
    };
    let repeated = tumble::viewer::record::repeated_frame_share(fps, coarsest);
    // From half a percent, which the message's whole percent can show.
    if repeated >= 0.005 {
        // Rounded down, so that the step suggested is short enough.
        let enough = (1e4 / fps).floor() / 1e4;
        eprintln!(
            "warning: --fps {} is more frames than steps a simulated second ({name} {}): \
             {:.0} % of the frames repeat the one before; a --dt of at most {enough:.4} gives \
             each frame a step of its own",
            tumble::io::echoed(fps),
            tumble::io::echoed(coarsest),
            100.0 * repeated,
        );
    }
    // GIF delays are whole centiseconds, and players show those under 2 at 10 (browsers, most
    // viewers): above 50 fps the file plays slower than it was recorded.
    if kind == tumble::viewer::OutputKind::Gif && fps > 50.0 {
        eprintln!(
            "warning: --fps {fps}: most players show GIF frames shorter than 1/50 s at 1/10 s"
        );
    }
}

#[cfg(feature = "viewer")]
pub fn record(args: &RecordArgs) -> anyhow::Result<()> {
    use tumble::viewer::{DrawOptions, OutputKind, RecordOptions};
    let kind = OutputKind::of(&args.output)?;
    let (settings, notes) = args.settings.checked()?;
    let (compare, compare_notes) = match compare_settings(args.comparison.compare.as_deref())? {
        Some((settings, notes)) => (Some(settings), notes),
        None => (None, Vec::new()),
    };
    // Refused before the settings' warnings: `--dt 0` warned that nothing would move, then was
    // refused.
    let dts = (settings.time_step, compare.as_ref().map(|s| s.time_step));
    tumble::viewer::record::check_rates(args.seconds, args.fps, dts)?;
    for note in notes {
        eprintln!("warning: {note}");
    }
    for note in compare_notes {
        eprintln!("warning: --compare: {note}");
    }
    warn_of_frames(kind, args.fps, dts);
    let (width, height) = args.size.unwrap_or(if kind == OutputKind::Gif {
        (640, 360)
    } else {
        (1280, 720)
    });
    let world = args.scene.load(settings)?;
    warn_of_compared_budget(compare.as_ref(), &world);
    let output = tumble::viewer::record::check_recording_output(&args.output, &world.inputs)?;
    let options = RecordOptions {
        output,
        seconds: args.seconds,
        fps: args.fps,
        width,
        height,
        camera: args.camera.clone(),
        draw: DrawOptions {
            grid: !args.no_grid,
            constraints: !args.no_constraints,
            contacts: args.contacts,
            shadows: !args.no_shadows,
            fixed_bodies: !args.no_fixed,
            layout: layout(args.comparison.ghost),
            ..DrawOptions::default()
        },
        compare,
    };
    super::interrupt::install(true);
    let bar = super::progress_bar(
        ((args.seconds * args.fps).round() as u64).max(1),
        "recording",
    );
    let report = tumble::viewer::record(
        world,
        &options,
        &mut |done, _| bar.set_position(done),
        &super::interrupt::interrupted,
    )?;
    bar.finish_and_clear();
    if report.interrupted && report.frames == 0 {
        eprintln!("interrupted before the first frame: no frame written");
        std::process::exit(super::interrupt::exit_status());
    }
    let frames = report.frames.max(1) as f64;
    println!(
        "wrote {} ({width}x{height}, {:.2} s at {} fps, the last frame at simulated time {:.2} s \
         after {}) to {} in {:.2} s: {:.1} ms/frame (simulate {:.1}, render+readback {:.1}, \
         waiting for the encoder {:.1}; the encoder thread worked {:.1} ms/frame alongside) on {}",
        counted(report.frames, "frame", "frames"),
        report.frames as f64 / args.fps,
        args.fps,
        report.sim_time,
        counted(report.steps, "step", "steps"),
        args.output.display(),
        report.wall_s,
        1e3 * report.wall_s / frames,
        1e3 * report.simulate_s / frames,
        1e3 * report.render_s / frames,
        1e3 * report.encode_wait_s / frames,
        1e3 * report.encode_s / frames,
        report.adapter,
    );
    warn_of_frozen_bodies(&report.frozen);
    if report.interrupted {
        eprintln!(
            "interrupted: {} holds the {} rendered before it",
            args.output.display(),
            counted(report.frames, "frame", "frames")
        );
        std::process::exit(super::interrupt::exit_status());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::parse_size;
    use tumble::Settings;

    #[test]
    fn compare_specs() {
        use super::parse_compare;
        use tumble::sim::settings::Solver;
        assert_eq!(parse_compare("accurate"), Ok(Settings::accurate()));
        assert_eq!(parse_compare("coursework"), Ok(Settings::default()));
        let s = parse_compare("--solver coursework --dt 0.01").unwrap();
        assert_eq!((s.solver, s.time_step), (Solver::Coursework, 0.01));
        let s = parse_compare("accurate --substeps 8").unwrap();
        assert_eq!((s.solver, s.substeps), (Solver::SoftStep, 8));
        assert!(parse_compare("--dt").is_err());
        assert!(parse_compare("--bogus 1").is_err());
        let unknown = parse_compare("bogus").unwrap_err();
        assert!(
            unknown.contains("expected a preset (accurate, coursework)"),
            "{unknown}"
        );
        assert!(parse_compare("").is_err());
    }

    #[test]
    fn sizes() {
        assert_eq!(parse_size("640x360"), Ok((640, 360)));
        assert!(parse_size("640").is_err());
        assert!(parse_size("0x10").is_err());
    }
}
