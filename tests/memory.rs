//! Every large allocation is checked before it happens, and `--max-memory` covers
//! all of it (issue 10, item 2): the plan's estimate (volume, gradient volumes,
//! prefiltered coefficients and the prefilter's copies, tables, images in flight,
//! previews, encoders) is compared with the limit before the volume is read, and a
//! run over it exits 1 with the estimate broken down. Where an estimate can be wrong,
//! allocation is fallible: an error, never an abort.

use std::io::Write;
use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

use crate::util::volcast;

fn refused(o: &Output, needles: &[&str]) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "{err}");
    for n in needles {
        assert!(err.contains(n), "expected {n:?} in: {err}");
    }
    err
}

/// A gzip NRRD of `n`^3 zero bytes (a few hundred kilobytes for hundreds of MB).
fn zeros_gzip(path: &Path, n: usize) {
    let mut f = std::fs::File::create(path).unwrap();
    write!(
        f,
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: {n} {n} {n}\nencoding: gzip\n\n"
    )
    .unwrap();
    let mut e = flate2::write::GzEncoder::new(f, flate2::Compression::fast());
    let slab = vec![0u8; n * n];
    for _ in 0..n {
        e.write_all(&slab).unwrap();
    }
    e.finish().unwrap();
}

#[test]
fn huge_images_are_refused_before_any_film_is_allocated() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    // the reproducer: this started and died of SIGABRT on a 16 GiB allocation
    std::fs::write(
        dir.join("s.toml"),
        "[volume]\nsynthetic = \"ball\"\nsizes = [8, 8, 8]\n[image]\nsize = [32768, 32768]\n[[render]]\nmode = \"mip\"\n",
    )
    .unwrap();
    let t0 = Instant::now();
    let o = volcast(
        dir,
        &["render", "s.toml", "--max-memory", "1G", "--out", "o"],
    );
    let err = refused(
        &o,
        &[
            "s.toml: this run needs about",
            "more than the 1.0 GiB allowed by --max-memory",
            "rendered images in flight (32768 x 32768",
            "--max-memory",
        ],
    );
    assert!(!err.contains("abort"), "{err}");
    assert!(t0.elapsed() < Duration::from_secs(5));
    assert!(!dir.join("o").exists());
    // the same with --size, and from `check`
    std::fs::write(
        dir.join("t.toml"),
        "[volume]\nsynthetic = \"ball\"\nsizes = [8, 8, 8]\n[[render]]\nmode = \"mip\"\n",
    )
    .unwrap();
    for cmd in ["render", "check"] {
        let o = volcast(
            dir,
            &[
                cmd,
                "t.toml",
                "--size",
                "32768x32768",
                "--max-memory",
                "1G",
                "--out",
                "o",
            ],
        );
        refused(&o, &["rendered images in flight (32768 x 32768"]);
    }
    assert!(!dir.join("o").exists());
}

#[test]
fn gradient_volumes_count_before_the_volume_is_read() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    // the reproducer: a 1.3 MB gzip NRRD of 1100^3 voxels with a shaded composite
    // aborted on a 16 GB gradient volume. The data here is not even gzip: the run
    // is refused before it is read.
    std::fs::write(
        dir.join("v.nrrd"),
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1100 1100 1100\nencoding: gzip\n\nnot gzip",
    )
    .unwrap();
    std::fs::write(
        dir.join("s.toml"),
        "[volume]\npath = \"v.nrrd\"\nwindow = [0, 255]\n[[render]]\nmode = \"composite\"\nshading = \"phong\"\ngradient = \"sobel\"\n",
    )
    .unwrap();
    let o = volcast(
        dir,
        &["render", "s.toml", "--max-memory", "16G", "--out", "o"],
    );
    refused(
        &o,
        &[
            "this run needs about 16.2 GiB",
            "more than the 16.0 GiB allowed",
            "volume, read into memory (gzip encoding)",
            "1.2 GiB",
            "sobel gradient volume (3 floats per voxel)",
            "14.9 GiB",
        ],
    );
    assert!(!dir.join("o").exists());
}

/// Max resident memory of a run in bytes, by `/usr/bin/time` (None where it is
/// missing).
fn max_rss(dir: &Path, args: &[&str]) -> Option<(Output, u64)> {
    if !Path::new("/usr/bin/time").exists() {
        return None;
    }
    let o = Command::new("/usr/bin/time")
        .arg("-f")
        .arg("maxrss=%M")
        .arg(env!("CARGO_BIN_EXE_volcast"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    let kib: u64 = err
        .lines()
        .find_map(|l| l.strip_prefix("maxrss="))?
        .trim()
        .parse()
        .ok()?;
    Some((o, kib * 1024))
}

#[test]
fn cubic_and_sobel_stay_within_the_limit() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    zeros_gzip(&dir.join("v.nrrd"), 128);
    std::fs::write(
        dir.join("s.toml"),
        "[volume]\npath = \"v.nrrd\"\nwindow = [0, 255]\n[image]\nsize = [48, 48]\n\
         [[render]]\nmode = \"composite\"\ninterpolation = \"cubic\"\nshading = \"phong\"\ngradient = \"sobel\"\n",
    )
    .unwrap();
    // the reproducer: this used 17 times its --max-memory 40M (scaled down here)
    let o = volcast(
        dir,
        &["render", "s.toml", "--max-memory", "12M", "--out", "o"],
    );
    let err = refused(
        &o,
        &[
            "sobel gradient volume",
            "cubic B-spline coefficients",
            "cubic prefilter while it runs",
            "volume, read into memory (gzip encoding)",
        ],
    );
    assert!(!dir.join("o").exists());
    // a limit the estimate fits in is a limit the run keeps (measured)
    let need: f64 = err
        .split("needs about ")
        .nth(1)
        .and_then(|r| r.split(" MiB").next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no estimate in {err}"));
    let limit = format!("{}M", need.ceil());
    let args = [
        "render",
        "s.toml",
        "--max-memory",
        &limit,
        "--out",
        "o",
        "--quiet",
        "--threads",
        "2",
    ];
    match max_rss(dir, &args) {
        Some((o, rss)) => {
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            // the process itself (code, stacks, allocator) needs about 10 MiB
            let allowed = (need.ceil() as u64 + 12) << 20;
            assert!(
                rss <= allowed,
                "max resident {} MiB > limit {limit} + 12 MiB",
                rss >> 20
            );
        }
        None => {
            let o = volcast(dir, &args);
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        }
    }
}

#[cfg(unix)]
#[test]
fn an_allocation_that_fails_is_an_error_not_an_abort() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    zeros_gzip(&dir.join("v.nrrd"), 512);
    // A limit the machine cannot honour (address space capped at 100 MB): the
    // decoder's buffer cannot grow, and that is a message and status 1, not SIGABRT.
    let exe = env!("CARGO_BIN_EXE_volcast");
    let o = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v 100000 && exec '{exe}' info v.nrrd --max-memory 100G"
        ))
        .current_dir(dir)
        .output()
        .unwrap();
    refused(
        &o,
        &["v.nrrd: out of memory: allocating", "for the voxels failed"],
    );
}
