//! The memory budget: an estimate of a fit's peak bytes, checked before the
//! coefficients are built.

use crate::chamfer::{ChamferOptions, Coefficients, PointModel};

/// Physical memory in bytes (Linux `/proc/meminfo`), or 8 GiB when unknown.
pub(crate) fn physical_memory() -> u64 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            let line = s.lines().find(|l| l.starts_with("MemTotal:"))?;
            line.split_whitespace()
                .nth(1)?
                .parse::<u64>()
                .ok()
                .map(|kb| kb * 1024)
        })
        .unwrap_or(8 << 30)
}

/// Estimated **peak** bytes of a fit of `points` points under `chamfer` with `candidates`
/// candidates (at most `max_samples` samples each), for the memory-budget check.
///
/// Per point, with `E` entries (`β`, or `β·α` for the independent model) and `U ≤ β`
/// distinct candidates:
///
/// * the coefficients themselves: `12·E + 8` bytes ([`Coefficients::BYTES_PER_ENTRY`]
///   plus a row offset), held from the build to the end;
/// * plus the larger of two transients: the build's per-chunk rows, copied into the
///   final arrays (`12·E`, plus 16 bytes per point saying where each row lies), and the
///   polish's per-candidate transpose (16 bytes per distinct (point, candidate): `16·U`);
/// * plus [`BYTES_PER_POINT`] for the cloud, its KD-tree and per-point solver state.
///
/// The benchmark table (`scripts/bench.sh`) prints this estimate next to the measured
/// peak RSS of every scene.
pub fn estimate_bytes(
    points: usize,
    candidates: usize,
    max_samples: usize,
    chamfer: &ChamferOptions,
) -> u64 {
    let distinct = chamfer.beta.unwrap_or(candidates).min(candidates) as u64;
    let entries = distinct
        * match chamfer.model {
            PointModel::Existence => 1,
            PointModel::Independent => chamfer.alpha.unwrap_or(max_samples).min(max_samples) as u64,
        };
    let per_entry = Coefficients::BYTES_PER_ENTRY as u64;
    let coefficients = entries * per_entry + 8;
    let transient = (entries * per_entry + 16).max(16 * distinct);
    points as u64 * (coefficients + transient + BYTES_PER_POINT)
}

/// Bytes per input point besides the coefficients in [`estimate_bytes`]: the cloud
/// (24), the KD-tree built over it (~28, shared by the settings and the primitive term),
/// the build's cell order (12), and the polish's per-point owner and cost (12), rounded
/// up.
pub const BYTES_PER_POINT: u64 = 96;
