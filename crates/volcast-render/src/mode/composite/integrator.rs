//! Emission-absorption compositing, front to back (docs/formulas.md
//! "Emission-absorption and compositing"). Each segment between two sample
//! positions is represented by the field at its midpoint; its opacity is corrected
//! from the transfer function's reference step to the segment's own length, so the
//! image converges as the step shrinks (whole steps read a table whose opacities are
//! corrected once for the pass's step; the shorter first and last segments are
//! corrected one by one). Colour and opacity accumulate in f64: with tiny opacities
//! and tiny steps (1e-7 per voxel at 1e-3 voxel) each sample adds hundreds of f32
//! ulps' worth, and f32 rounding would drift as the step shrinks.
//!
//! Pre-integrated passes (`preintegrated = true`) instead sample the field at the
//! march positions and take each segment's colour and opacity from the table of
//! segment integrals over (front value, back value) ([`Preintegrated`]; Engel et al.
//! 2001), so a thin peak of the transfer function between two samples still counts.
//!
//! Skipping passes over the macrocells over whose value range the transfer function
//! is transparent (a test in O(1) from a prefix count of the table's opaque
//! entries); a pre-integrated segment that spans the edge of a skipped cell is
//! integrated from a sample taken there.

use std::mem::MaybeUninit;
use std::ops::ControlFlow;

use glam::{DVec3, Vec3, Vec4};

use super::unclear::Unclear;
use crate::mode::crossing::normal_from_gradient;
use crate::render::integrator::{drive, take_each, Consumer, Counts, Integrand, PixelRay, BATCH};
use crate::render::march::{March, Midpoints};
use crate::render::skip::MacroGrid;
use crate::sample::Field;
use crate::shade::Shader;
use crate::transfer::{
    clamp_unit, correct_opacity, table_position, Preintegrated, Table1D, Table2D,
};

/// A transfer-function table.
#[derive(Clone, Debug)]
pub enum CompositeTable {
    /// Over the normalised value.
    OneD(Table1D),
    /// Over (value, gradient magnitude per voxel of the smallest spacing).
    TwoD(Table2D),
}

/// A pass's transfer-function table as given, and with its opacities corrected for
/// one whole step, both of one kind: a ray's loop is compiled for that kind
/// ([`Lookup`]), with no match on it per sample.
#[derive(Clone, Debug)]
enum Tables {
    OneD(Pair<Table1D>),
    TwoD(Pair<Table2D>),
}

/// A table as given and corrected for a whole step.
#[derive(Clone, Debug)]
struct Pair<T> {
    given: T,
    full_step: T,
}

impl Tables {
    /// `table`, and `table` with opacities corrected for segments of `ratio`
    /// reference steps.
    fn new(table: CompositeTable, ratio: f64) -> Tables {
        let c = |a: f32| correct_opacity(a, ratio as f32);
        match table {
            CompositeTable::OneD(t) => Tables::OneD(Pair {
                full_step: t.map_alpha(c),
                given: t,
            }),
            CompositeTable::TwoD(t) => Tables::TwoD(Pair {
                full_step: t.map_alpha(c),
                given: t,
            }),
        }
    }

    /// For each entry along the value axis, whether any entry there is not
    /// transparent.
    fn opaque_entries(&self) -> Vec<bool> {
        match self {
            Tables::OneD(t) => t.given.alphas().map(|a| a > 0.0).collect(),
            Tables::TwoD(t) => t
                .given
                .max_alpha_per_value()
                .into_iter()
                .map(|a| a > 0.0)
                .collect(),
        }
    }

    /// Memory held by both tables, in bytes.
    fn byte_size(&self) -> usize {
        match self {
            Tables::OneD(t) => t.given.byte_size() + t.full_step.byte_size(),
            Tables::TwoD(t) => t.given.byte_size() + t.full_step.byte_size(),
        }
    }
}

/// A table's RGBA lookup, with the gradient when the lookup needs one.
trait Lookup {
    /// The table itself where it is a 1D table: then [`Lookup::rgba`] reads `x`,
    /// the value's table position, alone (no gradient, no field), so that a
    /// batch's lookups may all be made before any of them is composited, and
    /// their table positions split eight at a time ([`Unclear`]).
    #[inline(always)]
    fn one_d(&self) -> Option<&Table1D> {
        None
    }

    /// RGBA of value `v` at `p()` (index space; asked for the gradient magnitude of
    /// 2D tables only, expressed per voxel with `voxel_length`), with the gradient
    /// when one was computed; `x` is `v`'s position along the value axis
    /// ([`Composite::position_of_unit`]).
    ///
    /// # Safety
    /// `x` is in `[0, n - 1]` for a table of `n` entries along the value axis (as
    /// every position `Composite::position_of_unit` gives is, for the pass's
    /// tables): a 1D table reads at `x` unchecked.
    unsafe fn rgba<F: Field>(
        &self,
        field: &F,
        p: impl FnOnce() -> DVec3,
        v: f32,
        x: f32,
        voxel_length: f64,
    ) -> ([f32; 4], Option<DVec3>);
}

impl Lookup for Table1D {
    #[inline(always)]
    fn one_d(&self) -> Option<&Table1D> {
        Some(self)
    }

    /// # Safety
    /// As [`Lookup::rgba`]: `x` is in `[0, len - 1]`.
    #[inline(always)]
    unsafe fn rgba<F: Field>(
        &self,
        _field: &F,
        _p: impl FnOnce() -> DVec3,
        _v: f32,
        x: f32,
        _voxel_length: f64,
    ) -> ([f32; 4], Option<DVec3>) {
        // SAFETY (the caller's): x is in [0, len - 1]
        (unsafe { self.lookup_within(x) }, None)
    }
}

