//! `volcast bench speed`: whole frames of every render mode through the real
//! pipeline (`pipeline::render_films_of`), on a shipped real volume and on the peer
//! benchmark's field at 256^3 and 512^3: milliseconds per frame, samples per second
//! taken and nominal (the march without empty-space skipping), peak memory, and the
//! speed-up from one thread to all of them.
//!
//! A frame's time is measured as the issue asks for whole runs: `(T(F frames) -
//! T(1 frame)) / (F - 1)`, the frames of a turntable, so that the one-off work of a
//! run (the macrocell grid, tables, coefficients) is reported apart as its setup.
//! Each case is repeated and the median reported. Peak memory is the process's
//! resident high-water mark (`VmHWM`, reset before each case through
//! `/proc/self/clear_refs`), so it includes the volume.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use super::{machine, sig, today, write_file, BenchError};
use crate::pipeline::render_films_of_all;
use crate::plan::RunOptions;
use crate::volume::{Limits, Volume};

/// What to run.
#[derive(Clone, Debug)]
pub struct SpeedOptions {
    /// The CI-sized run: small volumes and images, one repeat.
    pub quick: bool,
    /// Image side in pixels.
    pub size: usize,
    /// Frames of the timed turntable (at least 2).
    pub frames: usize,
    /// Repeats per case (the median is reported).
    pub repeats: usize,
    /// Thread counts to measure (1 and all, by default).
    pub threads: Vec<usize>,
    /// The real volume to include (the shipped engine CT), if found.
    pub real_volume: Option<PathBuf>,
    /// Only the cases whose mode contains this text.
    pub only: Option<String>,
}

impl SpeedOptions {
    /// The full run (`quick = false`) or the CI-sized one, with `threads` workers at
    /// most (default: every core).
    pub fn new(quick: bool, threads: Option<usize>) -> SpeedOptions {
        let all =
            threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
        let mut counts = vec![1, all];
        counts.dedup();
        SpeedOptions {
            quick,
            size: if quick { 64 } else { 512 },
            frames: if quick { 6 } else { 5 },
            repeats: if quick { 1 } else { 5 },
            threads: counts,
            real_volume: find_real_volume(),
            only: None,
        }
    }
}

/// `data/ct_engine.nrrd` in the working directory or in the source tree volcast
/// was built from.
fn find_real_volume() -> Option<PathBuf> {
    [
        PathBuf::from("data/ct_engine.nrrd"),
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/ct_engine.nrrd"),
    ]
    .into_iter()
    .find(|p| p.is_file())
}

/// One (volume, mode, threads) case.
#[derive(Clone, Debug, Serialize)]
pub struct SpeedRow {
    /// The volume.
    pub volume: String,
    /// Render mode.
    pub mode: String,
    /// Worker threads.
    pub threads: usize,
    /// Median milliseconds per frame.
    pub ms_per_frame: f64,
    /// Median milliseconds of the run's one-off work (loading excluded).
    pub setup_ms: f64,
    /// Field samples taken per second, millions.
    pub msamples_taken_per_s: f64,
    /// Samples of the march without skipping per second of frame time, millions.
    pub msamples_nominal_per_s: f64,
    /// Share of the march's samples passed over by empty-space skipping.
    pub skipped: f64,
    /// Peak resident memory of the case, MiB (the volume included).
    pub peak_mib: f64,
    /// Time per frame with one thread divided by this row's.
    pub speedup: f64,
}

/// Everything one run measured.
#[derive(Clone, Debug, Serialize)]
pub struct SpeedReport {
    /// The exact command.
    pub command: String,
    /// `nproc` and the CPU model.
    pub machine: String,
    /// The date (UTC) of the run.
    pub date: String,
    /// Image side.
    pub size: usize,
    /// Frames per timed turntable.
    pub frames: usize,
    /// Repeats per case.
    pub repeats: usize,
    /// The cases.
    pub rows: Vec<SpeedRow>,
    /// Volumes left out, and why.
    pub notes: Vec<String>,
}

