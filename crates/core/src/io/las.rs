//! LAS 1.0–1.4 and LAZ (LASzip) reading through the `las` crate (its `laz` feature
//! decompresses with the pure-Rust `laz` crate).
//!
//! Positions come out in the file's world coordinates (`integer × scale + offset`, as
//! `f64`: georeferenced values near 10⁶ m keep their millimetres); colours, in point
//! formats that have them, are scaled from LAS's 16 bits to 8 (values all ≤ 255, as some
//! writers store them, are kept as they are). Other dimensions (intensity, returns,
//! classification, GPS time) are read past.
//!
//! Before the `las` crate reads anything, the raw header is checked against the file's
//! size, because the crate trusts its counts: uncompressed points must fit in the bytes
//! after the header; the one extended VLR it reads must fit in the file (its 64-bit
//! length is otherwise allocated as it stands); a LAZ chunk table may not declare more
//! chunks than the file has room for (each chunk starts with one raw point); and a LAZ
//! file may not declare more than [`MAX_LAZ_POINTS_PER_BYTE`] points per byte. Points
//! are then read in batches of [`BATCH`], so no allocation follows a count that the
//! data does not back.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use las::{PointDataBuilder, Reader};

use super::collect::Collector;
use super::{CloudFormat, ReadReport};
use nalgebra::Point3;

use crate::{Error, PointCloud, Result};

/// Points read at a time.
const BATCH: u64 = 1 << 16;

/// The most points a LAZ file may declare per byte of compressed data. LASzip stores
/// real scans in 1–4 bytes a point; even a cloud of identical points costs more than a
/// few thousandths of a bit a point, so more than this is a corrupt count.
const MAX_LAZ_POINTS_PER_BYTE: u64 = 4096;

/// Bytes of an extended VLR's header before its data (the length is at byte 20).
const EVLR_HEADER_BYTES: u64 = 60;

/// What the raw header says, once checked.
struct RawInfo {
    compressed: bool,
    version: (u8, u8),
}

/// Reads a LAS or LAZ file as a point cloud (see the module docs).
pub(crate) fn read_cloud_report(path: &Path) -> Result<(PointCloud, ReadReport)> {
    let (mut file, len) = open_regular(path)?;
    let raw = precheck(&mut file, len, path)?;
    file.seek(SeekFrom::Start(0))
        .map_err(|e| Error::io(path, e))?;
    let mut reader =
        Reader::new(BufReader::with_capacity(1 << 16, file)).map_err(|e| las_error(path, &e))?;
    let header = reader.header().clone();
    let declared = header.number_of_points();
    let has_color = header.point_format().has_color;
    let mut out = Collector::new(
        false,
        has_color,
        usize::try_from(declared).unwrap_or(usize::MAX),
        !raw.compressed,
    );
    let mut rgb16 = Vec::new();
    let mut data = PointDataBuilder::new().for_header(&header).build();
    while out.seen() < declared as usize {
        let got = reader
            .fill_points(BATCH, &mut data)
            .map_err(|e| las_error(path, &e))?;
        if got == 0 {
            let msg = format!("truncated point data: {} of {declared} points", out.seen());
            return Err(Error::format(path, msg));
        }
        let xyz = data.x().zip(data.y()).zip(data.z());
        for ((x, y), z) in xyz {
            out.push([x, y, z], [0.0; 3], [0; 3]);
        }
        if let Some(colors) = data.rgb() {
            rgb16.extend(colors.map(|(r, g, b)| [r, g, b]));
        }
    }
    if let Some(colors) = out.colors_mut() {
        *colors = eight_bit(&rgb16);
    }
    let format = CloudFormat::Las {
        version: raw.version,
        compressed: raw.compressed,
    };
    Ok(out.finish(format, Vec::new(), Vec::new()))
}

/// Visits the points of a LAS/LAZ file in batches of [`BATCH`] (world coordinates, scene
/// units), holding one batch at a time: the memory used does not grow with the file.
/// Checks the file as [`read_cloud_report`] does. Returns the number of points read.
pub(crate) fn visit_points(path: &Path, visit: &mut dyn FnMut(&[[f64; 3]])) -> Result<u64> {
    visit_point_range(path, 0, u64::MAX, visit)
}

