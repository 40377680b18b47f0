//! The plan of a run: which views and passes will be rendered, what each pass must
//! precompute, and how much memory that takes. Built from the scene and the
//! volume's *header* (no voxels read), so `volcast check` can print it and a scene
//! that cannot be rendered is rejected before anything is loaded or written.
//!
//! The plan is the one factory of render passes: each scene pass becomes a
//! [`RenderPass`], which says what it needs (see `render::pass`); the plan adds up
//! those needs, shared between passes (one gradient volume per estimator, one set of
//! cubic coefficients, one macrocell grid per kind), and nothing downstream decides
//! again. Each pass computes only what it needs: a gradient volume only for composite
//! passes that shade or use a 2D transfer function with a grid estimator (surface
//! passes take gradients on the fly at their one hit per ray, and `gradient =
//! "analytic"` differentiates the spline on the fly), prefiltered coefficients only
//! for `cubic` interpolation, a transfer-function table only for composite passes, a
//! pre-integration table only for `preintegrated` composite passes (built for the
//! pass's step), a macrocell grid for empty-space skipping (one per kind of filter
//! support), and a preview pass for the grey window only for intensity modes written
//! as PNG without a fixed `window`.

use std::fmt::Write as _;
use std::ops::Range;

use crate::error::Error;
use crate::mode::{Mode, NoteContext, PassContext};
use crate::output::manifest::SceneRecord;
use crate::output::Outputs;
use crate::render::footprint::Footprint;
use crate::render::pass::{GridSource, Sampling};
use crate::render::{ClipPlane, ImageKind, IndexFrame, RenderPass};
use crate::sample::{GradientMethod, PAIR_TABLE_BYTES};
use crate::scene::{
    Format, Integration, Layout, LightKindSpec, OrbitPath, Scene, Units, VolumeSpec,
};
use crate::shade::{Light, LightKind};
use crate::views::Eye;
use crate::volume::{human_bytes, VolumeHeader};

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
    /// March every sample of every ray instead of skipping empty space (the same
    /// images, slower; for comparisons).
    pub no_skip: bool,
    /// Render nothing: merge the manifest and assemble the animations from the images
    /// that exist, and report what is missing (`--finish-only`).
    pub finish_only: bool,
    /// The folder the volume's files and the output folder must lie in (`--confine`).
    pub confine: Option<std::path::PathBuf>,
    /// Write the turntable page `index.html` even if the scene has no `[viewer]`
    /// (`--viewer`).
    pub viewer: bool,
    /// Render into an output folder whose manifest is of another scene (`--force`);
    /// without it such a run is refused before anything is written.
    pub force: bool,
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
    /// Whether the run writes the turntable page `{out}/index.html` once every frame
    /// exists (`[viewer] html` or `--viewer`).
    pub viewer: bool,
    /// The volume's length unit (`space units` or `units` of its file, when every
    /// axis has the same one), for the scale bar.
    pub length_unit: Option<String>,
    /// One render pass per scene pass, in order.
    pub passes: Vec<RenderPass>,
    /// The passes as the frames render them: [`Plan::passes`] itself, unless
    /// keyframes animate pass values or clip offsets; then one variant per distinct
    /// set of values (see [`Plan::variant`]).
    pub variants: Vec<RenderPass>,
    /// Per pass, per frame of the orbit: its variant (`None`: pass `p` is variant `p`).
    variant_of: Option<Vec<Vec<usize>>>,
    /// Per pass: whether its grey window comes from a preview pass.
    pub auto_window: Vec<bool>,
    /// Per pass: its fixed grey window (`window`, normalised), if it has one.
    pub windows: Vec<Option<[f64; 2]>>,
    /// What the run writes around the rendered values (formats, overlays, stereo
    /// layout, animations, the page).
    pub output: Outputs,
    /// What the manifest records of the scene.
    pub scene: SceneRecord,
    /// The scene's volumes, in its order: where each one's voxels come from, where
    /// it sits, and which passes read it.
    pub volumes: Vec<PlannedVolume>,
    /// The bounding sphere of the volumes' boxes (what cameras frame): of the one
    /// box, or around the union of several.
    pub sphere: (glam::DVec3, f64),
    /// Size of the preview used for automatic grey windows.
    pub preview: (usize, usize),
    /// Bytes of the voxels volcast allocates (0 when they are mapped), of every
    /// volume a pass reads.
    pub volume_bytes: u64,
    /// Bytes of all precomputed volumes and tables.
    pub precomputed_bytes: u64,
    /// Bytes allocated only while the precomputations are built (the prefilter's
    /// double-precision copy).
    pub transient_bytes: u64,
    /// Bytes of the films in flight (one per thread, at most).
    pub film_bytes: u64,
    /// Bytes of the grey-window previews (every distinct view of the orbit at the
    /// preview size, kept until the window is known).
    pub preview_bytes: u64,
    /// Bytes of images being laid out and encoded (one per thread).
    pub output_bytes: u64,
    /// Bytes at the peak of assembling the animations (after rendering).
    pub animation_bytes: u64,
    /// The estimate, item by item: what, and bytes (what `--max-memory` is checked
    /// against; see [`Plan::check_memory`]).
    pub memory: Vec<(String, u64)>,
    /// Worker threads assumed for the estimate.
    pub threads: usize,
    /// Rough number of field samples (ray length x pixels / step, upper bound).
    pub samples_estimate: f64,
    /// The normalised value whose voxels `zoom = "fit"` frames (`None`: the scene
    /// has a zoom of its own).
    pub fit_threshold: Option<f64>,
}

/// One volume of a run, planned from its header.
#[derive(Clone, Debug)]
pub struct PlannedVolume {
    /// Its name (`[[volume]] name`).
    pub name: String,
    /// Where its voxels come from, their value window and units, and the crop.
    pub spec: VolumeSpec,
    /// Its header, its geometry moved by the scene's `transform` (where it sits in
    /// the world).
    pub header: VolumeHeader,
    /// Its box in index space and the map to it (rays are clipped to it).
    pub frame: IndexFrame,
    /// Where its voxels come from: mapped from a file, or read into memory.
    pub storage: crate::volume::Storage,
    /// The passes that read it (indices into the plan's passes); none: it is not
    /// loaded.
    pub passes: Vec<usize>,
}

