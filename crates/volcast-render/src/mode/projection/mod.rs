//! The projection family: one value per ray from the values along it. The maximum
//! (MIP, optionally depth-cued, or the depth of its maximum, or colour-coded by
//! that depth), the minimum (MinIP), the length-weighted mean (average) and the
//! first local maximum above a threshold (local MIP).

pub mod integrator;

use std::sync::Arc;

pub use integrator::{Average, CuedMip, CuedOutput, Lmip, Minip, Mip};

use super::exact::Exact;
use super::{choose, level_note, Keys, Level, Mode, NoteContext, PassContext, Registration};
use crate::render::frame::RenderView;
use crate::render::integrator::Integrand;
use crate::render::pass::{ImageKind, RayMode, RenderPass, Resources};
use crate::transfer::Colormap;

/// `mode = "mip"`.
pub const MIP: Registration = Registration {
    name: "mip",
    keys: &[
        "output",
        "depth_cue",
        "colormap",
        "window",
        "integration",
        "jitter",
    ],
    // a MIP's depth of the maximum is a distance, like a depth pass's
    window_in_values: |output| output != Some("depth-of-max"),
    resolve: |keys| Some(Arc::new(resolve_mip(keys))),
};

/// `mode = "minip"`.
pub const MINIP: Registration = Registration {
    name: "minip",
    keys: &["colormap", "window", "integration", "jitter"],
    window_in_values: |_| true,
    resolve: |_| Some(Arc::new(Projection::Minip)),
};

/// `mode = "average"`.
pub const AVERAGE: Registration = Registration {
    name: "average",
    keys: &["colormap", "window", "integration", "jitter"],
    window_in_values: |_| true,
    resolve: |_| Some(Arc::new(Projection::Average)),
};

/// `mode = "lmip"` (sampled only: it has no `integration`).
pub const LMIP: Registration = Registration {
    name: "lmip",
    keys: &["colormap", "threshold", "window", "jitter"],
    window_in_values: |_| true,
    resolve: |keys| {
        Some(Arc::new(Projection::Lmip {
            threshold: keys.value("threshold", 0.5),
        }))
    },
};

/// What a MIP pass stores per pixel (`output`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MipOutput {
    /// The (depth-cued) maximum.
    Value,
    /// The depth `s` of the first sample that reaches the maximum (NaN where the
    /// ray misses).
    DepthOfMax,
    /// Colour: the map at `s / D` times the maximum's brightness in the pass's
    /// window.
    DepthCoded(Colormap),
}

fn resolve_mip(keys: &mut dyn Keys) -> Projection {
    let depth_cue = keys.number(
        "depth_cue",
        0.0,
        |c| (0.0..=1.0).contains(&c),
        "a weight from 0 (no depth cue) to 1 (the far side of the bounding sphere weighted 0)",
    );
    #[derive(Clone, Copy, PartialEq)]
    enum Out {
        Value,
        DepthOfMax,
        DepthCoded,
    }
    let out = choose(
        keys,
        "output",
        &[
            ("value", Out::Value),
            ("depth-of-max", Out::DepthOfMax),
            ("depth-coded", Out::DepthCoded),
        ],
        Out::Value,
    );
    let output = match out {
        Out::Value => MipOutput::Value,
        Out::DepthOfMax => MipOutput::DepthOfMax,
        // the pass's colour map colours the depth
        Out::DepthCoded => MipOutput::DepthCoded(keys.colormap()),
    };
    Projection::Mip { depth_cue, output }
}

/// A projection pass's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Maximum intensity projection, optionally depth-cued.
    Mip {
        /// `c` in [0, 1]: each sample is weighted by `1 - c s / D` before the
        /// maximum (`s` the depth from the bounding sphere's entry, `D` its
        /// diameter); 0 = the plain MIP.
        depth_cue: f64,
        /// What is stored.
        output: MipOutput,
    },
    /// Minimum intensity projection.
    Minip,
    /// Path-length weighted mean along the ray.
    Average,
    /// First local maximum above `threshold` (the MIP where the ray never exceeds it).
    Lmip {
        /// Normalised value.
        threshold: f64,
    },
}

