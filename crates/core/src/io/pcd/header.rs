//! PCD header (PCL's point cloud data format, v0.5–0.7): read with a size limit and
//! checked line by line.
//!
//! Keywords: `VERSION`, `FIELDS` (or `COLUMNS`), `SIZE`, `TYPE`, `COUNT` (default 1 each),
//! `WIDTH`, `HEIGHT`, `VIEWPOINT`, `POINTS` (default `WIDTH × HEIGHT`) and `DATA` last;
//! `#` starts a comment. `WIDTH × HEIGHT` must equal `POINTS` (PCL's rule): an
//! organised cloud has `HEIGHT > 1` and marks its holes with NaN coordinates.

use std::io::{BufRead, Read};
use std::path::Path;

use crate::io::PcdData;
use crate::{Error, Result};

/// The longest header accepted, in bytes (comments included).
const MAX_HEADER_BYTES: u64 = 1 << 20;

/// The largest record (one point, all fields) accepted, in bytes.
const MAX_RECORD_BYTES: u64 = 1 << 20;

/// The `DATA` encodings.
const DATA_KINDS: &str = "ascii, binary, binary_compressed";

/// One field (`FIELDS` entry) with its `TYPE`, `SIZE` and `COUNT`.
#[derive(Debug, Clone)]
pub(super) struct Field {
    /// Its name (`x`, `normal_x`, `rgb`, `_` for padding, …).
    pub name: String,
    /// `F` (float), `I` (signed) or `U` (unsigned).
    pub ty: u8,
    /// Bytes per value: 1, 2, 4 or 8.
    pub size: usize,
    /// Values per point.
    pub count: usize,
    /// Byte offset of its first value in a binary record.
    pub offset: usize,
    /// Index of its first value in an ascii line.
    pub value_index: usize,
}

impl Field {
    /// Bytes the field takes in one record.
    pub fn bytes(&self) -> usize {
        self.size * self.count
    }

    /// Bytes the field takes in one point of a compressed body (none for padding).
    pub fn column_bytes(&self) -> usize {
        if self.name == "_" { 0 } else { self.bytes() }
    }
}

/// A checked PCD header and where the body starts.
#[derive(Debug)]
pub(super) struct PcdHeader {
    /// The fields in record order.
    pub fields: Vec<Field>,
    /// Number of points (`POINTS`, equal to `WIDTH × HEIGHT`).
    pub points: u64,
    /// The body encoding.
    pub data: PcdData,
    /// Bytes before the body (the `DATA` line included).
    pub byte_len: u64,
    /// Header lines (the body's first ascii line is `line_count + 1`).
    pub line_count: usize,
    /// The comment lines, without `#`.
    pub comments: Vec<String>,
}

impl PcdHeader {
    /// Bytes of one binary record.
    pub fn record_bytes(&self) -> usize {
        self.fields.iter().map(Field::bytes).sum()
    }

    /// Bytes of one point in a compressed body, whose columns leave out `_` padding
    /// fields (as PCL writes and reads them).
    pub fn column_record_bytes(&self) -> usize {
        self.fields.iter().map(Field::column_bytes).sum()
    }

    /// Values on one ascii line.
    pub fn values_per_line(&self) -> usize {
        self.fields.iter().map(|f| f.count).sum()
    }

    /// The field named `name`, if any.
    pub fn field(&self, name: &str) -> Option<usize> {
        self.fields.iter().position(|f| f.name == name)
    }
}

/// The header's keyword lines as read (tokens after the keyword), before checking.
#[derive(Default)]
struct Raw {
    fields: Option<Vec<String>>,
    size: Option<Vec<String>>,
    ty: Option<Vec<String>>,
    count: Option<Vec<String>>,
    width: Option<u64>,
    height: Option<u64>,
    points: Option<u64>,
    data: Option<PcdData>,
    comments: Vec<String>,
}

/// Reads and checks the header from the start of `reader`, leaving `reader` at the
/// first byte of the body.
pub(super) fn read_header<R: BufRead>(reader: &mut R, path: &Path) -> Result<PcdHeader> {
    let mut raw = Raw::default();
    let mut consumed = 0u64;
    let mut line_count = 0usize;
    let mut buf = Vec::new();
    while raw.data.is_none() {
        buf.clear();
        let n = reader
            .by_ref()
            .take(MAX_HEADER_BYTES - consumed)
            .read_until(b'\n', &mut buf)
            .map_err(|e| Error::io(path, e))?;
        consumed += n as u64;
        line_count += 1;
        if n == 0 || (!buf.ends_with(b"\n") && consumed >= MAX_HEADER_BYTES) {
            let msg = if n == 0 {
                "the PCD header has no 'DATA' line (truncated file?)".to_string()
            } else {
                format!("the PCD header is longer than {MAX_HEADER_BYTES} bytes without 'DATA'")
            };
            return Err(Error::format(path, msg));
        }
        let line = String::from_utf8_lossy(&buf);
        parse_line(&mut raw, line.trim(), line_count, path)?;
    }
    let (fields, points) = check(&raw, path)?;
    Ok(PcdHeader {
        fields,
        points,
        data: raw.data.unwrap_or(PcdData::Ascii),
        byte_len: consumed,
        line_count,
        comments: raw.comments,
    })
}

