//! PLY header: read it with a size limit, check it, parse it with ply-rs-bw, and check
//! the declared element counts against the number of bytes that follow it.
//!
//! The raw header is read here rather than by ply-rs-bw so that (a) a file that is not a
//! PLY file is rejected after its first line, (b) a header without `end_header` cannot
//! make us read an unbounded line, (c) the exact byte offset of the body is known, and
//! (d) the faults that ply-rs-bw reports in multi-line messages, or silently merges
//! (duplicate element or property names: its header maps are keyed by name), get clear
//! one-line messages.

use std::collections::HashSet;
use std::io::{BufRead, Cursor, Read};
use std::path::Path;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{ElementDef, Encoding, Header, PropertyType, ScalarType};

use super::records::Skip;
use crate::io::PlyFormat;
use crate::{Error, Result};

/// The longest header we accept, in bytes (comments included).
pub(super) const MAX_HEADER_BYTES: u64 = 1 << 20;

/// The body encodings that a `format` line may name.
const FORMATS: [&str; 3] = ["ascii", "binary_little_endian", "binary_big_endian"];

/// A parsed header and where the body starts.
pub(super) struct PlyHeader {
    /// The header as ply-rs-bw models it (elements in file order).
    pub inner: Header,
    /// The body encoding.
    pub format: PlyFormat,
    /// Number of bytes before the body (the header, `end_header` line included).
    pub byte_len: u64,
    /// Number of header lines (the body's first ascii line is `line_count + 1`).
    pub line_count: usize,
}

impl PlyHeader {
    /// The `comment` and `obj_info` lines, without their keyword, in that order.
    pub fn comments(&self) -> Vec<String> {
        let h = &self.inner;
        h.comments.iter().chain(&h.obj_infos).cloned().collect()
    }

    /// The element named `name`, if declared.
    pub fn element(&self, name: &str) -> Option<&ElementDef> {
        self.inner.elements.get(name)
    }

    /// The names of all elements, in file order.
    pub fn element_names(&self) -> Vec<&str> {
        self.inner.elements.keys().map(String::as_str).collect()
    }
}

/// Reads and parses the header from the start of `reader`, leaving `reader` at the
/// first byte of the body.
pub(super) fn read_header<R: BufRead>(reader: &mut R, path: &Path) -> Result<PlyHeader> {
    let (lines, byte_len) = read_header_lines(reader, path)?;
    prescan(&lines, path)?;
    let text = normalized(&lines);
    let mut cursor = Reader::new(Cursor::new(text.as_bytes()));
    let inner = Parser::<Skip>::new()
        .read_header(&mut cursor)
        .map_err(|e| parse_error(path, &lines, &e))?;
    let format = match inner.encoding {
        Encoding::Ascii => PlyFormat::Ascii,
        Encoding::BinaryLittleEndian => PlyFormat::BinaryLittleEndian,
        Encoding::BinaryBigEndian => PlyFormat::BinaryBigEndian,
    };
    Ok(PlyHeader {
        inner,
        format,
        byte_len,
        line_count: lines.len(),
    })
}

/// Reads header lines (line endings and trailing blanks removed) up to and including
/// `end_header`, and the number of bytes they took.
fn read_header_lines<R: BufRead>(reader: &mut R, path: &Path) -> Result<(Vec<String>, u64)> {
    let mut lines = Vec::new();
    let mut consumed = 0u64;
    let mut buf = Vec::new();
    loop {
        buf.clear();
        let budget = MAX_HEADER_BYTES - consumed;
        let n = reader
            .by_ref()
            .take(budget)
            .read_until(b'\n', &mut buf)
            .map_err(|e| Error::io(path, e))?;
        consumed += n as u64;
        let line = String::from_utf8_lossy(&buf).trim_end().to_string();
        if lines.is_empty() {
            check_magic(&line, n, path)?;
        }
        if n == 0 && consumed < MAX_HEADER_BYTES {
            return Err(Error::format(
                path,
                "the PLY header has no 'end_header' line (truncated file?)",
            ));
        }
        if !buf.ends_with(b"\n") && consumed >= MAX_HEADER_BYTES {
            let msg = format!(
                "the PLY header is longer than {MAX_HEADER_BYTES} bytes without 'end_header'"
            );
            return Err(Error::format(path, msg));
        }
        let done = line.trim_start() == "end_header";
        lines.push(line);
        if done {
            return Ok((lines, consumed));
        }
    }
}

/// Checks that the first line is the magic word `ply`.
fn check_magic(first_line: &str, bytes: usize, path: &Path) -> Result<()> {
    if bytes == 0 {
        return Err(Error::format(path, "the file is empty, not a PLY file"));
    }
    if first_line != "ply" {
        let start: String = first_line
            .chars()
            .take(16)
            .filter(|c| !c.is_control())
            .collect();
        let msg = format!("not a PLY file: it must start with the line 'ply', found '{start}'");
        return Err(Error::format(path, msg));
    }
    Ok(())
}

