//! Which reader a point cloud file goes to: chosen by its extension, checked by its
//! first bytes (the magic of each binary or header format).
//!
//! | extension (any case) | format | content check |
//! |---|---|---|
//! | `.ply` | PLY | first line `ply` (by the PLY reader) |
//! | `.pcd` | PCD | `# .PCD` or a first header keyword `VERSION`/`FIELDS` |
//! | `.las`, `.laz` | LAS / LAZ | `LASF` |
//! | `.e57` | E57 | `ASTM-E57` |
//! | `.xyz`, `.txt`, `.pts`, `.csv` | text | none of the magics above |
//!
//! A regular file without an extension is recognised by its magic alone; a device or a
//! pipe without one is read as PLY (as before other formats were read), and one with an
//! extension goes to that extension's reader as a stream where the format allows it.

use std::fmt;
use std::fs::File;
use std::io::Read;
use std::path::Path;

use super::PlyFormat;
use crate::{Error, Result};

/// The formats accepted, as named in error messages.
pub const ACCEPTED_FORMATS: &str = "PLY (.ply), PCD (.pcd), LAS/LAZ (.las, .laz), E57 (.e57), \
                                    XYZ/PTS/CSV text (.xyz, .txt, .pts, .csv)";

/// How many leading bytes are read to recognise a format.
const SNIFF_BYTES: u64 = 4096;

/// The dialect of a text point cloud, from its extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TextKind {
    /// `.xyz` or `.txt`: one point a line.
    Xyz,
    /// `.pts` (Leica): blocks, each a line with the point count and then the points.
    Pts,
    /// `.csv`: one point a line, usually with a header row.
    Csv,
}

/// The body encoding of a PCD file (its `DATA` line).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PcdData {
    /// `DATA ascii`.
    Ascii,
    /// `DATA binary`: little-endian records, one after another.
    Binary,
    /// `DATA binary_compressed`: LZF-compressed columns.
    BinaryCompressed,
}

/// The format a cloud was read from ([`ReadReport::format`](super::ReadReport::format)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CloudFormat {
    /// PLY, with its body encoding.
    Ply(PlyFormat),
    /// PCD, with its body encoding.
    Pcd(PcdData),
    /// ASPRS LAS (`compressed`: LAZ), with its version `(major, minor)`.
    Las {
        /// The file's LAS version, e.g. `(1, 4)`.
        version: (u8, u8),
        /// True for LASzip-compressed points (LAZ).
        compressed: bool,
    },
    /// ASTM E57.
    E57,
    /// Text, with its dialect.
    Text(TextKind),
}

impl fmt::Display for CloudFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CloudFormat::Ply(e) => write!(f, "PLY {e}"),
            CloudFormat::Pcd(d) => write!(f, "PCD {}", pcd_data_name(*d)),
            CloudFormat::Las {
                version: (major, minor),
                compressed,
            } => {
                let name = if *compressed { "LAZ" } else { "LAS" };
                write!(f, "{name} {major}.{minor}")
            }
            CloudFormat::E57 => f.write_str("E57"),
            CloudFormat::Text(TextKind::Xyz) => f.write_str("XYZ text"),
            CloudFormat::Text(TextKind::Pts) => f.write_str("PTS text"),
            CloudFormat::Text(TextKind::Csv) => f.write_str("CSV text"),
        }
    }
}

/// The `DATA` keyword of a PCD encoding.
pub(crate) fn pcd_data_name(d: PcdData) -> &'static str {
    match d {
        PcdData::Ascii => "ascii",
        PcdData::Binary => "binary",
        PcdData::BinaryCompressed => "binary_compressed",
    }
}

/// The reader a file goes to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    Ply,
    Pcd,
    Las,
    E57,
    Text(TextKind),
}

impl Kind {
    /// The format's name in messages.
    fn name(self) -> &'static str {
        match self {
            Kind::Ply => "PLY",
            Kind::Pcd => "PCD",
            Kind::Las => "LAS/LAZ",
            Kind::E57 => "E57",
            Kind::Text(_) => "text",
        }
    }
}

/// The reader for `path`: by extension, checked against the file's first bytes.
pub(crate) fn detect(path: &Path) -> Result<Kind> {
    let by_name = kind_of_extension(path)?;
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        return Err(Error::format(
            path,
            "is a directory, not a point cloud file",
        ));
    }
    if !meta.is_file() {
        // A device or pipe: its bytes cannot be read twice, so the name decides.
        return Ok(by_name.unwrap_or(Kind::Ply));
    }
    if meta.len() == 0 {
        let name = by_name.map_or("point cloud", Kind::name);
        return Err(Error::format(
            path,
            format!("the file is empty, not a {name} file"),
        ));
    }
    let mut head = Vec::new();
    file.take(SNIFF_BYTES)
        .read_to_end(&mut head)
        .map_err(|e| Error::io(path, e))?;
    let by_content = sniff(&head);
    match (by_name, by_content) {
        (None, Some(kind)) => Ok(kind),
        (None, None) if !head.contains(&0) => Ok(Kind::Text(TextKind::Xyz)),
        (None, None) => Err(unknown(
            path,
            "no extension, and content of no known format",
        )),
        (Some(named), Some(found)) if named != found => {
            let msg = format!(
                "the name says {} but the content is {}",
                named.name(),
                found.name()
            );
            Err(unknown(path, &msg))
        }
        (Some(Kind::Las | Kind::E57 | Kind::Pcd), None) => Err(bad_magic(path, by_name)),
        (Some(Kind::Text(_)), None) if head.contains(&0) => Err(Error::format(
            path,
            "not a text file: it has NUL bytes (binary data)",
        )),
        (Some(named), _) => Ok(named),
    }
}

