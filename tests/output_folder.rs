//! A shared output folder where someone else planted symbolic links (issue 10,
//! item 1): volcast never writes through a link, at a temporary name, at a final
//! name or at `manifest.d`, and a link at `manifest.d` or `manifest.json` is an error.
//! A frame that cannot be written ends the run, naming it.

#![cfg(unix)]

use std::os::unix::fs::symlink;
use std::path::Path;
use std::process::{Command, Stdio};

use crate::util::volcast;

const SCENE: &str = "[volume]\nsynthetic = \"ball\"\nsizes = [8, 8, 8]\n\
    [orbit]\nframes = 3\n[image]\nsize = [12, 10]\n[[render]]\nmode = \"mip\"\n";

fn setup() -> (tempfile::TempDir, std::path::PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("s.toml"), SCENE).unwrap();
    let victim = tmp.path().join("victim.txt");
    std::fs::write(&victim, b"precious").unwrap();
    (tmp, victim)
}

fn host() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .unwrap_or_default()
}

#[test]
fn links_at_final_names_are_replaced_not_followed() {
    let (tmp, victim) = setup();
    let dir = tmp.path();
    let out = dir.join("out");
    std::fs::create_dir(&out).unwrap();
    for name in ["mip_0000.png", "mip_0001.png", "mip.gif"] {
        symlink(&victim, out.join(name)).unwrap();
    }
    let o = volcast(dir, &["render", "s.toml", "--out", "out", "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    for name in ["mip_0000.png", "mip_0001.png"] {
        let meta = std::fs::symlink_metadata(out.join(name)).unwrap();
        assert!(meta.is_file(), "{name} is a regular file now");
    }
}

#[test]
fn links_at_the_old_temporary_names_are_never_opened() {
    let (tmp, victim) = setup();
    let dir = tmp.path();
    let out = dir.join("out");
    std::fs::create_dir_all(out.join("manifest.d")).unwrap();
    // The temporary names of earlier versions were predictable from the process ID:
    // plant links at those of the process as soon as it exists.
    let child = Command::new(env!("CARGO_BIN_EXE_volcast"))
        .args(["render", "s.toml", "--out", "out", "--quiet"])
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let tag = format!("{}@{}", child.id(), host());
    for k in 0..3 {
        let _ = symlink(&victim, out.join(format!(".mip_{k:04}.png.{tag}.tmp")));
        let _ = symlink(
            &victim,
            out.join(format!("manifest.d/.mip_{k:04}.json.{tag}.tmp")),
        );
    }
    let _ = symlink(&victim, out.join(format!(".manifest.json.{tag}.tmp")));
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    for k in 0..3 {
        let p = out.join(format!("mip_{k:04}.png"));
        assert!(std::fs::symlink_metadata(&p).unwrap().is_file(), "{p:?}");
    }
}

fn refused(dir: &Path, what: &str) -> String {
    let o = volcast(dir, &["render", "s.toml", "--out", "out", "--quiet"]);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "{what}: {err}");
    assert!(err.contains("is a symbolic link"), "{what}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

#[test]
fn a_link_at_manifest_d_or_manifest_json_is_an_error() {
    let (tmp, victim) = setup();
    let dir = tmp.path();
    let out = dir.join("out");
    std::fs::create_dir(&out).unwrap();
    let elsewhere = dir.join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    symlink(&elsewhere, out.join("manifest.d")).unwrap();
    let err = refused(dir, "manifest.d");
    assert!(err.contains("manifest.d"), "{err}");
    assert_eq!(
        std::fs::read_dir(&elsewhere).unwrap().count(),
        0,
        "nothing was written through the link"
    );
    // a link to a file there is refused alike
    std::fs::remove_file(out.join("manifest.d")).unwrap();
    symlink(&victim, out.join("manifest.d")).unwrap();
    refused(dir, "manifest.d to a file");
    std::fs::remove_file(out.join("manifest.d")).unwrap();

    symlink(&victim, out.join("manifest.json")).unwrap();
    let err = refused(dir, "manifest.json");
    assert!(err.contains("manifest.json"), "{err}");
    assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
}

#[test]
fn a_planted_record_link_is_not_read() {
    let (tmp, _) = setup();
    let dir = tmp.path();
    let o = volcast(dir, &["render", "s.toml", "--out", "out", "--quiet"]);
    assert!(o.status.success());
    // a record replaced by a link to a FIFO would block a reader that follows it
    let out = dir.join("out");
    let fifo = dir.join("fifo");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    std::fs::remove_file(out.join("manifest.d/mip_0001.json")).unwrap();
    symlink(&fifo, out.join("manifest.d/mip_0001.json")).unwrap();
    let o = volcast(dir, &["render", "s.toml", "--out", "out", "--resume"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("mip_0001.json") && err.contains("is a symbolic link"),
        "{err}"
    );
}

#[test]
fn a_frame_that_cannot_be_written_ends_the_run_with_its_name() {
    // ten frames on two threads: batches of four, each written (by a thread of its
    // own) while the next renders; a folder at frame 5's name makes its rename fail
    let tmp = tempfile::tempdir().unwrap();
    let scene = SCENE.replace("frames = 3", "frames = 10");
    std::fs::write(tmp.path().join("s.toml"), scene).unwrap();
    let out = tmp.path().join("out");
    std::fs::create_dir_all(out.join("mip_0005.png")).unwrap();
    let o = volcast(
        tmp.path(),
        &[
            "render",
            "s.toml",
            "--out",
            "out",
            "--quiet",
            "--threads",
            "2",
        ],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains("mip_0005.png"), "{err}");
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    // the frames before it are written whole, none after its batch, and no
    // temporary file is left
    for k in 0..5 {
        let f = out.join(format!("mip_{k:04}.png"));
        assert!(
            f.is_file() && std::fs::metadata(&f).unwrap().len() > 0,
            "{names:?}"
        );
    }
    assert!(out.join("mip_0005.png").is_dir());
    for k in 8..10 {
        assert!(!out.join(format!("mip_{k:04}.png")).exists(), "{names:?}");
    }
    assert!(!names.iter().any(|n| n.ends_with(".tmp")), "{names:?}");
}

/// A run that cannot write its files is refused before it writes anything (issue
/// 48, item 6): a pass name too long for a file name fails `check` and `render`
/// alike, with nothing left behind.
#[test]
fn a_name_too_long_for_a_file_is_refused_before_anything_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let name = "n".repeat(250);
    let scene = format!("{SCENE}name = \"{name}\"\n");
    std::fs::write(dir.join("s.toml"), scene).unwrap();
    for cmd in ["check", "render"] {
        let o = volcast(dir, &[cmd, "s.toml", "--out", "o"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{cmd}: {err}");
        assert!(
            err.contains("[[render]] name") && err.contains("too long for a file name"),
            "{cmd}: {err}"
        );
        assert!(!dir.join("o").exists(), "{cmd} left the output folder");
    }
    // a name that fits is rendered
    let scene = format!("{SCENE}name = \"{}\"\n", "n".repeat(100));
    std::fs::write(dir.join("s.toml"), scene).unwrap();
    let o = volcast(dir, &["render", "s.toml", "--out", "o", "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A run that fails removes every folder it created on the way to its output
/// folder, also along a path through `..` (issue 48, item 6).
#[test]
fn a_failed_run_leaves_no_folders_along_a_path_through_dot_dot() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    std::fs::write(dir.join("s.toml"), SCENE).unwrap();
    // enough `..` to reach / from any temporary folder: /proc takes no new folder
    let out = format!("newdir/up/{}proc/x", "../".repeat(40));
    let o = volcast(dir, &["render", "s.toml", "--out", &out]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(
        !dir.join("newdir").exists(),
        "left {:?} ({err})",
        std::fs::read_dir(dir.join("newdir"))
            .map(|d| d.map(|e| e.unwrap().path()).collect::<Vec<_>>())
            .ok()
    );
}
