//! The composite family: emission-absorption compositing, front to back, of a
//! transfer function's colours and opacities (1D over the value, or 2D over value
//! and gradient magnitude), optionally shaded and pre-integrated.

use std::sync::Arc;

mod blend;
mod integrator;
mod unclear;

pub use integrator::{Composite, CompositeTable};

use super::{Keys, Mode, PassContext, Registration, Shading};
use crate::render::frame::RenderView;
use crate::render::pass::{ImageKind, RayMode, RenderPass, Resources};
use crate::render::IndexFrame;
use crate::shade::Shader;
use crate::transfer::{Preintegrated, Transfer, COLOR_ENTRIES, INTEGRAL_ENTRIES};
use crate::volume::human_bytes;

/// Entries of a 1D transfer-function table.
pub const TABLE_1D: usize = 4096;
/// Entries per axis of a 2D transfer-function table.
pub const TABLE_2D: usize = 256;

/// `mode = "composite"` (sampled only: it has no `integration`).
pub const COMPOSITE: Registration = Registration {
    name: "composite",
    keys: &[
        "material",
        "shading",
        "gradient",
        "transfer",
        "reference_step",
        "early_stop",
        "jitter",
        "preintegrated",
        "volumes",
    ],
    window_in_values: |_| false,
    resolve: |keys| Some(Arc::new(resolve(keys)?)),
};

fn resolve(keys: &mut dyn Keys) -> Option<CompositeSettings> {
    let name = keys.pass_name().to_string();
    let shaded = keys.text("shading").is_some_and(|s| s != "none");
    if !shaded {
        for k in ["material", "gradient"] {
            if let Some(s) = keys.text(k) {
                let message =
                    format!("pass `{name}`: `{k} = \"{s}\"` has no effect with shading = \"none\"");
                keys.warn(message);
            }
        }
    }
    let shading = if shaded { Some(keys.shading()?) } else { None };
    let mut transfers = keys.transfers()?;
    let (transfer_name, transfer) = transfers.remove(0);
    let more = transfers;
    let preintegrated = keys.flag("preintegrated");
    if preintegrated && !more.is_empty() {
        keys.error("preintegrated", "preintegrated = true tabulates the segments of one transfer function: a composite of several volumes blends midpoint samples (remove preintegrated, or composite one volume)".into());
    }
    if let (true, Transfer::TwoD(_)) = (preintegrated, &transfer) {
        keys.error("preintegrated", format!(
            "preintegrated = true needs a 1D transfer function, but `{transfer_name}` is 2D (value x gradient magnitude); pre-integration tabulates segments over (front value, back value)"
        ));
    }
    if more.is_empty() {
        if let Transfer::OneD(tf) = &transfer {
            if tf.max_alpha() == 0.0 {
                keys.warn(format!(
                    "pass `{name}`: transfer function `{transfer_name}` has zero alpha everywhere: the image will be empty"
                ));
            }
        }
    }
    Some(CompositeSettings {
        transfer_name,
        transfer,
        shading,
        reference_step_voxels: keys.number(
            "reference_step",
            1.0,
            |x| x > 0.0,
            "a positive step in voxels",
        ),
        early_stop: keys.number(
            "early_stop",
            0.99,
            |x| x > 0.0 && x <= 1.0,
            "an opacity in (0, 1]",
        ),
        preintegrated,
        more,
    })
}

/// A composite pass's settings.
#[derive(Clone, Debug)]
pub struct CompositeSettings {
    /// Transfer function name (for the plan and messages).
    pub transfer_name: String,
    /// The transfer function.
    pub transfer: Transfer,
    /// Optional shading of each sample.
    pub shading: Option<Shading>,
    /// The step (in voxels of the smallest spacing) the transfer function's alpha is defined for.
    pub reference_step_voxels: f64,
    /// Stop when the accumulated opacity reaches this (1 = never stop early).
    pub early_stop: f64,
    /// Pre-integrated segments (1D transfer functions only).
    pub preintegrated: bool,
    /// The transfer functions (with their names) of the pass's other volumes, in
    /// the order of its `volumes` (empty: it composites one volume).
    pub more: Vec<(String, Transfer)>,
}

