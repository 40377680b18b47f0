//! The parallel loop over the pixels of one view, shared by every render mode.
//!
//! The image is cut into bands of [`TILE`] rows rendered in parallel (rayon) into
//! disjoint slices of the film; inside a band, pixels go in tiles of [`TILE`] x
//! [`TILE`], so that neighbouring rays, which read the same voxels, run one after
//! the other while those voxels are in cache. A pixel's value depends only on the
//! view and the pixel, so the image is the same whatever the thread count or the
//! order in which bands finish.

use std::sync::OnceLock;

use super::camera::Projection;
use super::clip::{clip_ray, ClipPlane};
use super::footprint::{Footprint, Windows, WINDOW_TILE};
use super::integrator::{jitter_fraction, Counts, Integrand, PixelRay};
use super::march::March;
use super::skip::MacroGrid;
use super::{IndexFrame, View};
use crate::parallel::map_chunks_mut;
use crate::sample::Field;

/// Pixels per side of a tile (and rows per band).
pub const TILE: usize = 16;

/// An image of `f32` channels (1 = intensity, 4 = RGBA not premultiplied), row 0
/// at the top, channels fastest.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Channels per pixel.
    pub channels: usize,
    /// `width * height * channels` values.
    pub data: Vec<f32>,
}

impl Film {
    /// A film filled with zeros.
    pub fn new(width: usize, height: usize, channels: usize) -> Film {
        Film {
            width,
            height,
            channels,
            data: vec![0.0; width * height * channels],
        }
    }

    /// The channels of pixel `(i, j)`.
    pub fn pixel(&self, i: usize, j: usize) -> &[f32] {
        let s = (j * self.width + i) * self.channels;
        &self.data[s..s + self.channels]
    }
}

/// A pass ready to render: its reconstruction of the field, its integrand, the
/// macrocell grid it skips empty space with (if any), its step and its jitter.
/// Generic over the field and the integrand, so the loop over a view's pixels and
/// the integrand's loop over a ray's samples are compiled together, once per
/// (voxel type, filter, mode).
pub struct Kernel<'a, F: Field, I: Integrand> {
    /// The reconstruction.
    pub field: F,
    /// What each ray computes.
    pub integrand: I,
    /// Empty-space skipping, or `None` to march every sample.
    pub grid: Option<&'a MacroGrid>,
    /// Sample spacing in world units.
    pub dt: f64,
    /// `1 / dt`, for every ray's march.
    inv_dt: f64,
    /// Per-pass seed of the jittered first sample; `None` = no jitter.
    pub jitter: Option<u64>,
    /// The clipping planes that apply to the pass.
    pub clips: &'a [ClipPlane],
    /// The macrocells the integrand cannot pass over, found when a view first
    /// needs them (`None` inside: the integrand's answer depends on the ray).
    footprint: OnceLock<Option<Footprint>>,
}

impl<'a, F: Field, I: Integrand> Kernel<'a, F, I> {
    /// The pass of `integrand` over `field`, sampled every `dt` (world units) from a
    /// first sample jittered by `jitter`'s seed, passing over empty space with
    /// `grid`, cut by `clips`.
    pub fn new(
        field: F,
        integrand: I,
        grid: Option<&'a MacroGrid>,
        dt: f64,
        jitter: Option<u64>,
        clips: &'a [ClipPlane],
    ) -> Self {
        Kernel {
            field,
            integrand,
            grid,
            dt,
            inv_dt: 1.0 / dt,
            jitter,
            clips,
            footprint: OnceLock::new(),
        }
    }

    /// Per tile of `view`, the part of the rays a macrocell walk must cover: for
    /// integrands that say which cells a walk may leave out
    /// ([`Integrand::window_passes`]), on passes that skip.
    fn windows(&self, view: &View, frame: &IndexFrame) -> Option<Windows> {
        let grid = self.grid?;
        let footprint = self.footprint.get_or_init(|| {
            // an integrand answers `None` for every cell or for none
            self.integrand.window_passes(0, grid.range(0))?;
            Some(Footprint::new(grid, |m, range| {
                self.integrand.window_passes(m, range) == Some(false)
            }))
        });
        Some(footprint.as_ref()?.windows(view, frame, WINDOW_TILE))
    }

