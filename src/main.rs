//! `tumble`: simulate, view, record and benchmark rigid-body scenes.

mod cli;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[global_allocator]
static ALLOCATOR: tumble::bench::alloc::CountingAlloc = tumble::bench::alloc::CountingAlloc;

#[derive(Parser)]
#[command(
    name = "tumble",
    version,
    about = "Rigid-body simulation of convex tet meshes with distance constraints",
    long_about = None,
    after_help = EXAMPLES
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

const EXAMPLES: &str = "Examples:
  tumble                               the viewer on the built-in mixed scene
  tumble view tower --accurate         the viewer on the tower, under tumble's own solver
  tumble run two-chain --steps 1000    headless, with a summary (--json for JSON)
  tumble record tower -o tower.mp4     a video, offscreen
  tumble scenes                        the built-in scenes and the generated families
A command's flags: tumble <COMMAND> --help";

#[derive(Subcommand)]
enum Command {
    /// Open the real-time viewer (the default when no command is given).
    View(cli::view::ViewArgs),
    /// Render a scene offscreen to .mp4, .gif or PNG frames.
    Record(cli::view::RecordArgs),
    /// Simulate headless and print a summary (or JSON).
    Run(cli::run::RunArgs),
    /// Benchmarks: `scale` (run time against scene size), `accuracy` (error against run time),
    /// `soak` (100,000 steps: drift, violation, energy) and `replot` (an earlier run's plots
    /// from its JSON).
    #[command(subcommand)]
    Bench(BenchCommand),
    /// List the built-in scenes and the generated families.
    Scenes,
    /// Regenerate tumble's meshes in assets/ and its generated scene in scenes/ (the folders
    /// are made where missing).
    GenAssets {
        /// Repository root to write into.
        #[arg(long, default_value = ".")]
        root: std::path::PathBuf,
    },
}

/// `tumble` alone: the viewer on the default scene.
#[derive(Parser)]
struct DefaultView {
    #[command(flatten)]
    args: cli::view::ViewArgs,
}

#[derive(Subcommand)]
enum BenchCommand {
    /// ms/step against N for generated scenes: the coursework's loop, both of tumble's solvers
    /// on 1 and all cores, and Rapier in a build with --features compare-rapier.
    Scale(cli::bench::ScaleArgs),
    /// Error against run time per scenario, setting combination and time step (run time, on one
    /// thread for every engine, as Rapier's default build runs: the fastest of a job's runs:
    /// three, and more until its steps took 0.1 s, at most 15, interleaved with the other
    /// combinations' at the same scenario and dt).
    Accuracy(cli::bench::AccuracyArgs),
    /// The tower, a stack of ten built at rest and the two chains for 100,000 steps (--steps):
    /// drift, violation, energy. A quick look: --steps 5000.
    Soak(cli::bench::SoakArgs),
    /// Draws an earlier run's plots again from its accuracy.json and scale.json, beside them
    /// (the plots' drawing may change without running the benches again).
    Replot(cli::bench::ReplotArgs),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(error) => {
            let hint = misplaced_argument_hint(&error);
            let code = error.exit_code();
            let _ = error.print();
            if let Some(hint) = hint {
                eprintln!("\n{hint}");
            }
            return ExitCode::from(code as u8);
        }
    };
    // Text commands piped into `head` should end quietly like other Unix tools instead of
    // panicking on the closed pipe. Not for view/record: a dying ffmpeg must be an error the
    // recorder handles (finishing its file), not a silent kill.
    #[cfg(unix)]
    if !matches!(
        cli.command,
        None | Some(Command::View(_)) | Some(Command::Record(_))
    ) {
        // SAFETY: restoring the default disposition of SIGPIPE before any thread starts.
        unsafe {
            libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        }
    }
    let result = match cli.command {
        Some(Command::Run(args)) => cli::run::run(&args),
        Some(Command::Bench(BenchCommand::Scale(args))) => cli::bench::scale(&args),
        Some(Command::Bench(BenchCommand::Accuracy(args))) => cli::bench::accuracy(&args),
        Some(Command::Bench(BenchCommand::Soak(args))) => cli::bench::soak(&args),
        Some(Command::Bench(BenchCommand::Replot(args))) => cli::bench::replot(&args),
        Some(Command::Scenes) => {
            println!("built in (compiled into the binary):");
            for (name, file) in tumble::BUILTIN_SCENES {
                let what = tumble::scene::builtin_description(file);
                println!("{name:16} {what}");
            }
            println!(
                "\ngenerated (N bodies, at most {}; sparse-N at most {}):",
                tumble::scene::MAX_GENERATED,
                tumble::scene::MAX_SPARSE
            );
            for (name, what) in tumble::scene::generate::FAMILIES {
                println!("{name:16} {what}");
            }
            Ok(())
        }
        Some(Command::GenAssets { root }) => gen_assets(&root),
        Some(Command::View(args)) => cli::view::view(&args),
        Some(Command::Record(args)) => cli::view::record(&args),
        None => cli::view::view(&DefaultView::parse_from(["tumble"]).args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// What to type instead, where the command line begins with a scene (`tumble tower`) or with
/// settings flags that `tumble view` takes (`tumble --accurate`), which only the commands take:
/// clap's own tip for `tumble scenes/tower-scene.txt` pointed at `tumble scenes`.
fn misplaced_argument_hint(error: &clap::Error) -> Option<String> {
    use clap::error::ErrorKind;
    // Not `args`: an argument that is not UTF-8 must reach clap's message, not a panic here.
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    let first = args.get(1)?.to_str()?;
    match error.kind() {
        ErrorKind::InvalidSubcommand if tumble::scene::names_a_scene(first) => Some(format!(
            "'{first}' is a scene: `tumble view {first}` shows it, `tumble run {first}` runs it headless"
        )),
        ErrorKind::UnknownArgument if DefaultView::try_parse_from(&args).is_ok() => Some(format!(
            "settings flags follow a command: `tumble view {first} ...` (`tumble view --help` lists them)"
        )),
        _ => None,
    }
}

fn gen_assets(root: &std::path::Path) -> anyhow::Result<()> {
    use std::io::Write;
    for (path, text) in tumble::scene::assets::generated_files() {
        let full = root.join(&path);
        if let Some(folder) = full.parent() {
            std::fs::create_dir_all(folder)
                .map_err(|e| anyhow::anyhow!("cannot make {}: {e}", folder.display()))?;
        }
        // Written whole or not at all, as every other output.
        tumble::io::write_file_atomically(&full, |w| w.write_all(text.as_bytes()))?;
        println!("wrote {}", full.display());
    }
    Ok(())
}
