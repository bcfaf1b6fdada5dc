//! PCD bodies: ascii lines, binary records, and LZF-compressed columns.
//!
//! Every count is checked against the number of bytes after the header before anything
//! proportional to it is allocated: binary needs `POINTS × record` bytes; ascii at least
//! two bytes a value; a compressed body's stated sizes must fit the file, its
//! uncompressed size must be `POINTS × record` exactly, and at most
//! [`LZF_MAX_RATIO`] times its compressed size (the most LZF can expand).

use std::io::{BufRead, Read};
use std::path::Path;

use super::header::PcdHeader;
use super::{Schema, le_u32, unpack_rgb};
use crate::io::collect::{Collector, Lines};
use crate::{Error, Result};

/// The most an LZF stream expands: a 3-byte back reference stands for 264 bytes.
const LZF_MAX_RATIO: u64 = 88;

/// Bytes read at a time when checking what follows the last record.
const TAIL_CHUNK: u64 = 1 << 16;

/// A PCD body after its header.
pub(super) struct Body<'a, R> {
    pub reader: R,
    pub path: &'a Path,
    pub header: &'a PcdHeader,
    pub schema: &'a Schema,
    /// Bytes after the header, for a regular file (`None` for a stream).
    pub body_len: Option<u64>,
}

impl<R: BufRead> Body<'_, R> {
    /// Fails when the body needs more than `need` bytes and the file has fewer.
    fn check_size(&self, need: u128, what: &str) -> Result<()> {
        match self.body_len {
            Some(have) if need > u128::from(have) => {
                let msg = format!(
                    "the header declares {} points, which need at least {need} bytes of {what} \
                     data, but only {have} bytes follow the header (truncated file or corrupt \
                     count)",
                    self.header.points
                );
                Err(Error::format(self.path, msg))
            }
            _ => Ok(()),
        }
    }

    /// Reads `DATA ascii`: one point a line, its values separated by blanks.
    pub fn ascii(&mut self, out: &mut Collector) -> Result<()> {
        let h = self.header;
        let per_line = h.values_per_line();
        // One digit and one separator a value; the last may lack its separator.
        self.check_size(
            (2 * per_line as u128 * u128::from(h.points)).saturating_sub(1),
            "ascii",
        )?;
        let mut lines = Lines::new(&mut self.reader, self.path, h.line_count + 1);
        let mut read = 0u64;
        while lines.next_line()? {
            let line = lines.line();
            if line.trim().is_empty() {
                continue;
            }
            if read == h.points {
                return Err(lines.error(format!(
                    "more data after the last of the {} points declared",
                    h.points
                )));
            }
            let tokens: Vec<&str> = line.split_ascii_whitespace().collect();
            if tokens.len() != per_line {
                let msg = format!("{} values, expected {per_line}", tokens.len());
                return Err(lines.error(msg));
            }
            match self.schema.ascii_point(h, &tokens) {
                Ok((xyz, normal, rgb)) => out.push(xyz, normal, rgb),
                Err(msg) => return Err(lines.error(msg)),
            }
            read += 1;
        }
        if read < h.points {
            let msg = format!(
                "truncated ascii body: {read} of the {} points declared",
                h.points
            );
            return Err(Error::format(self.path, msg));
        }
        Ok(())
    }

    /// Reads `DATA binary`: `POINTS` records of the fields' bytes, little-endian.
    pub fn binary(&mut self, out: &mut Collector) -> Result<()> {
        let h = self.header;
        let record = h.record_bytes();
        self.check_size(record as u128 * u128::from(h.points), "binary")?;
        let mut buf = vec![0u8; record];
        for i in 0..h.points {
            self.reader.read_exact(&mut buf).map_err(|e| {
                if e.kind() == std::io::ErrorKind::UnexpectedEof {
                    let msg = format!(
                        "truncated binary body: the file ends inside point {i} of {} declared",
                        h.points
                    );
                    Error::format(self.path, msg)
                } else {
                    Error::io(self.path, e)
                }
            })?;
            let fields = &h.fields;
            self.schema
                .push_binary(fields, |k| &buf[fields[k].offset..], out);
        }
        self.finish()
    }

    /// Reads `DATA binary_compressed`: the compressed and uncompressed sizes (`u32`
    /// each), then one LZF stream holding each field's column in turn.
    pub fn compressed(&mut self, out: &mut Collector) -> Result<()> {
        let h = self.header;
        let mut sizes = [0u8; 8];
        self.reader
            .read_exact(&mut sizes)
            .map_err(|_| self.fail("truncated binary_compressed body: no sizes"))?;
        let packed = u64::from(le_u32(&sizes[..4]));
        let unpacked = u64::from(le_u32(&sizes[4..]));
        let need = h.column_record_bytes() as u128 * u128::from(h.points);
        if u128::from(unpacked) != need {
            let msg = format!(
                "the compressed body says it holds {unpacked} bytes, but {} points of {} bytes \
                 are {need} (corrupt count)",
                h.points,
                h.column_record_bytes()
            );
            return Err(self.fail(&msg));
        }
        self.check_size(8 + u128::from(packed), "compressed")?;
        if unpacked > LZF_MAX_RATIO * packed {
            let msg =
                format!("{packed} compressed bytes cannot hold {unpacked} bytes (corrupt count)");
            return Err(self.fail(&msg));
        }
        let mut input = Vec::new();
        (&mut self.reader)
            .take(packed)
            .read_to_end(&mut input)
            .map_err(|e| Error::io(self.path, e))?;
        if input.len() as u64 != packed {
            let msg = format!(
                "truncated binary_compressed body: {} of {packed} compressed bytes",
                input.len()
            );
            return Err(self.fail(&msg));
        }
        let columns = decompress(&input, unpacked as usize).map_err(|m| self.fail(&m))?;
        self.push_columns(&columns, out);
        self.finish()
    }

    /// Decodes points from the column layout: field `k`'s values for all points, then
    /// field `k + 1`'s (padding fields have no column).
    fn push_columns(&self, columns: &[u8], out: &mut Collector) {
        let h = self.header;
        let n = h.points as usize;
        let mut start = Vec::with_capacity(h.fields.len());
        let mut offset = 0;
        for f in &h.fields {
            start.push(offset);
            offset += f.column_bytes() * n;
        }
        for i in 0..n {
            let fields = &h.fields;
            let at = |k: usize| &columns[start[k] + i * fields[k].column_bytes()..];
            self.schema.push_binary(fields, at, out);
        }
    }

    /// Checks that at most whitespace follows the last record.
    fn finish(&mut self) -> Result<()> {
        let mut chunk = Vec::new();
        loop {
            chunk.clear();
            let n = (&mut self.reader)
                .take(TAIL_CHUNK)
                .read_to_end(&mut chunk)
                .map_err(|e| Error::io(self.path, e))?;
            if n == 0 {
                return Ok(());
            }
            if !chunk.iter().all(u8::is_ascii_whitespace) {
                let msg = format!(
                    "data follows the last of the {} points declared (corrupt count?)",
                    self.header.points
                );
                return Err(self.fail(&msg));
            }
        }
    }

    /// A format error about this file.
    fn fail(&self, msg: &str) -> Error {
        Error::format(self.path, msg)
    }
}

