//! First crossing of a threshold along the ray (depth coding, iso-surfaces;
//! docs/formulas.md "Render modes"). The crossing is bracketed between two samples
//! and refined on the interpolant (Illinois false position, which also converges on
//! the jumps of nearest-neighbour reconstruction), not snapped to a sample.
//! Skipping passes over the macrocells that cannot reach the threshold; the sample
//! before the first one that does is then taken again to bracket the crossing.

use std::ops::ControlFlow;

use glam::{DVec3, Vec3};

use crate::render::integrator::root::illinois;
use crate::render::integrator::{drive, Consumer, Counts, Integrand, PixelRay};
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

/// How the search for a ray's crossing starts: where the ray enters through a
/// clipping plane inside the object (at or above the level), a capped plane is the
/// surface there, and an uncapped one shows the surface from inside, the first
/// point where the field falls below the level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Entry {
    /// The first point at or above the level (also a ray that enters the box
    /// inside the object: the box face is the surface).
    Rising,
    /// The first point below the level.
    Falling,
    /// The cut face at the entry, with this outward normal.
    Cap(DVec3),
}

impl Entry {
    /// How `ray`'s search for `level` starts (one sample at the entry when the ray
    /// enters through a clipping plane).
    pub(super) fn of<F: Field>(field: &F, ray: &PixelRay, level: f32) -> Entry {
        match ray.cut {
            Some(cut) if field.value(ray.index.at(ray.t_enter)) >= level => {
                if cut.cap {
                    Entry::Cap(cut.normal)
                } else {
                    Entry::Falling
                }
            }
            _ => Entry::Rising,
        }
    }

    /// The hit of `level` along `ray`: the cap at the entry, or what `crossing`
    /// (the first crossing, rising or not) finds; `nominal` is the count of samples
    /// (or cells) the ray would take.
    pub(super) fn search<F: Field>(
        field: &F,
        ray: &PixelRay,
        level: f32,
        nominal: u64,
        crossing: impl FnOnce(bool) -> (Option<f64>, Counts),
    ) -> (Option<Hit>, Counts) {
        let rising = match Entry::of(field, ray, level) {
            Entry::Cap(normal) => {
                let counts = Counts { taken: 1, nominal };
                return (Some(Hit::Cap(ray.t_enter, normal)), counts);
            }
            Entry::Rising => true,
            Entry::Falling => false,
        };
        let (t, counts) = crossing(rising);
        (t.map(Hit::Level), counts)
    }
}

/// What a crossing search found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Hit {
    /// A crossing of the level at `t`.
    Level(f64),
    /// The cut face of a capped clipping plane at `t`, with its outward normal.
    Cap(f64, DVec3),
}

impl Hit {
    /// The ray parameter of the hit.
    pub(super) fn t(self) -> f64 {
        match self {
            Hit::Level(t) | Hit::Cap(t, _) => t,
        }
    }

    /// The distance from the depth reference (NaN where there is no hit).
    pub(super) fn depth(hit: Option<Hit>, ray: &PixelRay) -> f32 {
        hit.map_or(f32::NAN, |h| (h.t() - ray.t_depth_ref) as f32)
    }

    /// The shaded colour of a hit (transparent where there is none).
    pub(super) fn shade<F: Field>(
        hit: Option<Hit>,
        field: &F,
        shader: &Shader,
        ray: &PixelRay,
    ) -> [f32; 4] {
        match hit {
            Some(Hit::Level(t)) => shade_hit(field, shader, ray, t),
            Some(Hit::Cap(t, normal)) => shade_normal(shader, ray, t, Some(normal)),
            None => [0.0; 4],
        }
    }
}

/// The search for the first sample at or above `level` (below it, when falling).
struct FirstCrossing<'a, F: Field> {
    field: &'a F,
    ray: &'a PixelRay,
    march: &'a March,
    level: f32,
    rising: bool,
    /// The previous sample, unless it was passed over.
    prev: Option<(f64, f32)>,
    hit: Option<f64>,
    extra: u64,
}

impl<F: Field> FirstCrossing<'_, F> {
    #[inline(always)]
    fn reached(&self, f: f32) -> bool {
        if self.rising {
            f >= self.level
        } else {
            f < self.level
        }
    }
}

/// Whether every value of `range` lies below `level`: a macrocell that a rising
/// search for `level` passes over.
#[inline(always)]
fn below(range: [f32; 2], level: f32) -> bool {
    range[1] < level
}

