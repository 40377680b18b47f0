//! `volcast bench accuracy`: speed against error, measured (issue 4); `volcast bench
//! speed` (`speed.rs`): whole frames of every mode, with and without threads.
//!
//! Every render mode is rendered on the analytic fields of docs/formulas.md through the
//! real pipeline, over steps, interpolations, gradient estimators and integration
//! methods (`accuracy.rs`), and compared with the closed-form answers (`truth.rs`).
//! The results are a [`Report`]: rows of time per frame, samples per second and
//! max / RMS error, plus the Marschner-Lobb reconstruction error and the normals'
//! angular error. [`Report::write`] writes them as CSV, JSON, a Markdown page and a
//! speed-against-error plot (`plot.rs`). Nothing here prints: the CLI does.

mod accuracy;
mod plot;
mod speed;
mod truth;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use accuracy::{GRID, STEPS};
pub use speed::{speed, SpeedOptions, SpeedReport, SpeedRow};

/// Errors of a bench run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BenchError {
    /// A case's scene did not resolve (a bug in the bench's scene text).
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    /// A case did not render.
    #[error(transparent)]
    Render(#[from] crate::Error),
    /// A synthetic volume could not be built.
    #[error(transparent)]
    Volume(#[from] crate::volume::VolumeError),
    /// An output file could not be written.
    #[error("writing {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// The plot could not be drawn or encoded.
    #[error("drawing the plot: {0}")]
    Plot(String),
}

/// What to run.
#[derive(Clone, Debug)]
pub struct Options {
    /// The CI-sized run: two fields, two steps, two interpolations, tiny images.
    pub quick: bool,
    /// Image side in pixels.
    pub size: usize,
    /// Views per case (quarter turns about z, which see the same picture).
    pub frames: usize,
    /// Timed renders per case (the median is reported).
    pub repeats: usize,
    /// Random points of the reconstruction and normal measurements.
    pub points: usize,
}

impl Options {
    /// The full run (`quick = false`) or the CI-sized one.
    pub fn new(quick: bool) -> Options {
        if quick {
            Options {
                quick,
                size: 12,
                frames: 1,
                repeats: 1,
                points: 5_000,
            }
        } else {
            Options {
                quick,
                size: 48,
                frames: 2,
                repeats: 3,
                points: 1_000_000,
            }
        }
    }
}

/// One rendered configuration and its measured speed and error.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Row {
    /// Analytic field.
    pub field: String,
    /// Render mode.
    pub mode: String,
    /// `sampled`, `exact`, `jitter` or `preintegrated`; for composites also
    /// `early 0.995` and `early 0.99`: sampled, stopped once the opacity reaches that
    /// value (the others run to the end of the ray).
    pub method: String,
    /// Reconstruction filter.
    pub interpolation: String,
    /// Gradient estimator (shaded modes).
    pub gradient: Option<String>,
    /// Transfer function (composite).
    pub transfer: Option<String>,
    /// Step in voxels (`None` for exact integration, which has none).
    pub step_voxels: Option<f64>,
    /// Median wall time of one view, including the run's setup (volume synthesis,
    /// precomputed tables), in milliseconds.
    pub ms_per_frame: f64,
    /// Field samples (cells for exact passes) per second, in millions.
    pub msamples_per_s: f64,
    /// Largest pixel error.
    pub max_error: f64,
    /// Root-mean-square pixel error.
    pub rms_error: f64,
    /// Pixels compared (over all views).
    pub pixels: usize,
}

/// Reconstruction error of one filter on Marschner-Lobb 41^3.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ReconstructionRow {
    /// Reconstruction filter.
    pub interpolation: String,
    /// `cube` ([-1, 1]^3) or `interior` ([-0.9, 0.9]^3).
    pub region: String,
    /// Random points.
    pub points: usize,
    /// Largest error.
    pub max_error: f64,
    /// RMS error.
    pub rms_error: f64,
}

/// Angular error of one normal estimator on a sphere.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct NormalRow {
    /// Interpolation + gradient estimator.
    pub estimator: String,
    /// Random points.
    pub points: usize,
    /// Mean angle, degrees.
    pub mean_deg: f64,
    /// Largest angle, degrees.
    pub max_deg: f64,
}

