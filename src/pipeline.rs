//! One run, top to bottom (like pbrt's `RenderCPU`): read the header, plan, find
//! the (pass, frame) images that remain (`--resume`), load the voxels, precompute
//! what the passes need, fix the grey windows, then batch by batch of frames render
//! the distinct views in parallel and lay out, encode and write each image
//! atomically with its manifest record; at the end, merge the manifest and, once
//! every frame of the orbit exists, assemble the animations.
//!
//! Nothing is created on disk until the scene, the volume and the plan have all
//! been checked. Every pixel depends only on the scene, the view and the pixel; a
//! view's pose depends only on its [`ViewKey`], so sharing a view between two
//! frames (toe-in reuse) changes no byte; and the preview pass that fixes automatic
//! grey windows always covers every view of the whole orbit. So any frame range,
//! shard or resumed run gives the same bytes as a full run, with any number of
//! threads.

use std::collections::{BTreeSet, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use serde_json::json;

use crate::error::Error;
use crate::output::animation::{self, Sequence};
use crate::output::display::{to_display, DisplayKind, Window};
use crate::output::manifest::{
    self, FileRecord, FrameRecord, ManifestHead, ManifestStatus, ViewRecord,
};
use crate::output::write::remove_stale_temporaries;
use crate::output::{encode, frame_path, stereo, write_atomic, Eye};
use crate::plan::{Plan, RunOptions, TABLE_1D, TABLE_2D};
use crate::render::{render_view, Film, IndexFrame, Kernel, TransferTable, View};
use crate::sample::{gradient_volume, prefilter_cubic, GradientMethod, Normalize, Sampler};
use crate::scene::{AnaglyphColors, Format, Layout, LightKindSpec, Mode, Scene, Transfer};
use crate::shade::{Light, LightKind, Shader};
use crate::transfer::{Table1D, Table2D};
use crate::views::{frames_per_batch, ViewKey};
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
    /// Image files written, in (pass, frame, eye) order.
    pub files: Vec<PathBuf>,
    /// (pass, frame) images written.
    pub images: usize,
    /// (pass, frame) images skipped because `--resume` found them complete.
    pub skipped: usize,
    /// Distinct views rendered (excluding preview passes).
    pub views: usize,
    /// Field samples taken (excluding preview passes).
    pub samples: u64,
    /// Wall-clock seconds of the whole run.
    pub seconds: f64,
    /// Grey windows used per pass (`None` for colour passes, NRRD output, and runs
    /// that rendered nothing).
    pub windows: Vec<Option<Window>>,
    /// The merged manifest (`None` for runs that keep films in memory).
    pub manifest: Option<ManifestStatus>,
    /// Animations written by this run.
    pub animations: Vec<animation::Written>,
    /// The ffmpeg command that makes an MP4 of each image sequence (none for NRRD).
    pub ffmpeg: Vec<String>,
    /// Things worth telling the user (unreadable records, removed temporaries).
    pub notes: Vec<String>,
}

