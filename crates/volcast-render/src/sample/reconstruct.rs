//! The reconstruction filters as concrete [`Field`]s, one type per filter, so the
//! renderer's inner loop is compiled once per (voxel type, filter) with no match per
//! sample; and [`Sampler`], which picks the filter at run time (for tools and tests).

use glam::{DMat3, DVec3};

use super::grid::{normalisation_table, Gradients, Grid};
use super::{CellCache, Field, GradientMethod, Interpolation, Normalize};
use crate::volume::{Voxel, Voxels};

/// The nearest voxel.
#[derive(Clone, Copy, Debug)]
pub struct Nearest<'a, T: Voxel> {
    /// The voxels.
    pub grid: Grid<'a, T>,
    /// Gradient source (for shading).
    pub gradients: Gradients<'a>,
}

/// Trilinear interpolation of the 8 voxels around the position.
#[derive(Clone, Copy, Debug)]
pub struct Trilinear<'a, T: Voxel> {
    /// The voxels.
    pub grid: Grid<'a, T>,
    /// Gradient source (for shading).
    pub gradients: Gradients<'a>,
}

/// The smoothing cubic B-spline on the voxels themselves (64 voxels).
#[derive(Clone, Copy, Debug)]
pub struct BSpline<'a, T: Voxel> {
    /// The voxels.
    pub grid: Grid<'a, T>,
    /// Gradient source (for shading).
    pub gradients: Gradients<'a>,
}

/// The interpolating cubic B-spline: the B-spline over prefiltered coefficients.
/// Its values do not depend on the voxels' type (the coefficients are `f32`), so it
/// is one type for all of them; grid gradients and cell corners, read once per hit
/// at most, come from the voxels through `voxels`.
pub struct Cubic<'a> {
    /// Prefiltered coefficients of the normalised voxels ([`super::prefilter_cubic`]),
    /// one per voxel (checked in [`Cubic::new`]: the values read them unchecked).
    coefficients: &'a [f32],
    /// Voxels per axis.
    n: [usize; 3],
    /// How gradients are estimated (`Analytic`: the spline's own derivative).
    method: GradientMethod,
    /// World gradient = this matrix times the index-space gradient.
    world_from_index: DMat3,
    /// The voxels, for grid gradients and cell corners.
    voxels: Box<dyn Field + 'a>,
}

impl<'a> Cubic<'a> {
    /// The spline over `coefficients` (prefiltered, one per voxel of a grid of `n`
    /// voxels), with gradients by `method` taken to world space by
    /// `world_from_index`, and grid gradients and cell corners from `voxels`.
    ///
    /// # Panics
    /// If `coefficients` is empty or does not hold one value per voxel.
    pub fn new(
        coefficients: &'a [f32],
        n: [usize; 3],
        method: GradientMethod,
        world_from_index: DMat3,
        voxels: Box<dyn Field + 'a>,
    ) -> Cubic<'a> {
        let count = n[0].checked_mul(n[1]).and_then(|m| m.checked_mul(n[2]));
        assert!(
            !coefficients.is_empty() && count == Some(coefficients.len()),
            "{} cubic coefficients for a grid of {n:?} voxels",
            coefficients.len()
        );
        Cubic {
            coefficients,
            n,
            method,
            world_from_index,
            voxels,
        }
    }
}

impl<T: Voxel> Field for Nearest<'_, T> {
    fn sizes(&self) -> [usize; 3] {
        self.grid.n
    }

    #[inline(always)]
    fn value(&self, p: DVec3) -> f32 {
        let n = self.grid.n;
        let idx = |x: f64, n: usize| ((x + 0.5).max(0.0) as usize).min(n - 1);
        self.grid
            .voxel(idx(p.x, n[0]), idx(p.y, n[1]), idx(p.z, n[2]))
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        self.gradients.interpolated(&self.grid, p)
    }

    fn cell_corners(&self, c: [usize; 3]) -> [f32; 8] {
        self.grid.cell_corners(c)
    }
}

