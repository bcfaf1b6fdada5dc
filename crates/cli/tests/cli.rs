//! Integration tests of the `primfit` binary: PLY variants as other tools write them,
//! every kind of bad input (one `error:` line naming the file, exit code, no partial or
//! clobbered output), the synth → fit → eval round trip, determinism, and terminal
//! behaviour. Every run sets `RUST_BACKTRACE=1` and checks that nothing panicked.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

// ---------------------------------------------------------------------------------------
// Running the binary
// ---------------------------------------------------------------------------------------

/// A fresh, empty folder for one test.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("primfit-cli-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

/// Runs `primfit ARGS` in `dir` with piped stdout and stderr.
fn primfit(dir: &Path, args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_primfit"))
        .args(args)
        .current_dir(dir)
        .env("RUST_BACKTRACE", "1")
        .env("NO_COLOR", "1")
        .output()
        .expect("run primfit");
    let (stdout, stderr) = texts(&out);
    for text in [&stdout, &stderr] {
        assert!(
            !text.contains("panicked") && !text.contains("stack backtrace"),
            "primfit {args:?} panicked:\n{text}"
        );
    }
    out
}

fn texts(out: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Runs `primfit ARGS` and asserts success; returns (stdout, stderr).
fn ok(dir: &Path, args: &[&str]) -> (String, String) {
    let out = primfit(dir, args);
    let (stdout, stderr) = texts(&out);
    assert!(
        out.status.success(),
        "primfit {args:?} failed ({:?}):\n{stdout}\n{stderr}",
        out.status.code()
    );
    (stdout, stderr)
}

/// Runs `primfit ARGS`, asserts exit code 1 and a single `error:` line on stderr that
/// contains `needle` (the file or flag at fault); returns that line.
fn fails(dir: &Path, args: &[&str], needle: &str) -> String {
    let out = primfit(dir, args);
    let (stdout, stderr) = texts(&out);
    assert_eq!(
        out.status.code(),
        Some(1),
        "primfit {args:?} should fail with 1:\n{stdout}\n{stderr}"
    );
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "one error line expected:\n{stderr}");
    assert_eq!(
        stderr.trim_end().lines().count(),
        1,
        "nothing but the error line expected on stderr:\n{stderr}"
    );
    let line = errors[0].to_string();
    assert!(
        line.contains(needle),
        "the error should name {needle:?}: {line}"
    );
    line
}

fn read_json(path: &Path) -> Value {
    let text = fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn file_names(dir: &Path) -> BTreeSet<String> {
    fs::read_dir(dir)
        .expect("list dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect()
}

/// The PLY header of a file (up to and including `end_header`).
fn ply_header(path: &Path) -> String {
    let bytes = fs::read(path).expect("read ply");
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("end_header");
    String::from_utf8_lossy(&bytes[..end + 11]).into_owned()
}

// ---------------------------------------------------------------------------------------
// Fixtures: a small scene, written with other tools' PLY conventions
// ---------------------------------------------------------------------------------------

/// A floor (2 m × 2 m, z = 0) and a wall (x = 0, 1 m high) sampled every 0.125 m: every
/// coordinate is exact in `float`, so every encoding holds the very same points.
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

/// PCL's `pcl::io::savePLYFileASCII` of a `PointNormal` cloud: `normal_x…`, `curvature`,
/// a `camera` element after the vertices, and `nan` for invalid points.
fn write_pcl_ascii(path: &Path, points: &[[f64; 3]], nan_rows: usize) {
    let n = points.len() + nan_rows;
    let mut s = format!(
        "ply\nformat ascii 1.0\ncomment PCL generated\nelement vertex {n}\n\
         property float x\nproperty float y\nproperty float z\n\
         property float normal_x\nproperty float normal_y\nproperty float normal_z\n\
         property float curvature\n\
         element camera 1\nproperty float view_px\nproperty float view_py\nproperty float view_pz\n\
         property float x_axisx\nproperty float x_axisy\nproperty float x_axisz\n\
         property float y_axisx\nproperty float y_axisy\nproperty float y_axisz\n\
         property float z_axisx\nproperty float z_axisy\nproperty float z_axisz\n\
         property float focal\nproperty float scalex\nproperty float scaley\n\
         property float centerx\nproperty float centery\n\
         property int viewportx\nproperty int viewporty\n\
         property float k1\nproperty float k2\nend_header\n"
    );
    for (i, p) in points.iter().enumerate() {
        s += &format!("{} {} {} 0 0 1 0\n", p[0], p[1], p[2]);
        if i < nan_rows {
            s += "nan nan nan nan nan nan nan\n";
        }
    }
    s += "0 0 0 1 0 0 0 1 0 0 0 1 0 0 0 0 0 640 480 0 0\n";
    fs::write(path, s).expect("write pcl fixture");
}

/// MeshLab (VCG) binary little-endian export of a point set: float coordinates and
/// normals, uchar RGBA, and an empty `face` element.
fn write_meshlab_binary(path: &Path, points: &[[f64; 3]]) {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\ncomment VCGLIB generated\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n\
         element face 0\nproperty list uchar int vertex_indices\nend_header\n",
        points.len()
    )
    .into_bytes();
    for p in points {
        for v in [p[0], p[1], p[2], 0.0, 0.0, 1.0] {
            b.extend((v as f32).to_le_bytes());
        }
        b.extend([200u8, 100, 50, 255]);
    }
    fs::write(path, b).expect("write meshlab fixture");
}

/// CloudCompare binary little-endian export: `obj_info` line, colours and scalar fields
/// (`scalar_Intensity`, `scalar_Classification`).
fn write_cloudcompare_binary(path: &Path, points: &[[f64; 3]]) {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\n\
         comment Created by CloudCompare v2.13.0\ncomment Created 2024-05-01T10:00:00\n\
         obj_info Generated by CloudCompare!\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n\
         property float scalar_Intensity\nproperty float scalar_Classification\nend_header\n",
        points.len()
    )
    .into_bytes();
    for (i, p) in points.iter().enumerate() {
        for v in p {
            b.extend((*v as f32).to_le_bytes());
        }
        b.extend([1u8, 2, 3]);
        b.extend((i as f32 * 0.5).to_le_bytes());
        b.extend(2.0f32.to_le_bytes());
    }
    fs::write(path, b).expect("write cloudcompare fixture");
}

