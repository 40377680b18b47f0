//! Exact integration along the trilinear interpolant (`integration = "exact"`).
//!
//! The ray is walked cell by cell (a 3D DDA in index space). Inside one cell the
//! trilinear interpolant restricted to the ray, `f(t0 + s)`, is a cubic polynomial
//! in `s` (a product of three functions linear in `s`), so each mode is answered in
//! closed form on every cell segment:
//! - `xray` / `average`: the integral of the cubic;
//! - `mip` / `minip`: its maximum / minimum over the segment, among the end points
//!   and the roots of its derivative (a quadratic);
//! - `depth` / `surface`: its first point at or above the threshold, found as in
//!   Marmitt et al. 2004 ("Fast and accurate ray-voxel intersection techniques for
//!   iso-surface ray tracing"): the segment is split at the roots of the derivative
//!   into monotone pieces, and the first piece that reaches the threshold holds the
//!   crossing, refined on the polynomial to round-off. A piece ending in a local
//!   maximum that touches the threshold (a tangent ray, a double root) counts as a
//!   hit at the maximum.
//!
//! The only error left is the reconstruction's (docs/formulas.md "Reconstruction"): the
//! result is exact for the trilinear interpolant, up to f64 round-off.
//!
//! Robustness of the walk: cell boundaries are the integer planes crossed between
//! the entry and the exit, each crossing computed from its plane index (never
//! accumulated). The cell of a segment is the one containing the segment's
//! midpoint, so rays along an axis, on a face, through an edge or a corner, and
//! zero-length segments where several planes are crossed at once, need no special
//! case: the interpolant is continuous, and on a shared face the two cells agree.

use std::ops::ControlFlow;

use super::crossing::{Entry, Hit};
pub use super::projection::integrator::CuedMip;
use super::xray::integrator::{finish, XrayOutput};
use crate::render::integrator::root::illinois;
use crate::render::integrator::{Counts, Integrand, PixelRay};
use crate::render::march::March;
use crate::render::skip::MacroGrid;
use crate::sample::Field;
use crate::shade::Shader;

/// What an exact pass computes per ray.
#[derive(Clone, Debug)]
pub enum Exact {
    /// Line integral of the interpolant.
    Xray {
        /// Stored quantity.
        output: XrayOutput,
        /// Attenuation scale.
        mu: f64,
    },
    /// True maximum along the ray.
    Mip,
    /// True maximum of the depth-weighted interpolant, and where it is.
    CuedMip(CuedMip),
    /// True minimum along the ray.
    Minip,
    /// Integral divided by the ray's length.
    Average,
    /// Distance from the depth reference to the first crossing.
    Depth {
        /// Normalised value.
        threshold: f32,
    },
    /// Shaded first crossing.
    Surface {
        /// Normalised value.
        iso: f32,
        /// Reflection model, material and light.
        shader: Shader,
    },
}

/// The interpolant on one cell segment: `f(t0 + s) = c0 + c1 s + c2 s^2 + c3 s^3`
/// for `s` in `[0, len]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// Coefficients, constant term first.
    pub c: [f64; 4],
    /// Ray parameter at `s = 0` (world units).
    pub t0: f64,
    /// Length of the segment (world units).
    pub len: f64,
}

impl Segment {
    /// The trilinear interpolant of `corners` (corner `(a, b, c)` at `a + 2b + 4c`)
    /// along `u(s) = u0 + s du`, `u` the position inside the cell (docs/formulas.md
    /// "Reconstruction"): interpolate along x (4 lines, linear in `s`), then y (2
    /// quadratics), then z (the cubic).
    pub fn from_corners(corners: [f32; 8], u0: [f64; 3], du: [f64; 3], t0: f64, len: f64) -> Self {
        let v = corners.map(f64::from);
        // e[b + 2c]: linear in s
        let e: [[f64; 2]; 4] = std::array::from_fn(|bc| {
            let (v0, v1) = (v[2 * bc], v[2 * bc + 1]);
            let dv = v1 - v0;
            [v0 + dv * u0[0], dv * du[0]]
        });
        // g[c]: quadratic in s
        let g: [[f64; 3]; 2] = std::array::from_fn(|c| {
            let (lo, hi) = (e[2 * c], e[2 * c + 1]);
            let d = [hi[0] - lo[0], hi[1] - lo[1]];
            [
                lo[0] + d[0] * u0[1],
                lo[1] + d[0] * du[1] + d[1] * u0[1],
                d[1] * du[1],
            ]
        });
        let d = [g[1][0] - g[0][0], g[1][1] - g[0][1], g[1][2] - g[0][2]];
        let c = [
            g[0][0] + d[0] * u0[2],
            g[0][1] + d[0] * du[2] + d[1] * u0[2],
            g[0][2] + d[1] * du[2] + d[2] * u0[2],
            d[2] * du[2],
        ];
        Segment { c, t0, len }
    }

