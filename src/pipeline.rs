//! One run, top to bottom (like pbrt's `RenderCPU`): read the header, plan, load
//! the voxels, precompute what the passes need, fix the grey windows, render every
//! (pass, frame) in parallel, write each image atomically.
//!
//! Nothing is created on disk until the scene, the volume and the plan have all
//! been checked. Every pixel depends only on the scene, the view and the pixel, and
//! the preview pass that fixes automatic grey windows always covers the whole orbit,
//! so any subset of frames gives the same bytes as a full run, with any number of
//! threads.

use std::path::PathBuf;
use std::time::Instant;

use rayon::prelude::*;

use crate::error::Error;
use crate::output::display::{to_display, DisplayKind, Window};
use crate::output::{encode, frame_path, stereo, write_atomic, Eye};
use crate::plan::{Plan, RunOptions, TABLE_1D, TABLE_2D};
use crate::render::{render_view, Film, IndexFrame, Kernel, TransferTable, View};
use crate::sample::{gradient_volume, prefilter_cubic, GradientMethod, Normalize, Sampler};
use crate::scene::{Format, Layout, LightKindSpec, Mode, Scene, Transfer};
use crate::shade::{Light, LightKind, Shader};
use crate::transfer::{Table1D, Table2D};
use crate::volume::{Limits, Stats, Volume, VolumeHeader, Voxel};
use crate::with_volume_data;

/// Reports progress in units of finished (pass, frame) images.
pub trait Progress: Sync {
    /// The run will produce `total` images.
    fn start(&self, _total: u64) {}
    /// `n` more images are done.
    fn advance(&self, _n: u64) {}
    /// All done.
    fn finish(&self) {}
}

/// Progress that is not shown.
pub struct NoProgress;
impl Progress for NoProgress {}

/// What a run did.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    /// Files written, in (pass, frame, eye) order.
    pub files: Vec<PathBuf>,
    /// Views rendered (excluding preview passes).
    pub views: usize,
    /// Field samples taken (excluding preview passes).
    pub samples: u64,
    /// Wall-clock seconds of the whole run.
    pub seconds: f64,
    /// Grey windows used per pass (`None` for colour passes and NRRD output).
    pub windows: Vec<Option<Window>>,
}

/// Renders `scene` and writes its images.
pub fn render(
    scene: &Scene,
    opts: &RunOptions,
    limits: &Limits,
    progress: &dyn Progress,
) -> Result<Summary, Error> {
    let start = Instant::now();
    let header = scene.volume.source.header()?;
    let plan = Plan::build(scene, &header, opts)?;
    let volume = scene.volume.source.load(limits)?;
    let norm = value_window(scene, &volume)?;
    let sink = |p: usize, k: usize, window: Option<Window>, films: Vec<(Eye, Film)>| {
        write_frame(scene, &plan, p, k, window, films)
    };
    let mut summary = with_volume_data!(&volume.data, v => render_typed(scene, &plan, &volume.header, v, norm, &Emit { progress, out_dir: Some(&plan.out), sink: &sink }))?;
    summary.seconds = start.elapsed().as_secs_f64();
    Ok(summary)
}

/// One rendered view, kept in memory.
#[derive(Clone, Debug)]
pub struct RenderedView {
    /// Index of the pass in the scene.
    pub pass: usize,
    /// Frame number.
    pub frame: usize,
    /// Which eye.
    pub eye: Eye,
    /// The unquantised values (what `nrrd` output stores for a mono view).
    pub film: Film,
}