impl Lookup for Table2D {
    /// # Safety
    /// None beyond the trait's: a 2D table's lookup clamps its own positions (the
    /// method is `unsafe` for the 1D table's sake).
    #[inline(always)]
    unsafe fn rgba<F: Field>(
        &self,
        field: &F,
        p: impl FnOnce() -> DVec3,
        v: f32,
        _x: f32,
        voxel_length: f64,
    ) -> ([f32; 4], Option<DVec3>) {
        let g = field.gradient(p());
        (self.lookup(v, (g.length() * voxel_length) as f32), Some(g))
    }
}

/// Front-to-back compositing through a transfer function.
#[derive(Clone, Debug)]
pub struct Composite {
    tables: Tables,
    shader: Option<Shader>,
    reference_step: f64,
    early_stop: f32,
    voxel_length: f64,
    preintegrated: Option<Preintegrated>,
    /// Per macrocell of the pass's grid: true where the transfer function is
    /// transparent over the cell's values.
    transparent: Vec<bool>,
    /// Per macrocell of a grid with octants: the octants over whose values the
    /// transfer function is transparent, as the bits of a mask.
    transparent_parts: Vec<u8>,
    /// How many entries along the value axis before each are not transparent (a
    /// prefix count, one longer than the axis; empty before
    /// [`Composite::classify`]).
    opaque_before: Vec<u32>,
    /// Entries along the value axis, less one: the tables look a value `v` up at
    /// `table_position(v, value_last)`.
    value_last: f32,
    /// The largest value in [0, 1] whose table position is at most the last one up
    /// to which every lookup is transparent (-1 when there is none, the first entry
    /// not being transparent): see [`Composite::clear`].
    clear_unit_up_to: f32,
    /// Whether batches through a 1D table find their samples that are not clear
    /// eight at a time ([`Unclear`]: this machine has AVX2).
    eight_lanes: bool,
}

impl Composite {
    /// Compositing through `table` at step `dt` (world units) with the transfer
    /// function's alpha defined for `reference_step`; `voxel_length` expresses
    /// gradient magnitudes per voxel for 2D tables; `preintegrated` replaces the
    /// midpoint samples by pre-integrated segments (1D tables).
    pub fn new(
        table: CompositeTable,
        dt: f64,
        reference_step: f64,
        shader: Option<Shader>,
        early_stop: f32,
        voxel_length: f64,
        preintegrated: Option<Preintegrated>,
    ) -> Composite {
        // entries 0..z are transparent at every gradient magnitude: a lookup between
        // two of them interpolates zeros, and one at position z - 1 exactly reads
        // entry z - 1 with weight 1 (and entry z with weight 0)
        let tables = Tables::new(table, dt / reference_step);
        let opaque = tables.opaque_entries();
        if let Tables::OneD(t) = &tables {
            // the lookups' safety: both tables are as long as the value axis
            debug_assert!(t.given.len() == opaque.len() && t.full_step.len() == opaque.len());
        }
        let z = opaque.iter().position(|&o| o).unwrap_or(opaque.len());
        let value_last = (opaque.len() - 1) as f32;
        Composite {
            value_last,
            clear_unit_up_to: last_clear_unit(value_last, z as f32 - 1.0),
            tables,
            shader,
            reference_step,
            early_stop,
            voxel_length,
            preintegrated,
            transparent: Vec::new(),
            transparent_parts: Vec::new(),
            opaque_before: Vec::new(),
            eight_lanes: Unclear::available(),
        }
    }

    /// Marks the macrocells of `grid` over whose values the transfer function is
    /// transparent (found in O(1) per cell from a prefix count of the table's
    /// entries that are not), and keeps the count for the parts of cells
    /// (`Composite::transparent_over`).
    pub fn classify(&mut self, grid: &MacroGrid) {
        let opaque = self.tables.opaque_entries();
        let mut prefix = Vec::with_capacity(opaque.len() + 1);
        prefix.push(0u32);
        for (i, &o) in opaque.iter().enumerate() {
            prefix.push(prefix[i] + u32::from(o));
        }
        self.opaque_before = prefix;
        self.transparent = (0..grid.len())
            .map(|m| self.transparent_over(grid.range(m)))
            .collect();
        self.transparent_parts = if grid.has_parts() {
            (0..grid.len())
                .map(|m| {
                    (0..8).fold(0u8, |mask, o| {
                        mask | u8::from(self.transparent_over(grid.part_range(m, o))) << o
                    })
                })
                .collect()
        } else {
            Vec::new()
        };
    }

    /// Whether the transfer function is transparent over macrocell `cell` (false
    /// before [`Composite::classify`]).
    #[inline(always)]
    fn transparent_cell(&self, cell: usize) -> bool {
        self.transparent.get(cell).copied().unwrap_or(false)
    }

    /// Whether the transfer function is transparent over octant `octant` of
    /// macrocell `cell` (false for a grid without octants).
    #[inline(always)]
    fn transparent_part(&self, cell: usize, octant: usize) -> bool {
        self.transparent_parts
            .get(cell)
            .is_some_and(|m| m >> octant & 1 != 0)
    }

    /// Whether the transfer function is transparent over the values `[lo, hi]`
    /// (after [`Composite::classify`]; false before).
    #[inline]
    fn transparent_over(&self, [lo, hi]: [f32; 2]) -> bool {
        if let Some(p) = &self.preintegrated {
            return p.transparent(f64::from(lo), f64::from(hi));
        }
        let prefix = &self.opaque_before;
        if prefix.len() < 2 {
            return false;
        }
        let last = prefix.len() - 2;
        // a lookup of v reads the entries around v * last: one entry more on each
        // side covers the f32 rounding of that product
        let entry = |v: f32| table_position(v, last as f32) as usize;
        let a = entry(lo).saturating_sub(1);
        let b = (entry(hi) + 2).min(last);
        prefix[b + 1] == prefix[a]
    }

