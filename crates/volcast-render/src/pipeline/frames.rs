//! The parallel rendering of the remaining frames, batch by batch: distinct views
//! rendered once (stereo reuse), handed to the sink with their grey windows. A
//! batch is written, by a thread of its own, while the next one renders.

use std::borrow::Borrow;
use std::collections::{BTreeSet, HashMap, HashSet};
use std::path::PathBuf;
use std::time::Instant;

use rayon::prelude::*;

use super::{CacheKey, Emit, EyeView, FrameViews, Rendered, Summary};
use crate::error::Error;
use crate::output::display::Window;
use crate::plan::Plan;
use crate::render::{ImageKind, RenderView, Resources, View};
use crate::sample::Normalize;
use crate::scene::Format;
use crate::views::Eye;
use crate::views::{frames_per_batch, ViewKey};
use crate::volume::Volume;

/// The prepared passes (or keyframed variants) by variant.
type Runtimes<'a> = HashMap<usize, Box<dyn RenderView + 'a>>;

/// The files written for each (pass, frame).
type Written = Vec<((usize, usize), Vec<PathBuf>)>;

/// Renders the frames `jobs` ((pass, frame) pairs, in order) as `plan` says (its
/// zoom already fitted to the voxels where the scene asks), and hands each to
/// `emit`'s sink: the grey windows found ([`grey_windows`]), then the frames in batches ([`Schedule`]), each batch's distinct views
/// rendered on the workers while a thread of its own writes the batch before.
pub(super) fn render_passes<V: Borrow<Volume>>(
    plan: &Plan,
    volumes: &[Option<V>],
    norms: &[Option<Normalize>],
    jobs: &[(usize, usize)],
    emit: &Emit,
) -> Result<Summary, Error> {
    let Emit {
        progress,
        prepare,
        sink,
    } = *emit;
    // each loaded volume's precomputations, for the passes (or parts) that read it
    let mut resources: Vec<Option<Resources>> = Vec::with_capacity(plan.volumes.len());
    for (k, ((v, loaded), norm)) in plan.volumes.iter().zip(volumes).zip(norms).enumerate() {
        let (Some(volume), Some(norm)) = (loaded, norm) else {
            resources.push(None);
            continue;
        };
        let volume = volume.borrow();
        // where the volume sits, as planned (its transform applied)
        let index_from_world =
            v.header
                .geometry
                .index_from_world_matrix()
                .ok_or_else(|| Error::Plan {
                    scene: plan.scene.file.clone(),
                    message: format!("the volume {} has degenerate axes", v.header.source),
                })?;
        let reads = plan
            .passes
            .iter()
            .flat_map(|p| p.reads())
            .filter(|(r, _)| *r == k)
            .map(|(_, p)| p);
        resources.push(Some(Resources::build(
            &volume.data,
            volume.header.sizes,
            *norm,
            // without a window, the run's is the data's range (`value_window`)
            v.spec.window.is_none(),
            index_from_world,
            reads,
        )));
    }
    let windows = grey_windows(plan, &resources);

    prepare()?;
    let views = &plan.views;
    let schedule = Schedule::new(plan, jobs);
    // One runtime per variant (the passes, or their keyframed values per frame),
    // prepared when a batch first needs it and dropped after the last batch that
    // does: a keyframed sequence holds a few variants' tables at a time, not one
    // per frame.
    let mut runtimes: Runtimes = HashMap::new();
    let mut cache: HashMap<CacheKey, Rendered> = HashMap::new();
    let mut results: Written = Vec::with_capacity(jobs.len());
    let (mut rendered_views, mut samples, mut nominal) = (0usize, 0u64, 0u64);
    // `None` when the caller cancelled the run before every view was rendered
    let render = |todo: &[(CacheKey, (usize, usize))], runtimes: &Runtimes<'_>| {
        todo.par_iter()
            .map(|&(ck, first)| {
                if progress.cancelled() {
                    return None;
                }
                let rt = &runtimes[&ck.0];
                let view = view_of(plan, ck.1, (plan.width, plan.height));
                let t0 = Instant::now();
                let (film, counts) = rt.render(&view, plan.frame_of(&plan.variants[ck.0]));
                let r = Rendered {
                    view,
                    film,
                    samples: counts.taken,
                    nominal: counts.nominal,
                    seconds: t0.elapsed().as_secs_f64(),
                    first,
                };
                Some((ck, r))
            })
            .collect::<Option<Vec<(CacheKey, Rendered)>>>()
    };
    // Hands frame `k` of pass `p` to the sink, from the cached views.
    let write_one = |&(p, k): &(usize, usize),
                     cache: &HashMap<CacheKey, Rendered>|
     -> Result<((usize, usize), Vec<PathBuf>), Error> {
        let cks: Vec<CacheKey> = views
            .eyes()
            .iter()
            .map(|&e| schedule.cache_key(p, k, e))
            .collect();
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
    };
    // The frames of batch `b`, one after another or on the workers.
    let write = |b: usize, cache: &HashMap<CacheKey, Rendered>, parallel: bool| {
        let batch = &schedule.batches[b];
        if parallel {
            batch.par_iter().map(|j| write_one(j, cache)).collect()
        } else {
            batch
                .iter()
                .map(|j| write_one(j, cache))
                .collect::<Result<Written, Error>>()
        }
    };
    progress.start(jobs.len() as u64);
    // Batch `b` renders on the workers while a thread of its own writes batch
    // `b - 1`: the writes' encoding and hashing fill the time the workers would
    // wait for each other at the end of a batch, and their waits on the device
    // (the sync before each rename) hold no worker.
    let batches = schedule.batches.len();
    for b in 0..=batches {
        let todo = if b < batches {
            schedule.todo(b, &cache)
        } else {
            Vec::new()
        };
        for &(ck, _) in &todo {
            runtimes
                .entry(ck.0)
                .or_insert_with(|| plan.variants[ck.0].prepare(&resources));
        }
        if progress.cancelled() {
            return Err(Error::Cancelled);
        }
        let (fresh, written) = match b.checked_sub(1) {
            None => (render(&todo, &runtimes), Ok(Vec::new())),
            // the last batch: nothing left to render beside it
            Some(w) if todo.is_empty() => (Some(Vec::new()), write(w, &cache, true)),
            Some(w) => std::thread::scope(|s| {
                let writer = std::thread::Builder::new()
                    .name("volcast-writer".into())
                    .spawn_scoped(s, || write(w, &cache, false));
                let fresh = render(&todo, &runtimes);
                let written = match writer {
                    Ok(h) => h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)),
                    // no thread to be had: after the renders, on the workers
                    Err(_) => write(w, &cache, true),
                };
                (fresh, written)
            }),
        };
        results.extend(written?);
        let fresh = fresh.ok_or(Error::Cancelled)?;
        if let Some(w) = b.checked_sub(1) {
            schedule.forget_after(w, &mut cache, &mut runtimes);
        }
        rendered_views += fresh.len();
        samples += fresh.iter().map(|(_, r)| r.samples).sum::<u64>();
        nominal += fresh.iter().map(|(_, r)| r.nominal).sum::<u64>();
        cache.extend(fresh);
    }
    progress.finish();
    results.sort_by_key(|r| r.0);
    Ok(Summary {
        files: results.into_iter().flat_map(|r| r.1).collect(),
        images: jobs.len(),
        views: rendered_views,
        samples,
        nominal_samples: nominal,
        windows,
        ..Summary::default()
    })
}

