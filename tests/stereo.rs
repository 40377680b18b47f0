//! Stereo: where the eyes are (toe-in views are the turned camera; parallel eyes
//! converge at the target distance), how the layouts combine them (anaglyph
//! channels, side-by-side halves), and toe-in view reuse (fewer views, same bytes).

use std::collections::BTreeMap;
use std::path::Path;

use volcast::output::Eye;
use volcast::pipeline::{render_films, RenderedView};
use volcast::plan::RunOptions;
use volcast::render::Film;
use volcast::volume::Limits;

use crate::util::volcast;

fn films(text: &str, opts: &RunOptions) -> (Vec<RenderedView>, volcast::pipeline::Summary) {
    let scene =
        volcast::scene::parse(text, Path::new("stereo.toml")).unwrap_or_else(|e| panic!("{e}"));
    render_films(&scene, opts, &Limits::default()).unwrap_or_else(|e| panic!("{e}"))
}

/// Bit-for-bit equality of two films (NaN marks pixels without a value).
fn same(a: &Film, b: &Film) -> bool {
    (a.width, a.height, a.channels) == (b.width, b.height, b.channels)
        && a.data
            .iter()
            .zip(&b.data)
            .all(|(x, y)| x.to_bits() == y.to_bits())
}

fn film_of(views: &[RenderedView], pass: usize, frame: usize, eye: Eye) -> &Film {
    &views
        .iter()
        .find(|v| v.pass == pass && v.frame == frame && v.eye == eye)
        .unwrap_or_else(|| panic!("no view for pass {pass} frame {frame} eye {eye:?}"))
        .film
}

const VOLUME: &str = "[volume]\nsynthetic = \"marschner-lobb\"\nsizes = [16, 16, 16]\n\
    [image]\nsize = [24, 20]\n[[render]]\nmode = \"mip\"\n\
    [[render]]\nmode = \"composite\"\ntransfer = \"bone\"\nshading = \"phong\"\n";

#[test]
fn toe_in_eyes_are_the_camera_turned_by_half_the_angle() {
    // step 10 degrees, angle 8: no reuse, every eye rendered at k*10 -/+ 4
    let orbit = "[orbit]\nframes = 5\ndegrees = 50.0\n";
    let stereo = "[stereo]\nangle = 8.0\nlayout = \"pair\"\n";
    let (s, _) = films(&format!("{VOLUME}{orbit}{stereo}"), &RunOptions::default());
    let (left, _) = films(
        &format!("{VOLUME}{orbit}[camera]\nazimuth = -4.0\n"),
        &RunOptions::default(),
    );
    let (right, _) = films(
        &format!("{VOLUME}{orbit}[camera]\nazimuth = 4.0\n"),
        &RunOptions::default(),
    );
    for pass in 0..2 {
        for k in 0..5 {
            assert!(
                same(
                    film_of(&s, pass, k, Eye::Left),
                    film_of(&left, pass, k, Eye::Mono)
                ),
                "pass {pass} frame {k}: the left eye is the camera at azimuth -4 + 10k"
            );
            assert!(
                same(
                    film_of(&s, pass, k, Eye::Right),
                    film_of(&right, pass, k, Eye::Mono)
                ),
                "pass {pass} frame {k}: the right eye is the camera at azimuth 4 + 10k"
            );
        }
    }
    // and the two eyes differ
    assert!(!same(
        film_of(&s, 0, 2, Eye::Left),
        film_of(&s, 0, 2, Eye::Right)
    ));
}

#[test]
fn reused_toe_in_views_are_still_the_turned_camera() {
    // step 10, angle 10: the left eye of frame k is the right eye of frame k-1
    let orbit = "[orbit]\nframes = 5\ndegrees = 50.0\n";
    let stereo = "[stereo]\nangle = 10.0\nlayout = \"pair\"\n";
    let (s, summary) = films(&format!("{VOLUME}{orbit}{stereo}"), &RunOptions::default());
    assert_eq!(summary.views, 2 * 6, "2 passes x 6 distinct views");
    let (left, _) = films(
        &format!("{VOLUME}{orbit}[camera]\nazimuth = -5.0\n"),
        &RunOptions::default(),
    );
    for pass in 0..2 {
        for k in 0..5 {
            assert!(
                same(
                    film_of(&s, pass, k, Eye::Left),
                    film_of(&left, pass, k, Eye::Mono)
                ),
                "pass {pass} frame {k}: the left eye is the camera at azimuth -5 + 10k"
            );
        }
        for k in 1..5 {
            assert!(
                same(
                    film_of(&s, pass, k, Eye::Left),
                    film_of(&s, pass, k - 1, Eye::Right)
                ),
                "pass {pass}: left eye of frame {k} = right eye of frame {}",
                k - 1
            );
        }
    }
}

