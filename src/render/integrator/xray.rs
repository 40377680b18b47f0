//! X-ray / look-through (REFERENCE.md "Render modes"): the line integral of the
//! normalised value by the trapezoid rule, accumulated in f64; Beer-Lambert for the
//! absorbed and transmitted images. Skips all-zero macrocells.

use std::ops::ControlFlow;

use super::{drive, Consumer, Counts, Integrand, PixelRay};
use crate::render::march::March;
use crate::render::skip::MacroGrid;
use crate::sample::Field;
use crate::scene::XrayOutput;

/// The line integral, as the pass stores it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Xray {
    /// Stored quantity.
    pub output: XrayOutput,
    /// Attenuation scale.
    pub mu: f64,
}

impl Integrand for Xray {
    fn channels(&self) -> usize {
        1
    }

    fn miss(&self) -> [f32; 4] {
        // the line integral of nothing is zero
        [finish(0.0, self.output, 1.0), 0.0, 0.0, 0.0]
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
        ([finish(t.sum, self.output, self.mu), 0.0, 0.0, 0.0], counts)
    }
}

/// The trapezoid-rule integral of the samples, accumulated in f64, and the value of
/// the first sample. Passes over all-zero cells: their samples add exact zeros, and
/// the trapezoids at the edges of a gap get their zero end.
pub(super) struct Trapezoid<'a> {
    march: &'a March,
    pub sum: f64,
    pub first: f64,
    t_prev: f64,
    f_prev: f64,
}

impl<'a> Trapezoid<'a> {
    pub fn new(march: &'a March) -> Self {
        Trapezoid {
            march,
            sum: 0.0,
            first: 0.0,
            t_prev: 0.0,
            f_prev: 0.0,
        }
    }

    #[inline(always)]
    fn add(&mut self, i: usize, t: f64, f: f64) {
        if i == 0 {
            self.first = f;
        } else {
            self.sum += (t - self.t_prev) * (self.f_prev + f) * 0.5;
        }
        self.t_prev = t;
        self.f_prev = f;
    }
}

impl Consumer for Trapezoid<'_> {
    #[inline(always)]
    fn skippable(&self, _cell: usize, range: [f32; 2]) -> bool {
        // values are normalised to [0, 1]: a maximum of zero is all zeros
        range[1] <= 0.0
    }

    #[inline]
    fn skip(&mut self, i: usize, j: usize) -> ControlFlow<()> {
        // the first skipped sample closes the trapezoid before the gap; the samples
        // inside add zeros; the last one opens the trapezoid after it
        self.add(i, self.march.t(i), 0.0);
        self.t_prev = self.march.t(j - 1);
        self.f_prev = 0.0;
        ControlFlow::Continue(())
    }

    #[inline(always)]
    fn take(&mut self, i: usize, t: f64, f: f32) -> ControlFlow<()> {
        self.add(i, t, f64::from(f));
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
