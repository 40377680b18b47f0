//! Normalised voxel reads and grid gradients: what every reconstruction filter is
//! built on.

use glam::{DMat3, DVec3};

use super::{filter, GradientMethod, Normalize};
use crate::volume::{ScalarType, Voxel, Voxels};

/// The four rows of a group of lanes' cells, `[$row($add($base, $rows[r]))]` for
/// r = 0..4, written out: the closure of `array::map` is not always inlined, and
/// where it is not, the vector paths pay a call and a copy per row (the compiler's
/// choice moves with changes elsewhere in the crate).
#[cfg(target_arch = "x86_64")]
macro_rules! each_row {
    ($self:ident . $row:ident :: <$k:tt>, $add:ident, $base:expr, $rows:expr) => {
        [
            $self.$row::<$k>($add($base, $rows[0])),
            $self.$row::<$k>($add($base, $rows[1])),
            $self.$row::<$k>($add($base, $rows[2])),
            $self.$row::<$k>($add($base, $rows[3])),
        ]
    };
    ($self:ident . $row:ident, $add:ident, $base:expr, $rows:expr) => {
        [
            $self.$row($add($base, $rows[0])),
            $self.$row($add($base, $rows[1])),
            $self.$row($add($base, $rows[2])),
            $self.$row($add($base, $rows[3])),
        ]
    };
}

/// The lanes of one call's constants ([`avx2::LaneConstants`]), broadcast with
/// `$set1` (the path's 64-bit broadcast): the three axes as the path's own `Axis`,
/// the strides of y and z, and the offsets of a cell's four rows. Written out here
/// rather than through `array::map`, whose closures do not take the calling
/// function's target features: each `set1` was then a call and the arrays were
/// copied by `memcpy`, a cost per call that short calls felt.
#[cfg(target_arch = "x86_64")]
macro_rules! broadcast_lanes {
    ($c:expr, $set1:ident) => {{
        let c = $c;
        let b = |x: i64| $set1(x);
        (
            [
                Axis::new(c.axes[0]),
                Axis::new(c.axes[1]),
                Axis::new(c.axes[2]),
            ],
            [b(c.strides[0]), b(c.strides[1])],
            [b(c.rows[0]), b(c.rows[1]), b(c.rows[2]), b(c.rows[3])],
        )
    }};
}

/// Runs `$run!(K)` with the loop code `K` ([`avx2::Loop`]) of storage `$kind`
/// (gathered: raw bytes read by gathers), each loop its own code with the storage
/// chosen once per call, not once per group of lanes, so that no group of lanes
/// pays a branch on the storage (`bench/peers/README.md`). Only the loops of voxel
/// type `$t`'s storage are compiled, and with `$raw`, only those of raw bytes.
#[cfg(target_arch = "x86_64")]
macro_rules! each_storage {
    ($t:ty, $raw:expr, $kind:expr, $gathered:expr, $run:ident) => {{
        use crate::sample::grid::avx2::Loop;
        use crate::volume::ScalarType;
        let code = Loop::of($kind, $gathered);
        debug_assert!(
            !$raw || code == Loop::RAW || code == Loop::RAW_GATHERED,
            "raw values are read from raw bytes only"
        );
        match <$t as Voxel>::TYPE {
            ScalarType::Uint8 if $raw => match code {
                Loop::RAW_GATHERED => $run!(Loop::RAW_GATHERED),
                _ => $run!(Loop::RAW),
            },
            ScalarType::Uint8 => match code {
                Loop::BITS8 => $run!(Loop::BITS8),
                Loop::PAIRS => $run!(Loop::PAIRS),
                Loop::RAW_GATHERED => $run!(Loop::RAW_GATHERED),
                _ => $run!(Loop::RAW),
            },
            ScalarType::Float32 => match code {
                Loop::F32 => $run!(Loop::F32),
                Loop::F32_UNIT => $run!(Loop::F32_UNIT),
                _ => $run!(Loop::F32_BARE),
            },
            _ => $run!(Loop::BITS16),
        }
    }};
}

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;

/// The normalised value of every possible voxel value of `T`, for 8- and 16-bit
/// types (empty for the others, which normalise each voxel as it is read).
pub fn normalisation_table<T: Voxel>(norm: Normalize) -> Vec<f32> {
    (0..T::LUT_SIZE)
        .map(|i| norm.apply(T::lut_value(i)))
        .collect()
}

/// The normalised value of every bit pattern of an 8- or 16-bit voxel of type `ty`,
/// indexed by the pattern read as `u8` / `u16` (so signed and unsigned data share
/// one [`Grid`] over unsigned bits); `None` for the other types.
pub fn bits_table(ty: ScalarType, norm: Normalize) -> Option<Vec<f32>> {
    let table = |n: usize, value: &dyn Fn(usize) -> f64| -> Vec<f32> {
        (0..n).map(|b| norm.apply(value(b))).collect()
    };
    Some(match ty {
        ScalarType::Uint8 => table(256, &|b| b as f64),
        ScalarType::Int8 => table(256, &|b| f64::from(b as u8 as i8)),
        ScalarType::Uint16 => table(65536, &|b| b as f64),
        ScalarType::Int16 => table(65536, &|b| f64::from(b as u16 as i16)),
        _ => return None,
    })
}

/// Bytes of a [`pair_table`].
pub const PAIR_TABLE_BYTES: u64 = (1 << 16) * 8;

/// The normalised values of two adjacent 8-bit voxels for every 16-bit word they
/// make in memory (the first voxel in the low byte): `[lut[w & 0xff], lut[w >> 8]]`
/// for each word `w`, from a 256-entry table `lut` ([`bits_table`] or
/// [`normalisation_table`]). The vector paths read a cell row's two voxels as one
/// word and take both values with one load ([`Grid::with_pairs`]), as they read
/// two float32 voxels; 512 KiB ([`PAIR_TABLE_BYTES`]).
pub fn pair_table(lut: &[f32]) -> Vec<[f32; 2]> {
    assert_eq!(lut.len(), 256, "a table of 8-bit values");
    (0..1usize << 16)
        .map(|w| [lut[w & 0xff], lut[w >> 8]])
        .collect()
}

