//! The volumes of a run: those a pass reads, loaded with the identity of their
//! voxels (what the manifest records and `--resume` compares), and each one's
//! value normalisation.

use std::borrow::Borrow;

use crate::error::Error;
use crate::plan::Plan;
use crate::sample::Normalize;
use crate::volume::{FileStamp, Limits, Volume, VolumeIdentity};

use super::prepare::value_window;

/// The run's volumes in the plan's order, loaded where a pass reads them.
pub(crate) type Volumes = Vec<Option<Volume>>;

/// Loads every volume a pass reads.
pub(super) fn load(plan: &Plan, limits: &Limits) -> Result<Volumes, Error> {
    plan.volumes
        .iter()
        .map(|v| {
            v.is_read()
                .then(|| v.spec.source.load(limits).map_err(Error::from))
                .transpose()
        })
        .collect()
}

/// Loads every volume a pass reads, with the identity of all their voxels: one
/// volume's own, or, for several, their hashes joined and their files in order.
pub(super) fn load_identified(
    plan: &Plan,
    limits: &Limits,
) -> Result<(Volumes, VolumeIdentity), Error> {
    let mut volumes = Vec::with_capacity(plan.volumes.len());
    let mut identities = Vec::new();
    for v in &plan.volumes {
        if !v.is_read() {
            volumes.push(None);
            continue;
        }
        let (volume, identity) = v.spec.source.load_identified(limits)?;
        volumes.push(Some(volume));
        identities.push(identity);
    }
    Ok((volumes, joined(identities)))
}

/// The identity of several volumes' voxels as one.
fn joined(mut identities: Vec<VolumeIdentity>) -> VolumeIdentity {
    if identities.len() == 1 {
        return identities.remove(0);
    }
    let hashes: Vec<String> = identities
        .iter()
        .map(|i| i.data_xxh3.clone().unwrap_or_else(|| "-".into()))
        .collect();
    VolumeIdentity {
        data_xxh3: identities
            .iter()
            .any(|i| i.data_xxh3.is_some())
            .then(|| hashes.join("+")),
        files: identities.into_iter().flat_map(|i| i.files).collect(),
    }
}

/// Whether every volume a pass reads is a synthetic field (its scene defines it).
pub(super) fn all_synthetic(plan: &Plan) -> bool {
    plan.volumes
        .iter()
        .filter(|v| v.is_read())
        .all(|v| v.spec.source.is_synthetic())
}

/// The files every volume a pass reads would read, stamped now, in order.
pub(super) fn stamps(plan: &Plan) -> Result<Vec<FileStamp>, Error> {
    let mut all = Vec::new();
    for v in plan.volumes.iter().filter(|v| v.is_read()) {
        all.extend(v.spec.source.stamps()?);
    }
    Ok(all)
}

/// Each loaded volume's value normalisation: its window, or its data's range.
pub(super) fn norms<V: Borrow<Volume>>(
    plan: &Plan,
    volumes: &[Option<V>],
) -> Result<Vec<Option<Normalize>>, Error> {
    plan.volumes
        .iter()
        .zip(volumes)
        .map(|(v, loaded)| {
            loaded
                .as_ref()
                .map(|volume| value_window(&v.spec, &plan.scene.file, volume.borrow()))
                .transpose()
        })
        .collect()
}
