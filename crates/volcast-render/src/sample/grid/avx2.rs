//! Trilinear samples four at a time with AVX2 (detected at run time): the positions,
//! the cell search and the interpolation in vector lanes, one sample per lane, the
//! voxels read lane by lane with scalar loads ([`f32_pair`]: not with the gather
//! instructions, which cost several times as much on this project's machines). Each
//! lane does the operations of
//! [`Grid::trilinear_sse2`] in the same order (no fused multiply-add), so a sample has
//! the same bits whichever path takes it, on any machine.
//!
//! The helpers that work on registers alone are safe `#[target_feature]`
//! functions; those that read voxels or tables at indices held in vector lanes
//! are `unsafe fn`s whose contract is that the indices are a cell's rows (each
//! `# Safety` section says which), and each read is an `unsafe` block of its own.

#![deny(unsafe_op_in_unsafe_fn)]

use std::arch::x86_64::*;

use super::Grid;
use crate::sample::Normalize;
use crate::volume::{ScalarType, Voxel};

/// The voxel storage the vector paths read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Gather {
    /// float32 voxels, normalised in f64 lanes.
    Float32,
    /// float32 voxels in the window [0, 1], where normalising is clamping: in f32
    /// lanes, the same bits (`(v - 0) * 1` is `v`, and the clamped value converts
    /// to f64 and back exactly).
    Float32Unit,
    /// float32 voxels in the window [0, 1], every one of them in [0, 1] (checked by
    /// the caller of [`Grid::with_unit_voxels`](super::Grid::with_unit_voxels)):
    /// normalising is the identity, so they are read as they are. The same bits as
    /// [`Gather::Float32Unit`]: the clamp changes only -0 into +0, and an
    /// interpolation `a + (b - a) t` of corners that are zeros of either sign gives
    /// the same bits either way.
    Float32Bare,
    /// 8-bit voxels read as `u8` bits, normalised by the table.
    Bits8,
    /// 8-bit voxels read two at a time, as the 16-bit word they make, normalised by
    /// the table of pairs ([`Grid::with_pairs`](super::Grid::with_pairs)): as
    /// [`Gather::Bits8`], with one table load per row of a cell rather than two.
    Bits8Pairs,
    /// Unsigned 8-bit voxels interpolated as they are, the result normalised in f64
    /// lanes ([`Grid::with_raw_bytes`](super::Grid::with_raw_bytes)): each row's
    /// two bytes become two f32 lanes with integer operations, no table.
    Bits8Raw,
    /// 16-bit voxels read as `u16` bits, normalised by the table.
    Bits16,
}

impl Gather {
    /// The storage a vector path reads voxels of type `ty` as, if any: float32
    /// voxels as they are, 8- and 16-bit ones as the raw bits that index the
    /// normalisation table (signed data is read through them, see `bits_table`).
    const fn storage(ty: ScalarType) -> Option<Gather> {
        match ty {
            ScalarType::Float32 => Some(Gather::Float32),
            ScalarType::Uint8 => Some(Gather::Bits8),
            ScalarType::Uint16 => Some(Gather::Bits16),
            _ => None,
        }
    }

    /// Whether a vector path reads voxels of type `ty`.
    pub(super) const fn reads(ty: ScalarType) -> bool {
        Gather::storage(ty).is_some()
    }

    /// The vector path for voxels of type `T` on a grid of `n` voxels per axis, if
    /// this machine has AVX2 and the grid suits it: the cell search converts to i32
    /// and the flat index multiplies 32-bit lanes, and the x axis has two voxels (so
    /// a cell's two voxels along x are adjacent in memory).
    pub(super) fn for_grid<T: Voxel>(n: [usize; 3], norm: Normalize) -> Option<Gather> {
        let kind = match Gather::storage(T::TYPE)? {
            Gather::Float32 if norm.lo_scale() == (0.0, 1.0) => Gather::Float32Unit,
            kind => kind,
        };
        let fits = n.iter().all(|&n| n < i32::MAX as usize)
            && n[0].checked_mul(n[1]).is_some_and(|s| s < 1 << 31)
            && n[0] >= 2;
        (fits && std::is_x86_feature_detected!("avx2")).then_some(kind)
    }
}

/// The code of a vector path's loop ([`each_storage`]): one per storage kind
/// ([`Gather`]), with raw bytes read by gathers apart (the eight-lane path where
/// gathers pay).
pub(super) struct Loop;

impl Loop {
    pub(super) const F32: u8 = 0;
    pub(super) const F32_UNIT: u8 = 1;
    pub(super) const F32_BARE: u8 = 2;
    pub(super) const BITS8: u8 = 3;
    pub(super) const PAIRS: u8 = 4;
    pub(super) const RAW: u8 = 5;
    pub(super) const RAW_GATHERED: u8 = 6;
    pub(super) const BITS16: u8 = 7;

