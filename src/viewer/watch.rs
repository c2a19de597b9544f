//! Watching files for changes by polling their modification times and sizes (no file-system
//! notification crate): cheap enough for the handful of files a scene is made of.

use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// What a file looked like when last polled: None while it does not exist.
type Stamp = Option<(SystemTime, u64)>;

fn stamp(path: &Path) -> Stamp {
    let meta = std::fs::metadata(path).ok()?;
    Some((meta.modified().ok()?, meta.len()))
}

#[derive(Debug, Default, Clone)]
pub struct FileWatch {
    files: Vec<(PathBuf, Stamp)>,
}

impl FileWatch {
    /// Watches `files` from their current state on.
    pub fn new(files: Vec<PathBuf>) -> FileWatch {
        FileWatch {
            files: files.into_iter().map(|f| (f.clone(), stamp(&f))).collect(),
        }
    }

    pub fn files(&self) -> impl Iterator<Item = &Path> {
        self.files.iter().map(|(f, _)| f.as_path())
    }

    /// The first file that changed (written, created or removed) since the last poll; every
    /// file's new state is taken, so one change is reported once.
    pub fn poll(&mut self) -> Option<PathBuf> {
        let mut changed = None;
        for (path, last) in &mut self.files {
            let now = stamp(path);
            if now != *last {
                *last = now;
                changed.get_or_insert_with(|| path.clone());
            }
        }
        changed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reports_writes_creations_and_removals_once() {
        let dir = std::env::temp_dir().join(format!("tumble-watch-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (a, b) = (dir.join("a.txt"), dir.join("b.txt"));
        std::fs::write(&a, "one").unwrap();
        let _ = std::fs::remove_file(&b);
        let mut watch = FileWatch::new(vec![a.clone(), b.clone()]);
        assert_eq!(watch.poll(), None);
        std::fs::write(&a, "three").unwrap();
        assert_eq!(watch.poll(), Some(a.clone()));
        assert_eq!(watch.poll(), None);
        std::fs::write(&b, "new").unwrap();
        assert_eq!(watch.poll(), Some(b.clone()));
        std::fs::remove_file(&b).unwrap();
        assert_eq!(watch.poll(), Some(b));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