/// Renders `scene` and writes its images, their manifest records, the merged
/// manifest and, once the sequence is complete, its animations.
pub fn render(
    scene: &Scene,
    opts: &RunOptions,
    limits: &Limits,
    progress: &dyn Progress,
) -> Result<Summary, Error> {
    let start = Instant::now();
    let header = scene.volume.source.header()?;
    let plan = Plan::build(scene, &header, opts)?;
    let digest = manifest::scene_digest(scene, &header, plan.width, plan.height);
    let done = if opts.resume {
        completed(scene, &plan, &digest)?
    } else {
        HashSet::new()
    };
    let jobs = jobs(scene, &plan, &done);
    let mut summary = Summary {
        skipped: done.len(),
        ..Summary::default()
    };
    if let (Some(shard), true) = (plan.shard, plan.frame_list.is_empty()) {
        summary.notes.push(format!(
            "shard {shard} has no frames of {}..{}: nothing to render",
            plan.frames.start, plan.frames.end
        ));
    }
    if !jobs.is_empty() {
        let volume = scene.volume.source.load(limits)?;
        let norm = value_window(scene, &volume)?;
        let shard = plan.shard.map(|s| s.to_string());
        let prepare = || create_folders(&plan.out);
        let sink = |fv: &FrameViews| -> Result<Vec<PathBuf>, Error> {
            let t0 = Instant::now();
            let files = write_frame(scene, &plan, fv)?;
            let record = FrameRecord {
                scene_hash: digest.clone(),
                volcast_version: env!("CARGO_PKG_VERSION").into(),
                pass: scene.passes[fv.pass].name.clone(),
                frame: fv.frame,
                views: fv
                    .eyes
                    .iter()
                    .map(|e| {
                        ViewRecord::new(
                            e.eye,
                            e.key,
                            scene.camera.azimuth_deg + plan.views.azimuth_offset_deg(e.key),
                            scene.camera.elevation_deg,
                            &e.view,
                            e.samples,
                        )
                    })
                    .collect(),
                window: fv.window.map(|w| [w.lo, w.hi]),
                samples: fv.eyes.iter().map(|e| e.samples).sum(),
                seconds: fv.seconds + t0.elapsed().as_secs_f64(),
                shard: shard.clone(),
                files: files.iter().map(|f| f.1.clone()).collect(),
            };
            manifest::write_record(&plan.out, &record)?;
            Ok(files.into_iter().map(|f| f.0).collect())
        };
        let emit = Emit {
            progress,
            prepare: &prepare,
            sink: &sink,
        };
        let s = with_volume_data!(&volume.data, v => render_typed(scene, &plan, &volume.header, v, norm, &jobs, &emit))?;
        summary = Summary {
            skipped: summary.skipped,
            ..s
        };
    }
    finish(scene, &plan, &header, &digest, &mut summary)?;
    summary.seconds = start.elapsed().as_secs_f64();
    Ok(summary)
}

/// How many (pass, frame) images of the plan's frames `--resume` would skip.
pub fn completed_images(scene: &Scene, header: &VolumeHeader, plan: &Plan) -> Result<usize, Error> {
    let digest = manifest::scene_digest(scene, header, plan.width, plan.height);
    Ok(completed(scene, plan, &digest)?.len())
}

/// The (pass, frame) images of the plan's frames that `--resume` may skip.
fn completed(scene: &Scene, plan: &Plan, digest: &str) -> Result<HashSet<(usize, usize)>, Error> {
    let mut done = HashSet::new();
    for &k in &plan.frame_list {
        for (p, pass) in scene.passes.iter().enumerate() {
            if let Some(r) = manifest::read_record(&plan.out, &pass.name, k)? {
                if manifest::is_complete(&plan.out, &r, digest) {
                    done.insert((p, k));
                }
            }
        }
    }
    Ok(done)
}

/// The (pass, frame) images to render, frame by frame.
fn jobs(scene: &Scene, plan: &Plan, done: &HashSet<(usize, usize)>) -> Vec<(usize, usize)> {
    plan.frame_list
        .iter()
        .flat_map(|&k| (0..scene.passes.len()).map(move |p| (p, k)))
        .filter(|j| !done.contains(j))
        .collect()
}

fn create_folders(out: &Path) -> Result<(), Error> {
    let records = out.join(manifest::RECORDS);
    std::fs::create_dir_all(&records).map_err(|source| Error::Output {
        path: records,
        source,
    })
}

