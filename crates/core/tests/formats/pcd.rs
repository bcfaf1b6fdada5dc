//! PCD: ascii, binary and LZF-compressed bodies written here, organised clouds with NaN
//! holes, other field types, and the bad-input catalogue.

use primfit_core::io::{CloudFormat, PcdData, read_cloud, read_cloud_report};

use super::{Sample, Scratch, cloud_of, fails, samples};

/// The fields of the files written here: PCL's `PointXYZRGBNormal` plus curvature.
const FIELDS: &str = "x y z normal_x normal_y normal_z rgb curvature";

/// A PCD header for `points` points of `FIELDS` (all `F 4`), `extra` fields appended.
fn header(width: usize, height: usize, data: &str, extra: &[(&str, &str, usize, usize)]) -> String {
    let mut names = FIELDS.to_string();
    let mut size = "4 4 4 4 4 4 4 4".to_string();
    let mut ty = "F F F F F F F F".to_string();
    let mut count = "1 1 1 1 1 1 1 1".to_string();
    for (name, t, s, c) in extra {
        names += &format!(" {name}");
        size += &format!(" {s}");
        ty += &format!(" {t}");
        count += &format!(" {c}");
    }
    format!(
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {names}\nSIZE {size}\n\
         TYPE {ty}\nCOUNT {count}\nWIDTH {width}\nHEIGHT {height}\nVIEWPOINT 0 0 0 1 0 0 0\n\
         POINTS {}\nDATA {data}\n",
        width * height
    )
}

/// PCL's packed colour.
fn packed(rgb: [u8; 3]) -> u32 {
    (u32::from(rgb[0]) << 16) | (u32::from(rgb[1]) << 8) | u32::from(rgb[2])
}

/// The eight field values of a point, as little-endian bytes.
fn values(s: &Sample) -> [[u8; 4]; 8] {
    let f = |v: f64| (v as f32).to_le_bytes();
    [
        f(s.xyz[0]),
        f(s.xyz[1]),
        f(s.xyz[2]),
        f(s.normal[0]),
        f(s.normal[1]),
        f(s.normal[2]),
        packed(s.rgb).to_le_bytes(), // the float whose bits are the colour
        f(0.25),
    ]
}

/// An ascii PCD file of `pts` (colour as PCL writes it: the packed integer).
pub(super) fn ascii(pts: &[Sample], width: usize) -> Vec<u8> {
    let mut text = header(width, pts.len() / width, "ascii", &[]);
    for s in pts {
        let [x, y, z] = s.xyz;
        let [a, b, c] = s.normal;
        text += &format!("{x} {y} {z} {a} {b} {c} {} 0.25\n", packed(s.rgb));
    }
    text.into_bytes()
}

/// A binary PCD file of `pts`, with a 4-byte `_` padding field after each record.
pub(super) fn binary(pts: &[Sample], width: usize) -> Vec<u8> {
    let mut out = header(width, pts.len() / width, "binary", &[("_", "U", 1, 4)]).into_bytes();
    for s in pts {
        out.extend(values(s).iter().flatten());
        out.extend([0xAB; 4]);
    }
    out
}

/// The column layout of `pts` (field after field), uncompressed.
fn columns(pts: &[Sample]) -> Vec<u8> {
    let mut out = Vec::new();
    for k in 0..8 {
        for s in pts {
            out.extend(values(s)[k]);
        }
    }
    out
}

/// A binary_compressed PCD file of `pts`, compressed with lzf-rust.
pub(super) fn compressed(pts: &[Sample], width: usize) -> Vec<u8> {
    let raw = columns(pts);
    let mut packed = vec![0u8; lzf_rust::max_compressed_size(raw.len())];
    let n = lzf_rust::compress(&raw, &mut packed).expect("compress");
    packed.truncate(n);
    let mut out = header(width, pts.len() / width, "binary_compressed", &[]).into_bytes();
    out.extend((packed.len() as u32).to_le_bytes());
    out.extend((raw.len() as u32).to_le_bytes());
    out.extend(packed);
    out
}

