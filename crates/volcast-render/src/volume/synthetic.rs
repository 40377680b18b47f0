//! Analytic test fields sampled on a grid spanning the cube [-1, 1]^3.
//!
//! The fields and their closed-form renderings are listed in docs/formulas.md
//! ("Analytic references for accuracy tests"); `blobs` is the field of the common
//! benchmark (docs/performance.md). Values lie in [0, 1]; the data is
//! stored as `float`, or quantised to `uint8` / `uint16` (`round(max v)`, where
//! `max` is the type's largest value).

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
    /// Four Gaussian blobs and a thin spherical shell in air (the common benchmark's
    /// field: values below 1e-3 are 0, the sum is clipped to 1).
    Blobs,
}

/// The blobs of [`Field::Blobs`]: centre, sigma, amplitude.
const BLOBS: [([f64; 3], f64, f64); 4] = [
    ([-0.30, -0.20, 0.10], 0.18, 1.00),
    ([0.35, 0.10, -0.20], 0.12, 0.80),
    ([0.05, 0.40, 0.35], 0.10, 0.60),
    ([0.00, -0.35, -0.35], 0.22, 0.45),
];

impl Field {
    /// The scene-file name of the field.
    pub fn name(&self) -> &'static str {
        match self {
            Field::Gaussian { .. } => "gaussian",
            Field::Ball { .. } => "ball",
            Field::SphereDistance { .. } => "sphere-distance",
            Field::MarschnerLobb => "marschner-lobb",
            Field::Blobs => "blobs",
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
            Field::Blobs => {
                let mut v: f64 = BLOBS
                    .iter()
                    .map(|&(c, sigma, a)| {
                        a * (-(p - DVec3::from_array(c)).length_squared() / (2.0 * sigma * sigma))
                            .exp()
                    })
                    .sum();
                v += 0.35 * (-(p.length() - 0.8).powi(2) / (2.0 * 0.015 * 0.015)).exp();
                if v < 1e-3 {
                    0.0
                } else {
                    v.min(1.0)
                }
            }
        }
    }
}

/// docs/formulas.md "Reconstruction": the Marschner-Lobb signal on [-1, 1]^3.
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
    /// How the values are stored: `Float32`, or quantised `Uint8` / `Uint16`.
    pub scalar_type: ScalarType,
}

impl Synthetic {
    /// The field on a grid of `sizes`, as float32.
    pub fn new(field: Field, sizes: [usize; 3]) -> Synthetic {
        Synthetic {
            field,
            sizes,
            scalar_type: ScalarType::Float32,
        }
    }

    /// The largest stored value (the value 1 of the field): 1 for float32, 255 for
    /// uint8, 65535 for uint16 (the default window's upper end).
    pub fn max_value(&self) -> f64 {
        match self.scalar_type {
            ScalarType::Uint8 => 255.0,
            ScalarType::Uint16 => 65535.0,
            _ => 1.0,
        }
    }
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
            scalar_type: self.scalar_type,
            geometry: self.geometry(),
            source: format!("synthetic {}", self.field.name()),
            fields: Vec::new(),
            rescale: Default::default(),
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
        let (count, _) = limits.check(&self.sizes, self.scalar_type.size())?;
        let header = self.header();
        let g = header.geometry;
        let [nx, ny, _] = self.sizes;
        // planes in parallel, each voxel from its own index: the same values whatever
        // the thread count
        let plane = nx * ny;
        let values = |k: usize| -> Vec<f64> {
            (0..plane)
                .map(|ij| {
                    let p = g.world_from_index(DVec3::new(
                        (ij % nx) as f64,
                        (ij / nx) as f64,
                        k as f64,
                    ));
                    self.field.eval(p)
                })
                .collect()
        };
        use rayon::prelude::*;
        let planes = (0..count / plane.max(1)).into_par_iter().map(values);
        let max = self.max_value();
        let data = match self.scalar_type {
            ScalarType::Uint8 => VolumeData::U8(
                planes
                    .flat_map_iter(|p| p.into_iter().map(|v| (v * max).round() as u8))
                    .collect(),
            ),
            ScalarType::Uint16 => VolumeData::U16(
                planes
                    .flat_map_iter(|p| p.into_iter().map(|v| (v * max).round() as u16))
                    .collect(),
            ),
            _ => VolumeData::F32(
                planes
                    .flat_map_iter(|p| p.into_iter().map(|v| v as f32))
                    .collect(),
            ),
        };
        Ok(Volume { header, data })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_spans_cube() {
        let s = Synthetic::new(Field::Gaussian { sigma: 0.25 }, [5, 9, 3]);
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

#[cfg(test)]
mod blob_tests {
    use super::*;

    #[test]
    fn blobs_are_quantised_as_asked() {
        let f = Synthetic::new(Field::Blobs, [9, 9, 9]);
        let u = Synthetic {
            scalar_type: ScalarType::Uint8,
            ..f
        };
        let (vf, vu) = (
            f.load(&Limits::default()).unwrap(),
            u.load(&Limits::default()).unwrap(),
        );
        assert_eq!(vu.header.scalar_type, ScalarType::Uint8);
        for i in 0..9 * 9 * 9 {
            let (a, b) = (vf.data.get_f64(i), vu.data.get_f64(i));
            assert_eq!(b, (a * 255.0).round(), "voxel {i}");
        }
        // air at the corners, the brightest blob near its centre
        assert_eq!(Field::Blobs.eval(DVec3::splat(1.0)), 0.0);
        assert!(Field::Blobs.eval(DVec3::new(-0.3, -0.2, 0.1)) > 0.99);
    }
}
