//! The closed-form answer for every pixel of a bench image (docs/formulas.md "Analytic
//! references for accuracy tests"), computed from the analytic field, never from
//! the renderer.
//!
//! Bench images are orthographic views at azimuth [`AZIMUTH_DEG`] and elevation
//! [`ELEVATION_DEG`] (oblique, so that rays cross the cells in general position:
//! along an axis the trilinear interpolant is piecewise linear and sampling at the
//! voxel planes would be exact), plus quarter turns about z, which see the same
//! picture (every bench field and its box are symmetric under them). Pixel `(i, j)`
//! of an `n x n` image is the line of docs/formulas.md "Cameras" (the image spans the
//! bounding sphere's diameter, `2 sqrt 3`), clipped to the box `[-1, 1]^3`.
//!
//! Closed forms where they exist (the ball's chords and extrema, spherical
//! iso-surfaces and their radial normals); elsewhere, careful f64 numerics on the
//! analytic function: Simpson's rule with 20 000 intervals for integrals, a dense
//! scan refined by ternary search or bisection for extrema and crossings, and
//! front-to-back compositing over 20 000 steps with exact per-step opacities for
//! emission-absorption.

use glam::DVec3;

use crate::transfer::Transfer1D;
use crate::volume::synthetic::Field;

/// Intervals of the numerical integrals and scans.
const STEPS: usize = 20_000;

/// Azimuth of the bench views, degrees.
pub const AZIMUTH_DEG: f64 = 30.0;
/// Elevation of the bench views, degrees.
pub const ELEVATION_DEG: f64 = 20.0;

/// A pixel's line `p + t d` (`|d| = 1`) and its interval `[t0, t1]` in the box.
#[derive(Clone, Copy, Debug)]
pub struct Line {
    /// A point of the line (on the plane through the centre, normal to `d`).
    pub p: DVec3,
    /// Unit direction.
    pub d: DVec3,
    /// Entry into the box.
    pub t0: f64,
    /// Exit from the box.
    pub t1: f64,
}