    /// The polynomial at `s` (Horner).
    #[inline]
    pub fn eval(&self, s: f64) -> f64 {
        let [c0, c1, c2, c3] = self.c;
        c0 + s * (c1 + s * (c2 + s * c3))
    }

    /// Its integral over `[0, len]`.
    #[inline]
    pub fn integral(&self) -> f64 {
        let [c0, c1, c2, c3] = self.c;
        let l = self.len;
        l * (c0 + l * (c1 / 2.0 + l * (c2 / 3.0 + l * (c3 / 4.0))))
    }

    /// The roots of the derivative `c1 + 2 c2 s + 3 c3 s^2` strictly inside
    /// `(0, len)`, ascending (the stable quadratic formula: no cancellation, and a
    /// vanishing leading coefficient leaves the linear root).
    pub fn critical_points(&self) -> ([f64; 2], usize) {
        let (a, b, c) = (3.0 * self.c[3], 2.0 * self.c[2], self.c[1]);
        let mut out = [0.0; 2];
        let mut n = 0;
        let mut push = |r: f64| {
            if r > 0.0 && r < self.len {
                out[n] = r;
                n += 1;
            }
        };
        if a == 0.0 {
            if b != 0.0 {
                push(-c / b);
            }
        } else {
            let disc = b * b - 4.0 * a * c;
            if disc >= 0.0 {
                let q = -0.5 * (b + disc.sqrt().copysign(b));
                if q != 0.0 {
                    push(q / a);
                    push(c / q);
                } else {
                    // b = 0 and disc = 0: a double root at 0, an end point
                }
            }
        }
        if n == 2 && out[0] > out[1] {
            out.swap(0, 1);
        }
        (out, n)
    }

    /// The largest (`max`) or smallest value over `[0, len]`.
    pub fn extremum(&self, max: bool) -> f64 {
        let pick = |a: f64, b: f64| if max { a.max(b) } else { a.min(b) };
        let mut best = pick(self.eval(0.0), self.eval(self.len));
        let (roots, n) = self.critical_points();
        for &r in &roots[..n] {
            best = pick(best, self.eval(r));
        }
        best
    }

    /// The largest value over `[0, len]` of the interpolant weighted by `a + b s`,
    /// and the first `s` where it is reached: a quartic, whose interior maxima are
    /// roots of its cubic derivative. The roots of the derivative's own derivative
    /// (a quadratic, solved like [`Segment::critical_points`]) split the segment
    /// into pieces where the derivative is monotone; a piece where it falls from
    /// positive to negative holds one maximum, refined to round-off by the
    /// crossings' Illinois search.
    pub fn weighted_max(&self, a: f64, b: f64) -> (f64, f64) {
        let [c0, c1, c2, c3] = self.c;
        let q = [
            a * c0,
            a * c1 + b * c0,
            a * c2 + b * c1,
            a * c3 + b * c2,
            b * c3,
        ];
        let g = |u: f64| q[0] + u * (q[1] + u * (q[2] + u * (q[3] + u * q[4])));
        // the derivative as a cubic "segment": its critical points are the roots of
        // the second derivative
        let dg = Segment {
            c: [q[1], 2.0 * q[2], 3.0 * q[3], 4.0 * q[4]],
            t0: self.t0,
            len: self.len,
        };
        let (cuts, n) = dg.critical_points();
        let mut best = (g(0.0), 0.0);
        let mut consider = |u: f64| {
            let v = g(u);
            if v > best.0 {
                best = (v, u);
            }
        };
        let mut x0 = 0.0;
        for &x1 in cuts[..n].iter().chain([self.len].iter()) {
            let (d0, d1) = (dg.eval(x0), dg.eval(x1));
            if d0 > 0.0 && d1 < 0.0 {
                // the root of the falling derivative: a rising root of -g'
                let (root, _) = illinois(
                    |u| -dg.eval(u),
                    (x0, -d0),
                    (x1, -d1),
                    |a, b| b - a <= 4.0 * f64::EPSILON * b.abs().max(a.abs()) || b <= a,
                    200,
                );
                consider(root);
            }
            x0 = x1;
        }
        consider(self.len);
        best
    }

