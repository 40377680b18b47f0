//! What every per-ray integrator is built on: the [`Integrand`] interface (a pure
//! function of the field and the ray: no I/O, no locks, no allocation, generic over
//! the field so that the inner loop is compiled once per (voxel type, filter,
//! mode)), the ray it is given ([`PixelRay`]), and the one sampling loop. The modes'
//! own integrands live with their families in `crate::mode`.
//!
//! Sampled modes are [`Consumer`]s: the one sampling loop, [`drive`], walks the
//! ray's macrocells (when the pass skips empty space), passes over the samples of
//! the cells the consumer says cannot change its result, and hands it the others in
//! order, [`BATCH`] at a time. Exact passes (`mode::exact`) walk the voxel cells
//! instead; `root` is the root finder they share with the crossing searches.
//! Formulas: docs/formulas.md "Render modes" and "Emission-absorption and compositing".

pub(crate) mod root;

use std::ops::ControlFlow;

use glam::DVec3;

use super::clip::Cut;
use super::march::{Lattice, March};
use super::ray::IndexRay;
use super::skip::{MacroGrid, Piece};
use crate::sample::{CellCache, Field};

/// Samples a ray took, and the samples the plain march would have taken.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Field samples actually taken (cells visited, for exact passes).
    pub taken: u64,
    /// Field samples of the march without skipping (cells on the ray, for exact
    /// passes).
    pub nominal: u64,
}

impl std::ops::AddAssign for Counts {
    fn add_assign(&mut self, o: Counts) {
        self.taken += o.taken;
        self.nominal += o.nominal;
    }
}

/// Everything about one pixel's ray an integrator needs.
#[derive(Clone, Copy, Debug)]
pub struct PixelRay {
    /// World origin.
    pub origin: DVec3,
    /// World unit direction.
    pub dir: DVec3,
    /// Index-space form.
    pub index: IndexRay,
    /// Entry into the box (world-unit parameter).
    pub t_enter: f64,
    /// Exit from the box.
    pub t_exit: f64,
    /// Where depth is measured from (the ray's entry into the box where the
    /// integrand does not read it: [`Integrand::reads_depth_reference`]).
    pub t_depth_ref: f64,
    /// The clipping plane the ray enters through, when a plane (not the box) sets
    /// `t_enter`.
    pub cut: Option<Cut>,
    /// The part of `[t_enter, t_exit]` a walk through the macrocells must cover:
    /// outside it lie only cells the integrand's [`Integrand::window_passes`]
    /// answers true for (`footprint.rs`): cells the pass passes over whatever the
    /// ray has seen ([`Integrand::fixed_skippable`]), or, for MIP, cells of zeros.
    /// The whole interval unless the view found a narrower one; empty (start above
    /// end) when nothing on the ray can matter. The walk's ends lie in such cells,
    /// so the samples a pass with fixed answers is handed are those of the whole
    /// walk.
    pub walk: [f64; 2],
}

impl PixelRay {
    /// World position at `t`.
    #[inline(always)]
    pub fn world(&self, t: f64) -> DVec3 {
        self.origin + self.dir * t
    }
}

/// A render mode's computation along one ray.
pub trait Integrand: Sync {
    /// Channels per pixel (1 for intensity modes, 4 for RGBA).
    fn channels(&self) -> usize;

    /// The pixel value where a ray misses the volume.
    fn miss(&self) -> [f32; 4] {
        if self.channels() == 4 {
            [0.0; 4]
        } else {
            [f32::NAN, 0.0, 0.0, 0.0]
        }
    }

    /// Whether the integrand reads [`PixelRay::t_depth_ref`] (depth output, depth
    /// cues): true by default; the integrands that never do say false, and their
    /// rays skip the bounding-sphere intersection that finds it (a square root per
    /// ray).
    fn reads_depth_reference(&self) -> bool {
        true
    }

    /// Whether every ray passes over macrocell `cell`, whose values lie in `range`,
    /// whatever it has seen before: `Some` for integrands whose consumers answer
    /// [`Consumer::skippable`] from the cell alone (and then with this answer),
    /// `None` (the default) where the answer depends on the ray, as a running
    /// maximum's does. With `Some`, a view's rays walk only the part where a cell
    /// that is not passed over can lie ([`PixelRay::walk`]).
    fn fixed_skippable(&self, _cell: usize, _range: [f32; 2]) -> Option<bool> {
        None
    }

