//! The command-line interface, as clap definitions (also the source of `--help`).

use std::ops::Range;
use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

/// Render images of 3D scalar volumes from declarative TOML scene files.
#[derive(Debug, Parser)]
#[command(name = "volcast", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a scene: one numbered image sequence per [[render]] pass.
    Render(RenderArgs),
    /// Validate a scene and print its plan without rendering.
    Check(CheckArgs),
    /// Describe a volume (NRRD, NIfTI, MetaImage, a DICOM folder, or the volume of a scene .toml).
    Info(InfoArgs),
    /// Write the value histogram and the value x gradient-magnitude histogram of a
    /// volume (or of a scene's volume, with its window, iso values, thresholds and
    /// transfer functions drawn over them) as PNG plots and CSV files.
    Histogram(HistogramArgs),
    /// Measure the renderer: `bench accuracy` reports speed against error.
    #[command(subcommand)]
    Bench(BenchCommand),
}

/// The benchmarks.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Every render mode on analytic fields over steps, interpolations, gradient
    /// estimators and methods: time per view, samples per second, max and RMS error
    /// against the closed forms. Prints the summary and writes accuracy.csv,
    /// accuracy.json, accuracy.md and images/accuracy.png into --out.
    Accuracy(AccuracyArgs),
    /// Whole frames of every render mode on the shipped engine CT and on the peer
    /// benchmark's field at 256^3 and 512^3 (uint8): ms per frame, samples per second
    /// taken and nominal, the share skipped, peak memory, and the speed-up from one
    /// thread to all. Prints a Markdown table; with --out, also writes speed.md,
    /// speed.csv and speed.json.
    Speed(SpeedArgs),
}

#[derive(Debug, Args)]
pub struct SpeedArgs {
    /// A CI-sized run (a 64^3 field, 64 x 64 images, one repeat): seconds, not minutes.
    #[arg(long)]
    pub quick: bool,
    /// Folder for speed.md, speed.csv and speed.json.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// The most worker threads to measure (default: one per core); one thread is
    /// always measured too.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
    /// Repeats per case, the thread counts taking turns within each (default 5;
    /// 1 with --quick); the median is reported.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub repeats: Option<u16>,
    /// Only the cases whose mode contains this text (e.g. `composite`: the
    /// composites of one and of several volumes).
    #[arg(long, value_name = "TEXT")]
    pub only: Option<String>,
}

#[derive(Debug, Args)]
pub struct AccuracyArgs {
    /// A CI-sized run (two fields, two steps, tiny images): seconds, not minutes.
    #[arg(long)]
    pub quick: bool,
    /// Folder for the results.
    #[arg(long, value_name = "DIR", default_value = "bench-accuracy")]
    pub out: PathBuf,
    /// Worker threads (default: one per core).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
}

/// Options shared by `render` and `check`.
#[derive(Debug, Args)]
pub struct SceneArgs {
    /// The scene file.
    pub scene: PathBuf,
    /// Output folder (instead of the scene's [image] out).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Frames to render: `A..B` (A up to but excluding B), `A..=B`, or one frame `N`.
    #[arg(long, value_name = "A..B", value_parser = parse_frames)]
    pub frames: Option<Range<usize>>,
    /// Image size instead of the scene's, e.g. `128x128` (for previews).
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    pub size: Option<(usize, usize)>,
    /// Worker threads (default: one per core). Output is identical for any value.
    /// Frames are written by one more thread, which mostly waits on the disk.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
    /// Most memory the run may use, e.g. `8G`, `512M` (default: 16G or 3/4 of RAM):
    /// the voxels read, gradient volumes, coefficients, tables and images. The plan's
    /// estimate is checked before anything is read. Memory-mapped volumes (raw data in
    /// native byte order) do not count.
    #[arg(long, value_name = "BYTES", value_parser = parse_bytes)]
    pub max_memory: Option<u64>,
    /// Render the K-th of N interleaved parts of the frames (K from 0 to N-1): frames
    /// K, K+N, K+2N, ... of the selected range. `auto/N` (for Slurm job arrays) takes
    /// K = SLURM_ARRAY_TASK_ID, so a resubmitted task renders its own shard of N;
    /// `auto` takes K and N from the array (SLURM_ARRAY_TASK_ID, _COUNT and _MIN).
    #[arg(long, value_name = "K/N|auto/N|auto", value_parser = parse_shard)]
    pub shard: Option<ShardArg>,
    /// Only read volume files, and write output, under DIR (after resolving `..` and
    /// links): the scene's volume path, every NRRD `data file` and the output folder.
    /// Use it to render untrusted scenes or volumes (course submissions, a shared
    /// service).
    #[arg(long, value_name = "DIR")]
    pub confine: Option<PathBuf>,
    /// Skip the images that the output folder's manifest shows are complete and
    /// belong to this very scene (same scene, volume header, size and version).
    #[arg(long)]
    pub resume: bool,
    /// Render both eyes of every stereo frame even where a view equals one of
    /// another frame (same bytes, more work; for comparisons).
    #[arg(long)]
    pub no_view_reuse: bool,
    /// March every sample of every ray instead of skipping empty space (the same
    /// images, slower; for comparisons and benchmarks).
    #[arg(long)]
    pub no_skip: bool,
    /// Also write {out}/index.html, a self-contained page that turns the object in
    /// a browser (as [viewer] html = true in the scene), once every frame exists.
    #[arg(long)]
    pub viewer: bool,
}

