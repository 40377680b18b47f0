//! Atomic file writes: the bytes go to a temporary file in the destination folder,
//! which is then renamed over the destination, so an interrupted run never leaves a
//! truncated image under a final name.
//!
//! Temporary files are named `.{name}.{pid}@{host}.tmp`. A killed run can leave
//! them behind; [`remove_stale_temporaries`] deletes those of processes that are
//! gone (same host, process no longer running) or that nobody has written to for
//! an hour (a shard on another machine of a cluster).

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, SystemTime};

/// Writes `bytes` to `path` atomically (same-folder temporary file, fsync, rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Writes `path` atomically from a writer callback (for files too large to hold
/// in memory, such as animations): `fill` writes into a buffered temporary file,
/// which is synced and renamed over `path` only if `fill` succeeds.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let tmp = temporary_path(path);
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut w = BufWriter::new(file);
        fill(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// The temporary name `write_atomic` uses for `path`.
fn temporary_path(path: &Path) -> PathBuf {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    dir.join(format!(
        ".{name}.{}@{}.tmp",
        std::process::id(),
        host_name()
    ))
}

/// This machine's name, reduced to characters safe in a file name.
fn host_name() -> &'static str {
    static HOST: OnceLock<String> = OnceLock::new();
    HOST.get_or_init(|| {
        let raw = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .ok()
            .or_else(|| std::env::var("HOSTNAME").ok())
            .or_else(|| std::env::var("COMPUTERNAME").ok())
            .unwrap_or_default();
        let clean: String = raw
            .trim()
            .chars()
            .filter(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
            .collect();
        if clean.is_empty() {
            "localhost".into()
        } else {
            clean
        }
    })
}

/// Splits one of our temporary names into (pid, host).
fn parse_temporary(name: &str) -> Option<(u32, &str)> {
    let rest = name.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (front, host) = rest.rsplit_once('@')?;
    let (_, pid) = front.rsplit_once('.')?;
    Some((pid.parse().ok()?, host))
}

/// Whether process `pid` of this machine may still be running (`true` where that
/// cannot be told).
fn may_be_running(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    let proc = Path::new("/proc");
    if proc.join("self").exists() {
        proc.join(pid.to_string()).exists()
    } else {
        true
    }
}

/// Removes the temporary files of our own naming in `dir` that no running process
/// will finish: those of this machine whose process has ended, and any not written
/// to for an hour. Returns how many were removed. Other files are never touched.
pub fn remove_stale_temporaries(dir: &Path) -> std::io::Result<usize> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(e),
    };
    let mut removed = 0;
    for entry in entries {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some((pid, host)) = parse_temporary(&name) else {
            continue;
        };
        let old = entry
            .metadata()
            .and_then(|m| m.modified())
            .ok()
            .and_then(|t| SystemTime::now().duration_since(t).ok())
            .is_some_and(|age| age > Duration::from_secs(3600));
        let orphan = host == host_name() && !may_be_running(pid);
        if (old || orphan) && entry.file_type()?.is_file() {
            match std::fs::remove_file(entry.path()) {
                Ok(()) => removed += 1,
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(e),
            }
        }
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_and_leaves_no_temporary() {
        let dir = std::env::temp_dir().join(format!("volcast-write-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("a.bin");
        write_atomic(&p, b"hello").unwrap();
        write_atomic(&p, b"bye").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"bye");
        // a failing writer leaves the old file and no temporary
        let e = write_atomic_with(&p, |w| {
            w.write_all(b"partial")?;
            Err(std::io::Error::other("interrupted"))
        });
        assert!(e.is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"bye");
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn stale_temporaries_are_removed_and_others_kept() {
        let dir = std::env::temp_dir().join(format!("volcast-stale-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let own = temporary_path(&dir.join("mine.png"));
        assert_eq!(
            parse_temporary(&own.file_name().unwrap().to_string_lossy()),
            Some((std::process::id(), host_name()))
        );
        // pid 4294967295 cannot be running (Linux pids are below 2^22)
        let dead = dir.join(format!(".a_0001.png.4294967295@{}.tmp", host_name()));
        let elsewhere = dir.join(".a_0002.png.4294967295@some-other-host.tmp");
        let unrelated = dir.join(".notes.tmp");
        for p in [&own, &dead, &elsewhere, &unrelated] {
            std::fs::write(p, b"x").unwrap();
        }
        let n = remove_stale_temporaries(&dir).unwrap();
        let on_linux = Path::new("/proc/self").exists();
        assert_eq!(n, usize::from(on_linux));
        assert_eq!(dead.exists(), !on_linux);
        assert!(own.exists() && elsewhere.exists() && unrelated.exists());
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(remove_stale_temporaries(&dir).unwrap(), 0);
    }
}