    /// Memory held by the tables, in bytes.
    pub fn byte_size(&self) -> usize {
        self.tables.byte_size()
            + self.preintegrated.as_ref().map_or(0, |p| p.byte_size())
            + self.transparent.len()
            + self.transparent_parts.len()
            + 4 * self.opaque_before.len()
    }

    /// Whether the transfer function is transparent at value `v` (whatever the
    /// gradient magnitude), found without a lookup: true only where both tables'
    /// lookups give an opacity of exactly zero (correcting an opacity of zero for a
    /// step keeps it zero). Most samples a composite takes in a cell that is not
    /// passed over are clear, so this test saves their lookup (and the gradient of
    /// a 2D table).
    #[cfg(test)]
    fn clear(&self, v: f32) -> bool {
        self.clear_unit(clamp_unit(v))
    }

    /// [`Composite::clear`] from the value clamped to [0, 1] (`clamp_unit`): the
    /// same answer as comparing its table position `y * value_last` with the last
    /// transparent one, since that product does not decrease as `y` grows (rounded
    /// too), without the multiplication, which only the samples that are not clear
    /// then need.
    #[inline(always)]
    fn clear_unit(&self, y: f32) -> bool {
        y <= self.clear_unit_up_to
    }

    /// The position of value `v` along the tables' value axis, as their lookups
    /// compute it, from `y = clamp_unit(v)` (`table_position(v, value_last)`).
    #[inline(always)]
    fn position_of_unit(&self, y: f32) -> f32 {
        y * self.value_last
    }

    /// The table position of sample value `v`, or `None` where it is clear: the
    /// start of every midpoint sample's compositing, one sample at a time or a
    /// batch at once. The position is in [0, value_last]: `clamp_unit(v)` is in
    /// [0, 1], the product rounds monotonically, and 1 * value_last is exact.
    #[inline(always)]
    fn position_unless_clear(&self, v: f32) -> Option<f32> {
        let y = clamp_unit(v);
        if self.clear_unit(y) {
            None
        } else {
            Some(self.position_of_unit(y))
        }
    }
}

/// The largest `y` in [0, 1] with `y * last <= up_to` in f32 (the table position of
/// a value clamped to [0, 1]), found by bisection over the bit patterns, on which the
/// product does not decrease: -1 when even 0 is above `up_to`, 1 when every value is
/// at or below it.
fn last_clear_unit(last: f32, up_to: f32) -> f32 {
    let clear = |y: f32| y * last <= up_to;
    if !clear(0.0) {
        return -1.0;
    }
    if clear(1.0) {
        return 1.0;
    }
    // clear(lo) and !clear(hi)
    let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if clear(f32::from_bits(mid)) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    f32::from_bits(lo)
}

impl Integrand for Composite {
    fn reads_depth_reference(&self) -> bool {
        false
    }

    fn channels(&self) -> usize {
        4
    }

    /// Cells over which the transfer function is transparent, as both ways of
    /// compositing pass over them.
    fn fixed_skippable(&self, cell: usize, _range: [f32; 2]) -> Option<bool> {
        Some(self.transparent_cell(cell))
    }

    fn trace<F: Field>(
        &self,
        field: &F,
        ray: &PixelRay,
        march: &March,
        grid: Option<&MacroGrid>,
    ) -> ([f32; 4], Counts) {
        let to_eye = (-ray.dir).as_vec3();
        let nominal = march.len() as u64;
        if let Some(pre) = &self.preintegrated {
            let mut c = Segments {
                pass: self,
                pre,
                field,
                ray,
                march,
                acc: FrontToBack::new(self.early_stop),
                prev: None,
                extra: 0,
                to_eye,
            };
            let taken = drive(march, field, ray, grid, &mut c);
            let counts = Counts {
                taken: taken + c.extra,
                nominal,
            };
            return (c.acc.finish(), counts);
        }
        let (rgba, taken) = match &self.tables {
            Tables::OneD(tables) => self.midpoints(tables, field, ray, march, grid, to_eye),
            Tables::TwoD(tables) => self.midpoints(tables, field, ray, march, grid, to_eye),
        };
        (rgba, Counts { taken, nominal })
    }
}