impl PlannedVolume {
    /// Whether a pass reads it (else it is not loaded).
    pub fn is_read(&self) -> bool {
        !self.passes.is_empty()
    }

    /// World length of one voxel of its smallest spacing.
    pub fn voxel_length(&self) -> f64 {
        self.header
            .geometry
            .spacings()
            .into_iter()
            .fold(f64::INFINITY, f64::min)
    }
}

/// The headers of the scene's volumes as the run places them: each one's geometry
/// moved by its `transform`.
pub fn placed_headers(scene: &Scene, headers: Vec<VolumeHeader>) -> Vec<VolumeHeader> {
    headers
        .into_iter()
        .zip(&scene.volumes)
        .map(|(mut h, v)| {
            if let Some(t) = v.transform {
                h.geometry = t.place(&h.geometry);
            }
            h
        })
        .collect()
}

impl Plan {
    /// The variant of pass `p` that frame `k` renders (an index into
    /// [`Plan::variants`]).
    pub fn variant(&self, p: usize, k: usize) -> usize {
        self.variant_of.as_ref().map_or(p, |v| v[p][k])
    }

    /// Plans `scene` for volumes described by `headers` (the files' headers, in the
    /// order of the scene's volumes; each is placed by its `transform` here).
    pub fn build(
        scene: &Scene,
        headers: &[VolumeHeader],
        opts: &RunOptions,
    ) -> Result<Plan, Error> {
        let (width, height) = opts.size.unwrap_or((scene.image.width, scene.image.height));
        let headers = placed_headers(scene, headers.to_vec());
        let plan_err = |message| Error::Plan {
            scene: scene.path.clone(),
            message,
        };
        let frames = check(scene, &headers, opts, (width, height)).map_err(plan_err)?;
        let mut volumes = Vec::with_capacity(headers.len());
        for (v, header) in scene.volumes.iter().zip(headers) {
            let storage = v.spec.source.storage()?;
            let index_from_world = header
                .geometry
                .index_from_world_matrix()
                .expect("checked by is_valid in check");
            let frame = IndexFrame::new(
                header.sizes,
                v.spec.crop,
                &header.geometry,
                index_from_world,
            );
            volumes.push(PlannedVolume {
                name: v.name.clone(),
                spec: v.spec.clone(),
                header,
                frame,
                storage,
                passes: Vec::new(),
            });
        }
        for (p, pass) in scene.passes.iter().enumerate() {
            for &k in &pass.volumes {
                volumes[k].passes.push(p);
            }
        }
        let sphere = bounding_sphere(&volumes);
        let passes = render_passes(scene, &volumes, sphere, opts);
        let (variants, variant_of) = pass_variants(scene, &passes);
        let auto_window = scene
            .passes
            .iter()
            .zip(&passes)
            .map(|(p, rp)| {
                rp.kind() != ImageKind::Rgba
                    && p.window.is_none()
                    && scene.image.format != Format::Nrrd
            })
            .collect();
        let frame_list = match opts.shard {
            Some(shard) => shard.select(frames.clone()),
            None => frames.clone().collect(),
        };
        let mut plan = Plan {
            frames,
            shard: opts.shard,
            frame_list,
            views: crate::views::Views::new(scene, !opts.no_view_reuse),
            eyes: eyes(scene),
            width,
            height,
            out: opts.out.clone().unwrap_or_else(|| scene.image.out.clone()),
            viewer: scene.viewer || opts.viewer,
            length_unit: length_unit(&volumes[0].header),
            passes,
            variants,
            variant_of,
            auto_window,
            windows: scene.passes.iter().map(|p| p.window).collect(),
            output: Outputs::of_scene(scene),
            scene: SceneRecord::new(scene, &headers_of(&volumes), width, height),
            volume_bytes: volumes
                .iter()
                .filter(|v| v.is_read())
                .map(|v| v.storage.allocated_bytes())
                .sum(),
            volumes,
            sphere,
            preview: (width.div_ceil(4).max(8), height.div_ceil(4).max(8)),
            precomputed_bytes: 0,
            transient_bytes: 0,
            film_bytes: 0,
            preview_bytes: 0,
            output_bytes: 0,
            animation_bytes: 0,
            memory: Vec::new(),
            threads: opts
                .threads
                .unwrap_or_else(rayon::current_num_threads)
                .max(1),
            samples_estimate: 0.0,
            fit_threshold: fit_threshold(scene),
        };
        plan.check_views().map_err(|message| Error::Plan {
            scene: scene.path.clone(),
            message,
        })?;
        plan.estimate(scene);
        Ok(plan)
    }

    /// The frame of the volume pass `p` reads (a blend's first; its view renders
    /// over every volume's own).
    pub fn frame_of(&self, p: &RenderPass) -> &IndexFrame {
        &self.volumes[p.volume()].frame
    }

    /// Refuses views the renderer cannot compute: it marches in f32, so every eye
    /// position, direction and image extent must be finite there, and the extent
    /// not so small that it vanishes (a camera far beyond the volume, or a zoom
    /// near the f64 limits). Checked for the frames this run renders and the frames
    /// keyframes set (what every other frame's camera is interpolated from, and
    /// what an automatic grey window previews), with the zoom `fit` finds checked
    /// again once it is known.
    pub(crate) fn check_views(&self) -> Result<(), String> {
        let f32_ok = |x: f64| (x as f32).is_finite();
        let keyed = self.views.keyed_frames();
        for &k in self.frame_list.iter().chain(&keyed) {
            for &e in self.views.eyes() {
                let v = self
                    .views
                    .view(self.views.key(k, e), self.width, self.height, self.sphere);
                let vectors = [v.eye, v.forward, v.right, v.up];
                let finite = vectors.iter().all(|a| a.to_array().into_iter().all(f32_ok))
                    && [v.distance, v.shift].into_iter().all(f32_ok);
                let extent = [v.half_width, v.half_height]
                    .into_iter()
                    .all(|x| (x as f32).is_normal());
                if !(finite && extent) {
                    let eye = v.eye.to_array().map(|x| format!("{x:e}")).join(", ");
                    return Err(format!(
                        "frame {k}: the camera cannot be rendered: its eye is at [{eye}] and its image {:e} wide (half width), beyond what the renderer computes in (32-bit floats: magnitudes from about 1e-38 to 3.4e38): check [camera] target, distance and zoom, and the keyframes",
                        v.half_width
                    ));
                }
            }
        }
        Ok(())
    }

