//! Where in a view the macrocells a pass cannot pass over lie: per tile of pixels,
//! the part of its rays that can meet one.
//!
//! For a pass whose integrand decides from a macrocell alone whether to pass over
//! it ([`Integrand::fixed_skippable`](super::integrator::Integrand::fixed_skippable):
//! the composite's transparent cells, the X-ray's and the average's zero cells), a
//! ray's walk through the macrocells only needs to cover the part of the ray where
//! a cell it does not pass over can lie: in front of it and behind it, the walk
//! would pass over every cell anyway. MIP's walks cover the part where a cell that
//! is not all zero can lie ([`Integrand::window_passes`](super::integrator::Integrand::window_passes)):
//! the zeros outside it cannot raise a maximum. Iso-surface and depth passes
//! cover the part where a cell that can reach the level lies: a ray's search for
//! the first crossing passes over the cells below it (a ray that enters through a
//! cut inside the object searches for the level falling, and walks its whole
//! ray). [`Footprint`] holds the boxes of those cells (index space,
//! merged into blocks on large grids); [`Footprint::windows`] projects them into a
//! view and gives each tile of pixels the interval of `t` its rays need, widened by
//! a voxel for round-off. The walk ([`drive`](super::integrator::drive)) then starts
//! and ends inside cells it passes over, so it hands the integrand the same samples
//! in the same calls: the image and the samples taken are the same, bit for bit
//! (`frame.rs` tests every pixel of views against the walk of the whole ray; for
//! MIP, the image, with no more samples).
//!
//! On the peer benchmark's composite (bench/peers/README.md), the walks spend about
//! two thirds of their steps in front of the first cell that is not transparent or
//! behind the last, and four rays in ten meet none.

use glam::DVec3;

use super::camera::Projection;
use super::camera::View;
use super::ray::IndexFrame;
use super::skip::{MacroGrid, MACROCELL};

/// Pixels per side of the tiles whose rays share a window: smaller than the
/// render's tiles (`frame::TILE`), for tighter windows, and so fewer samples
/// per ray, where smaller tiles gained little more (bench/peers/README.md).
pub const WINDOW_TILE: usize = 8;

/// Boxes projected per view at most: beyond this many macrocells, neighbouring
/// cells are merged into blocks (a box per block holding one that matters).
const MAX_BOXES: usize = 1 << 16;

/// The index-space boxes of the macrocells (or blocks of them) a pass cannot pass
/// over.
#[derive(Clone, Debug)]
pub struct Footprint {
    boxes: Vec<[DVec3; 2]>,
}

/// The interval of `t` of each tile's rays that can meet a box of a [`Footprint`]
/// (empty, start above end, where none can).
#[derive(Clone, Debug)]
pub struct Windows {
    /// log2 of the tiles' side in pixels.
    shift: u32,
    tiles_x: usize,
    spans: Vec<[f64; 2]>,
}

impl Windows {
    /// The interval for pixel `(i, j)`'s tile.
    #[inline]
    pub fn at(&self, i: usize, j: usize) -> [f64; 2] {
        self.spans[(j >> self.shift) * self.tiles_x + (i >> self.shift)]
    }
}

impl Footprint {
    /// Bytes a pass's footprint over a grid of `n` voxels takes at most, with the
    /// windows of `views` renders of `width x height` pixels in flight.
    pub fn max_bytes(n: [usize; 3], width: usize, height: usize, views: usize) -> u64 {
        let cells = MacroGrid::dims(n)
            .iter()
            .fold(1u64, |a, &d| a.saturating_mul(d as u64));
        // a box and a flag per block, at most MAX_BOXES of them
        let boxes = cells.min(MAX_BOXES as u64) * (std::mem::size_of::<[DVec3; 2]>() as u64 + 1);
        let tiles = (width.div_ceil(WINDOW_TILE) * height.div_ceil(WINDOW_TILE)) as u64;
        boxes.saturating_add((views as u64).saturating_mul(tiles * 16))
    }