impl Composite {
    /// The colour (shaded where the pass shades) and opacity of midpoint `i` of
    /// `march`, at `t`, of value `v`: `None` where it is transparent. Its opacity
    /// is corrected for the segment's length (whole steps read the table corrected
    /// once).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn midpoint<T: Lookup, F: Field>(
        &self,
        tables: &Pair<T>,
        field: &F,
        ray: &PixelRay,
        march: &March,
        i: usize,
        t: f64,
        v: f32,
        to_eye: Vec3,
    ) -> Option<(Vec4, f32)> {
        let x = self.position_unless_clear(v)?;
        let full = march.is_full_step(i + 1);
        let pos = || ray.index.at(t);
        // SAFETY (both lookups): x is in [0, value_last]
        // (`Composite::position_unless_clear`), and both tables have value_last + 1
        // entries along the value axis (`Composite::new`)
        let (rgba, grad, a) = if full {
            // opacity already corrected for a whole step
            let (rgba, grad) =
                unsafe { tables.full_step.rgba(field, pos, v, x, self.voxel_length) };
            (rgba, grad, rgba[3])
        } else {
            let length = march.t(i + 1) - march.t(i);
            if length <= 0.0 {
                return None;
            }
            let (rgba, grad) = unsafe { tables.given.rgba(field, pos, v, x, self.voxel_length) };
            let a = correct_opacity(rgba[3], (length / self.reference_step) as f32);
            (rgba, grad, a)
        };
        if a <= 0.0 {
            return None;
        }
        let base = Vec4::from_array(rgba);
        let c = shade(self.shader.as_ref(), field, ray, t, grad, base, to_eye);
        Some((c, a))
    }

    /// [`Composite::midpoint`] through the pass's own tables (of either kind): one
    /// volume's part of a sample that several volumes blend (`blend.rs`).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(super) fn midpoint_of<F: Field>(
        &self,
        field: &F,
        ray: &PixelRay,
        march: &March,
        i: usize,
        t: f64,
        v: f32,
        to_eye: Vec3,
    ) -> Option<(Vec4, f32)> {
        match &self.tables {
            Tables::OneD(tables) => self.midpoint(tables, field, ray, march, i, t, v, to_eye),
            Tables::TwoD(tables) => self.midpoint(tables, field, ray, march, i, t, v, to_eye),
        }
    }

    /// [`Composite::midpoint_of`] of a batch of midpoints (`from` the index of the
    /// first in `march`, at `ts`, of `values`), each that is not transparent
    /// appended to `out` as (index, colour, opacity). A batch of whole steps
    /// through a 1D table, unshaded, takes the lookups of the one-volume path
    /// ([`Midpoint::take_batch`]: the same bits), eight at a time where the
    /// machine has AVX2.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(super) fn terms_of_batch<F: Field>(
        &self,
        field: &F,
        ray: &PixelRay,
        march: &March,
        from: usize,
        ts: &[f64],
        values: &[f32],
        to_eye: Vec3,
        out: &mut Vec<(u32, Vec4, f32)>,
    ) {
        let n = values.len();
        let table = match &self.tables {
            Tables::OneD(t)
                if self.shader.is_none()
                    && (1..=BATCH).contains(&n)
                    && march.is_full_step(from + 1)
                    && march.is_full_step(from + n) =>
            {
                &t.full_step
            }
            _ => {
                for (k, (&t, &v)) in ts.iter().zip(values).enumerate() {
                    if let Some((c, a)) =
                        self.midpoint_of(field, ray, march, from + k, t, v, to_eye)
                    {
                        out.push(((from + k) as u32, c, a));
                    }
                }
                return;
            }
        };
        if self.eight_lanes {
            let mut found = Unclear::new();
            found.find(values, self.clear_unit_up_to, (table.len() - 1) as u32);
            for j in 0..found.len() {
                let (k, i, t) = found.get(j);
                // SAFETY: i is at most the table's last index less one (`Unclear::find`)
                let rgba = unsafe { table.lerp_entries(i, t) };
                if rgba[3] > 0.0 {
                    out.push(((from + k) as u32, Vec4::from_array(rgba), rgba[3]));
                }
            }
            return;
        }
        for (k, &v) in values.iter().enumerate() {
            let Some(x) = self.position_unless_clear(v) else {
                continue;
            };
            // SAFETY: x is in [0, value_last] (`Composite::position_unless_clear`)
            let rgba = unsafe { table.lookup_within(x) };
            if rgba[3] > 0.0 {
                out.push(((from + k) as u32, Vec4::from_array(rgba), rgba[3]));
            }
        }
    }

    /// Whether the transfer function is transparent over macrocell `cell`, and the
    /// mask of its octants over which it is (for `blend.rs`).
    #[inline(always)]
    pub(super) fn transparency(&self, cell: usize) -> (bool, u8) {
        (
            self.transparent_cell(cell),
            self.transparent_parts.get(cell).copied().unwrap_or(0),
        )
    }

    /// Whether the transfer function is transparent over octant `octant` of `cell`.
    #[inline(always)]
    pub(super) fn transparent_octant(&self, cell: usize, octant: usize) -> bool {
        self.transparent_part(cell, octant)
    }
}

impl Composite {
    /// Composites the midpoint samples of `march` through `tables` (shading
    /// towards `to_eye`); the pixel and the samples taken.
    #[inline(always)]
    fn midpoints<T: Lookup, F: Field>(
        &self,
        tables: &Pair<T>,
        field: &F,
        ray: &PixelRay,
        march: &March,
        grid: Option<&MacroGrid>,
        to_eye: Vec3,
    ) -> ([f32; 4], u64) {
        let mut c = Midpoint {
            pass: self,
            tables,
            field,
            ray,
            march,
            acc: FrontToBack::new(self.early_stop),
            to_eye,
        };
        let taken = drive(&Midpoints(march), field, ray, grid, &mut c);
        (c.acc.finish(), taken)
    }
}

/// Compositing of the segments' midpoint samples through tables of one kind.
struct Midpoint<'a, F: Field, T> {
    pass: &'a Composite,
    tables: &'a Pair<T>,
    field: &'a F,
    ray: &'a PixelRay,
    march: &'a March,
    acc: FrontToBack,
    to_eye: Vec3,
}

