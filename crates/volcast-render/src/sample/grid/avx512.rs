//! Trilinear samples eight at a time with AVX-512 (detected at run time): the
//! AVX2 path of `avx2.rs` on twice as many lanes. The positions and the cell search
//! take 512-bit f64 lanes, the voxel loads 64-bit indices in 512-bit vectors (read
//! lane by lane, as in `avx2.rs`, or with a gather per float32 row on the
//! processors where gathers pay, [`gathers_pay`]), and the interpolation 256-bit
//! f32 lanes. Each lane does the operations of
//! [`Grid::trilinear_sse2`] in the same order (no fused multiply-add), so a sample
//! has the same bits whichever path takes it.
//!
//! As in `avx2.rs`, the helpers that work on registers alone are safe
//! `#[target_feature]` functions, and those that read voxels at indices held in
//! vector lanes are `unsafe fn`s whose `# Safety` sections say which indices.

#![deny(unsafe_op_in_unsafe_fn)]

use std::arch::x86_64::*;

use super::avx2::{
    f32_pair, Gather, LaneConstants, Loop, ROW_BARE, ROW_GENERAL, ROW_PAIRS, ROW_UNIT,
};
use super::Grid;
use crate::sample::Normalize;
use crate::volume::Voxel;

/// Whether this machine runs the eight-lane path (AVX-512 Foundation, with AVX2 for
/// the 256-bit halves).
pub(super) fn available() -> bool {
    std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("avx2")
}

/// Whether the eight-lane float32 path reads its rows with gather instructions:
/// on Intel's server cores from Sapphire Rapids on (family 6, models 0x8f and
/// 0xcf), which the "Gather Data Sampling" mitigation does not cover, an
/// eight-lane gather is faster than eight scalar loads put into a vector
/// (`bench/peers/README.md`). Elsewhere they do not pay where that mitigation
/// microcodes them, nor on the AMD processors measured; on the other Intel cores
/// with AVX-512 (Skylake to Rocket Lake) they pay where the kernel reports the
/// processor not affected by that mitigation (`gather_data_sampling`: "Not
/// affected"). Either way a row reads the same two words, so the choice changes
/// the time and not the bits.
pub(super) fn gathers_pay() -> bool {
    static PAY: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *PAY.get_or_init(|| {
        // (every x86-64 processor has CPUID leaves 0 and 1)
        let (vendor, signature) = (__cpuid(0), __cpuid(1).eax);
        // "GenuineIntel", as EBX, EDX, ECX
        let intel = [vendor.ebx, vendor.edx, vendor.ecx] == [0x756e_6547, 0x4965_6e69, 0x6c65_746e];
        let family = (signature >> 8) & 0xf;
        let model = ((signature >> 4) & 0xf) | ((signature >> 12) & 0xf0);
        intel && family == 6 && (matches!(model, 0x8f | 0xcf) || gathers_not_microcoded())
    })
}

/// Whether the kernel reports this processor not affected by "Gather Data
/// Sampling" (Linux's `gather_data_sampling` file), and so its gathers not
/// slowed by that mitigation's microcode; false where it says anything else
/// ("Mitigation: Microcode", "Vulnerable", "Unknown: ...") or there is no such file.
fn gathers_not_microcoded() -> bool {
    std::fs::read_to_string("/sys/devices/system/cpu/vulnerabilities/gather_data_sampling")
        .is_ok_and(|s| s.trim() == "Not affected")
}

/// One axis' broadcast constants (as in `avx2.rs`, eight lanes).
struct Axis {
    o: __m512d,
    d: __m512d,
    last: __m512d,
    top: __m512d,
}

impl Axis {
    /// The lanes of one axis' `[o, d, last, top]` (`LaneConstants::axes`).
    #[target_feature(enable = "avx2,avx512f")]
    #[inline]
    fn new([o, d, last, top]: [f64; 4]) -> Axis {
        Axis {
            o: _mm512_set1_pd(o),
            d: _mm512_set1_pd(d),
            last: _mm512_set1_pd(last),
            top: _mm512_set1_pd(top),
        }
    }
}

