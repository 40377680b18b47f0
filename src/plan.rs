//! The plan of a run: which views and passes will be rendered, what each pass must
//! precompute, and how much memory that takes. Built from the scene and the
//! volume's *header* (no voxels read), so `volcast check` can print it and a scene
//! that cannot be rendered is rejected before anything is loaded or written.
//!
//! Each pass computes only what it needs: a gradient volume only for composite
//! passes that shade or use a 2D transfer function with a grid estimator (surface
//! passes take gradients on the fly at their one hit per ray, and `gradient =
//! "analytic"` differentiates the spline on the fly), prefiltered coefficients only
//! for `cubic` interpolation, a transfer-function table only for composite passes, a
//! pre-integration table only for `preintegrated` composite passes (built for the
//! pass's step), and a preview pass for the grey window only for intensity modes
//! written as PNG without a fixed `window`. Exact passes (`integration = "exact"`)
//! precompute nothing: they walk the cells of the voxels themselves.

use std::fmt::Write as _;
use std::ops::Range;

use crate::error::Error;
use crate::output::Eye;
use crate::sample::{GradientMethod, Interpolation};
use crate::scene::Integration;
use crate::scene::{Format, Layout, Mode, Scene, Transfer};
use crate::transfer::{Preintegrated, COLOR_ENTRIES, INTEGRAL_ENTRIES};
use crate::volume::{human_bytes, VolumeHeader};

/// Entries of a 1D transfer-function table.
pub const TABLE_1D: usize = 4096;
/// Entries per axis of a 2D transfer-function table.
pub const TABLE_2D: usize = 256;

/// Options of a run that are not part of the scene.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Output folder instead of the scene's `out`.
    pub out: Option<std::path::PathBuf>,
    /// Frames to render (half-open), instead of all.
    pub frames: Option<Range<usize>>,
    /// Image size instead of the scene's (for previews and tests).
    pub size: Option<(usize, usize)>,
    /// Worker threads (`None` = one per core); reported in the plan.
    pub threads: Option<usize>,
    /// Render only this interleaved part of the frames (of `frames`, or of all).
    pub shard: Option<crate::batch::Shard>,
    /// Skip (pass, frame) images already written for the same scene (see
    /// `output::manifest`).
    pub resume: bool,
    /// Render every (frame, eye) image on its own even where stereo views coincide
    /// (the same bytes, more work; for comparisons).
    pub no_view_reuse: bool,
}

/// What a pass needs before its first ray.
#[derive(Clone, Debug, PartialEq)]
pub struct PassPlan {
    /// Sample spacing in world units.
    pub dt: f64,
    /// Gradient volume to precompute (3 x f32 per voxel), if any.
    pub gradient_volume: Option<GradientMethod>,
    /// Whether the pass samples prefiltered cubic coefficients.
    pub cubic: bool,
    /// Transfer-function table entries, if any.
    pub table_entries: Option<usize>,
    /// Bytes of the pre-integration table (pre-integrated composite passes only).
    pub preintegrated_bytes: Option<u64>,
    /// Whether the grey window comes from a preview pass.
    pub auto_window: bool,
}

/// The plan of a run.
#[derive(Clone, Debug)]
pub struct Plan {
    /// The range of frames selected (`--frames`, or all).
    pub frames: Range<usize>,
    /// The shard of that range this run renders, if any.
    pub shard: Option<crate::batch::Shard>,
    /// Frames to render, in order: the range, or the shard's part of it.
    pub frame_list: Vec<usize>,
    /// The views of the orbit: eye placement and which views coincide.
    pub views: crate::views::Views,
    /// The eyes of each frame and their azimuth offsets (degrees).
    pub eyes: Vec<(Eye, f64)>,
    /// Image size of one view.
    pub width: usize,
    /// Image size of one view.
    pub height: usize,
    /// Output folder.
    pub out: std::path::PathBuf,
    /// One entry per scene pass.
    pub passes: Vec<PassPlan>,
    /// Size of the preview used for automatic grey windows.
    pub preview: (usize, usize),
    /// World length of one voxel of the smallest spacing.
    pub voxel_length: f64,
    /// Bytes of the voxels.
    pub volume_bytes: u64,
    /// Bytes of all precomputed volumes and tables.
    pub precomputed_bytes: u64,
    /// Bytes of the films in flight (one per thread, at most).
    pub film_bytes: u64,
    /// Worker threads assumed for the estimate.
    pub threads: usize,
    /// Rough number of field samples (ray length x pixels / step, upper bound).
    pub samples_estimate: f64,
}

