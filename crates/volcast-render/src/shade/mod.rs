//! Shading: materials, lights and the Phong, Blinn-Phong and Cook-Torrance reflection models.
//!
//! Pure per-sample math, used by the `surface` integrator (iso-surfaces, shaded white) and by
//! shaded `composite` passes (each sample shaded with its transfer-function colour). In: a world
//! position, a unit normal facing the viewer (or none where the gradient is zero), the
//! direction to the eye and a base colour. Out: linear RGB, not clamped. Formulas:
//! docs/formulas.md "Shading" and "Material presets"; the reflection models' specular
//! terms live in `brdf.rs`.
//!
//! All three models share the ambient and diffuse terms
//! `I = M_a base L + M_d base L max(n.l, 0) + specular`, with `k_a = k_d = k_s = 1` (scale a
//! material instead) and the ambient term lit by the same light `L` (so a point light's ambient
//! contribution falls off with distance as its direct light does).

mod brdf;
mod light;
mod material;

use glam::Vec3;

pub use light::{Incident, Light, LightKind, MIN_LIGHT_DISTANCE};
pub use material::{Material, EXPONENT_PER_SHININESS};

/// The reflection model that computes the specular term (docs/formulas.md "Shading").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    /// `M_s L max(r.v, 0)^e`, `r` the light vector mirrored about the normal.
    Phong,
    /// `M_s L max(n.h, 0)^e`, `h` the half vector between light and eye.
    BlinnPhong,
    /// The microfacet model `L F D G / (4 (n.v))` (Fresnel, Beckmann, geometric attenuation).
    CookTorrance,
}

/// A reflection model, a material and a light: everything needed to shade one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shader {
    /// Which specular term to use.
    pub model: Model,
    /// The surface's reflection coefficients.
    pub material: Material,
    /// The single light source.
    pub light: Light,
}

impl Shader {
    /// Shades one sample; returns linear RGB, not clamped.
    ///
    /// - `p`: world position of the sample (matters for point lights only).
    /// - `normal`: unit normal already flipped to face the viewer, or `None` where the gradient
    ///   is zero: such a sample has no direction and gets the ambient term only
    ///   (docs/formulas.md "Gradients").
    /// - `to_eye`: unit vector from `p` towards the eye (`-ray direction`).
    /// - `base`: colour multiplying the ambient and diffuse terms: `Vec3::ONE` for iso-surfaces,
    ///   the transfer function's colour for shaded compositing. The highlight keeps the
    ///   material's specular colour.
    ///
    /// Diffuse and specular light arrive only where `n.l > 0`. The result is never NaN for
    /// finite inputs, including zero vectors, a light behind the surface, `to_eye = -l` and a
    /// sample at a point light's position (every division is guarded).
    pub fn shade(&self, p: Vec3, normal: Option<Vec3>, to_eye: Vec3, base: Vec3) -> Vec3 {
        let Incident { to_light, radiance } = self.light.incident(p, to_eye);
        let ambient = self.material.ambient * base * radiance;
        let Some(n) = normal else {
            return ambient;
        };
        let n_dot_l = n.dot(to_light);
        if n_dot_l.is_nan() || n_dot_l <= 0.0 {
            return ambient;
        }
        let diffuse = self.material.diffuse * base * n_dot_l.min(1.0);
        let specular = self.specular(n, to_light, to_eye, n_dot_l);
        ambient + (diffuse + specular) * radiance
    }