    /// Whether a ray's walk may leave macrocell `cell`, whose values lie in
    /// `range`, outside its window ([`PixelRay::walk`]): `Some` for every cell or
    /// for none, and then a view's rays walk only the part where a cell answered
    /// `Some(false)` can lie. The integrand's [`Integrand::trace`] must give the
    /// pixel of the whole walk from the window. The default is
    /// [`Integrand::fixed_skippable`], whose cells the walk passes over anyway.
    fn window_passes(&self, cell: usize, range: [f32; 2]) -> Option<bool> {
        self.fixed_skippable(cell, range)
    }

    /// Integrates one ray sampled at `march` (exact integrands ignore it), passing
    /// over empty space with `grid` when given. Returns the pixel value and the
    /// samples taken.
    fn trace<F: Field>(
        &self,
        field: &F,
        ray: &PixelRay,
        march: &March,
        grid: Option<&MacroGrid>,
    ) -> ([f32; 4], Counts);
}

/// What a sampled integrator does with the samples of one ray, in order.
pub trait Consumer {
    /// Whether every sample inside macrocell `cell`, whose values lie in `range`,
    /// can be passed over now without changing the result. [`drive`] may ask before
    /// the samples of the cells just in front of `cell` are handed over (it samples
    /// consecutive cells as one run); when the answer is true it asks again after
    /// them, so only the second answer decides, and a false one only costs samples.
    fn skippable(&self, cell: usize, range: [f32; 2]) -> bool;
    /// Whether every sample inside octant `octant` of macrocell `cell`, whose values
    /// lie in `range`, can be passed over now (asked as [`Consumer::skippable`] is,
    /// for a cell that cannot be passed over whole, on grids with octants, which
    /// only the composite's passes have). Never, unless a consumer says otherwise.
    fn skippable_part(&self, _cell: usize, _octant: usize, _range: [f32; 2]) -> bool {
        false
    }

    /// The octants of macrocell `cell` of `grid` that [`Consumer::skippable_part`]
    /// says can be passed over now, as the bits of a mask.
    #[inline(always)]
    fn skippable_parts(&self, grid: &MacroGrid, cell: usize) -> u8 {
        let mut mask = 0;
        for octant in 0..8 {
            if self.skippable_part(cell, octant, grid.part_range(cell, octant)) {
                mask |= 1 << octant;
            }
        }
        mask
    }
    /// The samples `i..j` are passed over (the consumer accounts for the gap);
    /// `Break` ends the ray.
    fn skip(&mut self, i: usize, j: usize) -> ControlFlow<()>;
    /// Sample `i`, at `t`, has value `f`; `Break` ends the ray.
    fn take(&mut self, i: usize, t: f64, f: f32) -> ControlFlow<()>;
    /// Samples `from..from + values.len()`, at `ts`, have `values`: [`Consumer::take`]
    /// of each in order, unless a consumer does the same for a batch at a time;
    /// `Break(k)` when sample `from + k` ended the ray.
    #[inline(always)]
    fn take_batch(&mut self, from: usize, ts: &[f64], values: &[f32]) -> ControlFlow<usize> {
        take_each(self, from, ts, values)
    }
}

/// [`Consumer::take`] of each sample of a batch in order (the default
/// [`Consumer::take_batch`], and the way of a consumer's own for the batches it
/// does not handle at once).
#[inline(always)]
pub fn take_each<C: Consumer + ?Sized>(
    consumer: &mut C,
    from: usize,
    ts: &[f64],
    values: &[f32],
) -> ControlFlow<usize> {
    for k in 0..values.len() {
        if consumer.take(from + k, ts[k], values[k]).is_break() {
            return ControlFlow::Break(k);
        }
    }
    ControlFlow::Continue(())
}