impl Plan {
    /// Plans `scene` for a volume described by `header`.
    pub fn build(scene: &Scene, header: &VolumeHeader, opts: &RunOptions) -> Result<Plan, Error> {
        let fail = |message: String| Error::Plan {
            scene: scene.path.clone(),
            message,
        };
        let geometry = &header.geometry;
        if !geometry.is_valid() {
            return Err(fail(format!(
                "the volume {} has degenerate axes (space directions or spacings are zero, non-finite or coplanar)",
                header.source
            )));
        }
        if let Some(crop) = scene.volume.crop {
            for (a, (&[lo, hi], &n)) in crop.iter().zip(&header.sizes).enumerate() {
                if hi >= n {
                    return Err(fail(format!(
                        "volume.crop: the {} range [{lo}, {hi}] is outside the volume's {n} voxels (0..={})",
                        ["x", "y", "z"][a],
                        n - 1
                    )));
                }
                debug_assert!(lo <= hi, "checked by the scene resolver");
            }
        }
        let total = scene.orbit.frames;
        let frames = match &opts.frames {
            None => 0..total,
            Some(r) if r.start < r.end && r.end <= total => r.clone(),
            Some(r) => {
                return Err(fail(format!(
                    "frames {}..{} are not within the orbit's {total} frames (0..{total})",
                    r.start, r.end
                )))
            }
        };
        let eyes = match &scene.stereo {
            None => vec![(Eye::Mono, 0.0)],
            Some(s) if s.method == crate::scene::StereoMethod::ToeIn => vec![
                (Eye::Left, -s.angle_deg / 2.0),
                (Eye::Right, s.angle_deg / 2.0),
            ],
            Some(_) => vec![(Eye::Left, 0.0), (Eye::Right, 0.0)],
        };
        let views = crate::views::Views::new(scene, !opts.no_view_reuse);
        let frame_list = match opts.shard {
            Some(shard) => shard.select(frames.clone()),
            None => frames.clone().collect(),
        };
        let (width, height) = opts.size.unwrap_or((scene.image.width, scene.image.height));
        if let Some(a) = &scene.animation {
            let file_width = match scene.stereo {
                Some(s) if matches!(s.layout, Layout::SideBySide | Layout::CrossEyed) => {
                    2 * width + s.gap
                }
                _ => width,
            };
            if a.formats.contains(&crate::scene::AnimationFormat::Gif)
                && file_width.max(height) > usize::from(u16::MAX)
            {
                return Err(fail(format!(
                    "[animation] gif: GIF images are at most 65535 pixels wide and high, these frames are {file_width} x {height} (use formats = [\"apng\"] or a smaller size)"
                )));
            }
        }
        let voxel_length = geometry
            .spacings()
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        let voxels = header.voxel_count() as u64;
        let mut gradient_methods = Vec::new();
        let mut cubic = false;
        let mut table_bytes = 0u64;
        let passes: Vec<PassPlan> = scene
            .passes
            .iter()
            .map(|p| {
                let (gradient_volume, table_entries) = match &p.mode {
                    Mode::Composite {
                        transfer, shading, ..
                    } => {
                        let two_d = matches!(transfer, Transfer::TwoD(_));
                        // analytic gradients come from the spline on the fly
                        let g = (shading.is_some() || two_d)
                            .then(|| {
                                shading
                                    .as_ref()
                                    .map_or(GradientMethod::Central, |s| s.gradient)
                            })
                            .filter(|g| *g != GradientMethod::Analytic);
                        (g, Some(if two_d { TABLE_2D * TABLE_2D } else { TABLE_1D }))
                    }
                    _ => (None, None),
                };
                if let Some(g) = gradient_volume {
                    if !gradient_methods.contains(&g) {
                        gradient_methods.push(g);
                    }
                }
                table_bytes += table_entries.map_or(0, |n| n as u64 * 16);
                let preintegrated_bytes = matches!(
                    p.mode,
                    Mode::Composite {
                        preintegrated: true,
                        ..
                    }
                )
                .then(Preintegrated::planned_bytes);
                table_bytes += preintegrated_bytes.unwrap_or(0);
                cubic |= p.interpolation == Interpolation::Cubic;
                PassPlan {
                    dt: p.step_voxels * voxel_length,
                    gradient_volume,
                    cubic: p.interpolation == Interpolation::Cubic,
                    table_entries,
                    preintegrated_bytes,
                    auto_window: p.mode.is_intensity()
                        && p.window.is_none()
                        && scene.image.format != Format::Nrrd,
                }
            })
            .collect();
        let precomputed_bytes = voxels
            .saturating_mul(12 * gradient_methods.len() as u64 + if cubic { 4 } else { 0 })
            .saturating_add(table_bytes);
        let threads = opts
            .threads
            .unwrap_or_else(rayon::current_num_threads)
            .max(1);
        let channels_max = scene
            .passes
            .iter()
            .map(|p| if p.mode.is_intensity() { 1 } else { 4 })
            .max()
            .unwrap_or(1);
        // Views kept for one batch of frames (plus those a reused toe-in eye keeps
        // for later frames), and display copies for the images being encoded.
        let kept_views = (crate::views::frames_per_batch(threads)
            + views.reuse_steps().map_or(0, |m| m.unsigned_abs() as usize))
            * eyes.len()
            * scene.passes.len();
        let film_bytes = (width * height) as u64
            * 4
            * (kept_views as u64 * channels_max as u64 + threads as u64 * eyes.len() as u64 * 3);
        let diagonal = {
            let c = geometry.corners(header.sizes);
            (c[7] - c[0]).length()
        };
        let samples_estimate: f64 = passes
            .iter()
            .map(|p| (diagonal / p.dt + 2.0) * (width * height) as f64)
            .sum::<f64>()
            * views.needed(frame_list.iter().copied()) as f64;
        let out = opts.out.clone().unwrap_or_else(|| scene.image.out.clone());
        Ok(Plan {
            frames,
            shard: opts.shard,
            frame_list,
            views,
            eyes,
            width,
            height,
            out,
            passes,
            preview: (width.div_ceil(4).max(8), height.div_ceil(4).max(8)),
            voxel_length,
            volume_bytes: header.data_bytes(),
            precomputed_bytes,
            film_bytes,
            threads,
            samples_estimate,
        })
    }

