//! `--resume` trusts nothing it can check cheaply (issue 10, item 4): kept images
//! must have their recorded SHA-256, animations whose bytes differ from their record
//! are rebuilt, the scene hash covers the voxel data (hashed while decoding), a run
//! with nothing left to render trusts volume files of the recorded size and
//! modification time instead of decoding them, and an older manifest is said so.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

use crate::util::volcast;

fn ok(dir: &Path, args: &[&str]) -> String {
    let o = volcast(dir, args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{args:?}: {err}");
    err
}

fn files(dir: &Path, ext: &str) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect()
}

/// Flips one byte in the middle of a file, keeping its size and modification time.
fn flip_byte(path: &Path) {
    let modified = std::fs::metadata(path).unwrap().modified().unwrap();
    let mut b = std::fs::read(path).unwrap();
    let i = b.len() / 2;
    b[i] ^= 0x55;
    std::fs::write(path, &b).unwrap();
    let f = std::fs::File::options().write(true).open(path).unwrap();
    f.set_modified(modified).unwrap();
}

const SCENE: &str = "[volume]\nsynthetic = \"marschner-lobb\"\nsizes = [12, 12, 12]\n\
    [orbit]\nframes = 4\n[image]\nsize = [16, 12]\n[animation]\nformats = [\"gif\", \"apng\"]\nfps = 10\n\
    [[render]]\nmode = \"mip\"\n";

#[test]
fn damaged_images_and_animations_are_repaired() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    std::fs::write(dir.join("s.toml"), SCENE).unwrap();
    ok(dir, &["render", "s.toml", "--out", "o", "--quiet"]);
    let out = dir.join("o");
    let pngs = files(&out, "png");
    let gif = std::fs::read(out.join("mip.gif")).unwrap();
    let apng = std::fs::read(out.join("mip.apng")).unwrap();
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    let entry = &m["animation"]["files"][0];
    assert_eq!(entry["file"], "mip.gif");
    assert_eq!(entry["bytes"], gif.len());
    assert_eq!(entry["sha256"].as_str().unwrap().len(), 64);
    assert_eq!(entry["frames_sha256"].as_str().unwrap().len(), 64);

    // nothing damaged: nothing rendered, no animation rebuilt
    let err = ok(dir, &["render", "s.toml", "--out", "o", "--resume"]);
    assert!(
        err.contains("0 files (0 views rendered, 4 images already complete"),
        "{err}"
    );
    assert!(!err.contains("volcast: animation"), "{err}");

    // the reproducer: a flipped byte in a finished PNG (same size) survived a resume
    // and then broke every later animation rebuild with a CRC error
    flip_byte(&out.join("mip_0002.png"));
    let err = ok(dir, &["render", "s.toml", "--out", "o", "--resume"]);
    assert!(err.contains("volcast: 1 files"), "{err}");
    assert!(err.contains("3 images already complete"), "{err}");
    assert_eq!(files(&out, "png"), pngs, "the image was rendered again");
    assert_eq!(std::fs::read(out.join("mip.gif")).unwrap(), gif);

    // a corrupted GIF and APNG are rebuilt, though no frame is re-rendered
    flip_byte(&out.join("mip.gif"));
    flip_byte(&out.join("mip.apng"));
    let err = ok(dir, &["render", "s.toml", "--out", "o", "--resume"]);
    assert!(err.contains("volcast: 0 files"), "{err}");
    assert!(err.contains("volcast: animation"), "{err}");
    assert_eq!(std::fs::read(out.join("mip.gif")).unwrap(), gif);
    assert_eq!(std::fs::read(out.join("mip.apng")).unwrap(), apng);

    // an image replaced by a link to a copy of itself is not trusted either
    #[cfg(unix)]
    {
        std::fs::copy(out.join("mip_0001.png"), dir.join("copy.png")).unwrap();
        std::fs::remove_file(out.join("mip_0001.png")).unwrap();
        std::os::unix::fs::symlink(dir.join("copy.png"), out.join("mip_0001.png")).unwrap();
        let err = ok(dir, &["render", "s.toml", "--out", "o", "--resume"]);
        assert!(err.contains("volcast: 1 files"), "{err}");
        assert!(std::fs::symlink_metadata(out.join("mip_0001.png"))
            .unwrap()
            .is_file());
    }
}

