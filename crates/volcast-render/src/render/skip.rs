//! Empty-space skipping: a coarse grid of macrocells, each holding the range of
//! values the reconstructed field can take inside it, and the walk of a ray through
//! those macrocells.
//!
//! A macrocell covers [`MACROCELL`] voxel cells per axis. Its range is the min and
//! max of the values the pass's filter reads anywhere in the cell (the voxels of
//! the cell plus the filter's support beyond it), widened by a few ulps for the
//! round-off of interpolation, and so that a sample a round-off outside the cell is
//! still covered: by one voxel more of support, or, for the modes that need no
//! exact zeros on trilinear and nearest passes, by `ROUND_OFF_REACH` (see
//! [`Support::LinearTight`]). Every filter volcast has is a weighted average with
//! non-negative weights of the values it reads (trilinear, the
//! B-splines) or one of them (nearest), so no sample in the cell lies outside that
//! range. An integrator that can tell from a range that no sample in a cell can
//! change its result (the transfer function is transparent over it, it cannot beat
//! the running maximum, it cannot reach the threshold, it is all zero) passes over
//! the cell's samples; the samples it does take are those of the unskipped march,
//! so the image is the same (bit for bit: see the tests that compare both).

use crate::parallel::map_indices;

use super::ray::IndexRay;

/// Voxel cells per macrocell and axis.
pub const MACROCELL: usize = 8;

/// How far beyond its cell a filter reads, in voxels: the support the macrocell
/// ranges must include.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Support {
    /// Nearest and trilinear: the cell's own corner voxels, and one voxel of margin
    /// on each side, so that a sample a round-off outside the cell is covered and
    /// a cell whose range is zero holds only exact zeros (X-ray and average skip
    /// such cells, and must add nothing where they do).
    Linear,
    /// Nearest and trilinear for the modes that need no exact zeros: the cell's own
    /// corner voxels only, the range widened by `ROUND_OFF_REACH` instead (see
    /// `Support::cell_range`). Often far narrower at the edge of an object (a
    /// window of 9^3 voxels instead of 11^3).
    LinearTight,
    /// [`Support::LinearTight`], with the ranges of each macrocell's eight octants
    /// (4^3 voxel cells each, their own 5^3 voxels, widened the same way), for a
    /// mode that samples a ray in order through `drive` and passes over the octants
    /// of a cell it cannot pass over whole ([`Walk::pieces`]): the composite.
    LinearOctants,
    /// The cubic B-splines: one voxel before and two after, and the margin.
    Cubic,
}

impl Support {
    /// Voxels read beyond each side of a cell, plus the margin where there is one.
    fn reach(self) -> (usize, usize) {
        match self {
            Support::Linear => (1, 1),
            Support::LinearTight | Support::LinearOctants => (0, 0),
            Support::Cubic => (2, 3),
        }
    }

    /// A macrocell's range from the min and max of the values the filter reads
    /// over [`Support::reach`]: widened by a few ulps for interpolation's
    /// round-off, and for [`Support::LinearTight`] and [`Support::LinearOctants`] by `ROUND_OFF_REACH` more (kept in
    /// [0, 1]), which bounds what a sample a round-off outside the cell reads from
    /// the voxels beyond it: a trilinear sample's weight on a voxel it is a
    /// round-off away from is that round-off (nearest reads no such voxel).
    fn cell_range(self, lo: f32, hi: f32) -> [f32; 2] {
        let [lo, hi] = widen(lo, hi);
        match self {
            Support::LinearTight | Support::LinearOctants => [
                (lo - ROUND_OFF_REACH).max(0.0),
                (hi + ROUND_OFF_REACH).min(1.0),
            ],
            _ => [lo, hi],
        }
    }
}

/// The most a sample a round-off outside its macrocell can differ from one on the
/// cell's face, in normalised values: 2^-14.
///
/// A sample belongs to a cell when its parameter lies in the cell's span of the
/// walk: before the ray's crossing into the next cell, both computed in f64 from
/// the ray's origin, and the first span's cell is the one a point a little after
/// the entry lies in (`Walk::new`: 10^-9 of the ray's length). For the rays the
/// renderer skips with ([`rounds_off_inside`]: origin within 2^31 voxels of index
/// 0, at most 2^15 voxels long), a sample is within 2^-18.5 voxels of its cell by
/// round-off, and within 3.3 10^-5 voxels by the entry's offset: under 2^-14 in
/// all. A trilinear sample's weight on a voxel beyond the cell's is at most that
/// distance, and values are normalised to [0, 1], so the sample moves by at most
/// that much.
const ROUND_OFF_REACH: f32 = 1.0 / 16384.0;

/// Whether the ray `o + d t`, `t` from `t_enter` to `t_exit` (index space), is one
/// for which the bound of `ROUND_OFF_REACH` (2^-14) holds: its origin within 2^31
/// voxels of index 0 along each axis (the volume's sizes are below 2^31) and its
/// length at most 2^15 voxels.
#[inline(always)]
fn rounds_off_inside(o: [f64; 3], d: [f64; 3], t_enter: f64, t_exit: f64) -> bool {
    const ORIGIN: f64 = (1u64 << 31) as f64;
    const LENGTH: f64 = (1u64 << 15) as f64;
    let length = (t_exit - t_enter) * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    o.iter().all(|x| x.abs() <= ORIGIN) && length <= LENGTH
}

/// Writes the ranges of one voxel row's windows: see [`MacroGrid::build`].
type RowRanges<'a> = dyn Fn(usize, &[(usize, usize)], &mut [[f32; 2]]) + Sync + 'a;

/// One slab of macrocells' raw ranges, and their octants' codes (empty for grids
/// without octants).
type SlabRanges = (Vec<[f32; 2]>, Vec<[u8; 8]>);

