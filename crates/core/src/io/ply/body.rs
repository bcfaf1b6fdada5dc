//! PLY body: element records, one at a time, in header order.
//!
//! Binary elements are decoded by ply-rs-bw (`read_*_endian_element`), one element per
//! call, so we control the loop and allocate nothing per header count. Ascii elements
//! are tokenised here rather than by ply-rs-bw, whose number grammar rejects `nan`,
//! `inf`, `.5` and `5.` (all of which real files contain, e.g. PCL's `nan` for invalid
//! points); each value is parsed by its declared type and handed to the same
//! [`PropertyAccess`] setters, float and double values both as `f64`.
//!
//! Ascii conventions: one element per line; blank lines are skipped; a line with fewer
//! or more values than its element declares is an error; after the last element only
//! whitespace may follow (binary files likewise).

use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};
use std::str::SplitAsciiWhitespace;

use ply_rs_bw::parser::{ParseError, Parser};
use ply_rs_bw::ply::{ElementDef, PropertyAccess, PropertyType, ScalarType};

use super::header::one_line;
use super::records::Skip;
use crate::io::PlyFormat;
use crate::{Error, Result};

/// The longest ascii body line we accept, in bytes.
const MAX_LINE_BYTES: u64 = 16 << 20;

/// Reads a PLY body, element by element.
pub(super) struct Body<R> {
    reader: R,
    path: PathBuf,
    format: PlyFormat,
    /// 1-based number of the ascii line in `line`.
    line_no: usize,
    /// The current ascii line.
    line: Vec<u8>,
}

impl<R: BufRead> Body<R> {
    /// A body reader positioned at the first body byte; `header_lines` is the number of
    /// header lines (for ascii line numbers in messages).
    pub fn new(reader: R, path: &Path, format: PlyFormat, header_lines: usize) -> Self {
        Body {
            reader,
            path: path.to_path_buf(),
            format,
            line_no: header_lines,
            line: Vec::new(),
        }
    }

    /// Reads all `def.count` elements of `def` as `E`, passing each with its index to
    /// `sink`. Elements without properties occupy no bytes and are not visited.
    pub fn read_element<E, F>(&mut self, def: &ElementDef, mut sink: F) -> Result<()>
    where
        E: PropertyAccess,
        F: FnMut(usize, E) -> Result<()>,
    {
        if def.properties.is_empty() {
            return Ok(());
        }
        for i in 0..def.count {
            let record = match self.format {
                PlyFormat::Ascii => self.ascii_element(def, i)?,
                _ => self.binary_element(def, i)?,
            };
            sink(i, record)?;
        }
        Ok(())
    }

    /// Reads past all elements of `def`, checking them as strictly as those that are
    /// read (value counts, types, list lengths), in ascii as in binary.
    pub fn skip_element(&mut self, def: &ElementDef) -> Result<()> {
        self.read_element(def, |_, _: Skip| Ok(()))
    }

    /// Checks that nothing but whitespace follows the last element.
    pub fn finish(mut self) -> Result<()> {
        match self.format {
            PlyFormat::Ascii => self.finish_ascii(),
            _ => self.finish_binary(),
        }
    }

    /// Decodes one binary element with ply-rs-bw.
    fn binary_element<E: PropertyAccess>(&mut self, def: &ElementDef, i: usize) -> Result<E> {
        let parser = Parser::<E>::new();
        let result = match self.format {
            PlyFormat::BinaryBigEndian => parser.read_big_endian_element(&mut self.reader, def),
            _ => parser.read_little_endian_element(&mut self.reader, def),
        };
        result.map_err(|e| self.binary_error(def, i, &e))
    }

    /// A one-line error for a failed binary element read.
    fn binary_error(&self, def: &ElementDef, i: usize, e: &ParseError) -> Error {
        let msg = if e.kind() == std::io::ErrorKind::UnexpectedEof {
            format!(
                "truncated {} body: the file ends inside '{}' element {i} of {} declared",
                self.format, def.name, def.count
            )
        } else {
            format!("'{}' element {i}: {}", def.name, one_line(&e.to_string()))
        };
        Error::format(&self.path, msg)
    }