/// Everything one run measured.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Report {
    /// The exact command.
    pub command: String,
    /// `nproc` and the CPU model.
    pub machine: String,
    /// The date (UTC) of the run.
    #[serde(default)]
    pub date: String,
    /// Worker threads used.
    pub threads: usize,
    /// Image side, views per case, timed repeats.
    pub size: usize,
    /// Views per case.
    pub frames: usize,
    /// Timed repeats per case.
    pub repeats: usize,
    /// The sweep.
    pub rows: Vec<Row>,
    /// Marschner-Lobb reconstruction.
    pub reconstruction: Vec<ReconstructionRow>,
    /// Normals on a sphere.
    pub normals: Vec<NormalRow>,
}

/// Runs the accuracy bench; `progress(done, total)` is called between cases.
pub fn accuracy(
    opts: &Options,
    command: &str,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Report, BenchError> {
    let rows = accuracy::sweep(opts, progress)?;
    Ok(Report {
        command: command.to_string(),
        machine: machine(),
        date: today(),
        threads: rayon::current_num_threads(),
        size: opts.size,
        frames: opts.frames,
        repeats: opts.repeats,
        rows,
        reconstruction: accuracy::reconstruction(opts.points)?,
        normals: accuracy::normals(opts.points.min(100_000))?,
    })
}

/// Today's date (UTC) as YYYY-MM-DD, from the system clock.
pub(crate) fn today() -> String {
    let days = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() / 86_400) as i64;
    // civil from days (Howard Hinnant's algorithm)
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

/// `nproc` and the CPU model from /proc/cpuinfo (where readable).
fn machine() -> String {
    let cpus = std::thread::available_parallelism().map_or(0, |n| n.get());
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, m)| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    format!("{cpus} CPUs (nproc), {model}")
}