    /// Files written per frame and pass.
    pub fn files_per_frame(scene: &Scene) -> usize {
        match &scene.stereo {
            Some(s) if s.layout == Layout::Pair => 2,
            _ => 1,
        }
    }

    /// Total estimated memory.
    pub fn memory_bytes(&self) -> u64 {
        self.volume_bytes
            .saturating_add(self.precomputed_bytes)
            .saturating_add(self.film_bytes)
    }

    /// A human-readable description (what `volcast check` prints).
    pub fn describe(&self, scene: &Scene, header: &VolumeHeader) -> String {
        let mut s = String::new();
        let [nx, ny, nz] = header.sizes;
        let sp = header.geometry.spacings();
        let _ = writeln!(s, "scene    {}", scene.path.display());
        let _ = writeln!(
            s,
            "volume   {} ({nx} x {ny} x {nz} {}, spacing {:.4} {:.4} {:.4}, {})",
            header.source,
            header.scalar_type,
            sp[0],
            sp[1],
            sp[2],
            human_bytes(header.data_bytes())
        );
        match scene.volume.window {
            Some([lo, hi]) => {
                let _ = writeln!(s, "window   [{lo}, {hi}] -> [0, 1]");
            }
            None => {
                let _ = writeln!(
                    s,
                    "window   the data's min..max (read when the volume is loaded)"
                );
            }
        }
        if let Some(c) = scene.volume.crop {
            let _ = writeln!(
                s,
                "crop     x {}..={}, y {}..={}, z {}..={} (rays are clipped to this box)",
                c[0][0], c[0][1], c[1][0], c[1][1], c[2][0], c[2][1]
            );
        }
        let shard = match self.shard {
            Some(sh) => format!(", shard {sh}: {} frames", self.frame_list.len()),
            None => String::new(),
        };
        let _ = writeln!(
            s,
            "frames   {}..{} of {} ({} deg sweep, {:.3} deg per frame){shard}",
            self.frames.start,
            self.frames.end,
            scene.orbit.frames,
            scene.orbit.degrees,
            scene.orbit.degrees / scene.orbit.frames as f64
        );
        let _ = writeln!(s, "stereo   {}", crate::output::describe_stereo(scene));
        let _ = writeln!(s, "views    {}", self.views.describe(&self.frame_list));
        let _ = writeln!(
            s,
            "images   {} x {} {:?} -> {}/",
            self.width,
            self.height,
            scene.image.format,
            self.out.display()
        );
        let files = self.frame_list.len() * Self::files_per_frame(scene) * scene.passes.len();
        let _ = writeln!(s, "passes   {} ({files} files)", scene.passes.len());
        for (p, pp) in scene.passes.iter().zip(&self.passes) {
            let _ = writeln!(
                s,
                "  {:<12} {:<9} step {} voxels ({:.4} world), {}",
                p.name,
                p.mode.name(),
                p.step_voxels,
                pp.dt,
                p.interpolation.name()
            );
            let mut needs = Vec::new();
            if p.integration == Integration::Exact {
                needs.push(
                    "exact integration of the trilinear interpolant, cell by cell (no step)".into(),
                );
            }
            if p.jitter {
                needs.push("jittered first sample per pixel".into());
            }
            if let Some(g) = pp.gradient_volume {
                needs.push(format!("{} gradient volume", g.name()));
            }
            if let Some(sh) = p.mode.shading() {
                if sh.gradient == GradientMethod::Analytic {
                    needs.push(format!(
                        "analytic gradients of the {} spline, on the fly",
                        p.interpolation.name()
                    ));
                } else if pp.gradient_volume.is_none() {
                    needs.push(format!(
                        "{} gradients at the hit points",
                        sh.gradient.name()
                    ));
                }
                needs.push(
                    format!("{:?} shading, material {}", sh.model, sh.material_name).to_lowercase(),
                );
            }
            if pp.cubic {
                needs.push("prefiltered cubic coefficients".into());
            }
            if let (Some(n), Mode::Composite { transfer_name, .. }) = (pp.table_entries, &p.mode) {
                needs.push(format!("transfer table `{transfer_name}` ({n} entries)"));
            }
            if let Some(b) = pp.preintegrated_bytes {
                needs.push(format!(
                    "pre-integration table ({} integral entries, {}x{} segment colours for this step, {})",
                    INTEGRAL_ENTRIES + 1,
                    COLOR_ENTRIES,
                    COLOR_ENTRIES,
                    human_bytes(b)
                ));
            }
            if pp.auto_window {
                needs.push(format!(
                    "grey window from a {}x{} preview of every frame",
                    self.preview.0, self.preview.1
                ));
            } else if let Some([lo, hi]) = p.window {
                needs.push(format!("grey window [{lo}, {hi}]"));
            }
            if needs.is_empty() {
                needs.push("nothing precomputed".into());
            }
            let _ = writeln!(s, "               {}", needs.join("; "));
        }
        s.push_str(&crate::output::describe_outputs(scene, &self.out));
        let _ = writeln!(
            s,
            "memory   about {} (volume {}, precomputed {}, images in flight {} for {} threads)",
            human_bytes(self.memory_bytes()),
            human_bytes(self.volume_bytes),
            human_bytes(self.precomputed_bytes),
            human_bytes(self.film_bytes),
            self.threads
        );
        let _ = write!(s, "samples  at most about {:.3e}", self.samples_estimate);
        s
    }
}
