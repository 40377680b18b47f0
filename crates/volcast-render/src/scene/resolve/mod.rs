//! From what the user wrote ([`super::schema`]) to what it means ([`super::Scene`]):
//! defaults, ranges, names, cross-references and mode-specific keys. Every problem
//! is collected with its place in the file; the scene is returned only if there
//! are none. One submodule per part of the scene: [`volume`], [`view`] (camera,
//! orbit, image, stereo, animation, viewer, light), [`appearance`] (materials and
//! transfer functions), [`passes`], [`clip`] and [`keyframes`].

mod appearance;
mod clip;
mod keyframes;
mod labels;
mod passes;
mod view;
mod volume;

use crate::number::shown;
use std::ops::Range;
use std::path::Path;

use glam::DVec3;
use toml::Spanned;

use super::diag::{quoted_list, suggest, with_suggestion, Diagnostic, SceneError};
use super::schema::{SceneFile, Sp};
use super::{Scene, Units};

struct Resolver<'a> {
    diags: Vec<Diagnostic>,
    warnings: Vec<String>,
    base_dir: &'a Path,
    /// `[volume] units`, once the volume is resolved.
    units: Units,
    /// `[volume] window` (or a synthetic field's default), once the volume is
    /// resolved: what places the data-unit knots of transfer-function presets.
    window: Option<[f64; 2]>,
    /// Each volume's units and window, in the order of the scene's volumes: a
    /// pass's values are written in its volume's.
    contexts: Vec<(Units, Option<[f64; 2]>)>,
    /// Transfer functions resolved per (name, volume context), where the volumes
    /// have units of their own: each table is read in the units of the volumes
    /// whose passes use it.
    transfer_cache: std::collections::BTreeMap<(String, usize), Option<super::Transfer>>,
}

pub fn resolve(text: &str, path: &Path) -> Result<Scene, SceneError> {
    let fail = |diags: Vec<Diagnostic>| SceneError {
        path: path.to_path_buf(),
        text: text.to_string(),
        diagnostics: diags,
    };
    let (file, mut diags, removed) = deserialize_all(text);
    let Some(file) = file else {
        return Err(fail(diags));
    };
    let base_dir = path.parent().unwrap_or(Path::new("."));
    let mut r = Resolver {
        diags: Vec::new(),
        warnings: Vec::new(),
        base_dir,
        units: Units::Normalised,
        window: None,
        contexts: Vec::new(),
        transfer_cache: Default::default(),
    };
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    let volumes = r.volumes(&file.volume);
    let camera = r.camera(file.camera.as_ref());
    let mut orbit = r.orbit(file.orbit.as_ref());
    let image = r.image(file.image.as_ref(), &name, camera.projection);
    let stereo = file
        .stereo
        .as_ref()
        .map(|s| r.stereo(s, image.format, camera.projection));
    let animation = file
        .animation
        .as_ref()
        .map(|a| r.animation(a, image.format));
    let viewer = file
        .viewer
        .as_ref()
        .is_some_and(|v| r.viewer(v, image.format));
    let light = r.light(file.light.as_ref());
    let materials = r.materials(&file.material);
    // with volumes of several units, each table is read in the units of the
    // volumes that use it (when a pass does), not once in the first volume's
    let lazy = r.contexts.iter().any(|c| Some(c) != r.contexts.first());
    let no_tables = Default::default();
    let transfers = r.transfers(if lazy { &no_tables } else { &file.transfer });
    let passes = r.passes(
        file.render.as_deref(),
        &materials,
        &transfers,
        &file.transfer,
        &volumes,
    );
    if lazy {
        // the tables no pass read: checked in the first volume's units
        for (name, t) in &file.transfer {
            if !r.transfer_cache.keys().any(|(n, _)| n == name) {
                let _ = r.transfer(name, t);
            }
        }
    }
    let clips = r.clips(file.clip.as_deref(), &passes);
    let keyframes = r.keyframes(
        file.keyframe.as_deref(),
        file.orbit.as_ref(),
        &mut orbit,
        &passes,
        &clips,
        camera.fit.is_some(),
    );
    let labels = r.labels(file.label.as_deref(), &image, &passes);
    // "needs `key`" adds nothing when `key` was given but of the wrong type
    diags.extend(r.diags.into_iter().filter(|d| {
        !(d.message.contains("needs")
            && removed
                .iter()
                .any(|k| d.message.contains(&format!("`{k}`"))))
    }));
    if !diags.is_empty() {
        diags.sort_by_key(|d| d.span.as_ref().map_or(0, |s| s.start));
        // (a table read for several volumes reports each problem once)
        diags.dedup_by(|a, b| a.span == b.span && a.message == b.message);
        return Err(fail(diags));
    }
    Ok(Scene {
        path: path.to_path_buf(),
        name,
        volumes,
        camera,
        orbit,
        stereo,
        image,
        passes,
        light,
        clips,
        keyframes,
        labels,
        animation,
        viewer,
        text: text.to_string(),
        warnings: r.warnings,
    })
}