    /// Reads the next non-blank line into `self.line`; `Ok(false)` at the end of file.
    fn next_line(&mut self) -> Result<bool> {
        loop {
            self.line.clear();
            let n = (&mut self.reader)
                .take(MAX_LINE_BYTES)
                .read_until(b'\n', &mut self.line)
                .map_err(|e| Error::io(&self.path, e))?;
            if n == 0 {
                return Ok(false);
            }
            self.line_no += 1;
            if n as u64 == MAX_LINE_BYTES && !self.line.ends_with(b"\n") {
                let msg = format!(
                    "line {} is longer than {MAX_LINE_BYTES} bytes",
                    self.line_no
                );
                return Err(Error::format(&self.path, msg));
            }
            if !self.line.iter().all(u8::is_ascii_whitespace) {
                return Ok(true);
            }
        }
    }

    /// Reads the line of element `i` of `def`, failing at the end of file.
    fn element_line(&mut self, def: &ElementDef, i: usize) -> Result<()> {
        if self.next_line()? {
            return Ok(());
        }
        let msg = format!(
            "truncated ascii body: the file ends after {i} of {} '{}' elements declared",
            def.count, def.name
        );
        Err(Error::format(&self.path, msg))
    }

    /// Reads and parses ascii element `i` of `def`.
    fn ascii_element<E: PropertyAccess>(&mut self, def: &ElementDef, i: usize) -> Result<E> {
        self.element_line(def, i)?;
        let parsed = match std::str::from_utf8(&self.line) {
            Ok(text) => parse_ascii_element(text, def),
            Err(_) => Err("not text (binary data in an ascii file?)".to_string()),
        };
        parsed.map_err(|msg| {
            let msg = format!("line {} ('{}' element {i}): {msg}", self.line_no, def.name);
            Error::format(&self.path, msg)
        })
    }

    /// Fails on any non-blank line after the last ascii element.
    fn finish_ascii(&mut self) -> Result<()> {
        if !self.next_line()? {
            return Ok(());
        }
        let text = String::from_utf8_lossy(&self.line);
        let start: String = text.trim().chars().take(40).collect();
        let msg = format!(
            "line {}: unexpected data '{start}' after the last element the header declares \
             (the header's counts do not match the body)",
            self.line_no
        );
        Err(Error::format(&self.path, msg))
    }

    /// Fails on any non-whitespace byte after the last binary element.
    fn finish_binary(&mut self) -> Result<()> {
        let mut offset = 0usize;
        loop {
            let chunk = self
                .reader
                .fill_buf()
                .map_err(|e| Error::io(&self.path, e))?;
            if chunk.is_empty() {
                return Ok(());
            }
            if let Some(k) = chunk.iter().position(|b| !b.is_ascii_whitespace()) {
                let at = match offset + k {
                    0 => "right after".to_string(),
                    n => format!("{n} bytes after"),
                };
                let msg = format!(
                    "unexpected data {at} the last element the header declares \
                     (the header's counts or types do not match the {} body)",
                    self.format
                );
                return Err(Error::format(&self.path, msg));
            }
            let n = chunk.len();
            offset += n;
            self.reader.consume(n);
        }
    }
}

/// Parses one ascii element line into an `E` through its setters.
fn parse_ascii_element<E: PropertyAccess>(
    text: &str,
    def: &ElementDef,
) -> std::result::Result<E, String> {
    let mut tokens = text.split_ascii_whitespace();
    let mut record = E::new();
    for (name, prop) in &def.properties {
        match &prop.data_type {
            PropertyType::Scalar(t) => {
                let token = next_token(&mut tokens, name, def)?;
                set_scalar(&mut record, name, t, token)?;
            }
            PropertyType::List(_, t) => {
                let token = next_token(&mut tokens, name, def)?;
                let len: usize = parse_int(token, "list length")?;
                set_list(&mut record, name, t, len, &mut tokens)?;
            }
        }
    }
    match tokens.next() {
        None => Ok(record),
        Some(extra) => Err(format!(
            "unexpected extra value '{extra}' (the header declares {} properties)",
            def.properties.len()
        )),
    }
}

