//! Views: from the scene's camera, orbit and eye to one ray per pixel.
//!
//! Conventions (docs/formulas.md "Cameras"): at azimuth 0, elevation 0 and up = +z the eye
//! is on the -y side of the target looking along +y, image right is +x and image up
//! is +z. Azimuth turns the eye counter-clockwise about `up` seen from above;
//! elevation raises it towards `up`. For another `up`, the whole construction is
//! rotated by the shortest rotation taking +z to `up`. The image basis is built from
//! the azimuth directly (right = the orbit's tangent), never from a cross product
//! with `up`, so a view straight along `up` (elevation ±90) is as well defined as
//! any other. Pixel `(i, j)` (row 0 at the top) samples at its centre.

use glam::{DQuat, DVec3};

/// Perspective or parallel projection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Projection {
    /// Pinhole camera.
    Perspective,
    /// Parallel rays.
    Orthographic,
}

/// The camera description of docs/scene-reference.md.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Projection.
    pub projection: Projection,
    /// Vertical field of view in degrees (perspective).
    pub fov_deg: f64,
    /// Degrees, counter-clockwise about `up` seen from above.
    pub azimuth_deg: f64,
    /// Degrees towards `up`.
    pub elevation_deg: f64,
    /// World up, also the orbit axis (unit length).
    pub up: DVec3,
    /// Image magnification (1 until a `zoom = "fit"` is computed).
    pub zoom: f64,
    /// `zoom = "fit"`: the zoom is computed from the voxels when they are loaded.
    pub fit: Option<ZoomFit>,
    /// Eye-target distance in world units (perspective); `None` frames the bounding sphere.
    pub distance: Option<f64>,
    /// Look-at point; `None` = the centre of the volume's box.
    pub target: Option<DVec3>,
}

/// `[camera] zoom = "fit"`: one zoom for every frame that frames the box of the
/// voxels at or above `threshold`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZoomFit {
    /// Normalised value (`fit_threshold`); `None` = the scene passes' smallest
    /// threshold, iso value, first opaque knot or window low end.
    pub threshold: Option<f64>,
}

/// One rendered view: a camera pose and its image plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Projection.
    pub projection: Projection,
    /// Eye position (perspective); for orthographic views, the centre of the plane
    /// the parallel rays start from (outside the bounding sphere).
    pub eye: DVec3,
    /// Unit viewing direction.
    pub forward: DVec3,
    /// Unit image-right vector.
    pub right: DVec3,
    /// Unit image-up vector.
    pub up: DVec3,
    /// Perspective: tangent of the half field of view horizontally; orthographic:
    /// half the image width in world units.
    pub half_width: f64,
    /// As `half_width`, vertically.
    pub half_height: f64,
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// Bounding sphere of the volume's box (depth is measured from where rays enter it).
    pub sphere: (DVec3, f64),
    /// Distance from the eye to the target along `forward` (perspective: the
    /// camera's distance; orthographic: from the plane the rays start from).
    pub distance: f64,
    /// Horizontal offset of the image window, in the units of `half_width`: 0 for
    /// a symmetric frustum; an off-axis stereo eye's window is shifted so that
    /// both eyes' windows coincide at the target distance.
    pub shift: f64,
}

/// A ray in world space: `origin + t * dir`, `|dir| = 1`, `t >= 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point.
    pub origin: DVec3,
    /// Unit direction.
    pub dir: DVec3,
}