    /// Fills in the estimates: memory, item by item, and samples.
    fn estimate(&mut self, scene: &Scene) {
        let several = self.volumes.len() > 1;
        let mut items: Vec<(String, u64)> = Vec::new();
        let (mut bytes, mut transient) = (0u64, 0u64);
        for (k, v) in self.volumes.iter().enumerate() {
            if !v.is_read() {
                continue;
            }
            let of = |what: String| {
                if several {
                    format!("volume `{}`: {what}", v.name)
                } else {
                    what
                }
            };
            let header = &v.header;
            let voxels = header.voxel_count() as u64;
            let pre = self.precomputations(k);
            bytes = bytes.saturating_add(pre.bytes);
            transient = transient.saturating_add(pre.transient);
            if let crate::volume::Storage::Read { bytes, reason } = &v.storage {
                let what = if several {
                    format!("read into memory ({reason})")
                } else {
                    format!("volume, read into memory ({reason})")
                };
                items.push((of(what), *bytes));
            }
            for g in &pre.gradient_methods {
                items.push((
                    of(format!("{} gradient volume (3 floats per voxel)", g.name())),
                    voxels.saturating_mul(12),
                ));
            }
            if pre.cubic {
                items.push((
                    of("cubic B-spline coefficients (a float per voxel)".into()),
                    voxels.saturating_mul(4),
                ));
                items.push((
                    of("cubic prefilter while it runs (two double-precision copies)".into()),
                    pre.transient,
                ));
            }
            if pre.small > 0 {
                items.push((
                    of(
                        "macrocell grids and their footprints, transfer-function and lookup tables"
                            .into(),
                    ),
                    pre.small,
                ));
            }
        }
        self.precomputed_bytes = bytes;
        self.transient_bytes = transient;
        self.estimate_images(scene);
        // the longest ray: through the box of every volume a pass reads
        let diagonal = self
            .volumes
            .iter()
            .map(|v| {
                let c = v.header.geometry.corners(v.header.sizes);
                (c[7] - c[0]).length()
            })
            .fold(0.0, f64::max);
        self.samples_estimate = self
            .passes
            .iter()
            .map(|p| {
                let parts = p.reads().len() as f64;
                (diagonal / p.dt + 2.0) * parts * (self.width * self.height) as f64
            })
            .sum::<f64>()
            * self.views.needed(self.frame_list.iter().copied()) as f64;
        let memory = &mut self.memory;
        memory.append(&mut items);
        memory.push((
            format!(
                "rendered images in flight ({} x {}, {} threads)",
                self.width, self.height, self.threads
            ),
            self.film_bytes,
        ));
        if self.preview_bytes > 0 {
            memory.push((
                "grey-window previews (one per thread) and every view's range".into(),
                self.preview_bytes,
            ));
        }
        memory.push(("images being encoded and written".into(), self.output_bytes));
    }

    /// What the passes precompute over volume `k`, shared between them and each
    /// counted once.
    fn precomputations(&self, k: usize) -> Precomputations {
        let header = &self.volumes[k].header;
        let voxels = header.voxel_count() as u64;
        let passes: Vec<&RenderPass> = self
            .passes
            .iter()
            .flat_map(|p| p.reads())
            .filter(|(v, _)| *v == k)
            .map(|(_, p)| p)
            .collect();
        let mut gradient_methods: Vec<_> = passes
            .iter()
            .filter_map(|p| p.needs().gradient_volume)
            .collect();
        gradient_methods.sort_by_key(|g| g.name());
        gradient_methods.dedup();
        let cubic = passes.iter().any(|p| p.needs().coefficients);
        let mut grids: Vec<GridSource> = passes.iter().filter_map(|p| p.needs().grid).collect();
        grids.sort();
        grids.dedup();
        let pair_bytes = if passes.iter().any(|p| p.needs().voxel_pairs()) {
            PAIR_TABLE_BYTES
        } else {
            0
        };
        let lut_bytes = header.scalar_type.lut_size() as u64 * 4 + pair_bytes;
        // at most: the macrocells a skipping pass cannot pass over, as boxes, and per
        // view being rendered the windows of its tiles' rays (render/footprint.rs;
        // only the passes whose skipping is fixed build them)
        let footprint_bytes = passes.iter().filter(|p| p.needs().grid.is_some()).count() as u64
            * Footprint::max_bytes(header.sizes, self.width, self.height, self.threads);
        let table_bytes: u64 = passes
            .iter()
            .map(|p| p.table_bytes(header.sizes))
            .sum::<u64>()
            .saturating_add(footprint_bytes);
        let grid_bytes = grids
            .iter()
            .map(|g| g.grid_bytes(header.sizes))
            .sum::<u64>();
        let small = grid_bytes
            .saturating_add(table_bytes)
            .saturating_add(lut_bytes);
        // The prefilter works in double precision on a copy of the volume and gathers
        // the z lines into a second copy (plus a small header per line).
        let transient = if cubic {
            voxels.saturating_mul(16).saturating_add(
                (header.sizes[0] as u64).saturating_mul(header.sizes[1] as u64 * 48),
            )
        } else {
            0
        };
        Precomputations {
            bytes: voxels
                .saturating_mul(12 * gradient_methods.len() as u64 + if cubic { 4 } else { 0 })
                .saturating_add(small),
            transient,
            small,
            gradient_methods,
            cubic,
        }
    }

