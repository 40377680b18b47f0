//! X-ray / look-through (docs/formulas.md "Render modes"): the line integral of the
//! normalised value by the trapezoid rule, accumulated in f64; Beer-Lambert for the
//! absorbed and transmitted images. Skips all-zero macrocells.

use std::ops::ControlFlow;

use crate::render::integrator::{drive, Consumer, Counts, Integrand, PixelRay};
use crate::render::march::March;
use crate::render::skip::MacroGrid;
use crate::sample::Field;

/// What an X-ray pass stores.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum XrayOutput {
    /// `mu` times the line integral of the normalised value (world units).
    Integral,
    /// `1 - exp(-integral)`.
    Absorbed,
    /// `exp(-integral)`.
    Transmitted,
}

/// The line integral, as the pass stores it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Xray {
    /// Stored quantity.
    pub output: XrayOutput,
    /// Attenuation scale.
    pub mu: f64,
}

impl Integrand for Xray {
    fn reads_depth_reference(&self) -> bool {
        false
    }

    fn channels(&self) -> usize {
        1
    }

    fn miss(&self) -> [f32; 4] {
        // the line integral of nothing is zero
        [finish(0.0, self.output, 1.0), 0.0, 0.0, 0.0]
    }

    /// All-zero cells, as `Trapezoid` passes over them.
    fn fixed_skippable(&self, _cell: usize, range: [f32; 2]) -> Option<bool> {
        Some(skippable(range))
    }

    #[inline]
    fn trace<F: Field>(
        &self,
        field: &F,
        ray: &PixelRay,
        march: &March,
        grid: Option<&MacroGrid>,
    ) -> ([f32; 4], Counts) {
        let mut t = Trapezoid::new(march);
        let taken = drive(march, field, ray, grid, &mut t);
        let counts = Counts {
            taken,
            nominal: march.len() as u64,
        };
        (
            [finish(t.sum(), self.output, self.mu), 0.0, 0.0, 0.0],
            counts,
        )
    }
}

/// Whether the trapezoid passes over a macrocell of values in `range`: values are
/// normalised to [0, 1], so a maximum of zero is all zeros.
#[inline(always)]
pub(crate) fn skippable(range: [f32; 2]) -> bool {
    range[1] <= 0.0
}

/// The trapezoid-rule integral of the samples, accumulated in f64, and the value of
/// the first sample. A sample's weight is half the length of the segments either
/// side of it: the whole step `dt` inside the march, so the samples there are
/// summed plainly and the sum multiplied by `dt` once ([`Trapezoid::sum`]); the few
/// at the ends (the entry, the exit, a jittered first step, the shorter last one)
/// are weighted one by one. Passes over all-zero cells: their samples would add
/// exact zeros, so nothing is done for them, and the skipped render is the
/// unskipped one to the bit.
///
/// The interior samples are summed in [`LANES`] sums, sample `i` into sum `i %
/// LANES`, each in the order of the samples, and the sums added in a fixed order at
/// the end: a batch adds its samples to the sums in vector lanes, with [`LANES`]
/// chains of additions instead of one, so the loop no longer waits on each
/// addition (`bench/peers/README.md`). Which sum a sample joins
/// depends on its index alone, so the integral has the same bits whatever the
/// batches (one sample at a time, or runs cut by skipped cells, whose zeros would
/// leave any sum as it is).
pub(crate) struct Trapezoid<'a> {
    march: &'a March,
    /// The march's [`March::interior`] samples: the first, and how many.
    interior_from: usize,
    interior_count: usize,
    /// The samples whose segments on both sides are whole steps, sample `i` in
    /// sum `i % LANES`.
    interior: [f64; LANES],
    /// The other samples, each times its weight.
    ends: f64,
    pub first: f64,
}

/// How many sums the interior samples of a [`Trapezoid`] are split into.
const LANES: usize = 4;

