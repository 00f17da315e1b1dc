//! Running a long engine call from Python: on a thread of its own, the GIL released, progress
//! passed to an optional callback on the calling thread, stopped by a [`CancelToken`], by Ctrl-C
//! (`PyErr_CheckSignals`, on the main thread) or by an exception raised in the callback.

use std::sync::Mutex;
use std::time::Duration;

use meshmatch::work::{self, Event};
use pyo3::prelude::*;

/// How often the calling thread wakes to report progress and check for Ctrl-C.
const POLL: Duration = Duration::from_millis(50);

/// A flag that stops a running meshmatch call: pass it as `cancel=` and call `cancel()` from
/// another thread (a Blender modal operator's Esc, a GUI button). The call then raises
/// `meshmatch.Cancelled`. A token stays cancelled; make a new one for the next call.
#[pyclass(module = "meshmatch", name = "CancelToken", frozen)]
pub struct CancelToken {
    pub(crate) inner: work::CancelToken,
}

#[pymethods]
impl CancelToken {
    #[new]
    fn new() -> Self {
        CancelToken {
            inner: work::CancelToken::new(),
        }
    }

    /// Ask the running call (and every later call given this token) to stop.
    fn cancel(&self) {
        self.inner.cancel();
    }

    /// Whether `cancel()` was called.
    #[getter]
    fn cancelled(&self) -> bool {
        self.inner.is_cancelled()
    }

    fn __repr__(&self) -> String {
        format!("CancelToken(cancelled={})", self.inner.is_cancelled())
    }
}

/// The newest progress the job reported, not yet passed to the callback.
#[derive(Default)]
struct Latest(Mutex<Option<(f32, &'static str)>>);

impl Latest {
    fn set(&self, fraction: f32, stage: &'static str) {
        if let Ok(mut l) = self.0.lock() {
            *l = Some((fraction.clamp(0.0, 1.0), stage));
        }
    }
    fn take(&self) -> Option<(f32, &'static str)> {
        self.0.lock().ok().and_then(|mut l| l.take())
    }
}

/// What a job gets: the event sink and a fraction sink (for calls that report a bare fraction),
/// and the cancel token.
pub struct Ctx<'a> {
    latest: &'a Latest,
    pub cancel: work::CancelToken,
}

impl Ctx<'_> {
    /// Pass an engine event on.
    pub fn event(&self, e: Event) {
        match e {
            Event::Progress(p) | Event::Partial { progress: p, .. } => {
                self.latest.set(p.fraction, p.stage)
            }
            Event::StageTime(..) => {}
        }
    }
    /// Pass a bare fraction on, under `stage`.
    pub fn fraction(&self, f: f32, stage: &'static str) {
        self.latest.set(f, stage);
    }
}

/// Run `work` on a thread of its own; meanwhile the calling thread releases the GIL, and every
/// [`POLL`] takes it back to call `progress(fraction, stage)` with the newest report and check
/// for Ctrl-C. Ctrl-C, or an exception in the callback, cancels the job; once it has stopped,
/// that exception is raised. `cancel` (a [`CancelToken`]) stops it with `meshmatch.Cancelled`.
pub fn run<T: Send>(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    cancel: Option<&Bound<'_, CancelToken>>,
    work: impl FnOnce(&Ctx) -> meshmatch::Result<T> + Send,
) -> PyResult<T> {
    let token = match cancel {
        Some(c) => c.get().inner.child(),
        None => work::CancelToken::new(),
    };
    if token.is_cancelled() {
        return Err(crate::to_py(meshmatch::Error::Cancelled));
    }
    let latest = Latest::default();
    let (tx, rx) = crossbeam_channel::bounded(1);
    let mut pending: Option<PyErr> = None;
    let result = std::thread::scope(|s| {
        let ctx = Ctx {
            latest: &latest,
            cancel: token.clone(),
        };
        s.spawn(move || {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work(&ctx)));
            let _ = tx.send(r);
        });
        loop {
            let got = py.detach(|| rx.recv_timeout(POLL).ok());
            if pending.is_none() {
                if let Err(e) = py.check_signals() {
                    token.cancel();
                    pending = Some(e);
                } else if let (Some(cb), Some((f, stage))) = (progress, latest.take())
                    && let Err(e) = cb.call1((f, stage))
                {
                    token.cancel();
                    pending = Some(e);
                }
            }
            if let Some(r) = got {
                break r;
            }
        }
    });
    if let Some(e) = pending {
        return Err(e);
    }
    match result {
        Ok(r) => r.map_err(crate::to_py),
        Err(panic) => {
            let msg = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(crate::MeshMatchError::new_err(format!(
                "internal error: {msg}"
            )))
        }
    }
}