    /// The specular reflectance of [`Shader::model`] for light from `l` seen from `v`.
    fn specular(&self, n: Vec3, l: Vec3, v: Vec3, n_dot_l: f32) -> Vec3 {
        let Material {
            specular, exponent, ..
        } = self.material;
        match self.model {
            Model::Phong => specular * brdf::phong(n, l, v, n_dot_l, exponent),
            Model::BlinnPhong => specular * brdf::blinn_phong(n, l, v, exponent),
            Model::CookTorrance => brdf::cook_torrance(specular, exponent, n, l, v),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MODELS: [Model; 3] = [Model::Phong, Model::BlinnPhong, Model::CookTorrance];

    fn shader(model: Model, kind: LightKind) -> Shader {
        Shader {
            model,
            material: Material::preset("gold").expect("gold is a preset"),
            light: Light {
                kind,
                color: Vec3::new(1.0, 0.9, 0.8),
                intensity: 1.5,
            },
        }
    }

    fn assert_close(got: Vec3, expected: Vec3, tolerance: f32) {
        assert!(
            (got - expected).abs().max_element() <= tolerance,
            "got {got}, expected {expected}, tolerance {tolerance}"
        );
    }

    #[test]
    fn phong_with_n_l_v_equal_is_ambient_plus_diffuse_plus_specular() {
        // n = l = v: n.l = 1 and r = 2(n.l)n - l = n exactly, so every term is at full strength.
        let s = shader(Model::Phong, LightKind::Headlight);
        let light = s.light.color * s.light.intensity;
        let base = Vec3::new(0.5, 0.7, 0.9);
        let m = s.material;
        let expected = m.ambient * base * light + m.diffuse * base * light + m.specular * light;
        let got = s.shade(Vec3::ZERO, Some(Vec3::Y), Vec3::Y, base);
        assert_close(got, expected, 1e-6);
    }

    #[test]
    fn blinn_phong_equals_phong_when_n_l_v_are_equal() {
        let v = Vec3::new(0.6, 0.0, 0.8);
        let phong =
            shader(Model::Phong, LightKind::Headlight).shade(Vec3::ZERO, Some(v), v, Vec3::ONE);
        let blinn = shader(Model::BlinnPhong, LightKind::Headlight).shade(
            Vec3::ZERO,
            Some(v),
            v,
            Vec3::ONE,
        );
        assert_close(blinn, phong, 1e-6);
    }

    #[test]
    fn phong_highlight_follows_the_mirror_direction() {
        // Light at 45 degrees: the highlight is full along the mirror direction, zero 90 degrees
        // away from it.
        let d = std::f32::consts::FRAC_1_SQRT_2;
        let s = shader(
            Model::Phong,
            LightKind::Directional {
                direction: Vec3::new(d, 0.0, -d),
            },
        );
        let light = s.light.color * s.light.intensity;
        let m = s.material;
        let mirror = Vec3::new(d, 0.0, d);
        let lit = m.ambient * light + m.diffuse * light * d;
        assert_close(
            s.shade(Vec3::ZERO, Some(Vec3::Z), mirror, Vec3::ONE),
            lit + m.specular * light,
            1e-5,
        );
        let away = Vec3::new(-d, 0.0, d);
        assert_close(
            s.shade(Vec3::ZERO, Some(Vec3::Z), away, Vec3::ONE),
            lit,
            1e-5,
        );
    }

    #[test]
    fn headlight_on_a_surface_facing_the_eye_gives_maximal_diffuse() {
        let to_eye = Vec3::new(0.0, -0.6, 0.8);
        for model in MODELS {
            let mut s = shader(model, LightKind::Headlight);
            s.material.specular = Vec3::ZERO; // isolate ambient + diffuse
            let light = s.light.color * s.light.intensity;
            let facing = s.shade(Vec3::ZERO, Some(to_eye), to_eye, Vec3::ONE);
            let m = s.material;
            assert_close(facing, (m.ambient + m.diffuse) * light, 1e-6);
            for tilt in [0.1f32, 0.5, 1.0, 1.5] {
                let n = (to_eye + tilt * Vec3::X).normalize();
                let tilted = s.shade(Vec3::ZERO, Some(n), to_eye, Vec3::ONE);
                assert!(
                    tilted.cmplt(facing).all(),
                    "{model:?} tilt {tilt}: {tilted} vs {facing}"
                );
            }
        }
    }

    #[test]
    fn directional_light_from_behind_gives_ambient_only() {
        let to_eye = Vec3::new(0.0, 0.0, 1.0);
        let base = Vec3::new(0.3, 0.6, 0.9);
        for model in MODELS {
            // The light travels towards the eye: it comes from behind the surface.
            let s = shader(model, LightKind::Directional { direction: to_eye });
            let ambient = s.material.ambient * base * s.light.color * s.light.intensity;
            assert_eq!(
                s.shade(Vec3::ZERO, Some(to_eye), to_eye, base),
                ambient,
                "{model:?}"
            );
        }
    }

    #[test]
    fn no_normal_gives_ambient_only() {
        let base = Vec3::new(0.3, 0.6, 0.9);
        for model in MODELS {
            let s = shader(model, LightKind::Headlight);
            let ambient = s.material.ambient * base * s.light.color * s.light.intensity;
            assert_eq!(
                s.shade(Vec3::ZERO, None, Vec3::Z, base),
                ambient,
                "{model:?}"
            );
        }
    }

    #[test]
    fn point_light_falls_off_as_inverse_square() {
        let light_at = Vec3::new(1.0, -2.0, 3.0);
        let axis = Vec3::new(0.0, 0.6, 0.8);
        for model in MODELS {
            let s = shader(model, LightKind::Point { position: light_at });
            // Same geometry at distance r and 2r: light, normal and eye all along `axis`.
            let at = |r: f32| s.shade(light_at - r * axis, Some(axis), axis, Vec3::ONE);
            for r in [0.5f32, 2.0, 7.0] {
                let ratio = at(r) / at(2.0 * r);
                assert_close(ratio, Vec3::splat(4.0), 1e-4);
            }
        }
    }

    #[test]
    fn cook_torrance_adds_ambient_and_diffuse_as_phong_does() {
        // At n = l = v both models reduce to ambient + diffuse + their peak highlight; for
        // Cook-Torrance F = M_s (v.h = 1), D = 1/(pi m^2) (tan a = 0) and G/(n.v) = 1.
        let mut s = shader(Model::CookTorrance, LightKind::Headlight);
        let light = s.light.color * s.light.intensity;
        let m = s.material;
        let got = s.shade(Vec3::ZERO, Some(Vec3::Z), Vec3::Z, Vec3::ONE);
        let m2 = 2.0 / (m.exponent + 2.0);
        let peak = m.specular / (4.0 * std::f32::consts::PI * m2);
        assert_close(got, (m.ambient + m.diffuse + peak) * light, 1e-5);
        s.model = Model::Phong;
        let phong = s.shade(Vec3::ZERO, Some(Vec3::Z), Vec3::Z, Vec3::ONE);
        assert_close(got - peak * light, phong - m.specular * light, 1e-5);
    }

    /// Unit directions spread over the sphere (a Fibonacci lattice), plus the axes.
    fn directions(count: usize) -> Vec<Vec3> {
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        let lattice = (0..count).map(|i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f32;
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        });
        let axes = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z];
        lattice.chain(axes).collect()
    }