/// The end of every run: remove stale temporaries, merge the manifest, and
/// assemble the animations when the sequence is complete and they are missing,
/// out of date, or this run wrote frames.
fn finish(
    scene: &Scene,
    plan: &Plan,
    header: &VolumeHeader,
    digest: &str,
    summary: &mut Summary,
) -> Result<(), Error> {
    let out = &plan.out;
    // what the previous manifest says about the animations, before it is replaced
    let previous = std::fs::read(out.join(manifest::MANIFEST))
        .ok()
        .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
        .and_then(|v| v.get("animation").and_then(|a| a.get("settings")).cloned());
    create_folders(out)?;
    let mut removed = 0;
    for dir in [out.clone(), out.join(manifest::RECORDS)] {
        removed += remove_stale_temporaries(&dir).map_err(|source| Error::Output {
            path: dir.clone(),
            source,
        })?;
    }
    if removed > 0 {
        summary.notes.push(format!(
            "removed {removed} temporary file(s) left by an interrupted run"
        ));
    }
    let sequences = animation::sequences(scene);
    let fps = scene.animation.as_ref().map_or(24.0, |a| a.fps);
    let ffmpeg: Vec<String> = if scene.image.format == Format::Nrrd {
        Vec::new()
    } else {
        sequences
            .iter()
            .map(|q| animation::ffmpeg_command(out, q, fps))
            .collect()
    };
    let settings = scene.animation.as_ref().map(|a| {
        json!({
            "formats": a.formats.iter().map(|f| f.extension()).collect::<Vec<_>>(),
            "fps": a.fps,
            "loop": a.looping,
        })
    });
    let mut head = ManifestHead {
        scene,
        header,
        digest,
        size: (plan.width, plan.height),
        extra: json!({ "ffmpeg": &ffmpeg }),
    };
    let status = manifest::write_manifest(out, &head)?;
    summary.notes.extend(
        status
            .unreadable
            .iter()
            .map(|u| format!("{u} (that frame counts as missing)")),
    );
    if let (Some(anim), true) = (&scene.animation, status.complete()) {
        let missing = sequences.iter().any(|q: &Sequence| {
            anim.formats
                .iter()
                .any(|&f| !q.animation_path(out, f).is_file())
        });
        let stale = previous.as_ref() != settings.as_ref();
        if summary.images > 0 || missing || stale {
            summary.animations = animation::assemble(out, scene, anim)?;
        }
        let files: Vec<serde_json::Value> = sequences
            .iter()
            .flat_map(|q| {
                anim.formats.iter().map(|&f| {
                    json!({
                        "file": q.animation_path(out, f).file_name().map(|n| n.to_string_lossy().into_owned()),
                        "format": f.extension(),
                        "frames": scene.orbit.frames,
                        "fps": match f {
                            crate::scene::AnimationFormat::Gif => 100.0 / animation::gif_delay(anim.fps) as f64,
                            crate::scene::AnimationFormat::Apng => anim.fps,
                        },
                    })
                })
            })
            .collect();
        head.extra = json!({
            "ffmpeg": head.extra["ffmpeg"],
            "animation": { "settings": settings, "files": files },
        });
        manifest::write_manifest(out, &head)?;
    }
    summary.manifest = Some(status);
    summary.ffmpeg = ffmpeg;
    Ok(())
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
    /// The distinct view this eye shows.
    pub key: ViewKey,
    /// Its pose and image plane.
    pub view: View,
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
    let sink = |fv: &FrameViews| {
        let mut c = collected.lock().expect("no panics while holding the lock");
        c.extend(fv.eyes.iter().map(|e| RenderedView {
            pass: fv.pass,
            frame: fv.frame,
            eye: e.eye,
            key: e.key,
            view: e.view,
            film: e.film.clone(),
        }));
        Ok(Vec::new())
    };
    let jobs = jobs(scene, &plan, &HashSet::new());
    let emit = Emit {
        progress: &NoProgress,
        prepare: &|| Ok(()),
        sink: &sink,
    };
    let mut summary = with_volume_data!(&volume.data, v => render_typed(scene, &plan, &volume.header, v, norm, &jobs, &emit))?;
    summary.seconds = start.elapsed().as_secs_f64();
    let mut views = collected
        .into_inner()
        .expect("no panics while holding the lock");
    views.sort_by_key(|v| (v.pass, v.frame, v.eye));
    Ok((views, summary))
}

/// One eye of a (pass, frame), rendered.
struct EyeView<'a> {
    eye: Eye,
    key: ViewKey,
    view: View,
    film: &'a Film,
    samples: u64,
}

/// The views of one (pass, frame), ready to lay out and write.
struct FrameViews<'a> {
    pass: usize,
    frame: usize,
    /// The pass's grey window.
    window: Option<Window>,
    /// In the plan's eye order.
    eyes: Vec<EyeView<'a>>,
    /// Seconds spent rendering the views first needed by this (pass, frame).
    seconds: f64,
}

/// Receives the views of one (pass, frame); returns the files written.
type Sink<'a> = dyn Fn(&FrameViews) -> Result<Vec<PathBuf>, Error> + Sync + 'a;

/// Where rendered views go.
struct Emit<'a> {
    progress: &'a dyn Progress,
    /// Called once before the first image is handed to the sink (creates folders).
    prepare: &'a (dyn Fn() -> Result<(), Error> + Sync + 'a),
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

/// A view rendered at full size, kept while frames still need it.
struct Rendered {
    view: View,
    film: Film,
    samples: u64,
    seconds: f64,
    /// The (pass, frame) it was rendered for (its time is counted there).
    first: (usize, usize),
}