    /// The boxes of the macrocells of `grid` for which `matters(cell, range)` is
    /// true. A cell's box is the region the walk assigns to it: `MACROCELL` voxels
    /// per axis, the cells at the grid's faces reaching beyond the sampled box.
    pub fn new(grid: &MacroGrid, matters: impl Fn(usize, [f32; 2]) -> bool) -> Footprint {
        let dims = grid.cell_dims();
        let n = grid.sizes();
        // cells per block edge: one, unless the grid has more than MAX_BOXES cells
        let mut b = 1;
        while dims.iter().map(|&d| d.div_ceil(b)).product::<usize>() > MAX_BOXES {
            b += 1;
        }
        let blocks = dims.map(|d| d.div_ceil(b));
        let mut hit = vec![false; blocks.iter().product()];
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let m = x + dims[0] * (y + dims[1] * z);
                    if matters(m, grid.range(m)) {
                        hit[x / b + blocks[0] * (y / b + blocks[1] * (z / b))] = true;
                    }
                }
            }
        }
        // the region of cells c0..=c1 along axis a
        let region = |a: usize, c0: usize, c1: usize| -> [f64; 2] {
            let lo = if c0 == 0 {
                -1.0
            } else {
                (c0 * MACROCELL) as f64
            };
            let hi = if c1 + 1 >= dims[a] {
                ((dims[a] * MACROCELL).max(n[a]) + 1) as f64
            } else {
                ((c1 + 1) * MACROCELL) as f64
            };
            [lo, hi]
        };
        let mut boxes = Vec::new();
        for bz in 0..blocks[2] {
            for by in 0..blocks[1] {
                for bx in 0..blocks[0] {
                    if !hit[bx + blocks[0] * (by + blocks[1] * bz)] {
                        continue;
                    }
                    let k = [bx, by, bz];
                    let r: [[f64; 2]; 3] = std::array::from_fn(|a| {
                        region(a, k[a] * b, ((k[a] + 1) * b - 1).min(dims[a] - 1))
                    });
                    boxes.push([
                        DVec3::new(r[0][0], r[1][0], r[2][0]),
                        DVec3::new(r[0][1], r[1][1], r[2][1]),
                    ]);
                }
            }
        }
        Footprint { boxes }
    }

    /// Per tile of `tile` x `tile` pixels of `view` (a power of two), the interval
    /// of `t` (world units, as [`View::ray`]'s rays) outside which no ray of the tile
    /// meets a box, widened by a voxel.
    pub fn windows(&self, view: &View, frame: &IndexFrame, tile: usize) -> Windows {
        assert!(tile.is_power_of_two(), "tiles of a power of two pixels");
        let (origin, m) = frame.world_from_index();
        // a voxel's diagonal, at most, in world units
        let margin = m.x_axis.length() + m.y_axis.length() + m.z_axis.length();
        let tiles_x = view.width.div_ceil(tile);
        let tiles_y = view.height.div_ceil(tile);
        let mut spans = vec![[f64::INFINITY, f64::NEG_INFINITY]; tiles_x * tiles_y];
        let (w, h) = (view.width as f64, view.height as f64);
        let perspective = view.projection == Projection::Perspective;
        // pixel coordinates of a direction's image-plane offsets (a, b): x of `a`
        // (`ray`: a = px hw + shift, px = 2 x / w - 1), y of `b` (b = py hh,
        // py = 1 - 2 y / h)
        let (hw, hh) = (view.half_width, view.half_height);
        let shift = if perspective { view.shift } else { 0.0 };
        let x_of = |a: f64| ((a - shift) / hw + 1.0) * 0.5 * w;
        let y_of = |b: f64| (1.0 - b / hh) * 0.5 * h;
        for [lo, hi] in &self.boxes {
            let mut x = [f64::INFINITY, f64::NEG_INFINITY];
            let mut y = [f64::INFINITY, f64::NEG_INFINITY];
            let mut t = [f64::INFINITY, f64::NEG_INFINITY];
            let mut everywhere = false;
            for k in 0..8 {
                let p = DVec3::new(
                    if k & 1 == 0 { lo.x } else { hi.x },
                    if k & 2 == 0 { lo.y } else { hi.y },
                    if k & 4 == 0 { lo.z } else { hi.z },
                );
                let r = origin + m * p - view.eye;
                let z = r.dot(view.forward);
                let (a, b) = (r.dot(view.right), r.dot(view.up));
                let (a, b) = if perspective {
                    if z <= 1e-9 * r.length() {
                        // at or behind the eye: anywhere on the image
                        everywhere = true;
                        (0.0, 0.0)
                    } else {
                        (a / z, b / z)
                    }
                } else {
                    (a, b)
                };
                let (px, py) = (x_of(a), y_of(b));
                x = [x[0].min(px), x[1].max(px)];
                y = [y[0].min(py), y[1].max(py)];
                // t along the ray through the point: its depth (orthographic), its
                // distance (perspective), which is at least its depth
                let (t_lo, t_hi) = if perspective { (z, r.length()) } else { (z, z) };
                t = [t[0].min(t_lo), t[1].max(t_hi)];
            }
            let tiles = |v: [f64; 2], count: usize| -> Option<(usize, usize)> {
                if everywhere {
                    return Some((0, count - 1));
                }
                // a pixel of margin; the tile k holds the pixel centres of [k tile,
                // (k + 1) tile)
                let (a, b) = ((v[0] - 1.0) / tile as f64, (v[1] + 1.0) / tile as f64);
                if !(a.is_finite() && b.is_finite()) {
                    return Some((0, count - 1));
                }
                if b < 0.0 || a >= count as f64 {
                    return None;
                }
                Some((a.max(0.0) as usize, (b as usize).min(count - 1)))
            };
            let (Some((x0, x1)), Some((y0, y1))) = (tiles(x, tiles_x), tiles(y, tiles_y)) else {
                continue;
            };
            let t_lo = if perspective && everywhere {
                f64::NEG_INFINITY
            } else {
                t[0]
            };
            for ty in y0..=y1 {
                for tx in x0..=x1 {
                    let s = &mut spans[ty * tiles_x + tx];
                    *s = [s[0].min(t_lo), s[1].max(t[1])];
                }
            }
        }
        for ty in 0..tiles_y {
            for tx in 0..tiles_x {
                let s = &mut spans[ty * tiles_x + tx];
                if s[0] > s[1] {
                    continue;
                }
                // perspective: a ray of the tile at angle theta to the axis meets a
                // point of depth z at t = z / cos(theta), and cos(theta) is at most
                // its largest over the tile
                let lo = if perspective && s[0] > 0.0 {
                    s[0] / max_cos(view, tx * tile, ty * tile, tile)
                } else {
                    s[0]
                };
                *s = [lo - margin, s[1] + margin];
            }
        }
        Windows {
            shift: tile.trailing_zeros(),
            tiles_x,
            spans,
        }
    }
}