/// Big-endian `double` coordinates with an integer label and a `ushort` intensity, CRLF
/// header lines and sized type names (`float64`, `int32`, `uint16`).
fn write_big_endian_double(path: &Path, points: &[[f64; 3]]) {
    let mut b = format!(
        "ply\r\nformat binary_big_endian 1.0\r\ncomment big-endian doubles\r\n\
         element vertex {}\r\nproperty float64 x\r\nproperty float64 y\r\nproperty float64 z\r\n\
         property int32 label\r\nproperty uint16 intensity\r\nend_header\r\n",
        points.len()
    )
    .into_bytes();
    for p in points {
        for v in p {
            b.extend(v.to_be_bytes());
        }
        b.extend(2i32.to_be_bytes());
        b.extend(1000u16.to_be_bytes());
    }
    fs::write(path, b).expect("write big-endian fixture");
}

/// Plain ascii with tabs, blank lines between records and a trailing newline missing.
fn write_plain_ascii(path: &Path, points: &[[f64; 3]]) {
    let mut s = format!(
        "ply\nformat ascii 1.0\ncomment hand-written\nobj_info scanner: none\n\
         element vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
         property uchar intensity\nend_header\n",
        points.len()
    );
    let rows: Vec<String> = points
        .iter()
        .map(|p| format!("{}\t{}  {} 7", p[0], p[1], p[2]))
        .collect();
    s += &rows.join("\n");
    fs::write(path, s).expect("write ascii fixture");
}

/// An ascii PLY body of `x y z` rows with the given header vertex count.
fn ascii_xyz(count: &str, rows: &[&str]) -> String {
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {count}\n\
         property float x\nproperty float y\nproperty float z\nend_header\n"
    );
    for r in rows {
        s += r;
        s += "\n";
    }
    s
}

/// A closed 0.4 × 0.3 × 0.2 m box centred at the origin, as quads (ascii PLY).
fn write_box_mesh(path: &Path) {
    let s = "ply\nformat ascii 1.0\ncomment box 0.4 x 0.3 x 0.2, quad faces\n\
             element vertex 8\nproperty float x\nproperty float y\nproperty float z\n\
             element face 6\nproperty list uchar int vertex_indices\nend_header\n\
             -0.2 -0.15 -0.1\n0.2 -0.15 -0.1\n0.2 0.15 -0.1\n-0.2 0.15 -0.1\n\
             -0.2 -0.15 0.1\n0.2 -0.15 0.1\n0.2 0.15 0.1\n-0.2 0.15 0.1\n\
             4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n";
    fs::write(path, s).expect("write box mesh");
}