    /// The loop of storage `kind`, its raw bytes read by gathers if `gathered`.
    #[inline(always)]
    pub(super) fn of(kind: Gather, gathered: bool) -> u8 {
        match kind {
            Gather::Float32 => Loop::F32,
            Gather::Float32Unit => Loop::F32_UNIT,
            Gather::Float32Bare => Loop::F32_BARE,
            Gather::Bits8 => Loop::BITS8,
            Gather::Bits8Pairs => Loop::PAIRS,
            Gather::Bits8Raw if gathered => Loop::RAW_GATHERED,
            Gather::Bits8Raw => Loop::RAW,
            Gather::Bits16 => Loop::BITS16,
        }
    }
}

/// How the paths that read a row's two voxels as one 64-bit word get that word and
/// normalise its voxels (their const parameter): two float32 voxels normalised in
/// f64 lanes ([`Gather::Float32`]), by clamping ([`Gather::Float32Unit`]) or not at
/// all ([`Gather::Float32Bare`]), or the normalised pair of two 8-bit voxels from
/// the table of pairs ([`Gather::Bits8Pairs`]).
pub(super) const ROW_GENERAL: u8 = 0;
pub(super) const ROW_UNIT: u8 = 1;
pub(super) const ROW_BARE: u8 = 2;
pub(super) const ROW_PAIRS: u8 = 3;

/// What the vector paths broadcast into their lanes for one call.
pub(super) struct LaneConstants {
    /// The voxel storage the vector paths read.
    pub kind: Gather,
    /// Per axis: the ray's origin and direction, the last voxel and the last cell's
    /// first voxel (positions are clamped to them).
    pub axes: [[f64; 4]; 3],
    /// The flat strides of y and z.
    pub strides: [i64; 2],
    /// The flat offsets of a cell's four rows along x (y0z0, y1z0, y0z1, y1z1).
    pub rows: [i64; 4],
}

impl<T: Voxel> Grid<'_, T> {
    /// The constants of the vector paths for the ray `o + d t`.
    pub(super) fn lane_constants(&self, o: [f64; 3], d: [f64; 3]) -> LaneConstants {
        let kind = self.gather.expect("the caller checked the gather path");
        let [_, dy, dz] = self.step;
        LaneConstants {
            kind,
            axes: [0, 1, 2].map(|a| [o[a], d[a], self.last[a], self.top_f[a]]),
            strides: [self.sx as i64, self.sxy as i64],
            rows: [0, dy, dz, dy + dz].map(|r| r as i64),
        }
    }
}

