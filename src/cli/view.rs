//! `tumble view` and `tumble record`. The arguments exist in every build; without the `viewer`
//! feature the commands explain how to get it.

use super::{SceneArgs, SettingsArgs};
use clap::Args;
use std::path::PathBuf;

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

#[derive(Debug, Args)]
pub struct ViewArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Window size in pixels.
    #[arg(long, value_name = "WxH", default_value = "1280x800", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Quit after this many frames (smoke tests, frame-time measurements).
    #[arg(long, value_name = "N")]
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
    /// Camera: YAW,PITCH[,DISTANCE[,X,Y,Z]] in degrees and scene units (default: framed scene).
    #[arg(long, value_name = "SPEC", allow_hyphen_values = true)]
    pub camera: Option<String>,
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
    #[arg(long, value_name = "T", default_value_t = 5.0)]
    pub seconds: f64,
    /// Frames per second of simulated time (the simulation steps at its own fixed dt).
    #[arg(long, value_name = "F", default_value_t = 30.0)]
    pub fps: f64,
    /// Frame size [default: 1280x720, 640x360 for .gif].
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Camera: YAW,PITCH[,DISTANCE[,X,Y,Z]] in degrees and scene units (default: the scene
    /// framed from yaw 35, pitch 25).
    #[arg(long, value_name = "SPEC", allow_hyphen_values = true)]
    pub camera: Option<String>,
    /// Draw contact points and normals.
    #[arg(long)]
    pub contacts: bool,
    /// No ground grid.
    #[arg(long)]
    pub no_grid: bool,
    /// No constraint segments.
    #[arg(long)]
    pub no_constraints: bool,
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

#[cfg(feature = "viewer")]
pub fn view(args: &ViewArgs) -> anyhow::Result<()> {
    let world = args.scene.load(args.settings.settings()?)?;
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
    };
    super::interrupt::install();
    tumble::viewer::run_viewer(world, options)
}

#[cfg(feature = "viewer")]
pub fn record(args: &RecordArgs) -> anyhow::Result<()> {
    use tumble::viewer::{DrawOptions, OutputKind, RecordOptions};
    let kind = OutputKind::of(&args.output)?;
    let (width, height) = args.size.unwrap_or(if kind == OutputKind::Gif {
        (640, 360)
    } else {
        (1280, 720)
    });
    let mut world = args.scene.load(args.settings.settings()?)?;
    let options = RecordOptions {
        output: args.output.clone(),
        seconds: args.seconds,
        fps: args.fps,
        width,
        height,
        camera: args.camera.clone(),
        draw: DrawOptions {
            grid: !args.no_grid,
            constraints: !args.no_constraints,
            contacts: args.contacts,
            ..DrawOptions::default()
        },
    };
    super::interrupt::install();
    let bar = super::progress_bar(
        ((args.seconds * args.fps).round() as u64).max(1),
        "recording",
    );
    let report = tumble::viewer::record(
        &mut world,
        &options,
        &mut |done, _| bar.set_position(done),
        &super::interrupt::interrupted,
    )?;
    bar.finish_and_clear();
    let frames = report.frames.max(1) as f64;
    println!(
        "wrote {} frames ({width}x{height}, {:.2} s simulated in {} steps) to {} in {:.2} s: {:.1} ms/frame \
         (simulate {:.1}, render+readback {:.1}, waiting for the encoder {:.1}; the encoder thread worked {:.1} ms/frame alongside) on {}",
        report.frames,
        report.sim_time,
        report.steps,
        args.output.display(),
        report.wall_s,
        1e3 * report.wall_s / frames,
        1e3 * report.simulate_s / frames,
        1e3 * report.render_s / frames,
        1e3 * report.encode_wait_s / frames,
        1e3 * report.encode_s / frames,
        report.adapter,
    );
    if report.interrupted {
        eprintln!(
            "interrupted (Ctrl-C): {} holds the {} frames rendered before it",
            args.output.display(),
            report.frames
        );
        // The shell's convention for "stopped by SIGINT".
        std::process::exit(130);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::parse_size;

    #[test]
    fn sizes() {
        assert_eq!(parse_size("640x360"), Ok((640, 360)));
        assert!(parse_size("640").is_err());
        assert!(parse_size("0x10").is_err());
    }
}
