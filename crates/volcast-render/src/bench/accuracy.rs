//! The sweep of `volcast bench accuracy`: every render mode on the analytic fields,
//! over steps, interpolations, gradient estimators and integration methods, each
//! case rendered through the real pipeline ([`render_films`]) from scene text and
//! compared pixel by pixel with [`super::truth`]; plus the reconstruction error on
//! Marschner-Lobb and the angular error of normals on a sphere, measured on the
//! real [`Sampler`].

use std::collections::HashMap;
use std::path::Path;
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::truth::{answer, pixel_line, Answer, Quantity, AZIMUTH_DEG, ELEVATION_DEG};
use super::{BenchError, NormalRow, Options, ReconstructionRow, Row};
use crate::pipeline::render_films;
use crate::plan::RunOptions;
use crate::sample::{
    prefilter_cubic, Field as _, GradientMethod, Interpolation, Normalize, Sampler,
};
use crate::transfer::{Interpolation as TfInterpolation, Transfer1D};
use crate::volume::synthetic::Field;
use crate::volume::{Limits, Synthetic, VolumeData};

/// Voxels per axis of every bench volume (the classic Marschner-Lobb grid).
pub const GRID: usize = 41;
/// Steps swept, in voxels.
pub const STEPS: [f64; 5] = [2.0, 1.0, 0.5, 0.25, 0.125];

/// One analytic field: its scene-file snippet and its definition.
struct FieldCase {
    name: &'static str,
    toml: &'static str,
    field: Field,
}

fn fields(quick: bool) -> Vec<FieldCase> {
    let all = vec![
        FieldCase {
            name: "gaussian",
            toml: "synthetic = \"gaussian\"\nsigma = 0.25",
            field: Field::Gaussian { sigma: 0.25 },
        },
        FieldCase {
            name: "ball",
            toml: "synthetic = \"ball\"\nradius = 0.5",
            field: Field::Ball { radius: 0.5 },
        },
        FieldCase {
            name: "sphere",
            toml: "synthetic = \"sphere-distance\"\nradius = 1.0",
            field: Field::SphereDistance { radius: 1.0 },
        },
        FieldCase {
            name: "fog",
            toml: "synthetic = \"ball\"\nradius = 3.0",
            field: Field::Ball { radius: 3.0 },
        },
        FieldCase {
            name: "marschner-lobb",
            toml: "synthetic = \"marschner-lobb\"",
            field: Field::MarschnerLobb,
        },
    ];
    if quick {
        all.into_iter()
            .filter(|f| matches!(f.name, "gaussian" | "sphere"))
            .collect()
    } else {
        all
    }
}

/// The transfer functions of the composite cases: a smooth ramp, and a narrow
/// peak (a tent of half-width 0.02 at 0.5) that sampling misses at coarse steps.
const TRANSFERS: [(&str, &str); 2] = [
    (
        "ramp",
        "color = [[0.0, [0.1, 0.2, 0.9]], [1.0, [1.0, 0.9, 0.2]]]\nalpha = [[0.0, 0.0], [1.0, 0.3]]",
    ),
    (
        "narrow",
        "color = [[0.0, [1.0, 0.3, 0.1]], [1.0, [0.2, 0.5, 1.0]]]\nalpha = [[0.0, 0.0], [0.48, 0.0], [0.5, 0.8], [0.52, 0.0], [1.0, 0.0]]",
    ),
];

fn transfer(name: &str) -> Transfer1D {
    // the knots of TRANSFERS, for the truth (which evaluates them directly)
    let (color, alpha) = if name == "ramp" {
        (
            vec![(0.0, [0.1, 0.2, 0.9]), (1.0, [1.0, 0.9, 0.2])],
            vec![(0.0, 0.0), (1.0, 0.3)],
        )
    } else {
        (
            vec![(0.0, [1.0, 0.3, 0.1]), (1.0, [0.2, 0.5, 1.0])],
            vec![(0.0, 0.0), (0.48, 0.0), (0.5, 0.8), (0.52, 0.0), (1.0, 0.0)],
        )
    };
    Transfer1D::new(color, alpha, TfInterpolation::Linear)
        .expect("bench transfer functions are valid")
}

