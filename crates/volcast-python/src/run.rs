//! Runs on a thread of their own, the GIL released, cancelled by Ctrl-C.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use pyo3::prelude::*;
use volcast::pipeline::Progress;

/// Progress that tells the run to stop once `flag` is set.
struct Cancel<'a>(&'a AtomicBool);

impl Progress for Cancel<'_> {
    fn cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// How often the calling thread looks for a signal while the run goes on.
const POLL: Duration = Duration::from_millis(20);

/// Runs `f` on a thread of its own while this thread, without the GIL except to
/// look, polls `Python::check_signals`: a signal's exception (`KeyboardInterrupt`
/// for Ctrl-C) sets the flag `f`'s progress reports, waits for the run to stop
/// (between two views) and is raised; otherwise `f`'s result is returned.
pub fn cancellable<T: Send>(
    py: Python<'_>,
    f: impl FnOnce(&dyn Progress) -> T + Send,
) -> PyResult<T> {
    let flag = AtomicBool::new(false);
    std::thread::scope(|s| {
        let flag = &flag;
        let handle = std::thread::Builder::new()
            .name("volcast-run".into())
            .spawn_scoped(s, move || f(&Cancel(flag)))
            .map_err(|e| {
                pyo3::exceptions::PyRuntimeError::new_err(format!("starting a thread: {e}"))
            })?;
        loop {
            if handle.is_finished() {
                break;
            }
            py.detach(|| std::thread::sleep(POLL));
            if let Err(e) = py.check_signals() {
                flag.store(true, Ordering::Relaxed);
                // the run stops at its next view; its result (Cancelled) is dropped
                let _ = py.detach(|| handle.join());
                return Err(e);
            }
        }
        Ok(handle
            .join()
            .unwrap_or_else(|p| std::panic::resume_unwind(p)))
    })
}
