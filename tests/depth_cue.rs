//! Depth-cued and depth-coded MIP (issue 8, item 4) against an independent
//! computation: the Gaussian blob of `analytic.rs`, whose weighted profile along
//! each ray is maximised here by brute force on the continuous field.
//!
//! Geometry: an orthographic camera at azimuth 0 looking along +y; the box
//! [-1, 1]^3 has the bounding sphere of radius sqrt 3 about the origin, so the ray
//! at (x, z) enters it at y_e = -sqrt(3 - x^2 - z^2), depth is s = y - y_e, and
//! D = 2 sqrt 3.

use crate::analytic::{gauss_trilinear_bound, pixel_xz, render, GAUSS};
use crate::assert_close;
use crate::colormap::{table_at, tables};

const D: f64 = 2.0 * 1.732_050_807_568_877_2;

/// The maximum over y in [-1, 1] of `exp(-r^2 / (2 s^2)) (1 - c s / D)` along the
/// ray at (x, z), and the depth where it is reached (a fine grid, then a golden
/// section search around the best grid point).
fn weighted_max(x: f64, z: f64, c: f64) -> (f64, f64) {
    let ye = -(3.0 - x * x - z * z).sqrt();
    let g = |y: f64| {
        let f = (-(x * x + y * y + z * z) / (2.0 * 0.25 * 0.25)).exp();
        f * (1.0 - c * (y - ye) / D)
    };
    let n = 20_000;
    let y_at = |k: usize| -1.0 + 2.0 * k as f64 / n as f64;
    let k = (0..=n)
        .max_by(|&a, &b| g(y_at(a)).total_cmp(&g(y_at(b))))
        .unwrap();
    let (mut a, mut b) = (y_at(k.saturating_sub(1)), y_at((k + 1).min(n)));
    let r = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..100 {
        let (p, q) = (b - r * (b - a), a + r * (b - a));
        if g(p) < g(q) {
            a = p;
        } else {
            b = q;
        }
    }
    let y = 0.5 * (a + b);
    (g(y), y - ye)
}

/// Pixels whose rays cross the box, away from its edges (where the maximum of a
/// strongly cued ray sits on the box face and its depth is still well defined,
/// but the value is tiny).
fn pixels(n: usize) -> impl Iterator<Item = (usize, usize, f64, f64)> {
    (0..n).flat_map(move |j| {
        (0..n).filter_map(move |i| {
            let (x, z) = pixel_xz(i, j, n);
            (x.abs() < 0.9 && z.abs() < 0.9).then_some((i, j, x, z))
        })
    })
}

fn passes(c: f64, integration: &str) -> String {
    let mut t = GAUSS.to_string();
    for out in ["value", "depth-of-max", "depth-coded"] {
        t += &format!(
            "[[render]]\nname = \"{out}\"\nmode = \"mip\"\ndepth_cue = {c}\noutput = \"{out}\"\nintegration = \"{integration}\"\n"
        );
    }
    t
}

#[test]
fn exact_depth_cued_mip_is_the_maximum_of_the_weighted_interpolant() {
    for c in [0.0, 0.5, 1.0] {
        let v = render(&passes(c, "exact"));
        let (mut worst_v, mut worst_s) = (0.0f64, 0.0f64);
        for (i, j, x, z) in pixels(41) {
            let (want_v, want_s) = weighted_max(x, z, c);
            let got_v = v[0].film.pixel(i, j)[0] as f64;
            let got_s = v[1].film.pixel(i, j)[0] as f64;
            assert_close!(
                got_v,
                want_v,
                gauss_trilinear_bound(),
                "c {c} value at ({i},{j})"
            );
            worst_v = worst_v.max((got_v - want_v).abs());
            // where the peak is sharp enough to place (away from the flat tails)
            if want_v > 0.05 {
                assert_close!(
                    got_s,
                    want_s,
                    0.03,
                    "c {c} depth of the maximum at ({i},{j})"
                );
                worst_s = worst_s.max((got_s - want_s).abs());
            }
        }
        eprintln!("exact, cue {c}: value error {worst_v:.2e}, depth error {worst_s:.2e}");
    }
}

