//! Numerical stability on hard cases (issue 4, item 5): each case asserts what
//! must hold, against truth computed here.

use std::path::Path;

use glam::{DMat3, DVec3};
use volcast::mode::crossing::Depth;
use volcast::mode::exact::Exact;
use volcast::mode::projection::{Minip, Mip};
use volcast::mode::xray::Xray;
use volcast::render::integrator::{trace, Integrand, PixelRay};
use volcast::render::IndexFrame;
use volcast::sample::{GradientMethod, Interpolation, Normalize, Sampler};
use volcast::scene::XrayOutput;
use volcast::volume::nrrd::{self, NrrdHeader};
use volcast::volume::{Geometry, ScalarType, VolumeData};

use crate::accuracy::write_volume;
use crate::analytic::render;

/// Voxels of `f(i, j, k)` (x fastest).
fn voxels(n: [usize; 3], f: impl Fn(f64, f64, f64) -> f64) -> Vec<f32> {
    let mut v = Vec::new();
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                v.push(f(i as f64, j as f64, k as f64) as f32);
            }
        }
    }
    v
}

fn sampler(v: &[f32], n: [usize; 3]) -> Sampler<'_, f32> {
    Sampler::new(
        v,
        n,
        Normalize::new(0.0, 1.0),
        Interpolation::Trilinear,
        None,
        GradientMethod::Central,
        None,
        DMat3::IDENTITY,
    )
}

/// The ray `o + t d` (index = world) clipped to the grid's box; `None` if it misses.
fn pixel_ray(n: [usize; 3], o: DVec3, d: DVec3) -> Option<PixelRay> {
    let frame = IndexFrame::new(n, None, &Geometry::default(), DMat3::IDENTITY);
    let index = frame.to_index(o, d);
    let (t_enter, t_exit) = frame.clip(&index, f64::NEG_INFINITY)?;
    Some(PixelRay {
        origin: o,
        dir: d,
        index,
        t_enter,
        t_exit,
        t_depth_ref: t_enter,
        cut: None,
        walk: [t_enter, t_exit],
    })
}

/// One ray through `integrand` (no skipping): the value and the samples taken.
fn run(integrand: &impl Integrand, s: &Sampler<f32>, r: &PixelRay, step: f64) -> ([f32; 4], u64) {
    trace(integrand, s, r, step, 0.0)
}

/// A multilinear field (reproduced exactly by trilinear interpolation), in (0, 1)
/// on a 6^3 grid, increasing along +y.
fn multilinear(x: f64, y: f64, z: f64) -> f64 {
    0.2 + 0.01 * x + 0.08 * y + 0.015 * z + 0.002 * x * y - 0.001 * y * z + 0.0004 * x * y * z
}

