//! `[[render]]` passes: modes, their keys, methods and shading.

use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::Arc;

use toml::Spanned;

use super::Resolver;
use crate::mode::{self, projection::MipOutput, projection::Projection, Keys, Shading};
use crate::sample::{GradientMethod, Interpolation};
use crate::scene::diag::{quoted_list, suggest};
use crate::scene::schema::{RenderTable, TransferChoice, TransferTable};
use crate::scene::{Integration, RenderPass, SceneVolume, Transfer, Units};
use crate::shade::{Material, Model};
use crate::transfer;

/// The neutral material's name (a white plastic, the default of shaded passes).
pub const NEUTRAL: &str = "neutral";

impl Resolver<'_> {
    pub(super) fn passes(
        &mut self,
        tables: Option<&[Spanned<RenderTable>]>,
        materials: &BTreeMap<String, Material>,
        transfers: &BTreeMap<String, Transfer>,
        transfer_tables: &BTreeMap<String, Spanned<TransferTable>>,
        volumes: &[SceneVolume],
    ) -> Vec<RenderPass> {
        let scene = SceneParts {
            materials,
            transfers,
            transfer_tables,
            volumes,
        };
        let Some(tables) = tables else {
            return vec![RenderPass {
                name: "mip".into(),
                mode: Arc::new(Projection::Mip {
                    depth_cue: 0.0,
                    output: MipOutput::Value,
                }),
                volumes: vec![0],
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
            let Some(p) = self.pass(t, &scene) else {
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
        if volumes.len() > 1 {
            for (k, vol) in volumes.iter().enumerate() {
                if !passes.iter().any(|p| p.volumes.contains(&k)) {
                    self.warnings.push(format!(
                        "volume `{}` is read by no pass: it is not loaded",
                        vol.name
                    ));
                }
            }
        }
        passes
    }

    /// The volume named `name` (at `span`), or an error naming the scene's.
    fn volume_named(
        &mut self,
        key: &str,
        name: &Spanned<String>,
        volumes: &[SceneVolume],
    ) -> Option<usize> {
        let n = name.get_ref();
        if let Some(k) = volumes.iter().position(|v| v.name == *n) {
            return Some(k);
        }
        let names: Vec<&str> = volumes.iter().map(|v| v.name.as_str()).collect();
        let hint = suggest(n, names.iter().copied())
            .map(|s| format!("; did you mean `{s}`?"))
            .unwrap_or_default();
        self.err(
            name.span(),
            format!(
                "{key} = \"{n}\" is not a volume of this scene: its volumes are {}{hint}",
                quoted_list(names.iter().copied())
            ),
        );
        None
    }

    /// The volumes a pass reads: `volume` (default: the first), or a composite's
    /// `volumes` (checked against the scene's names, each once).
    fn pass_volumes(&mut self, v: &RenderTable, volumes: &[SceneVolume]) -> Option<Vec<usize>> {
        match (&v.volume, &v.volumes) {
            (Some(one), Some(list)) => {
                self.err(
                    one.span(),
                    "give `volume` (the one volume a pass reads) or `volumes` (those a composite blends), not both",
                );
                let _ = list;
                None
            }
            (Some(one), None) => Some(vec![self.volume_named("volume", one, volumes)?]),
            (None, Some(list)) => {
                if list.get_ref().is_empty() {
                    self.err(list.span(), "volumes = []: name at least one volume");
                    return None;
                }
                let mut out = Vec::new();
                let mut ok = true;
                for name in list.get_ref() {
                    match self.volume_named("volumes", name, volumes) {
                        Some(k) if out.contains(&k) => {
                            self.err(
                                name.span(),
                                format!("volumes: `{}` is named twice", name.get_ref()),
                            );
                            ok = false;
                        }
                        Some(k) => out.push(k),
                        None => ok = false,
                    }
                }
                ok.then_some(out)
            }
            (None, None) => Some(vec![0]),
        }
    }

    pub(super) fn pass(
        &mut self,
        t: &Spanned<RenderTable>,
        scene: &SceneParts<'_>,
    ) -> Option<RenderPass> {
        let v = t.get_ref();
        let pass_volumes = self.pass_volumes(v, scene.volumes)?;
        // the pass's values are in its own volume's units
        let saved = (self.units, self.window);
        if let Some(&(units, window)) = self.contexts.get(pass_volumes[0]) {
            self.units = units;
            self.window = window;
        }
        let pass = self.pass_of(t, scene, pass_volumes);
        (self.units, self.window) = saved;
        pass
    }

    fn pass_of(
        &mut self,
        t: &Spanned<RenderTable>,
        scene: &SceneParts<'_>,
        volumes: Vec<usize>,
    ) -> Option<RenderPass> {
        let v = t.get_ref();
        let (materials, transfers) = (scene.materials, scene.transfers);
        let Some(mode_s) = &v.mode else {
            self.err(
                t.span(),
                format!(
                    "[[render]] needs `mode`: one of {}",
                    quoted_list(mode::names())
                ),
            );
            return None;
        };
        let mode_name = mode_s.get_ref().as_str();
        let Some(registration) = mode::find(mode_name) else {
            let hint = suggest(mode_name, mode::names())
                .map(|n| format!("; did you mean `{n}`?"))
                .unwrap_or_default();
            self.err(
                mode_s.span(),
                format!(
                    "mode = \"{mode_name}\" is not known: expected one of {}{hint}",
                    quoted_list(mode::names())
                ),
            );
            return None;
        };
        for (key, span) in v.present_keys() {
            if !registration.keys.contains(&key) {
                let users: Vec<&str> = mode::MODES
                    .iter()
                    .filter(|m| m.keys.contains(&key))
                    .map(|m| m.name)
                    .collect();
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
            let output = v.output.as_ref().map(|o| o.get_ref().as_str());
            if !(registration.window_in_values)(output) || self.units == Units::Normalised {
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
        let mode = (registration.resolve)(&mut PassKeys {
            resolver: self,
            table: t,
            name: &name,
            colormap: map,
            materials,
            transfers,
            scene,
            volumes: &volumes,
        })?;
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
        let colormap = (v.colormap.is_some() && mode.is_intensity()).then_some(map);
        Some(RenderPass {
            name,
            mode,
            volumes,
            step_voxels,
            interpolation,
            window,
            integration,
            jitter,
            colormap,
        })
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

/// The field of the mode-specific string key `key` (`None`: not one).
fn string_key<'t>(v: &'t RenderTable, key: &str) -> Option<&'t Option<Spanned<String>>> {
    Some(match key {
        "output" => &v.output,
        "colormap" => &v.colormap,
        "material" => &v.material,
        "shading" => &v.shading,
        "gradient" => &v.gradient,
        _ => return None,
    })
}

/// The field of the mode-specific boolean key `key` (`None`: not one).
fn bool_key<'t>(v: &'t RenderTable, key: &str) -> Option<&'t Option<Spanned<bool>>> {
    Some(match key {
        "preintegrated" => &v.preintegrated,
        "jitter" => &v.jitter,
        _ => return None,
    })
}

/// What passes refer to: the scene's materials, transfer functions (resolved in
/// the first volume's units, and as written) and volumes.
pub(super) struct SceneParts<'a> {
    materials: &'a BTreeMap<String, Material>,
    transfers: &'a BTreeMap<String, Transfer>,
    transfer_tables: &'a BTreeMap<String, Spanned<TransferTable>>,
    volumes: &'a [SceneVolume],
}

/// One pass's keys as its mode reads them ([`mode::Keys`]): each read goes through
/// the resolver's checks, so messages are the scene's own.
struct PassKeys<'r, 'a, 't> {
    resolver: &'r mut Resolver<'a>,
    table: &'t Spanned<RenderTable>,
    name: &'t str,
    colormap: transfer::Colormap,
    materials: &'t BTreeMap<String, Material>,
    transfers: &'t BTreeMap<String, Transfer>,
    scene: &'t SceneParts<'t>,
    /// The volumes the pass reads (the first is its own).
    volumes: &'t [usize],
}

impl PassKeys<'_, '_, '_> {
    fn numeric(&self, key: &str) -> &'_ Option<Spanned<f64>> {
        let v = self.table.get_ref();
        match key {
            "mu" => &v.mu,
            "depth_cue" => &v.depth_cue,
            "threshold" => &v.threshold,
            "iso" => &v.iso,
            "reference_step" => &v.reference_step,
            "early_stop" => &v.early_stop,
            _ => unreachable!("`{key}` is not a numeric key of [[render]]"),
        }
    }

    fn string(&self, key: &str) -> &'_ Option<Spanned<String>> {
        string_key(self.table.get_ref(), key)
            .unwrap_or_else(|| unreachable!("`{key}` is not a string key of [[render]]"))
    }

    /// Where `key` is written (the pass's table where it is absent).
    fn span(&self, key: &str) -> Range<usize> {
        let v = self.table.get_ref();
        let at = match (string_key(v, key), bool_key(v, key)) {
            (Some(s), _) => s.as_ref().map(|s| s.span()),
            (_, Some(b)) => b.as_ref().map(|b| b.span()),
            _ if key == "transfer" => v.transfer.as_ref().map(|s| s.span()),
            _ if key == "volumes" => v.volumes.as_ref().map(|s| s.span()),
            _ => self.numeric(key).as_ref().map(|s| s.span()),
        };
        at.unwrap_or_else(|| self.table.span())
    }
}

