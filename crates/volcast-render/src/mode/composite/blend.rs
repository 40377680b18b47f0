//! A composite of several volumes in one ray (docs/formulas.md "Several volumes"):
//! at each sample position each volume gives its transfer function's colour
//! `c_i` and opacity `a_i` (corrected for the segment's length; nothing outside
//! its box), the sample's opacity is `1 - prod(1 - a_i)` and its colour
//! `sum(a_i c_i) / sum(a_i)`, composited front to back as one volume's samples
//! are. Each volume is shaded with its own gradient.
//!
//! The samples sit on one march over the union of the volumes' boxes (cut by the
//! clipping planes), so every volume is sampled at the same positions. Each
//! volume is walked through its own macrocells, a chunk of the march at a time,
//! and sampled only in the cells its transfer function is not transparent in: the
//! ray costs what the volumes it meets are not transparent in (the union of their
//! occupancy), and an overlay that is empty in most of the box costs little. A
//! sample only one volume contributes to is that volume's own sample, bit for bit
//! (a second volume that is transparent there changes nothing); where several
//! contribute, their terms are taken in an order of their own values, so the
//! blend does not depend on the order the scene lists the volumes in.

use std::ops::ControlFlow;

use glam::{Vec3, Vec4};

use super::integrator::{Composite, FrontToBack};
use crate::render::camera::Projection;
use crate::render::clip::{clip_ray, ClipPlane};
use crate::render::footprint::{Footprint, Windows, WINDOW_TILE};
use crate::render::frame::{Film, RenderView, TILE};
use crate::render::integrator::{drive, jitter_fraction, Consumer, Counts, PixelRay};
use crate::render::march::{Lattice, March, Midpoints};
use crate::render::skip::MacroGrid;
use crate::render::{IndexFrame, View};
use crate::sample::Field;

/// Midpoints of a ray's march handed to each volume's walk at a time, at most:
/// the volumes' contributions to them are blended before the next chunk is
/// walked, so a ray that turns opaque stops within a chunk. The first chunk is
/// shorter, and each next one twice as long, so that a ray that turns opaque
/// soon wastes few samples and a long one walks its cells in few chunks.
const CHUNK: usize = 4096;

/// The first chunk of a ray.
const FIRST_CHUNK: usize = 256;

/// One volume of a blend, ready to sample.
pub(super) struct Layer<'a> {
    /// Its reconstruction.
    pub field: Box<dyn Field + 'a>,
    /// Its transfer function's tables and transparency per macrocell.
    pub composite: Composite,
    /// Its macrocells, when the pass skips empty space.
    pub grid: Option<&'a MacroGrid>,
    /// Its box in index space and the map to it.
    pub frame: IndexFrame,
    /// The macrocells its transfer function is not transparent in, as boxes:
    /// per tile of a view, the part of a ray that can meet them.
    pub footprint: Option<Footprint>,
}

impl<'a> Layer<'a> {
    /// The volume's part of a blend: its field, tables, grid and frame.
    pub fn new(
        field: Box<dyn Field + 'a>,
        composite: Composite,
        grid: Option<&'a MacroGrid>,
        frame: IndexFrame,
    ) -> Layer<'a> {
        let footprint = grid.map(|g| Footprint::new(g, |m, _range| !composite.transparency(m).0));
        Layer {
            field,
            composite,
            grid,
            frame,
            footprint,
        }
    }
}

/// A composite of several volumes, ready to render views.
pub(super) struct Blend<'a> {
    /// The volumes, in the pass's order.
    pub layers: Vec<Layer<'a>>,
    /// The step (world units) and its reciprocal.
    pub dt: f64,
    pub inv_dt: f64,
    /// Per-pass seed of the jittered first sample.
    pub jitter: Option<u64>,
    /// The clipping planes of the pass.
    pub clips: &'a [ClipPlane],
    /// Stop when the accumulated opacity reaches this.
    pub early_stop: f32,
}

/// One volume's part of a ray: its index-space ray and its interval inside the box.
#[derive(Clone, Copy)]
struct Hit {
    ray: PixelRay,
    t0: f64,
    t1: f64,
    /// Whether its macrocells' ranges hold for this ray (else it is sampled whole).
    skips: bool,
}

/// A sample one volume contributes: the index of its midpoint, colour, opacity.
type Term = (u32, Vec4, f32);