#[test]
fn axis_rays_on_faces_edges_corners_and_box_faces_are_never_lost() {
    let n = [6usize, 6, 6];
    let v = voxels(n, multilinear);
    let s = sampler(&v, n);
    // x, z of rays along +y: voxel lines (edges of cells), cell faces (half-integer
    // in one coordinate), cell interiors, and the box's faces and edges
    let spots = [
        (2.0, 3.0),
        (2.5, 3.0),
        (2.0, 3.5),
        (2.5, 3.5),
        (0.0, 2.5),
        (5.0, 2.5),
        (2.5, 0.0),
        (0.0, 0.0),
        (5.0, 5.0),
        (0.0, 5.0),
    ];
    for (x, z) in spots {
        let r = pixel_ray(n, DVec3::new(x, -3.0, z), DVec3::Y).expect("the ray is not lost");
        assert_eq!((r.t_enter, r.t_exit), (3.0, 8.0), "({x}, {z})");
        let g = |y: f64| multilinear(x, y, z);
        // Simpson is exact for this field along the ray (linear in y)
        let integral = 5.0 / 6.0 * (g(0.0) + 4.0 * g(2.5) + g(5.0));
        for step in [0.37, 1.0, 5.0, 7.0] {
            let xray = Xray {
                output: XrayOutput::Integral,
                mu: 1.0,
            };
            let (got, n_samples) = run(&xray, &s, &r, step);
            assert!(n_samples >= 2, "entry and exit are both sampled");
            // the trapezoid rule is exact for a function linear along the ray
            assert!(
                (got[0] as f64 - integral).abs() < 1e-5,
                "({x},{z}) step {step}: {} vs {integral}",
                got[0]
            );
            // the exit (the maximum) and the entry (the minimum) are sampled exactly
            let (mip, _) = run(&Mip, &s, &r, step);
            let (minip, _) = run(&Minip, &s, &r, step);
            assert!(
                (mip[0] as f64 - g(5.0)).abs() < 1e-6 && (minip[0] as f64 - g(0.0)).abs() < 1e-6
            );
        }
        let exact = Exact::Xray {
            output: XrayOutput::Integral,
            mu: 1.0,
        };
        let (got, cells) = trace(&exact, &s, &r, 1.0, 0.0);
        assert_eq!(cells, 5, "five cells along y");
        assert!((got[0] as f64 - integral).abs() < 1e-5);
    }
    // a diagonal through the grid's corners (every cell entered at a corner)
    let d = DVec3::ONE.normalize();
    let r = pixel_ray(n, DVec3::splat(-1.0), d).expect("diagonal");
    let len = r.t_exit - r.t_enter;
    assert!((len - 5.0 * 3f64.sqrt()).abs() < 1e-12);
    let g = |t: f64| {
        let p = r.index.at(t);
        multilinear(p.x, p.y, p.z)
    };
    let (a, b) = (r.t_enter, r.t_exit);
    let integral = len / 6.0 * (g(a) + 4.0 * g(0.5 * (a + b)) + g(b));
    let exact = Exact::Xray {
        output: XrayOutput::Integral,
        mu: 1.0,
    };
    let (got, cells) = trace(&exact, &s, &r, 1.0, 0.0);
    assert_eq!(
        cells, 5,
        "one segment per cell even where three planes meet"
    );
    assert!(
        (got[0] as f64 - integral).abs() < 1e-5,
        "{} vs {integral}",
        got[0]
    );
    // grazing the box at one corner: a ray of zero length still has its value
    let r = pixel_ray(
        n,
        DVec3::new(-1.0, 1.0, 0.0),
        DVec3::new(1.0, -1.0, 0.0).normalize(),
    )
    .expect("grazes the corner");
    assert!((r.t_exit - r.t_enter).abs() < 1e-12);
    for got in [
        run(&Mip, &s, &r, 0.5).0,
        run(&Exact::Mip, &s, &r, 0.5).0,
        run(&Exact::Average, &s, &r, 0.5).0,
    ] {
        assert!(
            (got[0] as f64 - multilinear(0.0, 0.0, 0.0)).abs() < 1e-6,
            "{got:?}"
        );
    }
}

const FOG: &str = "[volume]\nsynthetic = \"ball\"\nradius = 3.0\nsizes = [21, 21, 21]\n";

#[test]
fn camera_inside_the_volume() {
    // eye at (0, -0.5, 0) looking along +y: the centre ray runs 1.5 inside the fog
    for integration in ["sampled", "exact"] {
        let v = render(&format!(
            "{FOG}[camera]\ndistance = 0.5\nfov = 60\n[image]\nsize = [9, 9]\nformat = \"nrrd\"\n\
             [[render]]\nmode = \"xray\"\nintegration = \"{integration}\"\n"
        ));
        let film = &v[0].film;
        assert!(
            film.data.iter().all(|x| x.is_finite() && *x > 0.0),
            "{integration}"
        );
        assert!(
            (film.pixel(4, 4)[0] - 1.5).abs() < 1e-5,
            "{integration}: {}",
            film.pixel(4, 4)[0]
        );
    }
}

