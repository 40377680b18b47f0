//! Animated GIF and APNG files assembled from a pass's written PNG frames.
//!
//! Animations are made from the frame files on disk, after all of them exist, so
//! they work the same for one run, for shards (the shard that completes the
//! sequence assembles it) and for resumed runs. One animation per image sequence:
//! `{pass}.gif` / `{pass}.apng`, or `{pass}_left.*` and `{pass}_right.*` for the
//! `pair` stereo layout.
//!
//! - **APNG** (`png` crate): the frames' own colour type and bit depth (16-bit
//!   frames stay 16-bit), every frame shown for `1/fps` seconds.
//! - **GIF** (`gif` crate): 8 bits per sample; grey frames use an exact 256-grey
//!   palette, colour frames a palette per frame (NeuQuant). GIF delays are whole
//!   hundredths of a second, so the frame time is `round(100/fps)` hundredths, at
//!   least 2 (browsers slow smaller delays down): 24 fps plays at 25.
//! - **MP4** (H.264, yuv420p, `+faststart`) and **WebM** (VP9, yuv420p): encoded by
//!   the `ffmpeg` program found on `PATH`, the decoded frames streamed to it through
//!   a pipe (no copies on disk). ffmpeg writes into a private folder made beside the
//!   video, and the finished file is renamed into place, so a failed encoding
//!   leaves nothing and a planted link is replaced, never written through. Sizes
//!   are padded to even numbers, which yuv420p needs.
//!
//! `ping_pong` plays the frames forward, then backward without repeating the two
//! ends (2n - 2 frames), for rocking paths.

use std::io::{BufReader, Write};
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::write::write_atomic_with;
use super::{frame_path, Outputs};
use crate::error::Error;
use crate::scene::{Animation, AnimationFormat};
use crate::views::Eye;

/// One image sequence of a run: a pass and, for the `pair` layout, an eye.
#[derive(Clone, Debug, PartialEq)]
pub struct Sequence {
    /// Pass name.
    pub pass: String,
    /// `Mono` for single-file layouts.
    pub eye: Eye,
}

impl Sequence {
    /// File stem of the sequence's animations and videos: `mip`, `mip_left`.
    pub fn stem(&self) -> String {
        match self.eye {
            Eye::Mono => self.pass.clone(),
            Eye::Left => format!("{}_left", self.pass),
            Eye::Right => format!("{}_right", self.pass),
        }
    }

    /// The animation file of `format`.
    pub fn animation_path(&self, out: &Path, format: AnimationFormat) -> PathBuf {
        out.join(format!("{}.{}", self.stem(), format.extension()))
    }
}

/// GIF frame delay in hundredths of a second.
pub fn gif_delay(fps: f64) -> u16 {
    (100.0 / fps).round().clamp(2.0, 65535.0) as u16
}

/// APNG frame delay as a fraction of a second `(numerator, denominator)`.
pub fn apng_delay(fps: f64) -> (u16, u16) {
    for scale in [1.0, 1000.0, 100.0, 10.0] {
        let den = fps * scale;
        if (scale == 1.0 && den.fract() == 0.0 && den <= 65535.0)
            || (scale > 1.0 && den.round() <= 65535.0 && den.round() >= 1.0)
        {
            return (scale as u16, den.round() as u16);
        }
    }
    (1, fps.round().clamp(1.0, 65535.0) as u16)
}

/// What was written.
#[derive(Clone, Debug, PartialEq)]
pub struct Written {
    /// The animation file.
    pub path: PathBuf,
    /// Its format.
    pub format: AnimationFormat,
    /// Frames in it.
    pub frames: usize,
    /// The frame rate it plays at (GIF: after rounding the delay).
    pub fps: f64,
    /// SHA-256 of the frames' hashes it was made from, when known (recorded in the
    /// manifest to tell whether it is still up to date).
    pub frames_sha256: Option<String>,
}

