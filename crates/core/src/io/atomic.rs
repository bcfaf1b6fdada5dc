//! Atomic file writes: write a temporary file beside the target, then rename it over.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};

use crate::{Error, Result};

/// Distinguishes temporary files made by one process (with the process id).
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// The temporary files of this process not yet renamed or removed, for
/// [`remove_temporary_files`]. A file is listed here from its creation until its rename or
/// removal, both done while holding the lock, so a signal handler that takes the lock
/// never removes a file that has become an output.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Removes every temporary file this process is writing, and keeps the lock so that no
/// other is renamed into place: for a signal handler about to end the process (the CLI's
/// SIGINT/SIGTERM handler), so that an interrupted write leaves nothing behind and the
/// outputs as they were.
pub fn remove_temporary_files() {
    let live = LIVE.lock().unwrap_or_else(PoisonError::into_inner);
    for path in live.iter() {
        let _ = fs::remove_file(path);
    }
    // The process ends next; holding the lock until then stops any rename.
    std::mem::forget(live);
}

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
    let target = writable_target(path)?;
    let temp = TempFile::beside(&target)?;
    let mut out = BufWriter::new(&temp.file);
    write(&mut out)?;
    out.flush().map_err(|e| Error::io(path, e))?;
    drop(out);
    temp.file.sync_all().map_err(|e| Error::io(path, e))?;
    Ok(StagedFile { temp, target })
}

/// The file a write to `path` must replace: `path` itself, or where a symbolic link
/// there points (the link is kept, its target replaced, as `>` in a shell does). An
/// existing FIFO, socket, device or folder is refused: renaming over it would
/// silently turn it into a regular file.
pub fn writable_target(path: &Path) -> Result<PathBuf> {
    let mut target = path.to_path_buf();
    for _ in 0..MAX_LINK_HOPS {
        let meta = match fs::symlink_metadata(&target) {
            Ok(m) => m,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(target),
            Err(e) => return Err(Error::io(path, e)),
        };
        if meta.file_type().is_symlink() {
            let link = fs::read_link(&target).map_err(|e| Error::io(path, e))?;
            target = match target.parent() {
                Some(dir) => dir.join(link),
                None => link,
            };
        } else if meta.is_file() {
            return Ok(target);
        } else {
            let what = if meta.is_dir() {
                "a folder"
            } else {
                "not a regular file"
            };
            let e = io::Error::new(io::ErrorKind::InvalidInput, format!("{what}: not replaced"));
            return Err(Error::io(path, e));
        }
    }
    let e = io::Error::new(
        io::ErrorKind::InvalidInput,
        "too many levels of symbolic links",
    );
    Err(Error::io(path, e))
}

/// Symbolic links followed before [`writable_target`] gives up (Linux's own limit).
const MAX_LINK_HOPS: usize = 40;

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
            let mut live = LIVE.lock().unwrap_or_else(PoisonError::into_inner);
            match OpenOptions::new().write(true).create_new(true).open(&path) {
                Ok(file) => {
                    live.push(path.clone());
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
        let mut live = LIVE.lock().unwrap_or_else(PoisonError::into_inner);
        fs::rename(&self.path, target).map_err(|e| Error::io(target, e))?;
        live.retain(|p| p != &self.path);
        self.keep = true;
        Ok(())
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if !self.keep {
            let mut live = LIVE.lock().unwrap_or_else(PoisonError::into_inner);
            // Best effort: the error that got us here matters more than this one.
            let _ = fs::remove_file(&self.path);
            live.retain(|p| p != &self.path);
        }
    }
}