/// A 12^3 uint8 volume of a smooth blob, as raw bytes.
fn blob() -> Vec<u8> {
    let n = 12i32;
    let mut v = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r2 = (i - 6).pow(2) + (j - 5).pow(2) + (k - 6).pow(2);
                v.push((250 - 6 * r2).clamp(0, 255) as u8);
            }
        }
    }
    v
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

const HEAD: &str = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 12 12 12\n";

fn write_volumes(dir: &Path, data: &[u8]) {
    // raw, memory-mapped
    std::fs::write(dir.join("v.raw"), data).unwrap();
    // gzip, decoded
    let mut nrrd = format!("{HEAD}encoding: gzip\n\n").into_bytes();
    nrrd.extend(gzip(data));
    std::fs::write(dir.join("v.nrrd"), nrrd).unwrap();
    // detached raw data file
    std::fs::write(
        dir.join("d.nhdr"),
        format!("{HEAD}encoding: raw\ndata file: d.dat\n"),
    )
    .unwrap();
    std::fs::write(dir.join("d.dat"), data).unwrap();
}

#[test]
fn the_scene_hash_covers_the_voxel_data() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let data = blob();
    write_volumes(dir, &data);
    for (name, volume) in [
        (
            "raw",
            "path = \"v.raw\"\nsizes = [12, 12, 12]\ntype = \"uint8\"",
        ),
        ("gzip", "path = \"v.nrrd\""),
        ("detached", "path = \"d.nhdr\""),
    ] {
        std::fs::write(
            dir.join(format!("{name}.toml")),
            format!("[volume]\n{volume}\nwindow = [0, 255]\n[orbit]\nframes = 2\n[image]\nsize = [16, 16]\n[[render]]\nmode = \"mip\"\nwindow = [0, 1]\n"),
        )
        .unwrap();
        ok(
            dir,
            &["render", &format!("{name}.toml"), "--out", name, "--quiet"],
        );
    }
    let before: Vec<_> = ["raw", "gzip", "detached"]
        .iter()
        .map(|n| files(&dir.join(n), "png"))
        .collect();
    assert_eq!(before[0], before[1]);

    // unchanged voxels in touched files: hashed again, and the images kept
    write_volumes(dir, &data);
    for name in ["raw", "gzip", "detached"] {
        let err = ok(
            dir,
            &["render", &format!("{name}.toml"), "--out", name, "--resume"],
        );
        assert!(err.contains("2 images already complete"), "{name}: {err}");
    }

    // the reproducer: inverting every voxel kept the old images
    let inverted: Vec<u8> = data.iter().map(|v| 255 - v).collect();
    write_volumes(dir, &inverted);
    for (i, name) in ["raw", "gzip", "detached"].iter().enumerate() {
        let err = ok(
            dir,
            &["render", &format!("{name}.toml"), "--out", name, "--resume"],
        );
        assert!(err.contains("volcast: 2 files"), "{name}: {err}");
        assert!(!err.contains("already complete"), "{name}: {err}");
        let now = files(&dir.join(name), "png");
        assert!(
            now.iter().all(|(n, b)| before[i][n] != *b),
            "{name}: every image changed"
        );
    }
}

#[test]
fn nothing_left_to_render_trusts_unchanged_volume_files() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    write_volumes(dir, &blob());
    std::fs::write(
        dir.join("s.toml"),
        "[volume]\npath = \"v.nrrd\"\nwindow = [0, 255]\n[orbit]\nframes = 2\n[image]\nsize = [16, 16]\n[[render]]\nmode = \"mip\"\n",
    )
    .unwrap();
    ok(dir, &["render", "s.toml", "--out", "o", "--quiet"]);
    // Damage the gzip data but keep the file's size and modification time: a run
    // that decoded it would fail. With nothing left to render, it is not decoded.
    flip_byte(&dir.join("v.nrrd"));
    let err = ok(dir, &["render", "s.toml", "--out", "o", "--resume"]);
    assert!(err.contains("2 images already complete"), "{err}");
    let check = volcast(dir, &["check", "s.toml", "--out", "o", "--resume"]);
    let plan = String::from_utf8_lossy(&check.stdout);
    assert!(plan.contains("resume   2 of 2 images"), "{plan}");
    // once its modification time changes, it is decoded (and found damaged)
    let f = std::fs::File::options()
        .write(true)
        .open(dir.join("v.nrrd"))
        .unwrap();
    f.set_modified(std::time::SystemTime::now() + std::time::Duration::from_secs(5))
        .unwrap();
    let check = volcast(dir, &["check", "s.toml", "--out", "o", "--resume"]);
    let plan = String::from_utf8_lossy(&check.stdout);
    assert!(plan.contains("render --resume hashes the voxels"), "{plan}");
    let o = volcast(dir, &["render", "s.toml", "--out", "o", "--resume"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("v.nrrd") && err.contains("gzip data"), "{err}");
}