    /// Fills in the bytes of the images: rendered, previewed, encoded and animated.
    fn estimate_images(&mut self, scene: &Scene) {
        let threads = self.threads as u64;
        let eyes = self.eyes.len();
        let channels_max = self.passes.iter().map(|p| p.channels()).max().unwrap_or(1);
        // Views kept for two batches of frames, one being written while the next
        // renders (plus those a reused toe-in eye keeps for later frames), and
        // display copies for the images being encoded.
        let kept_views = (2 * crate::views::frames_per_batch(self.threads)
            + self
                .views
                .reuse_steps()
                .map_or(0, |m| m.unsigned_abs() as usize))
        .min(self.frame_list.len().max(1))
            * eyes
            * scene.passes.len();
        let pixels = self.width as u64 * self.height as u64;
        self.film_bytes = pixels.saturating_mul(
            4 * (kept_views as u64 * channels_max as u64 + threads * eyes as u64 * 3),
        );
        // what the files hold: one image, or both eyes side by side
        let file_pixels = match scene.stereo {
            Some(s) if matches!(s.layout, Layout::SideBySide | Layout::CrossEyed) => {
                (2 * self.width as u64 + s.gap as u64) * self.height as u64
            }
            _ => pixels,
        };
        let combined = scene.stereo.is_some_and(|s| s.layout != Layout::Pair);
        // per thread writing a frame: the quantised samples and the encoded file (or
        // the NRRD's float samples and its text) and the file's aligned copy for a
        // direct write (`output::write`), and a combined stereo picture
        let per_file = match scene.image.format {
            Format::Nrrd => file_pixels.saturating_mul(12 * channels_max as u64),
            _ => file_pixels.saturating_mul(24),
        };
        self.output_bytes = threads.saturating_mul(per_file.saturating_add(if combined {
            file_pixels.saturating_mul(16)
        } else {
            0
        }));
        self.preview_bytes = if self.auto_window.iter().any(|&a| a) {
            let (w, h) = self.preview;
            // a preview per thread, and each view of the orbit's key and range
            let orbit_views = self.views.needed(0..scene.orbit.frames) as u64;
            ((w * h) as u64)
                .saturating_mul(4 * threads)
                .saturating_add(64 * orbit_views)
        } else {
            0
        };
        // animations: a batch of decoded frames (8 bytes per pixel at most) and, for
        // GIF, a frame being quantised per thread
        self.animation_bytes = if scene.animation.is_some() {
            file_pixels.saturating_mul(8 * 3 * threads)
        } else {
            0
        };
    }

    /// Files written per frame and pass.
    pub fn files_per_frame(scene: &Scene) -> usize {
        match &scene.stereo {
            Some(s) if s.layout == Layout::Pair => 2,
            _ => 1,
        }
    }

    /// Total estimated memory at its peak: everything of [`Plan::memory`] at once
    /// (an upper bound: the prefilter's copies are freed before rendering), or the
    /// animations' assembly after the images are written, if that is more.
    pub fn memory_bytes(&self) -> u64 {
        let render = self
            .memory
            .iter()
            .fold(0u64, |a, (_, b)| a.saturating_add(*b));
        let animate = self
            .volume_bytes
            .saturating_add(self.precomputed_bytes)
            .saturating_add(self.animation_bytes);
        render.max(animate)
    }

    /// An error, before anything is read, allocated or written, if the run's
    /// estimated memory ([`Plan::memory_bytes`]) exceeds `limits.max_bytes`
    /// (`--max-memory`); the message lists the estimate item by item.
    pub fn check_memory(&self, limits: &crate::volume::Limits) -> Result<(), Error> {
        let need = self.memory_bytes();
        if need <= limits.max_bytes {
            return Ok(());
        }
        let mut items: Vec<(String, u64)> = self.memory.clone();
        if self.animation_bytes > 0 {
            items.push((
                "assembling the animations (after rendering)".into(),
                self.animation_bytes,
            ));
        }
        let width = items
            .iter()
            .map(|(w, _)| w.chars().count())
            .max()
            .unwrap_or(0);
        let mut list = String::new();
        for (what, bytes) in &items {
            let _ = write!(list, "\n  {what:<width$}  {:>10}", human_bytes(*bytes));
        }
        let want = need as f64 * 1.1;
        let suggest = if want < (1u64 << 30) as f64 {
            format!("{}M", (want / (1u64 << 20) as f64).ceil())
        } else {
            format!("{}G", (want / (1u64 << 30) as f64).ceil())
        };
        Err(Error::Plan {
            scene: self.scene.file.clone(),
            message: format!(
                "this run needs about {} of memory, more than the {} allowed by --max-memory:{list}\n\
                 raise the limit (e.g. --max-memory {suggest}) if the machine has the memory, or need less: \
                 smaller images (--size), gradients computed at the hit points instead of a gradient volume, \
                 trilinear instead of cubic interpolation, or a raw volume in native byte order (mapped, not read)",
                human_bytes(need),
                human_bytes(limits.max_bytes),
            ),
        })
    }

