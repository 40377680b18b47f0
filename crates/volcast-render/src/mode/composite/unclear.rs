//! The first half of the composite's lookups over a batch of samples, eight at a
//! time (AVX2): which samples are not clear (`Composite::position_unless_clear`),
//! and for each of those its table entry and fraction
//! (`transfer::split_position`), packed to the front in the batch's order. The
//! second half, the interpolation between two entries
//! ([`Table1D::lerp_entries`]), stays one sample at a time.
//!
//! One sample at a time, a sample's test for clear is a branch that the values
//! decide, taken one way or the other at random where a ray crosses the edge of a
//! transfer function's ramp; here it is a mask, and the samples kept are moved to
//! the front by a permutation looked up from the mask. Each lane goes through the
//! operations of the one-sample path (clamp, compare, multiply, truncate, convert,
//! subtract, each correctly rounded the same way), so the results have the same
//! bits: the composite's images do not depend on which path ran.
//!
//! [`Table1D::lerp_entries`]: crate::transfer::Table1D::lerp_entries

use std::mem::MaybeUninit;

use crate::render::integrator::BATCH;

/// The samples of a batch that are not clear: their indices in the batch, table
/// entries and fractions, in order. Room for eight more than a batch, as the last
/// group's store writes eight lanes whatever it keeps.
pub(super) struct Unclear {
    index: [MaybeUninit<u32>; BATCH + 8],
    entry: [MaybeUninit<u32>; BATCH + 8],
    fraction: [MaybeUninit<f32>; BATCH + 8],
    len: usize,
}

impl Unclear {
    /// Whether this machine runs [`Unclear::find`] (x86-64 with AVX2).
    pub(super) fn available() -> bool {
        #[cfg(target_arch = "x86_64")]
        return std::is_x86_feature_detected!("avx2");
        #[cfg(not(target_arch = "x86_64"))]
        return false;
    }

    /// An empty list, its lanes not written.
    #[inline(always)]
    pub(super) fn new() -> Unclear {
        Unclear {
            index: [MaybeUninit::uninit(); BATCH + 8],
            entry: [MaybeUninit::uninit(); BATCH + 8],
            fraction: [MaybeUninit::uninit(); BATCH + 8],
            len: 0,
        }
    }