/// Whether this machine's vector paths read 8-bit voxels through a [`pair_table`]
/// (x86-64 with AVX2): where they do not, none needs to be built.
pub fn reads_pairs() -> bool {
    #[cfg(target_arch = "x86_64")]
    return std::is_x86_feature_detected!("avx2");
    #[cfg(not(target_arch = "x86_64"))]
    return false;
}

/// Whether normalising by `norm` clamps none of the 8-bit values `lo..=hi` (the
/// data's range), so that a grid over them may interpolate the bytes as they are
/// ([`Grid::with_raw_bytes`]): `(v - lo) * scale` lies in [0, 1] at both ends, and
/// so (affine, rounded monotonically) between them.
pub fn raw_bytes_unclamped(norm: Normalize, [lo, hi]: [u8; 2]) -> bool {
    let (l, s) = norm.lo_scale();
    let inside = |v: u8| (0.0..=1.0).contains(&((f64::from(v) - l) * s));
    inside(lo) && inside(hi)
}

/// Native-typed voxels read as normalised values in [0, 1]: the voxels, the grid's
/// sizes and strides, and the value window (a table load per voxel for 8- and
/// 16-bit data, see [`normalisation_table`]; on the vector paths, one per two 8-bit
/// voxels with a [`pair_table`]).
#[derive(Clone, Copy, Debug)]
pub struct Grid<'a, T: Voxel> {
    voxels: Voxels<'a, T>,
    lut: &'a [f32],
    norm: Normalize,
    /// Voxels per axis.
    pub n: [usize; 3],
    /// Stride of y (private: the unchecked reads of the cells trust it).
    sx: usize,
    /// Stride of z (private, as `sx`).
    sxy: usize,
    /// Per axis: the last voxel index as `f64` (positions are clamped to it).
    last: [f64; 3],
    /// Per axis: the last cell's first voxel (`n - 2`, or 0 on a one-voxel axis).
    top: [usize; 3],
    /// `top` as `f64`.
    top_f: [f64; 3],
    /// Per axis: the step to the cell's second voxel (the stride, or 0 on a
    /// one-voxel axis).
    step: [usize; 3],
    /// XOR turning a table index into an index in the order of the values: the sign
    /// bit for signed data read as unsigned bits, else 0.
    flip: usize,
    /// 8-bit voxels interpolated as the bytes they are, the result normalised
    /// ([`Grid::with_raw_bytes`]), rather than normalised and then interpolated.
    raw_bytes: bool,
    /// Every index fits an i32 (the SSE2 cell search converts to i32).
    sse2: bool,
    /// The AVX2 path of [`Grid::trilinear_along`], when the machine and the grid
    /// allow it.
    #[cfg(target_arch = "x86_64")]
    gather: Option<avx2::Gather>,
    /// The vector path runs eight lanes wide (`avx512.rs`): `gather` is set and the
    /// machine has AVX-512.
    #[cfg(target_arch = "x86_64")]
    wide: bool,
    /// The eight-lane path reads a float32 row of eight lanes with one gather
    /// instruction rather than eight scalar loads ([`avx512::gathers_pay`]): the
    /// same words, so the same bits.
    #[cfg(target_arch = "x86_64")]
    row_gathers: bool,
    /// The [`pair_table`] of `lut` for 8-bit voxels ([`Grid::with_pairs`]), or empty.
    #[cfg(target_arch = "x86_64")]
    pairs: &'a [[f32; 2]],
}

/// The normalised corners (on a grid of raw bytes, the bytes) of the cell a ray
/// sampled last (see [`Grid::trilinear_cached`]). It is keyed by the cell only, so
/// any order of samples is fine, but one cache must serve one grid: keep one per
/// ray.
#[derive(Clone, Copy, Debug)]
pub struct CellCache {
    /// Flat index of the cell's first voxel (`usize::MAX`: none yet).
    base: usize,
    #[cfg(target_arch = "x86_64")]
    a: std::arch::x86_64::__m128,
    #[cfg(target_arch = "x86_64")]
    b: std::arch::x86_64::__m128,
}

impl Default for CellCache {
    fn default() -> Self {
        CellCache {
            base: usize::MAX,
            // SAFETY: SSE2 is part of x86-64.
            #[cfg(target_arch = "x86_64")]
            a: unsafe { std::arch::x86_64::_mm_setzero_ps() },
            #[cfg(target_arch = "x86_64")]
            b: unsafe { std::arch::x86_64::_mm_setzero_ps() },
        }
    }
}

/// A trilinear cell and the position inside it: the flat index of its first voxel,
/// the offsets to the next voxel along x, y and z, and the fractions.
#[derive(Clone, Copy, Debug)]
pub struct CellPosition {
    /// Flat index of the cell's first voxel.
    pub base: usize,
    /// Offsets to the next voxel along x, y and z (0 on a one-voxel axis).
    pub d: [usize; 3],
    /// The position's fraction of the way across the cell, per axis.
    pub f: [f32; 3],
}

impl<'a, T: Voxel> Grid<'a, T> {
    /// The grid of `voxels` (x fastest, `n` per axis); `lut` is
    /// [`normalisation_table`] of `norm`.
    pub fn new(voxels: Voxels<'a, T>, n: [usize; 3], norm: Normalize, lut: &'a [f32]) -> Self {
        assert_eq!(
            voxels.len(),
            n[0] * n[1] * n[2],
            "data length matches the sizes"
        );
        assert_eq!(lut.len(), T::LUT_SIZE, "normalisation table of the type");
        let stride = [1, n[0], n[0] * n[1]];
        #[cfg(target_arch = "x86_64")]
        let gather = avx2::Gather::for_grid::<T>(n, norm);
        Grid {
            voxels,
            lut,
            norm,
            n,
            sx: n[0],
            sxy: n[0] * n[1],
            last: n.map(|n| n.saturating_sub(1) as f64),
            top: n.map(|n| n.saturating_sub(2)),
            top_f: n.map(|n| n.saturating_sub(2) as f64),
            step: std::array::from_fn(|a| if n[a] >= 2 { stride[a] } else { 0 }),
            flip: 0,
            raw_bytes: false,
            sse2: n.iter().all(|&n| n < i32::MAX as usize),
            #[cfg(target_arch = "x86_64")]
            gather,
            #[cfg(target_arch = "x86_64")]
            wide: gather.is_some() && avx512::available(),
            #[cfg(target_arch = "x86_64")]
            row_gathers: avx512::gathers_pay(),
            #[cfg(target_arch = "x86_64")]
            pairs: &[],
        }
    }

