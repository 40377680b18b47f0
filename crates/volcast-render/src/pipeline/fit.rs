//! `[camera] zoom = "fit"`: one zoom for the whole sequence, computed from the voxels
//! once they are loaded. The box of the voxels at or above the fit threshold (voxel
//! centres, inside the crop; of each volume a pass reads, where the boxes of
//! several are framed together) is projected into every view of the sequence (every
//! frame and eye, at zoom 1): each view could be magnified until the box's corners
//! reach its image's edges, and the zoom is the smallest of these, less a margin of
//! 4 % per side, so the object is as large as it can be while every frame shows it
//! whole.

use std::borrow::Borrow;

use glam::DVec3;
use rayon::prelude::*;

use crate::error::Error;
use crate::plan::Plan;
use crate::sample::Normalize;
use crate::scene::Projection;
use crate::volume::Volume;

/// The plan of a run whose zoom is fitted to the voxels, and the note that says so.
pub(super) struct Fitted {
    /// The plan with the fitted zoom.
    pub plan: Plan,
    /// What the run reports about the zoom.
    pub note: String,
}

/// `zoom = "fit"`: the plan with the zoom that frames the voxels at or above the
/// fit threshold, found before anything is written (`None` for a plan with a zoom
/// of its own). An error when no voxel reaches the threshold.
pub(super) fn fit<V: Borrow<Volume>>(
    plan: &Plan,
    volumes: &[Option<V>],
    norms: &[Option<Normalize>],
) -> Result<Option<Fitted>, Error> {
    let Some(t) = plan.fit_threshold else {
        return Ok(None);
    };
    // the corners of each loaded volume's voxels at or above the threshold
    let mut corners = Vec::new();
    for ((v, loaded), norm) in plan.volumes.iter().zip(volumes).zip(norms) {
        if let (Some(volume), Some(norm)) = (loaded, norm) {
            corners.extend(
                voxel_box(v, t, volume.borrow(), *norm)
                    .into_iter()
                    .flatten(),
            );
        }
    }
    let Some(z) = zoom(plan, &corners) else {
        let sources: Vec<&str> = plan
            .volumes
            .iter()
            .filter(|v| v.is_read())
            .map(|v| v.header.source.as_str())
            .collect();
        return Err(Error::Plan {
            scene: plan.scene.file.clone(),
            message: format!(
                "[camera] zoom = \"fit\": no voxel of {} is at or above the fit threshold {t} (normalised): set `fit_threshold` lower, or give `zoom` a number",
                sources.join(", ")
            ),
        });
    };
    let mut fitted = plan.clone();
    fitted.views = fitted.views.with_zoom(z);
    fitted.check_views().map_err(|message| Error::Plan {
        scene: plan.scene.file.clone(),
        message: format!("[camera] zoom = \"fit\" ({z:e}): {message}"),
    })?;
    Ok(Some(Fitted {
        plan: fitted,
        note: format!("zoom = \"fit\": {z:.4}, framing the voxels at or above {t:.4} (normalised)"),
    }))
}

/// The world corners of the box of `v`'s voxels at or above threshold `t`
/// (normalised by `norm`; inside its crop), or `None` when no voxel reaches it.
fn voxel_box(
    v: &crate::plan::PlannedVolume,
    t: f64,
    volume: &Volume,
    norm: Normalize,
) -> Option<[DVec3; 8]> {
    let [nx, ny, nz] = volume.header.sizes;
    let crop = v
        .spec
        .crop
        .unwrap_or([[0, nx - 1], [0, ny - 1], [0, nz - 1]]);
    // voxels at zero threshold: strictly above the window's low end
    let hit = |v: f32| if t > 0.0 { f64::from(v) >= t } else { v > 0.0 };
    let boxes = (crop[2][0]..=crop[2][1])
        .into_par_iter()
        .filter_map(|k| {
            let mut b: Option<[[usize; 2]; 3]> = None;
            for j in crop[1][0]..=crop[1][1] {
                for i in crop[0][0]..=crop[0][1] {
                    if hit(norm.apply(volume.value(i, j, k))) {
                        let e = b.get_or_insert([[i, i], [j, j], [k, k]]);
                        for (a, x) in [i, j, k].into_iter().enumerate() {
                            e[a] = [e[a][0].min(x), e[a][1].max(x)];
                        }
                    }
                }
            }
            b
        })
        .reduce_with(|a, b| {
            std::array::from_fn(|x| [a[x][0].min(b[x][0]), a[x][1].max(b[x][1])])
        })?;
    // (where the volume sits: its geometry as the plan placed it)
    Some(v.header.geometry.box_corners(
        DVec3::from_array(boxes.map(|r| r[0] as f64)),
        DVec3::from_array(boxes.map(|r| r[1] as f64)),
    ))
}

/// The zoom that frames `corners` in every view, or `None` when there are none.
fn zoom(plan: &Plan, corners: &[DVec3]) -> Option<f64> {
    if corners.is_empty() {
        return None;
    }
    // every view of the sequence at zoom 1: how much larger it could be
    let views = &plan.views;
    let mut zoom = f64::INFINITY;
    for k in 0..views.orbit_frames() {
        for &e in views.eyes() {
            let v = views.view(views.key(k, e), plan.width, plan.height, plan.sphere);
            let (mut x, mut y) = (0.0f64, 0.0f64);
            for c in corners {
                let d = *c - v.eye;
                let (dx, dy) = (d.dot(v.right), d.dot(v.up));
                let (dx, dy) = match v.projection {
                    Projection::Orthographic => (dx, dy),
                    Projection::Perspective => {
                        // a corner behind (or at) the eye cannot be framed by zooming
                        let depth = d.dot(v.forward).max(1e-9 * v.distance);
                        (dx / depth, dy / depth)
                    }
                };
                x = x.max(dx.abs());
                y = y.max(dy.abs());
            }
            let fits = (v.half_width / x.max(1e-12)).min(v.half_height / y.max(1e-12));
            zoom = zoom.min(fits);
        }
    }
    Some(zoom / MARGIN)
}

/// Room left around the framed box: 4 % of the image on each side.
const MARGIN: f64 = 1.08;
