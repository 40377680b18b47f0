//! Batch runs: shards render disjoint frames whose union is the full run byte for
//! byte (sequentially or at once), `--resume` finishes killed or damaged runs with
//! the same bytes and re-renders a changed scene, the manifest reproduces the run,
//! and the animations hold every frame.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use crate::util::volcast;

/// 7 frames, toe-in pair (reused views), an automatic grey window, a colour pass,
/// and both animations.
const SCENE: &str = "[volume]\nsynthetic = \"marschner-lobb\"\nsizes = [14, 14, 14]\n\
    [orbit]\nframes = 7\ndegrees = 70.0\n[stereo]\nangle = 10.0\nlayout = \"pair\"\n\
    [image]\nsize = [20, 16]\n[animation]\nformats = [\"gif\", \"apng\"]\nfps = 10\n\
    [[render]]\nmode = \"mip\"\n[[render]]\nmode = \"composite\"\ntransfer = \"bone\"\n";

/// Runs volcast with extra environment variables (and no Slurm ones of our own).
fn volcast_env(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_volcast"));
    c.args(args).current_dir(dir);
    for (k, _) in std::env::vars() {
        if k.starts_with("SLURM_") {
            c.env_remove(k);
        }
    }
    c.envs(env.iter().copied());
    c.output().expect("the volcast binary runs")
}

fn ok(o: &Output) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    err
}

fn render(dir: &Path, out: &str, extra: &[&str]) -> String {
    let mut args = vec!["render", "s.toml", "--out", out];
    args.extend_from_slice(extra);
    ok(&volcast(dir, &args))
}

/// Files of a folder with one of the extensions, by name.
fn files(dir: &Path, exts: &[&str]) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| exts.iter().any(|x| e == *x)))
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect()
}

fn images(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    files(dir, &["png"])
}

fn manifest(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap()
}

fn temporaries(dir: &Path) -> Vec<PathBuf> {
    let mut v = Vec::new();
    for d in [dir.to_path_buf(), dir.join("manifest.d")] {
        if let Ok(rd) = std::fs::read_dir(&d) {
            v.extend(
                rd.map(|e| e.unwrap().path())
                    .filter(|p| p.to_string_lossy().ends_with(".tmp")),
            );
        }
    }
    v
}

fn setup(scene: &str) -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("s.toml"), scene).unwrap();
    tmp
}

#[test]
fn shards_together_are_the_full_run_byte_for_byte() {
    let tmp = setup(SCENE);
    let dir = tmp.path();
    render(dir, "full", &["--quiet"]);
    let full = images(&dir.join("full"));
    assert_eq!(full.len(), 7 * 2 * 2);
    let full_anim = files(&dir.join("full"), &["gif", "apng"]);
    assert_eq!(full_anim.len(), 2 * 2 * 2, "{:?}", full_anim.keys());
    assert_eq!(manifest(&dir.join("full"))["complete"], true);

    // one shard alone: its frames only, the same bytes (same grey window), no animation
    let err = render(dir, "alone", &["--shard", "2/3"]);
    let alone = images(&dir.join("alone"));
    let names: Vec<&str> = alone.keys().map(|s| s.as_str()).collect();
    assert_eq!(
        names,
        [
            "composite_0002_left.png",
            "composite_0002_right.png",
            "composite_0005_left.png",
            "composite_0005_right.png",
            "mip_0002_left.png",
            "mip_0002_right.png",
            "mip_0005_left.png",
            "mip_0005_right.png"
        ]
    );
    for (n, b) in &alone {
        assert_eq!(Some(b), full.get(n), "{n} differs from the unsharded run");
    }
    assert!(files(&dir.join("alone"), &["gif", "apng"]).is_empty());
    assert!(err.contains("4 of 14 images done"), "{err}");
    assert_eq!(manifest(&dir.join("alone"))["complete"], false);

    // all shards, one after the other, into one folder: the full run, animations included
    for k in 0..3 {
        render(dir, "sharded", &["--quiet", "--shard", &format!("{k}/3")]);
    }
    assert!(images(&dir.join("sharded")) == full, "shards differ");
    assert!(
        files(&dir.join("sharded"), &["gif", "apng"]) == full_anim,
        "animations differ"
    );
    let m = manifest(&dir.join("sharded"));
    assert_eq!(m["complete"], true);
    assert_eq!(m["frames"].as_array().unwrap().len(), 14);

    // a shard of a range
    render(
        dir,
        "range",
        &["--quiet", "--frames", "1..6", "--shard", "1/2"],
    );
    let names: Vec<String> = images(&dir.join("range"))
        .into_keys()
        .filter(|n| n.starts_with("mip") && n.ends_with("left.png"))
        .collect();
    assert_eq!(names, ["mip_0002_left.png", "mip_0004_left.png"]);
}