/// Writes every animation of `outputs` (as `anim` says) into `out` from the frame
/// files there.
pub fn assemble(out: &Path, outputs: &Outputs, anim: &Animation) -> Result<Vec<Written>, Error> {
    let mut written = Vec::new();
    for seq in outputs.sequences() {
        let frames: Vec<PathBuf> = (0..outputs.frames)
            .map(|k| frame_path(out, &seq.pass, k, seq.eye, "png"))
            .collect();
        let frames: Vec<PathBuf> = played(frames.len(), anim.ping_pong)
            .into_iter()
            .map(|k| frames[k].clone())
            .collect();
        for &format in &anim.formats {
            let path = seq.animation_path(out, format);
            let fps = match format {
                AnimationFormat::Gif => write_gif(&path, &frames, anim)?,
                AnimationFormat::Apng => write_apng(&path, &frames, anim)?,
                AnimationFormat::Mp4 | AnimationFormat::Webm => {
                    write_video(&path, &frames, anim, format)?
                }
            };
            written.push(Written {
                path,
                format,
                frames: frames.len(),
                fps,
                frames_sha256: None,
            });
        }
    }
    Ok(written)
}

/// A decoded PNG frame, as stored (no conversion).
struct Decoded {
    width: u32,
    height: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    data: Vec<u8>,
}

/// Decodes the frame at `path`, opened in its folder without following a link and
/// decoded into a fallibly allocated buffer.
fn decode(path: &Path) -> Result<Decoded, Error> {
    let fail = |message: String| Error::Encode {
        path: path.to_path_buf(),
        message,
    };
    let (dir, name) = (
        path.parent().unwrap_or(Path::new(".")),
        path.file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| fail("not a frame file name".into()))?,
    );
    let file = super::write::Folder::open(dir)
        .and_then(|f| f.open_regular(name))
        .map_err(|e| fail(format!("cannot read a frame: {e}")))?;
    let mut decoder = png::Decoder::new(BufReader::new(file));
    decoder.set_transformations(png::Transformations::IDENTITY);
    let mut reader = decoder
        .read_info()
        .map_err(|e| fail(format!("not a PNG frame: {e}")))?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| fail("frame too large".into()))?;
    let mut data = super::try_zeroed(size).map_err(|e| fail(e.to_string()))?;
    let info = reader
        .next_frame(&mut data)
        .map_err(|e| fail(format!("cannot decode the frame: {e}")))?;
    data.truncate(info.buffer_size());
    Ok(Decoded {
        width: info.width,
        height: info.height,
        color: info.color_type,
        depth: info.bit_depth,
        data,
    })
}

/// Checks that a frame has the first frame's size and type.
fn same_kind(first: &Decoded, d: &Decoded, path: &Path) -> Result<(), Error> {
    if (d.width, d.height, d.color, d.depth)
        == (first.width, first.height, first.color, first.depth)
    {
        Ok(())
    } else {
        Err(Error::Encode {
            path: path.to_path_buf(),
            message: format!(
                "frames of one sequence must share size and type: this one is {}x{} {:?} {:?}, the first {}x{} {:?} {:?}",
                d.width, d.height, d.color, d.depth, first.width, first.height, first.color, first.depth
            ),
        })
    }
}

/// Frames per batch decoded in parallel.
fn batch() -> usize {
    (2 * rayon::current_num_threads()).max(2)
}

/// Writes `dest` atomically from `fill`, keeping `fill`'s own error (the atomic
/// writer only carries I/O errors, so an encoder's error is passed around it).
fn stream_atomic(
    dest: &Path,
    fill: impl FnOnce(&mut dyn Write) -> Result<(), Error>,
) -> Result<(), Error> {
    let mut inner: Result<(), Error> = Ok(());
    let io = write_atomic_with(dest, |w| {
        fill(w).map_err(|e| {
            inner = Err(e);
            std::io::Error::other("animation not written")
        })
    });
    inner?;
    io.map_err(|source| Error::Output {
        path: dest.to_path_buf(),
        source,
    })
}

