//! Rays in index space and their clipping to the sampled box (docs/formulas.md
//! "Coordinates": the slab method, with care for zero direction components).

use glam::{DMat3, DVec3};

use crate::volume::Geometry;

/// The index-space frame of a volume: the box rays are clipped to and the map from
/// world to index coordinates.
#[derive(Clone, Copy, Debug)]
pub struct IndexFrame {
    /// Lower corner of the sampled box in index space.
    pub lo: DVec3,
    /// Upper corner.
    pub hi: DVec3,
    origin: DVec3,
    index_from_world: DMat3,
}

/// A ray in index space over world-unit parameter `t`: `p(t) = o + t * d`.
#[derive(Clone, Copy, Debug)]
pub struct IndexRay {
    /// Index-space start.
    pub o: DVec3,
    /// Index-space displacement per world unit of `t`.
    pub d: DVec3,
}

impl IndexRay {
    /// Index-space position at `t`.
    #[inline(always)]
    pub fn at(&self, t: f64) -> DVec3 {
        self.o + self.d * t
    }
}

impl IndexFrame {
    /// The frame of a grid of `sizes` with `geometry`. The box spans the voxel
    /// centres, `[0, n-1]` per axis, or the voxel index ranges of `crop` (inclusive,
    /// already checked to lie inside the grid); an axis one voxel wide gets a slab one
    /// voxel thick, `[i - 0.5, i + 0.5]`, so that thin volumes are visible from every side.
    pub fn new(
        sizes: [usize; 3],
        crop: Option<[[usize; 2]; 3]>,
        geometry: &Geometry,
        index_from_world: DMat3,
    ) -> IndexFrame {
        let range = |a: usize| crop.map_or([0, sizes[a].max(1) - 1], |c| c[a]);
        let lo = DVec3::from_array(std::array::from_fn(|a| {
            let [l, h] = range(a);
            if l == h {
                l as f64 - 0.5
            } else {
                l as f64
            }
        }));
        let hi = DVec3::from_array(std::array::from_fn(|a| {
            let [l, h] = range(a);
            if l == h {
                h as f64 + 0.5
            } else {
                h as f64
            }
        }));
        IndexFrame {
            lo,
            hi,
            origin: geometry.origin,
            index_from_world,
        }
    }

    /// Centre and radius (world units) of the sphere through the corners of the box:
    /// what cameras frame, and where depth is measured from.
    pub fn bounding_sphere(&self, geometry: &Geometry) -> (DVec3, f64) {
        geometry.box_bounding_sphere(self.lo, self.hi)
    }

    /// The map from index to world coordinates: `world = origin + matrix * index`.
    pub fn world_from_index(&self) -> (DVec3, DMat3) {
        (self.origin, self.index_from_world.inverse())
    }

    /// The index-space form of a world ray.
    #[inline]
    pub fn to_index(&self, origin: DVec3, dir: DVec3) -> IndexRay {
        IndexRay {
            o: self.index_from_world * (origin - self.origin),
            d: self.index_from_world * dir,
        }
    }

    /// The parameter interval `[t_enter, t_exit]` (with `t_enter >= t_min`) where
    /// the ray is inside the box, or `None` if it misses. A ray that grazes an
    /// edge or corner gets a one-point interval; a component of `d` equal to zero
    /// is handled without dividing by it.
    #[inline]
    pub fn clip(&self, ray: &IndexRay, t_min: f64) -> Option<(f64, f64)> {
        let mut t0 = t_min;
        let mut t1 = f64::INFINITY;
        for a in 0..3 {
            let (o, d, lo, hi) = (ray.o[a], ray.d[a], self.lo[a], self.hi[a]);
            if d == 0.0 {
                if o < lo || o > hi {
                    return None;
                }
                continue;
            }
            let inv = 1.0 / d;
            let (mut ta, mut tb) = ((lo - o) * inv, (hi - o) * inv);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
        (t0 <= t1 && t1.is_finite() && t0.is_finite()).then_some((t0, t1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(n: [usize; 3]) -> IndexFrame {
        IndexFrame::new(n, None, &Geometry::default(), DMat3::IDENTITY)
    }

    #[test]
    fn axis_aligned_rays_on_faces_edges_and_corners() {
        let f = frame([5, 5, 5]);
        // along +x exactly on an edge of the box (y = 0, z = 4)
        let r = f.to_index(DVec3::new(-10.0, 0.0, 4.0), DVec3::X);
        assert_eq!(f.clip(&r, 0.0), Some((10.0, 14.0)));
        // grazing a corner diagonally
        let d = DVec3::new(1.0, -1.0, 0.0).normalize();
        let r = f.to_index(DVec3::new(-1.0, 1.0, 0.0), d);
        let (a, b) = f.clip(&r, 0.0).unwrap();
        assert!((a - b).abs() < 1e-12);
        // just outside a face: miss
        let r = f.to_index(DVec3::new(-10.0, -1e-9, 2.0), DVec3::X);
        assert_eq!(f.clip(&r, 0.0), None);
    }

    #[test]
    fn camera_inside_starts_at_t_min() {
        let f = frame([5, 5, 5]);
        let r = f.to_index(DVec3::splat(2.0), DVec3::Z);
        assert_eq!(f.clip(&r, 0.0), Some((0.0, 2.0)));
    }

    #[test]
    fn crop_box_and_its_sphere() {
        let f = IndexFrame::new(
            [10, 10, 10],
            Some([[2, 4], [0, 9], [5, 5]]),
            &Geometry::default(),
            DMat3::IDENTITY,
        );
        assert_eq!(
            (f.lo, f.hi),
            (DVec3::new(2.0, 0.0, 4.5), DVec3::new(4.0, 9.0, 5.5))
        );
        let (c, r) = f.bounding_sphere(&Geometry::default());
        assert_eq!(c, DVec3::new(3.0, 4.5, 5.0));
        assert!((r - (1.0f64 + 4.5 * 4.5 + 0.25).sqrt()).abs() < 1e-12);
    }

    /// A ray starting on a face with a subnormal direction component has the bound
    /// 0 * inf = NaN on that axis: it is left out, as a zero component's would be,
    /// and the interval stays a number.
    #[test]
    fn a_nan_bound_is_left_out() {
        let f = frame([5, 5, 5]);
        let tiny = f64::from_bits(1); // 1 / tiny is infinite
        for t_min in [0.0, f64::NEG_INFINITY] {
            for (o, face) in [(0.0, "low"), (4.0, "high")] {
                let r = IndexRay {
                    o: DVec3::new(o, 2.0, -3.0),
                    d: DVec3::new(tiny, 0.0, 1.0),
                };
                assert!(
                    ((f.lo.x - o) * (1.0 / tiny)).is_nan()
                        || ((f.hi.x - o) * (1.0 / tiny)).is_nan()
                );
                let flat = IndexRay {
                    d: DVec3::new(0.0, 0.0, 1.0),
                    ..r
                };
                assert_eq!(
                    f.clip(&r, t_min),
                    Some((3.0, 7.0)),
                    "{face} face, t_min {t_min}"
                );
                assert_eq!(f.clip(&r, t_min), f.clip(&flat, t_min));
            }
        }
    }

    #[test]
    fn single_voxel_axis_is_a_slab() {
        let f = frame([4, 4, 1]);
        let r = f.to_index(DVec3::new(1.0, 1.0, -5.0), DVec3::Z);
        assert_eq!(f.clip(&r, 0.0), Some((4.5, 5.5)));
    }
}
