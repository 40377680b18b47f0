//! Reconstruction of a continuous field from voxels, and its gradient.
//!
//! Positions are in *index space* (voxel `(i, j, k)` at `(i, j, k)`; see
//! `volume::geometry`). Each voxel is read in its native type and mapped to a
//! normalised value in [0, 1] by the value window ([`Normalize`]) before it is
//! interpolated, so NaN or infinite voxels never reach an image (NaN and -inf count
//! as 0, +inf as 1) and every interpolant with non-negative weights stays in [0, 1].
//!
//! Filters (REFERENCE.md "Reconstruction"): `nearest`, `trilinear` (8 voxels),
//! `bspline` (the smoothing cubic B-spline on the voxels themselves, 64 voxels) and
//! `cubic` (the interpolating cubic B-spline: the same kernel applied to prefiltered
//! coefficients, so the field passes through the voxel values). Gradients
//! (REFERENCE.md "Gradients"): central differences or 3D Sobel on the voxel grid,
//! trilinearly interpolated between the 8 voxels around the position, then mapped to
//! world units with the inverse-transpose of the grid's axis matrix (so anisotropic
//! and sheared grids get each axis' own spacing).

mod filter;

pub use filter::{gradient_volume, prefilter_cubic};

use glam::{DMat3, DVec3};

use crate::volume::Voxel;

/// Reconstruction filter.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Interpolation {
    /// The nearest voxel.
    Nearest,
    /// Trilinear interpolation of the 8 surrounding voxels.
    Trilinear,
    /// Cubic B-spline on the raw voxels (smooths; does not pass through them).
    BSpline,
    /// Interpolating cubic B-spline (prefiltered coefficients).
    Cubic,
}

impl Interpolation {
    /// The scene-file name.
    pub fn name(self) -> &'static str {
        match self {
            Interpolation::Nearest => "nearest",
            Interpolation::Trilinear => "trilinear",
            Interpolation::BSpline => "bspline",
            Interpolation::Cubic => "cubic",
        }
    }
}

/// Gradient estimator on the voxel grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GradientMethod {
    /// `(f(x+1) - f(x-1)) / 2h` per axis (one-sided at the border).
    Central,
    /// Central difference along the axis, `[1, 2, 1]/4` smoothing along the other two.
    Sobel,
    /// The exact gradient of the reconstruction itself: the derivative of the cubic
    /// B-spline (of the prefiltered coefficients for `cubic`, of the voxels for
    /// `bspline`). Only for those two interpolations.
    Analytic,
}

impl GradientMethod {
    /// The scene-file name.
    pub fn name(self) -> &'static str {
        match self {
            GradientMethod::Central => "central",
            GradientMethod::Sobel => "sobel",
            GradientMethod::Analytic => "analytic",
        }
    }
}

/// Maps a stored value to [0, 1]: `(v - lo) / (hi - lo)`, clamped; NaN maps to 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Normalize {
    lo: f64,
    scale: f64,
}

impl Normalize {
    /// The map for the value window `[lo, hi]` (`lo < hi`, both finite).
    pub fn new(lo: f64, hi: f64) -> Normalize {
        debug_assert!(lo < hi, "window must be increasing");
        Normalize {
            lo,
            scale: 1.0 / (hi - lo),
        }
    }

    /// The normalised value of one voxel.
    #[inline(always)]
    pub fn apply(&self, v: f64) -> f32 {
        let x = (v - self.lo) * self.scale;
        // NaN fails both comparisons and maps to 0; +inf maps to 1.
        if x >= 1.0 {
            1.0
        } else if x > 0.0 {
            x as f32
        } else {
            0.0
        }
    }
}

