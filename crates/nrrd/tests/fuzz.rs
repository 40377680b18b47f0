//! A short, seeded fuzz run of the reader: the workspace's NRRD fixtures and bad
//! headers, mutated (the same mutator and corpus as volcast's fuzz suite), through
//! `read_header`, `storage` and `read` within 64 MiB, about two seconds, every panic
//! caught and reported with the case that caused it (saved under `fuzz-failures/`).

// The mutator (which allows its own unused parts) also serves volcast's scene and
// format fuzzing.
#[path = "../../../tests/fuzz/mutate.rs"]
mod mutate;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use mutate::{case, corpus, Kind};

/// How long the run takes in `cargo test`.
const BUDGET: Duration = Duration::from_millis(2000);
/// The seed of the run in `cargo test` (`VOLCAST_FUZZ_SEED` overrides it).
const SEED: u64 = 10;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// What a program inspecting an untrusted file does, within 64 MiB.
fn nrrd_case(path: &Path) {
    let reader = nrrd::Reader::new().max_bytes(64 << 20);
    let _ = reader.read_header(path);
    let _ = reader.storage(path);
    if let Ok((header, data)) = reader.read(path) {
        assert_eq!(
            header.element_count(),
            Some(data.len()),
            "{}",
            path.display()
        );
    }
}

#[test]
fn fuzz_nrrd_files() {
    let root = workspace();
    let seeds = corpus(Kind::Nrrd, &root);
    assert!(seeds.len() >= 8, "the NRRD corpus is empty");
    let tmp = tempfile::tempdir().unwrap();
    for e in std::fs::read_dir(root.join("tests/fixtures/nrrd")).unwrap() {
        let p = e.unwrap().path();
        if p.is_file() {
            std::fs::copy(&p, tmp.path().join(p.file_name().unwrap())).unwrap();
        }
    }
    mutate::prepare_dir(tmp.path());
    let seed = std::env::var("VOLCAST_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(SEED);
    let start = Instant::now();
    let mut n = 0u64;
    while start.elapsed() < BUDGET {
        let (name, bytes) = case(Kind::Nrrd, &seeds, seed, n);
        let path = mutate::place(tmp.path(), &name, &bytes).unwrap();
        if let Err(e) = catch_unwind(AssertUnwindSafe(|| nrrd_case(&path))) {
            let msg = e
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            let keep = root.join(format!("fuzz-failures/nrrd-crate-{seed}-{n}"));
            let _ = std::fs::create_dir_all(&keep);
            let _ = std::fs::write(keep.join(&name), &bytes);
            panic!(
                "case {n} (seed {seed}) panicked: {msg}; input saved in {}",
                keep.display()
            );
        }
        n += 1;
    }
    println!("fuzz nrrd: {n} cases in {:?}, no panic", start.elapsed());
    assert!(n > 50, "only {n} cases ran");
}
