//! Every render mode against the closed-form answers of docs/formulas.md ("Analytic
//! references for accuracy tests"), computed here independently of the renderer.
//!
//! Geometry used throughout: synthetic fields on [-1, 1]^3, an orthographic camera
//! at azimuth 0 (rays along +y, image right = +x, image up = +z). With zoom 1 the
//! image's side spans the diameter of the box's bounding sphere, 2*sqrt(3), so pixel
//! (i, j) of an N x N image looks along the line x = (2(i+0.5)/N - 1) sqrt(3),
//! z = (1 - 2(j+0.5)/N) sqrt(3).

use std::path::Path;

use volcast::pipeline::{render_films, RenderedView};
use volcast::plan::RunOptions;
use volcast::volume::Limits;

use crate::assert_close;

const SQRT3: f64 = 1.732_050_807_568_877_2;

/// Renders scene text (as if at the project root) and returns its views.
pub fn render(text: &str) -> Vec<RenderedView> {
    let scene =
        volcast::scene::parse(text, Path::new("test.toml")).unwrap_or_else(|e| panic!("{e}"));
    render_films(&scene, &RunOptions::default(), &Limits::default())
        .expect("renders")
        .0
}

/// World (x, z) of the centre of pixel (i, j) of an n x n orthographic image.
pub fn pixel_xz(i: usize, j: usize, n: usize) -> (f64, f64) {
    let u = 2.0 * (i as f64 + 0.5) / n as f64 - 1.0;
    let v = 1.0 - 2.0 * (j as f64 + 0.5) / n as f64;
    (u * SQRT3, v * SQRT3)
}

/// erf by Abramowitz & Stegun 7.1.26 (absolute error below 1.5e-7).
pub fn erf(x: f64) -> f64 {
    let s = x.signum();
    let x = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let y = 1.0
        - (((((1.061_405_429 * t - 1.453_152_027) * t) + 1.421_413_741) * t - 0.284_496_736) * t
            + 0.254_829_592)
            * t
            * (-x * x).exp();
    s * y
}

/// Pixels whose rays pass through the box, strictly inside `margin` of its faces.
fn inner_pixels(n: usize, margin: f64) -> impl Iterator<Item = (usize, usize, f64, f64)> {
    (0..n).flat_map(move |j| {
        (0..n).filter_map(move |i| {
            let (x, z) = pixel_xz(i, j, n);
            (x.abs() < 1.0 - margin && z.abs() < 1.0 - margin).then_some((i, j, x, z))
        })
    })
}

pub const GAUSS: &str = r#"
[volume]
synthetic = "gaussian"
sigma = 0.25
sizes = [97, 97, 97]
[camera]
projection = "orthographic"
[image]
size = [41, 41]
format = "nrrd"
"#;

/// Bound on the trilinear reconstruction error of the Gaussian blob:
/// |f - I f| <= h^2/8 (|f_xx| + |f_yy| + |f_zz|), |f_aa| <= 1/sigma^2, h = 2/96.
pub fn gauss_trilinear_bound() -> f64 {
    let h = 2.0 / 96.0;
    h * h / 8.0 * 3.0 / (0.25 * 0.25)
}

#[test]
fn xray_of_a_gaussian_is_its_line_integral() {
    let v = render(&format!("{GAUSS}[[render]]\nmode = \"xray\"\nstep = 0.5\n"));
    let film = &v[0].film;
    let s = 0.25f64;
    let mut max_err = 0.0f64;
    for (i, j, x, z) in inner_pixels(41, 0.0) {
        // the blob is cut off at the box faces y = -1 and y = +1
        let want = (2.0 * std::f64::consts::PI).sqrt()
            * s
            * (-(x * x + z * z) / (2.0 * s * s)).exp()
            * erf(1.0 / (s * 2f64.sqrt()));
        let got = film.pixel(i, j)[0] as f64;
        max_err = max_err.max((got - want).abs());
    }
    // reconstruction error integrated over a chord of length 2, plus the trapezoid
    // rule's (L dt^2 / 12) max|f''| with dt = h/2
    let h: f64 = 2.0 / 96.0;
    let tol = 2.0 * gauss_trilinear_bound() + 2.0 * (h / 2.0).powi(2) / 12.0 / (s * s);
    eprintln!("xray of a gaussian: max error {max_err:.3e}, tolerance {tol:.3e}");
    assert!(max_err < tol, "max error {max_err} > {tol}");
    assert!(max_err > 0.0, "a sampled render is never exact here");
}

