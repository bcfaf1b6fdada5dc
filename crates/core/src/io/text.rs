//! Text point clouds: XYZ (`.xyz`, `.txt`), PTS (`.pts`) and CSV (`.csv`).
//!
//! One point a line, values separated by commas, semicolons, blanks or tabs (the first
//! line that is not blank or a comment decides: a comma or semicolon in it makes that
//! the separator, and blanks around values are then ignored). Lines starting with `#`
//! are comments; blank lines are skipped.
//!
//! - **Header**: when the first line has a value that is not a number, it names the
//!   columns (a leading `//`, as CloudCompare writes it, is dropped; names are matched
//!   without case or punctuation): `x y z` (required), `nx ny nz` or
//!   `normal_x normal_y normal_z`, `r g b` or `red green blue` (0–255). Other columns
//!   are read past and listed in the report.
//! - **No header**: the first three columns are `x y z`. A PTS line of seven values is
//!   Leica's `x y z intensity r g b`, and its colour is read.
//! - **PTS counts**: a line holding one integer starts a block of that many points (a
//!   PTS file may hold several scans); a block with more or fewer points is an error.
//!
//! More columns than are read are ignored; fewer is an error naming the line. Points
//! with a NaN or infinite coordinate are dropped and counted.

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use super::collect::{Collector, Lines};
use super::{CloudFormat, ReadReport, TextKind};
use crate::{Error, PointCloud, Result};

/// How the values of a line are separated.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Separator {
    /// Blanks and tabs (runs count as one).
    Blank,
    /// This character, with blanks around values ignored.
    Char(char),
}

impl Separator {
    /// The separator of a first line.
    fn of(line: &str) -> Self {
        [',', ';']
            .into_iter()
            .find(|c| line.contains(*c))
            .map_or(Separator::Blank, Separator::Char)
    }

    /// Splits `line` into `out`.
    fn split<'a>(self, line: &'a str, out: &mut Vec<&'a str>) {
        out.clear();
        match self {
            Separator::Blank => out.extend(line.split_ascii_whitespace()),
            Separator::Char(c) => out.extend(line.split(c).map(str::trim)),
        }
    }
}

/// Which columns hold what.
#[derive(Debug, Clone)]
struct Columns {
    xyz: [usize; 3],
    normal: Option<[usize; 3]>,
    rgb: Option<[usize; 3]>,
    /// Header names read past.
    ignored: Vec<String>,
}

impl Columns {
    /// The columns a line without a header has.
    fn positional(kind: TextKind, values: usize) -> Self {
        let rgb = (kind == TextKind::Pts && values == 7).then_some([4, 5, 6]);
        Columns {
            xyz: [0, 1, 2],
            normal: None,
            rgb,
            ignored: Vec::new(),
        }
    }

    /// The columns named by a header, failing when `x`, `y` or `z` is missing.
    fn named(names: &[&str], line: &Lines<impl std::io::BufRead>) -> Result<Self> {
        let keys: Vec<String> = names.iter().map(|n| key(n)).collect();
        let find = |aliases: &[&str]| keys.iter().position(|k| aliases.contains(&k.as_str()));
        let three = |a: [&[&str]; 3]| match a.map(find) {
            [Some(i), Some(j), Some(k)] => Some([i, j, k]),
            _ => None,
        };
        let xyz = three([&["x"], &["y"], &["z"]]).ok_or_else(|| {
            line.error(format!(
                "the header names no x, y and z columns (it has: [{}])",
                names.join(", ")
            ))
        })?;
        let normal = three([&["nx", "normalx"], &["ny", "normaly"], &["nz", "normalz"]]);
        let rgb = three([&["r", "red"], &["g", "green"], &["b", "blue"]]);
        let used: Vec<usize> = xyz
            .iter()
            .chain(normal.iter().flatten())
            .chain(rgb.iter().flatten())
            .copied()
            .collect();
        let ignored = (0..names.len())
            .filter(|k| !used.contains(k))
            .map(|k| names[k].to_string())
            .collect();
        Ok(Columns {
            xyz,
            normal,
            rgb,
            ignored,
        })
    }

    /// The number of values a line must have at least.
    fn needed(&self) -> usize {
        let all = self
            .xyz
            .iter()
            .chain(self.normal.iter().flatten())
            .chain(self.rgb.iter().flatten());
        all.max().map_or(0, |m| m + 1)
    }
}

/// A header name reduced for matching: lower case, letters and digits only.
fn key(name: &str) -> String {
    name.chars()
        .filter(char::is_ascii_alphanumeric)
        .map(|c| c.to_ascii_lowercase())
        .collect()
}