#[test]
fn cameras_at_the_poles() {
    // looking straight down and up the orbit axis: the centre ray runs along z
    // through the Gaussian's centre; its integral is sqrt(2 pi) s erf(1 / (s sqrt 2))
    // (erf(2.83) = 0.99994, from its series: see crates/volcast-render/src/bench/truth.rs's test)
    let s: f64 = 0.25;
    let erf_value = 0.999_936_657_516_333_8;
    let want = (2.0 * std::f64::consts::PI).sqrt() * s * erf_value;
    for elevation in [90.0, -90.0] {
        for integration in ["sampled", "exact"] {
            let v = render(&format!(
                "[volume]\nsynthetic = \"gaussian\"\nsigma = 0.25\nsizes = [41, 41, 41]\n\
                 [camera]\nprojection = \"orthographic\"\nelevation = {elevation}\n[image]\nsize = [9, 9]\nformat = \"nrrd\"\n\
                 [[render]]\nmode = \"xray\"\nintegration = \"{integration}\"\n"
            ));
            let film = &v[0].film;
            assert!(film.data.iter().all(|x| x.is_finite()));
            // the trilinear reconstruction's error on a 41^3 grid, integrated: below 2e-3
            let got = film.pixel(4, 4)[0] as f64;
            assert!(
                (got - want).abs() < 2e-3,
                "elevation {elevation} {integration}: {got} vs {want}"
            );
        }
    }
}

fn fog_composite(alpha: f64, step: f64, size: usize, extra: &str) -> [f32; 4] {
    let v = render(&format!(
        "{FOG}[camera]\nprojection = \"orthographic\"\n[image]\nsize = [{size}, {size}]\nformat = \"nrrd\"\n\
         [transfer.fog]\ncolor = [[0.0, [1.0, 0.5, 0.25]]]\nalpha = [[0.0, {alpha}], [1.0, {alpha}]]\n\
         [[render]]\nmode = \"composite\"\ntransfer = \"fog\"\nstep = {step}\nreference_step = 1.0\nearly_stop = 1.0\n{extra}"
    ));
    let c = size / 2;
    let p = v[0].film.pixel(c, c);
    [p[0], p[1], p[2], p[3]]
}

#[test]
fn opaque_samples_and_huge_steps() {
    // alpha = 1 at any step, and alpha * step >> 1: the first segment is opaque and
    // its colour is the transfer function's
    for (alpha, step) in [(1.0, 0.5), (1.0, 0.001), (0.9, 50.0), (0.99, 1000.0)] {
        for extra in ["", "preintegrated = true\n"] {
            let p = fog_composite(alpha, step, 3, extra);
            assert_eq!(p[3], 1.0, "alpha {alpha} step {step} {extra}");
            assert!(
                (p[0] - 1.0).abs() < 1e-6
                    && (p[1] - 0.5).abs() < 1e-6
                    && (p[2] - 0.25).abs() < 1e-6,
                "{p:?}"
            );
        }
    }
}

#[test]
fn tiny_opacity_converges_as_the_step_shrinks() {
    // a = 1e-7 per voxel over a chord of 20 voxels (21^3 on [-1, 1]):
    // A = 1 - (1 - a)^20, by the series -x - x^2/2 with x = 20 ln(1 - a)
    let a: f64 = 1e-7;
    let x = 20.0 * (-a - a * a / 2.0);
    let want = -x - x * x / 2.0;
    let mut last = None;
    for step in [1.0, 0.1, 0.01, 0.001] {
        let got = fog_composite(a, step, 1, "")[3] as f64;
        let rel = (got - want).abs() / want;
        eprintln!("alpha 1e-7, step {step}: A = {got:.9e} (closed form {want:.9e}, relative error {rel:.1e})");
        // f64 accumulation of up to 20 000 terms, each opacity rounded to f32 (relative
        // 6e-8): 1e-6 allows for that; f32 accumulation drifted to 2e-4 at step 0.001
        assert!(rel < 1e-6, "step {step}: {got} vs {want}");
        if let Some(prev) = last {
            let drift: f64 = (got - prev) / want;
            assert!(drift.abs() < 1e-6, "drift {drift} from the previous step");
        }
        last = Some(got);
    }
}