#[test]
fn xray_outputs_follow_beer_lambert() {
    let mut text = GAUSS.to_string();
    for out in ["integral", "absorbed", "transmitted"] {
        text += &format!(
            "[[render]]\nname = \"{out}\"\nmode = \"xray\"\noutput = \"{out}\"\nmu = 2.5\n"
        );
    }
    let v = render(&text);
    for (i, j, _, _) in inner_pixels(41, 0.0) {
        let tau = v[0].film.pixel(i, j)[0] as f64;
        assert_close!(
            v[1].film.pixel(i, j)[0],
            1.0 - (-tau).exp(),
            1e-6,
            "absorbed at ({i},{j})"
        );
        assert_close!(
            v[2].film.pixel(i, j)[0],
            (-tau).exp(),
            1e-6,
            "transmitted at ({i},{j})"
        );
    }
    // mu scales the integral: the centre ray of a mu = 2.5 integral is 2.5 x the mu = 1 one
    let base = render(&format!("{GAUSS}[[render]]\nmode = \"xray\"\n"));
    assert_close!(
        v[0].film.pixel(20, 20)[0],
        2.5 * base[0].film.pixel(20, 20)[0],
        1e-5,
        "mu scaling"
    );
}

#[test]
fn mip_minip_average_of_a_gaussian() {
    let v = render(&format!(
        "{GAUSS}[[render]]\nmode = \"mip\"\nstep = 0.5\n[[render]]\nmode = \"minip\"\nstep = 0.5\n[[render]]\nmode = \"average\"\nstep = 0.5\n[[render]]\nmode = \"xray\"\nstep = 0.5\n"
    ));
    let s2 = 2.0 * 0.25 * 0.25;
    // MIP: the maximum along the ray is at y = 0; sampling misses it by at most dt/2,
    // which costs at most (dt/2)^2 / (2 s^2) of the peak.
    let dt: f64 = 2.0 / 96.0 / 2.0;
    let tol = gauss_trilinear_bound() + (dt / 2.0).powi(2) / s2;
    for (i, j, x, z) in inner_pixels(41, 0.0) {
        let d2 = x * x + z * z;
        assert_close!(
            v[0].film.pixel(i, j)[0],
            (-d2 / s2).exp(),
            tol,
            "mip at ({i},{j})"
        );
        // MinIP: the minimum is at the box faces y = +-1, which are always sampled
        assert_close!(
            v[1].film.pixel(i, j)[0],
            (-(d2 + 1.0) / s2).exp(),
            gauss_trilinear_bound(),
            "minip at ({i},{j})"
        );
        // average = integral / chord (2 for every ray along y through the box)
        assert_close!(
            v[2].film.pixel(i, j)[0],
            v[3].film.pixel(i, j)[0] as f64 / 2.0,
            1e-6,
            "average at ({i},{j})"
        );
    }
}

#[test]
fn lmip_finds_the_first_local_maximum() {
    // two blobs on the ray through the centre would need a custom field; instead:
    // above the threshold the first local maximum of one blob is its peak (= MIP),
    // and where the ray never reaches the threshold LMIP falls back to the MIP.
    let v = render(&format!(
        "{GAUSS}[[render]]\nmode = \"lmip\"\nthreshold = 0.3\n[[render]]\nmode = \"mip\"\n"
    ));
    for (i, j, _, _) in inner_pixels(41, 0.0) {
        assert_eq!(
            v[0].film.pixel(i, j)[0],
            v[1].film.pixel(i, j)[0],
            "({i},{j})"
        );
    }
}