#[test]
fn pcd_ascii_binary_and_compressed_read_the_same_points() {
    let dir = Scratch::new("pcd-round");
    let pts = samples(300);
    let want = cloud_of(&pts, true, true);
    let cases = [
        ("a.pcd", ascii(&pts, 300), PcdData::Ascii),
        ("b.PCD", binary(&pts, 300), PcdData::Binary),
        ("c.pcd", compressed(&pts, 300), PcdData::BinaryCompressed),
    ];
    for (name, bytes, data) in cases {
        let path = dir.write(name, &bytes);
        let (cloud, report) = read_cloud_report(&path).expect(name);
        assert_eq!(cloud, want, "{name}");
        assert_eq!(report.format, CloudFormat::Pcd(data));
        assert_eq!(report.vertices_in_file, 300);
        assert_eq!(report.skipped_non_finite, 0);
        assert_eq!(report.ignored_properties, ["curvature"], "{name}");
        assert_eq!(
            report.comments,
            [".PCD v0.7 - Point Cloud Data file format"]
        );
    }
    // The compressed body really is compressed (the columns repeat a lot).
    assert!(compressed(&pts, 300).len() < binary(&pts, 300).len());
}

#[test]
fn pcd_organised_cloud_drops_nan_holes() {
    let dir = Scratch::new("pcd-organised");
    let mut pts = samples(12);
    let holes = [1, 4, 5, 11];
    for &k in &holes {
        pts[k].xyz = [f64::NAN; 3];
    }
    let kept: Vec<Sample> = (0..12)
        .filter(|k| !holes.contains(k))
        .map(|k| pts[k])
        .collect();
    for (name, bytes) in [
        ("o.pcd", ascii(&pts, 4)),
        ("ob.pcd", binary(&pts, 4)),
        ("oc.pcd", compressed(&pts, 4)),
    ] {
        let path = dir.write(name, &bytes);
        let (cloud, report) = read_cloud_report(&path).expect(name);
        assert_eq!(cloud, cloud_of(&kept, true, true), "{name}");
        assert_eq!(report.vertices_in_file, 12);
        assert_eq!(report.skipped_non_finite, 4);
        assert!(report.warnings()[0].contains("skipped 4 of 12"));
    }
}

#[test]
fn pcd_double_and_integer_fields_without_colour_or_normals() {
    let dir = Scratch::new("pcd-types");
    let head = "VERSION .7\nFIELDS x y z intensity label\nSIZE 8 8 8 2 4\nTYPE F F F U I\n\
                COUNT 1 1 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n";
    let mut bytes = head.as_bytes().to_vec();
    let pts: [[f64; 3]; 2] = [[1e6 + 0.001, -2.5, 3.0e-7], [0.1, 0.2, 0.3]];
    for p in pts {
        for v in p {
            bytes.extend(v.to_le_bytes());
        }
        bytes.extend(7u16.to_le_bytes());
        bytes.extend((-3i32).to_le_bytes());
    }
    let path = dir.write("d.pcd", &bytes);
    let (cloud, report) = read_cloud_report(&path).expect("doubles");
    assert_eq!(cloud.points[0].coords.as_slice(), &pts[0]);
    assert_eq!(cloud.points[1].coords.as_slice(), &pts[1]);
    assert!(cloud.normals.is_none() && cloud.colors.is_none());
    assert_eq!(report.ignored_properties, ["intensity", "label"]);
    // Integer coordinates, a histogram field of COUNT 3, and an rgba field (U 4), ascii.
    let text = "VERSION 0.7\nFIELDS x y z hist rgba\nSIZE 2 2 2 4 4\nTYPE I I U F U\n\
                COUNT 1 1 1 3 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n\
                -4 5 6 0.1 0.2 0.3 4294901760\n";
    let path = dir.write("i.pcd", text.as_bytes());
    let cloud = read_cloud(&path).expect("integers");
    assert_eq!(cloud.points[0].coords.as_slice(), &[-4.0, 5.0, 6.0]);
    assert_eq!(cloud.colors.as_deref(), Some(&[[255, 0, 0]][..]));
}