impl<T: Voxel> Grid<'_, T> {
    /// The trilinear samples at `o + d t` (index space) for each `t` of `ts`, into
    /// `out` (as long as `ts`): the bits of [`Grid::trilinear`] at each position
    /// (with `RAW`, on a grid of raw bytes, the raw values of
    /// [`Grid::trilinear_along`]). Safe to call where AVX2 is enabled; a grid whose
    /// `gather` is set (only where the machine has AVX2, [`Gather::for_grid`]) may
    /// call it with `unsafe` after that check.
    ///
    /// # Panics
    /// Where `self.gather` is `None`, or `out` is shorter than `ts`.
    #[target_feature(enable = "avx2")]
    pub(super) fn trilinear_avx2<const RAW: bool>(
        &self,
        o: [f64; 3],
        d: [f64; 3],
        ts: &[f64],
        out: &mut [f32],
    ) {
        debug_assert_eq!(ts.len(), out.len());
        let c = self.lane_constants(o, d);
        let groups = ts.len() / 4;
        let (ts4, out4) = (&ts[..4 * groups], &mut out[..4 * groups]);
        macro_rules! run {
            ($k:expr) => {
                // SAFETY: `each_storage!` runs the loop of `c.kind`, the grid's
                // storage; `ts4` and `out4` are whole groups of four, as long
                unsafe { self.groups_avx2::<RAW, { $k }>(&c, ts4, out4) }
            };
        }
        each_storage!(T, RAW, c.kind, false, run);
        for k in 4 * groups..ts.len() {
            let t = ts[k];
            out[k] = self.single::<RAW>([0, 1, 2].map(|a| o[a] + d[a] * t));
        }
    }

    /// [`Grid::trilinear_avx2`] of whole groups of four (`ts.len()` a multiple of
    /// 4), with the loop of storage `K` ([`Loop`]).
    ///
    /// # Safety
    /// `K` is the loop of this grid's storage (`Loop::of(self.gather, false)`: it
    /// reads the voxels as that storage's type, and the table of pairs only where
    /// the grid has one), and `ts` and `out` have the same length, a multiple of 4.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn groups_avx2<const RAW: bool, const K: u8>(
        &self,
        c: &LaneConstants,
        ts: &[f64],
        out: &mut [f32],
    ) {
        debug_assert!(ts.len().is_multiple_of(4) && ts.len() == out.len());
        let (axes, [sx, sxy], rows) = broadcast_lanes!(c, _mm256_set1_epi64x);
        for g in 0..ts.len() / 4 {
            // SAFETY: 4 g + 3 < ts.len()
            let t = unsafe { _mm256_loadu_pd(ts.as_ptr().add(4 * g)) };
            let (ix, fx) = locate(&axes[0], t);
            let (iy, fy) = locate(&axes[1], t);
            let (iz, fz) = locate(&axes[2], t);
            // flat index of each lane's cell: i + sx j + sxy k (each below 2^31, the
            // products below 2^62)
            // SAFETY (each row read below): `locate` clamps each axis to the
            // grid's cells, so `base + rows[r]` is a cell's row start and it and
            // the voxel after it are voxels; `K` is the grid's storage (the caller's)
            let base = _mm256_add_epi64(
                _mm256_add_epi64(
                    _mm256_cvtepi32_epi64(ix),
                    _mm256_mul_epu32(_mm256_cvtepi32_epi64(iy), sx),
                ),
                _mm256_mul_epu32(_mm256_cvtepi32_epi64(iz), sxy),
            );
            let sample = match K {
                Loop::F32 => {
                    let c = unsafe {
                        each_row!(self.row_words::<ROW_GENERAL>, _mm256_add_epi64, base, rows)
                    };
                    interpolate(c, fx, fy, fz)
                }
                Loop::F32_UNIT => {
                    let c = unsafe {
                        each_row!(self.row_words::<ROW_UNIT>, _mm256_add_epi64, base, rows)
                    };
                    interpolate(c, fx, fy, fz)
                }
                Loop::F32_BARE => {
                    let c = unsafe {
                        each_row!(self.row_words::<ROW_BARE>, _mm256_add_epi64, base, rows)
                    };
                    interpolate(c, fx, fy, fz)
                }
                Loop::BITS16 => {
                    let c = unsafe { each_row!(self.row_bits::<2>, _mm256_add_epi64, base, rows) };
                    interpolate(c, fx, fy, fz)
                }
                Loop::BITS8 => {
                    let c = unsafe { each_row!(self.row_bits::<1>, _mm256_add_epi64, base, rows) };
                    interpolate(c, fx, fy, fz)
                }
                Loop::PAIRS => {
                    let c = unsafe {
                        each_row!(self.row_words::<ROW_PAIRS>, _mm256_add_epi64, base, rows)
                    };
                    interpolate(c, fx, fy, fz)
                }
                _ => {
                    // raw bytes (the four-lane path reads them with scalar loads)
                    let c = unsafe { each_row!(self.row_bytes, _mm256_add_epi64, base, rows) };
                    let v = lerps(c, fx, fy, fz);
                    if RAW {
                        v
                    } else {
                        normalise(&self.norm, v)
                    }
                }
            };
            // SAFETY: 4 g + 3 < ts.len() == out.len() (the caller's)
            unsafe { _mm_storeu_ps(out.as_mut_ptr().add(4 * g), sample) };
        }
    }

    /// The normalised voxels at flat indices `at` and `at + 1` of each lane:
    /// (voxel `at` of lanes 0..4, voxel `at + 1` of lanes 0..4): float32 voxels
    /// normalised as `KIND` says ([`ROW_GENERAL`], [`ROW_UNIT`], [`ROW_BARE`]), or
    /// 8-bit ones through the table of pairs ([`ROW_PAIRS`]).
    ///
    /// # Safety
    /// Every lane's `at` and `at + 1` are voxels of the grid (`at` a cell's row
    /// start); the voxels are float32, or with [`ROW_PAIRS`], 8-bit with a table of
    /// pairs ([`Grid::pair_word`]).
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn row_words<const KIND: u8>(&self, at: __m256i) -> (__m128, __m128) {
        // SAFETY: four i64 lanes, and every bit pattern is an i64
        let at: [i64; 4] = unsafe { std::mem::transmute(at) };
        // SAFETY (the caller's): each lane reads the two adjacent voxels `at` and
        // `at + 1` as one word
        let w = |k: usize| unsafe {
            if KIND == ROW_PAIRS {
                self.pair_word(at[k])
            } else {
                f32_pair(self.voxels.as_ptr().cast(), at[k])
            }
        };
        let pairs = _mm256_castsi256_ps(_mm256_set_epi64x(w(3), w(2), w(1), w(0)));
        let lo = _mm256_castps256_ps128(pairs); // a0 b0 a1 b1
        let hi = _mm256_extractf128_ps::<1>(pairs); // a2 b2 a3 b3
        let a = _mm_shuffle_ps::<0b10_00_10_00>(lo, hi);
        let b = _mm_shuffle_ps::<0b11_01_11_01>(lo, hi);
        if KIND == ROW_BARE || KIND == ROW_PAIRS {
            return (a, b);
        }
        if KIND == ROW_UNIT {
            // max with 0 (NaN -> 0, -0 -> 0), min with 1, as below
            let (zero, one) = (_mm_setzero_ps(), _mm_set1_ps(1.0));
            let clamp = |v: __m128| _mm_min_ps(_mm_max_ps(v, zero), one);
            return (clamp(a), clamp(b));
        }
        // as `trilinear_sse2`
        (normalise(&self.norm, a), normalise(&self.norm, b))
    }

    /// The 8-bit voxels at flat indices `at` and `at + 1` of each lane as floats,
    /// not normalised ([`Gather::Bits8Raw`]).
    ///
    /// # Safety
    /// Every lane's `at` and `at + 1` are voxels of the grid, whose voxels are 8-bit.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn row_bytes(&self, at: __m256i) -> (__m128, __m128) {
        // SAFETY: four i64 lanes, and every bit pattern is an i64
        let at: [i64; 4] = unsafe { std::mem::transmute(at) };
        // SAFETY (the caller's): every `at` is a cell's row start, so `at + 1` is a
        // voxel; each lane reads the two bytes as one 16-bit word
        let w = |k: usize| i32::from(unsafe { self.byte_pair(at[k]) });
        bytes_to_floats(_mm_set_epi32(w(3), w(2), w(1), w(0)))
    }

    /// The two 8-bit voxels at flat index `at` and `at + 1` as one little-endian
    /// 16-bit word.
    ///
    /// # Safety
    /// Voxels `at` and `at + 1` are in the grid, whose voxels are 8-bit.
    #[inline(always)]
    pub(super) unsafe fn byte_pair(&self, at: i64) -> u16 {
        // SAFETY (the caller's): bytes `at` and `at + 1` are in the data
        let word = unsafe {
            let p = self.voxels.as_ptr().cast::<u8>().add(at as usize);
            p.cast::<u16>().read_unaligned()
        };
        u16::from_le(word)
    }

    /// The normalised 8- or 16-bit voxels (`BYTES` per voxel) at flat indices `at`
    /// and `at + 1` of each lane, through the normalisation table.
    ///
    /// # Safety
    /// As [`Grid::row_bits_lanes`]: every lane's `at` and `at + 1` are voxels of the
    /// grid, which holds `BYTES`-byte voxels, and `BYTES` is 1 or 2.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn row_bits<const BYTES: usize>(&self, at: __m256i) -> (__m128, __m128) {
        // SAFETY: four i64 lanes, and every bit pattern is an i64
        let at: [i64; 4] = unsafe { std::mem::transmute(at) };
        // SAFETY (the caller's): every `at` is a cell's row start, so `at + 1` is a
        // voxel
        let [a, b] = unsafe { self.row_bits_lanes::<BYTES, 4>(at) };
        // SAFETY: `a` and `b` are four f32 each
        unsafe { (_mm_loadu_ps(a.as_ptr()), _mm_loadu_ps(b.as_ptr())) }
    }

    /// The normalised 8-bit voxels at flat indices `at` and `at + 1`, as one 64-bit
    /// word (the first in the low half): the entry of the table of pairs
    /// ([`Gather::Bits8Pairs`]) for the 16-bit word the two voxels make.
    ///
    /// # Safety
    /// Voxels `at` and `at + 1` are in the grid, whose voxels are 8-bit and whose
    /// table of pairs has 2^16 entries.
    #[inline(always)]
    pub(super) unsafe fn pair_word(&self, at: i64) -> i64 {
        debug_assert_eq!(self.pairs.len(), 1 << 16);
        // SAFETY (the caller's): bytes `at` and `at + 1` are in the data
        let word = unsafe {
            self.voxels
                .as_ptr()
                .cast::<u8>()
                .add(at as usize)
                .cast::<u16>()
                .read_unaligned()
        };
        // SAFETY: a 16-bit word indexes the table's 2^16 entries (the caller's); an
        // entry is two f32 (8 bytes, aligned to 4)
        unsafe {
            self.pairs
                .as_ptr()
                .add(usize::from(u16::from_le(word)))
                .cast::<i64>()
                .read_unaligned()
        }
    }

    /// The normalised 8- or 16-bit voxels (`BYTES` per voxel) at flat indices `at`
    /// and `at + 1` of each of `N` lanes, through the normalisation table, one lane
    /// at a time (scalar loads, as [`f32_pair`]).
    ///
    /// # Safety
    /// Every `at` and `at + 1` is a voxel of the grid, which holds `BYTES`-byte
    /// voxels, and `BYTES` is 1 or 2.
    #[inline(always)]
    pub(super) unsafe fn row_bits_lanes<const BYTES: usize, const N: usize>(
        &self,
        at: [i64; N],
    ) -> [[f32; N]; 2] {
        debug_assert!(BYTES <= 2 && self.lut.len() == 1 << (8 * BYTES));
        let data = self.voxels.as_ptr().cast::<u8>();
        // SAFETY: the table has 2^(8 BYTES) entries (`Grid::new`: one per value of
        // the voxel type, whose size `BYTES` is) and every index is below that
        let lut = |i: u32| unsafe { *self.lut.get_unchecked(i as usize) };
        let mut a = [0.0f32; N];
        let mut b = [0.0f32; N];
        for k in 0..N {
            // SAFETY (the caller's): voxels `at` and `at + 1`, 2 BYTES bytes, are
            // inside the data
            let (lo, hi) = unsafe {
                let p = data.add(at[k] as usize * BYTES);
                if BYTES == 1 {
                    let w = u32::from(p.cast::<u16>().read_unaligned());
                    (w & 0xff, w >> 8)
                } else {
                    let w = p.cast::<u32>().read_unaligned();
                    (w & 0xffff, w >> 16)
                }
            };
            a[k] = lut(lo);
            b[k] = lut(hi);
        }
        [a, b]
    }
}