/// Renders `scene` like [`render`] but returns the films instead of writing files
/// (the same code path up to the encoders; used by tests and benchmarks). Views come
/// in (pass, frame, eye) order.
pub fn render_films(
    scene: &Scene,
    opts: &RunOptions,
    limits: &Limits,
) -> Result<(Vec<RenderedView>, Summary), Error> {
    let start = Instant::now();
    let header = scene.volume.source.header()?;
    let plan = Plan::build(scene, &header, opts)?;
    let volume = scene.volume.source.load(limits)?;
    let norm = value_window(scene, &volume)?;
    let collected = std::sync::Mutex::new(Vec::new());
    let sink = |p: usize, k: usize, _: Option<Window>, films: Vec<(Eye, Film)>| {
        let mut c = collected.lock().expect("no panics while holding the lock");
        c.extend(films.into_iter().map(|(eye, film)| RenderedView {
            pass: p,
            frame: k,
            eye,
            film,
        }));
        Ok(Vec::new())
    };
    let mut summary = with_volume_data!(&volume.data, v => render_typed(scene, &plan, &volume.header, v, norm, &Emit { progress: &NoProgress, out_dir: None, sink: &sink }))?;
    summary.seconds = start.elapsed().as_secs_f64();
    let mut views = collected
        .into_inner()
        .expect("no panics while holding the lock");
    views.sort_by_key(|v| (v.pass, v.frame, v.eye != Eye::Left && v.eye != Eye::Mono));
    Ok((views, summary))
}

/// Receives the views of one (pass, frame) with the pass's grey window; returns the files written.
type Sink<'a> = dyn Fn(usize, usize, Option<Window>, Vec<(Eye, Film)>) -> Result<Vec<PathBuf>, Error>
    + Sync
    + 'a;

/// Where rendered views go.
struct Emit<'a> {
    progress: &'a dyn Progress,
    /// Folder to create before the first image (none when keeping films in memory).
    out_dir: Option<&'a std::path::Path>,
    sink: &'a Sink<'a>,
}

/// The normalisation of the scene's value window, or of the data's finite range.
pub fn value_window(scene: &Scene, volume: &Volume) -> Result<Normalize, Error> {
    if let Some([lo, hi]) = scene.volume.window {
        return Ok(Normalize::new(lo, hi));
    }
    let stats = Stats::of(&volume.data);
    if stats.finite == 0 {
        return Err(Error::Plan {
            scene: scene.path.clone(),
            message: format!(
                "the volume {} has no finite values to take a window from",
                volume.header.source
            ),
        });
    }
    let w = Window::from_range(stats.min, stats.max);
    Ok(Normalize::new(w.lo, w.hi))
}

/// Owned precomputations of one run.
struct Precomputed {
    coefficients: Option<Vec<f32>>,
    gradients: Vec<(GradientMethod, Vec<[f32; 3]>)>,
    tables: Vec<Option<OwnedTable>>,
}

enum OwnedTable {
    OneD(Table1D),
    TwoD(Table2D),
}

impl Precomputed {
    fn build<T: Voxel>(
        scene: &Scene,
        plan: &Plan,
        data: &[T],
        sizes: [usize; 3],
        norm: Normalize,
    ) -> Precomputed {
        let coefficients = plan
            .passes
            .iter()
            .any(|p| p.cubic)
            .then(|| prefilter_cubic(data, sizes, norm));
        let mut gradients: Vec<(GradientMethod, Vec<[f32; 3]>)> = Vec::new();
        for p in &plan.passes {
            if let Some(m) = p.gradient_volume {
                if !gradients.iter().any(|(g, _)| *g == m) {
                    gradients.push((m, gradient_volume(data, sizes, norm, m)));
                }
            }
        }
        let tables = scene
            .passes
            .iter()
            .map(|p| match &p.mode {
                Mode::Composite {
                    transfer: Transfer::OneD(t),
                    ..
                } => Some(OwnedTable::OneD(t.table(TABLE_1D))),
                Mode::Composite {
                    transfer: Transfer::TwoD(t),
                    ..
                } => Some(OwnedTable::TwoD(t.table(TABLE_2D, TABLE_2D))),
                _ => None,
            })
            .collect();
        Precomputed {
            coefficients,
            gradients,
            tables,
        }
    }
}

