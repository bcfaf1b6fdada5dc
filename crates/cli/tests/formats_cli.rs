//! `primfit fit` of one scene stored as PCD (ascii, binary, binary_compressed), LAS,
//! LAZ and XYZ/CSV/PTS text gives the PLY's primitives and metrics; a bad file of each
//! format fails with one `error:` line naming the file, exit code 1, nothing written.

use std::fs;
use std::path::Path;

use serde_json::Value;

mod common;
use common::{primfit, temp_dir};

/// A floor (2 m × 2 m) and a wall (1 m high) every 0.125 m: exact in `float`, in
/// decimal, and on a LAS scale of 1/1024, so every format holds the same points.
fn floor_and_wall() -> Vec<[f64; 3]> {
    let mut p = Vec::new();
    for i in 0..16 {
        for j in 0..16 {
            p.push([0.0625 + 0.125 * i as f64, 0.0625 + 0.125 * j as f64, 0.0]);
        }
    }
    for j in 0..16 {
        for k in 0..8 {
            p.push([0.0, 0.0625 + 0.125 * j as f64, 0.0625 + 0.125 * k as f64]);
        }
    }
    p
}

/// Lattice flags that make the floor-and-wall fit small and exact.
const FLOOR_FLAGS: [&str; 6] = ["--types", "square", "--size", "1", "--spacing", "0.5"];

fn write_ply(path: &Path, pts: &[[f64; 3]]) {
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nend_header\n",
        pts.len()
    );
    for [x, y, z] in pts {
        text += &format!("{x} {y} {z}\n");
    }
    fs::write(path, text).expect("write ply");
}

fn pcd_header(n: usize, data: &str) -> String {
    format!(
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n\
         TYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\n\
         DATA {data}\n"
    )
}

fn write_pcd(path: &Path, pts: &[[f64; 3]], data: &str) {
    let mut out = pcd_header(pts.len(), data).into_bytes();
    let f = |v: f64| (v as f32).to_le_bytes();
    match data {
        "ascii" => {
            for [x, y, z] in pts {
                out.extend(format!("{x} {y} {z}\n").bytes());
            }
        }
        "binary" => out.extend(pts.iter().flat_map(|p| p.map(f)).flatten()),
        _ => {
            let raw: Vec<u8> = (0..3)
                .flat_map(|k| pts.iter().flat_map(move |p| f(p[k])))
                .collect();
            let mut packed = vec![0u8; lzf_rust::max_compressed_size(raw.len())];
            let n = lzf_rust::compress(&raw, &mut packed).expect("lzf");
            out.extend((n as u32).to_le_bytes());
            out.extend((raw.len() as u32).to_le_bytes());
            out.extend(&packed[..n]);
        }
    }
    fs::write(path, out).expect("write pcd");
}

fn write_las(path: &Path, pts: &[[f64; 3]]) {
    let mut builder = las::Builder::from((1, 4));
    builder.point_format = las::point::Format::new(6).expect("format");
    let t = las::Transform {
        scale: 1.0 / 1024.0,
        offset: 0.0,
    };
    builder.transforms = las::Vector { x: t, y: t, z: t };
    let mut w =
        las::Writer::from_path(path, builder.into_header().expect("header")).expect("writer");
    for &[x, y, z] in pts {
        let p = las::Point {
            x,
            y,
            z,
            return_number: 1,
            number_of_returns: 1,
            gps_time: Some(0.0),
            ..Default::default()
        };
        w.write_point(p).expect("point");
    }
    w.close().expect("close");
}

fn write_text(path: &Path, pts: &[[f64; 3]], head: &str, sep: &str) {
    let mut text = head.to_string();
    for p in pts {
        text += &p.map(|v| v.to_string()).join(sep);
        text += &format!("{sep}7\n"); // an extra column, ignored
    }
    fs::write(path, text).expect("write text");
}