impl<T: Voxel> Grid<'_, T> {
    /// The trilinear samples at `o + d t` (index space) for each `t` of `ts`, into
    /// `out` (as long as `ts`), eight at a time: the bits of [`Grid::trilinear`] at
    /// each position. The last `ts.len() % 8` samples go through
    /// [`Grid::trilinear_avx2`]. With `RAW`, on a grid of raw bytes, the bits of
    /// raw values of [`Grid::trilinear_along`]. Safe to call where AVX-512F and
    /// AVX2 are enabled; a grid whose `wide` is set (only where the machine has
    /// them, [`available`]) may call it with `unsafe` after that check.
    ///
    /// # Panics
    /// Where `self.gather` is `None`, or `out` is shorter than `ts`.
    #[target_feature(enable = "avx2,avx512f")]
    pub(super) fn trilinear_avx512<const RAW: bool>(
        &self,
        o: [f64; 3],
        d: [f64; 3],
        ts: &[f64],
        out: &mut [f32],
    ) {
        debug_assert_eq!(ts.len(), out.len());
        let c = self.lane_constants(o, d);
        let groups = ts.len() / 8;
        let rest = 8 * groups;
        if groups > 0 {
            // a position `o + d t` moves monotonically with `t` on each axis (its
            // rounding too), so when every `t` lies between the first and the last
            // (as a march's do; NaN does not) and the positions of those two lie
            // inside every axis' cells (0 < x < last), every lane's does: the
            // clamps are then identities, and are left out
            let (lo, hi) = (ts[0], ts[rest - 1]);
            let between = ts[..rest]
                .iter()
                .fold(true, |ok, &t| ok & (t >= lo) & (t <= hi));
            let inside = between
                && c.axes.iter().all(|&[o, d, last, _]| {
                    let x = |t: f64| o + d * t;
                    let (a, b) = (x(lo), x(hi));
                    a > 0.0 && a < last && b > 0.0 && b < last
                });
            // raw bytes read by gathers: whether every lane's cell starts at flat
            // index 2 or later, so that each row's gather may start two bytes
            // before its two voxels. A lane's cell index on an axis does not
            // decrease or does not increase with `t` (the clamps and the floor
            // are monotone), so the axes' least indices at the ends bound every
            // lane's
            let from_two = self.row_gathers && between && c.kind == Gather::Bits8Raw && {
                let [i, j, k] = c.axes.map(|axis| least_cell(axis, lo, hi));
                i + self.sx * j + self.sxy * k >= 2
            };
            let (ts, out) = (&ts[..rest], &mut out[..rest]);
            // SAFETY: `ts` and `out` are as long, whole groups of eight; the clamps
            // are left out only where `inside` found every position inside the
            // cells, and `from_two` is as found above
            unsafe {
                if inside {
                    self.groups_avx512::<false, RAW>(&c, ts, out, from_two);
                } else {
                    self.groups_avx512::<true, RAW>(&c, ts, out, from_two);
                }
            }
        }
        // (a call whose length is a multiple of eight, as every call of a MIP along
        // an axis is, has no tail: the four-lane path would only set up its lanes)
        if rest < ts.len() {
            self.trilinear_avx2::<RAW>(o, d, &ts[rest..], &mut out[rest..]);
        }
    }

    /// [`Grid::trilinear_avx512`] of whole groups of eight (`ts.len()` a multiple of
    /// 8), the positions clamped to the grid unless `CLAMP` is false (the caller
    /// has found every position inside the grid's cells, where the clamps change
    /// nothing); `from_two`: every position's cell starts at flat index 2 or later,
    /// and gathers pay (the caller's, for [`Grid::rows_bytes_gathered`]); `RAW`:
    /// raw bytes left as interpolated ([`Grid::trilinear_along`]). The storage kind
    /// is chosen once, each kind's loop its own ([`Grid::groups_of`]), and only the
    /// kinds of `T`'s storage have one.
    ///
    /// # Safety
    /// `ts` and `out` have the same length, a multiple of 8; without `CLAMP`, every
    /// position `o + d t` (of the constants `c`) lies strictly inside the grid's
    /// cells on every axis (`0 < x < last`), so that its cell is the truncation;
    /// with `from_two`, every position's cell starts at flat index 2 or later.
    #[target_feature(enable = "avx2,avx512f")]
    #[inline]
    unsafe fn groups_avx512<const CLAMP: bool, const RAW: bool>(
        &self,
        c: &LaneConstants,
        ts: &[f64],
        out: &mut [f32],
        from_two: bool,
    ) {
        macro_rules! run {
            ($k:expr) => {
                // SAFETY: `each_storage!` runs the loop of `c.kind`, the grid's
                // storage (raw bytes gathered only with `from_two`); the rest is
                // the caller's
                unsafe { self.groups_of::<CLAMP, RAW, { $k }>(c, ts, out) }
            };
        }
        each_storage!(T, RAW, c.kind, from_two, run);
    }

    /// [`Grid::groups_avx512`] with the loop of storage `K` ([`Loop`]).
    ///
    /// # Safety
    /// As [`Grid::groups_avx512`], with `from_two` where `K` is
    /// [`Loop::RAW_GATHERED`], and `K` the loop of this grid's storage
    /// (`Loop::of(self.gather, from_two)`: it reads the voxels as that storage's
    /// type, and the table of pairs only where the grid has one).
    #[target_feature(enable = "avx2,avx512f")]
    #[inline]
    unsafe fn groups_of<const CLAMP: bool, const RAW: bool, const K: u8>(
        &self,
        c: &LaneConstants,
        ts: &[f64],
        out: &mut [f32],
    ) {
        debug_assert!(ts.len().is_multiple_of(8) && ts.len() == out.len());
        let (axes, [sx, sxy], rows) = broadcast_lanes!(c, _mm512_set1_epi64);
        for g in 0..ts.len() / 8 {
            let at = 8 * g;
            // SAFETY: at + 7 < ts.len()
            let t = unsafe { _mm512_loadu_pd(ts.as_ptr().add(at)) };
            let (ix, fx) = locate::<CLAMP>(&axes[0], t);
            let (iy, fy) = locate::<CLAMP>(&axes[1], t);
            let (iz, fz) = locate::<CLAMP>(&axes[2], t);
            // flat index of each lane's cell (each below 2^31, the products below 2^62)
            // SAFETY (each row read below): `locate` clamps each axis to the
            // grid's cells (without `CLAMP`, the caller found every position
            // inside them), so `base + rows[r]` is a cell's row start and it and
            // the voxel after it are voxels, and with `K` the grid's storage, the
            // reads are of its type (the caller's)
            let base = _mm512_add_epi64(
                _mm512_add_epi64(
                    _mm512_cvtepi32_epi64(ix),
                    _mm512_mul_epu32(_mm512_cvtepi32_epi64(iy), sx),
                ),
                _mm512_mul_epu32(_mm512_cvtepi32_epi64(iz), sxy),
            );
            let sample = match K {
                Loop::F32 => {
                    let corners = unsafe { self.rows_words_x8::<ROW_GENERAL>(base, c.rows) };
                    interpolate(corners, fx, fy, fz)
                }
                Loop::F32_UNIT => {
                    let corners = unsafe { self.rows_words_x8::<ROW_UNIT>(base, c.rows) };
                    interpolate(corners, fx, fy, fz)
                }
                Loop::F32_BARE => {
                    let corners = unsafe { self.rows_words_x8::<ROW_BARE>(base, c.rows) };
                    interpolate(corners, fx, fy, fz)
                }
                Loop::BITS16 => {
                    let c =
                        unsafe { each_row!(self.row_bits_x8::<2>, _mm512_add_epi64, base, rows) };
                    interpolate(c, fx, fy, fz)
                }
                Loop::BITS8 => {
                    let c =
                        unsafe { each_row!(self.row_bits_x8::<1>, _mm512_add_epi64, base, rows) };
                    interpolate(c, fx, fy, fz)
                }
                Loop::PAIRS => {
                    let corners = unsafe { self.rows_words_x8::<ROW_PAIRS>(base, c.rows) };
                    interpolate(corners, fx, fy, fz)
                }
                Loop::RAW_GATHERED => {
                    let corners = unsafe { self.rows_bytes_gathered(base, c.rows) };
                    self.raw_or_normalised::<RAW>(lerps(corners, fx, fy, fz))
                }
                _ => {
                    let corners = unsafe { self.rows_bytes_x8(base, c.rows) };
                    self.raw_or_normalised::<RAW>(lerps(corners, fx, fy, fz))
                }
            };
            // SAFETY: at + 7 < ts.len() == out.len() (the caller's)
            unsafe { _mm256_storeu_ps(out.as_mut_ptr().add(at), sample) };
        }
    }

    /// Eight lanes of interpolated raw bytes as they are (`RAW`,
    /// [`Grid::trilinear_along`]) or normalised.
    #[target_feature(enable = "avx2,avx512f")]
    #[inline]
    fn raw_or_normalised<const RAW: bool>(&self, v: __m256) -> __m256 {
        if RAW {
            v
        } else {
            normalise(&self.norm, v)
        }
    }

    /// The normalised voxels of the four rows of each of eight lanes' cells: row
    /// `r` of the lane whose cell starts at flat index `base` holds voxels
    /// `base + rows[r]` and the one after it, float32 voxels normalised as `KIND`
    /// says or 8-bit ones through the table of pairs ([`ROW_PAIRS`]). The lanes'
    /// cell starts are read out once, and each row's float32 voxels through a
    /// pointer to that row's offset (one load per lane and row, the offset in the
    /// address).
    ///
    /// # Safety
    /// Every lane's `base + rows[r]` and the voxel after it are voxels of the grid
    /// (a cell's row start) for each `r`; the voxels are float32, or with
    /// [`ROW_PAIRS`], 8-bit with a table of pairs ([`Grid::pair_word`]).
    #[target_feature(enable = "avx2,avx512f")]
    #[inline]
    unsafe fn rows_words_x8<const KIND: u8>(
        &self,
        base: __m512i,
        rows: [i64; 4],
    ) -> [(__m256, __m256); 4] {
        let data: *const f32 = self.voxels.as_ptr().cast();
        if KIND != ROW_PAIRS && self.row_gathers {
            // SAFETY (the caller's): as for the loads below, each lane's word is
            // the two voxels from a cell's row start, 4 bytes per index
            let row = |r: usize| {
                let at = _mm512_add_epi64(base, _mm512_set1_epi64(rows[r]));
                self.row_words_x8::<KIND>(unsafe { _mm512_i64gather_epi64::<4>(at, data.cast()) })
            };
            return [row(0), row(1), row(2), row(3)];
        }
        // SAFETY: eight i64 lanes, and every bit pattern is an i64
        let base: [i64; 8] = unsafe { std::mem::transmute(base) };
        // SAFETY (the caller's, both reads): every `base + rows[r]` is a cell's row
        // start, so it and the voxel after it are in the data
        let row = |r: usize| {
            // (8-bit voxels read through the table of pairs do not use it)
            let p = if KIND == ROW_PAIRS {
                data
            } else {
                // SAFETY: a cell's row offset is below the data's length
                unsafe { data.offset(rows[r] as isize) }
            };
            let w = |k: usize| unsafe {
                if KIND == ROW_PAIRS {
                    self.pair_word(base[k] + rows[r])
                } else {
                    f32_pair(p, base[k])
                }
            };
            self.row_words_x8::<KIND>(_mm512_set_epi64(
                w(7),
                w(6),
                w(5),
                w(4),
                w(3),
                w(2),
                w(1),
                w(0),
            ))
        };
        [row(0), row(1), row(2), row(3)]
    }

    /// The normalised voxels of eight lanes from `pairs`, each lane two adjacent
    /// voxels as one 64-bit word (the first in the low half): float32 voxels
    /// normalised as `KIND` says (`avx2.rs`: [`ROW_GENERAL`], [`ROW_UNIT`],
    /// [`ROW_BARE`]), or the normalised values from the table of pairs
    /// ([`ROW_PAIRS`]).
    #[target_feature(enable = "avx2,avx512f")]
    #[inline]
    fn row_words_x8<const KIND: u8>(&self, pairs: __m512i) -> (__m256, __m256) {
        // the low and high halves of each 64-bit element: voxels `at` and `at + 1`
        let a = _mm256_castsi256_ps(_mm512_cvtepi64_epi32(pairs));
        let b = _mm256_castsi256_ps(_mm512_cvtepi64_epi32(_mm512_srli_epi64::<32>(pairs)));
        if KIND == ROW_BARE || KIND == ROW_PAIRS {
            return (a, b);
        }
        if KIND == ROW_UNIT {
            // max with 0 (NaN -> 0, -0 -> 0), min with 1, as `avx2.rs`
            let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
            let clamp = |v: __m256| _mm256_min_ps(_mm256_max_ps(v, zero), one);
            return (clamp(a), clamp(b));
        }
        // as `trilinear_sse2`
        (normalise(&self.norm, a), normalise(&self.norm, b))
    }

    /// The 8-bit voxels of the four rows of each of eight lanes' cells as floats,
    /// not normalised ([`Gather::Bits8Raw`]): row `r` of the lane whose cell starts
    /// at flat index `base` holds voxels `base + rows[r]` and the one after it,
    /// each lane's two bytes read with one scalar load.
    ///
    /// # Safety
    /// Every lane's `base + rows[r]` and the voxel after it are voxels of the grid
    /// for each `r`, and the voxels are 8-bit.
    #[target_feature(enable = "avx2,avx512f")]
    #[inline]
    unsafe fn rows_bytes_x8(&self, base: __m512i, rows: [i64; 4]) -> [(__m256, __m256); 4] {
        // SAFETY: eight i64 lanes, and every bit pattern is an i64
        let base: [i64; 8] = unsafe { std::mem::transmute(base) };
        // SAFETY (the caller's): each lane's two bytes are voxels
        let row = |r: usize| {
            let w = |k: usize| i32::from(unsafe { self.byte_pair(base[k] + rows[r]) });
            bytes_to_floats(_mm256_set_epi32(
                w(7),
                w(6),
                w(5),
                w(4),
                w(3),
                w(2),
                w(1),
                w(0),
            ))
        };
        [row(0), row(1), row(2), row(3)]
    }

    /// [`Grid::rows_bytes_x8`] with a gather per row, where gathers pay
    /// ([`gathers_pay`]) and every cell starts at flat index 2 or later (the
    /// caller's `from_two`: all but the rays that pass the first two voxels'
    /// cells): the gather reads the four bytes that end with the row's two, so
    /// that no lane reads past the data's end.
    ///
    /// # Safety
    /// Every lane's `at = base + rows[r]` is at least 2, and it and `at + 1` are
    /// voxels of the grid for each `r`; the voxels are 8-bit.
    #[target_feature(enable = "avx2,avx512f")]
    #[inline]
    unsafe fn rows_bytes_gathered(&self, base: __m512i, rows: [i64; 4]) -> [(__m256, __m256); 4] {
        let data = self.voxels.as_ptr().cast::<u8>();
        let row = |r: usize| {
            let start = _mm512_add_epi64(base, _mm512_set1_epi64(rows[r] - 2));
            // SAFETY (the caller's): every `at` is a cell's row start, at least 2,
            // and `at + 1` is a voxel: bytes `at - 2 ..= at + 1` are in the data
            let words = unsafe { _mm512_i64gather_epi32::<1>(start, data.cast()) };
            // voxel `at` in bits 16-23, `at + 1` in bits 24-31
            let a = _mm256_and_si256(_mm256_srli_epi32::<16>(words), _mm256_set1_epi32(0xff));
            let b = _mm256_srli_epi32::<24>(words);
            (_mm256_cvtepi32_ps(a), _mm256_cvtepi32_ps(b))
        };
        [row(0), row(1), row(2), row(3)]
    }

    /// The normalised 8- or 16-bit voxels (`BYTES` per voxel) at flat indices `at`
    /// and `at + 1` of each of eight lanes, through the normalisation table.
    ///
    /// # Safety
    /// As [`Grid::row_bits_lanes`]: every lane's `at` and `at + 1` are voxels of the
    /// grid, which holds `BYTES`-byte voxels, and `BYTES` is 1 or 2.
    #[target_feature(enable = "avx2,avx512f")]
    #[inline]
    unsafe fn row_bits_x8<const BYTES: usize>(&self, at: __m512i) -> (__m256, __m256) {
        // SAFETY: eight i64 lanes, and every bit pattern is an i64
        let at: [i64; 8] = unsafe { std::mem::transmute(at) };
        // SAFETY (the caller's): every `at` is a cell's row start, so `at + 1` is a
        // voxel
        let [a, b] = unsafe { self.row_bits_lanes::<BYTES, 8>(at) };
        // SAFETY: `a` and `b` are eight f32 each
        unsafe { (_mm256_loadu_ps(a.as_ptr()), _mm256_loadu_ps(b.as_ptr())) }
    }
}