/// Intensity-weighted centroid (x, y) of the pixels above `floor`.
fn centroid(f: &Film, floor: f32) -> (f64, f64) {
    let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
    for j in 0..f.height {
        for i in 0..f.width {
            let v = f.pixel(i, j)[0];
            if v.is_finite() && v > floor {
                let w = (v - floor) as f64;
                sx += w * (i as f64 + 0.5);
                sy += w * (j as f64 + 0.5);
                sw += w;
            }
        }
    }
    assert!(sw > 0.0, "the ball is in the picture");
    (sx / sw, sy / sw)
}

/// A small bright ball at the origin seen by off-axis eyes 0.3 x the distance apart,
/// converging at `target`.
fn ball_pair(target: [f64; 3]) -> Vec<RenderedView> {
    let text = format!(
        "[volume]\nsynthetic = \"ball\"\nradius = 0.12\nsizes = [48, 48, 48]\n\
         [camera]\nfov = 40.0\ntarget = {target:?}\n[image]\nsize = [64, 64]\n\
         [[render]]\nmode = \"mip\"\n\
         [stereo]\nmethod = \"parallel\"\nseparation_fraction = 0.3\nlayout = \"pair\"\n"
    );
    films(&text, &RunOptions::default()).0
}

#[test]
fn parallel_eyes_converge_at_the_target_distance() {
    // converging on the ball: no disparity
    let v = ball_pair([0.0, 0.0, 0.0]);
    let (l, r) = (film_of(&v, 0, 0, Eye::Left), film_of(&v, 0, 0, Eye::Right));
    let (cl, cr) = (centroid(l, 0.05), centroid(r, 0.05));
    assert!(
        (cl.0 - cr.0).abs() < 0.05 && (cl.1 - cr.1).abs() < 0.05,
        "a point at the target distance has zero disparity: {cl:?} vs {cr:?}"
    );
    assert!(
        (cl.0 - 32.0).abs() < 0.05,
        "and sits in the middle of the picture: {cl:?}"
    );
    // the views do differ (the eyes see the ball from two sides)
    assert!(!same(l, r));
    // converging 0.6 behind the ball (the eyes look along +y): the ball is nearer
    // than the target plane and shifts by s (1/z - 1/d) / half_width * W/2 pixels
    let v = ball_pair([0.0, 0.6, 0.0]);
    let left = v.iter().find(|x| x.eye == Eye::Left).expect("a left view");
    let d = left.view.distance;
    let (z, s) = (d - 0.6, 0.3 * d);
    let expected = s * (1.0 / z - 1.0 / d) / left.view.half_width * 64.0 / 2.0;
    let (cl, cr) = (
        centroid(film_of(&v, 0, 0, Eye::Left), 0.05),
        centroid(film_of(&v, 0, 0, Eye::Right), 0.05),
    );
    assert!(expected > 2.0, "a measurable disparity: {expected}");
    assert!(
        ((cl.0 - cr.0) - expected).abs() < 0.25 && (cl.1 - cr.1).abs() < 0.05,
        "crossed disparity of a near point: left {cl:?}, right {cr:?}, expected {expected} px"
    );
}

/// Decodes a PNG into (width, height, channels, 8-bit samples).
fn png(path: &Path) -> (u32, u32, usize, Vec<u8>) {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let c = usize::from(img.color().channel_count());
    let (w, h) = (img.width(), img.height());
    assert!(c == 1 || c == 3, "{}: {c} channels", path.display());
    (w, h, c, img.into_bytes())
}