/// A continuous scalar field in index space: what integrators sample.
pub trait Field: Sync {
    /// Grid size (index space spans `[0, n-1]` on each axis).
    fn sizes(&self) -> [usize; 3];
    /// The reconstructed normalised value at `p` (clamped to the grid).
    fn value(&self, p: DVec3) -> f32;
    /// The gradient of the normalised value at `p`, in world units
    /// (normalised value per world unit).
    fn gradient(&self, p: DVec3) -> DVec3;
    /// The normalised voxels at the eight corners of cell `c` (the cell from voxel
    /// `c` to `c + 1` on each axis; an axis of a single voxel repeats voxel 0),
    /// corner `(a, b, c)` at index `a + 2 b + 4 c`. The exact integrators treat the
    /// trilinear interpolant of these values as a polynomial along the ray.
    fn cell_corners(&self, c: [usize; 3]) -> [f32; 8];
}

/// Native-typed voxels plus everything needed to reconstruct them.
pub struct Sampler<'a, T: Voxel> {
    data: &'a [T],
    /// Normalised value of every possible voxel value, for 8- and 16-bit types.
    lut: Vec<f32>,
    n: [usize; 3],
    sx: usize,
    sxy: usize,
    norm: Normalize,
    interpolation: Interpolation,
    /// Prefiltered coefficients (normalised), for `Interpolation::Cubic`.
    coefficients: Option<&'a [f32]>,
    gradient: GradientMethod,
    /// Precomputed index-space gradients, when the plan made them.
    gradients: Option<&'a [[f32; 3]]>,
    world_grad_from_index_grad: DMat3,
}