/// The two adjacent float32 voxels at flat index `at` of `data`, as one 64-bit
/// word: what each lane of the float32 paths reads, with a scalar load rather
/// than a gather instruction, which is microcoded (and slow) on processors with
/// the "Gather Data Sampling" mitigation and did not pay on the others measured
/// (bench/peers/README.md, "Loads, not gathers"), except for the eight-lane
/// path's float32 rows on some processors (`avx512::gathers_pay`).
///
/// # Safety
/// Voxels `at` and `at + 1` are inside `data`'s allocation.
#[inline(always)]
pub(super) unsafe fn f32_pair(data: *const f32, at: i64) -> i64 {
    // SAFETY (the caller's): the 8 bytes from voxel `at` are in the allocation
    unsafe { data.add(at as usize).cast::<i64>().read_unaligned() }
}

/// One axis' broadcast constants: the ray's origin and direction, the clamp to the
/// grid and the last cell.
struct Axis {
    o: __m256d,
    d: __m256d,
    last: __m256d,
    top: __m256d,
}

impl Axis {
    /// The lanes of one axis' `[o, d, last, top]` ([`LaneConstants::axes`]).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn new([o, d, last, top]: [f64; 4]) -> Axis {
        Axis {
            o: _mm256_set1_pd(o),
            d: _mm256_set1_pd(d),
            last: _mm256_set1_pd(last),
            top: _mm256_set1_pd(top),
        }
    }
}

