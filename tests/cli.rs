//! The command line: every example scene renders, `check` prints a plan and writes
//! nothing, `info` describes volumes, and the exit status tells success from failure.

use std::path::{Path, PathBuf};

use crate::util::{root, volcast};

fn example_scenes() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(root().join("scenes"))
        .expect("scenes/ exists")
        .map(|e| e.expect("readable entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    assert!(v.len() >= 8, "the project ships example scenes");
    v
}

/// `volcast render SCENE --out OUT --size SIZE --quiet EXTRA...` in `dir`.
fn render_at(
    dir: &Path,
    scene: &Path,
    out: &Path,
    size: &str,
    extra: &[&str],
) -> std::process::Output {
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--size",
        size,
        "--quiet",
    ];
    args.extend_from_slice(extra);
    volcast(dir, &args)
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Decodes every image of a folder (PNG with the image crate, NRRD by its magic and
/// our reader) and returns how many there are (the manifest is checked to be JSON).
fn decode_all(dir: &Path) -> usize {
    let mut n = 0;
    for e in std::fs::read_dir(dir).expect("output folder exists") {
        let p = e.expect("entry").path();
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            !name.starts_with('.'),
            "a temporary file was left behind: {}",
            p.display()
        );
        if name == "manifest.d" && p.is_dir() {
            continue;
        }
        match p.extension().and_then(|e| e.to_str()) {
            Some("json") if name == "manifest.json" => {
                let _: serde_json::Value =
                    serde_json::from_slice(&std::fs::read(&p).unwrap()).expect("a JSON manifest");
                continue;
            }
            Some("html") if name == "index.html" => {
                let page = std::fs::read_to_string(&p).unwrap();
                assert!(page.starts_with("<!DOCTYPE html>"), "{}", p.display());
                continue;
            }
            Some("png") => {
                image::open(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            }
            Some("nrrd") => {
                volcast::volume::nrrd::read(&p, &volcast::volume::Limits::default())
                    .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            }
            _ => panic!("unexpected file {}", p.display()),
        }
        n += 1;
    }
    n
}

#[test]
fn every_example_scene_renders() {
    let tmp = tempfile::tempdir().unwrap();
    for scene in example_scenes() {
        let name = scene.file_stem().unwrap().to_string_lossy().into_owned();
        let out = tmp.path().join(&name);
        let o = render_at(tmp.path(), &scene, &out, "40x32", &["--frames", "0"]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        let text = std::fs::read_to_string(&scene).unwrap();
        let passes = text.matches("[[render]]").count().max(1);
        let per_pass = if text.contains("layout = \"pair\"") {
            2
        } else {
            1
        };
        assert_eq!(decode_all(&out), passes * per_pass, "{name}: files written");
        let o = volcast(tmp.path(), &["check", scene.to_str().unwrap()]);
        assert!(o.status.success(), "check {name}: {}", stderr(&o));
    }
}

#[test]
fn check_prints_the_plan_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = root().join("scenes/composite_engine_bone.toml");
    let o = volcast(tmp.path(), &["check", scene.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    for needle in [
        "frames",
        "transfer table `bone`",
        "blinnphong shading",
        "gradient volume",
        "memory",
        "ok",
    ] {
        assert!(out.contains(needle), "`{needle}` missing from:\n{out}");
    }
    // the composite skips where its transfer function is transparent
    assert!(
        out.contains("empty-space skipping") && out.contains("transfer function is transparent"),
        "{out}"
    );
    // its 8-bit voxels are read in pairs where the machine's vector paths do so
    let pairs = "8-bit voxels read two at a time through a table of normalised pairs (512.0 KiB; \
                 none for unsigned voxels the window covers: interpolated as they are)";
    assert_eq!(out.contains(pairs), volcast::sample::reads_pairs(), "{out}");
    // a MIP computes neither gradients nor tables, skips cells that cannot beat its
    // maximum and walks only where cells are not all zero, and says so; --no-skip
    // takes the grid away
    let scene = root().join("scenes/mip_head.toml");
    let o = volcast(tmp.path(), &["check", scene.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        !out.contains("gradient") && !out.contains("transfer table"),
        "{out}"
    );
    assert_eq!(out.contains(pairs), volcast::sample::reads_pairs(), "{out}");
    assert!(
        out.contains("cannot beat the running maximum, walking only where cells are not all zero"),
        "{out}"
    );
    // exact integration reads cells rather than runs of samples: no table of pairs
    let exact = tmp.path().join("exact.toml");
    let text = std::fs::read_to_string(&scene)
        .unwrap()
        .replace("mode = \"mip\"", "mode = \"mip\"\nintegration = \"exact\"");
    assert!(text.contains("integration = \"exact\""));
    std::fs::write(
        &exact,
        text.replace("../data/", &format!("{}/data/", root().display())),
    )
    .unwrap();
    let o = volcast(tmp.path(), &["check", exact.to_str().unwrap()]);
    let exact_out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success()
            && exact_out.contains("exact integration")
            && !exact_out.contains("normalised pairs"),
        "{exact_out}"
    );
    std::fs::remove_file(&exact).unwrap();
    // 16-bit voxels (and cubic interpolation) need no table of pairs
    let skull = root().join("scenes/golden_skull.toml");
    let o = volcast(tmp.path(), &["check", skull.to_str().unwrap()]);
    let skull_out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && !skull_out.contains("normalised pairs"),
        "{skull_out}"
    );
    let o = volcast(tmp.path(), &["check", scene.to_str().unwrap(), "--no-skip"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && !out.contains("skipping"), "{out}");
    assert_eq!(
        std::fs::read_dir(tmp.path()).unwrap().count(),
        0,
        "check wrote files"
    );
}

#[test]
fn render_writes_numbered_sequences() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("s.toml"),
        "[volume]\nsynthetic = \"ball\"\nsizes = [16, 16, 16]\n[orbit]\nframes = 4\n[image]\nsize = [16, 16]\n\
         [[render]]\nmode = \"mip\"\n[[render]]\nname = \"d\"\nmode = \"depth\"\n",
    )
    .unwrap();
    let o = volcast(tmp.path(), &["render", "s.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut names: Vec<String> = std::fs::read_dir(tmp.path().join("out/s"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !n.starts_with("manifest"))
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "d_0000.png",
            "d_0001.png",
            "d_0002.png",
            "d_0003.png",
            "mip_0000.png",
            "mip_0001.png",
            "mip_0002.png",
            "mip_0003.png"
        ]
    );
    // the summary goes to stderr (no terminal here, so no progress bar)
    assert!(stderr(&o).contains("8 files"), "{}", stderr(&o));
}

#[test]
fn info_describes_a_volume() {
    let tmp = tempfile::tempdir().unwrap();
    let engine = root().join("data/ct_engine.nrrd");
    let o = volcast(tmp.path(), &["info", engine.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert_eq!(v["sizes"], serde_json::json!([256, 256, 110]));
    assert_eq!(v["type"], "uint8");
    assert_eq!(v["spacing"], serde_json::json!([1.0, 1.0, 1.0]));
    // min/max as `teem-unu minmax ct_engine.nrrd` prints them: 0 and 255
    assert_eq!(v["min"], 0.0);
    assert_eq!(v["max"], 255.0);
    assert!(v["mean"].as_f64().unwrap() > 0.0);
    let o = volcast(tmp.path(), &["info", engine.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("256 x 256 x 110") && text.contains("histogram"),
        "{text}"
    );
    // a scene's synthetic volume
    std::fs::write(
        tmp.path().join("g.toml"),
        "[volume]\nsynthetic = \"gaussian\"\nsizes = [9, 9, 9]\n",
    )
    .unwrap();
    let o = volcast(tmp.path(), &["info", "g.toml", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert_eq!(v["max"], 1.0);
}

#[test]
fn missing_files_fail_with_a_message() {
    let tmp = tempfile::tempdir().unwrap();
    let o = volcast(tmp.path(), &["render", "nope.toml"]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("nope.toml") && stderr(&o).contains("cannot read"),
        "{}",
        stderr(&o)
    );
    let o = volcast(tmp.path(), &["info", "nope.nrrd"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("nope.nrrd"), "{}", stderr(&o));
}

#[test]
fn bench_speed_quick_measures_every_mode() {
    let tmp = tempfile::tempdir().unwrap();
    let o = volcast(
        &root(),
        &[
            "bench",
            "speed",
            "--quick",
            "--threads",
            "2",
            "--repeats",
            "2",
            "--out",
            tmp.path().to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let md = String::from_utf8_lossy(&o.stdout);
    for mode in volcast::mode::names() {
        assert!(md.contains(&format!("| {mode} |")), "{mode} missing:\n{md}");
    }
    assert!(
        md.contains("ct_engine") && md.contains("blobs 64^3"),
        "{md}"
    );
    assert!(
        md.contains("--repeats 2")
            && md.contains("median of 2 runs (the thread counts interleaved)"),
        "{md}"
    );
    // and the composites of several volumes, on the synthetic field
    for case in [
        "composite (gaussian alone)",
        "composite of 2 volumes",
        "composite (dense transfer function)",
        "composite of 2, overlapping",
    ] {
        assert!(
            md.contains(&format!("| blobs 64^3 uint8 | {case} |")),
            "{case} missing:\n{md}"
        );
    }
    let csv = std::fs::read_to_string(tmp.path().join("speed.csv")).unwrap();
    // a header and 2 volumes x 8 modes x 2 thread counts, and 4 blend cases x 2 on
    // the synthetic field
    assert_eq!(csv.lines().count(), 1 + 2 * 8 * 2 + 4 * 2, "{csv}");
    // skipping skips on the blobs (air around them), and never takes more than the march
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("speed.json")).unwrap())
            .unwrap();
    for row in json["rows"].as_array().unwrap() {
        let skipped = row["skipped"].as_f64().unwrap();
        assert!((0.0..1.0).contains(&skipped), "{row}");
    }
    // one and two threads of each case, in that order
    let rows = json["rows"].as_array().unwrap();
    for pair in rows.chunks(2) {
        assert_eq!(pair[0]["threads"], 1, "{pair:?}");
        assert_eq!(pair[1]["threads"], 2, "{pair:?}");
        assert_eq!(pair[0]["mode"], pair[1]["mode"]);
    }
}

/// `scenes/golden_skull.toml` on the shipped CT head: every frame of the turntable shows
/// the skull filling the frame without being cut at the sides or the top (at most two
/// edge pixels: the thin head rest), and upright
/// (the cranium, the heavier part, above the jaw and neck: the covered pixels' centre
/// lies in the upper half of their bounding box).
#[test]
fn golden_skull_fills_the_frame_upright() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = root().join("scenes/golden_skull.toml");
    let out = tmp.path().join("skull");
    let o = render_at(tmp.path(), &scene, &out, "64x64", &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let n = 64usize;
    for k in 0..36 {
        let path = out.join(format!("skull_{k:04}.png"));
        let img = image::open(&path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            .to_rgb8();
        assert_eq!(img.dimensions(), (n as u32, n as u32));
        // the background is [0.1, 0.1, 0.12]: about (26, 26, 31)
        let covered = |x: usize, y: usize| {
            let p = img.get_pixel(x as u32, y as u32).0;
            (p[0] as i32 - 26).abs() > 12 || (p[2] as i32 - 31).abs() > 12
        };
        let (mut x0, mut x1, mut y0, mut y1) = (n, 0, n, 0);
        let (mut count, mut sum_y) = (0usize, 0usize);
        for y in 0..n {
            for x in 0..n {
                if covered(x, y) {
                    (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
                    count += 1;
                    sum_y += y;
                }
            }
        }
        assert!(count > 0, "frame {k}: nothing drawn");
        // the thin head rest under the neck may reach the side: a pixel or two
        let on_edge = (0..n)
            .filter(|&i| covered(0, i) || covered(n - 1, i) || covered(i, 0))
            .count();
        assert!(
            on_edge <= 2,
            "frame {k}: cut at the frame's edge ({on_edge} pixels; box x {x0}..{x1}, y {y0}..{y1})"
        );
        let extent = (x1 - x0 + 1).max(y1 - y0 + 1);
        assert!(
            extent >= n * 6 / 10,
            "frame {k}: the skull spans {extent} of {n} pixels"
        );
        let centre_y = sum_y as f64 / count as f64;
        assert!(
            centre_y < (y0 + y1) as f64 / 2.0,
            "frame {k}: covered pixels centred at row {centre_y:.1} in rows {y0}..{y1}: upside down?"
        );
    }
}
