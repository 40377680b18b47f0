//! Cameras and orbits end to end: frame k of an orbit is the view at
//! `azimuth + k * degrees / frames`, a full turn has no duplicated frame, and views
//! straight along `up` render.

use crate::analytic::render;

/// An asymmetric field, so that different views give different images.
const ML: &str = "[volume]\nsynthetic = \"marschner-lobb\"\nsizes = [20, 20, 20]\n[image]\nsize = [24, 20]\nformat = \"nrrd\"\n";

#[test]
fn frame_k_is_the_view_at_its_azimuth() {
    let orbit = render(&format!(
        "{ML}[camera]\nazimuth = 10.0\nelevation = 20.0\n[orbit]\nframes = 4\ndegrees = 360.0\n[[render]]\nmode = \"xray\"\n"
    ));
    assert_eq!(orbit.len(), 4);
    for (k, view) in orbit.iter().enumerate() {
        let single = render(&format!(
            "{ML}[camera]\nazimuth = {}\nelevation = 20.0\n[[render]]\nmode = \"xray\"\n",
            10.0 + 90.0 * k as f64
        ));
        assert_eq!(view.film, single[0].film, "frame {k}");
    }
    // 360 degrees over 4 frames: four distinct views, none repeating frame 0
    for k in 1..4 {
        assert_ne!(orbit[k].film, orbit[0].film, "frame {k} repeats frame 0");
    }
}

#[test]
fn views_along_up_render_without_nan() {
    for (el, proj) in [
        (90.0, "perspective"),
        (-90.0, "orthographic"),
        (90.0, "orthographic"),
    ] {
        let v = render(&format!(
            "{ML}[camera]\nprojection = \"{proj}\"\nelevation = {el}\n[[render]]\nmode = \"xray\"\n[[render]]\nmode = \"surface\"\n"
        ));
        for view in &v {
            assert!(
                view.film.data.iter().all(|x| x.is_finite()),
                "elevation {el} {proj}"
            );
            assert!(
                view.film.data.iter().any(|&x| x > 0.0),
                "elevation {el} {proj}: empty image"
            );
        }
    }
}

#[test]
fn other_up_vectors_and_a_camera_inside_the_volume() {
    // y up: elevation 90 looks straight down -y (X-ray: a ray that misses is 0, not NaN)
    let v = render(&format!(
        "{ML}[camera]\nup = [0, 1, 0]\nelevation = 90.0\n[[render]]\nmode = \"xray\"\n"
    ));
    assert!(v[0].film.data.iter().all(|x| x.is_finite()));
    assert!(v[0].film.data.iter().any(|&x| x > 0.0));
    // a perspective eye inside the box: every ray starts inside and is sampled
    let v = render(&format!(
        "{ML}[camera]\ndistance = 0.3\nfov = 90.0\n[[render]]\nmode = \"mip\"\n[[render]]\nmode = \"depth\"\nthreshold = 0.0\n"
    ));
    assert!(
        v[0].film.data.iter().all(|x| x.is_finite()),
        "every ray hits from inside"
    );
    // threshold 0 is crossed at the first sample: depth 0 from the eye
    assert!(v[1].film.data.iter().all(|&x| x == 0.0));
}
