//! `volcast info`: header, sizes, type, geometry, value range and a histogram summary.

use std::fmt::Write as _;
use std::path::Path;
use std::process::ExitCode;
use volcast::number::shown;

use volcast::volume::{human_bytes, Limits, Stats, VolumeSource};

use super::args::InfoArgs;

pub fn run(a: InfoArgs) -> anyhow::Result<ExitCode> {
    let sources = sources_of(&a.volume)?;
    let mut limits = Limits::default();
    if let Some(m) = a.max_memory {
        limits.max_bytes = m;
    }
    if let [(_, source)] = sources.as_slice() {
        let (text, _) = describe(source, &limits, a.json)?;
        super::print(&text)?;
        return Ok(ExitCode::SUCCESS);
    }
    // a scene of several volumes: each one, under its name
    if a.json {
        let mut all = Vec::new();
        for (name, source) in &sources {
            let (_, mut json) = describe(source, &limits, true)?;
            if let serde_json::Value::Object(m) = &mut json {
                m.insert("name".into(), name.clone().into());
            }
            all.push(json);
        }
        let mut text = serde_json::to_string_pretty(&serde_json::json!({ "volumes": all }))?;
        text.push('\n');
        super::print(&text)?;
    } else {
        let mut text = String::new();
        for (k, (name, source)) in sources.iter().enumerate() {
            if k > 0 {
                text.push('\n');
            }
            writeln!(text, "volume     {name}")?;
            text += &describe(source, &limits, false)?.0;
        }
        super::print(&text)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// What `info` prints of one volume: the text (or the JSON text) and the JSON.
fn describe(
    source: &VolumeSource,
    limits: &Limits,
    json: bool,
) -> anyhow::Result<(String, serde_json::Value)> {
    let volume = source.load(limits)?;
    let h = &volume.header;
    let stats = Stats::of(&volume.data);
    let sp = h.geometry.spacings();
    let q = |x: f64| stats.quantile(x);
    // the physical values the stored range stands for (NIfTI scl_slope/scl_inter)
    let mut value_range = [stats.min, stats.max].map(|x| h.rescale.apply(x));
    value_range.sort_by(f64::total_cmp);
    if json {
        let json = volcast::volume::info::json(&volume);
        let mut text = serde_json::to_string_pretty(&json)?;
        text.push('\n');
        return Ok((text, json));
    }
    let mut s = String::new();
    let [nx, ny, nz] = h.sizes;
    writeln!(s, "source     {}", h.source)?;
    writeln!(
        s,
        "sizes      {nx} x {ny} x {nz} ({} voxels)",
        h.voxel_count()
    )?;
    match volume.data.mapped() {
        Some(m) => writeln!(
            s,
            "type       {} ({} mapped from {})",
            h.scalar_type,
            human_bytes(h.data_bytes()),
            m.path().display()
        )?,
        None => writeln!(
            s,
            "type       {} ({} in memory)",
            h.scalar_type,
            human_bytes(h.data_bytes())
        )?,
    }
    writeln!(
        s,
        "spacing    {} {} {}",
        shown(sp[0]),
        shown(sp[1]),
        shown(sp[2])
    )?;
    let o = h.geometry.origin;
    writeln!(s, "origin     {} {} {}", shown(o.x), shown(o.y), shown(o.z))?;
    let ax = h.geometry.axes;
    writeln!(
        s,
        "axes       ({}, {}, {}) ({}, {}, {}) ({}, {}, {})",
        shown(ax[0].x),
        shown(ax[0].y),
        shown(ax[0].z),
        shown(ax[1].x),
        shown(ax[1].y),
        shown(ax[1].z),
        shown(ax[2].x),
        shown(ax[2].y),
        shown(ax[2].z)
    )?;
    writeln!(
        s,
        "range      {} .. {} (mean {})",
        shown(stats.min),
        shown(stats.max),
        fixed6(stats.mean)
    )?;
    if !h.rescale.is_identity() {
        writeln!(
            s,
            "values     {} .. {} (= {} * stored + {}: the units of windows and of units = \"data\")",
            shown(value_range[0]),
            shown(value_range[1]),
            shown(h.rescale.slope),
            shown(h.rescale.intercept)
        )?;
    }
    if stats.non_finite > 0 {
        writeln!(
            s,
            "non-finite {} voxels (NaN or infinite; ignored above)",
            stats.non_finite
        )?;
    }
    writeln!(
        s,
        "percentile 1%: {}  50%: {}  99%: {} (histogram bin centres)",
        fixed6(q(0.01)),
        fixed6(q(0.5)),
        fixed6(q(0.99))
    )?;
    writeln!(s, "histogram  {}", sparkline(&stats.histogram))?;
    for (k, v) in &h.fields {
        writeln!(s, "{k:<10} {v}")?;
    }
    Ok((s, serde_json::Value::Null))
}

/// `x` with six decimals, in exponent form (seven digits) where that would be a
/// long run of digits or zeros.
fn fixed6(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-3..1e15).contains(&x.abs()) {
        format!("{x:.6}")
    } else {
        format!("{x:.6e}")
    }
}

/// Whether `path` names a scene file (`.toml`) rather than a volume.
pub(super) fn is_scene(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
}

/// The volumes a path names, with their names: a volume file (NRRD, NIfTI,
/// MetaImage, ...), or the `[volume]` (or each `[[volume]]`) of a scene file.
fn sources_of(path: &Path) -> anyhow::Result<Vec<(String, VolumeSource)>> {
    if is_scene(path) {
        let scene = volcast::scene::load(path)?;
        Ok(scene
            .volumes
            .into_iter()
            .map(|v| (v.name, v.spec.source))
            .collect())
    } else {
        Ok(vec![(String::new(), VolumeSource::from_path(path)?)])
    }
}

/// A one-line histogram, log-scaled so small populations stay visible.
fn sparkline(h: &[u64]) -> String {
    const BARS: [char; 8] = ['▁', '▂', '▃', '▄', '▅', '▆', '▇', '█'];
    let max = h.iter().copied().max().unwrap_or(0);
    if max == 0 {
        return String::new();
    }
    let lmax = (max as f64).ln_1p();
    h.iter()
        .map(|&c| {
            if c == 0 {
                ' '
            } else {
                BARS[(((c as f64).ln_1p() / lmax) * 7.0).round() as usize]
            }
        })
        .collect()
}