/// Checks what ply-rs-bw would report unclearly or not at all: unknown formats and
/// keywords, bad element counts, and duplicate element or property names.
fn prescan(lines: &[String], path: &Path) -> Result<()> {
    let mut elements = HashSet::new();
    let mut properties: Option<HashSet<&str>> = None;
    for (i, line) in lines.iter().enumerate().skip(1) {
        let fail = |msg: String| Error::format(path, format!("PLY header line {}: {msg}", i + 1));
        let tokens: Vec<&str> = line.split_whitespace().collect();
        match tokens.as_slice() {
            [] | ["comment" | "obj_info" | "end_header", ..] => {}
            ["format", encoding, ..] if !FORMATS.contains(encoding) => {
                let msg = format!(
                    "unknown format '{encoding}' (expected {})",
                    FORMATS.join(", ")
                );
                return Err(fail(msg));
            }
            ["format", ..] => {}
            ["element", name, count] => {
                if count.parse::<u64>().is_err() {
                    let msg = format!(
                        "element '{name}' has count '{count}', expected a non-negative integer"
                    );
                    return Err(fail(msg));
                }
                if !elements.insert(*name) {
                    return Err(fail(format!("element '{name}' is declared twice")));
                }
                properties = Some(HashSet::new());
            }
            ["element", ..] => {
                return Err(fail(format!(
                    "expected 'element NAME COUNT', found '{line}'"
                )));
            }
            ["property"] => return Err(fail("incomplete property line".to_string())),
            ["property", .., name] => {
                let Some(seen) = properties.as_mut() else {
                    return Err(fail(format!("property '{name}' comes before any element")));
                };
                if !seen.insert(*name) {
                    return Err(fail(format!(
                        "property '{name}' is declared twice in one element"
                    )));
                }
            }
            [keyword, ..] => return Err(fail(format!("unknown keyword '{keyword}'"))),
        }
    }
    Ok(())
}

/// The header text as handed to ply-rs-bw: lines left-trimmed, blank lines turned into
/// empty comments (so line numbers stay those of the file).
fn normalized(lines: &[String]) -> String {
    let mut text = String::new();
    for line in lines {
        let line = line.trim_start();
        text.push_str(if line.is_empty() { "comment" } else { line });
        text.push('\n');
    }
    text
}

/// Turns a ply-rs-bw header error into a one-line message quoting the offending line.
fn parse_error(path: &Path, lines: &[String], e: &ply_rs_bw::parser::ParseError) -> Error {
    let quoted = e
        .line()
        .and_then(|n| Some((n, lines.get(n.checked_sub(1)?)?)));
    let msg = match quoted {
        Some((n, line)) if line.trim_start().starts_with("property") => format!(
            "PLY header line {n}: cannot parse '{line}' (property types: char/int8, uchar/uint8, \
             short/int16, ushort/uint16, int/int32, uint/uint32, float/float32, double/float64)"
        ),
        Some((n, line)) => format!("PLY header line {n}: cannot parse '{line}'"),
        None => format!("bad PLY header: {}", one_line(&e.to_string())),
    };
    Error::format(path, msg)
}

/// Collapses a multi-line message into one line.
pub(super) fn one_line(msg: &str) -> String {
    msg.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Fails when the header's element counts need more bytes than `body_len`, the number
/// of bytes after the header: a truncated file or a corrupt (e.g. hostile) count.
///
/// Lower bounds per element: in binary, the sum of its scalar sizes and list-count
/// sizes (lists may be empty); in ascii, two bytes per value (one digit and one
/// separator), a list counting as at least its length value. This check runs before
/// anything is allocated for the body, so allocations sized by a count are bounded by a
/// constant times the file size.
pub(super) fn check_body_size(header: &PlyHeader, body_len: u64, path: &Path) -> Result<()> {
    let ascii = header.format == PlyFormat::Ascii;
    // The last ascii value of a file may lack its separator.
    let available = u128::from(body_len) + u128::from(ascii);
    let mut need = 0u128;
    for def in header.inner.elements.values() {
        let per = if ascii {
            2 * min_values(def)
        } else {
            min_binary_bytes(def)
        };
        need += per * def.count as u128;
        if need > available {
            let msg = format!(
                "the header declares {} '{}' elements, which with those before need at least \
                 {need} bytes of {} data, but only {body_len} bytes follow the header \
                 (truncated file or corrupt count)",
                def.count, def.name, header.format
            );
            return Err(Error::format(path, msg));
        }
    }
    Ok(())
}

/// The least number of ascii values one element takes.
fn min_values(def: &ElementDef) -> u128 {
    def.properties.len() as u128
}

/// The least number of bytes one binary element takes.
pub(super) fn min_binary_bytes(def: &ElementDef) -> u128 {
    def.properties
        .values()
        .map(|p| match &p.data_type {
            PropertyType::Scalar(t) | PropertyType::List(t, _) => scalar_size(t),
        })
        .sum()
}

/// Size in bytes of a binary scalar.
fn scalar_size(t: &ScalarType) -> u128 {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}