impl Keys for PassKeys<'_, '_, '_> {
    fn pass_name(&self) -> &str {
        self.name
    }

    fn number(&mut self, key: &str, default: f64, ok: fn(f64) -> bool, expected: &str) -> f64 {
        let v = self.numeric(key).clone();
        self.resolver.number(key, &v, default, ok, expected)
    }

    fn value(&mut self, key: &str, default: f64) -> f64 {
        let v = self.numeric(key).clone();
        self.resolver.value(key, &v, default)
    }

    fn pick(&mut self, key: &str, names: &[&str], default: usize) -> usize {
        let options: Vec<(&str, usize)> = names.iter().copied().zip(0..).collect();
        let v = self.string(key).clone();
        self.resolver.choice(key, &v, &options, default)
    }

    fn flag(&self, key: &str) -> bool {
        bool_key(self.table.get_ref(), key)
            .is_some_and(|b| b.as_ref().is_some_and(|b| *b.get_ref()))
    }

    fn colormap(&self) -> transfer::Colormap {
        self.colormap
    }

    fn shading(&mut self) -> Option<Shading> {
        self.resolver
            .shading(self.table.get_ref(), self.materials, Model::Phong)
    }

    fn text(&self, key: &str) -> Option<&str> {
        if key == "transfer" {
            return match self.table.get_ref().transfer.as_ref().map(|t| t.get_ref()) {
                Some(TransferChoice::Name(n)) => Some(n.as_str()),
                _ => None,
            };
        }
        string_key(self.table.get_ref(), key)?
            .as_ref()
            .map(|s| s.get_ref().as_str())
    }

    fn transfer(&mut self) -> Option<(String, Transfer)> {
        let mut all = self.transfers()?;
        Some(all.remove(0))
    }

    fn transfers(&mut self) -> Option<Vec<(String, Transfer)>> {
        let v = self.table.get_ref();
        let span = self.span("transfer");
        let volumes = self.scene.volumes;
        // the transfer function's name for each volume the pass reads
        let names: Vec<(String, Range<usize>)> = match v.transfer.as_ref().map(|t| t.get_ref()) {
            None if self.volumes.len() == 1 => vec![("grey".to_string(), span.clone())],
            Some(TransferChoice::Name(n)) if self.volumes.len() == 1 => {
                vec![(n.clone(), span.clone())]
            }
            None | Some(TransferChoice::Name(_)) => {
                let list: Vec<String> = self
                    .volumes
                    .iter()
                    .map(|&k| format!("{} = \"...\"", volumes[k].name))
                    .collect();
                self.resolver.err(span, format!(
                    "a composite of several volumes takes one transfer function per volume: transfer = {{ {} }}",
                    list.join(", ")
                ));
                return None;
            }
            Some(TransferChoice::PerVolume(table)) => {
                let mut ok = true;
                for key in table.keys() {
                    if !self.volumes.iter().any(|&k| volumes[k].name == *key) {
                        let read: Vec<&str> = self
                            .volumes
                            .iter()
                            .map(|&k| volumes[k].name.as_str())
                            .collect();
                        self.resolver.err(span.clone(), format!(
                            "transfer: `{key}` is not a volume this pass reads (it reads {}; list the volumes a composite blends in `volumes`)",
                            quoted_list(read.iter().copied())
                        ));
                        ok = false;
                    }
                }
                let mut names = Vec::new();
                for &k in self.volumes {
                    match table.get(&volumes[k].name) {
                        Some(n) => names.push((n.clone(), span.clone())),
                        None => {
                            self.resolver.err(span.clone(), format!(
                                "transfer has no transfer function for volume `{}`: give one for each volume the pass reads (transfer = {{ {} = \"...\", ... }})",
                                volumes[k].name, volumes[k].name
                            ));
                            ok = false;
                        }
                    }
                }
                if !ok {
                    return None;
                }
                names
            }
        };
        let mut out = Vec::new();
        for (&k, (name, at)) in self.volumes.iter().zip(names) {
            out.push((name.clone(), self.transfer_for(k, &name, at)?));
        }
        Some(out)
    }

    fn error(&mut self, key: &str, message: String) {
        let span = self.span(key);
        self.resolver.err(span, message);
    }

    fn warn(&mut self, message: String) {
        self.resolver.warnings.push(message);
    }
}

