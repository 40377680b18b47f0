//! Numbers that overflow never make a silent wrong image: a window, a data range,
//! an angle or a camera beyond what the arithmetic holds is a located error before
//! anything is written, and statistics of finite data stay finite.

use std::path::Path;

use crate::util::volcast;

const M: f64 = f64::MAX;

/// An 8^3 float64 NIfTI-1 (pixdim geometry) holding `M` inside a ball of radius
/// 2.5 voxels about the centre and `-M` elsewhere; returns how many voxels are `M`.
fn write_extreme_nifti(path: &Path) -> usize {
    let n = 8usize;
    let mut h = vec![0u8; 352];
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    for (i, d) in [3i16, 8, 8, 8, 1, 1, 1, 1].iter().enumerate() {
        h[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_le_bytes());
    }
    h[70..72].copy_from_slice(&64i16.to_le_bytes()); // DT_FLOAT64
    h[72..74].copy_from_slice(&64i16.to_le_bytes());
    for i in 0..4 {
        h[76 + 4 * i..80 + 4 * i].copy_from_slice(&1f32.to_le_bytes());
    }
    h[108..112].copy_from_slice(&352f32.to_le_bytes());
    h[344..348].copy_from_slice(b"n+1\0");
    let mut inside = 0;
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let d = |i: usize| i as f64 - 3.5;
                let r = (d(x) * d(x) + d(y) * d(y) + d(z) * d(z)).sqrt();
                let v = if r < 2.5 { M } else { -M };
                inside += usize::from(r < 2.5);
                h.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    std::fs::write(path, h).unwrap();
    inside
}

