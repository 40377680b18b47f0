//! Clipping planes (`[[clip]]`) against closed forms: a Gaussian cut through its
//! centre, an oblique cut of its MIP, planes parallel to the rays, and the cut face
//! of an iso-sphere with and without a cap. The geometry is that of `analytic.rs`:
//! an orthographic camera at azimuth 0 looking along +y (from y < 0), image right
//! = +x, image up = +z.

use crate::analytic::{erf, gauss_trilinear_bound, pixel_xz, render, GAUSS, SPHERE};
use crate::assert_close;

/// Pixels of an n x n image whose rays cross the box [-1, 1]^3.
fn box_pixels(n: usize) -> impl Iterator<Item = (usize, usize, f64, f64)> {
    (0..n).flat_map(move |j| {
        (0..n).filter_map(move |i| {
            let (x, z) = pixel_xz(i, j, n);
            (x.abs() < 1.0 && z.abs() < 1.0).then_some((i, j, x, z))
        })
    })
}

#[test]
fn a_plane_through_the_centre_halves_the_exact_xray_of_a_gaussian() {
    // the plane y = 0 across the rays; either side keeps half of the symmetric blob
    for normal in ["[0, 1, 0]", "[0, -1, 0]"] {
        let v = render(&format!(
            "{GAUSS}[[render]]\nname = \"full\"\nmode = \"xray\"\nintegration = \"exact\"\n\
             [[render]]\nname = \"cut\"\nmode = \"xray\"\nintegration = \"exact\"\n\
             [[clip]]\npoint = [0, 0, 0]\nnormal = {normal}\npasses = [\"cut\"]\n"
        ));
        let s = 0.25f64;
        let mut worst = 0.0f64;
        for (i, j, x, z) in box_pixels(41) {
            let full = v[0].film.pixel(i, j)[0] as f64;
            let cut = v[1].film.pixel(i, j)[0] as f64;
            if full > 1e-3 {
                worst = worst.max((cut / full - 0.5).abs());
            }
            // and against the closed form: half the chord's integral
            let want = 0.5
                * (2.0 * std::f64::consts::PI).sqrt()
                * s
                * (-(x * x + z * z) / (2.0 * s * s)).exp()
                * erf(1.0 / (s * 2f64.sqrt()));
            assert_close!(cut, want, gauss_trilinear_bound(), "cut xray at ({i},{j})");
        }
        eprintln!("normal {normal}: cut / full - 1/2 at most {worst:.2e}");
        assert!(worst < 1e-5, "normal {normal}: {worst}");
    }
}

#[test]
fn a_sampled_cut_keeps_the_analytic_half_too() {
    let v = render(&format!(
        "{GAUSS}[[render]]\nmode = \"xray\"\nstep = 0.5\n\
         [[clip]]\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\n"
    ));
    let s = 0.25f64;
    let h: f64 = 2.0 / 96.0;
    // reconstruction over a chord of length 1, plus the trapezoid rule's error
    let tol = gauss_trilinear_bound() + (h / 2.0).powi(2) / 12.0 / (s * s);
    for (i, j, x, z) in box_pixels(41) {
        let want = 0.5
            * (2.0 * std::f64::consts::PI).sqrt()
            * s
            * (-(x * x + z * z) / (2.0 * s * s)).exp()
            * erf(1.0 / (s * 2f64.sqrt()));
        assert_close!(v[0].film.pixel(i, j)[0], want, tol, "({i},{j})");
    }
}

#[test]
fn an_oblique_cut_moves_the_maximum_of_a_gaussian() {
    // the plane y + z = 0 removes y + z > 0: along the ray (x, y, z) the kept part
    // is y <= -z, so the maximum is at y = 0 when z <= 0 and at y = -z otherwise
    let v = render(&format!(
        "{GAUSS}[[render]]\nmode = \"mip\"\nintegration = \"exact\"\n\
         [[clip]]\npoint = [0, 0, 0]\nnormal = [0, 1, 1]\n"
    ));
    let s2 = 2.0 * 0.25 * 0.25;
    for (i, j, x, z) in box_pixels(41) {
        let want = if z <= 0.0 {
            (-(x * x + z * z) / s2).exp()
        } else {
            (-(x * x + 2.0 * z * z) / s2).exp()
        };
        assert_close!(
            v[0].film.pixel(i, j)[0],
            want,
            gauss_trilinear_bound(),
            "({i},{j}) at x {x:.3}, z {z:.3}"
        );
    }
}

