//! The `tumble` command line: argument types shared by the subcommands, and the subcommands.

pub mod bench;
pub mod interrupt;
pub mod run;
pub mod view;

use clap::Args;
use glam::DVec3;
use std::path::PathBuf;
use tumble::sim::settings::{BroadPhase, ConstraintSchedule, RotationIntegrator, Solver};
use tumble::{ConstraintsChoice, Settings};

/// Largest `--max-iterations`: a billion, where one step of a few constraints that cannot all
/// hold takes some seconds.
const MAX_ITERATIONS: usize = 1_000_000_000;

/// Simulation settings common to `run`, `view`, `record` and the benchmarks. Defaults reproduce
/// the coursework exactly; every improvement is opt-in.
#[derive(Debug, Clone, Args)]
pub struct SettingsArgs {
    /// Solver: the coursework's method or tumble's soft step [default: coursework; soft-step
    /// with --accurate].
    #[arg(long, value_enum)]
    pub solver: Option<Solver>,
    /// Time step in seconds [default: 0.02].
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub dt: Option<f64>,
    /// Coefficient of restitution (0 = plastic, 1 = elastic) [default: 1].
    #[arg(long, value_name = "E", allow_negative_numbers = true)]
    pub restitution: Option<f64>,
    /// Coulomb friction coefficient (soft-step solver; the coursework has no friction)
    /// [default: 0.5].
    #[arg(long, value_name = "MU", allow_negative_numbers = true)]
    pub friction: Option<f64>,
    /// The coursework's maxIterations: the constraint loop stops once visits x M reach K (at most
    /// 1000000000), M being the number of inequality constraints (two per constraint record), so
    /// a step makes at most ceil(K / M) constraint visits (coursework solver) [default: 10000].
    #[arg(long, value_name = "K", allow_negative_numbers = true, value_parser = whole_number::<usize>)]
    pub max_iterations: Option<usize>,
    /// Gravity, X,Y,Z in units/s^2 (the ground is y = 0) [default: 0,-9.8,0].
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = parse_vector)]
    pub gravity: Option<DVec3>,
    /// Constraint tolerance (coursework solver) [default: 0.001].
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    pub tolerance: Option<f64>,
    /// Start from the best setting combination found by `tumble bench accuracy`.
    #[arg(long)]
    pub accurate: bool,
    /// No impulse for contacts whose bodies already separate (coursework solver).
    #[arg(long)]
    pub skip_separating_contacts: bool,
    /// Contacts closing slower than this (units/s) bounce with e = 0 [default: 0; 0.5 with
    /// --accurate].
    #[arg(long, value_name = "SPEED", allow_negative_numbers = true)]
    pub restitution_threshold: Option<f64>,
    /// Never put resting islands to sleep (soft-step solver).
    #[arg(long)]
    pub no_sleep: bool,
    /// Contacts act on the whole contact patch instead of at one deepest point: at the patch's
    /// point nearest under the centre of mass of the body resting there, on the ground or on
    /// another body (coursework solver).
    #[arg(long)]
    pub contact_patches: bool,
    /// Substeps per step (the soft step takes more in a step that begins with contacts touching
    /// where N would make them longer than 1/200 s, and in a scene with distance constraints
    /// where they would be longer than 1/80 s) [default: 1; 4 with --accurate].
    #[arg(long, value_name = "N")]
    pub substeps: Option<u32>,
    /// Step length from which a step takes all its substeps; a shorter one takes
    /// proportionally fewer, down to half, so substeps stay about as long as at this length
    /// (soft step; 0: always all) [default: 0; 0.01 with --accurate].
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub full_substeps_from: Option<f64>,
    /// Rotation integrator [default: coursework; angular-momentum with --accurate].
    #[arg(long, value_enum)]
    pub rotation_integrator: Option<RotationIntegrator>,
    /// Broad phase of the coursework solver (both give identical results; the soft step
    /// always uses the grid) [default: grid].
    #[arg(long, value_enum)]
    pub broad_phase: Option<BroadPhase>,
    /// Constraint schedule (coursework solver) [default: sweep].
    #[arg(long, value_enum)]
    pub constraint_schedule: Option<ConstraintSchedule>,
}