impl<T: Voxel> Field for Trilinear<'_, T> {
    fn sizes(&self) -> [usize; 3] {
        self.grid.n
    }

    #[inline(always)]
    fn value(&self, p: DVec3) -> f32 {
        self.grid.trilinear(p.to_array())
    }

    #[inline(always)]
    fn value_cached(&self, p: DVec3, cache: &mut CellCache) -> f32 {
        self.grid.trilinear_cached(p.to_array(), cache)
    }

    #[inline(always)]
    fn values_along(&self, o: DVec3, d: DVec3, ts: &[f64], out: &mut [f32], cache: &mut CellCache) {
        self.grid
            .trilinear_along::<false>(o.to_array(), d.to_array(), ts, out, cache)
    }

    #[inline(always)]
    fn lanes(&self) -> usize {
        self.grid.lanes()
    }

    #[inline(always)]
    fn raw_map(&self) -> Option<Normalize> {
        // (a constant `None` for the types that are never read as raw bytes)
        if const { matches!(T::TYPE, crate::volume::ScalarType::Uint8) } {
            self.grid.raw_map()
        } else {
            None
        }
    }

    #[inline(always)]
    fn raw_values_along(
        &self,
        o: DVec3,
        d: DVec3,
        ts: &[f64],
        out: &mut [f32],
        cache: &mut CellCache,
    ) {
        // (only 8-bit grids read raw bytes: the other types do not compile the path)
        if const { matches!(T::TYPE, crate::volume::ScalarType::Uint8) } {
            self.grid
                .trilinear_along::<true>(o.to_array(), d.to_array(), ts, out, cache)
        } else {
            self.values_along(o, d, ts, out, cache)
        }
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        self.gradients.interpolated(&self.grid, p)
    }

    #[inline]
    fn cell_corners(&self, c: [usize; 3]) -> [f32; 8] {
        self.grid.cell_corners(c)
    }
}

impl<T: Voxel> Field for BSpline<'_, T> {
    fn sizes(&self) -> [usize; 3] {
        self.grid.n
    }

    #[inline]
    fn value(&self, p: DVec3) -> f32 {
        let g = &self.grid;
        bspline(g.n, p, |i, j, k| g.voxel(i, j, k))
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        let g = &self.grid;
        if self.gradients.method == GradientMethod::Analytic {
            self.gradients.world_from_index * bspline_gradient(g.n, p, |i, j, k| g.voxel(i, j, k))
        } else {
            self.gradients.interpolated(g, p)
        }
    }

    fn cell_corners(&self, c: [usize; 3]) -> [f32; 8] {
        self.grid.cell_corners(c)
    }
}

impl Field for Cubic<'_> {
    fn sizes(&self) -> [usize; 3] {
        self.n
    }

    #[inline]
    fn value(&self, p: DVec3) -> f32 {
        let (c, n) = (self.coefficients, self.n);
        let (sx, sxy) = (n[0], n[0] * n[1]);
        let (ix, wx) = bspline_weights(p.x, n[0]);
        if ix[1] == ix[0] + 1 && ix[2] == ix[0] + 2 && ix[3] == ix[0] + 3 {
            // the four x indices consecutive (inside the grid): each row's four
            // coefficients read as one slice, their products formed two at a time
            // and summed in the same order from zero (the bits of the reads one by
            // one)
            return bspline_rows(n, p, |j, k| {
                let at = ix[0] + sx * j + sxy * k;
                let v: &[f32; 4] = c[at..at + 4].try_into().expect("four coefficients");
                let mut row = 0.0f64;
                for q in products(v, &wx) {
                    row += q;
                }
                row
            });
        }
        // SAFETY: `Cubic::new` checked that `c` holds one value per voxel of a
        // grid with at least one voxel per axis, and `bspline` asks only for
        // indices from `mirror`, which are below their axis' size there: `i + sx j
        // + sxy k <= sxy n[2] - 1 < c.len()`
        bspline(n, p, |i, j, k| unsafe {
            *c.get_unchecked(i + sx * j + sxy * k)
        })
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        if self.method == GradientMethod::Analytic {
            let (c, sx, sxy) = (self.coefficients, self.n[0], self.n[0] * self.n[1]);
            self.world_from_index * bspline_gradient(self.n, p, |i, j, k| c[i + sx * j + sxy * k])
        } else {
            self.voxels.gradient(p)
        }
    }

    fn cell_corners(&self, c: [usize; 3]) -> [f32; 8] {
        self.voxels.cell_corners(c)
    }
}