/// Per band of rows, what its rays reuse.
struct Scratch {
    hits: Vec<Option<Hit>>,
    terms: Vec<Vec<Term>>,
    cursors: Vec<usize>,
    at: Vec<(Vec4, f32)>,
    /// The volumes a ray meets: each one's index and its midpoints' range.
    parts: Vec<(usize, usize, usize)>,
    /// The volumes with terms in the current chunk.
    busy: Vec<usize>,
}

impl Blend<'_> {
    fn scratch(&self) -> Scratch {
        let n = self.layers.len();
        Scratch {
            hits: vec![None; n],
            terms: (0..n).map(|_| Vec::with_capacity(CHUNK)).collect(),
            cursors: vec![0; n],
            at: Vec::with_capacity(n),
            parts: Vec::with_capacity(n),
            busy: Vec::with_capacity(n),
        }
    }

    /// The pixel `(i, j)` of `view`; `None` where its ray misses every volume.
    /// `windows[k]`, where given, limits volume `k` to the part of its tile's rays
    /// that can meet its cells that are not transparent (the samples outside it
    /// add nothing).
    fn trace_pixel(
        &self,
        view: &View,
        i: usize,
        j: usize,
        windows: &[Option<Windows>],
        s: &mut Scratch,
    ) -> Option<([f32; 4], Counts)> {
        let ray = view.pixel_ray(i, j);
        let t_min = match view.projection {
            Projection::Perspective => 0.0,
            Projection::Orthographic => f64::NEG_INFINITY,
        };
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (l, hit) in self.layers.iter().zip(s.hits.iter_mut()) {
            let index = l.frame.to_index(ray.origin, ray.dir);
            *hit = l.frame.clip(&index, t_min).map(|(t0, t1)| {
                lo = lo.min(t0);
                hi = hi.max(t1);
                Hit {
                    ray: PixelRay {
                        origin: ray.origin,
                        dir: ray.dir,
                        index,
                        t_enter: t0,
                        t_exit: t1,
                        t_depth_ref: t0,
                        cut: None,
                        walk: [t0, t1],
                    },
                    t0,
                    t1,
                    skips: false,
                }
            });
        }
        if lo > hi {
            return None;
        }
        let (t_enter, t_exit, cut) = if self.clips.is_empty() {
            (lo, hi, None)
        } else {
            clip_ray(self.clips, ray.origin, ray.dir, (lo, hi))?
        };
        let jitter = self.jitter.map_or(0.0, |seed| {
            let (e, f) = (view.eye, view.forward);
            jitter_fraction(seed, [e.x, e.y, e.z, f.x, f.y, f.z], i, j)
        });
        let march = March::jittered_by(t_enter, t_exit, self.dt, self.inv_dt, jitter);
        let mids = Midpoints(&march);
        let n = mids.len();
        let to_eye = (-ray.dir).as_vec3();
        let mut counts = Counts::default();
        // each volume's samples: those of the march inside its box (and the cut)
        let parts = &mut s.parts;
        parts.clear();
        for (k, (l, hit)) in self.layers.iter().zip(s.hits.iter_mut()).enumerate() {
            let Some(h) = hit else { continue };
            let (a, b) = (h.t0.max(t_enter), h.t1.min(t_exit));
            if a > b {
                continue;
            }
            let (from_box, to_box) = within(&mids, a, b);
            counts.nominal += to_box.saturating_sub(from_box) as u64;
            // the part its cells that are not transparent can lie in
            let (wa, wb) = match windows.get(k).and_then(|w| w.as_ref()) {
                Some(w) => {
                    let [lo, hi] = w.at(i, j);
                    (a.max(lo), b.min(hi))
                }
                None => (a, b),
            };
            if wa > wb {
                continue;
            }
            let (first, end) = within(&mids, wa, wb);
            if first >= end {
                continue;
            }
            h.ray.t_enter = a;
            h.ray.t_exit = b;
            h.ray.cut = cut;
            // the grid's ranges hold for this ray's samples (as in a one-volume pass)
            let (o, d) = (h.ray.index.o.to_array(), h.ray.index.d.to_array());
            h.skips = l.grid.is_some_and(|g| g.bounds(o, d, a, b));
            parts.push((k, first, end));
        }
        let mut acc = FrontToBack::new(self.early_stop);
        let (mut from, mut chunk) = (0, FIRST_CHUNK);
        'ray: while from < n {
            let to = (from + chunk).min(n);
            chunk = (2 * chunk).min(CHUNK);
            for &(k, first, end) in s.parts.iter() {
                let terms = &mut s.terms[k];
                terms.clear();
                s.cursors[k] = 0;
                let (a, b) = (first.max(from), end.min(to));
                if a >= b {
                    continue;
                }
                let l = &self.layers[k];
                let Some(h) = &s.hits[k] else { continue };
                let part = Part {
                    all: mids,
                    from: a,
                    len: b - a,
                };
                let mut ray = h.ray;
                let skip = l.grid.filter(|_| h.skips);
                ray.walk = [part.t(0), part.t(b - a - 1)];
                let field: &dyn Field = &*l.field;
                let mut collect = Collect {
                    composite: &l.composite,
                    field: &field,
                    ray: &ray,
                    march: &march,
                    offset: a,
                    to_eye,
                    terms,
                };
                counts.taken += drive(&part, &field, &ray, skip, &mut collect);
            }
            // the chunk's terms in order of their midpoints, those of one midpoint
            // blended
            s.busy.clear();
            for &(k, _, _) in s.parts.iter() {
                if !s.terms[k].is_empty() {
                    s.busy.push(k);
                }
            }
            let busy = &s.busy;
            if let [k] = busy.as_slice() {
                // one volume: its terms as they are
                for &(_, c, a) in &s.terms[*k] {
                    if acc.add(c, a).is_break() {
                        break 'ray;
                    }
                }
            } else {
                loop {
                    let next = busy
                        .iter()
                        .filter_map(|&k| s.terms[k].get(s.cursors[k]).map(|t| t.0))
                        .min();
                    let Some(m) = next else { break };
                    s.at.clear();
                    for &k in busy.iter() {
                        let c = s.cursors[k];
                        if let Some(&(at, colour, a)) = s.terms[k].get(c) {
                            if at == m {
                                s.at.push((colour, a));
                                s.cursors[k] = c + 1;
                            }
                        }
                    }
                    let (c, a) = blended(&mut s.at);
                    if acc.add(c, a).is_break() {
                        break 'ray;
                    }
                }
            }
            from = to;
        }
        Some((acc.finish(), counts))
    }
}