/// Points on the faces of that box, moved to `centre` (a regular grid per face).
fn box_points(centre: [f64; 3]) -> Vec<[f64; 3]> {
    let half: [f64; 3] = [0.2, 0.15, 0.1];
    let step = 0.025;
    let mut out = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let nu = (2.0 * half[u] / step).round() as usize;
        let nv = (2.0 * half[v] / step).round() as usize;
        for side in [-1.0, 1.0] {
            for i in 0..nu {
                for j in 0..nv {
                    let mut p = [0.0; 3];
                    p[axis] = side * half[axis];
                    p[u] = -half[u] + step * (i as f64 + 0.5);
                    p[v] = -half[v] + step * (j as f64 + 0.5);
                    out.push([p[0] + centre[0], p[1] + centre[1], p[2] + centre[2]]);
                }
            }
        }
    }
    out
}

// ---------------------------------------------------------------------------------------
// PLY variants
// ---------------------------------------------------------------------------------------

#[test]
fn every_ply_variant_gives_the_same_fit() {
    let dir = temp_dir("variants");
    let points = floor_and_wall();
    write_plain_ascii(&dir.join("plain.ply"), &points);
    write_pcl_ascii(&dir.join("pcl.ply"), &points, 5);
    write_meshlab_binary(&dir.join("meshlab.ply"), &points);
    write_cloudcompare_binary(&dir.join("cloudcompare.ply"), &points);
    write_big_endian_double(&dir.join("bigendian.ply"), &points);

    let fit = |name: &str| {
        let json = format!("{name}.json");
        let mut args = vec!["fit", name, "-o", &json];
        args.extend(FLOOR_FLAGS);
        let (stdout, stderr) = ok(&dir, &args);
        let doc = read_json(&dir.join(&json));
        (stdout, stderr, doc)
    };
    let (stdout, stderr, reference) = fit("plain.ply");
    assert!(stderr.is_empty(), "no warnings expected: {stderr}");
    assert!(
        stdout.contains("plain.ply"),
        "summary names the scan: {stdout}"
    );
    assert_eq!(reference["metrics"]["points"], points.len());
    let primitives = reference["primitives"].as_array().expect("primitives");
    // The floor is four 1 m squares, the wall two.
    assert_eq!(primitives.len(), 6, "{reference:#}");
    assert!(primitives.iter().all(|p| p["type"] == "square"));

    for name in [
        "pcl.ply",
        "meshlab.ply",
        "cloudcompare.ply",
        "bigendian.ply",
    ] {
        let (_, stderr, doc) = fit(name);
        assert_eq!(doc["metrics"]["points"], points.len(), "{name}");
        assert_eq!(doc["primitives"], reference["primitives"], "{name}");
        assert_eq!(doc["metrics"], reference["metrics"], "{name}");
        if name == "pcl.ply" {
            // NaN points are skipped with one warning that names the file.
            assert!(
                stderr.starts_with("warning: pcl.ply") && stderr.contains("skipped 5 of"),
                "{stderr}"
            );
            assert_eq!(stderr.lines().count(), 1, "{stderr}");
        } else {
            assert!(stderr.is_empty(), "{name}: {stderr}");
        }
    }
    // --quiet silences the NaN warning too.
    let mut args = vec!["fit", "pcl.ply", "-q"];
    args.extend(FLOOR_FLAGS);
    let (stdout, stderr) = ok(&dir, &args);
    assert!(stdout.is_empty() && stderr.is_empty(), "{stdout}{stderr}");
}

