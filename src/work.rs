//! The ground floor for long work: how a computation reports progress and how it is stopped.
//!
//! Every solver takes a `&dyn Fn(Event)` sink and a [`CancelToken`]. The CLI turns events into a
//! progress bar; the app runs work on its own threads and streams events over channels. This
//! module imports nothing of the engine: every layer above may use it.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// A cheap, cloneable cancel flag checked by solvers between small units of work.
#[derive(Clone, Debug, Default)]
pub struct CancelToken {
    own: Arc<AtomicBool>,
    /// The token this one was made from by [`CancelToken::child`]: cancelling it cancels this.
    parent: Option<Arc<CancelToken>>,
}

impl CancelToken {
    /// A fresh, un-cancelled token.
    pub fn new() -> Self {
        Self::default()
    }
    /// A token cancelled with this one, or on its own (cancelling it leaves this one running):
    /// one part of a job stops its sibling parts without stopping the caller.
    pub fn child(&self) -> Self {
        CancelToken {
            own: Arc::default(),
            parent: Some(Arc::new(self.clone())),
        }
    }
    /// Ask the job to stop.
    pub fn cancel(&self) {
        self.own.store(true, Ordering::Relaxed);
    }
    /// Has a stop been requested (of this token or of one it was made from)?
    pub fn is_cancelled(&self) -> bool {
        self.own.load(Ordering::Relaxed) || self.parent.as_ref().is_some_and(|p| p.is_cancelled())
    }
    /// `Err(Error::Cancelled)` once a stop was requested.
    pub fn check(&self) -> crate::error::Result<()> {
        if self.is_cancelled() {
            Err(crate::error::Error::Cancelled)
        } else {
            Ok(())
        }
    }
}

/// Lower the calling thread's scheduling priority (Linux: nice 10; elsewhere nothing), so that
/// background computation yields the CPU to the window and its renderer.
pub fn lower_thread_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: setpriority only reads its integer arguments; on Linux `who = 0` names the calling
    // thread, whose nice value it raises (lowering priority needs no privilege).
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, 0, 10);
    }
}

/// Run `work` on its own thread and wait for it, returning `Err(Cancelled)` within about 10 ms
/// of `cancel` being set even when `work` is one long uninterruptible call (a dense
/// factorisation): the abandoned work then finishes in the background and its result is dropped.
pub fn run_cancellable<T: Send + 'static>(
    cancel: &CancelToken,
    work: impl FnOnce() -> T + Send + 'static,
) -> crate::error::Result<T> {
    cancel.check()?;
    spawn_detached(work)?.wait(cancel)
}

/// Work running on a thread of its own ([`spawn_detached`]), to be collected with
/// [`Detached::wait`].
pub struct Detached<T>(crossbeam_channel::Receiver<T>);

/// Start `work` on its own thread and return at once, so the caller can do other work meanwhile
/// (a preparation builds its fan tables while the eigen-solve runs). Dropping the handle
/// abandons the result; the work still finishes in the background.
///
/// The work's parallel loops get as many threads as the caller's: called from a rayon pool of
/// another size than the global one (`bench --threads 1`), `work` runs in a pool of that size of
/// its own, so a one-thread row measures one core instead of handing its eigen-solves to every
/// core.
pub fn spawn_detached<T: Send + 'static>(
    work: impl FnOnce() -> T + Send + 'static,
) -> crate::error::Result<Detached<T>> {
    let (tx, rx) = crossbeam_channel::bounded(1);
    let callers = rayon::current_thread_index().map(|_| rayon::current_num_threads());
    std::thread::Builder::new()
        .name("meshmatch-detached".into())
        .spawn(move || {
            // On this thread (outside every pool) `current_num_threads` is the global pool's.
            let own = callers
                .filter(|&n| n != rayon::current_num_threads())
                .and_then(|n| rayon::ThreadPoolBuilder::new().num_threads(n).build().ok());
            let out = match own {
                Some(pool) => pool.install(work),
                None => work(),
            };
            let _ = tx.send(out);
        })
        .map_err(|e| crate::error::Error::InvalidInput(format!("cannot start a thread: {e}")))?;
    Ok(Detached(rx))
}

impl<T> Detached<T> {
    /// A handle whose result is already there (work that was waited for early).
    pub fn done(value: T) -> Detached<T> {
        let (tx, rx) = crossbeam_channel::bounded(1);
        let _ = tx.send(value);
        Detached(rx)
    }

    /// Wait for the result, returning `Err(Cancelled)` within about 10 ms of `cancel` being set.
    pub fn wait(self, cancel: &CancelToken) -> crate::error::Result<T> {
        loop {
            match self.0.recv_timeout(std::time::Duration::from_millis(10)) {
                Ok(v) => return Ok(v),
                Err(crossbeam_channel::RecvTimeoutError::Timeout) => cancel.check()?,
                Err(crossbeam_channel::RecvTimeoutError::Disconnected) => {
                    return Err(crate::error::Error::InvalidInput(
                        "a background computation panicked".into(),
                    ));
                }
            }
        }
    }
}

/// A progress report from a running job.
#[derive(Clone, Debug, Default)]
pub struct Progress {
    /// Stage name ("refine", "hierarchy", "features", "fans", "solve", "deliver").
    pub stage: &'static str,
    /// Current level (0 = finest) while solving.
    pub level: usize,
    /// Number of levels.
    pub levels: usize,
    /// EM iteration within the level (1-based), 0 outside the solve.
    pub iteration: usize,
    /// Mean patch distance of the current NNF (lower is better), 0 when not known.
    pub energy: f64,
    /// Seconds since the job started.
    pub elapsed: f64,
    /// Overall fraction done, in [0, 1].
    pub fraction: f32,
}

