//! What `volcast info --json` prints about a loaded volume (and the Python module's
//! `volcast.info` returns): header, type, geometry, value range, percentiles and
//! the histogram of [`Stats`].

use serde_json::{json, Value};

use super::{Stats, Volume, VolumeData};

/// The `info --json` object of `volume` (non-finite statistics as `null`).
pub fn json(volume: &Volume) -> Value {
    let h = &volume.header;
    let stats = Stats::of(&volume.data);
    let sp = h.geometry.spacings();
    let q = |x: f64| stats.quantile(x);
    // the physical values the stored range stands for (NIfTI scl_slope/scl_inter)
    let mut value_range = [stats.min, stats.max].map(|x| h.rescale.apply(x));
    value_range.sort_by(f64::total_cmp);
    let storage = match &volume.data {
        VolumeData::Mapped(_) => "mapped",
        VolumeData::Shared(_) => "memory",
        _ => "read",
    };
    json!({
        "source": h.source,
        "sizes": h.sizes,
        "type": h.scalar_type.nrrd_name(),
        "bytes": h.data_bytes(),
        "storage": storage,
        "spacing": sp,
        "origin": h.geometry.origin.to_array(),
        "axes": h.geometry.axes.map(|a| a.to_array()),
        "min": finite_or_null(stats.min),
        "max": finite_or_null(stats.max),
        "mean": finite_or_null(stats.mean),
        "finite": stats.finite,
        "non_finite": stats.non_finite,
        "percentiles": { "1": finite_or_null(q(0.01)), "50": finite_or_null(q(0.5)), "99": finite_or_null(q(0.99)) },
        "histogram": { "bins": stats.histogram.len(), "min": finite_or_null(stats.min), "max": finite_or_null(stats.max), "counts": stats.histogram },
        "rescale": { "slope": h.rescale.slope, "intercept": h.rescale.intercept },
        "value_min": finite_or_null(value_range[0]),
        "value_max": finite_or_null(value_range[1]),
        "fields": h.fields.iter().map(|(k, v)| (k.clone(), Value::String(v.clone()))).collect::<serde_json::Map<_, _>>(),
    })
}

fn finite_or_null(x: f64) -> Value {
    if x.is_finite() {
        json!(x)
    } else {
        Value::Null
    }
}