/// LZF-decompresses `input` into exactly `len` bytes.
fn decompress(input: &[u8], len: usize) -> std::result::Result<Vec<u8>, String> {
    let mut output = vec![0u8; len];
    if len == 0 {
        return Ok(output);
    }
    match lzf_rust::decompress(input, &mut output) {
        Ok(n) if n == len => Ok(output),
        Ok(n) => Err(format!(
            "the compressed body decompresses to {n} bytes, not the {len} stated"
        )),
        Err(e) => Err(format!("the compressed body is not valid LZF data ({e})")),
    }
}

impl Schema {
    /// Parses the values that are read from one ascii line's tokens.
    #[allow(clippy::type_complexity)]
    fn ascii_point(
        &self,
        h: &PcdHeader,
        tokens: &[&str],
    ) -> std::result::Result<([f64; 3], [f64; 3], [u8; 3]), String> {
        let num = |k: usize| -> std::result::Result<f64, String> {
            let t = tokens[h.fields[k].value_index];
            t.parse::<f64>()
                .map_err(|_| format!("'{t}' is not a number (field '{}')", h.fields[k].name))
        };
        let xyz = [num(self.xyz[0])?, num(self.xyz[1])?, num(self.xyz[2])?];
        let normal = match self.normal {
            Some([a, b, c]) => [num(a)?, num(b)?, num(c)?],
            None => [0.0; 3],
        };
        let rgb = match self.rgb {
            Some(k) => unpack_rgb(packed_ascii(tokens[h.fields[k].value_index]).ok_or_else(
                || {
                    format!(
                        "'{}' is not a packed colour",
                        tokens[h.fields[k].value_index]
                    )
                },
            )?),
            None => [0; 3],
        };
        Ok((xyz, normal, rgb))
    }
}

/// An ascii packed colour: an unsigned integer (PCL writes `rgb` so), or a float whose
/// bits are the colour.
fn packed_ascii(t: &str) -> Option<u32> {
    t.parse::<u32>()
        .ok()
        .or_else(|| t.parse::<f32>().ok().map(f32::to_bits))
}
