//! From what the user wrote ([`super::schema`]) to what it means ([`super::Scene`]):
//! defaults, ranges, names, cross-references and mode-specific keys. Every problem
//! is collected with its place in the file; the scene is returned only if there
//! are none.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DVec3, Vec3};
use toml::Spanned;

use super::diag::{quoted_list, suggest, with_suggestion, Diagnostic, SceneError};
use super::schema::*;
use super::*;
use crate::sample::{GradientMethod, Interpolation};
use crate::shade::{Material, Model};
use crate::transfer::{self, Transfer1D, Transfer2D, Widget, WidgetShape};
use crate::volume::raw::RawSpec;
use crate::volume::synthetic::Field;
use crate::volume::{ScalarType, Synthetic, VolumeSource};

/// Which render modes use each mode-specific key of `[[render]]`.
const MODE_KEYS: &[(&str, &[&str])] = &[
    ("output", &["xray"]),
    ("mu", &["xray"]),
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

const MODES: &[&str] = &[
    "xray",
    "mip",
    "minip",
    "average",
    "lmip",
    "depth",
    "surface",
    "composite",
];

/// The neutral material's name (a white plastic, the default of shaded passes).
pub const NEUTRAL: &str = "neutral";

/// Largest image side accepted.
const MAX_IMAGE_SIDE: i64 = 32768;

struct Resolver<'a> {
    diags: Vec<Diagnostic>,
    warnings: Vec<String>,
    base_dir: &'a Path,
}

