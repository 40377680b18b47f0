//! Overlays (issue 9, item 4): labels, the scale bar and the colour bar land at the
//! right pixels of the written PNG frames and leave every other pixel as it was;
//! NRRD output never has them.

use std::path::{Path, PathBuf};

use volcast::output::overlay::{colorbar_rect, margin};
use volcast::pipeline::{render, NoProgress};
use volcast::plan::RunOptions;
use volcast::volume::Limits;

use crate::colormap::{table_at, tables};

/// A ball in the middle of an orthographic view, black around it.
fn scene(size: [usize; 2], image_extra: &str, rest: &str) -> String {
    format!(
        "[volume]\nsynthetic = \"ball\"\nradius = 0.4\nsizes = [17, 17, 17]\n\
         [camera]\nprojection = \"orthographic\"\nazimuth = 30\n[orbit]\nframes = 4\n\
         [image]\nsize = [{}, {}]\n{image_extra}\n[[render]]\nmode = \"mip\"\nwindow = [0, 1]\n{rest}",
        size[0], size[1]
    )
}

/// Renders `text` (frames 0..2) into a fresh folder; returns it.
fn written(text: &str) -> (tempfile::TempDir, PathBuf) {
    let scene =
        volcast::scene::parse(text, Path::new("overlay.toml")).unwrap_or_else(|e| panic!("{e}"));
    let dir = tempfile::tempdir().unwrap();
    let opts = RunOptions {
        out: Some(dir.path().to_path_buf()),
        frames: Some(0..2),
        ..RunOptions::default()
    };
    render(&scene, &opts, &Limits::default(), &NoProgress).expect("renders");
    let p = dir.path().to_path_buf();
    (dir, p)
}

fn rgb(dir: &Path, file: &str) -> image::RgbImage {
    image::open(dir.join(file)).unwrap().into_rgb8()
}

/// The pixels that differ between two pictures.
fn changed(a: &image::RgbImage, b: &image::RgbImage) -> Vec<(u32, u32)> {
    assert_eq!(a.dimensions(), b.dimensions());
    a.enumerate_pixels()
        .filter(|(x, y, p)| b.get_pixel(*x, *y) != *p)
        .map(|(x, y, _)| (x, y))
        .collect()
}

#[test]
fn labels_touch_only_their_corner() {
    let plain = scene([96, 96], "", "");
    let (_d0, bare) = written(&plain);
    let base = rgb(&bare, "mip_0000.png");
    let m = margin(96, 96) as u32;
    for (position, size, region) in [
        // (x range, y range) the label must stay in: its corner, one line high
        ("top-left", 16.0, (m - 1..48, m - 1..m + 21)),
        ("bottom-right", 12.0, (48..97 - m, 96 - m - 16..97 - m)),
        ("top", 12.0, (10..86, m - 1..m + 16)),
    ] {
        let text = scene(
            [96, 96],
            "",
            &format!("[[label]]\ntext = \"Hg 42\"\nposition = \"{position}\"\nsize = {size}\ncolor = [1.0, 0.5, 0.0]\n"),
        );
        let (_d, dir) = written(&text);
        let img = rgb(&dir, "mip_0000.png");
        let diff = changed(&base, &img);
        assert!(
            diff.len() > 30,
            "{position}: the label is drawn ({} pixels)",
            diff.len()
        );
        for (x, y) in &diff {
            assert!(
                region.0.contains(x) && region.1.contains(y),
                "{position}: pixel ({x}, {y}) changed outside {region:?}"
            );
        }
        // drawn in its colour (orange, blended with black at the glyphs' edges)
        for &(x, y) in &diff {
            let [r, g, b] = img.get_pixel(x, y).0;
            assert!(
                b == 0 && g.abs_diff(r / 2) <= 1,
                "{position}: ({x}, {y}) is {r} {g} {b}"
            );
        }
        assert!(
            diff.iter().any(|&(x, y)| img.get_pixel(x, y).0[0] > 200),
            "{position}: no pixel near the label's colour"
        );
    }
}

#[test]
fn placeholders_are_the_frames_values() {
    // frame 1 of 4 from azimuth 30: azimuth 120
    let with = |t: &str| {
        scene(
            [240, 48],
            "",
            &format!("[[label]]\ntext = \"{t}\"\nsize = 10\n"),
        )
    };
    let (_a, a) = written(&with("{scene} {pass} {frame} {azimuth} {elevation}"));
    let (_b, b) = written(&with("overlay mip 1 120 0"));
    let (x, y) = (
        std::fs::read(a.join("mip_0001.png")).unwrap(),
        std::fs::read(b.join("mip_0001.png")).unwrap(),
    );
    assert_eq!(x, y, "placeholders filled with the frame's values");
    let (x0, y0) = (
        std::fs::read(a.join("mip_0000.png")).unwrap(),
        std::fs::read(b.join("mip_0000.png")).unwrap(),
    );
    assert_ne!(x0, y0, "frame 0 shows other values");
}

