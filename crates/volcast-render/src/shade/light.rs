//! Light sources: where the light comes from and how much arrives at a sample.
//!
//! docs/formulas.md "Shading": directional lights (the sun, parallel rays), point lights (falling
//! off as `1/r^2`) and the common headlight (a directional light from the camera).

use glam::Vec3;

/// Distances to a point light below this (world units) count as this, so a sample at the
/// light's position gets a large but finite radiance instead of a division by zero.
pub const MIN_LIGHT_DISTANCE: f32 = 1e-4;

/// Where a light is and which way its light travels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// A directional light from the camera: the light vector is the direction to the eye.
    Headlight,
    /// Parallel light, like the sun.
    Directional {
        /// Direction the light travels (from the light into the scene), unit length; it is
        /// normalised when used, and a zero vector gives no direct light (ambient only).
        direction: Vec3,
    },
    /// A point light whose radiance falls off as `1/r^2` with the distance `r`.
    Point {
        /// World position of the light.
        position: Vec3,
    },
}

/// A light source: its kind, colour and intensity (docs/formulas.md "Shading").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Where the light is and which way it shines.
    pub kind: LightKind,
    /// Linear RGB colour of the light.
    pub color: Vec3,
    /// Scale on `color` (for a point light: the radiance at distance 1).
    pub intensity: f32,
}

/// The light arriving at one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incident {
    /// Unit vector from the sample towards the light (zero where that has no direction).
    pub to_light: Vec3,
    /// Radiance `L` arriving at the sample: `color * intensity`, divided by `r^2` for a point
    /// light.
    pub radiance: Vec3,
}

impl Light {
    /// A white headlight of intensity 1: the usual default.
    pub fn headlight() -> Light {
        Light {
            kind: LightKind::Headlight,
            color: Vec3::ONE,
            intensity: 1.0,
        }
    }

    /// The light arriving at world position `p`, seen along `to_eye` (unit vector from `p`
    /// towards the eye; the headlight shines along it).
    ///
    /// A point light at `p` itself gives `to_light = 0` (no direct light) and the radiance at
    /// [`MIN_LIGHT_DISTANCE`].
    pub fn incident(&self, p: Vec3, to_eye: Vec3) -> Incident {
        let radiance = self.color * self.intensity;
        match self.kind {
            LightKind::Headlight => Incident {
                to_light: to_eye,
                radiance,
            },
            LightKind::Directional { direction } => Incident {
                to_light: -direction.normalize_or_zero(),
                radiance,
            },
            LightKind::Point { position } => {
                let offset = position - p;
                let r2 = offset
                    .length_squared()
                    .max(MIN_LIGHT_DISTANCE * MIN_LIGHT_DISTANCE);
                Incident {
                    to_light: offset.normalize_or_zero(),
                    radiance: radiance / r2,
                }
            }
        }
    }
}

impl Default for Light {
    /// [`Light::headlight`].
    fn default() -> Self {
        Light::headlight()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn light(kind: LightKind) -> Light {
        Light {
            kind,
            color: Vec3::new(1.0, 0.5, 0.25),
            intensity: 2.0,
        }
    }

    #[test]
    fn headlight_shines_along_the_view_direction() {
        let to_eye = Vec3::new(0.0, -1.0, 0.0);
        let inc = light(LightKind::Headlight).incident(Vec3::new(3.0, 4.0, 5.0), to_eye);
        assert_eq!(inc.to_light, to_eye);
        assert_eq!(inc.radiance, Vec3::new(2.0, 1.0, 0.5));
    }

    #[test]
    fn directional_light_comes_from_minus_its_direction() {
        let l = light(LightKind::Directional {
            direction: Vec3::new(0.0, 0.0, -3.0),
        });
        let inc = l.incident(Vec3::ZERO, Vec3::X);
        assert_eq!(inc.to_light, Vec3::Z);
        assert_eq!(inc.radiance, Vec3::new(2.0, 1.0, 0.5));
    }

    #[test]
    fn zero_direction_gives_no_direction() {
        let l = light(LightKind::Directional {
            direction: Vec3::ZERO,
        });
        assert_eq!(l.incident(Vec3::ZERO, Vec3::X).to_light, Vec3::ZERO);
    }

    #[test]
    fn point_light_falls_off_as_inverse_square() {
        let position = Vec3::new(1.0, 2.0, 3.0);
        let l = light(LightKind::Point { position });
        let near = l.incident(position - Vec3::new(0.0, 0.0, 0.5), Vec3::X);
        let far = l.incident(position - Vec3::new(0.0, 0.0, 1.0), Vec3::X);
        assert_eq!(near.to_light, Vec3::Z);
        assert_eq!(far.to_light, Vec3::Z);
        // Distance 1: radiance is color * intensity; distance 0.5: four times that.
        assert_eq!(far.radiance, Vec3::new(2.0, 1.0, 0.5));
        assert_eq!(near.radiance, 4.0 * far.radiance);
    }

    #[test]
    fn point_light_at_the_sample_is_finite() {
        let position = Vec3::new(1.0, 2.0, 3.0);
        let inc = light(LightKind::Point { position }).incident(position, Vec3::X);
        assert_eq!(inc.to_light, Vec3::ZERO);
        assert!(inc.radiance.is_finite());
        let r_min2 = MIN_LIGHT_DISTANCE * MIN_LIGHT_DISTANCE;
        assert_eq!(inc.radiance, Vec3::new(2.0, 1.0, 0.5) / r_min2);
    }
}