    /// A bound on the round-off of [`Segment::eval`] over the segment.
    fn eval_tolerance(&self) -> f64 {
        let l = self.len;
        let [c0, c1, c2, c3] = self.c.map(f64::abs);
        8.0 * f64::EPSILON * (c0 + l * (c1 + l * (c2 + l * c3)))
    }

    /// The first `s` in `[0, len]` where the polynomial is at or above `level`.
    pub fn first_reach(&self, level: f64) -> Option<f64> {
        let mut a = 0.0;
        let mut fa = self.eval(0.0);
        if fa >= level {
            return Some(0.0);
        }
        let (roots, n) = self.critical_points();
        let tol = self.eval_tolerance();
        for (idx, &b) in roots[..n].iter().chain([self.len].iter()).enumerate() {
            let fb = self.eval(b);
            // A local maximum touching the level within round-off: a tangent ray
            // (a double root), whose crossing is the maximum itself; refining would
            // wander over the flat top, where f - level is below round-off.
            if idx < n && (fb - level).abs() <= tol && fb >= fa {
                return Some(b);
            }
            if fb >= level {
                return Some(self.refine(level, (a, fa), (b, fb)));
            }
            a = b;
            fa = fb;
        }
        None
    }

    /// The crossing of `level` in `[a, b]`, where the polynomial is monotone with
    /// `f(a) < level <= f(b)`, to round-off. Returns a point where `f >= level`.
    fn refine(&self, level: f64, (a, fa): (f64, f64), (b, fb): (f64, f64)) -> f64 {
        let round_off =
            |a: f64, b: f64| b - a <= 4.0 * f64::EPSILON * b.abs().max(a.abs()) || b <= a;
        illinois(
            |s| self.eval(s) - level,
            (a, fa - level),
            (b, fb - level),
            round_off,
            200,
        )
        .0
    }
}

/// Neumaier's compensated sum (an improved Kahan sum): the error of adding many
/// terms stays at round-off of the total instead of growing with their number.
#[derive(Clone, Copy, Debug, Default)]
pub struct CompensatedSum {
    sum: f64,
    compensation: f64,
}

impl CompensatedSum {
    /// Adds one term.
    #[inline]
    pub fn add(&mut self, x: f64) {
        let t = self.sum + x;
        if self.sum.abs() >= x.abs() {
            self.compensation += (self.sum - t) + x;
        } else {
            self.compensation += (x - t) + self.sum;
        }
        self.sum = t;
    }

    /// The total.
    pub fn total(&self) -> f64 {
        self.sum + self.compensation
    }
}

/// One voxel cell on a ray: the cell and the ray's parameter interval inside it.
#[derive(Clone, Copy, Debug)]
pub struct CellSpan {
    /// The cell (from voxel `c` to `c + 1` on each axis).
    pub c: [usize; 3],
    /// Entry into the cell.
    pub ta: f64,
    /// Exit from the cell.
    pub tb: f64,
}