fn write_apng(dest: &Path, frames: &[PathBuf], anim: &Animation) -> Result<f64, Error> {
    let first = decode(&frames[0])?;
    let (num, den) = apng_delay(anim.fps);
    let fail = |e: png::EncodingError| Error::Encode {
        path: dest.to_path_buf(),
        message: e.to_string(),
    };
    stream_atomic(dest, |w: &mut dyn Write| {
        let mut enc = png::Encoder::new(&mut *w, first.width, first.height);
        enc.set_color(first.color);
        enc.set_depth(first.depth);
        enc.set_animated(frames.len() as u32, if anim.looping { 0 } else { 1 })
            .map_err(fail)?;
        enc.set_frame_delay(num, den).map_err(fail)?;
        let mut writer = enc.write_header().map_err(fail)?;
        for chunk in frames.chunks(batch()) {
            let decoded: Vec<Decoded> = chunk
                .par_iter()
                .map(|p| decode(p))
                .collect::<Result<_, _>>()?;
            for (d, p) in decoded.iter().zip(chunk) {
                same_kind(&first, d, p)?;
                writer.write_image_data(&d.data).map_err(fail)?;
            }
        }
        writer.finish().map_err(fail)
    })?;
    Ok(den as f64 / num as f64)
}

/// 8-bit samples of a decoded frame (16-bit samples rounded to 8 bits).
fn eight_bit(d: &Decoded) -> Vec<u8> {
    match d.depth {
        png::BitDepth::Sixteen => d
            .data
            .chunks_exact(2)
            .map(|b| ((u16::from_be_bytes([b[0], b[1]]) as u32 * 255 + 32767) / 65535) as u8)
            .collect(),
        _ => d.data.clone(),
    }
}

fn write_gif(dest: &Path, frames: &[PathBuf], anim: &Animation) -> Result<f64, Error> {
    let first = decode(&frames[0])?;
    let fail = |message: String| Error::Encode {
        path: dest.to_path_buf(),
        message,
    };
    let (w, h) = match (u16::try_from(first.width), u16::try_from(first.height)) {
        (Ok(w), Ok(h)) => (w, h),
        _ => {
            return Err(fail(format!(
            "GIF images are at most 65535 pixels wide and high; these frames are {}x{} (use apng)",
            first.width, first.height
        )))
        }
    };
    let grey = match first.color {
        png::ColorType::Grayscale => true,
        png::ColorType::Rgb => false,
        other => {
            return Err(fail(format!(
                "expected grey or RGB frames, found {other:?}"
            )))
        }
    };
    let delay = gif_delay(anim.fps);
    let palette: Vec<u8> = if grey {
        (0..=255u8).flat_map(|v| [v, v, v]).collect()
    } else {
        Vec::new()
    };
    stream_atomic(dest, |out: &mut dyn Write| {
        let gif_err = |e: gif::EncodingError| fail(e.to_string());
        let mut enc = gif::Encoder::new(&mut *out, w, h, &palette).map_err(gif_err)?;
        if anim.looping {
            enc.set_repeat(gif::Repeat::Infinite).map_err(gif_err)?;
        }
        for chunk in frames.chunks(batch()) {
            let encoded: Vec<gif::Frame<'static>> = chunk
                .par_iter()
                .map(|p| {
                    let d = decode(p)?;
                    same_kind(&first, &d, p)?;
                    let px = eight_bit(&d);
                    let mut f = if grey {
                        gif::Frame {
                            width: w,
                            height: h,
                            buffer: px.into(),
                            ..gif::Frame::default()
                        }
                    } else {
                        gif::Frame::from_rgb_speed(w, h, &px, 10)
                    };
                    f.delay = delay;
                    Ok(f)
                })
                .collect::<Result<_, Error>>()?;
            for f in &encoded {
                enc.write_frame(f).map_err(gif_err)?;
            }
        }
        Ok(())
    })?;
    Ok(100.0 / delay as f64)
}

/// The frame numbers an animation of `n` frames plays: `0..n`, and with
/// `ping_pong` back again from `n - 2` to 1.
pub fn played(n: usize, ping_pong: bool) -> Vec<usize> {
    let back = if ping_pong && n > 2 {
        (1..n - 1).rev().collect()
    } else {
        Vec::new()
    };
    (0..n).chain(back).collect()
}

/// The `ffmpeg` program on `PATH`, if there is one.
pub fn find_ffmpeg() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join("ffmpeg"))
        .find(|p| is_executable(p))
}

fn is_executable(p: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
    }
    #[cfg(not(unix))]
    {
        p.is_file()
    }
}