#[test]
fn sampled_depth_cued_mip_is_within_the_sampling_error() {
    let c = 0.7;
    let v = render(&passes(c, "sampled"));
    let h: f64 = 2.0 / 96.0;
    let dt = h / 2.0;
    // the profile's curvature is at most 1/s^2 (+ the weight's slope times the
    // Gaussian's, small): missing the top by dt/2 costs (dt/2)^2 / (2 s^2) * 2
    let tol = gauss_trilinear_bound() + (dt / 2.0).powi(2) / (0.25 * 0.25);
    for (i, j, x, z) in pixels(41) {
        let (want_v, want_s) = weighted_max(x, z, c);
        assert_close!(v[0].film.pixel(i, j)[0], want_v, tol, "value at ({i},{j})");
        if want_v > 0.05 {
            assert_close!(
                v[1].film.pixel(i, j)[0],
                want_s,
                0.03 + dt,
                "depth of the maximum at ({i},{j})"
            );
        }
    }
}

#[test]
fn a_cue_darkens_the_far_side_only() {
    // c = 0 is the plain MIP, bit for bit; a cue never brightens a pixel
    let plain = render(&format!("{GAUSS}[[render]]\nmode = \"mip\"\n"));
    let zero = render(&passes(0.0, "sampled"));
    let cued = render(&passes(0.8, "sampled"));
    for (a, b) in plain[0].film.data.iter().zip(&zero[0].film.data) {
        assert_eq!(a.to_bits(), b.to_bits());
    }
    let mut darker = 0;
    for (a, b) in plain[0].film.data.iter().zip(&cued[0].film.data) {
        if a.is_nan() {
            assert!(b.is_nan(), "a miss is a miss");
            continue;
        }
        assert!(b <= a, "{b} > {a}");
        darker += usize::from(b < a);
    }
    assert!(darker > 500, "{darker}");
}

#[test]
fn depth_coded_is_the_colour_map_at_the_depth_times_the_value() {
    let turbo = &tables()["turbo"];
    for integration in ["sampled", "exact"] {
        let v = render(&passes(0.5, integration));
        for j in 0..41 {
            for i in 0..41 {
                let value = v[0].film.pixel(i, j)[0];
                let depth = v[1].film.pixel(i, j)[0] as f64;
                let coded = v[2].film.pixel(i, j);
                if value.is_nan() {
                    // a miss: no depth, and the background shows through
                    assert!(depth.is_nan());
                    assert_eq!(coded, &[0.0; 4]);
                    continue;
                }
                // matplotlib's turbo table at s / D
                let c = table_at(turbo, (depth / D).clamp(0.0, 1.0));
                let want = c.map(|x| x * f64::from(value.clamp(0.0, 1.0)));
                for k in 0..3 {
                    assert_close!(
                        f64::from(coded[k]),
                        want[k],
                        1e-5,
                        "{integration} channel {k} at ({i},{j})"
                    );
                }
                assert_eq!(coded[3], 1.0);
            }
        }
    }
}

#[test]
fn depth_cue_errors_name_the_key() {
    let bad = [
        (
            "mode = \"mip\"\ndepth_cue = 1.5\n",
            "depth_cue = 1.5: expected",
        ),
        (
            "mode = \"surface\"\ncolormap = \"viridis\"\n",
            "`colormap` is not used by mode = \"surface\"",
        ),
        (
            "mode = \"mip\"\noutput = \"depth-coded\"\ncolormap = \"virdis\"\n",
            "did you mean `viridis`",
        ),
        (
            "mode = \"minip\"\ndepth_cue = 0.5\n",
            "`depth_cue` is not used by mode = \"minip\"",
        ),
        (
            "mode = \"mip\"\noutput = \"absorbed\"\n",
            "output = \"absorbed\" is not known",
        ),
    ];
    for (pass, want) in bad {
        let text = format!("{GAUSS}[[render]]\n{pass}");
        let err = volcast::scene::parse(&text, std::path::Path::new("cue.toml"))
            .expect_err(pass)
            .to_string();
        assert!(err.contains(want), "{pass}: {err}");
    }
}