    /// The grid of 8-bit voxels with the [`pair_table`] of its normalisation table:
    /// its vector paths then read each row's two voxels with one table load rather
    /// than two (the same values, so the same bits). Any other grid, or an empty
    /// table, leaves the grid as it was.
    pub fn with_pairs(self, pairs: &'a [[f32; 2]]) -> Self {
        #[cfg(target_arch = "x86_64")]
        if self.gather == Some(avx2::Gather::Bits8) && pairs.len() == 1 << 16 {
            debug_assert!(pairs
                .iter()
                .enumerate()
                .all(|(w, p)| p[0].to_bits() == self.lut[w & 0xff].to_bits()
                    && p[1].to_bits() == self.lut[w >> 8].to_bits()));
            return Grid {
                pairs,
                gather: Some(avx2::Gather::Bits8Pairs),
                ..self
            };
        }
        let _ = pairs;
        self
    }

    /// The grid, told that every voxel lies in [0, 1] (no NaN) while the window is
    /// [0, 1]: normalising each voxel is then the identity, and the vector paths
    /// read float32 voxels as they are (`avx2::Gather::Float32Bare`), with the
    /// same bits as when they clamp them. A grid of another type or window is
    /// returned unchanged. The caller checks the voxels
    /// ([`Voxels::all_in_unit_interval`](crate::volume::Voxels::all_in_unit_interval)):
    /// a voxel outside [0, 1] would then be sampled unclamped.
    pub fn with_unit_voxels(self) -> Self {
        #[cfg(target_arch = "x86_64")]
        if self.gather == Some(avx2::Gather::Float32Unit) {
            return Grid {
                gather: Some(avx2::Gather::Float32Bare),
                ..self
            };
        }
        self
    }

    /// The grid of unsigned 8-bit voxels, told that the window covers every one of
    /// them (no voxel's normalisation is clamped: [`raw_bytes_unclamped`]): its
    /// trilinear samples then interpolate the bytes as they are and normalise the
    /// result (`(v - lo) * scale` in f64, clamped to [0, 1], as
    /// [`Normalize::apply`]). Normalising is affine there, so this is the same
    /// interpolant up to rounding (the corners are exact integers, so one rounding
    /// fewer per corner), and its vector paths read no table: the bytes become
    /// floats in the lanes. Every path of such a grid samples this way, on any
    /// machine, so a sample has the same bits whichever path takes it. Any other
    /// grid is returned unchanged.
    pub fn with_raw_bytes(self) -> Self {
        if T::TYPE != crate::volume::ScalarType::Uint8 || self.flip != 0 {
            return self;
        }
        #[cfg(target_arch = "x86_64")]
        let gather = self.gather.map(|_| avx2::Gather::Bits8Raw);
        Grid {
            raw_bytes: true,
            #[cfg(target_arch = "x86_64")]
            gather,
            // (the bytes are read as they are, not through the table of pairs)
            #[cfg(target_arch = "x86_64")]
            pairs: &[],
            ..self
        }
    }

    /// The grid of signed 8- or 16-bit data read as the unsigned bits `T` (whose
    /// normalisation table, [`bits_table`], is indexed by bits).
    pub fn signed_bits(self) -> Self {
        Grid {
            flip: T::LUT_SIZE / 2,
            ..self
        }
    }

    /// The trilinear cell holding index-space position `p` (clamped to the grid;
    /// NaN counts as 0), and the fractions.
    #[inline(always)]
    pub fn locate(&self, p: [f64; 3]) -> CellPosition {
        let mut base = 0;
        let mut f = [0.0f32; 3];
        let stride = [1, self.sx, self.sxy];
        for a in 0..3 {
            // `x > 0` is false for NaN; both comparisons compile to max/min
            let x = if p[a] > 0.0 { p[a] } else { 0.0 };
            let x = if x < self.last[a] { x } else { self.last[a] };
            // SAFETY: `x` is finite and in [0, n - 1], which an i64 holds (a volume
            // has fewer than 2^63 voxels); one instruction, where a checked or an
            // unsigned conversion takes several.
            let i = (unsafe { x.to_int_unchecked::<i64>() } as usize).min(self.top[a]);
            f[a] = (x - i as f64) as f32;
            base += i * stride[a];
        }
        CellPosition {
            base,
            d: self.step,
            f,
        }
    }

    /// The trilinear interpolant of the normalised voxels at `p` (clamped to the
    /// grid; NaN counts as 0), clamped to [0, 1]: along x, then y, then z (on a
    /// grid of raw bytes, [`Grid::with_raw_bytes`], of the bytes, then normalised).
    #[inline(always)]
    pub fn trilinear(&self, p: [f64; 3]) -> f32 {
        self.single::<false>(p)
    }

    /// [`Grid::trilinear`], keeping the last cell's normalised corners in `cache`:
    /// a sample in the same cell as the one before (about every other sample at a
    /// half-voxel step) reads no voxel. The same values, so the same bits.
    #[inline(always)]
    pub fn trilinear_cached(&self, p: [f64; 3], cache: &mut CellCache) -> f32 {
        self.cached::<false>(p, cache)
    }