/// Checks, before a bench spends minutes measuring, that its files can be written
/// into `dir` (and its `subfolders`): creates the folders and a probe file there,
/// and removes the probe. On failure the folders it created are removed again.
pub fn check_writable(dir: &Path, subfolders: &[&str]) -> Result<(), BenchError> {
    let mut created = Vec::new();
    let mut result = Ok(());
    for d in std::iter::once(dir.to_path_buf()).chain(subfolders.iter().map(|s| dir.join(s))) {
        let mut missing: Vec<PathBuf> = d
            .ancestors()
            .take_while(|a| !a.as_os_str().is_empty() && !a.exists())
            .map(Path::to_path_buf)
            .collect();
        missing.reverse();
        let probe = d.join(format!(".volcast-bench-probe-{}", std::process::id()));
        let step = std::fs::create_dir_all(&d)
            .map_err(|source| BenchError::Write {
                path: d.clone(),
                source,
            })
            .and_then(|()| {
                created.extend(missing);
                std::fs::OpenOptions::new()
                    .write(true)
                    .create_new(true)
                    .open(&probe)
                    .map_err(|source| BenchError::Write {
                        path: d.clone(),
                        source,
                    })
            });
        match step {
            Ok(_) => {
                let _ = std::fs::remove_file(&probe);
            }
            Err(e) => {
                result = Err(e);
                break;
            }
        }
    }
    if result.is_err() {
        for d in created.iter().rev() {
            let _ = std::fs::remove_dir(d);
        }
    }
    result
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), BenchError> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|source| BenchError::Write {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    crate::output::write_atomic(path, bytes).map_err(|source| BenchError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// A number with 3 significant digits, in a fixed notation for tables.
fn sig(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if !x.is_finite() {
        format!("{x}")
    } else if (1e-3..1e4).contains(&x.abs()) {
        let digits = (2 - x.abs().log10().floor() as i32).max(0) as usize;
        format!("{x:.digits$}")
    } else {
        format!("{x:.2e}")
    }
}

impl Report {
    /// Writes `accuracy.csv`, `accuracy.json`, `accuracy.md` and
    /// `images/accuracy.png` into `dir`; returns the files written.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>, BenchError> {
        let files = [
            (dir.join("accuracy.csv"), self.csv().into_bytes()),
            (
                dir.join("accuracy.json"),
                serde_json::to_string_pretty(self)
                    .map_err(|e| BenchError::Plot(e.to_string()))?
                    .into_bytes(),
            ),
            (dir.join("accuracy.md"), self.markdown().into_bytes()),
            (dir.join("images/accuracy.png"), plot::speed_vs_error(self)?),
        ];
        for (p, b) in &files {
            write_file(p, b)?;
        }
        Ok(files.into_iter().map(|(p, _)| p).collect())
    }

    /// The speed-against-error plot (`images/accuracy.png`) as PNG bytes; a report
    /// read back from its `accuracy.json` draws the plot of that run.
    pub fn plot(&self) -> Result<Vec<u8>, BenchError> {
        plot::speed_vs_error(self)
    }

    /// The sweep as CSV (one row per case).
    pub fn csv(&self) -> String {
        let mut s = String::from("field,mode,method,interpolation,gradient,transfer,step_voxels,ms_per_frame,msamples_per_s,max_error,rms_error,pixels\n");
        for r in &self.rows {
            let _ = writeln!(
                s,
                "{},{},{},{},{},{},{},{:.4},{:.3},{:.6e},{:.6e},{}",
                r.field,
                r.mode,
                r.method,
                r.interpolation,
                r.gradient.as_deref().unwrap_or(""),
                r.transfer.as_deref().unwrap_or(""),
                r.step_voxels.map_or(String::new(), |x| x.to_string()),
                r.ms_per_frame,
                r.msamples_per_s,
                r.max_error,
                r.rms_error,
                r.pixels
            );
        }
        s
    }

    fn find(
        &self,
        field: &str,
        mode: &str,
        method: &str,
        interp: &str,
        step: Option<f64>,
    ) -> Option<&Row> {
        self.rows.iter().find(|r| {
            r.field == field
                && r.mode == mode
                && r.method == method
                && r.interpolation == interp
                && r.step_voxels == step
                && r.gradient.as_deref().is_none_or(|g| g == "central")
        })
    }

    /// The summary tables (what the README and docs/accuracy.md show).
    pub fn summary(&self) -> String {
        let mut s = String::new();
        let steps: Vec<f64> = {
            let mut v: Vec<f64> = self.rows.iter().filter_map(|r| r.step_voxels).collect();
            v.sort_by(|a, b| b.total_cmp(a));
            v.dedup();
            v
        };
        let fields: Vec<&str> = {
            let mut v: Vec<&str> = self.rows.iter().map(|r| r.field.as_str()).collect();
            v.dedup();
            v.sort();
            v.dedup();
            v
        };
        // the filters and surfaces at a mid step
        let mid = if steps.contains(&0.5) {
            0.5
        } else {
            steps.last().copied().unwrap_or(1.0)
        };
        self.sampled_table(&mut s, &fields, &steps);
        self.filters_table(&mut s, &fields, mid);
        self.surfaces_table(&mut s, &fields, mid);
        let tables = [
            ("**Compositing** (transfer functions `ramp` and the narrow peak `narrow`): RMS error of premultiplied colour and opacity, sampled / jittered / pre-integrated.", ["sampled", "jitter", "preintegrated"]),
            ("**Early termination** (compositing, sampled trilinear): RMS error of premultiplied colour and opacity with `early_stop` 1.0 (no early stop) / 0.995 / 0.99.", ["sampled", "early 0.995", "early 0.99"]),
        ];
        for (heading, methods) in tables {
            let _ = writeln!(s, "\n{heading}\n");
            self.composite_table(&mut s, &fields, &steps, methods);
        }
        self.reconstruction_table(&mut s);
        self.normals_table(&mut s);
        s
    }

    /// Sampled trilinear passes over the steps against exact integration.
    fn sampled_table(&self, s: &mut String, fields: &[&str], steps: &[f64]) {
        let _ = writeln!(s, "**Sampled (trilinear) against exact integration**: RMS error, and in brackets ms per view. Exact has no step; its error is the reconstruction's alone.\n");
        let mut head = String::from("| field | mode |");
        let mut rule = String::from("| --- | --- |");
        for st in steps {
            let _ = write!(head, " step {st} |");
            rule += " --- |";
        }
        head += " exact |";
        rule += " --- |";
        let _ = writeln!(s, "{head}\n{rule}");
        for f in fields {
            for mode in [
                "xray", "mip", "minip", "average", "lmip", "depth", "surface",
            ] {
                if self
                    .find(f, mode, "sampled", "trilinear", steps.first().copied())
                    .is_none()
                {
                    continue;
                }
                let _ = write!(s, "| {f} | {mode} |");
                for st in steps {
                    let cell = self
                        .find(f, mode, "sampled", "trilinear", Some(*st))
                        .map_or("".into(), |r| {
                            format!("{} ({})", sig(r.rms_error), sig(r.ms_per_frame))
                        });
                    let _ = write!(s, " {cell} |");
                }
                let cell = self
                    .find(f, mode, "exact", "trilinear", None)
                    .map_or("-".into(), |r| {
                        format!("{} ({})", sig(r.rms_error), sig(r.ms_per_frame))
                    });
                let _ = writeln!(s, " {cell} |");
            }
        }
    }

    /// The interpolation filters' sampled passes at step `mid`.
    fn filters_table(&self, s: &mut String, fields: &[&str], mid: f64) {
        let interps = ["nearest", "trilinear", "bspline", "cubic"];
        let _ = writeln!(
            s,
            "\n**Reconstruction filters** at step {mid}: RMS error (ms per view).\n"
        );
        let _ = writeln!(
            s,
            "| field | mode | {} |\n| --- | --- |{}",
            interps.join(" | "),
            " --- |".repeat(interps.len())
        );
        for f in fields {
            for mode in ["xray", "mip", "minip", "average", "lmip", "depth"] {
                let cells: Vec<String> = interps
                    .iter()
                    .map(|i| {
                        self.find(f, mode, "sampled", i, Some(mid))
                            .map_or("-".into(), |r| {
                                format!("{} ({})", sig(r.rms_error), sig(r.ms_per_frame))
                            })
                    })
                    .collect();
                if cells.iter().all(|c| c == "-") {
                    continue;
                }
                let _ = writeln!(s, "| {f} | {mode} | {} |", cells.join(" | "));
            }
        }
    }

    /// Shaded iso-surfaces by interpolation and gradient estimator at step `mid`.
    fn surfaces_table(&self, s: &mut String, fields: &[&str], mid: f64) {
        let mut combos: Vec<(String, String)> = self
            .rows
            .iter()
            .filter(|r| r.mode == "surface" && r.method == "sampled")
            .map(|r| {
                (
                    r.interpolation.clone(),
                    r.gradient.clone().unwrap_or_default(),
                )
            })
            .collect();
        combos.dedup();
        combos.sort();
        combos.dedup();
        let _ = writeln!(s, "\n**Shaded iso-surfaces** (`n . v` of a matte surface) by interpolation and gradient estimator at step {mid}: RMS error.\n");
        let _ = writeln!(
            s,
            "| field | {} |\n| --- |{}",
            combos
                .iter()
                .map(|(i, g)| format!("{i} + {g}"))
                .collect::<Vec<_>>()
                .join(" | "),
            " --- |".repeat(combos.len())
        );
        for f in fields {
            let cells: Vec<String> = combos
                .iter()
                .map(|(i, g)| {
                    self.rows
                        .iter()
                        .find(|r| {
                            r.field == *f
                                && r.mode == "surface"
                                && r.method == "sampled"
                                && r.interpolation == *i
                                && r.gradient.as_deref() == Some(g.as_str())
                                && r.step_voxels == Some(mid)
                        })
                        .map_or("-".into(), |r| sig(r.rms_error))
                })
                .collect();
            if cells.iter().any(|c| c != "-") {
                let _ = writeln!(s, "| {f} | {} |", cells.join(" | "));
            }
        }
    }

    /// The Marschner-Lobb reconstruction errors.
    fn reconstruction_table(&self, s: &mut String) {
        let _ = writeln!(s, "\n**Reconstruction of Marschner-Lobb 41^3** (error of the reconstructed field against the analytic signal at {} uniform random points, fixed seed):\n", self.reconstruction.first().map_or(0, |r| r.points));
        let _ = writeln!(s, "| interpolation | max, [-1,1]^3 | RMS, [-1,1]^3 | max, [-0.9,0.9]^3 | RMS, [-0.9,0.9]^3 |\n| --- | --- | --- | --- | --- |");
        for pair in self.reconstruction.chunks(2) {
            if let [a, b] = pair {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {} |",
                    a.interpolation,
                    sig(a.max_error),
                    sig(a.rms_error),
                    sig(b.max_error),
                    sig(b.rms_error)
                );
            }
        }
    }

    /// The normals' angles on a sphere.
    fn normals_table(&self, s: &mut String) {
        let _ = writeln!(s, "\n**Normals on a sphere** (iso-surface f = 0.5 of the sphere-distance field, radius 11 voxels; angle to the radial normal at {} uniform points):\n", self.normals.first().map_or(0, |r| r.points));
        let _ = writeln!(
            s,
            "| estimator | mean (deg) | max (deg) |\n| --- | --- | --- |"
        );
        for n in &self.normals {
            let _ = writeln!(
                s,
                "| {} | {} | {} |",
                n.estimator,
                sig(n.mean_deg),
                sig(n.max_deg)
            );
        }
    }

    /// A table of the trilinear composites' RMS errors: a row per field and transfer
    /// function, a column per step, and in each cell the three methods' errors.
    fn composite_table(&self, s: &mut String, fields: &[&str], steps: &[f64], methods: [&str; 3]) {
        let mut head = String::from("| field | transfer |");
        let mut rule = String::from("| --- | --- |");
        for st in steps {
            let _ = write!(head, " step {st} |");
            rule += " --- |";
        }
        let _ = writeln!(s, "{head}\n{rule}");
        for f in fields {
            for tf in ["ramp", "narrow"] {
                let _ = write!(s, "| {f} | {tf} |");
                for st in steps {
                    let get = |m: &str| {
                        self.rows
                            .iter()
                            .find(|r| {
                                r.field == *f
                                    && r.mode == "composite"
                                    && r.method == m
                                    && r.interpolation == "trilinear"
                                    && r.step_voxels == Some(*st)
                                    && r.transfer.as_deref() == Some(tf)
                            })
                            .map_or("-".into(), |r| sig(r.rms_error))
                    };
                    let [a, b, c] = methods.map(get);
                    let _ = write!(s, " {a} / {b} / {c} |");
                }
                let _ = writeln!(s);
            }
        }
    }

    /// The Markdown page: machine, command, summary tables, methods.
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "# Accuracy: speed against error\n");
        let _ = writeln!(s, "Generated by `{}` (every number below comes from that command; the full sweep is in `accuracy.csv` / `accuracy.json` beside this file).\n", self.command);
        let _ = writeln!(s, "Machine: {}, {}; {} worker threads. Images {}x{} pixels, {} view(s) per case, median of {} timed run(s). Times are wall-clock per view and include each run's setup (synthesising the 41^3 volume, prefiltering, tables), so they are upper bounds on the marching cost.\n", self.machine, self.date, self.threads, self.size, self.size, self.frames, self.repeats);
        let _ = writeln!(s, "![speed against error](images/accuracy.png)\n");
        s += &self.summary();
        s += METHODS;
        s
    }
}

