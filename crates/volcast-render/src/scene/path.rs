//! Camera paths and keyframes: where the camera is at each frame, and the pass and
//! clip values that change over the frames.
//!
//! Without keyframes the camera follows `[orbit] path`: a `circle` about `up`
//! (frame `k` at `azimuth + k degrees / frames`), a `rock` (the azimuth swings
//! `azimuth + degrees/2 sin(2 pi k / frames)`, so a loop of the sequence is smooth)
//! or an `elevation` swing (`lo + (hi - lo) (1 - cos(2 pi k / frames)) / 2`, from
//! `lo` up to `hi` at the middle frame and back). With `[[keyframe]]` tables every
//! animated value has its own keys (the keyframes that give it): between two keys
//! it is interpolated linearly, or on a uniform Catmull-Rom spline with
//! `interpolation = "smooth"`, and it is held before its first key and after its
//! last. Angles are interpolated as the numbers written: 350 to 370 passes through
//! 360 (= 0), not back through 180.

use super::Scene;

/// The path the camera follows over the frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OrbitPath {
    /// A turn about `up` of `degrees` over the frames.
    Circle,
    /// The azimuth swings sinusoidally over `degrees` about the start.
    Rock,
    /// The elevation swings between `lo` and `hi` (degrees).
    Elevation {
        /// The lowest elevation (frame 0).
        lo: f64,
        /// The highest (the middle frame).
        hi: f64,
    },
    /// The camera's values come from `[[keyframe]]` tables.
    Keyframes,
}

impl OrbitPath {
    /// The scene-file name.
    pub fn name(self) -> &'static str {
        match self {
            OrbitPath::Circle => "circle",
            OrbitPath::Rock => "rock",
            OrbitPath::Elevation { .. } => "elevation",
            OrbitPath::Keyframes => "keyframes",
        }
    }
}

/// One animated value: its keys, `(frame, value)` in increasing frame order.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// At least one key; frames strictly increasing.
    pub keys: Vec<(f64, f64)>,
}

impl Channel {
    /// The value at `frame`: held before the first key and after the last,
    /// interpolated between (linearly, or on a uniform Catmull-Rom spline whose end
    /// segments repeat their end key). Exactly the key's value at a key.
    pub fn at(&self, frame: f64, smooth: bool) -> f64 {
        let k = &self.keys;
        let n = k.len();
        if frame <= k[0].0 {
            return k[0].1;
        }
        if frame >= k[n - 1].0 {
            return k[n - 1].1;
        }
        // the segment [k[i], k[i + 1]] holding the frame
        let i = k.partition_point(|&(f, _)| f <= frame) - 1;
        let u = (frame - k[i].0) / (k[i + 1].0 - k[i].0);
        let (p1, p2) = (k[i].1, k[i + 1].1);
        if !smooth {
            return p1 + u * (p2 - p1);
        }
        let p0 = k[i.saturating_sub(1)].1;
        let p3 = k[(i + 2).min(n - 1)].1;
        0.5 * (2.0 * p1
            + u * ((p2 - p0)
                + u * ((2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) + u * (3.0 * (p1 - p2) + p3 - p0))))
    }
}

/// What `[[keyframe]]` tables animate. A value no keyframe gives keeps the
/// scene's own.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Keyframes {
    /// Catmull-Rom (`interpolation = "smooth"`) instead of linear.
    pub smooth: bool,
    /// The frames that have a keyframe, in order (for `check`).
    pub frames: Vec<usize>,
    /// Camera azimuth (degrees).
    pub azimuth: Option<Channel>,
    /// Camera elevation (degrees).
    pub elevation: Option<Channel>,
    /// Camera zoom.
    pub zoom: Option<Channel>,
    /// Eye-target distance.
    pub distance: Option<Channel>,
    /// Target, per axis.
    pub target: Option<[Channel; 3]>,
    /// Per pass (by index): its iso value or threshold (normalised).
    pub pass_values: Vec<(usize, Channel)>,
    /// Per clipping plane (by index): its offset.
    pub clip_offsets: Vec<(usize, Channel)>,
}

