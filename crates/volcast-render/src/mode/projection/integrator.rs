//! MIP, MinIP, average and local MIP (docs/formulas.md "Render modes").
//!
//! Skipping: MIP passes over macrocells whose maximum cannot beat the running
//! maximum (MinIP symmetrically), and walks only the part of a ray where a cell
//! that is not all zero can lie (`footprint.rs`); the average passes over all-zero
//! cells, and local MIP,
//! while it looks for the first sample at or above its threshold, over those that
//! cannot reach it (a ray that never reaches it is then answered by MIP).

use std::ops::ControlFlow;

use crate::mode::xray::integrator::Trapezoid;
use crate::render::integrator::{
    drive, padded, take_each, Batch, Consumer, Counts, Integrand, PixelRay, BATCH,
};
use crate::render::march::{Lattice, March, UNKNOWN};
use crate::render::ray::IndexRay;
use crate::render::skip::MacroGrid;
use crate::sample::{Field, Normalize};
use crate::transfer::Colormap;

/// Maximum intensity projection.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Mip;

/// Minimum intensity projection.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Minip;

/// The length-weighted mean along the ray.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Average;

/// The first local maximum at or above `threshold` (else the maximum).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lmip {
    /// Normalised value.
    pub threshold: f32,
}

/// Depth-cued MIP, and where its maximum is: each sample's value `f` at depth `s`
/// (from the bounding sphere's entry) is weighted by `w(s) = 1 - cue * s / D`
/// (`s / D` clamped to [0, 1], so `w` is in `[1 - cue, 1]`) before the maximum;
/// the depth of the maximum is that of the first sample, in ray order, that
/// reaches it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CuedMip {
    /// `cue` in [0, 1] (0 = the plain maximum).
    pub cue: f64,
    /// `D`, the bounding sphere's diameter (world units).
    pub diameter: f64,
    /// What the pixel holds.
    pub output: CuedOutput,
}

/// What a [`CuedMip`] pixel holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CuedOutput {
    /// The weighted maximum.
    Value,
    /// The depth `s` of the maximum.
    Depth,
    /// RGBA: `map(s / D)` times the maximum's brightness in `window`, alpha 1.
    Coded {
        /// The colour map of depth.
        map: Colormap,
        /// The values shown black and full brightness (normalised).
        window: [f32; 2],
    },
}

/// A cell's ranking for [`brightest_first`]: the consumer's best case over a cell
/// whose values lie in `range` (larger = sampled sooner).
trait Ranked: Consumer {
    fn rank(&self, range: [f32; 2]) -> f32;
    /// [`Consumer::skippable`] for a cell that lies before samples already taken
    /// (the consumer's answer may depend on the order).
    fn skippable_earlier(&self, range: [f32; 2]) -> bool {
        self.skippable(0, range)
    }

    /// Whether a cell of `range` can be passed over now: one before samples
    /// already taken (`earlier`, [`Ranked::skippable_earlier`]) or after every one
    /// ([`Consumer::skippable`]).
    #[inline(always)]
    fn passes_over(&self, range: [f32; 2], earlier: bool) -> bool {
        if earlier {
            self.skippable_earlier(range)
        } else {
            self.skippable(0, range)
        }
    }

    /// Whether the ray's first sample alone gives the result when the best rank
    /// of its cells is `best` (a maximum over cells of zeros only).
    fn first_settles(&self, _best: f32) -> bool {
        false
    }

    /// Whether the consumer takes a field's raw values ([`Ranked::take_raw_batch`])
    /// where the field has them ([`Field::raw_map`]).
    const TAKES_RAW: bool = false;

    /// Whether [`brightest_first`] finds every span's end at once
    /// ([`March::first_at_or_after_known`]) rather than each end when its span is
    /// sampled: for consumers that sample many of a ray's spans, as a MIP does, for
    /// which finding the ends at once is faster; a MinIP often samples one span (a
    /// cell of zeros, whose minimum no other cell beats), for which it is slower
    /// (`bench/peers/interleaved.py ortho_mip ... --degrees 360 --mode minip`;
    /// `bench/peers/README.md`).
    const ENDS_TOGETHER: bool = false;