impl Mode for Projection {
    fn name(&self) -> &'static str {
        match self {
            Projection::Mip { .. } => "mip",
            Projection::Minip => "minip",
            Projection::Average => "average",
            Projection::Lmip { .. } => "lmip",
        }
    }

    fn is_intensity(&self) -> bool {
        !matches!(
            self,
            Projection::Mip {
                output: MipOutput::DepthCoded(_),
                ..
            }
        )
    }

    fn window_in_values(&self) -> bool {
        !matches!(
            self,
            Projection::Mip {
                output: MipOutput::DepthOfMax,
                ..
            }
        )
    }

    fn level(&self) -> Option<Level> {
        match self {
            Projection::Lmip { threshold } => Some(Level {
                key: "threshold",
                value: *threshold,
            }),
            _ => None,
        }
    }

    fn fit_value(&self, window: Option<[f64; 2]>) -> Option<f64> {
        match self {
            Projection::Lmip { threshold } => Some(*threshold),
            _ => window.map(|w| w[0]),
        }
    }

    fn notes(&self, ctx: &NoteContext<'_>) -> Vec<String> {
        let mut notes = Vec::new();
        if let Some(l) = self.level() {
            notes.push(level_note(l, ctx));
        }
        if let Projection::Mip { depth_cue, output } = *self {
            let d = ctx.sphere_diameter;
            if depth_cue > 0.0 {
                notes.push(format!(
                    "depth cue {depth_cue}: each sample weighted by 1 - {depth_cue} s / {d:.4} (s = depth from the bounding sphere's entry, {d:.4} = its diameter)"
                ));
            }
            match output {
                MipOutput::Value => {}
                MipOutput::DepthOfMax => notes.push(
                    "stores the depth s of the first sample reaching the maximum (NaN where the ray misses)".into(),
                ),
                MipOutput::DepthCoded(map) => {
                    let [lo, hi] = ctx.window.unwrap_or([0.0, 1.0]);
                    notes.push(format!(
                        "depth-coded colour: {} from depth 0 to {d:.4}, brightness from the maximum over [{}, {}]",
                        map.name(),
                        (ctx.show)(lo),
                        (ctx.show)(hi)
                    ));
                }
            }
        }
        notes
    }

    fn plan(&self, ctx: &PassContext) -> Arc<dyn RayMode> {
        let exact = ctx.exact;
        Arc::new(match *self {
            Projection::Mip {
                depth_cue: 0.0,
                output: MipOutput::Value,
            } => ProjectionPass::Mip { exact },
            Projection::Mip { depth_cue, output } => ProjectionPass::CuedMip {
                cued: CuedMip {
                    cue: depth_cue,
                    diameter: ctx.sphere_diameter,
                    output: match output {
                        MipOutput::Value => CuedOutput::Value,
                        MipOutput::DepthOfMax => CuedOutput::Depth,
                        MipOutput::DepthCoded(map) => CuedOutput::Coded {
                            map,
                            window: ctx.window.unwrap_or([0.0, 1.0]).map(|x| x as f32),
                        },
                    },
                },
                exact,
            },
            Projection::Minip => ProjectionPass::Minip { exact },
            Projection::Average => ProjectionPass::Average { exact },
            // the scene takes no `integration` for the local MIP
            Projection::Lmip { threshold } => ProjectionPass::Lmip(Lmip {
                threshold: threshold as f32,
            }),
        })
    }
}

/// A projection pass as it renders.
#[derive(Clone, Copy, Debug)]
enum ProjectionPass {
    Mip { exact: bool },
    CuedMip { cued: CuedMip, exact: bool },
    Minip { exact: bool },
    Average { exact: bool },
    Lmip(Lmip),
}

impl RayMode for ProjectionPass {
    fn kind(&self) -> ImageKind {
        match self {
            ProjectionPass::CuedMip { cued, .. } => match cued.output {
                CuedOutput::Value => ImageKind::Intensity,
                CuedOutput::Depth => ImageKind::Depth,
                CuedOutput::Coded { .. } => ImageKind::Rgba,
            },
            _ => ImageKind::Intensity,
        }
    }

    fn is_exact(&self) -> bool {
        match *self {
            ProjectionPass::Mip { exact }
            | ProjectionPass::CuedMip { exact, .. }
            | ProjectionPass::Minip { exact }
            | ProjectionPass::Average { exact } => exact,
            ProjectionPass::Lmip(_) => false,
        }
    }

    fn skips_zero_cells(&self) -> bool {
        matches!(self, ProjectionPass::Average { .. })
    }

    fn skips(&self) -> &'static str {
        match self {
            ProjectionPass::Mip { exact: false } => {
                "cells that cannot beat the running maximum, walking only where cells are not all zero"
            }
            ProjectionPass::Mip { exact: true } => "cells that cannot beat the running maximum",
            ProjectionPass::CuedMip { .. } => "cells that cannot beat the running weighted maximum",
            ProjectionPass::Minip { .. } => "cells that cannot beat the running minimum",
            ProjectionPass::Average { .. } => "all-zero cells",
            // as its windows are (zero cells, for a threshold above zero)
            ProjectionPass::Lmip(l) if l.window_passes(0, [0.0; 2]).is_some() => {
                "cells that cannot reach the threshold, walking only where cells are not all zero"
            }
            ProjectionPass::Lmip(_) => "cells that cannot reach the threshold",
        }
    }

    fn with_value(&self, value: f32) -> Option<Arc<dyn RayMode>> {
        match self {
            ProjectionPass::Lmip(_) => {
                Some(Arc::new(ProjectionPass::Lmip(Lmip { threshold: value })))
            }
            _ => None,
        }
    }

    fn view<'a>(
        &'a self,
        pass: &'a RenderPass,
        res: &'a Resources<'a>,
    ) -> Box<dyn RenderView + 'a> {
        match *self {
            ProjectionPass::Mip { exact: false } => pass.render_with(res, Mip),
            ProjectionPass::Mip { exact: true } => pass.render_with(res, Exact::Mip),
            ProjectionPass::CuedMip { cued, exact: false } => pass.render_with(res, cued),
            ProjectionPass::CuedMip { cued, exact: true } => {
                pass.render_with(res, Exact::CuedMip(cued))
            }
            ProjectionPass::Minip { exact: false } => pass.render_with(res, Minip),
            ProjectionPass::Minip { exact: true } => pass.render_with(res, Exact::Minip),
            ProjectionPass::Average { exact: false } => pass.render_with(res, Average),
            ProjectionPass::Average { exact: true } => pass.render_with(res, Exact::Average),
            ProjectionPass::Lmip(l) => pass.render_with(res, l),
        }
    }
}