/// A view of a pass, as cached: with `share` off, each (frame, eye) has its own.
type CacheKey = (usize, ViewKey, Option<(usize, Eye)>);

fn render_typed<T: Voxel>(
    scene: &Scene,
    plan: &Plan,
    header: &VolumeHeader,
    data: &[T],
    norm: Normalize,
    jobs: &[(usize, usize)],
    emit: &Emit,
) -> Result<Summary, Error> {
    let Emit {
        progress,
        prepare,
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
    let views = &plan.views;
    let view_of = |key: ViewKey, w: usize, h: usize| views.view(&scene.camera, key, w, h, sphere);

    // Grey windows: fixed, or from a preview of every distinct view of the whole
    // orbit (whatever frames this run renders, so that all runs agree).
    let orbit_views: BTreeSet<ViewKey> = (0..scene.orbit.frames)
        .flat_map(|k| views.eyes().iter().map(move |&e| views.key(k, e)))
        .collect();
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
                let films: Vec<Film> = orbit_views
                    .par_iter()
                    .map(|&key| {
                        render_view(&view_of(key, w, h), &rt.kernel, &rt.sampler, &frame, rt.dt).0
                    })
                    .collect();
                Some(Window::of_films(&films))
            }
        })
        .collect();

    prepare()?;
    // Frames in batches: render the batch's views not yet rendered (in parallel),
    // write its images (in parallel), drop the views no later batch needs.
    let cache_key = |p: usize, k: usize, e: Eye| -> CacheKey {
        (p, views.key(k, e), (!views.share).then_some((k, e)))
    };
    let mut batches: Vec<Vec<(usize, usize)>> = Vec::new();
    let per_batch = frames_per_batch(rayon::current_num_threads());
    let mut frames_in_batch = 0;
    let mut last_frame = None;
    for &(p, k) in jobs {
        if last_frame != Some(k) {
            if frames_in_batch % per_batch == 0 {
                batches.push(Vec::new());
            }
            frames_in_batch += 1;
            last_frame = Some(k);
        }
        batches.last_mut().expect("pushed above").push((p, k));
    }
    let mut last_use: HashMap<CacheKey, usize> = HashMap::new();
    for (b, batch) in batches.iter().enumerate() {
        for &(p, k) in batch {
            for &e in views.eyes() {
                last_use.insert(cache_key(p, k, e), b);
            }
        }
    }
    let mut cache: HashMap<CacheKey, Rendered> = HashMap::new();
    let mut results: Vec<((usize, usize), Vec<PathBuf>)> = Vec::with_capacity(jobs.len());
    let (mut rendered_views, mut samples) = (0usize, 0u64);
    progress.start(jobs.len() as u64);
    for (b, batch) in batches.iter().enumerate() {
        let mut todo: Vec<(CacheKey, (usize, usize))> = Vec::new();
        let mut seen = HashSet::new();
        for &(p, k) in batch {
            for &e in views.eyes() {
                let ck = cache_key(p, k, e);
                if !cache.contains_key(&ck) && seen.insert(ck) {
                    todo.push((ck, (p, k)));
                }
            }
        }
        let fresh: Vec<(CacheKey, Rendered)> = todo
            .par_iter()
            .map(|&(ck, first)| {
                let rt = &runtimes[ck.0];
                let view = view_of(ck.1, plan.width, plan.height);
                let t0 = Instant::now();
                let (film, n) = render_view(&view, &rt.kernel, &rt.sampler, &frame, rt.dt);
                let r = Rendered {
                    view,
                    film,
                    samples: n,
                    seconds: t0.elapsed().as_secs_f64(),
                    first,
                };
                (ck, r)
            })
            .collect();
        rendered_views += fresh.len();
        samples += fresh.iter().map(|(_, r)| r.samples).sum::<u64>();
        cache.extend(fresh);
        let written: Vec<((usize, usize), Vec<PathBuf>)> = batch
            .par_iter()
            .map(|&(p, k)| {
                let cks: Vec<CacheKey> = views.eyes().iter().map(|&e| cache_key(p, k, e)).collect();
                let eyes: Vec<EyeView> = views
                    .eyes()
                    .iter()
                    .zip(&cks)
                    .map(|(&eye, ck)| {
                        let r = &cache[ck];
                        EyeView {
                            eye,
                            key: ck.1,
                            view: r.view,
                            film: &r.film,
                            samples: r.samples,
                        }
                    })
                    .collect();
                let seconds = cks
                    .iter()
                    .collect::<HashSet<_>>()
                    .into_iter()
                    .map(|ck| &cache[ck])
                    .filter(|r| r.first == (p, k))
                    .map(|r| r.seconds)
                    .sum();
                let files = sink(&FrameViews {
                    pass: p,
                    frame: k,
                    window: windows[p],
                    eyes,
                    seconds,
                })?;
                progress.advance(1);
                Ok(((p, k), files))
            })
            .collect::<Result<_, Error>>()?;
        results.extend(written);
        cache.retain(|ck, _| last_use.get(ck).is_some_and(|&last| last > b));
    }
    progress.finish();
    results.sort_by_key(|r| r.0);
    Ok(Summary {
        files: results.into_iter().flat_map(|r| r.1).collect(),
        images: jobs.len(),
        views: rendered_views,
        samples,
        windows,
        ..Summary::default()
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

/// Lays out, encodes and writes the images of one (pass, frame); returns each file
/// with its manifest entry.
fn write_frame(
    scene: &Scene,
    plan: &Plan,
    fv: &FrameViews,
) -> Result<Vec<(PathBuf, FileRecord)>, Error> {
    let (p, k, window) = (fv.pass, fv.frame, fv.window);
    let pass = &scene.passes[p];
    let format = scene.image.format;
    let bg = scene.image.background;
    let display_kind = match (&pass.mode, window) {
        (Mode::Depth { .. }, Some(w)) => DisplayKind::Depth(w),
        (_, Some(w)) => DisplayKind::Intensity(w),
        _ => DisplayKind::Rgba,
    };
    // Films in the form the format stores: raw values for NRRD, display colours for PNG.
    let stored: Vec<(Eye, std::borrow::Cow<Film>)> = fv
        .eyes
        .iter()
        .map(|e| match format {
            Format::Nrrd => (e.eye, std::borrow::Cow::Borrowed(e.film)),
            _ => (
                e.eye,
                std::borrow::Cow::Owned(to_display(e.film, display_kind, bg)),
            ),
        })
        .collect();
    let layout = scene.stereo.map(|s| s.layout);
    let images: Vec<(Eye, std::borrow::Cow<Film>)> = match (layout, stored.as_slice()) {
        (None, _) | (Some(Layout::Pair), _) => stored,
        (Some(l), [(_, left), (_, right)]) => {
            let st = scene.stereo.expect("layout implies stereo");
            let fill: Vec<f32> = match format {
                Format::Nrrd if left.channels == 1 => vec![f32::NAN],
                Format::Nrrd => vec![0.0; left.channels],
                _ => bg[..left.channels.min(3)].to_vec(),
            };
            // grey passes always combine luminance; shaded ones as the scene says
            let colors = if pass.mode.is_intensity() {
                AnaglyphColors::Gray
            } else {
                st.anaglyph_colors
            };
            let combined = match l {
                Layout::SideBySide => stereo::side_by_side(left, right, st.gap, &fill),
                Layout::CrossEyed => stereo::side_by_side(right, left, st.gap, &fill),
                Layout::Anaglyph => stereo::anaglyph(left, right, st.anaglyph, colors),
                Layout::Pair => unreachable!("handled above"),
            };
            vec![(Eye::Mono, std::borrow::Cow::Owned(combined))]
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
                let mut kv = vec![
                    ("volcast_pass".to_string(), pass.name.clone()),
                    ("volcast_mode".to_string(), pass.mode.name().to_string()),
                    ("volcast_frame".to_string(), k.to_string()),
                    ("volcast_azimuth_deg".to_string(), format!("{azimuth}")),
                ];
                if eye != Eye::Mono {
                    let e = fv.eyes.iter().find(|e| e.eye == eye);
                    if let Some(e) = e {
                        kv.push((
                            "volcast_eye_azimuth_deg".to_string(),
                            format!(
                                "{}",
                                scene.camera.azimuth_deg + plan.views.azimuth_offset_deg(e.key)
                            ),
                        ));
                    }
                }
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
        let record = manifest::file_record(&path, &bytes);
        files.push((path, record));
    }
    Ok(files)
}
