//! The render modes, one module per family: [`projection`] (MIP, MinIP, average,
//! local MIP), [`xray`], [`depth`], [`surface`] and [`composite`].
//!
//! A family's module holds each of its modes whole: the scene keys it takes and
//! their checks ([`Registration`]), its resolved settings (a type implementing
//! [`Mode`]), how it renders ([`RayMode`]) and its sampled integrand
//! (`projection::integrator`, `xray::integrator`, `composite::integrator`; depth and
//! surface share the level-crossing search of [`crossing`]). [`exact`] is the exact
//! integrand of every mode but composite: one walk of the trilinear interpolant's
//! cells with a closed form per mode, one kernel per filter rather than one per
//! mode. Everything
//! downstream asks the [`Mode`] object (the plan, `zoom = "fit"`, the manifest, the
//! histogram's overlays, `check`) instead of matching on the mode.
//!
//! Adding a mode: its family's module (its settings, its `Mode` and `RayMode`
//! implementations, its `Registration`) and one line in [`MODES`].

pub mod composite;
pub mod crossing;
pub mod depth;
pub mod exact;
pub mod projection;
pub mod surface;
pub mod xray;

use std::fmt;
use std::sync::Arc;

use crate::render::pass::RayMode;
use crate::sample::GradientMethod;
use crate::shade::{Light, Material, Model, Shader};
use crate::transfer::{Colormap, Transfer};

/// Every mode, in the order the scene reference, messages and suggestions list them.
pub const MODES: &[Registration] = &[
    xray::XRAY,
    projection::MIP,
    projection::MINIP,
    projection::AVERAGE,
    projection::LMIP,
    depth::DEPTH,
    surface::SURFACE,
    composite::COMPOSITE,
];

/// The scene-file names of the modes, in the order of [`MODES`].
pub fn names() -> impl Iterator<Item = &'static str> + Clone {
    MODES.iter().map(|m| m.name)
}

/// The mode named `name` in a scene file.
pub fn find(name: &str) -> Option<&'static Registration> {
    MODES.iter().find(|m| m.name == name)
}

/// How a mode enters the scene file: its name, its keys and how they resolve.
pub struct Registration {
    /// `mode = "..."`.
    pub name: &'static str,
    /// The mode-specific keys of `[[render]]` it takes (any other mode-specific key
    /// is an error naming the modes that take it).
    pub keys: &'static [&'static str],
    /// Whether the pass's grey `window` is on the value axis (so under `units =
    /// "data"` it is written in data values), given the pass's `output` key as
    /// written (the window is read before the mode's other keys).
    pub window_in_values: fn(Option<&str>) -> bool,
    /// The mode's settings from the pass's keys (`None`: an error was reported).
    pub resolve: fn(&mut dyn Keys) -> Option<Arc<dyn Mode>>,
}

/// The keys of one `[[render]]` pass as a mode reads them: each read checks the
/// value and reports an error located at the key (the scene implements it).
pub trait Keys {
    /// The pass's name.
    fn pass_name(&self) -> &str;
    /// A number that must satisfy `ok` (`expected` says what it must be); `default`
    /// when absent.
    fn number(&mut self, key: &str, default: f64, ok: fn(f64) -> bool, expected: &str) -> f64;
    /// A value of the volume's value axis in the scene's units, returned normalised;
    /// `default` (normalised) when absent.
    fn value(&mut self, key: &str, default: f64) -> f64;
    /// The index in `names` of a string key's value; `default` when absent.
    fn pick(&mut self, key: &str, names: &[&str], default: usize) -> usize;
    /// A boolean key (false when absent).
    fn flag(&self, key: &str) -> bool;
    /// A string key as written.
    fn text(&self, key: &str) -> Option<&str>;
    /// The pass's colour map (`colormap`, already checked; turbo when absent).
    fn colormap(&self) -> Colormap;
    /// The shading keys (`shading`, `material`, `gradient`), checked; `None` when
    /// one is wrong (reported).
    fn shading(&mut self) -> Option<Shading>;
    /// The transfer function (`transfer`, `grey` when absent) by its name: the
    /// scene's own or a preset; `None` when it is not defined (reported). For a
    /// pass over several volumes, its first volume's.
    fn transfer(&mut self) -> Option<(String, Transfer)>;
    /// The transfer function of each volume the pass reads, in the order of its
    /// `volumes` (one for a pass over one volume: [`Keys::transfer`]'s); `None`
    /// when one is missing or not defined (reported).
    fn transfers(&mut self) -> Option<Vec<(String, Transfer)>>;
    /// Reports an error at `key`.
    fn error(&mut self, key: &str, message: String);
    /// Reports a warning.
    fn warn(&mut self, message: String);
}