/// The position `o + d t` on one axis, clamped to the grid (NaN to 0), as the
/// cell's first voxel (i32 lanes) and the fraction across it: `trilinear_sse2`'s
/// operations.
#[target_feature(enable = "avx2")]
#[inline]
fn locate(a: &Axis, t: __m256d) -> (__m128i, __m128) {
    let x = _mm256_add_pd(a.o, _mm256_mul_pd(a.d, t));
    let x = _mm256_min_pd(_mm256_max_pd(x, _mm256_setzero_pd()), a.last);
    let i = _mm256_cvttpd_epi32(_mm256_min_pd(x, a.top));
    let f = _mm256_cvtpd_ps(_mm256_sub_pd(x, _mm256_cvtepi32_pd(i)));
    (i, f)
}

/// The trilinear interpolation of four lanes' cells from their rows (corner pairs
/// along x of rows y0z0, y1z0, y0z1, y1z1): along x, then y, then z, each
/// `a + (b - a) t`, clamped to [0, 1] as `f32::clamp` does.
#[target_feature(enable = "avx2")]
#[inline]
fn interpolate(c: [(__m128, __m128); 4], fx: __m128, fy: __m128, fz: __m128) -> __m128 {
    let v = lerps(c, fx, fy, fz);
    // `max(0, v)` keeps v when both are zeros (so -0.0 stays) and when v is NaN,
    // then `min(1, .)` likewise: f32::clamp's results
    _mm_min_ps(_mm_set1_ps(1.0), _mm_max_ps(_mm_setzero_ps(), v))
}

/// The low bytes of each 32-bit lane (as [`Grid::byte_pair`] gives them: voxel
/// `at` in bits 0-7, `at + 1` in bits 8-15) as two lanes of floats.
#[target_feature(enable = "avx2")]
#[inline]
fn bytes_to_floats(w: __m128i) -> (__m128, __m128) {
    let m = _mm_set1_epi32(0xff);
    let a = _mm_and_si128(w, m);
    let b = _mm_and_si128(_mm_srli_epi32::<8>(w), m);
    (_mm_cvtepi32_ps(a), _mm_cvtepi32_ps(b))
}

/// Four lanes normalised as [`Normalize::apply`] does: `(v - lo) * scale` in f64,
/// max with 0 (NaN -> 0), min with 1 (float32 voxels, or interpolated bytes).
#[target_feature(enable = "avx2")]
#[inline]
fn normalise(norm: &Normalize, v: __m128) -> __m128 {
    let (l, s) = norm.lo_scale();
    let x = _mm256_mul_pd(
        _mm256_sub_pd(_mm256_cvtps_pd(v), _mm256_set1_pd(l)),
        _mm256_set1_pd(s),
    );
    _mm256_cvtpd_ps(_mm256_min_pd(
        _mm256_max_pd(x, _mm256_setzero_pd()),
        _mm256_set1_pd(1.0),
    ))
}

