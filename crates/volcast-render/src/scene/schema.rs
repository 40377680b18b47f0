//! The scene file as written: serde structs mirroring the TOML, with the span of
//! every value kept for error messages. Nothing here leaves `scene/`; `resolve.rs`
//! turns it into the validated [`super::Scene`].
//!
//! Every table denies unknown keys; keys whose meaning depends on the render mode
//! are all accepted by [`RenderTable`] and checked against the mode in `resolve.rs`.

use std::collections::BTreeMap;

use serde::Deserialize;
use toml::Spanned;

/// An optional value with its span.
pub type Sp<T> = Option<Spanned<T>>;

/// The whole file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// `[volume]` (one table) or `[[volume]]` (an array of named tables).
    pub volume: Spanned<VolumeTables>,
    pub camera: Option<Spanned<CameraTable>>,
    pub orbit: Option<Spanned<OrbitTable>>,
    pub stereo: Option<Spanned<StereoTable>>,
    pub image: Option<Spanned<ImageTable>>,
    pub render: Option<Vec<Spanned<RenderTable>>>,
    #[serde(default)]
    pub transfer: BTreeMap<String, Spanned<TransferTable>>,
    #[serde(default)]
    pub material: BTreeMap<String, Spanned<MaterialTable>>,
    pub light: Option<Spanned<LightTable>>,
    pub animation: Option<Spanned<AnimationTable>>,
    pub viewer: Option<Spanned<ViewerTable>>,
    pub clip: Option<Vec<Spanned<ClipTable>>>,
    pub keyframe: Option<Vec<Spanned<KeyframeTable>>>,
    pub label: Option<Vec<Spanned<LabelTable>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LabelTable {
    pub text: Sp<String>,
    pub position: Sp<String>,
    pub size: Sp<f64>,
    pub color: Sp<[f64; 3]>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipTable {
    pub name: Sp<String>,
    pub point: Option<Spanned<[f64; 3]>>,
    pub normal: Option<Spanned<[f64; 3]>>,
    pub offset: Sp<f64>,
    pub cap: Sp<bool>,
    pub passes: Sp<Vec<Spanned<String>>>,
}

/// `[volume]`, or `[[volume]]` tables.
#[derive(Debug)]
pub enum VolumeTables {
    One(Box<VolumeTable>),
    Many(Vec<Spanned<VolumeTable>>),
}

impl<'de> Deserialize<'de> for VolumeTables {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Tables;
        impl<'de> serde::de::Visitor<'de> for Tables {
            type Value = VolumeTables;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a [volume] table or [[volume]] tables")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> Result<VolumeTables, A::Error> {
                VolumeTable::deserialize(serde::de::value::MapAccessDeserializer::new(map))
                    .map(|t| VolumeTables::One(Box::new(t)))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                seq: A,
            ) -> Result<VolumeTables, A::Error> {
                Vec::<Spanned<VolumeTable>>::deserialize(
                    serde::de::value::SeqAccessDeserializer::new(seq),
                )
                .map(VolumeTables::Many)
            }
        }
        d.deserialize_any(Tables)
    }
}

/// `transform`: a 4 x 4 row-major matrix, as four rows or sixteen numbers.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub enum MatrixValue {
    Rows(Vec<Vec<f64>>),
    Flat(Vec<f64>),
}

