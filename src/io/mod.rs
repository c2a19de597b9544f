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

/// A number a reader gave, echoed in a message as given (its shortest exact form), in
/// scientific notation outside 1e-6 to under 1e16: a density of -1e308 was echoed in 309
/// digits.
pub fn echoed(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-6..1e16).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// `v` to `figures` significant figures as a reader writes it (an axis's tick, a ratio): plainly
/// from 1e-3 to under 1e6 (`0.003`, `1000`), in scientific notation outside (`1e-4`,
/// `1.15e10`). Ticks came as computed (`9.999999999999999e-5`) or in full (`11500000000`).
pub fn significant(v: f64, figures: usize) -> String {
    let places = figures.clamp(1, 17) - 1;
    let rounded: f64 = format!("{v:.places$e}").parse().unwrap_or(v);
    if rounded == 0.0 || (1e-3..1e6).contains(&rounded.abs()) {
        format!("{rounded}")
    } else {
        format!("{rounded:e}")
    }
}

/// The figures that tell ticks `spacing` apart near `v`: down to the spacing's decade, and two
/// more for a spacing such as 0.25 (trailing zeros are not written: 1.15e10 and 1.2e10 apart
/// by 5e7, 1125.969 and 1125.970 by 1e-3).
pub fn tick_figures(v: f64, spacing: f64) -> usize {
    let decades = v.abs().log10().floor() - spacing.abs().log10().floor();
    if decades.is_finite() && decades >= 0.0 {
        (decades as usize + 3).min(15)
    } else {
        3
    }
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

    /// The same error with `note` after its message.
    pub fn noting(self, note: &str) -> Self {
        Self {
            message: format!("{}; {note}", self.message),
            ..self
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
        // An empty name shown as one (`tumble run ''` said ": no such file").
        let file = match self.file.as_os_str().is_empty() {
            true => "''".to_string(),
            false => self.file.display().to_string(),
        };
        match self.line {
            Some(line) => write!(f, "{file}:{line}: {}", self.message),
            None => write!(f, "{file}: {}", self.message),
        }
    }
}

impl std::error::Error for LoadError {}

#[cfg(test)]
mod tests {
    use super::{counted, echoed, significant, tick_figures};

    /// A number given is echoed exactly, and shortly at the ends of f64's range.
    #[test]
    fn numbers_given_are_echoed_shortly_and_exactly() {
        for (v, shown) in [
            (0.5, "0.5"),
            (-3.0, "-3"),
            (0.0, "0"),
            (123456.789, "123456.789"),
            (-1e308, "-1e308"),
            (1.5e-7, "1.5e-7"),
            (5e-324, "5e-324"),
            (1e16, "1e16"),
        ] {
            assert_eq!(echoed(v), shown);
            assert_eq!(shown.parse::<f64>().unwrap(), v);
        }
    }

    #[test]
    fn ticks_read_as_written() {
        let cases = [
            (9.999999999999999e-5, "1e-4"),
            (0.00030000000000000003, "3e-4"),
            (0.009999999999999998, "0.01"),
            (0.9999999999999999, "1"),
            (1000.0, "1000"),
            (2.5e6, "2.5e6"),
        ];
        for (v, label) in cases {
            assert_eq!(significant(v, 3), label);
        }
    }

    /// An axis's ticks keep the figures that tell them apart, and no more.
    #[test]
    fn ticks_keep_the_figures_their_spacing_needs() {
        let label = |v: f64, spacing: f64| significant(v, tick_figures(v, spacing));
        assert_eq!(label(1.15e10, 5e7), "1.15e10");
        assert_eq!(label(1.2e10, 5e7), "1.2e10");
        assert_eq!(label(1125.97 + 1e-12, 1e-3), "1125.97");
        assert_eq!(label(1125.969, 1e-3), "1125.969");
        assert_eq!(label(-250.0, 50.0), "-250");
        assert_eq!(label(0.0, 0.1), "0");
        assert_eq!(label(3e-7, 1e-7), "3e-7");
        assert_eq!(label(2.75, 0.25), "2.75");
        assert_eq!(label(0.30000000000000004, 0.1), "0.3");
    }

    #[test]
    fn counts_take_the_singular_only_for_one() {
        assert_eq!(counted(1u64, "frame", "frames"), "1 frame");
        assert_eq!(counted(0u64, "frame", "frames"), "0 frames");
        assert_eq!(counted(2u32, "body", "bodies"), "2 bodies");
    }
}