    /// The map from the raw values of [`Grid::trilinear_along`] to the samples, where this
    /// grid has that path: a grid of raw bytes ([`Grid::with_raw_bytes`]) whose
    /// window increases, so that the map, [`Normalize::apply`], does not decrease
    /// (its subtraction, multiplication by a positive scale, clamps and rounding to
    /// f32 each keep the order). The largest (smallest) of the samples at some
    /// positions is then the map of the largest (smallest) raw value there: a MIP
    /// over such a grid normalises once per batch rather than once per sample.
    pub fn raw_map(&self) -> Option<Normalize> {
        (self.raw_bytes && self.norm.lo_scale().1 > 0.0).then_some(self.norm)
    }

    /// [`Grid::trilinear_cached`] at `o + d t` for each `t` of `ts`, into `out` (as
    /// long as `ts`), four or eight samples at a time where the machine has AVX2 or
    /// AVX-512 (the same bits: `avx2.rs`). With `RAW`, on a grid of raw bytes
    /// ([`Grid::with_raw_bytes`]), each sample without its last step: the
    /// interpolated bytes, not normalised, which [`Normalize::apply`] by the grid's
    /// window turns into the bits the samples have ([`Grid::raw_map`]).
    ///
    /// # Panics
    /// In a debug build, with `RAW` on a grid that does not read raw bytes.
    #[inline(always)]
    pub fn trilinear_along<const RAW: bool>(
        &self,
        o: [f64; 3],
        d: [f64; 3],
        ts: &[f64],
        out: &mut [f32],
        cache: &mut CellCache,
    ) {
        debug_assert!(
            !RAW || self.raw_bytes,
            "raw values of a grid of raw bytes only"
        );
        // the vector paths exist for the types they read (a constant per `T`,
        // so the other types do not compile them)
        #[cfg(target_arch = "x86_64")]
        if const { avx2::Gather::reads(T::TYPE) } {
            if self.wide {
                // SAFETY: `wide` is set only with `gather`, where `avx512::available`
                // found AVX-512F and AVX2 (`is_x86_feature_detected!`).
                return unsafe { self.trilinear_avx512::<RAW>(o, d, ts, out) };
            }
            if self.gather.is_some() {
                // SAFETY: `gather` is set only where `Gather::for_grid` found AVX2
                // (`is_x86_feature_detected!`).
                return unsafe { self.trilinear_avx2::<RAW>(o, d, ts, out) };
            }
        }
        for (v, &t) in out.iter_mut().zip(ts) {
            *v = self.cached::<RAW>([0, 1, 2].map(|a| o[a] + d[a] * t), cache);
        }
    }

    /// [`Grid::trilinear_cached`], or with `RAW`, its value before the last step
    /// ([`Grid::finish`]).
    #[inline(always)]
    fn cached<const RAW: bool>(&self, p: [f64; 3], cache: &mut CellCache) -> f32 {
        #[cfg(target_arch = "x86_64")]
        if self.sse2 {
            // SAFETY: as in `single`.
            return unsafe { self.trilinear_sse2::<RAW>(p, Some(cache)) };
        }
        let _ = cache;
        self.trilinear_scalar::<RAW>(p)
    }

    /// [`Grid::trilinear`], or with `RAW`, its value before the last step
    /// ([`Grid::finish`]).
    #[inline(always)]
    pub(super) fn single<const RAW: bool>(&self, p: [f64; 3]) -> f32 {
        #[cfg(target_arch = "x86_64")]
        if self.sse2 {
            // SAFETY: SSE2 is part of x86-64; `sse2` says the indices fit an i32.
            return unsafe { self.trilinear_sse2::<RAW>(p, None) };
        }
        self.trilinear_scalar::<RAW>(p)
    }

    /// How many samples [`Grid::trilinear_along`] takes at once on this machine: 8
    /// on the AVX-512 path, 4 on the AVX2 path, 1 where it samples one at a time.
    #[inline(always)]
    pub fn lanes(&self) -> usize {
        #[cfg(target_arch = "x86_64")]
        if const { avx2::Gather::reads(T::TYPE) } {
            if self.wide {
                return 8;
            }
            if self.gather.is_some() {
                return 4;
            }
        }
        1
    }

    #[inline(always)]
    fn trilinear_scalar<const RAW: bool>(&self, p: [f64; 3]) -> f32 {
        let c = self.locate(p);
        let [fx, fy, fz] = c.f;
        let [c000, c100, c010, c110, c001, c101, c011, c111] = if self.raw_bytes {
            self.cell_bytes(c.base)
        } else {
            self.cell_values(c.base)
        };
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let x00 = lerp(c000, c100, fx);
        let x10 = lerp(c010, c110, fx);
        let x01 = lerp(c001, c101, fx);
        let x11 = lerp(c011, c111, fx);
        self.finish::<RAW>(lerp(lerp(x00, x10, fy), lerp(x01, x11, fy), fz))
    }

    /// A sample from its interpolated value: clamped to [0, 1] as `f32::clamp`
    /// does, or, for a grid of raw bytes, normalised ([`Normalize::apply`]); with
    /// `RAW` (a grid of raw bytes, [`Grid::trilinear_along`]), left as it is.
    #[inline(always)]
    fn finish<const RAW: bool>(&self, v: f32) -> f32 {
        if RAW {
            v
        } else if self.raw_bytes {
            self.norm.apply(f64::from(v))
        } else {
            v.clamp(0.0, 1.0)
        }
    }

    /// The voxels at the corners of the cell at `base` as floats, not normalised
    /// (a grid of raw bytes, [`Grid::with_raw_bytes`]), in the order of
    /// [`Grid::cell_values`].
    #[inline(always)]
    fn cell_bytes(&self, base: usize) -> [f32; 8] {
        let [dx, dy, dz] = self.step;
        // SAFETY: as in `cell_values`
        unsafe { self.voxels.corners_unchecked(base, dx, dy, dz) }.map(|v| v.to_f64() as f32)
    }