/// A string key that must be one of `options`; `default` when absent.
pub fn choose<T: Copy + PartialEq>(
    keys: &mut dyn Keys,
    key: &str,
    options: &[(&str, T)],
    default: T,
) -> T {
    let names: Vec<&str> = options.iter().map(|(n, _)| *n).collect();
    let at = options.iter().position(|(_, t)| *t == default).unwrap_or(0);
    options[keys.pick(key, &names, at)].1
}

/// Shading settings of surface and shaded composite passes.
#[derive(Clone, Debug, PartialEq)]
pub struct Shading {
    /// Reflection model.
    pub model: Model,
    /// Material coefficients.
    pub material: Material,
    /// Name of the material (for the plan).
    pub material_name: String,
    /// Gradient estimator for the normals.
    pub gradient: GradientMethod,
}

impl Shading {
    /// The shader of these settings lit by `light`.
    pub fn shader(&self, light: Light) -> Shader {
        Shader {
            model: self.model,
            material: self.material,
            light,
        }
    }
}

/// The value a mode looks for: an iso value or a threshold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level {
    /// Its scene key (`iso` or `threshold`), also what keyframes animate.
    pub key: &'static str,
    /// Normalised.
    pub value: f64,
}

/// What a pass is planned with, besides its mode's settings.
#[derive(Clone, Copy, Debug)]
pub struct PassContext {
    /// `integration = "exact"`.
    pub exact: bool,
    /// The diameter of the volume's bounding sphere (where depth cues are measured).
    pub sphere_diameter: f64,
    /// The scene's light, for modes that shade.
    pub light: Light,
    /// The pass's grey window (normalised), if it has one.
    pub window: Option<[f64; 2]>,
}

/// What `check` needs to describe a mode.
pub struct NoteContext<'a> {
    /// A normalised value as `check` shows it (with its data value under `units =
    /// "data"`).
    pub show: &'a dyn Fn(f64) -> String,
    /// The diameter of the volume's bounding sphere.
    pub sphere_diameter: f64,
    /// The pass's grey window (normalised), if it has one.
    pub window: Option<[f64; 2]>,
}

/// A pass's mode with its settings, as the scene resolves it: what every stage
/// after the scene asks of a mode.
pub trait Mode: fmt::Debug + Send + Sync {
    /// The scene-file name.
    fn name(&self) -> &'static str;

    /// Whether its image is one grey value per pixel.
    fn is_intensity(&self) -> bool {
        true
    }

    /// Whether its grey window is on the value axis (written in data values under
    /// `units = "data"`).
    fn window_in_values(&self) -> bool {
        false
    }

    /// Its shading, for modes that shade.
    fn shading(&self) -> Option<&Shading> {
        None
    }

    /// The iso value or threshold it looks for.
    fn level(&self) -> Option<Level> {
        None
    }

    /// The transfer function, with its name, of a mode that classifies.
    fn transfer(&self) -> Option<(&str, &Transfer)> {
        None
    }

    /// The smallest normalised value it shows (what `zoom = "fit"` frames by
    /// default): its level, a transfer function's first opaque value or the low end
    /// of the grey `window`.
    fn fit_value(&self, _window: Option<[f64; 2]>) -> Option<f64> {
        self.level().map(|l| l.value)
    }

    /// Whether clipping planes cap it (show the cut face inside the object).
    fn caps_clips(&self) -> bool {
        false
    }

    /// What `check` says of its settings, one item each (by default, its level).
    fn notes(&self, ctx: &NoteContext<'_>) -> Vec<String> {
        self.level()
            .map(|l| level_note(l, ctx))
            .into_iter()
            .collect()
    }

    /// Its settings in the manifest, beside the pass's name, mode, step,
    /// interpolation, window and shading (by default, its level under its key).
    fn manifest(&self) -> serde_json::Map<String, serde_json::Value> {
        let mut m = serde_json::Map::new();
        if let Some(l) = self.level() {
            m.insert(l.key.into(), l.value.into());
        }
        m
    }

