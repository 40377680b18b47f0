//! Render passes: a mode as the renderer runs it ([`RayMode`], which each family of
//! `crate::mode` implements), sampled as its pass says, over the run's shared
//! precomputations.
//!
//! ```text
//! mode's RayMode + Sampling + volume header --RenderPass::new--> RenderPass (no voxels)
//!     .needs(), .channels(), .kind(), .table_bytes(), .describe()
//! voxels + every pass's needs --Resources::build--> Resources   (shared precomputations)
//! RenderPass + Resources --RenderPass::prepare--> Box<dyn RenderView>   (tables, skipping)
//!     .render(view) -> Film
//! ```
//!
//! [`RenderPass::prepare`] asks the mode for its view ([`RayMode::view`]): the mode
//! builds its tables and its integrand and hands it to [`RenderPass::render_with`],
//! where the types meet: the voxel type and the reconstruction filter are picked
//! once, in a [`Kernel`] generic over both and the integrand, so no match on any of
//! them is left in the loops over pixels and samples; everything above sees a `dyn
//! RenderView`. A filter, a skipping structure or another way to traverse the volume
//! has this one place; a mode has its family's module.

use std::sync::OnceLock;

use glam::DMat3;

use super::clip::ClipPlane;
use super::frame::{Kernel, RenderView};
use super::integrator::Integrand;
use super::skip::{MacroGrid, Support};
use crate::sample::{
    bits_table, gradient_volume_normalised, pair_table, prefilter_normalised, raw_bytes_unclamped,
    reads_pairs, BSpline, Cubic, Field, GradientMethod, Gradients, Grid, Interpolation, Nearest,
    Normalize, Trilinear, PAIR_TABLE_BYTES,
};
use crate::shade::Shader;
use crate::volume::{human_bytes, ScalarType, VolumeData, Voxel};

/// The values a macrocell grid summarises.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum GridSource {
    /// The normalised voxels, read by a filter of this support.
    Voxels(Support),
    /// The prefiltered cubic coefficients (clamped to [0, 1]).
    Coefficients,
}

impl GridSource {
    /// Bytes its grid takes over `sizes` voxels.
    pub fn grid_bytes(self, sizes: [usize; 3]) -> u64 {
        match self {
            GridSource::Voxels(support) => MacroGrid::bytes(sizes, support),
            GridSource::Coefficients => MacroGrid::bytes(sizes, Support::Cubic),
        }
    }
}

/// What a pass needs computed over the whole volume before its first ray (shared
/// between the passes that need the same thing).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Needs {
    /// A gradient volume (3 x f32 per voxel) by this estimator.
    pub gradient_volume: Option<GradientMethod>,
    /// Prefiltered cubic B-spline coefficients (f32 per voxel).
    pub coefficients: bool,
    /// A macrocell grid for empty-space skipping.
    pub grid: Option<GridSource>,
    /// Trilinear samples of 8-bit voxels: unsigned ones are interpolated as the
    /// bytes they are where the window covers every voxel value
    /// ([`Grid::with_raw_bytes`]), the others read through a table of pairs where
    /// the machine's vector paths do so ([`Needs::voxel_pairs`]).
    pub trilinear_bytes: bool,
}

impl Needs {
    /// The table of normalised pairs of 8-bit voxels (512 KiB), which the vector
    /// paths of trilinear passes over 8-bit data read on machines that have them
    /// ([`reads_pairs`]); not built for unsigned voxels that the window covers,
    /// which are interpolated as they are.
    pub fn voxel_pairs(&self) -> bool {
        self.trilinear_bytes && reads_pairs()
    }
}

/// What a pass's films hold, for display.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageKind {
    /// One grey value per pixel.
    Intensity,
    /// One distance per pixel (near shown bright).
    Depth,
    /// RGBA, not premultiplied.
    Rgba,
}

/// A mode as the renderer runs it: what its films hold, what it needs over the
/// whole volume and how its view is built. Each mode family of [`crate::mode`]
/// implements it for the pass it plans; nothing here knows the modes.
pub trait RayMode: std::fmt::Debug + Send + Sync {
    /// What its films hold.
    fn kind(&self) -> ImageKind;

