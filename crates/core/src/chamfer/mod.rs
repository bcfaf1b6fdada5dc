//! The probabilistic chamfer distance (thesis ch. 5–6, DESIGN §2): coefficients, value
//! and exact gradient over existence probabilities `p ∈ [0, 1]^N`.
//!
//! `L(p) = w_prim · Σ_i p_i g_i + w_point · Σ_y E_y(p)` where
//!
//! * `g_i = Σ_{x∈σ_i} min_{y∈D} ‖x − y‖²` (thesis eq. 6.1), and
//! * `E_y` is the expected squared distance from `y` to the nearest existing sample
//!   (thesis eq. 5.14), with the tail cost `d_cap` when nothing exists:
//!   `E_y = Σ_k d_k q_k Π_{l<k}(1 − q_l) + Π_all(1 − q_l) · d_cap` over `y`'s sorted
//!   entries `(owner, d_k)`, `q_k = p_owner(k)`.
//!
//! Two point models decide what the entries are ([`PointModel`]); the approximations α
//! (samples kept per candidate) and β (candidates kept per point) of thesis §6.2 bound
//! their number. Coefficients are computed **once** ([`Coefficients::build`]): each
//! evaluation afterwards is pure arithmetic over flat arrays ([`Evaluator`]).
//!
//! Memory: one entry is a `u32` candidate id plus an `f64` squared distance, stored as
//! two flat arrays: **12 bytes per (point, candidate) entry**, plus 8 bytes per point
//! for the row offsets.
//!
//! In pipeline order:
//!
//! 1. `samples.rs`: what the loss needs of the candidates, their sample sets
//!    ([`CandidateGeometry`], [`SampleSets`]);
//! 2. `build.rs` and `row_builder.rs`: [`Coefficients::build`], the primitive term and each
//!    point's sorted entries; `dominance.rs`: [`Coefficients::build_reduced`], the same
//!    without the candidates that cannot exist at any minimum ([`Reduced`]);
//! 3. `coefficients.rs`: the flat arrays ([`Coefficients`]);
//! 4. `eval.rs`: value and gradient ([`Evaluator`]).

mod build;
mod coefficients;
mod dominance;
mod eval;
mod memory;
mod row_builder;
mod samples;
#[cfg(test)]
pub(crate) mod test_problems;
#[cfg(test)]
mod tests;

pub(crate) use build::primitive_coefficients;
pub use coefficients::Coefficients;
pub use dominance::Reduced;
pub use eval::Evaluator;
pub use memory::{BYTES_PER_POINT, check_memory, estimate_bytes};
pub use samples::{CandidateGeometry, SampleSets};

use crate::{Error, Result, check};
// The coefficient build's internals that `dominance.rs` reuses.
use build::{PointRows, check_candidate_count};

/// How the point term models which samples exist (DESIGN §2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PointModel {
    /// A candidate's samples exist together, with its probability (exact expectation of
    /// the binary chamfer under independent Bernoulli existences). One entry per
    /// (point, candidate): each candidate's nearest sample.
    #[default]
    Existence,
    /// Every sample is kept independently with its owner's probability (thesis eq. 5.14).
    /// Up to α entries per (point, candidate).
    Independent,
}

impl PointModel {
    /// Name used on the CLI and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            PointModel::Existence => "existence",
            PointModel::Independent => "independent",
        }
    }
    /// Parses `"existence"` or `"independent"`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "existence" => Ok(PointModel::Existence),
            "independent" => Ok(PointModel::Independent),
            other => Err(Error::Unknown {
                what: "point model",
                value: other.into(),
                expected: "existence or independent",
            }),
        }
    }
}

/// Options of the probabilistic chamfer.
#[derive(Debug, Clone, PartialEq)]
pub struct ChamferOptions {
    /// Point-term model.
    pub model: PointModel,
    /// α: samples kept per (point, candidate) for [`PointModel::Independent`]; `None` = all.
    pub alpha: Option<usize>,
    /// β: candidates kept per point (those whose nearest sample is closest); `None` = all.
    pub beta: Option<usize>,
    /// `d_cap` (squared distance): cost of a point that no existing candidate explains.
    pub cap: f64,
    /// Measure `d_i(y)` of the `existence` model (and the β ranking) to the candidate's
    /// continuous surface instead of its nearest sample.
    ///
    /// With sample distances, a second candidate overlapping the same surface lowers the
    /// point term (its samples interleave with the first one's), so the loss rewards
    /// redundant copies; surface distances remove that artefact. The fitter turns this on;
    /// the default (off) is DESIGN §2's sample-based definition.
    pub surface_distance: bool,
    /// Weight of the primitive term.
    pub primitive_weight: f64,
    /// Weight of the point term.
    pub point_weight: f64,
}

impl Default for ChamferOptions {
    fn default() -> Self {
        ChamferOptions {
            model: PointModel::Existence,
            alpha: None,
            beta: None,
            cap: 0.0,
            surface_distance: false,
            primitive_weight: 1.0,
            point_weight: 1.0,
        }
    }
}

impl ChamferOptions {
    /// Checks ranges (α, β ≥ 1; cap, weights finite and ≥ 0).
    pub fn validate(&self) -> Result<()> {
        for (name, limit) in [("alpha", self.alpha), ("beta", self.beta)] {
            if let Some(k) = limit {
                check::at_least(name, k, 1)?;
            }
        }
        check::non_negative("cap", self.cap)?;
        check::non_negative("primitive_weight", self.primitive_weight)?;
        check::non_negative("point_weight", self.point_weight)
    }

    /// These options for the loss of a scene in which every candidate exists (a binary
    /// chamfer of chosen primitives): under [`PointModel::Existence`] a point then costs
    /// its nearest candidate's distance, the first entry of its row whatever β, so β = 1
    /// gives the same value bit for bit with one entry a point instead of β; the
    /// independent model sums over its α × β entries and keeps them.
    pub fn for_all_existing(&self) -> ChamferOptions {
        match self.model {
            PointModel::Existence => ChamferOptions {
                beta: Some(1),
                ..self.clone()
            },
            PointModel::Independent => self.clone(),
        }
    }
}

/// The two terms of the loss and their weighted total.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LossValue {
    /// Σ_i p_i g_i (unweighted).
    pub primitive: f64,
    /// Σ_y E_y (unweighted).
    pub point: f64,
    /// `w_prim · primitive + w_point · point`.
    pub total: f64,
}
