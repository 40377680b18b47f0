//! The value normalisation of a run: the scene's window, or the data's range.

use super::*;

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
