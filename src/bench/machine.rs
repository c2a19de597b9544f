//! The machine a benchmark ran on, as Linux describes it: the processor's model, the logical
//! CPUs the run could use, and the first CPU's caches. Run times are only comparable on one
//! machine, and the scale bench's growth with N likely turns on what fits in the caches (a run
//! on a machine with 32 MiB of L3 grew 17.1x from scatter-10000 to scatter-100000 where another
//! machine's grew 11.3x; docs/scale-log.md, "Stop 58's run"), so the reports name the machine.

use serde::Serialize;
use std::path::Path;

#[derive(Debug, Clone, Serialize)]
pub struct Machine {
    /// The processor's model name ("unknown" where the system does not say).
    pub cpu: String,
    /// Logical CPUs this process may run on.
    pub logical_cpus: usize,
    /// The first CPU's caches, smallest level first: "L1d 32K", "L2 1024K", ...
    pub caches: Vec<String>,
}

impl Machine {
    /// This machine, from `/proc/cpuinfo` and `/sys/devices/system/cpu/cpu0/cache` where they
    /// exist (Linux); what cannot be read is left out.
    pub fn detect() -> Self {
        let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
        Self {
            cpu: model_name(&cpuinfo).unwrap_or_else(|| "unknown".into()),
            logical_cpus: std::thread::available_parallelism().map_or(1, |n| n.get()),
            caches: caches_in(Path::new("/sys/devices/system/cpu/cpu0/cache")),
        }
    }

    /// One line for a report: "AMD EPYC, 2 logical CPUs, caches L1d 32K, L1i 32K, ...".
    pub fn describe(&self) -> String {
        let mut line = format!("{}, {} logical CPUs", self.cpu, self.logical_cpus);
        if !self.caches.is_empty() {
            line.push_str(&format!(", caches {}", self.caches.join(", ")));
        }
        line
    }
}

/// The first "model name" of a `/proc/cpuinfo` text.
fn model_name(cpuinfo: &str) -> Option<String> {
    cpuinfo.lines().find_map(|line| {
        let (key, value) = line.split_once(':')?;
        (key.trim() == "model name" && !value.trim().is_empty()).then(|| value.trim().to_string())
    })
}

/// The caches listed under `dir` (`index0`, `index1`, ... each with `level`, `type` and
/// `size`), as `"L<level><d|i|> <size>"`, by level then name.
fn caches_in(dir: &Path) -> Vec<String> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let read = |index: &Path, name: &str| {
        std::fs::read_to_string(index.join(name))
            .ok()
            .map(|s| s.trim().to_string())
    };
    let mut caches: Vec<String> = entries
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with("index"))
        .filter_map(|e| {
            let index = e.path();
            let (level, kind, size) = (
                read(&index, "level")?,
                read(&index, "type")?,
                read(&index, "size")?,
            );
            Some(cache_name(&level, &kind, &size))
        })
        .collect();
    caches.sort();
    caches.dedup();
    caches
}

/// "L1d 32K" for a level-1 data cache of 32K; "L2 1024K" for a unified one.
fn cache_name(level: &str, kind: &str, size: &str) -> String {
    let suffix = match kind {
        "Data" => "d",
        "Instruction" => "i",
        _ => "",
    };
    format!("L{level}{suffix} {size}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_model_name_is_the_first_named_one() {
        let text = "processor\t: 0\nvendor_id\t: AuthenticAMD\nmodel name\t: AMD EPYC 9B14\n\
                    processor\t: 1\nmodel name\t: AMD EPYC 9B14\n";
        assert_eq!(model_name(text).as_deref(), Some("AMD EPYC 9B14"));
        assert_eq!(model_name("processor\t: 0\nmodel name\t:  \n"), None);
        assert_eq!(model_name(""), None);
    }

    #[test]
    fn caches_are_read_by_level_and_type() {
        let dir = std::env::temp_dir().join(format!("tumble-caches-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        for (index, level, kind, size) in [
            ("index2", "2", "Unified", "1024K"),
            ("index0", "1", "Data", "32K"),
            ("index1", "1", "Instruction", "32K"),
            ("index3", "3", "Unified", "32768K"),
        ] {
            let d = dir.join(index);
            std::fs::create_dir_all(&d).unwrap();
            for (name, value) in [("level", level), ("type", kind), ("size", size)] {
                std::fs::write(d.join(name), format!("{value}\n")).unwrap();
            }
        }
        // An index without its size is left out, as is anything not named index*.
        std::fs::create_dir_all(dir.join("index4")).unwrap();
        std::fs::create_dir_all(dir.join("power")).unwrap();
        let caches = caches_in(&dir);
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(caches, ["L1d 32K", "L1i 32K", "L2 1024K", "L3 32768K"]);
        assert!(caches_in(Path::new("/no/such/folder")).is_empty());
    }

    #[test]
    fn a_machine_is_one_line() {
        let m = Machine {
            cpu: "AMD EPYC".into(),
            logical_cpus: 2,
            caches: vec!["L1d 32K".into(), "L3 32768K".into()],
        };
        assert_eq!(
            m.describe(),
            "AMD EPYC, 2 logical CPUs, caches L1d 32K, L3 32768K"
        );
        let bare = Machine {
            caches: Vec::new(),
            ..m
        };
        assert_eq!(bare.describe(), "AMD EPYC, 2 logical CPUs");
    }
}