pub const SPHERE: &str = r#"
[volume]
synthetic = "sphere-distance"
radius = 1.0
sizes = [97, 97, 97]
[camera]
projection = "orthographic"
[image]
size = [41, 41]
format = "nrrd"
"#;

#[test]
fn depth_of_a_sphere_is_refined_between_samples() {
    // f = 1 - |x|: threshold T crosses on the sphere of radius r = 1 - T. Depth is
    // measured from the entry into the bounding sphere (radius sqrt 3).
    let t = 0.5;
    let r = 1.0 - t;
    for step in [0.5, 2.0] {
        let v = render(&format!(
            "{SPHERE}[[render]]\nmode = \"depth\"\nthreshold = {t}\nstep = {step}\n"
        ));
        let dt = step * 2.0 / 96.0;
        let mut max_err = 0.0f64;
        let mut hits = 0;
        for j in 0..41 {
            for i in 0..41 {
                let (x, z) = pixel_xz(i, j, 41);
                let d2 = x * x + z * z;
                let got = v[0].film.pixel(i, j)[0] as f64;
                if d2 >= r * r {
                    if d2 > (r * 1.05).powi(2) {
                        assert!(
                            got.is_nan(),
                            "({i},{j}) misses the iso-sphere but got {got}"
                        );
                    }
                    continue;
                }
                if d2 > (0.9 * r).powi(2) {
                    continue; // near the silhouette depth is ill-conditioned
                }
                let want = (3.0 - d2).sqrt() - (r * r - d2).sqrt();
                max_err = max_err.max((got - want).abs());
                hits += 1;
            }
        }
        eprintln!("depth at step {step}: max error {max_err:.3e} (dt {dt:.3e})");
        assert!(hits > 50);
        // Snapping to samples would err by up to dt; refinement leaves only the
        // reconstruction error of the cone |x|: about (h^2/8) * (2/r) in value per
        // axis pair, and |grad f| = 1, so the same in depth; 4x that as the bound.
        let h: f64 = 2.0 / 96.0;
        let tol = 4.0 * h * h / 8.0 * 2.0 / r;
        assert!(
            max_err < tol && max_err < dt / 10.0,
            "step {step}: max depth error {max_err} > {tol} (dt {dt})"
        );
    }
}

#[test]
fn surface_normals_of_a_sphere_are_radial() {
    // A purely diffuse white material under a headlight shows n . v, which for the
    // radial normal of an iso-sphere of radius r seen along y is sqrt(1 - d^2/r^2).
    for gradient in ["central", "sobel"] {
        let v = render(&format!(
            "{SPHERE}[material.matte]\nambient = [0, 0, 0]\ndiffuse = [1, 1, 1]\nspecular = [0, 0, 0]\n\
             [[render]]\nmode = \"surface\"\niso = 0.5\nmaterial = \"matte\"\ngradient = \"{gradient}\"\nstep = 0.5\n"
        ));
        let r: f64 = 0.5;
        let mut max_angle = 0.0f64;
        let mut sum = 0.0;
        let mut n = 0;
        for j in 0..41 {
            for i in 0..41 {
                let (x, z) = pixel_xz(i, j, 41);
                let d2 = x * x + z * z;
                if d2 > (0.9 * r).powi(2) {
                    continue;
                }
                let px = v[0].film.pixel(i, j);
                assert_eq!(px[3], 1.0, "hit");
                let cos_got = (px[0] as f64).clamp(-1.0, 1.0);
                let cos_want = (1.0 - d2 / (r * r)).sqrt();
                let err = (cos_got.acos() - cos_want.acos()).abs();
                max_angle = max_angle.max(err);
                sum += err;
                n += 1;
            }
        }
        let mean = sum / n as f64;
        eprintln!("{gradient} normals: max {max_angle:.3e} rad, mean {mean:.3e} rad");
        // The gradient of the cone |x| is exactly radial; the estimators (differences
        // over 2h, trilinearly interpolated) err at second order in h/r:
        // (h/r)^2 = 1.7e-3 rad with h = 2/96, r = 0.5; twice that as the bound.
        let h: f64 = 2.0 / 96.0;
        let tol = 2.0 * (h / r).powi(2);
        assert!(
            max_angle < tol,
            "{gradient}: max normal error {max_angle} rad > {tol}"
        );
        assert!(
            mean < tol / 2.0,
            "{gradient}: mean normal error {mean} rad > {}",
            tol / 2.0
        );
    }
}

