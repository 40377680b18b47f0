//! Which (pass, frame) images remain to be rendered (`--resume`), what identifies
//! the voxels they were rendered from, and what a run does once its images are
//! written: merge the manifest, assemble the animations, write the turntable page.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde_json::json;

use super::Summary;
use crate::error::Error;
use crate::output::manifest::{self, FrameRecord, ManifestHead, ManifestStatus};
use crate::output::{animation, frame_path, viewer, Outputs};
use crate::plan::Plan;
use crate::scene::Format;
use crate::volume::VolumeIdentity;

/// How many (pass, frame) images of the plan's frames `--resume` would skip, when
/// that can be told without reading the voxels: `None` when the volume's files
/// changed since the output folder's manifest recorded them (or it recorded none),
/// since only hashing the data can then tell which images still belong to it.
pub fn completed_images(plan: &Plan) -> Result<Option<usize>, Error> {
    let previous = manifest::read_manifest(&plan.out)?;
    let Some(identity) = trusted_identity(plan, previous.as_ref())? else {
        return Ok(None);
    };
    let digest = manifest::data_digest(&plan.scene.digest, identity.data_xxh3.as_deref());
    Ok(Some(completed(plan, &digest, &mut Vec::new())?.len()))
}

/// The identity of the voxels when it is known without reading them: synthetic
/// fields' (their scene defines them), or the one `manifest.json` recorded if every
/// file of the volumes the passes read still has the recorded size and
/// modification time.
pub(super) fn trusted_identity(
    plan: &Plan,
    previous: Option<&serde_json::Value>,
) -> Result<Option<VolumeIdentity>, Error> {
    if super::volumes::all_synthetic(plan) {
        return Ok(Some(VolumeIdentity {
            data_xxh3: None,
            files: Vec::new(),
        }));
    }
    // an array in memory has no files to stamp: its voxels are hashed
    if plan
        .volumes
        .iter()
        .any(|v| v.is_read() && matches!(v.spec.source, crate::volume::VolumeSource::Memory(_)))
    {
        return Ok(None);
    }
    let Some(recorded) = previous.and_then(manifest::recorded_identity) else {
        return Ok(None);
    };
    let now = super::volumes::stamps(plan)?;
    Ok((recorded.data_xxh3.is_some() && recorded.files == now).then_some(recorded))
}

/// The (pass, frame) images of the plan's frames that `--resume` may skip: those
/// whose record has `digest`, names the files the plan gives that (pass, frame),
/// and whose files all have the recorded size and SHA-256 (checked in parallel). A
/// record that cannot be read (empty, broken, not a record) counts as damaged: its
/// image is rendered again, and `notes` says so.
pub(super) fn completed(
    plan: &Plan,
    digest: &str,
    notes: &mut Vec<String>,
) -> Result<HashSet<(usize, usize)>, Error> {
    let keys: Vec<(usize, usize)> = plan
        .frame_list
        .iter()
        .flat_map(|&k| (0..plan.passes.len()).map(move |p| (p, k)))
        .collect();
    // Ok(None): to render; Err(note): a damaged record, to render
    let found: Vec<Result<Option<(usize, usize)>, String>> = keys
        .par_iter()
        .map(|&(p, k)| {
            let name = &plan.passes[p].name;
            let r = match manifest::read_record(&plan.out, name, k) {
                Ok(r) => r,
                Err(e @ Error::Manifest { .. }) => {
                    return Ok(Err(format!("{e}: that frame is rendered again")))
                }
                Err(e) => return Err(e),
            };
            let names = plan.output.file_names(name, k);
            if let Some(e) = r
                .as_ref()
                .and_then(|r| manifest::foreign_files(&plan.out, r, digest, &names))
            {
                return Ok(Err(e.to_string()));
            }
            Ok(Ok(r
                .filter(|r| manifest::is_complete(&plan.out, r, digest, &names))
                .map(|_| (p, k))))
        })
        .collect::<Result<_, Error>>()?;
    let mut done = HashSet::new();
    for f in found {
        match f {
            Ok(key) => done.extend(key),
            Err(note) => notes.push(note),
        }
    }
    Ok(done)
}

/// The (pass, frame) images to render, frame by frame.
pub(super) fn jobs(plan: &Plan, done: &HashSet<(usize, usize)>) -> Vec<(usize, usize)> {
    let passes = plan.passes.len();
    plan.frame_list
        .iter()
        .flat_map(|&k| (0..passes).map(move |p| (p, k)))
        .filter(|j| !done.contains(j))
        .collect()
}

