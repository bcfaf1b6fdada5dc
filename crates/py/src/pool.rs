//! A per-process rayon thread pool, so the bindings survive `os.fork()`.
//!
//! rayon's global pool is started once per process; a forked child inherits the
//! pool's bookkeeping but none of its threads, and its first parallel call then waits
//! forever (PyTorch's `DataLoader` forks its workers on Linux). Every call of the
//! bindings therefore runs inside a pool owned by the current process id: a child
//! sees a different id and builds its own pool. The parent's stale pool is leaked in
//! the child (its threads do not exist there, so it cannot be shut down).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use primfit_core::Progress;

use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use rayon::{ThreadPool, ThreadPoolBuilder};

/// The pool of the process that built it.
static POOL: Mutex<Option<(u32, Arc<ThreadPool>)>> = Mutex::new(None);

/// The current process's pool, built on first use ([`threads_from_env`]).
fn current() -> PyResult<Arc<ThreadPool>> {
    let pid = std::process::id();
    let mut slot = POOL.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some((owner, pool)) = slot.as_ref()
        && *owner == pid
    {
        return Ok(Arc::clone(pool));
    }
    if let Some((_, stale)) = slot.take() {
        std::mem::forget(stale);
    }
    let pool = ThreadPoolBuilder::new()
        .thread_name(|i| format!("primfit-{i}"))
        .num_threads(threads_from_env()?)
        .build()
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start worker threads: {e}")))?;
    let pool = Arc::new(pool);
    *slot = Some((pid, Arc::clone(&pool)));
    Ok(pool)
}

/// Worker threads: `RAYON_NUM_THREADS` when set (bounded by
/// [`primfit_core::budget::max_threads`]), else one per core.
fn threads_from_env() -> PyResult<usize> {
    let Ok(text) = std::env::var("RAYON_NUM_THREADS") else {
        return Ok(primfit_core::budget::available_cores());
    };
    let n = text.trim().parse::<usize>().map_err(|_| {
        PyValueError::new_err(format!("RAYON_NUM_THREADS must be a count, got {text:?}"))
    })?;
    match n {
        0 => Ok(primfit_core::budget::available_cores()),
        n => primfit_core::budget::check_threads("RAYON_NUM_THREADS", n)
            .map_err(|e| PyValueError::new_err(e.to_string())),
    }
}

/// Runs `f` on this process's pool (call it with the GIL released).
fn run<R: Send>(f: impl FnOnce() -> R + Send) -> PyResult<R> {
    Ok(current()?.install(f))
}

/// A [`Progress`] that only says whether the caller pressed Ctrl-C.
#[derive(Debug, Default)]
pub struct Interrupt(AtomicBool);

impl Progress for Interrupt {
    fn cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// How often the waiting thread looks for a pending Ctrl-C.
const SIGNAL_POLL: Duration = Duration::from_millis(100);

/// Runs `f` on this process's pool with the GIL released, like [`detached`], for calls
/// long enough to interrupt (a fit): while `f` runs, the calling thread checks Python's
/// signal handlers every [`SIGNAL_POLL`]; on a `KeyboardInterrupt` it flags the
/// [`Interrupt`] that `f` reports progress to, waits for `f` to stop at its next
/// checkpoint, and raises the interrupt.
pub fn cancellable<R: Send>(py: Python<'_>, f: impl FnOnce(&Interrupt) -> R + Send) -> PyResult<R> {
    let pool = current()?;
    let interrupt = Interrupt::default();
    let slot: Mutex<Option<R>> = Mutex::new(None);
    let finished = AtomicBool::new(false);
    let waiter = std::thread::current();
    let mut raised = None;
    pool.in_place_scope(|scope| {
        scope.spawn(|_| {
            let result = f(&interrupt);
            *slot.lock().unwrap_or_else(PoisonError::into_inner) = Some(result);
            finished.store(true, Ordering::Release);
            waiter.unpark();
        });
        while !finished.load(Ordering::Acquire) {
            py.detach(|| std::thread::park_timeout(SIGNAL_POLL));
            if raised.is_none()
                && let Err(e) = py.check_signals()
            {
                interrupt.0.store(true, Ordering::Relaxed);
                raised = Some(e);
            }
        }
    });
    if let Some(e) = raised {
        return Err(e);
    }
    let result = slot.into_inner().unwrap_or_else(PoisonError::into_inner);
    result.ok_or_else(|| PyRuntimeError::new_err("the worker thread ended without a result"))
}

/// Runs `f` on this process's pool with the GIL released: how every long call of the
/// bindings runs.
pub fn detached<R: Send>(py: Python<'_>, f: impl FnOnce() -> R + Send) -> PyResult<R> {
    py.detach(|| run(f))
}