/// The one sampling loop: hands `consumer` the samples of `lattice` along `ray`
/// (values of `field`), in order, passing over the samples of the macrocells it can
/// skip when `grid` is given (consecutive cells it cannot skip are sampled as one
/// run). In a macrocell it cannot skip whole, on a grid with octants, it is asked
/// again for each part of the span in one octant ([`Walk::pieces`](crate::render::skip::Walk::pieces)). Returns
/// the number of samples taken.
#[inline(always)]
pub fn drive<L: Lattice, F: Field, C: Consumer>(
    lattice: &L,
    field: &F,
    ray: &PixelRay,
    grid: Option<&MacroGrid>,
    consumer: &mut C,
) -> u64 {
    let mut runs = Runs {
        lattice,
        field,
        index: &ray.index,
        batch: Batch::for_field(field),
        i: 0,
        gap: false,
        open: None,
        taken: 0,
    };
    let Some(grid) = grid else {
        let n = lattice.len();
        let _ = runs.take(0, n, consumer);
        return runs.taken;
    };
    let [w0, w1] = ray.walk;
    if w0 > w1 {
        // every cell on the ray is passed over (as the last span of a whole walk
        // would pass over the samples)
        let n = lattice.len();
        if n > 0 {
            let _ = consumer.skip(0, n);
        }
        return 0;
    }
    let mut pieces = [Piece::default(); 4];
    let mut walk = grid.walk(&ray.index, w0, w1);
    while let Some(span) = walk.next() {
        let (cell, range) = (span.cell, grid.range(span.cell));
        // a cell that cannot be passed over whole, but some of whose octants can
        if grid.has_parts()
            && !consumer.skippable(cell, range)
            && consumer.skippable_parts(grid, cell) != 0
        {
            let k = walk.pieces(&ray.index, &span, &mut pieces);
            for (p, piece) in pieces[..k].iter().enumerate() {
                let last = span.last && p + 1 == k;
                let part = grid.part_range(cell, piece.octant);
                let ask = |c: &C| c.skippable_part(cell, piece.octant, part);
                if runs
                    .visit(piece.t0, piece.t1, last, consumer, ask)
                    .is_break()
                {
                    return runs.taken;
                }
            }
            continue;
        }
        let ask = |c: &C| c.skippable(span.cell, range);
        if runs
            .visit(span.t0, span.t1, span.last, consumer, ask)
            .is_break()
        {
            return runs.taken;
        }
    }
    // a walk that ended early (non-finite parameters) leaves its samples here
    let n = lattice.len();
    if runs.i < n {
        let _ = runs.take(runs.i, n, consumer);
    }
    runs.taken
}

/// [`drive`]'s state along one ray.
struct Runs<'a, L, F> {
    lattice: &'a L,
    field: &'a F,
    index: &'a IndexRay,
    batch: Batch,
    /// Samples before `i` are handled; those from `i` to the start of the current
    /// part lie in parts that were passed over while `gap` is true. Consecutive
    /// parts that are not passed over are sampled as one run (full batches, and the
    /// sample index found once per run rather than per part): `open` is where the
    /// run from `i` ends so far.
    i: usize,
    gap: bool,
    open: Option<f64>,
    taken: u64,
}

impl<L: Lattice, F: Field> Runs<'_, L, F> {
    /// Takes samples `from..to`; `Break` when the consumer stopped.
    #[inline(always)]
    fn take<C: Consumer>(&mut self, from: usize, to: usize, consumer: &mut C) -> ControlFlow<()> {
        let (field, index, lattice) = (self.field, self.index, self.lattice);
        match self.batch.sample(field, index, lattice, from, to, consumer) {
            Some(i) => {
                self.taken += (i + 1 - from) as u64;
                ControlFlow::Break(())
            }
            None => {
                self.taken += (to - from) as u64;
                ControlFlow::Continue(())
            }
        }
    }

    /// The part `t0..t1` of the ray (`last`: the ray's last), which `consumer`
    /// may pass over when `skippable` says so; `Break` once the ray is done.
    #[inline(always)]
    fn visit<C: Consumer>(
        &mut self,
        t0: f64,
        t1: f64,
        last: bool,
        consumer: &mut C,
        skippable: impl Fn(&C) -> bool,
    ) -> ControlFlow<()> {
        let n = self.lattice.len();
        let mut skip = skippable(consumer);
        if skip {
            if let Some(end) = self.open.take() {
                let j = self.lattice.first_at_or_after(end).max(self.i);
                if j > self.i {
                    self.take(self.i, j, consumer)?;
                    self.i = j;
                }
                // asked again, now that every earlier sample is handed over: they
                // may change the answer (a local MIP that started climbing samples
                // on). A part that was not skippable before them is sampled, which
                // is always right (a running maximum that has grown since would
                // only have passed over it)
                skip = skippable(consumer);
            }
        }
        if skip {
            self.gap = true;
            if !last {
                return ControlFlow::Continue(());
            }
            if self.i < n {
                // the last samples are passed over: the ray ends either way
                let _ = consumer.skip(self.i, n);
            }
            return ControlFlow::Break(());
        }
        if self.gap {
            let j = self.lattice.first_at_or_after(t0).max(self.i);
            self.gap = false;
            if j > self.i {
                consumer.skip(self.i, j)?;
                self.i = j;
            }
        }
        if last {
            if self.i < n {
                let _ = self.take(self.i, n, consumer);
            }
            return ControlFlow::Break(());
        }
        self.open = Some(t1);
        ControlFlow::Continue(())
    }
}

