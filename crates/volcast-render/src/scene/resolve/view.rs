//! `[camera]`, `[orbit]`, `[image]`, `[stereo]`, `[animation]`, `[viewer]` and
//! `[light]`.

use std::ops::Range;
use std::path::PathBuf;

use glam::DVec3;
use toml::Spanned;

use super::Resolver;
use crate::scene::schema::{
    AnimationTable, CameraTable, ImageTable, LightTable, OrbitTable, StereoTable, ViewerTable,
    ZoomValue,
};
use crate::scene::{
    Anaglyph, AnaglyphColors, Animation, AnimationFormat, Camera, Format, ImageSpec, Layout,
    LightKindSpec, LightSpec, Orbit, OrbitPath, Projection, Separation, Stereo, StereoMethod,
    ZoomFit,
};

/// Largest image side accepted.
const MAX_IMAGE_SIDE: i64 = 32768;

/// The largest azimuth or sweep, in degrees: far beyond any path (2,777 turns),
/// and small enough that every frame's angle is finite and exact to well below a
/// millionth of a degree.
pub(super) const MAX_ANGLE: f64 = 1e6;
impl Resolver<'_> {
    pub(super) fn camera(&mut self, t: Option<&Spanned<CameraTable>>) -> Camera {
        let mut cam = Camera {
            projection: Projection::Perspective,
            fov_deg: 30.0,
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            up: DVec3::Z,
            zoom: 1.0,
            fit: None,
            distance: None,
            target: None,
        };
        let Some(t) = t else { return cam };
        let c = t.get_ref();
        cam.projection = self.choice(
            "projection",
            &c.projection,
            &[
                ("perspective", Projection::Perspective),
                ("orthographic", Projection::Orthographic),
            ],
            Projection::Perspective,
        );
        cam.fov_deg = self.number(
            "fov",
            &c.fov,
            30.0,
            |x| x > 0.0 && x < 180.0,
            "degrees in (0, 180)",
        );
        if cam.projection == Projection::Orthographic {
            if let Some(f) = &c.fov {
                self.warnings.push(format!(
                    "camera.fov = {} has no effect with an orthographic projection",
                    f.get_ref()
                ));
            }
            if let Some(d) = &c.distance {
                self.err(
                    d.span(),
                    "`distance` is not used by the orthographic projection (use `zoom`)",
                );
            }
        }
        cam.azimuth_deg = self.number(
            "azimuth",
            &c.azimuth,
            0.0,
            |x| x.abs() <= MAX_ANGLE,
            "degrees from -1000000 to 1000000",
        );
        cam.elevation_deg = self.number(
            "elevation",
            &c.elevation,
            0.0,
            |x| (-90.0..=90.0).contains(&x),
            "degrees in [-90, 90]",
        );
        if let Some(up) = &c.up {
            cam.up = self
                .vec3("up", up, true)
                .map_or(DVec3::Z, |u| u.normalize());
        }
        match c.zoom.as_ref().map(|z| (z.get_ref(), z.span())) {
            None => {}
            Some((ZoomValue::Number(x), _)) if x.is_finite() && *x > 0.0 => cam.zoom = *x,
            Some((ZoomValue::Word(w), _)) if w == "fit" => {
                cam.fit = Some(ZoomFit {
                    threshold: c
                        .fit_threshold
                        .as_ref()
                        .and_then(|f| self.value_at("fit_threshold", *f.get_ref(), f.span())),
                });
            }
            Some((z, span)) => {
                let got = match z {
                    ZoomValue::Number(x) => x.to_string(),
                    ZoomValue::Word(w) => format!("\"{w}\""),
                };
                self.err(span, format!("zoom = {got}: expected a positive magnification, or \"fit\" (the zoom that frames the voxels at or above `fit_threshold`)"));
            }
        }
        if let (Some(f), None) = (&c.fit_threshold, cam.fit) {
            self.err(f.span(), "`fit_threshold` is used with zoom = \"fit\"");
        }
        cam.distance = c.distance.as_ref().map(|_| {
            self.number(
                "distance",
                &c.distance,
                1.0,
                |x| x > 0.0,
                "a positive distance in world units",
            )
        });
        cam.target = c
            .target
            .as_ref()
            .and_then(|t| self.vec3("target", t, false));
        cam
    }

    pub(super) fn orbit(&mut self, t: Option<&Spanned<OrbitTable>>) -> Orbit {
        let mut o = Orbit {
            frames: 1,
            degrees: 360.0,
            path: OrbitPath::Circle,
        };
        let Some(t) = t else { return o };
        let v = t.get_ref();
        if let Some(f) = &v.frames {
            if (1..=1_000_000).contains(f.get_ref()) {
                o.frames = *f.get_ref() as usize;
            } else {
                self.err(
                    f.span(),
                    format!(
                        "frames = {}: expected an integer from 1 to 1000000",
                        f.get_ref()
                    ),
                );
            }
        }
        let path = self.choice(
            "path",
            &v.path,
            &[("circle", 0), ("rock", 1), ("elevation", 2)],
            0,
        );
        o.degrees = self.number(
            "degrees",
            &v.degrees,
            // a rock swings 30 degrees unless told otherwise
            if path == 1 { 30.0 } else { 360.0 },
            |x| x.abs() <= MAX_ANGLE,
            "degrees from -1000000 to 1000000",
        );
        o.path = match path {
            1 => OrbitPath::Rock,
            2 => match &v.elevations {
                Some(e) => {
                    let [lo, hi] = *e.get_ref();
                    if lo.is_finite()
                        && hi.is_finite()
                        && (-90.0..=90.0).contains(&lo)
                        && (-90.0..=90.0).contains(&hi)
                    {
                        OrbitPath::Elevation { lo, hi }
                    } else {
                        self.err(e.span(), format!("elevations = [{lo}, {hi}]: expected two elevations in degrees from -90 to 90"));
                        OrbitPath::Circle
                    }
                }
                None => {
                    let span = v.path.as_ref().map_or(t.span(), |p| p.span());
                    self.err(span, "path = \"elevation\" needs `elevations = [lo, hi]`: the elevations in degrees (-90 to 90) the camera swings between");
                    OrbitPath::Circle
                }
            },
            _ => OrbitPath::Circle,
        };
        if let (Some(e), false) = (&v.elevations, path == 2) {
            self.err(e.span(), "`elevations` is used by path = \"elevation\"");
        }
        if let (Some(d), 2) = (&v.degrees, path) {
            self.err(d.span(), "`degrees` is not used by path = \"elevation\" (the azimuth stays; the elevation swings between `elevations`)");
        }
        o
    }

    pub(super) fn image(
        &mut self,
        t: Option<&Spanned<ImageTable>>,
        scene_name: &str,
        projection: Projection,
    ) -> ImageSpec {
        let mut im = ImageSpec {
            width: 512,
            height: 512,
            background: [0.0; 3],
            format: Format::Png,
            out: PathBuf::from("out").join(scene_name),
            scale_bar: false,
            colorbar: false,
        };
        let Some(t) = t else { return im };
        let v = t.get_ref();
        if let Some(s) = &v.size {
            let [w, h] = *s.get_ref();
            if (1..=MAX_IMAGE_SIDE).contains(&w) && (1..=MAX_IMAGE_SIDE).contains(&h) {
                im.width = w as usize;
                im.height = h as usize;
            } else {
                self.err(s.span(), format!("size = [{w}, {h}]: expected [width, height], each from 1 to {MAX_IMAGE_SIDE}"));
            }
        }
        if let Some(b) = &v.background {
            im.background = self.unit_color("background", b).map(|x| x as f32);
        }
        im.format = self.choice(
            "format",
            &v.format,
            &[
                ("png", Format::Png),
                ("png16", Format::Png16),
                ("nrrd", Format::Nrrd),
            ],
            Format::Png,
        );
        if let Some(o) = &v.out {
            match substitute_out(o.get_ref(), scene_name) {
                Ok(p) => im.out = PathBuf::from(p),
                Err(m) => self.err(o.span(), m),
            }
        }
        im.colorbar = v.colorbar.as_ref().is_some_and(|c| *c.get_ref());
        if let Some(s) = &v.scale_bar {
            im.scale_bar = *s.get_ref();
            if im.scale_bar && projection == Projection::Perspective {
                self.err(s.span(), "scale_bar = true needs [camera] projection = \"orthographic\": in a perspective view the length of a world unit in pixels changes with depth");
            }
        }
        im
    }

    pub(super) fn stereo(
        &mut self,
        t: &Spanned<StereoTable>,
        format: Format,
        projection: Projection,
    ) -> Stereo {
        let v = t.get_ref();
        let method_name = self.choice(
            "method",
            &v.method,
            &[("toe-in", false), ("parallel", true)],
            false,
        );
        let angle_deg = self.number(
            "angle",
            &v.angle,
            8.0,
            |x| x > 0.0 && x < 180.0,
            "degrees in (0, 180)",
        );
        let method = if method_name {
            let given: Vec<(&str, Range<usize>)> = [
                ("angle", v.angle.as_ref().map(|s| s.span())),
                ("separation", v.separation.as_ref().map(|s| s.span())),
                (
                    "separation_fraction",
                    v.separation_fraction.as_ref().map(|s| s.span()),
                ),
            ]
            .into_iter()
            .filter_map(|(k, s)| s.map(|s| (k, s)))
            .collect();
            if given.len() > 1 {
                let names: Vec<String> = given.iter().map(|(k, _)| format!("`{k}`")).collect();
                self.err(
                    given[1].1.clone(),
                    format!(
                        "give only one of `angle`, `separation` and `separation_fraction` for parallel stereo (found {})",
                        names.join(" and ")
                    ),
                );
            }
            if projection == Projection::Orthographic {
                self.err(
                    v.method.as_ref().map_or(t.span(), |m| m.span()),
                    "method = \"parallel\" needs projection = \"perspective\": orthographic eyes with parallel directions see the same picture (use method = \"toe-in\")",
                );
            }
            let separation = if let Some(s) = &v.separation {
                Separation::World(self.number(
                    "separation",
                    &Some(s.clone()),
                    1.0,
                    |x| x > 0.0,
                    "a positive distance between the eyes in world units",
                ))
            } else if let Some(f) = &v.separation_fraction {
                Separation::Fraction(self.number(
                    "separation_fraction",
                    &Some(f.clone()),
                    0.03,
                    |x| x > 0.0 && x <= 1.0,
                    "a fraction of the eye-target distance in (0, 1]",
                ))
            } else {
                // The eyes see the target under `angle`, as toe-in eyes would.
                Separation::Fraction(2.0 * (angle_deg.to_radians() / 2.0).tan())
            };
            StereoMethod::Parallel(separation)
        } else {
            for (k, s) in [
                ("separation", v.separation.as_ref().map(|s| s.span())),
                (
                    "separation_fraction",
                    v.separation_fraction.as_ref().map(|s| s.span()),
                ),
            ] {
                if let Some(span) = s {
                    self.err(
                        span,
                        format!("`{k}` is only used with method = \"parallel\" (toe-in eyes are placed by `angle`)"),
                    );
                }
            }
            StereoMethod::ToeIn
        };
        let layout = self.choice(
            "layout",
            &v.layout,
            &[
                ("pair", Layout::Pair),
                ("side-by-side", Layout::SideBySide),
                ("cross-eyed", Layout::CrossEyed),
                ("anaglyph", Layout::Anaglyph),
            ],
            Layout::Pair,
        );
        let anaglyph = self.choice(
            "anaglyph",
            &v.anaglyph,
            &[
                ("red-cyan", Anaglyph::RedCyan),
                ("red-green", Anaglyph::RedGreen),
            ],
            Anaglyph::RedCyan,
        );
        let anaglyph_colors = self.choice(
            "anaglyph_colors",
            &v.anaglyph_colors,
            &[
                ("color", AnaglyphColors::Color),
                ("half-color", AnaglyphColors::HalfColor),
                ("gray", AnaglyphColors::Gray),
            ],
            AnaglyphColors::Color,
        );
        for (key, value) in [
            ("anaglyph", v.anaglyph.as_ref().map(|a| a.span())),
            (
                "anaglyph_colors",
                v.anaglyph_colors.as_ref().map(|a| a.span()),
            ),
        ] {
            if let (Some(span), false) = (value, layout == Layout::Anaglyph) {
                self.err(
                    span,
                    format!("`{key}` is only used with layout = \"anaglyph\""),
                );
            }
        }
        if layout == Layout::Anaglyph && format == Format::Nrrd {
            self.err(
                v.layout.as_ref().map_or(t.span(), |l| l.span()),
                "layout = \"anaglyph\" makes a colour picture: use format = \"png\" or \"png16\" (nrrd output keeps unquantised values; use layout = \"pair\")",
            );
        }
        let gap = match &v.gap {
            None => 0,
            Some(g) if (0..=4096).contains(g.get_ref()) => *g.get_ref() as usize,
            Some(g) => {
                self.err(g.span(), "gap: expected a number of pixels from 0 to 4096");
                0
            }
        };
        if let (Some(g), false) = (
            &v.gap,
            matches!(layout, Layout::SideBySide | Layout::CrossEyed),
        ) {
            self.err(
                g.span(),
                "`gap` is only used with layout = \"side-by-side\" or \"cross-eyed\"",
            );
        }
        Stereo {
            method,
            angle_deg,
            layout,
            anaglyph,
            anaglyph_colors,
            gap,
        }
    }

    pub(super) fn animation(&mut self, t: &Spanned<AnimationTable>, format: Format) -> Animation {
        let v = t.get_ref();
        let mut formats = Vec::new();
        match &v.formats {
            None => formats.push(AnimationFormat::Gif),
            Some(list) if list.get_ref().is_empty() => self.err(
                list.span(),
                "formats = []: expected a list of \"gif\", \"apng\", \"mp4\" and \"webm\" (or leave out [animation])",
            ),
            Some(list) => {
                for f in list.get_ref() {
                    let chosen = self.choice(
                        "formats",
                        &Some(f.clone()),
                        &[
                            ("gif", AnimationFormat::Gif),
                            ("apng", AnimationFormat::Apng),
                            ("mp4", AnimationFormat::Mp4),
                            ("webm", AnimationFormat::Webm),
                        ],
                        AnimationFormat::Gif,
                    );
                    if formats.contains(&chosen) {
                        self.err(f.span(), format!("\"{}\" is listed twice", f.get_ref()));
                    } else {
                        formats.push(chosen);
                    }
                }
            }
        }
        let fps = self.number(
            "fps",
            &v.fps,
            24.0,
            |x| x > 0.0 && x <= 100.0,
            "frames per second in (0, 100]",
        );
        if format == Format::Nrrd {
            self.err(
                t.span(),
                "[animation] is assembled from the PNG frames: use format = \"png\" or \"png16\" (nrrd frames hold unquantised values)",
            );
        }
        let quality = v.quality.as_ref().and_then(|q| {
            let videos: Vec<AnimationFormat> =
                formats.iter().copied().filter(|f| f.is_video()).collect();
            let most = videos.iter().filter_map(|f| f.quality_range()).map(|r| r.1).min();
            match most {
                None => {
                    self.err(q.span(), "`quality` is the videos' (formats \"mp4\" and \"webm\"): the GIF and APNG files are lossless");
                    None
                }
                Some(most) if (0..=i64::from(most)).contains(q.get_ref()) => Some(*q.get_ref() as u32),
                Some(most) => {
                    self.err(q.span(), format!("quality = {}: expected a constant rate factor from 0 (best, largest) to {most} (mp4: 0-51, default 18; webm: 0-63, default 31)", q.get_ref()));
                    None
                }
            }
        });
        Animation {
            formats,
            fps,
            looping: v.looping.as_ref().is_none_or(|l| *l.get_ref()),
            quality,
            ping_pong: v.ping_pong.as_ref().is_some_and(|p| *p.get_ref()),
        }
    }

    /// `[viewer]`: whether to write the turntable page (`html`, default `true` when the
    /// table is there).
    pub(super) fn viewer(&mut self, t: &Spanned<ViewerTable>, format: Format) -> bool {
        let html = t.get_ref().html.as_ref().is_none_or(|h| *h.get_ref());
        if html && format == Format::Nrrd {
            let span = t.get_ref().html.as_ref().map_or(t.span(), |h| h.span());
            self.err(
                span,
                "[viewer] html = true shows the PNG frames in a browser: use format = \"png\" or \"png16\" (browsers cannot show nrrd frames)",
            );
        }
        html
    }

    pub(super) fn light(&mut self, t: Option<&Spanned<LightTable>>) -> LightSpec {
        let mut l = LightSpec {
            kind: LightKindSpec::Headlight,
            color: DVec3::ONE,
            intensity: Some(1.0),
        };
        let Some(t) = t else { return l };
        let v = t.get_ref();
        #[derive(Clone, Copy, PartialEq)]
        enum K {
            Head,
            Dir,
            Point,
        }
        let kind = self.choice(
            "kind",
            &v.kind,
            &[
                ("headlight", K::Head),
                ("directional", K::Dir),
                ("point", K::Point),
            ],
            K::Head,
        );
        l.kind = match kind {
            K::Head => {
                self.not_for(
                    "by a headlight (it shines from the camera)",
                    &[
                        ("direction", v.direction.as_ref().map(|s| s.span())),
                        ("position", v.position.as_ref().map(|s| s.span())),
                    ],
                );
                LightKindSpec::Headlight
            }
            K::Dir => {
                self.not_for(
                    "by a directional light",
                    &[("position", v.position.as_ref().map(|s| s.span()))],
                );
                match &v.direction {
                    Some(d) => LightKindSpec::Directional(
                        self.vec3("direction", d, true)
                            .unwrap_or(DVec3::Z)
                            .normalize(),
                    ),
                    None => {
                        self.err(t.span(), "a directional light needs `direction = [x, y, z]` (the direction the light travels)");
                        LightKindSpec::Headlight
                    }
                }
            }
            K::Point => {
                self.not_for(
                    "by a point light",
                    &[("direction", v.direction.as_ref().map(|s| s.span()))],
                );
                l.intensity = None;
                match &v.position {
                    Some(p) => {
                        LightKindSpec::Point(self.vec3("position", p, false).unwrap_or(DVec3::ZERO))
                    }
                    None => {
                        self.err(
                            t.span(),
                            "a point light needs `position = [x, y, z]` (world units)",
                        );
                        LightKindSpec::Headlight
                    }
                }
            }
        };
        if let Some(c) = &v.color {
            l.color = DVec3::from_array(self.unit_color("color", c));
        }
        if v.intensity.is_some() {
            l.intensity = Some(self.number(
                "intensity",
                &v.intensity,
                1.0,
                |x| x >= 0.0,
                "a number >= 0",
            ));
        }
        l
    }
}

/// Replaces `{scene}` in the output folder template.
fn substitute_out(template: &str, scene: &str) -> Result<String, String> {
    let out = template.replace("{scene}", scene);
    if let Some(i) = out.find(['{', '}']) {
        return Err(format!(
            "out = \"{template}\": unknown placeholder at \"{}\"; the only placeholder is {{scene}}",
            &out[i..]
        ));
    }
    if out.trim().is_empty() {
        return Err("out: expected a folder name".into());
    }
    Ok(out)
}