/// The scene of one mode on a volume (`volume` is the `[volume]` table's body).
fn scene_text(volume: &str, mode: &str, size: usize, frames: usize) -> String {
    let pass = match mode {
        "lmip" => "mode = \"lmip\"\nthreshold = 0.5\n".to_string(),
        "depth" => "mode = \"depth\"\nthreshold = 0.3\n".to_string(),
        "surface" => "mode = \"surface\"\niso = 0.5\nmaterial = \"gold\"\n".to_string(),
        "composite" => "mode = \"composite\"\ntransfer = \"ramp\"\n".to_string(),
        m => format!("mode = \"{m}\"\n"),
    };
    format!(
        "[volume]\n{volume}\n\
         [camera]\nprojection = \"orthographic\"\nazimuth = 20\nelevation = 15\n\
         [orbit]\nframes = {frames}\n\
         [image]\nsize = [{size}, {size}]\nformat = \"nrrd\"\n\
         [transfer.ramp]\ncolor = [[0.0, [0.0, 0.0, 0.0]], [1.0, [1.0, 1.0, 1.0]]]\n\
         alpha = [[0.0, 0.0], [0.1, 0.0], [1.0, 0.2]]\n\
         [[render]]\n{pass}step = 0.5\n"
    )
}

/// The label of a case of several volumes.
fn blend_label(what: &str) -> String {
    match what {
        "second" => "composite (gaussian alone)",
        "blend" => "composite of 2 volumes",
        "dense" => "composite (dense transfer function)",
        _ => "composite of 2, overlapping",
    }
    .into()
}

/// A composite case of several volumes on the synthetic field `table` (the
/// `[volume]` body of the blobs): `second`, a Gaussian of the same size alone;
/// `blend`, the blobs and the Gaussian blended; `dense`, the blobs alone through
/// an opaque-ish transfer function that is nowhere transparent; `overlap`, the
/// blobs blended with themselves through it (every sample of both contributes:
/// the worst case, against `dense`).
fn blend_text(table: &str, what: &str, opts: &SpeedOptions) -> String {
    let gaussian = table.replace(
        "synthetic = \"blobs\"",
        "synthetic = \"gaussian\"\nsigma = 0.3",
    );
    let (volumes, pass) = match what {
        "second" => (
            format!("[[volume]]\nname = \"g\"\n{gaussian}\n"),
            "transfer = \"hot\"\n".to_string(),
        ),
        "dense" => (
            format!("[[volume]]\nname = \"b\"\n{table}\n"),
            "transfer = \"dense\"\n".to_string(),
        ),
        "blend" => (
            format!("[[volume]]\nname = \"b\"\n{table}\n[[volume]]\nname = \"g\"\n{gaussian}\n"),
            "volumes = [\"b\", \"g\"]\ntransfer = { b = \"ramp\", g = \"hot\" }\n".to_string(),
        ),
        _ => (
            format!("[[volume]]\nname = \"b\"\n{table}\n[[volume]]\nname = \"c\"\n{table}\n"),
            "volumes = [\"b\", \"c\"]\ntransfer = { b = \"dense\", c = \"dense\" }\n".to_string(),
        ),
    };
    format!(
        "{volumes}\
         [camera]\nprojection = \"orthographic\"\nazimuth = 20\nelevation = 15\n\
         [orbit]\nframes = {}\n\
         [image]\nsize = [{s}, {s}]\nformat = \"nrrd\"\n\
         [transfer.ramp]\ncolor = [[0.0, [0.0, 0.0, 0.0]], [1.0, [1.0, 1.0, 1.0]]]\n\
         alpha = [[0.0, 0.0], [0.1, 0.0], [1.0, 0.2]]\n\
         [transfer.hot]\ncolor = [[0.0, [1.0, 0.5, 0.0]]]\nalpha = [[0.0, 0.0], [0.6, 0.0], [1.0, 0.3]]\n\
         [transfer.dense]\ncolor = [[0.0, [0.5, 0.5, 1.0]]]\nalpha = [[0.0, 0.02], [1.0, 0.3]]\n\
         [[render]]\nmode = \"composite\"\n{pass}step = 0.5\n",
        opts.frames,
        s = opts.size
    )
}