    /// [`Grid::trilinear_scalar`] with the cell search and the interpolation in
    /// SSE2 registers: the same operations in the same order, so the same bits, in
    /// fewer instructions. An `unsafe fn` rather than a `#[target_feature]` one
    /// (SSE2 is part of x86-64), which could not be `#[inline(always)]`.
    ///
    /// # Safety
    /// `self.sse2`: every index of the grid fits an i32, so that the conversions
    /// to i32 give the cell of each clamped position.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn trilinear_sse2<const RAW: bool>(
        &self,
        p: [f64; 3],
        cache: Option<&mut CellCache>,
    ) -> f32 {
        use std::arch::x86_64::*;
        // x and y in one register, z in another: clamp to [0, last], the cell's
        // first voxel is the truncation of min(x, top) (the same as min(trunc(x),
        // top) for x >= 0), the fraction what is left
        let zero = _mm_setzero_pd();
        let xy = _mm_set_pd(p[1], p[0]);
        let xy = _mm_min_pd(_mm_max_pd(xy, zero), _mm_set_pd(self.last[1], self.last[0]));
        let ixy = _mm_cvttpd_epi32(_mm_min_pd(xy, _mm_set_pd(self.top_f[1], self.top_f[0])));
        let fxy = _mm_cvtpd_ps(_mm_sub_pd(xy, _mm_cvtepi32_pd(ixy)));
        let z = _mm_set_sd(p[2]);
        let z = _mm_min_sd(_mm_max_sd(z, zero), _mm_set_sd(self.last[2]));
        let iz = _mm_cvttsd_si32(_mm_min_sd(z, _mm_set_sd(self.top_f[2])));
        let fz = (_mm_cvtsd_f64(z) - iz as f64) as f32;
        let i = _mm_cvtsi128_si32(ixy) as usize;
        let j = _mm_cvtsi128_si32(_mm_shuffle_epi32(ixy, 1)) as usize;
        let base = i + self.sx * j + self.sxy * iz as usize;
        let (a, b) = match cache {
            Some(c) if c.base == base => (c.a, c.b),
            Some(c) => {
                let (a, b) = self.cell_vectors_sse2(base);
                *c = CellCache { base, a, b };
                (a, b)
            }
            None => self.cell_vectors_sse2(base),
        };
        // x: four lerps at once, lanes (x00, x10, x01, x11)
        let fx = _mm_shuffle_ps(fxy, fxy, 0b00_00_00_00);
        let x = _mm_add_ps(a, _mm_mul_ps(_mm_sub_ps(b, a), fx));
        // y: lanes (x00, x01) towards (x10, x11)
        let lo = _mm_shuffle_ps(x, x, 0b00_00_10_00);
        let hi = _mm_shuffle_ps(x, x, 0b00_00_11_01);
        let fy = _mm_shuffle_ps(fxy, fxy, 0b01_01_01_01);
        let y = _mm_add_ps(lo, _mm_mul_ps(_mm_sub_ps(hi, lo), fy));
        // z: lane 0 towards lane 1
        let y0 = _mm_cvtss_f32(y);
        let y1 = _mm_cvtss_f32(_mm_shuffle_ps(y, y, 0b00_00_00_01));
        self.finish::<RAW>(y0 + (y1 - y0) * fz)
    }

    /// The normalised voxels of the cell at `base` as the interpolation along x takes
    /// them: `a` = voxels (000, 010, 001, 011), `b` = (100, 110, 101, 111). float32
    /// voxels are loaded two at a time along x and normalised in f64 lanes (the same
    /// operations as [`Normalize::apply`], so the same bits); 8-bit voxels two at a
    /// time through the table of pairs where the grid has one ([`Grid::with_pairs`]),
    /// or as they are ([`Grid::cell_bytes`]) on a grid of raw bytes; the others
    /// through [`Grid::cell_values`].
    ///
    /// # Safety
    /// `base` is the flat index of a cell's first voxel, as [`Grid::locate`] gives
    /// it (so `base + dx + dy + dz` is a voxel, [`Grid::cell_values`]).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn cell_vectors_sse2(
        &self,
        base: usize,
    ) -> (std::arch::x86_64::__m128, std::arch::x86_64::__m128) {
        use std::arch::x86_64::*;
        if T::TYPE == crate::volume::ScalarType::Float32 && self.step[0] == 1 {
            let [_, dy, dz] = self.step;
            let p = self.voxels.as_ptr().cast::<f32>();
            // SAFETY: as in `cell_values`: `base + 1 + dy + dz <= len - 1`, so each
            // pair (i, i + 1) read here is inside the voxels; unaligned loads.
            let pair = |i: usize| _mm_castsi128_ps(_mm_loadl_epi64(p.add(i).cast::<__m128i>()));
            let lo = _mm_movelh_ps(pair(base), pair(base + dy)); // 000 100 010 110
            let hi = _mm_movelh_ps(pair(base + dz), pair(base + dy + dz)); // 001 101 011 111
            let (l, s) = self.norm.lo_scale();
            let (l, s) = (_mm_set1_pd(l), _mm_set1_pd(s));
            let (zero, one) = (_mm_setzero_pd(), _mm_set1_pd(1.0));
            // (v - lo) * scale, then max with 0 (NaN -> 0) and min with 1, in f64
            let norm2 = |v: __m128| {
                let x = _mm_mul_pd(_mm_sub_pd(_mm_cvtps_pd(v), l), s);
                _mm_cvtpd_ps(_mm_min_pd(_mm_max_pd(x, zero), one))
            };
            let lo = _mm_movelh_ps(norm2(lo), norm2(_mm_movehl_ps(lo, lo)));
            let hi = _mm_movelh_ps(norm2(hi), norm2(_mm_movehl_ps(hi, hi)));
            let a = _mm_shuffle_ps(lo, hi, 0b10_00_10_00);
            let b = _mm_shuffle_ps(lo, hi, 0b11_01_11_01);
            return (a, b);
        }
        if T::TYPE == crate::volume::ScalarType::Uint8 && !self.pairs.is_empty() {
            let [_, dy, dz] = self.step;
            // SAFETY: as above, each pair (i, i + 1) is inside the voxels (the grid
            // has a table of pairs only where x has two voxels or more, so `dx` is 1);
            // each row's two normalised voxels come as one word of the table
            let pair = |i: usize| _mm_castsi128_ps(_mm_cvtsi64_si128(self.pair_word(i as i64)));
            let lo = _mm_movelh_ps(pair(base), pair(base + dy)); // 000 100 010 110
            let hi = _mm_movelh_ps(pair(base + dz), pair(base + dy + dz)); // 001 101 011 111
            let a = _mm_shuffle_ps(lo, hi, 0b10_00_10_00);
            let b = _mm_shuffle_ps(lo, hi, 0b11_01_11_01);
            return (a, b);
        }
        let [c000, c100, c010, c110, c001, c101, c011, c111] = if self.raw_bytes {
            self.cell_bytes(base)
        } else {
            self.cell_values(base)
        };
        (
            _mm_set_ps(c011, c001, c010, c000),
            _mm_set_ps(c111, c101, c110, c100),
        )
    }

    /// The value window.
    pub fn norm(&self) -> Normalize {
        self.norm
    }

    /// Normalised value of one raw voxel.
    #[inline(always)]
    fn normalise(&self, v: T) -> f32 {
        if T::LUT_SIZE > 0 {
            let i = v.lut_index();
            debug_assert!(i < self.lut.len());
            // SAFETY: `new` checked `lut.len() == T::LUT_SIZE`, and `lut_index` is
            // below `LUT_SIZE` for every value (the sealed `Voxel` implementations).
            unsafe { *self.lut.get_unchecked(i) }
        } else {
            self.norm.apply(v.to_f64())
        }
    }

    /// Normalised voxel at a flat index.
    #[inline(always)]
    pub fn at(&self, idx: usize) -> f32 {
        self.normalise(self.voxels.get(idx))
    }

    /// The normalised voxels at the corners of the cell of [`Grid::locate`] or the
    /// trilinear search: no bounds check, the indices come from positions clamped to
    /// the grid (`base <= top`, so the largest index is at most `len - 1`).
    #[inline(always)]
    fn cell_values(&self, base: usize) -> [f32; 8] {
        let [dx, dy, dz] = self.step;
        // SAFETY: `base` is `i + sx j + sxy k` with each index at most the axis'
        // `top` (n - 2, or 0 on a one-voxel axis, where the step is 0), so
        // `base + dx + dy + dz <= (n0 - 1) + sx (n1 - 1) + sxy (n2 - 1) = len - 1`.
        unsafe { self.voxels.corners_unchecked(base, dx, dy, dz) }.map(|v| self.normalise(v))
    }

    /// The normalised voxels at the corners of a trilinear cell (see
    /// [`Voxels::corners`]), one bounds check.
    #[inline(always)]
    pub fn corners(&self, base: usize, dx: usize, dy: usize, dz: usize) -> [f32; 8] {
        self.voxels
            .corners(base, dx, dy, dz)
            .map(|v| self.normalise(v))
    }

    /// The ranges `[min, max]` of the normalised values (NaN counts as 0, as when it
    /// is read) of the voxels `x0..=x1` of the x row starting at flat index `row`,
    /// for each window `(x0, x1)` of `windows`, into `out`. For 8- and 16-bit data,
    /// the extremes of the raw values, normalised (the table is monotone in the
    /// value).
    pub fn row_ranges(&self, row: usize, windows: &[(usize, usize)], out: &mut [[f32; 2]]) {
        let run = self.voxels.slice(row..row + self.n[0]);
        if T::LUT_SIZE > 0 {
            let flip = self.flip;
            let extremes = |s: &[T]| {
                s.iter().fold((usize::MAX, 0), |(lo, hi), v| {
                    let k = v.lut_index() ^ flip;
                    (lo.min(k), hi.max(k))
                })
            };
            let owned;
            let values: &[T] = match run.as_slice() {
                Some(s) => s,
                None => {
                    owned = run.iter().collect::<Vec<T>>();
                    &owned
                }
            };
            for (o, &(x0, x1)) in out.iter_mut().zip(windows) {
                let (lo, hi) = extremes(&values[x0..=x1]);
                *o = [self.lut[lo ^ flip], self.lut[hi ^ flip]];
            }
        } else {
            for (o, &(x0, x1)) in out.iter_mut().zip(windows) {
                let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                for v in run.slice(x0..x1 + 1).iter() {
                    // normalised values are never NaN: plain comparisons are min and max
                    let v = self.normalise(v);
                    lo = if v < lo { v } else { lo };
                    hi = if v > hi { v } else { hi };
                }
                *o = [lo, hi];
            }
        }
    }

    /// Normalised voxel at an in-range index.
    #[inline(always)]
    pub fn voxel(&self, i: usize, j: usize, k: usize) -> f32 {
        self.at(i + self.sx * j + self.sxy * k)
    }

    /// Normalised voxel with indices clamped to the grid.
    #[inline(always)]
    pub fn voxel_clamped(&self, i: isize, j: isize, k: isize) -> f32 {
        self.voxel(
            clamp_index(i, self.n[0]),
            clamp_index(j, self.n[1]),
            clamp_index(k, self.n[2]),
        )
    }

    /// The normalised voxels at the eight corners of cell `c` (an axis of a single
    /// voxel repeats voxel 0), corner `(a, b, c)` at index `a + 2 b + 4 c`.
    #[inline]
    pub fn cell_corners(&self, [i, j, k]: [usize; 3]) -> [f32; 8] {
        let step = |x: usize, n: usize| usize::from(x + 1 < n);
        let base = i + self.sx * j + self.sxy * k;
        let (dx, dy, dz) = (
            step(i, self.n[0]),
            self.sx * step(j, self.n[1]),
            self.sxy * step(k, self.n[2]),
        );
        self.corners(base, dx, dy, dz)
    }
}

