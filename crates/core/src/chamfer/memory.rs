//! The memory budget of the coefficients: an estimate of their peak bytes, checked
//! before they are built.

use super::{CandidateGeometry, ChamferOptions, Coefficients, PointModel};
use crate::Result;
use crate::budget;
use crate::error::Remedy;

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
///   polish's per-candidate transpose (16 bytes per distinct (point, candidate) and a
///   byte for its place in the row: `17·U`);
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
    let transient = (entries * per_entry + 16).max(POLISH_BYTES_PER_ROW_ENTRY * distinct);
    points as u64 * (coefficients + transient + BYTES_PER_POINT)
}

/// Refuses, before anything is built, coefficients of `points` points over `geometry`
/// whose estimated peak ([`estimate_bytes`]) is over `memory_budget` bytes; returns the
/// estimate otherwise. For callers that build [`Coefficients`] from their own samples
/// (the fit checks its lattice the same way, with its own wording).
pub fn check_memory(
    points: usize,
    geometry: &impl CandidateGeometry,
    options: &ChamferOptions,
    memory_budget: u64,
) -> Result<u64> {
    let max_samples = (0..geometry.len())
        .map(|i| geometry.sample_count(i))
        .max()
        .unwrap_or(1);
    let need = estimate_bytes(points, geometry.len(), max_samples, options);
    let what = format!(
        "the coefficients of {points} points × {} candidates",
        geometry.len()
    );
    let remedies = vec![
        Remedy::Lower("beta"),
        Remedy::Lower("alpha"),
        Remedy::Subsample,
    ];
    budget::check_memory(&what, need, memory_budget, remedies)?;
    Ok(need)
}

/// Bytes of the polish's transpose per distinct (point, candidate): the row, the distance
/// (16 with padding) and the entry's place in its row (1).
const POLISH_BYTES_PER_ROW_ENTRY: u64 = 17;

/// Bytes per input point besides the coefficients in [`estimate_bytes`]: the cloud
/// (24), the KD-tree built over it (~28, for the settings), the primitive term's box tree
/// (~35: a copy of the points and a 64-byte node per 6 points), the build's cell order
/// (12), and the polish's per-point explanation (24: owner, runner-up and their costs)
/// and mask of existing entries (8), rounded up.
pub const BYTES_PER_POINT: u64 = 136;