/// The next value of the line, or an error naming the property it was for.
fn next_token<'a>(
    tokens: &mut SplitAsciiWhitespace<'a>,
    name: &str,
    def: &ElementDef,
) -> std::result::Result<&'a str, String> {
    tokens.next().ok_or_else(|| {
        format!(
            "too few values: missing '{name}' (the header declares {} properties)",
            def.properties.len()
        )
    })
}

/// Parses `token` by type `t` and calls the matching setter.
fn set_scalar<E: PropertyAccess>(
    record: &mut E,
    name: &str,
    t: &ScalarType,
    token: &str,
) -> std::result::Result<(), String> {
    let _ignored_or_set = match t {
        ScalarType::Char => record.set_char(name, parse_int(token, "char")?),
        ScalarType::UChar => record.set_uchar(name, parse_int(token, "uchar")?),
        ScalarType::Short => record.set_short(name, parse_int(token, "short")?),
        ScalarType::UShort => record.set_ushort(name, parse_int(token, "ushort")?),
        ScalarType::Int => record.set_int(name, parse_int(token, "int")?),
        ScalarType::UInt => record.set_uint(name, parse_int(token, "uint")?),
        ScalarType::Float | ScalarType::Double => record.set_double(name, parse_real(token)?),
    };
    Ok(())
}

/// Parses `len` values of type `t` and calls the matching list setter.
fn set_list<E: PropertyAccess>(
    record: &mut E,
    name: &str,
    t: &ScalarType,
    len: usize,
    tokens: &mut SplitAsciiWhitespace<'_>,
) -> std::result::Result<(), String> {
    let _ignored_or_set = match t {
        ScalarType::Char => record.set_list_char(name, int_list(tokens, len, "char")?),
        ScalarType::UChar => record.set_list_uchar(name, int_list(tokens, len, "uchar")?),
        ScalarType::Short => record.set_list_short(name, int_list(tokens, len, "short")?),
        ScalarType::UShort => record.set_list_ushort(name, int_list(tokens, len, "ushort")?),
        ScalarType::Int => record.set_list_int(name, int_list(tokens, len, "int")?),
        ScalarType::UInt => record.set_list_uint(name, int_list(tokens, len, "uint")?),
        ScalarType::Float | ScalarType::Double => {
            let values = list(tokens, len, parse_real)?;
            record.set_list_double(name, values)
        }
    };
    Ok(())
}

/// Parses `len` integer values of type `T`.
fn int_list<T: TryFrom<i64>>(
    tokens: &mut SplitAsciiWhitespace<'_>,
    len: usize,
    type_name: &str,
) -> std::result::Result<Vec<T>, String> {
    list(tokens, len, |s| parse_int(s, type_name))
}

/// Parses `len` values with `parse`. Reserves no more than the line can hold.
fn list<T>(
    tokens: &mut SplitAsciiWhitespace<'_>,
    len: usize,
    parse: impl Fn(&str) -> std::result::Result<T, String>,
) -> std::result::Result<Vec<T>, String> {
    let mut out = Vec::with_capacity(len.min(64));
    for k in 0..len {
        let token = tokens
            .next()
            .ok_or_else(|| format!("list declares {len} values but has {k}"))?;
        out.push(parse(token)?);
    }
    Ok(out)
}

/// Parses an integer of the named PLY type. Integral decimals (`3.0`) are accepted.
fn parse_int<T: TryFrom<i64>>(token: &str, type_name: &str) -> std::result::Result<T, String> {
    let value = match token.parse::<i64>() {
        Ok(v) => v,
        Err(_) => match token.parse::<f64>() {
            Ok(f) if f.fract() == 0.0 && f.abs() < 9.0e18 => f as i64,
            _ => return Err(format!("'{token}' is not an integer ({type_name})")),
        },
    };
    T::try_from(value).map_err(|_| format!("{value} is out of range for {type_name}"))
}

/// Parses a real number; accepts `nan`, `inf`, `-inf`, `.5`, `5.` and exponents.
fn parse_real(token: &str) -> std::result::Result<f64, String> {
    token
        .parse()
        .map_err(|_| format!("'{token}' is not a number"))
}
