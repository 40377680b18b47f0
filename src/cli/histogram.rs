//! `volcast histogram`: the value and value x gradient-magnitude histograms of a
//! volume as PNG plots and CSV files, with a scene's settings drawn over them.

use std::path::Path;
use std::process::ExitCode;

use anyhow::Context;

use volcast::histogram::{self, plot, Options, Overlays};
use volcast::volume::{Limits, VolumeSource};

use super::args::HistogramArgs;
use super::info::is_scene;

pub fn run(a: HistogramArgs) -> anyhow::Result<ExitCode> {
    let scene = if is_scene(&a.volume) {
        Some(volcast::scene::load(&a.volume)?)
    } else {
        None
    };
    let source = match &scene {
        Some(s) => s.volume().source.clone(),
        None => VolumeSource::from_path(&a.volume)?,
    };
    let volume = source.load(&Limits::default())?;
    let name = file_name(&volume.header.source);
    let norm = match &scene {
        Some(s) => volcast::pipeline::value_window(s.volume(), &s.path, &volume)?,
        None => volcast::pipeline::data_window(&volume)?,
    };
    let opts = Options {
        bins: usize::from(a.bins),
        gradient_bins: usize::from(a.gradient_bins),
        gradient_max: a.gradient_max,
        ..scene
            .as_ref()
            .map_or_else(Options::default, Options::for_scene)
    };
    let h = histogram::compute(&volume, norm, &opts)
        .with_context(|| format!("counting the histograms of {name}"))?;
    let overlays = scene.as_ref().map_or_else(Overlays::default, |s| {
        Overlays::of_scene(s, norm, volume.header.rescale)
    });
    let of = match &scene {
        Some(s) => format!("{name} (scene {})", file_name(&s.path.to_string_lossy())),
        None => name.clone(),
    };
    let [w0, w1] = h.window.map(plot::number);
    let value = plot::value_plot(
        &h,
        &overlays,
        &format!("value histogram of {of}: {} voxels", h.counted),
    )?;
    let gradient = plot::gradient_plot(
        &h,
        &overlays,
        &format!(
            "value x gradient magnitude of {of} ({} differences, window [{w0}, {w1}])",
            h.gradient.name()
        ),
    )?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("creating the output folder {}", a.out.display()))?;
    let (csv, csv_2d) = (h.csv(), h.csv_2d());
    let files: [(&str, &[u8]); 4] = [
        ("histogram.png", &value.png),
        ("histogram2d.png", &gradient.png),
        ("histogram.csv", csv.as_bytes()),
        ("histogram2d.csv", csv_2d.as_bytes()),
    ];
    let mut written = Vec::new();
    for (file, bytes) in files {
        let path = a.out.join(file);
        volcast::output::write_atomic(&path, bytes)
            .with_context(|| format!("writing {}", path.display()))?;
        written.push(path.display().to_string());
    }
    let [v0, v1] = h.value_range.map(plot::number);
    let mut text = format!(
        "volcast: {} voxels of {name} counted: values {v0} .. {v1} (data units, {} bins), gradient magnitudes 0 .. {} (normalised value per voxel of the smallest spacing, window [{w0}, {w1}], {} differences, {} bins)\n",
        h.counted,
        h.bins(),
        plot::number(h.gradient_range[1]),
        h.gradient.name(),
        h.gradient_bins,
    );
    if h.non_finite > 0 {
        text.push_str(&format!(
            "volcast: {} voxels are NaN or infinite and not counted\n",
            h.non_finite
        ));
    }
    text.push_str(&format!("volcast: wrote {}\n", written.join(", ")));
    super::print(&text)?;
    Ok(ExitCode::SUCCESS)
}

/// The last component of a path as text.
fn file_name(path: &str) -> String {
    Path::new(path)
        .file_name()
        .map_or_else(|| path.to_string(), |n| n.to_string_lossy().into_owned())
}