/// The error for a file whose first bytes are not its format's magic.
fn bad_magic(path: &Path, kind: Option<Kind>) -> Error {
    let msg = match kind {
        Some(Kind::Las) => "not a LAS/LAZ file: it does not start with 'LASF'",
        Some(Kind::E57) => "not an E57 file: it does not start with 'ASTM-E57'",
        _ => "not a PCD file: it must start with '# .PCD' or a 'VERSION' or 'FIELDS' line",
    };
    Error::format(path, msg)
}

/// [`Error::UnknownFormat`] for `path`.
fn unknown(path: &Path, found: &str) -> Error {
    Error::UnknownFormat {
        path: path.to_path_buf(),
        found: found.to_string(),
        accepted: ACCEPTED_FORMATS,
    }
}

/// The reader named by the extension; `None` when there is no extension.
fn kind_of_extension(path: &Path) -> Result<Option<Kind>> {
    let Some(ext) = path.extension() else {
        return Ok(None);
    };
    let lower = ext.to_string_lossy().to_ascii_lowercase();
    let kind = match lower.as_str() {
        "ply" => Kind::Ply,
        "pcd" => Kind::Pcd,
        "las" | "laz" => Kind::Las,
        "e57" => Kind::E57,
        "xyz" | "txt" => Kind::Text(TextKind::Xyz),
        "pts" => Kind::Text(TextKind::Pts),
        "csv" => Kind::Text(TextKind::Csv),
        _ => {
            let found = format!("the extension '.{}'", ext.to_string_lossy());
            return Err(unknown(path, &found));
        }
    };
    Ok(Some(kind))
}

/// The format whose magic `head` starts with, if any (text has none).
fn sniff(head: &[u8]) -> Option<Kind> {
    if head.starts_with(b"LASF") {
        return Some(Kind::Las);
    }
    if head.starts_with(b"ASTM-E57") {
        return Some(Kind::E57);
    }
    if head.starts_with(b"ply\n") || head.starts_with(b"ply\r\n") {
        return Some(Kind::Ply);
    }
    looks_like_pcd(head).then_some(Kind::Pcd)
}

/// True when `head` starts like a PCD header: `# .PCD`, or comment lines followed by a
/// `VERSION` or `FIELDS` line.
fn looks_like_pcd(head: &[u8]) -> bool {
    if head.starts_with(b"# .PCD") {
        return true;
    }
    let text = String::from_utf8_lossy(head);
    let first = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'));
    first.is_some_and(|l| {
        let word = l.split_whitespace().next().unwrap_or("");
        word.eq_ignore_ascii_case("VERSION") || word.eq_ignore_ascii_case("FIELDS")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn magics_are_recognised() {
        assert_eq!(sniff(b"LASF\x00\x00"), Some(Kind::Las));
        assert_eq!(sniff(b"ASTM-E57\x00"), Some(Kind::E57));
        assert_eq!(sniff(b"ply\nformat ascii 1.0\n"), Some(Kind::Ply));
        assert_eq!(sniff(b"# .PCD v0.7\nVERSION 0.7\n"), Some(Kind::Pcd));
        assert_eq!(sniff(b"# made by hand\nVERSION .7\n"), Some(Kind::Pcd));
        assert_eq!(sniff(b"1 2 3\n4 5 6\n"), None);
        assert_eq!(sniff(b"\x89PNG\r\n\x1a\n\0\0"), None);
    }

    #[test]
    fn extensions_are_case_insensitive_and_unknown_ones_fail() {
        let k = |p: &str| kind_of_extension(Path::new(p)).expect("known");
        assert_eq!(k("a.PLY"), Some(Kind::Ply));
        assert_eq!(k("a.Laz"), Some(Kind::Las));
        assert_eq!(k("dir.v2/a.TXT"), Some(Kind::Text(TextKind::Xyz)));
        assert_eq!(k("noext"), None);
        let e = kind_of_extension(Path::new("scan.bin")).expect_err("unknown");
        assert!(matches!(e, Error::UnknownFormat { .. }));
        let msg = e.to_string();
        assert!(msg.starts_with("scan.bin: "), "{msg}");
        assert!(
            msg.contains("'.bin'") && msg.contains("E57 (.e57)"),
            "{msg}"
        );
    }
}
