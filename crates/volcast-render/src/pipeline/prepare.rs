//! The value normalisation of a run: the scene's window, or the data's range.

use std::path::{Path, PathBuf};

use crate::error::Error;
use crate::output::display::Window;
use crate::sample::Normalize;
use crate::scene::VolumeSpec;
use crate::volume::{Stats, Volume, VolumeError};

/// The normalisation of the value window of `spec` (the `[volume]` of the scene
/// file `scene`), or of the data's finite range. Both are in the volume's physical
/// values (its [`Rescale`](crate::volume::Rescale) folded in: the voxels keep their
/// stored values, the window is mapped to them).
pub fn value_window(spec: &VolumeSpec, scene: &Path, volume: &Volume) -> Result<Normalize, Error> {
    let rescale = volume.header.rescale;
    if let Some(window) = spec.window {
        let [lo, hi] = rescale.stored_window(window);
        return Normalize::checked(lo, hi).ok_or_else(|| Error::Plan {
            scene: scene.to_path_buf(),
            message: format!(
                "[volume] window = [{:e}, {:e}] is [{lo:e}, {hi:e}] in the stored values of {} (rescale slope {:e}, intercept {:e}), whose width overflows: give a narrower window",
                window[0], window[1], volume.header.source, rescale.slope, rescale.intercept
            ),
        });
    }
    data_window(volume).map_err(|e| Error::Plan {
        scene: scene.to_path_buf(),
        message: e.to_string(),
    })
}

/// The normalisation of the data's finite range, in its physical values (what a
/// scene without `[volume] window` renders with). An error when no value is finite,
/// or when the range is wider than an f64 holds (values near the f64 limits).
pub fn data_window(volume: &Volume) -> Result<Normalize, VolumeError> {
    let stats = Stats::of(&volume.data);
    let err = |message: String| VolumeError::Data {
        path: PathBuf::from(&volume.header.source),
        message,
    };
    if stats.finite == 0 {
        return Err(err(
            "the volume has no finite values to take a window from".into()
        ));
    }
    let w = Window::from_range(stats.min, stats.max);
    let [lo, hi] = volume.header.rescale.stored_range_window([w.lo, w.hi]);
    Normalize::checked(lo, hi).ok_or_else(|| {
        err(format!(
            "the values span [{:e}, {:e}], a width that overflows: give `[volume] window` a narrower range (values outside it are clamped to its ends)",
            stats.min, stats.max
        ))
    })
}
