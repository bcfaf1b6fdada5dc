//! Third-party decoders (the `las`/`laz` and `e57` crates) meet damaged files that their
//! authors did not foresee, and some then panic (an out-of-range slice in `laz`'s chunk
//! reader, found by `tests/formats/mutations.rs`). A file is data: a panic while
//! decoding it becomes a one-line format error naming the file, and the panic message is
//! not printed. Our own readers are not guarded: a panic there is a bug the tests catch.

use std::cell::Cell;
use std::panic::{self, AssertUnwindSafe};
use std::path::Path;
use std::sync::Once;

use crate::{Error, Result};

thread_local! {
    /// Set while this thread runs a guarded decoder: its panics are not printed.
    static GUARDED: Cell<bool> = const { Cell::new(false) };
}

/// Installs, once, a panic hook that stays silent for guarded decoders and hands every
/// other panic to the hook that was there before.
fn install_quiet_hook() {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let previous = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            if !GUARDED.with(Cell::get) {
                previous(info);
            }
        }));
    });
}

/// Runs `decode` (a third-party `decoder`'s read of `path`); a panic inside it becomes
/// [`Error::Format`] naming the file.
pub(crate) fn decoder<T>(
    path: &Path,
    decoder: &str,
    decode: impl FnOnce() -> Result<T>,
) -> Result<T> {
    install_quiet_hook();
    let was = GUARDED.with(|g| g.replace(true));
    let outcome = panic::catch_unwind(AssertUnwindSafe(decode));
    GUARDED.with(|g| g.set(was));
    outcome.unwrap_or_else(|payload| {
        let why = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "no message".into());
        let msg = format!("damaged {decoder} data: the decoder failed ({why})");
        Err(Error::format(path, msg))
    })
}