/// How the numbers are measured (the fixed part of the page).
const METHODS: &str = "
## How it is measured

- **Fields** (docs/formulas.md \"Analytic references\"), each sampled on a 41^3 grid over [-1, 1]^3
  (one voxel = 0.05): `gaussian` (sigma 0.25), `ball` (radius 0.5, values 0/1), `sphere`
  (distance field 1 - |x|), `fog` (a ball of radius 3: the value 1 everywhere) and
  `marschner-lobb`.
- **Views**: orthographic along +y (and along -x, which sees the same picture by symmetry);
  pixels whose rays cross the box are compared with the closed-form answer along the same
  line (`crates/volcast-render/src/bench/truth.rs`): chords and radial normals where closed forms exist, otherwise
  f64 numerics on the analytic function (Simpson with 20 000 intervals, dense scans refined
  by bisection or ternary search, compositing over 20 000 steps with exact opacities).
- **Errors** are per pixel: absolute for grey modes (`depth` in world units; a pixel that
  hits where the truth misses, or the reverse, counts 1.0), the shade `n . v` of a matte
  surface under a headlight for `surface` (pixels seen at grazing angles, `n . v < 0.2`, are
  left out: there the answer is ill-conditioned), and the largest error of premultiplied
  colour and opacity for `composite`. The error includes the reconstruction's, so at fine
  steps every method meets the floor of its interpolation.
- **Methods**: `sampled` marches at the step; `exact` walks the cells and integrates the
  trilinear interpolant in closed form (`integration = \"exact\"`); `jitter` offsets each
  ray's samples by a per-pixel fraction of the step; `preintegrated` looks segments up in the
  pre-integrated transfer function table (Engel et al. 2001).
- **Early termination** (`early_stop = e`, default 0.99): once the accumulated opacity
  reaches `e`, the remaining samples could add at most `1 - e` to any premultiplied channel
  or to the opacity, so a pixel changes by at most `1 - e` (tested in
  `tests/analytic.rs::early_termination_changes_a_pixel_by_at_most_one_minus_e`). The bench
  uses `early_stop = 1.0`, except in its early-termination table, which shows what the
  default 0.99 and a later 0.995 add to the error at each step. Empty-space skipping is on, as
  in every render: it changes no pixel's bits (`tests/skipping.rs` renders every mode with and
  without it), so it costs nothing in error.
";