impl<F: Field + ?Sized> Field for Box<F> {
    fn sizes(&self) -> [usize; 3] {
        (**self).sizes()
    }
    #[inline(always)]
    fn value(&self, p: DVec3) -> f32 {
        (**self).value(p)
    }
    #[inline(always)]
    fn value_cached(&self, p: DVec3, cache: &mut CellCache) -> f32 {
        (**self).value_cached(p, cache)
    }
    fn gradient(&self, p: DVec3) -> DVec3 {
        (**self).gradient(p)
    }
    #[inline(always)]
    fn cell_corners(&self, c: [usize; 3]) -> [f32; 8] {
        (**self).cell_corners(c)
    }
}

/// A reconstruction chosen at run time: owns its normalisation table and
/// dispatches on the filter at every call. For tools and tests; the renderer uses
/// the concrete filters.
pub struct Sampler<'a, T: Voxel> {
    voxels: Voxels<'a, T>,
    lut: Vec<f32>,
    n: [usize; 3],
    norm: Normalize,
    interpolation: Interpolation,
    coefficients: Option<&'a [f32]>,
    method: GradientMethod,
    gradients: Option<&'a [[f32; 3]]>,
    index_from_world: DMat3,
}

impl<'a, T: Voxel> Sampler<'a, T> {
    /// A sampler over `data` (x fastest, `n` voxels per axis).
    ///
    /// `index_from_world` is the inverse of the grid's axis matrix (used to express
    /// gradients in world units). `coefficients` must be given for
    /// `Interpolation::Cubic` (see [`super::prefilter_cubic`]); `gradients`, when given,
    /// replaces the on-the-fly gradient (see [`super::gradient_volume`]).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        data: impl Into<Voxels<'a, T>>,
        n: [usize; 3],
        norm: Normalize,
        interpolation: Interpolation,
        coefficients: Option<&'a [f32]>,
        gradient: GradientMethod,
        gradients: Option<&'a [[f32; 3]]>,
        index_from_world: DMat3,
    ) -> Sampler<'a, T> {
        let voxels = data.into();
        let count = n[0] * n[1] * n[2];
        assert_eq!(voxels.len(), count, "data length matches the sizes");
        assert!(
            interpolation != Interpolation::Cubic || coefficients.is_some_and(|c| c.len() == count),
            "cubic interpolation needs prefiltered coefficients of the same size"
        );
        assert!(
            gradients.is_none_or(|g| g.len() == count),
            "gradient volume matches the sizes"
        );
        Sampler {
            voxels,
            lut: normalisation_table::<T>(norm),
            n,
            norm,
            interpolation,
            coefficients,
            method: gradient,
            gradients,
            index_from_world,
        }
    }

    fn grid(&self) -> Grid<'_, T> {
        Grid::new(self.voxels, self.n, self.norm, &self.lut)
    }

    fn grads(&self) -> Gradients<'a> {
        Gradients::new(self.method, self.gradients, self.index_from_world)
    }

    /// Calls `f` with the concrete filter.
    fn with<R>(&self, f: impl FnOnce(&dyn Field) -> R) -> R {
        let (grid, gradients) = (self.grid(), self.grads());
        match self.interpolation {
            Interpolation::Nearest => f(&Nearest { grid, gradients }),
            Interpolation::Trilinear => f(&Trilinear { grid, gradients }),
            Interpolation::BSpline => f(&BSpline { grid, gradients }),
            Interpolation::Cubic => f(&Cubic::new(
                self.coefficients.expect("checked in Sampler::new"),
                self.n,
                self.method,
                gradients.world_from_index,
                Box::new(Trilinear { grid, gradients }),
            )),
        }
    }
}

