//! The crate's error type: every fallible public function returns [`Result`].

use std::path::PathBuf;

/// Errors of primfit-core. Messages are one line, name the offending input, and say
/// what would fix it where that is known.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An argument is out of its documented range (a size ≤ 0, an empty cloud, …).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// Array or slice lengths that must agree do not.
    #[error("shape mismatch: {0}")]
    Shape(String),
    /// A file could not be opened, read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying OS error.
        source: std::io::Error,
    },
    /// A file was read but its contents are not what they must be.
    #[error("{}: {message}", path.display())]
    Format {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// The problem would need more memory than the configured budget allows.
    #[error("too large: {0}")]
    TooLarge(String),
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Shorthand for [`Error::InvalidArgument`].
    pub fn invalid(msg: impl Into<String>) -> Self {
        Error::InvalidArgument(msg.into())
    }
    /// Shorthand for [`Error::Format`].
    pub fn format(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Format {
            path: path.into(),
            message: msg.into(),
        }
    }
    /// Shorthand for [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}