/// One rendered configuration.
#[derive(Clone, Debug)]
struct Case {
    field: usize,
    mode: &'static str,
    /// Mode keys for the scene file.
    keys: String,
    /// Key of the truth this case is compared with.
    truth: String,
    method: &'static str,
    interpolation: Interpolation,
    gradient: Option<GradientMethod>,
    step: Option<f64>,
    transfer: Option<&'static str>,
}

fn cases(opts: &Options, nfields: usize, fog: Option<usize>) -> Vec<Case> {
    let steps: &[f64] = if opts.quick { &[1.0, 0.25] } else { &STEPS };
    let interps: &[Interpolation] = if opts.quick {
        &[Interpolation::Trilinear, Interpolation::Cubic]
    } else {
        &[
            Interpolation::Nearest,
            Interpolation::Trilinear,
            Interpolation::BSpline,
            Interpolation::Cubic,
        ]
    };
    let mut out = Vec::new();
    let push =
        |out: &mut Vec<Case>, f, mode, keys: &str, truth: &str, method, interp, gradient, step| {
            out.push(Case {
                field: f,
                mode,
                keys: keys.to_string(),
                truth: truth.to_string(),
                method,
                interpolation: interp,
                gradient,
                step,
                transfer: None,
            })
        };
    for f in 0..nfields {
        let intensity: [(&str, &str, &str, bool); 6] = [
            ("xray", "mode = \"xray\"", "integral", true),
            ("mip", "mode = \"mip\"", "max", true),
            ("minip", "mode = \"minip\"", "min", true),
            ("average", "mode = \"average\"", "mean", true),
            ("lmip", "mode = \"lmip\"\nthreshold = 0.5", "lmip", false),
            ("depth", "mode = \"depth\"\nthreshold = 0.5", "depth", true),
        ];
        for (mode, keys, truth, exact) in intensity {
            for &interp in interps {
                for &s in steps {
                    push(
                        &mut out,
                        f,
                        mode,
                        keys,
                        truth,
                        "sampled",
                        interp,
                        None,
                        Some(s),
                    );
                }
            }
            if exact {
                let k = format!("{keys}\nintegration = \"exact\"");
                push(
                    &mut out,
                    f,
                    mode,
                    &k,
                    truth,
                    "exact",
                    Interpolation::Trilinear,
                    None,
                    None,
                );
            }
        }
        // surfaces: a matte white material under the headlight shows n . v
        if Some(f) != fog {
            let matte = "mode = \"surface\"\niso = 0.5\nmaterial = \"matte\"";
            let grads: &[(Interpolation, GradientMethod)] = if opts.quick {
                &[
                    (Interpolation::Trilinear, GradientMethod::Central),
                    (Interpolation::Cubic, GradientMethod::Analytic),
                ]
            } else {
                &[
                    (Interpolation::Trilinear, GradientMethod::Central),
                    (Interpolation::Trilinear, GradientMethod::Sobel),
                    (Interpolation::Cubic, GradientMethod::Central),
                    (Interpolation::Cubic, GradientMethod::Analytic),
                    (Interpolation::BSpline, GradientMethod::Analytic),
                ]
            };
            for &(interp, g) in grads {
                let k = format!("{matte}\ngradient = \"{}\"", g.name());
                for &s in steps {
                    push(
                        &mut out,
                        f,
                        "surface",
                        &k,
                        "facing",
                        "sampled",
                        interp,
                        Some(g),
                        Some(s),
                    );
                }
            }
            for g in [GradientMethod::Central, GradientMethod::Sobel] {
                let k = format!(
                    "{matte}\ngradient = \"{}\"\nintegration = \"exact\"",
                    g.name()
                );
                push(
                    &mut out,
                    f,
                    "surface",
                    &k,
                    "facing",
                    "exact",
                    Interpolation::Trilinear,
                    Some(g),
                    None,
                );
            }
        }
        for (tf, _) in TRANSFERS {
            let base = format!(
                "mode = \"composite\"\ntransfer = \"{tf}\"\nreference_step = 1.0\nearly_stop = 1.0"
            );
            let truth = format!("composite-{tf}");
            let stop = |e: f64| base.replace("early_stop = 1.0", &format!("early_stop = {e}"));
            for &s in steps {
                for (method, k) in [
                    ("sampled", base.clone()),
                    ("jitter", format!("{base}\njitter = true")),
                    ("preintegrated", format!("{base}\npreintegrated = true")),
                    // early termination: the scenes' default 0.99 and a later 0.995
                    ("early 0.995", stop(0.995)),
                    ("early 0.99", stop(0.99)),
                ] {
                    push(
                        &mut out,
                        f,
                        "composite",
                        &k,
                        &truth,
                        method,
                        Interpolation::Trilinear,
                        None,
                        Some(s),
                    );
                    if let Some(c) = out.last_mut() {
                        c.transfer = Some(tf);
                    }
                }
                if !opts.quick {
                    push(
                        &mut out,
                        f,
                        "composite",
                        &base,
                        &truth,
                        "sampled",
                        Interpolation::Cubic,
                        None,
                        Some(s),
                    );
                    if let Some(c) = out.last_mut() {
                        c.transfer = Some(tf);
                    }
                }
            }
        }
    }
    out
}

