//! `volcast render`: load, plan, render, write, summarise.

use std::process::ExitCode;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use volcast::pipeline::{self, Progress};
use volcast::volume::human_bytes;

use volcast::batch::Shard;

use super::args::{RenderArgs, SceneArgs, ShardArg};
use super::say;

/// The scene, options and limits common to `render` and `check`.
pub(super) fn prepare(
    a: &SceneArgs,
) -> anyhow::Result<(
    volcast::scene::Scene,
    volcast::plan::RunOptions,
    volcast::volume::Limits,
)> {
    let scene = volcast::scene::load(&a.scene)?;
    let shard = match a.shard {
        None => None,
        Some(ShardArg::Fixed(s)) => Some(s),
        Some(ShardArg::Auto) => Some(Shard::from_slurm(|k| std::env::var(k).ok())?),
        Some(ShardArg::AutoOf(n)) => Some(Shard::from_slurm_of(n, |k| std::env::var(k).ok())?),
    };
    let opts = volcast::plan::RunOptions {
        out: a.out.clone(),
        frames: a.frames.clone(),
        size: a.size,
        threads: a.threads.map(usize::from),
        shard,
        resume: a.resume,
        no_view_reuse: a.no_view_reuse,
        no_skip: a.no_skip,
        confine: a.confine.clone(),
        viewer: a.viewer,
        ..Default::default()
    };
    let mut limits = volcast::volume::Limits::default();
    if let Some(m) = a.max_memory {
        limits.max_bytes = m;
    }
    Ok((scene, opts, limits))
}

/// Runs `f` on a pool of `threads` workers (or rayon's default pool).
pub(super) fn with_threads<R: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> R + Send,
) -> anyhow::Result<R> {
    match threads {
        None => Ok(f()),
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .context("starting the worker threads")?;
            Ok(pool.install(f))
        }
    }
}

struct Bar(ProgressBar);

impl Progress for Bar {
    fn start(&self, total: u64) {
        self.0.set_length(total);
        self.0.reset_eta();
    }
    fn advance(&self, n: u64) {
        self.0.inc(n);
    }
    fn finish(&self) {
        self.0.finish_and_clear();
    }
}

pub fn run(a: RenderArgs) -> anyhow::Result<ExitCode> {
    let (scene, mut opts, limits) = prepare(&a.scene)?;
    opts.finish_only = a.finish_only;
    opts.force = a.force;
    if !a.quiet {
        for w in &scene.warnings {
            say!("volcast: warning: {w}");
        }
    }
    let bar = if a.quiet {
        ProgressBar::hidden()
    } else {
        let b = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::stderr());
        b.set_style(
            ProgressStyle::with_template(
                "{spinner} {elapsed_precise} [{wide_bar}] {pos}/{len} images, eta {eta}",
            )
            .expect("the progress template is valid")
            .progress_chars("=> "),
        );
        b
    };
    let progress = Bar(bar);
    let summary = with_threads(opts.threads, || {
        pipeline::render(&scene, &opts, &limits, &progress)
    })?
    .with_context(|| format!("rendering {}", scene.path.display()))?;
    if !a.quiet {
        report(&summary);
    }
    if a.finish_only {
        if let Some(m) = summary.manifest.as_ref().filter(|m| !m.complete()) {
            anyhow::bail!("{}", missing_message(m));
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// What `--finish-only` found missing: the images by pass, as frame ranges, and
/// which shards to render again when the records name one shard count.
fn missing_message(m: &volcast::output::manifest::ManifestStatus) -> String {
    let mut by_pass: Vec<(&str, Vec<usize>)> = Vec::new();
    for (pass, k) in &m.missing {
        match by_pass.last_mut() {
            Some((p, frames)) if *p == pass.as_str() => frames.push(*k),
            _ => by_pass.push((pass.as_str(), vec![*k])),
        }
    }
    let passes: Vec<String> = by_pass
        .iter()
        .map(|(p, frames)| format!("{p} frames {}", ranges(frames)))
        .collect();
    let shards = match m.shard_counts.as_slice() {
        [n] => {
            let mut ks: Vec<usize> = m.missing.iter().map(|(_, k)| k % n).collect();
            ks.sort_unstable();
            ks.dedup();
            let list: Vec<String> = ks.iter().map(|k| k.to_string()).collect();
            format!(
                "; they belong to shard{} {} of {n}: resubmit those array tasks (sbatch --array={} ...) with --shard auto/{n}",
                if ks.len() > 1 { "s" } else { "" },
                list.join(", "),
                list.join(",")
            )
        }
        _ => String::new(),
    };
    format!(
        "--finish-only: {} of {} images are missing or damaged, so the sequence is incomplete ({}){shards}; render them with --resume",
        m.total - m.done,
        m.total,
        passes.join("; ")
    )
}

/// `0..=3, 7, 9..=10` for frames 0 1 2 3 7 9 10.
fn ranges(frames: &[usize]) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < frames.len() {
        let mut j = i;
        while j + 1 < frames.len() && frames[j + 1] == frames[j] + 1 {
            j += 1;
        }
        out.push(if j == i {
            frames[i].to_string()
        } else {
            format!("{}..={}", frames[i], frames[j])
        });
        i = j + 1;
    }
    out.join(", ")
}

/// The closing summary, on stderr.
fn report(summary: &pipeline::Summary) {
    let rate = summary.samples as f64 / summary.seconds.max(1e-9);
    let folder = summary
        .manifest
        .as_ref()
        .and_then(|m| m.path.parent())
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| "-".into());
    let bytes: u64 = summary
        .files
        .iter()
        .filter_map(|f| std::fs::metadata(f).ok())
        .map(|m| m.len())
        .sum();
    let skipped = if summary.skipped > 0 {
        format!(", {} images already complete", summary.skipped)
    } else {
        String::new()
    };
    let skipping = if summary.nominal_samples > summary.samples {
        format!(
            " ({:.0}% of {:.1} M samples skipped)",
            100.0 * (1.0 - summary.samples as f64 / summary.nominal_samples as f64),
            summary.nominal_samples as f64 / 1e6
        )
    } else {
        String::new()
    };
    say!(
        "volcast: {} files ({} views rendered{skipped}, {}) in {:.2} s, {:.1} M samples/s{skipping} -> {folder}",
        summary.files.len(),
        summary.views,
        human_bytes(bytes),
        summary.seconds,
        rate / 1e6
    );
    if let Some(m) = &summary.manifest {
        if m.complete() {
            say!(
                "volcast: manifest {}: all {} images complete",
                m.path.display(),
                m.total
            );
            if let Some(cmd) = summary.ffmpeg.first() {
                let more = if summary.ffmpeg.len() > 1 {
                    " (the other sequences' commands are in the manifest)"
                } else {
                    ""
                };
                say!("volcast: to make a video: {cmd}{more}");
            }
        } else {
            say!(
                "volcast: manifest {}: {} of {} images done; the rest come from other shards or runs (animations and the viewer page are written once every frame exists: rerun with --resume to finish)",
                m.path.display(),
                m.done,
                m.total
            );
        }
    }
    for a in &summary.animations {
        say!(
            "volcast: animation {} ({} frames at {} fps)",
            a.path.display(),
            a.frames,
            (a.fps * 1000.0).round() / 1000.0
        );
    }
    if let Some(page) = &summary.viewer {
        say!(
            "volcast: viewer {}: open it in a browser, drag or use the arrow keys to turn the object",
            page.display()
        );
    }
    for n in &summary.notes {
        say!("volcast: note: {n}");
    }
}