/// The lesser of the cells on one axis (`[o, d, last, top]`,
/// `LaneConstants::axes`) of the positions at `lo` and `hi`, clamped as `locate`
/// clamps them. Out of line, as the closure it replaces was before the vector
/// paths' helpers became safe functions: inlined, it changed the register
/// allocation of the loops it sits beside.
#[inline(never)]
fn least_cell([o, d, last, top]: [f64; 4], lo: f64, hi: f64) -> usize {
    let cell = |t: f64| {
        let x = o + d * t;
        let x = if x > 0.0 { x } else { 0.0 };
        let x = if x < last { x } else { last };
        (if x < top { x } else { top }) as usize
    };
    cell(lo).min(cell(hi))
}

/// The position `o + d t` on one axis, clamped to the grid (NaN to 0), as the
/// cell's first voxel (i32 lanes) and the fraction across it (as `avx2.rs`).
#[target_feature(enable = "avx2,avx512f")]
#[inline]
fn locate<const CLAMP: bool>(a: &Axis, t: __m512d) -> (__m256i, __m256) {
    let x = _mm512_add_pd(a.o, _mm512_mul_pd(a.d, t));
    if !CLAMP {
        // 0 < x < last (the caller's): x is its own clamp, and its floor, at most
        // the last cell's first voxel, the cell
        let i = _mm512_cvttpd_epi32(x);
        let f = _mm512_cvtpd_ps(_mm512_sub_pd(x, _mm512_cvtepi32_pd(i)));
        return (i, f);
    }
    let x = _mm512_min_pd(_mm512_max_pd(x, _mm512_setzero_pd()), a.last);
    let i = _mm512_cvttpd_epi32(_mm512_min_pd(x, a.top));
    let f = _mm512_cvtpd_ps(_mm512_sub_pd(x, _mm512_cvtepi32_pd(i)));
    (i, f)
}