    /// Finds the samples among `values` (at most [`BATCH`]) that are not clear, for
    /// tables whose last index is `last` (at least 1) and whose clamped values up
    /// to `clear_up_to` are clear (`Composite::clear_unit`), in place of those it
    /// held. In place: returned by value, the list was copied (`memcpy`) for every
    /// batch.
    ///
    /// # Panics
    /// Where [`Unclear::available`] is false, or `values` is longer than a batch.
    #[inline]
    pub(super) fn find(&mut self, values: &[f32], clear_up_to: f32, last: u32) {
        assert!(values.len() <= BATCH, "{} values in a batch", values.len());
        assert!((1..1 << 24).contains(&last), "a table's last index {last}");
        assert!(Unclear::available(), "the eight-lane lookups need AVX2");
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Unclear::available` found AVX2 (`is_x86_feature_detected!`,
        // asserted above)
        unsafe {
            avx2::find(values, clear_up_to, last, self)
        };
    }

    /// How many samples are not clear.
    #[inline(always)]
    pub(super) fn len(&self) -> usize {
        self.len
    }

    /// Sample `k` of those not clear (`k < len`): its index in the batch, its table
    /// entry `i` (at most `last - 1`) and its fraction towards entry `i + 1`.
    #[inline(always)]
    pub(super) fn get(&self, k: usize) -> (usize, usize, f32) {
        assert!(k < self.len);
        // SAFETY: the first `len` lanes of each array were written by `find`
        unsafe {
            (
                self.index.get_unchecked(k).assume_init() as usize,
                self.entry.get_unchecked(k).assume_init() as usize,
                self.fraction.get_unchecked(k).assume_init(),
            )
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use super::{Unclear, BATCH};

    /// For each mask of eight lanes, the indices of its set lanes in order, then
    /// zeros: the permutation that moves the kept lanes to the front.
    static PACK: [[u32; 8]; 256] = pack_table();

    const fn pack_table() -> [[u32; 8]; 256] {
        let mut table = [[0u32; 8]; 256];
        let mut mask = 0;
        while mask < 256 {
            let mut lane = 0;
            let mut n = 0;
            while lane < 8 {
                if mask >> lane & 1 != 0 {
                    table[mask][n] = lane as u32;
                    n += 1;
                }
                lane += 1;
            }
            mask += 1;
        }
        table
    }

    /// [`Unclear::find`]'s work, for `1 <= last < 2^24`.
    ///
    /// # Panics
    /// Where `values` is longer than a batch (the stores' room).
    #[target_feature(enable = "avx2")]
    pub(super) fn find(values: &[f32], clear_up_to: f32, last: u32, out: &mut Unclear) {
        let n = values.len();
        assert!(n <= BATCH, "{n} values in a batch");
        let zero = _mm256_setzero_ps();
        let one = _mm256_set1_ps(1.0);
        let up_to = _mm256_set1_ps(clear_up_to);
        let last_f = _mm256_set1_ps(last as f32);
        let last_entry = _mm256_set1_epi32((last - 1) as i32);
        let lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        let mut len = 0;
        let mut k = 0;
        while k < n {
            let rest = n - k;
            // SAFETY: lanes k..k + min(8, rest) are inside `values`; the others are
            // not read (a masked load) and not kept (the mask below)
            let v = if rest >= 8 {
                unsafe { _mm256_loadu_ps(values.as_ptr().add(k)) }
            } else {
                let inside = _mm256_cmpgt_epi32(_mm256_set1_epi32(rest as i32), lanes);
                unsafe { _mm256_maskload_ps(values.as_ptr().add(k), inside) }
            };
            // clamp_unit: `if v > 0 { v } else { 0 }` is max(v, 0) (NaN gives the
            // second operand, 0), `if y < 1 { y } else { 1 }` is min(y, 1)
            let y = _mm256_min_ps(_mm256_max_ps(v, zero), one);
            // not clear: !(y <= clear_up_to), y being a number
            let kept = _mm256_cmp_ps::<_CMP_GT_OQ>(y, up_to);
            let mut mask = _mm256_movemask_ps(kept) as u32;
            if rest < 8 {
                mask &= (1 << rest) - 1;
            }
            if mask != 0 {
                // split_position: x = y * last, i = min(trunc(x), last - 1), x - i
                let x = _mm256_mul_ps(y, last_f);
                let i = _mm256_min_epi32(_mm256_cvttps_epi32(x), last_entry);
                let t = _mm256_sub_ps(x, _mm256_cvtepi32_ps(i));
                let index = _mm256_add_epi32(lanes, _mm256_set1_epi32(k as i32));
                // SAFETY: PACK has 256 entries and mask < 256
                let pack = unsafe {
                    _mm256_loadu_si256(PACK.get_unchecked(mask as usize).as_ptr().cast())
                };
                // SAFETY: len <= k < n <= BATCH (asserted above), and each array has
                // BATCH + 8 lanes
                unsafe {
                    _mm256_storeu_si256(
                        out.index.as_mut_ptr().add(len).cast(),
                        _mm256_permutevar8x32_epi32(index, pack),
                    );
                    _mm256_storeu_si256(
                        out.entry.as_mut_ptr().add(len).cast(),
                        _mm256_permutevar8x32_epi32(i, pack),
                    );
                    _mm256_storeu_ps(
                        out.fraction.as_mut_ptr().add(len).cast(),
                        _mm256_permutevar8x32_ps(t, pack),
                    );
                }
                len += mask.count_ones() as usize;
            }
            k += 8;
        }
        out.len = len;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transfer::{clamp_unit, split_position};

    /// The one-sample path: the clamp, the test for clear, the split.
    fn one_at_a_time(values: &[f32], clear_up_to: f32, last: u32) -> Vec<(usize, u32, u32)> {
        values
            .iter()
            .enumerate()
            .filter_map(|(k, &v)| {
                let y = clamp_unit(v);
                if y <= clear_up_to {
                    return None;
                }
                // SAFETY: y is in [0, 1], so y * last in [0, last]
                let (i, t) = unsafe { split_position(y * last as f32, last) };
                Some((k, i, t.to_bits()))
            })
            .collect()
    }

    /// Values around every entry of a table of `last + 1` entries and around the
    /// clear threshold, NaN, signed zeros, infinities and values outside [0, 1].
    fn values(last: u32, clear_up_to: f32) -> Vec<f32> {
        let mut out = vec![
            f32::NAN,
            -f32::NAN,
            -1.0,
            -0.0,
            0.0,
            1.0,
            1.5,
            f32::INFINITY,
        ];
        out.push(f32::NEG_INFINITY);
        let mut around = |v: f32| {
            let (mut lo, mut hi) = (v, v);
            for _ in 0..3 {
                lo = f32::from_bits(lo.to_bits().saturating_sub(1));
                hi = f32::from_bits(hi.to_bits() + 1);
                out.extend([lo, v, hi]);
            }
        };
        for e in 0..=last.min(300) {
            around(e as f32 / last as f32);
            around((e as f32 + 0.5) / last as f32);
        }
        around(clear_up_to.max(0.0));
        out
    }

    /// Every batch length 0-64 (whole groups of eight and tails), at every offset of
    /// a long list of awkward values, finds what the one-sample path keeps, with its
    /// entries and the bits of its fractions.
    #[test]
    fn eight_lanes_find_what_one_sample_at_a_time_keeps() {
        if !Unclear::available() {
            eprintln!(
                "skipped: this machine has no AVX2, so the composite never finds eight at a time"
            );
            return;
        }
        let mut checked = 0;
        let mut kept = 0;
        for last in [1u32, 2, 255, 4095] {
            // the clear threshold: none clear (-1), some, every value clear (1)
            for clear_up_to in [-1.0f32, 0.0, 0.1, 0.37, 0.999, 1.0] {
                let all = values(last, clear_up_to);
                for n in 0..=BATCH {
                    for from in (0..all.len().saturating_sub(n)).step_by(29) {
                        let batch = &all[from..from + n];
                        let mut found = Unclear::new();
                        found.find(batch, clear_up_to, last);
                        let found: Vec<(usize, u32, u32)> = (0..found.len())
                            .map(|k| {
                                let (index, i, t) = found.get(k);
                                (index, i as u32, t.to_bits())
                            })
                            .collect();
                        let expected = one_at_a_time(batch, clear_up_to, last);
                        assert_eq!(
                            found, expected,
                            "{n} values from {from}, last {last}, clear up to {clear_up_to}"
                        );
                        checked += 1;
                        kept += found.len();
                    }
                }
            }
        }
        // not vacuous: batches were checked and samples kept
        assert!(
            checked > 1000 && kept > 1000,
            "{checked} batches, {kept} kept"
        );
    }
}
