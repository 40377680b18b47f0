//! `[[keyframe]]` tables: per frame, camera values and pass and clip values as
//! dotted keys (`render.NAME.iso`, `render.NAME.threshold`, `clip.NAME.offset`).

use std::collections::BTreeMap;
use std::ops::Range;

use toml::Spanned;

use super::Resolver;
use crate::scene::diag::{quoted_list, suggest};
use crate::scene::schema::{KeyframeTable, OrbitTable, Sp};
use crate::scene::{Channel, Clip, Keyframes, Orbit, OrbitPath, RenderPass};

/// A camera key of a keyframe: its name, value, test and what it expects.
type CameraCheck<'a> = (&'a str, &'a Sp<f64>, &'a dyn Fn(f64) -> bool, &'a str);

impl Resolver<'_> {
    /// The keyframes, and the orbit they drive (`orbit.path` becomes keyframes);
    /// `[orbit] interpolation` is read here.
    pub(super) fn keyframes(
        &mut self,
        tables: Option<&[Spanned<KeyframeTable>]>,
        orbit_table: Option<&Spanned<OrbitTable>>,
        orbit: &mut Orbit,
        passes: &[RenderPass],
        clips: &[Clip],
        camera_fit: bool,
    ) -> Option<Keyframes> {
        let ot = orbit_table.map(|t| t.get_ref());
        let smooth = self.choice(
            "interpolation",
            &ot.and_then(|o| o.interpolation.clone()),
            &[("linear", false), ("smooth", true)],
            false,
        );
        let Some(tables) = tables.filter(|t| !t.is_empty()) else {
            if let Some(i) = ot.and_then(|o| o.interpolation.as_ref()) {
                self.warnings.push(format!(
                    "[orbit] interpolation = \"{}\" has no effect without [[keyframe]] tables",
                    i.get_ref()
                ));
            }
            return None;
        };
        if let Some(d) = ot.and_then(|o| o.degrees.as_ref()) {
            self.err(d.span(), "`degrees` cannot be combined with [[keyframe]] tables: the keyframes' azimuths set the path (write azimuth = ... in the keyframes)");
        }
        if let Some(p) = ot.and_then(|o| o.path.as_ref()) {
            if p.get_ref() != "circle" {
                self.err(p.span(), format!("path = \"{}\" cannot be combined with [[keyframe]] tables: the keyframes set the path", p.get_ref()));
            }
        }
        orbit.path = OrbitPath::Keyframes;
        let mut kf = Keyframes {
            smooth,
            ..Keyframes::default()
        };
        // (frame, value) per channel, gathered in file order, sorted at the end
        let mut cam: [Vec<(f64, f64)>; 7] = Default::default();
        let mut pass_keys: BTreeMap<usize, Vec<(f64, f64)>> = BTreeMap::new();
        let mut clip_keys: BTreeMap<usize, Vec<(f64, f64)>> = BTreeMap::new();
        let mut seen: BTreeMap<i64, Range<usize>> = BTreeMap::new();
        for t in tables {
            let v = t.get_ref();
            let Some(f) = &v.frame else {
                self.err(
                    t.span(),
                    format!(
                        "[[keyframe]] needs `frame = N`: the frame (0 to {}) it sets values for",
                        orbit.frames - 1
                    ),
                );
                continue;
            };
            let n = *f.get_ref();
            if !(0..orbit.frames as i64).contains(&n) {
                self.err(f.span(), format!("[[keyframe]] frame = {n}: expected a frame from 0 to {} (the orbit has {} frames)", orbit.frames - 1, orbit.frames));
                continue;
            }
            if seen.insert(n, f.span()).is_some() {
                self.err(
                    f.span(),
                    format!("two [[keyframe]] tables have frame = {n}: merge them"),
                );
                continue;
            }
            let frame = n as f64;
            let angle = |x: f64| x.is_finite() && x.abs() <= super::view::MAX_ANGLE;
            let checks: [CameraCheck; 4] = [
                ("azimuth", &v.azimuth, &angle, "an azimuth in degrees"),
                (
                    "elevation",
                    &v.elevation,
                    &|x: f64| (-90.0..=90.0).contains(&x),
                    "an elevation in degrees from -90 to 90",
                ),
                (
                    "zoom",
                    &v.zoom,
                    &|x: f64| x > 0.0 && x <= 1e6,
                    "a magnification > 0",
                ),
                (
                    "distance",
                    &v.distance,
                    &|x: f64| x > 0.0,
                    "a distance > 0 in world units",
                ),
            ];
            for (c, (key, value, ok, expected)) in checks.into_iter().enumerate() {
                if let Some(x) = value {
                    let x = *x.get_ref();
                    if x.is_finite() && ok(x) {
                        cam[c].push((frame, x));
                    } else if let Some(s) = value {
                        self.err(
                            s.span(),
                            format!("[[keyframe]] {key} = {x}: expected {expected}"),
                        );
                    }
                }
            }
            if let (Some(z), true) = (&v.zoom, camera_fit) {
                self.err(z.span(), "[[keyframe]] zoom cannot be combined with [camera] zoom = \"fit\" (one zoom for the whole sequence): remove one of them");
            }
            if let Some(tg) = &v.target {
                if let Some(p) = self.vec3("[[keyframe]] target", tg, false) {
                    for a in 0..3 {
                        cam[4 + a].push((frame, p[a]));
                    }
                }
            }
            for (name, table) in v.render.iter().flatten() {
                let Some(p) = passes.iter().position(|q| q.name == *name) else {
                    let hint = suggest(name, passes.iter().map(|q| q.name.as_str()))
                        .map(|n| format!("; did you mean `{n}`?"))
                        .unwrap_or_default();
                    self.err(
                        table.span(),
                        format!(
                            "[[keyframe]] render.{name}: no pass is named `{name}`: the passes are {}{hint}",
                            quoted_list(passes.iter().map(|q| q.name.as_str()))
                        ),
                    );
                    continue;
                };
                let kt = table.get_ref();
                let (key, value) = match passes[p].mode.level() {
                    Some(l) if l.key == "iso" => ("iso", &kt.iso),
                    Some(_) => ("threshold", &kt.threshold),
                    None => {
                        self.err(table.span(), format!("[[keyframe]] render.{name}: pass `{name}` has mode = \"{}\", which has no iso value or threshold to animate", passes[p].mode.name()));
                        continue;
                    }
                };
                for (other, v) in [("iso", &kt.iso), ("threshold", &kt.threshold)] {
                    if let (Some(s), true) = (v, other != key) {
                        self.err(s.span(), format!("[[keyframe]] render.{name}.{other}: pass `{name}` has mode = \"{}\", whose value is `{key}`", passes[p].mode.name()));
                    }
                }
                if let Some(s) = value {
                    let label = format!("[[keyframe]] render.{name}.{key}");
                    // in the units of the volume the pass reads
                    let saved = (self.units, self.window);
                    if let Some(&(units, window)) = self.contexts.get(passes[p].volumes[0]) {
                        (self.units, self.window) = (units, window);
                    }
                    let t = self.value_at(&label, *s.get_ref(), s.span());
                    (self.units, self.window) = saved;
                    if let Some(t) = t {
                        pass_keys.entry(p).or_default().push((frame, t));
                    }
                }
            }
            for (name, table) in v.clip.iter().flatten() {
                let Some(c) = clips.iter().position(|q| q.name.as_deref() == Some(name)) else {
                    let named: Vec<&str> = clips.iter().filter_map(|q| q.name.as_deref()).collect();
                    self.err(
                        table.span(),
                        format!(
                            "[[keyframe]] clip.{name}: no [[clip]] plane is named `{name}` (planes named: {})",
                            if named.is_empty() {
                                "none; give the plane a `name`".to_string()
                            } else {
                                quoted_list(named.iter().copied())
                            }
                        ),
                    );
                    continue;
                };
                if let Some(o) = &table.get_ref().offset {
                    let x = *o.get_ref();
                    if x.is_finite() {
                        clip_keys.entry(c).or_default().push((frame, x));
                    } else {
                        self.err(
                            o.span(),
                            format!("[[keyframe]] clip.{name}.offset = {x}: expected a distance in world units"),
                        );
                    }
                }
            }
        }
        let channel = |mut keys: Vec<(f64, f64)>| {
            keys.sort_by(|a, b| a.0.total_cmp(&b.0));
            (!keys.is_empty()).then_some(Channel { keys })
        };
        let [az, el, zoom, dist, tx, ty, tz] = cam;
        kf.azimuth = channel(az);
        kf.elevation = channel(el);
        kf.zoom = channel(zoom);
        kf.distance = channel(dist);
        if let (Some(x), Some(y), Some(z)) = (channel(tx), channel(ty), channel(tz)) {
            kf.target = Some([x, y, z]);
        }
        kf.pass_values = pass_keys
            .into_iter()
            .filter_map(|(p, k)| Some((p, channel(k)?)))
            .collect();
        kf.clip_offsets = clip_keys
            .into_iter()
            .filter_map(|(c, k)| Some((c, channel(k)?)))
            .collect();
        kf.frames = seen.keys().map(|&f| f as usize).collect();
        Some(kf)
    }
}