/// Runs volcast in `dir`, expects exit status 1 with every needle in the message and
/// no output folder, and returns the message.
fn refused(dir: &Path, args: &[&str], needles: &[&str]) -> String {
    let o = volcast(dir, args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
    for n in needles {
        assert!(err.contains(n), "`{n}` missing from:\n{err}");
    }
    assert!(!dir.join("out").exists(), "{args:?} wrote output: {err}");
    err
}

const MIP: &str =
    "[orbit]\nframes = 2\n[image]\nsize = [16, 16]\nout = \"out\"\n[[render]]\nmode = \"mip\"\n";

#[test]
fn a_window_wider_than_an_f64_is_a_located_error() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // the pass's grey window
    let scene = format!(
        "[volume]\nsynthetic = \"ball\"\nsizes = [8, 8, 8]\n{MIP}window = [-1e308, 1e308]\n"
    );
    std::fs::write(d.join("s.toml"), scene).unwrap();
    let err = refused(
        d,
        &["render", "s.toml"],
        &["s.toml:11:10", "window = [-1e308, 1e308]", "overflows"],
    );
    assert!(!err.contains("000000000"), "numbers quoted in full: {err}");
    // the volume's window in data units, for render, check and histogram alike
    let scene = format!(
        "[volume]\nsynthetic = \"ball\"\nsizes = [8, 8, 8]\nunits = \"data\"\nwindow = [-1e308, 1e308]\n{MIP}"
    );
    std::fs::write(d.join("v.toml"), scene).unwrap();
    for args in [
        &["render", "v.toml"][..],
        &["check", "v.toml"],
        &["histogram", "v.toml", "--out", "out"],
    ] {
        refused(d, args, &["v.toml:5:10", "window", "overflows"]);
    }
    // a window of ordinary width still renders
    let scene = format!(
        "[volume]\nsynthetic = \"ball\"\nsizes = [8, 8, 8]\n{MIP}window = [-1e300, 1e300]\n"
    );
    std::fs::write(d.join("ok.toml"), scene).unwrap();
    let o = volcast(d, &["render", "ok.toml", "-q"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn data_at_the_f64_limits_is_refused_or_rendered_right_never_black() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let inside = write_extreme_nifti(&d.join("big.nii"));
    // the data's own range is 3.6e308 wide: refused, with the way out
    std::fs::write(
        d.join("s.toml"),
        format!("[volume]\npath = \"big.nii\"\n{MIP}"),
    )
    .unwrap();
    refused(
        d,
        &["render", "s.toml"],
        &["big.nii", "overflows", "[volume] window"],
    );
    // a window that fits: the ball is white, the rest of the box black (nearest
    // samples, so that every value is one of the two)
    std::fs::write(
        d.join("w.toml"),
        format!(
            "[volume]\npath = \"big.nii\"\nwindow = [-1e300, 1e300]\n{}",
            MIP.replace("[image]\n", "[image]\nformat = \"nrrd\"\n")
                + "interpolation = \"nearest\"\n"
        ),
    )
    .unwrap();
    let o = volcast(d, &["render", "w.toml", "-q"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let film = std::fs::read(d.join("out/mip_0000.nrrd")).unwrap();
    let start = film.windows(2).position(|w| w == b"\n\n").unwrap() + 2;
    let px: Vec<f32> = film[start..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(px.len(), 16 * 16);
    assert_eq!(px[8 * 16 + 8], 1.0, "the ball's centre");
    // rays through the box beside the ball see only -M, clamped to the window's
    // low end; rays that miss the box have no value
    assert!(px.contains(&0.0), "{px:?}");
    assert!(
        px.iter().all(|&v| v == 0.0 || v == 1.0 || v.is_nan()),
        "{px:?}"
    );
    // info: finite statistics, in exponent form
    let o = volcast(d, &["info", "big.nii", "--json"]);
    assert!(o.status.success());
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let mean = j["mean"].as_f64().expect("a finite mean");
    let want = (2.0 * inside as f64 - 512.0) / 512.0 * M;
    assert!(
        (mean - want).abs() <= 1e-12 * M,
        "mean {mean:e}, want {want:e}"
    );
    let o = volcast(d, &["info", "big.nii"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("range      -1.7976931348623157e308 .. 1.7976931348623157e308 (mean -"),
        "{text}"
    );
    assert!(!text.contains("inf") && !text.contains("NaN"), "{text}");
}

#[test]
fn angles_beyond_a_million_degrees_are_located_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let base = "[volume]\nsynthetic = \"ball\"\nsizes = [8, 8, 8]\n[image]\nsize = [8, 8]\nout = \"out\"\n[[render]]\nmode = \"mip\"\n";
    for (table, key, line) in [
        (
            "[orbit]\nframes = 3\ndegrees = 1e308\n",
            "degrees = 1e308",
            "s.toml:3:11",
        ),
        (
            "[camera]\nazimuth = -1e308\n",
            "azimuth = -1e308",
            "s.toml:2:11",
        ),
        (
            "[orbit]\nframes = 3\ndegrees = 1000001\n",
            "degrees = 1000001",
            "s.toml:3:11",
        ),
    ] {
        std::fs::write(d.join("s.toml"), format!("{table}{base}")).unwrap();
        refused(
            d,
            &["render", "s.toml"],
            &[line, key, "degrees from -1000000 to 1000000"],
        );
    }
    std::fs::write(
        d.join("s.toml"),
        format!("[orbit]\nframes = 3\ndegrees = 1e6\n{base}"),
    )
    .unwrap();
    let o = volcast(d, &["render", "s.toml", "-q"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn a_camera_beyond_the_renderers_range_is_refused_before_any_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    for camera in [
        "target = [1e300, 0, 0]",
        "zoom = 1e-300",
        "zoom = 1e300",
        "distance = 1e308",
    ] {
        std::fs::write(
            d.join("s.toml"),
            format!("[camera]\n{camera}\n[volume]\nsynthetic = \"ball\"\nsizes = [8, 8, 8]\n{MIP}"),
        )
        .unwrap();
        refused(
            d,
            &["render", "s.toml"],
            &[
                "frame 0: the camera cannot be rendered",
                "[camera] target, distance and zoom",
            ],
        );
    }
    // a keyframe far away is refused even when the run renders other frames: every
    // frame's camera is interpolated from the keyframes
    std::fs::write(
        d.join("k.toml"),
        format!(
            "[volume]\nsynthetic = \"ball\"\nsizes = [8, 8, 8]\n{}[[keyframe]]\nframe = 0\nazimuth = 0\ntarget = [3.5, 3.5, 3.5]\n[[keyframe]]\nframe = 9\ntarget = [1e300, 0, 0]\n",
            MIP.replace("frames = 2", "frames = 10")
        ),
    )
    .unwrap();
    refused(
        d,
        &["render", "k.toml", "--frames", "0..1"],
        &["frame 9: the camera cannot be rendered"],
    );
}