#[test]
fn written_ply_files_are_binary_by_default_ascii_on_request_and_read_back() {
    let dir = temp_dir("written");
    ok(
        &dir,
        &[
            "synth", "hallway", "-o", "bin.ply", "--points", "2000", "--length", "3",
        ],
    );
    ok(
        &dir,
        &[
            "synth", "hallway", "-o", "asc.ply", "--points", "2000", "--length", "3", "--ascii",
            "-q",
        ],
    );
    assert!(ply_header(&dir.join("bin.ply")).contains("format binary_little_endian 1.0"));
    assert!(ply_header(&dir.join("asc.ply")).contains("format ascii 1.0"));

    // Both encodings of the same scene hold the same points: the fits agree exactly.
    let flags = ["--types", "square", "--size", "1", "--spacing", "0.5", "-q"];
    let mut a = vec!["fit", "bin.ply", "-o", "bin.json", "--mesh", "bin-mesh.ply"];
    a.extend(flags);
    ok(&dir, &a);
    let mut b = vec![
        "fit",
        "asc.ply",
        "-o",
        "asc.json",
        "--mesh",
        "asc-mesh.ply",
        "--ascii",
    ];
    b.extend(flags);
    ok(&dir, &b);
    let (x, y) = (
        read_json(&dir.join("bin.json")),
        read_json(&dir.join("asc.json")),
    );
    assert_eq!(x["primitives"], y["primitives"]);
    assert_eq!(x["metrics"], y["metrics"]);
    assert_eq!(x["metrics"]["points"], 2000);

    // The fitted mesh: binary LE by default, ascii with --ascii, one `primitive` index
    // per face; it reads back as a mesh (--mesh-model) and as a cloud (its vertices).
    let bin_mesh = ply_header(&dir.join("bin-mesh.ply"));
    assert!(
        bin_mesh.contains("format binary_little_endian 1.0"),
        "{bin_mesh}"
    );
    let asc_mesh = ply_header(&dir.join("asc-mesh.ply"));
    assert!(asc_mesh.contains("format ascii 1.0"), "{asc_mesh}");
    for header in [&bin_mesh, &asc_mesh] {
        let face = header.split("element face").nth(1).expect("face element");
        assert!(face.contains("vertex_indices"), "{header}");
        assert!(face.contains("property int primitive"), "{header}");
    }
    for mesh in ["bin-mesh.ply", "asc-mesh.ply"] {
        let mut args = vec!["fit", "bin.ply", "--mesh-model", mesh];
        args.extend(flags);
        ok(&dir, &args);
        let mut args = vec!["fit", mesh];
        args.extend(flags);
        ok(&dir, &args);
    }
}

// ---------------------------------------------------------------------------------------
// Bad input
// ---------------------------------------------------------------------------------------

/// Asserts that `primfit fit SCENE -o good.json --mesh good.ply --mesh …` fails naming
/// `needle`, leaves the existing good outputs untouched and adds no file to `dir`.
fn fit_fails_cleanly(dir: &Path, scene: &str, extra: &[&str], needle: &str) -> String {
    fs::write(dir.join("good.json"), "{\"good\": true}\n").expect("write good json");
    fs::write(dir.join("good.ply"), "good mesh\n").expect("write good mesh");
    let before = file_names(dir);
    let mut args = vec!["fit", scene, "-o", "good.json", "--mesh", "good.ply"];
    args.extend(extra);
    let line = fails(dir, &args, needle);
    assert_eq!(
        fs::read_to_string(dir.join("good.json")).expect("good json"),
        "{\"good\": true}\n",
        "{scene} {extra:?} clobbered good.json"
    );
    assert_eq!(
        fs::read_to_string(dir.join("good.ply")).expect("good mesh"),
        "good mesh\n",
        "{scene} {extra:?} clobbered good.ply"
    );
    assert_eq!(
        before,
        file_names(dir),
        "{scene} {extra:?} left files behind"
    );
    // Without pre-existing outputs, nothing is created.
    let mut args = vec!["fit", scene, "-o", "new.json", "--mesh", "new.ply"];
    args.extend(extra);
    fails(dir, &args, needle);
    assert_eq!(
        before,
        file_names(dir),
        "{scene} {extra:?} left files behind"
    );
    line
}