fn render(dir: &Path, name: &str, text: &str) {
    std::fs::write(dir.join(format!("{name}.toml")), text).unwrap();
    let o = volcast(
        dir,
        &["render", &format!("{name}.toml"), "--quiet", "--out", name],
    );
    assert!(
        o.status.success(),
        "{name}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

const LAYOUT_SCENE: &str = "[volume]\nsynthetic = \"marschner-lobb\"\nsizes = [16, 16, 16]\n\
    [orbit]\nframes = 2\ndegrees = 30.0\n[image]\nsize = [20, 16]\nbackground = [0.1, 0.2, 0.3]\n\
    [[render]]\nmode = \"mip\"\n[[render]]\nmode = \"surface\"\nmaterial = \"ruby\"\n\
    [camera]\nelevation = 20.0\n";

#[test]
fn anaglyph_red_comes_from_the_left_view_the_rest_from_the_right() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    render(
        dir,
        "pair",
        &format!("{LAYOUT_SCENE}[stereo]\nlayout = \"pair\"\n"),
    );
    for (name, glasses, colors) in [
        ("cyan", "red-cyan", "color"),
        ("green", "red-green", "color"),
        ("gray", "red-cyan", "gray"),
    ] {
        render(
            dir,
            name,
            &format!("{LAYOUT_SCENE}[stereo]\nlayout = \"anaglyph\"\nanaglyph = \"{glasses}\"\nanaglyph_colors = \"{colors}\"\n"),
        );
        for (pass, grey) in [("mip", true), ("surface", false)] {
            for k in 0..2 {
                let f = format!("{pass}_{k:04}");
                let (w, h, c, a) = png(&dir.join(format!("{name}/{f}.png")));
                let (lw, lh, lc, l) = png(&dir.join(format!("pair/{f}_left.png")));
                let (_, _, _, r) = png(&dir.join(format!("pair/{f}_right.png")));
                assert_eq!((w, h, c), (lw, lh, 3), "{name} {f}");
                // grey passes with a coloured background are stored as RGB too
                assert_eq!(lc, 3, "{f}");
                let luma = |p: &[u8]| {
                    (0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64) / 255.0
                };
                for ((ap, lp), rp) in a.chunks(3).zip(l.chunks(3)).zip(r.chunks(3)) {
                    if colors == "color" && !grey {
                        assert_eq!(ap[0], lp[0], "{name} {f}: red from the left view");
                        assert_eq!(ap[1], rp[1], "{name} {f}: green from the right view");
                    } else {
                        // luminance of the (quantised) views, within quantisation
                        assert!((ap[0] as f64 / 255.0 - luma(lp)).abs() <= 1.5 / 255.0);
                        assert!((ap[1] as f64 / 255.0 - luma(rp)).abs() <= 1.5 / 255.0);
                    }
                    match glasses {
                        "red-green" => assert_eq!(ap[2], 0, "{name} {f}: no blue"),
                        _ if colors == "color" && !grey => assert_eq!(ap[2], rp[2]),
                        _ => assert_eq!(ap[2], ap[1], "{name} {f}: cyan = green + blue"),
                    }
                }
            }
        }
    }
}

#[test]
fn side_by_side_halves_are_the_pair_images() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    render(
        dir,
        "pair",
        &format!("{LAYOUT_SCENE}[stereo]\nlayout = \"pair\"\n"),
    );
    for (name, layout, gap) in [("sbs", "side-by-side", 3usize), ("cross", "cross-eyed", 0)] {
        render(
            dir,
            name,
            &format!("{LAYOUT_SCENE}[stereo]\nlayout = \"{layout}\"\ngap = {gap}\n"),
        );
        for pass in ["mip", "surface"] {
            for k in 0..2 {
                let f = format!("{pass}_{k:04}");
                let (w, h, c, s) = png(&dir.join(format!("{name}/{f}.png")));
                let (lw, lh, lc, l) = png(&dir.join(format!("pair/{f}_left.png")));
                let (_, _, _, r) = png(&dir.join(format!("pair/{f}_right.png")));
                assert_eq!((w as usize, h, c), (2 * lw as usize + gap, lh, lc));
                let (first, second) = if layout == "side-by-side" {
                    (&l, &r)
                } else {
                    (&r, &l)
                };
                let row = w as usize * c;
                let half = lw as usize * c;
                for j in 0..h as usize {
                    let line = &s[j * row..(j + 1) * row];
                    assert_eq!(
                        &line[..half],
                        &first[j * half..(j + 1) * half],
                        "{name} {f}"
                    );
                    assert_eq!(&line[row - half..], &second[j * half..(j + 1) * half]);
                    // the gap shows the background (0.1, 0.2, 0.3)
                    for px in line[half..row - half].chunks(c) {
                        assert_eq!(px, [26, 51, 77]);
                    }
                }
            }
        }
    }
}

fn folder(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect()
}

