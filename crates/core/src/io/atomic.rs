//! Atomic file writes: write a temporary file beside the target, then rename it over.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::{Error, Result};

/// Distinguishes temporary files made by one process (with the process id).
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// How many temporary names to try before giving up (names collide only with files
/// left by a crashed process that had the same id).
const TEMP_ATTEMPTS: u32 = 100;

/// Writes `path` atomically: `write` fills a buffered temporary file in the same
/// directory (named `.NAME.primfit-PID-N.tmp`), which is flushed, synced and renamed
/// over `path` only when `write` returns `Ok`.
///
/// On any error, including one returned by `write` or a panic inside it, the temporary
/// file is removed and an existing file at `path` is left untouched. Errors from `write`
/// are returned as they are; errors of the temporary file name `path`.
pub fn write_atomic<F>(path: &Path, write: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> Result<()>,
{
    stage(path, write)?.commit()
}

/// Writes a JSON value, pretty-printed and newline-terminated, with [`write_atomic`].
pub fn write_json_atomic(path: &Path, value: &serde_json::Value) -> Result<()> {
    stage_json(path, value)?.commit()
}

/// The first half of [`write_atomic`]: the temporary file is written, flushed and synced,
/// but only [`StagedFile::commit`] renames it over `path`; dropping the result instead
/// removes it and leaves `path` untouched. For outputs that must appear together or not
/// at all: stage the first, write the second, then commit the first.
pub fn stage<F>(path: &Path, write: F) -> Result<StagedFile>
where
    F: FnOnce(&mut dyn Write) -> Result<()>,
{
    let temp = TempFile::beside(path)?;
    let mut out = BufWriter::new(&temp.file);
    write(&mut out)?;
    out.flush().map_err(|e| Error::io(path, e))?;
    drop(out);
    temp.file.sync_all().map_err(|e| Error::io(path, e))?;
    Ok(StagedFile {
        temp,
        target: path.to_path_buf(),
    })
}

/// [`stage`] for a JSON value, formatted as by [`write_json_atomic`].
pub fn stage_json(path: &Path, value: &serde_json::Value) -> Result<StagedFile> {
    stage(path, |w| {
        serde_json::to_writer_pretty(&mut *w, value)
            .map_err(|e| Error::io(path, io::Error::other(e)))?;
        w.write_all(b"\n").map_err(|e| Error::io(path, e))
    })
}

/// A complete temporary file waiting to replace its target ([`stage`]); removed on drop
/// unless committed.
#[must_use = "a staged file is removed on drop unless committed"]
pub struct StagedFile {
    temp: TempFile,
    target: PathBuf,
}

impl StagedFile {
    /// Renames the temporary file over the target.
    pub fn commit(self) -> Result<()> {
        self.temp.persist(&self.target)
    }
}

/// A temporary file that deletes itself on drop unless persisted.
struct TempFile {
    path: PathBuf,
    file: File,
    keep: bool,
}

impl TempFile {
    /// Creates a fresh temporary file in the directory of `target`.
    fn beside(target: &Path) -> Result<Self> {
        let name = target.file_name().ok_or_else(|| {
            Error::io(
                target,
                io::Error::new(io::ErrorKind::InvalidInput, "not a file path"),
            )
        })?;
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let mut last_error = None;
        for _ in 0..TEMP_ATTEMPTS {
            let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
            let mut temp_name = std::ffi::OsString::from(".");
            temp_name.push(name);
            temp_name.push(format!(".primfit-{}-{n}.tmp", std::process::id()));
            let path = dir.join(temp_name);
            match OpenOptions::new().write(true).create_new(true).open(&path) {
                Ok(file) => {
                    return Ok(TempFile {
                        path,
                        file,
                        keep: false,
                    });
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last_error = Some(e),
                Err(e) => return Err(Error::io(target, e)),
            }
        }
        let e = last_error.unwrap_or_else(|| io::Error::other("no temporary name available"));
        Err(Error::io(target, e))
    }

    /// Renames the temporary file to `target`, replacing any file there.
    fn persist(mut self, target: &Path) -> Result<()> {
        fs::rename(&self.path, target).map_err(|e| Error::io(target, e))?;
        self.keep = true;
        Ok(())
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if !self.keep {
            // Best effort: the error that got us here matters more than this one.
            let _ = fs::remove_file(&self.path);
        }
    }
}