/// A composite pass's `transfer`: one name, or one per volume.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub enum TransferChoice {
    Name(String),
    PerVolume(BTreeMap<String, String>),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VolumeTable {
    // several volumes
    pub name: Sp<String>,
    pub transform: Sp<MatrixValue>,
    pub path: Sp<String>,
    pub format: Sp<String>,
    pub window: Sp<[f64; 2]>,
    pub units: Sp<String>,
    pub crop: Sp<[[i64; 2]; 3]>,
    // 4D NIfTI
    pub index: Sp<i64>,
    // DICOM
    pub series: Sp<String>,
    // multi-channel TIFF
    pub channel: Sp<i64>,
    // raw
    // numbers, so that `4e9` is reported as too large rather than as a float
    pub sizes: Sp<Vec<f64>>,
    #[serde(rename = "type")]
    pub ty: Sp<String>,
    pub endian: Sp<String>,
    pub spacing: Sp<[f64; 3]>,
    pub offset: Sp<i64>,
    // synthetic
    pub synthetic: Sp<String>,
    pub sigma: Sp<f64>,
    pub radius: Sp<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraTable {
    pub projection: Sp<String>,
    pub fov: Sp<f64>,
    pub azimuth: Sp<f64>,
    pub elevation: Sp<f64>,
    pub up: Sp<[f64; 3]>,
    pub zoom: Sp<ZoomValue>,
    pub fit_threshold: Sp<f64>,
    pub distance: Sp<f64>,
    pub target: Sp<[f64; 3]>,
}

/// `zoom = 1.5` or `zoom = "fit"`.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub enum ZoomValue {
    Number(f64),
    Word(String),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrbitTable {
    pub frames: Sp<i64>,
    pub degrees: Sp<f64>,
    pub path: Sp<String>,
    pub elevations: Sp<[f64; 2]>,
    pub interpolation: Sp<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyframeTable {
    pub frame: Sp<i64>,
    pub azimuth: Sp<f64>,
    pub elevation: Sp<f64>,
    pub zoom: Sp<f64>,
    pub distance: Sp<f64>,
    pub target: Option<Spanned<[f64; 3]>>,
    pub render: Option<BTreeMap<String, Spanned<KeyPassTable>>>,
    pub clip: Option<BTreeMap<String, Spanned<KeyClipTable>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyPassTable {
    pub iso: Sp<f64>,
    pub threshold: Sp<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyClipTable {
    pub offset: Sp<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StereoTable {
    pub method: Sp<String>,
    pub angle: Sp<f64>,
    pub separation: Sp<f64>,
    pub separation_fraction: Sp<f64>,
    pub layout: Sp<String>,
    pub anaglyph: Sp<String>,
    pub anaglyph_colors: Sp<String>,
    pub gap: Sp<i64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnimationTable {
    pub formats: Sp<Vec<Spanned<String>>>,
    pub fps: Sp<f64>,
    #[serde(rename = "loop")]
    pub looping: Sp<bool>,
    pub quality: Sp<i64>,
    pub ping_pong: Sp<bool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewerTable {
    pub html: Sp<bool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageTable {
    pub size: Sp<[i64; 2]>,
    pub background: Sp<[f64; 3]>,
    pub format: Sp<String>,
    pub out: Sp<String>,
    pub scale_bar: Sp<bool>,
    pub colorbar: Sp<bool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderTable {
    pub name: Sp<String>,
    pub mode: Sp<String>,
    pub step: Sp<f64>,
    pub interpolation: Sp<String>,
    pub window: Sp<[f64; 2]>,
    pub integration: Sp<String>,
    pub jitter: Sp<bool>,
    // xray, mip
    pub output: Sp<String>,
    pub mu: Sp<f64>,
    // mip
    pub depth_cue: Sp<f64>,
    pub colormap: Sp<String>,
    // lmip, depth
    pub threshold: Sp<f64>,
    // surface
    pub iso: Sp<f64>,
    pub material: Sp<String>,
    pub shading: Sp<String>,
    pub gradient: Sp<String>,
    // the volume it reads
    pub volume: Sp<String>,
    // composite
    pub volumes: Sp<Vec<Spanned<String>>>,
    pub transfer: Sp<TransferChoice>,
    pub reference_step: Sp<f64>,
    pub early_stop: Sp<f64>,
    pub preintegrated: Sp<bool>,
}

impl RenderTable {
    /// The keys present, with their spans, in a fixed order (for mode checks).
    pub fn present_keys(&self) -> Vec<(&'static str, std::ops::Range<usize>)> {
        fn k<T>(out: &mut Vec<(&'static str, std::ops::Range<usize>)>, n: &'static str, v: &Sp<T>) {
            if let Some(s) = v {
                out.push((n, s.span()));
            }
        }
        let mut out = Vec::new();
        k(&mut out, "output", &self.output);
        k(&mut out, "mu", &self.mu);
        k(&mut out, "depth_cue", &self.depth_cue);
        k(&mut out, "colormap", &self.colormap);
        k(&mut out, "threshold", &self.threshold);
        k(&mut out, "iso", &self.iso);
        k(&mut out, "material", &self.material);
        k(&mut out, "shading", &self.shading);
        k(&mut out, "gradient", &self.gradient);
        k(&mut out, "transfer", &self.transfer);
        k(&mut out, "volumes", &self.volumes);
        k(&mut out, "reference_step", &self.reference_step);
        k(&mut out, "early_stop", &self.early_stop);
        k(&mut out, "window", &self.window);
        k(&mut out, "integration", &self.integration);
        k(&mut out, "jitter", &self.jitter);
        k(&mut out, "preintegrated", &self.preintegrated);
        out
    }
}

/// One knot of a colour ramp: position and RGB.
pub type ColorKnot = (f64, [f64; 3]);
/// One knot of an opacity ramp: position and alpha.
pub type AlphaKnot = (f64, f64);

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransferTable {
    pub kind: Sp<String>,
    pub interpolation: Sp<String>,
    pub color: Sp<Vec<ColorKnot>>,
    pub alpha: Sp<Vec<AlphaKnot>>,
    pub widget: Option<Vec<Spanned<WidgetTable>>>,
    pub gradient_max: Sp<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WidgetTable {
    pub shape: Sp<String>,
    pub value: Sp<[f64; 2]>,
    pub gradient: Sp<[f64; 2]>,
    pub color: Sp<[f64; 3]>,
    pub alpha: Sp<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialTable {
    pub ambient: Sp<[f64; 3]>,
    pub diffuse: Sp<[f64; 3]>,
    pub specular: Sp<[f64; 3]>,
    pub shininess: Sp<f64>,
    pub exponent: Sp<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightTable {
    pub kind: Sp<String>,
    pub direction: Sp<[f64; 3]>,
    pub position: Sp<[f64; 3]>,
    pub color: Sp<[f64; 3]>,
    pub intensity: Sp<f64>,
}