impl PassKeys<'_, '_, '_> {
    /// The transfer function `name` for volume `k`: as resolved in the first
    /// volume's units, or, for a volume with units of its own, resolved again in
    /// those (its knots, or a preset's, placed on that volume's window).
    fn transfer_for(&mut self, k: usize, name: &str, span: Range<usize>) -> Option<Transfer> {
        let r = &mut *self.resolver;
        let own = r.contexts.get(k).copied();
        // the first volume with the same units and window
        let context = r.contexts.iter().position(|c| Some(*c) == own).unwrap_or(0);
        let table = self.scene.transfer_tables.get(name);
        let lazy = table.is_some() && !self.transfers.contains_key(name);
        if own == r.contexts.first().copied() && !lazy {
            return match self.transfers.get(name) {
                Some(tf) => Some(tf.clone()),
                None => r.preset(name, self.transfers, span),
            };
        }
        if let Some(tf) = r.transfer_cache.get(&(name.to_string(), context)) {
            return tf.clone();
        }
        let saved = (r.units, r.window);
        if let Some((units, window)) = own {
            r.units = units;
            r.window = window;
        }
        let before = r.diags.len();
        let tf = match table {
            Some(table) => r.transfer(name, table),
            None if self.transfers.contains_key(name) => self.transfers.get(name).cloned(),
            None => r.preset(name, self.transfers, span),
        };
        r.transfer_cache
            .insert((name.to_string(), context), tf.clone());
        let several = r.contexts.iter().any(|c| Some(c) != r.contexts.first());
        let volume = &self.scene.volumes[k].name;
        if several {
            for d in &mut r.diags[before..] {
                d.message = format!("for volume `{volume}`: {}", d.message);
            }
        }
        (r.units, r.window) = saved;
        tf
    }
}
