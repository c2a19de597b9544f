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

/// Makes the folder a benchmark writes into and checks that a file can be written there, before
/// the benchmark runs: `--out` naming a file, or a folder that cannot be written, failed after
/// the whole run with "File exists (os error 17)" and threw its results away.
#[cfg(feature = "bench")]
pub fn output_folder(folder: &std::path::Path) -> anyhow::Result<()> {
    use anyhow::Context;
    let shown = folder.display();
    std::fs::create_dir_all(folder)
        .with_context(|| format!("--out {shown}: cannot make the folder"))?;
    let probe = folder.join(format!(".tumble-write-check-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .with_context(|| format!("--out {shown}: cannot write there"))?;
    std::fs::remove_file(&probe).with_context(|| format!("--out {shown}: cannot write there"))
}

/// A JSON object's entries, none where `value` is not an object: the replots' reader takes
/// what it can of a report.
#[cfg(feature = "bench")]
pub(crate) fn json_object(value: &serde_json::Value) -> serde_json::Map<String, serde_json::Value> {
    value.as_object().cloned().unwrap_or_default()
}

/// `contents` into `path`, whole or not at all ([`crate::io::AtomicFile`]: a run stopped
/// midway leaves the last report whole), an error naming the file.
#[cfg(feature = "bench")]
pub fn write_named(path: &std::path::Path, contents: impl AsRef<[u8]>) -> anyhow::Result<()> {
    use anyhow::Context;
    use std::io::Write;
    let mut file = crate::io::AtomicFile::create(path)?;
    file.writer()
        .write_all(contents.as_ref())
        .with_context(|| format!("cannot write {}", path.display()))?;
    file.commit()
}

/// No progress shown.
pub struct Silent;

impl Progress for Silent {
    fn start(&self, _: u64, _: &str) {}
    fn message(&self, _: &str) {}
    fn set_position(&self, _: u64) {}
    fn finish(&self) {}
}
