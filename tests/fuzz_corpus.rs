//! Stable-Rust replay of the fuzzing corpus (tests/corpus/<target>/), plus a deterministic
//! mutation run over it, so CI keeps every interesting input that `cargo fuzz` found. Each input
//! must load or fail with an error; none may panic, hang or allocate by an unchecked count. The
//! `world` target's inputs are scenes and settings in bytes: each must step without a panic and
//! stay finite or report the bodies it froze.
mod common;

use std::path::Path;
use tumble::scene::generate::Rng;

fn corpus(target: &str) -> Vec<(String, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/corpus")
        .join(target);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    files
        .into_iter()
        .map(|p| (p.display().to_string(), std::fs::read(&p).unwrap()))
        .collect()
}

/// Byte-level mutations in the spirit of libFuzzer's: flips, deletions, duplications, and
/// splices of numbers that stress parsers (huge, negative, non-finite, overflowing) and of line
/// ends (LF, and a lone CR, which the readers take as one too).
fn mutate(input: &[u8], rng: &mut Rng) -> Vec<u8> {
    const TOKENS: [&str; 11] = [
        " 4294967296 ",
        " -1 ",
        " nan ",
        " inf ",
        " 1e308 ",
        " 0 ",
        "\n",
        "\r",
        " 18446744073709551616 ",
        " 1e-320 ",
        " End ",
    ];
    let mut out = input.to_vec();
    for _ in 0..1 + rng.next_u64() % 4 {
        let at = if out.is_empty() {
            0
        } else {
            (rng.next_u64() % out.len() as u64) as usize
        };
        match rng.next_u64() % 5 {
            0 if !out.is_empty() => out[at] ^= 1 << (rng.next_u64() % 8),
            1 if !out.is_empty() => {
                let len = ((rng.next_u64() % 16) as usize).min(out.len() - at);
                out.drain(at..at + len);
            }
            2 => {
                let token = TOKENS[(rng.next_u64() % TOKENS.len() as u64) as usize];
                out.splice(at..at, token.bytes());
            }
            3 if !out.is_empty() => {
                let len = ((rng.next_u64() % 32) as usize).min(out.len() - at);
                let copy = out[at..at + len].to_vec();
                out.splice(at..at, copy);
            }
            _ => out.truncate(at),
        }
    }
    out
}

#[test]
fn every_reader_survives_its_corpus_and_mutations_of_it() {
    for target in ["medit", "off", "scene", "constraints"] {
        let run = tumble::io::fuzzing::by_name(target).unwrap();
        let inputs = corpus(target);
        assert!(!inputs.is_empty(), "no corpus for {target}");
        let mut rng = Rng::new(0xF022);
        for (name, bytes) in &inputs {
            let ok = std::panic::catch_unwind(|| run(bytes));
            assert!(ok.is_ok(), "{target}: panic on corpus file {name}");
            for k in 0..300 {
                let mutated = mutate(bytes, &mut rng);
                let ok = std::panic::catch_unwind(|| run(&mutated));
                assert!(
                    ok.is_ok(),
                    "{target}: panic on mutation {k} of {name}: {:?}",
                    String::from_utf8_lossy(&mutated)
                );
            }
        }
    }
}

#[test]
fn the_world_target_survives_its_corpus_and_mutations_of_it() {
    let inputs = corpus("world");
    assert!(!inputs.is_empty(), "no corpus for world");
    let mut rng = Rng::new(0x30D1D);
    for (name, bytes) in &inputs {
        let ok = std::panic::catch_unwind(|| tumble::scene::fuzzing::world(bytes));
        assert!(ok.is_ok(), "world: panic on corpus file {name}");
        for k in 0..20 {
            let mutated = mutate(bytes, &mut rng);
            let ok = std::panic::catch_unwind(|| tumble::scene::fuzzing::world(&mutated));
            assert!(
                ok.is_ok(),
                "world: panic on mutation {k} of {name}: {mutated:?}"
            );
        }
    }
}
