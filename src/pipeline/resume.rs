//! Which (pass, frame) images remain to be rendered (`--resume`), and what a run
//! does once its images are written: merge the manifest, assemble the animations.

use super::*;

/// How many (pass, frame) images of the plan's frames `--resume` would skip.
pub fn completed_images(scene: &Scene, header: &VolumeHeader, plan: &Plan) -> Result<usize, Error> {
    let digest = manifest::scene_digest(scene, header, plan.width, plan.height);
    Ok(completed(scene, plan, &digest)?.len())
}

/// The (pass, frame) images of the plan's frames that `--resume` may skip.
pub(super) fn completed(
    scene: &Scene,
    plan: &Plan,
    digest: &str,
) -> Result<HashSet<(usize, usize)>, Error> {
    let mut done = HashSet::new();
    for &k in &plan.frame_list {
        for (p, pass) in scene.passes.iter().enumerate() {
            if let Some(r) = manifest::read_record(&plan.out, &pass.name, k)? {
                if manifest::is_complete(&plan.out, &r, digest) {
                    done.insert((p, k));
                }
            }
        }
    }
    Ok(done)
}

/// The (pass, frame) images to render, frame by frame.
pub(super) fn jobs(
    scene: &Scene,
    plan: &Plan,
    done: &HashSet<(usize, usize)>,
) -> Vec<(usize, usize)> {
    plan.frame_list
        .iter()
        .flat_map(|&k| (0..scene.passes.len()).map(move |p| (p, k)))
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

/// The folders from `out` up that do not exist yet (innermost first), with the
/// records folder: what a run may create.
pub(super) fn missing_folders(out: &Path) -> Vec<PathBuf> {
    let mut missing = Vec::new();
    let mut p = Some(out);
    while let Some(dir) = p.filter(|d| !d.as_os_str().is_empty()) {
        if std::fs::symlink_metadata(dir).is_ok() {
            break;
        }
        missing.push(dir.to_path_buf());
        p = dir.parent();
    }
    if !missing.is_empty() {
        missing.insert(0, out.join(manifest::RECORDS));
    }
    missing
}

/// Removes those of `folders` (innermost first) that are empty; stops at the first
/// that is not (a run that failed after writing something keeps it).
pub(super) fn remove_empty_folders(folders: &[PathBuf]) {
    for dir in folders {
        if std::fs::remove_dir(dir).is_err() && dir.exists() {
            break;
        }
    }
}

/// The end of every run: remove stale temporaries, merge the manifest, and
/// assemble the animations when the sequence is complete and they are missing,
/// out of date, or this run wrote frames.
pub(super) fn finish(
    scene: &Scene,
    plan: &Plan,
    header: &VolumeHeader,
    digest: &str,
    summary: &mut Summary,
) -> Result<(), Error> {
    let out = &plan.out;
    // what the previous manifest says about the animations, before it is replaced
    let previous = manifest::read_manifest(out)?
        .and_then(|v| v.get("animation").and_then(|a| a.get("settings")).cloned());
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
    let sequences = animation::sequences(scene);
    let fps = scene.animation.as_ref().map_or(24.0, |a| a.fps);
    let ffmpeg: Vec<String> = if scene.image.format == Format::Nrrd {
        Vec::new()
    } else {
        sequences
            .iter()
            .map(|q| animation::ffmpeg_command(out, q, fps))
            .collect()
    };
    let settings = scene.animation.as_ref().map(|a| {
        json!({
            "formats": a.formats.iter().map(|f| f.extension()).collect::<Vec<_>>(),
            "fps": a.fps,
            "loop": a.looping,
        })
    });
    let mut head = ManifestHead {
        scene,
        header,
        digest,
        size: (plan.width, plan.height),
        extra: json!({ "ffmpeg": &ffmpeg }),
    };
    let status = manifest::write_manifest(out, &head)?;
    summary.notes.extend(
        status
            .unreadable
            .iter()
            .map(|u| format!("{u} (that frame counts as missing)")),
    );
    if let (Some(anim), true) = (&scene.animation, status.complete()) {
        let missing = sequences.iter().any(|q: &Sequence| {
            anim.formats
                .iter()
                .any(|&f| !q.animation_path(out, f).is_file())
        });
        let stale = previous.as_ref() != settings.as_ref();
        if summary.images > 0 || missing || stale {
            summary.animations = animation::assemble(out, scene, anim)?;
        }
        let files: Vec<serde_json::Value> = sequences
            .iter()
            .flat_map(|q| {
                anim.formats.iter().map(|&f| {
                    json!({
                        "file": q.animation_path(out, f).file_name().map(|n| n.to_string_lossy().into_owned()),
                        "format": f.extension(),
                        "frames": scene.orbit.frames,
                        "fps": match f {
                            crate::scene::AnimationFormat::Gif => 100.0 / animation::gif_delay(anim.fps) as f64,
                            crate::scene::AnimationFormat::Apng => anim.fps,
                        },
                    })
                })
            })
            .collect();
        head.extra = json!({
            "ffmpeg": head.extra["ffmpeg"],
            "animation": { "settings": settings, "files": files },
        });
        manifest::write_manifest(out, &head)?;
    }
    summary.manifest = Some(status);
    summary.ffmpeg = ffmpeg;
    Ok(())
}
