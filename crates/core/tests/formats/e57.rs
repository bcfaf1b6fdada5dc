//! E57 written by the `e57` crate's own writer: two scans with poses (one georeferenced
//! near 10⁶ m), colours and invalid points; and the bad-input catalogue.

use std::path::PathBuf;

use e57::{E57Writer, Quaternion, Record, RecordValue, Transform, Translation};
use primfit_core::io::{CloudFormat, read_cloud, read_cloud_report};

use super::{Sample, Scratch, fails, samples};

/// Bytes of an E57 page (the last 4 are its CRC-32C, big-endian).
const PAGE: usize = 1024;

/// The guid of the first scan: the padding is cut to make room in the lying-count test.
const GUID_A: &str = "scan-a-padding-padding";

/// Scan A's pose: a pure translation to a georeferenced place.
const OFFSET: [f64; 3] = [1_000_000.0, 2_000_000.0, 100.0];

/// Writes scan A (`a`, pose: translation by [`OFFSET`]) and scan B (`b`, pose: 90° about
/// z then (10, 0, 0); every fifth point flagged invalid).
pub(super) fn write_e57(dir: &Scratch, name: &str, a: &[Sample], b: &[Sample]) -> PathBuf {
    let path = dir.path(name);
    let mut w = E57Writer::from_file(&path, "file-guid").expect("writer");
    let xyz_rgb = || {
        vec![
            Record::CARTESIAN_X_F64,
            Record::CARTESIAN_Y_F64,
            Record::CARTESIAN_Z_F64,
            Record::COLOR_RED_U8,
            Record::COLOR_GREEN_U8,
            Record::COLOR_BLUE_U8,
        ]
    };
    let values = |s: &Sample| -> Vec<RecordValue> {
        let mut v: Vec<RecordValue> = s.xyz.iter().map(|&c| RecordValue::Double(c)).collect();
        v.extend(s.rgb.iter().map(|&c| RecordValue::Integer(i64::from(c))));
        v
    };
    let half = std::f64::consts::FRAC_1_SQRT_2;
    let scans = [
        (GUID_A, a, [1.0, 0.0, 0.0, 0.0], OFFSET, false),
        ("scan-b", b, [half, 0.0, 0.0, half], [10.0, 0.0, 0.0], true),
    ];
    for (guid, pts, [qw, qx, qy, qz], [tx, ty, tz], flagged) in scans {
        let mut proto = xyz_rgb();
        if flagged {
            proto.push(Record::CARTESIAN_INVALID_STATE);
        }
        let mut pc = w.add_pointcloud(guid, proto).expect("scan");
        pc.set_transform(Some(Transform {
            rotation: Quaternion {
                w: qw,
                x: qx,
                y: qy,
                z: qz,
            },
            translation: Translation {
                x: tx,
                y: ty,
                z: tz,
            },
        }));
        for (i, s) in pts.iter().enumerate() {
            let mut v = values(s);
            if flagged {
                v.push(RecordValue::Integer(if i % 5 == 0 { 2 } else { 0 }));
            }
            pc.add_point(v).expect("point");
        }
        pc.finalize().expect("finalize scan");
    }
    w.finalize().expect("finalize file");
    path
}

#[test]
fn e57_scans_read_with_their_poses() {
    let dir = Scratch::new("e57-round");
    let pts = samples(500);
    let (a, b) = pts.split_at(300);
    let path = write_e57(&dir, "two.E57", a, b);
    let (cloud, report) = read_cloud_report(&path).expect("e57");
    assert_eq!(report.format, CloudFormat::E57);
    assert_eq!(report.vertices_in_file, 500);
    assert_eq!(report.skipped_non_finite, 40); // every fifth of scan B
    assert_eq!(cloud.len(), 460);
    // Scan A: translated exactly (the samples are exact binary fractions).
    for (p, s) in cloud.points.iter().zip(a) {
        assert_eq!([p.x, p.y, p.z], [0, 1, 2].map(|k| s.xyz[k] + OFFSET[k]));
    }
    // Scan B: rotated by 90° about z, then moved by (10, 0, 0).
    let kept: Vec<&Sample> = b
        .iter()
        .enumerate()
        .filter(|(i, _)| i % 5 != 0)
        .map(|(_, s)| s)
        .collect();
    for (p, s) in cloud.points[300..].iter().zip(&kept) {
        let want = [10.0 - s.xyz[1], s.xyz[0], s.xyz[2]];
        for k in 0..3 {
            assert!((p[k] - want[k]).abs() < 1e-12, "{p:?} vs {want:?}");
        }
    }
    let colors = cloud.colors.as_ref().expect("colours");
    let want: Vec<[u8; 3]> = a
        .iter()
        .chain(kept.iter().copied())
        .map(|s| s.rgb)
        .collect();
    assert_eq!(colors, &want);
}

