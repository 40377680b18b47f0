//! `--confine DIR` (issue 10, item 7): the scene's volume path, every `data file`
//! and the output folder must lie under DIR after resolving `..` and links.

use std::path::Path;

use crate::util::volcast;

const HEAD: &str = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n";

fn scene(dir: &Path, volume: &str) {
    std::fs::write(
        dir.join("s.toml"),
        format!("[volume]\npath = \"{volume}\"\nwindow = [0, 255]\n[image]\nsize = [8, 8]\n[[render]]\nmode = \"mip\"\nwindow = [0, 1]\n"),
    )
    .unwrap();
}

fn refused(dir: &Path, args: &[&str], needles: &[&str]) {
    let o = volcast(dir, args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: expected {n:?} in {err}");
    }
}

#[test]
fn data_files_outside_the_folder_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    // a file outside the submission folder, standing for a system file
    let secret = tmp.path().join("secret.txt");
    std::fs::write(&secret, b"password=hunter2").unwrap();
    let sub = tmp.path().join("submission");
    std::fs::create_dir(&sub).unwrap();
    // the reproducer: an absolute `data file` with `byte skip: -1` renders the last
    // bytes of any readable file
    std::fs::write(
        sub.join("v.nhdr"),
        format!("{HEAD}byte skip: -1\ndata file: {}\n", secret.display()),
    )
    .unwrap();
    scene(&sub, "v.nhdr");
    let o = volcast(&sub, &["render", "s.toml", "--out", "open"]);
    assert!(
        o.status.success(),
        "without --confine it renders (documented)"
    );
    for cmd in ["render", "check"] {
        refused(
            &sub,
            &[cmd, "s.toml", "--out", "out", "--confine", "."],
            &[
                "secret.txt",
                "a data file named by",
                "is outside",
                "(--confine)",
            ],
        );
    }
    assert!(!sub.join("out").exists());
    // the same through `..`, through a link inside the folder, and in a LIST
    let cases = [
        format!("{HEAD}byte skip: -1\ndata file: ../secret.txt\n"),
        format!("{HEAD}byte skip: -1\ndata file: link.txt\n"),
        format!("{HEAD}data file: LIST 2\nok.raw\n../secret.txt\n"),
    ];
    #[cfg(unix)]
    std::os::unix::fs::symlink(&secret, sub.join("link.txt")).unwrap();
    std::fs::write(sub.join("ok.raw"), [1u8; 4]).unwrap();
    for (i, text) in cases.iter().enumerate() {
        if cfg!(not(unix)) && i == 1 {
            continue;
        }
        std::fs::write(sub.join("v.nhdr"), text).unwrap();
        refused(
            &sub,
            &["render", "s.toml", "--out", "out", "--confine", "."],
            &["is outside", "secret.txt"],
        );
    }
    assert!(!sub.join("out").exists());
}

#[test]
fn volume_paths_and_output_folders_outside_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let sub = tmp.path().join("submission");
    std::fs::create_dir(&sub).unwrap();
    let mut inside = HEAD.as_bytes().to_vec();
    inside.extend(b"\n\x01\x02\x03\x04\x05\x06\x07\x08");
    std::fs::write(tmp.path().join("outside.nrrd"), &inside).unwrap();
    std::fs::write(sub.join("inside.nrrd"), &inside).unwrap();
    // the volume itself outside
    scene(&sub, "../outside.nrrd");
    refused(
        &sub,
        &["render", "s.toml", "--out", "out", "--confine", "."],
        &["outside.nrrd", "the volume is outside"],
    );
    // a raw volume outside
    std::fs::write(
        sub.join("r.toml"),
        "[volume]\npath = \"../outside.nrrd\"\nformat = \"raw\"\nsizes = [2, 2, 2]\ntype = \"uint8\"\noffset = -1\n[[render]]\nmode = \"mip\"\n",
    )
    .unwrap();
    refused(
        &sub,
        &["render", "r.toml", "--out", "out", "--confine", "."],
        &["the raw volume is outside"],
    );
    // the output folder outside, directly or through `..`
    scene(&sub, "inside.nrrd");
    for out in ["../out", "a/../../out"] {
        refused(
            &sub,
            &["render", "s.toml", "--out", out, "--confine", "."],
            &["the output folder is outside"],
        );
    }
    assert!(!tmp.path().join("out").exists());
    // inside: renders, also through a link that stays inside
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink("inside.nrrd", sub.join("alias.nrrd")).unwrap();
        scene(&sub, "alias.nrrd");
    }
    let o = volcast(
        &sub,
        &["render", "s.toml", "--out", "a/b/out", "--confine", "."],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(sub.join("a/b/out/mip_0000.png").is_file());
    // --confine names a folder that exists
    refused(
        &sub,
        &["render", "s.toml", "--confine", "nowhere"],
        &["nowhere"],
    );
}