    /// A human-readable description (what `volcast check` prints).
    pub fn describe(&self, scene: &Scene) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "scene    {}", scene.path.display());
        if let [one] = self.volumes.as_slice() {
            describe_volume(&mut s, one);
        } else {
            self.describe_volumes(&mut s, scene);
        }
        self.describe_frames(&mut s, scene);
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
        for ((p, rp), &auto) in scene.passes.iter().zip(&self.passes).zip(&self.auto_window) {
            let _ = writeln!(
                s,
                "  {:<12} {:<9} step {} voxels ({:.4} world), {}",
                p.name,
                p.mode.name(),
                p.step_voxels,
                rp.dt,
                p.interpolation.name()
            );
            for n in self.pass_notes(scene, p, rp, auto) {
                let _ = writeln!(s, "               {n}");
            }
        }
        s.push_str(&crate::output::describe_outputs(
            scene,
            &self.out,
            self.viewer,
        ));
        self.describe_memory(&mut s);
        s
    }

    /// The frames line of [`Plan::describe`] (and the zoom's, when it fits).
    fn describe_frames(&self, s: &mut String, scene: &Scene) {
        let shard = match self.shard {
            Some(sh) => format!(", shard {sh}: {} frames", self.frame_list.len()),
            None => String::new(),
        };
        let o = &scene.orbit;
        let path = match o.path {
            OrbitPath::Circle => format!(
                "{} deg sweep, {:.3} deg per frame",
                o.degrees,
                o.degrees / o.frames as f64
            ),
            OrbitPath::Rock => format!(
                "rock: the azimuth swings {} deg, {} +- {} sinusoidally",
                o.degrees,
                scene.camera.azimuth_deg,
                o.degrees / 2.0
            ),
            OrbitPath::Elevation { lo, hi } => {
                format!(
                    "elevation: swings from {lo} deg up to {hi} deg at the middle frame and back"
                )
            }
            OrbitPath::Keyframes => describe_keyframes(scene),
        };
        let _ = writeln!(
            s,
            "frames   {}..{} of {} ({path}){shard}",
            self.frames.start, self.frames.end, o.frames,
        );
        if let Some(t) = self.fit_threshold {
            let _ = writeln!(
                s,
                "zoom     \"fit\": frames the voxels at or above {t} (normalised) in every frame; computed when the voxels are loaded"
            );
        }
    }

    /// What [`Plan::describe`] says under the line of pass `p` (`rp` its render
    /// pass): the value it looks for, what it precomputes, its clip planes,
    /// material, grey window and colour map.
    fn pass_notes(
        &self,
        scene: &Scene,
        p: &crate::scene::RenderPass,
        rp: &RenderPass,
        auto: bool,
    ) -> Vec<String> {
        let units = self.volumes[rp.volume()].spec.units;
        let mut needs = self.mode_notes(units, p);
        if self.volumes.len() > 1 && rp.parts().is_empty() {
            needs.push(format!("reads volume `{}`", self.volumes[rp.volume()].name));
        }
        needs.extend(rp.describe(self.volumes[rp.volume()].header.sizes));
        if !rp.parts().is_empty() {
            let names: Vec<String> = p
                .volumes
                .iter()
                .map(|&k| format!("`{}`", self.volumes[k].name))
                .collect();
            needs.push(format!(
                "blends volumes {} at each sample: opacity 1 - prod(1 - a_i), colour sum(a_i c_i) / sum(a_i); each shaded with its own gradient",
                names.join(", ")
            ));
            for (i, (k, part)) in rp.parts().iter().enumerate() {
                let v = &self.volumes[*k];
                let tf = p
                    .mode
                    .part(i)
                    .and_then(|m| m.transfer().map(|(n, _)| format!(" through `{n}`")))
                    .unwrap_or_default();
                let what = part.describe(v.header.sizes).join("; ");
                needs.push(format!("volume `{}`{tf}: {what}", v.name));
            }
        }
        for (k, c) in scene.clips.iter().enumerate() {
            if c.applies_to(&p.name) {
                let mut line = describe_clip(k, c, &*p.mode);
                if scene
                    .keyframes
                    .as_ref()
                    .is_some_and(|kf| kf.clip_offsets.iter().any(|(q, _)| *q == k))
                {
                    line.push_str("; its offset is keyframed");
                }
                needs.push(line);
            }
        }
        if let Some(sh) = p.mode.shading() {
            needs.push(format!("material {}", sh.material_name));
        }
        if auto {
            needs.push(format!(
                "grey window from a {}x{} preview of every frame",
                self.preview.0, self.preview.1
            ));
        } else if let (Some([lo, hi]), false) = (p.window, rp.kind() == ImageKind::Rgba) {
            if p.mode.window_in_values() && units != Units::Normalised {
                needs.push(format!(
                    "grey window [{lo}, {hi}] (data values [{}, {}])",
                    units.show(lo),
                    units.show(hi)
                ));
            } else {
                needs.push(format!("grey window [{lo}, {hi}]"));
            }
        }
        if let (Some(map), true) = (p.colormap, scene.image.format != Format::Nrrd) {
            needs.push(format!(
                "colour map {}: the windowed grey level {} (PNG in RGB; rays without a value show the background)",
                map.name(),
                if rp.kind() == ImageKind::Depth {
                    "(near bright) through it"
                } else {
                    "through it"
                }
            ));
        }
        if needs.is_empty() {
            needs.push("nothing precomputed".into());
        }
        needs
    }

    /// What [`Plan::describe`] says of a pass's mode: the threshold or iso value it
    /// looks for (normalised and, under `units = "data"`, as written), and a MIP's
    /// depth cue and output.
    fn mode_notes(&self, units: Units, p: &crate::scene::RenderPass) -> Vec<String> {
        let both = |t: f64| match units {
            Units::Data { .. } => format!("{t} (data value {})", units.show(t)),
            Units::Normalised => format!("{t}"),
        };
        p.mode.notes(&NoteContext {
            show: &both,
            sphere_diameter: 2.0 * self.sphere.1,
            window: p.window,
        })
    }

    /// The memory and samples lines of [`Plan::describe`].
    fn describe_memory(&self, s: &mut String) {
        let mut parts: Vec<String> = Vec::new();
        for v in self.volumes.iter().filter(|v| v.is_read()) {
            if let crate::volume::Storage::Mapped { path, bytes, .. } = &v.storage {
                parts.push(format!(
                    "volume mapped, not allocated: {} of {}",
                    human_bytes(*bytes),
                    path.display()
                ));
            }
        }
        parts.extend(
            self.memory
                .iter()
                .map(|(what, b)| format!("{what} {}", human_bytes(*b))),
        );
        if self.animation_bytes > 0 {
            parts.push(format!(
                "then {} to assemble the animations",
                human_bytes(self.animation_bytes)
            ));
        }
        let _ = writeln!(
            s,
            "memory   about {} at the peak, checked against --max-memory ({})",
            human_bytes(self.memory_bytes()),
            parts.join("; ")
        );
        let _ = write!(s, "samples  at most about {:.3e}", self.samples_estimate);
    }
}

/// The volume, value, window and crop lines of [`Plan::describe`] for a scene of
/// one volume.
fn describe_volume(s: &mut String, v: &PlannedVolume) {
    let header = &v.header;
    let [nx, ny, nz] = header.sizes;
    let sp = header.geometry.spacings();
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
    describe_values(s, v, "");
}

/// The rescale, window and crop lines of a volume (`indent` before each).
fn describe_values(s: &mut String, v: &PlannedVolume, indent: &str) {
    let header = &v.header;
    if !header.rescale.is_identity() {
        let _ = writeln!(
            s,
            "{indent}values   {} * stored + {} (the volume's rescale, folded into the window: windows are values)",
            header.rescale.slope, header.rescale.intercept
        );
    }
    match v.spec.window {
        Some([lo, hi]) => {
            let units = match v.spec.units {
                Units::Data { .. } => " (units = \"data\": the scene's values are data values)",
                Units::Normalised => "",
            };
            let _ = writeln!(s, "{indent}window   [{lo}, {hi}] -> [0, 1]{units}");
        }
        None => {
            let _ = writeln!(
                s,
                "{indent}window   the data's min..max (read when the volume is loaded)"
            );
        }
    }
    if let Some(c) = v.spec.crop {
        let _ = writeln!(
            s,
            "{indent}crop     x {}..={}, y {}..={}, z {}..={} (rays are clipped to this box)",
            c[0][0], c[0][1], c[1][0], c[1][1], c[2][0], c[2][1]
        );
    }
}

