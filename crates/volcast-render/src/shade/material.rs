//! Surface materials: RGB reflection coefficients and a specular exponent.
//!
//! The named presets are the table of docs/formulas.md "Material presets" (seed 004, the
//! "golden skull" exercise). The course converts a preset's `shininess` to a Phong exponent
//! as `32 * shininess`; OpenGL's tables use `128 * shininess`, so the same names look glossier
//! there.

use glam::Vec3;

/// RGB reflection coefficients of a surface (docs/formulas.md "Shading").
///
/// `ambient`, `diffuse` and `specular` are the `M_a`, `M_d` and `M_s` of the Phong equation;
/// `exponent` is its `n`. Coefficients are linear RGB, usually in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Ambient reflectance `M_a`.
    pub ambient: Vec3,
    /// Diffuse (Lambertian) reflectance `M_d`.
    pub diffuse: Vec3,
    /// Specular reflectance `M_s` (Cook-Torrance: the Fresnel reflectance at normal incidence).
    pub specular: Vec3,
    /// Specular exponent `n` (>= 0; larger is glossier).
    pub exponent: f32,
}

/// The course's conversion from a preset's `shininess` to a Phong exponent.
pub const EXPONENT_PER_SHININESS: f32 = 32.0;

/// One row of docs/formulas.md's preset table, as typed there.
struct Preset {
    name: &'static str,
    ambient: [f32; 3],
    diffuse: [f32; 3],
    specular: [f32; 3],
    shininess: f32,
}

/// docs/formulas.md "Material presets", in the table's order.
#[rustfmt::skip]
const PRESETS: [Preset; 12] = [
    preset_row("emerald", [0.0215, 0.1745, 0.0215], [0.07568, 0.61424, 0.07568], [0.633, 0.727811, 0.633], 0.6),
    preset_row("jade", [0.135, 0.2225, 0.1575], [0.54, 0.89, 0.63], [0.316228, 0.316228, 0.316228], 0.1),
    preset_row("obsidian", [0.05375, 0.05, 0.06625], [0.18275, 0.17, 0.22525], [0.332741, 0.328634, 0.346435], 0.3),
    preset_row("pearl", [0.25, 0.20725, 0.20725], [1.0, 0.829, 0.829], [0.296648, 0.296648, 0.296648], 0.088),
    preset_row("ruby", [0.1745, 0.01175, 0.01175], [0.61424, 0.04136, 0.04136], [0.727811, 0.626959, 0.626959], 0.6),
    preset_row("turquoise", [0.1, 0.18725, 0.1745], [0.396, 0.74151, 0.69102], [0.297254, 0.30829, 0.306678], 0.1),
    preset_row("brass", [0.329412, 0.223529, 0.027451], [0.780392, 0.568627, 0.113725], [0.992157, 0.941176, 0.807843], 0.21794872),
    preset_row("bronze", [0.2125, 0.1275, 0.054], [0.714, 0.4284, 0.18144], [0.393548, 0.271906, 0.166721], 0.2),
    preset_row("chrome", [0.25, 0.25, 0.25], [0.4, 0.4, 0.4], [0.774597, 0.774597, 0.774597], 0.6),
    preset_row("copper", [0.19125, 0.0735, 0.0225], [0.7038, 0.27048, 0.0828], [0.256777, 0.137622, 0.086014], 0.1),
    preset_row("gold", [0.24725, 0.1995, 0.0745], [0.75164, 0.60648, 0.22648], [0.628281, 0.555802, 0.366065], 0.4),
    preset_row("silver", [0.19225, 0.19225, 0.19225], [0.50754, 0.50754, 0.50754], [0.508273, 0.508273, 0.508273], 0.4),
];

const fn preset_row(
    name: &'static str,
    ambient: [f32; 3],
    diffuse: [f32; 3],
    specular: [f32; 3],
    shininess: f32,
) -> Preset {
    Preset {
        name,
        ambient,
        diffuse,
        specular,
        shininess,
    }
}

impl Material {
    /// The preset names accepted by [`Material::preset`], in docs/formulas.md's order.
    pub const PRESET_NAMES: [&'static str; 12] = {
        let mut names = [""; 12];
        let mut i = 0;
        while i < PRESETS.len() {
            names[i] = PRESETS[i].name;
            i += 1;
        }
        names
    };