pub fn resolve(text: &str, path: &Path) -> Result<Scene, SceneError> {
    let fail = |diags: Vec<Diagnostic>| SceneError {
        path: path.to_path_buf(),
        text: text.to_string(),
        diagnostics: diags,
    };
    let file: SceneFile = match toml::from_str(text) {
        Ok(f) => f,
        Err(e) => {
            return Err(fail(vec![Diagnostic {
                span: e.span(),
                message: with_suggestion(e.message()),
            }]))
        }
    };
    let base_dir = path.parent().unwrap_or(Path::new("."));
    let mut r = Resolver {
        diags: Vec::new(),
        warnings: Vec::new(),
        base_dir,
    };
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    let volume = r.volume(&file.volume);
    let camera = r.camera(file.camera.as_ref());
    let orbit = r.orbit(file.orbit.as_ref());
    let image = r.image(file.image.as_ref(), &name);
    let stereo = file
        .stereo
        .as_ref()
        .map(|s| r.stereo(s, image.format, camera.projection));
    let animation = file
        .animation
        .as_ref()
        .map(|a| r.animation(a, image.format));
    let light = r.light(file.light.as_ref());
    let materials = r.materials(&file.material);
    let transfers = r.transfers(&file.transfer);
    let passes = r.passes(file.render.as_deref(), &materials, &transfers);
    if !r.diags.is_empty() {
        let mut d = r.diags;
        d.sort_by_key(|d| d.span.as_ref().map_or(0, |s| s.start));
        return Err(fail(d));
    }
    Ok(Scene {
        path: path.to_path_buf(),
        name,
        volume,
        camera,
        orbit,
        stereo,
        image,
        passes,
        light,
        animation,
        text: text.to_string(),
        warnings: r.warnings,
    })
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
                    format!("{key} = {}: expected {expected}", s.get_ref()),
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
        if lo.is_finite() && hi.is_finite() && lo < hi {
            Some([lo, hi])
        } else {
            self.err(
                s.span(),
                format!("{key} = [{lo}, {hi}]: expected [low, high] with low < high"),
            );
            None
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

    fn volume(&mut self, t: &Spanned<VolumeTable>) -> VolumeSpec {
        let v = t.get_ref();
        let window = self.window("window", &v.window);
        let raw_keys = [
            ("sizes", v.sizes.as_ref().map(|s| s.span())),
            ("type", v.ty.as_ref().map(|s| s.span())),
            ("endian", v.endian.as_ref().map(|s| s.span())),
            ("spacing", v.spacing.as_ref().map(|s| s.span())),
            ("offset", v.offset.as_ref().map(|s| s.span())),
        ];
        let placeholder = VolumeSource::Synthetic(Synthetic {
            field: Field::MarschnerLobb,
            sizes: [2, 2, 2],
        });
        let source = match (&v.path, &v.synthetic) {
            (Some(p), Some(s)) => {
                self.err(s.span(), "give either `path` or `synthetic`, not both");
                let _ = p;
                placeholder
            }
            (None, None) => {
                self.err(t.span(), "[volume] needs `path` (a .nrrd/.nhdr or raw file) or `synthetic` (gaussian, ball, sphere-distance, marschner-lobb)");
                placeholder
            }
            (None, Some(s)) => {
                self.not_for("by synthetic volumes (raw files only)", &raw_keys[1..]);
                if let Some(f) = &v.format {
                    self.err(f.span(), "`format` is not used by synthetic volumes");
                }
                self.synthetic(v, s).unwrap_or(placeholder)
            }
            (Some(p), None) => self.file_source(v, p, &raw_keys).unwrap_or(placeholder),
        };
        let window = window.or(match source {
            VolumeSource::Synthetic(_) => Some([0.0, 1.0]),
            _ => None,
        });
        let crop = v.crop.as_ref().and_then(|c| {
            let r = *c.get_ref();
            if r.iter().all(|&[a, b]| 0 <= a && a <= b && b <= (1 << 31)) {
                Some(r.map(|[a, b]| [a as usize, b as usize]))
            } else {
                self.err(c.span(), format!(
                    "crop = {r:?}: expected [[x0, x1], [y0, y1], [z0, z1]], voxel index ranges with 0 <= low <= high"
                ));
                None
            }
        });
        VolumeSpec {
            source,
            window,
            crop,
        }
    }

    fn synthetic(&mut self, v: &VolumeTable, s: &Spanned<String>) -> Option<VolumeSource> {
        let kinds = ["gaussian", "ball", "sphere-distance", "marschner-lobb"];
        let sizes = self.sizes(&v.sizes, [64, 64, 64], 2);
        let positive = |x: f64| x > 0.0;
        let field = match s.get_ref().as_str() {
            "gaussian" => {
                if let Some(r) = &v.radius {
                    self.err(
                        r.span(),
                        "`radius` is not used by the gaussian field (it takes `sigma`)",
                    );
                }
                Field::Gaussian {
                    sigma: self.number("sigma", &v.sigma, 0.25, positive, "a positive number"),
                }
            }
            "ball" | "sphere-distance" => {
                if let Some(g) = &v.sigma {
                    self.err(
                        g.span(),
                        format!(
                            "`sigma` is not used by the {} field (it takes `radius`)",
                            s.get_ref()
                        ),
                    );
                }
                let ball = s.get_ref() == "ball";
                let radius = self.number(
                    "radius",
                    &v.radius,
                    if ball { 0.5 } else { 1.0 },
                    positive,
                    "a positive number",
                );
                if ball {
                    Field::Ball { radius }
                } else {
                    Field::SphereDistance { radius }
                }
            }
            "marschner-lobb" => {
                for (k, sp) in [("sigma", &v.sigma), ("radius", &v.radius)] {
                    if let Some(sp) = sp {
                        self.err(
                            sp.span(),
                            format!("`{k}` is not used by the marschner-lobb field"),
                        );
                    }
                }
                Field::MarschnerLobb
            }
            other => {
                let hint = suggest(other, kinds)
                    .map(|n| format!("; did you mean `{n}`?"))
                    .unwrap_or_default();
                self.err(
                    s.span(),
                    format!(
                        "synthetic = \"{other}\" is not known: expected one of {}{hint}",
                        quoted_list(kinds)
                    ),
                );
                return None;
            }
        };
        Some(VolumeSource::Synthetic(Synthetic { field, sizes }))
    }

    fn sizes(&mut self, v: &Sp<Vec<i64>>, default: [usize; 3], min: i64) -> [usize; 3] {
        let Some(s) = v else { return default };
        match s.get_ref().as_slice() {
            &[a, b, c] if [a, b, c].iter().all(|&x| x >= min && x <= (1 << 31)) => {
                [a as usize, b as usize, c as usize]
            }
            other => {
                self.err(
                    s.span(),
                    format!("sizes = {other:?}: expected three integers, each at least {min}"),
                );
                default
            }
        }
    }

    fn file_source(
        &mut self,
        v: &VolumeTable,
        p: &Spanned<String>,
        raw_keys: &[(&str, Option<Range<usize>>)],
    ) -> Option<VolumeSource> {
        for (k, sp) in [("sigma", &v.sigma), ("radius", &v.radius)] {
            if let Some(sp) = sp {
                self.err(
                    sp.span(),
                    format!("`{k}` is only used by synthetic volumes"),
                );
            }
        }
        let path = self.base_dir.join(p.get_ref());
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        let looks_nrrd = ext == "nrrd" || ext == "nhdr";
        let has_raw_keys = raw_keys.iter().any(|(_, s)| s.is_some());
        let format = self.choice(
            "format",
            &v.format,
            &[("nrrd", Some(true)), ("raw", Some(false))],
            if looks_nrrd {
                Some(true)
            } else if has_raw_keys {
                Some(false)
            } else {
                None
            },
        );
        match format {
            None => {
                self.err(p.span(), format!(
                    "cannot tell the format of \"{}\": use a .nrrd/.nhdr file, or set format = \"raw\" with sizes and type",
                    p.get_ref()
                ));
                None
            }
            Some(true) => {
                self.not_for("by NRRD files (their header describes the data)", raw_keys);
                Some(VolumeSource::Nrrd(path))
            }
            Some(false) => self.raw(v, path, p.span()),
        }
    }

    fn raw(&mut self, v: &VolumeTable, path: PathBuf, span: Range<usize>) -> Option<VolumeSource> {
        let mut ok = true;
        if v.sizes.is_none() {
            self.err(span.clone(), "a raw volume needs `sizes = [x, y, z]`");
            ok = false;
        }
        let sizes = self.sizes(&v.sizes, [1, 1, 1], 1);
        let scalar_type = match &v.ty {
            None => {
                self.err(
                    span,
                    "a raw volume needs `type` (uint8, int16, uint16, float32, ...)",
                );
                ok = false;
                ScalarType::Uint8
            }
            Some(t) => match ScalarType::parse(t.get_ref()) {
                Some(ty) => ty,
                None => {
                    let names = ScalarType::ALL.map(|t| t.nrrd_name());
                    self.err(t.span(), format!("type = \"{}\" is not known: expected one of uint8, int8, uint16, int16, uint32, int32, uint64, int64, float32, float64 (or a NRRD alias such as {})", t.get_ref(), quoted_list(names)));
                    ok = false;
                    ScalarType::Uint8
                }
            },
        };
        let little_endian = self.choice(
            "endian",
            &v.endian,
            &[("little", true), ("big", false)],
            true,
        );
        let spacing = match &v.spacing {
            None => [1.0; 3],
            Some(s) if s.get_ref().iter().all(|x| x.is_finite() && *x > 0.0) => *s.get_ref(),
            Some(s) => {
                self.err(s.span(), "spacing: expected three positive numbers");
                [1.0; 3]
            }
        };
        let offset = match &v.offset {
            None => 0,
            Some(o) if *o.get_ref() >= -1 => *o.get_ref(),
            Some(o) => {
                self.err(o.span(), "offset: expected a byte count >= 0, or -1 for \"the data is at the end of the file\"");
                0
            }
        };
        ok.then_some(VolumeSource::Raw(RawSpec {
            path,
            sizes,
            scalar_type,
            little_endian,
            spacing,
            offset,
        }))
    }

    fn camera(&mut self, t: Option<&Spanned<CameraTable>>) -> Camera {
        let mut cam = Camera {
            projection: Projection::Perspective,
            fov_deg: 30.0,
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            up: DVec3::Z,
            zoom: 1.0,
            distance: None,
            target: None,
        };
        let Some(t) = t else { return cam };
        let c = t.get_ref();
        cam.projection = self.choice(
            "projection",
            &c.projection,
            &[
                ("perspective", Projection::Perspective),
                ("orthographic", Projection::Orthographic),
            ],
            Projection::Perspective,
        );
        cam.fov_deg = self.number(
            "fov",
            &c.fov,
            30.0,
            |x| x > 0.0 && x < 180.0,
            "degrees in (0, 180)",
        );
        if cam.projection == Projection::Orthographic {
            if let Some(f) = &c.fov {
                self.warnings.push(format!(
                    "camera.fov = {} has no effect with an orthographic projection",
                    f.get_ref()
                ));
            }
            if let Some(d) = &c.distance {
                self.err(
                    d.span(),
                    "`distance` is not used by the orthographic projection (use `zoom`)",
                );
            }
        }
        cam.azimuth_deg = self.number(
            "azimuth",
            &c.azimuth,
            0.0,
            |_| true,
            "a finite number of degrees",
        );
        cam.elevation_deg = self.number(
            "elevation",
            &c.elevation,
            0.0,
            |x| (-90.0..=90.0).contains(&x),
            "degrees in [-90, 90]",
        );
        if let Some(up) = &c.up {
            cam.up = self
                .vec3("up", up, true)
                .map_or(DVec3::Z, |u| u.normalize());
        }
        cam.zoom = self.number("zoom", &c.zoom, 1.0, |x| x > 0.0, "a positive number");
        cam.distance = c.distance.as_ref().map(|_| {
            self.number(
                "distance",
                &c.distance,
                1.0,
                |x| x > 0.0,
                "a positive distance in world units",
            )
        });
        cam.target = c
            .target
            .as_ref()
            .and_then(|t| self.vec3("target", t, false));
        cam
    }

    fn orbit(&mut self, t: Option<&Spanned<OrbitTable>>) -> Orbit {
        let mut o = Orbit {
            frames: 1,
            degrees: 360.0,
        };
        let Some(t) = t else { return o };
        let v = t.get_ref();
        if let Some(f) = &v.frames {
            if (1..=1_000_000).contains(f.get_ref()) {
                o.frames = *f.get_ref() as usize;
            } else {
                self.err(
                    f.span(),
                    format!(
                        "frames = {}: expected an integer from 1 to 1000000",
                        f.get_ref()
                    ),
                );
            }
        }
        o.degrees = self.number(
            "degrees",
            &v.degrees,
            360.0,
            |_| true,
            "a finite number of degrees",
        );
        o
    }

    fn image(&mut self, t: Option<&Spanned<ImageTable>>, scene_name: &str) -> ImageSpec {
        let mut im = ImageSpec {
            width: 512,
            height: 512,
            background: [0.0; 3],
            format: Format::Png,
            out: PathBuf::from("out").join(scene_name),
        };
        let Some(t) = t else { return im };
        let v = t.get_ref();
        if let Some(s) = &v.size {
            let [w, h] = *s.get_ref();
            if (1..=MAX_IMAGE_SIDE).contains(&w) && (1..=MAX_IMAGE_SIDE).contains(&h) {
                im.width = w as usize;
                im.height = h as usize;
            } else {
                self.err(s.span(), format!("size = [{w}, {h}]: expected [width, height], each from 1 to {MAX_IMAGE_SIDE}"));
            }
        }
        if let Some(b) = &v.background {
            im.background = self.unit_color("background", b).map(|x| x as f32);
        }
        im.format = self.choice(
            "format",
            &v.format,
            &[
                ("png", Format::Png),
                ("png16", Format::Png16),
                ("nrrd", Format::Nrrd),
            ],
            Format::Png,
        );
        if let Some(o) = &v.out {
            match substitute_out(o.get_ref(), scene_name) {
                Ok(p) => im.out = PathBuf::from(p),
                Err(m) => self.err(o.span(), m),
            }
        }
        im
    }

    fn stereo(
        &mut self,
        t: &Spanned<StereoTable>,
        format: Format,
        projection: Projection,
    ) -> Stereo {
        let v = t.get_ref();
        let method_name = self.choice(
            "method",
            &v.method,
            &[("toe-in", false), ("parallel", true)],
            false,
        );
        let angle_deg = self.number(
            "angle",
            &v.angle,
            8.0,
            |x| x > 0.0 && x < 180.0,
            "degrees in (0, 180)",
        );
        let method = if method_name {
            let given: Vec<(&str, Range<usize>)> = [
                ("angle", v.angle.as_ref().map(|s| s.span())),
                ("separation", v.separation.as_ref().map(|s| s.span())),
                (
                    "separation_fraction",
                    v.separation_fraction.as_ref().map(|s| s.span()),
                ),
            ]
            .into_iter()
            .filter_map(|(k, s)| s.map(|s| (k, s)))
            .collect();
            if given.len() > 1 {
                let names: Vec<String> = given.iter().map(|(k, _)| format!("`{k}`")).collect();
                self.err(
                    given[1].1.clone(),
                    format!(
                        "give only one of `angle`, `separation` and `separation_fraction` for parallel stereo (found {})",
                        names.join(" and ")
                    ),
                );
            }
            if projection == Projection::Orthographic {
                self.err(
                    v.method.as_ref().map_or(t.span(), |m| m.span()),
                    "method = \"parallel\" needs projection = \"perspective\": orthographic eyes with parallel directions see the same picture (use method = \"toe-in\")",
                );
            }
            let separation = if let Some(s) = &v.separation {
                Separation::World(self.number(
                    "separation",
                    &Some(s.clone()),
                    1.0,
                    |x| x > 0.0,
                    "a positive distance between the eyes in world units",
                ))
            } else if let Some(f) = &v.separation_fraction {
                Separation::Fraction(self.number(
                    "separation_fraction",
                    &Some(f.clone()),
                    0.03,
                    |x| x > 0.0 && x <= 1.0,
                    "a fraction of the eye-target distance in (0, 1]",
                ))
            } else {
                // The eyes see the target under `angle`, as toe-in eyes would.
                Separation::Fraction(2.0 * (angle_deg.to_radians() / 2.0).tan())
            };
            StereoMethod::Parallel(separation)
        } else {
            for (k, s) in [
                ("separation", v.separation.as_ref().map(|s| s.span())),
                (
                    "separation_fraction",
                    v.separation_fraction.as_ref().map(|s| s.span()),
                ),
            ] {
                if let Some(span) = s {
                    self.err(
                        span,
                        format!("`{k}` is only used with method = \"parallel\" (toe-in eyes are placed by `angle`)"),
                    );
                }
            }
            StereoMethod::ToeIn
        };
        let layout = self.choice(
            "layout",
            &v.layout,
            &[
                ("pair", Layout::Pair),
                ("side-by-side", Layout::SideBySide),
                ("cross-eyed", Layout::CrossEyed),
                ("anaglyph", Layout::Anaglyph),
            ],
            Layout::Pair,
        );
        let anaglyph = self.choice(
            "anaglyph",
            &v.anaglyph,
            &[
                ("red-cyan", Anaglyph::RedCyan),
                ("red-green", Anaglyph::RedGreen),
            ],
            Anaglyph::RedCyan,
        );
        let anaglyph_colors = self.choice(
            "anaglyph_colors",
            &v.anaglyph_colors,
            &[
                ("color", AnaglyphColors::Color),
                ("half-color", AnaglyphColors::HalfColor),
                ("gray", AnaglyphColors::Gray),
            ],
            AnaglyphColors::Color,
        );
        for (key, value) in [
            ("anaglyph", v.anaglyph.as_ref().map(|a| a.span())),
            (
                "anaglyph_colors",
                v.anaglyph_colors.as_ref().map(|a| a.span()),
            ),
        ] {
            if let (Some(span), false) = (value, layout == Layout::Anaglyph) {
                self.err(
                    span,
                    format!("`{key}` is only used with layout = \"anaglyph\""),
                );
            }
        }
        if layout == Layout::Anaglyph && format == Format::Nrrd {
            self.err(
                v.layout.as_ref().map_or(t.span(), |l| l.span()),
                "layout = \"anaglyph\" makes a colour picture: use format = \"png\" or \"png16\" (nrrd output keeps unquantised values; use layout = \"pair\")",
            );
        }
        let gap = match &v.gap {
            None => 0,
            Some(g) if (0..=4096).contains(g.get_ref()) => *g.get_ref() as usize,
            Some(g) => {
                self.err(g.span(), "gap: expected a number of pixels from 0 to 4096");
                0
            }
        };
        if let (Some(g), false) = (
            &v.gap,
            matches!(layout, Layout::SideBySide | Layout::CrossEyed),
        ) {
            self.err(
                g.span(),
                "`gap` is only used with layout = \"side-by-side\" or \"cross-eyed\"",
            );
        }
        Stereo {
            method,
            angle_deg,
            layout,
            anaglyph,
            anaglyph_colors,
            gap,
        }
    }

    fn animation(&mut self, t: &Spanned<AnimationTable>, format: Format) -> Animation {
        let v = t.get_ref();
        let mut formats = Vec::new();
        match &v.formats {
            None => formats.push(AnimationFormat::Gif),
            Some(list) if list.get_ref().is_empty() => self.err(
                list.span(),
                "formats = []: expected a list of \"gif\" and/or \"apng\" (or leave out [animation])",
            ),
            Some(list) => {
                for f in list.get_ref() {
                    let chosen = self.choice(
                        "formats",
                        &Some(f.clone()),
                        &[("gif", AnimationFormat::Gif), ("apng", AnimationFormat::Apng)],
                        AnimationFormat::Gif,
                    );
                    if formats.contains(&chosen) {
                        self.err(f.span(), format!("\"{}\" is listed twice", f.get_ref()));
                    } else {
                        formats.push(chosen);
                    }
                }
            }
        }
        let fps = self.number(
            "fps",
            &v.fps,
            24.0,
            |x| x > 0.0 && x <= 100.0,
            "frames per second in (0, 100]",
        );
        if format == Format::Nrrd {
            self.err(
                t.span(),
                "[animation] is assembled from the PNG frames: use format = \"png\" or \"png16\" (nrrd frames hold unquantised values)",
            );
        }
        Animation {
            formats,
            fps,
            looping: v.looping.as_ref().is_none_or(|l| *l.get_ref()),
        }
    }

    fn light(&mut self, t: Option<&Spanned<LightTable>>) -> LightSpec {
        let mut l = LightSpec {
            kind: LightKindSpec::Headlight,
            color: DVec3::ONE,
            intensity: Some(1.0),
        };
        let Some(t) = t else { return l };
        let v = t.get_ref();
        #[derive(Clone, Copy, PartialEq)]
        enum K {
            Head,
            Dir,
            Point,
        }
        let kind = self.choice(
            "kind",
            &v.kind,
            &[
                ("headlight", K::Head),
                ("directional", K::Dir),
                ("point", K::Point),
            ],
            K::Head,
        );
        l.kind = match kind {
            K::Head => {
                self.not_for(
                    "by a headlight (it shines from the camera)",
                    &[
                        ("direction", v.direction.as_ref().map(|s| s.span())),
                        ("position", v.position.as_ref().map(|s| s.span())),
                    ],
                );
                LightKindSpec::Headlight
            }
            K::Dir => {
                self.not_for(
                    "by a directional light",
                    &[("position", v.position.as_ref().map(|s| s.span()))],
                );
                match &v.direction {
                    Some(d) => LightKindSpec::Directional(
                        self.vec3("direction", d, true)
                            .unwrap_or(DVec3::Z)
                            .normalize(),
                    ),
                    None => {
                        self.err(t.span(), "a directional light needs `direction = [x, y, z]` (the direction the light travels)");
                        LightKindSpec::Headlight
                    }
                }
            }
            K::Point => {
                self.not_for(
                    "by a point light",
                    &[("direction", v.direction.as_ref().map(|s| s.span()))],
                );
                l.intensity = None;
                match &v.position {
                    Some(p) => {
                        LightKindSpec::Point(self.vec3("position", p, false).unwrap_or(DVec3::ZERO))
                    }
                    None => {
                        self.err(
                            t.span(),
                            "a point light needs `position = [x, y, z]` (world units)",
                        );
                        LightKindSpec::Headlight
                    }
                }
            }
        };
        if let Some(c) = &v.color {
            l.color = DVec3::from_array(self.unit_color("color", c));
        }
        if v.intensity.is_some() {
            l.intensity = Some(self.number(
                "intensity",
                &v.intensity,
                1.0,
                |x| x >= 0.0,
                "a number >= 0",
            ));
        }
        l
    }

    fn materials(
        &mut self,
        m: &BTreeMap<String, Spanned<MaterialTable>>,
    ) -> BTreeMap<String, Material> {
        let mut out = BTreeMap::new();
        for (name, t) in m {
            let v = t.get_ref();
            let base = Material::neutral();
            let color = |r: &mut Self, key: &str, s: &Sp<[f64; 3]>, d: Vec3| {
                s.as_ref().map_or(d, |s| {
                    Vec3::from_array(r.unit_color(key, s).map(|x| x as f32))
                })
            };
            let ambient = color(self, "ambient", &v.ambient, base.ambient);
            let diffuse = color(self, "diffuse", &v.diffuse, base.diffuse);
            let specular = color(self, "specular", &v.specular, base.specular);
            let exponent = match (&v.shininess, &v.exponent) {
                (Some(_), Some(e)) => {
                    self.err(e.span(), "give either `shininess` (exponent = 32 * shininess) or `exponent`, not both");
                    base.exponent
                }
                (Some(_), None) => {
                    32.0 * self.number(
                        "shininess",
                        &v.shininess,
                        1.0,
                        |x| x >= 0.0,
                        "a number >= 0",
                    ) as f32
                }
                (None, Some(_)) => {
                    self.number("exponent", &v.exponent, 32.0, |x| x >= 0.0, "a number >= 0") as f32
                }
                (None, None) => base.exponent,
            };
            out.insert(
                name.clone(),
                Material {
                    ambient,
                    diffuse,
                    specular,
                    exponent,
                },
            );
        }
        out
    }

    fn transfers(
        &mut self,
        m: &BTreeMap<String, Spanned<TransferTable>>,
    ) -> BTreeMap<String, Transfer> {
        let mut out = builtin_transfers();
        for (name, t) in m {
            if let Some(tf) = self.transfer(name, t) {
                out.insert(name.clone(), tf);
            }
        }
        out
    }

    fn transfer(&mut self, name: &str, t: &Spanned<TransferTable>) -> Option<Transfer> {
        let v = t.get_ref();
        let two_d = self.choice(
            "kind",
            &v.kind,
            &[("1d", false), ("2d", true)],
            v.widget.is_some(),
        );
        let here = format!("[transfer.{name}]");
        if two_d {
            self.not_for(&format!("by the 2D transfer function {here} (it is built from [[transfer.{name}.widget]])"), &[
                ("color", v.color.as_ref().map(|s| s.span())),
                ("alpha", v.alpha.as_ref().map(|s| s.span())),
                ("interpolation", v.interpolation.as_ref().map(|s| s.span())),
            ]);
            let gradient_max = self.number(
                "gradient_max",
                &v.gradient_max,
                1.0,
                |x| x > 0.0,
                "a positive gradient magnitude",
            );
            let mut widgets = Vec::new();
            for w in v.widget.iter().flatten() {
                widgets.push(self.widget(w)?);
            }
            if widgets.is_empty() {
                self.err(
                    t.span(),
                    format!("{here} is 2D but has no [[transfer.{name}.widget]]"),
                );
                return None;
            }
            match Transfer2D::new(widgets, gradient_max as f32) {
                Ok(tf) => Some(Transfer::TwoD(Arc::new(tf))),
                Err(e) => {
                    self.err(t.span(), format!("{here}: {e}"));
                    None
                }
            }
        } else {
            self.not_for(
                &format!("by the 1D transfer function {here}"),
                &[("gradient_max", v.gradient_max.as_ref().map(|s| s.span()))],
            );
            let interpolation = self.choice(
                "interpolation",
                &v.interpolation,
                &[
                    ("linear", transfer::Interpolation::Linear),
                    ("cubic", transfer::Interpolation::Cubic),
                ],
                transfer::Interpolation::Linear,
            );
            let color: Vec<(f32, [f32; 3])> = match &v.color {
                Some(c) => c
                    .get_ref()
                    .iter()
                    .map(|(p, c)| (*p as f32, c.map(|x| x as f32)))
                    .collect(),
                None => vec![(0.0, [1.0; 3])],
            };
            let Some(alpha) = &v.alpha else {
                self.err(
                    t.span(),
                    format!("{here} needs `alpha = [[position, alpha], ...]` knots"),
                );
                return None;
            };
            let alpha: Vec<(f32, f32)> = alpha
                .get_ref()
                .iter()
                .map(|(p, a)| (*p as f32, *a as f32))
                .collect();
            match Transfer1D::new(color, alpha, interpolation) {
                Ok(tf) => Some(Transfer::OneD(Arc::new(tf))),
                Err(e) => {
                    let span = if e.to_string().starts_with("color") {
                        v.color.as_ref().map_or(t.span(), |s| s.span())
                    } else {
                        v.alpha.as_ref().map_or(t.span(), |s| s.span())
                    };
                    self.err(span, format!("{here}: {e}"));
                    None
                }
            }
        }
    }

    fn widget(&mut self, w: &Spanned<WidgetTable>) -> Option<Widget> {
        let v = w.get_ref();
        let shape = self.choice(
            "shape",
            &v.shape,
            &[
                ("rectangle", WidgetShape::Rectangle),
                ("gaussian", WidgetShape::Gaussian),
            ],
            WidgetShape::Rectangle,
        );
        let range = |r: &mut Self, key: &str, s: &Sp<[f64; 2]>, d: [f32; 2]| -> [f32; 2] {
            match s {
                None => d,
                Some(s) => {
                    let [a, b] = *s.get_ref();
                    if a.is_finite() && b.is_finite() && a <= b {
                        [a as f32, b as f32]
                    } else {
                        r.err(
                            s.span(),
                            format!("{key} = [{a}, {b}]: expected [low, high] with low <= high"),
                        );
                        d
                    }
                }
            }
        };
        let value = range(self, "value", &v.value, [0.0, 1.0]);
        let gradient = range(self, "gradient", &v.gradient, [0.0, f32::MAX]);
        let color = v
            .color
            .as_ref()
            .map_or([1.0; 3], |c| self.unit_color("color", c).map(|x| x as f32));
        let alpha = self.number(
            "alpha",
            &v.alpha,
            1.0,
            |x| (0.0..=1.0).contains(&x),
            "a number in [0, 1]",
        ) as f32;
        if v.value.is_none() {
            self.err(
                w.span(),
                "a widget needs `value = [low, high]` (normalised values)",
            );
            return None;
        }
        Some(Widget {
            shape,
            value,
            gradient,
            color,
            alpha,
        })
    }

    fn passes(
        &mut self,
        tables: Option<&[Spanned<RenderTable>]>,
        materials: &BTreeMap<String, Material>,
        transfers: &BTreeMap<String, Transfer>,
    ) -> Vec<RenderPass> {
        let Some(tables) = tables else {
            return vec![RenderPass {
                name: "mip".into(),
                mode: Mode::Mip,
                step_voxels: 0.5,
                interpolation: Interpolation::Trilinear,
                window: None,
                integration: Integration::Sampled,
                jitter: false,
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

    fn pass(
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
        let window = self.window("window", &v.window);
        self.check_method(v, integration, interpolation, jitter);
        let unit = |x: f64| (0.0..=1.0).contains(&x);
        const UNIT: &str =
            "a normalised value in [0, 1] (0 = the volume window's low end, 1 = its high end)";
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
            "mip" => Mode::Mip,
            "minip" => Mode::Minip,
            "average" => Mode::Average,
            "lmip" => Mode::Lmip {
                threshold: self.number("threshold", &v.threshold, 0.5, unit, UNIT),
            },
            "depth" => Mode::Depth {
                threshold: self.number("threshold", &v.threshold, 0.5, unit, UNIT),
            },
            "surface" => Mode::Surface {
                iso: self.number("iso", &v.iso, 0.5, unit, UNIT),
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
                let Some(transfer) = transfers.get(&transfer_name).cloned() else {
                    let span = v.transfer.as_ref().map_or(t.span(), |s| s.span());
                    let hint = suggest(&transfer_name, transfers.keys().map(|s| s.as_str()))
                        .map(|n| format!("; did you mean `{n}`?"))
                        .unwrap_or_default();
                    self.err(span, format!(
                        "transfer = \"{transfer_name}\" is not defined: add a [transfer.{transfer_name}] table, or use one of {}{hint}",
                        quoted_list(transfers.keys().map(|s| s.as_str()))
                    ));
                    return None;
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
        Some(RenderPass {
            name,
            mode,
            step_voxels,
            interpolation,
            window,
            integration,
            jitter,
        })
    }

    /// Combinations of integration, interpolation and jitter that do not work.
    fn check_method(
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

    fn shading(
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

/// Replaces `{scene}` in the output folder template.
fn substitute_out(template: &str, scene: &str) -> Result<String, String> {
    let out = template.replace("{scene}", scene);
    if let Some(i) = out.find(['{', '}']) {
        return Err(format!(
            "out = \"{template}\": unknown placeholder at \"{}\"; the only placeholder is {{scene}}",
            &out[i..]
        ));
    }
    if out.trim().is_empty() {
        return Err("out: expected a folder name".into());
    }
    Ok(out)
}

/// Transfer functions every scene can name without defining them.
fn builtin_transfers() -> BTreeMap<String, Transfer> {
    let mut m = BTreeMap::new();
    let grey = Transfer1D::new(
        vec![(0.0, [1.0; 3]), (1.0, [1.0; 3])],
        vec![(0.0, 0.0), (1.0, 1.0)],
        transfer::Interpolation::Linear,
    )
    .expect("built-in transfer function is valid");
    m.insert("grey".to_string(), Transfer::OneD(Arc::new(grey)));
    // The example of SCENES.md.
    let bone = Transfer1D::new(
        vec![
            (0.0, [0.91, 0.70, 0.61]),
            (0.32, [1.0, 1.0, 0.85]),
            (1.0, [1.0, 1.0, 0.85]),
        ],
        vec![(0.0, 0.0), (0.30, 0.0), (0.32, 0.9), (1.0, 1.0)],
        transfer::Interpolation::Linear,
    )
    .expect("built-in transfer function is valid");
    m.insert("bone".to_string(), Transfer::OneD(Arc::new(bone)));
    m
}