    /// [`Consumer::take_batch`] of the samples `map.apply(raw)` of `raws` (raw
    /// values of a field, [`Field::raw_values_along`], whose map does not
    /// decrease), with the same result. Called only where [`Ranked::TAKES_RAW`].
    fn take_raw_batch(&mut self, _map: &Normalize, _raws: &[f32]) {
        unreachable!("raw values go only to a consumer that takes them");
    }
}

/// The running maximum of weighted samples and where it was first reached.
struct WeightedMax {
    cue: f64,
    inv_diameter: f64,
    t_ref: f64,
    best: f32,
    t_best: f64,
    /// Whether the depth matters: then a cell whose bound equals the maximum and
    /// that lies before the samples taken may hold an earlier sample that reaches
    /// it (a cell after them may not: a tie keeps the earlier sample).
    keep_ties: bool,
}

impl WeightedMax {
    /// The largest weighted value a cell of `range` can give: weights are in
    /// `[1 - cue, 1]`.
    #[inline(always)]
    fn bound(&self, range: [f32; 2]) -> f32 {
        if range[1] >= 0.0 {
            range[1]
        } else {
            (f64::from(range[1]) * (1.0 - self.cue)) as f32
        }
    }
}

impl Ranked for WeightedMax {
    fn rank(&self, range: [f32; 2]) -> f32 {
        self.bound(range)
    }

    /// (as the plain MIP)
    const ENDS_TOGETHER: bool = true;

    fn skippable_earlier(&self, range: [f32; 2]) -> bool {
        let b = self.bound(range);
        if self.keep_ties {
            b < self.best
        } else {
            b <= self.best
        }
    }
}

impl Consumer for WeightedMax {
    /// For cells after every sample taken (the order of [`drive`]).
    #[inline(always)]
    fn skippable(&self, _cell: usize, range: [f32; 2]) -> bool {
        self.bound(range) <= self.best
    }

    #[inline(always)]
    fn skip(&mut self, _i: usize, _j: usize) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }

    #[inline(always)]
    fn take(&mut self, _i: usize, t: f64, f: f32) -> ControlFlow<()> {
        let s = ((t - self.t_ref) * self.inv_diameter).clamp(0.0, 1.0);
        let g = (f64::from(f) * (1.0 - self.cue * s)) as f32;
        if g > self.best || (g == self.best && t < self.t_best) {
            self.best = g;
            self.t_best = t;
        }
        ControlFlow::Continue(())
    }
}

impl CuedMip {
    /// The pixel from the weighted maximum `best` first reached at `t_best`.
    pub fn finish(&self, best: f32, t_best: f64, ray: &PixelRay) -> [f32; 4] {
        let s = t_best - ray.t_depth_ref;
        match self.output {
            CuedOutput::Value => [best, 0.0, 0.0, 0.0],
            CuedOutput::Depth => [s as f32, 0.0, 0.0, 0.0],
            CuedOutput::Coded {
                map,
                window: [lo, hi],
            } => {
                let c = map.at(s / self.diameter);
                let v = ((best - lo) / (hi - lo)).clamp(0.0, 1.0);
                [c[0] * v, c[1] * v, c[2] * v, 1.0]
            }
        }
    }
}

impl Integrand for CuedMip {
    fn channels(&self) -> usize {
        match self.output {
            CuedOutput::Coded { .. } => 4,
            _ => 1,
        }
    }

    #[inline]
    fn trace<F: Field>(
        &self,
        field: &F,
        ray: &PixelRay,
        march: &March,
        grid: Option<&MacroGrid>,
    ) -> ([f32; 4], Counts) {
        let mut e = WeightedMax {
            cue: self.cue,
            inv_diameter: 1.0 / self.diameter,
            t_ref: ray.t_depth_ref,
            best: f32::NEG_INFINITY,
            t_best: f64::INFINITY,
            keep_ties: self.output != CuedOutput::Value,
        };
        let nominal = march.len() as u64;
        let taken = drive_ranked(field, ray, march, grid, &mut e);
        (
            self.finish(e.best, e.t_best, ray),
            Counts { taken, nominal },
        )
    }
}

/// The running extremum of the samples: the maximum when `MAX`, else the minimum.
struct Extremum<const MAX: bool> {
    best: f32,
}