/// `X,Y,Z` as a vector of three finite numbers.
fn parse_vector(text: &str) -> Result<DVec3, String> {
    let numbers: Result<Vec<f64>, _> = text.split(',').map(|v| v.trim().parse::<f64>()).collect();
    match numbers.as_deref() {
        Ok(&[x, y, z]) if [x, y, z].iter().all(|v| v.is_finite()) => Ok(DVec3::new(x, y, z)),
        _ => Err(format!(
            "expected three finite numbers X,Y,Z (e.g. 0,-9.8,0), got '{text}'"
        )),
    }
}

/// Longest time step taken without a warning. The mixed scene's deepest penetration after 4 s
/// with the coursework's solver: 0.59 units at dt 0.02, 2.7 at 0.1, 4.8 at 0.2, 28 at 0.5; at
/// 1e9 s the soft step's bodies blow up and are frozen.
const LONGEST_SENSIBLE_STEP: f64 = 0.1;

/// Shortest time step taken without a warning: below it a simulated second takes over ten
/// million steps, and at 1e-300 s no body moves at all (its moves are below its position's
/// rounding).
const SHORTEST_SENSIBLE_STEP: f64 = 1e-7;

impl SettingsArgs {
    /// The settings the flags ask for, their warnings printed on standard error.
    pub fn settings(&self) -> anyhow::Result<Settings> {
        let (settings, notes) = self.checked()?;
        for note in notes {
            eprintln!("warning: {note}");
        }
        Ok(settings)
    }

    /// The settings the flags ask for, with the warnings they earn (for a command that may
    /// refuse the settings before they are worth a warning).
    pub fn checked(&self) -> anyhow::Result<(Settings, Vec<String>)> {
        let mut s = if self.accurate {
            Settings::accurate()
        } else {
            Settings::default()
        };
        if let Some(v) = self.dt {
            anyhow::ensure!(
                v.is_finite() && v >= 0.0,
                "--dt must be a non-negative number of seconds, got {}",
                tumble::io::echoed(v)
            );
            s.time_step = v;
        }
        if let Some(v) = self.solver {
            s.solver = v;
        }
        if let Some(v) = self.friction {
            anyhow::ensure!(
                v.is_finite() && v >= 0.0,
                "--friction must be a non-negative number, got {}",
                tumble::io::echoed(v)
            );
            s.friction = v;
        }
        if let Some(v) = self.restitution {
            anyhow::ensure!(
                (0.0..=1.0).contains(&v),
                "--restitution must lie in [0, 1], got {}",
                tumble::io::echoed(v)
            );
            s.restitution = v;
        }
        if let Some(v) = self.max_iterations {
            // 2^64 - 1 ran one step of three rods that cannot all hold for ever; a billion is
            // the README's "unlimited" budget (some seconds a step).
            anyhow::ensure!(
                v <= MAX_ITERATIONS,
                "--max-iterations must be at most {MAX_ITERATIONS}, got {v}"
            );
            s.max_iterations = v;
        }
        if let Some(v) = self.gravity {
            s.gravity = v;
        }
        if let Some(v) = self.tolerance {
            anyhow::ensure!(
                v.is_finite() && v >= 0.0,
                "--tolerance must be non-negative, got {}",
                tumble::io::echoed(v)
            );
            s.tolerance = v;
        }
        s.skip_separating_contacts |= self.skip_separating_contacts;
        s.contact_patches |= self.contact_patches;
        s.sleep &= !self.no_sleep;
        if let Some(v) = self.restitution_threshold {
            anyhow::ensure!(
                v.is_finite() && v >= 0.0,
                "--restitution-threshold must be non-negative, got {}",
                tumble::io::echoed(v)
            );
            s.restitution_threshold = v;
        }
        if let Some(v) = self.substeps {
            anyhow::ensure!(
                (1..=1000).contains(&v),
                "--substeps must lie in 1..=1000, got {v}"
            );
            s.substeps = v;
        }
        if let Some(v) = self.full_substeps_from {
            anyhow::ensure!(
                v.is_finite() && v >= 0.0,
                "--full-substeps-from must be a non-negative number of seconds, got {}",
                tumble::io::echoed(v)
            );
            s.full_substeps_from = v;
        }
        if let Some(v) = self.rotation_integrator {
            s.rotation_integrator = v;
        }
        if let Some(v) = self.broad_phase {
            s.broad_phase = v;
        }
        if let Some(v) = self.constraint_schedule {
            s.constraint_schedule = v;
        }
        let notes = self.ineffective(&s);
        Ok((s, notes))
    }