/// Records one header line in `raw`.
fn parse_line(raw: &mut Raw, line: &str, no: usize, path: &Path) -> Result<()> {
    let fail = |msg: String| Error::format(path, format!("PCD header line {no}: {msg}"));
    if let Some(comment) = line.strip_prefix('#') {
        raw.comments.push(comment.trim().to_string());
        return Ok(());
    }
    let mut tokens = line.split_whitespace();
    let Some(keyword) = tokens.next() else {
        return Ok(());
    };
    let rest: Vec<String> = tokens.map(str::to_string).collect();
    let number = |rest: &[String]| -> Result<u64> {
        match rest {
            [v] => v.parse::<u64>().map_err(|_| {
                fail(format!(
                    "{keyword} must be a non-negative integer, got '{v}'"
                ))
            }),
            _ => Err(fail(format!(
                "{keyword} takes one value, got {}",
                rest.len()
            ))),
        }
    };
    match keyword.to_ascii_uppercase().as_str() {
        "VERSION" | "VIEWPOINT" => {}
        "FIELDS" | "COLUMNS" => raw.fields = Some(rest),
        "SIZE" => raw.size = Some(rest),
        "TYPE" => raw.ty = Some(rest),
        "COUNT" => raw.count = Some(rest),
        "WIDTH" => raw.width = Some(number(&rest)?),
        "HEIGHT" => raw.height = Some(number(&rest)?),
        "POINTS" => raw.points = Some(number(&rest)?),
        "DATA" => {
            raw.data = Some(
                match rest.first().map(|s| s.to_ascii_lowercase()).as_deref() {
                    Some("ascii") => PcdData::Ascii,
                    Some("binary") => PcdData::Binary,
                    Some("binary_compressed") => PcdData::BinaryCompressed,
                    other => {
                        let got = other.unwrap_or("nothing");
                        return Err(fail(format!(
                            "unknown DATA encoding '{got}' (expected {DATA_KINDS})"
                        )));
                    }
                },
            )
        }
        other => return Err(fail(format!("unknown keyword '{other}'"))),
    }
    Ok(())
}

/// Checks the keyword lines against each other: the fields with their layout, and the
/// point count (`WIDTH × HEIGHT`; an organised cloud's rows need nothing else).
fn check(raw: &Raw, path: &Path) -> Result<(Vec<Field>, u64)> {
    let fail = |msg: String| Error::format(path, format!("PCD header: {msg}"));
    let need = |v: &Option<Vec<String>>, key: &str| {
        v.clone()
            .ok_or_else(|| fail(format!("no {key} line before DATA")))
    };
    let names = need(&raw.fields, "FIELDS")?;
    let sizes = need(&raw.size, "SIZE")?;
    let types = need(&raw.ty, "TYPE")?;
    let counts = raw
        .count
        .clone()
        .unwrap_or_else(|| vec!["1".to_string(); names.len()]);
    for (key, list) in [("SIZE", &sizes), ("TYPE", &types), ("COUNT", &counts)] {
        if list.len() != names.len() {
            return Err(fail(format!(
                "{key} has {} entries for {} FIELDS",
                list.len(),
                names.len()
            )));
        }
    }
    let mut fields = Vec::with_capacity(names.len());
    let (mut offset, mut value_index) = (0u64, 0u64);
    for (k, name) in names.iter().enumerate() {
        let field = field(name, &types[k], &sizes[k], &counts[k], offset, value_index)
            .map_err(|msg| fail(format!("field '{name}': {msg}")))?;
        if name != "_" && fields.iter().any(|f: &Field| &f.name == name) {
            return Err(fail(format!("field '{name}' is declared twice")));
        }
        offset += field.bytes() as u64;
        value_index += field.count as u64;
        if offset > MAX_RECORD_BYTES {
            return Err(fail(format!(
                "one point's fields take more than {MAX_RECORD_BYTES} bytes"
            )));
        }
        fields.push(field);
    }
    let width = raw.width.ok_or_else(|| fail("no WIDTH line".into()))?;
    let height = raw.height.ok_or_else(|| fail("no HEIGHT line".into()))?;
    let grid = width.checked_mul(height);
    let points = raw.points.or(grid).unwrap_or(u64::MAX);
    if grid != Some(points) {
        return Err(fail(format!(
            "WIDTH {width} × HEIGHT {height} is not POINTS {points} (corrupt count)"
        )));
    }
    Ok((fields, points))
}

/// One field from its header tokens.
fn field(
    name: &str,
    ty: &str,
    size: &str,
    count: &str,
    offset: u64,
    value_index: u64,
) -> std::result::Result<Field, String> {
    let ty = match ty {
        "F" | "f" => b'F',
        "I" | "i" => b'I',
        "U" | "u" => b'U',
        _ => return Err(format!("unknown TYPE '{ty}' (expected F, I or U)")),
    };
    let size: usize = size
        .parse()
        .map_err(|_| format!("SIZE '{size}' is not a number"))?;
    let valid = match ty {
        b'F' => matches!(size, 4 | 8),
        _ => matches!(size, 1 | 2 | 4 | 8),
    };
    if !valid {
        return Err(format!("SIZE {size} is not a size of TYPE {}", ty as char));
    }
    let count: u64 = count
        .parse()
        .ok()
        .filter(|&c| c >= 1)
        .ok_or_else(|| format!("COUNT '{count}' is not a positive integer"))?;
    if count > MAX_RECORD_BYTES {
        return Err(format!("COUNT {count} is larger than {MAX_RECORD_BYTES}"));
    }
    Ok(Field {
        name: name.to_string(),
        ty,
        size,
        count: count as usize,
        offset: offset as usize,
        value_index: value_index as usize,
    })
}
