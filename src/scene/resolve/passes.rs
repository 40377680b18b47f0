//! `[[render]]` passes: modes, their keys, methods and shading.

use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::Arc;

use toml::Spanned;

use super::Resolver;
use crate::sample::{GradientMethod, Interpolation};
use crate::scene::diag::{quoted_list, suggest};
use crate::scene::schema::RenderTable;
use crate::scene::{
    Integration, MipOutput, Mode, RenderPass, Shading, Transfer, Units, XrayOutput,
};
use crate::shade::{Material, Model};
use crate::transfer;

/// Which render modes use each mode-specific key of `[[render]]`.
const MODE_KEYS: &[(&str, &[&str])] = &[
    ("output", &["xray", "mip"]),
    ("mu", &["xray"]),
    ("depth_cue", &["mip"]),
    (
        "colormap",
        &["xray", "mip", "minip", "average", "lmip", "depth"],
    ),
    ("threshold", &["lmip", "depth"]),
    ("iso", &["surface"]),
    ("material", &["surface", "composite"]),
    ("shading", &["surface", "composite"]),
    ("gradient", &["surface", "composite"]),
    ("transfer", &["composite"]),
    ("reference_step", &["composite"]),
    ("early_stop", &["composite"]),
    (
        "window",
        &["xray", "mip", "minip", "average", "lmip", "depth"],
    ),
    (
        "integration",
        &["xray", "mip", "minip", "average", "depth", "surface"],
    ),
    ("jitter", MODES),
    ("preintegrated", &["composite"]),
];

use super::super::MODE_NAMES as MODES;

/// The neutral material's name (a white plastic, the default of shaded passes).
pub const NEUTRAL: &str = "neutral";

