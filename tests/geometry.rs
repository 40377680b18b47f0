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

#[test]
fn crop_clips_rays_to_the_sub_volume_and_frames_it() {
    // f = 1 everywhere (a ball larger than the box); grid 33^3 on [-1, 1], h = 1/16.
    // Crop x to voxels 0..=8, i.e. x in [-1, -0.5]: the camera looks at the crop box's
    // centre, rays through it cross the full y range (integral 2), rays beside it miss.
    let v = render(
        "[volume]\nsynthetic = \"ball\"\nradius = 3.0\nsizes = [33, 33, 33]\ncrop = [[0, 8], [0, 32], [0, 32]]\n\
         [camera]\nprojection = \"orthographic\"\n[image]\nsize = [21, 21]\nformat = \"nrrd\"\n[[render]]\nmode = \"xray\"\n",
    );
    let f = &v[0].film;
    crate::assert_close!(
        f.pixel(10, 10)[0],
        2.0,
        1e-5,
        "centre ray through the crop box"
    );
    // the image spans the crop box's bounding sphere: its radius is
    // sqrt(0.25^2 + 1 + 1) = 1.5, so the box's x half-width 0.25 covers the middle
    // 0.25/1.5 of each half of the image: pixel centres are 3/21 apart, so
    // columns 8..=12 hit and columns 7 and 13 miss
    assert_eq!(f.pixel(0, 10)[0], 0.0);
    assert_eq!(f.pixel(20, 10)[0], 0.0);
    assert!(f.pixel(9, 10)[0] > 1.9 && f.pixel(11, 10)[0] > 1.9);
    assert_eq!(f.pixel(7, 10)[0], 0.0);
    assert_eq!(f.pixel(13, 10)[0], 0.0);
}

#[test]
fn crop_outside_the_volume_is_rejected() {
    let scene = volcast::scene::parse(
        "[volume]\nsynthetic = \"ball\"\nsizes = [8, 8, 8]\ncrop = [[0, 8], [0, 7], [0, 7]]\n",
        std::path::Path::new("c.toml"),
    )
    .unwrap();
    let err = volcast::pipeline::render_films(&scene, &Default::default(), &Default::default())
        .unwrap_err();
    assert!(
        err.to_string()
            .contains("volume.crop: the x range [0, 8] is outside the volume's 8 voxels"),
        "{err}"
    );
}