impl<F: Field, T: Lookup> Consumer for Midpoint<'_, F, T> {
    #[inline(always)]
    fn skippable(&self, cell: usize, _range: [f32; 2]) -> bool {
        self.pass.transparent_cell(cell)
    }

    #[inline(always)]
    fn skippable_part(&self, cell: usize, octant: usize, _range: [f32; 2]) -> bool {
        self.pass.transparent_part(cell, octant)
    }

    #[inline(always)]
    fn skippable_parts(&self, _grid: &MacroGrid, cell: usize) -> u8 {
        self.pass.transparent_parts.get(cell).copied().unwrap_or(0)
    }

    #[inline(always)]
    fn skip(&mut self, _i: usize, _j: usize) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }

    /// A batch of whole steps through a 1D table, unshaded (the common case), in
    /// two loops: the lookups, each sample's independent of the others, keeping
    /// up to [`KEPT`] samples that are not transparent; then their front-to-back
    /// accumulation, in order; and again to the batch's end. Each sample goes
    /// through the operations of [`Consumer::take`] (its start is the same
    /// [`Composite::position_unless_clear`]), so the bits are the same. Split, the
    /// lookups overlap one another, and the accumulation runs in a loop of its own
    /// ([`FrontToBack::add_all`]) that keeps its state in registers
    /// (`bench/peers/README.md`).
    /// Where this machine has AVX2, the first half of the lookups (clear or not,
    /// and the split of the table position) runs eight samples at a time
    /// ([`Midpoint::take_found`]). Other batches are taken one sample at a time.
    #[inline(always)]
    fn take_batch(&mut self, from: usize, ts: &[f64], values: &[f32]) -> ControlFlow<usize> {
        let n = values.len();
        let p = self.pass;
        // whole steps are one run of indices, so its two ends stand for the batch
        let one_d = self.tables.full_step.one_d();
        let plain = one_d.is_some()
            && p.shader.is_none()
            && (1..=BATCH).contains(&n)
            && self.march.is_full_step(from + 1)
            && self.march.is_full_step(from + n);
        if !plain {
            return take_each(self, from, ts, values);
        }
        if let (true, Some(table)) = (p.eight_lanes, one_d) {
            return self.take_found(table, values);
        }
        // the samples kept, a chunk at a time: their indices in the batch and their
        // colours
        let mut index = [MaybeUninit::<u8>::uninit(); KEPT];
        let mut rgbas = [MaybeUninit::<[f32; 4]>::uninit(); KEPT];
        let mut k = 0;
        while k < n {
            let mut m = 0;
            while k < n && m < KEPT {
                let v = values[k];
                k += 1;
                let Some(x) = p.position_unless_clear(v) else {
                    continue;
                };
                // SAFETY: as in `take` (x is in [0, value_last]); a 1D table reads
                // neither the field nor the position
                let (rgba, _) = unsafe {
                    self.tables
                        .full_step
                        .rgba(self.field, || DVec3::ZERO, v, x, p.voxel_length)
                };
                if rgba[3] <= 0.0 {
                    continue;
                }
                const _: () = assert!(BATCH <= 256, "a batch's indices are kept as u8");
                index[m].write((k - 1) as u8);
                rgbas[m].write(rgba);
                m += 1;
            }
            // SAFETY: the first `m` of each were written above
            let kept = unsafe { std::slice::from_raw_parts(rgbas.as_ptr().cast::<[f32; 4]>(), m) };
            if let Some(j) = self.acc.add_all(kept) {
                // SAFETY: j < m
                return ControlFlow::Break(usize::from(unsafe { index[j].assume_init() }));
            }
        }
        ControlFlow::Continue(())
    }

    /// Midpoint `i` is the middle of the segment from sample `i` to sample `i + 1`.
    #[inline(always)]
    fn take(&mut self, i: usize, t: f64, v: f32) -> ControlFlow<()> {
        match self.pass.midpoint(
            self.tables,
            self.field,
            self.ray,
            self.march,
            i,
            t,
            v,
            self.to_eye,
        ) {
            Some((c, a)) => self.acc.add(c, a),
            None => ControlFlow::Continue(()),
        }
    }
}

impl<F: Field, T: Lookup> Midpoint<'_, F, T> {
    /// [`Midpoint::take_batch`]'s two loops where this machine finds a batch's
    /// samples that are not clear eight at a time ([`Unclear::find`]: their table
    /// entries and fractions, with the operations of
    /// [`Composite::position_unless_clear`] and [`Table1D::lookup_within`], so the
    /// same bits); only the interpolation between two entries is left per sample.
    /// `table` is the whole step's 1D table, `values` a batch of whole steps.
    #[inline(always)]
    fn take_found(&mut self, table: &Table1D, values: &[f32]) -> ControlFlow<usize> {
        let mut found = Unclear::new();
        found.find(values, self.pass.clear_unit_up_to, (table.len() - 1) as u32);
        let mut index = [MaybeUninit::<u8>::uninit(); KEPT];
        let mut rgbas = [MaybeUninit::<[f32; 4]>::uninit(); KEPT];
        let mut j = 0;
        while j < found.len() {
            let mut m = 0;
            while j < found.len() && m < KEPT {
                let (k, i, t) = found.get(j);
                j += 1;
                // SAFETY: i is at most the table's last index less one (`Unclear::find`)
                let rgba = unsafe { table.lerp_entries(i, t) };
                if rgba[3] <= 0.0 {
                    continue;
                }
                // k < BATCH <= 256 (asserted in `take_batch`)
                index[m].write(k as u8);
                rgbas[m].write(rgba);
                m += 1;
            }
            // SAFETY: the first `m` of each were written above
            let kept = unsafe { std::slice::from_raw_parts(rgbas.as_ptr().cast::<[f32; 4]>(), m) };
            if let Some(s) = self.acc.add_all(kept) {
                // SAFETY: s < m
                return ControlFlow::Break(usize::from(unsafe { index[s].assume_init() }));
            }
        }
        ControlFlow::Continue(())
    }
}

/// Samples kept by [`Midpoint::take_batch`]'s lookups before they are composited:
/// a ray that stops early has looked up at most this many samples beyond its last.
/// A whole batch at once wastes the lookups past an early stop of an opaque
/// transfer function; with the accumulation in registers
/// ([`FrontToBack::add_all`]), this many was the fastest of those measured on the
/// peer composites (`bench/peers/README.md`).
const KEPT: usize = 16;

/// Compositing of pre-integrated segments between consecutive samples.
struct Segments<'a, F: Field> {
    pass: &'a Composite,
    pre: &'a Preintegrated,
    field: &'a F,
    ray: &'a PixelRay,
    march: &'a March,
    acc: FrontToBack,
    /// The previous sample, unless it was passed over.
    prev: Option<(f64, f32)>,
    extra: u64,
    to_eye: Vec3,
}

