//! ASTM E57 reading through the `e57` crate (pure Rust).
//!
//! Every point cloud (scan) in the file is read, with its pose applied, so the points of
//! all scans come out in the file's common frame as `f64`; spherical coordinates are
//! converted to Cartesian ones. Colours, when every scan has them, are scaled from the
//! file's colour limits to 0–255. Points without a valid position (E57's
//! `cartesianInvalidState` ≠ 0, or a direction without a range) are dropped and counted
//! like non-finite points. Intensity, row and column indices, returns and times are read
//! past.
//!
//! The `e57` crate streams records in packets of at most 64 KiB and refuses XML sections
//! over 50 MiB; before it reads, the XML section is checked to fit in the file, and each
//! scan's record count against the bits a record takes and the bits the file holds, so
//! a corrupt count fails before points are produced from nothing.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

use e57::{CartesianCoordinate, E57Reader, RecordDataType};

use super::collect::Collector;
use super::{CloudFormat, ReadReport};
use crate::{Error, PointCloud, Result};

/// Bytes of the E57 file header read here (the XML length is at byte 32).
const HEADER_BYTES: usize = 48;

/// Reads an E57 file as a point cloud (see the module docs).
pub(crate) fn read_cloud_report(path: &Path) -> Result<(PointCloud, ReadReport)> {
    let mut file = File::open(path).map_err(|e| Error::io(path, e))?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::format(
            path,
            "E57 is read from regular files only (not a pipe or device)",
        ));
    }
    let len = meta.len();
    check_xml_length(&mut file, len, path)?;
    let reader =
        BufReader::with_capacity(1 << 16, File::open(path).map_err(|e| Error::io(path, e))?);
    let mut e57 = E57Reader::new(reader).map_err(|e| e57_error(path, &e))?;
    let scans = e57.pointclouds();
    let mut total = 0u64;
    for (k, scan) in scans.iter().enumerate() {
        check_records(k, scan, len, path)?;
        total = total.saturating_add(scan.records);
    }
    let colors = !scans.is_empty() && scans.iter().all(e57::PointCloud::has_color);
    let mut out = Collector::new(
        false,
        colors,
        usize::try_from(total).unwrap_or(usize::MAX),
        false,
    );
    for scan in &scans {
        let mut points = e57
            .pointcloud_simple(scan)
            .map_err(|e| e57_error(path, &e))?;
        points.apply_pose(true);
        points.spherical_to_cartesian(true);
        points.intensity_to_color(false);
        points.normalize_color(true);
        for p in points {
            let p = p.map_err(|e| e57_error(path, &e))?;
            let xyz = match p.cartesian {
                CartesianCoordinate::Valid { x, y, z } => [x, y, z],
                _ => [f64::NAN; 3],
            };
            let rgb = p.color.map_or([0; 3], |c| {
                [c.red, c.green, c.blue]
                    .map(|v| (f64::from(v) * 255.0).round().clamp(0.0, 255.0) as u8)
            });
            out.push(xyz, [0.0; 3], rgb);
        }
    }
    Ok(out.finish(CloudFormat::E57, Vec::new(), Vec::new()))
}

/// Fails when the header's XML section is longer than the file.
fn check_xml_length(file: &mut File, len: u64, path: &Path) -> Result<()> {
    let mut head = [0u8; HEADER_BYTES];
    file.read_exact(&mut head).map_err(|_| {
        Error::format(
            path,
            format!("truncated E57 file: shorter than its {HEADER_BYTES}-byte header"),
        )
    })?;
    let at = |k: usize| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&head[k..k + 8]);
        u64::from_le_bytes(b)
    };
    let (offset, xml) = (at(24), at(32));
    if offset.saturating_add(xml) > len {
        let msg = format!(
            "the header's XML section ({xml} bytes at byte {offset}) does not fit in the \
             {len}-byte file (truncated file or corrupt length)"
        );
        return Err(Error::format(path, msg));
    }
    Ok(())
}

/// Fails when scan `k` declares more records than the file's bits can hold.
fn check_records(k: usize, scan: &e57::PointCloud, len: u64, path: &Path) -> Result<()> {
    let bits: u128 = scan.prototype.iter().map(|r| bits_of(&r.data_type)).sum();
    let need = u128::from(scan.records) * bits.max(1);
    if need > 8 * u128::from(len) {
        let msg = format!(
            "scan {k} declares {} points of {bits} bits, more than the {len}-byte file holds \
             (corrupt count)",
            scan.records
        );
        return Err(Error::format(path, msg));
    }
    Ok(())
}

/// Bits one value of a record type takes in the file (0 for a constant integer).
fn bits_of(t: &RecordDataType) -> u128 {
    let range_bits = |min: i64, max: i64| {
        let range = i128::from(max) - i128::from(min);
        if range > 0 {
            u128::from(range.ilog2()) + 1
        } else {
            0
        }
    };
    match *t {
        RecordDataType::Single { .. } => 32,
        RecordDataType::Double { .. } => 64,
        RecordDataType::ScaledInteger { min, max, .. } | RecordDataType::Integer { min, max } => {
            range_bits(min, max)
        }
    }
}

/// An `e57` crate error as a one-line format error naming the file.
fn e57_error(path: &Path, e: &e57::Error) -> Error {
    let text = e
        .to_string()
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ");
    Error::format(path, format!("bad E57 file: {text}"))
}
