//! First crossing of a threshold along the ray (depth coding, iso-surfaces;
//! REFERENCE.md "Render modes"). The crossing is bracketed between two samples
//! and refined on the interpolant (Illinois false position, which also converges on
//! the jumps of nearest-neighbour reconstruction), not snapped to a sample.

use glam::{DVec3, Vec3};

use super::root::illinois;
use super::{March, PixelRay};
use crate::sample::Field;
use crate::shade::Shader;

/// Finds the first `t` where the field reaches `level`; returns `(t, samples)`.
fn first_crossing(march: &March, value: &impl Fn(f64) -> f32, level: f32) -> (Option<f64>, u64) {
    let n = march.len();
    let mut t_prev = march.t(0);
    let mut f_prev = value(t_prev);
    if f_prev >= level {
        return (Some(t_prev), 1);
    }
    for i in 1..n {
        let t = march.t(i);
        let f = value(t);
        if f >= level {
            let (t_hit, extra) = refine(value, level, (t_prev, f_prev), (t, f));
            return (Some(t_hit), i as u64 + 1 + extra);
        }
        t_prev = t;
        f_prev = f;
    }
    (None, n as u64)
}

/// Refines the crossing of `level` between samples `a` and `b` (`f(a) < level <=
/// f(b)`) to 1e-7 of their distance. Returns it and the extra samples taken.
fn refine(value: &impl Fn(f64) -> f32, level: f32, a: (f64, f32), b: (f64, f32)) -> (f64, u64) {
    let g = |t: f64| (value(t) - level) as f64;
    let tol = (b.0 - a.0) * 1e-7;
    illinois(
        g,
        (a.0, (a.1 - level) as f64),
        (b.0, (b.1 - level) as f64),
        |ta, tb| tb - ta <= tol,
        60,
    )
}

/// Depth coding: distance from the depth reference to the first crossing (NaN if none).
pub fn depth(
    march: &March,
    value: impl Fn(f64) -> f32,
    threshold: f32,
    ray: &PixelRay,
) -> ([f32; 4], u64) {
    let (hit, n) = first_crossing(march, &value, threshold);
    let d = hit.map_or(f32::NAN, |t| (t - ray.t_depth_ref) as f32);
    ([d, 0.0, 0.0, 0.0], n)
}

/// The unit surface normal from a world gradient: `-grad / |grad|` (the object is
/// denser than air), flipped to face the viewer; `None` where the gradient vanishes.
pub fn normal_from_gradient(grad: DVec3, ray_dir: DVec3) -> Option<DVec3> {
    let len = grad.length();
    if !len.is_finite() || len <= 1e-12 {
        // zero or NaN gradients have no direction (NaN fails `len > 1e-12` too)
        return None;
    }
    let n = -grad / len;
    Some(if n.dot(ray_dir) > 0.0 { -n } else { n })
}

/// Shaded iso-surface: RGBA with alpha 1 at a hit, transparent otherwise.
pub fn surface<F: Field>(
    march: &March,
    field: &F,
    iso: f32,
    shader: &Shader,
    ray: &PixelRay,
) -> ([f32; 4], u64) {
    let value = |t: f64| field.value(ray.index.at(t));
    let (hit, n) = first_crossing(march, &value, iso);
    let Some(t) = hit else { return ([0.0; 4], n) };
    (shade_hit(field, shader, ray, t), n)
}

/// The shaded colour of an iso-surface hit at `t` (white, alpha 1), with the
/// normal from the field's gradient there.
pub fn shade_hit<F: Field>(field: &F, shader: &Shader, ray: &PixelRay, t: f64) -> [f32; 4] {
    let normal = normal_from_gradient(field.gradient(ray.index.at(t)), ray.dir);
    let c = shader.shade(
        ray.world(t).as_vec3(),
        normal.map(|n| n.as_vec3()),
        (-ray.dir).as_vec3(),
        Vec3::ONE,
    );
    [c.x, c.y, c.z, 1.0]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refines_between_samples() {
        // f(t) = t / 10 crosses 0.437 at t = 4.37, between samples 4 and 5
        let m = March::new(0.0, 10.0, 1.0);
        let f = |t: f64| (t / 10.0) as f32;
        let (t, _) = first_crossing(&m, &f, 0.437);
        assert!((t.unwrap() - 4.37).abs() < 1e-5);
    }

    #[test]
    fn finds_a_jump() {
        let m = March::new(0.0, 10.0, 1.0);
        let f = |t: f64| if t >= 3.3 { 1.0 } else { 0.0 };
        let (t, _) = first_crossing(&m, &f, 0.5);
        assert!((t.unwrap() - 3.3).abs() < 1e-5);
    }

    #[test]
    fn zero_gradient_has_no_normal() {
        assert_eq!(normal_from_gradient(DVec3::ZERO, DVec3::X), None);
        assert_eq!(
            normal_from_gradient(DVec3::new(f64::NAN, 0.0, 0.0), DVec3::X),
            None
        );
        let n = normal_from_gradient(DVec3::new(-2.0, 0.0, 0.0), DVec3::X).unwrap();
        assert_eq!(n, -DVec3::X, "flipped to face the viewer");
    }
}
