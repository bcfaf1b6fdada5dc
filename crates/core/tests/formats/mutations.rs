//! Mutation testing of every cloud reader: valid files of each format and encoding (made
//! by the writers of this test binary and by `io::write_cloud`) are damaged at random —
//! bytes flipped, runs overwritten with extreme values, cut short, spliced, header
//! numbers replaced by huge, negative or malformed ones — and every result must be a
//! cloud or a typed one-line error naming the file: no panic, no abort, no unbounded
//! allocation (a lying count must not be trusted), no hang.
//!
//! The mutator is a small one here rather than a fuzzing framework: the cases must be
//! the same on every run and on stable Rust (a fixed ChaCha8 seed), a few thousand run in
//! CI, and `scripts/fuzz_readers.sh` runs as many more as asked
//! (`PRIMFIT_MUTATION_CASES`, per seed file) and prints the outcome table the README's
//! "Reliability" section quotes.

use std::collections::BTreeMap;
use std::path::Path;

use primfit_core::Error;
use primfit_core::io;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{Scratch, cloud_of, samples};

/// Cases per seed file in CI (13 seed files: about 4 000 cases, a few seconds).
const DEFAULT_CASES: usize = 300;

/// Numbers a mutation writes over header fields: the edges of every integer type,
/// negatives, non-numbers.
const NASTY_NUMBERS: [&str; 12] = [
    "0",
    "-1",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "99999999999999999999999",
    "-9223372036854775808",
    "1e308",
    "nan",
    "inf",
    "0x10",
    "",
];

/// Byte values a run overwrite writes (all bits set or clear, sign bits, text).
const NASTY_BYTES: [u8; 6] = [0x00, 0xff, 0x7f, 0x80, b'\n', b' '];

/// The ways a file is damaged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Mutation {
    /// Random bytes flipped (1 to 8).
    FlipBytes,
    /// A run of up to 16 bytes overwritten with one extreme value.
    OverwriteRun,
    /// The file cut at a random length.
    Truncate,
    /// A random slice of the file inserted at another place (repeated structure).
    Splice,
    /// A number in the first 4 KiB (the header) replaced by a nasty one.
    HeaderNumber,
}

const MUTATIONS: [Mutation; 5] = [
    Mutation::FlipBytes,
    Mutation::OverwriteRun,
    Mutation::Truncate,
    Mutation::Splice,
    Mutation::HeaderNumber,
];

/// `bytes` damaged by `m`.
fn mutate(bytes: &[u8], m: Mutation, rng: &mut ChaCha8Rng) -> Vec<u8> {
    let mut out = bytes.to_vec();
    let len = out.len().max(1);
    match m {
        Mutation::FlipBytes => {
            for _ in 0..rng.random_range(1..=8) {
                let at = rng.random_range(0..len).min(out.len().saturating_sub(1));
                if let Some(b) = out.get_mut(at) {
                    *b ^= 1 << rng.random_range(0..8);
                }
            }
        }
        Mutation::OverwriteRun => {
            let at = rng.random_range(0..len);
            let value = NASTY_BYTES[rng.random_range(0..NASTY_BYTES.len())];
            for b in out.iter_mut().skip(at).take(rng.random_range(1..=16)) {
                *b = value;
            }
        }
        Mutation::Truncate => out.truncate(rng.random_range(0..len)),
        Mutation::Splice => {
            let from = rng.random_range(0..len);
            let to = (from + rng.random_range(1..=256)).min(out.len());
            let piece = out[from.min(out.len())..to].to_vec();
            let at = rng.random_range(0..=out.len());
            out.splice(at..at, piece);
        }
        Mutation::HeaderNumber => replace_header_number(&mut out, rng),
    }
    out
}

/// Replaces one run of ASCII digits in the first 4 KiB with a [`NASTY_NUMBERS`] entry.
fn replace_header_number(out: &mut Vec<u8>, rng: &mut ChaCha8Rng) {
    let head = &out[..out.len().min(4096)];
    let mut runs = Vec::new();
    let mut k = 0;
    while k < head.len() {
        if head[k].is_ascii_digit() {
            let start = k;
            while k < head.len() && head[k].is_ascii_digit() {
                k += 1;
            }
            runs.push(start..k);
        } else {
            k += 1;
        }
    }
    if runs.is_empty() {
        return;
    }
    let run = runs[rng.random_range(0..runs.len())].clone();
    let number = NASTY_NUMBERS[rng.random_range(0..NASTY_NUMBERS.len())];
    out.splice(run, number.bytes());
}