/// The value range of the field over every macrocell.
#[derive(Clone, Debug)]
pub struct MacroGrid {
    dims: [usize; 3],
    /// `[min, max]` per macrocell, x fastest.
    ranges: Vec<[f32; 2]>,
    /// Per macrocell of a grid of [`Support::LinearOctants`] (empty for the others):
    /// the ranges of its eight octants (bit `a` of the octant's index set for the
    /// upper half along axis `a`), each a byte of two 4-bit levels of the cell's
    /// range ([`encode_part`]).
    parts: Vec<[u8; 8]>,
    /// Voxels per axis.
    n: [usize; 3],
    /// Whether the ranges bound the samples of any ray (else only of the rays of
    /// [`rounds_off_inside`]).
    any_ray: bool,
}

impl MacroGrid {
    /// Macrocells per axis for a grid of `n` voxels.
    pub fn dims(n: [usize; 3]) -> [usize; 3] {
        n.map(|n| n.saturating_sub(1).div_ceil(MACROCELL).max(1))
    }

    /// Bytes a grid for `n` voxels and `support` takes: 8 per macrocell, 16 with the
    /// octants' ranges of [`Support::LinearOctants`].
    pub fn bytes(n: [usize; 3], support: Support) -> u64 {
        let per_cell = if support == Support::LinearOctants {
            16
        } else {
            8
        };
        // saturating: a hostile header's sizes must not overflow (the plan rejects them)
        Self::dims(n)
            .iter()
            .fold(per_cell, |a, &d| a.saturating_mul(d as u64))
    }

    /// Bytes this grid holds.
    pub fn byte_size(&self) -> usize {
        std::mem::size_of_val(self.ranges.as_slice()) + std::mem::size_of_val(self.parts.as_slice())
    }

    /// The grid over `n` voxels for a filter of `support`, where `rows(row, windows,
    /// out)` writes into `out` the range `[min, max]` of the normalised values (as
    /// the filter reads them) of the voxels `x0..=x1` of the x row starting at flat
    /// index `row`, for each `(x0, x1)` of `windows`.
    ///
    /// Separable: the ranges of each voxel row's windows along x, then of those
    /// along y, then along z, one slab of macrocells at a time (in parallel), so
    /// each voxel is read little more than once.
    pub fn build(
        n: [usize; 3],
        support: Support,
        rows: impl Fn(usize, &[(usize, usize)], &mut [[f32; 2]]) + Sync,
    ) -> Self {
        Self::build_rows(n, support, &rows)
    }

    /// [`MacroGrid::build`] through a dynamic `rows` (one call per voxel row), so
    /// that the parallel loop is compiled once, not once per voxel type and filter.
    fn build_rows(n: [usize; 3], support: Support, rows: &RowRanges) -> Self {
        let dims = Self::dims(n);
        let windows = Windows { n, support };
        // per slab of macrocells: their raw ranges, and their octants' codes
        // (grids without the margin)
        let slabs: Vec<SlabRanges> = map_indices(dims[2], &|ck| windows.slab(ck, dims, rows));
        let mut raw: Vec<[f32; 2]> = Vec::with_capacity(dims.iter().product());
        let mut parts: Vec<[u8; 8]> = Vec::new();
        for (cells, codes) in slabs {
            raw.extend(cells);
            parts.extend(codes);
        }
        let mut ranges: Vec<[f32; 2]> = raw
            .iter()
            .map(|&[lo, hi]| support.cell_range(lo, hi))
            .collect();
        if support.reach() == (0, 0) {
            windows.exact_zeros(dims, &raw, &mut ranges, rows);
        }
        MacroGrid {
            dims,
            ranges,
            parts,
            n,
            any_ray: support.reach() != (0, 0),
        }
    }

    /// [`MacroGrid::build`] from the normalised value of every voxel,
    /// `value(flat index)` (one call per voxel read; for tests and small grids).
    pub fn from_values(
        n: [usize; 3],
        support: Support,
        value: impl Fn(usize) -> f32 + Sync,
    ) -> Self {
        Self::build(n, support, |row, windows, out| {
            for (o, &(x0, x1)) in out.iter_mut().zip(windows) {
                *o = (row + x0..=row + x1).fold(
                    [f32::INFINITY, f32::NEG_INFINITY],
                    |[lo, hi], i| {
                        let v = value(i);
                        [lo.min(v), hi.max(v)]
                    },
                );
            }
        })
    }

    /// Whether the ranges bound the samples of a ray from `o` along `d` (index
    /// space) between `t_enter` and `t_exit`: of any ray, unless the grid is of
    /// [`Support::LinearTight`] or [`Support::LinearOctants`], whose ranges hold for the rays of
    /// `rounds_off_inside`.
    #[inline(always)]
    pub fn bounds(&self, o: [f64; 3], d: [f64; 3], t_enter: f64, t_exit: f64) -> bool {
        self.any_ray || rounds_off_inside(o, d, t_enter, t_exit)
    }

    /// Macrocells per axis.
    pub fn cell_dims(&self) -> [usize; 3] {
        self.dims
    }

    /// The value range of macrocell `m` (a flat index).
    #[inline(always)]
    pub fn range(&self, m: usize) -> [f32; 2] {
        self.ranges[m]
    }

    /// Voxels per axis of the grid the macrocells cover.
    pub fn sizes(&self) -> [usize; 3] {
        self.n
    }

    /// Number of macrocells.
    pub fn len(&self) -> usize {
        self.ranges.len()
    }

    /// True for a grid without cells (never: every grid has at least one).
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }

    /// The flat index of the macrocell holding the voxel cell `c`.
    #[inline(always)]
    pub fn of_cell(&self, c: [usize; 3]) -> usize {
        let m = |a: usize| (c[a] / MACROCELL).min(self.dims[a] - 1);
        m(0) + self.dims[0] * (m(1) + self.dims[1] * m(2))
    }

    /// The macrocells `ray` crosses between `t_enter` and `t_exit`, in order.
    pub fn walk(&self, ray: &IndexRay, t_enter: f64, t_exit: f64) -> Walk<'_> {
        Walk::new(self, ray, t_enter, t_exit)
    }
}