    /// Whether it integrates the trilinear interpolant exactly, cell by cell.
    fn is_exact(&self) -> bool {
        false
    }

    /// Whether it skips only all-zero cells (X-ray, the average): its grid's ranges
    /// must then be exact zeros, without the margin of the narrower ranges.
    fn skips_zero_cells(&self) -> bool {
        false
    }

    /// Whether its grid also summarises each cell's octants (compositing: fewer
    /// samples and fewer instructions per frame; the other modes skip the octants'
    /// set-up).
    fn skips_octants(&self) -> bool {
        false
    }

    /// What its macrocell grid lets it skip (for `check`).
    fn skips(&self) -> &'static str {
        "cells that cannot reach the threshold"
    }

    /// The shader of a mode that shades.
    fn shader(&self) -> Option<&Shader> {
        None
    }

    /// Whether many samples per ray take a gradient (shaded compositing, 2D
    /// transfer functions): then a gradient volume is built, unless the gradients
    /// are analytic.
    fn samples_gradients(&self) -> bool {
        false
    }

    /// Bytes of its own tables, built when it is prepared (`grid_bytes`: its
    /// macrocell grid's, if it skips).
    fn table_bytes(&self, _grid_bytes: Option<u64>) -> u64 {
        0
    }

    /// Its own tables, one `check` item each.
    fn describe_tables(&self, _needs: &mut Vec<String>) {}

    /// The mode with its iso value or threshold (normalised) set to `value` (a
    /// keyframed frame's); `None` for modes without one.
    fn with_value(&self, _value: f32) -> Option<std::sync::Arc<dyn RayMode>> {
        None
    }

    /// The view of `pass` over the run's precomputations: the mode builds its
    /// tables and its integrand, and hands it to [`RenderPass::render_with`].
    fn view<'a>(&'a self, pass: &'a RenderPass, res: &'a Resources<'a>)
        -> Box<dyn RenderView + 'a>;

    /// The view of `pass` over the precomputations of every volume of the run
    /// (`res[k]`: volume `k`'s, where a pass reads it): by default
    /// [`RayMode::view`] over the pass's own volume; a pass over several volumes
    /// reads each of its parts' ([`RenderPass::parts`]).
    fn view_of_volumes<'a>(
        &'a self,
        pass: &'a RenderPass,
        res: &'a [Option<Resources<'a>>],
    ) -> Box<dyn RenderView + 'a> {
        let r = res[pass.volume]
            .as_ref()
            .expect("the run prepares every volume a pass reads");
        assert_eq!(
            r.data.scalar_type(),
            pass.scalar_type,
            "the volume has the type its header announced"
        );
        self.view(pass, r)
    }
}

/// How a pass samples, as the scene gives it (the mode aside).
#[derive(Clone, Debug)]
pub struct Sampling {
    /// The pass's name (file prefix).
    pub name: String,
    /// The scene-file name of its mode.
    pub mode_name: &'static str,
    /// The reconstruction filter (exact modes walk the trilinear interpolant
    /// whatever this says).
    pub interpolation: Interpolation,
    /// The gradient estimator of a mode that shades.
    pub gradient: GradientMethod,
    /// Sample spacing in voxels of the smallest spacing.
    pub step_voxels: f64,
    /// Jitter each ray's first sample.
    pub jitter: bool,
}

/// One render pass, as planned from the scene and the volume's header: what it
/// needs, what it stores, and, once the voxels and the shared precomputations are
/// there, the [`RenderView`] that renders it.
#[derive(Clone, Debug)]
pub struct RenderPass {
    /// The pass's name (file prefix).
    pub name: String,
    mode: std::sync::Arc<dyn RayMode>,
    mode_name: &'static str,
    interpolation: Interpolation,
    gradient: GradientMethod,
    /// Sample spacing in world units.
    pub dt: f64,
    step_voxels: f64,
    voxel_length: f64,
    jitter: Option<u64>,
    needs: Needs,
    scalar_type: ScalarType,
    clips: Vec<ClipPlane>,
    /// The volume it reads (an index into the run's volumes; a blend's first).
    volume: usize,
    /// A pass over several volumes: each volume's part, as a pass of its own over
    /// that volume (its needs, its field); empty for a pass over one volume.
    parts: Vec<(usize, RenderPass)>,
}