/// A valid file of each format and encoding: (label, file name, bytes).
fn seed_files(dir: &Scratch) -> Vec<(String, &'static str, Vec<u8>)> {
    let pts = samples(60);
    let full = cloud_of(&pts, true, true);
    let mut seeds = Vec::new();
    for (label, encoding) in [
        ("PLY ascii", io::Encoding::Ascii),
        ("PLY binary", io::Encoding::BinaryLittleEndian),
    ] {
        let path = dir.path("seed.ply");
        io::write_cloud(&path, &full, encoding).expect("write PLY seed");
        seeds.push((label.to_string(), "case.ply", std::fs::read(&path).unwrap()));
    }
    seeds.push(("PCD ascii".into(), "case.pcd", super::pcd::ascii(&pts, 60)));
    seeds.push((
        "PCD binary".into(),
        "case.pcd",
        super::pcd::binary(&pts, 60),
    ));
    seeds.push((
        "PCD compressed".into(),
        "case.pcd",
        super::pcd::compressed(&pts, 60),
    ));
    for (label, name, version, format) in [
        ("LAS 1.2", "seed.las", (1, 2), 3),
        ("LAS 1.4", "seed.las", (1, 4), 7),
        ("LAZ 1.2", "seed.laz", (1, 2), 3),
    ] {
        let path = super::las::write_las(dir, name, &pts, version, format, false);
        let case = if name.ends_with(".laz") {
            "case.laz"
        } else {
            "case.las"
        };
        seeds.push((label.into(), case, std::fs::read(&path).unwrap()));
    }
    let e57 = super::e57::write_e57(dir, "seed.e57", &pts[..30], &pts[30..]);
    seeds.push(("E57".into(), "case.e57", std::fs::read(&e57).unwrap()));
    let xyz: String = pts
        .iter()
        .map(|s| {
            format!(
                "{} {} {} {} {} {}\n",
                s.xyz[0], s.xyz[1], s.xyz[2], s.rgb[0], s.rgb[1], s.rgb[2]
            )
        })
        .collect();
    seeds.push(("text xyz".into(), "case.xyz", xyz.into_bytes()));
    let csv: String = std::iter::once("x,y,z\n".to_string())
        .chain(
            pts.iter()
                .map(|s| format!("{},{},{}\n", s.xyz[0], s.xyz[1], s.xyz[2])),
        )
        .collect();
    seeds.push(("text csv".into(), "case.csv", csv.into_bytes()));
    seeds
}

/// What one read gave.
#[derive(Debug, Default, Clone, Copy)]
struct Outcomes {
    /// Read as a cloud (the damage hit values, not structure).
    read: usize,
    /// Refused with a one-line error naming the file.
    refused: usize,
}

/// Reads `path`, asserting the contract: a cloud no larger than the file could hold, or
/// a one-line error that names the file. A panic fails the test with the case's label.
fn read_one(path: &Path, size: usize, label: &str, outcomes: &mut Outcomes) {
    let result = std::panic::catch_unwind(|| io::read_cloud_report(path));
    let result = result.unwrap_or_else(|_| panic!("{label}: the reader panicked"));
    match result {
        Ok((cloud, _)) => {
            // A point takes at least a few bytes in every format (LAZ: a bit less than
            // one byte for identical points), so a cloud far larger than its file
            // means a count was trusted.
            assert!(
                cloud.len() <= 8 * size + 64,
                "{label}: {} points from {size} bytes",
                cloud.len()
            );
            outcomes.read += 1;
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(!msg.contains('\n'), "{label}: not one line: {msg:?}");
            assert!(
                msg.contains(&path.display().to_string()) || matches!(e, Error::EmptyCloud),
                "{label}: the error does not name the file: {msg}"
            );
            outcomes.refused += 1;
        }
    }
}

#[test]
fn every_reader_survives_thousands_of_damaged_files() {
    let cases: usize = std::env::var("PRIMFIT_MUTATION_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(DEFAULT_CASES);
    let dir = Scratch::new("mutations");
    let mut table: BTreeMap<(String, Mutation), Outcomes> = BTreeMap::new();
    for (k, (label, name, bytes)) in seed_files(&dir).into_iter().enumerate() {
        // The undamaged seed reads.
        let path = dir.write(name, &bytes);
        io::read_cloud(&path).unwrap_or_else(|e| panic!("{label}: the seed file fails: {e}"));
        let mut rng = ChaCha8Rng::seed_from_u64(0x5eed + k as u64);
        for case in 0..cases {
            let m = MUTATIONS[case % MUTATIONS.len()];
            let damaged = mutate(&bytes, m, &mut rng);
            let path = dir.write(name, &damaged);
            let tag = format!("{label} case {case} ({m:?})");
            let outcomes = table.entry((label.clone(), m)).or_default();
            read_one(&path, damaged.len(), &tag, outcomes);
        }
    }
    print_table(&table);
    let refused: usize = table.values().map(|o| o.refused).sum();
    assert!(
        refused > 0,
        "no damaged file was refused: the mutations do nothing"
    );
}

/// The outcome table, per format and mutation (`cargo test -- --nocapture` shows it).
fn print_table(table: &BTreeMap<(String, Mutation), Outcomes>) {
    println!("| format | mutation | cases | read | refused |");
    println!("|---|---|---|---|---|");
    for ((label, m), o) in table {
        println!(
            "| {label} | {m:?} | {} | {} | {} |",
            o.read + o.refused,
            o.read,
            o.refused
        );
    }
    let total: usize = table.values().map(|o| o.read + o.refused).sum();
    println!("{total} damaged files: no panic, no abort, every error one line naming the file");
}

#[test]
fn the_mutator_damages_every_seed_file() {
    let dir = Scratch::new("mutator");
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for (label, _, bytes) in seed_files(&dir) {
        for m in MUTATIONS {
            let changed = (0..20).any(|_| mutate(&bytes, m, &mut rng) != bytes);
            assert!(changed, "{label}: {m:?} never changes the file");
        }
    }
}
