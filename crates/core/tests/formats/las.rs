//! LAS 1.2/1.4 and LAZ written by the `las` crate's own writer (georeferenced offsets
//! near 10⁶ m), read back point for point; and the bad-input catalogue.

use std::path::{Path, PathBuf};

use las::point::Format;
use las::{Builder, Color, Transform, Vector, Writer};
use primfit_core::io::{CloudFormat, read_cloud, read_cloud_report};

use super::{Sample, Scratch, fails, samples};

/// The scale of the files written here: exact for the samples' multiples of 1/64.
const SCALE: f64 = 1.0 / 1024.0;

/// A georeferenced offset, as a UTM file would have.
const OFFSET: [f64; 3] = [1_000_000.0, 2_000_000.0, 100.0];

/// Writes `pts` shifted by [`OFFSET`] as LAS `version` in point format `format`; LAZ when
/// `name` ends in `.laz`. Colours are stored 16-bit (`c × 257`) unless `eight_bit`.
pub(super) fn write_las(
    dir: &Scratch,
    name: &str,
    pts: &[Sample],
    version: (u8, u8),
    format: u8,
    eight_bit: bool,
) -> PathBuf {
    let path = dir.path(name);
    let mut builder = Builder::from(version);
    builder.point_format = Format::new(format).expect("point format");
    let t = |offset| Transform {
        scale: SCALE,
        offset,
    };
    builder.transforms = Vector {
        x: t(OFFSET[0]),
        y: t(OFFSET[1]),
        z: t(OFFSET[2]),
    };
    let header = builder.into_header().expect("header");
    let mut writer = Writer::from_path(&path, header).expect("writer");
    for s in pts {
        let c = |v: u8| {
            if eight_bit {
                u16::from(v)
            } else {
                u16::from(v) * 257
            }
        };
        let point = las::Point {
            x: s.xyz[0] + OFFSET[0],
            y: s.xyz[1] + OFFSET[1],
            z: s.xyz[2] + OFFSET[2],
            return_number: 1,
            number_of_returns: 1,
            gps_time: writer.header().point_format().has_gps_time.then_some(12.5),
            color: writer
                .header()
                .point_format()
                .has_color
                .then(|| Color::new(c(s.rgb[0]), c(s.rgb[1]), c(s.rgb[2]))),
            ..Default::default()
        };
        writer.write_point(point).expect("write point");
    }
    writer.close().expect("close");
    path
}

/// The samples' positions shifted by [`OFFSET`], as the reader must give them.
fn shifted(pts: &[Sample]) -> Vec<[f64; 3]> {
    pts.iter()
        .map(|s| [0, 1, 2].map(|k| s.xyz[k] + OFFSET[k]))
        .collect()
}

#[test]
fn las_and_laz_versions_read_the_same_points() {
    let dir = Scratch::new("las-round");
    let pts = samples(70_000); // more than one LAZ chunk of 50 000 and one read batch
    let want = shifted(&pts);
    let colors: Vec<[u8; 3]> = pts.iter().map(|s| s.rgb).collect();
    let cases = [
        ("a12.las", (1, 2), 2, false),
        ("b14.las", (1, 4), 7, false),
        ("c12.laz", (1, 2), 3, false),
        ("d14.LAZ", (1, 4), 7, true),
        ("e13.las", (1, 3), 0, false),
    ];
    for (name, version, format, eight) in cases {
        let path = write_las(&dir, name, &pts, version, format, eight);
        let (cloud, report) = read_cloud_report(&path).expect(name);
        let got: Vec<[f64; 3]> = cloud.points.iter().map(|p| [p.x, p.y, p.z]).collect();
        assert!(got == want, "{name}: positions differ");
        let compressed = name.to_lowercase().ends_with(".laz");
        assert_eq!(
            report.format,
            CloudFormat::Las {
                version,
                compressed
            }
        );
        let has_color = format != 0;
        assert_eq!(
            cloud.colors.as_ref(),
            has_color.then_some(&colors),
            "{name}"
        );
        assert!(cloud.normals.is_none());
    }
}