/// Samples along a ray taken [`BATCH`] at a time ([`Field::values_along`]), with the
/// sampler's cell cache: the positions and values of one batch. Aligned to a cache
/// line, so that the vector paths' loads and stores of eight positions never
/// straddle two lines, wherever the batch lands on the stack.
#[repr(C, align(64))]
pub(crate) struct Batch {
    pub(crate) ts: [f64; BATCH],
    pub(crate) values: [f32; BATCH],
    pub(crate) cache: CellCache,
    /// The field's [`Field::lanes`], asked once per ray ([`Batch::for_field`]; 1,
    /// no padding, by default).
    pub(crate) lanes: usize,
}

/// Samples per batch of a ray's march: enough to amortise a call into the vector path (its
/// constants and the tail of fewer than eight samples), few enough that a ray
/// stopping early wastes little: faster than smaller batches for X-ray and
/// composite frames, no different for MIP and iso-surface ones
/// (measured when it was chosen; the figures are in the commit).
pub const BATCH: usize = 64;

impl Default for Batch {
    fn default() -> Self {
        Batch {
            ts: [0.0; BATCH],
            values: [0.0; BATCH],
            cache: CellCache::default(),
            lanes: 1,
        }
    }
}

/// The number of positions to sample for the first `n` of `ts`: `n`, or, where the
/// field takes `lanes` samples at once and the last `n % lanes` are two or more,
/// `n` rounded up to a multiple of `lanes` (at most [`BATCH`]) with the last
/// position repeated in the places added. The tail then goes through the field's
/// widest path with the others (on the eight-lane path, rather than the four-lane
/// and one-sample ones), and the caller discards the extra samples. Repeating the
/// last position keeps every lane's position between the first and the last,
/// where the sampler may leave out its clamps. Most of an oblique view's MIP
/// flushes end in such a tail (along an axis none do), and the test costs a view
/// along an axis little (`bench/peers/README.md`).
#[inline(always)]
pub(crate) fn padded(ts: &mut [f64; BATCH], n: usize, lanes: usize) -> usize {
    // a mask, not `%`: `lanes` is known at run time only, and a division per
    // batch cost more than the padding saves
    debug_assert!(lanes.is_power_of_two());
    let tail = n & (lanes - 1);
    if tail >= 2 {
        pad(ts, n, n - tail + lanes)
    } else {
        n
    }
}

/// [`padded`]'s padding of `ts` from `n` to `m` positions (at most [`BATCH`]), out
/// of line, so that views along an axis, whose batches need none, run the code
/// they ran before.
#[cold]
#[inline(never)]
fn pad(ts: &mut [f64; BATCH], n: usize, m: usize) -> usize {
    let m = m.min(BATCH);
    let last = ts[n - 1];
    ts[n..m].fill(last);
    m
}

impl Batch {
    /// A batch for samples of `field`, padded to its lanes ([`padded`]).
    #[inline(always)]
    pub(crate) fn for_field<F: Field>(field: &F) -> Batch {
        Batch {
            lanes: field.lanes(),
            ..Batch::default()
        }
    }

    /// Hands `consumer` samples `from..to` of `lattice` in order; the sample at
    /// which it stopped, if it did (a few samples after that one may have been
    /// computed, never handed over).
    #[inline(always)]
    pub(crate) fn sample<L: Lattice, F: Field, C: Consumer>(
        &mut self,
        field: &F,
        ray: &IndexRay,
        lattice: &L,
        from: usize,
        to: usize,
        consumer: &mut C,
    ) -> Option<usize> {
        let mut i = from;
        while i < to {
            let m = (to - i).min(BATCH);
            lattice.fill(i, &mut self.ts[..m]);
            // the sampler's share: `m`, or more where the tail is padded
            let sampled = padded(&mut self.ts, m, self.lanes);
            field.values_along(
                ray.o,
                ray.d,
                &self.ts[..sampled],
                &mut self.values[..sampled],
                &mut self.cache,
            );
            if let ControlFlow::Break(k) = consumer.take_batch(i, &self.ts[..m], &self.values[..m])
            {
                return Some(i + k);
            }
            i += m;
        }
        None
    }
}