impl Plan {
    /// The volumes lines of [`Plan::describe`] for a scene of several: each one's
    /// file, box in world units, memory and the passes that read it.
    fn describe_volumes(&self, s: &mut String, scene: &Scene) {
        let _ = writeln!(s, "volumes  {}", self.volumes.len());
        for (v, sv) in self.volumes.iter().zip(&scene.volumes) {
            let header = &v.header;
            let [nx, ny, nz] = header.sizes;
            let corners = header.geometry.box_corners(v.frame.lo, v.frame.hi);
            let lo = corners.iter().fold(glam::DVec3::INFINITY, |a, &c| a.min(c));
            let hi = corners
                .iter()
                .fold(glam::DVec3::NEG_INFINITY, |a, &c| a.max(c));
            let memory = match &v.storage {
                crate::volume::Storage::Read { bytes, .. } => {
                    format!("{} read into memory", human_bytes(*bytes))
                }
                crate::volume::Storage::Mapped { bytes, .. } => {
                    format!("{} mapped", human_bytes(*bytes))
                }
            };
            let read: Vec<String> = v
                .passes
                .iter()
                .map(|&p| format!("`{}`", scene.passes[p].name))
                .collect();
            let read = if read.is_empty() {
                "read by no pass: not loaded".to_string()
            } else {
                format!("read by {}", read.join(", "))
            };
            let _ = writeln!(
                s,
                "  {:<12} {} ({nx} x {ny} x {nz} {}, {memory}), {read}",
                v.name, header.source, header.scalar_type
            );
            let _ = writeln!(
                s,
                "               box x {:.4}..{:.4}, y {:.4}..{:.4}, z {:.4}..{:.4} (world){}",
                lo.x,
                hi.x,
                lo.y,
                hi.y,
                lo.z,
                hi.z,
                if sv.transform.is_some() {
                    ", moved by its transform"
                } else {
                    ""
                }
            );
            describe_values(s, v, "               ");
        }
    }
}

/// The headers of the plan's volumes, in order.
fn headers_of(volumes: &[PlannedVolume]) -> Vec<VolumeHeader> {
    volumes.iter().map(|v| v.header.clone()).collect()
}

/// The sphere cameras frame: around the one volume's box (its circumsphere), or
/// around the union of several boxes (centred on the box of all their corners,
/// through the farthest corner).
fn bounding_sphere(volumes: &[PlannedVolume]) -> (glam::DVec3, f64) {
    if let [one] = volumes {
        return one.frame.bounding_sphere(&one.header.geometry);
    }
    let corners: Vec<glam::DVec3> = volumes
        .iter()
        .flat_map(|v| v.header.geometry.box_corners(v.frame.lo, v.frame.hi))
        .collect();
    let lo = corners.iter().fold(glam::DVec3::INFINITY, |a, &c| a.min(c));
    let hi = corners
        .iter()
        .fold(glam::DVec3::NEG_INFINITY, |a, &c| a.max(c));
    let centre = 0.5 * (lo + hi);
    let radius = corners
        .iter()
        .map(|&c| (c - centre).length())
        .fold(0.0, f64::max);
    (centre, radius)
}

/// What `check` says of a scene's keyframes.
fn describe_keyframes(scene: &Scene) -> String {
    let Some(kf) = &scene.keyframes else {
        return "keyframes".into();
    };
    let mut what: Vec<String> = Vec::new();
    for (name, ch) in [
        ("azimuth", &kf.azimuth),
        ("elevation", &kf.elevation),
        ("zoom", &kf.zoom),
        ("distance", &kf.distance),
    ] {
        if ch.is_some() {
            what.push(name.into());
        }
    }
    if kf.target.is_some() {
        what.push("target".into());
    }
    for (p, _) in &kf.pass_values {
        let key = scene.passes[*p].mode.level().map_or("threshold", |l| l.key);
        what.push(format!("render.{}.{key}", scene.passes[*p].name));
    }
    for (c, _) in &kf.clip_offsets {
        what.push(format!(
            "clip.{}.offset",
            scene.clips[*c].name.as_deref().unwrap_or("?")
        ));
    }
    let frames: Vec<String> = kf.frames.iter().map(|f| f.to_string()).collect();
    format!(
        "keyframes at frames {}, {} interpolation, held before the first and after the last; animated: {}",
        frames.join(", "),
        if kf.smooth { "Catmull-Rom (smooth)" } else { "linear" },
        if what.is_empty() {
            "nothing".to_string()
        } else {
            what.join(", ")
        }
    )
}

/// What the passes of a plan precompute ([`Plan::precomputations`]).
struct Precomputations {
    /// Bytes of every precomputed volume and table.
    bytes: u64,
    /// Bytes allocated only while the cubic prefilter runs.
    transient: u64,
    /// Bytes of the grids, their footprints and the tables.
    small: u64,
    /// The gradient volumes, one per estimator.
    gradient_methods: Vec<crate::sample::GradientMethod>,
    /// Whether cubic coefficients are computed.
    cubic: bool,
}