/// The trilinear interpolation of eight lanes' cells from their rows, as
/// `avx2.rs`'s `interpolate`.
#[target_feature(enable = "avx2,avx512f")]
#[inline]
fn interpolate(c: [(__m256, __m256); 4], fx: __m256, fy: __m256, fz: __m256) -> __m256 {
    let v = lerps(c, fx, fy, fz);
    _mm256_min_ps(_mm256_set1_ps(1.0), _mm256_max_ps(_mm256_setzero_ps(), v))
}

/// The low bytes of each 32-bit lane (voxel `at` in bits 0-7, `at + 1` in bits
/// 8-15) as two lanes of floats, as `avx2.rs`'s `bytes_to_floats`.
#[target_feature(enable = "avx2,avx512f")]
#[inline]
fn bytes_to_floats(w: __m256i) -> (__m256, __m256) {
    let m = _mm256_set1_epi32(0xff);
    let a = _mm256_and_si256(w, m);
    let b = _mm256_and_si256(_mm256_srli_epi32::<8>(w), m);
    (_mm256_cvtepi32_ps(a), _mm256_cvtepi32_ps(b))
}

/// Eight lanes normalised as `avx2.rs`'s `normalise` (float32 voxels, or
/// interpolated bytes).
#[target_feature(enable = "avx2,avx512f")]
#[inline]
fn normalise(norm: &Normalize, v: __m256) -> __m256 {
    let (l, s) = norm.lo_scale();
    let x = _mm512_mul_pd(
        _mm512_sub_pd(_mm512_cvtps_pd(v), _mm512_set1_pd(l)),
        _mm512_set1_pd(s),
    );
    _mm512_cvtpd_ps(_mm512_min_pd(
        _mm512_max_pd(x, _mm512_setzero_pd()),
        _mm512_set1_pd(1.0),
    ))
}