/// Most problems of the serde stage reported for one file (each costs one more pass
/// over the parsed document).
const MAX_SCHEMA_PROBLEMS: usize = 50;

/// Deserializes the scene, collecting every problem of the schema stage (unknown
/// keys, values of the wrong type) instead of stopping at the first: after each
/// error, the entry it points at is taken out of the parsed document and the rest is
/// deserialized again. Returns the scene as written when what is left deserializes
/// (so the resolver can report its own problems too), the problems found, and the
/// keys taken out.
fn deserialize_all(text: &str) -> (Option<SceneFile>, Vec<Diagnostic>, Vec<String>) {
    use serde::Deserialize as _;
    let mut doc = match toml::de::DeTable::parse(text) {
        Ok(d) => d,
        Err(e) => return (None, vec![schema_diagnostic(&e, text)], Vec::new()),
    };
    let mut diags = Vec::new();
    let mut removed = Vec::new();
    for _ in 0..MAX_SCHEMA_PROBLEMS {
        let e = match SceneFile::deserialize(toml::de::Deserializer::from(doc.clone())) {
            Ok(f) => return (Some(f), diags, removed),
            Err(e) => e,
        };
        // A required key missing only because a bad one was taken out adds nothing.
        if !diags.is_empty() && e.message().starts_with("missing field") {
            return (None, diags, removed);
        }
        diags.push(schema_diagnostic(&e, text));
        match e.span().and_then(|span| remove_entry(doc.get_mut(), &span)) {
            Some(key) => removed.push(key),
            None => return (None, diags, removed),
        }
    }
    (None, diags, removed)
}

/// A diagnostic for a TOML or schema error, with a place in the file whenever the
/// error gives one (else the end of the file, for errors such as an unclosed string
/// at the end, or its start).
fn schema_diagnostic(e: &toml::de::Error, text: &str) -> Diagnostic {
    let message = match e.message() {
        "missing field `volume`" => "missing [volume] table: every scene needs one, with `path` (a .nrrd/.nhdr or raw file) or `synthetic`".to_string(),
        m if m.contains("recursion") || m.contains("recurse") => format!(
            "nesting too deep: arrays, inline tables or dotted keys nest deeper than a TOML reader follows (a scene never needs this) ({m})"
        ),
        m => with_suggestion(m),
    };
    Diagnostic {
        span: e.span().or(Some(if text.is_empty() {
            0..0
        } else {
            text.len() - 1..text.len()
        })),
        message,
    }
}

/// Takes out of `table` (recursively, through tables and arrays of tables) the
/// entry whose key is at `span`, or the innermost entry whose value contains it.
/// Returns the key taken out. (The span of a `[table]` value covers only its header,
/// so tables are searched whatever their span.)
fn remove_entry(table: &mut toml::de::DeTable<'_>, span: &Range<usize>) -> Option<String> {
    let contains = |outer: &Range<usize>| outer.start <= span.start && span.end <= outer.end;
    let mut hit = None;
    for (k, v) in table.iter_mut() {
        if k.span() == *span {
            hit = Some(k.clone());
            break;
        }
        let value_span = v.span();
        let inner = match v.get_mut() {
            toml::de::DeValue::Table(t) => remove_entry(t, span),
            toml::de::DeValue::Array(a) => a.iter_mut().find_map(|x| match x.get_mut() {
                toml::de::DeValue::Table(t) => remove_entry(t, span),
                _ => None,
            }),
            _ => None,
        };
        if inner.is_some() {
            return inner;
        }
        if contains(&value_span) {
            hit = Some(k.clone());
            break;
        }
    }
    // keys compare by their text, not their span
    let key = hit?;
    table.remove(&key)?;
    Some(key.get_ref().to_string())
}