#[test]
fn extinction_so_large_that_exp_underflows() {
    let v = render(&format!(
        "{FOG}[camera]\nprojection = \"orthographic\"\n[image]\nsize = [5, 5]\nformat = \"nrrd\"\n\
         [[render]]\nname = \"t\"\nmode = \"xray\"\noutput = \"transmitted\"\nmu = 1e300\n\
         [[render]]\nname = \"a\"\nmode = \"xray\"\noutput = \"absorbed\"\nmu = 1e300\nintegration = \"exact\"\n\
         [[render]]\nname = \"i\"\nmode = \"xray\"\noutput = \"integral\"\nmu = 1e30\n"
    ));
    // exp(-2e300) underflows to 0; 1 - exp(-inf) is 1; nothing is NaN
    assert_eq!(v[0].film.pixel(2, 2)[0], 0.0);
    assert_eq!(v[1].film.pixel(2, 2)[0], 1.0);
    assert!((v[2].film.pixel(2, 2)[0] - 2e30).abs() < 1e24);
    for view in &v {
        assert!(view.film.data.iter().all(|x| !x.is_nan()));
    }
}

#[test]
fn flat_regions_have_no_normal_and_are_shaded_ambient() {
    // the fog is flat: every ray hits at its entry with a zero gradient; the neutral
    // material there gets its ambient term only (never NaN), and so does compositing
    let v = render(&format!(
        "{FOG}[camera]\nprojection = \"orthographic\"\n[image]\nsize = [5, 5]\nformat = \"nrrd\"\n\
         [material.flat]\nambient = [0.25, 0.25, 0.25]\ndiffuse = [1, 1, 1]\nspecular = [1, 1, 1]\n\
         [[render]]\nmode = \"surface\"\niso = 0.5\nmaterial = \"flat\"\n\
         [[render]]\nname = \"se\"\nmode = \"surface\"\niso = 0.5\nmaterial = \"flat\"\nintegration = \"exact\"\n\
         [[render]]\nmode = \"composite\"\nshading = \"phong\"\nmaterial = \"flat\"\n"
    ));
    for view in &v[..2] {
        let p = view.film.pixel(2, 2);
        assert_eq!(p[3], 1.0);
        assert!((p[0] - 0.25).abs() < 1e-6, "ambient only: {p:?}");
    }
    assert!(v[2].film.data.iter().all(|x| x.is_finite()));
}

#[test]
fn nan_and_infinite_voxels_never_reach_an_image() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_volume(dir.path(), "bad.nrrd", [6, 6, 6], |i, j, k| {
        match (i + j + k) % 4 {
            0 => f32::NAN,
            1 => f32::INFINITY,
            2 => f32::NEG_INFINITY,
            _ => 0.25 + 0.5 * (i % 2) as f32,
        }
    });
    let mut passes = String::new();
    for (mode, extra) in [
        ("xray", ""),
        ("mip", ""),
        ("minip", ""),
        ("average", ""),
        ("lmip", ""),
        ("surface", ""),
        ("composite", "shading = \"phong\"\n"),
        ("composite", "preintegrated = true\n"),
        ("xray", "integration = \"exact\"\n"),
        ("mip", "integration = \"exact\"\n"),
        ("surface", "integration = \"exact\"\n"),
        ("composite", "interpolation = \"cubic\"\n"),
    ] {
        passes += &format!(
            "[[render]]\nname = \"p{}\"\nmode = \"{mode}\"\n{extra}",
            passes.len()
        );
    }
    // no window: the data's finite range; the zoomed orthographic view keeps every
    // ray inside the box, so no pixel is a miss (NaN by design in grey NRRD images)
    for window in ["window = [0.0, 1.0]\n", ""] {
        let v = render(&format!(
            "[volume]\npath = {:?}\n{window}[camera]\nprojection = \"orthographic\"\nzoom = 2.5\n[image]\nsize = [12, 12]\nformat = \"nrrd\"\n{passes}",
            path.display().to_string()
        ));
        for view in &v {
            assert!(
                view.film.data.iter().all(|x| x.is_finite()),
                "pass {}",
                view.pass
            );
        }
    }
}

