//! Clipping planes (`[[clip]]`): each removes a half-space from the volume, and a
//! ray's interval inside the box is cut analytically at each plane, so a cut has no
//! staircase and an integral over the kept part is exact to round-off.
//!
//! A plane through `point` with unit `normal` removes the points `p` with
//! `(p - point) . normal > 0` (the side the normal points into); points on the plane
//! are kept. Along a ray `p(t) = o + t d` the kept part of one plane is
//! `s + t r <= 0` with `s = (o - point) . normal` and `r = d . normal`: an upper
//! bound on `t` when `r > 0`, a lower bound when `r < 0`, all or nothing when
//! `r = 0`. The kept region of any number of planes is convex, so a ray keeps one
//! interval.

use glam::DVec3;

/// One clipping plane in world coordinates (the scene's `offset` already applied).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClipPlane {
    /// A point of the plane.
    pub point: DVec3,
    /// Unit normal, pointing into the removed half-space.
    pub normal: DVec3,
    /// Whether surface and depth passes treat the cut face as a surface where it
    /// lies inside the object (`cap = true`).
    pub cap: bool,
}

/// The plane through which a ray enters the kept region, when it is a clipping
/// plane rather than a face of the box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cut {
    /// The plane's unit normal: the outward normal of the cut face, which faces
    /// the viewer (the ray enters against it).
    pub normal: DVec3,
    /// The plane's `cap`.
    pub cap: bool,
}

/// Cuts the ray `origin + t dir` inside `[t0, t1]` by `planes`: the interval that
/// is kept, and the plane the ray enters through when one moved the entry; `None`
/// when nothing is kept.
pub fn clip_ray(
    planes: &[ClipPlane],
    origin: DVec3,
    dir: DVec3,
    (mut t0, mut t1): (f64, f64),
) -> Option<(f64, f64, Option<Cut>)> {
    let mut cut = None;
    for p in planes {
        let s = (origin - p.point).dot(p.normal);
        let r = dir.dot(p.normal);
        if r > 0.0 {
            t1 = t1.min(-s / r);
        } else if r < 0.0 {
            let t = -s / r;
            if t > t0 {
                t0 = t;
                cut = Some(Cut {
                    normal: p.normal,
                    cap: p.cap,
                });
            }
        } else if s > 0.0 || s.is_nan() {
            return None;
        }
    }
    (t0 <= t1).then_some((t0, t1, cut))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(point: [f64; 3], normal: [f64; 3]) -> ClipPlane {
        ClipPlane {
            point: DVec3::from_array(point),
            normal: DVec3::from_array(normal).normalize(),
            cap: false,
        }
    }

    #[test]
    fn a_plane_across_the_ray_moves_one_end() {
        // removes x > 2: a ray along +x keeps [.., 2]
        let p = [plane([2.0, 0.0, 0.0], [1.0, 0.0, 0.0])];
        assert_eq!(
            clip_ray(&p, DVec3::ZERO, DVec3::X, (0.0, 5.0)),
            Some((0.0, 2.0, None))
        );
        // along -x from x = 5 the ray enters the kept side through the plane
        let (t0, t1, cut) = clip_ray(&p, DVec3::new(5.0, 0.0, 0.0), -DVec3::X, (0.0, 5.0)).unwrap();
        assert_eq!((t0, t1), (3.0, 5.0));
        assert_eq!(cut.unwrap().normal, DVec3::X);
    }

    #[test]
    fn parallel_rays_are_kept_or_removed_whole() {
        let p = [plane([0.0, 1.0, 0.0], [0.0, 1.0, 0.0])];
        assert!(clip_ray(&p, DVec3::new(0.0, 2.0, 0.0), DVec3::X, (0.0, 1.0)).is_none());
        // on the plane: kept
        assert_eq!(
            clip_ray(&p, DVec3::new(0.0, 1.0, 0.0), DVec3::X, (0.0, 1.0)),
            Some((0.0, 1.0, None))
        );
    }

    #[test]
    fn two_planes_keep_a_slab_and_report_the_later_entry() {
        let p = [
            plane([1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]),
            plane([3.0, 0.0, 0.0], [1.0, 0.0, 0.0]),
        ];
        let (t0, t1, cut) = clip_ray(&p, DVec3::ZERO, DVec3::X, (0.0, 10.0)).unwrap();
        assert_eq!((t0, t1), (1.0, 3.0));
        assert_eq!(cut.unwrap().normal, -DVec3::X);
        // a slab the ray's interval does not reach
        assert!(clip_ray(&p, DVec3::ZERO, DVec3::X, (4.0, 10.0)).is_none());
    }
}