/// The state of a PTS file's point-count blocks.
#[derive(Debug, Default)]
struct Blocks {
    /// Points the current block declares, and how many have been read.
    current: Option<(u64, u64)>,
}

impl Blocks {
    /// Starts a block of `n` points, failing when the previous one is incomplete.
    fn start(&mut self, n: u64, lines: &Lines<impl std::io::BufRead>) -> Result<()> {
        if let Some((declared, read)) = self.current
            && read < declared
        {
            return Err(lines.error(format!(
                "a new point count comes after {read} of the {declared} points declared"
            )));
        }
        self.current = Some((n, 0));
        Ok(())
    }

    /// Counts one point, failing when the block is already complete.
    fn point(&mut self, lines: &Lines<impl std::io::BufRead>) -> Result<()> {
        if let Some((declared, read)) = self.current.as_mut() {
            if *read == *declared {
                return Err(lines.error(format!(
                    "more points than the {declared} the count line declares"
                )));
            }
            *read += 1;
        }
        Ok(())
    }

    /// Fails when the last block is incomplete.
    fn finish(&self, path: &Path) -> Result<()> {
        match self.current {
            Some((declared, read)) if read < declared => Err(Error::format(
                path,
                format!("truncated PTS body: {read} of the {declared} points declared"),
            )),
            _ => Ok(()),
        }
    }
}

/// Reads a text point cloud (see the module docs).
pub(crate) fn read_cloud_report(path: &Path, kind: TextKind) -> Result<(PointCloud, ReadReport)> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let mut lines = Lines::new(BufReader::with_capacity(1 << 16, file), path, 1);
    let mut layout: Option<(Separator, Columns)> = None;
    let mut out: Option<Collector> = None;
    let mut blocks = Blocks::default();
    let mut comments = Vec::new();
    let mut pending_reserve = 0usize;
    while lines.next_line()? {
        let trimmed = lines.line().trim();
        if trimmed.is_empty() {
            continue;
        }
        if let Some(c) = trimmed.strip_prefix('#') {
            comments.push(c.trim().to_string());
            continue;
        }
        if kind == TextKind::Pts
            && let Ok(n) = trimmed.parse::<u64>()
        {
            blocks.start(n, &lines)?;
            pending_reserve = usize::try_from(n).unwrap_or(usize::MAX);
            continue;
        }
        let mut tokens = Vec::new();
        if layout.is_none() {
            let first = trimmed.trim_start_matches("//").trim();
            let sep = Separator::of(first);
            sep.split(first, &mut tokens);
            let header = tokens.iter().any(|t| t.parse::<f64>().is_err());
            let columns = if header {
                Columns::named(&tokens, &lines)?
            } else {
                Columns::positional(kind, tokens.len())
            };
            out = Some(Collector::new(
                columns.normal.is_some(),
                columns.rgb.is_some(),
                pending_reserve,
                false,
            ));
            layout = Some((sep, columns));
            if header {
                continue;
            }
        }
        let (sep, columns) = layout.as_ref().expect("set above");
        sep.split(trimmed, &mut tokens);
        let point = parse_point(columns, &tokens).map_err(|m| lines.error(m))?;
        blocks.point(&lines)?;
        let out = out.as_mut().expect("made with the layout");
        out.push(point.0, point.1, point.2);
    }
    blocks.finish(path)?;
    let format = CloudFormat::Text(kind);
    let (collector, ignored) = match (out, layout) {
        (Some(c), Some((_, columns))) => (c, columns.ignored),
        _ => (Collector::new(false, false, 0, false), Vec::new()),
    };
    Ok(collector.finish(format, ignored, comments))
}

/// One point's position, normal and colour from a line's values.
#[allow(clippy::type_complexity)]
fn parse_point(
    c: &Columns,
    tokens: &[&str],
) -> std::result::Result<([f64; 3], [f64; 3], [u8; 3]), String> {
    let needed = c.needed();
    if tokens.len() < needed {
        return Err(format!(
            "{} values, expected at least {needed}",
            tokens.len()
        ));
    }
    let num = |k: usize| -> std::result::Result<f64, String> {
        let t = tokens[k];
        t.parse::<f64>()
            .map_err(|_| format!("'{t}' is not a number (column {})", k + 1))
    };
    let three = |cols: [usize; 3]| -> std::result::Result<[f64; 3], String> {
        Ok([num(cols[0])?, num(cols[1])?, num(cols[2])?])
    };
    let xyz = three(c.xyz)?;
    let normal = c.normal.map_or(Ok([0.0; 3]), three)?;
    let rgb = match c.rgb {
        Some(cols) => three(cols)?.map(|v| v.round().clamp(0.0, 255.0) as u8),
        None => [0; 3],
    };
    Ok((xyz, normal, rgb))
}