impl Resolver<'_> {
    fn err(&mut self, span: Range<usize>, message: impl Into<String>) {
        self.diags.push(Diagnostic {
            span: Some(span),
            message: message.into(),
        });
    }

    /// A string key that must be one of `options`; `default` when absent.
    fn choice<T: Copy>(
        &mut self,
        key: &str,
        v: &Sp<String>,
        options: &[(&str, T)],
        default: T,
    ) -> T {
        let Some(s) = v else { return default };
        if let Some((_, t)) = options.iter().find(|(n, _)| *n == s.get_ref().as_str()) {
            return *t;
        }
        let names: Vec<&str> = options.iter().map(|(n, _)| *n).collect();
        let hint = suggest(s.get_ref(), names.iter().copied())
            .map(|n| format!("; did you mean `{n}`?"))
            .unwrap_or_default();
        self.err(
            s.span(),
            format!(
                "{key} = \"{}\" is not known: expected one of {}{hint}",
                s.get_ref(),
                quoted_list(names)
            ),
        );
        default
    }

    /// A number that must satisfy `ok`; `default` when absent.
    fn number(
        &mut self,
        key: &str,
        v: &Sp<f64>,
        default: f64,
        ok: impl Fn(f64) -> bool,
        expected: &str,
    ) -> f64 {
        match v {
            None => default,
            Some(s) if s.get_ref().is_finite() && ok(*s.get_ref()) => *s.get_ref(),
            Some(s) => {
                self.err(
                    s.span(),
                    format!("{key} = {}: expected {expected}", shown(*s.get_ref())),
                );
                default
            }
        }
    }

    fn vec3(&mut self, key: &str, v: &Spanned<[f64; 3]>, nonzero: bool) -> Option<DVec3> {
        let a = DVec3::from_array(*v.get_ref());
        if !a.is_finite() {
            self.err(v.span(), format!("{key}: expected three finite numbers"));
            None
        } else if nonzero && a.length() < 1e-12 {
            self.err(v.span(), format!("{key}: expected a non-zero vector"));
            None
        } else {
            Some(a)
        }
    }

    fn unit_color(&mut self, key: &str, v: &Spanned<[f64; 3]>) -> [f64; 3] {
        let c = *v.get_ref();
        if c.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)) {
            c
        } else {
            self.err(
                v.span(),
                format!("{key}: expected three numbers in [0, 1], got {c:?}"),
            );
            [0.0; 3]
        }
    }

    fn window(&mut self, key: &str, v: &Sp<[f64; 2]>) -> Option<[f64; 2]> {
        let s = v.as_ref()?;
        let [lo, hi] = *s.get_ref();
        let inverse = 1.0 / (hi - lo);
        if lo.is_finite() && hi.is_finite() && lo < hi && inverse.is_finite() && inverse != 0.0 {
            Some([lo, hi])
        } else if lo.is_finite() && hi.is_finite() && lo < hi {
            self.err(
                s.span(),
                format!("{key} = [{}, {}]: its width high - low overflows an f64 (or its inverse does): expected a narrower window", shown(lo), shown(hi)),
            );
            None
        } else {
            self.err(
                s.span(),
                format!(
                    "{key} = [{}, {}]: expected [low, high] with low < high",
                    shown(lo),
                    shown(hi)
                ),
            );
            None
        }
    }

    /// A value of the volume's value axis (a threshold, an iso value, a knot), in the
    /// scene's units: returned normalised, `(x - lo) / (hi - lo)` in f64 under
    /// `units = "data"`; it must lie in [0, 1] once normalised (inside the volume
    /// window). `None` (reported) when it does not.
    fn value_at(&mut self, key: &str, x: f64, span: Range<usize>) -> Option<f64> {
        let t = match self.units {
            Units::Normalised => x,
            Units::Data { lo, hi } => (x - lo) / (hi - lo),
        };
        if x.is_finite() && (0.0..=1.0).contains(&t) {
            return Some(t);
        }
        let expected = match self.units {
            Units::Normalised => {
                "a normalised value in [0, 1] (0 = the volume window's low end, 1 = its high end)"
                    .to_string()
            }
            Units::Data { lo, hi } => {
                format!("a value of the volume in its window [{lo}, {hi}] (units = \"data\")")
            }
        };
        self.err(span, format!("{key} = {}: expected {expected}", shown(x)));
        None
    }

    /// [`Resolver::value_at`] of an optional key, `default` (normalised) when absent.
    fn value(&mut self, key: &str, v: &Sp<f64>, default: f64) -> f64 {
        match v {
            None => default,
            Some(s) => self
                .value_at(key, *s.get_ref(), s.span())
                .unwrap_or(default),
        }
    }

    /// Reports keys that do not belong to the chosen variant of a table.
    fn not_for(&mut self, what: &str, keys: &[(&str, Option<Range<usize>>)]) {
        for (k, span) in keys {
            if let Some(span) = span {
                self.err(span.clone(), format!("`{k}` is not used {what}"));
            }
        }
    }
}