#[test]
fn concurrent_shards_do_not_clobber_the_manifest() {
    let tmp = setup(SCENE);
    let dir = tmp.path();
    render(dir, "full", &["--quiet"]);
    let children: Vec<_> = (0..3)
        .map(|k| {
            Command::new(env!("CARGO_BIN_EXE_volcast"))
                .args([
                    "render",
                    "s.toml",
                    "--quiet",
                    "--out",
                    "par",
                    "--threads",
                    "1",
                ])
                .args(["--shard", &format!("{k}/3")])
                .current_dir(dir)
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for c in children {
        let o = c.wait_with_output().unwrap();
        ok(&o);
    }
    let par = dir.join("par");
    assert!(images(&par) == images(&dir.join("full")));
    let m = manifest(&par);
    assert_eq!(m["complete"], true, "{m:#}");
    let mut seen: Vec<(String, u64)> = m["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            (
                f["pass"].as_str().unwrap().to_string(),
                f["frame"].as_u64().unwrap(),
            )
        })
        .collect();
    seen.sort();
    seen.dedup();
    assert_eq!(seen.len(), 14);
    let shards: std::collections::BTreeSet<&str> = m["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["shard"].as_str().unwrap())
        .collect();
    assert_eq!(shards.len(), 3, "records of every shard: {shards:?}");
    assert_eq!(files(&par, &["gif", "apng"]).len(), 8);
    assert!(temporaries(&par).is_empty());
}

#[test]
fn resume_finishes_a_killed_run_with_the_same_bytes() {
    // enough work that a kill lands in the middle: 40 frames, one thread
    let scene = SCENE
        .replace("frames = 7\ndegrees = 70.0", "frames = 40\ndegrees = 400.0")
        .replace("size = [20, 16]", "size = [40, 32]")
        .replace("sizes = [14, 14, 14]", "sizes = [24, 24, 24]");
    let tmp = setup(&scene);
    let dir = tmp.path();
    render(dir, "full", &["--quiet"]);
    let full = images(&dir.join("full"));
    let out = dir.join("killed");
    let mut child = Command::new(env!("CARGO_BIN_EXE_volcast"))
        .args([
            "render",
            "s.toml",
            "--quiet",
            "--threads",
            "1",
            "--out",
            "killed",
        ])
        .current_dir(dir)
        .spawn()
        .unwrap();
    let start = Instant::now();
    while images_present(&out) < 4 && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    // only complete images: every PNG present decodes
    let partial = images(&out);
    for (n, b) in &partial {
        assert!(image::load_from_memory(b).is_ok(), "{n} is truncated");
        assert_eq!(Some(b), full.get(n), "{n}");
    }
    let err = render(dir, "killed", &["--resume"]);
    let skipped = err
        .split(", ")
        .find_map(|s| s.strip_suffix(" images already complete"))
        .map_or(0, |n| n.parse::<usize>().unwrap());
    if partial.len() < full.len() {
        // the kill landed mid-run: the finished images were not rendered again
        assert!(skipped >= (partial.len() / 2).saturating_sub(1), "{err}");
        assert!(skipped < 80, "{err}");
    }
    assert!(
        images(&out) == full,
        "resumed images differ from a whole run"
    );
    if Path::new("/proc/self").exists() {
        assert!(temporaries(&out).is_empty(), "{:?}", temporaries(&out));
    }
    assert_eq!(manifest(&out)["complete"], true);
    assert!(files(&out, &["gif", "apng"]) == files(&dir.join("full"), &["gif", "apng"]));
}

fn images_present(dir: &Path) -> usize {
    std::fs::read_dir(dir).map_or(0, |rd| {
        rd.filter(|e| {
            e.as_ref()
                .is_ok_and(|e| e.file_name().to_string_lossy().ends_with(".png"))
        })
        .count()
    })
}

fn host() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .unwrap_or_default()
}