impl<const MAX: bool> Ranked for Extremum<MAX> {
    fn rank(&self, range: [f32; 2]) -> f32 {
        if MAX {
            range[1]
        } else {
            -range[0]
        }
    }

    /// Ranges lie in [0, 1] (`skip.rs`): cells whose maximum is at most zero hold
    /// only zeros, and the maximum of zeros is the first (a tie keeps the earlier
    /// sample, +0 or -0).
    fn first_settles(&self, best: f32) -> bool {
        MAX && best <= 0.0
    }

    const TAKES_RAW: bool = true;

    const ENDS_TOGETHER: bool = MAX;

    /// The raw values' extremum in eight lanes, mapped, then taken as one sample:
    /// the map does not decrease, so it is the extremum of the mapped values (a
    /// sample among them). Mapped values are never -0 ([`Normalize::apply`] gives
    /// +0 at and below the window), so the one that compares equal to the
    /// extremum has its bits, as the samples in order would leave it.
    #[inline(always)]
    fn take_raw_batch(&mut self, map: &Normalize, raws: &[f32]) {
        let raw = if MAX {
            lane_extremum(raws, f32::NEG_INFINITY, |a, b| a > b)
        } else {
            lane_extremum(raws, f32::INFINITY, |a, b| a < b)
        };
        let _ = self.take(0, 0.0, map.apply(f64::from(raw)));
    }
}

/// Hands `e` the first sample of `march` (if it has one); the samples taken.
fn first_sample<F: Field, C: Consumer>(field: &F, ray: &PixelRay, march: &March, e: &mut C) -> u64 {
    let first = march.len().min(1);
    let _ = Batch::for_field(field).sample(field, &ray.index, march, 0, first, e);
    first as u64
}

impl<const MAX: bool> Consumer for Extremum<MAX> {
    #[inline(always)]
    fn skippable(&self, _cell: usize, range: [f32; 2]) -> bool {
        if MAX {
            range[1] <= self.best
        } else {
            range[0] >= self.best
        }
    }

    #[inline(always)]
    fn skip(&mut self, _i: usize, _j: usize) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }

    #[inline(always)]
    fn take(&mut self, _i: usize, _t: f64, f: f32) -> ControlFlow<()> {
        // samples are never NaN: plain comparisons (one instruction each)
        self.best = if MAX {
            if f > self.best {
                f
            } else {
                self.best
            }
        } else if f < self.best {
            f
        } else {
            self.best
        };
        ControlFlow::Continue(())
    }

    /// The batch's extremum in eight lanes (one vector instruction for eight
    /// samples instead of a chain of one per sample), then the lanes'. The result is
    /// the bits of [`Consumer::take`] in order: values that compare equal have the
    /// same bits, but for +0 and -0, so a batch that brings the extremum to zero goes
    /// again in order. (One that starts at zero and ends there leaves every lane at
    /// its start: nothing beats the extremum.)
    #[inline(always)]
    fn take_batch(&mut self, from: usize, ts: &[f64], values: &[f32]) -> ControlFlow<usize> {
        let before = self.best;
        let lanes = if MAX {
            lane_extremum(values, before, |a, b| a > b)
        } else {
            lane_extremum(values, before, |a, b| a < b)
        };
        if lanes == 0.0 && before != 0.0 {
            return take_each(self, from, ts, values);
        }
        self.best = lanes;
        ControlFlow::Continue(())
    }
}

/// The extremum of `start` and `values` by `better` (`better(a, b)`: `a` replaces
/// `b`), in eight lanes, each starting at `start`, then across them; of values that
/// compare equal, any one.
#[inline(always)]
fn lane_extremum(values: &[f32], start: f32, better: impl Fn(f32, f32) -> bool) -> f32 {
    let mut lanes = [start; 8];
    let chunks = values.chunks_exact(8);
    let tail = chunks.remainder();
    for chunk in chunks {
        for (l, &v) in lanes.iter_mut().zip(chunk) {
            *l = if better(v, *l) { v } else { *l };
        }
    }
    for (l, &v) in lanes.iter_mut().zip(tail) {
        *l = if better(v, *l) { v } else { *l };
    }
    // halves against halves: a value that wins compares equal to the extremum
    let mut width = lanes.len();
    while width > 1 {
        width /= 2;
        for l in 0..width {
            let v = lanes[l + width];
            lanes[l] = if better(v, lanes[l]) { v } else { lanes[l] };
        }
    }
    lanes[0]
}

