//! Where scene, mesh and constraint files are read from: the disk, or the copies of tumble's
//! own scenes and meshes compiled into the binary.

use crate::io::{LoadError, limits};
use std::path::{Component, Path, PathBuf};

/// Files compiled into the binary, addressed by their path in the repository.
const EMBEDDED: &[(&str, &str)] = &[
    (
        "scenes/mixed-scene.txt",
        include_str!("../../scenes/mixed-scene.txt"),
    ),
    (
        "scenes/tower-scene.txt",
        include_str!("../../scenes/tower-scene.txt"),
    ),
    (
        "scenes/two-chain-scene.txt",
        include_str!("../../scenes/two-chain-scene.txt"),
    ),
    (
        "scenes/two-chain-constraints.txt",
        include_str!("../../scenes/two-chain-constraints.txt"),
    ),
    (
        "scenes/cube-scene.txt",
        include_str!("../../scenes/cube-scene.txt"),
    ),
    (
        "scenes/cube-constraints.txt",
        include_str!("../../scenes/cube-constraints.txt"),
    ),
    (
        "scenes/stress-scene.txt",
        include_str!("../../scenes/stress-scene.txt"),
    ),
    (
        "scenes/two-cylinders-scene.txt",
        include_str!("../../scenes/two-cylinders-scene.txt"),
    ),
    (
        "scenes/two-cylinders-constraints.txt",
        include_str!("../../scenes/two-cylinders-constraints.txt"),
    ),
    (
        "assets/tetrahedron.mesh",
        include_str!("../../assets/tetrahedron.mesh"),
    ),
    ("assets/box.mesh", include_str!("../../assets/box.mesh")),
    (
        "assets/octahedron.mesh",
        include_str!("../../assets/octahedron.mesh"),
    ),
    (
        "assets/long-octahedron.mesh",
        include_str!("../../assets/long-octahedron.mesh"),
    ),
    (
        "assets/cylinder.mesh",
        include_str!("../../assets/cylinder.mesh"),
    ),
    (
        "assets/ellipsoid.mesh",
        include_str!("../../assets/ellipsoid.mesh"),
    ),
];

/// Where scene, mesh and constraint files are read from.
pub(super) trait FileSource {
    fn read(&self, path: &Path) -> Result<String, LoadError>;
    fn exists(&self, path: &Path) -> bool;
    /// Whether `path` is a folder (where a file was expected: said so, not "not found").
    fn is_folder(&self, _path: &Path) -> bool {
        false
    }
    /// Whether the files are the disk's (which a run's outputs must not replace).
    fn on_disk(&self) -> bool {
        false
    }
    /// A file beside `path` whose name differs from its only in case (`Box.MESH` for
    /// `box.mesh`, found on a file system that ignores case and not on this one).
    fn named_alike(&self, _path: &Path) -> Option<PathBuf> {
        None
    }
}

pub(super) struct Disk;

impl FileSource for Disk {
    fn read(&self, path: &Path) -> Result<String, LoadError> {
        let meta = std::fs::metadata(path)
            .map_err(|e| LoadError::new(path, None, format!("cannot open: {e}")))?;
        if meta.is_dir() {
            return Err(LoadError::new(path, None, "is a folder, not a file"));
        }
        if meta.len() > limits::MAX_FILE_BYTES {
            return Err(LoadError::new(
                path,
                None,
                format!(
                    "file is {} bytes, more than the limit of {}",
                    meta.len(),
                    limits::MAX_FILE_BYTES
                ),
            ));
        }
        let bytes = read_at_most(path, limits::MAX_FILE_BYTES)?;
        crate::io::decode_text(path, bytes)
    }
    /// A file, or a device or pipe (read up to the limit), not a folder.
    fn exists(&self, path: &Path) -> bool {
        path.exists() && !path.is_dir()
    }
    fn is_folder(&self, path: &Path) -> bool {
        path.is_dir()
    }
    fn on_disk(&self) -> bool {
        true
    }
    fn named_alike(&self, path: &Path) -> Option<PathBuf> {
        let name = path.file_name()?.to_str()?;
        let folder = path.parent().filter(|p| !p.as_os_str().is_empty());
        let entries = std::fs::read_dir(folder.unwrap_or(Path::new("."))).ok()?;
        entries.flatten().map(|entry| entry.path()).find(|other| {
            let other_name = other.file_name().and_then(|n| n.to_str());
            other_name.is_some_and(|n| n != name && n.eq_ignore_ascii_case(name)) && !other.is_dir()
        })
    }
}

/// The bytes of `path`, refused past `limit`: a device or a pipe has no length to check first
/// (`tumble run /dev/zero` read until memory ran out).
fn read_at_most(path: &Path, limit: u64) -> Result<Vec<u8>, LoadError> {
    use std::io::Read;
    let cannot = |e: std::io::Error| LoadError::new(path, None, format!("cannot read: {e}"));
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .map_err(cannot)?
        .take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(cannot)?;
    if bytes.len() as u64 > limit {
        return Err(LoadError::new(
            path,
            None,
            format!("more than the limit of {limit} bytes"),
        ));
    }
    Ok(bytes)
}

pub(super) struct Embedded;

impl Embedded {
    fn key(path: &Path) -> String {
        let mut parts: Vec<String> = Vec::new();
        for component in path.components() {
            match component {
                Component::ParentDir => {
                    parts.pop();
                }
                Component::Normal(s) => parts.push(s.to_string_lossy().into_owned()),
                _ => {}
            }
        }
        parts.join("/")
    }
}

impl FileSource for Embedded {
    fn read(&self, path: &Path) -> Result<String, LoadError> {
        let key = Self::key(path);
        EMBEDDED
            .iter()
            .find(|(name, _)| *name == key)
            .map(|(_, text)| text.to_string())
            .ok_or_else(|| LoadError::new(path, None, "no such file among the built-in scenes"))
    }
    fn exists(&self, path: &Path) -> bool {
        let key = Self::key(path);
        EMBEDDED.iter().any(|(name, _)| *name == key)
    }
}

/// Text of a built-in file (used by the asset tests and `tumble scenes`).
pub fn embedded_file(path: &str) -> Option<&'static str> {
    EMBEDDED
        .iter()
        .find(|(name, _)| *name == path)
        .map(|(_, text)| *text)
}
