//! Which views a run renders: the eyes of each frame, where each eye stands, and
//! which (frame, eye) images are the same view and so are rendered once.
//!
//! A view is named by a [`ViewKey`]: an orbit position (in frames, frame `k` at
//! `azimuth + k * degrees / frames`) and an eye. Two cases make different
//! (frame, eye) pairs name the same key:
//!
//! - **Toe-in reuse.** Each toe-in eye is turned `±angle/2` about `up`, so when the
//!   stereo angle is a whole number `m` of orbit steps, the left eye of frame `k`
//!   (at `k*step - angle/2`) is the right eye of frame `k - m` (at
//!   `(k-m)*step + angle/2`). The left view is then *defined* as that right view,
//!   whether or not a run actually shares it, so the bytes never depend on reuse.
//! - **Periodic orbits.** When `degrees` divides a multiple of 360 into a whole
//!   number of frames (a full turn, or a 720-degree one), positions are taken modulo
//!   the period: the left eye of frame 0 of a 360-degree stereo turntable is the
//!   right eye of its last frame (for `m = 1`).
//!
//! Off-axis (`parallel`) eyes are shifted, not turned, and never coincide with
//! another frame's eye.

use std::collections::BTreeSet;
use std::fmt::Write as _;

use glam::DVec3;

use crate::render::View;
use crate::scene::camera_on_path;
use crate::scene::{Camera, Keyframes, Orbit, OrbitPath, Scene, Separation, StereoMethod};

/// Which eye an image belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Eye {
    /// No stereo.
    Mono,
    /// Left eye (turned -angle/2).
    Left,
    /// Right eye (turned +angle/2).
    Right,
}

/// One distinct view: an orbit position and an eye placed there.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ViewKey {
    /// Orbit position in frames (reduced modulo the orbit's period, if it has one;
    /// may be negative or beyond the last frame for a reused toe-in left eye).
    pub position: i64,
    /// The eye at that position.
    pub eye: Eye,
}

/// Where the eyes of a frame stand relative to the orbit's camera.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Placement {
    Mono,
    /// Each eye turned by ∓`half_angle_deg` about `up`.
    ToeIn {
        half_angle_deg: f64,
    },
    /// Each eye shifted by ∓separation/2 along `right`.
    Parallel(Separation),
}

/// The views of a scene's orbit.
#[derive(Clone, Debug, PartialEq)]
pub struct Views {
    placement: Placement,
    frames: usize,
    degrees: f64,
    /// `m`: the left eye of frame `k` is the right eye of frame `k - m`.
    reuse: Option<i64>,
    /// Orbit positions `p` and `p + period` are the same view.
    period: Option<i64>,
    /// Whether identical views are rendered once (`false` renders every (frame,
    /// eye) image on its own, with the same poses; for tests and comparisons).
    pub share: bool,
    /// The scene's camera: what the circle turns by the orbit offset.
    camera: Camera,
    /// The path other than the circle (rock, elevation, keyframes) that places
    /// each frame's camera, computed per frame from `camera`.
    path: Option<(Orbit, Option<Keyframes>)>,
    /// The zoom `fit` found, which replaces every frame's (keyframes included).
    zoom: Option<f64>,
}

/// A whole number `n` when `x` is within a relative 1e-9 of it (and not zero).
fn whole(x: f64) -> Option<i64> {
    let r = x.round();
    (x.is_finite() && r != 0.0 && r.abs() < 1e12 && (x - r).abs() <= 1e-9 * r.abs())
        .then_some(r as i64)
}

impl Views {
    /// The views of `scene`'s orbit; `share` renders identical views once.
    pub fn new(scene: &Scene, share: bool) -> Views {
        let (frames, degrees) = (scene.orbit.frames, scene.orbit.degrees);
        let placement = match &scene.stereo {
            None => Placement::Mono,
            Some(s) => match s.method {
                StereoMethod::ToeIn => Placement::ToeIn {
                    half_angle_deg: s.angle_deg / 2.0,
                },
                StereoMethod::Parallel(sep) => Placement::Parallel(sep),
            },
        };
        let path =
            (scene.orbit.path != OrbitPath::Circle).then(|| (scene.orbit, scene.keyframes.clone()));
        let reuse = match (placement, &scene.stereo) {
            // views coincide only on the circle
            _ if path.is_some() => None,
            (Placement::ToeIn { .. }, Some(s)) if degrees != 0.0 => {
                whole(s.angle_deg * frames as f64 / degrees)
            }
            _ => None,
        };
        let period = if path.is_some() {
            None
        } else if degrees == 0.0 {
            Some(1)
        } else {
            whole(360.0 * frames as f64 / degrees.abs()).filter(|&q| q > 0)
        };
        Views {
            placement,
            frames,
            degrees,
            reuse,
            period,
            share,
            camera: scene.camera,
            path,
            zoom: None,
        }
    }

