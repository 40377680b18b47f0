//! Value statistics of a volume: range, mean and a histogram, ignoring non-finite
//! voxels (which are counted separately).

use super::{VolumeData, Voxel, Voxels};
use crate::parallel::{map_indices, map_runs};
use crate::with_voxels;

/// Number of histogram bins in [`Stats::histogram`].
pub const HISTOGRAM_BINS: usize = 64;

/// Summary statistics of the finite voxels.
#[derive(Clone, Debug, PartialEq)]
pub struct Stats {
    /// Smallest finite value (NaN when there is none).
    pub min: f64,
    /// Largest finite value (NaN when there is none).
    pub max: f64,
    /// Mean of the finite values.
    pub mean: f64,
    /// Number of finite values.
    pub finite: usize,
    /// Number of NaN or infinite values.
    pub non_finite: usize,
    /// Counts over `HISTOGRAM_BINS` equal bins spanning `min..=max`.
    pub histogram: Vec<u64>,
}

impl Stats {
    /// Computes the statistics (two passes over the data, in parallel chunks whose
    /// results are combined in a fixed order, so the result is deterministic and the
    /// same for owned and mapped data). Mapped data is streamed from the page cache
    /// chunk by chunk, never copied.
    pub fn of(data: &VolumeData) -> Stats {
        with_voxels!(data, v => stats_of(v, true))
    }

    /// The value at quantile `q` in [0, 1], read off the histogram (bin resolution).
    pub fn quantile(&self, q: f64) -> f64 {
        let total: u64 = self.histogram.iter().sum();
        if total == 0 {
            return f64::NAN;
        }
        let target = (q.clamp(0.0, 1.0) * total as f64).ceil().max(1.0) as u64;
        let mut acc = 0;
        // (in halves where the range is wider than an f64 holds, as it was binned)
        let half = if (self.max - self.min).is_finite() {
            1.0
        } else {
            0.5
        };
        let width = (self.max * half - self.min * half) / HISTOGRAM_BINS as f64;
        for (b, &c) in self.histogram.iter().enumerate() {
            acc += c;
            if acc >= target {
                return (self.min * half + width * (b as f64 + 0.5)) / half;
            }
        }
        self.max
    }
}

const CHUNK: usize = 1 << 16;

