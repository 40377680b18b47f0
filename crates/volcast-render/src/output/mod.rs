//! From films to files: grey windows and colour, stereo layouts, encoders, atomic
//! writes, the output folder's manifest and animations. Knows nothing about render
//! modes beyond what a film holds and whether its values are intensities, depths or
//! RGBA.

pub mod animation;
pub mod display;
pub mod encode;
pub mod manifest;
pub mod overlay;
pub(crate) mod plotting;
pub mod stereo;
pub mod viewer;
pub mod write;

/// Which eye an image belongs to (defined with the views that make the eyes).
pub use crate::views::Eye;
pub use display::{DisplayKind, Window};
pub use write::write_atomic;

use std::path::{Path, PathBuf};

use crate::label::Label;
use crate::render::Film;
use crate::scene::{
    Anaglyph, AnaglyphColors, Animation, AnimationFormat, Format, Layout, Scene, Separation,
    Stereo, StereoMethod, Units,
};
use crate::transfer::Colormap;

/// What a run writes around the rendered values, fixed when the scene is planned:
/// the files' form, what is drawn over them, and the sequences, animations and page
/// made from them. Everything after planning reads this, not the scene.
#[derive(Clone, Debug)]
pub struct Outputs {
    /// The scene's name (`{scene}`: the page's title, label text).
    pub title: String,
    /// Per pass, in order.
    pub passes: Vec<PassOutput>,
    /// Frames of the whole orbit.
    pub frames: usize,
    /// Degrees the orbit turns.
    pub degrees: f64,
    /// The image files' format.
    pub format: Format,
    /// Colour where rays miss (linear RGB in [0, 1]).
    pub background: [f32; 3],
    /// Draw a scale bar into PNG frames of orthographic views.
    pub scale_bar: bool,
    /// Draw a colour bar of the window into PNG frames of intensity passes.
    pub colorbar: bool,
    /// How stereo frames are stored, when the scene has them.
    pub stereo: Option<Stereo>,
    /// Text drawn into PNG frames, in file order.
    pub labels: Vec<Label>,
    /// The units the scene's values are shown in (colour bars).
    pub units: Units,
    /// Animated files to assemble once the sequence is complete.
    pub animation: Option<Animation>,
}

/// What the outputs need of one pass.
#[derive(Clone, Debug)]
pub struct PassOutput {
    /// File name prefix.
    pub name: String,
    /// The mode's name (recorded in NRRD files and the page).
    pub mode: &'static str,
    /// Colour map of an intensity pass's grey values, if any.
    pub colormap: Option<Colormap>,
    /// Whether the pass's window is on the volume's value axis (shown in data units).
    pub window_in_values: bool,
}

impl Outputs {
    /// The outputs `scene` asks for.
    pub fn of_scene(scene: &Scene) -> Outputs {
        Outputs {
            title: scene.name.clone(),
            passes: scene
                .passes
                .iter()
                .map(|p| PassOutput {
                    name: p.name.clone(),
                    mode: p.mode.name(),
                    colormap: p.colormap,
                    window_in_values: p.mode.window_in_values(),
                })
                .collect(),
            frames: scene.orbit.frames,
            degrees: scene.orbit.degrees,
            format: scene.image.format,
            background: scene.image.background,
            scale_bar: scene.image.scale_bar,
            colorbar: scene.image.colorbar,
            stereo: scene.stereo,
            labels: scene.labels.clone(),
            units: scene.volume().units,
            animation: scene.animation.clone(),
        }
    }

    /// The names of the files of pass `pass`, frame `frame`, in the order its record
    /// lists them: `{pass}_{frame:04}.{ext}`, or its `_left` and `_right` files for
    /// the `pair` layout. A record that names other files is not this run's.
    pub fn file_names(&self, pass: &str, frame: usize) -> Vec<String> {
        let eyes: &[Eye] = match self.stereo {
            Some(s) if s.layout == Layout::Pair => &[Eye::Left, Eye::Right],
            _ => &[Eye::Mono],
        };
        let ext = self.format.extension();
        eyes.iter()
            .map(|&eye| {
                let path = frame_path(Path::new(""), pass, frame, eye, ext);
                path.to_string_lossy().into_owned()
            })
            .collect()
    }

