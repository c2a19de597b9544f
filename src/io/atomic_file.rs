//! Files that appear whole or not at all: written under a temporary sibling name
//! (`.NAME.partial`) and renamed into place when complete, so an interrupted run never leaves a
//! truncated file under the final name.

use anyhow::Context;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The temporary sibling a file is written under.
pub fn partial_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    path.with_file_name(format!(".{name}.partial"))
}

/// Refuses an output path that cannot become a file: a folder, a file in a folder that does not
/// exist (so that a long run does not end in that error), or a device, pipe or socket, which the
/// rename into place would replace with a plain file (`--trajectory /dev/null` run as root
/// replaced the machine's `/dev/null`). Returns the file to write: `path`, or for a symbolic
/// link the file it leads to, so that the link stays a link.
pub fn check_output_path(path: &Path) -> anyhow::Result<PathBuf> {
    let shown = path.display();
    let target = match std::fs::symlink_metadata(path) {
        Ok(meta) if meta.file_type().is_symlink() => link_target(path)
            .with_context(|| format!("cannot write {shown}: cannot follow the link"))?,
        _ => path.to_path_buf(),
    };
    // `out/` names a folder whether or not one is there (where none is, the run went to its
    // end and then failed to move its file into place).
    let folder_name = path
        .as_os_str()
        .to_string_lossy()
        .ends_with(std::path::is_separator);
    match std::fs::metadata(&target) {
        Ok(meta) if meta.is_dir() => anyhow::bail!("cannot write {shown}: it is a folder"),
        _ if folder_name => {
            anyhow::bail!(
                "cannot write {shown}: it names a folder (ends in a separator), not a file"
            )
        }
        Ok(meta) if !meta.is_file() => anyhow::bail!(
            "cannot write {shown}: it is not a regular file (a device, a pipe or a socket), and writing would replace it"
        ),
        _ => {}
    }
    match target.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(folder) if !folder.is_dir() => anyhow::bail!(
            "cannot write {shown}: the folder {} does not exist",
            folder.display()
        ),
        _ => Ok(target),
    }
}

/// The file the link at `path` leads to: where it exists, the end of the chain; where it does
/// not yet, the name the link holds (beside the link where it is relative).
fn link_target(path: &Path) -> std::io::Result<PathBuf> {
    match std::fs::canonicalize(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let named = std::fs::read_link(path)?;
            Ok(match path.parent() {
                Some(folder) if named.is_relative() => folder.join(named),
                _ => named,
            })
        }
        found => found,
    }
}

/// [`check_output_path`], and the refusal of an output that is one of `inputs`, the files the run
/// reads (`--trajectory scene.txt` replaced the scene it was simulating): the file to write.
pub fn check_output(path: &Path, inputs: &[PathBuf]) -> anyhow::Result<PathBuf> {
    let target = check_output_path(path)?;
    check_not_an_input(&target, inputs)?;
    Ok(target)
}

fn check_not_an_input(output: &Path, inputs: &[PathBuf]) -> anyhow::Result<()> {
    let Ok(written) = FileIdentity::of(output) else {
        return Ok(()); // Not there yet: no input.
    };
    match inputs
        .iter()
        .find(|input| FileIdentity::of(input).is_ok_and(|read| read == written))
    {
        Some(input) => anyhow::bail!(
            "cannot write {}: it is {}, which this run reads",
            output.display(),
            input.display()
        ),
        None => Ok(()),
    }
}

/// What makes two names one file: on Unix its device and inode, so that a hard link to an input
/// is that input too (the rename into place would have split the two names silently, the output
/// under one, the input as it was under the other); elsewhere its canonical path.
#[derive(PartialEq)]
enum FileIdentity {
    #[cfg(unix)]
    Inode(u64, u64),
    #[cfg(not(unix))]
    Path(PathBuf),
}

impl FileIdentity {
    fn of(path: &Path) -> std::io::Result<Self> {
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            let meta = std::fs::metadata(path)?;
            Ok(Self::Inode(meta.dev(), meta.ino()))
        }
        #[cfg(not(unix))]
        {
            std::fs::canonicalize(path).map(Self::Path)
        }
    }
}