/// `f` of each of the consecutive chunks of `CHUNK` voxels of `v` (the last one
/// shorter), computed in parallel, in index order.
fn map_chunks<T: Voxel, R: Send>(
    v: Voxels<'_, T>,
    f: &(dyn Fn(Voxels<'_, T>) -> R + Sync),
) -> Vec<R> {
    map_indices(v.len().div_ceil(CHUNK), &|c| {
        f(v.slice(c * CHUNK..((c + 1) * CHUNK).min(v.len())))
    })
}

/// Partial sums of one chunk.
#[derive(Clone, Copy)]
struct Acc {
    min: f64,
    max: f64,
    sum: f64,
    finite: usize,
    non_finite: usize,
}

const EMPTY: Acc = Acc {
    min: f64::INFINITY,
    max: f64::NEG_INFINITY,
    sum: 0.0,
    finite: 0,
    non_finite: 0,
};

/// Range and sum of a chunk, through `f64`.
fn acc_f64<T: Voxel>(c: Voxels<'_, T>) -> Acc {
    let mut a = EMPTY;
    for x in c.iter() {
        let x = x.to_f64();
        if x.is_finite() {
            a.min = a.min.min(x);
            a.max = a.max.max(x);
            a.sum += x;
            a.finite += 1;
        } else {
            a.non_finite += 1;
        }
    }
    a
}

/// The same for 8- and 16-bit integers, in integer arithmetic on the table index
/// (`lut_index` = value - MIN): several times faster, and the very same numbers,
/// since every partial sum of a chunk (at most 2^16 values below 2^16) is an integer
/// that `f64` holds exactly.
fn acc_small_int<T: Voxel>(c: Voxels<'_, T>) -> Acc {
    if c.is_empty() {
        return EMPTY;
    }
    let (mut lo, mut hi, mut sum) = (usize::MAX, 0usize, 0u64);
    for x in c.iter() {
        let i = x.lut_index();
        lo = lo.min(i);
        hi = hi.max(i);
        sum += i as u64;
    }
    Acc {
        min: T::lut_value(lo),
        max: T::lut_value(hi),
        sum: sum as f64 + c.len() as f64 * T::lut_value(0),
        finite: c.len(),
        non_finite: 0,
    }
}

/// The mean of the finite values of `v` (`finite` of them) when their plain sum
/// overflows: summed scaled by 2^-64 (exact, and tiny values no longer matter),
/// which cannot overflow for fewer than 2^63 finite values.
fn scaled_mean<T: Voxel>(v: Voxels<'_, T>, finite: usize) -> f64 {
    const DOWN: f64 = 1.0 / 18_446_744_073_709_551_616.0; // 2^-64
    let sums = map_chunks(v, &|c| {
        c.iter()
            .map(|x| x.to_f64())
            .filter(|x| x.is_finite())
            .map(|x| x * DOWN)
            .sum::<f64>()
    });
    sums.iter().sum::<f64>() / finite as f64 / DOWN
}

fn stats_of<T: Voxel>(v: Voxels<'_, T>, small_int_path: bool) -> Stats {
    let small_int = small_int_path && T::LUT_SIZE > 0;
    let parts: Vec<Acc> = map_chunks(v, &|c| {
        if small_int {
            acc_small_int(c)
        } else {
            acc_f64(c)
        }
    });
    let mut t = EMPTY;
    for p in parts {
        t.min = t.min.min(p.min);
        t.max = t.max.max(p.max);
        t.sum += p.sum;
        t.finite += p.finite;
        t.non_finite += p.non_finite;
    }
    if t.finite == 0 {
        return Stats {
            min: f64::NAN,
            max: f64::NAN,
            mean: f64::NAN,
            finite: 0,
            non_finite: t.non_finite,
            histogram: vec![0; HISTOGRAM_BINS],
        };
    }
    let (lo, hi) = (t.min, t.max);
    // a range wider than an f64 holds (values near the f64 limits) is binned in
    // halves, which no finite data overflows
    let half = if (hi - lo).is_finite() { 1.0 } else { 0.5 };
    let scale = if hi > lo {
        HISTOGRAM_BINS as f64 / (hi * half - lo * half)
    } else {
        0.0
    };
    let bin = |x: f64| (((x * half - lo * half) * scale) as usize).min(HISTOGRAM_BINS - 1);
    // 8- and 16-bit integers: each possible value's bin, computed once
    let bins: Vec<u8> = if small_int {
        (0..T::LUT_SIZE)
            .map(|i| bin(T::lut_value(i)) as u8)
            .collect()
    } else {
        Vec::new()
    };
    // a few runs of chunks per thread, each counted into its own histogram
    let parts = map_runs(v.len().div_ceil(CHUNK), &|run| {
        let mut h = [0u64; HISTOGRAM_BINS];
        for c in run {
            let c = v.slice(c * CHUNK..((c + 1) * CHUNK).min(v.len()));
            if small_int {
                for x in c.iter() {
                    h[usize::from(bins[x.lut_index()])] += 1;
                }
            } else {
                for x in c.iter() {
                    let x = x.to_f64();
                    if x.is_finite() {
                        h[bin(x)] += 1;
                    }
                }
            }
        }
        h
    });
    let mut histogram = vec![0u64; HISTOGRAM_BINS];
    for h in parts {
        histogram.iter_mut().zip(h).for_each(|(x, y)| *x += y);
    }
    let mean = if t.sum.is_finite() {
        t.sum / t.finite as f64
    } else {
        scaled_mean(v, t.finite)
    };
    Stats {
        min: lo,
        max: hi,
        mean,
        finite: t.finite,
        non_finite: t.non_finite,
        histogram,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ignores_non_finite() {
        let s = Stats::of(&VolumeData::F32(vec![1.0, f32::NAN, 3.0, f32::INFINITY]));
        assert_eq!((s.min, s.max, s.mean), (1.0, 3.0, 2.0));
        assert_eq!((s.finite, s.non_finite), (2, 2));
        assert_eq!(s.histogram.iter().sum::<u64>(), 2);
    }

    #[test]
    fn small_integers_take_the_fast_path_to_the_same_numbers() {
        fn both<T: Voxel>(v: &[T]) {
            let v = Voxels::from_slice(v);
            // (Debug, so that the NaN of empty data compares)
            let (fast, slow) = (stats_of(v, true), stats_of(v, false));
            assert_eq!(format!("{fast:?}"), format!("{slow:?}"), "{}", T::TYPE);
        }
        // more than one chunk, the extremes of each type, a skewed distribution
        let n = 3 * CHUNK + 17;
        let f = |i: usize| ((i * 7919) % 65536) as i64 * ((i % 5) as i64) / 4;
        both(&(0..n).map(|i| f(i) as u16).collect::<Vec<_>>());
        both(&(0..n).map(|i| (f(i) - 32768) as i16).collect::<Vec<_>>());
        both(&(0..n).map(|i| f(i) as u8).collect::<Vec<_>>());
        both(&(0..n).map(|i| (f(i) % 256 - 128) as i8).collect::<Vec<_>>());
        both(&[u16::MAX, 0, u16::MAX]);
        both(&[i16::MIN, i16::MAX]);
        both(&[7u8; 5]);
        both::<u16>(&[]);
    }

    #[test]
    fn values_near_the_f64_limits_do_not_overflow() {
        // three quarters at the top, a quarter at the bottom: the mean is half the
        // top (to rounding), the median the top bin (whose centre lies within a bin's width of it)
        let m = f64::MAX;
        let s = Stats::of(&VolumeData::F64(vec![m, m, m, -m]));
        assert_eq!((s.min, s.max), (-m, m));
        assert!((s.mean - m / 2.0).abs() <= 1e-15 * m, "{:e}", s.mean);
        let (q50, q0) = (s.quantile(0.5), s.quantile(0.0));
        let bin = m / HISTOGRAM_BINS as f64 * 2.0;
        assert!(q50.is_finite() && (m - q50) <= bin, "{q50:e}");
        assert!(q0.is_finite() && (q0 + m) <= bin, "{q0:e}");
        assert_eq!(s.histogram[0], 1);
        assert_eq!(s.histogram[HISTOGRAM_BINS - 1], 3);
        // finite sums keep the plain arithmetic
        let t = Stats::of(&VolumeData::F64(vec![1e300, 3e300]));
        assert_eq!(t.mean, 2e300);
    }
}