/// What a job reports.
#[derive(Clone, Debug)]
pub enum Event {
    /// Progress through the stages.
    Progress(Progress),
    /// A partial result: per-vertex signal on the displayed (working-resolution) target mesh,
    /// sent after every level and EM iteration.
    Partial {
        /// The progress at the time of the result.
        progress: Progress,
        /// Per-vertex sRGB colour (or signal) on the working target mesh.
        signal: Arc<[[f32; 3]]>,
    },
    /// A stage finished, with its wall time in seconds (for per-stage timings).
    StageTime(&'static str, f64),
}

/// A sink that drops every event.
pub fn no_events(_: Event) {}

/// Wall-clock helper for stage timings.
#[derive(Clone, Copy, Debug)]
pub struct Stopwatch(Instant);

impl Stopwatch {
    /// Start now.
    pub fn start() -> Self {
        Stopwatch(Instant::now())
    }
    /// Seconds since start.
    pub fn secs(&self) -> f64 {
        self.0.elapsed().as_secs_f64()
    }
}

/// The memory this process may still use, in bytes, where the system says: the smaller of its
/// address-space limit (`ulimit -v`, from `/proc/self/limits`) and the memory available
/// (`MemAvailable` + `SwapFree` in `/proc/meminfo`). `None` where neither is known.
pub fn memory_limit() -> Option<u64> {
    let field = |text: &str, key: &str| -> Option<u64> {
        let line = text.lines().find(|l| l.starts_with(key))?;
        line[key.len()..]
            .split_whitespace()
            .next()?
            .parse::<u64>()
            .ok()
    };
    let address_space = std::fs::read_to_string("/proc/self/limits")
        .ok()
        .and_then(|t| field(&t, "Max address space"));
    let available = std::fs::read_to_string("/proc/meminfo").ok().and_then(|t| {
        Some((field(&t, "MemAvailable:")? + field(&t, "SwapFree:").unwrap_or(0)) * 1024)
    });
    match (address_space, available) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// Memory each worker thread takes of its own, whatever the work: its stack and the packing
/// buffers of dense matrix products (faer's products keep two buffers the size of the
/// last-level cache on every thread that multiplies, so on a CPU with a 260 MiB L3 a thread
/// takes 520 MiB of address space). The cache size is read from `/sys`; 32 MiB where unknown.
pub fn per_thread_bytes() -> u64 {
    let llc = (0..8)
        .filter_map(|i| {
            let dir = format!("/sys/devices/system/cpu/cpu0/cache/index{i}");
            let size = std::fs::read_to_string(format!("{dir}/size")).ok()?;
            let size = size.trim();
            let (num, mul) = match size.strip_suffix('K') {
                Some(n) => (n, 1u64 << 10),
                None => match size.strip_suffix('M') {
                    Some(n) => (n, 1 << 20),
                    None => (size, 1),
                },
            };
            num.parse::<u64>().ok().map(|n| n.saturating_mul(mul))
        })
        .max()
        .unwrap_or(32 << 20);
    // the stack (2 MiB) and room for the allocator's per-thread arenas
    llc.saturating_mul(2).saturating_add(8 << 20)
}

/// Refuse work that needs more memory than this process may use ([`memory_limit`]), before any
/// of it is allocated: `need` bytes for `what` ("400000 working vertices", "a 8192x8192
/// texture"), with `advice` for the user ("use fewer --vertices"). Systems call it with their
/// measured peak per unit of work plus a margin, so a size that cannot fit is a one-line error
/// at once rather than an allocation failure halfway (or an abort).
pub fn check_memory(need: u64, what: &str, advice: &str) -> crate::error::Result<()> {
    match memory_limit() {
        Some(limit) if need > limit => Err(crate::error::Error::InvalidInput(format!(
            "{what} would take about {} MiB of memory, more than the {} MiB this process may use; \
             {advice}",
            need >> 20,
            limit >> 20
        ))),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_child_token_follows_its_parent_but_not_the_other_way() {
        let parent = CancelToken::new();
        let (a, b) = (parent.child(), parent.child());
        let grandchild = a.child();
        a.cancel();
        assert!(a.is_cancelled() && grandchild.is_cancelled());
        assert!(!parent.is_cancelled() && !b.is_cancelled());
        parent.clone().cancel();
        assert!(b.is_cancelled() && b.check().is_err());
    }

    #[test]
    fn run_cancellable_returns_on_cancel_without_waiting_for_the_work() {
        let done = Arc::new(AtomicBool::new(false));
        let (cancel, d) = (CancelToken::new(), done.clone());
        let stopper = {
            let c = cancel.clone();
            std::thread::spawn(move || {
                std::thread::sleep(std::time::Duration::from_millis(30));
                c.cancel();
            })
        };
        let r = run_cancellable(&cancel, move || {
            std::thread::sleep(std::time::Duration::from_secs(3));
            d.store(true, Ordering::SeqCst);
            7
        });
        stopper.join().unwrap();
        assert!(matches!(r, Err(crate::error::Error::Cancelled)), "{r:?}");
        // It returned while the work was still running.
        assert!(!done.load(Ordering::SeqCst));
        // Without a cancel the work's result comes back.
        assert_eq!(run_cancellable(&CancelToken::new(), || 7).unwrap(), 7);
    }
}
