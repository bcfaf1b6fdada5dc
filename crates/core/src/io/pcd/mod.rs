//! PCD (the Point Cloud Library's format) reading: `DATA ascii`, `binary` and
//! `binary_compressed` (LZF, decompressed by `lzf-rust`).
//!
//! Hand-written rather than through `pcd-rs` 0.13 because that crate keeps none of the
//! reading promises of [`crate::io`]: it allocates the compressed and uncompressed
//! sizes of a `binary_compressed` body as the file states them (two 32-bit counts,
//! up to 4 GiB each) before checking them against the file, allocates a buffer per
//! padding field and per point from an unchecked `COUNT`, builds one `Vec` per field
//! per point, and reports faults without the file or line. The format itself is a
//! short text header over little-endian records; only the LZF decoder is a crate.
//!
//! Fields read: `x y z` (required, one value each, any numeric type), `normal_x
//! normal_y normal_z` (all three, or none), and `rgb` or `rgba` (PCL's packed
//! `0x00RRGGBB` in a 4-byte float or unsigned field). Other fields (`curvature`,
//! `intensity`, histograms with `COUNT > 1`, `_` padding) are read past and listed in
//! [`ReadReport::ignored_properties`](crate::io::ReadReport::ignored_properties).
//! Points with a NaN or infinite coordinate (the holes of an organised cloud) are
//! dropped and counted.

mod body;
mod header;

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use self::header::{Field, PcdHeader, read_header};
use super::collect::Collector;
use super::{CloudFormat, PcdData, ReadReport};
use crate::{Error, PointCloud, Result};

/// Which fields hold the attributes that are read.
pub(super) struct Schema {
    /// The `x`, `y`, `z` fields.
    xyz: [usize; 3],
    /// The `normal_x`, `normal_y`, `normal_z` fields, when all three are there.
    normal: Option<[usize; 3]>,
    /// The packed `rgb`/`rgba` field.
    rgb: Option<usize>,
    /// Fields read past.
    ignored: Vec<String>,
}

impl Schema {
    /// The schema of `h`, failing when it has no `x`, `y` or `z`.
    fn of(h: &PcdHeader, path: &Path) -> Result<Self> {
        let single = |name: &str| -> Result<Option<usize>> {
            match h.field(name) {
                Some(k) if h.fields[k].count != 1 => Err(Error::format(
                    path,
                    format!(
                        "PCD field '{name}' has COUNT {}, expected 1",
                        h.fields[k].count
                    ),
                )),
                found => Ok(found),
            }
        };
        let mut xyz = [0; 3];
        for (slot, name) in xyz.iter_mut().zip(["x", "y", "z"]) {
            *slot = single(name)?.ok_or_else(|| {
                let have: Vec<&str> = h.fields.iter().map(|f| f.name.as_str()).collect();
                let msg = format!(
                    "the PCD file has no '{name}' field (it has: [{}])",
                    have.join(", ")
                );
                Error::format(path, msg)
            })?;
        }
        let normal = match ["normal_x", "normal_y", "normal_z"].map(single) {
            [Ok(Some(a)), Ok(Some(b)), Ok(Some(c))] => Some([a, b, c]),
            _ => None,
        };
        let rgb = ["rgb", "rgba"]
            .iter()
            .filter_map(|n| h.field(n))
            .find(|&k| h.fields[k].bytes() == 4 && h.fields[k].ty != b'I');
        let used: Vec<usize> = xyz
            .iter()
            .chain(normal.iter().flatten())
            .chain(rgb.iter())
            .copied()
            .collect();
        let ignored = (0..h.fields.len())
            .filter(|k| !used.contains(k) && h.fields[*k].name != "_")
            .map(|k| h.fields[k].name.clone())
            .collect();
        Ok(Schema {
            xyz,
            normal,
            rgb,
            ignored,
        })
    }

    /// Decodes one point from binary values: `at(k)` is the byte slice of field `k`.
    fn push_binary<'a>(
        &self,
        fields: &[Field],
        at: impl Fn(usize) -> &'a [u8],
        out: &mut Collector,
    ) {
        let num = |k: usize| number(at(k), &fields[k]);
        let xyz = self.xyz.map(num);
        let normal = self.normal.map_or([0.0; 3], |n| n.map(num));
        let rgb = self.rgb.map_or([0; 3], |k| unpack_rgb(le_u32(at(k))));
        out.push(xyz, normal, rgb);
    }
}

/// A binary value of `f` as `f64` (`b` holds at least `f.size` bytes).
fn number(b: &[u8], f: &Field) -> f64 {
    let mut raw = [0u8; 8];
    raw[..f.size].copy_from_slice(&b[..f.size]);
    match (f.ty, f.size) {
        (b'F', 4) => f64::from(f32::from_le_bytes([raw[0], raw[1], raw[2], raw[3]])),
        (b'F', _) => f64::from_le_bytes(raw),
        (b'I', 1) => f64::from(raw[0] as i8),
        (b'I', 2) => f64::from(i16::from_le_bytes([raw[0], raw[1]])),
        (b'I', 4) => f64::from(i32::from_le_bytes([raw[0], raw[1], raw[2], raw[3]])),
        (b'I', _) => i64::from_le_bytes(raw) as f64,
        _ => u64::from_le_bytes(raw) as f64,
    }
}

/// The little-endian `u32` at the start of `b`.
fn le_u32(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}

/// PCL's packed colour `0x??RRGGBB` as `[r, g, b]`.
fn unpack_rgb(v: u32) -> [u8; 3] {
    [(v >> 16) as u8, (v >> 8) as u8, v as u8]
}

/// Reads a PCD file as a point cloud (see the module docs).
pub(crate) fn read_cloud_report(path: &Path) -> Result<(PointCloud, ReadReport)> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    let mut reader = BufReader::with_capacity(1 << 16, file);
    let header = read_header(&mut reader, path)?;
    let schema = Schema::of(&header, path)?;
    let body_len = meta
        .is_file()
        .then(|| meta.len().saturating_sub(header.byte_len));
    let mut out = Collector::new(
        schema.normal.is_some(),
        schema.rgb.is_some(),
        usize::try_from(header.points).unwrap_or(usize::MAX),
        false,
    );
    let mut body = body::Body {
        reader,
        path,
        header: &header,
        schema: &schema,
        body_len,
    };
    match header.data {
        PcdData::Ascii => body.ascii(&mut out)?,
        PcdData::Binary => body.binary(&mut out)?,
        PcdData::BinaryCompressed => body.compressed(&mut out)?,
    }
    let ignored = schema.ignored;
    Ok(out.finish(CloudFormat::Pcd(header.data), ignored, header.comments))
}