impl<'a, T: Voxel> Sampler<'a, T> {
    /// A sampler over `data` (x fastest, `n` voxels per axis).
    ///
    /// `index_from_world` is the inverse of the grid's axis matrix (used to express
    /// gradients in world units). `coefficients` must be given for
    /// `Interpolation::Cubic` (see [`prefilter_cubic`]); `gradients`, when given,
    /// replaces the on-the-fly gradient (see [`gradient_volume`]).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        data: &'a [T],
        n: [usize; 3],
        norm: Normalize,
        interpolation: Interpolation,
        coefficients: Option<&'a [f32]>,
        gradient: GradientMethod,
        gradients: Option<&'a [[f32; 3]]>,
        index_from_world: DMat3,
    ) -> Sampler<'a, T> {
        let count = n[0] * n[1] * n[2];
        assert_eq!(data.len(), count, "data length matches the sizes");
        assert!(
            interpolation != Interpolation::Cubic || coefficients.is_some_and(|c| c.len() == count),
            "cubic interpolation needs prefiltered coefficients of the same size"
        );
        assert!(
            gradients.is_none_or(|g| g.len() == count),
            "gradient volume matches the sizes"
        );
        let lut = (0..T::LUT_SIZE)
            .map(|i| norm.apply(T::lut_value(i)))
            .collect();
        Sampler {
            data,
            lut,
            n,
            sx: n[0],
            sxy: n[0] * n[1],
            norm,
            interpolation,
            coefficients,
            gradient,
            gradients,
            world_grad_from_index_grad: index_from_world.transpose(),
        }
    }

    /// Normalised voxel at an in-range index.
    #[inline(always)]
    fn voxel(&self, i: usize, j: usize, k: usize) -> f32 {
        self.voxel_at(i + self.sx * j + self.sxy * k)
    }

    /// Normalised voxel at a flat index (a table load for 8- and 16-bit data).
    #[inline(always)]
    fn voxel_at(&self, idx: usize) -> f32 {
        let v = self.data[idx];
        if T::LUT_SIZE > 0 {
            self.lut[v.lut_index()]
        } else {
            self.norm.apply(v.to_f64())
        }
    }

    /// Normalised voxel with indices clamped to the grid.
    #[inline(always)]
    fn voxel_clamped(&self, i: isize, j: isize, k: isize) -> f32 {
        self.voxel(
            clamp_index(i, self.n[0]),
            clamp_index(j, self.n[1]),
            clamp_index(k, self.n[2]),
        )
    }

    fn nearest(&self, p: DVec3) -> f32 {
        let idx = |x: f64, n: usize| ((x + 0.5).max(0.0) as usize).min(n - 1);
        self.voxel(
            idx(p.x, self.n[0]),
            idx(p.y, self.n[1]),
            idx(p.z, self.n[2]),
        )
    }

    fn trilinear(&self, p: DVec3) -> f32 {
        let (i0, i1, fx) = cell(p.x, self.n[0]);
        let (j0, j1, fy) = cell(p.y, self.n[1]);
        let (k0, k1, fz) = cell(p.z, self.n[2]);
        // one base index and the offsets to the other seven corners
        let base = i0 + self.sx * j0 + self.sxy * k0;
        let (dx, dy, dz) = (i1 - i0, self.sx * (j1 - j0), self.sxy * (k1 - k0));
        let c = |o: usize| self.voxel_at(base + o);
        let x00 = lerp(c(0), c(dx), fx);
        let x10 = lerp(c(dy), c(dy + dx), fx);
        let x01 = lerp(c(dz), c(dz + dx), fx);
        let x11 = lerp(c(dz + dy), c(dz + dy + dx), fx);
        lerp(lerp(x00, x10, fy), lerp(x01, x11, fy), fz)
    }

    /// Cubic B-spline over `get` (mirror boundary, matching the prefilter).
    fn bspline_with(&self, p: DVec3, get: impl Fn(usize, usize, usize) -> f32) -> f32 {
        let (ix, wx) = bspline_weights(p.x, self.n[0]);
        let (iy, wy) = bspline_weights(p.y, self.n[1]);
        let (iz, wz) = bspline_weights(p.z, self.n[2]);
        let mut sum = 0.0f64;
        for c in 0..4 {
            let mut sy = 0.0f64;
            for b in 0..4 {
                let mut sx = 0.0f64;
                for a in 0..4 {
                    sx += wx[a] * get(ix[a], iy[b], iz[c]) as f64;
                }
                sy += wy[b] * sx;
            }
            sum += wz[c] * sy;
        }
        sum as f32
    }

    /// Index-space gradient of the cubic B-spline over `get` (the derivative of the
    /// same spline [`Sampler::bspline_with`] evaluates, mirror boundary).
    fn bspline_gradient_with(&self, p: DVec3, get: impl Fn(usize, usize, usize) -> f32) -> DVec3 {
        let (ix, wx, dx) = bspline_weights_and_derivatives(p.x, self.n[0]);
        let (iy, wy, dy) = bspline_weights_and_derivatives(p.y, self.n[1]);
        let (iz, wz, dz) = bspline_weights_and_derivatives(p.z, self.n[2]);
        let mut g = DVec3::ZERO;
        for c in 0..4 {
            let (mut gx, mut gy, mut gv) = (0.0f64, 0.0f64, 0.0f64);
            for b in 0..4 {
                let (mut sx, mut sv) = (0.0f64, 0.0f64);
                for a in 0..4 {
                    let v = get(ix[a], iy[b], iz[c]) as f64;
                    sx += dx[a] * v;
                    sv += wx[a] * v;
                }
                gx += wy[b] * sx;
                gy += dy[b] * sv;
                gv += wy[b] * sv;
            }
            g += DVec3::new(wz[c] * gx, wz[c] * gy, dz[c] * gv);
        }
        g
    }

    /// Index-space gradient at voxel (i, j, k) by the configured estimator.
    fn voxel_gradient(&self, i: usize, j: usize, k: usize) -> [f32; 3] {
        if let Some(g) = self.gradients {
            return g[i + self.sx * j + self.sxy * k];
        }
        filter::grid_gradient(self.gradient, self.n, [i, j, k], |a, b, c| {
            self.voxel_clamped(a, b, c)
        })
    }
}