impl<'a> Trapezoid<'a> {
    pub fn new(march: &'a March) -> Self {
        let (interior_from, interior_count) = march.interior();
        Trapezoid {
            march,
            interior_from,
            interior_count,
            interior: [0.0; LANES],
            ends: 0.0,
            first: 0.0,
        }
    }

    /// The integral of the samples handed over.
    pub fn sum(&self) -> f64 {
        let [a, b, c, d] = self.interior;
        ((a + b) + (c + d)) * self.march.dt() + self.ends
    }

    #[inline(always)]
    fn add(&mut self, i: usize, f: f64) {
        if i.wrapping_sub(self.interior_from) < self.interior_count {
            self.interior[i % LANES] += f;
        } else {
            self.end(i, f);
        }
    }

    /// Interior samples `from..from + values.len()` into their sums: the first
    /// few one by one up to an index that is a multiple of [`LANES`], then
    /// [`LANES`] at a time (one vector addition), then the rest.
    #[inline(always)]
    fn add_interior(&mut self, from: usize, values: &[f32]) {
        let head = from.wrapping_neg() % LANES;
        let (head, rest) = values.split_at(head.min(values.len()));
        let mut sums = self.interior;
        for (k, &f) in head.iter().enumerate() {
            sums[(from + k) % LANES] += f64::from(f);
        }
        let chunks = rest.chunks_exact(LANES);
        let tail = chunks.remainder();
        for chunk in chunks {
            for (s, &f) in sums.iter_mut().zip(chunk) {
                *s += f64::from(f);
            }
        }
        // (the tail starts at a multiple of LANES: sample k of it joins sum k)
        for (s, &f) in sums.iter_mut().zip(tail) {
            *s += f64::from(f);
        }
        self.interior = sums;
    }

    /// A sample at an end of the march (or of a march without whole steps).
    #[inline(never)]
    fn end(&mut self, i: usize, f: f64) {
        if i == 0 {
            self.first = f;
        }
        let m = self.march;
        let weight = 0.5 * (m.segment_length(i) + m.segment_length(i + 1));
        self.ends += weight * f;
    }
}

impl Consumer for Trapezoid<'_> {
    #[inline(always)]
    fn skippable(&self, _cell: usize, range: [f32; 2]) -> bool {
        skippable(range)
    }

    #[inline(always)]
    fn skip(&mut self, _i: usize, _j: usize) -> ControlFlow<()> {
        // zeros add nothing (and the first value stays 0 when sample 0 is one)
        ControlFlow::Continue(())
    }

    #[inline(always)]
    fn take(&mut self, i: usize, _t: f64, f: f32) -> ControlFlow<()> {
        self.add(i, f64::from(f));
        ControlFlow::Continue(())
    }

    /// A batch inside the march's interior is summed without a test per sample.
    #[inline(always)]
    fn take_batch(&mut self, from: usize, ts: &[f64], values: &[f32]) -> ControlFlow<usize> {
        let first = from.wrapping_sub(self.interior_from);
        if first < self.interior_count && values.len() <= self.interior_count - first {
            self.add_interior(from, values);
        } else {
            for (k, (&t, &f)) in ts.iter().zip(values).enumerate() {
                let _ = self.take(from + k, t, f);
            }
        }
        ControlFlow::Continue(())
    }
}