/// The largest cosine between `view.forward` and the rays of a perspective view
/// through the image positions of the tile `[x0, x0 + tile] x [y0, y0 + tile]`.
fn max_cos(view: &View, x0: usize, y0: usize, tile: usize) -> f64 {
    let (w, h) = (view.width as f64, view.height as f64);
    // the direction through (x, y) is forward + right a + up b
    let a_of = |x: f64| (x / w * 2.0 - 1.0) * view.half_width + view.shift;
    let b_of = |y: f64| (1.0 - y / h * 2.0) * view.half_height;
    let closest = |u: f64, v: f64| {
        let (lo, hi) = if u <= v { (u, v) } else { (v, u) };
        0.0f64.clamp(lo, hi)
    };
    let (x1, y1) = ((x0 + tile) as f64, (y0 + tile) as f64);
    let a = closest(a_of(x0 as f64), a_of(x1));
    let b = closest(b_of(y0 as f64), b_of(y1));
    1.0 / (1.0 + a * a + b * b).sqrt()
}

#[cfg(test)]
pub(crate) mod tests {
    use glam::{DMat3, DQuat, DVec3};

    use super::*;
    use crate::render::camera::Camera;
    use crate::render::skip::Support;
    use crate::volume::Geometry;

    /// A camera of `projection` at `azimuth` and `elevation` (degrees), `zoom`.
    pub(crate) fn camera(
        projection: Projection,
        azimuth: f64,
        elevation: f64,
        zoom: f64,
    ) -> Camera {
        Camera {
            projection,
            fov_deg: 30.0,
            azimuth_deg: azimuth,
            elevation_deg: elevation,
            up: DVec3::Z,
            zoom,
            fit: None,
            distance: None,
            target: None,
        }
    }

    /// The parameter interval where `o + t d` lies in the box `[lo, hi]` (slab
    /// method, written here independently of the code under test).
    fn slab(o: DVec3, d: DVec3, [lo, hi]: [DVec3; 2]) -> Option<[f64; 2]> {
        let (mut a, mut b) = (f64::NEG_INFINITY, f64::INFINITY);
        for k in 0..3 {
            if d[k] == 0.0 {
                if o[k] < lo[k] || o[k] > hi[k] {
                    return None;
                }
                continue;
            }
            let (t0, t1) = ((lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]);
            a = a.max(t0.min(t1));
            b = b.min(t0.max(t1));
        }
        (a <= b).then_some([a, b])
    }