    /// The same views with every camera's zoom set to `zoom` (`zoom = "fit"`, found
    /// once the voxels are loaded; keyframes cannot animate the zoom then, so this
    /// is what the scene with that zoom would give).
    pub fn with_zoom(mut self, zoom: f64) -> Views {
        self.camera.zoom = zoom;
        self.zoom = Some(zoom);
        self
    }

    /// The number of frames of the whole orbit.
    pub fn orbit_frames(&self) -> usize {
        self.frames
    }

    /// The eyes of every frame, in file order.
    pub fn eyes(&self) -> &'static [Eye] {
        match self.placement {
            Placement::Mono => &[Eye::Mono],
            _ => &[Eye::Left, Eye::Right],
        }
    }

    /// `m` when toe-in reuse applies: the left eye of frame `k` is the right eye of
    /// frame `k - m`.
    pub fn reuse_steps(&self) -> Option<i64> {
        self.reuse
    }

    /// The frames of the orbit that have a keyframe: where a keyframed camera takes
    /// the values it interpolates between (none on other paths).
    pub fn keyed_frames(&self) -> Vec<usize> {
        match &self.path {
            Some((_, Some(kf))) => kf
                .frames
                .iter()
                .copied()
                .filter(|&k| k < self.frames)
                .collect(),
            _ => Vec::new(),
        }
    }

    /// The orbit's period in frames, when it has one.
    pub fn period(&self) -> Option<i64> {
        self.period
    }

    /// The view that `eye` of `frame` shows.
    pub fn key(&self, frame: usize, eye: Eye) -> ViewKey {
        let k = frame as i64;
        let (position, eye) = match (eye, self.reuse) {
            (Eye::Left, Some(m)) => (k - m, Eye::Right),
            _ => (k, eye),
        };
        let position = match self.period {
            Some(q) => position.rem_euclid(q),
            None => position,
        };
        ViewKey { position, eye }
    }

    /// The distinct views the given frames need, in order. With `share` off, one
    /// entry per (frame, eye), even where views coincide.
    pub fn needed(&self, frames: impl IntoIterator<Item = usize>) -> usize {
        let frames: Vec<usize> = frames.into_iter().collect();
        if self.share {
            frames
                .iter()
                .flat_map(|&k| self.eyes().iter().map(move |&e| self.key(k, e)))
                .collect::<BTreeSet<_>>()
                .len()
        } else {
            frames.len() * self.eyes().len()
        }
    }

    /// Azimuth offset (degrees, added to the camera's azimuth) of an orbit position.
    /// The same expression as `Orbit::azimuth_offset_deg`, for any integer position.
    fn orbit_offset_deg(&self, position: i64) -> f64 {
        position as f64 * self.degrees / self.frames as f64
    }

    /// The azimuth offset of a view from its camera (the orbit position on the
    /// circle, plus the toe-in turn).
    pub fn azimuth_offset_deg(&self, key: ViewKey) -> f64 {
        let base = if self.path.is_some() {
            0.0
        } else {
            self.orbit_offset_deg(key.position)
        };
        match (self.placement, key.eye) {
            (Placement::ToeIn { half_angle_deg }, Eye::Left) => base + -half_angle_deg,
            (Placement::ToeIn { half_angle_deg }, Eye::Right) => base + half_angle_deg,
            _ => base,
        }
    }

    /// The camera a view turns by [`Views::azimuth_offset_deg`]: the scene's on
    /// the circle, the frame's on other paths.
    fn camera_of(&self, key: ViewKey) -> Camera {
        match &self.path {
            Some(_) => self.frame_camera(key.position as usize),
            None => self.camera,
        }
    }

    /// Frame `k`'s camera on a path other than the circle.
    fn frame_camera(&self, k: usize) -> Camera {
        let Some((orbit, keyframes)) = &self.path else {
            return self.camera;
        };
        let mut c = camera_on_path(self.camera, orbit, keyframes.as_ref(), k);
        if let Some(z) = self.zoom {
            c.zoom = z;
        }
        c
    }

    /// The azimuth and elevation (degrees) a view is seen from.
    pub fn angles_deg(&self, key: ViewKey) -> (f64, f64) {
        let c = self.camera_of(key);
        (
            c.azimuth_deg + self.azimuth_offset_deg(key),
            c.elevation_deg,
        )
    }

    /// The azimuth and elevation (degrees) of frame `k`'s camera, before any eye's
    /// turn: what labels and NRRD files name the frame by (the same values as
    /// `Scene::camera_at`, not reduced by the orbit's period).
    pub fn frame_angles_deg(&self, k: usize) -> (f64, f64) {
        match &self.path {
            Some(_) => {
                let c = self.frame_camera(k);
                (c.azimuth_deg, c.elevation_deg)
            }
            None => (
                self.camera.azimuth_deg + self.orbit_offset_deg(k as i64),
                self.camera.elevation_deg,
            ),
        }
    }

    /// The camera pose and image plane of a view.
    pub fn view(&self, key: ViewKey, width: usize, height: usize, sphere: (DVec3, f64)) -> View {
        let view = View::new(
            &self.camera_of(key),
            self.azimuth_offset_deg(key),
            width,
            height,
            sphere,
        );
        match (self.placement, key.eye) {
            (Placement::Parallel(sep), Eye::Left | Eye::Right) => {
                let s = match sep {
                    Separation::World(s) => s,
                    Separation::Fraction(f) => f * view.distance,
                };
                view.off_axis(if key.eye == Eye::Left {
                    -s / 2.0
                } else {
                    s / 2.0
                })
            }
            _ => view,
        }
    }

    /// One line for `volcast check`: how many views the frames need and why.
    pub fn describe(&self, frames: &[usize]) -> String {
        let images = frames.len() * self.eyes().len();
        let needed = self.needed(frames.iter().copied());
        let mut s = format!("{needed} to render per pass ({images} eye images");
        match (self.placement, self.reuse, self.share) {
            (Placement::ToeIn { .. }, None, true) if self.path.is_some() => {
                s.push_str("; no reuse: views coincide only on the circle path")
            }
            (Placement::ToeIn { .. }, Some(m), true) => {
                let _ = write!(
                    s,
                    "; toe-in reuse: the left eye of frame k is the right eye of frame k-{m}"
                );
                if self.period.is_some() {
                    s.push_str(", around the turn");
                }
            }
            (Placement::ToeIn { half_angle_deg }, None, true) if frames.len() > 1 => {
                let step = self.degrees / self.frames as f64;
                let _ = write!(
                    s,
                    "; no reuse: the stereo angle {} is not a whole number of {step:.4}-degree steps",
                    2.0 * half_angle_deg
                );
            }
            (_, _, false) => s.push_str("; reuse switched off"),
            _ => {}
        }
        s.push(')');
        s
    }
}