/// What to do when a scene asks for a video and no ffmpeg is found.
pub const NO_FFMPEG: &str = "the videos (formats \"mp4\", \"webm\") are encoded by the ffmpeg program, and none is on PATH: install it (Debian/Ubuntu: sudo apt install ffmpeg; Fedora: sudo dnf install ffmpeg; macOS: brew install ffmpeg; conda: conda install -c conda-forge ffmpeg), or leave the video formats out";

/// ffmpeg's raw pixel format for a decoded PNG frame (16-bit samples are
/// big-endian in PNG).
fn raw_pixel_format(d: &Decoded) -> Option<&'static str> {
    use png::{BitDepth, ColorType};
    Some(match (d.color, d.depth) {
        (ColorType::Grayscale, BitDepth::Eight) => "gray",
        (ColorType::Grayscale, BitDepth::Sixteen) => "gray16be",
        (ColorType::GrayscaleAlpha, BitDepth::Eight) => "ya8",
        (ColorType::GrayscaleAlpha, BitDepth::Sixteen) => "ya16be",
        (ColorType::Rgb, BitDepth::Eight) => "rgb24",
        (ColorType::Rgb, BitDepth::Sixteen) => "rgb48be",
        (ColorType::Rgba, BitDepth::Eight) => "rgba",
        (ColorType::Rgba, BitDepth::Sixteen) => "rgba64be",
        _ => return None,
    })
}

/// Encodes `frames` into the video `dest` with ffmpeg (see the module
/// documentation); returns the frame rate it plays at.
fn write_video(
    dest: &Path,
    frames: &[PathBuf],
    anim: &Animation,
    format: AnimationFormat,
) -> Result<f64, Error> {
    use std::process::{Command, Stdio};
    let fail = |message: String| Error::Encode {
        path: dest.to_path_buf(),
        message,
    };
    let ffmpeg = find_ffmpeg().ok_or_else(|| fail(NO_FFMPEG.into()))?;
    let first = decode(&frames[0])?;
    let pixels = raw_pixel_format(&first).ok_or_else(|| {
        fail(format!(
            "frames of {:?} {:?} cannot be encoded",
            first.color, first.depth
        ))
    })?;
    let (dir, name) = (
        dest.parent().unwrap_or(Path::new(".")),
        dest.file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| fail("not a video file name".into()))?,
    );
    // a folder only this process can write, so ffmpeg's file cannot be a planted link
    let private = dir.join(super::write::temporary_name(name));
    let mut builder = std::fs::DirBuilder::new();
    #[cfg(unix)]
    std::os::unix::fs::DirBuilderExt::mode(&mut builder, 0o700);
    builder.create(&private).map_err(|source| Error::Output {
        path: private.clone(),
        source,
    })?;
    let encoded = private.join(name);
    let result = (|| {
        let quality = anim
            .quality
            .or(format.quality_range().map(|r| r.0))
            .unwrap_or(18)
            .to_string();
        let size = format!("{}x{}", first.width, first.height);
        let fps = anim.fps.to_string();
        let mut args: Vec<&str> = vec![
            "-hide_banner",
            "-loglevel",
            "error",
            "-f",
            "rawvideo",
            "-pix_fmt",
            pixels,
            "-s",
            &size,
            "-framerate",
            &fps,
            "-i",
            "pipe:0",
            "-an",
            "-vf",
            "pad=ceil(iw/2)*2:ceil(ih/2)*2",
            "-pix_fmt",
            "yuv420p",
            "-crf",
            &quality,
            // no encoder version or time in the file: the same frames give the same bytes
            "-fflags",
            "+bitexact",
            "-flags:v",
            "+bitexact",
            "-map_metadata",
            "-1",
        ];
        match format {
            AnimationFormat::Mp4 => args.extend([
                "-c:v",
                "libx264",
                "-preset",
                "medium",
                "-movflags",
                "+faststart",
                "-f",
                "mp4",
            ]),
            _ => args.extend([
                "-c:v",
                "libvpx-vp9",
                "-b:v",
                "0",
                "-row-mt",
                "1",
                "-f",
                "webm",
            ]),
        }
        let mut child = Command::new(&ffmpeg)
            .args(&args)
            .arg(&encoded)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| fail(format!("cannot run {}: {e}", ffmpeg.display())))?;
        let mut stderr = child.stderr.take().expect("piped");
        let said = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = std::io::Read::read_to_string(&mut stderr, &mut s);
            s
        });
        let mut stdin = child.stdin.take().expect("piped");
        let mut fed: Result<(), Error> = Ok(());
        'feed: for chunk in frames.chunks(batch()) {
            let decoded: Vec<Decoded> = match chunk.par_iter().map(|p| decode(p)).collect() {
                Ok(d) => d,
                Err(e) => {
                    fed = Err(e);
                    break;
                }
            };
            for (d, p) in decoded.iter().zip(chunk) {
                if let Err(e) = same_kind(&first, d, p) {
                    fed = Err(e);
                    break 'feed;
                }
                // a closed pipe means ffmpeg stopped: its own message says why
                if stdin.write_all(&d.data).is_err() {
                    break 'feed;
                }
            }
        }
        drop(stdin);
        if fed.is_err() {
            let _ = child.kill();
        }
        let status = child
            .wait()
            .map_err(|e| fail(format!("waiting for ffmpeg: {e}")))?;
        let said = said.join().unwrap_or_default();
        fed?;
        if !status.success() {
            let last: Vec<&str> = said.lines().rev().take(4).collect();
            let last: Vec<&str> = last.into_iter().rev().collect();
            return Err(fail(format!(
                "{} failed ({status}): {}",
                ffmpeg.display(),
                if last.is_empty() {
                    "no message".into()
                } else {
                    last.join(" / ")
                }
            )));
        }
        std::fs::rename(&encoded, dest).map_err(|source| Error::Output {
            path: dest.to_path_buf(),
            source,
        })
    })();
    let _ = std::fs::remove_file(&encoded);
    let _ = std::fs::remove_dir(&private);
    result.map(|()| anim.fps)
}

