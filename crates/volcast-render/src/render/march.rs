//! Where a ray is sampled: the march of sample positions from the box entry to the
//! exit (docs/formulas.md "Render modes"), and the midpoints of its segments (where
//! compositing samples).
//!
//! A ray inside the box is sampled at `t_enter`, every `dt` after it, and at
//! `t_exit` (the last step is shorter), so the entry and exit points are always
//! sampled and the samples cover the whole segment. With jitter, the samples after
//! the entry are shifted back by a per-pixel fraction of `dt` (the entry and exit
//! are still sampled). Every position is computed from its index, `t0 + (i +
//! shift) dt`, never accumulated, so rays of millions of samples do not drift.

use std::mem::MaybeUninit;

/// Positions along a ray, in increasing order: what a sampled integrator visits.
pub trait Lattice {
    /// Number of positions.
    fn len(&self) -> usize;
    /// True when there are no positions.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Position `i` (`0 <= i < len()`), non-decreasing in `i`.
    fn t(&self, i: usize) -> f64;
    /// A guess of the first index whose position is at or after `t` (the exact index
    /// is found from it by [`Lattice::first_at_or_after`]).
    fn guess(&self, t: f64) -> f64;

    /// Positions `from..from + ts.len()` into `ts` (each as [`Lattice::t`] gives it).
    #[inline(always)]
    fn fill(&self, from: usize, ts: &mut [f64]) {
        for (k, t) in ts.iter_mut().enumerate() {
            *t = self.t(from + k);
        }
    }

    /// The smallest index `i` with `t(i) >= t` (`len()` if there is none), found by
    /// correcting [`Lattice::guess`] against the positions themselves, so that it
    /// agrees with `t(i)` to the last bit.
    #[inline]
    fn first_at_or_after(&self, t: f64) -> usize {
        let n = self.len();
        let g = self.guess(t);
        let i = if g > 0.0 {
            // the ceiling without a library call (no rounding instruction on
            // baseline x86-64), through i64 (one conversion each way, where
            // usize's take several); a huge guess saturates and is clamped
            let c = g as i64;
            let c = if (c as f64) < g {
                c.saturating_add(1)
            } else {
                c
            };
            c.min(n as i64) as usize
        } else {
            0
        };
        // the guess is right but for rounding: check it, and walk only if it is not
        // (out of line, so that the check stays two comparisons)
        let above = i == 0 || self.t(i - 1) < t;
        let below = i == n || self.t(i) >= t;
        if above && below {
            i
        } else {
            search(self, t, i)
        }
    }
}

/// [`Lattice::first_at_or_after`] from a wrong guess `i`.
#[cold]
#[inline(never)]
fn search<L: Lattice + ?Sized>(lattice: &L, t: f64, mut i: usize) -> usize {
    let n = lattice.len();
    while i > 0 && lattice.t(i - 1) >= t {
        i -= 1;
    }
    while i < n && lattice.t(i) < t {
        i += 1;
    }
    i
}

/// Sample positions along `[t0, t1]`: `t0`, every `dt` (shifted back by a
/// fraction of `dt` when jittered), and `t1`.
#[derive(Clone, Copy, Debug)]
pub struct March {
    t0: f64,
    t1: f64,
    dt: f64,
    /// `1 / dt`, for [`Lattice::guess`] (a multiplication where a division would
    /// wait longer: the guess is corrected against the positions anyway).
    inv_dt: f64,
    /// Sample `i >= 1` sits at `t0 + (i + shift) dt`; `shift` is in `(-1, 0]`.
    shift: f64,
    full_steps: usize,
    tail: bool,
    /// The first segment that is a whole step: 1, or 2 when jittered.
    first_full: usize,
    /// The number of whole-step segments, `first_full..=full_steps` (0 when none).
    full_count: usize,
}

impl March {
    /// The march for one ray segment.
    pub fn new(t0: f64, t1: f64, dt: f64) -> March {
        March::jittered(t0, t1, dt, 0.0)
    }

    /// The march with every sample after the entry moved back by `jitter * dt`,
    /// `jitter` in `[0, 1)` (0 = the plain march, bit for bit): the samples are
    /// `t0`, `t0 + (1 - jitter) dt`, `t0 + (2 - jitter) dt`, ..., `t1`.
    pub fn jittered(t0: f64, t1: f64, dt: f64, jitter: f64) -> March {
        March::jittered_by(t0, t1, dt, 1.0 / dt, jitter)
    }