/// [`interpolate`] without the clamp.
#[target_feature(enable = "avx2")]
#[inline]
fn lerps(c: [(__m128, __m128); 4], fx: __m128, fy: __m128, fz: __m128) -> __m128 {
    let lerp = |a: __m128, b: __m128, t: __m128| _mm_add_ps(a, _mm_mul_ps(_mm_sub_ps(b, a), t));
    // written out: `array::map`'s closure calls are not always inlined
    let x = [
        lerp(c[0].0, c[0].1, fx),
        lerp(c[1].0, c[1].1, fx),
        lerp(c[2].0, c[2].1, fx),
        lerp(c[3].0, c[3].1, fx),
    ];
    let y0 = lerp(x[0], x[1], fy);
    let y1 = lerp(x[2], x[3], fy);
    lerp(y0, y1, fz)
}

#[cfg(test)]
mod tests {
    use super::super::{bits_table, normalisation_table, pair_table, CellCache, Grid};
    use super::Gather;
    use crate::sample::Normalize;
    use crate::volume::{ScalarType, Voxel, Voxels};

    /// How a test grid reads its voxels.
    #[derive(Clone, Copy, PartialEq)]
    enum Read {
        /// As their type says.
        Plain,
        /// Told that they lie in [0, 1] ([`Grid::with_unit_voxels`]).
        Bare,
        /// 8- or 16-bit voxels as the bits of signed data ([`Grid::signed_bits`]).
        Signed,
        /// 8-bit voxels through the table of pairs ([`Grid::with_pairs`]).
        Pairs,
        /// Both: signed 8-bit data through its table of pairs.
        SignedPairs,
        /// Unsigned 8-bit voxels interpolated as they are ([`Grid::with_raw_bytes`]).
        Raw,
    }

