//! Where voxels sit in the world.
//!
//! Convention (docs/formulas.md "Coordinates"): voxel `(i, j, k)` sits at
//! `origin + i*a0 + j*a1 + k*a2`, with `a0, a1, a2` the axis vectors (NRRD
//! `space directions`, or `spacing * unit axis` for plain spacings). Voxel values are
//! point samples at those positions (cell-centred data is treated the same way); the
//! sampled domain is the box spanned by the first and last voxel centres, which in
//! index space is `[0, n-1]` on each axis.

use glam::{DMat3, DVec3};

/// An affine map between index space and world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Geometry {
    /// World position of voxel (0, 0, 0).
    pub origin: DVec3,
    /// The world vector from one voxel to the next along each index axis (columns).
    pub axes: [DVec3; 3],
}

impl Default for Geometry {
    fn default() -> Self {
        Geometry::from_spacing([1.0; 3])
    }
}

impl Geometry {
    /// Axis-aligned grid with the given spacings and origin 0.
    pub fn from_spacing(spacing: [f64; 3]) -> Geometry {
        Geometry {
            origin: DVec3::ZERO,
            axes: [
                DVec3::X * spacing[0],
                DVec3::Y * spacing[1],
                DVec3::Z * spacing[2],
            ],
        }
    }

    /// The matrix whose columns are the axis vectors (`world_from_index` without the origin).
    pub fn matrix(&self) -> DMat3 {
        DMat3::from_cols(self.axes[0], self.axes[1], self.axes[2])
    }

    /// World position of a (fractional) index position.
    pub fn world_from_index(&self, p_index: DVec3) -> DVec3 {
        self.origin + self.matrix() * p_index
    }

    /// The inverse map; `None` when the axes are degenerate (zero or coplanar).
    pub fn index_from_world_matrix(&self) -> Option<DMat3> {
        let m = self.matrix();
        let det = m.determinant();
        let scale = self.axes.iter().map(|a| a.length()).product::<f64>();
        if !det.is_finite() || scale == 0.0 || det.abs() <= 1e-12 * scale {
            return None;
        }
        Some(m.inverse())
    }

    /// Length of each axis vector (the voxel spacing along that axis).
    pub fn spacings(&self) -> [f64; 3] {
        [
            self.axes[0].length(),
            self.axes[1].length(),
            self.axes[2].length(),
        ]
    }

    /// True when every axis vector is finite, non-zero and the three are independent.
    pub fn is_valid(&self) -> bool {
        self.origin.is_finite()
            && self.axes.iter().all(|a| a.is_finite())
            && self.index_from_world_matrix().is_some()
    }

    /// The eight world-space corners of the box spanned by the voxel centres of a
    /// grid of `sizes`.
    pub fn corners(&self, sizes: [usize; 3]) -> [DVec3; 8] {
        let hi = DVec3::from_array(sizes.map(|n| (n.max(1) - 1) as f64));
        self.box_corners(DVec3::ZERO, hi)
    }

    /// The eight world-space corners of the index-space box `[lo, hi]`.
    pub fn box_corners(&self, lo: DVec3, hi: DVec3) -> [DVec3; 8] {
        std::array::from_fn(|n| {
            let p = DVec3::new(
                if n & 1 != 0 { hi.x } else { lo.x },
                if n & 2 != 0 { hi.y } else { lo.y },
                if n & 4 != 0 { hi.z } else { lo.z },
            );
            self.world_from_index(p)
        })
    }

    /// Centre and radius of the sphere around the index-space box `[lo, hi]` (its
    /// circumsphere: centred on the box centre, through the corners).
    pub fn box_bounding_sphere(&self, lo: DVec3, hi: DVec3) -> (DVec3, f64) {
        let corners = self.box_corners(lo, hi);
        let centre = corners.iter().fold(DVec3::ZERO, |a, &c| a + c) / 8.0;
        let radius = corners
            .iter()
            .map(|&c| (c - centre).length())
            .fold(0.0, f64::max);
        (centre, radius)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_sheared() {
        let g = Geometry {
            origin: DVec3::new(1.0, -2.0, 3.0),
            axes: [
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(0.5, 2.0, 0.0),
                DVec3::new(0.0, 0.3, 1.5),
            ],
        };
        let inv = g.index_from_world_matrix().unwrap();
        let p = DVec3::new(3.0, 4.5, 7.25);
        let w = g.world_from_index(p);
        let back = inv * (w - g.origin);
        assert!((back - p).length() < 1e-12);
    }

    #[test]
    fn degenerate_axes_rejected() {
        let g = Geometry {
            origin: DVec3::ZERO,
            axes: [DVec3::X, DVec3::X * 2.0, DVec3::Z],
        };
        assert!(!g.is_valid());
        assert!(!Geometry::from_spacing([1.0, 0.0, 1.0]).is_valid());
    }

    #[test]
    fn bounding_sphere_of_unit_grid() {
        let g = Geometry::from_spacing([1.0, 1.0, 1.0]);
        let (c, r) = g.box_bounding_sphere(DVec3::ZERO, DVec3::splat(2.0));
        assert_eq!(c, DVec3::splat(1.0));
        assert!((r - 3f64.sqrt()).abs() < 1e-12);
    }
}