/// Runs the speed bench; `progress(line)` reports each case as it ends.
pub fn speed(
    opts: &SpeedOptions,
    command: &str,
    progress: &mut dyn FnMut(&str),
) -> Result<SpeedReport, BenchError> {
    let mut volumes: Vec<(String, String)> = Vec::new();
    let mut notes = Vec::new();
    match &opts.real_volume {
        Some(p) => volumes.push((
            "ct_engine (256x256x110 uint8)".into(),
            format!("path = {:?}", p.display().to_string()),
        )),
        None => notes.push(
            "data/ct_engine.nrrd not found (run from the project folder): real volume skipped"
                .into(),
        ),
    }
    let sides: &[usize] = if opts.quick { &[64] } else { &[256, 512] };
    for &n in sides {
        volumes.push((
            format!("blobs {n}^3 uint8"),
            format!("synthetic = \"blobs\"\nsizes = [{n}, {n}, {n}]\ntype = \"uint8\""),
        ));
    }
    let mut rows = Vec::new();
    for (name, table) in &volumes {
        // one load per volume: every mode and thread count renders the same voxels
        let first = crate::scene::parse(
            &scene_text(table, "mip", opts.size, opts.frames),
            Path::new("speed.toml"),
        )?;
        let volume = first.volume().source.load(&Limits::default())?;
        let mut cases: Vec<(String, String, Vec<&Volume>)> = crate::mode::names()
            .map(|mode| {
                let text = scene_text(table, mode, opts.size, opts.frames);
                (mode.to_string(), text, vec![&volume])
            })
            .collect();
        // several volumes, on the synthetic field: a second volume alone, the two
        // blended, and the field blended with itself (fully overlapping)
        let second = match name.strip_prefix("blobs ") {
            Some(_) => Some(
                crate::scene::parse(&blend_text(table, "second", opts), Path::new("speed.toml"))?
                    .volumes[0]
                    .spec
                    .source
                    .load(&Limits::default())?,
            ),
            None => None,
        };
        if let Some(second) = &second {
            for what in ["second", "blend", "dense", "overlap"] {
                let volumes = match what {
                    "second" => vec![second],
                    "dense" => vec![&volume],
                    "blend" => vec![&volume, second],
                    _ => vec![&volume, &volume],
                };
                cases.push((blend_label(what), blend_text(table, what, opts), volumes));
            }
        }
        cases.retain(|(mode, _, _)| opts.only.as_ref().is_none_or(|o| mode.contains(o.as_str())));
        for (mode, text, vols) in &cases {
            let mode = mode.as_str();
            let cases = case(opts, name, mode, text, vols)?;
            let base = cases[0].ms_per_frame;
            for row in cases {
                let row = SpeedRow {
                    speedup: base / row.ms_per_frame,
                    ..row
                };
                progress(&format!(
                    "{name} {mode} {} thread(s): {} ms/frame, {} M samples/s",
                    row.threads,
                    sig(row.ms_per_frame),
                    sig(row.msamples_taken_per_s)
                ));
                rows.push(row);
            }
        }
    }
    Ok(SpeedReport {
        command: command.to_string(),
        machine: machine(),
        date: today(),
        size: opts.size,
        frames: opts.frames,
        repeats: opts.repeats,
        rows,
        notes,
    })
}