/// Rejects what `scene` cannot render on a volume described by `header` with
/// `opts`, at `(width, height)`, before anything is loaded: a degenerate volume, a crop
/// outside it, frames outside the orbit, a GIF too large for the format, a
/// turntable page over NRRD frames. The frames selected, or the message.
fn check(
    scene: &Scene,
    headers: &[VolumeHeader],
    opts: &RunOptions,
    (width, height): (usize, usize),
) -> Result<Range<usize>, String> {
    assert_eq!(headers.len(), scene.volumes.len(), "a header per volume");
    let several = headers.len() > 1;
    for (v, header) in scene.volumes.iter().zip(headers) {
        let which = if several {
            format!("volume `{}`: ", v.name)
        } else {
            String::new()
        };
        if !header.geometry.is_valid() {
            return Err(format!(
                "{which}the volume {} has degenerate axes (space directions or spacings are zero, non-finite or coplanar{})",
                header.source,
                if v.transform.is_some() { ", with its transform" } else { "" }
            ));
        }
        if let Some(crop) = v.spec.crop {
            for (a, (&[lo, hi], &n)) in crop.iter().zip(&header.sizes).enumerate() {
                if hi >= n {
                    return Err(format!(
                        "{which}volume.crop: the {} range [{lo}, {hi}] is outside the volume's {n} voxels (0..={})",
                        ["x", "y", "z"][a],
                        n - 1
                    ));
                }
                debug_assert!(lo <= hi, "checked by the scene resolver");
            }
        }
    }
    let total = scene.orbit.frames;
    let frames = match &opts.frames {
        None => 0..total,
        Some(r) if r.start < r.end && r.end <= total => r.clone(),
        Some(r) => {
            return Err(format!(
                "frames {}..{} are not within the orbit's {total} frames (0..{total})",
                r.start, r.end
            ))
        }
    };
    if let Some(a) = &scene.animation {
        let file_width = match scene.stereo {
            Some(s) if matches!(s.layout, Layout::SideBySide | Layout::CrossEyed) => {
                2 * width + s.gap
            }
            _ => width,
        };
        if a.formats.iter().any(|f| f.is_video())
            && crate::output::animation::find_ffmpeg().is_none()
        {
            return Err(format!(
                "[animation] formats: {}",
                crate::output::animation::NO_FFMPEG
            ));
        }
        if a.formats.contains(&crate::scene::AnimationFormat::Gif)
            && file_width.max(height) > usize::from(u16::MAX)
        {
            return Err(format!(
                "[animation] gif: GIF images are at most 65535 pixels wide and high, these frames are {file_width} x {height} (use formats = [\"apng\"] or a smaller size)"
            ));
        }
    }
    if (scene.viewer || opts.viewer) && scene.image.format == Format::Nrrd {
        return Err(
            "--viewer: the turntable page shows the PNG frames in a browser, and this scene writes nrrd (browsers cannot show it): use [image] format = \"png\" or \"png16\"".into(),
        );
    }
    check_file_names(scene, opts, total)?;
    Ok(frames)
}

/// The longest file name and path the file system takes (Linux's `NAME_MAX` and
/// `PATH_MAX` without its terminating zero, which every common file system has).
const NAME_MAX: usize = 255;
const PATH_MAX: usize = 4095;

/// Refuses a scene whose output files could not be created: a name longer than a
/// file name may be (with the temporary name it is first written under), or a path
/// longer than a path may be. Checked before anything is written, so such a run
/// leaves nothing behind.
fn check_file_names(scene: &Scene, opts: &RunOptions, frames: usize) -> Result<(), String> {
    let out = opts.out.as_deref().unwrap_or(&scene.image.out);
    let out = std::path::absolute(out).unwrap_or_else(|_| out.to_path_buf());
    let last = frames.saturating_sub(1);
    let ext = scene.image.format.extension();
    for pass in &scene.passes {
        let p = &pass.name;
        let mut names = vec![
            format!("{p}_{last:04}_right.{ext}"),
            format!("{p}_{last:04}.json"),
        ];
        if let Some(a) = &scene.animation {
            names.extend(
                a.formats
                    .iter()
                    .map(|f| format!("{p}_right.{}", f.extension())),
            );
        }
        for name in names {
            let temporary = crate::output::write::temporary_name(&name);
            if temporary.len() > NAME_MAX {
                return Err(format!(
                    "[[render]] name = \"{}...\" ({} bytes) is too long for a file name: its files (such as {} bytes of `{}...`, written first under a temporary name of {} bytes) must have names of at most {NAME_MAX} bytes; use a name of at most {} bytes",
                    p.chars().take(24).collect::<String>(),
                    p.len(),
                    name.len(),
                    name.chars().take(24).collect::<String>(),
                    temporary.len(),
                    p.len().saturating_sub(temporary.len() - NAME_MAX)
                ));
            }
            let path = out.join(crate::output::manifest::RECORDS).join(&temporary);
            if path.as_os_str().len() > PATH_MAX {
                return Err(format!(
                    "the output folder {} is too deep: the paths of its files (such as {}) would be {} bytes, over the {PATH_MAX} bytes a path may have",
                    out.display(),
                    name,
                    path.as_os_str().len()
                ));
            }
        }
    }
    Ok(())
}

/// The eyes of each frame and their azimuth offsets (degrees).
fn eyes(scene: &Scene) -> Vec<(Eye, f64)> {
    match &scene.stereo {
        None => vec![(Eye::Mono, 0.0)],
        Some(s) if s.method == crate::scene::StereoMethod::ToeIn => vec![
            (Eye::Left, -s.angle_deg / 2.0),
            (Eye::Right, s.angle_deg / 2.0),
        ],
        Some(_) => vec![(Eye::Left, 0.0), (Eye::Right, 0.0)],
    }
}

/// One render pass per scene pass, with the clip planes that apply to it: over
/// its volume, or, for a pass over several, over each volume's part.
fn render_passes(
    scene: &Scene,
    volumes: &[PlannedVolume],
    sphere: (glam::DVec3, f64),
    opts: &RunOptions,
) -> Vec<RenderPass> {
    let light = shade_light(scene, sphere.0);
    scene
        .passes
        .iter()
        .map(|p| {
            let clips = scene
                .clips
                .iter()
                .filter(|c| c.applies_to(&p.name))
                .map(|c| clip_plane(c, c.offset))
                .collect();
            let ctx = PassContext {
                exact: p.integration == Integration::Exact,
                sphere_diameter: 2.0 * sphere.1,
                light,
                window: p.window,
            };
            let sampling = Sampling {
                name: p.name.clone(),
                mode_name: p.mode.name(),
                interpolation: p.interpolation,
                gradient: p
                    .mode
                    .shading()
                    .map_or(GradientMethod::Central, |s| s.gradient),
                step_voxels: p.step_voxels,
                jitter: p.jitter,
            };
            // steps are in voxels of the smallest spacing of the volumes it reads
            let voxel_length = p
                .volumes
                .iter()
                .map(|&k| volumes[k].voxel_length())
                .fold(f64::INFINITY, f64::min);
            let skip = !opts.no_skip;
            let frames: Vec<IndexFrame> = p.volumes.iter().map(|&k| volumes[k].frame).collect();
            let pass = match p.mode.plan_blend(&ctx, frames) {
                Some(blend) => {
                    let parts = p
                        .volumes
                        .iter()
                        .enumerate()
                        .map(|(i, &k)| {
                            let mode = p.mode.part(i).expect("a blend has a part per volume");
                            let part = RenderPass::new(
                                sampling.clone(),
                                mode.plan(&ctx),
                                volumes[k].header.scalar_type,
                                voxel_length,
                                skip,
                            )
                            .on_volume(k);
                            (k, part)
                        })
                        .collect();
                    RenderPass::blend(sampling, blend, voxel_length, parts)
                }
                None => {
                    let k = p.volumes[0];
                    RenderPass::new(
                        sampling,
                        p.mode.plan(&ctx),
                        volumes[k].header.scalar_type,
                        voxel_length,
                        skip,
                    )
                    .on_volume(k)
                }
            };
            pass.with_clips(clips)
        })
        .collect()
}

