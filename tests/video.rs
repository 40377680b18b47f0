//! MP4 and WebM videos (issue 47, videos): encoded by ffmpeg from the frames, read
//! back by ffprobe with the right codec, size and frame count, their first frame the
//! PNG frame 0 within the codec's loss; `ping_pong` plays 2n - 2 frames; a scene
//! asking for a video without ffmpeg is refused before anything is written; an
//! ffmpeg that fails leaves no video and no temporary.
//!
//! The tests need `ffmpeg` and `ffprobe` on `PATH` (Debian: `apt-get install
//! ffmpeg`); without them they are skipped with a message, unless
//! `VOLCAST_REQUIRE_FFMPEG=1` (set by `.ci/run`), when they fail.

use std::path::Path;
use std::process::Command;

use crate::util::volcast;

/// Whether ffmpeg and ffprobe run; panics under `VOLCAST_REQUIRE_FFMPEG=1` when not.
fn have_ffmpeg() -> bool {
    let runs = |p: &str| {
        Command::new(p)
            .arg("-version")
            .output()
            .is_ok_and(|o| o.status.success())
    };
    if runs("ffmpeg") && runs("ffprobe") {
        return true;
    }
    let message =
        "the video tests need ffmpeg and ffprobe on PATH (Debian: apt-get install ffmpeg)";
    if std::env::var("VOLCAST_REQUIRE_FFMPEG").as_deref() == Ok("1") {
        panic!("{message}, and VOLCAST_REQUIRE_FFMPEG=1");
    }
    eprintln!("SKIPPED: {message}");
    false
}

fn scene(frames: usize, formats: &str, extra: &str) -> String {
    format!(
        "[volume]\nsynthetic = \"blobs\"\nsizes = [24, 24, 24]\n[orbit]\nframes = {frames}\n\
         [image]\nsize = [32, 24]\nout = \"out\"\n[[render]]\nmode = \"mip\"\n\
         [animation]\nformats = {formats}\nfps = 12\n{extra}"
    )
}

/// `ffprobe`'s codec, width, height, pixel format and decoded frame count.
fn probe(path: &Path) -> (String, u32, u32, String, usize) {
    let o = Command::new("ffprobe")
        .args(["-v", "error", "-count_frames", "-select_streams", "v:0"])
        .args([
            "-show_entries",
            "stream=codec_name,width,height,pix_fmt,nb_read_frames",
        ])
        .args(["-of", "default=noprint_wrappers=1"])
        .arg(path)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    let field = |k: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(&format!("{k}=")))
            .unwrap_or_else(|| panic!("{k} missing from {text}"))
            .to_string()
    };
    (
        field("codec_name"),
        field("width").parse().unwrap(),
        field("height").parse().unwrap(),
        field("pix_fmt"),
        field("nb_read_frames").parse().unwrap(),
    )
}