/// The number before `what` in `text` ("45 views rendered" -> 45).
fn number_before(text: &str, what: &str) -> usize {
    let at = text
        .find(what)
        .unwrap_or_else(|| panic!("`{what}` not in:\n{text}"));
    text[..at]
        .split_whitespace()
        .last()
        .and_then(|w| w.trim_start_matches('(').parse().ok())
        .unwrap_or_else(|| panic!("no number before `{what}` in:\n{text}"))
}

#[test]
fn view_reuse_renders_the_stated_views_and_the_same_bytes() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    // a full turn of 18 frames of 20 degrees, eyes 20 degrees apart: 18 views, not 36
    let scene = "[volume]\nsynthetic = \"marschner-lobb\"\nsizes = [12, 12, 12]\n\
        [orbit]\nframes = 18\n[stereo]\nangle = 20.0\nlayout = \"pair\"\n[image]\nsize = [16, 12]\n\
        [[render]]\nmode = \"mip\"\n[[render]]\nmode = \"composite\"\ntransfer = \"bone\"\n";
    std::fs::write(dir.join("s.toml"), scene).unwrap();
    let check = volcast(dir, &["check", "s.toml"]);
    let plan = String::from_utf8_lossy(&check.stdout).into_owned();
    assert!(check.status.success(), "{plan}");
    assert_eq!(number_before(&plan, "to render per pass"), 18, "{plan}");
    assert!(plan.contains("right eye of frame k-1"), "{plan}");
    let check = volcast(dir, &["check", "s.toml", "--no-view-reuse"]);
    let plan_no = String::from_utf8_lossy(&check.stdout).into_owned();
    assert_eq!(
        number_before(&plan_no, "to render per pass"),
        36,
        "{plan_no}"
    );
    // a part of the turn needs one more view than frames
    let check = volcast(dir, &["check", "s.toml", "--frames", "3..8"]);
    let part = String::from_utf8_lossy(&check.stdout).into_owned();
    assert_eq!(number_before(&part, "to render per pass"), 6, "{part}");

    let run = |out: &str, extra: &[&str]| {
        let mut args = vec!["render", "s.toml", "--out", out];
        args.extend_from_slice(extra);
        let o = volcast(dir, &args);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        (
            number_before(&err, "views rendered"),
            folder(&dir.join(out)),
        )
    };
    let (views, shared) = run("shared", &[]);
    let (views_no, separate) = run("separate", &["--no-view-reuse"]);
    assert_eq!((views, views_no), (2 * 18, 2 * 36));
    assert_eq!(shared.len(), 2 * 18 * 2);
    assert!(shared == separate, "reuse changed some bytes");
    // a range and a shard render the views they need, and the same bytes
    let (views, part) = run("part", &["--frames", "3..8"]);
    assert_eq!(views, 2 * 6);
    let (views, shard) = run("shard", &["--shard", "1/4"]);
    assert_eq!(views, 2 * 2 * 5, "frames 1, 5, 9, 13, 17 need both eyes");
    for (name, bytes) in part.iter().chain(&shard) {
        assert_eq!(Some(bytes), shared.get(name), "{name}");
    }
}

#[test]
fn stereo_settings_are_checked() {
    let base = "[volume]\nsynthetic = \"ball\"\nsizes = [4, 4, 4]\n";
    for (stereo, expect) in [
        (
            "method = \"parallel\"\nseparation = 0.1\nseparation_fraction = 0.1",
            "give only one of",
        ),
        ("separation = 0.1", "only used with method = \"parallel\""),
        ("method = \"paralel\"", "did you mean `parallel`"),
        (
            "anaglyph_colors = \"color\"",
            "only used with layout = \"anaglyph\"",
        ),
        (
            "layout = \"anaglyph\"\nanaglyph_colors = \"full\"",
            "expected one of `color`, `half-color`, `gray`",
        ),
        (
            "method = \"parallel\"\nseparation_fraction = 2.0",
            "fraction of the eye-target distance",
        ),
    ] {
        let text = format!("{base}[stereo]\n{stereo}\n");
        let e = volcast::scene::parse(&text, Path::new("s.toml"))
            .expect_err(stereo)
            .to_string();
        assert!(e.contains(expect), "{stereo}: {e}");
        assert!(e.contains("s.toml:"), "located: {e}");
    }
    let e = volcast::scene::parse(
        &format!(
            "{base}[camera]\nprojection = \"orthographic\"\n[stereo]\nmethod = \"parallel\"\n"
        ),
        Path::new("s.toml"),
    )
    .expect_err("orthographic parallel stereo")
    .to_string();
    assert!(e.contains("needs projection = \"perspective\""), "{e}");
}