#[test]
fn bad_scene_files_fail_with_one_line_naming_the_file() {
    let dir = temp_dir("bad-scenes");
    let good: Vec<[f64; 3]> = floor_and_wall();
    write_meshlab_binary(&dir.join("binary.ply"), &good);
    let binary = fs::read(dir.join("binary.ply")).expect("read");

    // Truncated binary body, and a binary body with trailing bytes.
    fs::write(dir.join("truncated.ply"), &binary[..binary.len() - 100]).expect("write");
    let mut long = binary.clone();
    long.extend([0u8; 12]);
    fs::write(dir.join("trailing.ply"), long).expect("write");
    // An absurd count in a small binary file.
    let header = ply_header(&dir.join("binary.ply"));
    let absurd = header.replace(
        &format!("element vertex {}", good.len()),
        "element vertex 999999999999",
    );
    fs::write(dir.join("absurd.ply"), absurd).expect("write");

    let files: Vec<(&str, String)> = vec![
        ("notply.ply", "solid cube\nfacet normal 0 0 1\n".into()),
        ("empty-file.ply", String::new()),
        (
            "noend.ply",
            "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n".into(),
        ),
        (
            "badformat.ply",
            ascii_xyz("1", &["0 0 0"]).replace("ascii 1.0", "binary_middle_endian 1.0"),
        ),
        ("short.ply", ascii_xyz("4", &["0 0 0", "1 0 0"])),
        ("extra.ply", ascii_xyz("2", &["0 0 0", "1 0 0", "1 1 0"])),
        (
            "hugecount.ply",
            ascii_xyz("99999999999999999999999", &["0 0 0"]),
        ),
        ("negcount.ply", ascii_xyz("-3", &["0 0 0"])),
        ("garbage.ply", ascii_xyz("2", &["0 0 0", "1 abc 0"])),
        (
            "shortrow.ply",
            ascii_xyz("3", &["0 0 0", "1000 0", "2 2 2"]),
        ),
        ("zero.ply", ascii_xyz("0", &[])),
        ("allnan.ply", ascii_xyz("2", &["nan nan nan", "1 inf 0"])),
        (
            "coincident.ply",
            ascii_xyz("3", &["1 1 1", "1 1 1", "1 1 1"]),
        ),
        (
            "nox.ply",
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float y\nproperty float z\n\
             end_header\n0 0\n"
                .into(),
        ),
        (
            "novertex.ply",
            "ply\nformat ascii 1.0\nelement point 1\nproperty float x\nproperty float y\n\
             property float z\nend_header\n0 0 0\n"
                .into(),
        ),
    ];
    for (name, text) in &files {
        fs::write(dir.join(name), text).expect("write fixture");
    }
    fs::create_dir(dir.join("folder.ply")).expect("mkdir");

    let cases: Vec<(&str, &str)> = vec![
        ("missing.ply", "no such file"),
        ("folder.ply", "directory"),
        ("notply.ply", "not a ply file"),
        ("empty-file.ply", "empty"),
        ("noend.ply", "end_header"),
        ("badformat.ply", "format"),
        ("truncated.ply", "truncated"),
        ("trailing.ply", "do not match"),
        ("absurd.ply", "999999999999"),
        ("short.ply", "truncated"),
        ("extra.ply", "do not match"),
        ("hugecount.ply", "count"),
        ("negcount.ply", "count"),
        ("garbage.ply", "abc"),
        ("shortrow.ply", "line"),
        ("zero.ply", "no points"),
        ("allnan.ply", "no points"),
        ("coincident.ply", "extent"),
        ("nox.ply", "'x'"),
        ("novertex.ply", "vertex"),
    ];
    for (scene, fault) in cases {
        let line = fit_fails_cleanly(&dir, scene, &FLOOR_FLAGS, scene);
        assert!(
            line.to_lowercase().contains(fault),
            "{scene}: the error should say {fault:?}: {line}"
        );
        // eval reads scans through the same reader.
        if !["zero.ply", "allnan.ply", "coincident.ply"].contains(&scene) {
            fails(&dir, &["eval", scene, "good.json"], scene);
        }
    }
    let line = fails(&dir, &["fit", "allnan.ply"], "allnan.ply");
    assert!(line.contains("NaN or infinite"), "{line}");
}

