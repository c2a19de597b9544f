//! Files that appear whole or not at all: written under a temporary sibling name
//! (`.NAME.partial`) and renamed into place when complete, so an interrupted run never leaves a
//! truncated file under the final name.

use anyhow::Context;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The temporary sibling a file is written under.
pub fn partial_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    path.with_file_name(format!(".{name}.partial"))
}

/// A file being written; [`AtomicFile::commit`] moves it to its final name.
pub struct AtomicFile {
    path: PathBuf,
    tmp: PathBuf,
    writer: BufWriter<File>,
}

impl AtomicFile {
    pub fn create(path: &Path) -> anyhow::Result<Self> {
        let tmp = partial_path(path);
        let file =
            File::create(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            tmp,
            writer: BufWriter::new(file),
        })
    }

    pub fn writer(&mut self) -> &mut BufWriter<File> {
        &mut self.writer
    }

    /// Flushes and renames into place.
    pub fn commit(mut self) -> anyhow::Result<()> {
        self.writer
            .flush()
            .with_context(|| format!("cannot write {}", self.tmp.display()))?;
        drop(self.writer);
        std::fs::rename(&self.tmp, &self.path).with_context(|| {
            format!(
                "cannot move {} to {}",
                self.tmp.display(),
                self.path.display()
            )
        })
    }
}

/// Writes `path` in one go through an [`AtomicFile`].
pub fn write_file_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> anyhow::Result<()> {
    let mut file = AtomicFile::create(path)?;
    write(file.writer())
        .with_context(|| format!("cannot write {}", partial_path(path).display()))?;
    file.commit()
}
