//! XYZ, PTS and CSV text: with and without a header, each separator, PTS counts, extra
//! columns, and the bad-input catalogue.

use primfit_core::io::{CloudFormat, TextKind, read_cloud, read_cloud_report};

use super::{Scratch, cloud_of, fails, samples};

#[test]
fn text_dialects_read_the_same_points() {
    let dir = Scratch::new("text-round");
    let pts = samples(40);
    let bare = cloud_of(&pts, false, false);
    let full = cloud_of(&pts, true, true);
    let row = |p: &super::Sample, sep: &str, all: bool| {
        let mut v: Vec<String> = p.xyz.iter().map(f64::to_string).collect();
        if all {
            v.extend(p.normal.iter().map(f64::to_string));
            v.extend(p.rgb.iter().map(u8::to_string));
        }
        v.join(sep)
    };
    let body =
        |sep: &str, all: bool| -> String { pts.iter().map(|p| row(p, sep, all) + "\n").collect() };
    // Plain XYZ, blank-separated, with an intensity column after it (ignored).
    let xyz: String = pts.iter().map(|p| row(p, " ", false) + " 0.5\n").collect();
    // Tab-separated .txt with a comment and blank lines; CRLF line ends.
    let txt = format!(
        "# exported by hand\n\n{}",
        body("\t", false).replace('\n', "\r\n")
    );
    // CSV with a CloudCompare-style header naming every attribute.
    let csv = format!("//X,Y,Z,Nx,Ny,Nz,R,G,B\n{}", body(",", true));
    // Semicolons, spaces around values, a header in another order with an extra column.
    let semi: String = std::iter::once("id; red; green; blue; x; y; z; nx; ny; nz\n".to_string())
        .chain(pts.iter().enumerate().map(|(i, p)| {
            let [r, g, b] = p.rgb;
            let [x, y, z] = p.xyz;
            let [a, bb, c] = p.normal;
            format!("{i}; {r}; {g}; {b}; {x}; {y}; {z}; {a}; {bb}; {c}\n")
        }))
        .collect();
    let cases = [
        ("a.xyz", xyz, &bare, TextKind::Xyz, vec![]),
        ("b.TXT", txt, &bare, TextKind::Xyz, vec![]),
        ("c.csv", csv, &full, TextKind::Csv, vec![]),
        ("d.csv", semi, &full, TextKind::Csv, vec!["id".to_string()]),
    ];
    for (name, text, want, kind, ignored) in cases {
        let path = dir.write(name, text.as_bytes());
        let (cloud, report) = read_cloud_report(&path).expect(name);
        assert_eq!(&cloud, want, "{name}");
        assert_eq!(report.format, CloudFormat::Text(kind));
        assert_eq!(report.ignored_properties, ignored, "{name}");
    }
}

#[test]
fn pts_blocks_and_leica_colour_columns() {
    let dir = Scratch::new("pts");
    let pts = samples(30);
    let line = |p: &super::Sample| {
        let [x, y, z] = p.xyz;
        let [r, g, b] = p.rgb;
        format!("{x} {y} {z} -1200 {r} {g} {b}\n")
    };
    let mut text = "20\n".to_string();
    text.extend(pts[..20].iter().map(line));
    text += "10\n";
    text.extend(pts[20..].iter().map(line));
    let path = dir.write("scan.pts", text.as_bytes());
    let (cloud, report) = read_cloud_report(&path).expect("pts");
    assert_eq!(cloud, cloud_of(&pts, false, true));
    assert_eq!(report.format, CloudFormat::Text(TextKind::Pts));
    // Four columns (x y z intensity): positions only; NaN rows dropped and counted.
    let path = dir.write("four.pts", b"3\n1 2 3 -5\nnan 0 0 1\n4 5 6 7\n");
    let (cloud, report) = read_cloud_report(&path).expect("four");
    assert_eq!(cloud.len(), 2);
    assert!(cloud.colors.is_none());
    assert_eq!(report.skipped_non_finite, 1);
    // A header-only file is an empty cloud, not an error.
    let path = dir.write("head.csv", b"x,y,z\n");
    assert!(read_cloud(&path).expect("empty").is_empty());
}

#[test]
fn text_bad_input_catalogue() {
    let dir = Scratch::new("text-bad");
    let cases: &[(&str, &[u8], &str)] = &[
        ("empty.xyz", b"", "empty"),
        (
            "short.xyz",
            b"1 2 3\n4 5\n",
            "line 2: 2 values, expected at least 3",
        ),
        (
            "word.xyz",
            b"1 2 3\n4 five 6\n",
            "line 2: 'five' is not a number (column 2)",
        ),
        (
            "names.csv",
            b"a,b,c\n1,2,3\n",
            "names no x, y and z columns",
        ),
        ("nul.xyz", b"1 2 3\n\0\0\0\0", "NUL"),
        (
            "count.pts",
            b"3\n1 2 3\n4 5 6\n",
            "truncated PTS body: 2 of the 3",
        ),
        ("over.pts", b"1\n1 2 3\n4 5 6\n", "more points than the 1"),
        (
            "early.pts",
            b"2\n1 2 3\n1\n4 5 6\n",
            "after 1 of the 2 points",
        ),
        (
            "ply.xyz",
            b"ply\nformat ascii 1.0\nend_header\n",
            "the name says text but the content is PLY",
        ),
        ("las.txt", b"LASF\0\0\0\0", "the content is LAS/LAZ"),
        ("latin1.xyz", b"1 2 3 \xe9\n", "not UTF-8"),
    ];
    for (name, bytes, needle) in cases {
        let path = dir.write(name, bytes);
        fails(read_cloud(&path), &path, needle);
    }
    assert_eq!(dir.files().len(), cases.len());
}