fn extremum<F: Field, const MAX: bool>(
    field: &F,
    ray: &PixelRay,
    march: &March,
    grid: Option<&MacroGrid>,
) -> ([f32; 4], Counts) {
    let mut e = Extremum::<MAX> {
        best: if MAX {
            f32::NEG_INFINITY
        } else {
            f32::INFINITY
        },
    };
    let nominal = march.len() as u64;
    let [w0, w1] = ray.walk;
    let taken = if MAX && grid.is_some() && w0 > w1 {
        // the ray meets only cells of zeros (`Mip::window_passes`)
        first_sample(field, ray, march, &mut e)
    } else {
        drive_ranked(field, ray, march, grid, &mut e)
    };
    ([e.best, 0.0, 0.0, 0.0], Counts { taken, nominal })
}

/// Hands `e` the ray's samples, the most promising macrocell first when the pass
/// skips ([`brightest_first`]), else in order; returns the samples taken.
fn drive_ranked<F: Field, C: Ranked>(
    field: &F,
    ray: &PixelRay,
    march: &March,
    grid: Option<&MacroGrid>,
    e: &mut C,
) -> u64 {
    match grid {
        Some(g) => match brightest_first(field, ray, march, g, e) {
            Some(taken) => taken,
            None => drive(march, field, ray, grid, e),
        },
        None => drive(march, field, ray, None, e),
    }
}

/// Most macrocells a ray's spans are listed for (a 512^3 volume's diagonal crosses
/// about 200); longer walks go in order.
const MAX_SPANS: usize = 320;
// (a whole number of groups of eight, for `March::first_at_or_after_known`)
const _: () = assert!(MAX_SPANS.is_multiple_of(8));

