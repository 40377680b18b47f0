//! Confinement of the files a run reads (`--confine DIR`): when rendering scenes and
//! volumes from anyone (course submissions, a shared service), the volume's path,
//! every NRRD `data file` and the output folder must lie under one folder, after
//! resolving `..` and symbolic links. Without it, a header's `data file:
//! /etc/passwd` with `byte skip: -1` renders that file's bytes into an image.
//!
//! Two layers:
//!
//! - [`check_source`] and [`check_output`] resolve every path before anything is
//!   read or created, and refuse one outside the folder with a message naming it;
//! - while a [`Scope`] is active on a thread, every volume file opened on it is
//!   checked again after opening, by the path the kernel reports for the open file
//!   (`/proc/self/fd`), so a link swapped in between the check and the open cannot
//!   lead outside either. (Volumes are loaded on the calling thread.)

use std::io;
use std::path::{Component, Path, PathBuf};

use super::mapped::set_confinement;
use super::{VolumeError, VolumeSource};

/// The folder every input must lie in, resolved (absolute, no links).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Root(PathBuf);

impl Root {
    /// Resolves `dir`, which must be an existing folder.
    pub fn new(dir: &Path) -> Result<Root, VolumeError> {
        let real = dir.canonicalize().map_err(|source| VolumeError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
        if !real.is_dir() {
            return Err(VolumeError::Invalid(format!(
                "--confine {}: not a folder",
                dir.display()
            )));
        }
        Ok(Root(real))
    }

    /// The resolved folder.
    pub fn path(&self) -> &Path {
        &self.0
    }

    /// Whether the resolved path `real` lies in this folder.
    fn holds(&self, real: &Path) -> bool {
        real.starts_with(&self.0)
    }

    fn outside(&self, path: &Path, real: &Path, what: &str) -> VolumeError {
        VolumeError::Outside {
            path: path.to_path_buf(),
            what: what.to_string(),
            real: real.to_path_buf(),
            root: self.0.clone(),
        }
    }

    /// An error unless the existing file `path` (`what` it is) resolves into this
    /// folder. A path that does not exist is left to the reader, which reports it.
    pub fn check_file(&self, path: &Path, what: &str) -> Result<(), VolumeError> {
        match path.canonicalize() {
            Ok(real) if self.holds(&real) => Ok(()),
            Ok(real) => Err(self.outside(path, &real, what)),
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
            Err(source) => Err(VolumeError::Io {
                path: path.to_path_buf(),
                source,
            }),
        }
    }
}

/// Every file of `source` (the volume's path, the data files a NRRD or MetaImage
/// header names) must lie in `root`. Reads a header only after its own path was
/// checked.
pub fn check_source(source: &VolumeSource, root: &Root) -> Result<(), VolumeError> {
    let Some(path) = source.path() else {
        return Ok(());
    };
    if matches!(source, VolumeSource::Raw(_)) {
        return root.check_file(path, "the raw volume");
    }
    root.check_file(path, "the volume")?;
    let _scope = Scope::enter(root);
    let files = source.input_files()?;
    // the first file of the others is the volume's path, checked above; a DICOM
    // series and a TIFF folder or glob list only their slices' files
    let skip = usize::from(!matches!(
        source,
        VolumeSource::Dicom(_) | VolumeSource::Tiff(_)
    ));
    for f in files.iter().skip(skip) {
        root.check_file(f, &format!("a data file named by {}", path.display()))?;
    }
    Ok(())
}

/// The folder `out` (which may not exist yet) must lie in `root`: its longest
/// existing ancestor is resolved, and the rest applied to it (`..` included).
pub fn check_output(out: &Path, root: &Root) -> Result<(), VolumeError> {
    let absolute = if out.is_absolute() {
        out.to_path_buf()
    } else {
        std::env::current_dir()
            .map_err(|source| VolumeError::Io {
                path: out.to_path_buf(),
                source,
            })?
            .join(out)
    };
    let mut existing = absolute.as_path();
    let mut rest: Vec<Component> = Vec::new();
    let base = loop {
        match existing.canonicalize() {
            Ok(real) => break real,
            Err(_) => {
                let Some(parent) = existing.parent() else {
                    break PathBuf::from("/");
                };
                if let Some(c) = existing.components().next_back() {
                    rest.push(c);
                }
                existing = parent;
            }
        }
    };
    let mut real = base;
    for c in rest.iter().rev() {
        match c {
            Component::ParentDir => {
                real.pop();
            }
            Component::Normal(n) => real.push(n),
            _ => {}
        }
    }
    if root.holds(&real) {
        Ok(())
    } else {
        Err(root.outside(out, &real, "the output folder"))
    }
}

/// While alive, every volume file opened on this thread must resolve into the root
/// (checked on the open file); dropping it ends that.
pub struct Scope {
    previous: Option<PathBuf>,
}

impl Scope {
    /// Confines this thread's volume reads to `root` until the scope is dropped.
    pub fn enter(root: &Root) -> Scope {
        let previous = set_confinement(Some(root.0.clone()));
        Scope { previous }
    }
}

impl Drop for Scope {
    fn drop(&mut self) {
        set_confinement(self.previous.take());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::mapped::check_opened;
    use std::fs::File;

    #[test]
    fn output_folders_resolve_before_they_exist() {
        let tmp = tempfile::tempdir().unwrap();
        let root = Root::new(tmp.path()).unwrap();
        let d = tmp.path();
        assert!(check_output(&d.join("a/b/c"), &root).is_ok());
        assert!(check_output(&d.join("a/b/../../c"), &root).is_ok());
        assert!(check_output(&d.join("a/../../x"), &root).is_err());
        assert!(check_output(Path::new("/tmp/../etc/x"), &root).is_err());
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink("/", d.join("up")).unwrap();
            let e = check_output(&d.join("up/x"), &root)
                .unwrap_err()
                .to_string();
            assert!(e.contains("outside") && e.contains("--confine"), "{e}");
        }
    }

    #[cfg(unix)]
    #[test]
    fn opened_files_are_checked_in_scope_only() {
        let tmp = tempfile::tempdir().unwrap();
        let inner = tmp.path().join("in");
        std::fs::create_dir(&inner).unwrap();
        std::fs::write(tmp.path().join("secret"), b"x").unwrap();
        std::os::unix::fs::symlink(tmp.path().join("secret"), inner.join("link")).unwrap();
        let root = Root::new(&inner).unwrap();
        let open = |p: &Path| {
            let f = File::open(p).unwrap();
            check_opened(p, &f)
        };
        assert!(open(&inner.join("link")).is_ok(), "no scope, no check");
        {
            let _s = Scope::enter(&root);
            let e = open(&inner.join("link")).unwrap_err();
            assert!(e.to_string().contains("outside"), "{e}");
        }
        assert!(open(&inner.join("link")).is_ok(), "the scope ended");
    }
}