impl CompositeSettings {
    /// The pass of one volume's part: its transfer function, the rest the same.
    fn part(&self, k: usize) -> Option<CompositeSettings> {
        let (transfer_name, transfer) = match k {
            0 => (self.transfer_name.clone(), self.transfer.clone()),
            _ => self.more.get(k - 1)?.clone(),
        };
        Some(CompositeSettings {
            transfer_name,
            transfer,
            more: Vec::new(),
            ..self.clone()
        })
    }

    fn pass(&self, ctx: &PassContext) -> CompositePass {
        CompositePass {
            transfer_name: self.transfer_name.clone(),
            transfer: self.transfer.clone(),
            shader: self.shading.as_ref().map(|s| s.shader(ctx.light)),
            reference_step_voxels: self.reference_step_voxels,
            early_stop: self.early_stop as f32,
            preintegrated: self.preintegrated && matches!(self.transfer, Transfer::OneD(_)),
        }
    }
}

impl Mode for CompositeSettings {
    fn name(&self) -> &'static str {
        "composite"
    }

    fn is_intensity(&self) -> bool {
        false
    }

    fn shading(&self) -> Option<&Shading> {
        self.shading.as_ref()
    }

    fn transfer(&self) -> Option<(&str, &Transfer)> {
        Some((&self.transfer_name, &self.transfer))
    }

    fn fit_value(&self, _window: Option<[f64; 2]>) -> Option<f64> {
        self.transfer.first_opaque()
    }

    fn manifest(&self) -> serde_json::Map<String, serde_json::Value> {
        let mut m = serde_json::Map::new();
        if self.more.is_empty() {
            m.insert("transfer".into(), self.transfer_name.clone().into());
        } else {
            let names =
                std::iter::once(&self.transfer_name).chain(self.more.iter().map(|(n, _)| n));
            m.insert(
                "transfers".into(),
                names.map(|n| serde_json::Value::from(n.clone())).collect(),
            );
        }
        m.insert(
            "reference_step_voxels".into(),
            self.reference_step_voxels.into(),
        );
        m.insert("early_stop".into(), self.early_stop.into());
        m
    }

    fn plan(&self, ctx: &PassContext) -> Arc<dyn RayMode> {
        Arc::new(self.pass(ctx))
    }

    fn part(&self, k: usize) -> Option<Arc<dyn Mode>> {
        if self.more.is_empty() {
            return None;
        }
        Some(Arc::new(CompositeSettings::part(self, k)?))
    }

    fn plan_blend(&self, ctx: &PassContext, frames: Vec<IndexFrame>) -> Option<Arc<dyn RayMode>> {
        if self.more.is_empty() {
            return None;
        }
        let layers = (0..=self.more.len())
            .filter_map(|k| Some(CompositeSettings::part(self, k)?.pass(ctx)))
            .collect();
        Some(Arc::new(BlendPass {
            layers,
            frames,
            early_stop: self.early_stop as f32,
        }))
    }
}

/// A composite of several volumes as it renders (`blend.rs`): each volume's part
/// as its own composite pass would classify and shade it, and each volume's frame.
#[derive(Clone, Debug)]
struct BlendPass {
    layers: Vec<CompositePass>,
    frames: Vec<IndexFrame>,
    early_stop: f32,
}

impl RayMode for BlendPass {
    fn kind(&self) -> ImageKind {
        ImageKind::Rgba
    }

    fn skips(&self) -> &'static str {
        "cells where every volume's transfer function is transparent"
    }

    fn view<'a>(
        &'a self,
        pass: &'a RenderPass,
        res: &'a Resources<'a>,
    ) -> Box<dyn RenderView + 'a> {
        let _ = res;
        unreachable!(
            "the blend of pass `{}` is prepared over all its volumes (view_of_volumes)",
            pass.name
        )
    }

    fn view_of_volumes<'a>(
        &'a self,
        pass: &'a RenderPass,
        res: &'a [Option<Resources<'a>>],
    ) -> Box<dyn RenderView + 'a> {
        let layers = pass
            .parts()
            .iter()
            .zip(&self.layers)
            .zip(&self.frames)
            .map(|(((k, part), mode), frame)| {
                let r = res[*k]
                    .as_ref()
                    .expect("the run prepares every volume a pass reads");
                blend::Layer::new(
                    part.boxed_field(r),
                    mode.integrand(part, r),
                    part.grid(r),
                    *frame,
                )
            })
            .collect();
        Box::new(blend::Blend {
            layers,
            dt: pass.dt,
            inv_dt: 1.0 / pass.dt,
            jitter: pass.jitter_seed(),
            clips: pass.clips(),
            early_stop: self.early_stop,
        })
    }
}