/// The empty range, which any range's union replaces.
const EMPTY: [f32; 2] = [f32::INFINITY, f32::NEG_INFINITY];

/// The smallest range holding ranges `a` and `b` (a NaN end of `b` is left out).
#[inline(always)]
fn union(a: [f32; 2], b: [f32; 2]) -> [f32; 2] {
    [
        if b[0] < a[0] { b[0] } else { a[0] },
        if b[1] > a[1] { b[1] } else { a[1] },
    ]
}

/// The voxel windows a grid's macrocells read on a grid of `n` voxels: each
/// cell's voxels and those its filter of `support` reaches beyond them.
struct Windows {
    n: [usize; 3],
    support: Support,
}

impl Windows {
    /// The voxels `lo..=hi` of macrocell `c` along `axis`.
    fn window(&self, c: usize, axis: usize) -> (usize, usize) {
        let (before, after) = self.support.reach();
        let lo = (c * MACROCELL).saturating_sub(before);
        let hi = ((c + 1) * MACROCELL + after).min(self.n[axis] - 1);
        (lo, hi)
    }

    /// The two halves of cell `c`'s window along `axis` (the windows of its
    /// octants), sharing the middle voxel.
    fn halves(&self, c: usize, axis: usize) -> [(usize, usize); 2] {
        let (lo, hi) = self.window(c, axis);
        let mid = (c * MACROCELL + MACROCELL / 2).min(hi);
        [(lo, mid), (mid, hi)]
    }

    /// The raw ranges of the macrocells of slab `ck` (along z) of a grid of `dims`
    /// macrocells, x fastest, and for [`Support::LinearOctants`] their octants'
    /// codes: the ranges of each voxel row's windows along x (`rows`), then their
    /// unions along y and z.
    fn slab(&self, ck: usize, dims: [usize; 3], rows: &RowRanges) -> SlabRanges {
        let n = self.n;
        let (sx, sxy) = (n[0], n[0] * n[1]);
        let tight = self.support == Support::LinearOctants;
        let (z0, z1) = self.window(ck, 2);
        let nz = z1 - z0 + 1;
        // along x: per (z, y) row, per macrocell column (per half of one, for
        // the octants)
        let windows: Vec<(usize, usize)> = if tight {
            (0..dims[0]).flat_map(|c| self.halves(c, 0)).collect()
        } else {
            (0..dims[0]).map(|c| self.window(c, 0)).collect()
        };
        let w = windows.len();
        let mut ranges = vec![EMPTY; nz * n[1] * w];
        for z in 0..nz {
            for y in 0..n[1] {
                let out = &mut ranges[(z * n[1] + y) * w..][..w];
                rows(sx * y + sxy * (z0 + z), &windows, out);
            }
        }
        let row = |z: usize, y: usize| &ranges[(z * n[1] + y) * w..][..w];
        if !tight {
            // along y, then z
            let mut cells = vec![EMPTY; dims[0] * dims[1]];
            for cj in 0..dims[1] {
                let (y0, y1) = self.window(cj, 1);
                for z in 0..nz {
                    for y in y0..=y1 {
                        let out = &mut cells[cj * dims[0]..][..dims[0]];
                        for (o, &r) in out.iter_mut().zip(row(z, y)) {
                            *o = union(*o, r);
                        }
                    }
                }
            }
            return (cells, Vec::new());
        }
        // the octants along y and z (a row on a middle plane counts in both
        // halves), then each cell as the union of its octants
        let zh = self.halves(ck, 2);
        let mut octants = vec![EMPTY; dims[0] * dims[1] * 8];
        for cj in 0..dims[1] {
            let yh = self.halves(cj, 1);
            for z in 0..nz {
                for y in yh[0].0..=yh[1].1 {
                    for (oz, &(za, zb)) in zh.iter().enumerate() {
                        for (oy, &(ya, yb)) in yh.iter().enumerate() {
                            if !(za..=zb).contains(&(z0 + z)) || !(ya..=yb).contains(&y) {
                                continue;
                            }
                            let cells = &mut octants[cj * dims[0] * 8..][..dims[0] * 8];
                            for (cell, r) in
                                cells.chunks_exact_mut(8).zip(row(z, y).chunks_exact(2))
                            {
                                for ox in 0..2 {
                                    let o = &mut cell[ox + 2 * oy + 4 * oz];
                                    *o = union(*o, r[ox]);
                                }
                            }
                        }
                    }
                }
            }
        }
        let cells: Vec<[f32; 2]> = octants
            .chunks_exact(8)
            .map(|o| o.iter().fold(EMPTY, |a, &b| union(a, b)))
            .collect();
        let support = self.support;
        let codes = octants
            .chunks_exact(8)
            .zip(&cells)
            .map(|(o, &[lo, hi])| {
                let cell = support.cell_range(lo, hi);
                std::array::from_fn(|k| encode_part(support.cell_range(o[k][0], o[k][1]), cell))
            })
            .collect();
        (cells, codes)
    }