    /// [`March::jittered`] with the step's reciprocal `inv_dt = 1 / dt` computed
    /// once for every ray of a pass (a division per ray fewer).
    #[inline]
    pub fn jittered_by(t0: f64, t1: f64, dt: f64, inv_dt: f64, jitter: f64) -> March {
        debug_assert_eq!(inv_dt.to_bits(), (1.0 / dt).to_bits());
        let shift = -jitter.clamp(0.0, 1.0 - f64::EPSILON);
        let len = (t1 - t0).max(0.0);
        // `len / dt - shift` is at least 0 (or NaN), where the conversion's
        // truncation is the floor (and NaN gives 0 either way): no library call
        let full_steps = (len / dt - shift) as usize;
        // a tail shorter than a millionth of a step is merged into the last sample
        let tail = len - (full_steps as f64 + shift) * dt > 1e-6 * dt;
        let first_full = if shift == 0.0 { 1 } else { 2 };
        March {
            t0,
            t1,
            dt,
            inv_dt,
            shift,
            full_steps,
            tail,
            first_full,
            full_count: full_steps.saturating_add(1).saturating_sub(first_full),
        }
    }

    /// Number of sample positions (at least 1: the entry).
    pub fn len(&self) -> usize {
        self.full_steps + 1 + usize::from(self.tail)
    }

    /// Always false: a march has at least its entry point.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Position `i` (`0 <= i < len()`): computed from the index, never accumulated,
    /// so long rays do not drift.
    #[inline(always)]
    pub fn t(&self, i: usize) -> f64 {
        if i > self.full_steps {
            self.t1
        } else {
            self.t_before_end(i)
        }
    }

    /// [`March::t`] for `i <= full_steps` (every position but the exit point).
    #[inline(always)]
    fn t_before_end(&self, i: usize) -> f64 {
        // `i + 0.0` is exact, so the plain march is unchanged by the shift; `i`
        // converts through i64 (one instruction; the same value below 2^63); the
        // comparisons (not `f64::max`/`min`, which also handle NaN) keep the
        // position inside the segment in two instructions
        self.t_at_index(i as i64 as f64)
    }

    /// [`March::t_before_end`] of the index `x`, given as a float (an integer).
    #[inline(always)]
    fn t_at_index(&self, x: f64) -> f64 {
        let t = self.t0 + (x + self.shift) * self.dt;
        let t = if t > self.t0 { t } else { self.t0 };
        if t < self.t1 {
            t
        } else {
            self.t1
        }
    }

    /// The middle of the whole step from sample `i` to sample `i + 1`
    /// ([`March::is_full_step`]`(i + 1)`), from its index.
    #[inline(always)]
    fn whole_step_middle(&self, i: usize) -> f64 {
        self.middle_at_index(i as i64 as f64)
    }

    /// [`March::whole_step_middle`] of the index `x`, given as a float (an integer).
    #[inline(always)]
    fn middle_at_index(&self, x: f64) -> f64 {
        self.t0 + (x + 0.5 + self.shift) * self.dt
    }

    /// True when the segment from sample `i - 1` to sample `i` (`i >= 1`) is a whole
    /// step long: every segment but a jittered first one and the shorter last one.
    #[inline(always)]
    pub fn is_full_step(&self, i: usize) -> bool {
        // `first_full <= i <= full_steps` as one unsigned comparison
        i.wrapping_sub(self.first_full) < self.full_count
    }

    /// The samples both of whose segments (from `i - 1` to `i`, and from `i` to
    /// `i + 1`) are whole steps ([`March::is_full_step`] of `i` and `i + 1`): the
    /// first and how many, so that `i` is one when `i.wrapping_sub(first) < count`.
    pub fn interior(&self) -> (usize, usize) {
        (self.first_full, self.full_count.saturating_sub(1))
    }

    /// The length of the segment from sample `i - 1` to sample `i`: `dt` for a
    /// whole step (exactly, where the difference of the two positions would carry
    /// their rounding), the positions' difference for the others, 0 for `i = 0`
    /// and for `i >= len()` (no such segment).
    pub fn segment_length(&self, i: usize) -> f64 {
        if i == 0 || i >= self.len() {
            0.0
        } else if self.is_full_step(i) {
            self.dt
        } else {
            self.t(i) - self.t(i - 1)
        }
    }

