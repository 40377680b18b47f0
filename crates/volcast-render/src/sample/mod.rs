//! Reconstruction of a continuous field from voxels, and its gradient.
//!
//! Positions are in *index space* (voxel `(i, j, k)` at `(i, j, k)`; see
//! `volume::geometry`). Each voxel is read in its native type and mapped to a
//! normalised value in [0, 1] by the value window ([`Normalize`]) before it is
//! interpolated, so NaN or infinite voxels never reach an image (NaN and -inf count
//! as 0, +inf as 1) and every interpolant with non-negative weights stays in [0, 1].
//!
//! Filters (docs/formulas.md "Reconstruction"): `nearest`, `trilinear` (8 voxels),
//! `bspline` (the smoothing cubic B-spline on the voxels themselves, 64 voxels) and
//! `cubic` (the interpolating cubic B-spline: the same kernel applied to prefiltered
//! coefficients, so the field passes through the voxel values). Gradients
//! (docs/formulas.md "Gradients"): central differences or 3D Sobel on the voxel grid,
//! trilinearly interpolated between the 8 voxels around the position, then mapped to
//! world units with the inverse-transpose of the grid's axis matrix (so anisotropic
//! and sheared grids get each axis' own spacing).

mod filter;
mod grid;
mod reconstruct;

pub use filter::{
    gradient_volume, gradient_volume_normalised, prefilter_cubic, prefilter_normalised,
};
pub use grid::{
    bits_table, normalisation_table, pair_table, raw_bytes_unclamped, reads_pairs, CellCache,
    CellPosition, Gradients, Grid, PAIR_TABLE_BYTES,
};
pub use reconstruct::{BSpline, Cubic, Nearest, Sampler, Trilinear};

use glam::DVec3;

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
    /// The map for the value window `[lo, hi]` (`lo != hi`, both finite): `lo` maps
    /// to 0 and `hi` to 1. A decreasing window (`lo > hi`) inverts the values: the
    /// stored window of a volume whose rescale slope is negative.
    pub fn new(lo: f64, hi: f64) -> Normalize {
        debug_assert!(lo != hi, "window must not be empty");
        Normalize {
            lo,
            scale: 1.0 / (hi - lo),
        }
    }

    /// The map for `[lo, hi]` when it can be computed: both ends finite, and the
    /// width and its reciprocal finite and non-zero (`[-1e308, 1e308]` is 2e308
    /// wide, which no f64 holds).
    pub fn checked(lo: f64, hi: f64) -> Option<Normalize> {
        let scale = 1.0 / (hi - lo);
        (lo.is_finite() && hi.is_finite() && scale.is_finite() && scale != 0.0)
            .then_some(Normalize { lo, scale })
    }

    /// The window's lower end and `1 / (hi - lo)`.
    pub fn lo_scale(&self) -> (f64, f64) {
        (self.lo, self.scale)
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
    /// [`Field::value`], free to keep what it read for the next sample in `cache`
    /// (the trilinear filter keeps the last cell's corners); the same bits.
    #[inline(always)]
    fn value_cached(&self, p: DVec3, cache: &mut CellCache) -> f32 {
        let _ = cache;
        self.value(p)
    }
    /// [`Field::value_cached`] at `o + d t` for each `t` of `ts`, into `out` (as long
    /// as `ts`): the same bits, possibly several samples at a time.
    #[inline(always)]
    fn values_along(&self, o: DVec3, d: DVec3, ts: &[f64], out: &mut [f32], cache: &mut CellCache) {
        for (v, &t) in out.iter_mut().zip(ts) {
            *v = self.value_cached(o + d * t, cache);
        }
    }
    /// How many samples [`Field::values_along`] takes at once on this machine, a
    /// power of two (1: one at a time). A call of a length that is not a multiple of it samples the
    /// last few on a narrower path, so a caller with samples to spare may pad a
    /// call to a multiple of it (the same bits for the samples it keeps).
    #[inline(always)]
    fn lanes(&self) -> usize {
        1
    }
    /// Where the values of [`Field::raw_values_along`] map to this field's samples
    /// through a map that does not decrease: that map (the sample at a position is
    /// `map.apply(raw)` there, bit for bit). The largest or smallest of a run of
    /// samples is then the map of the largest or smallest raw value, so a MIP or
    /// MinIP maps one value per batch instead of every sample. `None` (the
    /// default): no such path.
    fn raw_map(&self) -> Option<Normalize> {
        None
    }
    /// [`Field::values_along`] before the map of [`Field::raw_map`] (called only
    /// where that is `Some`; the default is [`Field::values_along`]).
    #[inline(always)]
    fn raw_values_along(
        &self,
        o: DVec3,
        d: DVec3,
        ts: &[f64],
        out: &mut [f32],
        cache: &mut CellCache,
    ) {
        self.values_along(o, d, ts, out, cache)
    }
    /// The gradient of the normalised value at `p`, in world units
    /// (normalised value per world unit).
    fn gradient(&self, p: DVec3) -> DVec3;
    /// The normalised voxels at the eight corners of cell `c` (the cell from voxel
    /// `c` to `c + 1` on each axis; an axis of a single voxel repeats voxel 0),
    /// corner `(a, b, c)` at index `a + 2 b + 4 c`. The exact integrators treat the
    /// trilinear interpolant of these values as a polynomial along the ray.
    fn cell_corners(&self, c: [usize; 3]) -> [f32; 8];
}