impl RenderPass {
    /// Plans a pass of `mode` sampled as `sampling` says, for a volume of
    /// `scalar_type` whose smallest spacing is `voxel_length`; `skip` = empty-space
    /// skipping.
    pub fn new(
        sampling: Sampling,
        mode: std::sync::Arc<dyn RayMode>,
        scalar_type: ScalarType,
        voxel_length: f64,
        skip: bool,
    ) -> RenderPass {
        let exact = mode.is_exact();
        let gradient = sampling.gradient;
        // exact integration walks the trilinear interpolant whatever the filter
        let interpolation = if exact {
            Interpolation::Trilinear
        } else {
            sampling.interpolation
        };
        // a gradient volume only where many samples per ray need a gradient: shaded
        // composites and 2D transfer functions (surfaces take one gradient per ray,
        // on the fly; analytic gradients differentiate the spline on the fly)
        let gradient_volume = mode
            .samples_gradients()
            .then_some(gradient)
            .filter(|g| *g != GradientMethod::Analytic);
        let grid = skip.then(|| grid_source(&*mode, interpolation));
        // trilinear samples of 8-bit voxels (exact integration reads cells)
        let bytes = !exact
            && interpolation == Interpolation::Trilinear
            && matches!(scalar_type, ScalarType::Uint8 | ScalarType::Int8);
        let name = sampling.name;
        RenderPass {
            // the pass's seed: a hash of its name, so each pass jitters differently
            jitter: sampling.jitter.then(|| {
                name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
                    (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
                })
            }),
            name,
            mode_name: sampling.mode_name,
            mode,
            interpolation,
            gradient,
            dt: sampling.step_voxels * voxel_length,
            step_voxels: sampling.step_voxels,
            voxel_length,
            needs: Needs {
                gradient_volume,
                coefficients: interpolation == Interpolation::Cubic,
                grid,
                trilinear_bytes: bytes,
            },
            scalar_type,
            clips: Vec::new(),
            volume: 0,
            parts: Vec::new(),
        }
    }

    /// A pass of `mode` over several volumes, whose `parts` are each volume's (its
    /// index among the run's volumes, and its part as a pass of its own, sampled
    /// as this pass is). The parts carry what each volume needs; the pass itself
    /// needs nothing more.
    pub fn blend(
        sampling: Sampling,
        mode: std::sync::Arc<dyn RayMode>,
        voxel_length: f64,
        parts: Vec<(usize, RenderPass)>,
    ) -> RenderPass {
        let (volume, first) = parts.first().expect("a blend has parts");
        let (volume, scalar_type) = (*volume, first.scalar_type);
        let mut pass = RenderPass::new(sampling, mode, scalar_type, voxel_length, false);
        pass.needs = Needs::default();
        pass.volume = volume;
        pass.parts = parts;
        pass
    }

    /// The pass over volume `volume` of the run (an index into its volumes).
    pub fn on_volume(mut self, volume: usize) -> RenderPass {
        self.volume = volume;
        self
    }

    /// The volume the pass reads (a blend's first).
    pub fn volume(&self) -> usize {
        self.volume
    }

    /// Each volume's part of a pass over several volumes (empty for one volume).
    pub fn parts(&self) -> &[(usize, RenderPass)] {
        &self.parts
    }

    /// What the pass reads: each volume with the pass that reads it (itself, or
    /// its parts), for the precomputations.
    pub fn reads(&self) -> Vec<(usize, &RenderPass)> {
        if self.parts.is_empty() {
            vec![(self.volume, self)]
        } else {
            self.parts.iter().map(|(k, p)| (*k, p)).collect()
        }
    }

    /// The per-pass seed of its jittered first samples (`None`: no jitter).
    pub fn jitter_seed(&self) -> Option<u64> {
        self.jitter
    }

    /// The pass with the clipping planes that apply to it (world coordinates).
    pub fn with_clips(mut self, clips: Vec<ClipPlane>) -> RenderPass {
        for (_, p) in &mut self.parts {
            p.clips = clips.clone();
        }
        self.clips = clips;
        self
    }

    /// The pass with its iso value or threshold (normalised) set to `value`: how a
    /// keyframed frame's pass is made (modes without one are returned unchanged).
    pub fn with_value(mut self, value: f64) -> RenderPass {
        if let Some(mode) = self.mode.with_value(value as f32) {
            self.mode = mode;
        }
        self
    }

    /// The clipping planes that apply to the pass.
    pub fn clips(&self) -> &[ClipPlane] {
        &self.clips
    }

    /// What the pass needs computed over the whole volume.
    pub fn needs(&self) -> &Needs {
        &self.needs
    }

    /// The scene-file name of the pass's mode.
    pub fn mode_name(&self) -> &'static str {
        self.mode_name
    }

    /// Sample spacing in voxels of the smallest spacing.
    pub fn step_voxels(&self) -> f64 {
        self.step_voxels
    }

    /// World length of one voxel of the smallest spacing.
    pub fn voxel_length(&self) -> f64 {
        self.voxel_length
    }

    /// Channels of its films (1 = intensity or depth, 4 = RGBA).
    pub fn channels(&self) -> usize {
        match self.kind() {
            ImageKind::Rgba => 4,
            _ => 1,
        }
    }

    /// What its films hold.
    pub fn kind(&self) -> ImageKind {
        self.mode.kind()
    }

    /// Bytes of the pass's own tables (transfer-function and pre-integration tables,
    /// the macrocells' transparency), built when it is prepared.
    pub fn table_bytes(&self, sizes: [usize; 3]) -> u64 {
        self.mode
            .table_bytes(self.needs.grid.map(|g| g.grid_bytes(sizes)))
    }

    /// What the pass computes and precomputes, one item per entry (for `volcast
    /// check`).
    pub fn describe(&self, sizes: [usize; 3]) -> Vec<String> {
        let mut needs = Vec::new();
        if self.mode.is_exact() {
            needs.push(
                "exact integration of the trilinear interpolant, cell by cell (no step)".into(),
            );
        }
        if self.jitter.is_some() {
            needs.push("jittered first sample per pixel".into());
        }
        if let Some(g) = self.needs.gradient_volume {
            needs.push(format!("{} gradient volume", g.name()));
        }
        if let Some(sh) = self.mode.shader() {
            if self.gradient == GradientMethod::Analytic {
                needs.push(format!(
                    "analytic gradients of the {} spline, on the fly",
                    self.interpolation.name()
                ));
            } else if self.needs.gradient_volume.is_none() {
                needs.push(format!(
                    "{} gradients at the hit points",
                    self.gradient.name()
                ));
            }
            needs.push(format!("{:?} shading", sh.model).to_lowercase());
        }
        if self.needs.coefficients {
            needs.push("prefiltered cubic coefficients".into());
        }
        if self.needs.voxel_pairs() {
            needs.push(format!(
                "8-bit voxels read two at a time through a table of normalised pairs ({}; \
                 none for unsigned voxels the window covers: interpolated as they are)",
                human_bytes(PAIR_TABLE_BYTES)
            ));
        }
        self.mode.describe_tables(&mut needs);
        if let Some(source) = self.needs.grid {
            let d = MacroGrid::dims(sizes);
            let what = self.mode.skips();
            let of = match source {
                GridSource::Voxels(Support::LinearOctants) => "voxels, and of each cell's octants",
                GridSource::Voxels(_) => "voxels",
                GridSource::Coefficients => "cubic coefficients",
            };
            needs.push(format!(
                "empty-space skipping: {} x {} x {} macrocells of {} voxels, min/max of the {of} ({}), skips {what}",
                d[0],
                d[1],
                d[2],
                super::skip::MACROCELL,
                human_bytes(source.grid_bytes(sizes))
            ));
        }
        needs
    }

    /// Builds the pass's tables over the run's shared precomputations (`res[k]`,
    /// volume `k`'s, for every volume it reads) and returns it ready to render.
    /// The mode builds its integrand ([`RayMode::view`]) and
    /// [`RenderPass::render_with`] meets it with the voxel type and the filter.
    pub fn prepare<'a>(&'a self, res: &'a [Option<Resources<'a>>]) -> Box<dyn RenderView + 'a> {
        self.mode.view_of_volumes(self, res)
    }

    /// The pass's reconstruction of its volume behind a virtual call (its
    /// samples the same bits as [`RenderPass::render_with`]'s): what a pass over
    /// several volumes samples each of them with, a batch of samples per call.
    pub fn boxed_field<'a>(&'a self, res: &'a Resources<'a>) -> Box<dyn Field + 'a> {
        match self.interpolation {
            Interpolation::Cubic => {
                let coefficients = res
                    .coefficients
                    .as_deref()
                    .expect("the plan makes coefficients for cubic passes");
                Box::new(Cubic::new(
                    coefficients,
                    res.sizes,
                    self.gradient,
                    res.index_from_world.transpose(),
                    self.dyn_field(res, Interpolation::Trilinear),
                ))
            }
            interpolation => self.dyn_field(res, interpolation),
        }
    }

    /// The pass's macrocell grid among the run's precomputations, if it skips.
    pub fn grid<'a>(&self, res: &'a Resources<'a>) -> Option<&'a MacroGrid> {
        self.needs.grid.and_then(|s| res.grid(s))
    }

    /// The view that renders `integrand` over the pass's field: the one place where
    /// the voxel type, the reconstruction filter and the mode's integrand meet, in
    /// a [`Kernel`] generic over all three, so no match on any of them is left in
    /// the loops over pixels and samples.
    ///
    /// The combinations that matter for speed are compiled for every mode: the
    /// trilinear filter over 8-bit (signed or unsigned: their bits index one
    /// normalisation table), 16-bit and float32 voxels, and the cubic filter (whose
    /// values come from its `f32` coefficients, whatever the voxels' type). The other
    /// combinations (nearest and B-spline filters, 32- and 64-bit integer and float64
    /// voxels) reach their filter through one virtual call per sample, which keeps
    /// the build small; their inner loops are otherwise the same.
    pub fn render_with<'a, I: Integrand + 'a>(
        &'a self,
        res: &'a Resources<'a>,
        integrand: I,
    ) -> Box<dyn RenderView + 'a> {
        let exact = self.mode.is_exact();
        match (self.interpolation, self.scalar_type) {
            (Interpolation::Cubic, _) if !exact => {
                let coefficients = res
                    .coefficients
                    .as_deref()
                    .expect("the plan makes coefficients for cubic passes");
                let cubic = Cubic::new(
                    coefficients,
                    res.sizes,
                    self.gradient,
                    res.index_from_world.transpose(),
                    self.dyn_field(res, Interpolation::Trilinear),
                );
                Box::new(self.kernel(cubic, integrand, res))
            }
            (Interpolation::Trilinear, ScalarType::Uint8 | ScalarType::Int8) => {
                Box::new(self.kernel(self.trilinear::<u8>(res), integrand, res))
            }
            (Interpolation::Trilinear, ScalarType::Uint16 | ScalarType::Int16) => {
                Box::new(self.kernel(self.trilinear::<u16>(res), integrand, res))
            }
            (Interpolation::Trilinear, ScalarType::Float32) => {
                Box::new(self.kernel(self.trilinear::<f32>(res), integrand, res))
            }
            (interpolation, _) => {
                Box::new(self.kernel(self.dyn_field(res, interpolation), integrand, res))
            }
        }
    }

    /// The grid over the volume's voxels as `T`: their own type, or the unsigned
    /// type of the same size for 8- and 16-bit data (read as bits).
    fn grid_of<'a, T: Voxel>(&self, res: &'a Resources<'a>) -> Grid<'a, T> {
        let voxels = match self.scalar_type {
            ScalarType::Int8 => res.data.voxels::<i8>().map(|v| v.reinterpret::<T>()),
            ScalarType::Int16 => res.data.voxels::<i16>().map(|v| v.reinterpret::<T>()),
            _ => res.data.voxels::<T>(),
        }
        .expect("the volume has the type its header announced");
        let grid = Grid::new(voxels, res.sizes, res.norm, &res.lut).with_pairs(&res.pairs);
        match self.scalar_type {
            ScalarType::Int8 | ScalarType::Int16 => grid.signed_bits(),
            ScalarType::Float32 if res.unit_voxels() => grid.with_unit_voxels(),
            ScalarType::Uint8 if res.raw_bytes => grid.with_raw_bytes(),
            _ => grid,
        }
    }

    fn gradients<'a>(&self, res: &'a Resources<'a>) -> Gradients<'a> {
        Gradients::new(
            self.gradient,
            self.needs
                .gradient_volume
                .and_then(|m| res.gradient_volume(m)),
            res.index_from_world,
        )
    }

    fn trilinear<'a, T: Voxel>(&self, res: &'a Resources<'a>) -> Trilinear<'a, T> {
        Trilinear {
            grid: self.grid_of::<T>(res),
            gradients: self.gradients(res),
        }
    }

    /// `interpolation` over the voxels, behind a virtual call.
    fn dyn_field<'a>(
        &self,
        res: &'a Resources<'a>,
        interpolation: Interpolation,
    ) -> Box<dyn Field + 'a> {
        fn typed<'a, T: Voxel>(
            pass: &RenderPass,
            res: &'a Resources<'a>,
            interpolation: Interpolation,
        ) -> Box<dyn Field + 'a> {
            let (grid, gradients) = (pass.grid_of::<T>(res), pass.gradients(res));
            match interpolation {
                Interpolation::Nearest => Box::new(Nearest { grid, gradients }),
                Interpolation::BSpline => Box::new(BSpline { grid, gradients }),
                // cubic passes read their coefficients; this serves their gradients
                Interpolation::Trilinear | Interpolation::Cubic => {
                    Box::new(Trilinear { grid, gradients })
                }
            }
        }
        match self.scalar_type {
            ScalarType::Int8 | ScalarType::Uint8 => typed::<u8>(self, res, interpolation),
            ScalarType::Int16 | ScalarType::Uint16 => typed::<u16>(self, res, interpolation),
            ScalarType::Int32 => typed::<i32>(self, res, interpolation),
            ScalarType::Uint32 => typed::<u32>(self, res, interpolation),
            ScalarType::Int64 => typed::<i64>(self, res, interpolation),
            ScalarType::Uint64 => typed::<u64>(self, res, interpolation),
            ScalarType::Float32 => typed::<f32>(self, res, interpolation),
            ScalarType::Float64 => typed::<f64>(self, res, interpolation),
        }
    }

    fn kernel<'a, F: Field, I: Integrand>(
        &'a self,
        field: F,
        integrand: I,
        res: &'a Resources<'a>,
    ) -> Kernel<'a, F, I> {
        Kernel::new(
            field,
            integrand,
            self.grid(res),
            self.dt,
            self.jitter,
            &self.clips,
        )
    }
}

