//! One run, top to bottom (like pbrt's `RenderCPU`): read the header, plan, find
//! the (pass, frame) images that remain (`--resume`), load the voxels, precompute
//! what the passes need, fix the grey windows, then batch by batch of frames render
//! the distinct views in parallel and lay out, encode and write each image
//! atomically with its manifest record (a batch is written while the next one
//! renders); at the end, merge the manifest and, once
//! every frame of the orbit exists, assemble the animations.
//!
//! Nothing is created on disk until the scene, the volume and the plan have all
//! been checked. Every pixel depends only on the scene, the view and the pixel; a
//! view's pose depends only on its [`ViewKey`], so sharing a view between two
//! frames (toe-in reuse) changes no byte; and the preview pass that fixes automatic
//! grey windows always covers every view of the whole orbit. So any frame range,
//! shard or resumed run gives the same bytes as a full run, with any number of
//! threads.

mod fit;
mod frames;
mod prepare;
mod resume;
mod volumes;
mod write;

pub use prepare::{data_window, value_window};
pub use resume::completed_images;

use frames::render_passes;
use resume::{completed, create_folders, finish, jobs};
use volumes::Volumes;
use write::write_frame;

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::Error;
use crate::output::animation;
use crate::output::display::Window;
use crate::output::manifest::{self, FrameRecord, ManifestStatus, ViewRecord};
use crate::plan::{Plan, RunOptions};
use crate::render::{Film, View};
use crate::scene::Scene;
use crate::views::Eye;
use crate::views::ViewKey;
use crate::volume::{confine, Limits, Volume};

/// Reports progress in units of finished (pass, frame) images.
pub trait Progress: Sync {
    /// The run will produce `total` images.
    fn start(&self, _total: u64) {}
    /// `n` more images are done.
    fn advance(&self, _n: u64) {}
    /// All done.
    fn finish(&self) {}
    /// Whether the caller asks the run to stop (a Ctrl-C in the Python module): read
    /// before each view is rendered and each batch is written; once it says so, the
    /// run ends with [`Error::Cancelled`].
    fn cancelled(&self) -> bool {
        false
    }
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
    /// Field samples the march would take without empty-space skipping (excluding
    /// preview passes).
    pub nominal_samples: u64,
    /// Wall-clock seconds of the whole run.
    pub seconds: f64,
    /// Grey windows used per pass (`None` for colour passes, NRRD output, and runs
    /// that rendered nothing).
    pub windows: Vec<Option<Window>>,
    /// The merged manifest (`None` for runs that keep films in memory).
    pub manifest: Option<ManifestStatus>,
    /// Animations written by this run.
    pub animations: Vec<animation::Written>,
    /// The turntable page, when the run wrote it (`[viewer] html`, `--viewer`).
    pub viewer: Option<PathBuf>,
    /// The ffmpeg command that makes an MP4 of each image sequence (none for NRRD).
    pub ffmpeg: Vec<String>,
    /// Things worth telling the user (unreadable records, removed temporaries).
    pub notes: Vec<String>,
}

/// Renders `scene` and writes its images, their manifest records, the merged
/// manifest and, once the sequence is complete, its animations. A run that fails
/// removes the folders it created if they are still empty (no stray folder).
pub fn render(
    scene: &Scene,
    opts: &RunOptions,
    limits: &Limits,
    progress: &dyn Progress,
) -> Result<Summary, Error> {
    let out = opts.out.clone().unwrap_or_else(|| scene.image.out.clone());
    let created = resume::missing_folders(&out);
    let result = render_run(scene, opts, limits, progress);
    if result.is_err() {
        resume::remove_empty_folders(&created);
    }
    result
}

/// The stages of a run, as pbrt's `RenderCPU` reads: check everything that can be
/// checked without voxels (the plan, after which the scene is not read again), find
/// what is already done, render what remains, finish.
fn render_run(
    scene: &Scene,
    opts: &RunOptions,
    limits: &Limits,
    progress: &dyn Progress,
) -> Result<Summary, Error> {
    let start = Instant::now();
    let (_scope, plan) = preflight(scene, opts, limits)?;
    let mut summary = run_plan(&plan, opts, limits, progress)?;
    summary.seconds = start.elapsed().as_secs_f64();
    Ok(summary)
}