/// Overwrites 4 or 8 little-endian bytes at `at`.
fn patch(path: &Path, at: usize, bytes: &[u8]) -> Vec<u8> {
    let mut b = std::fs::read(path).expect("read");
    b[at..at + bytes.len()].copy_from_slice(bytes);
    b
}

#[test]
fn las_bad_input_catalogue() {
    let dir = Scratch::new("las-bad");
    let pts = samples(500);
    let las12 = write_las(&dir, "good12.las", &pts, (1, 2), 2, false);
    let las14 = write_las(&dir, "good14.las", &pts, (1, 4), 6, false);
    let laz = write_las(&dir, "good.laz", &pts, (1, 2), 3, false);
    let bytes12 = std::fs::read(&las12).expect("read");
    let bytes_laz = std::fs::read(&laz).expect("read");
    // Byte offsets in the public header block.
    const POINT_COUNT: usize = 107; // u32, legacy count
    const EVLR_START: usize = 235; // u64 (1.4)
    const EVLR_COUNT: usize = 243; // u32 (1.4)
    const LARGE_COUNT: usize = 247; // u64 (1.4)
    let data_start = u32::from_le_bytes(bytes_laz[96..100].try_into().unwrap()) as usize;
    // One extended VLR 100 bytes before the end whose length is 2^62 bytes.
    let evlr_at = std::fs::metadata(&las14).expect("size").len() as usize - 100;
    let mut hostile_evlr = patch(&las14, EVLR_START, &(evlr_at as u64).to_le_bytes());
    hostile_evlr[EVLR_COUNT..EVLR_COUNT + 4].copy_from_slice(&1u32.to_le_bytes());
    hostile_evlr[evlr_at + 20..evlr_at + 28].copy_from_slice(&(1u64 << 62).to_le_bytes());
    let mut huge14 = patch(&las14, POINT_COUNT, &0u32.to_le_bytes());
    huge14[LARGE_COUNT..LARGE_COUNT + 8].copy_from_slice(&(u64::MAX / 2).to_le_bytes());
    // A chunk table of 2^31 chunks at the place the file says.
    let table = u64::from_le_bytes(bytes_laz[data_start..data_start + 8].try_into().unwrap());
    let chunks = patch(&laz, table as usize + 4, &(1u32 << 31).to_le_bytes());
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("empty.las", vec![], "empty"),
        (
            "magic.las",
            b"LASX and more bytes".to_vec(),
            "does not start with 'LASF'",
        ),
        ("short.las", b"LASF\x00\x00".to_vec(), "truncated"),
        (
            "cut.las",
            bytes12[..bytes12.len() - 9].to_vec(),
            "truncated file or corrupt count",
        ),
        (
            "count.las",
            patch(&las12, POINT_COUNT, &4_000_000_000u32.to_le_bytes()),
            "4000000000 points",
        ),
        ("huge14.las", huge14, "corrupt count"),
        ("evlr.las", hostile_evlr, "extended VLR"),
        (
            "cut.laz",
            bytes_laz[..bytes_laz.len() / 2].to_vec(),
            "LAS/LAZ",
        ),
        (
            "count.laz",
            patch(&laz, POINT_COUNT, &u32::MAX.to_le_bytes()),
            "corrupt count",
        ),
        (
            "chunks.laz",
            chunks,
            "chunk table declares 2147483648 chunks",
        ),
        (
            "named.las",
            b"ASTM-E57 file".to_vec(),
            "the name says LAS/LAZ but the content is E57",
        ),
    ];
    for (name, bytes, needle) in &cases {
        let path = dir.write(name, bytes);
        fails(read_cloud(&path), &path, needle);
    }
    assert_eq!(dir.files().len(), cases.len() + 3);
}