#[test]
fn bad_flags_fail_with_one_line_naming_the_flag_and_write_nothing() {
    let dir = temp_dir("bad-flags");
    write_plain_ascii(&dir.join("scene.ply"), &floor_and_wall());
    fs::write(dir.join("cloud-only.ply"), ascii_xyz("1", &["0 0 0"])).expect("write");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--types", "square,cube"], "cube"),
        (vec!["--types", ""], "--types"),
        (vec!["--types", "mesh"], "--mesh-model"),
        (
            vec!["--types", "mesh", "--mesh-model", "nothere.ply"],
            "nothere.ply",
        ),
        (
            vec!["--types", "mesh", "--mesh-model", "cloud-only.ply"],
            "cloud-only.ply",
        ),
        (vec!["--size", "0"], "--size"),
        (vec!["--size", "-1"], "--size"),
        (vec!["--size", "nan"], "--size"),
        (vec!["--size", "inf"], "--size"),
        (vec!["--spacing", "-0.5"], "--spacing"),
        (vec!["--spacing", "1e-9"], "--spacing"),
        (vec!["--radius", "0", "--types", "cylinder"], "--radius"),
        (
            vec!["--bend", "0.01", "--radius", "0.1", "--types", "elbow"],
            "bend",
        ),
        (vec!["--sample-spacing", "1e-9"], "--sample-spacing"),
        (vec!["--types", "sphere", "--size", "1e-12"], "--spacing"),
        (vec!["--cap", "-1"], "--cap"),
        (vec!["--weights", "1,nan"], "--weights"),
        (vec!["--origin", "1e15,0,0"], "--origin"),
        (vec!["--method", "mcmc"], "mcmc"),
        (vec!["--free-space"], "sensor"),
    ];
    for (extra, needle) in cases {
        fit_fails_cleanly(&dir, "scene.ply", &extra, needle);
    }
    // Outputs that cannot be written are refused before any work.
    fs::create_dir(dir.join("out.json")).expect("mkdir");
    for (flag, target, needle) in [
        ("-o", "out.json", "out.json"),
        ("-o", "nowhere/r.json", "nowhere"),
        ("--mesh", "scene.ply", "scene.ply"),
    ] {
        let before = file_names(&dir);
        fails(&dir, &["fit", "scene.ply", flag, target], needle);
        assert_eq!(before, file_names(&dir));
    }
    fails(
        &dir,
        &["fit", "scene.ply", "-o", "same", "--mesh", "same"],
        "same",
    );
    // synth and eval faults.
    fails(&dir, &["synth", "pipe", "-o", "nowhere/s.ply"], "nowhere");
    fails(
        &dir,
        &["synth", "pipe", "-o", "s.ply", "--points", "0"],
        "--points",
    );
    fails(
        &dir,
        &["synth", "hallway", "-o", "s.ply", "--size", "-1"],
        "--size",
    );
    fails(
        &dir,
        &["synth", "hallway", "-o", "s.ply", "--size", "1e-5"],
        "squares",
    );
    fails(
        &dir,
        &["synth", "pipe", "-o", "s.ply", "--points", "100000000000"],
        "--points",
    );
    fails(
        &dir,
        &["synth", "pipe", "-o", "s.ply", "--jitter", "nan"],
        "--jitter",
    );
    fails(
        &dir,
        &["synth", "pipe", "-o", "s.ply", "--segments", "0"],
        "--segments must be at least 1",
    );
    assert!(!dir.join("s.ply").exists());
    fs::write(dir.join("broken.json"), "{\"primitives\": [").expect("write");
    fs::write(dir.join("noprims.json"), "{}").expect("write");
    fails(&dir, &["eval", "scene.ply", "missing.json"], "missing.json");
    fails(&dir, &["eval", "scene.ply", "broken.json"], "broken.json");
    fails(&dir, &["eval", "scene.ply", "noprims.json"], "noprims.json");
    fs::write(dir.join("none.json"), "{\"primitives\": []}").expect("write");
    fails(
        &dir,
        &["eval", "scene.ply", "none.json", "--tau", "-1"],
        "--tau must be finite",
    );
}