/// The stored quantity for a line integral `integral` of the normalised value.
pub fn finish(integral: f64, output: XrayOutput, mu: f64) -> f32 {
    let tau = mu * integral;
    (match output {
        XrayOutput::Integral => tau,
        XrayOutput::Absorbed => -(-tau).exp_m1(),
        XrayOutput::Transmitted => (-tau).exp(),
    }) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The trapezoid sums of `march` of the values `f(t)`, one sample at a time and
    /// in batches of `batch`.
    fn sums(march: &March, f: impl Fn(f64) -> f32, batch: usize) -> (f64, f64) {
        let n = march.len();
        let ts: Vec<f64> = (0..n).map(|i| march.t(i)).collect();
        let vs: Vec<f32> = ts.iter().map(|&t| f(t)).collect();
        let mut one = Trapezoid::new(march);
        for i in 0..n {
            let _ = one.take(i, ts[i], vs[i]);
        }
        let mut batched = Trapezoid::new(march);
        for from in (0..n).step_by(batch) {
            let to = (from + batch).min(n);
            let _ = batched.take_batch(from, &ts[from..to], &vs[from..to]);
        }
        (one.sum(), batched.sum())
    }

    #[test]
    fn trapezoids_integrate_a_linear_field_exactly_in_batches_or_not() {
        // f = 0.25 + t / 64 on [t0, t1]: the trapezoid rule is exact for it, with
        // the entry, a jittered first step and a shorter last one
        let f = |t: f64| (0.25 + t / 64.0) as f32;
        for (t0, t1, dt, jitter) in [
            (3.0, 40.0, 0.5, 0.0),
            (3.0, 40.3, 0.5, 0.0),
            (2.7, 41.9, 0.5, 0.37),
            (0.0, 0.2, 0.5, 0.0),
            (1.0, 1.0, 0.5, 0.0),
            (5.0, 17.0, 0.25, 0.9),
        ] {
            let march = March::jittered(t0, t1, dt, jitter);
            let exact = |t: f64| 0.25 * t + t * t / 128.0;
            let truth = exact(t1) - exact(t0);
            for batch in [1, 3, 8, 64] {
                let (one, batched) = sums(&march, f, batch);
                // the values are f32: their rounding, not the rule, sets the error
                let tol = 1e-6 * (t1 - t0).max(1.0);
                assert!(
                    (one - truth).abs() <= tol,
                    "{t0} {t1} {jitter}: {one} vs {truth}"
                );
                assert_eq!(one.to_bits(), batched.to_bits(), "batch {batch}");
            }
        }
    }

    #[test]
    fn skipped_zeros_leave_the_sum_as_taken_ones() {
        // samples 10..29 are zeros: handed over, or skipped, one at a time or in
        // batches that start where the zeros end (not a multiple of the sums'
        // count), the same bits. The others mix values near 1 with values near
        // 1e-9, whose sum in f64 rounds (a sum of f32 values of similar size is
        // exact in any order), so that a sample added to another sum would show
        let march = March::jittered(0.0, 30.3, 0.5, 0.41);
        let n = march.len();
        let zero = |i: usize| (10..29).contains(&i);
        let f = |i: usize| match (zero(i), i % 3) {
            (true, _) => 0.0,
            (false, 0) => 0.5 + i as f32 * 0.01,
            _ => 1e-9 * (1 + i % 7) as f32,
        };
        let mut all = Trapezoid::new(&march);
        let mut gaps = Trapezoid::new(&march);
        for i in 0..n {
            let _ = all.take(i, march.t(i), f(i));
            if !zero(i) {
                let _ = gaps.take(i, march.t(i), f(i));
            }
        }
        let _ = gaps.skip(10, 29);
        // the interior's samples in two batches, the ends one at a time
        let (from, count) = march.interior();
        assert!(from < 10 && from + count > 40, "{from} {count}");
        let mut runs = Trapezoid::new(&march);
        for i in (0..from).chain(from + count..n) {
            let _ = runs.take(i, march.t(i), f(i));
        }
        for (a, b) in [(from, 10), (29, from + count)] {
            let ts: Vec<f64> = (a..b).map(|i| march.t(i)).collect();
            let vs: Vec<f32> = (a..b).map(f).collect();
            let _ = runs.take_batch(a, &ts, &vs);
        }
        assert_eq!(all.sum().to_bits(), gaps.sum().to_bits());
        assert_eq!(all.sum().to_bits(), runs.sum().to_bits());
        assert!(all.sum() > 0.0);
    }
}
