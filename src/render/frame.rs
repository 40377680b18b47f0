//! The parallel loop over the pixels of one view, shared by every render mode.
//!
//! The image is cut into bands of [`TILE`] rows rendered in parallel (rayon) into
//! disjoint slices of the film; inside a band, pixels go in tiles of [`TILE`] x
//! [`TILE`], so that neighbouring rays, which read the same voxels, run one after
//! the other while those voxels are in cache. A pixel's value depends only on the
//! view and the pixel, so the image is the same whatever the thread count or the
//! order in which bands finish.

use super::clip::{clip_ray, ClipPlane};
use super::integrator::{jitter_fraction, Counts, Integrand, PixelRay};
use super::march::March;
use super::skip::MacroGrid;
use super::{IndexFrame, View};
use crate::parallel::map_chunks_mut;
use crate::sample::Field;
use crate::scene::Projection;

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
    /// Per-pass seed of the jittered first sample; `None` = no jitter.
    pub jitter: Option<u64>,
    /// The clipping planes that apply to the pass.
    pub clips: &'a [ClipPlane],
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
        let band = |band: usize, rows: &mut [f32]| {
            let mut counts = Counts::default();
            let j0 = band * TILE;
            let j1 = (j0 + TILE).min(height);
            for i0 in (0..width).step_by(TILE) {
                for j in j0..j1 {
                    for i in i0..(i0 + TILE).min(width) {
                        let (value, c) = self
                            .pixel(view, frame, i, j)
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

    #[inline]
    fn pixel(
        &self,
        view: &View,
        frame: &IndexFrame,
        i: usize,
        j: usize,
    ) -> Option<([f32; 4], Counts)> {
        let ray = view.pixel_ray(i, j);
        let index = frame.to_index(ray.origin, ray.dir);
        let t_min = match view.projection {
            Projection::Perspective => 0.0,
            Projection::Orthographic => f64::NEG_INFINITY,
        };
        let (t_box, t_exit) = frame.clip(&index, t_min)?;
        // depth is measured from the bounding sphere (or the box), whatever the cut
        let t_depth_ref = view.depth_reference(&ray).unwrap_or(t_box);
        let (t_enter, t_exit, cut) = if self.clips.is_empty() {
            (t_box, t_exit, None)
        } else {
            clip_ray(self.clips, ray.origin, ray.dir, (t_box, t_exit))?
        };
        let pixel_ray = PixelRay {
            origin: ray.origin,
            dir: ray.dir,
            index,
            t_enter,
            t_exit,
            t_depth_ref,
            cut,
        };
        let jitter = self.jitter.map_or(0.0, |seed| {
            let (e, f) = (view.eye, view.forward);
            jitter_fraction(seed, [e.x, e.y, e.z, f.x, f.y, f.z], i, j)
        });
        let march = March::jittered(t_enter, t_exit, self.dt, jitter);
        // the grid's ranges hold for this ray's samples (for every ray but those far
        // from a grid without the margin)
        let (o, d) = (index.o.to_array(), index.d.to_array());
        let grid = self.grid.filter(|g| g.bounds(o, d, t_enter, t_exit));
        Some(self.integrand.trace(&self.field, &pixel_ray, &march, grid))
    }
}