/// Where gradients come from: the estimator, an optional precomputed gradient
/// volume, and the map from index-space to world-space gradients (the
/// inverse-transpose of the grid's axis matrix, so anisotropic and sheared grids
/// get each axis' own spacing).
#[derive(Clone, Copy, Debug)]
pub struct Gradients<'a> {
    /// The estimator.
    pub method: GradientMethod,
    /// Precomputed index-space gradients at the voxels, when the plan made them.
    pub volume: Option<&'a [[f32; 3]]>,
    /// World gradient = this matrix times the index-space gradient.
    pub world_from_index: DMat3,
}

impl<'a> Gradients<'a> {
    /// Gradients by `method` (on the fly unless `volume` is given) for a grid whose
    /// inverse axis matrix is `index_from_world`.
    pub fn new(
        method: GradientMethod,
        volume: Option<&'a [[f32; 3]]>,
        index_from_world: DMat3,
    ) -> Gradients<'a> {
        Gradients {
            method,
            volume,
            world_from_index: index_from_world.transpose(),
        }
    }

    /// Index-space gradient at voxel (i, j, k) by the estimator, from the grid (the
    /// gradient volume, where there is one, holds these).
    fn estimate<T: Voxel>(&self, grid: &Grid<T>, i: usize, j: usize, k: usize) -> [f32; 3] {
        filter::grid_gradient(self.method, grid.n, [i, j, k], |a, b, c| {
            grid.voxel_clamped(a, b, c)
        })
    }

    /// The world gradient at `p`: the voxel gradients trilinearly interpolated.
    pub fn interpolated<T: Voxel>(&self, grid: &Grid<T>, p: DVec3) -> DVec3 {
        // the gradient volume's eight reads in a loop of their own, not behind the
        // estimator's branch at each corner: how well that shared loop compiled
        // depended on how the crate happened to be split into code-generation
        // units (a build could spend much longer here on the frames of
        // `scenes/transfer_2d.toml`)
        if let Some(g) = self.volume {
            return self.interpolate(grid.n, p, |i, j, k| g[i + grid.sx * j + grid.sxy * k]);
        }
        // without a gradient volume, a Sobel estimate at each of the cell's eight
        // corners reads 54 voxels, all within the 4^3 voxels around the cell: those
        // are read once, and each corner's estimate reads them from there (the same
        // values, so the same bits)
        if self.method == GradientMethod::Sobel {
            let x = p.to_array();
            let first = [0, 1, 2].map(|a| cell(x[a], grid.n[a]).0);
            let block = Neighbourhood::read(grid, first);
            return self.interpolate(grid.n, p, |i, j, k| {
                filter::grid_gradient(self.method, grid.n, [i, j, k], |a, b, c| block.at(a, b, c))
            });
        }
        self.interpolate(grid.n, p, |i, j, k| self.estimate(grid, i, j, k))
    }

    /// The index-space gradients `corner` gives at the corners of the cell of `p`
    /// (in a grid of `n` voxels), trilinearly interpolated (corners of weight zero
    /// left out), and taken to world space.
    #[inline(always)]
    fn interpolate(
        &self,
        n: [usize; 3],
        p: DVec3,
        corner: impl Fn(usize, usize, usize) -> [f32; 3],
    ) -> DVec3 {
        let (i0, i1, fx) = cell(p.x, n[0]);
        let (j0, j1, fy) = cell(p.y, n[1]);
        let (k0, k1, fz) = cell(p.z, n[2]);
        let mut g = [0.0f64; 3];
        for (k, wk) in [(k0, 1.0 - fz), (k1, fz)] {
            for (j, wj) in [(j0, 1.0 - fy), (j1, fy)] {
                for (i, wi) in [(i0, 1.0 - fx), (i1, fx)] {
                    let w = (wi * wj * wk) as f64;
                    if w == 0.0 {
                        continue;
                    }
                    let v = corner(i, j, k);
                    for a in 0..3 {
                        g[a] += w * v[a] as f64;
                    }
                }
            }
        }
        self.world_from_index * DVec3::from_array(g)
    }
}

