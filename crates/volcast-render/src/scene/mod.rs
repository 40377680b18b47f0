//! Scene files: parsing, validation and the resolved [`Scene`] the renderer uses.
//!
//! `schema.rs` mirrors what the user wrote (with spans); `resolve.rs` fills in
//! defaults, checks every value and cross-reference, collects *all* problems and
//! produces a [`Scene`] whose paths are absolute and whose values are in range. The
//! user's reference for every key, its type, default and meaning is
//! docs/scene-reference.md.

mod diag;
mod path;
mod resolve;
mod schema;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::DVec3;

pub use diag::{Diagnostic, SceneError};
pub(crate) use path::camera_on_path;
pub use path::{Channel, Keyframes, OrbitPath};

pub use crate::mode::projection::MipOutput;
pub use crate::mode::xray::XrayOutput;
pub use crate::mode::{Mode, Shading};
pub use crate::render::camera::{Camera, Projection, ZoomFit};
pub use crate::transfer::Transfer;

use crate::sample::Interpolation;
use crate::volume::VolumeSource;

/// A validated scene: everything needed to plan and render, with defaults filled in.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The scene file.
    pub path: PathBuf,
    /// The file name without extension (`{scene}` in `out`).
    pub name: String,
    /// The volumes (`[volume]`, or the `[[volume]]` tables in file order; at least
    /// one): each pass reads one of them, a composite pass may blend several.
    pub volumes: Vec<SceneVolume>,
    /// The camera at frame 0.
    pub camera: Camera,
    /// The turntable.
    pub orbit: Orbit,
    /// Stereo views, when requested.
    pub stereo: Option<Stereo>,
    /// Image size, background, format and output folder.
    pub image: ImageSpec,
    /// The render passes, each writing its own numbered sequence.
    pub passes: Vec<RenderPass>,
    /// The light for shaded passes.
    pub light: LightSpec,
    /// Clipping planes (`[[clip]]`), in file order.
    pub clips: Vec<Clip>,
    /// What `[[keyframe]]` tables animate (with `orbit.path` = keyframes).
    pub keyframes: Option<Keyframes>,
    /// Text drawn into PNG frames (`[[label]]`), in file order.
    pub labels: Vec<crate::label::Label>,
    /// Animated files to assemble from each pass's frames, when requested.
    pub animation: Option<Animation>,
    /// Write `{out}/index.html`, a turntable page for the browser, once every frame
    /// exists (`[viewer] html`; `--viewer` sets it too).
    pub viewer: bool,
    /// The scene file's text as read (recorded in the output's manifest and hashed
    /// to decide whether existing images belong to this scene).
    pub text: String,
    /// Legal but suspicious settings, to print before rendering.
    pub warnings: Vec<String>,
}

impl Scene {
    /// The first volume (the only one of a `[volume]` scene): what the tools that
    /// read one volume (`histogram`, `info`) take.
    pub fn volume(&self) -> &VolumeSpec {
        &self.volumes[0].spec
    }
}

/// One volume of a scene: its name, its source and window, and where it sits.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneVolume {
    /// `name` (passes name their volume by it); `volume` for a `[volume]` without one.
    pub name: String,
    /// Where its voxels come from and how its values are normalised.
    pub spec: VolumeSpec,
    /// `transform`: a world-from-file map applied after the file's own geometry.
    pub transform: Option<Transform>,
}

/// An affine world-from-file map (`transform`, a registration): `x' = m x + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// The linear part (rotation, scale, shear); invertible.
    pub matrix: glam::DMat3,
    /// The translation.
    pub translation: DVec3,
}

impl Transform {
    /// The file's geometry moved by the transform: the same voxels at `m x + t`.
    pub fn place(&self, g: &crate::volume::Geometry) -> crate::volume::Geometry {
        crate::volume::Geometry {
            origin: self.matrix * g.origin + self.translation,
            axes: g.axes.map(|a| self.matrix * a),
        }
    }
}