#[test]
fn planes_along_the_rays_remove_whole_pixels_and_offset_moves_them() {
    // x > 0.2 removed: by the point, or by a plane through the origin moved 0.2
    for clip in [
        "point = [0.2, 0, 0]\nnormal = [1, 0, 0]",
        "point = [0, 0, 0]\nnormal = [2, 0, 0]\noffset = 0.2",
    ] {
        let v = render(&format!(
            "{GAUSS}[[render]]\nname = \"full\"\nmode = \"mip\"\n\
             [[render]]\nname = \"cut\"\nmode = \"mip\"\n\
             [[clip]]\n{clip}\npasses = [\"cut\"]\n"
        ));
        let mut kept = 0;
        for (i, j, x, _) in box_pixels(41) {
            let (full, cut) = (v[0].film.pixel(i, j)[0], v[1].film.pixel(i, j)[0]);
            if x > 0.2 {
                assert!(cut.is_nan(), "({i},{j}) at x {x} is removed, got {cut}");
            } else {
                assert_eq!(cut.to_bits(), full.to_bits(), "({i},{j}) is kept whole");
                kept += 1;
            }
        }
        assert!(kept > 300, "{kept}");
    }
}

#[test]
fn a_capped_cut_shows_the_face_an_uncapped_one_the_inside() {
    // The iso-sphere of radius r = 0.5 cut by the plane y = 0 with its normal
    // towards the camera (-y): the near half is removed. A capped cut is a flat
    // face at y = 0 facing the viewer (a matte white material under a headlight
    // shows n . v = 1); without a cap the ray goes on inside the sphere to its far
    // wall at y = sqrt(r^2 - d^2), seen from inside (n . v = sqrt(1 - d^2/r^2)).
    // Depth is measured from the bounding sphere's entry at y = -sqrt(3 - d^2).
    let matte =
        "[material.matte]\nambient = [0, 0, 0]\ndiffuse = [1, 1, 1]\nspecular = [0, 0, 0]\n";
    let passes = "[[render]]\nname = \"surface\"\nmode = \"surface\"\niso = 0.5\nmaterial = \"matte\"\n\
                  [[render]]\nname = \"depth\"\nmode = \"depth\"\nthreshold = 0.5\n\
                  [[render]]\nname = \"exact\"\nmode = \"depth\"\nthreshold = 0.5\nintegration = \"exact\"\n";
    let clip = "[[clip]]\npoint = [0, 0, 0]\nnormal = [0, -1, 0]\n";
    let capped = render(&format!("{SPHERE}{matte}{passes}{clip}cap = true\n"));
    let open = render(&format!("{SPHERE}{matte}{passes}{clip}"));
    let r: f64 = 0.5;
    let h: f64 = 2.0 / 96.0;
    let depth_tol = 4.0 * h * h / 8.0 * 2.0 / r;
    let mut inside = 0;
    for (i, j, x, z) in box_pixels(41) {
        let d2 = x * x + z * z;
        if d2 > (0.9 * r).powi(2) {
            continue; // the silhouette is ill-conditioned
        }
        inside += 1;
        let cap = capped[0].film.pixel(i, j);
        assert_close!(cap[0], 1.0, 1e-6, "cap shading at ({i},{j})");
        assert_eq!(cap[3], 1.0);
        let wall = open[0].film.pixel(i, j);
        assert_close!(
            wall[0],
            (1.0 - d2 / (r * r)).sqrt(),
            0.03,
            "inner wall shading at ({i},{j})"
        );
        let reference = (3.0 - d2).sqrt();
        for p in [1, 2] {
            assert_close!(
                capped[p].film.pixel(i, j)[0],
                reference,
                1e-5,
                "capped depth (pass {p}) at ({i},{j})"
            );
            assert_close!(
                open[p].film.pixel(i, j)[0],
                reference + (r * r - d2).sqrt(),
                depth_tol,
                "depth of the far wall (pass {p}) at ({i},{j})"
            );
        }
    }
    assert!(inside > 50);
}

#[test]
fn clip_errors_name_the_key() {
    let bad = [
        ("[[clip]]\nnormal = [0, 0, 1]\n", "needs `point"),
        ("[[clip]]\npoint = [0, 0, 0]\n", "needs `normal"),
        (
            "[[clip]]\npoint = [0, 0, 0]\nnormal = [0, 0, 0]\n",
            "non-zero",
        ),
        (
            "[[clip]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\npasses = [\"mpi\"]\n",
            "did you mean `mip`",
        ),
        (
            "[[clip]]\nname = \"a\"\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\n[[clip]]\nname = \"a\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\n",
            "two [[clip]] planes are named `a`",
        ),
        (
            "[[clip]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nside = 1\n",
            "unknown field `side`",
        ),
    ];
    for (clip, want) in bad {
        let text = format!("{GAUSS}[[render]]\nmode = \"mip\"\n{clip}");
        let err = volcast::scene::parse(&text, std::path::Path::new("clip.toml"))
            .expect_err(clip)
            .to_string();
        assert!(err.contains(want), "{clip}: {err}");
        assert!(err.contains("clip.toml:"), "a location: {err}");
    }
}