    /// The step.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// [`Lattice::first_at_or_after`] of each of `ts` where it is found cheaply,
    /// else [`UNKNOWN`]: written into `out` (of the same length) and returned
    /// there, for a march of fewer than `u32::MAX` positions. Where the machine has
    /// AVX-512 and `ts` comes in whole groups of eight, each guess is checked eight
    /// at a time, as `first_at_or_after` checks it, and a wrong one (rare: a
    /// rounding) is left unknown; elsewhere every one is, so that a caller finds
    /// only those it needs, one at a time.
    pub fn first_at_or_after_known<'a>(
        &self,
        ts: &[f64],
        out: &'a mut [MaybeUninit<u32>],
    ) -> &'a [u32] {
        assert!(self.len() < UNKNOWN as usize && ts.len() == out.len());
        #[cfg(target_arch = "x86_64")]
        if ts.len().is_multiple_of(8) && std::is_x86_feature_detected!("avx512f") {
            // SAFETY: `is_x86_feature_detected!` found AVX-512F just above
            unsafe { guesses_avx512(self, ts, out) };
            // SAFETY: `guesses_avx512` wrote every entry (`out` is as long as `ts`,
            // a multiple of 8); `MaybeUninit<u32>` has the layout of `u32`
            return unsafe { &*(out as *const [MaybeUninit<u32>] as *const [u32]) };
        }
        for i in out.iter_mut() {
            i.write(UNKNOWN);
        }
        // SAFETY: as above, every entry was written
        unsafe { &*(out as *const [MaybeUninit<u32>] as *const [u32]) }
    }
}

/// An index that [`March::first_at_or_after_known`] did not find.
pub const UNKNOWN: u32 = u32::MAX;

/// The guesses of [`March::first_at_or_after_known`], checked as
/// [`Lattice::first_at_or_after`] checks them, eight to a register: a right one
/// into `out`, [`UNKNOWN`] for a wrong one: every entry of `out` where `ts` and
/// `out` have the same length, a multiple of 8 (else the whole groups of eight of
/// the shorter).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn guesses_avx512(m: &March, ts: &[f64], out: &mut [MaybeUninit<u32>]) {
    use std::arch::x86_64::*;
    debug_assert!(ts.len() == out.len() && ts.len().is_multiple_of(8));
    let n = _mm512_set1_pd(m.len() as f64);
    let last_before_end = _mm512_set1_pd(m.full_steps as f64);
    let (t0, t1) = (_mm512_set1_pd(m.t0), _mm512_set1_pd(m.t1));
    let (dt, inv_dt, shift) = (
        _mm512_set1_pd(m.dt),
        _mm512_set1_pd(m.inv_dt),
        _mm512_set1_pd(m.shift),
    );
    let (zero, one) = (_mm512_setzero_pd(), _mm512_set1_pd(1.0));
    let wrong = _mm512_set1_pd(f64::from(UNKNOWN));
    // `March::t` of indices given as floats: the operations of `t_at_index` (no
    // fused multiply-add; `max`/`min` return their second operand unless the first
    // is beyond it, as the comparisons there), the exit past `full_steps`
    let at = |x: __m512d| {
        let t = _mm512_add_pd(t0, _mm512_mul_pd(_mm512_add_pd(x, shift), dt));
        let t = _mm512_min_pd(_mm512_max_pd(t, t0), t1);
        _mm512_mask_blend_pd(_mm512_cmp_pd_mask::<_CMP_GT_OQ>(x, last_before_end), t, t1)
    };
    for (ts, out) in ts.chunks_exact(8).zip(out.chunks_exact_mut(8)) {
        // SAFETY: `ts` is eight f64
        let t = unsafe { _mm512_loadu_pd(ts.as_ptr()) };
        // the guess's ceiling in [0, n] (NaN gives 0), as `first_at_or_after`
        let g = _mm512_sub_pd(_mm512_mul_pd(_mm512_sub_pd(t, t0), inv_dt), shift);
        let c = _mm512_roundscale_pd::<{ _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC }>(g);
        let c = _mm512_min_pd(_mm512_max_pd(c, zero), n);
        let above = _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(c, zero)
            | _mm512_cmp_pd_mask::<_CMP_LT_OQ>(at(_mm512_sub_pd(c, one)), t);
        let below =
            _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(c, n) | _mm512_cmp_pd_mask::<_CMP_GE_OQ>(at(c), t);
        let ok = above & below;
        let i = _mm512_cvttpd_epu32(_mm512_mask_blend_pd(ok, wrong, c));
        // SAFETY: `out` is eight u32 (`MaybeUninit<u32>` has the layout of `u32`)
        unsafe { _mm256_storeu_si256(out.as_mut_ptr() as *mut __m256i, i) };
    }
}

