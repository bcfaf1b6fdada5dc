//! [`Progress`]: how long-running stages report progress without knowing about terminals.

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
}

/// A [`Progress`] that ignores everything.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Progress for Silent {}