/// Quotes a path for a POSIX shell when it needs it.
fn shell_quote(s: &str) -> String {
    if !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "%_./-:+=@".contains(c))
    {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

/// The ffmpeg command that turns a sequence's numbered PNGs into an H.264 MP4
/// (padded to even sizes, which yuv420p needs).
pub fn ffmpeg_command(out: &Path, seq: &Sequence, fps: f64) -> String {
    let suffix = match seq.eye {
        Eye::Mono => "",
        Eye::Left => "_left",
        Eye::Right => "_right",
    };
    let input = out.join(format!("{}_%04d{suffix}.png", seq.pass));
    let output = out.join(format!("{}.mp4", seq.stem()));
    format!(
        "ffmpeg -framerate {fps} -i {} -vf 'pad=ceil(iw/2)*2:ceil(ih/2)*2' -c:v libx264 -pix_fmt yuv420p -crf 18 {}",
        shell_quote(&input.to_string_lossy()),
        shell_quote(&output.to_string_lossy())
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delays() {
        assert_eq!(gif_delay(24.0), 4);
        assert_eq!(gif_delay(10.0), 10);
        assert_eq!(gif_delay(100.0), 2);
        assert_eq!(gif_delay(0.5), 200);
        assert_eq!(apng_delay(24.0), (1, 24));
        assert_eq!(apng_delay(29.97), (1000, 29970));
        assert_eq!(apng_delay(0.5), (1000, 500));
        assert_eq!(apng_delay(70.25), (100, 7025));
    }

    #[test]
    fn ffmpeg_commands_quote_when_needed() {
        let seq = Sequence {
            pass: "mip".into(),
            eye: Eye::Left,
        };
        let c = ffmpeg_command(Path::new("out/head"), &seq, 24.0);
        assert_eq!(
            c,
            "ffmpeg -framerate 24 -i out/head/mip_%04d_left.png -vf 'pad=ceil(iw/2)*2:ceil(ih/2)*2' -c:v libx264 -pix_fmt yuv420p -crf 18 out/head/mip_left.mp4"
        );
        let c = ffmpeg_command(
            Path::new("my out"),
            &Sequence {
                pass: "a".into(),
                eye: Eye::Mono,
            },
            12.5,
        );
        assert!(
            c.contains("-i 'my out/a_%04d.png'") && c.contains("12.5"),
            "{c}"
        );
    }
}