/// The volume source and its value window.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeSpec {
    /// File or synthetic field.
    pub source: VolumeSource,
    /// Data values mapped linearly to [0, 1]; `None` = the data's finite min..max.
    pub window: Option<[f64; 2]>,
    /// The units the scene's values were written in (`[volume] units`); they are
    /// normalised values in the resolved scene either way.
    pub units: Units,
    /// Voxel index ranges (inclusive) of the sub-volume to render; `None` = all.
    /// Checked against the volume's sizes when the plan is built.
    pub crop: Option<[[usize; 2]; 3]>,
}

/// The units of a scene's thresholds, iso values, transfer-function knots and the
/// windows of the value-based passes (`[volume] units`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Units {
    /// Normalised values: 0 and 1 are the ends of the volume's window.
    #[default]
    Normalised,
    /// The volume's own values (Hounsfield units for CT), converted at resolve time
    /// to `t = (x - lo) / (hi - lo)` with the volume's window `[lo, hi]`.
    Data {
        /// The window's low end.
        lo: f64,
        /// The window's high end.
        hi: f64,
    },
}

impl Units {
    /// A normalised value `t` in the units the scene was written in (for display).
    pub fn show(self, t: f64) -> f64 {
        match self {
            Units::Normalised => t,
            Units::Data { lo, hi } => lo + t * (hi - lo),
        }
    }
}

/// The frames' camera path: on the default circle, frame k at `azimuth + k *
/// degrees / frames` (see `path.rs` for the others).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    /// Number of frames (at least 1).
    pub frames: usize,
    /// Total sweep in degrees (circle), or the swing (rock).
    pub degrees: f64,
    /// The path.
    pub path: OrbitPath,
}

impl Orbit {
    /// Azimuth offset of frame `k`, in degrees.
    pub fn azimuth_offset_deg(&self, k: usize) -> f64 {
        k as f64 * self.degrees / self.frames as f64
    }
}

/// How the two eyes of a stereo frame are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// Two files, `_left` and `_right`.
    Pair,
    /// One file: left image on the left (parallel viewing).
    SideBySide,
    /// One file: right image on the left (cross-eyed viewing).
    CrossEyed,
    /// One file: colour anaglyph.
    Anaglyph,
}

/// Anaglyph glasses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Anaglyph {
    /// Red left eye, cyan (green + blue) right eye.
    RedCyan,
    /// Red left eye, green right eye.
    RedGreen,
}

/// Which colours of the two views an anaglyph keeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AnaglyphColors {
    /// Full-colour anaglyph: red from the left view's red, green and blue (red-cyan)
    /// or green (red-green) from the right view's. Grey images give the same result
    /// as `Gray`.
    Color,
    /// Red from the left view's luminance, the other channels from the right view's
    /// colours (less retinal rivalry than `Color` for saturated reds).
    HalfColor,
    /// Every channel from the views' luminance.
    Gray,
}

/// How the eye separation of `parallel` stereo is given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Separation {
    /// World units between the eyes.
    World(f64),
    /// A fraction of the eye-target distance.
    Fraction(f64),
}

/// How the two eyes of a stereo frame are placed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StereoMethod {
    /// Each eye turned `angle/2` about `up` through the target (the course's method).
    ToeIn,
    /// Off-axis: eyes shifted along the image's right vector, parallel viewing
    /// directions, asymmetric frusta that converge at the target distance.
    Parallel(Separation),
}

/// Stereo settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stereo {
    /// Placement of the eyes.
    pub method: StereoMethod,
    /// Degrees between the eyes (toe-in; for `parallel` the separation is in `method`).
    pub angle_deg: f64,
    /// Output layout.
    pub layout: Layout,
    /// Glasses, for the anaglyph layout.
    pub anaglyph: Anaglyph,
    /// Colours an anaglyph keeps (shaded passes; grey passes always use luminance).
    pub anaglyph_colors: AnaglyphColors,
    /// Pixels between the halves of side-by-side and cross-eyed images.
    pub gap: usize,
}