    /// Settings given that will not do what they say with the rest: a value accepted without a
    /// word would let a user believe it acted.
    fn ineffective(&self, s: &Settings) -> Vec<String> {
        let mut notes = Vec::new();
        if s.time_step == 0.0 {
            notes.push("--dt 0: time does not advance, nothing will move".to_string());
        }
        if s.time_step > 0.0 && s.time_step < SHORTEST_SENSIBLE_STEP {
            notes.push(format!(
                "--dt {:e}: under {SHORTEST_SENSIBLE_STEP:e} s a simulated second takes over ten million steps, and far shorter steps (1e-300) move no body at all (the default is 0.02)",
                s.time_step
            ));
        }
        if s.time_step > LONGEST_SENSIBLE_STEP {
            notes.push(format!(
                "--dt {}: steps over {LONGEST_SENSIBLE_STEP} s let bodies sink deep into each other (the default is 0.02)",
                if s.time_step >= 1e15 {
                    format!("{:e}", s.time_step)
                } else {
                    s.time_step.to_string()
                }
            ));
        }
        let (other, given, hint) = match s.solver {
            Solver::Coursework => (
                "the soft-step solver",
                vec![
                    (self.friction.is_some(), "--friction"),
                    (self.no_sleep, "--no-sleep"),
                    (self.full_substeps_from.is_some(), "--full-substeps-from"),
                ],
                "add --accurate or --solver soft-step",
            ),
            Solver::SoftStep => (
                "the coursework's solver",
                vec![
                    (self.max_iterations.is_some(), "--max-iterations"),
                    (self.tolerance.is_some(), "--tolerance"),
                    (self.constraint_schedule.is_some(), "--constraint-schedule"),
                    (self.skip_separating_contacts, "--skip-separating-contacts"),
                    (self.contact_patches, "--contact-patches"),
                    (self.broad_phase.is_some(), "--broad-phase"),
                ],
                "the soft step solves contacts and constraints its own way; add --solver coursework",
            ),
        };
        for (_, flag) in given.into_iter().filter(|(given, _)| *given) {
            notes.push(format!(
                "{flag} acts on {other} only and changes nothing here ({hint})"
            ));
        }
        notes
    }
}

/// A scene and its constraints.
#[derive(Debug, Clone, Args)]
pub struct SceneArgs {
    /// Scene file, or a built-in scene (mixed, tower, two-chain, cube, stress, two-cylinders),
    /// or a generated one (sparse-N, scatter-N, pile-N, chain-N, rope-N, stack-N); `tumble
    /// scenes` says what each is.
    #[arg(default_value = tumble::DEFAULT_SCENE)]
    pub scene: String,
    /// Constraint file, or `none`. Default: X-constraints.txt beside X-scene.txt, if present.
    #[arg(long, value_name = "FILE|none")]
    pub constraints: Option<String>,
}

/// `x` with `places` decimal places, or in scientific notation from a billion up (`--dt 1e300`
/// printed three hundred digits).
pub fn decimals(x: f64, places: usize) -> String {
    if x.abs() >= 1e9 {
        format!("{x:.places$e}")
    } else {
        format!("{x:.places$}")
    }
}

/// A count given on the command line: clap's own message for "-1" is "invalid digit".
pub fn whole_number<T: Count>(text: &str) -> Result<T, String> {
    text.parse().map_err(|e: std::num::ParseIntError| {
        if *e.kind() == std::num::IntErrorKind::PosOverflow {
            format!("{text} is more than the most allowed here, {}", T::LARGEST)
        } else {
            format!("expected a whole number, 0 or more, got '{text}'")
        }
    })
}

/// The unsigned counts a flag may take ([`whole_number`]) and their largest values.
pub trait Count: std::str::FromStr<Err = std::num::ParseIntError> + std::fmt::Display {
    const LARGEST: Self;
}

impl Count for u64 {
    const LARGEST: Self = u64::MAX;
}

impl Count for usize {
    const LARGEST: Self = usize::MAX;
}

/// `--constraints FILE|none`.
fn constraints_choice(arg: Option<&str>) -> ConstraintsChoice {
    match arg {
        None => ConstraintsChoice::Auto,
        Some(s) if s.eq_ignore_ascii_case("none") => ConstraintsChoice::None,
        Some(s) => ConstraintsChoice::File(PathBuf::from(s)),
    }
}

