//! The X-ray family: the line integral of the value along each ray, stored as the
//! integral itself, the absorbed or the transmitted fraction (Beer-Lambert).

pub mod integrator;

use std::sync::Arc;

pub use integrator::{Xray, XrayOutput};

use super::exact::Exact;
use super::{choose, Keys, Mode, PassContext, Registration};
use crate::render::frame::RenderView;
use crate::render::pass::{ImageKind, RayMode, RenderPass, Resources};

/// `mode = "xray"`.
pub const XRAY: Registration = Registration {
    name: "xray",
    keys: &[
        "output",
        "mu",
        "colormap",
        "window",
        "integration",
        "jitter",
    ],
    window_in_values: |_| false,
    resolve: |keys| Some(Arc::new(resolve(keys))),
};

fn resolve(keys: &mut dyn Keys) -> XraySettings {
    XraySettings {
        output: choose(
            keys,
            "output",
            &[
                ("integral", XrayOutput::Integral),
                ("absorbed", XrayOutput::Absorbed),
                ("transmitted", XrayOutput::Transmitted),
            ],
            XrayOutput::Integral,
        ),
        mu: keys.number("mu", 1.0, |x| x >= 0.0, "an attenuation scale >= 0"),
    }
}

/// An X-ray pass's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct XraySettings {
    /// Stored quantity.
    pub output: XrayOutput,
    /// Attenuation scale.
    pub mu: f64,
}

impl Mode for XraySettings {
    fn name(&self) -> &'static str {
        "xray"
    }

    fn manifest(&self) -> serde_json::Map<String, serde_json::Value> {
        let mut m = serde_json::Map::new();
        m.insert(
            "output".into(),
            format!("{:?}", self.output).to_lowercase().into(),
        );
        m.insert("mu".into(), self.mu.into());
        m
    }

    fn plan(&self, ctx: &PassContext) -> Arc<dyn RayMode> {
        Arc::new(XrayPass {
            xray: Xray {
                output: self.output,
                mu: self.mu,
            },
            exact: ctx.exact,
        })
    }
}

/// An X-ray pass as it renders: sampled by the trapezoid rule, or exact.
#[derive(Clone, Copy, Debug)]
struct XrayPass {
    xray: Xray,
    exact: bool,
}

impl RayMode for XrayPass {
    fn kind(&self) -> ImageKind {
        ImageKind::Intensity
    }

    fn is_exact(&self) -> bool {
        self.exact
    }

    fn skips_zero_cells(&self) -> bool {
        true
    }

    fn skips(&self) -> &'static str {
        "all-zero cells"
    }

    fn view<'a>(
        &'a self,
        pass: &'a RenderPass,
        res: &'a Resources<'a>,
    ) -> Box<dyn RenderView + 'a> {
        if self.exact {
            pass.render_with(
                res,
                Exact::Xray {
                    output: self.xray.output,
                    mu: self.xray.mu,
                },
            )
        } else {
            pass.render_with(res, self.xray)
        }
    }
}