/// The fit threshold of `scene` (normalised) when it asks for `zoom = "fit"`:
/// `fit_threshold`, else the smallest
/// value any pass looks for (a threshold, an iso value, the first knot or widget
/// with opacity, the low end of a grey window), else 0 (every voxel above the
/// window's low end).
fn fit_threshold(scene: &Scene) -> Option<f64> {
    let fit = scene.camera.fit?;
    if let Some(t) = fit.threshold {
        return Some(t);
    }
    let mut t = f64::INFINITY;
    for p in &scene.passes {
        if let Some(v) = p.mode.fit_value(p.window) {
            t = t.min(v);
        }
    }
    Some(if t.is_finite() { t.max(0.0) } else { 0.0 })
}

/// The plane of `clip` as the renderer takes it: through `point + offset normal`
/// (`offset` is the clip's own, or a keyframed one).
fn clip_plane(clip: &crate::scene::Clip, offset: f64) -> ClipPlane {
    ClipPlane {
        point: clip.point + offset * clip.normal,
        normal: clip.normal,
        cap: clip.cap,
    }
}

/// The passes each frame renders when keyframes animate pass values (iso,
/// threshold) or clip offsets: per pass and frame, the pass with that frame's values,
/// one variant per distinct set (a frame's pass is then exactly the pass a scene
/// with those values would plan). `None` when nothing is animated.
fn pass_variants(
    scene: &Scene,
    passes: &[RenderPass],
) -> (Vec<RenderPass>, Option<Vec<Vec<usize>>>) {
    let animated = scene
        .keyframes
        .as_ref()
        .is_some_and(|k| !k.pass_values.is_empty() || !k.clip_offsets.is_empty());
    if !animated {
        return (passes.to_vec(), None);
    }
    let mut variants: Vec<RenderPass> = Vec::new();
    let mut index: std::collections::HashMap<(usize, Vec<u64>), usize> = Default::default();
    let of = (0..passes.len())
        .map(|p| {
            (0..scene.orbit.frames)
                .map(|k| {
                    let value = scene.pass_value_at(p, k);
                    let clips: Vec<(usize, f64)> = scene
                        .clips
                        .iter()
                        .enumerate()
                        .filter(|(_, c)| c.applies_to(&scene.passes[p].name))
                        .map(|(c, _)| (c, scene.clip_offset_at(c, k)))
                        .collect();
                    let key = (
                        p,
                        value
                            .iter()
                            .chain(clips.iter().map(|(_, o)| o))
                            .map(|x| x.to_bits())
                            .collect(),
                    );
                    *index.entry(key).or_insert_with(|| {
                        let planes = clips
                            .iter()
                            .map(|&(c, o)| clip_plane(&scene.clips[c], o))
                            .collect();
                        let mut v = passes[p].clone().with_clips(planes);
                        if let Some(x) = value {
                            v = v.with_value(x);
                        }
                        variants.push(v);
                        variants.len() - 1
                    })
                })
                .collect()
        })
        .collect();
    (variants, Some(of))
}

/// One line of `check` for clipping plane `k` of a pass of `mode`.
fn describe_clip(k: usize, c: &crate::scene::Clip, mode: &dyn Mode) -> String {
    let name = c.name.clone().unwrap_or_else(|| format!("#{}", k + 1));
    let v = |p: glam::DVec3| format!("[{}, {}, {}]", p.x, p.y, p.z);
    let offset = if c.offset != 0.0 {
        format!(" moved {} along it", c.offset)
    } else {
        String::new()
    };
    let cap = match (c.cap, mode.caps_clips()) {
        (true, true) => ", the cut face capped where it is inside the object",
        (false, true) => {
            ", no cap (the surface is seen from inside where the cut is inside the object)"
        }
        (_, false) => "",
    };
    format!(
        "clipping plane {name}: through {} with normal {}{offset}, removes the side the normal points into (rays cut analytically){cap}",
        v(c.point),
        v(c.normal)
    )
}

/// The light of the scene in renderer form (`centre`: the volume box's centre, the
/// default target).
fn shade_light(scene: &Scene, centre: glam::DVec3) -> Light {
    let target = scene.camera.target.unwrap_or(centre);
    let l = &scene.light;
    let (kind, default_intensity) = match l.kind {
        LightKindSpec::Headlight => (LightKind::Headlight, 1.0),
        LightKindSpec::Directional(d) => (
            LightKind::Directional {
                direction: d.as_vec3(),
            },
            1.0,
        ),
        LightKindSpec::Point(p) => (
            LightKind::Point {
                position: p.as_vec3(),
            },
            (p - target).length_squared().max(1e-12),
        ),
    };
    Light {
        kind,
        color: l.color.as_vec3(),
        intensity: l.intensity.unwrap_or(default_intensity) as f32,
    }
}

/// The one length unit of every axis of the volume's file (`space units`, else
/// `units`), if it names one.
fn length_unit(header: &VolumeHeader) -> Option<String> {
    ["space units", "units"].iter().find_map(|key| {
        let (_, v) = header.fields.iter().find(|(k, _)| k == key)?;
        let mut units = v.split_whitespace();
        let first = units.next()?;
        (first != "???" && units.all(|u| u == first)).then(|| first.to_string())
    })
}