/// The extremum is the same whatever order the samples come in, and it grows fastest
/// from the cell that can hold the largest value: the ray's macrocells are listed
/// first, the one with the largest extreme of its range (its [`Ranked::rank`]: the
/// maximum for MIP, the minimum for MinIP, the bound of the weighted values for
/// depth-cued MIP) is sampled first, then the others in order, each passed over
/// when it cannot beat the running extremum (which the samples of the cells before
/// it have updated, but for the last fewer than [`FLUSH_AT`] of them, which are
/// collected into one call of the sampler). The samples are those of the march,
/// and a tie keeps the earlier sample; the result is the same bits as in order.
/// Returns the samples taken, or `None` (nothing taken) when the ray crosses more
/// than [`MAX_SPANS`] macrocells (or has more than 2^32 samples).
fn brightest_first<F: Field, C: Ranked>(
    field: &F,
    ray: &PixelRay,
    march: &March,
    grid: &MacroGrid,
    e: &mut C,
) -> Option<u64> {
    let n = march.len();
    if n >= u32::MAX as usize || grid.len() > u32::MAX as usize {
        return None;
    }
    // where each span ends, and its cell: the samples of span `s` are those from
    // `s - 1`'s end to its own (the first span starts at sample 0, the last ends
    // at `n`)
    let mut t_ends = [std::mem::MaybeUninit::<f64>::uninit(); MAX_SPANS];
    let mut cells = [std::mem::MaybeUninit::<u32>::uninit(); MAX_SPANS];
    let mut count = 0;
    let (mut best_key, mut best_span) = (f32::NEG_INFINITY, 0);
    let mut complete = false;
    // the ray's window (the whole ray but for MIP): the first span's samples start
    // at the ray's first, the last's end at its last, so samples outside the
    // window belong to the spans at its ends, cells of zeros (`Mip::window_passes`)
    let [w0, w1] = ray.walk;
    for span in grid.walk(&ray.index, w0, w1) {
        if count == MAX_SPANS {
            return None;
        }
        let key = e.rank(grid.range(span.cell));
        if key > best_key {
            (best_key, best_span) = (key, count);
        }
        t_ends[count].write(span.t1);
        cells[count].write(span.cell as u32);
        count += 1;
        if span.last {
            complete = true;
            break;
        }
    }
    // a walk that ended early (non-finite parameters) goes in order
    if !complete {
        return None;
    }
    if e.first_settles(best_key) {
        return Some(first_sample(field, ray, march, e));
    }
    // the ends' list padded to whole groups of eight (MAX_SPANS is a multiple) where
    // they are found together
    let padded_count = if C::ENDS_TOGETHER {
        count.next_multiple_of(8)
    } else {
        count
    };
    for t in &mut t_ends[count..padded_count] {
        t.write(w1);
    }
    // SAFETY: the first `padded_count` entries of `t_ends` and `count` of `cells`
    // were written above; `MaybeUninit<T>` has the layout of `T`.
    let (t_ends, cells): (&[f64], &[u32]) = unsafe {
        (
            &*(std::ptr::addr_of!(t_ends[..padded_count]) as *const [f64]),
            &*(std::ptr::addr_of!(cells[..count]) as *const [u32]),
        )
    };
    // every span's end at once where that is cheap (eight found together cost less
    // than two found one by one) and the consumer samples many spans; any other
    // end found only if it is needed
    let mut known = [std::mem::MaybeUninit::<u32>::uninit(); MAX_SPANS];
    let known: &[u32] = if C::ENDS_TOGETHER {
        march.first_at_or_after_known(t_ends, &mut known[..padded_count])
    } else {
        &[]
    };
    let end = |s: usize| {
        if s + 1 == count {
            n
        } else if C::ENDS_TOGETHER && known[s] != UNKNOWN {
            known[s] as usize
        } else {
            march.first_at_or_after(t_ends[s])
        }
    };
    let mut taken = 0u64;
    let mut runs = Runs::for_field(field);
    // the span last sampled and its end: a span sampled right after the one before
    // it starts where that one ended
    let mut last = (usize::MAX, 0);
    let mut sample = |e: &mut C, runs: &mut Runs, s: usize, earlier: bool| {
        // the span's samples are found before a flush, so that their chain of
        // dependent operations runs alongside the sampler's
        let a = if s == 0 {
            0
        } else if last.0 == s - 1 {
            last.1
        } else {
            end(s - 1)
        };
        let b_end = end(s);
        last = (s, b_end);
        if runs.len >= FLUSH_AT {
            runs.flush(field, &ray.index, e);
        }
        let range = grid.range(cells[s] as usize);
        if e.passes_over(range, earlier) {
            return;
        }
        let mut b = b_end.max(a);
        if e.first_settles(e.rank(range)) {
            // a cell of zeros, sampled only while nothing has been (as the one a
            // window starts in, with every sample in front of it): its first
            // sample is its maximum
            b = b.min(a + 1);
        }
        runs.push(field, &ray.index, march, a, b, e);
        taken += (b - a) as u64;
    };
    sample(e, &mut runs, best_span, false);
    runs.flush(field, &ray.index, e);
    // most cells are passed over: that test here, without a call (`sample` tests
    // again, after the flush it may owe first)
    for (s, &cell) in cells.iter().enumerate() {
        if s == best_span {
            continue;
        }
        let earlier = s < best_span;
        if runs.len < FLUSH_AT && e.passes_over(grid.range(cell as usize), earlier) {
            continue;
        }
        sample(e, &mut runs, s, earlier);
    }
    runs.flush(field, &ray.index, e);
    Some(taken)
}

/// Samples that [`brightest_first`] collects from the cells it cannot pass over
/// before it hands them to the sampler in one call, updating the running extremum
/// that decides which cells come next. A call costs about as much as a few
/// samples, so collecting across cells pays for the few more samples taken before
/// the extremum is updated; this many was the fastest of those measured on the
/// peer MIPs (`bench/peers/README.md`).
const FLUSH_AT: usize = 48;

/// Samples of several runs of a march, handed to a ranked consumer (which never
/// stops a ray) in one call of the sampler: in order, [`BATCH`] at a time, in the
/// first `len` places of `batch`.
struct Runs {
    batch: Batch,
    len: usize,
}

impl Runs {
    /// Runs of samples of `field`.
    #[inline(always)]
    fn for_field<F: Field>(field: &F) -> Runs {
        Runs {
            batch: Batch::for_field(field),
            len: 0,
        }
    }

