//! One exit status per kind of outcome (issue 10, item 5): 0 success (also when the
//! reader of standard output closes it early), 1 any error with one message, 2
//! command-line usage errors. Never a panic's 101 nor an abort's 134.

use std::path::Path;
use std::process::{Command, Output, Stdio};

use crate::util::volcast;

const SCENE: &str = "[volume]\nsynthetic = \"ball\"\nsizes = [8, 8, 8]\n\
    [image]\nsize = [8, 8]\n[[render]]\nmode = \"mip\"\n";

fn setup() -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("s.toml"), SCENE).unwrap();
    tmp
}

/// Runs volcast with its standard output connected to a pipe whose reading end is
/// already closed (`volcast ... | true`, deterministically).
#[cfg(unix)]
fn into_closed_pipe(dir: &Path, args: &[&str]) -> Output {
    use std::os::fd::{FromRawFd, OwnedFd};
    let mut fds = [0i32; 2];
    // SAFETY: pipe writes two new descriptors into the array it is given.
    assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0);
    // SAFETY: both descriptors were just created and are owned by nobody else.
    let (read, write) = unsafe { (OwnedFd::from_raw_fd(fds[0]), OwnedFd::from_raw_fd(fds[1])) };
    drop(read);
    Command::new(env!("CARGO_BIN_EXE_volcast"))
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::from(write))
        .stderr(Stdio::piped())
        .output()
        .unwrap()
}

#[cfg(unix)]
#[test]
fn a_closed_output_pipe_ends_quietly() {
    let tmp = setup();
    let dir = tmp.path();
    for args in [
        &["check", "s.toml"][..],
        &["info", "s.toml"],
        &["info", "s.toml", "--json"],
        &["--help"],
    ] {
        let o = into_closed_pipe(dir, args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(0), "{args:?}: {err}");
        assert!(err.is_empty(), "{args:?} printed {err}");
    }
}

fn status(o: &Output) -> Option<i32> {
    o.status.code()
}

#[test]
fn usage_errors_are_2_and_other_errors_1() {
    let tmp = setup();
    let dir = tmp.path();
    for args in [
        &["render"][..],
        &["render", "s.toml", "--bogus"],
        &["render", "s.toml", "--frames", "5..2"],
        &["render", "s.toml", "--frames", "18446744073709551615"],
        &["render", "s.toml", "--size", "0x10"],
        &["render", "s.toml", "--max-memory", "lots"],
        &["render", "s.toml", "--threads", "0"],
        &["render", "s.toml", "--shard", "4/4"],
        &["frobnicate"],
    ] {
        let o = volcast(dir, args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(status(&o), Some(2), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    let o = volcast(
        dir,
        &["render", "s.toml", "--frames", "18446744073709551615"],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("too large") && !err.contains("empty range"),
        "{err}"
    );
    for args in [
        &["render", "missing.toml"][..],
        &["check", "missing.toml"],
        &["info", "missing.nrrd"],
        &["render", "s.toml", "--frames", "3"],
        &["render", "s.toml", "--shard", "auto"],
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_volcast"))
            .args(args)
            .current_dir(dir)
            .env_remove("SLURM_ARRAY_TASK_ID")
            .env_remove("SLURM_ARRAY_TASK_COUNT")
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(status(&o), Some(1), "{args:?}: {err}");
        assert_eq!(
            err.matches("volcast: error:").count(),
            1,
            "one message: {err}"
        );
    }
    for args in [&["--help"][..], &["--version"], &["check", "s.toml"]] {
        assert_eq!(status(&volcast(dir, args)), Some(0), "{args:?}");
    }
}