    /// The pixel `(i, j)`, its ray's macrocell walk limited to `window` (the
    /// whole ray when `None`).
    #[inline(always)]
    fn trace_pixel(
        &self,
        view: &View,
        frame: &IndexFrame,
        i: usize,
        j: usize,
        window: Option<[f64; 2]>,
    ) -> Option<([f32; 4], Counts)> {
        let ray = view.pixel_ray(i, j);
        let index = frame.to_index(ray.origin, ray.dir);
        let t_min = match view.projection {
            Projection::Perspective => 0.0,
            Projection::Orthographic => f64::NEG_INFINITY,
        };
        let (t_box, t_exit) = frame.clip(&index, t_min)?;
        // depth is measured from the bounding sphere (or the box), whatever the cut
        let t_depth_ref = if self.integrand.reads_depth_reference() {
            view.depth_reference(&ray).unwrap_or(t_box)
        } else {
            t_box
        };
        let (t_enter, t_exit, cut) = if self.clips.is_empty() {
            (t_box, t_exit, None)
        } else {
            clip_ray(self.clips, ray.origin, ray.dir, (t_box, t_exit))?
        };
        let walk = match window {
            Some([lo, hi]) if t_enter.is_finite() && t_exit.is_finite() => {
                let (a, b) = (t_enter.max(lo), t_exit.min(hi));
                if a <= b {
                    [a, b]
                } else {
                    [f64::INFINITY, f64::NEG_INFINITY]
                }
            }
            _ => [t_enter, t_exit],
        };
        let pixel_ray = PixelRay {
            origin: ray.origin,
            dir: ray.dir,
            index,
            t_enter,
            t_exit,
            t_depth_ref,
            cut,
            walk,
        };
        let jitter = self.jitter.map_or(0.0, |seed| {
            let (e, f) = (view.eye, view.forward);
            jitter_fraction(seed, [e.x, e.y, e.z, f.x, f.y, f.z], i, j)
        });
        let march = March::jittered_by(t_enter, t_exit, self.dt, self.inv_dt, jitter);
        // the grid's ranges hold for this ray's samples (for every ray but those far
        // from a grid without the margin)
        let (o, d) = (index.o.to_array(), index.d.to_array());
        let grid = self.grid.filter(|g| g.bounds(o, d, t_enter, t_exit));
        Some(self.integrand.trace(&self.field, &pixel_ray, &march, grid))
    }
}

/// A pass ready to render views, with its types erased.
pub trait RenderView: Sync {
    /// Channels per pixel of its films.
    fn channels(&self) -> usize;
    /// Renders `view` of the volume framed by `frame`: the film and the samples.
    fn render(&self, view: &View, frame: &IndexFrame) -> (Film, Counts);
    /// One pixel (also the way to debug a single pixel); `None` where the ray misses.
    fn pixel(
        &self,
        view: &View,
        frame: &IndexFrame,
        i: usize,
        j: usize,
    ) -> Option<([f32; 4], Counts)>;
}