#[test]
fn resume_repairs_damage_and_rerenders_a_changed_scene() {
    let tmp = setup(SCENE);
    let dir = tmp.path();
    render(dir, "full", &["--quiet"]);
    let full = images(&dir.join("full"));
    render(dir, "run", &["--quiet"]);
    let out = dir.join("run");
    // nothing to do: nothing rendered
    let err = render(dir, "run", &["--resume"]);
    assert!(
        err.contains("0 files (0 views rendered, 14 images already complete"),
        "{err}"
    );
    // two images lost, one record from another scene, one stale temporary file
    std::fs::remove_file(out.join("mip_0003_right.png")).unwrap();
    std::fs::remove_file(out.join("composite_0006_left.png")).unwrap();
    let rec = out.join("manifest.d/mip_0005.json");
    let text = std::fs::read_to_string(&rec).unwrap();
    let hash = manifest(&out)["scene_hash"].as_str().unwrap().to_string();
    std::fs::write(&rec, text.replace(&hash, &"0".repeat(64))).unwrap();
    let stale = out.join(format!(".mip_0001_left.png.4294967295@{}.tmp", host()));
    std::fs::write(&stale, b"partial").unwrap();
    let check = volcast(dir, &["check", "s.toml", "--out", "run", "--resume"]);
    let plan = String::from_utf8_lossy(&check.stdout);
    assert!(plan.contains("resume   11 of 14 images"), "{plan}");
    let err = render(dir, "run", &["--resume"]);
    assert!(
        err.contains("volcast: 6 files"),
        "3 (pass, frame) images of 2 eyes: {err}"
    );
    assert!(err.contains("11 images already complete"), "{err}");
    assert!(images(&out) == full);
    if Path::new("/proc/self").exists() {
        assert!(!stale.exists(), "the stale temporary file was removed");
    }
    // a changed scene renders everything again
    let changed = SCENE.replace("[image]\n", "[camera]\nzoom = 1.3\n[image]\n");
    std::fs::write(dir.join("s.toml"), &changed).unwrap();
    let err = render(dir, "run", &["--resume"]);
    assert!(err.contains("volcast: 28 files"), "{err}");
    assert!(!err.contains("already complete"), "{err}");
    let now = images(&out);
    assert_eq!(now.len(), full.len());
    assert!(
        now.iter().all(|(n, b)| full[n] != *b),
        "every image changed"
    );
    // a record that is not a record is damaged: the resume says so and renders that
    // frame again
    std::fs::write(out.join("manifest.d/composite_0002.json"), b"{not json").unwrap();
    let o = volcast(dir, &["render", "s.toml", "--out", "run", "--resume"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("composite_0002.json")
            && err.contains("not a volcast frame record")
            && err.contains("that frame is rendered again")
            && err.contains("13 images already complete"),
        "{err}"
    );
    let record: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.d/composite_0002.json")).unwrap())
            .unwrap();
    assert_eq!(record["frame"], 2);
}

#[test]
fn the_manifest_reproduces_the_run() {
    let tmp = setup(SCENE);
    let dir = tmp.path();
    render(dir, "first", &["--quiet"]);
    let m = manifest(&dir.join("first"));
    assert_eq!(m["format"], "volcast-manifest-2");
    assert_eq!(m["volcast_version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(m["volume"]["sizes"], serde_json::json!([14, 14, 14]));
    assert_eq!(m["scene"]["resolved"]["stereo"]["method"], "toe-in");
    assert_eq!(m["scene"]["resolved"]["passes"][1]["transfer"], "bone");
    assert!(m["windows"]["mip"].is_array(), "{:#}", m["windows"]);
    let frames = m["frames"].as_array().unwrap();
    let f = frames
        .iter()
        .find(|f| f["pass"] == "mip" && f["frame"] == 3)
        .unwrap();
    // per-frame view parameters: the left eye of frame 3 at 3*10 - 5 degrees, shown
    // by the right-eye view of frame 2
    assert_eq!(f["views"][0]["eye"], "left");
    assert_eq!(f["views"][0]["azimuth_deg"], 25.0);
    assert_eq!(f["views"][0]["view"], serde_json::json!([2, "right"]));
    assert_eq!(f["views"][1]["azimuth_deg"], 35.0);
    assert!(f["samples"].as_u64().unwrap() > 0 && f["seconds"].as_f64().unwrap() >= 0.0);
    // the recorded checksums are the files'
    let file = &f["files"][1];
    let bytes = std::fs::read(dir.join("first").join(file["name"].as_str().unwrap())).unwrap();
    assert_eq!(file["bytes"], bytes.len());
    // checked with the sha2 crate, independently of how the manifest computes it
    let digest: String = {
        use sha2::Digest;
        sha2::Sha256::digest(&bytes)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    };
    assert_eq!(file["sha256"].as_str().unwrap(), digest);
    assert!(m["ffmpeg"][0]
        .as_str()
        .unwrap()
        .starts_with("ffmpeg -framerate 10 -i first/mip_%04d_left.png"));
    // the scene text in the manifest renders the same images
    std::fs::write(dir.join("again.toml"), m["scene"]["text"].as_str().unwrap()).unwrap();
    ok(&volcast(
        dir,
        &["render", "again.toml", "--quiet", "--out", "again"],
    ));
    assert!(images(&dir.join("again")) == images(&dir.join("first")));
    assert_eq!(manifest(&dir.join("again"))["scene_hash"], m["scene_hash"]);
}

#[test]
fn animations_hold_every_frame() {
    let tmp = setup(SCENE);
    let dir = tmp.path();
    render(dir, "a", &["--quiet"]);
    let out = dir.join("a");
    for stem in ["mip_left", "mip_right", "composite_left", "composite_right"] {
        // APNG: 7 frames, looping, each the PNG frame's own samples
        let file = std::fs::File::open(out.join(format!("{stem}.apng"))).unwrap();
        let mut reader = png::Decoder::new(std::io::BufReader::new(file))
            .read_info()
            .unwrap();
        let actl = reader.info().animation_control.expect("an animated PNG");
        assert_eq!((actl.num_frames, actl.num_plays), (7, 0), "{stem}");
        let (pass, eye) = stem.split_once('_').unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        for k in 0..7 {
            let info = reader.next_frame(&mut buf).unwrap();
            let png = image::open(out.join(format!("{pass}_{k:04}_{eye}.png"))).unwrap();
            assert_eq!(
                &buf[..info.buffer_size()],
                png.as_bytes(),
                "{stem} frame {k}"
            );
            let fc = reader.info().frame_control.unwrap();
            assert_eq!((fc.delay_num, fc.delay_den), (1, 10));
        }
        // GIF: 7 frames of the right size, looping, 10 hundredths each
        let file = std::fs::File::open(out.join(format!("{stem}.gif"))).unwrap();
        let mut opts = gif::DecodeOptions::new();
        opts.set_color_output(gif::ColorOutput::RGBA);
        let mut dec = opts.read_info(file).unwrap();
        let mut n = 0;
        while let Some(f) = dec.read_next_frame().unwrap() {
            assert_eq!((f.width, f.height, f.delay), (20, 16, 10));
            if pass == "mip" {
                // grey frames are exact
                let png = image::open(out.join(format!("{pass}_{n:04}_{eye}.png")))
                    .unwrap()
                    .to_luma8();
                let grey: Vec<u8> = f.buffer.chunks(4).map(|p| p[0]).collect();
                assert_eq!(grey, png.into_raw(), "{stem} frame {n}");
            }
            n += 1;
        }
        assert_eq!(n, 7, "{stem}");
        assert_eq!(dec.repeat(), gif::Repeat::Infinite);
    }
    // new [animation] settings rebuild the animations without rendering a frame
    let slower = SCENE.replace("fps = 10", "fps = 5");
    std::fs::write(dir.join("s.toml"), slower).unwrap();
    let err = render(dir, "a", &["--resume"]);
    assert!(
        err.contains("volcast: 0 files") && err.contains("mip_left.gif"),
        "{err}"
    );
    let mut dec = gif::DecodeOptions::new()
        .read_info(std::fs::File::open(out.join("mip_left.gif")).unwrap())
        .unwrap();
    assert_eq!(dec.read_next_frame().unwrap().unwrap().delay, 20);
    // playing once, anaglyph: one animation per pass, no loop
    let once = SCENE
        .replace("layout = \"pair\"", "layout = \"anaglyph\"")
        .replace("fps = 10", "fps = 10\nloop = false");
    std::fs::write(dir.join("s.toml"), once).unwrap();
    render(dir, "b", &["--quiet"]);
    let anims = files(&dir.join("b"), &["gif", "apng"]);
    let names: Vec<&str> = anims.keys().map(|s| s.as_str()).collect();
    assert_eq!(
        names,
        ["composite.apng", "composite.gif", "mip.apng", "mip.gif"]
    );
    let reader = png::Decoder::new(std::io::Cursor::new(&anims["mip.apng"]))
        .read_info()
        .unwrap();
    assert_eq!(reader.info().animation_control.unwrap().num_plays, 1);
    let mut dec = gif::DecodeOptions::new()
        .read_info(std::io::Cursor::new(&anims["mip.gif"]))
        .unwrap();
    let mut n = 0;
    while dec.read_next_frame().unwrap().is_some() {
        n += 1;
    }
    assert_eq!((n, dec.repeat()), (7, gif::Repeat::Finite(0)));
}

#[test]
fn shard_arguments_are_checked() {
    let tmp = setup(SCENE);
    let dir = tmp.path();
    for (args, expect) in [
        (vec!["--shard", "3/3"], "K must be below N"),
        (vec!["--shard", "1-3"], "expected K/N"),
        (vec!["--shard", "0/0"], "at least 1"),
        (vec!["--shard", "auto"], "SLURM_ARRAY_TASK_ID is not set"),
    ] {
        let mut a = vec!["render", "s.toml", "--out", "x"];
        a.extend(args.iter().copied());
        let o = volcast_env(dir, &a, &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?}");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(!dir.join("x").exists(), "{args:?} wrote files");
    }
    let o = volcast_env(
        dir,
        &["render", "s.toml", "--out", "x", "--shard", "auto"],
        &[
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ],
    );
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("consecutive"));
    // a Slurm array --array=1-3 runs task 2 as shard 1/3: frames 1 and 4
    let o = volcast_env(
        dir,
        &[
            "render", "s.toml", "--out", "x", "--shard", "auto", "--quiet",
        ],
        &[
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_MAX", "3"),
        ],
    );
    ok(&o);
    let names: Vec<String> = images(&dir.join("x"))
        .into_keys()
        .filter(|n| n.starts_with("mip") && n.ends_with("left.png"))
        .collect();
    assert_eq!(names, ["mip_0001_left.png", "mip_0004_left.png"]);
}

/// A Slurm job array of 8 tasks with `--shard auto/8`, one task failing: the safety
/// net (`--finish-only`, run `afterany`) renders nothing and names what is missing;
/// resubmitting the failed task alone (`sbatch --array=5`) renders exactly its shard,
/// and the sequence then completes byte for byte like one run.
#[test]
fn a_failed_array_task_is_resubmitted_alone_and_finished() {
    let tmp = setup(SCENE);
    let dir = tmp.path();
    render(dir, "full", &["--quiet"]);
    let full = images(&dir.join("full"));
    let full_anim = files(&dir.join("full"), &["gif", "apng"]);
    let task = |id: usize, array: (usize, usize)| {
        let (id, count) = (id.to_string(), (array.1 - array.0 + 1).to_string());
        let (min, max) = (array.0.to_string(), array.1.to_string());
        volcast_env(
            dir,
            &[
                "render", "s.toml", "--out", "arr", "--shard", "auto/8", "--resume", "--quiet",
            ],
            &[
                ("SLURM_ARRAY_TASK_ID", id.as_str()),
                ("SLURM_ARRAY_TASK_COUNT", count.as_str()),
                ("SLURM_ARRAY_TASK_MIN", min.as_str()),
                ("SLURM_ARRAY_TASK_MAX", max.as_str()),
            ],
        )
    };
    // --array=0-7, task 5 fails (here: never runs)
    for id in (0..8).filter(|&i| i != 5) {
        ok(&task(id, (0, 7)));
    }
    let out = dir.join("arr");
    assert_eq!(images(&out).len(), 6 * 2 * 2);
    // the safety net renders nothing and says what is missing, and which shard
    let o = volcast_env(
        dir,
        &["render", "s.toml", "--out", "arr", "--finish-only"],
        &[],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("--finish-only: 2 of 14 images are missing")
            && err.contains("composite frames 5")
            && err.contains("mip frames 5")
            && err.contains("shard 5 of 8")
            && err.contains("--array=5"),
        "{err}"
    );
    assert_eq!(images(&out).len(), 6 * 2 * 2, "nothing was rendered");
    assert!(files(&out, &["gif", "apng"]).is_empty());
    assert_eq!(manifest(&out)["complete"], false);
    // sbatch --array=5 turntable.sbatch: SLURM_ARRAY_TASK_COUNT is 1, the shard stays 5/8
    let err = ok(&task(5, (5, 5)));
    assert!(err.is_empty(), "{err}");
    let now = images(&out);
    assert_eq!(
        now.len(),
        7 * 2 * 2,
        "exactly the missing frame was rendered"
    );
    assert!(now == full);
    // the last task assembled the animations; the safety net now succeeds
    let o = volcast_env(
        dir,
        &["render", "s.toml", "--out", "arr", "--finish-only"],
        &[],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(err.contains("all 14 images complete"), "{err}");
    assert!(files(&out, &["gif", "apng"]) == full_anim);
    // a damaged animation is rebuilt by --finish-only too
    let gif = out.join("mip_left.gif");
    let mut b = std::fs::read(&gif).unwrap();
    let i = b.len() / 2;
    b[i] ^= 1;
    std::fs::write(&gif, &b).unwrap();
    ok(&volcast_env(
        dir,
        &[
            "render",
            "s.toml",
            "--out",
            "arr",
            "--finish-only",
            "--quiet",
        ],
        &[],
    ));
    assert!(files(&out, &["gif", "apng"]) == full_anim);
}

#[test]
fn finish_only_and_auto_n_arguments_are_checked() {
    let tmp = setup(SCENE);
    let dir = tmp.path();
    for (args, code, expect) in [
        (
            vec!["--finish-only", "--shard", "1/2"],
            2,
            "cannot be used with",
        ),
        (
            vec!["--finish-only", "--frames", "0..2"],
            2,
            "cannot be used with",
        ),
        (vec!["--shard", "auto/0"], 2, "auto/N"),
        (
            vec!["--shard", "auto/8"],
            1,
            "SLURM_ARRAY_TASK_ID is not set",
        ),
        (
            vec!["--finish-only"],
            1,
            "does not exist: nothing has been rendered",
        ),
    ] {
        let mut a = vec!["render", "s.toml", "--out", "x"];
        a.extend(args.iter().copied());
        let o = volcast_env(dir, &a, &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(code), "{args:?}: {err}");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(!dir.join("x").exists(), "{args:?} wrote files");
    }
    let o = volcast_env(
        dir,
        &["render", "s.toml", "--out", "x", "--shard", "auto/8"],
        &[
            ("SLURM_ARRAY_TASK_ID", "8"),
            ("SLURM_ARRAY_TASK_COUNT", "9"),
        ],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("--array=0-7"), "{err}");
}