impl<T: Voxel> Field for Sampler<'_, T> {
    fn sizes(&self) -> [usize; 3] {
        self.n
    }

    #[inline]
    fn value(&self, p: DVec3) -> f32 {
        let v = match self.interpolation {
            Interpolation::Nearest => self.nearest(p),
            Interpolation::Trilinear => self.trilinear(p),
            Interpolation::BSpline => self.bspline_with(p, |i, j, k| self.voxel(i, j, k)),
            Interpolation::Cubic => {
                let c = self.coefficients.expect("checked in Sampler::new");
                self.bspline_with(p, |i, j, k| c[i + self.sx * j + self.sxy * k])
            }
        };
        // The interpolating spline may overshoot the voxel values slightly.
        v.clamp(0.0, 1.0)
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        if self.gradient == GradientMethod::Analytic {
            let g = match self.interpolation {
                Interpolation::Cubic => {
                    let c = self.coefficients.expect("checked in Sampler::new");
                    Some(self.bspline_gradient_with(p, |i, j, k| c[i + self.sx * j + self.sxy * k]))
                }
                Interpolation::BSpline => {
                    Some(self.bspline_gradient_with(p, |i, j, k| self.voxel(i, j, k)))
                }
                // the scene rejects this combination; grid differences below
                Interpolation::Nearest | Interpolation::Trilinear => None,
            };
            if let Some(g) = g {
                return self.world_grad_from_index_grad * g;
            }
        }
        let (i0, i1, fx) = cell(p.x, self.n[0]);
        let (j0, j1, fy) = cell(p.y, self.n[1]);
        let (k0, k1, fz) = cell(p.z, self.n[2]);
        let mut g = [0.0f64; 3];
        for (k, wk) in [(k0, 1.0 - fz), (k1, fz)] {
            for (j, wj) in [(j0, 1.0 - fy), (j1, fy)] {
                for (i, wi) in [(i0, 1.0 - fx), (i1, fx)] {
                    let w = (wi * wj * wk) as f64;
                    if w == 0.0 {
                        continue;
                    }
                    let v = self.voxel_gradient(i, j, k);
                    for a in 0..3 {
                        g[a] += w * v[a] as f64;
                    }
                }
            }
        }
        self.world_grad_from_index_grad * DVec3::from_array(g)
    }

    #[inline]
    fn cell_corners(&self, [i, j, k]: [usize; 3]) -> [f32; 8] {
        let step = |x: usize, n: usize| usize::from(x + 1 < n);
        let base = i + self.sx * j + self.sxy * k;
        let (dx, dy, dz) = (
            step(i, self.n[0]),
            self.sx * step(j, self.n[1]),
            self.sxy * step(k, self.n[2]),
        );
        let c = |o: usize| self.voxel_at(base + o);
        [
            c(0),
            c(dx),
            c(dy),
            c(dy + dx),
            c(dz),
            c(dz + dx),
            c(dz + dy),
            c(dz + dy + dx),
        ]
    }
}

#[inline(always)]
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

#[inline(always)]
fn clamp_index(i: isize, n: usize) -> usize {
    i.clamp(0, n as isize - 1) as usize
}

/// The cell `[i0, i1]` containing coordinate `x` on an axis of `n` voxels, and the
/// fraction of the way from `i0` to `i1` (positions outside the grid clamp to it).
#[inline(always)]
fn cell(x: f64, n: usize) -> (usize, usize, f32) {
    if n < 2 {
        return (0, 0, 0.0);
    }
    let max = (n - 1) as f64;
    // NaN fails `x > 0` and maps to 0; for x >= 0, truncation is floor (and an
    // inlined conversion, where `floor` is a library call on baseline x86-64)
    let x = if x > 0.0 { x.min(max) } else { 0.0 };
    let i0 = (x as usize).min(n - 2);
    (i0, i0 + 1, (x - i0 as f64) as f32)
}

/// Mirror-boundary index (…, 2, 1, 0, 1, 2, …, n-1, n-2, …).
#[inline(always)]
fn mirror(i: isize, n: usize) -> usize {
    if n < 2 {
        return 0;
    }
    let period = 2 * (n as isize - 1);
    let m = i.rem_euclid(period);
    (if m >= n as isize { period - m } else { m }) as usize
}