impl<F: Field, I: Integrand> RenderView for Kernel<'_, F, I> {
    fn channels(&self) -> usize {
        self.integrand.channels()
    }

    fn render(&self, view: &View, frame: &IndexFrame) -> (Film, Counts) {
        let channels = self.integrand.channels();
        let mut film = Film::new(view.width, view.height, channels);
        let miss = self.integrand.miss();
        let (width, height) = (view.width, view.height);
        let row_len = width * channels;
        let windows = self.windows(view, frame);
        let band = |band: usize, rows: &mut [f32]| {
            let mut counts = Counts::default();
            let j0 = band * TILE;
            let j1 = (j0 + TILE).min(height);
            for i0 in (0..width).step_by(TILE) {
                for j in j0..j1 {
                    for i in i0..(i0 + TILE).min(width) {
                        let window = windows.as_ref().map(|w| w.at(i, j));
                        let (value, c) = self
                            .trace_pixel(view, frame, i, j, window)
                            .unwrap_or((miss, Counts::default()));
                        let s = (j - j0) * row_len + i * channels;
                        rows[s..s + channels].copy_from_slice(&value[..channels]);
                        counts += c;
                    }
                }
            }
            counts
        };
        // through `&dyn Fn` (`crate::parallel`), so that rayon is compiled once, not
        // once per (voxel type, filter, mode)
        let mut counts = Counts::default();
        for c in map_chunks_mut(&mut film.data, TILE * row_len, &band) {
            counts += c;
        }
        (film, counts)
    }

    fn pixel(
        &self,
        view: &View,
        frame: &IndexFrame,
        i: usize,
        j: usize,
    ) -> Option<([f32; 4], Counts)> {
        self.trace_pixel(view, frame, i, j, None)
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::mode::composite::{Composite, CompositeTable};
    use crate::mode::projection::Average;
    use crate::mode::xray::{Xray, XrayOutput};
    use crate::render::footprint::tests::camera;
    use crate::render::skip::Support;
    use crate::sample::{GradientMethod, Interpolation, Normalize, Sampler};
    use crate::transfer::{Interpolation as Ramp, Transfer1D};
    use crate::volume::Geometry;

    /// Each pixel of `kernel`'s render of `view` (walks limited to the tiles'
    /// windows) against its ray walked whole ([`RenderView::pixel`]): the same bits
    /// and the same samples taken.
    fn same_as_whole_walks<F: Field, I: Integrand>(
        kernel: &Kernel<'_, F, I>,
        view: &View,
        frame: &IndexFrame,
    ) -> u64 {
        let (windowed, whole) = same_pixels_as_whole_walks(kernel, view, frame);
        assert_eq!(windowed, whole, "{view:?}: samples taken");
        windowed.taken
    }

    /// Each pixel of `kernel`'s render of `view` against its ray walked whole: the
    /// same bits. Returns the samples of both.
    fn same_pixels_as_whole_walks<F: Field, I: Integrand>(
        kernel: &Kernel<'_, F, I>,
        view: &View,
        frame: &IndexFrame,
    ) -> (Counts, Counts) {
        let (film, counts) = kernel.render(view, frame);
        let miss = kernel.integrand.miss();
        let mut sum = Counts::default();
        for j in 0..view.height {
            for i in 0..view.width {
                let (value, c) = kernel
                    .pixel(view, frame, i, j)
                    .unwrap_or((miss, Counts::default()));
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(film.pixel(i, j)),
                    bits(&value[..film.channels]),
                    "{view:?}: pixel ({i}, {j})"
                );
                sum += c;
            }
        }
        (counts, sum)
    }

    /// The pixels of `view` whose rays' windows are empty.
    fn empty_windows(w: &Windows, view: &View) -> usize {
        (0..view.height)
            .flat_map(|j| (0..view.width).map(move |i| (i, j)))
            .filter(|&(i, j)| {
                let [lo, hi] = w.at(i, j);
                lo > hi
            })
            .count()
    }

    /// Three blobs in a 40 x 34 x 30 volume, zero elsewhere (every zero voxel with
    /// an odd index -0.0 when `negative_zeros`).
    fn blobs(negative_zeros: bool) -> ([usize; 3], Vec<f32>) {
        let n = [40, 34, 30];
        let blobs = [
            ([8.0, 7.0, 6.0], 3.0),
            ([29.0, 22.0, 12.0], 4.0),
            ([19.0, 17.0, 15.0], 2.5),
        ];
        let mut v = Vec::with_capacity(n[0] * n[1] * n[2]);
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    let p = DVec3::new(i as f64, j as f64, k as f64);
                    let f = blobs
                        .iter()
                        .map(|&(c, r)| (1.0 - p.distance(DVec3::from_array(c)) / r).max(0.0))
                        .sum::<f64>();
                    let f = f.min(1.0) as f32;
                    let odd = v.len() % 2 == 1;
                    v.push(if f == 0.0 && odd && negative_zeros {
                        -0.0
                    } else {
                        f
                    });
                }
            }
        }
        (n, v)
    }

    /// The field of voxels `v` (`n` of them, normalised over [0, 1]) sampled with
    /// `interpolation`, `m` taking world to index coordinates.
    fn blob_field<'a>(
        v: &'a [f32],
        n: [usize; 3],
        m: glam::DMat3,
        interpolation: Interpolation,
    ) -> Sampler<'a, f32> {
        Sampler::new(
            v,
            n,
            Normalize::new(0.0, 1.0),
            interpolation,
            None,
            GradientMethod::Central,
            None,
            m,
        )
    }

    /// The frame of a volume of `n` voxels with unequal spacings, and the views the
    /// windowed-walk tests render: orthographic ones, a perspective one, the same
    /// off axis, and one from inside the volume (the last).
    fn window_test_views(n: [usize; 3]) -> (IndexFrame, Vec<View>, glam::DMat3) {
        let geometry = Geometry::from_spacing([0.9, 1.2, 1.5]);
        let m = geometry.index_from_world_matrix().unwrap();
        let frame = IndexFrame::new(n, None, &geometry, m);
        let sphere = frame.bounding_sphere(&geometry);
        let mut views: Vec<View> = [
            (Projection::Orthographic, 20.0, 15.0),
            (Projection::Orthographic, 0.0, 90.0),
            (Projection::Perspective, -35.0, 40.0),
        ]
        .iter()
        .map(|&(p, az, el)| View::new(&camera(p, az, el, 1.3), 0.0, 61, 47, sphere))
        .collect();
        views.push(views[2].off_axis(0.1 * sphere.1));
        let mut inside = views[2];
        inside.eye = sphere.0;
        views.push(inside);
        (frame, views, m)
    }

    /// Walks limited to the windows of `footprint.rs` give every pixel, and take
    /// every sample, of the whole walks: X-ray, average and composite passes (with
    /// and without jitter) over scattered blobs, in orthographic and perspective views (an eye
    /// inside the volume, an off-axis one), and the windows do narrow the walks.
    #[test]
    fn windowed_walks_give_every_pixel_of_the_whole_walks() {
        let (n, v) = blobs(false);
        let grid = MacroGrid::from_values(n, Support::Linear, |i| v[i]);
        let octants = MacroGrid::from_values(n, Support::LinearOctants, |i| v[i]);
        let (frame, views, m) = window_test_views(n);
        let field = blob_field(&v, n, m, Interpolation::Trilinear);
        let xray = Xray {
            output: XrayOutput::Integral,
            mu: 1.0,
        };
        let (mut taken, mut nominal) = (0, 0);
        for jitter in [None, Some(7)] {
            let dt = 0.37;
            let alpha = vec![(0.0, 0.0), (0.3, 0.0), (1.0, 0.6)];
            let tf = Transfer1D::new(vec![(0.0, [1.0; 3])], alpha, Ramp::Linear).unwrap();
            let table = CompositeTable::OneD(tf.table(256));
            let mut composite = Composite::new(table, dt, 1.0, None, 0.99, 1.0, None);
            composite.classify(&octants);
            let k = Kernel::new(&field, xray, Some(&grid), dt, jitter, &[]);
            let a = Kernel::new(&field, Average, Some(&grid), dt, jitter, &[]);
            let c = Kernel::new(&field, composite, Some(&octants), dt, jitter, &[]);
            for (n, view) in views.iter().enumerate() {
                taken += same_as_whole_walks(&k, view, &frame);
                taken += same_as_whole_walks(&a, view, &frame);
                same_as_whole_walks(&c, view, &frame);
                assert!(
                    c.windows(view, &frame).is_some(),
                    "composite passes have windows"
                );
                nominal += 2 * k.render(view, &frame).1.nominal;
                let w = k.windows(view, &frame).expect("X-ray passes have windows");
                let empty = empty_windows(&w, view);
                // (from inside the volume, the cell around the eye covers the image)
                assert!(n == 4 || empty > 0, "{view:?}: no ray is passed over whole");
            }
        }
        assert!(taken > 0 && taken * 3 < nominal * 2, "{taken} of {nominal}");
    }

    /// Iso-surface and depth passes walk only their windows (the cells that can
    /// reach the level): every pixel and every sample of the whole walks, at two
    /// levels and two steps, in every view, without clipping planes and with one
    /// through the middle of a blob, capped and not (the rays that enter through
    /// it inside the blob search falling and walk whole), and the windows leave
    /// rays out.
    #[test]
    fn windowed_crossings_give_every_pixel_of_the_whole_walks() {
        use crate::mode::crossing::{Depth, Surface};
        use crate::render::ClipPlane;
        use crate::shade::{Light, Material, Model, Shader};
        let (n, v) = blobs(false);
        let grid = MacroGrid::from_values(n, Support::LinearTight, |i| v[i]);
        let (frame, views, m) = window_test_views(n);
        let field = blob_field(&v, n, m, Interpolation::Trilinear);
        let shader = Shader {
            model: Model::Phong,
            material: Material::preset("gold").expect("gold is a preset"),
            light: Light::headlight(),
        };
        // through the middle of the blob at (19, 17, 15) (index space; the world
        // point of that voxel with the test's spacings)
        let cut = |cap| ClipPlane {
            point: DVec3::new(19.0 * 0.9, 17.0 * 1.2, 15.0 * 1.5),
            normal: DVec3::new(1.0, 0.3, -0.2).normalize(),
            cap,
        };
        let clip_sets = [vec![], vec![cut(false)], vec![cut(true)]];
        let mut taken = 0;
        // (a fine step, and a coarse one: a few samples per macrocell)
        for (level, dt) in [(0.2, 0.37), (0.6, 0.37), (0.2, 2.5), (0.6, 2.5)] {
            let surface = Surface { iso: level, shader };
            let depth = Depth { threshold: level };
            for clips in &clip_sets {
                let s = Kernel::new(&field, surface, Some(&grid), dt, None, clips);
                let d = Kernel::new(&field, depth, Some(&grid), dt, None, clips);
                for (k, view) in views.iter().enumerate() {
                    taken += same_as_whole_walks(&s, view, &frame);
                    same_as_whole_walks(&d, view, &frame);
                    let w = s
                        .windows(view, &frame)
                        .expect("surface passes have windows");
                    assert!(
                        d.windows(view, &frame).is_some(),
                        "depth passes have windows"
                    );
                    // (from inside the volume, the cell around the eye covers the image)
                    assert!(k == 4 || empty_windows(&w, view) > 0, "{view:?}");
                }
            }
        }
        assert!(taken > 0);
    }

    /// MIP's walks limited to the windows of its cells that are not all zero
    /// (`Mip::window_passes`) give every pixel of the whole walks, with voxels of
    /// +0 and -0 (a ray that meets only zeros has the maximum of its first sample),
    /// and of every sample taken without skipping, and take no more samples than
    /// the whole walks; so do local MIP's with a threshold above zero; MinIP, and
    /// local MIP with a threshold of zero, have no windows.
    #[test]
    fn windowed_mip_and_local_mip_give_every_pixel_of_the_whole_walks() {
        use crate::mode::projection::{Lmip, Minip, Mip};
        for negative_zeros in [false, true] {
            let (n, v) = blobs(negative_zeros);
            let grid = MacroGrid::from_values(n, Support::Linear, |i| v[i]);
            let (frame, views, m) = window_test_views(n);
            for interpolation in [Interpolation::Trilinear, Interpolation::Nearest] {
                let field = blob_field(&v, n, m, interpolation);
                let mip = Kernel::new(&field, Mip, Some(&grid), 0.37, None, &[]);
                let minip = Kernel::new(&field, Minip, Some(&grid), 0.37, None, &[]);
                let every = Kernel::new(&field, Mip, None, 0.37, None, &[]);
                let lmip = |threshold, grid| {
                    Kernel::new(&field, Lmip { threshold }, grid, 0.37, None, &[])
                };
                let lmips = [0.3, 0.8].map(|t| (lmip(t, Some(&grid)), lmip(t, None)));
                let lmip_zero = lmip(0.0, Some(&grid));
                let bits = |f: &Film| f.data.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                for (k, view) in views.iter().enumerate() {
                    let (a, b) = same_pixels_as_whole_walks(&mip, view, &frame);
                    assert!(a.taken <= b.taken && a.nominal == b.nominal, "{view:?}");
                    // and those of every sample, unskipped
                    let (skipped, unskipped) =
                        (mip.render(view, &frame), every.render(view, &frame));
                    assert_eq!(bits(&skipped.0), bits(&unskipped.0), "{view:?}");
                    assert!(skipped.1.taken < unskipped.1.taken);
                    // local MIP over the same windows (a threshold of 0 has none)
                    for (l, unskipped) in &lmips {
                        let (a, b) = same_pixels_as_whole_walks(l, view, &frame);
                        assert!(a.taken <= b.taken, "{view:?}");
                        let (x, y) = (l.render(view, &frame), unskipped.render(view, &frame));
                        assert_eq!(bits(&x.0), bits(&y.0), "{view:?}");
                        assert!(l.windows(view, &frame).is_some());
                    }
                    assert!(lmip_zero.windows(view, &frame).is_none());
                    assert!(minip.windows(view, &frame).is_none());
                    same_as_whole_walks(&minip, view, &frame);
                    // the windows leave rays out (from inside the volume, the cell
                    // around the eye covers the image)
                    let w = mip.windows(view, &frame).expect("MIP passes have windows");
                    let empty = empty_windows(&w, view);
                    assert!(k == 4 || empty > 0, "{view:?}: no ray is left out");
                }
            }
        }
    }
}