/// The normalised voxels (indices clamped to the grid) of the 4^3 block from one
/// voxel before a cell's first corner to one after its last, which hold every
/// voxel a grid gradient estimate at the cell's corners reads.
struct Neighbourhood {
    origin: [isize; 3],
    v: [[[f32; 4]; 4]; 4],
}

impl Neighbourhood {
    /// The block around the cell whose first corner is `c`.
    fn read<T: Voxel>(grid: &Grid<T>, c: [usize; 3]) -> Neighbourhood {
        let origin = c.map(|x| x as isize - 1);
        let mut v = [[[0.0f32; 4]; 4]; 4];
        for (dz, plane) in v.iter_mut().enumerate() {
            for (dy, row) in plane.iter_mut().enumerate() {
                for (dx, x) in row.iter_mut().enumerate() {
                    let [a, b, c] = origin;
                    *x = grid.voxel_clamped(a + dx as isize, b + dy as isize, c + dz as isize);
                }
            }
        }
        Neighbourhood { origin, v }
    }

    /// The voxel at `(i, j, k)` with its indices clamped to the grid, as
    /// [`Grid::voxel_clamped`] reads it (for indices within the block).
    #[inline(always)]
    fn at(&self, i: isize, j: isize, k: isize) -> f32 {
        let [a, b, c] = self.origin;
        self.v[(k - c) as usize][(j - b) as usize][(i - a) as usize]
    }
}

#[inline(always)]
pub(super) fn clamp_index(i: isize, n: usize) -> usize {
    i.clamp(0, n as isize - 1) as usize
}