/// The line of pixel `(i, j)` of an `n x n` bench image, or `None` if it misses
/// the box (or grazes it: chords shorter than 1e-9 are left out).
pub fn pixel_line(n: usize, i: usize, j: usize) -> Option<Line> {
    let (az, el) = (AZIMUTH_DEG.to_radians(), ELEVATION_DEG.to_radians());
    let back = DVec3::new(az.sin() * el.cos(), -az.cos() * el.cos(), el.sin());
    let right = DVec3::new(az.cos(), az.sin(), 0.0);
    let d = -back;
    let up = right.cross(d).normalize();
    let radius = 3f64.sqrt();
    let px = 2.0 * (i as f64 + 0.5) / n as f64 - 1.0;
    let py = 1.0 - 2.0 * (j as f64 + 0.5) / n as f64;
    let p = right * (px * radius) + up * (py * radius);
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for a in 0..3 {
        if d[a] == 0.0 {
            if p[a].abs() > 1.0 {
                return None;
            }
            continue;
        }
        let (ta, tb) = ((-1.0 - p[a]) / d[a], (1.0 - p[a]) / d[a]);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    (t1 - t0 > 1e-9).then_some(Line { p, d, t0, t1 })
}

/// The quantity a bench mode renders, with its parameters.
#[derive(Clone, Debug)]
pub enum Quantity {
    /// Line integral of the value.
    Integral,
    /// Maximum along the ray.
    Max,
    /// Minimum along the ray.
    Min,
    /// Mean along the ray.
    Mean,
    /// First local maximum at or above the threshold (else the maximum).
    LocalMax(f64),
    /// Distance from the bounding-sphere entry to the first crossing.
    Depth(f64),
    /// `n . v` of the first crossing (a matte white surface under a headlight).
    Facing(f64),
    /// Emission-absorption: premultiplied RGB and alpha.
    Composite {
        /// The transfer function.
        tf: Transfer1D,
        /// Its reference step, world units.
        reference_step: f64,
    },
}

/// The answer for one pixel: up to four channels (premultiplied for composite), or
/// `None` where the pixel is excluded (a surface seen at a grazing angle, where
/// the answer is ill-conditioned: `n . v < 0.2`).
pub type Answer = Option<[f64; 4]>;

/// The analytic answer along `line`.
pub fn answer(field: &Field, q: &Quantity, line: &Line) -> Answer {
    let Line { p, d, t0, t1 } = *line;
    // the value at parameter s in [0, 1] of the chord, and the chord's length
    let len = t1 - t0;
    let f = |s: f64| field.eval(p + d * (t0 + s * len));
    let one = |v: f64| Some([v, 0.0, 0.0, 0.0]);
    // distance of the line from the centre (the fields are centred on 0)
    let d2 = (p - d * p.dot(d)).length_squared();
    match (q, field) {
        // the ball inside the box: its chord, and values 0/1 (closed forms; Simpson
        // and dense scans would blur or miss the jump)
        (Quantity::Integral | Quantity::Mean, Field::Ball { radius }) if *radius < 1.0 => {
            let chord = if d2 < radius * radius {
                2.0 * (radius * radius - d2).sqrt()
            } else {
                0.0
            };
            one(if matches!(q, Quantity::Mean) {
                chord / len
            } else {
                chord
            })
        }
        (Quantity::Max, Field::Ball { radius }) if *radius < 1.0 => {
            one(if d2 < radius * radius { 1.0 } else { 0.0 })
        }
        (Quantity::Integral, _) => one(simpson(f, 0.0, 1.0) * len),
        (Quantity::Mean, _) => one(simpson(f, 0.0, 1.0)),
        (Quantity::Max, _) => one(extremum(f, true)),
        (Quantity::Min, _) => one(extremum(f, false)),
        (Quantity::LocalMax(t), _) => one(local_max(f, *t)),
        (Quantity::Depth(t), _) | (Quantity::Facing(t), _) => {
            // the depth reference: the entry into the bounding sphere, radius sqrt 3
            let b = p.dot(d);
            let entry = -b - (b * b - (p.length_squared() - 3.0)).sqrt();
            let Some(s) = first_reach(f, *t) else {
                return Some(match q {
                    Quantity::Depth(_) => [f64::NAN, 0.0, 0.0, 0.0],
                    _ => [0.0; 4],
                });
            };
            let x = p + d * (t0 + s * len);
            let facing = normal_facing(field, x, d);
            // grazing hits are ill-conditioned; hits at the entry face are not
            if (facing.is_nan() || facing < 0.2) && s > 0.0 {
                return None;
            }
            match q {
                Quantity::Depth(_) => one(t0 + s * len - entry),
                _ => Some([facing, facing, facing, 1.0]),
            }
        }
        (Quantity::Composite { tf, reference_step }, _) => {
            Some(composite(f, len, tf, *reference_step))
        }
    }
}

/// `|n . d|` at `x`: radial normals for the isotropic fields, a central difference
/// (step 1e-6) of the analytic function for Marschner-Lobb.
fn normal_facing(field: &Field, p: DVec3, dir: DVec3) -> f64 {
    let g = match field {
        Field::MarschnerLobb => {
            let h = 1e-6;
            let d = |e: DVec3| (field.eval(p + e * h) - field.eval(p - e * h)) / (2.0 * h);
            DVec3::new(d(DVec3::X), d(DVec3::Y), d(DVec3::Z))
        }
        _ => p,
    };
    let len = g.length();
    if len > 0.0 {
        (g.dot(dir) / len).abs()
    } else {
        f64::NAN
    }
}

/// Simpson's rule on `[a, b]` with [`STEPS`] intervals.
fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64) -> f64 {
    let h = (b - a) / STEPS as f64;
    let mut s = f(a) + f(b);
    for k in 1..STEPS {
        s += f(a + k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
    }
    s * h / 3.0
}

/// Ternary search for the extremum of `f` in `[lo, hi]` (unimodal there).
fn refine_extremum(f: &impl Fn(f64) -> f64, mut lo: f64, mut hi: f64, max: bool) -> f64 {
    let better = |a: f64, b: f64| if max { a > b } else { a < b };
    for _ in 0..100 {
        let (m1, m2) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
        if better(f(m1), f(m2)) {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    f(0.5 * (lo + hi))
}

/// The maximum (`max`) or minimum of `f` over `[0, 1]`.
fn extremum(f: impl Fn(f64) -> f64, max: bool) -> f64 {
    let h = 1.0 / STEPS as f64;
    let y = |k: usize| k as f64 * h;
    let sign = if max { 1.0 } else { -1.0 };
    let k = (0..=STEPS)
        .max_by(|&a, &b| (sign * f(y(a))).total_cmp(&(sign * f(y(b)))))
        .unwrap_or(0);
    let (lo, hi) = (y(k.max(1) - 1), y((k + 1).min(STEPS)));
    let refined = refine_extremum(&f, lo, hi, max);
    if max {
        refined.max(f(y(k)))
    } else {
        refined.min(f(y(k)))
    }
}

/// The first local maximum of `f` over `[0, 1]` at or above `t` (else the maximum).
fn local_max(f: impl Fn(f64) -> f64, t: f64) -> f64 {
    let h = 1.0 / STEPS as f64;
    let y = |k: usize| k as f64 * h;
    let Some(start) = (0..=STEPS).find(|&k| f(y(k)) >= t) else {
        return extremum(f, true);
    };
    let mut k = start;
    while k < STEPS && f(y(k + 1)) >= f(y(k)) {
        k += 1;
    }
    if k == STEPS {
        return f(y(k));
    }
    refine_extremum(&f, y(k.max(start + 1) - 1), y(k + 1), true).max(f(y(k)))
}

/// The first `s` in `[0, 1]` with `f(s) >= t`.
fn first_reach(f: impl Fn(f64) -> f64, t: f64) -> Option<f64> {
    let h = 1.0 / STEPS as f64;
    let y = |k: usize| k as f64 * h;
    if f(0.0) >= t {
        return Some(0.0);
    }
    let k = (1..=STEPS).find(|&k| f(y(k)) >= t)?;
    let (mut lo, mut hi) = (y(k - 1), y(k));
    for _ in 0..100 {
        let m = 0.5 * (lo + hi);
        if f(m) >= t {
            hi = m;
        } else {
            lo = m;
        }
    }
    Some(hi)
}

/// Emission-absorption along a chord of length `len`, `f` over `[0, 1]`
/// (docs/formulas.md "Emission-absorption"): extinction `-ln(1 - alpha) /
/// reference_step` from the transfer function itself (not its table),
/// front-to-back over [`STEPS`] midpoint steps, each with its exact opacity.
/// Returns premultiplied RGB and alpha.
fn composite(f: impl Fn(f64) -> f64, len: f64, tf: &Transfer1D, reference_step: f64) -> [f64; 4] {
    let h = len / STEPS as f64;
    let mut c = [0.0f64; 3];
    let mut transparency = 1.0f64;
    for k in 0..STEPS {
        let v = f((k as f64 + 0.5) / STEPS as f64);
        let rgba = tf.eval(v as f32);
        let a = f64::from(rgba[3]);
        if a <= 0.0 {
            continue;
        }
        let sigma = -(-a).ln_1p() / reference_step;
        let step_alpha = -(-sigma * h).exp_m1();
        for ch in 0..3 {
            c[ch] += transparency * step_alpha * f64::from(rgba[ch]);
        }
        transparency *= 1.0 - step_alpha;
    }
    [c[0], c[1], c[2], 1.0 - transparency]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// erf by its Taylor series (|x| <= 3: 60 terms, error below 1e-13).
    fn erf(x: f64) -> f64 {
        let mut term = x;
        let mut sum = x;
        for n in 1..60 {
            term *= -x * x / n as f64;
            sum += term / (2 * n + 1) as f64;
        }
        sum * 2.0 / std::f64::consts::PI.sqrt()
    }

    /// The line along +y through (x, z): chord y in [-1, 1].
    fn along_y(x: f64, z: f64) -> Line {
        Line {
            p: DVec3::new(x, 0.0, z),
            d: DVec3::Y,
            t0: -1.0,
            t1: 1.0,
        }
    }

    #[test]
    fn numerics_match_the_closed_forms() {
        let s = 0.25;
        let g = Field::Gaussian { sigma: s };
        let (x, z) = (0.2, -0.1);
        let line = along_y(x, z);
        let d2 = x * x + z * z;
        // docs/formulas.md: line integral sqrt(2 pi) s exp(-d^2 / 2 s^2), cut at y = +-1
        let want = (2.0 * std::f64::consts::PI).sqrt()
            * s
            * (-d2 / (2.0 * s * s)).exp()
            * erf(1.0 / (s * 2f64.sqrt()));
        let got = answer(&g, &Quantity::Integral, &line).unwrap()[0];
        assert!((got - want).abs() < 1e-10, "{got} vs {want}");
        let mip = answer(&g, &Quantity::Max, &line).unwrap()[0];
        assert!((mip - (-d2 / (2.0 * s * s)).exp()).abs() < 1e-12);
        // sphere distance: iso-sphere of radius 1 - t; depth from the sphere entry
        let sd = Field::SphereDistance { radius: 1.0 };
        let r: f64 = 0.5;
        let depth = answer(&sd, &Quantity::Depth(0.5), &line).unwrap()[0];
        let want = (3.0 - d2).sqrt() - (r * r - d2).sqrt();
        assert!((depth - want).abs() < 1e-12, "{depth} vs {want}");
        let facing = answer(&sd, &Quantity::Facing(0.5), &line).unwrap()[0];
        assert!((facing - (1.0 - d2 / (r * r)).sqrt()).abs() < 1e-9);
        // constant fog: 1 - (1 - a)^(L / ds0)
        let fog = Field::Ball { radius: 3.0 };
        let tf = Transfer1D::new(
            vec![(0.0, [1.0, 0.5, 0.25])],
            vec![(0.0, 0.1), (1.0, 0.1)],
            crate::transfer::Interpolation::Linear,
        )
        .unwrap();
        let c = answer(
            &fog,
            &Quantity::Composite {
                tf,
                reference_step: 0.05,
            },
            &line,
        )
        .unwrap();
        let want = 1.0 - (1.0 - 0.1f64).powf(2.0 / 0.05);
        assert!((c[3] - want).abs() < 1e-6, "{} vs {want}", c[3]);
        assert!((c[1] - 0.5 * want).abs() < 1e-6);
        // the ball's chord
        let ball = Field::Ball { radius: 0.5 };
        let chord = answer(&ball, &Quantity::Integral, &line).unwrap()[0];
        assert!((chord - 2.0 * (0.25 - d2).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn bench_lines_cross_the_box() {
        let n = 16;
        let lines: Vec<Line> = (0..n * n)
            .filter_map(|k| pixel_line(n, k % n, k / n))
            .collect();
        assert!(lines.len() > n * n / 4);
        for l in &lines {
            for t in [l.t0, l.t1] {
                let x = l.p + l.d * t;
                assert!(x.abs().max_element() <= 1.0 + 1e-12, "{x}");
            }
        }
    }
}