/// Walks the ray's clipped interval cell by cell and calls `visit` with each cell
/// span of positive length, in order, until it breaks. Returns the number of cell
/// spans on the ray up to the break.
pub fn walk(
    n: [usize; 3],
    ray: &PixelRay,
    mut visit: impl FnMut(&CellSpan) -> ControlFlow<()>,
) -> u64 {
    let (o, d) = (ray.index.o.to_array(), ray.index.d.to_array());
    let (t_enter, t_exit) = (ray.t_enter, ray.t_exit);
    if !(t_enter.is_finite() && t_exit.is_finite()) || t_exit <= t_enter {
        return 0;
    }
    // Next plane index, its step and its crossing per axis.
    let mut k = [0.0f64; 3];
    let mut step = [0.0f64; 3];
    let mut t_next = [f64::INFINITY; 3];
    for a in 0..3 {
        if n[a] < 2 || d[a] == 0.0 {
            continue;
        }
        let p = o[a] + t_enter * d[a];
        if d[a] > 0.0 {
            k[a] = p.floor() + 1.0;
            step[a] = 1.0;
        } else {
            k[a] = p.ceil() - 1.0;
            step[a] = -1.0;
        }
        t_next[a] = (k[a] - o[a]) / d[a];
    }
    let mut t = t_enter;
    let mut count = 0u64;
    loop {
        let a = if t_next[0] <= t_next[1] && t_next[0] <= t_next[2] {
            0
        } else if t_next[1] <= t_next[2] {
            1
        } else {
            2
        };
        let tb = t_next[a].min(t_exit);
        if tb > t {
            count += 1;
            let span = CellSpan {
                c: cell_of(n, o, d, 0.5 * (t + tb)),
                ta: t,
                tb,
            };
            if visit(&span).is_break() {
                break;
            }
            t = tb;
        }
        if tb >= t_exit || !tb.is_finite() {
            break;
        }
        k[a] += step[a];
        t_next[a] = (k[a] - o[a]) / d[a];
    }
    count
}

/// The cell containing the point at `t` (clamped to the grid).
#[inline]
fn cell_of(n: [usize; 3], o: [f64; 3], d: [f64; 3], t: f64) -> [usize; 3] {
    std::array::from_fn(|a| {
        if n[a] < 2 {
            return 0; // constant along a single-voxel axis
        }
        let p = o[a] + t * d[a];
        if p > 0.0 {
            (p.floor() as usize).min(n[a] - 2)
        } else {
            0
        }
    })
}

/// The interpolant on a cell span, in its cell.
#[inline]
fn segment<F: Field>(field: &F, ray: &PixelRay, span: &CellSpan) -> Segment {
    let n = field.sizes();
    let (o, d) = (ray.index.o.to_array(), ray.index.d.to_array());
    let mut u0 = [0.0f64; 3];
    let mut du = [0.0f64; 3];
    for a in 0..3 {
        if n[a] < 2 {
            continue; // constant along a single-voxel axis
        }
        u0[a] = o[a] + span.ta * d[a] - span.c[a] as f64;
        du[a] = d[a];
    }
    Segment::from_corners(
        field.cell_corners(span.c),
        u0,
        du,
        span.ta,
        span.tb - span.ta,
    )
}

/// The interpolant's value at the ray's entry (for rays of zero length, which
/// graze an edge or a corner and have no segment).
fn entry_value<F: Field>(field: &F, ray: &PixelRay) -> f64 {
    let (o, d) = (ray.index.o.to_array(), ray.index.d.to_array());
    let span = CellSpan {
        c: cell_of(field.sizes(), o, d, ray.t_enter),
        ta: ray.t_enter,
        tb: ray.t_enter,
    };
    segment(field, ray, &span).eval(0.0)
}

/// Walks the ray's cells, passing over those whose macrocell range `skippable`
/// says cannot matter, and calls `visit` with the interpolant of the others.
/// Returns the cells visited and the cells on the ray.
fn walk_segments<F: Field>(
    field: &F,
    ray: &PixelRay,
    grid: Option<&MacroGrid>,
    skippable: impl Fn([f32; 2]) -> bool,
    mut visit: impl FnMut(&Segment) -> ControlFlow<()>,
) -> Counts {
    let mut taken = 0;
    let nominal = walk(field.sizes(), ray, |span| {
        if let Some(g) = grid {
            if skippable(g.range(g.of_cell(span.c))) {
                return ControlFlow::Continue(());
            }
        }
        taken += 1;
        visit(&segment(field, ray, span))
    });
    Counts { taken, nominal }
}

impl Integrand for Exact {
    fn channels(&self) -> usize {
        match self {
            Exact::Surface { .. } => 4,
            Exact::CuedMip(c) => c.channels(),
            _ => 1,
        }
    }

