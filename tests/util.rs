//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The project root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `../shared/data` beside the project, if present.
pub fn shared_data() -> Option<PathBuf> {
    let p = root().join("../shared/data");
    p.is_dir().then_some(p)
}

/// Runs the built `volcast` binary with `args` in `dir`.
pub fn volcast(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_volcast"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the volcast binary runs")
}

/// Renders the scene `text` (written to a temporary folder) through the CLI with
/// `args` added, and returns the bytes of every NRRD image written, by file name.
pub fn rendered_nrrds(text: &str, args: &[&str]) -> Vec<(String, Vec<u8>)> {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("s.toml"), text).unwrap();
    let mut all = vec!["render", "s.toml", "--out", "out", "--quiet"];
    all.extend_from_slice(args);
    let o = volcast(tmp.path(), &all);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(tmp.path().join("out"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "nrrd"))
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&p).unwrap())
        })
        .collect();
    files.sort();
    files
}

/// Asserts `|got - want| <= tol`, printing all three and a label on failure.
#[macro_export]
macro_rules! assert_close {
    ($got:expr, $want:expr, $tol:expr, $($what:tt)+) => {{
        let (g, w, t): (f64, f64, f64) = ($got as f64, $want as f64, $tol as f64);
        assert!(
            (g - w).abs() <= t,
            "{}: got {g}, want {w}, |diff| {} > tolerance {t}",
            format!($($what)+),
            (g - w).abs()
        );
    }};
}

/// How a run of the volcast binary ended, with its wall time and peak resident memory.
pub struct Measured {
    pub code: Option<i32>,
    pub stderr: String,
    pub elapsed: Duration,
    /// Peak resident set of the volcast process in bytes (`ru_maxrss`).
    pub peak_rss: u64,
}

/// Python that forks and runs its arguments with stdout to /dev/null, waits for the
/// child and prints its exit code and `ru_maxrss` (KiB).
const LAUNCHER: &str = r#"import os, sys
pid = os.fork()
if pid == 0:
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    os.execv(sys.argv[1], sys.argv[1:])
_, status, usage = os.wait4(pid, 0)
print(os.waitstatus_to_exitcode(status), usage.ru_maxrss)
"#;

/// Runs the volcast binary with `args` in `dir` and measures it. The run is
/// started by a small Python process: a child forked from this test process would
/// count this process's resident pages (those of every test running beside it) in
/// its own peak, since the peak survives `exec`.
#[cfg(unix)]
pub fn measured(dir: &Path, args: &[&str]) -> Measured {
    let start = Instant::now();
    let o = Command::new("python3")
        .arg("-c")
        .arg(LAUNCHER)
        .arg(env!("CARGO_BIN_EXE_volcast"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .output()
        .expect("python3 runs (it starts the measured volcast process)");
    let elapsed = start.elapsed();
    let report = String::from_utf8_lossy(&o.stdout);
    let mut words = report.split_whitespace();
    let code: i32 = words
        .next()
        .and_then(|w| w.parse().ok())
        .expect("an exit code");
    let kib: u64 = words
        .next()
        .and_then(|w| w.parse().ok())
        .expect("ru_maxrss");
    Measured {
        code: (code >= 0).then_some(code),
        stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
        elapsed,
        peak_rss: kib * 1024,
    }
}