#[test]
fn usage_errors_exit_with_2() {
    let dir = temp_dir("usage");
    for args in [
        vec!["fit"],
        vec!["frobnicate"],
        vec!["fit", "x.ply", "--model", "nonsense"],
        vec!["fit", "x.ply", "--no-such-flag"],
        vec!["fit", "x.ply", "--alpha", "0"],
        vec!["synth", "moon", "-o", "x.ply"],
        vec!["synth", "pipe"],
        vec!["eval", "x.ply"],
    ] {
        let out = primfit(&dir, &args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", texts(&out).1);
    }
    assert!(file_names(&dir).is_empty());
}

// ---------------------------------------------------------------------------------------
// Pipelines and behaviour
// ---------------------------------------------------------------------------------------

#[test]
fn synth_fit_eval_recovers_an_aligned_pipe() {
    let dir = temp_dir("pipe");
    let (stdout, _) = ok(
        &dir,
        &[
            "synth",
            "pipe",
            "-o",
            "scene.ply",
            "--truth",
            "t.json",
            "--points",
            "3000",
        ],
    );
    assert!(stdout.contains("scene.ply"), "{stdout}");
    let truth = read_json(&dir.join("t.json"));
    for key in ["primfit", "settings", "metrics", "primitives"] {
        assert!(truth.get(key).is_some(), "truth has no {key}: {truth:#}");
    }
    let spacing = truth["settings"]["lattice"]["spacing"]
        .as_f64()
        .expect("spacing");
    let prims = truth["primitives"].as_array().expect("primitives");
    let size_of = |kind: &str, key: &str| {
        prims
            .iter()
            .find(|p| p["type"] == kind)
            .and_then(|p| p["size"][key].as_f64())
            .unwrap_or_else(|| panic!("no {kind} {key} in the truth"))
    };
    let (length, radius, bend) = (
        size_of("cylinder", "length"),
        size_of("cylinder", "radius"),
        size_of("elbow", "bend"),
    );
    let (spacing, length, radius, bend) = (
        spacing.to_string(),
        length.to_string(),
        radius.to_string(),
        bend.to_string(),
    );
    ok(
        &dir,
        &[
            "fit",
            "scene.ply",
            "-o",
            "result.json",
            "--mesh",
            "fitted.ply",
            "-q",
            "--types",
            "cylinder,elbow",
            "--spacing",
            &spacing,
            "--size",
            &length,
            "--radius",
            &radius,
            "--bend",
            &bend,
            // The truth's own lattice, exactly: the scene axes, origin 0, and no
            // continuous refinement (which may merge two collinear cylinders into one
            // longer one, a valid but different model).
            "--frame",
            "axis",
            "--no-refine",
        ],
    );
    let result = read_json(&dir.join("result.json"));
    assert_eq!(
        result["primitives"].as_array().map(Vec::len),
        Some(prims.len())
    );
    assert_eq!(
        result["settings"]["types"],
        serde_json::json!(["cylinder", "elbow"])
    );
    for key in ["point_to_model_mean", "coverage", "chamfer"] {
        assert!(result["metrics"].get(key).is_some(), "metrics lack {key}");
    }
    let (stdout, _) = ok(
        &dir,
        &[
            "eval",
            "scene.ply",
            "result.json",
            "--truth",
            "t.json",
            "--json",
        ],
    );
    let m: Value = serde_json::from_str(&stdout).expect("eval prints JSON");
    assert_eq!(m["precision"], 1.0, "{m:#}");
    assert_eq!(m["recall"], 1.0, "{m:#}");
    assert_eq!(m["points"], 3000);
    // Piped, eval prints JSON even without --json.
    let (stdout, _) = ok(&dir, &["eval", "scene.ply", "t.json"]);
    let m: Value = serde_json::from_str(&stdout).expect("piped eval prints JSON");
    assert_eq!(m["coverage"], 1.0, "the truth covers the scan: {m:#}");
}

#[test]
fn seed_makes_runs_byte_identical() {
    let dir = temp_dir("seed");
    for name in ["a.ply", "b.ply"] {
        ok(
            &dir,
            &[
                "synth", "hallway", "-o", name, "--points", "2000", "--length", "3", "--seed", "7",
                "--jitter", "0.01", "-q",
            ],
        );
    }
    assert_eq!(
        fs::read(dir.join("a.ply")).expect("a"),
        fs::read(dir.join("b.ply")).expect("b")
    );
    for run in ["1", "2"] {
        let json = format!("r{run}.json");
        let mesh = format!("m{run}.ply");
        ok(
            &dir,
            &[
                "fit", "a.ply", "--seed", "7", "-q", "-o", &json, "--mesh", &mesh,
            ],
        );
    }
    for (x, y) in [("r1.json", "r2.json"), ("m1.ply", "m2.ply")] {
        assert_eq!(
            fs::read(dir.join(x)).expect("x"),
            fs::read(dir.join(y)).expect("y"),
            "{x} and {y} differ"
        );
    }
    assert_eq!(read_json(&dir.join("r1.json"))["settings"]["seed"], 7);
}

#[test]
fn quiet_verbose_and_piped_output() {
    let dir = temp_dir("output");
    write_plain_ascii(&dir.join("scene.ply"), &floor_and_wall());

    // Defaults only: a short human summary, no escape codes when piped.
    let (stdout, stderr) = ok(&dir, &["fit", "scene.ply"]);
    assert!(
        stdout.contains("scene.ply") && stdout.contains("primitives"),
        "{stdout}"
    );
    assert!(stdout.lines().count() <= 4, "{stdout}");
    assert!(
        !stdout.contains('\x1b') && !stderr.contains('\x1b'),
        "{stdout}{stderr}"
    );
    assert!(!stderr.contains('\r'), "progress bar on a pipe: {stderr:?}");

    // --quiet: nothing at all on success, for every command.
    let mut args = vec!["fit", "scene.ply", "-q", "-o", "r.json", "--mesh", "m.ply"];
    args.extend(FLOOR_FLAGS);
    let (stdout, stderr) = ok(&dir, &args);
    assert!(stdout.is_empty() && stderr.is_empty(), "{stdout}{stderr}");
    assert!(dir.join("r.json").exists() && dir.join("m.ply").exists());
    let (stdout, stderr) = ok(
        &dir,
        &["--quiet", "synth", "pipe", "-o", "p.ply", "--points", "500"],
    );
    assert!(stdout.is_empty() && stderr.is_empty(), "{stdout}{stderr}");

    // -v: the settings actually used, and more detail.
    let mut args = vec!["fit", "scene.ply", "-v"];
    args.extend(FLOOR_FLAGS);
    let (stdout, stderr) = ok(&dir, &args);
    let all = format!("{stdout}{stderr}");
    assert!(all.contains("settings"), "{all}");
    assert!(all.contains("\"spacing\":0.5"), "{all}");
    assert!(all.contains("candidates"), "{all}");
    assert!(!all.contains('\x1b'), "{all}");

    // Every option, defaults included, lands in the result's settings.
    let settings = &read_json(&dir.join("r.json"))["settings"];
    for key in [
        "size", "spacing", "radius", "bend", "cap", "beta", "model", "seed", "scene",
    ] {
        assert!(
            settings.get(key).is_some(),
            "settings lack {key}: {settings:#}"
        );
    }
}

#[test]
fn every_atlas_type_can_be_fitted() {
    let dir = temp_dir("types");
    write_plain_ascii(&dir.join("scene.ply"), &floor_and_wall());
    let (_, _) = ok(
        &dir,
        &[
            "fit",
            "scene.ply",
            "-q",
            "-o",
            "r.json",
            "--types",
            "square,disk,sphere,cylinder,elbow",
            "--size",
            "1",
            "--spacing",
            "0.5",
        ],
    );
    let doc = read_json(&dir.join("r.json"));
    assert_eq!(
        doc["settings"]["types"],
        serde_json::json!(["square", "disk", "sphere", "cylinder", "elbow"])
    );
    assert!(!doc["primitives"].as_array().expect("primitives").is_empty());
}

#[test]
fn mesh_type_fit_finds_the_object() {
    let dir = temp_dir("mesh");
    write_box_mesh(&dir.join("object.ply"));
    let points = box_points([1.0, 0.5, 0.0]);
    write_plain_ascii(&dir.join("scene.ply"), &points);
    let model = dir.join("object.ply");
    let model = model.to_str().expect("utf-8 path");
    ok(
        &dir,
        &[
            "fit",
            "scene.ply",
            "--types",
            "mesh",
            "--mesh-model",
            model,
            "--spacing",
            "0.5",
            "-o",
            "r.json",
            "--mesh",
            "fitted.ply",
            "-q",
        ],
    );
    let doc = read_json(&dir.join("r.json"));
    let prims = doc["primitives"].as_array().expect("primitives");
    assert_eq!(prims.len(), 1, "{doc:#}");
    assert_eq!(prims[0]["type"], "mesh");
    // Refinement fits the pose to the (noisy) points, so it is near, not on, the lattice.
    let t: Vec<f64> = prims[0]["pose"]["translation"]
        .as_array()
        .expect("translation")
        .iter()
        .filter_map(|v| v.as_f64())
        .collect();
    let expected = [1.0, 0.5, 0.0];
    assert!(
        t.len() == 3 && t.iter().zip(expected).all(|(a, b)| (a - b).abs() < 0.01),
        "translation {t:?}"
    );
    // The refined pose also answers to the model→point term, which finite point sampling
    // biases by a fraction of the point spacing: near-exact, not exact.
    assert!(
        doc["metrics"]["point_to_model_mean"]
            .as_f64()
            .expect("mean")
            < 1e-3
    );
    // The result names its mesh; eval loads it from there.
    let (stdout, _) = ok(&dir, &["eval", "scene.ply", "r.json", "--json"]);
    let m: Value = serde_json::from_str(&stdout).expect("json");
    assert_eq!(m["coverage"], 1.0, "{m:#}");
    // Defaults for a mesh-only fit still find it (lattice from the mesh's size).
    ok(
        &dir,
        &[
            "fit",
            "scene.ply",
            "--types",
            "mesh",
            "--mesh-model",
            model,
            "-q",
            "-o",
            "d.json",
        ],
    );
    let doc = read_json(&dir.join("d.json"));
    assert_eq!(
        doc["primitives"].as_array().map(Vec::len),
        Some(1),
        "{doc:#}"
    );
}

#[test]
fn real_scan_fits_with_defaults() {
    // PCL's SAC plane test scan, bundled (the same bytes as shared/data/sac_plane_test.ply).
    let scan = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/plane_scan.ply");
    let dir = temp_dir("real");
    let scan = scan.to_str().expect("utf-8 path");
    let (stdout, _) = ok(&dir, &["fit", scan, "-o", "r.json", "--mesh", "m.ply"]);
    assert!(stdout.contains("plane_scan.ply"), "{stdout}");
    let doc = read_json(&dir.join("r.json"));
    assert!(!doc["primitives"].as_array().expect("primitives").is_empty());
    assert!(
        doc["metrics"]["coverage"].as_f64().expect("coverage") > 0.5,
        "{doc:#}"
    );
    assert!(ply_header(&dir.join("m.ply")).contains("element face"));
}