/// As [`visit_points`], for the points `first .. first + count` of the file only (clipped
/// to the points it declares; a LAZ reader seeks to the chunk holding `first`), so that
/// several readers can share one pass over a file.
pub(crate) fn visit_point_range(
    path: &Path,
    first: u64,
    count: u64,
    visit: &mut dyn FnMut(&[[f64; 3]]),
) -> Result<u64> {
    let mut reader = open_checked(path)?;
    let header = reader.header().clone();
    let declared = header.number_of_points();
    let first = first.min(declared);
    let end = first.saturating_add(count).min(declared);
    if first > 0 {
        reader.seek(first).map_err(|e| las_error(path, &e))?;
    }
    let mut data = PointDataBuilder::new().for_header(&header).build();
    let mut batch = Vec::with_capacity(BATCH as usize);
    let mut seen = first;
    while seen < end {
        let got = reader
            .fill_points(BATCH.min(end - seen), &mut data)
            .map_err(|e| las_error(path, &e))?;
        if got == 0 {
            let msg = format!("truncated point data: {seen} of {declared} points");
            return Err(Error::format(path, msg));
        }
        batch.clear();
        batch.extend(
            data.x()
                .zip(data.y())
                .zip(data.z())
                .map(|((x, y), z)| [x, y, z]),
        );
        visit(&batch);
        seen += got;
    }
    Ok(seen - first)
}

/// The xyz bounds a LAS/LAZ file's header declares (world coordinates, scene units) and
/// its point count, without reading the points.
pub(crate) fn header_bounds(path: &Path) -> Result<([f64; 3], [f64; 3], u64)> {
    let reader = open_checked(path)?;
    let header = reader.header();
    let b = header.bounds();
    Ok((
        [b.min.x, b.min.y, b.min.z],
        [b.max.x, b.max.y, b.max.z],
        header.number_of_points(),
    ))
}

/// `path` opened, with its length in bytes, when it is a regular file (a LAS/LAZ reader
/// seeks, so a pipe or a device is refused).
fn open_regular(path: &Path) -> Result<(File, u64)> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::format(
            path,
            "LAS/LAZ is read from regular files only (not a pipe or device)",
        ));
    }
    Ok((file, meta.len()))
}

/// A `las` reader over a regular file whose raw header passed [`precheck`].
fn open_checked(path: &Path) -> Result<Reader> {
    let (mut file, len) = open_regular(path)?;
    precheck(&mut file, len, path)?;
    file.seek(SeekFrom::Start(0))
        .map_err(|e| Error::io(path, e))?;
    Reader::new(BufReader::with_capacity(1 << 16, file)).map_err(|e| las_error(path, &e))
}

/// Writes `points` (scene units) as LAS 1.2 point format 0, compressed (LAZ) when the
/// extension is `.laz`, coordinates stored at `scale` (scene units per integer step)
/// from an offset at the points' minimum corner. Written in place (callers stage it).
pub fn write_las(path: &Path, points: &[Point3<f64>], scale: f64) -> Result<()> {
    crate::check::positive("scale", scale)?;
    let (lo, _) = crate::bounds_of(points).ok_or(Error::EmptyCloud)?;
    let mut builder = las::Builder::from((1, 2));
    builder.point_format = las::point::Format::new(0).map_err(|e| las_error(path, &e))?;
    let transform = |offset: f64| las::Transform { scale, offset };
    builder.transforms = las::Vector {
        x: transform(lo.x.floor()),
        y: transform(lo.y.floor()),
        z: transform(lo.z.floor()),
    };
    let header = builder.into_header().map_err(|e| las_error(path, &e))?;
    let mut writer = las::Writer::from_path(path, header).map_err(|e| las_error(path, &e))?;
    for p in points {
        let point = las::Point {
            x: p.x,
            y: p.y,
            z: p.z,
            ..Default::default()
        };
        writer.write_point(point).map_err(|e| las_error(path, &e))?;
    }
    writer.close().map_err(|e| las_error(path, &e))
}

/// LAS colours (16 bits) as 8-bit ones: the high byte, or the value itself when every
/// channel of every point is ≤ 255 (8-bit values stored as they are).
fn eight_bit(rgb16: &[[u16; 3]]) -> Vec<[u8; 3]> {
    let wide = rgb16.iter().flatten().any(|&c| c > 255);
    let shift = if wide { 8 } else { 0 };
    rgb16
        .iter()
        .map(|c| c.map(|v| (v >> shift) as u8))
        .collect()
}

