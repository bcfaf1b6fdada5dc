//! Point cloud readers against independent writers: every format's files are made here
//! (by hand for PCD and text, by the `las` and `e57` crates' own writers, LZF by
//! `lzf-rust`'s compressor), read back through `io::read_cloud`, and compared point for
//! point; then each format's catalogue of bad files, each one typed one-line error
//! naming the file.

mod e57;
mod las;
mod mutations;
mod pcd;
mod text;

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use primfit_core::na::{Point3, Vector3};
use primfit_core::{Error, PointCloud, Result};

/// A scratch directory removed on drop.
pub struct Scratch(PathBuf);

impl Scratch {
    /// A new empty directory, `tag` in its name.
    pub fn new(tag: &str) -> Self {
        static N: AtomicUsize = AtomicUsize::new(0);
        let n = N.fetch_add(1, Ordering::Relaxed);
        let dir =
            std::env::temp_dir().join(format!("primfit-formats-{tag}-{}-{n}", std::process::id()));
        fs::create_dir_all(&dir).expect("scratch dir");
        Scratch(dir)
    }

    /// The path of `name` in the directory.
    pub fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    /// Writes `bytes` to `name` in the directory; returns its path.
    pub fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.path(name);
        fs::write(&p, bytes).expect("write test file");
        p
    }

    /// The names of the files in the directory, sorted.
    pub fn files(&self) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(&self.0)
            .expect("list")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

/// Asserts `r` failed with a one-line message that starts with the path and contains
/// `needle`, as a Format, Io or UnknownFormat error; returns the message.
pub fn fails<T: std::fmt::Debug>(r: Result<T>, path: &Path, needle: &str) -> String {
    let e = r.expect_err("expected an error");
    assert!(
        matches!(
            e,
            Error::Format { .. } | Error::Io { .. } | Error::UnknownFormat { .. }
        ),
        "{e:?}"
    );
    let msg = e.to_string();
    assert!(
        msg.starts_with(&path.display().to_string()),
        "message does not name the file: {msg}"
    );
    assert!(!msg.contains('\n'), "message is not one line: {msg:?}");
    assert!(msg.contains(needle), "expected {needle:?} in: {msg}");
    msg
}

/// One test point: position, normal, colour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Position.
    pub xyz: [f64; 3],
    /// Normal.
    pub normal: [f64; 3],
    /// Colour.
    pub rgb: [u8; 3],
}

/// `n` points whose values are exact in `f32` and in decimal (multiples of 1/64 and
/// 1/4), so that every format can hold them without rounding.
pub fn samples(n: usize) -> Vec<Sample> {
    (0..n)
        .map(|i| {
            let x = (i % 17) as f64 * 0.125 - 1.0;
            let y = (i / 17) as f64 * 0.0625;
            let z = ((i * 7) % 11) as f64 * 0.25 - 0.5;
            let normal = [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [0.5, 0.5, -0.5]][i % 3];
            let rgb = [
                (i * 37 % 256) as u8,
                (i * 11 % 256) as u8,
                (255 - i % 256) as u8,
            ];
            Sample {
                xyz: [x, y, z],
                normal,
                rgb,
            }
        })
        .collect()
}

/// The cloud of `samples`, with normals and colours if asked.
pub fn cloud_of(s: &[Sample], normals: bool, colors: bool) -> PointCloud {
    PointCloud {
        points: s.iter().map(|p| Point3::from(p.xyz)).collect(),
        normals: normals.then(|| s.iter().map(|p| Vector3::from(p.normal)).collect()),
        colors: colors.then(|| s.iter().map(|p| p.rgb).collect()),
        ..Default::default()
    }
}