/// The indices `first..end` of the midpoints of `mids` in `[a, b]`.
fn within(mids: &Midpoints<'_>, a: f64, b: f64) -> (usize, usize) {
    let n = mids.len();
    let first = mids.first_at_or_after(a);
    let mut end = mids.first_at_or_after(b);
    while end < n && mids.t(end) <= b {
        end += 1;
    }
    (first, end)
}

/// The colour and opacity of a sample from its volumes' `terms` (each with an
/// opacity above zero): one volume's own, or `1 - prod(1 - a_i)` and
/// `sum(a_i c_i) / sum(a_i)`, summed in the order of the terms' values, whatever
/// the order of the volumes.
fn blended(terms: &mut [(Vec4, f32)]) -> (Vec4, f32) {
    if let [one] = terms {
        return *one;
    }
    let key = |(c, a): &(Vec4, f32)| (a.to_bits(), c.x.to_bits(), c.y.to_bits(), c.z.to_bits());
    if let [x, y] = terms {
        if key(y) < key(x) {
            std::mem::swap(x, y);
        }
    } else {
        terms.sort_unstable_by_key(key);
    }
    let (mut transmit, mut weight) = (1.0f64, 0.0f64);
    let mut colour = glam::DVec3::ZERO;
    for (c, a) in terms.iter() {
        let a = f64::from(*a);
        transmit *= 1.0 - a;
        weight += a;
        colour += c.truncate().as_dvec3() * a;
    }
    let c: Vec3 = (colour / weight).as_vec3();
    (c.extend(0.0), (1.0 - transmit) as f32)
}

/// Positions `from..from + len` of a ray's midpoints, as a lattice of their own.
#[derive(Clone, Copy)]
struct Part<'a> {
    all: Midpoints<'a>,
    from: usize,
    len: usize,
}

impl Lattice for Part<'_> {
    fn len(&self) -> usize {
        self.len
    }

    #[inline(always)]
    fn t(&self, i: usize) -> f64 {
        self.all.t(self.from + i)
    }

    #[inline]
    fn guess(&self, t: f64) -> f64 {
        self.all.guess(t) - self.from as f64
    }

    #[inline(always)]
    fn fill(&self, from: usize, ts: &mut [f64]) {
        self.all.fill(self.from + from, ts)
    }
}

/// One volume's terms along a chunk of a ray: every midpoint it is not
/// transparent at, with its colour and opacity.
struct Collect<'b, F: Field> {
    composite: &'b Composite,
    field: &'b F,
    ray: &'b PixelRay,
    march: &'b March,
    /// The index of the chunk's first midpoint in the whole march.
    offset: usize,
    to_eye: Vec3,
    terms: &'b mut Vec<Term>,
}