/// A planned run: what is done, the rest rendered, the manifest merged, the
/// animations and the page made.
fn run_plan(
    plan: &Plan,
    opts: &RunOptions,
    limits: &Limits,
    progress: &dyn Progress,
) -> Result<Summary, Error> {
    if opts.finish_only && !plan.out.is_dir() {
        return Err(Error::Plan {
            scene: plan.scene.file.clone(),
            message: format!(
                "--finish-only: the output folder {} does not exist: nothing has been rendered there yet",
                plan.out.display()
            ),
        });
    }
    let mut notes = Vec::new();
    // what the folder's last run recorded, read once for both uses
    let previous = manifest::read_manifest(&plan.out)?;
    let mut known = Known::find(plan, previous.as_ref(), opts, limits, &mut notes)?;
    if !opts.force {
        refuse_another_scene(plan, previous.as_ref(), &known.digest, &mut notes)?;
    }
    let jobs = jobs(plan, &known.done);
    if let (Some(shard), true) = (plan.shard, plan.frame_list.is_empty()) {
        notes.push(format!(
            "shard {shard} has no frames of {}..{}: nothing to render",
            plan.frames.start, plan.frames.end
        ));
    }
    let mut summary = match known.volumes.take() {
        _ if jobs.is_empty() => Summary::default(),
        Some(volumes) => render_jobs(plan, &volumes, &jobs, &known.digest, progress)?,
        None => {
            let volumes = volumes::load(plan, limits)?;
            render_jobs(plan, &volumes, &jobs, &known.digest, progress)?
        }
    };
    summary.skipped = if opts.finish_only {
        0
    } else {
        known.done.len()
    };
    notes.append(&mut summary.notes);
    summary.notes = notes;
    finish(plan, &known.identity, &known.digest, &mut summary)?;
    Ok(summary)
}

/// Refuses to render into a folder whose `manifest.json` records another scene
/// file and another scene hash: two scenes would mix their images there. The same
/// scene file edited (or at another size, with other voxels, by another volcast)
/// renders again, replacing its images, and `notes` says so.
fn refuse_another_scene(
    plan: &Plan,
    previous: Option<&serde_json::Value>,
    digest: &str,
    notes: &mut Vec<String>,
) -> Result<(), Error> {
    let Some(previous) = previous else {
        return Ok(());
    };
    let hash = previous.get("scene_hash").and_then(|h| h.as_str());
    if hash.is_none_or(|h| h == digest) {
        return Ok(());
    }
    let text = |v: &serde_json::Value| v.as_str().map(str::to_string);
    let file = text(&previous["scene"]["file"]).unwrap_or_default();
    if !same_file(Path::new(&file), &plan.scene.file) {
        return Err(Error::Plan {
            scene: plan.scene.file.clone(),
            message: format!(
                "the output folder {} holds the images of another scene, {file} (its manifest's scene hash differs): render into another folder (--out), remove that one, or pass --force to render over it",
                plan.out.display()
            ),
        });
    }
    let size = previous["render_size"]
        .as_array()
        .map(|a| a.iter().filter_map(|x| x.as_u64()).collect::<Vec<_>>());
    let version = text(&previous["volcast_version"]).unwrap_or_default();
    let why = if text(&previous["scene"]["text"]).as_deref() != Some(plan.scene.text.as_str()) {
        "this scene as it was before it was edited".to_string()
    } else if size != Some(vec![plan.width as u64, plan.height as u64]) {
        let s = size.map_or("another size".into(), |s| {
            s.iter().map(u64::to_string).collect::<Vec<_>>().join(" x ")
        });
        format!("this scene at {s}")
    } else if version != env!("CARGO_PKG_VERSION") {
        format!("this scene rendered by volcast {version}")
    } else {
        let sources: Vec<&str> = plan
            .volumes
            .iter()
            .filter(|v| v.is_read())
            .map(|v| v.header.source.as_str())
            .collect();
        format!("this scene with other voxels in {}", sources.join(", "))
    };
    notes.push(format!(
        "{} held the images of {why}: the frames rendered now replace them",
        plan.out.display()
    ));
    Ok(())
}