/// A `--shard` value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShardArg {
    /// From the Slurm environment.
    Auto,
    /// The task ID from the Slurm environment, of this many shards.
    AutoOf(usize),
    /// Given on the command line.
    Fixed(volcast::batch::Shard),
}

fn parse_shard(s: &str) -> Result<ShardArg, String> {
    if s.trim() == "auto" {
        Ok(ShardArg::Auto)
    } else if let Some(n) = s.trim().strip_prefix("auto/") {
        match n.trim().parse::<usize>() {
            Ok(n) if n >= 1 => Ok(ShardArg::AutoOf(n)),
            _ => Err(format!(
                "--shard {s}: expected auto/N with N the number of shards, a whole number of at least 1 (e.g. auto/8)"
            )),
        }
    } else {
        s.parse()
            .map(ShardArg::Fixed)
            .map_err(|e: volcast::batch::ShardError| e.to_string())
    }
}

#[derive(Debug, Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Render nothing: merge the manifest and assemble the animations from the images
    /// that exist (and are intact), and report what is missing (exit status 1 if
    /// anything is). For the safety-net job after a Slurm array.
    #[arg(long, conflicts_with_all = ["shard", "frames"])]
    pub finish_only: bool,
    /// Render into an output folder whose manifest belongs to another scene (another
    /// scene file, an edited scene, another size, volume or volcast version). Without
    /// it such a run is refused, so that two scenes never mix their images in one
    /// folder; with it, this scene's images replace the other's where names coincide
    #[arg(long)]
    pub force: bool,
    /// No progress bar and no summary (errors are still printed).
    #[arg(long, short)]
    pub quiet: bool,
}

#[derive(Debug, Args)]
pub struct CheckArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
}

#[derive(Debug, Args)]
pub struct InfoArgs {
    /// A volume file (.nrrd/.nhdr, .nii/.nii.gz, .mha/.mhd), a DICOM folder, or a scene
    /// .toml whose volume to describe.
    pub volume: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Largest voxel buffer to allocate, e.g. `8G`, `512M` (mapped volumes do not count).
    #[arg(long, value_name = "BYTES", value_parser = parse_bytes)]
    pub max_memory: Option<u64>,
}

#[derive(Debug, Args)]
pub struct HistogramArgs {
    /// A volume (.nrrd/.nhdr, .nii/.nii.gz, .mha/.mhd file, or a DICOM folder), or a
    /// scene .toml: its volume, window, crop and gradient estimator, with its iso
    /// values, thresholds and transfer functions drawn over the plots.
    pub volume: PathBuf,
    /// Folder for histogram.png, histogram2d.png, histogram.csv and
    /// histogram2d.csv (created if needed; the files are replaced).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Bins along the value axis, from 1 to 4096.
    #[arg(long, value_name = "N", default_value_t = 256,
          value_parser = clap::value_parser!(u16).range(1..=4096))]
    pub bins: u16,
    /// Bins along the gradient-magnitude axis of the 2D histogram, from 1 to 1024.
    #[arg(long, value_name = "N", default_value_t = 128,
          value_parser = clap::value_parser!(u16).range(1..=1024))]
    pub gradient_bins: u16,
    /// Top of the gradient-magnitude axis, in normalised value per voxel (larger
    /// magnitudes count in the top bin); default: the largest in the data.
    #[arg(long, value_name = "G", value_parser = parse_positive, allow_negative_numbers = true)]
    pub gradient_max: Option<f64>,
}

