//! First crossing of a threshold along the ray (depth coding, iso-surfaces;
//! REFERENCE.md "Render modes"). The crossing is bracketed between two samples
//! and refined on the interpolant (Illinois false position, which also converges on
//! the jumps of nearest-neighbour reconstruction), not snapped to a sample.
//! Skipping passes over the macrocells that cannot reach the threshold; the sample
//! before the first one that does is then taken again to bracket the crossing.

use std::ops::ControlFlow;

use glam::{DVec3, Vec3};

use super::root::illinois;
use super::{drive, Consumer, Counts, Integrand, PixelRay};
use crate::render::march::March;
use crate::render::skip::MacroGrid;
use crate::sample::Field;
use crate::shade::Shader;

/// Depth coding: the distance from the depth reference to the first crossing of
/// `threshold` (NaN if none).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Depth {
    /// Normalised value.
    pub threshold: f32,
}

/// Shaded first crossing of `iso`: RGBA with alpha 1 at a hit, transparent
/// otherwise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// Normalised value.
    pub iso: f32,
    /// Reflection model, material and light.
    pub shader: Shader,
}

/// The search for the first sample at or above `level`.
struct FirstCrossing<'a, F: Field> {
    field: &'a F,
    ray: &'a PixelRay,
    march: &'a March,
    level: f32,
    /// The previous sample, unless it was passed over.
    prev: Option<(f64, f32)>,
    hit: Option<f64>,
    extra: u64,
}

impl<F: Field> Consumer for FirstCrossing<'_, F> {
    #[inline(always)]
    fn skippable(&self, _cell: usize, range: [f32; 2]) -> bool {
        range[1] < self.level
    }

    #[inline(always)]
    fn skip(&mut self, _i: usize, _j: usize) -> ControlFlow<()> {
        self.prev = None;
        ControlFlow::Continue(())
    }

    #[inline(always)]
    fn take(&mut self, i: usize, t: f64, f: f32) -> ControlFlow<()> {
        if f >= self.level {
            if i == 0 {
                self.hit = Some(t);
                return ControlFlow::Break(());
            }
            let prev = self.prev.unwrap_or_else(|| {
                let tp = self.march.t(i - 1);
                self.extra += 1;
                (tp, self.field.value(self.ray.index.at(tp)))
            });
            let (t_hit, extra) = refine(self.field, self.ray, self.level, prev, (t, f));
            self.extra += extra;
            self.hit = Some(t_hit);
            return ControlFlow::Break(());
        }
        self.prev = Some((t, f));
        ControlFlow::Continue(())
    }
}

/// Finds the first `t` where the field reaches `level`.
fn first_crossing<F: Field>(
    field: &F,
    ray: &PixelRay,
    march: &March,
    grid: Option<&MacroGrid>,
    level: f32,
) -> (Option<f64>, Counts) {
    let mut c = FirstCrossing {
        field,
        ray,
        march,
        level,
        prev: None,
        hit: None,
        extra: 0,
    };
    let taken = drive(march, field, ray, grid, &mut c);
    let counts = Counts {
        taken: taken + c.extra,
        nominal: march.len() as u64,
    };
    (c.hit, counts)
}

/// Refines the crossing of `level` between samples `a` and `b` (`f(a) < level <=
/// f(b)`) to 1e-7 of their distance. Returns it and the extra samples taken.
fn refine<F: Field>(
    field: &F,
    ray: &PixelRay,
    level: f32,
    a: (f64, f32),
    b: (f64, f32),
) -> (f64, u64) {
    let g = |t: f64| (field.value(ray.index.at(t)) - level) as f64;
    let tol = (b.0 - a.0) * 1e-7;
    illinois(
        g,
        (a.0, (a.1 - level) as f64),
        (b.0, (b.1 - level) as f64),
        |ta, tb| tb - ta <= tol,
        60,
    )
}

impl Integrand for Depth {
    fn channels(&self) -> usize {
        1
    }

    #[inline]
    fn trace<F: Field>(
        &self,
        field: &F,
        ray: &PixelRay,
        march: &March,
        grid: Option<&MacroGrid>,
    ) -> ([f32; 4], Counts) {
        let (hit, counts) = first_crossing(field, ray, march, grid, self.threshold);
        let d = hit.map_or(f32::NAN, |t| (t - ray.t_depth_ref) as f32);
        ([d, 0.0, 0.0, 0.0], counts)
    }
}

impl Integrand for Surface {
    fn channels(&self) -> usize {
        4
    }

    #[inline]
    fn trace<F: Field>(
        &self,
        field: &F,
        ray: &PixelRay,
        march: &March,
        grid: Option<&MacroGrid>,
    ) -> ([f32; 4], Counts) {
        let (hit, counts) = first_crossing(field, ray, march, grid, self.iso);
        match hit {
            Some(t) => (shade_hit(field, &self.shader, ray, t), counts),
            None => ([0.0; 4], counts),
        }
    }
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
    use crate::render::ray::IndexRay;

    /// `f(x)` along x.
    struct Along<G: Fn(f64) -> f32 + Sync>(G);
    impl<G: Fn(f64) -> f32 + Sync> Field for Along<G> {
        fn sizes(&self) -> [usize; 3] {
            [11, 1, 1]
        }
        fn value(&self, p: DVec3) -> f32 {
            (self.0)(p.x)
        }
        fn gradient(&self, _p: DVec3) -> DVec3 {
            DVec3::ZERO
        }
        fn cell_corners(&self, _c: [usize; 3]) -> [f32; 8] {
            [0.0; 8]
        }
    }

    fn crossing(f: impl Fn(f64) -> f32 + Sync, level: f32) -> Option<f64> {
        let ray = PixelRay {
            origin: DVec3::ZERO,
            dir: DVec3::X,
            index: IndexRay {
                o: DVec3::ZERO,
                d: DVec3::X,
            },
            t_enter: 0.0,
            t_exit: 10.0,
            t_depth_ref: 0.0,
        };
        let m = March::new(0.0, 10.0, 1.0);
        first_crossing(&Along(f), &ray, &m, None, level).0
    }

    #[test]
    fn refines_between_samples() {
        // f(t) = t / 10 crosses 0.437 at t = 4.37, between samples 4 and 5
        let t = crossing(|t| (t / 10.0) as f32, 0.437);
        assert!((t.unwrap() - 4.37).abs() < 1e-5);
    }

    #[test]
    fn finds_a_jump() {
        let t = crossing(|t| if t >= 3.3 { 1.0 } else { 0.0 }, 0.5);
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