fn quantity(truth: &str) -> Quantity {
    match truth {
        "integral" => Quantity::Integral,
        "max" => Quantity::Max,
        "min" => Quantity::Min,
        "mean" => Quantity::Mean,
        "lmip" => Quantity::LocalMax(0.5),
        "depth" => Quantity::Depth(0.5),
        "facing" => Quantity::Facing(0.5),
        other => Quantity::Composite {
            tf: transfer(other.trim_start_matches("composite-")),
            // one voxel of the 41^3 grid on [-1, 1]
            reference_step: 2.0 / (GRID - 1) as f64,
        },
    }
}

/// The scene text of one case.
fn scene_text(field: &FieldCase, case: &Case, size: usize, frames: usize) -> String {
    let mut s = format!(
        "[volume]\n{}\nsizes = [{GRID}, {GRID}, {GRID}]\n[camera]\nprojection = \"orthographic\"\nazimuth = {AZIMUTH_DEG}\nelevation = {ELEVATION_DEG}\n\
         [orbit]\nframes = {frames}\ndegrees = {}\n[image]\nsize = [{size}, {size}]\nformat = \"nrrd\"\n\
         [material.matte]\nambient = [0, 0, 0]\ndiffuse = [1, 1, 1]\nspecular = [0, 0, 0]\n",
        field.toml,
        90.0 * frames as f64
    );
    for (name, body) in TRANSFERS {
        s += &format!("[transfer.{name}]\n{body}\n");
    }
    s += &format!(
        "[[render]]\n{}\ninterpolation = \"{}\"\n",
        case.keys,
        case.interpolation.name()
    );
    if let Some(step) = case.step {
        s += &format!("step = {step}\n");
    }
    s
}