/// The ranges `mode`'s skipping grid holds for samples reconstructed with
/// `interpolation`.
fn grid_source(mode: &dyn RayMode, interpolation: Interpolation) -> GridSource {
    match interpolation {
        // all-zero cells need exact zeros; the other modes take the narrower ranges
        // without the margin
        Interpolation::Nearest | Interpolation::Trilinear if mode.skips_zero_cells() => {
            GridSource::Voxels(Support::Linear)
        }
        Interpolation::Nearest | Interpolation::Trilinear if mode.skips_octants() => {
            GridSource::Voxels(Support::LinearOctants)
        }
        Interpolation::Nearest | Interpolation::Trilinear => {
            GridSource::Voxels(Support::LinearTight)
        }
        Interpolation::BSpline => GridSource::Voxels(Support::Cubic),
        Interpolation::Cubic => GridSource::Coefficients,
    }
}

/// The run's shared precomputations over the voxels: the normalisation table,
/// prefiltered coefficients, gradient volumes and macrocell grids, each built once
/// for all the passes that need it, and only if one does.
pub struct Resources<'v> {
    data: &'v VolumeData,
    sizes: [usize; 3],
    norm: Normalize,
    lut: Vec<f32>,
    /// The [`pair_table`] of `lut`, where a pass needs it (else empty).
    pairs: Vec<[f32; 2]>,
    /// Unsigned 8-bit voxels, sampled by a trilinear pass, that the window covers
    /// ([`raw_bytes_unclamped`]): their grids interpolate the bytes as they are
    /// ([`Grid::with_raw_bytes`]), and no table of pairs is built.
    raw_bytes: bool,
    coefficients: Option<Vec<f32>>,
    gradients: Vec<(GradientMethod, Vec<[f32; 3]>)>,
    grids: Vec<(GridSource, MacroGrid)>,
    index_from_world: DMat3,
    /// Whether the voxels are float32 in the window [0, 1] and each in [0, 1]
    /// (found when a pass first asks: [`Resources::unit_voxels`]).
    unit_voxels: OnceLock<bool>,
}