impl Lattice for March {
    fn len(&self) -> usize {
        March::len(self)
    }

    #[inline(always)]
    fn t(&self, i: usize) -> f64 {
        March::t(self, i)
    }

    #[inline]
    fn guess(&self, t: f64) -> f64 {
        (t - self.t0) * self.inv_dt - self.shift
    }

    /// A run before the last position (the common case) without a test of the
    /// index per position: the same operations per position as [`March::t`].
    #[inline(always)]
    fn fill(&self, from: usize, ts: &mut [f64]) {
        if from + ts.len() <= self.full_steps + 1 {
            fill_from_indices(from, ts, |x| self.t_at_index(x));
        } else {
            for (k, t) in ts.iter_mut().enumerate() {
                *t = March::t(self, from + k);
            }
        }
    }
}

/// `ts[k] = at(from + k)`, the index given to `at` as a float: converted through
/// i32 below 2^31, which vectorises (two to a register on baseline x86-64, where the
/// conversion from i64 is scalar; eight with AVX-512, [`fill_avx512`]), through
/// i64 above; the same values either way.
#[inline(always)]
fn fill_from_indices(from: usize, ts: &mut [f64], at: impl Fn(f64) -> f64) {
    #[cfg(target_arch = "x86_64")]
    if from + ts.len() <= i32::MAX as usize && std::is_x86_feature_detected!("avx512f") {
        // SAFETY: `is_x86_feature_detected!` found AVX-512F just above
        unsafe { fill_avx512(from, ts, at) };
        return;
    }
    if from + ts.len() <= i32::MAX as usize {
        for (k, t) in ts.iter_mut().enumerate() {
            *t = at((from + k) as i32 as f64);
        }
    } else {
        for (k, t) in ts.iter_mut().enumerate() {
            *t = at((from + k) as i64 as f64);
        }
    }
}

/// [`fill_from_indices`] below 2^31 (`from + ts.len() <= i32::MAX`, else the
/// indices wrap) compiled for AVX-512: the same operations (no fused
/// multiply-add), eight positions to a register, which made the peer MIP and
/// X-ray frames faster (`bench/peers/README.md`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn fill_avx512(from: usize, ts: &mut [f64], at: impl Fn(f64) -> f64) {
    for (k, t) in ts.iter_mut().enumerate() {
        *t = at((from + k) as i32 as f64);
    }
}

/// The midpoints of a march's segments: position `i` is the middle of the segment
/// from sample `i` to sample `i + 1` (`len()` is the march's length minus one).
#[derive(Clone, Copy, Debug)]
pub struct Midpoints<'a>(pub &'a March);