/// A `las` crate error as a one-line format error naming the file.
fn las_error(path: &Path, e: &las::Error) -> Error {
    let text = e
        .to_string()
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ");
    let msg = match e {
        las::Error::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            format!("truncated LAS/LAZ file ({text})")
        }
        _ => format!("bad LAS/LAZ file: {text}"),
    };
    Error::format(path, msg)
}

/// Checks the raw header's counts against the file's size (see the module docs).
fn precheck(file: &mut File, len: u64, path: &Path) -> Result<RawInfo> {
    let raw = las::raw::Header::read_from(&mut *file).map_err(|e| las_error(path, &e))?;
    let fail = |msg: String| Error::format(path, msg);
    let compressed = raw.point_data_record_format & 0xC0 != 0;
    let points = match (raw.number_of_point_records, raw.large_file) {
        (0, Some(large)) => large.number_of_point_records,
        (legacy, _) => u64::from(legacy),
    };
    let start = u64::from(raw.offset_to_point_data);
    let Some(body) = len.checked_sub(start) else {
        return Err(fail(format!(
            "the point data would start at byte {start}, past the end of the {len}-byte file \
             (truncated file?)"
        )));
    };
    let record = u64::from(raw.point_data_record_length);
    if !compressed && u128::from(points) * u128::from(record) > u128::from(body) {
        return Err(fail(format!(
            "the header declares {points} points of {record} bytes, but only {body} bytes of \
             point data follow (truncated file or corrupt count)"
        )));
    }
    if compressed && points > body.saturating_mul(MAX_LAZ_POINTS_PER_BYTE) {
        return Err(fail(format!(
            "the header declares {points} points, more than {body} bytes of LAZ data can hold \
             (corrupt count)"
        )));
    }
    if let Some(evlr) = raw.evlr {
        check_evlr(file, evlr.start_of_first_evlr, len, path)?;
    }
    if compressed {
        check_chunk_table(file, start, len, record.max(1), path)?;
    }
    Ok(RawInfo {
        compressed,
        version: (raw.version.major, raw.version.minor),
    })
}

/// Checks that the first extended VLR (at byte `at`) fits in the file.
fn check_evlr(file: &mut File, at: u64, len: u64, path: &Path) -> Result<()> {
    let fail = || {
        let msg = format!(
            "the extended VLR at byte {at} does not fit in the {len}-byte file (truncated file or corrupt length)"
        );
        Error::format(path, msg)
    };
    if at.saturating_add(EVLR_HEADER_BYTES) > len {
        return Err(fail());
    }
    let data_len = read_u64_at(file, at + 20, path)?;
    if (at + EVLR_HEADER_BYTES).saturating_add(data_len) > len {
        return Err(fail());
    }
    Ok(())
}

/// Checks that a LAZ chunk table does not declare more chunks than the file holds:
/// each chunk begins with one point of `record` bytes stored raw. The table's place is
/// found as LASzip finds it: the offset at the start of the point data, or, when that
/// was never filled in, the last 8 bytes of the file.
fn check_chunk_table(
    file: &mut File,
    data_start: u64,
    len: u64,
    record: u64,
    path: &Path,
) -> Result<()> {
    if data_start + 8 > len {
        return Err(Error::format(
            path,
            "truncated LAZ file: no chunk table offset",
        ));
    }
    let mut table = read_u64_at(file, data_start, path)? as i64;
    if table <= data_start as i64 {
        table = read_u64_at(file, len - 8, path)? as i64;
    }
    let Ok(table) = u64::try_from(table) else {
        return Ok(()); // no table: the decoder reads without one, or fails itself
    };
    if table <= data_start || table.saturating_add(8) > len {
        return Ok(());
    }
    let chunks = read_u64_at(file, table, path)? >> 32;
    if chunks.saturating_mul(record) > len {
        let msg = format!(
            "the LAZ chunk table declares {chunks} chunks, more than the {len}-byte file holds \
             (corrupt count)"
        );
        return Err(Error::format(path, msg));
    }
    Ok(())
}

/// The little-endian `u64` at byte `at`.
fn read_u64_at(file: &mut File, at: u64, path: &Path) -> Result<u64> {
    let mut b = [0u8; 8];
    file.seek(SeekFrom::Start(at))
        .and_then(|_| file.read_exact(&mut b))
        .map_err(|e| Error::io(path, e))?;
    Ok(u64::from_le_bytes(b))
}