impl<'v> Resources<'v> {
    /// Builds what `passes` need over `data` (`sizes` voxels, normalised by `norm`;
    /// `norm_covers_data`: `norm` is the window of the data's own range, as in a
    /// scene without a window, so that it clamps no voxel).
    pub fn build<'p>(
        data: &'v VolumeData,
        sizes: [usize; 3],
        norm: Normalize,
        norm_covers_data: bool,
        index_from_world: DMat3,
        passes: impl IntoIterator<Item = &'p RenderPass>,
    ) -> Resources<'v> {
        let needs: Vec<Needs> = passes.into_iter().map(|p| p.needs).collect();
        let ty = data.scalar_type();
        // the data's range is read only where neither the window's nor the type's
        // range answers
        let raw_bytes = ty == ScalarType::Uint8
            && needs.iter().any(|n| n.trilinear_bytes)
            && (norm_covers_data
                || raw_bytes_unclamped(norm, [0, u8::MAX])
                || data
                    .voxels::<u8>()
                    .is_some_and(|v| raw_bytes_unclamped(norm, v.byte_range())));
        macro_rules! build {
            ($t:ty, $read:ty) => {
                build_typed::<$read>(
                    data,
                    data.voxels::<$t>()
                        .expect("dispatched on the data's own type")
                        .reinterpret::<$read>(),
                    sizes,
                    norm,
                    &needs,
                    raw_bytes,
                    index_from_world,
                )
            };
        }
        match ty {
            ScalarType::Int8 => build!(i8, u8),
            ScalarType::Uint8 => build!(u8, u8),
            ScalarType::Int16 => build!(i16, u16),
            ScalarType::Uint16 => build!(u16, u16),
            ScalarType::Int32 => build!(i32, i32),
            ScalarType::Uint32 => build!(u32, u32),
            ScalarType::Int64 => build!(i64, i64),
            ScalarType::Uint64 => build!(u64, u64),
            ScalarType::Float32 => build!(f32, f32),
            ScalarType::Float64 => build!(f64, f64),
        }
    }

    fn gradient_volume(&self, method: GradientMethod) -> Option<&[[f32; 3]]> {
        self.gradients
            .iter()
            .find(|(m, _)| *m == method)
            .map(|(_, v)| v.as_slice())
    }

    fn grid(&self, source: GridSource) -> Option<&MacroGrid> {
        self.grids
            .iter()
            .find(|(s, _)| *s == source)
            .map(|(_, g)| g)
    }

    /// Bytes held (tables, coefficients, gradient volumes, grids).
    pub fn bytes(&self) -> u64 {
        (std::mem::size_of_val(self.lut.as_slice())
            + std::mem::size_of_val(self.pairs.as_slice())
            + self
                .coefficients
                .as_ref()
                .map_or(0, |c| std::mem::size_of_val(c.as_slice()))
            + self
                .gradients
                .iter()
                .map(|(_, g)| std::mem::size_of_val(g.as_slice()))
                .sum::<usize>()
            + self.grids.iter().map(|(_, g)| g.byte_size()).sum::<usize>()) as u64
    }
}