impl Resolver<'_> {
    pub(super) fn passes(
        &mut self,
        tables: Option<&[Spanned<RenderTable>]>,
        materials: &BTreeMap<String, Material>,
        transfers: &BTreeMap<String, Transfer>,
    ) -> Vec<RenderPass> {
        let Some(tables) = tables else {
            return vec![RenderPass {
                name: "mip".into(),
                mode: Mode::Mip {
                    depth_cue: 0.0,
                    output: MipOutput::Value,
                },
                step_voxels: 0.5,
                interpolation: Interpolation::Trilinear,
                window: None,
                integration: Integration::Sampled,
                jitter: false,
                colormap: None,
            }];
        };
        if tables.is_empty() {
            self.warnings
                .push("the scene has no [[render]] pass: nothing will be rendered".into());
        }
        let mut passes: Vec<RenderPass> = Vec::new();
        let mut names: BTreeMap<String, Range<usize>> = BTreeMap::new();
        for t in tables {
            let Some(p) = self.pass(t, materials, transfers) else {
                continue;
            };
            let span = t.get_ref().name.as_ref().map_or(t.span(), |n| n.span());
            if names.contains_key(&p.name) {
                self.err(span, format!("two passes are named `{}`: their files would overwrite each other; give each pass its own `name`", p.name));
            } else {
                names.insert(p.name.clone(), span);
            }
            passes.push(p);
        }
        passes
    }

    pub(super) fn pass(
        &mut self,
        t: &Spanned<RenderTable>,
        materials: &BTreeMap<String, Material>,
        transfers: &BTreeMap<String, Transfer>,
    ) -> Option<RenderPass> {
        let v = t.get_ref();
        let Some(mode_s) = &v.mode else {
            self.err(
                t.span(),
                format!(
                    "[[render]] needs `mode`: one of {}",
                    quoted_list(MODES.iter().copied())
                ),
            );
            return None;
        };
        let mode_name = mode_s.get_ref().as_str();
        if !MODES.contains(&mode_name) {
            let hint = suggest(mode_name, MODES.iter().copied())
                .map(|n| format!("; did you mean `{n}`?"))
                .unwrap_or_default();
            self.err(
                mode_s.span(),
                format!(
                    "mode = \"{mode_name}\" is not known: expected one of {}{hint}",
                    quoted_list(MODES.iter().copied())
                ),
            );
            return None;
        }
        for (key, span) in v.present_keys() {
            let users = MODE_KEYS
                .iter()
                .find(|(k, _)| *k == key)
                .map_or(&[][..], |(_, m)| *m);
            if !users.contains(&mode_name) {
                self.err(
                    span,
                    format!(
                        "`{key}` is not used by mode = \"{mode_name}\"; it is used by {}",
                        users
                            .iter()
                            .map(|m| format!("\"{m}\""))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                );
            }
        }
        let name = match &v.name {
            None => mode_name.to_string(),
            Some(n) if valid_file_stem(n.get_ref()) => n.get_ref().clone(),
            Some(n) => {
                self.err(n.span(), format!("name = \"{}\": expected a file-name prefix of letters, digits, '-', '_' and '.'", n.get_ref()));
                mode_name.to_string()
            }
        };
        let integration = self.choice(
            "integration",
            &v.integration,
            &[
                ("sampled", Integration::Sampled),
                ("exact", Integration::Exact),
            ],
            Integration::Sampled,
        );
        let jitter = v.jitter.as_ref().is_some_and(|j| *j.get_ref());
        let step_voxels = self.number(
            "step",
            &v.step,
            0.5,
            |x| (1e-4..=1e4).contains(&x),
            "a sample spacing in voxels, from 0.0001 to 10000",
        );
        let interpolation = self.choice(
            "interpolation",
            &v.interpolation,
            &[
                ("nearest", Interpolation::Nearest),
                ("trilinear", Interpolation::Trilinear),
                ("cubic", Interpolation::Cubic),
                ("bspline", Interpolation::BSpline),
            ],
            Interpolation::Trilinear,
        );
        let window = self.window("window", &v.window).and_then(|w| {
            // the grey window of a value-based pass is on the value axis
            // (a MIP's depth of the maximum is a distance, like a depth pass's)
            let distance = v.output.as_ref().map(|o| o.get_ref().as_str()) == Some("depth-of-max");
            if !matches!(mode_name, "mip" | "minip" | "average" | "lmip")
                || distance
                || self.units == Units::Normalised
            {
                return Some(w);
            }
            let span = v.window.as_ref().map(|s| s.span()).unwrap_or_default();
            let lo = self.value_at("window[0]", w[0], span.clone())?;
            let hi = self.value_at("window[1]", w[1], span)?;
            Some([lo, hi])
        });
        self.check_method(v, integration, interpolation, jitter);
        let map = self.choice(
            "colormap",
            &v.colormap,
            crate::transfer::Colormap::ALL,
            crate::transfer::Colormap::Turbo,
        );
        let mode = match mode_name {
            "xray" => Mode::Xray {
                output: self.choice(
                    "output",
                    &v.output,
                    &[
                        ("integral", XrayOutput::Integral),
                        ("absorbed", XrayOutput::Absorbed),
                        ("transmitted", XrayOutput::Transmitted),
                    ],
                    XrayOutput::Integral,
                ),
                mu: self.number("mu", &v.mu, 1.0, |x| x >= 0.0, "an attenuation scale >= 0"),
            },
            "mip" => self.mip(v, map),
            "minip" => Mode::Minip,
            "average" => Mode::Average,
            "lmip" => Mode::Lmip {
                threshold: self.value("threshold", &v.threshold, 0.5),
            },
            "depth" => Mode::Depth {
                threshold: self.value("threshold", &v.threshold, 0.5),
            },
            "surface" => Mode::Surface {
                iso: self.value("iso", &v.iso, 0.5),
                shading: self.shading(v, materials, Model::Phong)?,
            },
            _ => {
                let shaded = v.shading.as_ref().is_some_and(|s| s.get_ref() != "none");
                if !shaded {
                    for (k, s) in [("material", &v.material), ("gradient", &v.gradient)] {
                        if let Some(s) = s {
                            self.warnings.push(format!(
                                "pass `{name}`: `{k} = \"{}\"` has no effect with shading = \"none\"",
                                s.get_ref()
                            ));
                        }
                    }
                }
                let shading = if shaded {
                    Some(self.shading(v, materials, Model::Phong)?)
                } else {
                    None
                };
                let transfer_name = v
                    .transfer
                    .as_ref()
                    .map_or("grey".to_string(), |t| t.get_ref().clone());
                let span = v.transfer.as_ref().map_or(t.span(), |s| s.span());
                let transfer = match transfers.get(&transfer_name) {
                    Some(tf) => tf.clone(),
                    None => self.preset(&transfer_name, transfers, span)?,
                };
                let preintegrated = v.preintegrated.as_ref().is_some_and(|p| *p.get_ref());
                if let (true, Transfer::TwoD(_), Some(p)) =
                    (preintegrated, &transfer, &v.preintegrated)
                {
                    self.err(p.span(), format!(
                        "preintegrated = true needs a 1D transfer function, but `{transfer_name}` is 2D (value x gradient magnitude); pre-integration tabulates segments over (front value, back value)"
                    ));
                }
                if let Transfer::OneD(tf) = &transfer {
                    if tf.max_alpha() == 0.0 {
                        self.warnings.push(format!(
                            "pass `{name}`: transfer function `{transfer_name}` has zero alpha everywhere: the image will be empty"
                        ));
                    }
                }
                Mode::Composite {
                    transfer_name,
                    transfer,
                    shading,
                    reference_step_voxels: self.number(
                        "reference_step",
                        &v.reference_step,
                        1.0,
                        |x| x > 0.0,
                        "a positive step in voxels",
                    ),
                    early_stop: self.number(
                        "early_stop",
                        &v.early_stop,
                        0.99,
                        |x| x > 0.0 && x <= 1.0,
                        "an opacity in (0, 1]",
                    ),
                    preintegrated,
                }
            }
        };
        if let (Some(sh), Some(g)) = (mode.shading(), &v.gradient) {
            if sh.gradient == GradientMethod::Analytic
                && !matches!(interpolation, Interpolation::Cubic | Interpolation::BSpline)
            {
                self.err(g.span(), format!(
                    "gradient = \"analytic\" is the derivative of the cubic spline: it needs interpolation = \"cubic\" or \"bspline\" (this pass has \"{}\"); with {} use gradient = \"central\" or \"sobel\"",
                    interpolation.name(),
                    interpolation.name()
                ));
            }
        }
        // a depth-coded MIP's map colours the depth; every other intensity pass's
        // colours its windowed value
        let depth_coded = matches!(
            mode,
            Mode::Mip {
                output: MipOutput::DepthCoded(_),
                ..
            }
        );
        let colormap = (v.colormap.is_some() && !depth_coded).then_some(map);
        Some(RenderPass {
            name,
            mode,
            step_voxels,
            interpolation,
            window,
            integration,
            jitter,
            colormap,
        })
    }

    /// A MIP pass's depth cue and output; `map` colours the depth of a depth-coded one.
    fn mip(&mut self, v: &RenderTable, map: crate::transfer::Colormap) -> Mode {
        let depth_cue = self.number(
            "depth_cue",
            &v.depth_cue,
            0.0,
            |c| (0.0..=1.0).contains(&c),
            "a weight from 0 (no depth cue) to 1 (the far side of the bounding sphere weighted 0)",
        );
        #[derive(Clone, Copy)]
        enum Out {
            Value,
            DepthOfMax,
            DepthCoded,
        }
        let out = self.choice(
            "output",
            &v.output,
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
            Out::DepthCoded => MipOutput::DepthCoded(map),
        };
        Mode::Mip { depth_cue, output }
    }

    /// The transfer-function preset `name` placed on the volume's window, or an error
    /// at `span` (not a preset, or no window to place its data values with).
    fn preset(
        &mut self,
        name: &str,
        transfers: &BTreeMap<String, Transfer>,
        span: Range<usize>,
    ) -> Option<Transfer> {
        let Some(preset) = transfer::Preset::find(name) else {
            let names: Vec<&str> = transfers
                .keys()
                .map(|s| s.as_str())
                .chain(transfer::PRESETS.iter().map(|p| p.name))
                .collect();
            let hint = suggest(name, names.iter().copied())
                .map(|n| format!("; did you mean `{n}`?"))
                .unwrap_or_default();
            self.err(span, format!(
                "transfer = \"{name}\" is not defined: add a [transfer.{name}] table, or use one of {}{hint}",
                quoted_list(names.iter().copied())
            ));
            return None;
        };
        let Some([lo, hi]) = self.window else {
            self.err(span, format!(
                "transfer = \"{name}\" is a preset with knots in data values (Slicer's {}): it needs `window = [lo, hi]` in [volume], the data values its knots are placed on (for CT in Hounsfield units, e.g. window = [-1024, 3071])",
                preset.slicer
            ));
            return None;
        };
        match preset.transfer(lo, hi) {
            Ok(tf) => Some(Transfer::OneD(Arc::new(tf))),
            Err(e) => {
                self.err(
                    span,
                    format!("transfer = \"{name}\" on the window [{lo}, {hi}]: {e}"),
                );
                None
            }
        }
    }

    /// Combinations of integration, interpolation and jitter that do not work.
    pub(super) fn check_method(
        &mut self,
        v: &RenderTable,
        integration: Integration,
        interpolation: Interpolation,
        jitter: bool,
    ) {
        if integration != Integration::Exact {
            return;
        }
        let Some(span) = v.integration.as_ref().map(|s| s.span()) else {
            return;
        };
        if interpolation != Interpolation::Trilinear {
            let at = v.interpolation.as_ref().map_or(span.clone(), |s| s.span());
            self.err(at, format!(
                "integration = \"exact\" integrates the trilinear interpolant in closed form: it needs interpolation = \"trilinear\" (this pass has \"{}\"); for {} use integration = \"sampled\"",
                interpolation.name(),
                interpolation.name()
            ));
        }
        if let (true, Some(j)) = (jitter, &v.jitter) {
            self.err(j.span(), "jitter = true moves the samples of integration = \"sampled\"; integration = \"exact\" takes no samples (it walks the cells): remove one of them");
        }
    }

    pub(super) fn shading(
        &mut self,
        v: &RenderTable,
        materials: &BTreeMap<String, Material>,
        default: Model,
    ) -> Option<Shading> {
        let model = self.choice(
            "shading",
            &v.shading,
            &[
                ("phong", Some(Model::Phong)),
                ("blinn-phong", Some(Model::BlinnPhong)),
                ("cook-torrance", Some(Model::CookTorrance)),
                ("none", None),
            ],
            Some(default),
        );
        let Some(model) = model else {
            // only composite accepts "none"; surface must shade
            let s = v.shading.as_ref()?;
            self.err(s.span(), "shading = \"none\" is not available for mode = \"surface\": use phong, blinn-phong or cook-torrance");
            return None;
        };
        let gradient = self.choice(
            "gradient",
            &v.gradient,
            &[
                ("central", GradientMethod::Central),
                ("sobel", GradientMethod::Sobel),
                ("analytic", GradientMethod::Analytic),
            ],
            GradientMethod::Central,
        );
        let (material, material_name) = match &v.material {
            None => (Material::neutral(), NEUTRAL.to_string()),
            Some(m) => {
                let n = m.get_ref().as_str();
                if let Some(mat) = materials.get(n) {
                    (*mat, n.to_string())
                } else if let Some(mat) = Material::preset(n) {
                    (mat, n.to_string())
                } else if n == NEUTRAL {
                    (Material::neutral(), NEUTRAL.to_string())
                } else {
                    let all: Vec<&str> = Material::PRESET_NAMES
                        .iter()
                        .copied()
                        .chain([NEUTRAL])
                        .chain(materials.keys().map(|s| s.as_str()))
                        .collect();
                    let hint = suggest(n, all.iter().copied())
                        .map(|s| format!("; did you mean `{s}`?"))
                        .unwrap_or_default();
                    self.err(m.span(), format!("material = \"{n}\" is not defined: use a preset ({}) or add a [material.{n}] table{hint}", quoted_list(all.iter().copied())));
                    return None;
                }
            }
        };
        Some(Shading {
            model,
            material,
            material_name,
            gradient,
        })
    }
}

fn valid_file_stem(s: &str) -> bool {
    !s.is_empty()
        && !s.starts_with('.')
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
}