/// The view of `key` at `size` (width, height).
fn view_of(plan: &Plan, key: ViewKey, (w, h): (usize, usize)) -> View {
    plan.views.view(key, w, h, plan.sphere)
}

/// Each pass's grey window: none for colour images and float NRRDs, the pass's
/// own, or one found from a preview of every distinct view of the whole orbit
/// (whatever frames this run renders, so that all runs agree).
fn grey_windows(plan: &Plan, resources: &[Option<Resources>]) -> Vec<Option<Window>> {
    let views = &plan.views;
    plan.windows
        .iter()
        .zip(&plan.passes)
        .zip(&plan.auto_window)
        .enumerate()
        .map(|(p, ((window, rp), &auto))| {
            if rp.kind() == ImageKind::Rgba || plan.output.format == Format::Nrrd {
                None
            } else if let Some([lo, hi]) = *window {
                Some(Window { lo, hi })
            } else {
                debug_assert!(auto);
                // every distinct (variant, view) of the whole orbit
                let orbit_views: BTreeSet<(usize, ViewKey)> = (0..views.orbit_frames())
                    .flat_map(|k| {
                        let v = plan.variant(p, k);
                        views.eyes().iter().map(move |&e| (v, views.key(k, e)))
                    })
                    .collect();
                // one variant at a time (previews are of intensity passes: no tables);
                // each preview is kept only as its range of finite values
                let mut ranges: Vec<(f64, f64)> = Vec::with_capacity(orbit_views.len());
                let variants: BTreeSet<usize> = orbit_views.iter().map(|&(v, _)| v).collect();
                for v in variants {
                    let rt = plan.variants[v].prepare(resources);
                    let keys: Vec<ViewKey> = orbit_views
                        .iter()
                        .filter(|&&(u, _)| u == v)
                        .map(|&(_, key)| key)
                        .collect();
                    let frame = plan.frame_of(&plan.variants[v]);
                    ranges.par_extend(keys.par_iter().map(|&key| {
                        Window::finite_range(&rt.render(&view_of(plan, key, plan.preview), frame).0)
                    }));
                }
                Some(Window::of_ranges(ranges))
            }
        })
        .collect()
}