    /// The mode as the renderer runs it.
    fn plan(&self, ctx: &PassContext) -> Arc<dyn RayMode>;

    /// For a pass over several volumes, the mode of its `k`-th volume's part (in
    /// the order of the pass's volumes) as a pass of its own would have it: what
    /// that volume needs precomputed. `None` for a pass over one volume.
    fn part(&self, _k: usize) -> Option<Arc<dyn Mode>> {
        None
    }

    /// For a pass over several volumes, the mode as the renderer runs it over
    /// all of them, given each one's frame (in the order of the pass's volumes).
    /// `None` for a pass over one volume.
    fn plan_blend(
        &self,
        _ctx: &PassContext,
        _frames: Vec<crate::render::IndexFrame>,
    ) -> Option<Arc<dyn RayMode>> {
        None
    }
}

/// The `check` note of a level: `threshold 0.3` or `iso value 0.3`.
fn level_note(level: Level, ctx: &NoteContext<'_>) -> String {
    let what = if level.key == "iso" {
        "iso value"
    } else {
        level.key
    };
    format!("{what} {}", (ctx.show)(level.value))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pass with no mode-specific keys: every read takes its default.
    struct Defaults;

    impl Keys for Defaults {
        fn pass_name(&self) -> &str {
            "p"
        }
        fn number(&mut self, _: &str, default: f64, ok: fn(f64) -> bool, _: &str) -> f64 {
            assert!(ok(default), "a mode's default passes its own check");
            default
        }
        fn value(&mut self, _: &str, default: f64) -> f64 {
            default
        }
        fn pick(&mut self, _: &str, names: &[&str], default: usize) -> usize {
            assert!(default < names.len());
            default
        }
        fn flag(&self, _: &str) -> bool {
            false
        }
        fn text(&self, _: &str) -> Option<&str> {
            None
        }
        fn colormap(&self) -> Colormap {
            Colormap::Turbo
        }
        fn shading(&mut self) -> Option<Shading> {
            Some(Shading {
                model: Model::Phong,
                material: Material::neutral(),
                material_name: "neutral".into(),
                gradient: GradientMethod::Central,
            })
        }
        fn transfer(&mut self) -> Option<(String, Transfer)> {
            let tf = crate::transfer::Transfer1D::new(
                vec![(0.0, [1.0; 3])],
                vec![(0.0, 0.0), (1.0, 1.0)],
                crate::transfer::Interpolation::Linear,
            )
            .unwrap();
            Some(("ramp".into(), Transfer::OneD(Arc::new(tf))))
        }
        fn transfers(&mut self) -> Option<Vec<(String, Transfer)>> {
            Some(vec![self.transfer()?])
        }
        fn error(&mut self, key: &str, message: String) {
            panic!("defaults give no error, but `{key}`: {message}");
        }
        fn warn(&mut self, _: String) {}
    }

    #[test]
    fn each_registration_resolves_to_its_own_mode() {
        for (k, r) in MODES.iter().enumerate() {
            assert!(
                MODES[..k].iter().all(|o| o.name != r.name),
                "{} is registered twice",
                r.name
            );
            assert_eq!(find(r.name).map(|f| f.name), Some(r.name));
            let mode = (r.resolve)(&mut Defaults).expect("defaults resolve");
            assert_eq!(mode.name(), r.name);
            assert!(r.keys.contains(&"jitter"), "{}: every mode jitters", r.name);
        }
        assert!(find("mip2").is_none());
    }

    #[test]
    fn levels_are_the_keys_the_modes_take() {
        for r in MODES {
            let mode = (r.resolve)(&mut Defaults).unwrap();
            if let Some(l) = mode.level() {
                assert!(r.keys.contains(&l.key), "{}: {}", r.name, l.key);
                assert_eq!(mode.fit_value(None), Some(l.value));
            }
            // a mode that shades takes the shading keys, and only those do
            let shades = mode.shading().is_some() || r.keys.contains(&"shading");
            assert_eq!(shades, r.keys.contains(&"material"), "{}", r.name);
        }
    }

    #[test]
    fn modes_are_listed_in_the_reference_order() {
        let names: Vec<&str> = names().collect();
        assert_eq!(
            names,
            [
                "xray",
                "mip",
                "minip",
                "average",
                "lmip",
                "depth",
                "surface",
                "composite"
            ]
        );
    }
}