#[test]
fn an_older_manifest_is_said_so_and_its_images_rendered_again() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    std::fs::write(dir.join("s.toml"), SCENE).unwrap();
    ok(dir, &["render", "s.toml", "--out", "o", "--quiet"]);
    let out = dir.join("o");
    let path = out.join("manifest.json");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("volcast-manifest-2", "volcast-manifest-1");
    std::fs::write(&path, text).unwrap();
    for f in std::fs::read_dir(out.join("manifest.d")).unwrap() {
        let p = f.unwrap().path();
        let t = std::fs::read_to_string(&p).unwrap();
        let v: serde_json::Value = serde_json::from_str(&t).unwrap();
        let h = v["scene_hash"].as_str().unwrap().to_string();
        std::fs::write(&p, t.replace(&h, &"1".repeat(64))).unwrap();
    }
    let err = ok(dir, &["render", "s.toml", "--out", "o", "--resume"]);
    assert!(
        err.contains("was written by an older volcast (volcast-manifest-1)"),
        "{err}"
    );
    assert!(err.contains("volcast: 4 files"), "{err}");
    let m: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    assert_eq!(m["format"], "volcast-manifest-2");
    assert_eq!(m["complete"], true);
}

/// A record names only the files the plan gives its (pass, frame) (issue 48, item
/// 2): one edited to name a file outside the output folder, even one with the
/// recorded bytes, is damaged. `--finish-only` reports it and neither opens that file
/// nor lists it in the manifest, the page or the animations; `--resume` renders the
/// frame again. An empty record is damaged too (item 7): `--resume` says so and
/// renders that frame again instead of failing.
#[test]
fn records_naming_other_files_are_damaged() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    std::fs::write(dir.join("s.toml"), SCENE).unwrap();
    ok(
        dir,
        &["render", "s.toml", "--out", "o", "--viewer", "--quiet"],
    );
    let out = dir.join("o");
    let frame1 = std::fs::read(out.join("mip_0001.png")).unwrap();
    std::fs::write(dir.join("outside_copy.png"), &frame1).unwrap();
    let record = out.join("manifest.d/mip_0001.json");
    let original: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&record).unwrap()).unwrap();
    let outside = dir.join("outside_copy.png");
    for name in [
        "../outside_copy.png",
        outside.to_str().unwrap(),
        "mip_0002.png",
    ] {
        let mut r = original.clone();
        r["files"][0]["name"] = name.into();
        std::fs::write(&record, serde_json::to_vec(&r).unwrap()).unwrap();
        let o = volcast(
            dir,
            &[
                "render",
                "s.toml",
                "--out",
                "o",
                "--viewer",
                "--finish-only",
                "--confine",
                "o",
            ],
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("mip_0001.json") && err.contains("treated as damaged"),
            "{name}: {err}"
        );
        let m: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
        assert_eq!(m["complete"], false, "{name}");
        assert_eq!(m["images_done"], 3, "{name}");
        let listed = m["frames"].to_string();
        assert!(!listed.contains("outside_copy"), "{name}: {listed}");
        let page = std::fs::read_to_string(out.join("index.html")).unwrap();
        assert!(!page.contains("outside_copy"), "{name}");
    }
    // --resume renders that frame again, into its own file and record
    std::fs::remove_file(out.join("mip_0001.png")).unwrap();
    std::fs::write(out.join("manifest.d/mip_0002.json"), b"").unwrap();
    let err = ok(
        dir,
        &["render", "s.toml", "--out", "o", "--viewer", "--resume"],
    );
    assert!(
        err.contains("mip_0002.json") && err.contains("rendered again"),
        "{err}"
    );
    assert_eq!(std::fs::read(out.join("mip_0001.png")).unwrap(), frame1);
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(m["complete"], true);
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&record).unwrap()).unwrap();
    assert_eq!(r["files"][0]["name"], "mip_0001.png");
    assert!(out.join("mip.gif").exists() && out.join("index.html").exists());
}
