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

/// Makes the folder a benchmark writes into and checks that a file can be written there, and
/// that none of its `reports` (file names) is a folder, before the benchmark runs: `--out`
/// naming a file, or a folder that cannot be written, failed after the whole run with "File
/// exists (os error 17)" and threw its results away.
#[cfg(feature = "bench")]
pub fn output_folder(folder: &std::path::Path, reports: &[&str]) -> anyhow::Result<()> {
    use anyhow::Context;
    let shown = folder.display();
    anyhow::ensure!(
        !folder.exists() || folder.is_dir(),
        "--out {shown}: a file is there; --out names the folder the reports and plots go into"
    );
    // (Found after the run, a folder named as a report left the others half written.)
    if let Some(taken) = reports.iter().find(|name| folder.join(name).is_dir()) {
        anyhow::bail!("--out {shown}: {taken} there is a folder, where the report goes");
    }
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

/// `items` in order without repeats: a scenario, size, variant or dt named twice is run once
/// (named twice, it was measured twice, the second replacing the first).
#[cfg(feature = "bench")]
pub(crate) fn first_of_each<T: PartialEq>(items: Vec<T>) -> Vec<T> {
    let mut kept: Vec<T> = Vec::with_capacity(items.len());
    for item in items {
        if !kept.contains(&item) {
            kept.push(item);
        }
    }
    kept
}

/// Removes the plots `{prefix}*.svg` in `out` that are not among `written`, this run's: a run
/// of fewer scenarios or scene families into an earlier run's folder left that run's other
/// plots beside a report without them.
#[cfg(feature = "bench")]
pub(crate) fn remove_stale_plots(
    out: &std::path::Path,
    prefix: &str,
    written: &[std::path::PathBuf],
) -> anyhow::Result<()> {
    use anyhow::Context;
    let Ok(entries) = std::fs::read_dir(out) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let ours = name
            .to_str()
            .is_some_and(|n| n.starts_with(prefix) && n.ends_with(".svg"));
        let kept = written
            .iter()
            .any(|w| w.file_name() == Some(name.as_os_str()));
        if ours && !kept && entry.file_type().is_ok_and(|t| t.is_file()) {
            std::fs::remove_file(entry.path())
                .with_context(|| format!("cannot remove {}", entry.path().display()))?;
        }
    }
    Ok(())
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