    /// The named preset of docs/formulas.md "Material presets" (`"gold"`, `"jade"`, ...), with
    /// `exponent = 32 * shininess`; `None` for a name not in [`Material::PRESET_NAMES`]
    /// (names are matched exactly, lower case, as the scene file writes them).
    pub fn preset(name: &str) -> Option<Material> {
        PRESETS.iter().find(|p| p.name == name).map(|p| Material {
            ambient: Vec3::from_array(p.ambient),
            diffuse: Vec3::from_array(p.diffuse),
            specular: Vec3::from_array(p.specular),
            exponent: EXPONENT_PER_SHININESS * p.shininess,
        })
    }

    /// The grey default for shaded passes without a material: ambient 0.15, diffuse 0.85,
    /// specular 0.3, exponent 32 (the seed 000 shader, docs/formulas.md "Shading").
    pub fn neutral() -> Material {
        Material {
            ambient: Vec3::splat(0.15),
            diffuse: Vec3::splat(0.85),
            specular: Vec3::splat(0.3),
            exponent: 32.0,
        }
    }
}

impl Default for Material {
    /// [`Material::neutral`].
    fn default() -> Self {
        Material::neutral()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Name, ambient, diffuse, specular, shininess.
    type Row = (&'static str, [f32; 3], [f32; 3], [f32; 3], f32);

    /// Rows typed again from docs/formulas.md, independently of `PRESETS`.
    #[test]
    fn presets_match_the_reference_table() {
        #[rustfmt::skip]
        let rows: [Row; 4] = [
            ("gold", [0.24725, 0.1995, 0.0745], [0.75164, 0.60648, 0.22648], [0.628281, 0.555802, 0.366065], 0.4),
            ("emerald", [0.0215, 0.1745, 0.0215], [0.07568, 0.61424, 0.07568], [0.633, 0.727811, 0.633], 0.6),
            ("brass", [0.329412, 0.223529, 0.027451], [0.780392, 0.568627, 0.113725], [0.992157, 0.941176, 0.807843], 0.21794872),
            ("pearl", [0.25, 0.20725, 0.20725], [1.0, 0.829, 0.829], [0.296648, 0.296648, 0.296648], 0.088),
        ];
        for (name, ambient, diffuse, specular, shininess) in rows {
            let m = Material::preset(name).unwrap_or_else(|| panic!("preset {name} missing"));
            assert_eq!(m.ambient.to_array(), ambient, "{name} ambient");
            assert_eq!(m.diffuse.to_array(), diffuse, "{name} diffuse");
            assert_eq!(m.specular.to_array(), specular, "{name} specular");
            assert_eq!(
                m.exponent,
                32.0 * shininess,
                "{name} exponent = 32 * shininess"
            );
        }
    }

    #[test]
    fn every_listed_name_is_a_preset_in_table_order() {
        let expected = [
            "emerald",
            "jade",
            "obsidian",
            "pearl",
            "ruby",
            "turquoise",
            "brass",
            "bronze",
            "chrome",
            "copper",
            "gold",
            "silver",
        ];
        assert_eq!(Material::PRESET_NAMES, expected);
        for name in Material::PRESET_NAMES {
            let m = Material::preset(name).unwrap_or_else(|| panic!("preset {name} missing"));
            let all = [m.ambient, m.diffuse, m.specular];
            assert!(all
                .iter()
                .all(|c| c.min_element() >= 0.0 && c.max_element() <= 1.0));
            assert!(m.exponent > 0.0);
        }
    }

    #[test]
    fn exponents_are_32_times_shininess() {
        let shininess = [
            ("jade", 0.1),
            ("chrome", 0.6),
            ("silver", 0.4),
            ("pearl", 0.088),
        ];
        for (name, s) in shininess {
            let m = Material::preset(name).unwrap_or_else(|| panic!("preset {name} missing"));
            assert_eq!(m.exponent, 32.0 * s, "{name}");
        }
    }

    #[test]
    fn unknown_names_are_none() {
        assert_eq!(Material::preset("unobtainium"), None);
        assert_eq!(Material::preset("Gold"), None);
        assert_eq!(Material::preset(""), None);
    }

    #[test]
    fn neutral_is_the_seed_000_shader() {
        let m = Material::neutral();
        assert_eq!(m.ambient, Vec3::splat(0.15));
        assert_eq!(m.diffuse, Vec3::splat(0.85));
        assert_eq!(m.specular, Vec3::splat(0.3));
        assert_eq!(m.exponent, 32.0);
        assert_eq!(Material::default(), m);
    }
}