    fn miss(&self) -> [f32; 4] {
        match self {
            // the line integral of nothing is zero
            Exact::Xray { output, .. } => [finish(0.0, *output, 1.0), 0.0, 0.0, 0.0],
            Exact::Surface { .. } => [0.0; 4],
            Exact::CuedMip(c) => c.miss(),
            _ => [f32::NAN, 0.0, 0.0, 0.0],
        }
    }

    /// Integrates one ray exactly (the march is not used); counts cells.
    fn trace<F: Field>(
        &self,
        field: &F,
        ray: &PixelRay,
        _march: &March,
        grid: Option<&MacroGrid>,
    ) -> ([f32; 4], Counts) {
        match self {
            Exact::Xray { .. } | Exact::Average => {
                let mut sum = CompensatedSum::default();
                // all-zero cells add exact zeros
                let counts = walk_segments(
                    field,
                    ray,
                    grid,
                    |r| r[1] <= 0.0,
                    |s| {
                        sum.add(s.integral());
                        ControlFlow::Continue(())
                    },
                );
                let v = match self {
                    Exact::Xray { output, mu } => finish(sum.total(), *output, *mu),
                    _ => {
                        let len = ray.t_exit - ray.t_enter;
                        (if counts.nominal == 0 || len <= 0.0 {
                            entry_value(field, ray)
                        } else {
                            sum.total() / len
                        }) as f32
                    }
                };
                ([v, 0.0, 0.0, 0.0], counts)
            }
            Exact::Mip | Exact::Minip => {
                let max = matches!(self, Exact::Mip);
                let best = std::cell::Cell::new(None::<f64>);
                // cells that cannot beat the running extremum
                let counts = walk_segments(
                    field,
                    ray,
                    grid,
                    |r| match best.get() {
                        Some(b) if max => f64::from(r[1]) <= b,
                        Some(b) => f64::from(r[0]) >= b,
                        None => false,
                    },
                    |s| {
                        // the interpolant of values in [0, 1] stays in [0, 1]: what
                        // the cubic's evaluation adds beyond is round-off
                        let e = s.extremum(max).clamp(0.0, 1.0);
                        best.set(Some(match best.get() {
                            None => e,
                            Some(b) if max => b.max(e),
                            Some(b) => b.min(e),
                        }));
                        ControlFlow::Continue(())
                    },
                );
                let v = best.get().unwrap_or_else(|| entry_value(field, ray));
                ([v as f32, 0.0, 0.0, 0.0], counts)
            }
            Exact::CuedMip(c) => {
                let (cue, inv_d) = (c.cue, 1.0 / c.diameter);
                // weights are in [1 - cue, 1]: a cell's weighted values are at most
                let bound = |hi: f64| if hi >= 0.0 { hi } else { hi * (1.0 - cue) };
                let best = std::cell::Cell::new(None::<(f64, f64)>);
                // cells come in ray order: one that can only tie with the best comes
                // after it, and a tie keeps the earlier point
                let counts = walk_segments(
                    field,
                    ray,
                    grid,
                    |r| best.get().is_some_and(|(b, _)| bound(f64::from(r[1])) <= b),
                    |s| {
                        let a = 1.0 - cue * (s.t0 - ray.t_depth_ref) * inv_d;
                        let (v, u) = s.weighted_max(a, -cue * inv_d);
                        if best.get().is_none_or(|(b, _)| v > b) {
                            best.set(Some((v, s.t0 + u)));
                        }
                        ControlFlow::Continue(())
                    },
                );
                let (v, t) = best.get().unwrap_or_else(|| {
                    let s = ((ray.t_enter - ray.t_depth_ref) * inv_d).clamp(0.0, 1.0);
                    (entry_value(field, ray) * (1.0 - cue * s), ray.t_enter)
                });
                (c.finish(v as f32, t, ray), counts)
            }
            Exact::Depth { threshold } => {
                let (hit, counts) = find_hit(field, ray, grid, *threshold);
                ([Hit::depth(hit, ray), 0.0, 0.0, 0.0], counts)
            }
            Exact::Surface { iso, shader } => {
                let (hit, counts) = find_hit(field, ray, grid, *iso);
                (Hit::shade(hit, field, shader, ray), counts)
            }
        }
    }
}