impl<F: Field> Consumer for FirstCrossing<'_, F> {
    #[inline(always)]
    fn skippable(&self, _cell: usize, range: [f32; 2]) -> bool {
        if self.rising {
            below(range, self.level)
        } else {
            range[0] >= self.level
        }
    }

    #[inline(always)]
    fn skip(&mut self, _i: usize, _j: usize) -> ControlFlow<()> {
        self.prev = None;
        ControlFlow::Continue(())
    }

    #[inline(always)]
    fn take(&mut self, i: usize, t: f64, f: f32) -> ControlFlow<()> {
        if self.reached(f) {
            if i == 0 {
                self.hit = Some(t);
                return ControlFlow::Break(());
            }
            let prev = self.prev.unwrap_or_else(|| {
                let tp = self.march.t(i - 1);
                self.extra += 1;
                (tp, self.field.value(self.ray.index.at(tp)))
            });
            let (t_hit, extra) =
                refine(self.field, self.ray, self.level, self.rising, prev, (t, f));
            self.extra += extra;
            self.hit = Some(t_hit);
            return ControlFlow::Break(());
        }
        self.prev = Some((t, f));
        ControlFlow::Continue(())
    }
}

/// Finds the first `t` where the field reaches `level` (falls below it, when not
/// `rising`).
fn first_crossing<F: Field>(
    field: &F,
    ray: &PixelRay,
    march: &March,
    grid: Option<&MacroGrid>,
    level: f32,
    rising: bool,
) -> (Option<f64>, Counts) {
    // a falling search (a ray entering through a cut inside the object) passes over
    // the cells above the level, which the ray's window, the part where a cell that
    // can reach the level lies, does not bound: it walks the whole ray
    let whole;
    let ray = if rising {
        ray
    } else {
        whole = PixelRay {
            walk: [ray.t_enter, ray.t_exit],
            ..*ray
        };
        &whole
    };
    let mut c = FirstCrossing {
        field,
        ray,
        march,
        level,
        rising,
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

/// The hit of `level` along a sampled ray: where it starts ([`Entry`]), then the
/// first crossing.
fn find_hit<F: Field>(
    field: &F,
    ray: &PixelRay,
    march: &March,
    grid: Option<&MacroGrid>,
    level: f32,
) -> (Option<Hit>, Counts) {
    Entry::search(field, ray, level, march.len() as u64, |rising| {
        first_crossing(field, ray, march, grid, level, rising)
    })
}

/// Refines the crossing of `level` between samples `a` and `b` (`f(a) < level <=
/// f(b)`, or the reverse when falling) to 1e-7 of their distance. Returns it and
/// the extra samples taken.
fn refine<F: Field>(
    field: &F,
    ray: &PixelRay,
    level: f32,
    rising: bool,
    a: (f64, f32),
    b: (f64, f32),
) -> (f64, u64) {
    let sign = if rising { 1.0 } else { -1.0 };
    let g = |t: f64| sign * (field.value(ray.index.at(t)) - level) as f64;
    let tol = (b.0 - a.0) * 1e-7;
    illinois(
        g,
        (a.0, sign * (a.1 - level) as f64),
        (b.0, sign * (b.1 - level) as f64),
        |ta, tb| tb - ta <= tol,
        60,
    )
}

impl Integrand for Depth {
    /// Cells whose values all lie below the level, which a rising search passes
    /// over (`FirstCrossing`; a falling one walks its whole ray).
    fn window_passes(&self, _cell: usize, range: [f32; 2]) -> Option<bool> {
        Some(below(range, self.threshold))
    }

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
        let (hit, counts) = find_hit(field, ray, march, grid, self.threshold);
        ([Hit::depth(hit, ray), 0.0, 0.0, 0.0], counts)
    }
}

impl Integrand for Surface {
    /// Cells whose values all lie below the level, which a rising search passes
    /// over (`FirstCrossing`; a falling one walks its whole ray).
    fn window_passes(&self, _cell: usize, range: [f32; 2]) -> Option<bool> {
        Some(below(range, self.iso))
    }

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
        let (hit, counts) = find_hit(field, ray, march, grid, self.iso);
        (Hit::shade(hit, field, &self.shader, ray), counts)
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
    shade_normal(shader, ray, t, normal)
}

/// The shaded colour (white, alpha 1) at `t` with a given unit normal.
fn shade_normal(shader: &Shader, ray: &PixelRay, t: f64, normal: Option<DVec3>) -> [f32; 4] {
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
    use crate::render::integrator::testing::along_x;

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
        let ray = along_x(10.0);
        let m = March::new(0.0, 10.0, 1.0);
        first_crossing(&Along(f), &ray, &m, None, level, true).0
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
