//! `volcast render`: load, plan, render, write, summarise.

use std::process::ExitCode;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use volcast::pipeline::{self, Progress};
use volcast::volume::human_bytes;

use super::args::{RenderArgs, SceneArgs};

/// The scene, options and limits common to `render` and `check`.
pub(super) fn prepare(
    a: &SceneArgs,
) -> anyhow::Result<(
    volcast::scene::Scene,
    volcast::plan::RunOptions,
    volcast::volume::Limits,
)> {
    let scene = volcast::scene::load(&a.scene)?;
    let opts = volcast::plan::RunOptions {
        out: a.out.clone(),
        frames: a.frames.clone(),
        size: a.size,
        threads: a.threads.map(usize::from),
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
    let (scene, opts, limits) = prepare(&a.scene)?;
    if !a.quiet {
        for w in &scene.warnings {
            eprintln!("volcast: warning: {w}");
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
        let rate = summary.samples as f64 / summary.seconds.max(1e-9);
        let folder = summary
            .files
            .first()
            .and_then(|f| f.parent())
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "-".into());
        let bytes: u64 = summary
            .files
            .iter()
            .filter_map(|f| std::fs::metadata(f).ok())
            .map(|m| m.len())
            .sum();
        eprintln!(
            "volcast: {} files ({} views, {}) in {:.2} s, {:.1} M samples/s -> {folder}",
            summary.files.len(),
            summary.views,
            human_bytes(bytes),
            summary.seconds,
            rate / 1e6
        );
    }
    Ok(ExitCode::SUCCESS)
}