impl<F: Field> Consumer for Collect<'_, F> {
    #[inline(always)]
    fn skippable(&self, cell: usize, _range: [f32; 2]) -> bool {
        self.composite.transparency(cell).0
    }

    #[inline(always)]
    fn skippable_part(&self, cell: usize, octant: usize, _range: [f32; 2]) -> bool {
        self.composite.transparent_octant(cell, octant)
    }

    #[inline(always)]
    fn skippable_parts(&self, _grid: &MacroGrid, cell: usize) -> u8 {
        self.composite.transparency(cell).1
    }

    fn skip(&mut self, _i: usize, _j: usize) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }

    #[inline(always)]
    fn take_batch(&mut self, from: usize, ts: &[f64], values: &[f32]) -> ControlFlow<usize> {
        self.composite.terms_of_batch(
            self.field,
            self.ray,
            self.march,
            self.offset + from,
            ts,
            values,
            self.to_eye,
            self.terms,
        );
        ControlFlow::Continue(())
    }

    #[inline(always)]
    fn take(&mut self, i: usize, t: f64, v: f32) -> ControlFlow<()> {
        let m = self.offset + i;
        if let Some((c, a)) =
            self.composite
                .midpoint_of(self.field, self.ray, self.march, m, t, v, self.to_eye)
        {
            self.terms.push((m as u32, c, a));
        }
        ControlFlow::Continue(())
    }
}

impl RenderView for Blend<'_> {
    fn channels(&self) -> usize {
        4
    }

    fn render(&self, view: &View, _frame: &IndexFrame) -> (Film, Counts) {
        let mut film = Film::new(view.width, view.height, 4);
        let windows: Vec<Option<Windows>> = self
            .layers
            .iter()
            .map(|l| {
                let f = l.footprint.as_ref()?;
                Some(f.windows(view, &l.frame, WINDOW_TILE))
            })
            .collect();
        let (width, height) = (view.width, view.height);
        let row_len = width * 4;
        let band = |band: usize, rows: &mut [f32]| {
            let mut s = self.scratch();
            let mut counts = Counts::default();
            let j0 = band * TILE;
            let j1 = (j0 + TILE).min(height);
            for i0 in (0..width).step_by(TILE) {
                for j in j0..j1 {
                    for i in i0..(i0 + TILE).min(width) {
                        let (value, c) = self
                            .trace_pixel(view, i, j, &windows, &mut s)
                            .unwrap_or(([0.0; 4], Counts::default()));
                        let at = (j - j0) * row_len + i * 4;
                        rows[at..at + 4].copy_from_slice(&value);
                        counts += c;
                    }
                }
            }
            counts
        };
        let mut counts = Counts::default();
        for c in crate::parallel::map_chunks_mut(&mut film.data, TILE * row_len, &band) {
            counts += c;
        }
        (film, counts)
    }

    fn pixel(
        &self,
        view: &View,
        _frame: &IndexFrame,
        i: usize,
        j: usize,
    ) -> Option<([f32; 4], Counts)> {
        self.trace_pixel(view, i, j, &[], &mut self.scratch())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_term_is_kept_as_it_is() {
        let c = Vec4::new(0.3, 0.2, 0.1, 0.0);
        let mut terms = [(c, 0.1f32)];
        assert_eq!(blended(&mut terms), (c, 0.1));
    }

    /// Two terms: 1 - (1 - a)(1 - b) and the opacity-weighted mean colour, the
    /// same bits in either order.
    #[test]
    fn two_terms_blend_by_the_rule_in_any_order() {
        let (c1, c2) = (Vec4::new(1.0, 0.0, 0.0, 0.0), Vec4::new(0.0, 0.0, 1.0, 0.0));
        let (a, b) = (0.25f32, 0.5f32);
        let (c, alpha) = blended(&mut [(c1, a), (c2, b)]);
        assert!((alpha - (1.0 - 0.75 * 0.5)).abs() < 1e-7);
        assert!((c.x - 0.25 / 0.75).abs() < 1e-6 && (c.z - 0.5 / 0.75).abs() < 1e-6);
        let swapped = blended(&mut [(c2, b), (c1, a)]);
        assert_eq!(
            swapped.0.to_array().map(f32::to_bits),
            c.to_array().map(f32::to_bits)
        );
        assert_eq!(swapped.1.to_bits(), alpha.to_bits());
    }
}