    /// Samples along random rays (inside, across and outside the grid, with NaN and
    /// out-of-window voxels, on grids whose last row ends the data) taken four (AVX2)
    /// or eight (AVX-512) at a time have the bits of one sample at a time, for each
    /// voxel type the vector paths read.
    fn along_is_one_at_a_time<T: Voxel>(
        voxel: impl Fn(usize) -> T,
        norm: Normalize,
        expect: Option<Gather>,
        read: Read,
    ) {
        // calls of the AVX2 and of the AVX-512 path (0 where the machine lacks one)
        let mut paths = [0usize; 2];
        for n in [
            [9, 8, 7],
            [2, 3, 2],
            [5, 1, 4],
            [3, 4, 1],
            [2, 2, 1],
            [3, 1, 1],
        ] {
            let len = n[0] * n[1] * n[2];
            let v: Vec<T> = (0..len).map(&voxel).collect();
            let lut = if matches!(read, Read::Signed | Read::SignedPairs) {
                let ty = [ScalarType::Int8, ScalarType::Int16][usize::from(T::LUT_SIZE > 256)];
                bits_table(ty, norm).expect("8- or 16-bit")
            } else {
                normalisation_table::<T>(norm)
            };
            let pairs = if T::LUT_SIZE == 256 {
                pair_table(&lut)
            } else {
                Vec::new()
            };
            let mut g = Grid::new(Voxels::from_slice(&v), n, norm, &lut);
            if matches!(read, Read::Signed | Read::SignedPairs) {
                g = g.signed_bits();
            }
            // the single samples the others are held to: through the normalisation
            // table, even where `g` reads pairs (its single samples read them too);
            // for raw bytes, the scalar path's (without SSE2)
            let plain = g;
            let reference = if read == Read::Raw {
                g.with_raw_bytes()
            } else {
                g
            };
            match read {
                Read::Plain | Read::Signed => {}
                Read::Bare => g = g.with_unit_voxels(),
                Read::Pairs | Read::SignedPairs => g = g.with_pairs(&pairs),
                // (the table of pairs is not read by a grid of raw bytes)
                Read::Raw => g = g.with_pairs(&pairs).with_raw_bytes(),
            }
            if std::is_x86_feature_detected!("avx2") {
                assert_eq!(g.gather, expect, "{n:?}");
            }
            let mut state = 12345u64;
            let mut next = |lo: f64, hi: f64| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                lo + (state >> 11) as f64 / (1u64 << 53) as f64 * (hi - lo)
            };
            for ray in 0..300 {
                let mut o = [0, 1, 2].map(|a| next(-2.0, n[a] as f64 + 1.0));
                let mut d = [0, 1, 2].map(|_| next(-1.0, 1.0));
                let count = (next(0.0, 40.0)) as usize;
                let mut t0 = next(-3.0, 1.0);
                if ray % 3 == 0 {
                    // short steps from the middle: every position inside the grid's
                    // cells, where the AVX-512 path leaves out its clamps
                    o = [0, 1, 2].map(|a| 0.5 * (n[a] - 1) as f64 + next(-0.2, 0.2));
                    d = d.map(|x| x * 0.05);
                    t0 = 0.0;
                }
                let ts: Vec<f64> = (0..count).map(|k| t0 + 0.37 * k as f64).collect();
                // the dispatching call, and each vector path this machine has
                let mut outs = vec![vec![0.0f32; count]];
                g.trilinear_along::<false>(o, d, &ts, &mut outs[0], &mut CellCache::default());
                if g.gather.is_some() {
                    let mut out = vec![0.0f32; count];
                    // SAFETY: the machine has AVX2 (`gather` is set)
                    unsafe { g.trilinear_avx2::<false>(o, d, &ts, &mut out) };
                    outs.push(out);
                    paths[0] += 1;
                    if super::super::avx512::available() {
                        // rows read with loads and with gathers, whichever this
                        // machine's grids choose
                        for row_gathers in [false, true] {
                            let g = Grid { row_gathers, ..g };
                            let mut out = vec![0.0f32; count];
                            // SAFETY: and AVX-512
                            unsafe { g.trilinear_avx512::<false>(o, d, &ts, &mut out) };
                            outs.push(out);
                            paths[1] += 1;
                        }
                    }
                }
                // and for raw bytes, the values before their normalisation
                // (`Grid::trilinear_along::<true>`), through the dispatching call and each path
                let mut raws = Vec::new();
                if read == Read::Raw {
                    let mut out = vec![0.0f32; count];
                    g.trilinear_along::<true>(o, d, &ts, &mut out, &mut CellCache::default());
                    raws.push(out);
                    if g.gather.is_some() {
                        let mut out = vec![0.0f32; count];
                        // SAFETY: as above
                        unsafe { g.trilinear_avx2::<true>(o, d, &ts, &mut out) };
                        raws.push(out);
                        if super::super::avx512::available() {
                            for row_gathers in [false, true] {
                                let g = Grid { row_gathers, ..g };
                                let mut out = vec![0.0f32; count];
                                // SAFETY: as above
                                unsafe { g.trilinear_avx512::<true>(o, d, &ts, &mut out) };
                                raws.push(out);
                            }
                        }
                    }
                }
                for (k, &t) in ts.iter().enumerate() {
                    let p = [0, 1, 2].map(|a| o[a] + d[a] * t);
                    for out in &raws {
                        let raw = reference.trilinear_scalar::<true>(p);
                        assert_eq!(out[k].to_bits(), raw.to_bits(), "raw {n:?} {p:?}");
                        let sample = norm.apply(f64::from(raw));
                        assert_eq!(sample.to_bits(), g.trilinear(p).to_bits(), "{p:?}");
                    }
                    let bits = if read == Read::Raw {
                        // and the interpolant of the normalised voxels, up to rounding
                        // (the windows of raw bytes cover every voxel)
                        let (raw, normalised) =
                            (reference.trilinear_scalar::<false>(p), plain.trilinear(p));
                        assert!((raw - normalised).abs() <= 4e-7, "{raw} {normalised}");
                        raw.to_bits()
                    } else {
                        reference.trilinear(p).to_bits()
                    };
                    assert_eq!(g.trilinear(p).to_bits(), bits, "single {n:?} {p:?}");
                    let paths = ["dispatch", "AVX2", "AVX-512 loads", "AVX-512 gathers"];
                    for (path, out) in paths.iter().zip(&outs) {
                        assert_eq!(out[k].to_bits(), bits, "{path} {n:?} {p:?}");
                    }
                }
            }
        }
        eprintln!("vector paths checked (AVX2, AVX-512 calls): {paths:?}");
    }

    /// float32 voxels in and out of the window, NaN, infinities and negative zero.
    fn float(i: usize) -> f32 {
        match i % 13 {
            0 => f32::NAN,
            1 => f32::INFINITY,
            2 => f32::NEG_INFINITY,
            3 => -0.0,
            _ => ((i * 37 % 101) as f32 - 20.0) / 70.0,
        }
    }

    #[test]
    fn float32_samples_along_a_ray_are_the_single_samples() {
        let norm = Normalize::new(-0.1, 1.2);
        along_is_one_at_a_time(float, norm, Some(Gather::Float32), Read::Plain);
    }

    #[test]
    fn float32_samples_in_the_unit_window_are_the_single_samples() {
        let norm = Normalize::new(0.0, 1.0);
        along_is_one_at_a_time(float, norm, Some(Gather::Float32Unit), Read::Plain);
    }

    /// float32 voxels all in [0, 1], zeros of both signs and both ends among them.
    fn unit(i: usize) -> f32 {
        match i % 11 {
            0 => -0.0,
            1 => 0.0,
            2 => 1.0,
            3 => f32::from_bits(1), // the smallest positive value
            _ => (i * 37 % 101) as f32 / 100.0,
        }
    }

    #[test]
    fn unit_voxels_read_bare_are_the_single_samples() {
        // read as they are, without the clamp: the bits of the clamped single samples
        let norm = Normalize::new(0.0, 1.0);
        along_is_one_at_a_time(unit, norm, Some(Gather::Float32Bare), Read::Bare);
        // and only in the unit window: any other stays as it was
        let norm = Normalize::new(-0.1, 1.2);
        along_is_one_at_a_time(unit, norm, Some(Gather::Float32), Read::Bare);
    }

    /// Windows of 8- and 16-bit data: inside the values, around them, decreasing
    /// (a negative rescale slope), and narrower than a step of the values.
    fn windows(max: f64) -> [Normalize; 5] {
        [
            Normalize::new(-0.1, max - 5.0),
            Normalize::new(0.0, max),
            Normalize::new(-max - 1.0, 2.0 * max),
            Normalize::new(max * 0.7, max * 0.2),
            Normalize::new(3.0, 3.0 + 1e-9),
        ]
    }

    #[test]
    fn uint8_samples_along_a_ray_are_the_single_samples() {
        for norm in windows(255.0) {
            let voxel = |i: usize| (i * 53 % 256) as u8;
            along_is_one_at_a_time(voxel, norm, Some(Gather::Bits8), Read::Plain);
            along_is_one_at_a_time(voxel, norm, Some(Gather::Bits8Pairs), Read::Pairs);
        }
    }

    #[test]
    fn uint8_samples_of_raw_bytes_are_the_single_samples() {
        // the windows that cover every byte value: as given, wider, decreasing
        for norm in [
            Normalize::new(0.0, 255.0),
            Normalize::new(-256.0, 510.0),
            Normalize::new(255.0, 0.0),
        ] {
            let voxel = |i: usize| (i * 53 % 256) as u8;
            along_is_one_at_a_time(voxel, norm, Some(Gather::Bits8Raw), Read::Raw);
        }
    }

    #[test]
    fn raw_bytes_at_voxels_are_the_normalised_voxels() {
        let n = [4, 3, 2];
        let v: Vec<u8> = (0..24).map(|i| (i * 97 % 256) as u8).collect();
        for norm in [Normalize::new(0.0, 255.0), Normalize::new(255.0, -3.0)] {
            let lut = normalisation_table::<u8>(norm);
            let g = Grid::new(Voxels::from_slice(&v), n, norm, &lut);
            let raw = g.with_raw_bytes();
            for (i, _) in v.iter().enumerate() {
                let p = [i % 4, i / 4 % 3, i / 12].map(|x| x as f64);
                assert_eq!(raw.trilinear(p).to_bits(), g.at(i).to_bits(), "{p:?}");
                assert_eq!(
                    raw.trilinear_scalar::<false>(p).to_bits(),
                    g.at(i).to_bits(),
                    "{p:?}"
                );
            }
        }
    }

    /// Raw values map to the samples only through a window that increases (a
    /// decreasing one would turn the largest raw value into the smallest sample).
    #[test]
    fn raw_values_map_to_samples_only_through_an_increasing_window() {
        let v = [1u8, 2, 3, 4];
        for (norm, mapped) in [
            (Normalize::new(0.0, 255.0), true),
            (Normalize::new(-256.0, 510.0), true),
            (Normalize::new(255.0, 0.0), false),
        ] {
            let lut = normalisation_table::<u8>(norm);
            let g = Grid::new(Voxels::from_slice(&v), [4, 1, 1], norm, &lut);
            assert!(g.raw_map().is_none(), "not a grid of raw bytes");
            let raw = g.with_raw_bytes().raw_map();
            assert_eq!(raw.is_some(), mapped, "{:?}", norm.lo_scale());
        }
    }

    #[test]
    fn only_unsigned_bytes_are_read_raw() {
        let v = [1u8, 2, 3, 4];
        let norm = Normalize::new(0.0, 255.0);
        let lut = bits_table(ScalarType::Int8, norm).expect("8-bit");
        let signed = Grid::new(Voxels::from_slice(&v), [4, 1, 1], norm, &lut).signed_bits();
        assert!(!signed.with_raw_bytes().raw_bytes);
        let v = [1u16, 2, 3, 4];
        let lut = normalisation_table::<u16>(norm);
        assert!(
            !Grid::new(Voxels::from_slice(&v), [4, 1, 1], norm, &lut)
                .with_raw_bytes()
                .raw_bytes
        );
    }

    #[test]
    fn int8_samples_along_a_ray_are_the_single_samples() {
        for norm in windows(127.0) {
            let voxel = |i: usize| (i * 53 % 256) as u8;
            along_is_one_at_a_time(voxel, norm, Some(Gather::Bits8), Read::Signed);
            let pairs = Some(Gather::Bits8Pairs);
            along_is_one_at_a_time(voxel, norm, pairs, Read::SignedPairs);
        }
    }

    #[test]
    fn uint16_samples_along_a_ray_are_the_single_samples() {
        for norm in windows(65535.0) {
            let voxel = |i: usize| (i * 4099 % 65536) as u16;
            along_is_one_at_a_time(voxel, norm, Some(Gather::Bits16), Read::Plain);
        }
    }

    #[test]
    fn int16_samples_along_a_ray_are_the_single_samples() {
        for norm in windows(32767.0) {
            let voxel = |i: usize| (i * 4099 % 65536) as u16;
            along_is_one_at_a_time(voxel, norm, Some(Gather::Bits16), Read::Signed);
        }
    }
}