/// The hit of `level` along the interpolant: where the search starts ([`Entry`]),
/// then the first crossing.
fn find_hit<F: Field>(
    field: &F,
    ray: &PixelRay,
    grid: Option<&MacroGrid>,
    level: f32,
) -> (Option<Hit>, Counts) {
    Entry::search(field, ray, level, 1, |rising| {
        first_crossing(field, ray, grid, level, rising)
    })
}

/// The first `t` where the interpolant reaches `level` (falls to it, when not
/// `rising`), passing over the cells that cannot.
fn first_crossing<F: Field>(
    field: &F,
    ray: &PixelRay,
    grid: Option<&MacroGrid>,
    level: f32,
    rising: bool,
) -> (Option<f64>, Counts) {
    let level_f32 = level;
    let level = f64::from(level);
    let mut hit = None;
    let counts = walk_segments(
        field,
        ray,
        grid,
        |r| {
            if rising {
                r[1] < level_f32
            } else {
                r[0] > level_f32
            }
        },
        |s| {
            // falling to the level is rising to its negative on the negated cubic
            let reach = if rising {
                s.first_reach(level)
            } else {
                Segment {
                    c: s.c.map(|c| -c),
                    ..*s
                }
                .first_reach(-level)
            };
            match reach {
                Some(x) => {
                    hit = Some(s.t0 + x);
                    ControlFlow::Break(())
                }
                None => ControlFlow::Continue(()),
            }
        },
    );
    if counts.nominal == 0 && ray.t_exit >= ray.t_enter {
        let f = entry_value(field, ray);
        if (rising && f >= level) || (!rising && f <= level) {
            hit = Some(ray.t_enter);
        }
    }
    (hit, counts)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seg(c: [f64; 4], len: f64) -> Segment {
        Segment { c, t0: 0.0, len }
    }

    #[test]
    fn corners_give_the_trilinear_polynomial() {
        // f = xyz along u(s) = (s, s, s): f = s^3
        let mut v = [0.0f32; 8];
        v[7] = 1.0;
        let s = Segment::from_corners(v, [0.0; 3], [1.0; 3], 0.0, 1.0);
        assert_eq!(s.c, [0.0, 0.0, 0.0, 1.0]);
        assert_eq!(s.integral(), 0.25);
        // f = x along u = (0.25 + 0.5 s, ., .): 0.25 + 0.5 s
        let v = [0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0];
        let s = Segment::from_corners(v, [0.25, 0.3, 0.9], [0.5, -0.2, 0.1], 0.0, 1.0);
        assert_eq!(s.c, [0.25, 0.5, 0.0, 0.0]);
    }

    #[test]
    fn extrema_at_critical_points() {
        // s (1 - s) on [0, 1]: max 1/4 at 1/2, min 0 at the ends
        let s = seg([0.0, 1.0, -1.0, 0.0], 1.0);
        assert_eq!(s.extremum(true), 0.25);
        assert_eq!(s.extremum(false), 0.0);
        // (s - 1)^3 + 0 has a double critical point at 1: monotone
        let s = seg([-1.0, 3.0, -3.0, 1.0], 2.0);
        assert_eq!(s.extremum(true), 1.0);
        assert_eq!(s.extremum(false), -1.0);
    }

    #[test]
    fn tangent_and_double_roots() {
        // s (1 - s) touches 1/4 at s = 1/2 only (a double root of f - 1/4)
        let s = seg([0.0, 1.0, -1.0, 0.0], 1.0);
        assert_eq!(s.first_reach(0.25), Some(0.5));
        assert_eq!(s.first_reach(0.25 + 1e-9), None);
        // (s - 1/2)^2 reaches 0 at its double root
        let s = seg([0.25, -1.0, 1.0, 0.0], 1.0);
        assert_eq!(s.first_reach(0.1), Some(0.0));
        // a simple root, refined to round-off: s^3 = 1/8 at s = 1/2
        let s = seg([0.0, 0.0, 0.0, 1.0], 1.0);
        let r = s.first_reach(0.125).unwrap();
        assert!((r - 0.5).abs() < 1e-15, "{r}");
    }

    #[test]
    fn compensated_sum_keeps_small_terms() {
        let mut c = CompensatedSum::default();
        c.add(1e16);
        for _ in 0..1000 {
            c.add(1.0);
        }
        c.add(-1e16);
        assert_eq!(c.total(), 1000.0);
    }
}
