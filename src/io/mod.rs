//! Files in and out. Readers for the coursework's formats turn text into plain data
//! ([`TetMesh`], [`SceneRecord`], [`ConstraintRecord`]) or a [`LoadError`] that names the file,
//! the line and the problem (physics never parses text); writers for meshes and trajectories;
//! files that appear whole or not at all.

pub mod atomic_file;
mod constraint_file;
pub mod fuzzing;
mod medit;
mod off;
mod scene_file;
mod tokens;
pub mod trajectory;

pub use crate::sim::shape::{TetMesh, TetVolumes};
pub use atomic_file::{
    AtomicFile, check_output, check_output_path, partial_path, write_file_atomically,
};
pub use constraint_file::{ConstraintRecord, parse_constraints};
pub use medit::{parse_medit, write_medit};
pub use off::parse_off;
pub use scene_file::{SceneRecord, parse_scene};
pub use tokens::decode_text;

use std::fmt;
use std::path::{Path, PathBuf};

/// A count with its noun for messages: "1 frame", "2 frames".
pub fn counted(n: impl Into<u64>, one: &str, many: &str) -> String {
    let n = n.into();
    format!("{n} {}", if n == 1 { one } else { many })
}

/// The first element that repeats an earlier one, by `keys` (one per element, in order): the
/// places `(earlier, later)` of that pair, or None. A mesh that lists an element twice counts
/// its volume twice.
pub(crate) fn first_repeat<K: Ord>(keys: impl Iterator<Item = K>) -> Option<(usize, usize)> {
    let mut keyed: Vec<(K, usize)> = keys.enumerate().map(|(k, key)| (key, k)).collect();
    keyed.sort_unstable();
    keyed
        .windows(2)
        .filter(|pair| pair[0].0 == pair[1].0)
        .map(|pair| (pair[0].1, pair[1].1))
        .min_by_key(|&(_, later)| later)
}

/// Hard limits on what a file may ask for, checked before anything is allocated, so a count of
/// four billion vertices is an error rather than an out-of-memory abort.
pub mod limits {
    /// Largest file any reader accepts.
    pub const MAX_FILE_BYTES: u64 = 256 * 1024 * 1024;
    /// Most vertices (and tetrahedra, and triangles) in one mesh.
    pub const MAX_MESH_ELEMENTS: usize = 5_000_000;
    /// Most bodies in one scene.
    pub const MAX_BODIES: usize = 1_000_000;
    /// Most constraint records in one file.
    pub const MAX_CONSTRAINTS: usize = 1_000_000;
}

/// The records of a scene or constraint file, and a warning when they were not laid out one a
/// line: the file loaded, but a missing field on one line and an extra one on another would
/// have shifted the records between them.
#[derive(Debug, Clone, PartialEq)]
pub struct Records<T> {
    pub records: Vec<T>,
    pub layout_warning: Option<LoadError>,
}

impl<T> Default for Records<T> {
    fn default() -> Self {
        Self {
            records: Vec::new(),
            layout_warning: None,
        }
    }
}

/// A problem with an input file: which file, which line (1-based) when one is to blame, and what.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadError {
    pub file: PathBuf,
    pub line: Option<usize>,
    pub message: String,
}

impl LoadError {
    pub fn new(file: impl Into<PathBuf>, line: Option<usize>, message: impl Into<String>) -> Self {
        Self {
            file: file.into(),
            line,
            message: message.into(),
        }
    }

    /// The same error attributed to another file (a reader works on text, the caller knows the
    /// path).
    pub fn in_file(mut self, file: &Path) -> Self {
        self.file = file.to_path_buf();
        self
    }
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}: {}", self.file.display(), line, self.message),
            None => write!(f, "{}: {}", self.file.display(), self.message),
        }
    }
}

impl std::error::Error for LoadError {}

#[cfg(test)]
mod tests {
    use super::counted;

    #[test]
    fn counts_take_the_singular_only_for_one() {
        assert_eq!(counted(1u64, "frame", "frames"), "1 frame");
        assert_eq!(counted(0u64, "frame", "frames"), "0 frames");
        assert_eq!(counted(2u32, "body", "bodies"), "2 bodies");
    }
}