/// The frames of a run in batches, and the last batch that needs each view and
/// each variant, so that a view is rendered once and dropped when no later batch
/// needs it.
struct Schedule<'a> {
    plan: &'a Plan,
    /// The (pass, frame) pairs of each batch: [`frames_per_batch`] frames each.
    batches: Vec<Vec<(usize, usize)>>,
    last_use: HashMap<CacheKey, usize>,
    variant_last_use: HashMap<usize, usize>,
}

impl<'a> Schedule<'a> {
    /// The batches of `jobs` ((pass, frame) pairs, a frame's passes together).
    fn new(plan: &'a Plan, jobs: &[(usize, usize)]) -> Schedule<'a> {
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
        let mut schedule = Schedule {
            plan,
            batches,
            last_use: HashMap::new(),
            variant_last_use: HashMap::new(),
        };
        for (b, batch) in schedule.batches.iter().enumerate() {
            for &(p, k) in batch {
                schedule.variant_last_use.insert(plan.variant(p, k), b);
                for &e in plan.views.eyes() {
                    schedule.last_use.insert(schedule.cache_key(p, k, e), b);
                }
            }
        }
        schedule
    }

    /// The key of the view eye `e` of frame `k` of pass `p` renders: keyed by the
    /// variant the frame renders, so frames with other keyframed values never
    /// share a view.
    fn cache_key(&self, p: usize, k: usize, e: Eye) -> CacheKey {
        let views = &self.plan.views;
        (
            self.plan.variant(p, k),
            views.key(k, e),
            (!views.share).then_some((k, e)),
        )
    }

    /// The views batch `b` needs that no batch before it rendered (those not in
    /// `cache`), each with the (pass, frame) it is first rendered for.
    fn todo(
        &self,
        b: usize,
        cache: &HashMap<CacheKey, Rendered>,
    ) -> Vec<(CacheKey, (usize, usize))> {
        let mut todo: Vec<(CacheKey, (usize, usize))> = Vec::new();
        let mut seen = HashSet::new();
        for &(p, k) in &self.batches[b] {
            for &e in self.plan.views.eyes() {
                let ck = self.cache_key(p, k, e);
                if !cache.contains_key(&ck) && seen.insert(ck) {
                    todo.push((ck, (p, k)));
                }
            }
        }
        todo
    }

    /// Drops the views and the variants' runtimes that no batch after batch `b`
    /// needs.
    fn forget_after(
        &self,
        b: usize,
        cache: &mut HashMap<CacheKey, Rendered>,
        runtimes: &mut Runtimes<'_>,
    ) {
        cache.retain(|ck, _| self.last_use.get(ck).is_some_and(|&last| last > b));
        runtimes.retain(|v, _| self.variant_last_use.get(v).is_some_and(|&last| last > b));
    }
}