    /// Three geometries: unit voxels, anisotropic ones, and oblique axes.
    fn geometries() -> Vec<Geometry> {
        let rot = DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.2, 0.5);
        vec![
            Geometry::default(),
            Geometry::from_spacing([0.8, 1.3, 2.0]),
            Geometry {
                origin: DVec3::new(3.0, -2.0, 1.0),
                axes: [
                    rot * DVec3::new(1.0, 0.0, 0.0),
                    rot * DVec3::new(0.3, 1.1, 0.0),
                    rot * DVec3::new(0.0, 0.2, 0.9),
                ],
            },
        ]
    }

    /// Every pixel's ray, through every box it meets, lies inside its tile's
    /// window, for orthographic and perspective views (from outside the volume and
    /// from inside it, off-axis stereo eyes too), on three geometries; and the
    /// windows narrow the rays: tiles meeting nothing are empty.
    #[test]
    fn windows_hold_every_ray_through_every_box() {
        let n = [41, 35, 29];
        // a few scattered macrocells hold values, one at the centre (where an eye
        // inside the volume is)
        let lit = [
            (5, 4, 3),
            (30, 20, 10),
            (12, 30, 25),
            (40, 0, 0),
            (20, 17, 14),
        ];
        let value = |i: usize| {
            let (x, y, z) = (i % n[0], i / n[0] % n[1], i / (n[0] * n[1]));
            if lit.contains(&(x, y, z)) {
                1.0
            } else {
                0.0
            }
        };
        let grid = MacroGrid::from_values(n, Support::Linear, value);
        let fp = Footprint::new(&grid, |_, r| r[1] > 0.0);
        let boxes = fp.boxes.len();
        assert!(boxes >= lit.len() && boxes < grid.len() / 4, "{boxes}");
        let (mut checked, mut empty, mut tiles) = (0usize, 0usize, 0usize);
        for geometry in geometries() {
            let m = geometry.index_from_world_matrix().unwrap();
            let frame = IndexFrame::new(n, None, &geometry, m);
            let sphere = frame.bounding_sphere(&geometry);
            let mut views = Vec::new();
            for (p, az, el) in [
                (Projection::Orthographic, 20.0, 15.0),
                (Projection::Orthographic, 0.0, 90.0),
                (Projection::Perspective, -35.0, 40.0),
                (Projection::Perspective, 160.0, -10.0),
            ] {
                views.push(View::new(&camera(p, az, el, 1.0), 0.0, 70, 45, sphere));
            }
            // off-axis eyes, and a perspective eye inside the volume
            views.push(views[2].off_axis(0.1 * sphere.1));
            let mut inside = views[3];
            inside.eye = sphere.0 + 0.01 * sphere.1 * inside.forward;
            views.push(inside);
            for view in &views {
                for tile in [4, 8, 16] {
                    let w = fp.windows(view, &frame, tile);
                    tiles += w.spans.len();
                    empty += w.spans.iter().filter(|s| s[0] > s[1]).count();
                    for j in 0..view.height {
                        for i in 0..view.width {
                            let ray = view.pixel_ray(i, j);
                            let index = frame.to_index(ray.origin, ray.dir);
                            let [lo, hi] = w.at(i, j);
                            for b in &fp.boxes {
                                let Some([a, z]) = slab(index.o, index.d, *b) else {
                                    continue;
                                };
                                let min = if view.projection == Projection::Perspective {
                                    0.0
                                } else {
                                    f64::NEG_INFINITY
                                };
                                if z < min {
                                    continue;
                                }
                                let a = a.max(min);
                                assert!(
                                    lo <= a && z <= hi,
                                    "{view:?} tile {tile} pixel ({i}, {j}): box {b:?} at \
                                     [{a}, {z}], window [{lo}, {hi}]"
                                );
                                checked += 1;
                            }
                        }
                    }
                }
            }
        }
        assert!(checked > 10_000, "{checked}");
        assert!(empty * 2 > tiles, "{empty} of {tiles} tiles empty");
    }

    /// A window is no longer than its boxes' extent along the ray and a voxel each
    /// side (orthographic: the extent in depth of the box).
    #[test]
    fn orthographic_windows_are_tight() {
        let n = [64, 64, 64];
        let grid = MacroGrid::from_values(n, Support::Linear, |i| {
            if i == 30 + 64 * (30 + 64 * 30) {
                1.0
            } else {
                0.0
            }
        });
        let fp = Footprint::new(&grid, |_, r| r[1] > 0.0);
        let geometry = Geometry::default();
        let frame = IndexFrame::new(n, None, &geometry, DMat3::IDENTITY);
        let sphere = frame.bounding_sphere(&geometry);
        let view = View::new(
            &camera(Projection::Orthographic, 0.0, 0.0, 1.0),
            0.0,
            64,
            64,
            sphere,
        );
        let w = fp.windows(&view, &frame, 8);
        let widest = w
            .spans
            .iter()
            .filter(|s| s[0] <= s[1])
            .map(|s| s[1] - s[0])
            .fold(0.0, f64::max);
        // the cells of the voxel's reach along the view (y): at most three
        // macrocells deep, and a voxel diagonal (sqrt 3 < 3) of margin each side
        assert!(widest > 0.0 && widest <= 3.0 * 8.0 + 2.0 * 3.0, "{widest}");
        let hit = w.spans.iter().filter(|s| s[0] <= s[1]).count();
        assert!(hit < w.spans.len() / 4, "{hit} of {}", w.spans.len());
    }
}