fn parse_positive(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(format!("expected a number greater than 0, got `{s}`")),
    }
}

fn parse_frames(s: &str) -> Result<Range<usize>, String> {
    let num = |t: &str| {
        t.trim()
            .parse::<usize>()
            .map_err(|_| format!("expected a frame number, got `{t}` (use A..B, A..=B or N)"))
    };
    let after = |n: usize| {
        n.checked_add(1)
            .ok_or_else(|| format!("frame {n} is too large to be a frame number"))
    };
    let r = if let Some((a, b)) = s.split_once("..=") {
        num(a)?..after(num(b)?)?
    } else if let Some((a, b)) = s.split_once("..") {
        num(a)?..num(b)?
    } else {
        let n = num(s)?;
        n..after(n)?
    };
    if r.start >= r.end {
        return Err(format!("`{s}` is an empty range of frames"));
    }
    Ok(r)
}

fn parse_size(s: &str) -> Result<(usize, usize), String> {
    let err = || format!("expected WIDTHxHEIGHT such as 256x256, got `{s}`");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(err)?;
    let w: usize = w.trim().parse().map_err(|_| err())?;
    let h: usize = h.trim().parse().map_err(|_| err())?;
    if w == 0 || h == 0 || w > 32768 || h > 32768 {
        return Err(format!(
            "width and height must be from 1 to 32768, got `{s}`"
        ));
    }
    Ok((w, h))
}

fn parse_bytes(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let (num, mult) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let m = match c.to_ascii_uppercase() {
                'K' => 1u64 << 10,
                'M' => 1 << 20,
                'G' => 1 << 30,
                'T' => 1 << 40,
                _ => return Err(format!("unknown unit in `{s}`: use K, M, G or T")),
            };
            (&t[..i], m)
        }
        _ => (t, 1),
    };
    let n: f64 = num
        .parse()
        .map_err(|_| format!("expected a size such as 8G or 512M, got `{s}`"))?;
    if !(n > 0.0 && n.is_finite()) {
        return Err(format!("expected a positive size, got `{s}`"));
    }
    Ok((n * mult as f64) as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames() {
        assert_eq!(parse_frames("2..5"), Ok(2..5));
        assert_eq!(parse_frames("2..=5"), Ok(2..6));
        assert_eq!(parse_frames("7"), Ok(7..8));
        assert!(parse_frames("5..2").is_err());
        assert!(parse_frames("a..b").is_err());
        let e = parse_frames("18446744073709551615").unwrap_err();
        assert!(e.contains("too large") && !e.contains("empty"), "{e}");
        assert!(parse_frames("0..=18446744073709551615").is_err());
    }

    #[test]
    fn shards() {
        assert_eq!(parse_shard("auto"), Ok(ShardArg::Auto));
        assert_eq!(
            parse_shard("2/3"),
            Ok(ShardArg::Fixed(volcast::batch::Shard {
                index: 2,
                count: 3
            }))
        );
        assert!(parse_shard("3/3").unwrap_err().contains("below N"));
        assert!(parse_shard("x").unwrap_err().contains("expected K/N"));
        assert_eq!(parse_shard("auto/8"), Ok(ShardArg::AutoOf(8)));
        assert!(parse_shard("auto/0").unwrap_err().contains("auto/N"));
        assert!(parse_shard("auto/x").is_err());
    }

    #[test]
    fn sizes_and_bytes() {
        assert_eq!(parse_size("64x32"), Ok((64, 32)));
        assert!(parse_size("64").is_err());
        assert_eq!(parse_bytes("2G"), Ok(2 << 30));
        assert_eq!(parse_bytes("1.5k"), Ok(1536));
        assert!(parse_bytes("-1").is_err());
    }
}