impl<F: Field> Segments<'_, F> {
    /// The sample at march position `i`, taken outside the march's loop.
    fn sample_at(&mut self, i: usize) -> (f64, f32) {
        let t = self.march.t(i);
        self.extra += 1;
        (t, self.field.value(self.ray.index.at(t)))
    }

    /// Composites the segment from `prev` to `(t, v)`; `Break` once opaque.
    #[inline(always)]
    fn segment(&mut self, (t_prev, v_prev): (f64, f32), t: f64, v: f32) -> ControlFlow<()> {
        let length = t - t_prev;
        if length <= 0.0 {
            return ControlFlow::Continue(());
        }
        let p = self.pass;
        let (rgb, a) = self.pre.segment(v_prev, v, length / p.reference_step);
        if a <= 0.0 {
            return ControlFlow::Continue(());
        }
        let t_mid = 0.5 * (t_prev + t);
        let base = Vec3::from_array(rgb).extend(0.0);
        let c = shade(
            p.shader.as_ref(),
            self.field,
            self.ray,
            t_mid,
            None,
            base,
            self.to_eye,
        );
        self.acc.add(c, a)
    }
}

impl<F: Field> Consumer for Segments<'_, F> {
    #[inline(always)]
    fn skippable(&self, cell: usize, _range: [f32; 2]) -> bool {
        self.pass.transparent_cell(cell)
    }

    #[inline(always)]
    fn skippable_part(&self, cell: usize, octant: usize, _range: [f32; 2]) -> bool {
        self.pass.transparent_part(cell, octant)
    }

    #[inline(always)]
    fn skippable_parts(&self, _grid: &MacroGrid, cell: usize) -> u8 {
        self.pass.transparent_parts.get(cell).copied().unwrap_or(0)
    }

    /// The segments between samples inside transparent cells are transparent; the
    /// one entering the gap is integrated here, the one leaving it when the next
    /// sample is taken.
    fn skip(&mut self, i: usize, _j: usize) -> ControlFlow<()> {
        if let Some(prev) = self.prev.take() {
            let (t, v) = self.sample_at(i);
            self.segment(prev, t, v)?;
        }
        ControlFlow::Continue(())
    }

    #[inline(always)]
    fn take(&mut self, i: usize, t: f64, v: f32) -> ControlFlow<()> {
        if i > 0 {
            let prev = match self.prev {
                Some(prev) => prev,
                None => self.sample_at(i - 1),
            };
            self.segment(prev, t, v)?;
        }
        self.prev = Some((t, v));
        ControlFlow::Continue(())
    }
}

/// The colour of a sample: the transfer function's colour `base` (its first three
/// lanes; the fourth is not used), shaded where the pass shades (with the gradient
/// already computed for a 2D transfer function, if any). Four lanes, so that an
/// unshaded colour stays in the register it was looked up in.
#[inline(always)]
fn shade<F: Field>(
    shader: Option<&Shader>,
    field: &F,
    ray: &PixelRay,
    t: f64,
    gradient: Option<DVec3>,
    base: Vec4,
    to_eye: Vec3,
) -> Vec4 {
    match shader {
        None => base,
        Some(shader) => shaded(shader, field, ray, t, gradient, base, to_eye),
    }
}

/// [`shade`] where the pass shades: out of line, so that the unshaded loop does not
/// set up its arguments for every sample.
#[inline(never)]
fn shaded<F: Field>(
    shader: &Shader,
    field: &F,
    ray: &PixelRay,
    t: f64,
    gradient: Option<DVec3>,
    base: Vec4,
    to_eye: Vec3,
) -> Vec4 {
    let g = gradient.unwrap_or_else(|| field.gradient(ray.index.at(t)));
    let normal = normal_from_gradient(g, ray.dir);
    shader
        .shade(
            ray.world(t).as_vec3(),
            normal.map(|n| n.as_vec3()),
            to_eye,
            base.truncate(),
        )
        .extend(0.0)
}

/// Front-to-back accumulation (docs/formulas.md: `C' += (1 - A') C_i`, `A' += (1 - A') A_i`)
/// in f64, with early ray termination. The transmittance `1 - A'` is carried as a
/// product of its own, so that one sample waits on the one before it for a single
/// multiplication (not a subtraction, a multiplication and an addition).
#[derive(Clone, Copy)]
pub(super) struct FrontToBack {
    color: DVec3,
    alpha: f64,
    /// `1 - alpha`, as the product of the samples' `1 - a`.
    transmit: f64,
    early_stop: f64,
}

impl FrontToBack {
    pub(super) fn new(early_stop: f32) -> FrontToBack {
        FrontToBack {
            color: DVec3::ZERO,
            alpha: 0.0,
            transmit: 1.0,
            early_stop: f64::from(early_stop),
        }
    }

    /// Adds a sample of colour `c` (its first three lanes) and opacity `a`; `Break`
    /// once the ray may stop.
    #[inline(always)]
    pub(super) fn add(&mut self, c: Vec4, a: f32) -> ControlFlow<()> {
        let a = f64::from(a);
        let w = self.transmit * a;
        self.transmit *= 1.0 - a;
        self.color += c.truncate().as_dvec3() * w;
        self.alpha += w;
        if self.alpha >= self.early_stop {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    }

    /// [`FrontToBack::add`] of each colour (its opacity last) in order; the index
    /// of the one after which the ray may stop. Out of line: one function for
    /// every voxel type's composite, whose loop keeps the state in registers
    /// (written back once, where a loop over `self`'s fields stored them after
    /// every sample).
    #[inline(never)]
    fn add_all(&mut self, rgbas: &[[f32; 4]]) -> Option<usize> {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: `is_x86_feature_detected!` found AVX2 just above
            return unsafe { self.add_all_avx2(rgbas) };
        }
        self.add_all_scalar(rgbas)
    }

    /// [`FrontToBack::add_all`] without AVX2: [`FrontToBack::add`] on a local copy
    /// of the state, which then stays in registers, written back once.
    #[inline(always)]
    fn add_all_scalar(&mut self, rgbas: &[[f32; 4]]) -> Option<usize> {
        let mut acc = *self;
        let stop = rgbas
            .iter()
            .position(|&rgba| acc.add(Vec4::from_array(rgba), rgba[3]).is_break());
        *self = acc;
        stop
    }