impl Scene {
    /// The camera of frame `k` on a path other than the circle (whose frames turn
    /// the scene's camera by [`super::Orbit::azimuth_offset_deg`] instead).
    pub fn camera_at(&self, k: usize) -> super::Camera {
        camera_on_path(self.camera, &self.orbit, self.keyframes.as_ref(), k)
    }

    /// Pass `p`'s iso value or threshold at frame `k`, when keyframes animate it.
    pub fn pass_value_at(&self, p: usize, k: usize) -> Option<f64> {
        let kf = self.keyframes.as_ref()?;
        let (_, ch) = kf.pass_values.iter().find(|(q, _)| *q == p)?;
        Some(ch.at(k as f64, kf.smooth).clamp(0.0, 1.0))
    }

    /// Clipping plane `c`'s offset at frame `k`.
    pub fn clip_offset_at(&self, c: usize, k: usize) -> f64 {
        self.keyframes
            .as_ref()
            .and_then(|kf| {
                let (_, ch) = kf.clip_offsets.iter().find(|(q, _)| *q == c)?;
                Some(ch.at(k as f64, kf.smooth))
            })
            .unwrap_or(self.clips[c].offset)
    }
}

/// The camera of frame `k` on the orbit's path, from the scene's `camera` (see
/// [`Scene::camera_at`]): computed per frame, so that a long orbit costs nothing
/// for the frames not rendered.
pub(crate) fn camera_on_path(
    camera: super::Camera,
    orbit: &super::Orbit,
    keyframes: Option<&Keyframes>,
    k: usize,
) -> super::Camera {
    let mut c = camera;
    let phase = 2.0 * std::f64::consts::PI * k as f64 / orbit.frames as f64;
    match orbit.path {
        OrbitPath::Circle => {
            c.azimuth_deg += orbit.azimuth_offset_deg(k);
        }
        OrbitPath::Rock => {
            c.azimuth_deg += 0.5 * orbit.degrees * phase.sin();
        }
        OrbitPath::Elevation { lo, hi } => {
            c.elevation_deg = lo + (hi - lo) * 0.5 * (1.0 - phase.cos());
        }
        OrbitPath::Keyframes => {
            let Some(kf) = keyframes else {
                return c;
            };
            let (f, s) = (k as f64, kf.smooth);
            if let Some(ch) = &kf.azimuth {
                c.azimuth_deg = ch.at(f, s);
            }
            if let Some(ch) = &kf.elevation {
                c.elevation_deg = ch.at(f, s).clamp(-90.0, 90.0);
            }
            if let Some(ch) = &kf.zoom {
                c.zoom = ch.at(f, s).max(1e-6);
            }
            if let Some(ch) = &kf.distance {
                c.distance = Some(ch.at(f, s).max(1e-9));
            }
            if let Some([x, y, z]) = &kf.target {
                c.target = Some(glam::DVec3::new(x.at(f, s), y.at(f, s), z.at(f, s)));
            }
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channels_hold_interpolate_and_hit_their_keys() {
        let ch = Channel {
            keys: vec![(2.0, 350.0), (6.0, 370.0), (10.0, 330.0)],
        };
        assert_eq!(ch.at(0.0, false), 350.0);
        assert_eq!(ch.at(12.0, true), 330.0);
        // linear: no wrapping, 350 to 370 passes through 360
        assert_eq!(ch.at(4.0, false), 360.0);
        assert_eq!(ch.at(8.0, false), 350.0);
        for s in [false, true] {
            for &(f, v) in &ch.keys {
                assert_eq!(ch.at(f, s), v);
            }
        }
        // uniform Catmull-Rom with p0 = p1 = 350 (the first segment repeats its end
        // key), p2 = 370, p3 = 330, at u = 1/2:
        // (2 p1 + u (p2 - p0) + u^2 (2 p0 - 5 p1 + 4 p2 - p3) + u^3 (-p0 + 3 p1 - 3 p2 + p3)) / 2
        // = (700 + 10 + 25 - 10) / 2
        assert_eq!(ch.at(4.0, true), 362.5);
    }
}
