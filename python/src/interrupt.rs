//! Long calls on a worker thread with the GIL released: Ctrl-C and progress callbacks.

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Duration;

/// A Python progress callback `progress(done, total)` and the count the search updates.
pub(crate) struct Progress {
    pub(crate) callback: Py<PyAny>,
    pub(crate) done: Arc<AtomicUsize>,
    pub(crate) total: usize,
}

impl Progress {
    /// Call the callback if the count moved since `last`.
    fn report(&self, py: Python<'_>, last: &mut usize) -> PyResult<()> {
        let now = self.done.load(Ordering::Relaxed);
        if now != *last {
            *last = now;
            self.callback.call1(py, (now, self.total))?;
        }
        Ok(())
    }
}

/// Run `work` on a scoped worker thread with the GIL released, polling for signals and
/// reporting progress; on Ctrl-C (or an exception in the callback) set `cancel`, wait for the
/// worker and raise.
pub(crate) fn run_interruptible<T: Send>(
    py: Python<'_>,
    cancel: &Arc<AtomicBool>,
    progress: Option<&Progress>,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    std::thread::scope(|scope| {
        let (tx, rx) = mpsc::channel();
        // A Receiver is not Sync; the mutex lets the GIL-free closures borrow it.
        let rx = std::sync::Mutex::new(rx);
        scope.spawn(move || {
            let _ = tx.send(work());
        });
        let mut last = 0;
        loop {
            let got = py.detach(|| {
                rx.lock()
                    .expect("only this thread locks it")
                    .recv_timeout(Duration::from_millis(50))
            });
            match got {
                Ok(v) => {
                    if let Some(p) = progress {
                        p.report(py, &mut last)?;
                    }
                    return Ok(v);
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    let polled = py
                        .check_signals()
                        .and_then(|_| progress.map_or(Ok(()), |p| p.report(py, &mut last)));
                    if let Err(e) = polled {
                        cancel.store(true, Ordering::Relaxed);
                        // The worker stops at its next rotation; drain it before raising.
                        let _ = py.detach(|| rx.lock().expect("only this thread").recv());
                        return Err(e);
                    }
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(PyRuntimeError::new_err("the registration thread panicked"))
                }
            }
        }
    })
}