/// Everything one pass needs at render time.
struct PassRuntime<'a, T: Voxel> {
    sampler: Sampler<'a, T>,
    kernel: Kernel<'a>,
    dt: f64,
}

fn render_typed<T: Voxel>(
    scene: &Scene,
    plan: &Plan,
    header: &VolumeHeader,
    data: &[T],
    norm: Normalize,
    emit: &Emit,
) -> Result<Summary, Error> {
    let Emit {
        progress,
        out_dir,
        sink,
    } = *emit;
    let geometry = header.geometry;
    let index_from_world = geometry
        .index_from_world_matrix()
        .ok_or_else(|| Error::Plan {
            scene: scene.path.clone(),
            message: format!("the volume {} has degenerate axes", header.source),
        })?;
    let frame = IndexFrame::new(header.sizes, scene.volume.crop, &geometry, index_from_world);
    let sphere = frame.bounding_sphere(&geometry);
    let pre = Precomputed::build(scene, plan, data, header.sizes, norm);
    let light = shade_light(scene, sphere.0);
    let runtimes: Vec<PassRuntime<T>> = scene
        .passes
        .iter()
        .zip(&plan.passes)
        .zip(&pre.tables)
        .map(|((pass, pp), table)| {
            let gradient_method = pass
                .mode
                .shading()
                .map_or(GradientMethod::Central, |s| s.gradient);
            let gradients = pp
                .gradient_volume
                .and_then(|m| pre.gradients.iter().find(|(g, _)| *g == m))
                .map(|(_, v)| v.as_slice());
            let sampler = Sampler::new(
                data,
                header.sizes,
                norm,
                pass.interpolation,
                pre.coefficients.as_deref(),
                gradient_method,
                gradients,
                index_from_world,
            );
            PassRuntime {
                sampler,
                kernel: kernel(pass, table.as_ref(), light, plan.voxel_length),
                dt: pp.dt,
            }
        })
        .collect();

    // Grey windows: fixed, or from a preview of the whole orbit.
    let windows: Vec<Option<Window>> = scene
        .passes
        .iter()
        .zip(&plan.passes)
        .zip(&runtimes)
        .map(|((pass, pp), rt)| {
            if !pass.mode.is_intensity() || scene.image.format == Format::Nrrd {
                None
            } else if let Some([lo, hi]) = pass.window {
                Some(Window { lo, hi })
            } else {
                debug_assert!(pp.auto_window);
                let (w, h) = plan.preview;
                let films: Vec<Film> = (0..scene.orbit.frames)
                    .into_par_iter()
                    .flat_map_iter(|k| {
                        plan.eyes.iter().map(move |&(_, offset)| {
                            let view = View::new(
                                &scene.camera,
                                scene.orbit.azimuth_offset_deg(k) + offset,
                                w,
                                h,
                                sphere,
                            );
                            render_view(&view, &rt.kernel, &rt.sampler, &frame, rt.dt).0
                        })
                    })
                    .collect();
                Some(Window::of_films(&films))
            }
        })
        .collect();

    if let Some(out) = out_dir {
        std::fs::create_dir_all(out).map_err(|source| Error::Output {
            path: out.to_path_buf(),
            source,
        })?;
    }
    let jobs: Vec<(usize, usize)> = (0..scene.passes.len())
        .flat_map(|p| plan.frames.clone().map(move |k| (p, k)))
        .collect();
    progress.start(jobs.len() as u64);
    let results: Vec<(Vec<PathBuf>, u64)> = jobs
        .par_iter()
        .map(|&(p, k)| {
            let rt = &runtimes[p];
            let films: Vec<(Eye, Film, u64)> = plan
                .eyes
                .iter()
                .map(|&(eye, offset)| {
                    let view = View::new(
                        &scene.camera,
                        scene.orbit.azimuth_offset_deg(k) + offset,
                        plan.width,
                        plan.height,
                        sphere,
                    );
                    let (film, n) = render_view(&view, &rt.kernel, &rt.sampler, &frame, rt.dt);
                    (eye, film, n)
                })
                .collect();
            let samples = films.iter().map(|f| f.2).sum();
            let files = sink(
                p,
                k,
                windows[p],
                films.into_iter().map(|(e, f, _)| (e, f)).collect(),
            )?;
            progress.advance(1);
            Ok((files, samples))
        })
        .collect::<Result<_, Error>>()?;
    progress.finish();
    Ok(Summary {
        files: results.iter().flat_map(|r| r.0.iter().cloned()).collect(),
        views: jobs.len() * plan.eyes.len(),
        samples: results.iter().map(|r| r.1).sum(),
        seconds: 0.0,
        windows,
    })
}