impl Lattice for Midpoints<'_> {
    fn len(&self) -> usize {
        self.0.len() - 1
    }

    /// The middle of a whole step directly from its index, the others from their
    /// ends.
    #[inline(always)]
    fn t(&self, i: usize) -> f64 {
        let m = self.0;
        if m.is_full_step(i + 1) {
            m.whole_step_middle(i)
        } else {
            0.5 * (m.t(i) + m.t(i + 1))
        }
    }

    #[inline]
    fn guess(&self, t: f64) -> f64 {
        self.0.guess(t) - 0.5
    }

    /// A run of whole steps (the common case) without a test per position: the
    /// same operations per position as [`Midpoints::t`], so the same bits.
    #[inline(always)]
    fn fill(&self, from: usize, ts: &mut [f64]) {
        let m = self.0;
        if m.is_full_step(from + 1) && m.is_full_step(from + ts.len()) {
            fill_from_indices(from, ts, |x| m.middle_at_index(x));
        } else {
            for (k, t) in ts.iter_mut().enumerate() {
                *t = self.t(from + k);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whether this CPU lacks AVX-512F, saying so.
    #[cfg(target_arch = "x86_64")]
    fn no_avx512(what: &str) -> bool {
        if std::is_x86_feature_detected!("avx512f") {
            return false;
        }
        eprintln!("skipped: this CPU has no AVX-512F, so {what} never runs");
        true
    }

    /// Marches with whole and partial steps, jittered or not, short and long.
    fn marches() -> [March; 5] {
        [
            March::new(0.3, 17.9, 0.7),
            March::jittered(-4.0, 9.0, 0.25, 0.61),
            March::new(5.0, 5.0, 1.0),
            March::new(-1e6, 1e6, 0.5),
            March::jittered(1e-3, 3.0, 1.0 / 3.0, 0.999),
        ]
    }

    /// [`fill_avx512`] called directly gives the positions of the scalar loop
    /// ([`March::t`]) to the bit, for runs of every length 0-40 from several
    /// starts (whole groups of eight and tails).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn fill_avx512_is_the_scalar_fill() {
        if no_avx512("fill_avx512") {
            return;
        }
        let mut checked = 0;
        for m in marches() {
            let whole = m.full_steps + 1;
            for from in [0, 1, 7, 13] {
                for len in 0..=40usize {
                    if from + len > whole {
                        continue;
                    }
                    let mut ts = vec![f64::NAN; len];
                    // SAFETY: the CPU has AVX-512F (checked above)
                    unsafe { fill_avx512(from, &mut ts, |x| m.t_at_index(x)) };
                    for (k, &t) in ts.iter().enumerate() {
                        assert_eq!(t.to_bits(), m.t(from + k).to_bits(), "{m:?} {from} {k}");
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 1000, "{checked} positions checked");
    }

    /// [`guesses_avx512`] called directly writes every entry, and each one it
    /// finds is [`Lattice::first_at_or_after`]'s (one at a time), for the positions
    /// themselves, the values a rounding off them, others between and beyond the
    /// ends, and non-finite ones; it finds most of them.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn guesses_avx512_are_first_at_or_after() {
        if no_avx512("guesses_avx512") {
            return;
        }
        for m in marches() {
            let mut ts = vec![f64::NAN, f64::NEG_INFINITY, f64::INFINITY, -0.0];
            for i in 0..m.len().min(300) {
                let t = m.t(i);
                ts.extend([t, t.next_up(), t.next_down(), t + 0.3 * m.dt()]);
            }
            for k in 0..100 {
                ts.push(-5.0 + k as f64 * 0.23);
            }
            ts.truncate(ts.len() / 8 * 8);
            let mut out = vec![MaybeUninit::new(UNKNOWN - 1); ts.len()];
            // SAFETY: the CPU has AVX-512F (checked above)
            unsafe { guesses_avx512(&m, &ts, &mut out) };
            let mut found = 0;
            for (&t, i) in ts.iter().zip(&out) {
                // SAFETY: initialised above, and written again
                let i = unsafe { i.assume_init() };
                assert_ne!(i, UNKNOWN - 1, "an entry left unwritten");
                if i != UNKNOWN {
                    assert_eq!(i as usize, m.first_at_or_after(t), "t = {t}, {m:?}");
                    found += 1;
                }
            }
            assert!(2 * found >= ts.len(), "{found} of {}", ts.len());
        }
    }

    #[test]
    fn march_covers_the_segment() {
        let m = March::new(1.0, 3.5, 1.0);
        let ts: Vec<f64> = (0..m.len()).map(|i| m.t(i)).collect();
        assert_eq!(ts, vec![1.0, 2.0, 3.0, 3.5]);
        let m = March::new(1.0, 3.0, 1.0);
        assert_eq!(
            (0..m.len()).map(|i| m.t(i)).collect::<Vec<_>>(),
            vec![1.0, 2.0, 3.0]
        );
        let m = March::new(2.0, 2.0, 0.5);
        assert_eq!(m.len(), 1);
        assert_eq!(m.t(0), 2.0);
    }

    #[test]
    fn jittered_march_keeps_entry_and_exit() {
        let m = March::jittered(1.0, 3.5, 1.0, 0.25);
        let ts: Vec<f64> = (0..m.len()).map(|i| m.t(i)).collect();
        assert_eq!(ts, vec![1.0, 1.75, 2.75, 3.5]);
        let m = March::jittered(1.0, 3.0, 1.0, 0.5);
        let ts: Vec<f64> = (0..m.len()).map(|i| m.t(i)).collect();
        assert_eq!(ts, vec![1.0, 1.5, 2.5, 3.0]);
        // zero jitter is the plain march, bit for bit
        let (a, b) = (
            March::new(0.1, 7.3, 0.37),
            March::jittered(0.1, 7.3, 0.37, 0.0),
        );
        assert_eq!(a.len(), b.len());
        for i in 0..a.len() {
            assert_eq!(a.t(i).to_bits(), b.t(i).to_bits());
        }
    }

    #[test]
    fn long_march_does_not_drift() {
        let m = March::new(0.0, 1.0, 1e-6);
        assert_eq!(m.t(m.len() - 1), 1.0);
        assert!((m.t(500_000) - 0.5).abs() < 1e-15);
    }

    #[test]
    fn full_steps_are_the_interior_segments() {
        let m = March::new(1.0, 3.5, 1.0); // 1, 2, 3, 3.5
        let full: Vec<bool> = (1..m.len()).map(|i| m.is_full_step(i)).collect();
        assert_eq!(full, vec![true, true, false]);
        let m = March::jittered(1.0, 3.5, 1.0, 0.25); // 1, 1.75, 2.75, 3.5
        let full: Vec<bool> = (1..m.len()).map(|i| m.is_full_step(i)).collect();
        assert_eq!(full, vec![false, true, false]);
        // no whole step: shorter than a step, jittered or not, and an empty segment
        for m in [
            March::new(0.0, 0.7, 1.0),
            March::jittered(0.0, 0.7, 1.0, 0.5),
            March::jittered(0.0, 1.2, 1.0, 0.5), // 0, 0.5, 1.2
            March::new(2.0, 2.0, 0.5),
        ] {
            assert!((0..m.len() + 3).all(|i| !m.is_full_step(i)), "{m:?}");
        }
        // the segments between whole-step positions, and none at index 0 or past the end
        for (t1, jitter) in [(9.0, 0.0), (9.3, 0.0), (9.0, 0.4), (9.3, 0.9)] {
            let m = March::jittered(0.0, t1, 1.0, jitter);
            for i in 0..m.len() + 3 {
                let whole = i >= 1 && i < m.len() && (m.t(i) - m.t(i - 1) - 1.0).abs() < 1e-12;
                assert_eq!(m.is_full_step(i), whole, "{m:?} {i}");
            }
        }
    }

    #[test]
    fn fill_gives_the_positions_bit_for_bit() {
        for m in [
            March::new(0.3, 17.9, 0.7),
            March::jittered(-4.0, 9.0, 0.25, 0.61),
            March::new(1e6, 1e6 + 1000.0, 1e-3),
            March::new(5.0, 5.0, 1.0),
        ] {
            let mid = Midpoints(&m);
            // every start on short marches; on the long one, some, and the last ones
            let n = m.len();
            let starts = (0..n)
                .step_by(if n > 1000 { 997 } else { 1 })
                .chain(n.saturating_sub(70)..n);
            for from in starts {
                for len in [1, 2, 7, 64] {
                    let n = len.min(m.len() - from);
                    let mut ts = vec![0.0; n];
                    m.fill(from, &mut ts);
                    for (k, t) in ts.iter().enumerate() {
                        assert_eq!(t.to_bits(), m.t(from + k).to_bits());
                    }
                    let n = len.min(mid.len().saturating_sub(from));
                    let mut ts = vec![0.0; n];
                    mid.fill(from, &mut ts);
                    for (k, t) in ts.iter().enumerate() {
                        assert_eq!(t.to_bits(), mid.t(from + k).to_bits());
                    }
                }
            }
        }
    }

    #[test]
    fn fill_beyond_two_to_the_31_gives_the_positions_too() {
        // indices at and past i32::MAX take the other conversion
        let m = March::jittered(-3.0, 3.0e9, 1.0, 0.3);
        let mid = Midpoints(&m);
        let top = i32::MAX as usize;
        for from in top - 70..top + 5 {
            for len in [1, 7, 64] {
                let mut ts = vec![0.0; len];
                m.fill(from, &mut ts);
                for (k, t) in ts.iter().enumerate() {
                    assert_eq!(t.to_bits(), m.t(from + k).to_bits(), "{from} {k}");
                }
                mid.fill(from, &mut ts);
                for (k, t) in ts.iter().enumerate() {
                    assert_eq!(t.to_bits(), mid.t(from + k).to_bits(), "{from} {k}");
                }
            }
        }
    }

    /// The whole steps counted without the floor's library call are the floor's,
    /// for short, long, empty, reversed, huge and NaN segments and jitters.
    #[test]
    fn whole_steps_are_the_floor_of_the_length_in_steps() {
        let ends = [
            (0.0, 0.0),
            (0.3, 17.9),
            (5.0, 4.0),
            (-1e300, 1e300),
            (0.0, f64::INFINITY),
            (f64::NAN, 3.0),
            (0.0, 1.0 - 1e-17),
        ];
        for (t0, t1) in ends {
            for dt in [0.5, 0.7, 1e-300, 3.0] {
                for jitter in [0.0, 0.25, 0.999_999, f64::NAN] {
                    let m = March::jittered(t0, t1, dt, jitter);
                    let shift = -jitter.clamp(0.0, 1.0 - f64::EPSILON);
                    let len = (t1 - t0).max(0.0);
                    let floor = (len / dt - shift).floor() as usize;
                    assert_eq!(m.full_steps, floor, "{t0} {t1} {dt} {jitter}");
                    assert_eq!(m.inv_dt.to_bits(), (1.0 / dt).to_bits());
                }
            }
        }
    }

    #[test]
    fn first_at_or_after_known_agrees_with_one_at_a_time() {
        #[cfg(target_arch = "x86_64")]
        let groups = std::is_x86_feature_detected!("avx512f");
        #[cfg(not(target_arch = "x86_64"))]
        let groups = false;
        for m in [
            March::new(0.3, 17.9, 0.7),
            March::jittered(-4.0, 9.0, 0.25, 0.61),
            March::new(5.0, 5.0, 1.0),
            March::new(-1e6, 1e6, 0.5),
        ] {
            // positions themselves, the values a rounding off each side of them,
            // and others in between (beyond both ends too)
            let mut ts = vec![f64::NAN, f64::NEG_INFINITY, f64::INFINITY];
            for i in 0..m.len().min(200) {
                let t = m.t(i);
                ts.extend([t, t.next_up(), t.next_down(), t + 0.3 * m.dt()]);
            }
            for k in 0..100 {
                ts.push(-5.0 + k as f64 * 0.23);
            }
            // whole groups of eight (found where the machine has AVX-512), and a
            // length that is not (none found)
            let whole = ts.len() / 8 * 8;
            assert_ne!(whole, ts.len());
            for len in [whole, ts.len()] {
                let mut out = vec![MaybeUninit::uninit(); len];
                let known = m.first_at_or_after_known(&ts[..len], &mut out);
                let mut found = 0;
                for (&t, &i) in ts.iter().zip(known.iter()) {
                    if i != UNKNOWN {
                        assert_eq!(i as usize, m.first_at_or_after(t), "t = {t}");
                        found += 1;
                    }
                }
                if groups && len == whole {
                    // all but the non-finite ones and some of those a rounding
                    // off a position (whose guess may round to it)
                    assert!(2 * found >= len, "{found} of {len}");
                } else {
                    assert_eq!(found, 0);
                }
            }
        }
    }

    #[test]
    fn first_at_or_after_agrees_with_the_positions() {
        for m in [
            March::new(0.3, 17.9, 0.7),
            March::jittered(-4.0, 9.0, 0.25, 0.61),
            March::new(5.0, 5.0, 1.0),
        ] {
            let mid = Midpoints(&m);
            for k in 0..400 {
                let t = -5.0 + k as f64 * 0.0625;
                let i = m.first_at_or_after(t);
                assert!(i == m.len() || m.t(i) >= t);
                assert!(i == 0 || m.t(i - 1) < t);
                let i = mid.first_at_or_after(t);
                assert!(i == mid.len() || mid.t(i) >= t);
                assert!(i == 0 || mid.t(i - 1) < t);
            }
            // at the positions themselves
            for i in 0..m.len() {
                assert!(m.first_at_or_after(m.t(i)) <= i);
            }
        }
    }
}
