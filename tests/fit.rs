//! `[camera] zoom = "fit"`: the box of the voxels at or above the fit threshold is
//! framed, checked on the iso-sphere of `analytic.rs` (f = 1 - |x| on [-1, 1]^3 at
//! 97^3, so the voxels at or above 0.5 span the grid points within 0.5 of the
//! centre: the box [-0.5, 0.5]^3 exactly).

use std::path::Path;

use volcast::pipeline::render_films;
use volcast::plan::RunOptions;
use volcast::volume::Limits;

const SPHERE: &str =
    "[volume]\nsynthetic = \"sphere-distance\"\nradius = 1.0\nsizes = [97, 97, 97]\n\
                      [image]\nsize = [64, 64]\nformat = \"nrrd\"\n";

/// The covered columns' span (pixels) of each frame's surface image.
fn spans(text: &str) -> Vec<usize> {
    let scene =
        volcast::scene::parse(text, Path::new("fit.toml")).unwrap_or_else(|e| panic!("{e}"));
    let (views, summary) =
        render_films(&scene, &RunOptions::default(), &Limits::default()).expect("renders");
    assert!(
        summary.notes.iter().any(|n| n.contains("zoom = \"fit\"")),
        "{:?}",
        summary.notes
    );
    views
        .iter()
        .map(|v| {
            let f = &v.film;
            let cols: Vec<usize> = (0..f.width)
                .filter(|&i| (0..f.height).any(|j| f.pixel(i, j)[3] > 0.0))
                .collect();
            // nothing touches the image's edges
            assert!(
                !cols.is_empty() && cols[0] > 0 && *cols.last().unwrap() < f.width - 1,
                "{cols:?}"
            );
            cols.last().unwrap() - cols[0] + 1
        })
        .collect()
}

#[test]
fn fit_frames_the_box_of_the_voxels_above_the_threshold() {
    // one frame looking along +y: the box's half-width 0.5 is framed with the margin
    // (4 % of the image per side): the image's half-width is 0.5 * 1.08 world units,
    // and the iso-sphere of radius 0.5 spans 64 / 1.08 = 59.3 pixels
    let pass = "[[render]]\nmode = \"surface\"\niso = 0.5\n";
    for projection in ["orthographic", "perspective"] {
        let s = spans(&format!(
            "{SPHERE}[camera]\nprojection = \"{projection}\"\nzoom = \"fit\"\n{pass}"
        ));
        if projection == "orthographic" {
            assert!((58..=60).contains(&s[0]), "{s:?}");
        } else {
            // the box's near corners are closer to the eye than the sphere's rim:
            // the sphere looks smaller than the box it is framed by
            assert!((44..=60).contains(&s[0]), "{s:?}");
        }
    }
    // turning 45 degrees shows the box's diagonal, sqrt 2 wider: one zoom for the
    // whole orbit frames that, and the sphere shrinks by sqrt 2 in every frame
    let s = spans(&format!(
        "{SPHERE}[camera]\nprojection = \"orthographic\"\nzoom = \"fit\"\n[orbit]\nframes = 8\n{pass}"
    ));
    for w in s {
        assert!((41..=43).contains(&w), "{w}");
    }
    // fit_threshold picks another box: the voxels at or above 0.75 span [-0.25, 0.25]
    let s = spans(&format!(
        "{SPHERE}[camera]\nprojection = \"orthographic\"\nzoom = \"fit\"\nfit_threshold = 0.75\n\
         [[render]]\nmode = \"surface\"\niso = 0.75\n"
    ));
    assert!((58..=60).contains(&s[0]), "{s:?}");
}

#[test]
fn fit_without_voxels_is_refused_before_anything_is_written() {
    // values up to 1 in a window [0, 2]: nothing reaches 0.9 of the window
    let text = "[volume]\nsynthetic = \"sphere-distance\"\nsizes = [9, 9, 9]\nwindow = [0, 2]\n\
                [camera]\nzoom = \"fit\"\nfit_threshold = 0.9\n[[render]]\nmode = \"mip\"\n";
    let scene = volcast::scene::parse(text, Path::new("fit.toml")).unwrap();
    let err = render_films(&scene, &RunOptions::default(), &Limits::default())
        .expect_err("no voxel to frame")
        .to_string();
    assert!(
        err.contains("no voxel") && err.contains("fit_threshold"),
        "{err}"
    );
    for (bad, want) in [
        (
            "zoom = \"fitt\"\n",
            "expected a positive magnification, or \"fit\"",
        ),
        ("zoom = -1\n", "expected a positive magnification"),
        (
            "fit_threshold = 0.5\n",
            "`fit_threshold` is used with zoom = \"fit\"",
        ),
    ] {
        let text = format!("[volume]\nsynthetic = \"ball\"\nsizes = [4, 4, 4]\n[camera]\n{bad}");
        let err = volcast::scene::parse(&text, Path::new("fit.toml"))
            .expect_err(bad)
            .to_string();
        assert!(err.contains(want), "{bad}: {err}");
    }
}