    /// Adds samples `a..b` of `march`, handing over a full batch.
    #[inline(always)]
    fn push<F: Field, C: Ranked>(
        &mut self,
        field: &F,
        ray: &IndexRay,
        march: &March,
        mut a: usize,
        b: usize,
        e: &mut C,
    ) {
        while a < b {
            let m = (b - a).min(BATCH - self.len);
            march.fill(a, &mut self.batch.ts[self.len..self.len + m]);
            self.len += m;
            a += m;
            if self.len == BATCH {
                self.flush(field, ray, e);
            }
        }
    }

    /// Hands over the samples added since the last call.
    #[inline(always)]
    fn flush<F: Field, C: Ranked>(&mut self, field: &F, ray: &IndexRay, e: &mut C) {
        let n = std::mem::take(&mut self.len);
        if n > 0 {
            let b = &mut self.batch;
            let m = padded(&mut b.ts, n, b.lanes);
            // raw values where the consumer takes them and the field has them (a
            // constant `None` for the fields that never do, asked again here so
            // that their flush keeps no test of it)
            let raw = if C::TAKES_RAW { field.raw_map() } else { None };
            if let Some(map) = &raw {
                let (ts, values) = (&b.ts[..m], &mut b.values[..m]);
                field.raw_values_along(ray.o, ray.d, ts, values, &mut b.cache);
                e.take_raw_batch(map, &b.values[..n]);
                return;
            }
            field.values_along(ray.o, ray.d, &b.ts[..m], &mut b.values[..m], &mut b.cache);
            // the extremum's consumers never stop a ray (nor use the indices)
            let _ = e.take_batch(0, &b.ts[..n], &b.values[..n]);
        }
    }
}

impl Integrand for Mip {
    fn reads_depth_reference(&self) -> bool {
        false
    }

    fn channels(&self) -> usize {
        1
    }

    /// Cells of zeros (whose samples are all zero): a ray's maximum is the same
    /// without those in front of and behind its other cells, as they are passed
    /// over once any sample is taken, and a ray that meets no other cell has the
    /// maximum of its first sample (`extremum`).
    fn window_passes(&self, _cell: usize, range: [f32; 2]) -> Option<bool> {
        Some(range[0] >= 0.0 && range[1] <= 0.0)
    }

    #[inline]
    fn trace<F: Field>(
        &self,
        field: &F,
        ray: &PixelRay,
        march: &March,
        grid: Option<&MacroGrid>,
    ) -> ([f32; 4], Counts) {
        extremum::<F, true>(field, ray, march, grid)
    }
}

impl Integrand for Minip {
    fn reads_depth_reference(&self) -> bool {
        false
    }

    fn channels(&self) -> usize {
        1
    }

    #[inline]
    fn trace<F: Field>(
        &self,
        field: &F,
        ray: &PixelRay,
        march: &March,
        grid: Option<&MacroGrid>,
    ) -> ([f32; 4], Counts) {
        extremum::<F, false>(field, ray, march, grid)
    }
}

impl Integrand for Average {
    fn reads_depth_reference(&self) -> bool {
        false
    }

    fn channels(&self) -> usize {
        1
    }

    /// All-zero cells, as the trapezoid passes over them.
    fn fixed_skippable(&self, _cell: usize, range: [f32; 2]) -> Option<bool> {
        Some(crate::mode::xray::integrator::skippable(range))
    }

    /// The trapezoid integral over the length; a ray of zero length (grazing a
    /// corner) gets its one sample.
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
        let n = march.len();
        let (t0, t1) = (march.t(0), march.t(n - 1));
        let mean = if n == 1 || t1 <= t0 {
            t.first
        } else {
            t.sum() / (t1 - t0)
        };
        let counts = Counts {
            taken,
            nominal: n as u64,
        };
        ([mean as f32, 0.0, 0.0, 0.0], counts)
    }
}

/// Local MIP's search: the last sample of the first non-decreasing run that
/// starts at or above the threshold.
struct Climb {
    threshold: f32,
    climbing: Option<f32>,
}

impl Consumer for Climb {
    #[inline(always)]
    fn skippable(&self, _cell: usize, range: [f32; 2]) -> bool {
        self.climbing.is_none() && range[1] < self.threshold
    }