/// `primfit fit NAME` with the floor flags; returns result.json.
fn fit(dir: &Path, name: &str) -> Value {
    let json = format!("{name}.json");
    let mut args = vec!["fit", name, "-o", &json, "-q"];
    args.extend(FLOOR_FLAGS);
    let out = primfit(dir, &args);
    assert!(
        out.status.success(),
        "{name}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = fs::read_to_string(dir.join(&json)).expect("result json");
    serde_json::from_str(&text).expect("json")
}

#[test]
fn every_format_of_one_scene_gives_the_same_fit() {
    let dir = temp_dir("same-fit");
    let pts = floor_and_wall();
    write_ply(&dir.join("scan.ply"), &pts);
    write_pcd(&dir.join("scan_ascii.pcd"), &pts, "ascii");
    write_pcd(&dir.join("scan_binary.pcd"), &pts, "binary");
    write_pcd(&dir.join("scan_packed.pcd"), &pts, "binary_compressed");
    write_las(&dir.join("scan.las"), &pts);
    write_las(&dir.join("scan.laz"), &pts);
    write_text(&dir.join("scan.xyz"), &pts, "", " ");
    write_text(&dir.join("scan.csv"), &pts, "x,y,z,intensity\n", ",");
    write_text(
        &dir.join("scan.pts"),
        &pts,
        &format!("{}\n", pts.len()),
        " ",
    );
    let reference = fit(&dir, "scan.ply");
    assert_eq!(reference["primitives"].as_array().map(Vec::len), Some(6));
    for name in [
        "scan_ascii.pcd",
        "scan_binary.pcd",
        "scan_packed.pcd",
        "scan.las",
        "scan.laz",
        "scan.xyz",
        "scan.csv",
        "scan.pts",
    ] {
        let doc = fit(&dir, name);
        assert_eq!(doc["primitives"], reference["primitives"], "{name}");
        assert_eq!(doc["metrics"], reference["metrics"], "{name}");
    }
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn bad_files_of_every_format_fail_with_one_line_and_write_nothing() {
    let dir = temp_dir("bad");
    let pts = floor_and_wall();
    write_pcd(&dir.join("good.pcd"), &pts, "binary_compressed");
    write_las(&dir.join("good.laz"), &pts);
    let pcd = fs::read(dir.join("good.pcd")).expect("read");
    let laz = fs::read(dir.join("good.laz")).expect("read");
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "cut.pcd",
            pcd[..pcd.len() - 10].to_vec(),
            "truncated file or corrupt count",
        ),
        (
            "lzma.pcd",
            pcd_header(3, "binary_lzma").into_bytes(),
            "unknown DATA encoding",
        ),
        ("empty.las", vec![], "empty"),
        (
            "count.laz",
            {
                let mut b = laz.clone();
                b[107..111].copy_from_slice(&u32::MAX.to_le_bytes());
                b
            },
            "corrupt count",
        ),
        (
            "cut.e57",
            b"ASTM-E57\0\0\0\0".to_vec(),
            "truncated E57 file",
        ),
        ("short.xyz", b"1 2 3\n4 5\n".to_vec(), "line 2"),
        ("liar.pts", b"5\n1 2 3\n".to_vec(), "truncated PTS body"),
        (
            "scan.obj",
            b"v 1 2 3\n".to_vec(),
            "accepted: PLY (.ply), PCD (.pcd)",
        ),
        (
            "las.pcd",
            laz.clone(),
            "the name says PCD but the content is LAS/LAZ",
        ),
    ];
    for (name, bytes, needle) in &cases {
        fs::write(dir.join(name), bytes).expect("write");
        let before: Vec<_> = fs::read_dir(&dir)
            .expect("ls")
            .map(|e| e.unwrap().file_name())
            .collect();
        let out = primfit(&dir, &["fit", name, "-o", "out.json", "--mesh", "out.ply"]);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(1), "{name}: {stderr}");
        assert_eq!(
            stderr.trim_end().lines().count(),
            1,
            "{name}: one line expected:\n{stderr}"
        );
        assert!(
            stderr.starts_with(&format!("error: {name}")),
            "{name}: {stderr}"
        );
        assert!(
            stderr.contains(needle),
            "{name}: expected {needle:?} in {stderr}"
        );
        let after: Vec<_> = fs::read_dir(&dir)
            .expect("ls")
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(before.len(), after.len(), "{name}: something was written");
    }
    let _ = fs::remove_dir_all(&dir);
}