/// The precomputations over `voxels` (the volume's data, read as `T`: its own type,
/// or the unsigned bits of 8- and 16-bit data, which the table of `norm`,
/// [`bits_table`], normalises).
fn build_typed<'v, T: Voxel>(
    data: &'v VolumeData,
    voxels: crate::volume::Voxels<'v, T>,
    sizes: [usize; 3],
    norm: Normalize,
    needs: &[Needs],
    raw_bytes: bool,
    index_from_world: DMat3,
) -> Resources<'v> {
    let lut = bits_table(data.scalar_type(), norm).unwrap_or_default();
    let grid = Grid::new(voxels, sizes, norm, &lut);
    let grid = match data.scalar_type() {
        ScalarType::Int8 | ScalarType::Int16 => grid.signed_bits(),
        _ => grid,
    };
    let value = |i: usize| grid.at(i);
    let coefficients = needs
        .iter()
        .any(|n| n.coefficients)
        .then(|| prefilter_normalised(sizes, value));
    let mut gradients: Vec<(GradientMethod, Vec<[f32; 3]>)> = Vec::new();
    for m in needs.iter().filter_map(|n| n.gradient_volume) {
        if !gradients.iter().any(|(g, _)| *g == m) {
            gradients.push((m, gradient_volume_normalised(sizes, m, value)));
        }
    }
    let mut sources: Vec<GridSource> = needs.iter().filter_map(|n| n.grid).collect();
    sources.sort();
    sources.dedup();
    let grids = sources
        .into_iter()
        .map(|s| {
            let g = match s {
                GridSource::Voxels(support) => {
                    MacroGrid::build(sizes, support, |row, windows, out| {
                        grid.row_ranges(row, windows, out)
                    })
                }
                GridSource::Coefficients => {
                    let c = coefficients
                        .as_deref()
                        .expect("cubic passes make coefficients");
                    MacroGrid::build(sizes, Support::Cubic, |row, windows, out| {
                        for (o, &(x0, x1)) in out.iter_mut().zip(windows) {
                            // the spline is clamped to [0, 1], and so are its extremes
                            *o = c[row + x0..=row + x1].iter().fold(
                                [1.0f32, 0.0f32],
                                |[lo, hi], &v| {
                                    let v = v.clamp(0.0, 1.0);
                                    [lo.min(v), hi.max(v)]
                                },
                            );
                        }
                    })
                }
            };
            (s, g)
        })
        .collect();
    let pairs = if needs.iter().any(Needs::voxel_pairs) && !raw_bytes {
        pair_table(&lut)
    } else {
        Vec::new()
    };
    Resources {
        data,
        sizes,
        norm,
        lut,
        pairs,
        raw_bytes,
        coefficients,
        gradients,
        grids,
        index_from_world,
        unit_voxels: OnceLock::new(),
    }
}

impl Resources<'_> {
    /// Whether the voxels are float32, the window is [0, 1] and every voxel lies in
    /// it: then sampling need not clamp them ([`Grid::with_unit_voxels`]). Read
    /// once (a pass over the voxels, in parallel), when a pass first asks.
    fn unit_voxels(&self) -> bool {
        *self.unit_voxels.get_or_init(|| {
            self.norm.lo_scale() == (0.0, 1.0)
                && self
                    .data
                    .voxels::<f32>()
                    .is_some_and(|v| v.all_in_unit_interval())
        })
    }
}

impl std::fmt::Debug for Resources<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Resources")
            .field("sizes", &self.sizes)
            .field("bytes", &self.bytes())
            .finish_non_exhaustive()
    }
}