/// The four indices, cubic B-spline weights and their derivatives for coordinate
/// `x`; outside the grid the position is clamped, so the derivative there is that
/// of the boundary point.
#[inline(always)]
fn bspline_weights_and_derivatives(x: f64, n: usize) -> ([usize; 4], [f64; 4], [f64; 4]) {
    let (idx, w) = bspline_weights(x, n);
    let max = (n.max(1) - 1) as f64;
    let x = if x > 0.0 { x.min(max) } else { 0.0 };
    let t = x - x as usize as f64;
    let t2 = t * t;
    let d = [
        -0.5 * (1.0 - t) * (1.0 - t),
        1.5 * t2 - 2.0 * t,
        -1.5 * t2 + t + 0.5,
        0.5 * t2,
    ];
    (idx, w, d)
}

/// The four indices and cubic B-spline weights for coordinate `x`.
#[inline(always)]
fn bspline_weights(x: f64, n: usize) -> ([usize; 4], [f64; 4]) {
    let max = (n.max(1) - 1) as f64;
    let x = if x > 0.0 { x.min(max) } else { 0.0 };
    let i = x as usize as f64;
    let t = x - i;
    let i = i as isize;
    let t2 = t * t;
    let t3 = t2 * t;
    let w = [
        (1.0 - t).powi(3) / 6.0,
        (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0,
        (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
        t3 / 6.0,
    ];
    (
        [
            mirror(i - 1, n),
            mirror(i, n),
            mirror(i + 1, n),
            mirror(i + 2, n),
        ],
        w,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn linear_field(n: [usize; 3]) -> Vec<f32> {
        let mut v = Vec::new();
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    v.push(0.01 * i as f32 + 0.02 * j as f32 + 0.03 * k as f32);
                }
            }
        }
        v
    }

    fn sampler<'a>(
        v: &'a [f32],
        n: [usize; 3],
        interp: Interpolation,
        c: Option<&'a [f32]>,
    ) -> Sampler<'a, f32> {
        Sampler::new(
            v,
            n,
            Normalize::new(0.0, 1.0),
            interp,
            c,
            GradientMethod::Central,
            None,
            DMat3::IDENTITY,
        )
    }

    #[test]
    fn trilinear_is_exact_on_linear_fields() {
        let n = [5, 6, 7];
        let v = linear_field(n);
        let s = sampler(&v, n, Interpolation::Trilinear, None);
        for p in [
            DVec3::new(1.25, 2.5, 3.75),
            DVec3::new(4.0, 5.0, 6.0),
            DVec3::new(0.0, 0.1, 5.9),
        ] {
            let want = 0.01 * p.x + 0.02 * p.y + 0.03 * p.z;
            assert!((s.value(p) as f64 - want).abs() < 1e-6, "{p}");
            let g = s.gradient(p);
            assert!((g - DVec3::new(0.01, 0.02, 0.03)).length() < 1e-6, "{g}");
        }
    }

    #[test]
    fn cubic_interpolates_and_reproduces_linear() {
        let n = [24, 23, 22];
        // values up to 1.3: normalise by [0, 2] so nothing is clamped
        let v: Vec<f32> = linear_field(n);
        let norm = Normalize::new(0.0, 2.0);
        let c = prefilter_cubic(&v, n, norm);
        let s = Sampler::new(
            &v,
            n,
            norm,
            Interpolation::Cubic,
            Some(&c),
            GradientMethod::Central,
            None,
            DMat3::IDENTITY,
        );
        // passes through the voxel values, boundaries included
        for (i, j, k) in [(0, 0, 0), (3, 2, 1), (23, 22, 21)] {
            let want = v[i + 24 * (j + 23 * k)] / 2.0;
            let got = s.value(DVec3::new(i as f64, j as f64, k as f64));
            assert!((got - want).abs() < 1e-5, "({i},{j},{k}): {got} vs {want}");
        }
        // A cubic spline reproduces linear functions; the mirror boundary bends it
        // near the faces, by a factor 0.268 per voxel (the prefilter's pole), so
        // ten voxels in the deviation is below 1e-6 of the slope.
        let p = DVec3::new(11.3, 10.7, 10.2);
        let want = (0.01 * p.x + 0.02 * p.y + 0.03 * p.z) / 2.0;
        assert!((s.value(p) as f64 - want).abs() < 1e-5);
    }

    #[test]
    fn analytic_gradient_is_the_derivative_of_the_spline() {
        // a smooth non-linear field; the analytic gradient of the reconstruction must
        // match central differences of the reconstruction itself (step 1e-4,
        // truncation error ~1e-8 times the third derivative)
        let n = [9, 8, 7];
        let mut v = Vec::new();
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    let (x, y, z) = (i as f32, j as f32, k as f32);
                    v.push(0.5 + 0.3 * (0.7 * x).sin() * (0.4 * y).cos() + 0.01 * z * z);
                }
            }
        }
        let norm = Normalize::new(-1.0, 2.0);
        let c = prefilter_cubic(&v, n, norm);
        let axes = DMat3::from_diagonal(DVec3::new(2.0, 1.0, 0.5));
        for interp in [Interpolation::Cubic, Interpolation::BSpline] {
            let s = Sampler::new(
                &v,
                n,
                norm,
                interp,
                Some(&c),
                GradientMethod::Analytic,
                None,
                axes.inverse(),
            );
            for p in [DVec3::new(3.3, 2.7, 4.1), DVec3::new(1.05, 5.5, 2.9)] {
                let h = 1e-4;
                let fd = DVec3::new(
                    (s.value(p + DVec3::X * h) - s.value(p - DVec3::X * h)) as f64 / (2.0 * h),
                    (s.value(p + DVec3::Y * h) - s.value(p - DVec3::Y * h)) as f64 / (2.0 * h),
                    (s.value(p + DVec3::Z * h) - s.value(p - DVec3::Z * h)) as f64 / (2.0 * h),
                );
                // world gradient = inverse-transpose of the axes times the index gradient
                let want = axes.inverse().transpose() * fd;
                let got = s.gradient(p);
                // f32 values differenced over 2e-4: about 6e-8 / 2e-4 = 3e-4 of noise
                assert!(
                    (got - want).length() < 2e-3,
                    "{interp:?} at {p}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn non_finite_voxels_do_not_poison() {
        let mut v = vec![0.5f32; 8];
        v[0] = f32::NAN;
        v[1] = f32::INFINITY;
        v[2] = f32::NEG_INFINITY;
        let s = sampler(&v, [2, 2, 2], Interpolation::Trilinear, None);
        let x = s.value(DVec3::splat(0.5));
        assert!(x.is_finite() && (0.0..=1.0).contains(&x));
        assert!(s.gradient(DVec3::splat(0.5)).is_finite());
    }

    #[test]
    fn anisotropic_gradient_uses_spacing() {
        // f = 0.01 i on a grid with spacing 2 along x: df/dx = 0.005 per world unit
        let n = [4, 2, 2];
        let v: Vec<f32> = (0..16).map(|idx| 0.01 * (idx % 4) as f32).collect();
        let m = DMat3::from_diagonal(DVec3::new(2.0, 1.0, 1.0));
        let s = Sampler::new(
            &v,
            n,
            Normalize::new(0.0, 1.0),
            Interpolation::Trilinear,
            None,
            GradientMethod::Sobel,
            None,
            m.inverse(),
        );
        let g = s.gradient(DVec3::new(1.5, 0.5, 0.5));
        assert!((g.x - 0.005).abs() < 1e-7 && g.y.abs() < 1e-7, "{g}");
    }

    #[test]
    fn normalize_handles_specials() {
        let n = Normalize::new(-1.0, 1.0);
        assert_eq!(n.apply(f64::NAN), 0.0);
        assert_eq!(n.apply(f64::INFINITY), 1.0);
        assert_eq!(n.apply(f64::NEG_INFINITY), 0.0);
        assert_eq!(n.apply(0.0), 0.5);
    }
}