/// Whether two scene paths name one file: the same file once resolved, or, where
/// the recorded one no longer resolves (written from another folder), the same name.
fn same_file(recorded: &Path, now: &Path) -> bool {
    match (recorded.canonicalize(), now.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => recorded.file_name() == now.file_name(),
    }
}

/// What a run finds before it renders: which voxels the volumes hold, the digest
/// its images are recorded under, and which (pass, frame) images already exist for
/// them; with the volumes themselves when they had to be read to know their voxels.
struct Known {
    identity: crate::volume::VolumeIdentity,
    digest: String,
    done: HashSet<(usize, usize)>,
    volumes: Option<Volumes>,
}

impl Known {
    /// The voxels are known from the manifest when the volume's files did not change,
    /// else hashed while they are read. Images count as done only for the same
    /// voxels (`--resume`); with `--finish-only` every image counts as done, and the
    /// manifest says which exist. `previous` is the folder's `manifest.json`.
    fn find(
        plan: &Plan,
        previous: Option<&serde_json::Value>,
        opts: &RunOptions,
        limits: &Limits,
        notes: &mut Vec<String>,
    ) -> Result<Known, Error> {
        let layout = &plan.scene.digest;
        if let Some(f) = previous.and_then(manifest::manifest_format) {
            if f != manifest::MANIFEST_FORMAT && opts.resume {
                notes.push(format!(
                    "{} was written by an older volcast ({f}) whose records do not cover the voxel data: its images are rendered again",
                    plan.out.join(manifest::MANIFEST).display()
                ));
            }
        }
        let done_for =
            |digest: &str, notes: &mut Vec<String>| -> Result<HashSet<(usize, usize)>, Error> {
                if opts.finish_only {
                    Ok(plan
                        .frame_list
                        .iter()
                        .flat_map(|&k| (0..plan.passes.len()).map(move |p| (p, k)))
                        .collect())
                } else if opts.resume {
                    completed(plan, digest, notes)
                } else {
                    Ok(HashSet::new())
                }
            };
        // the volume as read, and what is done for its voxels
        let known = |volumes: Volumes,
                     identity: crate::volume::VolumeIdentity,
                     notes: &mut Vec<String>|
         -> Result<Known, Error> {
            let digest = manifest::data_digest(layout, identity.data_xxh3.as_deref());
            let done = done_for(&digest, notes)?;
            Ok(Known {
                identity,
                digest,
                done,
                volumes: Some(volumes),
            })
        };
        let Some(recorded) = resume::trusted_identity(plan, previous)? else {
            let (volumes, identity) = volumes::load_identified(plan, limits)?;
            return known(volumes, identity, notes);
        };
        let digest = manifest::data_digest(layout, recorded.data_xxh3.as_deref());
        let done = done_for(&digest, notes)?;
        if jobs(plan, &done).is_empty() {
            return Ok(Known {
                identity: recorded,
                digest,
                done,
                volumes: None,
            });
        }
        // something is left to render: read the voxels, and if they are not the
        // recorded ones, find what is done for the voxels there are
        let (volumes, now) = volumes::load_identified(plan, limits)?;
        if now.data_xxh3 == recorded.data_xxh3 {
            return Ok(Known {
                identity: now,
                digest,
                done,
                volumes: Some(volumes),
            });
        }
        // (the damaged records were noted above)
        known(volumes, now, &mut Vec::new())
    }
}