impl<T: Voxel> Field for Sampler<'_, T> {
    fn sizes(&self) -> [usize; 3] {
        self.n
    }

    fn value(&self, p: DVec3) -> f32 {
        self.with(|f| f.value(p))
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        self.with(|f| f.gradient(p))
    }

    fn cell_corners(&self, c: [usize; 3]) -> [f32; 8] {
        self.grid().cell_corners(c)
    }
}

/// The cubic B-spline over `get` (mirror boundary, matching the prefilter), clamped
/// to [0, 1] (the interpolating spline may overshoot the voxel values slightly).
#[inline(always)]
fn bspline(n: [usize; 3], p: DVec3, get: impl Fn(usize, usize, usize) -> f32) -> f32 {
    let (ix, wx) = bspline_weights(p.x, n[0]);
    bspline_rows(n, p, |j, k| {
        let mut row = 0.0f64;
        for a in 0..4 {
            row += wx[a] * get(ix[a], j, k) as f64;
        }
        row
    })
}

/// The B-spline at `p` from `row(j, k)`, the x-weighted sum of the row of voxels
/// `(j, k)`: the rows weighted along y and then z, summed in order from zero, and
/// clamped to [0, 1].
#[inline(always)]
fn bspline_rows(n: [usize; 3], p: DVec3, row: impl Fn(usize, usize) -> f64) -> f32 {
    let (iy, wy) = bspline_weights(p.y, n[1]);
    let (iz, wz) = bspline_weights(p.z, n[2]);
    let mut sum = 0.0f64;
    for (k, wk) in iz.into_iter().zip(wz) {
        let mut sy = 0.0f64;
        for (j, wj) in iy.into_iter().zip(wy) {
            sy += wj * row(j, k);
        }
        sum += wk * sy;
    }
    (sum as f32).clamp(0.0, 1.0)
}

/// `w[a] * v[a]` in f64, two at a time on x86-64 (the same products).
#[inline(always)]
fn products(v: &[f32; 4], w: &[f64; 4]) -> [f64; 4] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        // SAFETY: SSE2 is part of x86-64; the loads and stores are unaligned ones
        // of the arrays' own sizes
        unsafe {
            let v4 = _mm_loadu_ps(v.as_ptr());
            let lo = _mm_mul_pd(_mm_cvtps_pd(v4), _mm_loadu_pd(w.as_ptr()));
            let hi = _mm_mul_pd(
                _mm_cvtps_pd(_mm_movehl_ps(v4, v4)),
                _mm_loadu_pd(w.as_ptr().add(2)),
            );
            let mut out = [0.0f64; 4];
            _mm_storeu_pd(out.as_mut_ptr(), lo);
            _mm_storeu_pd(out.as_mut_ptr().add(2), hi);
            out
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        std::array::from_fn(|a| w[a] * v[a] as f64)
    }
}