    /// For a grid without the margin: sets to exact zeros the `ranges` of the
    /// cells whose `raw` ranges read only zeros and the voxels one beyond whose
    /// windows are zeros too (those a sample a round-off outside the cell reads),
    /// so that X-ray-like tests and a MIP on a ray that meets nothing pass over
    /// them. Those voxels lie in the neighbours' windows, so only the sides
    /// towards a neighbour that reads something are read.
    fn exact_zeros(
        &self,
        dims: [usize; 3],
        raw: &[[f32; 2]],
        ranges: &mut [[f32; 2]],
        rows: &RowRanges,
    ) {
        let n = self.n;
        let (sx, sxy) = (n[0], n[0] * n[1]);
        let zero = |m: usize| raw[m][1] <= 0.0;
        let [dx, dy, dz] = dims;
        let flat = |c: [usize; 3]| c[0] + dx * (c[1] + dy * c[2]);
        // the voxels of cell `c` along `axis` on side `s`: -1, the one before its
        // window; 0, the window; +1, the one after it (none at the grid's ends)
        let side = |c: usize, axis: usize, s: i32| -> Option<(usize, usize)> {
            let (lo, hi) = self.window(c, axis);
            match s {
                -1 => lo.checked_sub(1).map(|v| (v, v)),
                0 => Some((lo, hi)),
                _ => (hi + 1 < n[axis]).then_some((hi + 1, hi + 1)),
            }
        };
        let mut out = [[0.0f32; 2]];
        for z in 0..dz {
            for y in 0..dy {
                for x in 0..dx {
                    let m = flat([x, y, z]);
                    if !zero(m) {
                        continue;
                    }
                    let c = [x, y, z];
                    let mut exact = true;
                    'sides: for s in 0..27i32 {
                        let d = [s % 3, s / 3 % 3, s / 9].map(|k| k - 1);
                        if d == [0, 0, 0] {
                            continue;
                        }
                        let nb = [0, 1, 2].map(|a| {
                            c[a].checked_add_signed(d[a] as isize)
                                .filter(|&v| v < dims[a])
                        });
                        let [Some(nx), Some(ny), Some(nz)] = nb else {
                            continue;
                        };
                        if zero(flat([nx, ny, nz])) {
                            continue;
                        }
                        let (Some(wx), Some(wy), Some(wz)) =
                            (side(x, 0, d[0]), side(y, 1, d[1]), side(z, 2, d[2]))
                        else {
                            continue;
                        };
                        for k in wz.0..=wz.1 {
                            for j in wy.0..=wy.1 {
                                rows(sx * j + sxy * k, &[wx], &mut out);
                                if out[0][1] > 0.0 {
                                    exact = false;
                                    break 'sides;
                                }
                            }
                        }
                    }
                    if exact {
                        ranges[m] = [0.0, 0.0];
                    }
                }
            }
        }
    }
}

/// A range widened by the round-off interpolation can add: a few ulps of the
/// larger magnitude (values are normalised to [0, 1], so the max), and kept in
/// [0, 1], to which every filter clamps its result. Exact zeros stay exact: a filter
/// reading only zeros returns zero.
fn widen(lo: f32, hi: f32) -> [f32; 2] {
    let slack = 8.0 * f32::EPSILON * hi.abs().max(lo.abs());
    [(lo - slack).max(0.0), (hi + slack).min(1.0)]
}

/// Level `q` (0 to 15) of the range `cell`: its ends for 0 and 15, the fraction
/// `q / 15` of the way between them otherwise (non-decreasing in `q`).
#[inline(always)]
fn level(q: u8, [lo, hi]: [f32; 2]) -> f32 {
    match q {
        0 => lo,
        15 => hi,
        _ => lo + (hi - lo) * (f32::from(q) * (1.0 / 15.0)),
    }
}

/// An octant's range `part` as two 4-bit levels of its cell's range `cell` (low
/// nibble: the lower end, high nibble: the upper end), rounded outwards: the
/// highest level at or below `part[0]` and the lowest at or above `part[1]`, so
/// that the decoded range ([`decode_part`]) holds `part`, which lies in `cell` (an
/// octant's range is part of its cell's; level 0 is `cell[0]` and level 15
/// `cell[1]`). The levels are guessed by division and corrected against
/// [`level`] itself.
fn encode_part(part: [f32; 2], cell: [f32; 2]) -> u8 {
    let [lo, hi] = cell;
    let guess = |v: f32| {
        let x = (v - lo) / (hi - lo) * 15.0;
        // NaN (an empty range) and values outside it clamp to the ends
        if x > 0.0 {
            x.min(15.0)
        } else {
            0.0
        }
    };
    let mut top = guess(part[1]).ceil() as u8;
    // below the part's top, or incomparable (NaN): not yet a bound
    while top < 15
        && level(top, cell)
            .partial_cmp(&part[1])
            .is_none_or(|o| o.is_lt())
    {
        top += 1;
    }
    while top > 0 && level(top - 1, cell) >= part[1] {
        top -= 1;
    }
    let mut bottom = guess(part[0]).floor() as u8;
    while bottom > 0
        && level(bottom, cell)
            .partial_cmp(&part[0])
            .is_none_or(|o| o.is_gt())
    {
        bottom -= 1;
    }
    while bottom < 15 && level(bottom + 1, cell) <= part[0] {
        bottom += 1;
    }
    bottom | top << 4
}

/// The range an octant's code stands for (see [`encode_part`]).
#[inline(always)]
fn decode_part(code: u8, cell: [f32; 2]) -> [f32; 2] {
    [level(code & 15, cell), level(code >> 4, cell)]
}

/// The part of a [`Span`] inside one octant of its macrocell, with the octant's
/// range: what a ray passes over inside a macrocell it cannot pass over whole.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Piece {
    /// Where the part starts (the span's start, or where the ray crosses one of the
    /// cell's middle planes).
    pub t0: f64,
    /// Where it ends.
    pub t1: f64,
    /// The octant: bit `a` set for the upper half along axis `a`.
    pub octant: usize,
}

impl MacroGrid {
    /// Whether the grid holds its octants' ranges (grids of
    /// [`Support::LinearOctants`]).
    #[inline(always)]
    pub fn has_parts(&self) -> bool {
        !self.parts.is_empty()
    }

    /// The range of octant `octant` of macrocell `cell` (grids with octants).
    #[inline(always)]
    pub fn part_range(&self, cell: usize, octant: usize) -> [f32; 2] {
        decode_part(self.parts[cell][octant], self.ranges[cell])
    }
}

