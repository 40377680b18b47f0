//! Analytic test fields sampled on a grid spanning the cube [-1, 1]^3.
//!
//! The fields and their closed-form renderings are listed in REFERENCE.md
//! ("Analytic references for accuracy tests"). Values lie in [0, 1]; the data is
//! stored as `float`.

use glam::DVec3;

use super::{Geometry, Limits, ScalarType, Volume, VolumeData, VolumeError, VolumeHeader};

/// Which analytic field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Field {
    /// `exp(-|x|^2 / (2 sigma^2))`
    Gaussian {
        /// standard deviation, world units
        sigma: f64,
    },
    /// 1 inside the ball of `radius`, 0 outside.
    Ball {
        /// world units
        radius: f64,
    },
    /// `clamp(1 - |x| / radius, 0, 1)`
    SphereDistance {
        /// world units
        radius: f64,
    },
    /// The Marschner-Lobb test signal (f_M = 6, alpha = 0.25).
    MarschnerLobb,
}

impl Field {
    /// The scene-file name of the field.
    pub fn name(&self) -> &'static str {
        match self {
            Field::Gaussian { .. } => "gaussian",
            Field::Ball { .. } => "ball",
            Field::SphereDistance { .. } => "sphere-distance",
            Field::MarschnerLobb => "marschner-lobb",
        }
    }

    /// The continuous field at world position `p`.
    pub fn eval(&self, p: DVec3) -> f64 {
        match *self {
            Field::Gaussian { sigma } => (-p.length_squared() / (2.0 * sigma * sigma)).exp(),
            Field::Ball { radius } => {
                if p.length() <= radius {
                    1.0
                } else {
                    0.0
                }
            }
            Field::SphereDistance { radius } => (1.0 - p.length() / radius).clamp(0.0, 1.0),
            Field::MarschnerLobb => marschner_lobb(p),
        }
    }
}

/// REFERENCE.md "Reconstruction": the Marschner-Lobb signal on [-1, 1]^3.
pub fn marschner_lobb(p: DVec3) -> f64 {
    use std::f64::consts::PI;
    const F_M: f64 = 6.0;
    const ALPHA: f64 = 0.25;
    let r = (p.x * p.x + p.y * p.y).sqrt();
    let rho_r = (2.0 * PI * F_M * (PI * r / 2.0).cos()).cos();
    (1.0 - (PI * p.z / 2.0).sin() + ALPHA * (1.0 + rho_r)) / (2.0 * (1.0 + ALPHA))
}

/// A synthetic source: a field and the grid it is sampled on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Synthetic {
    /// The field.
    pub field: Field,
    /// Grid size along x, y, z (each at least 2).
    pub sizes: [usize; 3],
}

impl Synthetic {
    /// Grid geometry: first voxel at -1, last at +1 on every axis.
    pub fn geometry(&self) -> Geometry {
        let sp = self.sizes.map(|n| 2.0 / (n.max(2) - 1) as f64);
        let mut g = Geometry::from_spacing(sp);
        g.origin = DVec3::splat(-1.0);
        g
    }

    /// Sizes, type and geometry.
    pub fn header(&self) -> VolumeHeader {
        VolumeHeader {
            sizes: self.sizes,
            scalar_type: ScalarType::Float32,
            geometry: self.geometry(),
            source: format!("synthetic {}", self.field.name()),
            fields: Vec::new(),
        }
    }

    /// Samples the field on the grid.
    pub fn load(&self, limits: &Limits) -> Result<Volume, VolumeError> {
        if self.sizes.iter().any(|&n| n < 2) {
            return Err(VolumeError::Invalid(format!(
                "synthetic sizes must be at least 2 on every axis, got {:?}",
                self.sizes
            )));
        }
        let (count, _) = limits.check(&self.sizes, 4)?;
        let header = self.header();
        let g = header.geometry;
        let [nx, ny, _] = self.sizes;
        let mut v = Vec::with_capacity(count);
        for idx in 0..count {
            let i = idx % nx;
            let j = (idx / nx) % ny;
            let k = idx / (nx * ny);
            let p = g.world_from_index(DVec3::new(i as f64, j as f64, k as f64));
            v.push(self.field.eval(p) as f32);
        }
        Ok(Volume {
            header,
            data: VolumeData::F32(v),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_spans_cube() {
        let s = Synthetic {
            field: Field::Gaussian { sigma: 0.25 },
            sizes: [5, 9, 3],
        };
        let g = s.geometry();
        assert_eq!(g.world_from_index(DVec3::ZERO), DVec3::splat(-1.0));
        let last = g.world_from_index(DVec3::new(4.0, 8.0, 2.0));
        assert!((last - DVec3::ONE).length() < 1e-12);
        let vol = s.load(&Limits::default()).unwrap();
        // centre voxel of the odd grid is at the origin: value 1
        assert_eq!(vol.value(2, 4, 1), 1.0);
    }

    #[test]
    fn marschner_lobb_range() {
        // rho is in [0, 1] by construction
        for i in 0..1000 {
            let t = i as f64 / 999.0 * 2.0 - 1.0;
            let v = marschner_lobb(DVec3::new(t, 0.3 * t, -t));
            assert!((0.0..=1.0).contains(&v));
        }
    }
}