#[test]
fn the_scale_bar_is_its_length_in_pixels() {
    // 200 x 100: the smaller side (100 px) spans the bounding sphere's diameter,
    // 2 sqrt 3 (docs/scene-reference.md, orthographic zoom 1), so a pixel is 2 sqrt 3 / 100 world
    // units; a quarter of the width is 1.73 units, so the bar is 1 unit: 28.87 px
    let (_d, dir) = written(&scene([200, 100], "scale_bar = true", ""));
    let (_e, bare) = written(&scene([200, 100], "", ""));
    let img = rgb(&dir, "mip_0000.png");
    let diff = changed(&rgb(&bare, "mip_0000.png"), &img);
    let pixel = 2.0 * 3f64.sqrt() / 100.0;
    let want = (1.0 / pixel).round() as u32;
    let m = margin(200, 100) as u32;
    // the bar: the bottom rows of white pixels, from the margin on
    let bar_rows: Vec<u32> = (0..100)
        .filter(|&y| (m..m + want).all(|x| img.get_pixel(x, y).0 == [255; 3]))
        .collect();
    assert!(!bar_rows.is_empty(), "a white bar from x = {m}");
    for &y in &bar_rows {
        let run = (m..200)
            .take_while(|&x| img.get_pixel(x, y).0 == [255; 3])
            .count() as u32;
        assert_eq!(run, want, "row {y}: bar of {run} px, want {want}");
        assert!(y < 100 - m + 1 && y > 100 - m - 6, "row {y} at the bottom");
    }
    // the bar and its number ("1") at the bottom left only
    for (x, y) in diff {
        assert!(x < m + want + 1 && y > 60, "({x}, {y}) changed");
    }
}

#[test]
fn the_colour_bar_shows_the_map_from_top_to_bottom() {
    let (_d, dir) = written(&scene(
        [80, 120],
        "colorbar = true",
        "colormap = \"viridis\"\n",
    ));
    let (_e, bare) = written(&scene([80, 120], "", "colormap = \"viridis\"\n"));
    let img = rgb(&dir, "mip_0000.png");
    let viridis = &tables()["viridis"];
    let (x0, y0, w, h) = colorbar_rect(80, 120);
    assert!(x0 + w < 80 && h >= 50, "on the right, half the height");
    for r in 0..h {
        let want = table_at(viridis, 1.0 - (r as f64 + 0.5) / h as f64);
        for x in [x0, x0 + w - 1] {
            let got = img.get_pixel(x as u32, (y0 + r) as u32).0;
            for c in 0..3 {
                let d = (f64::from(got[c]) / 255.0 - want[c]).abs();
                assert!(d <= 2.6 / 255.0, "row {r}: {got:?} vs {want:?}");
            }
        }
    }
    // the top is viridis's yellow end, the bottom its purple one
    assert!(img.get_pixel(x0 as u32, y0 as u32).0[1] > 200);
    assert!(img.get_pixel(x0 as u32, (y0 + h - 1) as u32).0[1] < 20);
    // only the bar and its numbers to its left changed
    for (x, y) in changed(&rgb(&bare, "mip_0000.png"), &img) {
        assert!(
            x >= 30 && (y0 as u32 - 8..(y0 + h) as u32 + 8).contains(&y),
            "({x}, {y}) changed"
        );
    }
}

#[test]
fn nrrd_output_has_no_overlays() {
    let over = "format = \"nrrd\"\nscale_bar = true\ncolorbar = true";
    let (_d, a) = written(&scene([32, 32], over, "[[label]]\ntext = \"{frame}\"\n"));
    let (_e, b) = written(&scene([32, 32], "format = \"nrrd\"", ""));
    for f in ["mip_0000.nrrd", "mip_0001.nrrd"] {
        assert_eq!(
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
            "{f}"
        );
    }
}

#[test]
fn overlay_errors_name_the_key() {
    let bad = [
        (
            "[volume]\nsynthetic = \"ball\"\n[image]\nscale_bar = true\n",
            "overlay.toml:4:13: scale_bar = true needs [camera] projection = \"orthographic\"",
        ),
        (
            "[volume]\nsynthetic = \"ball\"\n[[label]]\ntext = \"{frme}\"\n",
            "overlay.toml:4:8: text = \"{frme}\": `{frme}` is not a placeholder",
        ),
        (
            "[volume]\nsynthetic = \"ball\"\n[[label]]\ntext = \"a\"\nposition = \"top-centre\"\n",
            "position = \"top-centre\" is not known",
        ),
        (
            "[volume]\nsynthetic = \"ball\"\n[[label]]\nposition = \"top\"\n",
            "[[label]] needs `text`",
        ),
        (
            "[volume]\nsynthetic = \"ball\"\n[[label]]\ntext = \"a\"\nsize = 0\n",
            "size = 0: expected a font size in pixels",
        ),
    ];
    for (text, want) in bad {
        let err = volcast::scene::parse(text, Path::new("overlay.toml"))
            .expect_err(text)
            .to_string();
        assert!(err.contains(want), "{text}: {err}");
    }
}
