//! Specular terms of the three reflection models (docs/formulas.md "Shading").
//!
//! Every function takes unit vectors `n` (normal), `l` (towards the light) and `v` (towards
//! the eye), is called only where `n.l > 0`, and returns a finite value for any finite input:
//! each division is guarded, and a degenerate configuration (`l = -v`, grazing angles) gives
//! no highlight rather than NaN.

use std::f32::consts::PI;

use glam::Vec3;

/// Below this, `n.v` and `v.h` are clamped before dividing by them (Cook-Torrance).
const MIN_COSINE: f32 = 1e-6;

/// Largest exponent used by Cook-Torrance: keeps the Beckmann roughness `m >= 1.4e-3`, so its
/// normalisation `1 / (pi m^2 cos^4)` cannot overflow.
const MAX_COOK_TORRANCE_EXPONENT: f32 = 1e6;

/// `max(c, 0)^e` with `c` capped at 1 and `e` clamped to `>= 0`: the Phong lobe shape.
fn lobe(cosine: f32, exponent: f32) -> f32 {
    if cosine > 0.0 {
        cosine.min(1.0).powf(exponent.max(0.0))
    } else {
        0.0
    }
}

/// Phong: `max(r.v, 0)^e` with `r = reflect(-l, n) = 2(n.l)n - l`.
pub(crate) fn phong(n: Vec3, l: Vec3, v: Vec3, n_dot_l: f32, exponent: f32) -> f32 {
    let r = 2.0 * n_dot_l * n - l;
    lobe(r.dot(v), exponent)
}

/// Blinn-Phong: `max(n.h, 0)^e` with `h = normalize(l + v)`; no highlight where `l = -v`.
pub(crate) fn blinn_phong(n: Vec3, l: Vec3, v: Vec3, exponent: f32) -> f32 {
    let h = (l + v).normalize_or_zero();
    if h == Vec3::ZERO {
        return 0.0;
    }
    lobe(n.dot(h), exponent)
}

/// Cook-Torrance specular reflectance `F D G / (4 (n.v))` per channel, to be multiplied by the
/// light's radiance.
///
/// This is the standard microfacet form of docs/formulas.md's `k_s M_s L_s F D G / (n.v)`:
/// - `M_s` enters through the Fresnel term: `F` is Schlick's approximation with the material's
///   specular colour as the reflectance at normal incidence `F0`, per channel ([`schlick`]);
///   `k_s = 1`.
/// - `D` is the normalised Beckmann distribution ([`beckmann`]) with roughness
///   `m = sqrt(2 / (e + 2))` from the Phong exponent `e` (the usual mapping, which matches the
///   two lobes' widths); normalised, it needs the `1/4` of the half-vector Jacobian.
/// - `G = min(1, 2(n.h)(n.v)/(v.h), 2(n.h)(n.l)/(v.h))` (Cook and Torrance 1982); `G / (n.v)`
///   is evaluated as a minimum of bounded quotients ([`geometry_over_n_dot_v`]).
///
/// No highlight where the eye is below the surface (`n.v <= 0`) or `l = -v`.
pub(crate) fn cook_torrance(specular: Vec3, exponent: f32, n: Vec3, l: Vec3, v: Vec3) -> Vec3 {
    let n_dot_v = n.dot(v);
    let h = (l + v).normalize_or_zero();
    let n_dot_h = n.dot(h).min(1.0);
    let v_dot_h = v.dot(h).min(1.0);
    if !(n_dot_v > 0.0 && n_dot_h > 0.0 && v_dot_h > 0.0) {
        return Vec3::ZERO;
    }
    let n_dot_l = n.dot(l).min(1.0);
    let m2 = beckmann_roughness_squared(exponent);
    let d = beckmann(n_dot_h, m2);
    let g_over_nv = geometry_over_n_dot_v(n_dot_h, n_dot_v, n_dot_l, v_dot_h);
    schlick(specular, v_dot_h) * (d * g_over_nv / 4.0)
}

/// Schlick's Fresnel approximation `F0 + (1 - F0)(1 - v.h)^5`, per channel.
pub(crate) fn schlick(f0: Vec3, v_dot_h: f32) -> Vec3 {
    let k = (1.0 - v_dot_h.clamp(0.0, 1.0)).powi(5);
    f0 + (Vec3::ONE - f0) * k
}

/// Beckmann roughness squared, `m^2 = 2 / (e + 2)`, for a Phong exponent `e` (clamped to
/// `[0, 1e6]`, so `m^2` is in `[2e-6, 1]`).
pub(crate) fn beckmann_roughness_squared(exponent: f32) -> f32 {
    2.0 / (exponent.clamp(0.0, MAX_COOK_TORRANCE_EXPONENT) + 2.0)
}

/// Normalised Beckmann distribution `exp(-tan^2(a)/m^2) / (pi m^2 cos^4(a))`, `cos(a) = n.h`.
///
/// Zero for `n.h < 1e-3`: there `tan^2(a) > 1e6 - 1` and `m^2 <= 1`, so the exponential is
/// below `e^-999999`, zero in any float, while `cos^4` would underflow into `0/0`.
pub(crate) fn beckmann(n_dot_h: f32, m2: f32) -> f32 {
    if n_dot_h.is_nan() || n_dot_h < 1e-3 {
        return 0.0;
    }
    let c2 = n_dot_h * n_dot_h;
    let tan2 = (1.0 - c2).max(0.0) / c2;
    (-tan2 / m2).exp() / (PI * m2 * c2 * c2)
}

