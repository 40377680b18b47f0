//! A short, seeded fuzz run through the library's entry points (issue 10, item 9):
//! mutated NRRD fixtures through the reader (header, storage, load, statistics), the
//! same for the NIfTI, MetaImage and TIFF fixtures (issues 9 and 46), and
//! mutated example scenes through the scene parser, the header and the plan (what
//! `volcast check` does), about two seconds each, every panic caught and reported
//! with the case that caused it, and a case that raises the process's peak resident
//! memory past 1 GiB fails too (DICOM files whose hidden lengths made the `dicom`
//! crate allocate 4 GiB, issue 48). The long run, every case its own process under a
//! timeout with its peak resident memory measured, is `examples/fuzz.rs` (see docs/testing.md).

mod mutate;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::time::{Duration, Instant};

use mutate::{case, corpus, Kind};
use volcast::plan::{Plan, RunOptions};
use volcast::volume::{Limits, Stats, VolumeSource};

/// How long each kind runs in `cargo test`.
const BUDGET: Duration = Duration::from_millis(2000);
/// The seed of the run in `cargo test` (`VOLCAST_FUZZ_SEED` overrides it).
const SEED: u64 = 10;
/// Peak resident memory of the test process that a case may not raise it above:
/// the cases read within 64 MiB, so only a blow-up gets there.
const MAX_RSS: u64 = 1 << 30;

/// The peak resident memory of this process so far, in bytes (0 where unknown).
fn peak_rss() -> u64 {
    #[cfg(unix)]
    {
        // SAFETY: getrusage fills the zeroed struct it is given.
        let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
        if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } == 0 {
            return usage.ru_maxrss as u64 * 1024;
        }
    }
    0
}

fn seed() -> u64 {
    std::env::var("VOLCAST_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(SEED)
}

/// What `volcast info` does with a NRRD file, within 64 MiB.
fn nrrd_case(path: &Path) {
    let limits = Limits {
        max_bytes: 64 << 20,
    };
    let source = VolumeSource::Nrrd(path.to_path_buf());
    let _ = source.header();
    let _ = source.storage();
    if let Ok(v) = source.load(&limits) {
        let _ = Stats::of(&v.data);
    }
    let _ = volcast::volume::nrrd::read_header(path);
}

/// What `volcast info` does with a NIfTI or MetaImage file or a DICOM folder, within
/// 64 MiB.
fn formats_case(path: &Path) {
    let limits = Limits {
        max_bytes: 64 << 20,
    };
    let Ok(source) = VolumeSource::from_path(path) else {
        return;
    };
    let _ = source.header();
    let _ = source.storage();
    if let Ok(v) = source.load(&limits) {
        let _ = Stats::of(&v.data);
    }
}

/// What `volcast check` does with a scene file.
fn scene_case(path: &Path) {
    let Ok(scene) = volcast::scene::load(path) else {
        return;
    };
    let Ok(headers) = volcast::pipeline::headers(&scene) else {
        return;
    };
    let opts = RunOptions::default();
    if let Ok(plan) = Plan::build(&scene, &headers, &opts) {
        let _ = plan.check_memory(&Limits {
            max_bytes: 256 << 20,
        });
        let _ = plan.describe(&scene);
    }
}

/// Copies the fixtures of a kind (and their data files) into `dir`.
fn copy_fixtures(folder: &str, dir: &Path) {
    let src = crate::util::root().join(folder);
    for e in std::fs::read_dir(src).unwrap() {
        let p = e.unwrap().path();
        if p.is_file() {
            std::fs::copy(&p, dir.join(p.file_name().unwrap())).unwrap();
        }
    }
}

fn run(kind: Kind) {
    let root = crate::util::root();
    let seeds = corpus(kind, &root);
    assert!(seeds.len() >= 8, "the corpus of {kind:?} is empty");
    let tmp = tempfile::tempdir().unwrap();
    if let Some(folder) = kind.fixtures() {
        copy_fixtures(folder, tmp.path());
    }
    mutate::prepare_dir(tmp.path());
    let seed = seed();
    let start = Instant::now();
    let mut n = 0u64;
    let mut before = peak_rss();
    // the panic messages of caught cases are expected noise only on failure
    while start.elapsed() < BUDGET {
        let (name, bytes) = case(kind, &seeds, seed, n);
        let path = mutate::place(tmp.path(), &name, &bytes).unwrap();
        let outcome = catch_unwind(AssertUnwindSafe(|| match kind {
            Kind::Nrrd => nrrd_case(&path),
            Kind::Scene => scene_case(&path),
            Kind::Formats => formats_case(&path),
        }));
        let peak = peak_rss();
        let failure = match outcome {
            Err(e) => Some(format!(
                "panicked: {}",
                e.downcast_ref::<String>()
                    .cloned()
                    .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default()
            )),
            Ok(()) if peak > MAX_RSS && peak > before => Some(format!(
                "raised the peak resident memory to {} MiB",
                peak >> 20
            )),
            Ok(()) => None,
        };
        if let Some(why) = failure {
            let keep = root.join(format!("fuzz-failures/{}-{seed}-{n}", kind.name()));
            let _ = std::fs::create_dir_all(&keep);
            let _ = std::fs::write(keep.join(&name), &bytes);
            panic!(
                "{kind:?} case {n} (seed {seed}) {why}; input saved in {}",
                keep.display()
            );
        }
        before = peak;
        n += 1;
    }
    println!(
        "fuzz {}: {n} cases in {:?}, no panic, peak resident memory of the process {} MiB",
        kind.name(),
        start.elapsed(),
        peak_rss() >> 20
    );
    assert!(n > 50, "only {n} cases ran");
}

#[test]
fn fuzz_nrrd_files() {
    run(Kind::Nrrd);
}

#[test]
fn fuzz_nifti_and_metaimage_files() {
    run(Kind::Formats);
}

#[test]
fn fuzz_scene_files() {
    run(Kind::Scene);
}
