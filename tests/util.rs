//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

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