#[test]
fn pcd_bad_input_catalogue() {
    let dir = Scratch::new("pcd-bad");
    let pts = samples(50);
    let good_binary = binary(&pts, 50);
    let good_packed = compressed(&pts, 50);
    let head_len = header(50, 1, "binary_compressed", &[]).len();
    let patch = |bytes: &[u8], at: usize, v: u32| {
        let mut b = bytes.to_vec();
        b[at..at + 4].copy_from_slice(&v.to_le_bytes());
        b
    };
    let lying_points = String::from_utf8(ascii(&pts, 50))
        .unwrap()
        .replace("POINTS 50", "POINTS 49");
    let huge = header(4_000_000_000, 1, "binary", &[]);
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("empty.pcd", vec![], "empty"),
        (
            "magic.pcd",
            b"hello world\n1 2 3\n".to_vec(),
            "not a PCD file",
        ),
        (
            "png.pcd",
            b"\x89PNG\r\n\x1a\n\0\0\0".to_vec(),
            "not a PCD file",
        ),
        (
            "lzma.pcd",
            header(1, 1, "binary_lzma", &[]).into_bytes(),
            "unknown DATA encoding 'binary_lzma'",
        ),
        (
            "nodata.pcd",
            b"VERSION 0.7\nFIELDS x y z\n".to_vec(),
            "no 'DATA' line",
        ),
        ("grid.pcd", lying_points.into_bytes(), "is not POINTS 49"),
        (
            "noz.pcd",
            b"VERSION 0.7\nFIELDS x y\nSIZE 4 4\nTYPE F F\nWIDTH 0\nHEIGHT 1\nDATA ascii\n"
                .to_vec(),
            "no 'z' field",
        ),
        (
            "sizes.pcd",
            b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 0\nHEIGHT 1\nDATA ascii\n"
                .to_vec(),
            "SIZE has 2 entries for 3 FIELDS",
        ),
        (
            "type.pcd",
            b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 3\nTYPE F F F\nWIDTH 0\nHEIGHT 1\nDATA ascii\n"
                .to_vec(),
            "SIZE 3 is not a size of TYPE F",
        ),
        (
            "truncbin.pcd",
            good_binary[..good_binary.len() - 7].to_vec(),
            "truncated file or corrupt count",
        ),
        (
            "trailing.pcd",
            [good_binary.clone(), vec![1, 2, 3]].concat(),
            "data follows the last of the 50 points",
        ),
        ("huge.pcd", huge.into_bytes(), "4000000000 points"),
        (
            "trunczip.pcd",
            good_packed[..good_packed.len() - 5].to_vec(),
            "truncated file or corrupt count",
        ),
        (
            "liezip.pcd",
            patch(&good_packed, head_len + 4, u32::MAX),
            "corrupt count",
        ),
        (
            "bigzip.pcd",
            patch(&good_packed, head_len, u32::MAX),
            "truncated file or corrupt count",
        ),
        (
            "badlzf.pcd",
            {
                let mut b = good_packed.clone();
                b[head_len + 8] = 0xFF;
                b
            },
            "not valid LZF data",
        ),
    ];
    for (name, bytes, needle) in &cases {
        let path = dir.write(name, bytes);
        fails(read_cloud(&path), &path, needle);
    }
    // Ascii: too few points, a bad value, a short line, more lines than points.
    let text = String::from_utf8(ascii(&pts[..3], 3)).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let n = lines.len();
    let ascii_cases = [
        (
            "short.pcd",
            lines[..n - 1].join("\n"),
            "truncated ascii body: 2 of the 3",
        ),
        (
            "nan.pcd",
            text.replacen("-1 0 ", "-1 zero ", 1),
            "'zero' is not a number",
        ),
        (
            "fewer.pcd",
            text.replacen(" 0.25\n", "\n", 1),
            "7 values, expected 8",
        ),
        (
            "more.pcd",
            format!("{text}{}\n", lines[n - 1]),
            "more data after the last of the 3",
        ),
    ];
    for (name, body, needle) in &ascii_cases {
        let path = dir.write(name, body.as_bytes());
        fails(read_cloud(&path), &path, needle);
    }
    // Nothing but the inputs was written.
    assert_eq!(dir.files().len(), cases.len() + ascii_cases.len());
}