/// The partial files being written now, for [`remove_unfinished_files`].
static UNFINISHED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// A partial file being written: listed while it lives, and removed when dropped unless
/// [`Unfinished::keep`] says it was moved into place. Where the process ends without unwinding
/// (`std::process::exit` on a GPU out of memory), [`remove_unfinished_files`] removes the files
/// of those still alive.
pub struct Unfinished {
    tmp: PathBuf,
    kept: bool,
}

impl Unfinished {
    pub fn new(tmp: &Path) -> Self {
        let mut listed = UNFINISHED.lock().unwrap_or_else(|e| e.into_inner());
        listed.push(tmp.to_path_buf());
        Self {
            tmp: tmp.to_path_buf(),
            kept: false,
        }
    }

    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// The file was moved into place: nothing to remove.
    pub fn keep(mut self) {
        self.kept = true;
    }
}

impl Drop for Unfinished {
    fn drop(&mut self) {
        if !self.kept {
            let _ = std::fs::remove_file(&self.tmp);
        }
        let mut listed = UNFINISHED.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(k) = listed.iter().position(|p| *p == self.tmp) {
            listed.swap_remove(k);
        }
    }
}

/// Removes every partial file still being written: for an exit that skips destructors.
pub fn remove_unfinished_files() {
    let listed = UNFINISHED.lock().unwrap_or_else(|e| e.into_inner());
    for tmp in listed.iter() {
        let _ = std::fs::remove_file(tmp);
    }
}

/// A file being written; [`AtomicFile::commit`] moves it to its final name. Dropped without a
/// commit (an error on the way), it removes what it wrote.
pub struct AtomicFile {
    path: PathBuf,
    writer: BufWriter<File>,
    tmp: Unfinished,
}

impl AtomicFile {
    /// Errors name the file the user asked for (or the one its link leads to), not the temporary
    /// one; what [`check_output_path`] refuses is refused here, before any work is done for it.
    pub fn create(path: &Path) -> anyhow::Result<Self> {
        let target = check_output_path(path)?;
        // Listed before it exists, so that no exit finds it there unlisted.
        let tmp = Unfinished::new(&partial_path(&target));
        let file = File::create(tmp.path()).with_context(|| {
            format!(
                "cannot write {} (as {} first)",
                path.display(),
                tmp.path().display()
            )
        })?;
        Ok(Self {
            path: target,
            writer: BufWriter::new(file),
            tmp,
        })
    }

    pub fn writer(&mut self) -> &mut BufWriter<File> {
        &mut self.writer
    }

    /// The file it becomes (through a link, the file the link leads to): what errors name.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes and renames into place.
    pub fn commit(mut self) -> anyhow::Result<()> {
        self.writer
            .flush()
            .with_context(|| format!("cannot write {}", self.path.display()))?;
        let tmp = self.tmp.path();
        std::fs::rename(tmp, &self.path).with_context(|| {
            format!(
                "cannot write {} (moving {} into place)",
                self.path.display(),
                tmp.display()
            )
        })?;
        self.tmp.keep();
        Ok(())
    }
}

/// Writes `path` in one go through an [`AtomicFile`].
pub fn write_file_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> anyhow::Result<()> {
    let mut file = AtomicFile::create(path)?;
    write(file.writer()).with_context(|| format!("cannot write {}", path.display()))?;
    file.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Committed, the file is in place and nothing else; dropped on an error before its commit,
    /// neither it nor its partial file is left.
    #[test]
    fn a_file_appears_whole_or_not_at_all() {
        let dir = std::env::temp_dir().join(format!("tumble-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (kept, dropped) = (dir.join("kept.txt"), dir.join("dropped.txt"));
        let listed = |path: &Path| {
            let tmp = partial_path(path);
            UNFINISHED.lock().unwrap().contains(&tmp)
        };
        let mut file = AtomicFile::create(&kept).unwrap();
        file.writer().write_all(b"whole").unwrap();
        assert!(listed(&kept), "listed for an exit that skips destructors");
        file.commit().unwrap();
        assert!(!listed(&kept));
        let mut file = AtomicFile::create(&dropped).unwrap();
        file.writer().write_all(b"half").unwrap();
        assert!(partial_path(&dropped).exists());
        drop(file);
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("kept.txt")]);
        assert_eq!(std::fs::read_to_string(&kept).unwrap(), "whole");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