/// `G / (n.v)` with `G = min(1, 2(n.h)(n.v)/(v.h), 2(n.h)(n.l)/(v.h))`, computed as
/// `min(1/(n.v), 2(n.h)/(v.h), 2(n.h)(n.l)/((v.h)(n.v)))` so that no large quotient is
/// multiplied back down; `n.v` and `v.h` are clamped to `>= 1e-6`, so it is finite (for unit
/// vectors it is at most `4 / (n.l + n.v)`).
pub(crate) fn geometry_over_n_dot_v(n_dot_h: f32, n_dot_v: f32, n_dot_l: f32, v_dot_h: f32) -> f32 {
    let n_dot_v = n_dot_v.max(MIN_COSINE);
    let v_dot_h = v_dot_h.max(MIN_COSINE);
    let masking = 2.0 * n_dot_h / v_dot_h;
    let shadowing = masking * n_dot_l / n_dot_v;
    (1.0 / n_dot_v).min(masking).min(shadowing)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cook-Torrance at one configuration, written out with plain f64 arithmetic from the
    /// formulas (no shared code): n = z, l and v in the xz-plane at 30 and 50 degrees on either
    /// side of the normal.
    #[test]
    fn cook_torrance_matches_an_independent_f64_evaluation() {
        let (theta_l, theta_v) = (30f64.to_radians(), 50f64.to_radians());
        let l = [theta_l.sin(), 0.0, theta_l.cos()];
        let v = [-theta_v.sin(), 0.0, theta_v.cos()];
        let specular = [0.628281f64, 0.555802, 0.366065]; // gold
        let e = 32.0 * 0.4;

        let sum = [l[0] + v[0], l[1] + v[1], l[2] + v[2]];
        let len = (sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]).sqrt();
        let h = [sum[0] / len, sum[1] / len, sum[2] / len];
        let (nl, nv, nh) = (l[2], v[2], h[2]);
        let vh = v[0] * h[0] + v[1] * h[1] + v[2] * h[2];
        let m2 = 2.0 / (e + 2.0);
        let alpha = nh.acos();
        let d = (-alpha.tan().powi(2) / m2).exp() / (std::f64::consts::PI * m2 * nh.powi(4));
        let g = 1f64.min(2.0 * nh * nv / vh).min(2.0 * nh * nl / vh);
        let expected = specular.map(|f0| {
            let f = f0 + (1.0 - f0) * (1.0 - vh).powi(5);
            f * d * g / (4.0 * nv)
        });

        let to_f32 = |a: [f64; 3]| Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32);
        let got = cook_torrance(to_f32(specular), e as f32, Vec3::Z, to_f32(l), to_f32(v));
        for c in 0..3 {
            let rel = (f64::from(got[c]) - expected[c]).abs() / expected[c];
            // f32 evaluation of a handful of operations: a few ulps, well under 1e-5.
            assert!(
                rel < 1e-5,
                "channel {c}: got {}, expected {}",
                got[c],
                expected[c]
            );
        }
        assert!(
            expected.iter().all(|&x| x > 1e-3),
            "configuration shows a highlight"
        );
    }

    #[test]
    fn beckmann_peak_is_its_normalisation() {
        let m2 = beckmann_roughness_squared(30.0);
        assert_eq!(m2, 2.0 / 32.0);
        assert!((beckmann(1.0, m2) - 1.0 / (PI * m2)).abs() < 1e-6);
        assert_eq!(beckmann(0.0, m2), 0.0);
        assert_eq!(beckmann(5e-4, 1.0), 0.0);
    }

    #[test]
    fn beckmann_is_normalised_over_the_hemisphere() {
        // Integral of D(h) (n.h) dw over the hemisphere is 1 for a normalised distribution.
        let m2 = beckmann_roughness_squared(10.0);
        let steps = 20_000;
        let dtheta = std::f64::consts::FRAC_PI_2 / steps as f64;
        let integral: f64 = (0..steps)
            .map(|i| {
                let theta = (i as f64 + 0.5) * dtheta;
                let d = f64::from(beckmann(theta.cos() as f32, m2));
                d * theta.cos() * theta.sin() * 2.0 * std::f64::consts::PI * dtheta
            })
            .sum();
        assert!((integral - 1.0).abs() < 1e-3, "integral {integral}");
    }

    #[test]
    fn schlick_is_f0_at_normal_incidence_and_one_at_grazing() {
        let f0 = Vec3::new(0.2, 0.5, 0.9);
        assert_eq!(schlick(f0, 1.0), f0);
        assert_eq!(schlick(f0, 0.0), Vec3::ONE);
    }

    #[test]
    fn geometry_term_is_bounded_at_grazing_angles() {
        for &nv in &[0.0, 1e-30, 1e-8, 1e-3, 0.5, 1.0] {
            for &vh in &[0.0, 1e-30, 1e-3, 1.0] {
                let g = geometry_over_n_dot_v(1.0, nv, 1.0, vh);
                assert!(g.is_finite() && g >= 0.0, "nv {nv} vh {vh}: {g}");
            }
        }
        // Normal incidence: G = 1, so G/(n.v) = 1.
        assert_eq!(geometry_over_n_dot_v(1.0, 1.0, 1.0, 1.0), 1.0);
    }

    #[test]
    fn opposite_light_and_eye_give_no_highlight() {
        let v = Vec3::new(0.0, 0.6, 0.8);
        assert_eq!(blinn_phong(Vec3::Z, -v, v, 10.0), 0.0);
        assert_eq!(cook_torrance(Vec3::ONE, 10.0, Vec3::Z, -v, v), Vec3::ZERO);
    }
}