/// Frames rendered together: their views are rendered in parallel, then their
/// images written while the next batch renders (views a later frame reuses are
/// kept). Enough to keep every thread busy; bounded, so memory does not grow with
/// the length of the orbit (at most two batches' views are held).
pub fn frames_per_batch(threads: usize) -> usize {
    (2 * threads).max(4)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(stereo: &str, frames: usize, degrees: f64) -> Scene {
        let text = format!(
            "[volume]\nsynthetic = \"ball\"\nsizes = [4, 4, 4]\n[orbit]\nframes = {frames}\ndegrees = {degrees:?}\n{stereo}"
        );
        crate::scene::parse(&text, std::path::Path::new("t.toml")).unwrap()
    }

    #[test]
    fn toe_in_reuse_when_the_angle_is_a_whole_number_of_steps() {
        // 45 frames of 8 degrees, stereo angle 8: m = 1, a full turn costs 45 views
        let v = Views::new(&scene("[stereo]\nangle = 8.0", 45, 360.0), true);
        assert_eq!(v.reuse_steps(), Some(1));
        assert_eq!(v.period(), Some(45));
        assert_eq!(v.key(5, Eye::Left), v.key(4, Eye::Right));
        assert_eq!(v.key(0, Eye::Left), v.key(44, Eye::Right));
        assert_eq!(v.needed(0..45), 45);
        assert_eq!(v.needed(10..20), 11);
        // the poses agree: left of frame 5 is at 5*8 - 4 = 36 degrees
        assert_eq!(v.azimuth_offset_deg(v.key(5, Eye::Left)), 36.0);
        // without sharing, every eye image is rendered
        let v = Views::new(&scene("[stereo]\nangle = 8.0", 45, 360.0), false);
        assert_eq!(v.needed(0..45), 90);
        assert_eq!(v.key(5, Eye::Left), v.key(4, Eye::Right));
        // m = 2 over a quarter turn: not periodic within the frames, keys go negative
        let v = Views::new(&scene("[stereo]\nangle = 20.0", 9, 90.0), true);
        assert_eq!(v.reuse_steps(), Some(2));
        assert_eq!(v.period(), Some(36));
        assert_eq!(v.key(0, Eye::Left).position, 34);
        assert_eq!(v.needed(0..9), 11);
    }

    #[test]
    fn no_reuse_otherwise() {
        let v = Views::new(&scene("[stereo]\nangle = 8.0", 36, 360.0), true);
        assert_eq!(v.reuse_steps(), None);
        assert_eq!(v.needed(0..36), 72);
        assert_eq!(v.azimuth_offset_deg(v.key(1, Eye::Left)), 6.0);
        let v = Views::new(
            &scene("[stereo]\nmethod = \"parallel\"\nangle = 8.0", 45, 360.0),
            true,
        );
        assert_eq!(v.reuse_steps(), None);
        assert_eq!(v.needed(0..45), 90);
        let v = Views::new(&scene("", 10, 360.0), true);
        assert_eq!((v.eyes(), v.needed(0..10)), (&[Eye::Mono][..], 10));
        // a 720-degree orbit shows every view twice
        let v = Views::new(&scene("", 10, 720.0), true);
        assert_eq!(v.needed(0..10), 5);
        // a sweep of 0 degrees has one view
        let v = Views::new(&scene("", 4, 0.0), true);
        assert_eq!(v.needed(0..4), 1);
    }
}