/// Animated file formats written from a pass's frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AnimationFormat {
    /// Animated GIF (8-bit, a palette per frame).
    Gif,
    /// Animated PNG (the frames' own colour type and bit depth).
    Apng,
    /// MP4 video (H.264, yuv420p, `+faststart`), encoded by the `ffmpeg` program.
    Mp4,
    /// WebM video (VP9, yuv420p), encoded by the `ffmpeg` program.
    Webm,
}

impl AnimationFormat {
    /// File extension.
    pub fn extension(self) -> &'static str {
        match self {
            AnimationFormat::Gif => "gif",
            AnimationFormat::Apng => "apng",
            AnimationFormat::Mp4 => "mp4",
            AnimationFormat::Webm => "webm",
        }
    }

    /// Whether the format is a video that `ffmpeg` encodes.
    pub fn is_video(self) -> bool {
        matches!(self, AnimationFormat::Mp4 | AnimationFormat::Webm)
    }

    /// The default and the largest `quality` (a constant rate factor: lower is
    /// better and larger) of a video format: libx264's and libvpx-vp9's ranges.
    pub fn quality_range(self) -> Option<(u32, u32)> {
        match self {
            AnimationFormat::Mp4 => Some((18, 51)),
            AnimationFormat::Webm => Some((31, 63)),
            _ => None,
        }
    }
}

/// The `[animation]` table: whole sequences as animated files.
#[derive(Clone, Debug, PartialEq)]
pub struct Animation {
    /// Formats to write (at least one, no repeats).
    pub formats: Vec<AnimationFormat>,
    /// Frames per second.
    pub fps: f64,
    /// Loop forever (`true`) or play once.
    pub looping: bool,
    /// The videos' constant rate factor (`quality`), `None` for each format's default.
    pub quality: Option<u32>,
    /// Play the frames forward, then backward without repeating the ends
    /// (`ping_pong`, for rocking paths).
    pub ping_pong: bool,
}

/// Image file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// 8-bit PNG.
    Png,
    /// 16-bit PNG.
    Png16,
    /// Unquantised float32 NRRD.
    Nrrd,
}

impl Format {
    /// File extension.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Png | Format::Png16 => "png",
            Format::Nrrd => "nrrd",
        }
    }
}

/// The `[image]` table.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageSpec {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Colour where rays miss (linear RGB in [0, 1]).
    pub background: [f32; 3],
    /// File format.
    pub format: Format,
    /// Output folder, with `{scene}` already substituted (relative to the working directory).
    pub out: PathBuf,
    /// Draw a scale bar into PNG frames (orthographic views only).
    pub scale_bar: bool,
    /// Draw a colour bar of the window into the PNG frames of intensity passes.
    pub colorbar: bool,
}

/// One `[[render]]` pass.
#[derive(Clone, Debug)]
pub struct RenderPass {
    /// File name prefix.
    pub name: String,
    /// Mode and its settings.
    pub mode: Arc<dyn Mode>,
    /// The volumes it reads, as indices into [`Scene::volumes`] (`volume`, or a
    /// composite's `volumes`; never empty): the first is the pass's own, whose
    /// units its values are written in.
    pub volumes: Vec<usize>,
    /// Sample spacing in voxels of the smallest axis spacing.
    pub step_voxels: f64,
    /// Reconstruction filter.
    pub interpolation: Interpolation,
    /// Grey window of intensity modes in PNG output; `None` = automatic.
    pub window: Option<[f64; 2]>,
    /// Sampled (ray marching) or exact (cell by cell on the trilinear interpolant).
    pub integration: Integration,
    /// Jitter each ray's first sample by a per-pixel fraction of the step.
    pub jitter: bool,
    /// The colour map of an intensity pass's PNG output (`colormap`): the windowed
    /// value goes through it instead of showing as grey. `None` = grey; a depth-coded
    /// MIP keeps its map in [`MipOutput::DepthCoded`] and has `None` here.
    pub colormap: Option<crate::transfer::Colormap>,
}