    /// The image sequences the run writes: one per pass and, for the `pair` layout,
    /// per eye.
    pub fn sequences(&self) -> Vec<animation::Sequence> {
        let eyes: &[Eye] = match self.stereo {
            Some(s) if s.layout == Layout::Pair => &[Eye::Left, Eye::Right],
            _ => &[Eye::Mono],
        };
        self.passes
            .iter()
            .flat_map(|p| {
                eyes.iter().map(|&eye| animation::Sequence {
                    pass: p.name.clone(),
                    eye,
                })
            })
            .collect()
    }
}

/// An image buffer that could not be allocated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("out of memory: allocating {} for an image failed", crate::volume::human_bytes(*bytes))]
pub struct AllocError {
    /// Bytes asked for.
    pub bytes: u64,
}

/// A zero-filled buffer of `n` elements, or an error instead of an abort when the
/// memory is not there.
pub fn try_zeroed<T: Clone + Default>(n: usize) -> Result<Vec<T>, AllocError> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| AllocError {
        bytes: (n as u64).saturating_mul(std::mem::size_of::<T>() as u64),
    })?;
    v.resize(n, T::default());
    Ok(v)
}

/// A zero-filled film, allocated fallibly.
pub fn try_film(width: usize, height: usize, channels: usize) -> Result<Film, AllocError> {
    let n = width
        .checked_mul(height)
        .and_then(|p| p.checked_mul(channels))
        .ok_or(AllocError { bytes: u64::MAX })?;
    Ok(Film {
        width,
        height,
        channels,
        data: try_zeroed(n)?,
    })
}

/// `{out}/{pass}_{frame:04}{_left|_right}.{ext}` (docs/scene-reference.md).
pub fn frame_path(out: &Path, pass: &str, frame: usize, eye: Eye, ext: &str) -> PathBuf {
    let suffix = match eye {
        Eye::Mono => "",
        Eye::Left => "_left",
        Eye::Right => "_right",
    };
    out.join(format!("{pass}_{frame:04}{suffix}.{ext}"))
}

/// One line describing the stereo settings (for `volcast check`).
pub fn describe_stereo(scene: &Scene) -> String {
    let Some(st) = &scene.stereo else {
        return "none (one view per frame)".into();
    };
    let method = match st.method {
        StereoMethod::ToeIn => format!(
            "toe-in, eyes {} degrees apart (each turned {} about up)",
            st.angle_deg,
            st.angle_deg / 2.0
        ),
        StereoMethod::Parallel(Separation::World(w)) => {
            format!("parallel (off-axis), eyes {w} world units apart, converging at the target")
        }
        StereoMethod::Parallel(Separation::Fraction(f)) => format!(
            "parallel (off-axis), eyes {f:.4} x the eye-target distance apart, converging at the target"
        ),
    };
    let layout = match st.layout {
        Layout::Pair => "pair (_left and _right files)".to_string(),
        Layout::SideBySide => format!("side-by-side (left view on the left), gap {} px", st.gap),
        Layout::CrossEyed => format!("cross-eyed (right view on the left), gap {} px", st.gap),
        Layout::Anaglyph => format!(
            "anaglyph, {} glasses, {} (grey passes use luminance)",
            match st.anaglyph {
                Anaglyph::RedCyan => "red-cyan",
                Anaglyph::RedGreen => "red-green",
            },
            match st.anaglyph_colors {
                AnaglyphColors::Color => "colour: left red, right green and blue",
                AnaglyphColors::HalfColor => "half-colour: left luminance as red, right colours",
                AnaglyphColors::Gray => "luminance of both views",
            }
        ),
    };
    format!("{method}; layout {layout}")
}

