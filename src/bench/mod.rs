//! Measuring tumble: the accuracy scenarios (closed forms and independent references, always
//! built: tests use them), and with feature `bench` the drivers of `tumble bench scale`,
//! `accuracy` and `soak`, which return reports and write CSV files and plots. The command line
//! prints the reports; the drivers print nothing.

#[cfg(feature = "bench")]
pub mod accuracy;
pub mod alloc;
#[cfg(feature = "bench")]
pub mod machine;
#[cfg(feature = "bench")]
pub mod plot;
#[cfg(feature = "compare-rapier")]
pub mod rapier;
#[cfg(feature = "bench")]
pub mod scale;
pub mod scenarios;
#[cfg(feature = "bench")]
pub mod soak;

/// How a long benchmark reports its progress (the CLI draws a progress bar).
pub trait Progress: Sync {
    /// `total` units of work lie ahead.
    fn start(&self, total: u64, what: &str);
    /// What is being measured now.
    fn message(&self, text: &str);
    /// `done` units of work are done.
    fn set_position(&self, done: u64);
    fn finish(&self);
}

/// No progress shown.
pub struct Silent;

impl Progress for Silent {
    fn start(&self, _: u64, _: &str) {}
    fn message(&self, _: &str) {}
    fn set_position(&self, _: u64) {}
    fn finish(&self) {}
}