/// CRC-32C (Castagnoli), as E57 pages carry it.
fn crc32c(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &byte in data {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0x82F6_3B78
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// The file with `from` replaced by `to` (same length) in its logical bytes, and every
/// page's CRC recomputed: a well-formed file that says something else.
fn rewrite(bytes: &[u8], from: &str, to: &str) -> Vec<u8> {
    assert_eq!(from.len(), to.len());
    let mut logical: Vec<u8> = bytes
        .chunks(PAGE)
        .flat_map(|p| p[..PAGE - 4].to_vec())
        .collect();
    let at = logical
        .windows(from.len())
        .position(|w| w == from.as_bytes())
        .expect("text to replace");
    logical[at..at + to.len()].copy_from_slice(to.as_bytes());
    logical
        .chunks(PAGE - 4)
        .flat_map(|p| {
            let mut page = p.to_vec();
            page.extend(crc32c(p).to_be_bytes());
            page
        })
        .collect()
}

#[test]
fn e57_bad_input_catalogue() {
    let dir = Scratch::new("e57-bad");
    let pts = samples(400);
    let good = write_e57(&dir, "good.e57", &pts[..300], &pts[300..]);
    let bytes = std::fs::read(&good).expect("read");
    assert_eq!(
        rewrite(&bytes, "scan-b", "scan-b"),
        bytes,
        "the CRC is E57's"
    );
    let mut flipped = bytes.clone();
    flipped[5000] ^= 0x55;
    let mut xml_len = bytes.clone();
    xml_len[32..40].copy_from_slice(&(1u64 << 40).to_le_bytes());
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("empty.e57", vec![], "empty"),
        (
            "magic.e57",
            b"ASTM-E58 nope".to_vec(),
            "does not start with 'ASTM-E57'",
        ),
        (
            "short.e57",
            b"ASTM-E57\0\0\0\0".to_vec(),
            "truncated E57 file",
        ),
        (
            "cut.e57",
            bytes[..bytes.len() - PAGE].to_vec(),
            "truncated file",
        ),
        ("crc.e57", flipped, "checksum"),
        ("xml.e57", xml_len, "XML section"),
        (
            "named.e57",
            b"ply\nformat ascii 1.0\n".to_vec(),
            "the name says E57 but the content is PLY",
        ),
    ];
    for (name, bytes, needle) in &cases {
        let path = dir.write(name, bytes);
        fails(read_cloud(&path), &path, needle);
    }
    assert_eq!(dir.files().len(), cases.len() + 1);
}

#[test]
fn e57_lying_record_count_fails_before_reading_points() {
    let dir = Scratch::new("e57-count");
    let pts = samples(400);
    let good = write_e57(&dir, "good.e57", &pts[..300], &pts[300..]);
    let bytes = std::fs::read(&good).expect("read");
    // Scan A's count 300 becomes 300 000 000 000; its guid gives up the 9 bytes.
    let logical: Vec<u8> = bytes
        .chunks(PAGE)
        .flat_map(|p| p[..PAGE - 4].to_vec())
        .collect();
    let xml = String::from_utf8_lossy(&logical);
    let count_at = xml.find("recordCount=\"300\"").expect("scan A's count");
    let guid_at = xml.find(GUID_A).expect("scan A's guid");
    let (from, to) = if guid_at < count_at {
        let from = xml[guid_at..count_at + 17].to_string();
        let to = from.replacen(GUID_A, "scan-a-paddin", 1).replacen(
            "recordCount=\"300\"",
            "recordCount=\"300000000000\"",
            1,
        );
        (from, to)
    } else {
        let from = xml[count_at..guid_at + GUID_A.len()].to_string();
        let to = from
            .replacen("recordCount=\"300\"", "recordCount=\"300000000000\"", 1)
            .replacen(GUID_A, "scan-a-paddin", 1);
        (from, to)
    };
    let path = dir.write("count.e57", &rewrite(&bytes, &from, &to));
    fails(
        read_cloud(&path),
        &path,
        "scan 0 declares 300000000000 points",
    );
}