/// The light of the scene in renderer form.
fn shade_light(scene: &Scene, centre: glam::DVec3) -> Light {
    let target = scene.camera.target.unwrap_or(centre);
    let l = &scene.light;
    let (kind, default_intensity) = match l.kind {
        LightKindSpec::Headlight => (LightKind::Headlight, 1.0),
        LightKindSpec::Directional(d) => (
            LightKind::Directional {
                direction: d.as_vec3(),
            },
            1.0,
        ),
        LightKindSpec::Point(p) => (
            LightKind::Point {
                position: p.as_vec3(),
            },
            (p - target).length_squared().max(1e-12),
        ),
    };
    Light {
        kind,
        color: l.color.as_vec3(),
        intensity: l.intensity.unwrap_or(default_intensity) as f32,
    }
}

fn kernel<'a>(
    pass: &crate::scene::RenderPass,
    table: Option<&'a OwnedTable>,
    light: Light,
    voxel_length: f64,
) -> Kernel<'a> {
    use crate::render::integrator::{Exact, Integrand};
    use crate::scene::Integration;
    let shader = |s: &crate::scene::Shading| Shader {
        model: s.model,
        material: s.material,
        light,
    };
    let exact = match (&pass.mode, pass.integration) {
        (_, Integration::Sampled) => None,
        (Mode::Xray { output, mu }, _) => Some(Exact::Xray {
            output: *output,
            mu: *mu,
        }),
        (Mode::Mip, _) => Some(Exact::Mip),
        (Mode::Minip, _) => Some(Exact::Minip),
        (Mode::Average, _) => Some(Exact::Average),
        (Mode::Depth { threshold }, _) => Some(Exact::Depth {
            threshold: *threshold as f32,
        }),
        (Mode::Surface { iso, shading }, _) => Some(Exact::Surface {
            iso: *iso as f32,
            shader: shader(shading),
        }),
        // the scene rejects exact integration for the other modes
        _ => None,
    };
    let integrand = match (&pass.mode, exact) {
        (_, Some(e)) => Integrand::Exact(e),
        (Mode::Xray { output, mu }, None) => Integrand::Xray {
            output: *output,
            mu: *mu,
        },
        (Mode::Mip, None) => Integrand::Mip,
        (Mode::Minip, None) => Integrand::Minip,
        (Mode::Average, None) => Integrand::Average,
        (Mode::Lmip { threshold }, None) => Integrand::Lmip {
            threshold: *threshold as f32,
        },
        (Mode::Depth { threshold }, None) => Integrand::Depth {
            threshold: *threshold as f32,
        },
        (Mode::Surface { iso, shading }, None) => Integrand::Surface {
            iso: *iso as f32,
            shader: shader(shading),
        },
        (
            Mode::Composite {
                shading,
                reference_step_voxels,
                early_stop,
                transfer,
                preintegrated,
                ..
            },
            None,
        ) => Integrand::Composite {
            table: match table.expect("the plan builds a table for every composite pass") {
                OwnedTable::OneD(t) => TransferTable::OneD(t),
                OwnedTable::TwoD(t) => TransferTable::TwoD(t),
            },
            shader: shading.as_ref().map(shader),
            reference_step: reference_step_voxels * voxel_length,
            early_stop: *early_stop as f32,
            voxel_length,
            // built once per pass, for the pass's step (the plan counts its memory)
            preintegrated: match (preintegrated, transfer) {
                (true, Transfer::OneD(tf)) => {
                    Some(std::sync::Arc::new(crate::transfer::Preintegrated::build(
                        tf,
                        pass.step_voxels / reference_step_voxels,
                    )))
                }
                _ => None,
            },
        },
    };
    Kernel {
        integrand,
        // the pass's seed: a hash of its name, so each pass jitters differently
        jitter: pass.jitter.then(|| {
            pass.name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
                (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
            })
        }),
    }
}

