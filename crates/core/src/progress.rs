//! [`Progress`]: how long-running stages report progress without knowing about terminals,
//! and learn that the caller wants them stopped.

use crate::{Error, Result};

/// Receives progress of long stages. Implementations must be cheap and thread-safe:
/// `advance` is called from rayon workers.
pub trait Progress: Sync {
    /// A stage with `total` units of work begins.
    fn start(&self, _stage: &str, _total: u64) {}
    /// `n` more units are done.
    fn advance(&self, _n: u64) {}
    /// The current stage is over.
    fn finish(&self) {}
    /// A one-line message for verbose output.
    fn message(&self, _text: &str) {}
    /// Whether the caller wants the work stopped (a Ctrl-C in Python). Long stages ask
    /// between steps ([`Progress::checkpoint`]) and end with [`Error::Cancelled`].
    fn cancelled(&self) -> bool {
        false
    }
    /// [`Error::Cancelled`] when [`Progress::cancelled`]: `progress.checkpoint()?` between
    /// stages.
    fn checkpoint(&self) -> Result<()> {
        if self.cancelled() {
            Err(Error::Cancelled)
        } else {
            Ok(())
        }
    }
}

/// A [`Progress`] that ignores everything.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Progress for Silent {}