impl<F: Field + ?Sized> Field for &F {
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
    #[inline(always)]
    fn values_along(&self, o: DVec3, d: DVec3, ts: &[f64], out: &mut [f32], cache: &mut CellCache) {
        (**self).values_along(o, d, ts, out, cache)
    }
    #[inline(always)]
    fn lanes(&self) -> usize {
        (**self).lanes()
    }
    #[inline(always)]
    fn raw_map(&self) -> Option<Normalize> {
        (**self).raw_map()
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
        (**self).raw_values_along(o, d, ts, out, cache)
    }
    fn gradient(&self, p: DVec3) -> DVec3 {
        (**self).gradient(p)
    }
    #[inline(always)]
    fn cell_corners(&self, c: [usize; 3]) -> [f32; 8] {
        (**self).cell_corners(c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::Voxels;
    use glam::DMat3;

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

    /// The cell cache gives the bits of the uncached sample, in any order of samples
    /// (cells revisited, skipped, alternating), for float32 (with values outside the
    /// window) and 8-bit voxels.
    #[test]
    fn cached_trilinear_samples_are_the_uncached_bits() {
        let n = [9, 8, 7];
        let len = n[0] * n[1] * n[2];
        let f: Vec<f32> = (0..len)
            .map(|i| ((i * 37 % 101) as f32 - 20.0) / 70.0)
            .collect();
        let b: Vec<u8> = (0..len).map(|i| (i * 53 % 256) as u8).collect();
        let norm = Normalize::new(-0.1, 1.2);
        let lut_f = normalisation_table::<f32>(norm);
        let lut_b = normalisation_table::<u8>(norm);
        let gf = Grid::new(Voxels::from(&f), n, norm, &lut_f);
        let gb = Grid::new(Voxels::from(&b), n, norm, &lut_b);
        let mut state = 12345u64;
        let mut next = |hi: f64| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * hi
        };
        let (mut cf, mut cb) = (CellCache::default(), CellCache::default());
        let mut p = [1.0, 1.0, 1.0];
        for _ in 0..20_000 {
            // mostly small steps (same or next cell), sometimes a jump, sometimes
            // outside the grid (clamped)
            if next(1.0) < 0.1 {
                p = [next(11.0) - 1.0, next(10.0) - 1.0, next(9.0) - 1.0];
            } else {
                for x in &mut p {
                    *x += next(0.6) - 0.3;
                }
            }
            assert_eq!(
                gf.trilinear_cached(p, &mut cf).to_bits(),
                gf.trilinear(p).to_bits(),
                "{p:?}"
            );
            assert_eq!(
                gb.trilinear_cached(p, &mut cb).to_bits(),
                gb.trilinear(p).to_bits(),
                "{p:?}"
            );
        }
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