/// Index-space gradient of the cubic B-spline over `get` (the derivative of the
/// same spline [`bspline`] evaluates, mirror boundary).
fn bspline_gradient(n: [usize; 3], p: DVec3, get: impl Fn(usize, usize, usize) -> f32) -> DVec3 {
    let (ix, wx, dx) = bspline_weights_and_derivatives(p.x, n[0]);
    let (iy, wy, dy) = bspline_weights_and_derivatives(p.y, n[1]);
    let (iz, wz, dz) = bspline_weights_and_derivatives(p.z, n[2]);
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

/// Mirror-boundary index (…, 2, 1, 0, 1, 2, …, n-1, n-2, …): always below `n`
/// for `n >= 1` (the unchecked reads of [`Cubic`] rely on it), 0 for `n` of 0 or 1.
#[inline(always)]
fn mirror(i: isize, n: usize) -> usize {
    // inside the grid, as all but a sample's edge indices are: the index itself,
    // without the remainder's integer division
    if (i as usize) < n {
        return i as usize;
    }
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

    /// `Cubic::value` (which reads the four coefficients of a row at once where
    /// the x indices are inside the grid) gives the bits of [`bspline`] reading
    /// them one by one: at positions inside, near and on the faces and beyond, in
    /// grids whose axes have one to seven voxels, with coefficients of both signs
    /// and negative zeros.
    #[test]
    fn row_reads_give_the_bits_of_single_reads() {
        for n in [[7usize, 6, 5], [4, 4, 4], [1, 5, 3], [5, 1, 1], [2, 3, 6]] {
            let len = n[0] * n[1] * n[2];
            let c: Vec<f32> = (0..len)
                .map(|i| match i % 9 {
                    0 => -0.0,
                    r => (r as f32 - 3.5) * 0.37 + (i % 5) as f32 * 0.013,
                })
                .collect();
            let cubic = Cubic::new(
                &c,
                n,
                GradientMethod::Central,
                DMat3::IDENTITY,
                Box::new(Line),
            );
            let (sx, sxy) = (n[0], n[0] * n[1]);
            let mut rows = 0;
            for x in [-2.0, 0.0, 0.4, 1.0, 1.5, 2.99, 3.0, 3.7, 5.2, 6.0, 9.0] {
                for y in [-1.0, 0.0, 0.6, 2.5, 4.9, 7.0] {
                    for z in [0.0, 1.3, 2.0, 3.8, 4.0] {
                        let p = DVec3::new(x, y, z);
                        let want = bspline(n, p, |i, j, k| c[i + sx * j + sxy * k]);
                        assert_eq!(cubic.value(p).to_bits(), want.to_bits(), "{p} in {n:?}");
                        let (ix, _) = bspline_weights(x, n[0]);
                        rows += usize::from(ix[3] == ix[0] + 3);
                    }
                }
            }
            if n[0] >= 4 {
                assert!(rows > 0, "{n:?}: no position read rows");
            }
        }
    }

    /// A field of no use but to fill `Cubic::voxels`.
    struct Line;

    impl Field for Line {
        fn sizes(&self) -> [usize; 3] {
            [1, 1, 1]
        }
        fn value(&self, _p: DVec3) -> f32 {
            0.0
        }
        fn gradient(&self, _p: DVec3) -> DVec3 {
            DVec3::ZERO
        }
        fn cell_corners(&self, _c: [usize; 3]) -> [f32; 8] {
            [0.0; 8]
        }
    }

    /// The mirror index, with its shortcut inside the grid, is the reflection of
    /// `i` about `0` and `n - 1` repeated (period `2 (n - 1)`), for indices far
    /// outside the grid on both sides, and `0` for grids of one voxel or none.
    #[test]
    fn mirror_reflects_about_both_ends() {
        for n in 0..7usize {
            for i in -20isize..20 {
                let want = if n < 2 {
                    0
                } else {
                    let period = 2 * (n as isize - 1);
                    let m = i.rem_euclid(period);
                    (if m >= n as isize { period - m } else { m }) as usize
                };
                assert_eq!(mirror(i, n), want, "i = {i}, n = {n}");
                // what `Cubic`'s unchecked reads rely on
                assert!(mirror(i, n) < n.max(1));
            }
        }
        // one step outside each end
        assert_eq!(mirror(-1, 5), 1);
        assert_eq!(mirror(5, 5), 3);
    }
}