#[test]
fn composite_of_constant_fog_matches_opacity_correction() {
    // A ball of radius 3 fills the box: f = 1 everywhere. With constant alpha a
    // defined for the reference step ds0, a chord of length L must give
    // 1 - (1 - a)^(L / ds0) at every step size, and the transfer function's colour.
    let a = 0.1f64;
    let h = 2.0 / 32.0; // voxel spacing of a 33^3 grid on [-1, 1]
    for step in [0.3, 1.0, 2.7, 0.001] {
        let size = if step < 0.01 { 3 } else { 9 };
        let text = format!(
            "[volume]\nsynthetic = \"ball\"\nradius = 3.0\nsizes = [33, 33, 33]\n\
             [camera]\nprojection = \"orthographic\"\n[image]\nsize = [{size}, {size}]\nformat = \"nrrd\"\n\
             [transfer.fog]\ncolor = [[0.0, [1.0, 0.5, 0.25]]]\nalpha = [[0.0, {a}], [1.0, {a}]]\n\
             [[render]]\nmode = \"composite\"\ntransfer = \"fog\"\nstep = {step}\nreference_step = 1.0\nearly_stop = 1.0\n"
        );
        let v = render(&text);
        let want = 1.0 - (1.0 - a).powf(2.0 / h);
        let c = size / 2;
        let px = v[0].film.pixel(c, c);
        // round-off only: the segment lengths sum to the chord exactly
        assert_close!(px[3], want, 2e-5, "alpha at step {step}");
        assert_close!(px[0], 1.0, 1e-5, "red at step {step}");
        assert_close!(px[1], 0.5, 1e-5, "green at step {step}");
        assert_close!(px[2], 0.25, 1e-5, "blue at step {step}");
    }
}

#[test]
fn early_termination_changes_a_pixel_by_at_most_one_minus_e() {
    let base = "[volume]\nsynthetic = \"gaussian\"\nsigma = 0.4\nsizes = [33, 33, 33]\n\
        [camera]\nprojection = \"orthographic\"\n[image]\nsize = [15, 15]\nformat = \"nrrd\"\n\
        [transfer.t]\ncolor = [[0.0, [0.0, 0.0, 1.0]], [1.0, [1.0, 0.0, 0.0]]]\nalpha = [[0.0, 0.0], [1.0, 0.9]]\n";
    let full = render(&format!(
        "{base}[[render]]\nmode = \"composite\"\ntransfer = \"t\"\nearly_stop = 1.0\n"
    ));
    for e in [0.9, 0.95, 0.99] {
        let cut = render(&format!(
            "{base}[[render]]\nmode = \"composite\"\ntransfer = \"t\"\nearly_stop = {e}\n"
        ));
        for (a, b) in full[0].film.data.chunks(4).zip(cut[0].film.data.chunks(4)) {
            // compare premultiplied colours (what is composited) and opacity
            for ch in 0..3 {
                assert!((a[ch] * a[3] - b[ch] * b[3]).abs() <= (1.0 - e) as f32 + 1e-6);
            }
            assert!((a[3] - b[3]).abs() <= (1.0 - e) as f32 + 1e-6);
        }
    }
}