    #[inline(always)]
    fn skip(&mut self, _i: usize, _j: usize) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }

    #[inline(always)]
    fn take(&mut self, _i: usize, _t: f64, f: f32) -> ControlFlow<()> {
        match self.climbing {
            Some(prev) if f < prev => return ControlFlow::Break(()),
            Some(_) => self.climbing = Some(f),
            None if f >= self.threshold => self.climbing = Some(f),
            None => {}
        }
        ControlFlow::Continue(())
    }
}

impl Integrand for Lmip {
    fn reads_depth_reference(&self) -> bool {
        false
    }

    fn channels(&self) -> usize {
        1
    }

    /// Cells of zeros, as MIP's ([`Mip::window_passes`]), when the threshold is
    /// above zero: no climb starts in them, one that reaches them ends at their
    /// first sample (taken: a climbing ray passes over nothing), and the ray that
    /// never reaches the threshold is answered by MIP over the same window.
    fn window_passes(&self, cell: usize, range: [f32; 2]) -> Option<bool> {
        if self.threshold > 0.0 {
            Mip.window_passes(cell, range)
        } else {
            None
        }
    }

    /// The first local maximum among samples at or above the threshold. Where no
    /// sample reaches the threshold the result is the ray's maximum (as in Sato et
    /// al. 1998), so the image has no holes.
    #[inline]
    fn trace<F: Field>(
        &self,
        field: &F,
        ray: &PixelRay,
        march: &March,
        grid: Option<&MacroGrid>,
    ) -> ([f32; 4], Counts) {
        let mut c = Climb {
            threshold: self.threshold,
            climbing: None,
        };
        let taken = drive(march, field, ray, grid, &mut c);
        let nominal = march.len() as u64;
        match c.climbing {
            Some(v) => ([v, 0.0, 0.0, 0.0], Counts { taken, nominal }),
            None => {
                let (v, more) = extremum::<F, true>(field, ray, march, grid);
                let counts = Counts {
                    taken: taken + more.taken,
                    nominal,
                };
                (v, counts)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::integrator::testing::{along_x, Lanes, Line};
    use crate::render::integrator::trace;
    use glam::DVec3;

    fn run(i: impl Integrand, v: &'static [f32]) -> f32 {
        trace(&i, &Line(v), &along_x((v.len() - 1) as f64), 1.0, 0.0).0[0]
    }

    /// `Extremum::take_batch` from `start` against `take` in order: the same bits.
    fn same_bits<const MAX: bool>(start: f32, ts: &[f64], values: &[f32]) {
        let mut batch = Extremum::<MAX> { best: start };
        let mut each = Extremum::<MAX> { best: start };
        assert!(batch.take_batch(7, ts, values).is_continue());
        assert!(take_each(&mut each, 7, ts, values).is_continue());
        assert_eq!(
            batch.best.to_bits(),
            each.best.to_bits(),
            "max {MAX}, start {start}, values {values:?}"
        );
    }

    /// `Extremum::take_batch` (eight lanes) gives the bits of `take` in order, for
    /// maxima and minima, batches of every length, and ties of +0 and -0.
    #[test]
    fn extremum_of_a_batch_is_the_bits_of_the_samples_in_order() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let ts = [0.0; 64];
        for case in 0..4000 {
            let n = (next() % 65) as usize;
            let values: Vec<f32> = (0..n)
                .map(|_| match next() % 4 {
                    0 => 0.0,
                    1 => -0.0,
                    _ if case % 2 == 0 => (next() % 1000) as f32 / 999.0,
                    _ => -((next() % 1000) as f32) / 999.0,
                })
                .collect();
            for start in [f32::NEG_INFINITY, f32::INFINITY, 0.0, -0.0, 0.5] {
                same_bits::<true>(start, &ts[..n], &values);
                same_bits::<false>(start, &ts[..n], &values);
            }
        }
    }

    /// `Extremum::take_raw_batch` of raw values gives the bits of `take` of their
    /// mapped values in order, for maxima and minima, windows that clamp raw
    /// values at either end, and running extrema of either sign of zero.
    #[test]
    fn extremum_of_raw_values_is_the_bits_of_their_samples_in_order() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let maps = [
            Normalize::new(0.0, 255.0),
            Normalize::new(-20.0, 300.0),
            Normalize::new(30.0, 200.0),
        ];
        let ts = [0.0; 64];
        for map in maps {
            for _ in 0..500 {
                let n = 1 + (next() % 64) as usize;
                // interpolated bytes, some below and above the window
                let raws: Vec<f32> = (0..n)
                    .map(|_| (next() % 65536) as f32 / 255.0 - 0.5)
                    .collect();
                let mapped: Vec<f32> = raws.iter().map(|&r| map.apply(f64::from(r))).collect();
                for start in [f32::NEG_INFINITY, f32::INFINITY, 0.0, -0.0, 0.5, 1.0] {
                    let mut raw = Extremum::<true> { best: start };
                    let mut each = Extremum::<true> { best: start };
                    raw.take_raw_batch(&map, &raws);
                    assert!(take_each(&mut each, 0, &ts[..n], &mapped).is_continue());
                    assert_eq!(raw.best.to_bits(), each.best.to_bits(), "max, {start}");
                    let mut raw = Extremum::<false> { best: start };
                    let mut each = Extremum::<false> { best: start };
                    raw.take_raw_batch(&map, &raws);
                    assert!(take_each(&mut each, 0, &ts[..n], &mapped).is_continue());
                    assert_eq!(raw.best.to_bits(), each.best.to_bits(), "min, {start}");
                }
            }
        }
    }

    /// `Runs::flush` pads a tail of two or more samples to a multiple of the
    /// field's lanes with the last position, and hands the consumer only the
    /// samples it was given: the maximum is that of those samples.
    #[test]
    fn a_flush_pads_its_tail_to_the_lanes_and_keeps_only_its_samples() {
        let ray = along_x(63.0);
        let march = March::new(0.0, 63.0, 0.5);
        for lanes in [1, 4, 8] {
            for n in 1..BATCH {
                let field = Lanes::new(lanes);
                let mut runs = Runs::for_field(&field);
                let mut e = Extremum::<true> {
                    best: f32::NEG_INFINITY,
                };
                // the last samples: the values fall towards them
                let from = march.len() - n;
                runs.push(&field, &ray.index, &march, from, march.len(), &mut e);
                runs.flush(&field, &ray.index, &mut e);
                let calls = field.calls();
                assert_eq!(calls.len(), 1, "lanes {lanes}, n {n}");
                let asked = &calls[0];
                let padded = lanes > 1 && n % lanes >= 2;
                let want_len = if padded { n.next_multiple_of(lanes) } else { n };
                assert_eq!(asked.len(), want_len, "lanes {lanes}, n {n}");
                assert!(asked[n..].iter().all(|&t| t == asked[n - 1]));
                assert!((0..n).all(|k| asked[k] == march.t(from + k)));
                let want = (from..march.len())
                    .map(|i| field.value(ray.index.o + ray.index.d * march.t(i)))
                    .fold(f32::NEG_INFINITY, f32::max);
                assert_eq!(e.best.to_bits(), want.to_bits(), "lanes {lanes}, n {n}");
            }
        }
    }

    #[test]
    fn lmip_picks_first_peak_above_threshold() {
        let l = Lmip { threshold: 0.5 };
        assert_eq!(run(l, &[0.1, 0.6, 0.7, 0.65, 0.9, 0.2]), 0.7);
        assert_eq!(run(l, &[0.1, 0.3, 0.2]), 0.3, "falls back to the maximum");
        assert_eq!(run(l, &[0.1, 0.6, 0.8]), 0.8, "still climbing at the exit");
    }

    #[test]
    fn average_is_length_weighted() {
        // samples at 0, 1, 1.5 of f = x: (0.5 + 0.625) / 1.5 = 0.75
        struct X;
        impl Field for X {
            fn sizes(&self) -> [usize; 3] {
                [2, 1, 1]
            }
            fn value(&self, p: DVec3) -> f32 {
                p.x as f32
            }
            fn gradient(&self, _p: DVec3) -> DVec3 {
                DVec3::ZERO
            }
            fn cell_corners(&self, _c: [usize; 3]) -> [f32; 8] {
                [0.0; 8]
            }
        }
        let mut r = along_x(1.0);
        r.t_exit = 1.5;
        let got = trace(&Average, &X, &r, 1.0, 0.0).0[0];
        assert!((got - 0.75).abs() < 1e-7);
    }
}