/// Runs the sweep.
pub fn sweep(
    opts: &Options,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<Row>, BenchError> {
    let fields = fields(opts.quick);
    let fog = fields.iter().position(|f| f.name == "fog");
    let cases = cases(opts, fields.len(), fog);
    let (size, frames) = (opts.size, opts.frames);
    let mut truths: HashMap<(usize, String), Vec<Answer>> = HashMap::new();
    let mut rows = Vec::with_capacity(cases.len());
    for (idx, case) in cases.iter().enumerate() {
        progress(idx, cases.len());
        let fc = &fields[case.field];
        let truth = truths
            .entry((case.field, case.truth.clone()))
            .or_insert_with(|| {
                let q = quantity(&case.truth);
                (0..size * size)
                    .into_par_iter()
                    .map(|p| {
                        let (i, j) = (p % size, p / size);
                        pixel_line(size, i, j).and_then(|line| answer(&fc.field, &q, &line))
                    })
                    .collect()
            });
        let text = scene_text(fc, case, size, frames);
        let scene = crate::scene::parse(&text, Path::new("bench.toml"))?;
        let mut times = Vec::new();
        let mut result = None;
        for _ in 0..opts.repeats.max(1) {
            let start = Instant::now();
            let (views, summary) =
                render_films(&scene, &RunOptions::default(), &Limits::default())?;
            times.push(start.elapsed().as_secs_f64());
            result = Some((views, summary.samples));
        }
        let (views, samples) = result.expect("at least one repeat");
        times.sort_by(f64::total_cmp);
        let seconds = times[times.len() / 2];
        let (mut max, mut sq, mut count) = (0.0f64, 0.0f64, 0usize);
        for view in &views {
            let film = &view.film;
            for (p, want) in truth.iter().enumerate() {
                let Some(want) = want else { continue };
                let got = film.pixel(p % size, p / size);
                let e = pixel_error(case.mode, got, want);
                max = max.max(e);
                sq += e * e;
                count += 1;
            }
        }
        rows.push(Row {
            field: fc.name.to_string(),
            mode: case.mode.to_string(),
            method: case.method.to_string(),
            interpolation: case.interpolation.name().to_string(),
            gradient: case.gradient.map(|g| g.name().to_string()),
            transfer: case.transfer.map(str::to_string),
            step_voxels: case.step,
            ms_per_frame: 1e3 * seconds / views.len() as f64,
            msamples_per_s: samples as f64
                / views.len() as f64
                / (seconds / views.len() as f64)
                / 1e6,
            max_error: max,
            rms_error: (sq / count.max(1) as f64).sqrt(),
            pixels: count,
        });
    }
    progress(cases.len(), cases.len());
    Ok(rows)
}

/// Penalty for a depth pixel that hits where the truth misses, or the reverse
/// (world units: half the side of the bench box).
const DEPTH_MISMATCH: f64 = 1.0;

/// The error of one pixel: absolute for grey modes; for RGBA the largest error
/// of the premultiplied colour channels and the opacity.
fn pixel_error(mode: &str, got: &[f32], want: &[f64; 4]) -> f64 {
    match mode {
        "surface" => {
            // a miss shows nothing: error = the whole shade
            let shade = if got[3] > 0.0 { f64::from(got[0]) } else { 0.0 };
            (shade - want[0]).abs()
        }
        "composite" => {
            let a = f64::from(got[3]);
            (0..3)
                .map(|c| (f64::from(got[c]) * a - want[c]).abs())
                .fold((a - want[3]).abs(), f64::max)
        }
        _ => {
            let g = f64::from(got[0]);
            match (g.is_nan(), want[0].is_nan()) {
                (false, false) => (g - want[0]).abs(),
                (true, true) => 0.0,
                _ => DEPTH_MISMATCH,
            }
        }
    }
}

/// A deterministic uniform generator (xorshift64) for the sample points.
struct Xorshift(u64);
impl Xorshift {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The synthetic volume of `field` on the bench grid, as f32 voxels, plus the map
/// from world to index coordinates.
fn volume(field: Field) -> Result<(Vec<f32>, glam::DMat3), BenchError> {
    let s = Synthetic::new(field, [GRID; 3]);
    let v = s.load(&Limits::default())?;
    let VolumeData::F32(data) = v.data else {
        unreachable!("synthetic volumes are float32")
    };
    let inv = s
        .geometry()
        .index_from_world_matrix()
        .expect("the synthetic grid is regular");
    Ok((data, inv))
}

/// Max and RMS error of each reconstruction of Marschner-Lobb 41^3 against the
/// analytic signal at `points` uniform points (fixed seed), over the whole cube and
/// over its interior `[-0.9, 0.9]^3` (away from the boundary conditions).
pub fn reconstruction(points: usize) -> Result<Vec<ReconstructionRow>, BenchError> {
    let (data, inv) = volume(Field::MarschnerLobb)?;
    let n = [GRID; 3];
    let norm = Normalize::new(0.0, 1.0);
    let coefficients = prefilter_cubic(&data, n, norm);
    let mut rows = Vec::new();
    for interp in [
        Interpolation::Nearest,
        Interpolation::Trilinear,
        Interpolation::BSpline,
        Interpolation::Cubic,
    ] {
        let s = Sampler::new(
            &data,
            n,
            norm,
            interp,
            Some(&coefficients),
            GradientMethod::Central,
            None,
            inv,
        );
        for (region, extent) in [("cube", 1.0), ("interior", 0.9)] {
            let mut rng = Xorshift(0x9e37_79b9_7f4a_7c15);
            let (mut max, mut sq) = (0.0f64, 0.0f64);
            for _ in 0..points {
                let w = (DVec3::new(rng.next(), rng.next(), rng.next()) * 2.0 - 1.0) * extent;
                let e = (f64::from(s.value(inv * (w + 1.0))) - Field::MarschnerLobb.eval(w)).abs();
                max = max.max(e);
                sq += e * e;
            }
            rows.push(ReconstructionRow {
                interpolation: interp.name().to_string(),
                region: region.to_string(),
                points,
                max_error: max,
                rms_error: (sq / points as f64).sqrt(),
            });
        }
    }
    Ok(rows)
}

/// Angular error of the surface normal `-grad f / |grad f|` on the iso-sphere
/// `f = 0.5` (radius 0.5) of the sphere-distance field (41^3), whose true normal is
/// radial, at `points` uniform directions (fixed seed), for each estimator.
pub fn normals(points: usize) -> Result<Vec<NormalRow>, BenchError> {
    let (data, inv) = volume(Field::SphereDistance { radius: 1.0 })?;
    let n = [GRID; 3];
    let norm = Normalize::new(0.0, 1.0);
    let coefficients = prefilter_cubic(&data, n, norm);
    let mut rows = Vec::new();
    for (interp, g) in [
        (Interpolation::Trilinear, GradientMethod::Central),
        (Interpolation::Trilinear, GradientMethod::Sobel),
        (Interpolation::Cubic, GradientMethod::Analytic),
        (Interpolation::BSpline, GradientMethod::Analytic),
    ] {
        let s = Sampler::new(&data, n, norm, interp, Some(&coefficients), g, None, inv);
        let mut rng = Xorshift(0x2545_f491_4f6c_dd1d);
        let (mut max, mut sum) = (0.0f64, 0.0f64);
        for _ in 0..points {
            // uniform on the sphere: z uniform in [-1, 1], angle uniform
            let z = rng.next() * 2.0 - 1.0;
            let phi = rng.next() * std::f64::consts::TAU;
            let r = (1.0 - z * z).sqrt();
            let u = DVec3::new(r * phi.cos(), r * phi.sin(), z);
            let grad = s.gradient(inv * (u * 0.5 + 1.0));
            let normal = -grad.normalize_or_zero();
            let angle = normal.dot(u).clamp(-1.0, 1.0).acos().to_degrees();
            max = max.max(angle);
            sum += angle;
        }
        rows.push(NormalRow {
            estimator: format!("{} + {}", interp.name(), g.name()),
            points,
            mean_deg: sum / points as f64,
            max_deg: max,
        });
    }
    Ok(rows)
}