/// [`interpolate`] without the clamp.
#[target_feature(enable = "avx2,avx512f")]
#[inline]
fn lerps(c: [(__m256, __m256); 4], fx: __m256, fy: __m256, fz: __m256) -> __m256 {
    let lerp =
        |a: __m256, b: __m256, t: __m256| _mm256_add_ps(a, _mm256_mul_ps(_mm256_sub_ps(b, a), t));
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
    use super::super::{bits_table, normalisation_table, pair_table, Grid};
    use super::{available, Gather};
    use crate::sample::Normalize;
    use crate::volume::{ScalarType, Voxel, Voxels};

    /// Whether this CPU lacks the eight-lane path, saying so.
    fn skipped() -> bool {
        if available() {
            return false;
        }
        eprintln!(
            "skipped: this CPU has no AVX-512F (with AVX2), so the eight-lane path never runs"
        );
        true
    }

    /// How a test grid reads its voxels (as in `avx2.rs`'s tests).
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
        /// Unsigned 8-bit voxels interpolated as they are ([`Grid::with_raw_bytes`]).
        Raw,
    }

    /// [`Grid::trilinear_avx512`] called directly, with rows read by loads and by
    /// gathers, along random rays (inside the cells, where it leaves out its
    /// clamps; across and outside the grid; lengths with and without a tail of
    /// fewer than eight), has at each position the bits of the scalar path
    /// ([`Grid::trilinear_scalar`]); for raw bytes, of its raw values too.
    fn eight_lanes_are_scalar<T: Voxel>(
        voxel: impl Fn(usize) -> T,
        norm: Normalize,
        expect: Gather,
        read: Read,
    ) {
        let mut checked = 0usize;
        for n in [
            [9, 8, 7],
            [2, 3, 2],
            [5, 1, 4],
            [3, 4, 1],
            [2, 2, 1],
            [17, 3, 5],
        ] {
            let len = n[0] * n[1] * n[2];
            let v: Vec<T> = (0..len).map(&voxel).collect();
            let lut = if read == Read::Signed {
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
            match read {
                Read::Plain => {}
                Read::Bare => g = g.with_unit_voxels(),
                Read::Signed => g = g.signed_bits(),
                Read::Pairs => g = g.with_pairs(&pairs),
                Read::Raw => g = g.with_raw_bytes(),
            }
            assert_eq!(g.gather, Some(expect), "{n:?}");
            assert!(g.wide, "the grid takes the eight-lane path");
            let mut state = 0x2545_f491_4f6c_dd1du64;
            let mut next = |lo: f64, hi: f64| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                lo + (state >> 11) as f64 / (1u64 << 53) as f64 * (hi - lo)
            };
            for ray in 0..300 {
                let mut o = [0, 1, 2].map(|a| next(-2.0, n[a] as f64 + 1.0));
                let mut d = [0, 1, 2].map(|_| next(-1.0, 1.0));
                let mut t0 = next(-3.0, 1.0);
                // whole groups of eight, and lengths with a tail
                let count = if ray % 2 == 0 {
                    8 * (next(0.0, 6.0) as usize)
                } else {
                    next(0.0, 50.0) as usize
                };
                if ray % 3 == 0 {
                    // short steps from the middle: inside the cells
                    o = [0, 1, 2].map(|a| 0.5 * (n[a] - 1) as f64 + next(-0.2, 0.2));
                    d = d.map(|x| x * 0.02);
                    t0 = 0.0;
                }
                let ts: Vec<f64> = (0..count).map(|k| t0 + 0.37 * k as f64).collect();
                for row_gathers in [false, true] {
                    let g = Grid { row_gathers, ..g };
                    let mut out = vec![0.0f32; count];
                    // SAFETY: the CPU has AVX-512F and AVX2 (`available`)
                    unsafe { g.trilinear_avx512::<false>(o, d, &ts, &mut out) };
                    let mut raws = vec![0.0f32; count];
                    if read == Read::Raw {
                        // SAFETY: as above
                        unsafe { g.trilinear_avx512::<true>(o, d, &ts, &mut raws) };
                    }
                    for (k, &t) in ts.iter().enumerate() {
                        let p = [0, 1, 2].map(|a| o[a] + d[a] * t);
                        let scalar = g.trilinear_scalar::<false>(p);
                        assert_eq!(
                            out[k].to_bits(),
                            scalar.to_bits(),
                            "{n:?} {p:?}, gathers {row_gathers}"
                        );
                        if read == Read::Raw {
                            let raw = g.trilinear_scalar::<true>(p);
                            assert_eq!(raws[k].to_bits(), raw.to_bits(), "raw {n:?} {p:?}");
                        }
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 10_000, "{checked} samples checked");
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

    /// float32 voxels all in [0, 1], zeros of both signs and both ends among them.
    fn unit(i: usize) -> f32 {
        match i % 11 {
            0 => -0.0,
            1 => 0.0,
            2 => 1.0,
            3 => f32::from_bits(1),
            _ => (i * 37 % 101) as f32 / 100.0,
        }
    }

    fn byte(i: usize) -> u8 {
        (i * 53 % 256) as u8
    }

    fn word(i: usize) -> u16 {
        (i * 4099 % 65536) as u16
    }

    #[test]
    fn eight_lanes_of_float32_are_the_scalar_samples() {
        if skipped() {
            return;
        }
        let norm = Normalize::new(-0.1, 1.2);
        eight_lanes_are_scalar(float, norm, Gather::Float32, Read::Plain);
    }

    #[test]
    fn eight_lanes_of_float32_in_the_unit_window_are_the_scalar_samples() {
        if skipped() {
            return;
        }
        let norm = Normalize::new(0.0, 1.0);
        eight_lanes_are_scalar(float, norm, Gather::Float32Unit, Read::Plain);
        eight_lanes_are_scalar(unit, norm, Gather::Float32Bare, Read::Bare);
    }

    #[test]
    fn eight_lanes_of_8_bit_voxels_are_the_scalar_samples() {
        if skipped() {
            return;
        }
        for norm in [
            Normalize::new(-0.1, 250.0),
            Normalize::new(255.0 * 0.7, 255.0 * 0.2),
            Normalize::new(3.0, 3.0 + 1e-9),
        ] {
            eight_lanes_are_scalar(byte, norm, Gather::Bits8, Read::Plain);
            eight_lanes_are_scalar(byte, norm, Gather::Bits8, Read::Signed);
            eight_lanes_are_scalar(byte, norm, Gather::Bits8Pairs, Read::Pairs);
        }
    }

    #[test]
    fn eight_lanes_of_raw_bytes_are_the_scalar_samples() {
        if skipped() {
            return;
        }
        for norm in [
            Normalize::new(0.0, 255.0),
            Normalize::new(-256.0, 510.0),
            Normalize::new(255.0, 0.0),
        ] {
            eight_lanes_are_scalar(byte, norm, Gather::Bits8Raw, Read::Raw);
        }
    }

    #[test]
    fn eight_lanes_of_16_bit_voxels_are_the_scalar_samples() {
        if skipped() {
            return;
        }
        for norm in [
            Normalize::new(-0.1, 65530.0),
            Normalize::new(-65536.0, 131070.0),
            Normalize::new(65535.0 * 0.7, 65535.0 * 0.2),
        ] {
            eight_lanes_are_scalar(word, norm, Gather::Bits16, Read::Plain);
            eight_lanes_are_scalar(word, norm, Gather::Bits16, Read::Signed);
        }
    }
}