    /// [`FrontToBack::add_all`] with the colour in one 256-bit register: each
    /// sample's three channels converted and weighted at once (four lanes, the
    /// fourth not kept), each lane through the operations of
    /// [`FrontToBack::add`] (a multiplication, then an addition: the same bits).
    /// Fewer instructions a sample, in a loop whose chain of dependent operations
    /// (the transmittance's multiplication) leaves room for them.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn add_all_avx2(&mut self, rgbas: &[[f32; 4]]) -> Option<usize> {
        use std::arch::x86_64::*;
        let c = self.color;
        let mut color = _mm256_setr_pd(c.x, c.y, c.z, 0.0);
        let (mut alpha, mut transmit) = (self.alpha, self.transmit);
        let mut stop = None;
        for (j, rgba) in rgbas.iter().enumerate() {
            let a = f64::from(rgba[3]);
            let w = transmit * a;
            transmit *= 1.0 - a;
            // SAFETY: `rgba` is four f32
            let rgba = _mm256_cvtps_pd(unsafe { _mm_loadu_ps(rgba.as_ptr()) });
            color = _mm256_add_pd(color, _mm256_mul_pd(rgba, _mm256_set1_pd(w)));
            alpha += w;
            if alpha >= self.early_stop {
                stop = Some(j);
                break;
            }
        }
        let mut lanes = [0.0; 4];
        // SAFETY: `lanes` is four f64
        unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), color) };
        self.color = DVec3::new(lanes[0], lanes[1], lanes[2]);
        (self.alpha, self.transmit) = (alpha, transmit);
        stop
    }

    /// RGBA, not premultiplied.
    pub(super) fn finish(self) -> [f32; 4] {
        if self.alpha > 0.0 {
            let c = (self.color / self.alpha).as_vec3();
            [c.x, c.y, c.z, self.alpha as f32]
        } else {
            [0.0; 4]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transfer::{Interpolation, Transfer1D, Transfer2D, Widget, WidgetShape};

    /// Values around every table position: the positions themselves, a few ulps
    /// either side, points between them, and values outside [0, 1] and NaN.
    fn values(entries: usize) -> Vec<f32> {
        let last = (entries - 1) as f32;
        let mut out = vec![f32::NAN, -1.0, -0.0, 0.0, 1.0, 2.0, f32::INFINITY];
        for k in 0..entries {
            let v = k as f32 / last;
            let mut lo = v;
            let mut hi = v;
            for _ in 0..3 {
                lo = f32::from_bits(lo.to_bits().saturating_sub(1)).max(0.0);
                hi = f32::from_bits(hi.to_bits() + 1);
                out.extend([lo, hi]);
            }
            out.extend([v, (k as f32 + 0.5) / last]);
        }
        out
    }

    /// `clear(v)` is true only where both tables' lookups are transparent.
    fn check(pass: &Composite, entries: usize, lookup: impl Fn(&Tables, bool, f32) -> f32) {
        // the test on the clamped value gives the answer of the table position's
        // test against the last position of transparent entries, at the values
        // around every table position and a few ulps around its threshold
        let opaque = pass.tables.opaque_entries();
        let z = opaque.iter().position(|&o| o).unwrap_or(opaque.len());
        let last = (entries - 1) as f32;
        let edge = pass.clear_unit_up_to.max(0.0).to_bits();
        let near = (edge.saturating_sub(4)..=edge + 4).map(f32::from_bits);
        for v in values(entries).into_iter().chain(near) {
            let by_position = table_position(v, last) <= z as f32 - 1.0;
            assert_eq!(pass.clear(v), by_position, "v = {v:e}, {entries} entries");
        }
        let mut clear = 0;
        for v in values(entries) {
            if pass.clear(v) {
                clear += 1;
                for full_step in [false, true] {
                    let a = lookup(&pass.tables, full_step, v);
                    assert_eq!(a, 0.0, "v = {v:e} is clear but opaque");
                }
            }
        }
        // and the test is not vacuous: a table whose first two entries are
        // transparent has clear values
        if opaque.iter().take(2).all(|&o| !o) {
            assert!(clear > 0);
        }
    }

    fn pass(table: CompositeTable) -> Composite {
        Composite::new(table, 0.5, 1.0, None, 0.99, 1.0, None)
    }

    #[test]
    fn clear_values_look_up_transparent_in_1d_tables() {
        let lookup = |t: &Tables, full_step: bool, v: f32| match t {
            Tables::OneD(t) => [&t.given, &t.full_step][usize::from(full_step)].lookup(v)[3],
            Tables::TwoD(_) => unreachable!(),
        };
        let ramps = [
            vec![(0.0, 0.0), (0.1, 0.0), (1.0, 0.2)],
            vec![(0.0, 0.3), (1.0, 0.2)],
            vec![(0.0, 0.0), (1.0, 0.0)],
            vec![(0.0, 0.0), (0.5, 0.0), (0.5, 1.0)],
            vec![(0.0, 0.0), (0.37, 1e-30), (1.0, 0.0)],
        ];
        for alpha in ramps {
            for interpolation in [Interpolation::Linear, Interpolation::Cubic] {
                let tf =
                    Transfer1D::new(vec![(0.0, [1.0; 3])], alpha.clone(), interpolation).unwrap();
                for entries in [2, 3, 256, 4096] {
                    let p = pass(CompositeTable::OneD(tf.table(entries)));
                    check(&p, entries, lookup);
                }
            }
        }
    }

    /// A batch through [`Consumer::take_batch`] leaves the accumulator with the
    /// bits, and stops at the sample, of the same samples taken one at a time:
    /// batches inside the whole steps (the two loops) and touching the partial
    /// first and last steps (one at a time), with clear, transparent, opaque, NaN
    /// and out-of-range values, running to their end or stopping early.
    #[test]
    fn a_batch_composites_as_its_samples_one_at_a_time() {
        use crate::render::integrator::testing::{along_x, Line};
        let colour = vec![
            (0.0, [0.2, 0.9, 0.4]),
            (0.6, [1.0, 0.5, 0.0]),
            (1.0, [0.3, 0.3, 1.0]),
        ];
        let alpha = vec![(0.0, 0.0), (0.1, 0.0), (0.5, 0.02), (0.8, 0.0), (1.0, 0.3)];
        let tf = Transfer1D::new(colour, alpha, Interpolation::Linear).unwrap();
        let field = Line(&[0.0]);
        let ray = along_x(40.3);
        // samples at 0, 0.5, ..., 40, 40.3: whole steps are midpoints 1..=80
        let march = March::new(0.0, 40.3, 0.5);
        let values: Vec<f32> = (0..200)
            .map(|k| match k % 13 {
                0 => f32::NAN,
                1 => -0.5,
                2 => 1.5,
                3 => 0.05,
                4 => 0.9,
                _ => (k as f32 * 0.37).sin().abs(),
            })
            .collect();
        let ts: Vec<f64> = (0..values.len()).map(|k| k as f64 * 0.5 + 0.25).collect();
        let mut stopped = [0, 0];
        // both ways of finding the samples that are not clear: one at a time, and
        // eight at a time where this machine can
        let lanes = [false, true]
            .into_iter()
            .filter(|&e| !e || Unclear::available());
        for (eight_lanes, early_stop) in lanes.flat_map(|e| [0.2, 0.6, 0.99, 1.0].map(|s| (e, s))) {
            let mut pass = Composite::new(
                CompositeTable::OneD(tf.table(256)),
                0.5,
                1.0,
                None,
                early_stop,
                1.0,
                None,
            );
            pass.eight_lanes = eight_lanes;
            let Tables::OneD(tables) = &pass.tables else {
                unreachable!()
            };
            let new = || Midpoint {
                pass: &pass,
                tables,
                field: &field,
                ray: &ray,
                march: &march,
                acc: FrontToBack::new(early_stop),
                to_eye: Vec3::Z,
            };
            for (from, n) in [
                (0, 64),
                (1, 64),
                (3, 40),
                (17, 64),
                (16, 64),
                (60, 21),
                (70, 12),
            ] {
                let (ts, values) = (&ts[..n], &values[from..from + n]);
                let mut batch = new();
                let a = batch.take_batch(from, ts, values);
                let mut each = new();
                let b = take_each(&mut each, from, ts, values);
                assert_eq!(
                    a, b,
                    "from {from}, {n} samples, stop {early_stop}, eight lanes {eight_lanes}"
                );
                let bits = |f: &FrontToBack| {
                    let c = f.color;
                    [c.x, c.y, c.z, f.alpha, f.transmit].map(f64::to_bits)
                };
                assert_eq!(
                    bits(&batch.acc),
                    bits(&each.acc),
                    "from {from}, {n}, eight lanes {eight_lanes}"
                );
                stopped[usize::from(a.is_break())] += 1;
            }
        }
        // both ends of a batch are met
        assert!(stopped[0] > 0 && stopped[1] > 0, "{stopped:?}");
    }

    #[test]
    fn add_all_has_the_bits_of_add_one_at_a_time() {
        let mut next = {
            let mut state = 0x9e37_79b9_7f4a_7c15_u64;
            move || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 40) as f32 / (1u64 << 24) as f32
            }
        };
        let bits = |f: &FrontToBack| {
            let c = f.color;
            [c.x, c.y, c.z, f.alpha, f.transmit].map(f64::to_bits)
        };
        let mut stopped = 0;
        for case in 0..200 {
            let early_stop = [0.5, 0.99, 1.0][case % 3];
            let n = case % 40;
            let rgbas: Vec<[f32; 4]> = (0..n)
                .map(|_| [next(), next(), next(), 0.2 * next() * next()])
                .collect();
            let mut each = FrontToBack::new(early_stop);
            let stop = rgbas
                .iter()
                .position(|&c| each.add(Vec4::from_array(c), c[3]).is_break());
            stopped += usize::from(stop.is_some());
            let mut all = FrontToBack::new(early_stop);
            assert_eq!(all.add_all(&rgbas), stop, "case {case}");
            assert_eq!(bits(&all), bits(&each), "case {case}");
            let mut scalar = FrontToBack::new(early_stop);
            assert_eq!(scalar.add_all_scalar(&rgbas), stop, "case {case}");
            assert_eq!(bits(&scalar), bits(&each), "case {case}");
        }
        // rays that stop and rays that do not
        assert!((1..200).contains(&stopped), "{stopped} of 200 stopped");
    }

    #[test]
    fn clear_values_look_up_transparent_in_2d_tables() {
        let lookup = |t: &Tables, full_step: bool, v: f32| match t {
            Tables::TwoD(t) => [0.0, 0.3, 1.0, 7.0, f32::NAN, f32::INFINITY]
                .into_iter()
                .map(|g| [&t.given, &t.full_step][usize::from(full_step)].lookup(v, g)[3])
                .fold(0.0, f32::max),
            Tables::OneD(_) => unreachable!(),
        };
        for shape in [WidgetShape::Rectangle, WidgetShape::Gaussian] {
            let widget = Widget {
                shape,
                value: [0.3, 0.6],
                gradient: [0.2, 0.5],
                color: [1.0, 0.5, 0.0],
                alpha: 0.8,
            };
            let tf = Transfer2D::new(vec![widget], 1.0).unwrap();
            for (nv, ng) in [(256, 64), (2, 2), (17, 5)] {
                let p = pass(CompositeTable::TwoD(tf.table(nv, ng)));
                check(&p, nv, lookup);
            }
        }
    }
}