impl SceneArgs {
    pub fn load(&self, settings: Settings) -> anyhow::Result<tumble::World> {
        let choice = constraints_choice(self.constraints.as_deref());
        let world = tumble::scene::load(&self.scene, &choice, settings)?;
        let scene_file = std::path::Path::new(&self.scene);
        if matches!(choice, ConstraintsChoice::Auto)
            && scene_file.is_file()
            && let Some(found) =
                tumble::scene::default_constraints_path(scene_file).filter(|p| p.is_file())
        {
            eprintln!(
                "constraints: {} (beside the scene; --constraints none leaves them out)",
                found.display()
            );
        }
        for w in &world.warnings {
            eprintln!("warning: {w}");
        }
        if let Some(note) = short_budget(&world.settings, world.constraints.len()) {
            eprintln!("warning: {note}");
        }
        Ok(world)
    }
}

/// Said where the coursework's constraint budget cannot visit each inequality once a step: the
/// skeleton's rule (at most ceil(K / M) visits for M inequalities) is kept, but chain-10000 at
/// the default budget projects one constraint a step, in silence but for "budget hit". `s`:
/// the settings of a world of the scene's `m` inequalities (the first, or a compared one).
pub fn short_budget(s: &Settings, m: usize) -> Option<String> {
    let visits = s.max_iterations.div_ceil(m.max(1));
    (s.solver == Solver::Coursework && m > 0 && visits < m).then(|| {
        // ceil(K / M) >= M from K = (M - 1) M + 1 on: past the flag's limit for M over 31,623
        // (rope-100000 was told to give 39999000007, which the flag refuses).
        let one_pass = (m - 1).saturating_mul(m).saturating_add(1);
        let remedy = if one_pass <= MAX_ITERATIONS {
            format!("--max-iterations {one_pass} or more makes one pass")
        } else {
            format!(
                "no --max-iterations up to its limit of {MAX_ITERATIONS} makes one; \
                 --solver soft-step solves every constraint each step"
            )
        };
        format!(
            "--max-iterations {} allows {} a step for {m} inequalities (the coursework's \
             rule: ceil(K / M)), fewer than one pass over them; {remedy}",
            s.max_iterations,
            tumble::io::counted(visits as u64, "constraint visit", "constraint visits"),
        )
    })
}

/// Progress bar on stderr, hidden when stderr is not a terminal.
pub fn progress_bar(len: u64, what: &str) -> indicatif::ProgressBar {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ({eta} left)")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

/// A benchmark's progress as a bar on stderr (nothing when stderr is not a terminal). Behind a
/// lock: the benchmarks step in the thread pool, whose thread reports.
#[derive(Default)]
pub struct ProgressBar(std::sync::Mutex<Option<indicatif::ProgressBar>>);

impl ProgressBar {
    fn bar(&self) -> std::sync::MutexGuard<'_, Option<indicatif::ProgressBar>> {
        self.0
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

impl tumble::bench::Progress for ProgressBar {
    fn start(&self, total: u64, what: &str) {
        *self.bar() = Some(progress_bar(total, what));
    }
    fn message(&self, text: &str) {
        if let Some(bar) = &*self.bar() {
            bar.set_message(text.to_string());
        }
    }
    fn set_position(&self, done: u64) {
        if let Some(bar) = &*self.bar() {
            bar.set_position(done);
        }
    }
    fn finish(&self) {
        if let Some(bar) = self.bar().take() {
            bar.finish_and_clear();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The budget note names a `--max-iterations` that makes one pass only where the flag
    /// takes it: chain-2000's 3,600 inequalities need 12,956,401; rope-100000's 199,998 would
    /// need more than the limit.
    #[test]
    fn the_budget_note_names_only_a_budget_the_flag_takes() {
        let settings = Settings::default();
        let chain = short_budget(&settings, 3_600).unwrap();
        assert!(
            chain.contains("--max-iterations 12956401 or more"),
            "{chain}"
        );
        let rope = short_budget(&settings, 199_998).unwrap();
        assert!(
            rope.contains("no --max-iterations up to its limit"),
            "{rope}"
        );
        assert_eq!(short_budget(&settings, 100), None);
    }
}
