//! The depth family: the distance along each ray to the first crossing of a
//! threshold (near shown bright).

use std::sync::Arc;

use super::crossing::Depth;
use super::exact::Exact;
use super::{Level, Mode, PassContext, Registration};
use crate::render::frame::RenderView;
use crate::render::pass::{ImageKind, RayMode, RenderPass, Resources};

/// `mode = "depth"`.
pub const DEPTH: Registration = Registration {
    name: "depth",
    keys: &["colormap", "threshold", "window", "integration", "jitter"],
    window_in_values: |_| false,
    resolve: |keys| {
        Some(Arc::new(DepthSettings {
            threshold: keys.value("threshold", 0.5),
        }))
    },
};

/// A depth pass's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthSettings {
    /// Normalised value.
    pub threshold: f64,
}

impl Mode for DepthSettings {
    fn name(&self) -> &'static str {
        "depth"
    }

    fn level(&self) -> Option<Level> {
        Some(Level {
            key: "threshold",
            value: self.threshold,
        })
    }

    fn caps_clips(&self) -> bool {
        true
    }

    fn plan(&self, ctx: &PassContext) -> Arc<dyn RayMode> {
        Arc::new(DepthPass {
            depth: Depth {
                threshold: self.threshold as f32,
            },
            exact: ctx.exact,
        })
    }
}

/// A depth pass as it renders: sampled with a refined crossing, or exact.
#[derive(Clone, Copy, Debug)]
struct DepthPass {
    depth: Depth,
    exact: bool,
}

impl RayMode for DepthPass {
    fn kind(&self) -> ImageKind {
        ImageKind::Depth
    }

    fn is_exact(&self) -> bool {
        self.exact
    }

    fn with_value(&self, value: f32) -> Option<Arc<dyn RayMode>> {
        Some(Arc::new(DepthPass {
            depth: Depth { threshold: value },
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
                Exact::Depth {
                    threshold: self.depth.threshold,
                },
            )
        } else {
            pass.render_with(res, self.depth)
        }
    }
}