/// The first frame of a video decoded to 8-bit grey by ffmpeg.
fn first_frame_grey(path: &Path) -> Vec<u8> {
    let o = Command::new("ffmpeg")
        .args(["-v", "error", "-i"])
        .arg(path)
        .args(["-frames:v", "1", "-f", "rawvideo", "-pix_fmt", "gray", "-"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    o.stdout
}

#[test]
fn videos_are_what_ffprobe_reads_and_open_on_frame_0() {
    if !have_ffmpeg() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("s.toml"), scene(6, "[\"mp4\", \"webm\"]", "")).unwrap();
    let o = volcast(d, &["render", "s.toml"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        !err.contains("to make a video"),
        "the MP4 is written, no hint: {err}"
    );
    let frame0 = image::open(d.join("out/mip_0000.png")).unwrap().to_luma8();
    for (file, codec) in [("mip.mp4", "h264"), ("mip.webm", "vp9")] {
        let path = d.join("out").join(file);
        assert_eq!(
            probe(&path),
            (codec.to_string(), 32, 24, "yuv420p".to_string(), 6),
            "{file}"
        );
        let video = first_frame_grey(&path);
        assert_eq!(video.len(), frame0.as_raw().len(), "{file}");
        let diffs: Vec<i32> = video
            .iter()
            .zip(frame0.as_raw())
            .map(|(&a, &b)| (i32::from(a) - i32::from(b)).abs())
            .collect();
        let mean = diffs.iter().sum::<i32>() as f64 / diffs.len() as f64;
        let max = diffs.iter().copied().max().unwrap();
        // lossy, yuv420p: within a few grey levels on average
        assert!(mean <= 3.0 && max <= 48, "{file}: mean {mean}, max {max}");
    }
    // the manifest records each video's bytes and hash; --resume keeps them
    let manifest = std::fs::read_to_string(d.join("out/manifest.json")).unwrap();
    assert!(
        manifest.contains("\"file\": \"mip.mp4\"") && manifest.contains("\"format\": \"webm\"")
    );
    let before = std::fs::metadata(d.join("out/mip.mp4"))
        .unwrap()
        .modified()
        .unwrap();
    let o = volcast(d, &["render", "s.toml", "--resume", "-q"]);
    assert!(o.status.success());
    let after = std::fs::metadata(d.join("out/mip.mp4"))
        .unwrap()
        .modified()
        .unwrap();
    assert_eq!(before, after, "an up-to-date video was encoded again");
    // the same frames give the same bytes
    let first = std::fs::read(d.join("out/mip.mp4")).unwrap();
    std::fs::remove_file(d.join("out/mip.mp4")).unwrap();
    let o = volcast(d, &["render", "s.toml", "--resume", "-q"]);
    assert!(o.status.success());
    assert_eq!(std::fs::read(d.join("out/mip.mp4")).unwrap(), first);
}

#[test]
fn ping_pong_plays_forward_then_back() {
    if !have_ffmpeg() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(
        d.join("s.toml"),
        scene(5, "[\"mp4\", \"apng\"]", "ping_pong = true\nquality = 10\n"),
    )
    .unwrap();
    let o = volcast(d, &["render", "s.toml", "-q"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        probe(&d.join("out/mip.mp4")).4,
        8,
        "5 frames forward, 3 back"
    );
    let apng = std::fs::read(d.join("out/mip.apng")).unwrap();
    let decoder = png::Decoder::new(std::io::Cursor::new(apng));
    let reader = decoder.read_info().unwrap();
    assert_eq!(reader.info().animation_control().unwrap().num_frames, 8);
}

#[test]
fn a_video_without_ffmpeg_is_refused_before_anything_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("s.toml"), scene(3, "[\"webm\"]", "")).unwrap();
    std::fs::create_dir(d.join("empty")).unwrap();
    for cmd in ["render", "check"] {
        let o = Command::new(env!("CARGO_BIN_EXE_volcast"))
            .args([cmd, "s.toml"])
            .current_dir(d)
            .env("PATH", d.join("empty"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{cmd}: {err}");
        assert!(
            err.contains("none is on PATH") && err.contains("apt install ffmpeg"),
            "{err}"
        );
        assert!(!d.join("out").exists(), "{cmd} wrote output");
    }
}

#[cfg(unix)]
#[test]
fn a_failing_ffmpeg_leaves_no_video() {
    use std::os::unix::fs::PermissionsExt;
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("s.toml"), scene(3, "[\"mp4\"]", "")).unwrap();
    // an ffmpeg that writes half a file where it was told to, then fails
    let bin = d.join("bin");
    std::fs::create_dir(&bin).unwrap();
    let fake = bin.join("ffmpeg");
    std::fs::write(
        &fake,
        "#!/bin/sh\nfor last; do :; done\necho half > \"$last\"\ncat > /dev/null\necho 'Conversion failed!' >&2\nexit 1\n",
    )
    .unwrap();
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    let path = format!("{}:/usr/bin:/bin", bin.display());
    let o = Command::new(env!("CARGO_BIN_EXE_volcast"))
        .args(["render", "s.toml"])
        .current_dir(d)
        .env("PATH", path)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("mip.mp4") && err.contains("Conversion failed!"),
        "{err}"
    );
    let left: Vec<String> = std::fs::read_dir(d.join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("mp4"))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
    // the frames themselves were written and recorded
    assert!(d.join("out/mip_0002.png").is_file());
}

#[test]
fn quality_is_checked_against_the_formats() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    for (formats, quality, needle) in [
        (
            "[\"mp4\"]",
            "60",
            "quality = 60: expected a constant rate factor from 0 (best, largest) to 51",
        ),
        ("[\"mp4\", \"webm\"]", "55", "to 51"),
        ("[\"gif\"]", "20", "`quality` is the videos'"),
    ] {
        std::fs::write(
            d.join("s.toml"),
            scene(3, formats, &format!("quality = {quality}\n")),
        )
        .unwrap();
        let o = volcast(d, &["check", "s.toml"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(
            err.contains(needle) && err.contains("s.toml:"),
            "{formats}: {err}"
        );
    }
}
