//! The value normalisation of a run: the scene's window, or the data's range.

use std::path::Path;

use crate::error::Error;
use crate::output::display::Window;
use crate::sample::Normalize;
use crate::scene::VolumeSpec;
use crate::volume::{Stats, Volume};

/// The normalisation of the value window of `spec` (the `[volume]` of the scene
/// file `scene`), or of the data's finite range. Both are in the volume's physical
/// values (its [`Rescale`](crate::volume::Rescale) folded in: the voxels keep their
/// stored values, the window is mapped to them).
pub fn value_window(spec: &VolumeSpec, scene: &Path, volume: &Volume) -> Result<Normalize, Error> {
    let rescale = volume.header.rescale;
    if let Some(window) = spec.window {
        let [lo, hi] = rescale.stored_window(window);
        return Ok(Normalize::new(lo, hi));
    }
    data_window(volume).ok_or_else(|| Error::Plan {
        scene: scene.to_path_buf(),
        message: format!(
            "the volume {} has no finite values to take a window from",
            volume.header.source
        ),
    })
}

/// The normalisation of the data's finite range, in its physical values (what a
/// scene without `[volume] window` renders with); `None` when no value is finite.
pub fn data_window(volume: &Volume) -> Option<Normalize> {
    let stats = Stats::of(&volume.data);
    if stats.finite == 0 {
        return None;
    }
    let w = Window::from_range(stats.min, stats.max);
    let [lo, hi] = volume.header.rescale.stored_range_window([w.lo, w.hi]);
    Some(Normalize::new(lo, hi))
}