    #[test]
    fn never_nan_over_a_sweep_of_directions() {
        let dirs = directions(40);
        let p = Vec3::new(0.25, -0.5, 0.75);
        let mut kinds = vec![
            LightKind::Headlight,
            LightKind::Directional {
                direction: Vec3::ZERO,
            },
            LightKind::Point { position: p },
            LightKind::Point {
                position: p + Vec3::splat(1e-20),
            },
        ];
        kinds.extend(
            dirs.iter()
                .map(|&d| LightKind::Directional { direction: d }),
        );
        kinds.extend(dirs.iter().take(8).map(|&d| LightKind::Point {
            position: p + 3.0 * d,
        }));
        let mut normals: Vec<Option<Vec3>> = dirs.iter().map(|&d| Some(d)).collect();
        normals.extend([None, Some(Vec3::ZERO)]);
        let mut eyes = dirs.clone();
        eyes.push(Vec3::ZERO);
        let exponents = [0.0, 1.0, 32.0 * 0.088, 128.0, 1e9];

        let mut count = 0usize;
        for model in MODELS {
            for kind in &kinds {
                let mut s = shader(model, *kind);
                for &exponent in &exponents {
                    s.material.exponent = exponent;
                    for &to_eye in &eyes {
                        // Include the light vector itself and its opposite: l = v and l = -v.
                        let l = s.light.incident(p, to_eye).to_light;
                        for &normal in normals.iter().chain(&[Some(l), Some(-l)]) {
                            let c = s.shade(p, normal, to_eye, Vec3::new(0.2, 0.5, 1.0));
                            assert!(
                                c.is_finite() && c.min_element() >= 0.0,
                                "{model:?} {kind:?} e {exponent} n {normal:?} v {to_eye}: {c}"
                            );
                            count += 1;
                        }
                    }
                }
            }
        }
        assert!(count > 100_000);
    }
}