/// Renders the (pass, frame) images `jobs` of the loaded volumes and writes each
/// with its manifest record: the value windows, the zoom fitted where the scene
/// asks (the plan the frames then render), then the frames.
fn render_jobs(
    plan: &Plan,
    volumes: &Volumes,
    jobs: &[(usize, usize)],
    digest: &str,
    progress: &dyn Progress,
) -> Result<Summary, Error> {
    let norms = volumes::norms(plan, volumes)?;
    let fitted = fit::fit(plan, volumes, &norms)?;
    let plan = fitted.as_ref().map_or(plan, |f| &f.plan);
    let shard = plan.shard.map(|s| s.to_string());
    let prepare = || create_folders(&plan.out);
    let sink = |fv: &FrameViews| -> Result<Vec<PathBuf>, Error> {
        let t0 = Instant::now();
        let files = write_frame(plan, fv)?;
        let record = FrameRecord {
            scene_hash: digest.to_string(),
            volcast_version: env!("CARGO_PKG_VERSION").into(),
            pass: plan.passes[fv.pass].name.clone(),
            frame: fv.frame,
            views: fv
                .eyes
                .iter()
                .map(|e| {
                    let (azimuth, elevation) = plan.views.angles_deg(e.key);
                    ViewRecord::new(e.eye, e.key, azimuth, elevation, &e.view, e.samples)
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
    let mut summary = render_passes(plan, volumes, &norms, jobs, &emit)?;
    summary.notes.extend(fitted.map(|f| f.note));
    Ok(summary)
}

/// `--confine`: checks the volume's files and the output folder against the folder
/// of `opts.confine` before anything is read or created, and returns the scope that
/// checks every volume file again as it is opened (keep it alive while loading).
pub fn confine_run(scene: &Scene, opts: &RunOptions) -> Result<Option<confine::Scope>, Error> {
    let Some(dir) = &opts.confine else {
        return Ok(None);
    };
    let root = confine::Root::new(dir)?;
    for v in &scene.volumes {
        confine::check_source(&v.spec.source, &root)?;
    }
    confine::check_output(opts.out.as_deref().unwrap_or(&scene.image.out), &root)?;
    Ok(Some(confine::Scope::enter(&root)))
}

/// What a run checks before it reads a voxel: `--confine` (the scope it returns
/// keeps checking files as they are opened: keep it alive while loading), the
/// volumes' headers, the plan, and the plan's memory estimate against `limits`.
fn preflight(
    scene: &Scene,
    opts: &RunOptions,
    limits: &Limits,
) -> Result<(Option<confine::Scope>, Plan), Error> {
    let scope = confine_run(scene, opts)?;
    let plan = Plan::build(scene, &headers(scene)?, opts)?;
    plan.check_memory(limits)?;
    Ok((scope, plan))
}

/// The headers of the scene's volumes, in its order (no voxels read).
pub fn headers(scene: &Scene) -> Result<Vec<crate::volume::VolumeHeader>, Error> {
    scene
        .volumes
        .iter()
        .map(|v| v.spec.source.header().map_err(Error::from))
        .collect()
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
    let (_scope, plan) = preflight(scene, opts, limits)?;
    let start = Instant::now();
    let volumes = volumes::load(&plan, limits)?;
    let (views, mut summary) = films_of_plan(&plan, &volumes)?;
    summary.seconds = start.elapsed().as_secs_f64();
    Ok((views, summary))
}

/// [`render_films`] of a scene of one volume, already loaded (`volume` must be
/// the scene's: the benchmarks render many scenes of one volume). The summary's
/// time excludes loading.
pub fn render_films_of(
    scene: &Scene,
    volume: &Volume,
    opts: &RunOptions,
) -> Result<(Vec<RenderedView>, Summary), Error> {
    let start = Instant::now();
    let plan = Plan::build(scene, std::slice::from_ref(&volume.header), opts)?;
    // (a borrowed volume: the plan's one volume, read by its passes)
    let volumes = [Some(volume)];
    let (views, mut summary) = films_of_plan(&plan, &volumes)?;
    summary.seconds = start.elapsed().as_secs_f64();
    Ok((views, summary))
}

/// [`render_films_of`] of a scene of any number of volumes, already loaded
/// (`volumes` in the scene's order, each the scene's own).
pub fn render_films_of_all(
    scene: &Scene,
    volumes: &[&Volume],
    opts: &RunOptions,
) -> Result<(Vec<RenderedView>, Summary), Error> {
    let start = Instant::now();
    let headers: Vec<_> = volumes.iter().map(|v| v.header.clone()).collect();
    let plan = Plan::build(scene, &headers, opts)?;
    let volumes: Vec<Option<&Volume>> = volumes
        .iter()
        .zip(&plan.volumes)
        .map(|(v, p)| p.is_read().then_some(*v))
        .collect();
    let (views, mut summary) = films_of_plan(&plan, &volumes)?;
    summary.seconds = start.elapsed().as_secs_f64();
    Ok((views, summary))
}

/// The films of every (pass, frame) of `plan`, rendered from `volumes`.
fn films_of_plan<V: std::borrow::Borrow<Volume>>(
    plan: &Plan,
    volumes: &[Option<V>],
) -> Result<(Vec<RenderedView>, Summary), Error> {
    let norms = volumes::norms(plan, volumes)?;
    let fitted = fit::fit(plan, volumes, &norms)?;
    let plan = fitted.as_ref().map_or(plan, |f| &f.plan);
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
    let jobs = jobs(plan, &HashSet::new());
    let emit = Emit {
        progress: &NoProgress,
        prepare: &|| Ok(()),
        sink: &sink,
    };
    let mut summary = render_passes(plan, volumes, &norms, &jobs, &emit)?;
    summary.notes.extend(fitted.map(|f| f.note));
    let mut views = collected
        .into_inner()
        .expect("no panics while holding the lock");
    views.sort_by_key(|v| (v.pass, v.frame, v.eye));
    Ok((views, summary))
}

/// One image of a (pass, frame) as its file would store it (see [`render_images`]).
#[derive(Clone, Debug)]
pub struct StoredImage {
    /// Index of the pass in the scene.
    pub pass: usize,
    /// Frame number.
    pub frame: usize,
    /// The eye of a `pair` (or mono) frame; [`Eye::Mono`] for the other stereo
    /// layouts, which hold both eyes in one image.
    pub eye: Eye,
    /// For PNG formats the display colours in [0, 1], overlays drawn
    /// ([`encode::sample8`](crate::output::encode::sample8) and
    /// [`encode::sample16`](crate::output::encode::sample16) give the files'
    /// samples); for NRRD the raw float values the file holds.
    pub film: Film,
}

/// Renders `scene` like [`render`] but keeps every image in memory, exactly as the
/// files would store it (laid out, overlays drawn, before quantisation), instead of
/// writing files; in (pass, frame, eye) order. `progress` is told of each image and
/// may cancel the run ([`Progress::cancelled`]).
pub fn render_images(
    scene: &Scene,
    opts: &RunOptions,
    limits: &Limits,
    progress: &dyn Progress,
) -> Result<(Vec<StoredImage>, Summary), Error> {
    let start = Instant::now();
    let (_scope, plan) = preflight(scene, opts, limits)?;
    let volumes = volumes::load(&plan, limits)?;
    let norms = volumes::norms(&plan, &volumes)?;
    let fitted = fit::fit(&plan, &volumes, &norms)?;
    let plan = fitted.as_ref().map_or(&plan, |f| &f.plan);
    let collected = std::sync::Mutex::new(Vec::new());
    let sink = |fv: &FrameViews| {
        let images: Vec<StoredImage> = write::frame_images(plan, fv)?
            .into_iter()
            .map(|(eye, film)| StoredImage {
                pass: fv.pass,
                frame: fv.frame,
                eye,
                film: film.into_owned(),
            })
            .collect();
        let mut c = collected.lock().expect("no panics while holding the lock");
        c.extend(images);
        Ok(Vec::new())
    };
    let jobs = jobs(plan, &HashSet::new());
    let emit = Emit {
        progress,
        prepare: &|| Ok(()),
        sink: &sink,
    };
    let mut summary = render_passes(plan, &volumes, &norms, &jobs, &emit)?;
    summary.notes.extend(fitted.map(|f| f.note));
    let mut images = collected
        .into_inner()
        .expect("no panics while holding the lock");
    images.sort_by_key(|v| (v.pass, v.frame, v.eye));
    summary.seconds = start.elapsed().as_secs_f64();
    Ok((images, summary))
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

/// A view rendered at full size, kept while frames still need it.
struct Rendered {
    view: View,
    film: Film,
    samples: u64,
    nominal: u64,
    seconds: f64,
    /// The (pass, frame) it was rendered for (its time is counted there).
    first: (usize, usize),
}

/// A view of a pass, as cached: with `share` off, each (frame, eye) has its own.
type CacheKey = (usize, ViewKey, Option<(usize, Eye)>);