/// A composite pass as it renders.
#[derive(Clone, Debug)]
struct CompositePass {
    transfer_name: String,
    transfer: Transfer,
    shader: Option<Shader>,
    reference_step_voxels: f64,
    early_stop: f32,
    preintegrated: bool,
}

impl CompositePass {
    fn entries(&self) -> usize {
        match self.transfer {
            Transfer::OneD(_) => TABLE_1D,
            Transfer::TwoD(_) => TABLE_2D * TABLE_2D,
        }
    }
}

impl RayMode for CompositePass {
    fn kind(&self) -> ImageKind {
        ImageKind::Rgba
    }

    fn skips_octants(&self) -> bool {
        true
    }

    fn skips(&self) -> &'static str {
        "cells where the transfer function is transparent"
    }

    fn shader(&self) -> Option<&Shader> {
        self.shader.as_ref()
    }

    fn samples_gradients(&self) -> bool {
        self.shader.is_some() || matches!(self.transfer, Transfer::TwoD(_))
    }

    fn table_bytes(&self, grid_bytes: Option<u64>) -> u64 {
        let entries = self.entries() as u64;
        // the table and its copy corrected for one step
        let tables = 2 * entries * 16;
        let pre = if self.preintegrated {
            Preintegrated::planned_bytes()
        } else {
            0
        };
        // a byte per macrocell (whether it is transparent), and one more with the
        // octants (which of them are): an eighth of the grid
        let cells = grid_bytes.map_or(0, |g| g / 8);
        // the prefix count of opaque entries along the value axis (at most one per
        // entry, plus one)
        let prefix = 4 * (entries + 1);
        tables + pre + cells + prefix
    }

    fn describe_tables(&self, needs: &mut Vec<String>) {
        needs.push(format!(
            "transfer table `{}` ({} entries)",
            self.transfer_name,
            self.entries()
        ));
        if self.preintegrated {
            needs.push(format!(
                "pre-integration table ({} integral entries, {}x{} segment colours for this step, {})",
                INTEGRAL_ENTRIES + 1,
                COLOR_ENTRIES,
                COLOR_ENTRIES,
                human_bytes(Preintegrated::planned_bytes())
            ));
        }
    }

    fn view<'a>(
        &'a self,
        pass: &'a RenderPass,
        res: &'a Resources<'a>,
    ) -> Box<dyn RenderView + 'a> {
        pass.render_with(res, self.integrand(pass, res))
    }
}

impl CompositePass {
    /// The integrand of `pass` (this mode's) over the run's precomputations: its
    /// tables, and the macrocells it passes over.
    fn integrand(&self, pass: &RenderPass, res: &Resources<'_>) -> Composite {
        let table = match &self.transfer {
            Transfer::OneD(t) => CompositeTable::OneD(t.table(TABLE_1D)),
            Transfer::TwoD(t) => CompositeTable::TwoD(t.table(TABLE_2D, TABLE_2D)),
        };
        let pre = match (self.preintegrated, &self.transfer) {
            (true, Transfer::OneD(tf)) => Some(Preintegrated::build(
                tf,
                pass.step_voxels() / self.reference_step_voxels,
            )),
            _ => None,
        };
        let mut c = Composite::new(
            table,
            pass.dt,
            self.reference_step_voxels * pass.voxel_length(),
            self.shader,
            self.early_stop,
            pass.voxel_length(),
            pre,
        );
        if let Some(g) = pass.grid(res) {
            c.classify(g);
        }
        c
    }
}
