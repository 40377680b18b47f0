//! An output folder holds one scene's images: a second scene rendering there is
//! refused unless `--force`; a long orbit costs what a run renders, not what the
//! scene declares; a bench checks that it can write its folder before measuring.

use std::path::Path;
use std::time::Duration;

use crate::util::{measured, volcast};

fn scene(frames: usize, mode: &str) -> String {
    format!(
        "[volume]\nsynthetic = \"ball\"\nsizes = [8, 8, 8]\n[orbit]\nframes = {frames}\n\
         [image]\nsize = [8, 8]\n[[render]]\nname = \"p\"\nmode = \"{mode}\"\nwindow = [0, 1]\n"
    )
}

fn run(dir: &Path, args: &[&str]) -> (Option<i32>, String) {
    let o = volcast(dir, args);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn a_second_scene_in_one_folder_is_refused_unless_forced() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("a.toml"), scene(4, "mip")).unwrap();
    std::fs::write(d.join("b.toml"), scene(4, "minip")).unwrap();
    let (code, err) = run(d, &["render", "a.toml", "--out", "out", "-q"]);
    assert_eq!(code, Some(0), "{err}");
    let before = std::fs::read(d.join("out/p_0000.png")).unwrap();
    // b's images would replace a's under the same names: refused, nothing touched
    for extra in [
        &[][..],
        &["--resume"],
        &["--frames", "1..2"],
        &["--finish-only"],
    ] {
        let mut args = vec!["render", "b.toml", "--out", "out", "-q"];
        args.extend_from_slice(extra);
        let (code, err) = run(d, &args);
        assert_eq!(code, Some(1), "{extra:?}: {err}");
        for needle in [
            "b.toml",
            "holds the images of another scene, a.toml",
            "--force",
        ] {
            assert!(err.contains(needle), "`{needle}` missing from: {err}");
        }
        assert_eq!(std::fs::read(d.join("out/p_0000.png")).unwrap(), before);
    }
    let manifest = std::fs::read_to_string(d.join("out/manifest.json")).unwrap();
    assert!(manifest.contains("\"file\": \"a.toml\""), "{manifest}");
    // --force renders over it, and the folder is b's from then on
    let (code, err) = run(d, &["render", "b.toml", "--out", "out", "-q", "--force"]);
    assert_eq!(code, Some(0), "{err}");
    assert_ne!(std::fs::read(d.join("out/p_0000.png")).unwrap(), before);
    let (code, err) = run(d, &["render", "b.toml", "--out", "out", "-q", "--resume"]);
    assert_eq!(code, Some(0), "{err}");
    let (code, _) = run(d, &["render", "a.toml", "--out", "out", "-q"]);
    assert_eq!(code, Some(1));
    // the same scene file edited renders again over its own images, and says so
    std::fs::write(d.join("b.toml"), scene(4, "mip")).unwrap();
    let (code, err) = run(d, &["render", "b.toml", "--out", "out"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("held the images of this scene as it was before it was edited"),
        "{err}"
    );
    assert_eq!(std::fs::read(d.join("out/p_0000.png")).unwrap(), before);
}

#[cfg(unix)]
#[test]
fn a_long_orbit_costs_the_frames_rendered_not_the_frames_declared() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // a million frames on the circle, and on a keyframed path
    let circle = scene(1_000_000, "mip");
    let keyed = format!(
        "{circle}[[keyframe]]\nframe = 0\nazimuth = 0\n[[keyframe]]\nframe = 999999\nazimuth = 360\nzoom = 2\n"
    );
    for (name, text) in [("circle.toml", circle), ("keyed.toml", keyed)] {
        std::fs::write(d.join(name), text).unwrap();
        let out = format!("out_{name}");
        let m = measured(
            d,
            &["render", name, "--out", &out, "--frames", "0..1", "-q"],
        );
        assert_eq!(m.code, Some(0), "{name}: {}", m.stderr);
        assert!(d.join(&out).join("p_0000.png").is_file());
        // planning and the manifest of all 10^6 frames took 11.7 s (circle) and
        // 15.6 s (keyframes) and 284 MB and 409 MB; one frame takes a fraction
        assert!(
            m.peak_rss < 128 << 20,
            "{name}: peak resident memory {} MiB",
            m.peak_rss >> 20
        );
        assert!(
            m.elapsed < Duration::from_secs(4),
            "{name}: {:?}",
            m.elapsed
        );
        let manifest = std::fs::read_to_string(d.join(&out).join("manifest.json")).unwrap();
        assert!(manifest.contains("\"images_total\": 1000000"), "{name}");
        assert!(manifest.contains("\"images_done\": 1,"), "{name}");
    }
}

#[test]
fn a_bench_refuses_a_folder_it_cannot_write_before_it_measures() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("a_file"), b"not a folder").unwrap();
    for bench in ["accuracy", "speed"] {
        let (code, err) = run(d, &["bench", bench, "--quick", "--out", "a_file/results"]);
        assert_eq!(code, Some(1), "{bench}: {err}");
        assert!(err.contains("a_file/results"), "{bench}: {err}");
        // refused before the first case: no progress line
        assert!(!err.contains("bench: "), "{bench} measured first: {err}");
    }
    // a folder that does not exist yet is created, as before
    let (code, err) = run(d, &["bench", "accuracy", "--quick", "--out", "new/results"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(d.join("new/results/accuracy.csv").is_file());
    assert!(d.join("new/results/images/accuracy.png").is_file());
}