/// Lines describing the manifest, animations, turntable page (when `viewer`) and
/// ffmpeg commands of a run into `out` (for `volcast check`).
pub fn describe_outputs(scene: &Scene, out: &Path, viewer: bool) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "manifest {} (records in {}/, used by --resume)",
        out.join(manifest::MANIFEST).display(),
        out.join(manifest::RECORDS).display()
    );
    let seqs = Outputs::of_scene(scene).sequences();
    if let Some(a) = &scene.animation {
        let files: Vec<String> = seqs
            .iter()
            .flat_map(|q| {
                a.formats
                    .iter()
                    .map(move |&f| format!("{}.{}", q.stem(), f.extension()))
            })
            .collect();
        let gif = if a.formats.contains(&AnimationFormat::Gif) {
            let fps = 100.0 / animation::gif_delay(a.fps) as f64;
            format!(
                ", GIF at {} fps ({} hundredths of a second per frame)",
                (fps * 1000.0).round() / 1000.0,
                animation::gif_delay(a.fps)
            )
        } else {
            String::new()
        };
        let video = if a.formats.iter().any(|f| f.is_video()) {
            let crf = a
                .formats
                .iter()
                .filter_map(|f| {
                    let (default, _) = f.quality_range()?;
                    Some(format!(
                        "{} crf {}",
                        f.extension(),
                        a.quality.unwrap_or(default)
                    ))
                })
                .collect::<Vec<_>>()
                .join(", ");
            let by = animation::find_ffmpeg()
                .map_or("no ffmpeg found".into(), |p| p.display().to_string());
            format!("; videos by {by} ({crf})")
        } else {
            String::new()
        };
        let _ = writeln!(
            s,
            "animate  {} at {} fps{gif}, {}{}{video}; written once every frame exists",
            files.join(", "),
            a.fps,
            if a.looping { "looping" } else { "playing once" },
            if a.ping_pong {
                ", forward then back"
            } else {
                ""
            }
        );
    }
    if viewer {
        let _ = writeln!(
            s,
            "viewer   {}: a turntable page to open in a browser (drag or arrow keys turn the object), written once every frame exists",
            out.join(viewer::PAGE).display()
        );
    }
    if scene.image.format != Format::Nrrd {
        for l in &scene.labels {
            let text: String = l
                .text
                .iter()
                .map(|p| match p {
                    crate::label::Part::Text(t) => t.clone(),
                    other => crate::label::PLACEHOLDERS
                        .iter()
                        .find(|(_, q)| q == other)
                        .map_or(String::new(), |(n, _)| format!("{{{n}}}")),
                })
                .collect();
            let _ = writeln!(
                s,
                "label    {text:?} at {}, {} px, colour {:?}, drawn into every PNG frame",
                l.position.name(),
                l.size,
                l.color
            );
        }
        if scene.image.scale_bar {
            let _ = writeln!(
                s,
                "overlay  scale bar at the bottom left: 1, 2 or 5 x 10^k world units, at most a quarter of the width"
            );
        }
        if scene.image.colorbar {
            let names: Vec<&str> = scene
                .passes
                .iter()
                .filter(|p| p.mode.is_intensity())
                .map(|p| p.name.as_str())
                .collect();
            let _ = writeln!(
                s,
                "overlay  colour bar of the window on the right of {}",
                if names.is_empty() {
                    "no pass (none is an intensity pass)".to_string()
                } else {
                    format!("pass {}", names.join(", "))
                }
            );
        }
        let fps = scene.animation.as_ref().map_or(24.0, |a| a.fps);
        for q in &seqs {
            let _ = writeln!(s, "video    {}", animation::ffmpeg_command(out, q, fps));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names() {
        assert_eq!(
            frame_path(Path::new("out/x"), "mip", 7, Eye::Left, "png"),
            PathBuf::from("out/x/mip_0007_left.png")
        );
        assert_eq!(
            frame_path(Path::new("o"), "a", 12345, Eye::Mono, "nrrd"),
            PathBuf::from("o/a_12345.nrrd")
        );
    }
}