impl View {
    /// The view of `camera` turned by `azimuth_offset_deg` about `up` (orbit frames
    /// and stereo eyes), for an image of `width x height` pixels and a volume whose
    /// box has bounding sphere `sphere` (centre, radius).
    pub fn new(
        camera: &Camera,
        azimuth_offset_deg: f64,
        width: usize,
        height: usize,
        sphere: (DVec3, f64),
    ) -> View {
        let (centre, radius) = sphere;
        let target = camera.target.unwrap_or(centre);
        let az = (camera.azimuth_deg + azimuth_offset_deg).to_radians();
        let el = camera.elevation_deg.to_radians();
        let to_world = DQuat::from_rotation_arc(DVec3::Z, camera.up);
        let back = to_world * DVec3::new(az.sin() * el.cos(), -az.cos() * el.cos(), el.sin());
        let right = (to_world * DVec3::new(az.cos(), az.sin(), 0.0)).normalize();
        let forward = (-back).normalize();
        let up = right.cross(forward).normalize();
        let aspect = width as f64 / height as f64;
        // Radius around the target that must fit in the image.
        let reach = radius + (target - centre).length();
        match camera.projection {
            Projection::Perspective => {
                let tan_v = (camera.fov_deg.to_radians() / 2.0).tan();
                let tan_h = tan_v * aspect;
                let distance = camera.distance.unwrap_or_else(|| {
                    let half = tan_v.min(tan_h).atan();
                    reach / half.sin()
                });
                View {
                    projection: Projection::Perspective,
                    eye: target + back * distance,
                    forward,
                    right,
                    up,
                    half_width: tan_h / camera.zoom,
                    half_height: tan_v / camera.zoom,
                    width,
                    height,
                    sphere,
                    distance,
                    shift: 0.0,
                }
            }
            Projection::Orthographic => {
                let (hw, hh) = if aspect >= 1.0 {
                    (radius * aspect, radius)
                } else {
                    (radius, radius / aspect)
                };
                View {
                    projection: Projection::Orthographic,
                    eye: target + back * (2.0 * reach + 1.0),
                    forward,
                    right,
                    up,
                    half_width: hw / camera.zoom,
                    half_height: hh / camera.zoom,
                    width,
                    height,
                    sphere,
                    distance: 2.0 * reach + 1.0,
                    shift: 0.0,
                }
            }
        }
    }

    /// This view's eye moved by `offset` world units along `right`, looking in the
    /// same direction, with its image window shifted so that it still covers the
    /// same rectangle at the target distance (an off-axis, "parallel" stereo eye).
    /// A point at the target distance then projects to the same pixel for every
    /// offset; nearer points move against the offset, farther ones with it.
    ///
    /// Only meaningful for perspective views (orthographic eyes with parallel
    /// directions see the same picture; the scene resolver refuses that combination).
    pub fn off_axis(&self, offset: f64) -> View {
        View {
            eye: self.eye + self.right * offset,
            shift: self.shift - offset / self.distance,
            ..*self
        }
    }

