//! The surface family: the shaded first crossing of an iso value (RGBA, alpha 1
//! where a ray hits).

use std::sync::Arc;

use super::crossing::Surface;
use super::exact::Exact;
use super::{Level, Mode, PassContext, Registration, Shading};
use crate::render::frame::RenderView;
use crate::render::pass::{ImageKind, RayMode, RenderPass, Resources};
use crate::shade::Shader;

/// `mode = "surface"`.
pub const SURFACE: Registration = Registration {
    name: "surface",
    keys: &[
        "iso",
        "material",
        "shading",
        "gradient",
        "integration",
        "jitter",
    ],
    window_in_values: |_| false,
    resolve: |keys| {
        let iso = keys.value("iso", 0.5);
        let shading = keys.shading()?;
        Some(Arc::new(SurfaceSettings { iso, shading }))
    },
};

/// A surface pass's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceSettings {
    /// Normalised iso value.
    pub iso: f64,
    /// Shading settings.
    pub shading: Shading,
}

impl Mode for SurfaceSettings {
    fn name(&self) -> &'static str {
        "surface"
    }

    fn is_intensity(&self) -> bool {
        false
    }

    fn shading(&self) -> Option<&Shading> {
        Some(&self.shading)
    }

    fn level(&self) -> Option<Level> {
        Some(Level {
            key: "iso",
            value: self.iso,
        })
    }

    fn caps_clips(&self) -> bool {
        true
    }

    fn plan(&self, ctx: &PassContext) -> Arc<dyn RayMode> {
        Arc::new(SurfacePass {
            surface: Surface {
                iso: self.iso as f32,
                shader: self.shading.shader(ctx.light),
            },
            exact: ctx.exact,
        })
    }
}

/// A surface pass as it renders: sampled with a refined crossing, or exact.
#[derive(Clone, Copy, Debug)]
struct SurfacePass {
    surface: Surface,
    exact: bool,
}

impl RayMode for SurfacePass {
    fn kind(&self) -> ImageKind {
        ImageKind::Rgba
    }

    fn is_exact(&self) -> bool {
        self.exact
    }

    fn shader(&self) -> Option<&Shader> {
        Some(&self.surface.shader)
    }

    fn with_value(&self, value: f32) -> Option<Arc<dyn RayMode>> {
        Some(Arc::new(SurfacePass {
            surface: Surface {
                iso: value,
                ..self.surface
            },
            exact: self.exact,
        }))
    }

    fn view<'a>(
        &'a self,
        pass: &'a RenderPass,
        res: &'a Resources<'a>,
    ) -> Box<dyn RenderView + 'a> {
        if self.exact {
            pass.render_with(
                res,
                Exact::Surface {
                    iso: self.surface.iso,
                    shader: self.surface.shader,
                },
            )
        } else {
            pass.render_with(res, self.surface)
        }
    }
}