/// Creates the output folder (following its path as given) and its records folder
/// (never through a link).
pub(super) fn create_folders(out: &Path) -> Result<(), Error> {
    std::fs::create_dir_all(out).map_err(|source| Error::Output {
        path: out.to_path_buf(),
        source,
    })?;
    manifest::records_folder(out).map(drop)
}

/// The folders on the way to `out` that do not exist yet (innermost first), with the
/// records folder: what a run may create. Every prefix of the path counts, so a path
/// through `..` (`new/{scene}/../../x`) lists the folders it creates on the way too.
pub(super) fn missing_folders(out: &Path) -> Vec<PathBuf> {
    let mut prefix = PathBuf::new();
    let mut missing = Vec::new();
    for c in out.components() {
        prefix.push(c);
        // `a/b/..` names `a`, listed already; `a/.` likewise
        if matches!(c, std::path::Component::Normal(_))
            && std::fs::symlink_metadata(&prefix).is_err()
        {
            missing.push(prefix.clone());
        }
    }
    missing.reverse();
    if !missing.is_empty() {
        missing.insert(0, out.join(manifest::RECORDS));
    }
    missing
}

/// Removes those of `folders` (innermost first) that are empty (a run that failed
/// after writing something keeps it, and the folders it is in).
pub(super) fn remove_empty_folders(folders: &[PathBuf]) {
    for dir in folders {
        let _ = std::fs::remove_dir(dir);
    }
}

/// The end of every run: remove stale temporaries, merge the manifest (written
/// once, whole), and assemble the animations when the sequence is complete and they
/// are missing, damaged or out of date: their bytes differ from their record, the
/// `[animation]` settings changed, or the frames they hold are not the frames now.
/// The turntable page is written from the merged records whenever the sequence is
/// complete (it is small, and the same records give the same bytes).
pub(super) fn finish(
    plan: &Plan,
    identity: &VolumeIdentity,
    digest: &str,
    summary: &mut Summary,
) -> Result<(), Error> {
    let out = &plan.out;
    // what the previous manifest says about the animations, before it is replaced
    let previous = manifest::read_manifest(out)?;
    let previous_animation = previous.as_ref().and_then(|v| v.get("animation")).cloned();
    create_folders(out)?;
    let mut removed = 0;
    for (dir, folder) in [
        (out.clone(), manifest::out_folder(out)?),
        (out.join(manifest::RECORDS), manifest::records_folder(out)?),
    ] {
        removed += folder
            .remove_stale_temporaries()
            .map_err(|source| Error::Output { path: dir, source })?;
    }
    if removed > 0 {
        summary.notes.push(format!(
            "removed {removed} temporary file(s) left by an interrupted run"
        ));
    }
    let outputs = &plan.output;
    let sequences = outputs.sequences();
    let fps = outputs.animation.as_ref().map_or(24.0, |a| a.fps);
    // (no hint when the run writes the MP4 itself)
    let writes_mp4 = outputs
        .animation
        .as_ref()
        .is_some_and(|a| a.formats.contains(&crate::scene::AnimationFormat::Mp4));
    let ffmpeg: Vec<String> = if outputs.format == Format::Nrrd || writes_mp4 {
        Vec::new()
    } else {
        sequences
            .iter()
            .map(|q| animation::ffmpeg_command(out, q, fps))
            .collect()
    };
    let head = ManifestHead {
        scene: &plan.scene,
        outputs,
        headers: plan
            .volumes
            .iter()
            .map(|v| (v.name.as_str(), &v.header))
            .collect(),
        identity,
        digest,
        size: (plan.width, plan.height),
    };
    let folder = manifest::out_folder(out)?;
    let mut assembled: Vec<animation::Written> = Vec::new();
    let mut page = None;
    let mut extra = |status: &ManifestStatus, records: &[FrameRecord]| {
        let mut e = json!({ "ffmpeg": &ffmpeg });
        if plan.viewer && status.complete() {
            let size = (plan.width, plan.height);
            page = Some(viewer::write_page(&folder, out, outputs, size, records)?);
            e["viewer"] = json!(viewer::PAGE);
        }
        if let (Some(anim), true) = (&outputs.animation, status.complete()) {
            let entries = animation_entries(
                outputs,
                anim,
                out,
                &folder,
                records,
                previous_animation.as_ref(),
                &mut assembled,
            )?;
            e["animation"] = entries;
        }
        Ok(e)
    };
    let status = manifest::write_manifest(out, &head, &mut extra)?;
    summary.notes.extend(
        status.unreadable.iter().map(|u| {
            format!("{u}: that frame counts as missing (render --resume renders it again)")
        }),
    );
    summary.animations = assembled;
    summary.viewer = page;
    summary.manifest = Some(status);
    summary.ffmpeg = ffmpeg;
    Ok(())
}