/// Lays out, encodes and writes the images of one (pass, frame).
fn write_frame(
    scene: &Scene,
    plan: &Plan,
    p: usize,
    k: usize,
    window: Option<Window>,
    films: Vec<(Eye, Film)>,
) -> Result<Vec<PathBuf>, Error> {
    let pass = &scene.passes[p];
    let format = scene.image.format;
    let bg = scene.image.background;
    let display_kind = match (&pass.mode, window) {
        (Mode::Depth { .. }, Some(w)) => DisplayKind::Depth(w),
        (_, Some(w)) => DisplayKind::Intensity(w),
        _ => DisplayKind::Rgba,
    };
    // Films in the form the format stores: raw values for NRRD, display colours for PNG.
    let stored: Vec<(Eye, Film)> = films
        .into_iter()
        .map(|(eye, film)| match format {
            Format::Nrrd => (eye, film),
            _ => (eye, to_display(&film, display_kind, bg)),
        })
        .collect();
    let layout = scene.stereo.map(|s| s.layout);
    let images: Vec<(Eye, Film)> = match (layout, stored.as_slice()) {
        (None, _) | (Some(Layout::Pair), _) => stored,
        (Some(l), [(_, left), (_, right)]) => {
            let st = scene.stereo.expect("layout implies stereo");
            let fill: Vec<f32> = match format {
                Format::Nrrd if left.channels == 1 => vec![f32::NAN],
                Format::Nrrd => vec![0.0; left.channels],
                _ => bg[..left.channels.min(3)].to_vec(),
            };
            let combined = match l {
                Layout::SideBySide => stereo::side_by_side(left, right, st.gap, &fill),
                Layout::CrossEyed => stereo::side_by_side(right, left, st.gap, &fill),
                Layout::Anaglyph => stereo::anaglyph(left, right, st.anaglyph),
                Layout::Pair => unreachable!("handled above"),
            };
            vec![(Eye::Mono, combined)]
        }
        _ => unreachable!("stereo frames have two eyes"),
    };
    let mut files = Vec::new();
    for (eye, img) in images {
        let path = frame_path(&plan.out, &pass.name, k, eye, format.extension());
        let bytes = match format {
            Format::Png | Format::Png16 => {
                encode::png(&img, format == Format::Png16).map_err(|e| Error::Encode {
                    path: path.clone(),
                    message: e.to_string(),
                })?
            }
            Format::Nrrd => {
                let azimuth = scene.camera.azimuth_deg + scene.orbit.azimuth_offset_deg(k);
                let kv = vec![
                    ("volcast_pass".to_string(), pass.name.clone()),
                    ("volcast_mode".to_string(), pass.mode.name().to_string()),
                    ("volcast_frame".to_string(), k.to_string()),
                    ("volcast_azimuth_deg".to_string(), format!("{azimuth}")),
                ];
                encode::nrrd(&img, &kv).map_err(|e| Error::Encode {
                    path: path.clone(),
                    message: e.to_string(),
                })?
            }
        };
        write_atomic(&path, &bytes).map_err(|source| Error::Output {
            path: path.clone(),
            source,
        })?;
        files.push(path);
    }
    Ok(files)
}