impl Walk<'_> {
    /// The parts of `span`, the span this walk of `ray` returned last, in the
    /// octants of its macrocell, in order, into `out`; their number, 1 to 4. Only
    /// for grids with octants ([`MacroGrid::has_parts`]).
    ///
    /// The ray is cut where it crosses the cell's middle planes (computed from the
    /// plane, as the walk's crossings are), and each part's octant is the one its
    /// middle lies in (for a cell at the grid's edge, the middle plane is clamped to
    /// the last voxel, and a point beyond it counts in the upper half, whose window
    /// holds that voxel). A sample of a part lies within round-off of its octant, as
    /// one of a span does of its cell, and the octant's range is widened as the
    /// cell's is, so it bounds the sample.
    #[inline]
    pub fn pieces(&self, ray: &IndexRay, span: &Span, out: &mut [Piece; 4]) -> usize {
        let grid = self.grid;
        let (o, d, inv) = (self.o, ray.d.to_array(), self.inv);
        let (t0, t1) = (span.t0, span.t1);
        let stepped = usize::from(self.stepped);
        let mut mid = [0.0f64; 3];
        let mut cuts = [0.0f64; 3];
        let mut k = 0;
        // in i64, whose conversion to f64 is one instruction (a u64's is several)
        let m = MACROCELL as i64;
        for a in 0..3 {
            // the span's cell: the walk's, one step back along the axis it stepped
            // (read axis by axis: the walk has just stored them one by one, and a
            // load of two at once would wait for both stores to reach the cache)
            let back = if a == stepped { self.step[a] } else { 0 };
            let c = (self.cell[a] - back).clamp(0, grid.dims[a] as i64 - 1);
            let hi = ((c + 1) * m).min(grid.n[a] as i64 - 1);
            mid[a] = (c * m + m / 2).min(hi) as f64;
            if inv[a] != 0.0 {
                let t = (mid[a] - o[a]) * inv[a];
                if t > t0 && t < t1 {
                    cuts[k] = t;
                    k += 1;
                }
            }
        }
        // in order (at most three)
        if k >= 2 && cuts[1] < cuts[0] {
            cuts.swap(0, 1);
        }
        if k == 3 && cuts[2] < cuts[1] {
            cuts.swap(1, 2);
            if cuts[1] < cuts[0] {
                cuts.swap(0, 1);
            }
        }
        let mut start = t0;
        for (j, piece) in out.iter_mut().enumerate().take(k + 1) {
            let end = if j < k { cuts[j] } else { t1 };
            let t = 0.5 * (start + end);
            let mut octant = 0;
            for a in 0..3 {
                if o[a] + d[a] * t >= mid[a] {
                    octant |= 1 << a;
                }
            }
            *piece = Piece {
                t0: start,
                t1: end,
                octant,
            };
            start = end;
        }
        k + 1
    }
}

/// One step of a [`Walk`]: the ray's parameter interval inside one macrocell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    /// Where the ray enters the macrocell (or `t_enter`).
    pub t0: f64,
    /// Where it leaves (or `t_exit`).
    pub t1: f64,
    /// The macrocell's flat index.
    pub cell: usize,
    /// True for the last span of the ray.
    pub last: bool,
}

/// The macrocells a ray crosses, in order (a 3D DDA, Amanatides and Woo 1987, with
/// every crossing computed from its plane index, never accumulated). Cells outside
/// the grid (the half-voxel slabs of one-voxel axes, round-off at the box's faces)
/// count as the nearest cell inside it.
#[derive(Clone, Debug)]
pub struct Walk<'a> {
    grid: &'a MacroGrid,
    o: [f64; 3],
    /// `1 / d` per axis (0 where the ray is parallel to the axis' planes).
    inv: [f64; 3],
    cell: [i64; 3],
    step: [i64; 3],
    /// Per axis: how the flat index moves with a step (signed), the cells along
    /// it, and 1 when the next crossing is the cell's upper plane (0 for the lower).
    stride: [isize; 3],
    limit: [u64; 3],
    ahead: [i64; 3],
    /// The flat index of the cell, clamped to the grid.
    flat: usize,
    t_next: [f64; 3],
    t: f64,
    t_exit: f64,
    done: bool,
    /// The axis along which the walk stepped after the span it returned last (3
    /// when it did not: that span was the last), so that [`Walk::pieces`] finds
    /// that span's cell without the walk handing its position over with every span.
    stepped: u8,
}

impl<'a> Walk<'a> {
    fn new(grid: &'a MacroGrid, ray: &IndexRay, t_enter: f64, t_exit: f64) -> Walk<'a> {
        let b = MACROCELL as f64;
        let (o, d) = (ray.o.to_array(), ray.d.to_array());
        let mut cell = [0i64; 3];
        let mut step = [0i64; 3];
        let mut inv = [0.0; 3];
        let mut t_next = [f64::INFINITY; 3];
        // the cell of the point a little inside the entry, so that a ray entering
        // exactly on a macrocell face starts in the cell it goes into
        let mid = if t_exit > t_enter {
            t_enter + 1e-9 * (t_exit - t_enter)
        } else {
            t_enter
        };
        for a in 0..3 {
            let p = o[a] + mid * d[a];
            cell[a] = (p / b).floor() as i64;
            if d[a] != 0.0 {
                inv[a] = 1.0 / d[a];
                step[a] = if d[a] > 0.0 { 1 } else { -1 };
                let plane = if d[a] > 0.0 { cell[a] + 1 } else { cell[a] };
                t_next[a] = (plane as f64 * b - o[a]) * inv[a];
            }
        }
        let dims = grid.dims;
        let c = |a: usize| cell[a].clamp(0, dims[a] as i64 - 1) as usize;
        let ok = t_enter.is_finite() && t_exit.is_finite() && t_exit >= t_enter;
        let strides = [1, dims[0], dims[0] * dims[1]];
        Walk {
            grid,
            o,
            inv,
            cell,
            step,
            stride: std::array::from_fn(|a| step[a] as isize * strides[a] as isize),
            limit: dims.map(|d| d as u64),
            ahead: step.map(|s| i64::from(s > 0)),
            flat: c(0) + dims[0] * (c(1) + dims[1] * c(2)),
            t_next,
            t: t_enter,
            t_exit,
            done: !ok,
            stepped: 3,
        }
    }
}

impl Iterator for Walk<'_> {
    type Item = Span;