/// The `animation` entry of the manifest for a complete sequence: the settings and,
/// per animation file, its size and SHA-256 and the SHA-256 of the frames' hashes it
/// was made from. Assembles the animations first (into `assembled`) unless every
/// file already matches such an entry of `previous` for the same settings and
/// frames.
fn animation_entries(
    outputs: &Outputs,
    anim: &crate::scene::Animation,
    out: &Path,
    folder: &crate::output::write::Folder,
    records: &[FrameRecord],
    previous: Option<&serde_json::Value>,
    assembled: &mut Vec<animation::Written>,
) -> Result<serde_json::Value, Error> {
    let mut settings = json!({
        "formats": anim.formats.iter().map(|f| f.extension()).collect::<Vec<_>>(),
        "fps": anim.fps,
        "loop": anim.looping,
    });
    // (present only when used, so that older manifests' settings still match)
    if let serde_json::Value::Object(m) = &mut settings {
        if let Some(q) = anim.quality {
            m.insert("quality".into(), json!(q));
        }
        if anim.ping_pong {
            m.insert("ping_pong".into(), json!(true));
        }
    }
    // the SHA-256 of each frame file, by name
    let frame_hashes: HashMap<&str, &str> = records
        .iter()
        .flat_map(|r| r.files.iter().map(|f| (f.name.as_str(), f.sha256.as_str())))
        .collect();
    let mut wanted: Vec<(String, crate::scene::AnimationFormat, String)> = Vec::new();
    for q in outputs.sequences() {
        let names: Vec<String> = (0..outputs.frames)
            .map(|k| {
                frame_path(out, &q.pass, k, q.eye, "png")
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default()
            })
            .collect();
        let frames = manifest::digest_of_list(
            names
                .iter()
                .map(|n| frame_hashes.get(n.as_str()).copied().unwrap_or("missing")),
        );
        for &f in &anim.formats {
            let file = q
                .animation_path(out, f)
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            wanted.push((file, f, frames.clone()));
        }
    }
    let recorded = |file: &str| -> Option<&serde_json::Value> {
        previous?
            .get("files")?
            .as_array()?
            .iter()
            .find(|e| e.get("file").and_then(|v| v.as_str()) == Some(file))
    };
    let same_settings = previous.and_then(|p| p.get("settings")) == Some(&settings);
    let made_now = |file: &str, frames: &str| {
        assembled.iter().any(|w| {
            w.path
                .file_name()
                .is_some_and(|n| n.to_string_lossy() == file)
                && w.frames_sha256.as_deref() == Some(frames)
        })
    };
    let up_to_date = wanted.iter().all(|(file, _, frames)| {
        made_now(file, frames)
            || (same_settings
                && recorded(file).is_some_and(|e| {
                    e.get("frames_sha256").and_then(|v| v.as_str()) == Some(frames.as_str())
                        && match (
                            e.get("bytes").and_then(|v| v.as_u64()),
                            e.get("sha256").and_then(|v| v.as_str()),
                        ) {
                            (Some(b), Some(h)) => manifest::file_matches(folder, file, b, h),
                            _ => false,
                        }
                }))
    });
    if !up_to_date {
        let mut written = animation::assemble(out, outputs, anim)?;
        for w in &mut written {
            let name = w
                .path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            w.frames_sha256 = wanted
                .iter()
                .find(|(file, _, _)| *file == name)
                .map(|(_, _, frames)| frames.clone());
        }
        *assembled = written;
    }
    let mut files = Vec::new();
    for (file, format, frames) in &wanted {
        let (bytes, sha256) = manifest::hash_file(folder, file).map_err(|source| Error::Read {
            path: out.join(file),
            source,
        })?;
        files.push(json!({
            "file": file,
            "format": format.extension(),
            "frames": animation::played(outputs.frames, anim.ping_pong).len(),
            "fps": match format {
                crate::scene::AnimationFormat::Gif => 100.0 / animation::gif_delay(anim.fps) as f64,
                crate::scene::AnimationFormat::Apng
                | crate::scene::AnimationFormat::Mp4
                | crate::scene::AnimationFormat::Webm => anim.fps,
            },
            "bytes": bytes,
            "sha256": sha256,
            "frames_sha256": frames,
        }));
    }
    Ok(json!({ "settings": settings, "files": files }))
}