    /// The ray through image position `(x, y)` in pixels (`(i + 0.5, j + 0.5)` is the
    /// centre of pixel `(i, j)`; row 0 at the top).
    #[inline]
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let px = x / self.width as f64 * 2.0 - 1.0;
        let py = 1.0 - y / self.height as f64 * 2.0;
        match self.projection {
            Projection::Perspective => Ray {
                origin: self.eye,
                dir: (self.forward
                    + self.right * (px * self.half_width + self.shift)
                    + self.up * (py * self.half_height))
                    .normalize(),
            },
            Projection::Orthographic => Ray {
                origin: self.eye
                    + self.right * (px * self.half_width)
                    + self.up * (py * self.half_height),
                dir: self.forward,
            },
        }
    }

    /// The ray through the centre of pixel `(i, j)`.
    #[inline]
    pub fn pixel_ray(&self, i: usize, j: usize) -> Ray {
        self.ray(i as f64 + 0.5, j as f64 + 0.5)
    }

    /// Where depth is measured from along `ray`: its entry into the bounding sphere,
    /// or its origin if that is inside the sphere. `None` if it misses the sphere.
    #[inline]
    pub fn depth_reference(&self, ray: &Ray) -> Option<f64> {
        let (c, r) = self.sphere;
        let oc = ray.origin - c;
        let b = oc.dot(ray.dir);
        let q = oc.length_squared() - r * r;
        if q <= 0.0 {
            return Some(0.0);
        }
        let disc = b * b - q;
        if disc < 0.0 {
            return None;
        }
        let t = -b - disc.sqrt();
        (t >= 0.0).then_some(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam(projection: Projection) -> Camera {
        Camera {
            projection,
            fov_deg: 30.0,
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            up: DVec3::Z,
            zoom: 1.0,
            fit: None,
            distance: None,
            target: None,
        }
    }

    #[test]
    fn contract_orientation() {
        let v = View::new(
            &cam(Projection::Perspective),
            0.0,
            64,
            64,
            (DVec3::ZERO, 1.0),
        );
        assert!((v.forward - DVec3::Y).length() < 1e-12);
        assert!((v.right - DVec3::X).length() < 1e-12);
        assert!((v.up - DVec3::Z).length() < 1e-12);
        assert!(v.eye.y < 0.0);
        // azimuth 90: counter-clockwise seen from above moves the eye from -y to +x
        let v = View::new(
            &cam(Projection::Perspective),
            90.0,
            64,
            64,
            (DVec3::ZERO, 1.0),
        );
        assert!(v.eye.x > 0.0 && v.eye.y.abs() < 1e-9);
        // top-left pixel looks up and to the left
        let r = View::new(
            &cam(Projection::Orthographic),
            0.0,
            4,
            4,
            (DVec3::ZERO, 1.0),
        )
        .pixel_ray(0, 0);
        assert!(r.origin.x < 0.0 && r.origin.z > 0.0);
    }

    #[test]
    fn poles_are_finite() {
        for el in [90.0, -90.0] {
            let mut c = cam(Projection::Perspective);
            c.elevation_deg = el;
            for az in [0.0, 45.0, 180.0] {
                let v = View::new(&c, az, 8, 8, (DVec3::ZERO, 1.0));
                for d in [v.forward, v.right, v.up] {
                    assert!(d.is_finite() && (d.length() - 1.0).abs() < 1e-9);
                }
                assert!((v.forward - DVec3::Z * -el.signum()).length() < 1e-9);
            }
        }
    }

    #[test]
    fn other_up_vectors() {
        for up in [DVec3::Y, -DVec3::Z, DVec3::new(1.0, 1.0, 0.0).normalize()] {
            let mut c = cam(Projection::Perspective);
            c.up = up;
            let v = View::new(&c, 30.0, 8, 8, (DVec3::ZERO, 1.0));
            assert!(
                v.forward.dot(up).abs() < 1e-9,
                "elevation 0 looks perpendicular to up"
            );
            assert!(v.up.dot(up) > 0.999);
        }
    }

    #[test]
    fn default_distance_frames_the_sphere() {
        let v = View::new(
            &cam(Projection::Perspective),
            0.0,
            10,
            10,
            (DVec3::ZERO, 2.0),
        );
        let d = v.eye.length();
        // the sphere's silhouette touches the edge of the field of view
        assert!(((2.0 / d).asin() - 15f64.to_radians()).abs() < 1e-9);
    }

    /// Pixel position (x, y) where a world point appears in a perspective view.
    fn project(v: &View, p: DVec3) -> (f64, f64) {
        let d = p - v.eye;
        let (z, x, y) = (d.dot(v.forward), d.dot(v.right), d.dot(v.up));
        let px = (x / z - v.shift) / v.half_width;
        let py = y / z / v.half_height;
        (
            (px + 1.0) / 2.0 * v.width as f64,
            (1.0 - py) / 2.0 * v.height as f64,
        )
    }

    #[test]
    fn off_axis_eyes_converge_at_the_target_distance() {
        let mut c = cam(Projection::Perspective);
        c.distance = Some(10.0);
        c.target = Some(DVec3::new(0.5, 0.0, 0.0));
        let centre = View::new(&c, 25.0, 64, 48, (DVec3::ZERO, 1.0));
        assert!((centre.distance - 10.0).abs() < 1e-12);
        let (l, r) = (centre.off_axis(-0.3), centre.off_axis(0.3));
        assert_eq!(l.forward, centre.forward);
        assert!(((r.eye - l.eye).length() - 0.6).abs() < 1e-12);
        assert!((r.eye - l.eye).normalize().dot(centre.right) > 1.0 - 1e-12);
        // on the target plane: no disparity, anywhere in the picture
        let target = c.target.unwrap();
        for (dx, dy) in [(0.0, 0.0), (1.0, 0.5), (-2.0, -1.0)] {
            let p = target + centre.right * dx + centre.up * dy;
            let (pl, pr) = (project(&l, p), project(&r, p));
            assert!((pl.0 - pr.0).abs() < 1e-9 && (pl.1 - pr.1).abs() < 1e-9);
            // and the ray through that pixel hits the point
            let ray = r.ray(pr.0, pr.1);
            assert!((ray.origin + ray.dir * (p - ray.origin).length() - p).length() < 1e-9);
        }
        // nearer than the target: crossed disparity (left eye sees it further right)
        let near = target - centre.forward * 3.0;
        assert!(project(&l, near).0 > project(&r, near).0 + 1.0);
        let far = target + centre.forward * 3.0;
        assert!(project(&l, far).0 < project(&r, far).0 - 1.0);
        // the symmetric view is unchanged by a zero offset
        assert_eq!(centre.off_axis(0.0), centre);
    }

    #[test]
    fn depth_reference() {
        let v = View::new(
            &cam(Projection::Orthographic),
            0.0,
            1,
            1,
            (DVec3::ZERO, 1.0),
        );
        let r = v.pixel_ray(0, 0);
        let t = v.depth_reference(&r).unwrap();
        assert!(((r.origin + r.dir * t).length() - 1.0).abs() < 1e-9);
    }
}