#[test]
fn one_voxel_thick_volumes() {
    // 6 x 6 x 1 of value 0.5: a slab one voxel thick ([-0.5, 0.5] in z)
    let dir = tempfile::tempdir().unwrap();
    let path = write_volume(dir.path(), "slab.nrrd", [6, 6, 1], |_, _, _| 0.5);
    for integration in ["sampled", "exact"] {
        for (elevation, want) in [(90.0, 0.5), (0.0, 0.5 * 5.0)] {
            let v = render(&format!(
                "[volume]\npath = {:?}\nwindow = [0.0, 1.0]\n[camera]\nprojection = \"orthographic\"\nelevation = {elevation}\n\
                 [image]\nsize = [15, 15]\nformat = \"nrrd\"\n[[render]]\nmode = \"xray\"\nintegration = \"{integration}\"\n",
                path.display().to_string()
            ));
            // seen face on: a chord of 1 through the slab; edge on: 5 across it
            let got = v[0].film.pixel(7, 7)[0];
            assert!(
                (got - want).abs() < 1e-5,
                "{integration} elevation {elevation}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn sheared_and_anisotropic_grids() {
    // f linear in world coordinates, f = 0.5 + g . (x - c): trilinear interpolation
    // reproduces it exactly in any affine grid, so the X-ray of a chord is its length
    // times f at the chord's middle, and the surface normal is -g / |g|.
    let dir = tempfile::tempdir().unwrap();
    let axes = [
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(0.5, 2.0, 0.0),
        DVec3::new(0.0, 0.3, 1.5),
    ];
    let origin = DVec3::new(1.0, -2.0, 3.0);
    let n = [7usize, 5, 6];
    let m = DMat3::from_cols(axes[0], axes[1], axes[2]);
    let centre = origin + m * DVec3::new(3.0, 2.0, 2.5);
    let g = DVec3::new(0.02, -0.03, 0.025);
    let f = |w: DVec3| 0.5 + g.dot(w - centre);
    let mut data = Vec::new();
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let w = origin + m * DVec3::new(i as f64, j as f64, k as f64);
                let v = f(w);
                assert!(v > 0.0 && v < 1.0);
                data.push(v as f32);
            }
        }
    }
    let mut h = NrrdHeader::new(ScalarType::Float32, n.to_vec());
    h.space_dimension = Some(3);
    h.space_directions = Some(axes.iter().map(|a| Some(a.to_array().to_vec())).collect());
    h.space_origin = Some(origin.to_array().to_vec());
    let path = dir.path().join("sheared.nrrd");
    std::fs::write(&path, nrrd::encode(&h, &VolumeData::F32(data)).unwrap()).unwrap();
    let size = 11;
    let v = render(&format!(
        "[volume]\npath = {:?}\nwindow = [0.0, 1.0]\n[camera]\nprojection = \"orthographic\"\n\
         [image]\nsize = [{size}, {size}]\nformat = \"nrrd\"\n\
         [material.matte]\nambient = [0, 0, 0]\ndiffuse = [1, 1, 1]\nspecular = [0, 0, 0]\n\
         [[render]]\nmode = \"xray\"\nstep = 0.3\n[[render]]\nname = \"xe\"\nmode = \"xray\"\nintegration = \"exact\"\n\
         [[render]]\nmode = \"surface\"\niso = 0.5\nmaterial = \"matte\"\n",
        path.display().to_string()
    ));
    // The view (azimuth 0, orthographic): rays along +y; the image spans the
    // diameter of the sphere through the box's corners, centred on the box centre.
    let corners: Vec<DVec3> = (0..8)
        .map(|c| {
            let p = DVec3::new(
                if c & 1 != 0 { 6.0 } else { 0.0 },
                if c & 2 != 0 { 4.0 } else { 0.0 },
                if c & 4 != 0 { 5.0 } else { 0.0 },
            );
            origin + m * p
        })
        .collect();
    let mid = corners.iter().fold(DVec3::ZERO, |a, &c| a + c) / 8.0;
    let radius = corners
        .iter()
        .map(|c| (*c - mid).length())
        .fold(0.0, f64::max);
    let inv = m.inverse();
    let mut checked = 0;
    for j in 0..size {
        for i in 0..size {
            let px = 2.0 * (i as f64 + 0.5) / size as f64 - 1.0;
            let py = 1.0 - 2.0 * (j as f64 + 0.5) / size as f64;
            let p = mid + DVec3::X * px * radius + DVec3::Z * py * radius;
            // clip in index space: p + t y
            let (o, d) = (inv * (p - origin), inv * DVec3::Y);
            let hi = DVec3::new(6.0, 4.0, 5.0);
            let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
            for a in 0..3 {
                if d[a] == 0.0 {
                    if o[a] < 0.0 || o[a] > hi[a] {
                        t1 = f64::NEG_INFINITY;
                    }
                    continue;
                }
                let (ta, tb) = (-o[a] / d[a], (hi[a] - o[a]) / d[a]);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
            if t1 - t0 < 0.5 {
                continue;
            }
            let want = (t1 - t0) * f(p + DVec3::Y * (0.5 * (t0 + t1)));
            for pass in [0, 1] {
                let got = v[pass].film.pixel(i, j)[0] as f64;
                assert!(
                    (got - want).abs() < 1e-4 * want.max(1.0),
                    "pass {pass} ({i},{j}): {got} vs {want}"
                );
            }
            // where the iso-surface f = 0.5 is inside the chord: shade = |n . y|
            let surf = v[2].film.pixel(i, j);
            if surf[3] == 1.0 {
                let facing = (g.y / g.length()).abs();
                assert!(
                    (surf[0] as f64 - facing).abs() < 1e-4,
                    "({i},{j}): {} vs {facing}",
                    surf[0]
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 3, "{checked} surface pixels checked");
}

#[test]
fn float_data_spanning_1e_minus_30_to_1e30() {
    // voxel i of a line holds 10^(-30 + 6 i): the window is the data's range, and the
    // normalised values are v / 1e30 (the low end, 1e-30, is 0 to 60 digits)
    let dir = tempfile::tempdir().unwrap();
    let path = write_volume(dir.path(), "wide.nrrd", [11, 4, 4], |i, _, _| {
        10f32.powi(-30 + 6 * i as i32)
    });
    let v = render(&format!(
        "[volume]\npath = {:?}\n[camera]\nprojection = \"orthographic\"\nazimuth = 90\n[image]\nsize = [9, 9]\nformat = \"nrrd\"\n\
         [[render]]\nmode = \"mip\"\n[[render]]\nname = \"me\"\nmode = \"mip\"\nintegration = \"exact\"\n[[render]]\nmode = \"minip\"\n\
         [[render]]\nmode = \"xray\"\n",
        path.display().to_string()
    ));
    // azimuth 90 looks along -x, across all eleven voxels of a line
    let (mip, mip_exact, minip, xray) = (
        v[0].film.pixel(4, 4)[0],
        v[1].film.pixel(4, 4)[0],
        v[2].film.pixel(4, 4)[0],
        v[3].film.pixel(4, 4)[0] as f64,
    );
    assert_eq!((mip, mip_exact, minip), (1.0, 1.0, 0.0));
    // (rays that miss the volume are NaN by design: only the centre ray is checked)
    // integral of the trilinear interpolant: 1e30 (normalised 1) at the end, 1e24
    // (1e-6) next to it: the last cell's trapezoid (1 + 1e-6) / 2, plus ~6e-7
    assert!((xray - 0.5).abs() < 2e-6, "{xray}");
}

#[test]
fn a_million_samples_along_one_ray() {
    // a chord of 2 at a step of 2e-6 world units: 1e6 samples of the value 1
    let scene = "[volume]\nsynthetic = \"ball\"\nradius = 3.0\nsizes = [3, 3, 201]\n\
        [camera]\nprojection = \"orthographic\"\nelevation = 90\n[image]\nsize = [1, 1]\nformat = \"nrrd\"\n\
        [[render]]\nmode = \"xray\"\nstep = 0.0002\n";
    let parsed = volcast::scene::parse(scene, Path::new("t.toml")).unwrap();
    let (v, summary) = volcast::pipeline::render_films(
        &parsed,
        &volcast::plan::RunOptions::default(),
        &volcast::volume::Limits::default(),
    )
    .unwrap();
    assert!(summary.samples >= 1_000_000, "{} samples", summary.samples);
    let got = v[0].film.pixel(0, 0)[0];
    // the exact sum of the trapezoids is the chord, 2: the f64 sum is exact to f32
    // (2.0 exactly), where a naive f32 sum of the same terms is off by far more
    let dt = 2e-6f32;
    let mut naive = 0.0f32;
    for _ in 0..1_000_000 {
        naive += dt;
    }
    eprintln!(
        "1e6 samples: f64 sum error {:.1e}; naive f32 sum error {:.1e}",
        (got as f64 - 2.0).abs(),
        (naive as f64 - 2.0).abs()
    );
    assert_eq!(got, 2.0);
    assert!((naive as f64 - 2.0).abs() > 1e-4);
}

#[test]
fn ties_in_mip() {
    // two equal maxima on the ray: both methods return the tied value exactly
    let n = [3usize, 5, 3];
    let v = voxels(n, |_, y, _| if y == 1.0 || y == 3.0 { 0.8 } else { 0.2 });
    let s = sampler(&v, n);
    let r = pixel_ray(n, DVec3::new(1.0, -1.0, 1.0), DVec3::Y).unwrap();
    for step in [0.5, 1.0] {
        for (what, got) in [
            ("sampled", run(&Mip, &s, &r, step).0),
            ("exact", run(&Exact::Mip, &s, &r, step).0),
        ] {
            assert_eq!(got[0], 0.8f32, "{what} step {step}");
        }
    }
    let (got, _) = run(&Exact::Minip, &s, &r, 1.0);
    assert_eq!(got[0], 0.2f32);
}

#[test]
fn iso_surfaces_tangent_to_the_ray() {
    // f = x + y - 2xy (bilinear, exact under trilinear interpolation); along
    // u(s) = (s, s, 1/2) it is 2s - 2s^2, whose maximum 1/2 at s = 1/2 touches the
    // threshold 1/2: a double root.
    let n = [2usize, 2, 2];
    let v = voxels(n, |x, y, _| x + y - 2.0 * x * y);
    let s = sampler(&v, n);
    let d = DVec3::new(1.0, 1.0, 0.0).normalize();
    let r = pixel_ray(n, DVec3::new(-1.0, -1.0, 0.5), d).unwrap();
    let tangent = r.t_enter + 0.5 * 2f64.sqrt();
    let depth = |t: f32| trace(&Exact::Depth { threshold: t }, &s, &r, 1.0, 0.0).0[0];
    let hit = depth(0.5) as f64 - (r.t_enter - r.t_depth_ref);
    assert!(
        (hit - (tangent - r.t_enter)).abs() < 1e-6,
        "touches at the maximum: {hit}"
    );
    assert!(depth(0.500_001).is_nan(), "above the maximum: no hit");
    // just below: two simple roots, the first one found
    let below = depth(0.49) as f64;
    let s_root = (1.0 - (1.0 - 2.0 * 0.49f32 as f64).sqrt()) / 2.0;
    assert!((below - s_root * 2f64.sqrt()).abs() < 1e-5, "{below}");
    // sampled marching: a sample on the tangent point finds it; others miss cleanly
    for (step, hits) in [(2f64.sqrt() / 4.0, true), (0.3, false)] {
        let (got, _) = trace(&Depth { threshold: 0.5 }, &s, &r, step, 0.0);
        assert_eq!(!got[0].is_nan(), hits, "step {step}: {got:?}");
    }
}