/// The jitter of one pixel's first sample, in `[0, 1)` of a step: a hash of the
/// pass's seed, the view's pose (which identifies the frame and the eye) and the
/// pixel, so it is the same whatever thread renders the pixel (docs/formulas.md
/// "Emission-absorption and compositing": a fixed per-pixel seed keeps frames
/// reproducible).
pub fn jitter_fraction(seed: u64, pose: [f64; 6], i: usize, j: usize) -> f64 {
    let mut h = splitmix64(seed);
    for x in pose {
        h = splitmix64(h ^ x.to_bits());
    }
    h = splitmix64(h ^ i as u64);
    h = splitmix64(h ^ ((j as u64) << 32 | 0x5bd1));
    // the top 53 bits as a fraction in [0, 1)
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// SplitMix64's finaliser (Steele, Lea and Flood 2014): a bijective 64-bit mix.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Integrates one ray with `integrand` at step `dt`, the first sample after the
/// entry moved back by `jitter` (in `[0, 1)`) of a step, without skipping: the
/// value of one pixel, for tools and tests. Returns the pixel value and the
/// samples taken (cells visited, for exact passes).
pub fn trace<I: Integrand, F: Field>(
    integrand: &I,
    field: &F,
    ray: &PixelRay,
    dt: f64,
    jitter: f64,
) -> ([f32; 4], u64) {
    let march = March::jittered(ray.t_enter, ray.t_exit, dt, jitter);
    let (value, counts) = integrand.trace(field, ray, &march, None);
    (value, counts.taken)
}

/// Fields and rays along x for the integrators' tests.
#[cfg(test)]
pub(crate) mod testing {
    use glam::DVec3;

    use super::PixelRay;
    use crate::render::ray::IndexRay;
    use crate::sample::Field;

    /// A field that is `v[round(x)]` along x (clamped to the ends).
    pub struct Line<'a>(pub &'a [f32]);

    impl Field for Line<'_> {
        fn sizes(&self) -> [usize; 3] {
            [self.0.len(), 1, 1]
        }
        fn value(&self, p: DVec3) -> f32 {
            self.0[(p.x.round().max(0.0) as usize).min(self.0.len() - 1)]
        }
        fn gradient(&self, _p: DVec3) -> DVec3 {
            DVec3::ZERO
        }
        fn cell_corners(&self, _c: [usize; 3]) -> [f32; 8] {
            [0.0; 8]
        }
    }

    /// A field along x that says it takes `lanes` samples at a time, recording the
    /// positions of each call of [`Field::values_along`].
    pub struct Lanes {
        lanes: usize,
        calls: std::sync::Mutex<Vec<Vec<f64>>>,
    }

    impl Lanes {
        /// A field that says it takes `lanes` samples at a time.
        pub fn new(lanes: usize) -> Lanes {
            Lanes {
                lanes,
                calls: Default::default(),
            }
        }

        /// The positions of each call so far (and forgets them).
        pub fn calls(&self) -> Vec<Vec<f64>> {
            std::mem::take(&mut *self.calls.lock().unwrap())
        }
    }

    impl Field for Lanes {
        fn sizes(&self) -> [usize; 3] {
            [64, 1, 1]
        }
        fn value(&self, p: DVec3) -> f32 {
            // a maximum in the middle of the ray, and different values either side
            (1.0 - (p.x - 9.3).abs() / 40.0) as f32
        }
        fn values_along(
            &self,
            o: DVec3,
            d: DVec3,
            ts: &[f64],
            out: &mut [f32],
            _cache: &mut crate::sample::CellCache,
        ) {
            self.calls.lock().unwrap().push(ts.to_vec());
            for (v, &t) in out.iter_mut().zip(ts) {
                *v = self.value(o + d * t);
            }
        }
        fn lanes(&self) -> usize {
            self.lanes
        }
        fn gradient(&self, _p: DVec3) -> DVec3 {
            DVec3::ZERO
        }
        fn cell_corners(&self, _c: [usize; 3]) -> [f32; 8] {
            [0.0; 8]
        }
    }

    /// The ray along +x from 0 to `t_exit` (index space = world space).
    pub fn along_x(t_exit: f64) -> PixelRay {
        PixelRay {
            origin: DVec3::ZERO,
            dir: DVec3::X,
            index: IndexRay {
                o: DVec3::ZERO,
                d: DVec3::X,
            },
            t_enter: 0.0,
            t_exit,
            t_depth_ref: 0.0,
            cut: None,
            walk: [0.0, t_exit],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::testing::{along_x, Lanes, Line};
    use super::*;
    use crate::render::skip::Support;

    /// Records what `drive` hands it; passes over all-zero cells only until it has
    /// taken a sample of at least 0.5 (a consumer whose answer changes with the
    /// samples, as a local MIP's does once it climbs).
    #[derive(Default)]
    struct Watch {
        seen: bool,
        taken: Vec<usize>,
        skipped: Vec<(usize, usize)>,
    }

    impl Consumer for Watch {
        fn skippable(&self, _cell: usize, range: [f32; 2]) -> bool {
            !self.seen && range[1] <= 0.0
        }
        fn skip(&mut self, i: usize, j: usize) -> ControlFlow<()> {
            self.skipped.push((i, j));
            ControlFlow::Continue(())
        }
        fn take(&mut self, i: usize, _t: f64, f: f32) -> ControlFlow<()> {
            self.taken.push(i);
            self.seen |= f >= 0.5;
            ControlFlow::Continue(())
        }
    }

    /// The integrands that say they do not read [`PixelRay::t_depth_ref`] give the
    /// same bits wherever it lies; one that reads it (depth) does not, so the
    /// comparison can tell.
    #[test]
    fn integrands_that_skip_the_depth_reference_do_not_read_it() {
        use crate::mode::composite::{Composite, CompositeTable};
        use crate::mode::crossing::Depth;
        use crate::mode::projection::{Average, Lmip, Minip, Mip};
        use crate::mode::xray::{Xray, XrayOutput};
        use crate::transfer::{Interpolation as Ramp, Transfer1D};
        let v: Vec<f32> = (0..40).map(|i| ((i as f32) * 0.37).sin().abs()).collect();
        let field = Line(&v);
        let at = |depth_ref: f64| {
            let mut ray = along_x(39.0);
            ray.t_depth_ref = depth_ref;
            ray
        };
        fn bits<I: Integrand>(i: &I, field: &Line, ray: &PixelRay) -> [u32; 4] {
            trace(i, field, ray, 0.5, 0.0).0.map(f32::to_bits)
        }
        fn same<I: Integrand>(i: &I, field: &Line, a: &PixelRay, b: &PixelRay) -> bool {
            bits(i, field, a) == bits(i, field, b)
        }
        let (a, b) = (at(0.0), at(-7.25));
        let tf = Transfer1D::new(
            vec![(0.0, [1.0, 0.5, 0.2])],
            vec![(0.0, 0.0), (0.3, 0.0), (1.0, 0.4)],
            Ramp::Linear,
        )
        .unwrap();
        let composite = Composite::new(
            CompositeTable::OneD(tf.table(256)),
            0.5,
            1.0,
            None,
            0.99,
            1.0,
            None,
        );
        let xray = Xray {
            output: XrayOutput::Integral,
            mu: 1.0,
        };
        let lmip = Lmip { threshold: 0.6 };
        assert!(!composite.reads_depth_reference() && same(&composite, &field, &a, &b));
        assert!(!Mip.reads_depth_reference() && same(&Mip, &field, &a, &b));
        assert!(!Minip.reads_depth_reference() && same(&Minip, &field, &a, &b));
        assert!(!Average.reads_depth_reference() && same(&Average, &field, &a, &b));
        assert!(!lmip.reads_depth_reference() && same(&lmip, &field, &a, &b));
        assert!(!xray.reads_depth_reference() && same(&xray, &field, &a, &b));
        let depth = Depth { threshold: 0.5 };
        assert!(depth.reads_depth_reference() && !same(&depth, &field, &a, &b));
    }

    /// Every sample handed over: its index, position and value.
    #[derive(Default)]
    struct Record(Vec<(usize, f64, f32)>);

    impl Consumer for Record {
        fn skippable(&self, _cell: usize, _range: [f32; 2]) -> bool {
            false
        }
        fn skip(&mut self, _i: usize, _j: usize) -> ControlFlow<()> {
            ControlFlow::Continue(())
        }
        fn take(&mut self, i: usize, t: f64, f: f32) -> ControlFlow<()> {
            self.0.push((i, t, f));
            ControlFlow::Continue(())
        }
    }

    /// `Batch::sample` asks the field for a batch's tail of two or more samples
    /// padded to its lanes (the last position repeated), and hands the consumer
    /// the samples of the run alone, in order, with their own values.
    #[test]
    fn batches_pad_their_tail_to_the_lanes_and_hand_over_only_their_samples() {
        let ray = along_x(63.0);
        let march = March::new(0.0, 63.0, 0.5);
        for lanes in [1, 4, 8] {
            for (from, to) in [(0, 1), (3, 5), (0, 64), (1, 66), (10, 127), (0, 127)] {
                let field = Lanes::new(lanes);
                let mut rec = Record::default();
                let mut batch = Batch::for_field(&field);
                let stopped = batch.sample(&field, &ray.index, &march, from, to, &mut rec);
                assert_eq!(stopped, None);
                let want: Vec<_> = (from..to)
                    .map(|i| (i, march.t(i), field.value(DVec3::X * march.t(i))))
                    .collect();
                assert_eq!(rec.0, want, "lanes {lanes}, samples {from}..{to}");
                // one call per batch of up to BATCH samples, its tail padded
                let calls = field.calls();
                let mut i = from;
                for call in &calls {
                    let m = (to - i).min(BATCH);
                    let padded = lanes > 1 && m % lanes >= 2;
                    let k = if padded { m.next_multiple_of(lanes) } else { m };
                    assert_eq!(call.len(), k, "lanes {lanes}, batch at {i} of {m}");
                    assert!((0..m).all(|j| call[j] == march.t(i + j)));
                    assert!(call[m..].iter().all(|&t| t == call[m - 1]));
                    i += m;
                }
                assert_eq!(i, to, "lanes {lanes}: {} calls", calls.len());
            }
        }
    }

    #[test]
    fn drive_asks_again_after_sampling_a_run_of_cells() {
        // 65 voxels along x (eight macrocells): a peak in cell 1, zeros after it
        // up to a bump in cell 5
        let mut v = vec![0.0f32; 65];
        v[12] = 1.0;
        v[13] = 1.0;
        v[44] = 0.3;
        let grid = MacroGrid::from_values([65, 1, 1], Support::Linear, |i| v[i]);
        let field = Line(&v);
        let ray = along_x(64.0);
        let march = March::new(0.0, 64.0, 0.5);
        let n = march.len();
        let mut w = Watch::default();
        let taken = drive(&march, &field, &ray, Some(&grid), &mut w);
        assert_eq!(taken as usize, w.taken.len());
        // every sample handed over once, in order, as taken or passed over
        let mut all: Vec<usize> = w.taken.clone();
        for &(i, j) in &w.skipped {
            all.extend(i..j);
        }
        all.sort_unstable();
        assert_eq!(all, (0..n).collect::<Vec<_>>());
        assert!(w.taken.windows(2).all(|p| p[0] < p[1]));
        // cell 0 was passed over, and from the first sample of the peak (x = 12)
        // on, nothing is: the zero cells after the peak were asked again once the
        // run of cells before them was sampled
        assert!(!w.skipped.is_empty() && w.skipped[0].0 == 0);
        let first = march.first_at_or_after(12.0);
        assert!((first..n).all(|i| w.taken.contains(&i)), "{:?}", w.skipped);
    }

    #[test]
    fn jitter_is_a_deterministic_uniform_fraction() {
        let pose = [0.0, -3.0, 0.0, 0.0, 1.0, 0.0];
        let f = |i, j| jitter_fraction(7, pose, i, j);
        assert_eq!(f(3, 4), f(3, 4));
        assert_ne!(f(3, 4), f(4, 3));
        assert_ne!(f(3, 4), jitter_fraction(8, pose, 3, 4));
        // the mean of many pixels is near 1/2 (standard error 1/sqrt(12 n) = 0.003)
        let n = 10_000;
        let mean: f64 = (0..n).map(|k| f(k % 100, k / 100)).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.015, "{mean}");
        assert!((0..n).all(|k| (0.0..1.0).contains(&f(k % 100, k / 100))));
    }
}