/// The cell `[i0, i1]` containing coordinate `x` on an axis of `n` voxels, and the
/// fraction of the way from `i0` to `i1` (positions outside the grid clamp to it).
#[inline(always)]
pub(super) fn cell(x: f64, n: usize) -> (usize, usize, f32) {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Checks that `g.interpolated` at points inside, on the faces, edges and
    /// corners of, and beyond a grid of `n` voxels gives the bits of each corner's
    /// gradient (`corner(grid, i, j, k)`) interpolated; how many of those gradients
    /// were not zero.
    fn check_corner_reads(
        g: &Gradients,
        values: &[f32],
        n: [usize; 3],
        corner: impl Fn(&Grid<f32>, usize, usize, usize) -> [f32; 3],
    ) -> usize {
        let norm = Normalize::new(0.0, 1.0);
        let lut = normalisation_table::<f32>(norm);
        let grid = Grid::new(Voxels::from_slice(values), n, norm, &lut);
        let reference = |p: DVec3| g.interpolate(n, p, |i, j, k| corner(&grid, i, j, k));
        let mut checked = 0;
        for x in [-1.0, 0.0, 0.3, 1.0, 2.5, 4.99, 5.0, 7.0] {
            for y in [-0.5, 0.0, 1.7, 3.2, 4.0, 6.0] {
                for z in [0.0, 0.45, 1.5, 2.9, 3.0, 9.0] {
                    let p = DVec3::new(x, y, z);
                    let (got, want) = (g.interpolated(&grid, p), reference(p));
                    assert_eq!(
                        got.to_array().map(f64::to_bits),
                        want.to_array().map(f64::to_bits),
                        "{p} in {n:?}"
                    );
                    checked += usize::from(want != DVec3::ZERO);
                }
            }
        }
        checked
    }

    /// Sobel gradients on the fly, each corner's estimate read from the cell's 4^3
    /// neighbourhood, are the bits of each corner's estimate read from the grid
    /// interpolated as before, in grids with an axis of one or two voxels too.
    #[test]
    fn sobel_gradients_from_the_neighbourhood_are_those_from_the_grid() {
        for n in [[6usize, 5, 4], [1, 5, 4], [6, 1, 1], [2, 2, 3]] {
            let len = n[0] * n[1] * n[2];
            let values: Vec<f32> = (0..len)
                .map(|i| ((i * 7919 % 101) as f32 / 101.0).powi(2))
                .collect();
            let m = DMat3::from_diagonal(DVec3::new(1.0, 0.8, 1.3));
            let g = Gradients::new(GradientMethod::Sobel, None, m);
            // each corner's estimate read from the grid
            let checked =
                check_corner_reads(&g, &values, n, |grid, i, j, k| g.estimate(grid, i, j, k));
            assert!(checked > 0, "{n:?}: every gradient zero");
        }
    }

    /// With a gradient volume, the interpolated gradient is the bits of each
    /// corner's gradient read from the volume and interpolated, in grids with an
    /// axis of one voxel too.
    #[test]
    fn gradients_from_a_volume_are_its_voxels_interpolated() {
        for n in [[6usize, 5, 4], [1, 5, 4], [6, 1, 1]] {
            let len = n[0] * n[1] * n[2];
            let volume: Vec<[f32; 3]> = (0..len)
                .map(|i| {
                    [
                        i as f32,
                        (i * 7919 % 101) as f32 / 101.0,
                        -(i as f32).sqrt(),
                    ]
                })
                .collect();
            let m = DMat3::from_diagonal(DVec3::new(1.0, 0.8, 1.3));
            let g = Gradients::new(GradientMethod::Central, Some(&volume), m);
            let at = |_: &Grid<f32>, i, j, k| volume[i + n[0] * (j + n[1] * k)];
            let checked = check_corner_reads(&g, &vec![0.0; len], n, at);
            assert!(checked > 0, "{n:?}: every gradient zero");
        }
    }

    /// Each window's range from `row_ranges` is that of its voxels normalised one
    /// by one: NaN (as 0), infinities, signed zeros, increasing and decreasing
    /// windows, float and integer voxels.
    #[test]
    fn raw_bytes_are_unclamped_where_the_window_covers_both_ends() {
        let n = |lo, hi| Normalize::new(lo, hi);
        assert!(raw_bytes_unclamped(n(0.0, 255.0), [0, 255]));
        assert!(raw_bytes_unclamped(n(255.0, 0.0), [0, 255]));
        assert!(raw_bytes_unclamped(n(10.0, 240.0), [10, 240]));
        assert!(!raw_bytes_unclamped(n(10.0, 240.0), [9, 240]));
        assert!(!raw_bytes_unclamped(n(10.0, 240.0), [10, 241]));
        assert!(!raw_bytes_unclamped(n(0.0, 254.0), [0, 255]));
    }

    #[test]
    fn row_ranges_are_the_normalised_extremes() {
        fn check<T: Voxel>(values: &[T], norm: Normalize) {
            let n = [values.len(), 1, 1];
            let lut = normalisation_table::<T>(norm);
            let grid = Grid::new(Voxels::from_slice(values), n, norm, &lut);
            let windows: Vec<(usize, usize)> = (0..n[0])
                .flat_map(|a| (a..n[0].min(a + 6)).map(move |b| (a, b)))
                .collect();
            let mut out = vec![[0.0f32; 2]; windows.len()];
            grid.row_ranges(0, &windows, &mut out);
            for (&(a, b), got) in windows.iter().zip(&out) {
                let want = (a..=b)
                    .map(|i| grid.at(i))
                    .fold([f32::INFINITY, f32::NEG_INFINITY], |[lo, hi], v| {
                        [lo.min(v), hi.max(v)]
                    });
                assert_eq!(
                    got.map(f32::to_bits),
                    want.map(f32::to_bits),
                    "window {a}..={b} of {:?}",
                    values.iter().map(|v| v.to_f64()).collect::<Vec<_>>()
                );
            }
        }
        let floats = [
            0.25f32,
            f32::NAN,
            -0.0,
            0.0,
            f32::INFINITY,
            0.7,
            f32::NAN,
            f32::NAN,
            -3.0,
            f32::NEG_INFINITY,
            0.5,
            1.5,
        ];
        for norm in [Normalize::new(0.0, 1.0), Normalize::new(1.0, -0.5)] {
            check(&floats, norm);
            check(&floats.map(f64::from), norm);
            check(&[-7i32, 3, 0, 12, -1, 5, 9, 2], norm);
            check(&[7u64, 3, 0, 12, 1, 5, 9, 2], norm);
        }
        check(&[-7i32, 3, 0, 12, -1, 5, 9, 2], Normalize::new(-4.0, 8.0));
    }
}