/// One (volume, mode): for each thread count of `opts.threads`, the median over
/// repeats of T(1 frame) and T(F frames). The thread counts take turns within each
/// repeat (interleaved), so that a slow moment of a shared machine falls on all of
/// them rather than on one. Peak memory is the case's, over all thread counts.
fn case(
    opts: &SpeedOptions,
    name: &str,
    mode: &str,
    text: &str,
    volumes: &[&Volume],
) -> Result<Vec<SpeedRow>, BenchError> {
    let scene = crate::scene::parse(text, Path::new("speed.toml"))?;
    let pools = opts
        .threads
        .iter()
        .map(|&threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|e| BenchError::Plot(format!("starting {threads} worker threads: {e}")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let run = |t: usize, frames: usize| -> Result<(f64, u64, u64), BenchError> {
        let opts = RunOptions {
            frames: Some(0..frames),
            threads: Some(opts.threads[t]),
            ..RunOptions::default()
        };
        let t0 = Instant::now();
        let (_, summary) = pools[t].install(|| render_films_of_all(&scene, volumes, &opts))?;
        Ok((
            t0.elapsed().as_secs_f64(),
            summary.samples,
            summary.nominal_samples,
        ))
    };
    reset_peak_memory();
    let n = opts.threads.len();
    let (mut per_frame, mut setup) = (vec![Vec::new(); n], vec![Vec::new(); n]);
    let (mut taken, mut nominal) = (vec![0; n], vec![0; n]);
    for _ in 0..opts.repeats.max(1) {
        for t in 0..n {
            let (t1, s1, n1) = run(t, 1)?;
            let (tf, sf, nf) = run(t, opts.frames)?;
            // a run of F frames faster than one of 1 (noise, at tiny sizes) has no
            // measurable frame time: NaN, shown as such
            let frame = if tf > t1 {
                (tf - t1) / (opts.frames - 1) as f64
            } else {
                f64::NAN
            };
            per_frame[t].push(frame);
            setup[t].push((t1 - frame).max(0.0));
            taken[t] = sf - s1;
            nominal[t] = nf - n1;
        }
    }
    let peak = peak_memory().unwrap_or(f64::NAN);
    Ok((0..n)
        .map(|t| {
            let frame = median(&mut per_frame[t]);
            let frame_time = frame * (opts.frames - 1) as f64;
            SpeedRow {
                volume: name.to_string(),
                mode: mode.to_string(),
                threads: opts.threads[t],
                ms_per_frame: frame * 1e3,
                setup_ms: median(&mut setup[t]) * 1e3,
                msamples_taken_per_s: taken[t] as f64 / frame_time / 1e6,
                msamples_nominal_per_s: nominal[t] as f64 / frame_time / 1e6,
                skipped: if nominal[t] > 0 {
                    1.0 - taken[t] as f64 / nominal[t] as f64
                } else {
                    0.0
                },
                peak_mib: peak,
                speedup: 1.0,
            }
        })
        .collect())
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Resets the process's resident high-water mark (Linux; elsewhere nothing).
fn reset_peak_memory() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// The process's resident high-water mark in MiB (Linux), `None` elsewhere.
fn peak_memory() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

impl SpeedReport {
    /// The Markdown table (what the command prints and the README keeps).
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "`{}` on {}, {}: {} x {} images, orthographic turntable (azimuth 20, elevation 15), step 0.5 voxel, trilinear; ms per frame = (T({}) - T(1)) / {}, median of {} runs (the thread counts interleaved); peak memory over the case's thread counts.\n",
            self.command,
            self.machine,
            self.date,
            self.size,
            self.size,
            self.frames,
            self.frames - 1,
            self.repeats
        );
        s.push_str("| volume | mode | threads | ms per frame | setup ms | M samples/s taken | M samples/s nominal | skipped | peak MiB | speed-up |\n");
        s.push_str("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
        for r in &self.rows {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {:.0}% | {:.0} | {:.2} |",
                r.volume,
                r.mode,
                r.threads,
                sig(r.ms_per_frame),
                sig(r.setup_ms),
                sig(r.msamples_taken_per_s),
                sig(r.msamples_nominal_per_s),
                100.0 * r.skipped,
                r.peak_mib,
                r.speedup
            );
        }
        for n in &self.notes {
            let _ = writeln!(s, "\nNote: {n}");
        }
        s
    }

    /// The cases as CSV.
    pub fn csv(&self) -> String {
        let mut s = String::from("volume,mode,threads,ms_per_frame,setup_ms,msamples_taken_per_s,msamples_nominal_per_s,skipped,peak_mib,speedup\n");
        for r in &self.rows {
            let _ = writeln!(
                s,
                "{},{},{},{:.3},{:.3},{:.3},{:.3},{:.4},{:.1},{:.3}",
                r.volume,
                r.mode,
                r.threads,
                r.ms_per_frame,
                r.setup_ms,
                r.msamples_taken_per_s,
                r.msamples_nominal_per_s,
                r.skipped,
                r.peak_mib,
                r.speedup
            );
        }
        s
    }

    /// Writes `speed.md`, `speed.csv` and `speed.json` into `dir`.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>, BenchError> {
        let json =
            serde_json::to_string_pretty(self).map_err(|e| BenchError::Plot(e.to_string()))?;
        let files = [
            (dir.join("speed.md"), self.markdown().into_bytes()),
            (dir.join("speed.csv"), self.csv().into_bytes()),
            (dir.join("speed.json"), json.into_bytes()),
        ];
        for (p, b) in &files {
            write_file(p, b)?;
        }
        Ok(files.into_iter().map(|(p, _)| p).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_blend_scene_resolves() {
        let opts = SpeedOptions::new(true, Some(1));
        let table = "synthetic = \"blobs\"\nsizes = [8, 8, 8]\ntype = \"uint8\"";
        for what in ["second", "blend", "overlap"] {
            let s = crate::scene::parse(&blend_text(table, what, &opts), Path::new("s.toml"))
                .unwrap_or_else(|e| panic!("{what}: {e}"));
            assert_eq!(
                s.passes[0].volumes.len(),
                if what == "second" { 1 } else { 2 }
            );
        }
    }

    #[test]
    fn every_mode_scene_resolves() {
        for m in crate::mode::names() {
            let text = scene_text("synthetic = \"blobs\"\ntype = \"uint8\"", m, 8, 2);
            crate::scene::parse(&text, Path::new("s.toml")).expect(m);
        }
    }

    #[test]
    fn dates_are_civil() {
        let d = today();
        assert_eq!(d.len(), 10);
        assert!(d.starts_with("20"), "{d}");
    }

    #[test]
    fn median_of_even_and_odd() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), 2.5);
    }
}