/// One `[[clip]]` plane: removes the half-space its normal points into.
#[derive(Clone, Debug, PartialEq)]
pub struct Clip {
    /// Name (for `check` and for keyframes); `None` when not given.
    pub name: Option<String>,
    /// A point of the plane before the offset (world coordinates).
    pub point: DVec3,
    /// Unit normal (world), pointing into the removed half-space.
    pub normal: DVec3,
    /// Distance the plane is moved along its normal.
    pub offset: f64,
    /// Surface and depth passes show the cut face where it is inside the object.
    pub cap: bool,
    /// The passes it applies to; `None` = every pass.
    pub passes: Option<Vec<String>>,
}

impl Clip {
    /// Whether the plane clips the pass named `pass`.
    pub fn applies_to(&self, pass: &str) -> bool {
        self.passes
            .as_ref()
            .is_none_or(|names| names.iter().any(|n| n == pass))
    }
}

/// How a pass integrates along its rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integration {
    /// Samples every `step` (the default).
    Sampled,
    /// Walks the cells and integrates the trilinear interpolant in closed form.
    Exact,
}

impl Integration {
    /// The scene-file name.
    pub fn name(self) -> &'static str {
        match self {
            Integration::Sampled => "sampled",
            Integration::Exact => "exact",
        }
    }
}

/// The `[light]` table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSpec {
    /// Kind and geometry.
    pub kind: LightKindSpec,
    /// RGB colour.
    pub color: DVec3,
    /// Scale; `None` for a point light = the squared distance to the target
    /// (so that the light's irradiance at the target is `color`).
    pub intensity: Option<f64>,
}

/// Light geometry as written in the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKindSpec {
    /// A directional light from the camera.
    Headlight,
    /// Parallel light travelling along `direction` (unit).
    Directional(DVec3),
    /// A point light at `position`.
    Point(DVec3),
}

/// Largest scene file accepted, in bytes (a scene is a few kilobytes; this only
/// stops a huge or endless file from being read into memory).
pub const MAX_SCENE_BYTES: u64 = 16 << 20;

/// Reads and validates a scene file. The file is opened without blocking and must be
/// a regular file of at most [`MAX_SCENE_BYTES`] (a FIFO, a device such as
/// `/dev/zero` or a directory is refused with a message, never waited on or read).
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let text = read_text(path)?;
    parse(&text, path)
}

/// The text of the scene file at `path` (see [`load`]).
fn read_text(path: &Path) -> Result<String, SceneError> {
    use std::io::Read;
    let fail = |m: String| SceneError::whole_file(path, m);
    let cannot = |e: std::io::Error| fail(format!("cannot read the scene file: {e}"));
    let file = crate::volume::mapped::open_nonblocking(path).map_err(cannot)?;
    let meta = file.metadata().map_err(cannot)?;
    if !meta.is_file() {
        return Err(fail(format!(
            "is {}, not a regular file: a scene is read only from a regular file (a .toml text file)",
            crate::volume::mapped::file_kind(&meta.file_type())
        )));
    }
    let too_big = |n: u64| {
        fail(format!(
            "the scene file is {} bytes; scene files are at most {} MiB (is it really a scene?)",
            n,
            MAX_SCENE_BYTES >> 20
        ))
    };
    if meta.len() > MAX_SCENE_BYTES {
        return Err(too_big(meta.len()));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(MAX_SCENE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(cannot)?;
    if bytes.len() as u64 > MAX_SCENE_BYTES {
        return Err(too_big(bytes.len() as u64));
    }
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let text = String::from_utf8_lossy(e.as_bytes()).into_owned();
        // the lossy text has the same bytes up to the first invalid one
        SceneError {
            path: path.to_path_buf(),
            text,
            diagnostics: vec![Diagnostic {
                span: Some(at..at + 1),
                message: "the scene file is not UTF-8 text: a byte here is not valid UTF-8 (TOML files are UTF-8)".into(),
            }],
        }
    })
}

/// Validates scene text as if it were the file at `path` (relative paths in the
/// scene resolve against `path`'s folder).
pub fn parse(text: &str, path: &Path) -> Result<Scene, SceneError> {
    resolve::resolve(text, path)
}