    #[inline]
    fn next(&mut self) -> Option<Span> {
        if self.done {
            return None;
        }
        // the axis whose plane comes first: a constant index in each branch, so that
        // the walk's state can live in registers rather than in an indexed array
        let (x, y, z) = (self.t_next[0], self.t_next[1], self.t_next[2]);
        if x <= y && x <= z {
            self.advance::<0>(x)
        } else if y <= z {
            self.advance::<1>(y)
        } else {
            self.advance::<2>(z)
        }
    }
}

impl Walk<'_> {
    /// The span up to `next`, where the ray crosses a plane of axis `A`, and the step
    /// into the next cell along `A`.
    #[inline(always)]
    fn advance<const A: usize>(&mut self, next: f64) -> Option<Span> {
        let t0 = self.t;
        // a NaN crossing (not `< t_exit`) ends the walk too
        if next.partial_cmp(&self.t_exit) != Some(std::cmp::Ordering::Less) {
            self.done = true;
            self.stepped = 3;
            return Some(Span {
                t0,
                t1: self.t_exit,
                cell: self.flat,
                last: true,
            });
        }
        let t1 = if next > t0 { next } else { t0 };
        let span = Span {
            t0,
            t1,
            cell: self.flat,
            last: false,
        };
        self.stepped = A as u8;
        self.t = t1;
        let step = self.step[A];
        let c = self.cell[A] + step;
        self.cell[A] = c;
        // a step inside the grid moves the flat index (as unsigned numbers, indices
        // below 0 lie above the limit); one from or to outside it does not
        let limit = self.limit[A];
        if (c as u64) < limit && ((c - step) as u64) < limit {
            self.flat = self.flat.wrapping_add_signed(self.stride[A]);
        }
        let plane = c + self.ahead[A];
        self.t_next[A] = (plane as f64 * MACROCELL as f64 - self.o[A]) * self.inv[A];
        Some(span)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// A fixed pseudo-random sequence in [0, 1) (xorshift64) from `seed`.
    fn xorshift(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// The trilinear reconstruction of the values `v` of `n` voxels (in [0, 1]).
    fn trilinear(v: &[f32], n: [usize; 3]) -> crate::sample::Sampler<'_, f32> {
        use crate::sample::{GradientMethod, Interpolation, Normalize, Sampler};
        Sampler::new(
            v,
            n,
            Normalize::new(0.0, 1.0),
            Interpolation::Trilinear,
            None,
            GradientMethod::Central,
            None,
            glam::DMat3::IDENTITY,
        )
    }

    #[test]
    fn ranges_cover_the_support() {
        // a single bright voxel at (9, 0, 0) of a 20 x 2 x 2 grid: macrocell 0 covers
        // cells 0..8 (voxels 0..=8) plus one voxel of margin (9); macrocell 1 covers
        // voxels 7..=17, macrocell 2 voxels 15..=19
        let n = [20, 2, 2];
        let value = |i: usize| if i == 9 { 1.0 } else { 0.0 };
        let g = MacroGrid::from_values(n, Support::Linear, value);
        assert_eq!(g.cell_dims(), [3, 1, 1]);
        assert_eq!(g.range(0), [0.0, 1.0]);
        assert_eq!(g.range(1), [0.0, 1.0]);
        assert_eq!(g.range(2), [0.0, 0.0]);
        // without the margin: macrocell 0 reads voxels 0..=8, of which a sample a
        // round-off outside it reads at most that round-off (so its zeros are not
        // exact), macrocell 1 voxels 8..=16, macrocell 2 16..=19 (exact zeros: the
        // voxel one beyond, 15, is zero too)
        let g = MacroGrid::from_values(n, Support::LinearTight, value);
        assert_eq!(g.range(0), [0.0, ROUND_OFF_REACH]);
        assert_eq!(g.range(1), [0.0, 1.0]);
        assert_eq!(g.range(2), [0.0, 0.0]);
        // the same across y and z, and at a corner: a bright voxel one beyond
        // macrocell (0, 0, 0)'s corner, at (9, 9, 9) of a 20^3 grid
        let m = [20, 20, 20];
        let corner = |i: usize| if i == 9 + 20 * (9 + 20 * 9) { 1.0 } else { 0.0 };
        let g = MacroGrid::from_values(m, Support::LinearTight, corner);
        assert_eq!(g.range(0), [0.0, ROUND_OFF_REACH]);
        assert_eq!(g.range(2), [0.0, 0.0], "macrocell (2, 0, 0) is two away");
        let value = |i: usize| if i == 9 { 1.0 } else { 0.5 };
        let g = MacroGrid::from_values(n, Support::LinearTight, value);
        let [lo, hi] = widen(0.5, 0.5);
        assert_eq!(g.range(0), [lo - ROUND_OFF_REACH, hi + ROUND_OFF_REACH]);
        let value = |i: usize| if i == 9 { 1.0 } else { 0.0 };
        let g = MacroGrid::from_values(n, Support::Cubic, value);
        assert!(g.range(2)[1] == 0.0, "voxels 14..=19 for the cubic support");
        let value = |i: usize| if i == 14 { 1.0 } else { 0.0 };
        let g = MacroGrid::from_values(n, Support::Cubic, value);
        assert!(g.range(2)[1] > 0.0);
    }

    /// The samples a ray takes in a macrocell's span lie in the cell's range
    /// without the margin (random rays across a face, at the ends of the spans),
    /// and so do samples placed up to 2^-14 voxels beyond the face, where the range
    /// of the support alone, not widened, would not hold them (the random rays
    /// happen not to round past the face: the second part is the one that fails
    /// with no widening).
    #[test]
    fn samples_a_round_off_beyond_a_face_stay_in_the_range() {
        use crate::sample::Field;
        let mut random = xorshift(0x9e37_79b9_7f4a_7c15);
        let n = [33, 17, 17];
        // ones on the plane x = 9, just beyond macrocell 0's support (voxels 0..=8),
        // or on x = 7, just before macrocell 1's (8..=16); zeros elsewhere
        for (plane, cell, side) in [(9, 0, 1.0), (7, 1, -1.0)] {
            let v: Vec<f32> = (0..n[0] * n[1] * n[2])
                .map(|i| if i % n[0] == plane { 1.0 } else { 0.0 })
                .collect();
            let field = trilinear(&v, n);
            let g = MacroGrid::from_values(n, Support::LinearTight, |i| v[i]);
            assert!(g.range(cell)[1] < 1e-3, "the plane is outside the support");
            // rays crossing x = 8 either way: every sample of a span in its range
            let mut checked = 0;
            for k in 0..2000 {
                let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
                let d =
                    DVec3::new(sign * (0.2 + random()), random() - 0.5, random() - 0.5).normalize();
                let o = DVec3::new(
                    8.0 - sign * (1.0 + 3.0 * random()),
                    4.0 + 8.0 * random(),
                    4.0 + 8.0 * random(),
                );
                let ray = IndexRay { o, d };
                for span in g.walk(&ray, 0.0, 12.0) {
                    // the first parameters before the span's end, and one inside it
                    let before_end = |ulps: u64| f64::from_bits(span.t1.to_bits() - ulps);
                    let mid = 0.5 * (span.t0 + span.t1);
                    for t in [span.t0, mid, before_end(1), before_end(2), before_end(4)] {
                        if t < span.t0 || (t >= span.t1 && !span.last) {
                            continue;
                        }
                        let p = ray.at(t);
                        let f = field.value(p);
                        let [lo, hi] = g.range(span.cell);
                        assert!(lo <= f && f <= hi, "{f:e} outside {lo:e}..{hi:e} at {p}");
                        checked += 1;
                    }
                }
            }
            assert!(checked > 5_000);
            // the bound itself: samples up to 2^-14 voxels (the most round-off and the
            // walk's entry put them there: see ROUND_OFF_REACH) beyond the cell's
            // face, towards the plane, read it with that weight and stay in the
            // cell's range
            let mut leaked = 0;
            for e in [-50, -40, -30, -20, -15] {
                let x = 8.0 + side * 1.9 * 2f64.powi(e);
                for (y, z) in [(4.0, 4.0), (4.3, 5.7), (6.99, 4.01)] {
                    let f = field.value(DVec3::new(x, y, z));
                    let [lo, hi] = g.range(cell);
                    assert!(
                        lo <= f && f <= hi,
                        "{f:e} outside {lo:e}..{hi:e} at x = {x}"
                    );
                    leaked += usize::from(f > 0.0);
                }
            }
            // the case this is about does occur
            assert!(leaked > 0);
        }
    }

    #[test]
    fn walk_visits_the_cells_in_order_and_covers_the_interval() {
        let g = MacroGrid::from_values([33, 33, 33], Support::Linear, |_| 0.0);
        assert_eq!(g.cell_dims(), [4, 4, 4]);
        let ray = IndexRay {
            o: DVec3::new(-1.0, 3.0, 30.0),
            d: DVec3::new(1.0, 0.7, -0.9).normalize(),
        };
        let spans: Vec<Span> = g.walk(&ray, 2.0, 30.0).collect();
        assert_eq!(spans.first().unwrap().t0, 2.0);
        assert_eq!(spans.last().unwrap().t1, 30.0);
        assert!(spans.last().unwrap().last);
        for w in spans.windows(2) {
            assert_eq!(w[0].t1, w[1].t0);
            assert_ne!(w[0].cell, w[1].cell);
        }
        // each span's midpoint lies in its cell
        for s in &spans {
            let p = ray.at(0.5 * (s.t0 + s.t1));
            let c = p
                .to_array()
                .map(|x| ((x / 8.0).floor() as i64).clamp(0, 3) as usize);
            assert_eq!(s.cell, c[0] + 4 * (c[1] + 4 * c[2]), "{s:?} at {p}");
        }
    }

    #[test]
    fn axis_rays_and_zero_length_rays() {
        let g = MacroGrid::from_values([17, 17, 1], Support::Linear, |_| 0.0);
        assert_eq!(g.cell_dims(), [2, 2, 1]);
        let ray = IndexRay {
            o: DVec3::new(8.0, -5.0, 0.0),
            d: DVec3::Y,
        };
        let spans: Vec<Span> = g.walk(&ray, 5.0, 21.0).collect();
        assert_eq!(spans.len(), 2);
        assert_eq!((spans[0].t0, spans[0].t1), (5.0, 13.0));
        let spans: Vec<Span> = g.walk(&ray, 7.0, 7.0).collect();
        assert_eq!(spans.len(), 1);
        assert!(spans[0].last);
    }

    #[test]
    fn grid_is_small() {
        // 1/64 of a uint8 volume with 8^3 voxels per macrocell, 1/32 with the
        // octants' ranges
        let n = [257, 257, 257];
        assert_eq!(MacroGrid::bytes(n, Support::Linear), 32 * 32 * 32 * 8);
        assert_eq!(MacroGrid::bytes(n, Support::LinearTight), 32 * 32 * 32 * 8);
        assert_eq!(
            MacroGrid::bytes(n, Support::LinearOctants),
            32 * 32 * 32 * 16
        );
        assert_eq!(MacroGrid::bytes([1, 1, 1], Support::Linear), 8);
        let g = MacroGrid::from_values([33, 17, 9], Support::LinearOctants, |_| 0.5);
        assert_eq!(
            g.byte_size() as u64,
            MacroGrid::bytes([33, 17, 9], Support::LinearOctants)
        );
        let g = MacroGrid::from_values([33, 17, 9], Support::LinearTight, |_| 0.5);
        assert_eq!(
            g.byte_size() as u64,
            MacroGrid::bytes([33, 17, 9], Support::LinearTight)
        );
    }

    #[test]
    fn octant_codes_round_outwards() {
        let cells = [
            [0.0, 1.0],
            [0.1, 0.7],
            [0.3, 0.3],
            [0.0, 0.0],
            [0.25, 0.2500001],
        ];
        let mut next = xorshift(0x2545_f491_4f6c_dd1d);
        let mut random = move || next() as f32;
        for cell in cells {
            for _ in 0..2000 {
                let (a, b) = (random(), random());
                let part = [
                    cell[0] + (cell[1] - cell[0]) * a.min(b),
                    cell[0] + (cell[1] - cell[0]) * a.max(b),
                ];
                let part = [part[0].max(cell[0]), part[1].min(cell[1])];
                let [lo, hi] = decode_part(encode_part(part, cell), cell);
                assert!(
                    lo <= part[0] && part[1] <= hi,
                    "{part:?} in {cell:?}: {lo} {hi}"
                );
            }
            // a part equal to the cell, and the ends
            assert_eq!(decode_part(encode_part(cell, cell), cell), cell);
        }
        // a narrow part far below the top of its cell decodes to well below it
        let [_, hi] = decode_part(encode_part([0.0, 0.05], [0.0, 1.0]), [0.0, 1.0]);
        assert!(hi <= 1.0 / 15.0, "{hi}");
    }

    /// Every sample of a ray's part in an octant lies in the octant's range: random
    /// rays through a field with bright voxels in some octants only, at the ends of
    /// the parts and in between; and the parts tile each span in order.
    #[test]
    fn samples_of_a_part_stay_in_its_octant_range() {
        use crate::sample::Field;
        let mut random = xorshift(0x9e37_79b9_7f4a_7c15);
        // 21 x 19 x 18 voxels: the last cells along each axis are partial (voxels
        // 16..=20, 16..=18, 16..=17), so their middle planes are clamped
        let n = [21, 19, 18];
        let v: Vec<f32> = (0..n[0] * n[1] * n[2])
            .map(|i| {
                let (x, y, z) = (i % n[0], i / n[0] % n[1], i / (n[0] * n[1]));
                // bright in the upper-x, lower-y halves of cells, and a ramp elsewhere
                if x % 8 >= 5 && y % 8 <= 2 {
                    1.0
                } else {
                    0.02 * ((x + 2 * y + 3 * z) % 7) as f32
                }
            })
            .collect();
        let field = trilinear(&v, n);
        let g = MacroGrid::from_values(n, Support::LinearOctants, |i| v[i]);
        assert!(g.has_parts());
        let mut checked = 0;
        let mut narrower = 0;
        let mut pieces = [Piece::default(); 4];
        for k in 0..3000 {
            let d = DVec3::new(random() - 0.5, random() - 0.5, random() - 0.5).normalize();
            let d = if k % 10 == 0 { DVec3::X } else { d };
            let o = DVec3::new(10.0, 9.0, 8.5) - d * 40.0
                + DVec3::new(random() - 0.5, random() - 0.5, random() - 0.5) * 12.0;
            let ray = IndexRay { o, d };
            // the parameters where the ray is inside the box of voxel centres
            let (mut t0, mut t1) = (0.0f64, 80.0f64);
            for a in 0..3 {
                let (oa, da) = (o[a], d[a]);
                if da == 0.0 {
                    if oa < 0.0 || oa > (n[a] - 1) as f64 {
                        t1 = -1.0;
                    }
                    continue;
                }
                let (x, y) = ((0.0 - oa) / da, ((n[a] - 1) as f64 - oa) / da);
                t0 = t0.max(x.min(y));
                t1 = t1.min(x.max(y));
            }
            if t1 <= t0 {
                continue;
            }
            let mut walk = g.walk(&ray, t0, t1);
            while let Some(span) = walk.next() {
                let count = walk.pieces(&ray, &span, &mut pieces);
                assert!((1..=4).contains(&count));
                assert_eq!(pieces[0].t0, span.t0);
                assert_eq!(pieces[count - 1].t1, span.t1);
                for p in &pieces[..count] {
                    let [lo, hi] = g.part_range(span.cell, p.octant);
                    let cell = g.range(span.cell);
                    assert!(cell[0] <= lo && hi <= cell[1]);
                    narrower += usize::from(hi < cell[1]);
                    let before_end = |ulps: u64| f64::from_bits(p.t1.to_bits() - ulps);
                    let mid = 0.5 * (p.t0 + p.t1);
                    for t in [p.t0, mid, before_end(1), before_end(3)] {
                        if t < p.t0 || (t >= p.t1 && !span.last) {
                            continue;
                        }
                        let f = field.value(ray.at(t));
                        assert!(
                            lo <= f && f <= hi,
                            "{f:e} outside {lo:e}..{hi:e} at {} (octant {})",
                            ray.at(t),
                            p.octant
                        );
                        checked += 1;
                    }
                }
                for w in pieces[..count].windows(2) {
                    assert_eq!(w[0].t1, w[1].t0);
                    assert!(w[0].t0 <= w[0].t1);
                }
            }
        }
        assert!(checked > 20_000, "{checked}");
        // the octants do narrow the ranges
        assert!(narrower > 1000, "{narrower}");
    }
}
