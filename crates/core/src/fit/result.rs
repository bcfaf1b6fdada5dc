//! What a fit returns: [`FitResult`] with its [`FitStats`], the `result.json` document,
//! the primitives as one mesh, and the binary chamfer a result is judged by.

use serde_json::{Value, json};

use super::{McmcRun, Settings};
use crate::atlas::TriMesh;
use crate::chamfer::{ChamferOptions, Coefficients, Evaluator, LossValue};
use crate::lattice::CandidateSet;
use crate::progress::Silent;
use crate::solve::Solution;
use crate::{PointCloud, Primitive, Result};

/// Size and timing facts of a fit, for the summary and the benchmark table.
#[derive(Debug, Clone, Default)]
pub struct FitStats {
    /// Input points J.
    pub points: usize,
    /// Lattice candidates near the data (after the occupancy prior).
    pub lattice_candidates: usize,
    /// Candidates N the solver saw: those not dominated (`chamfer::dominance`).
    pub candidates: usize,
    /// (point, candidate) entries of the point term.
    pub entries: usize,
    /// Bytes per entry.
    pub bytes_per_entry: usize,
    /// Bytes held by the coefficients.
    pub coefficient_bytes: usize,
    /// The peak estimate checked against the memory budget ([`estimate_bytes`]).
    pub estimated_bytes: u64,
    /// Seconds spent building the lattice.
    pub lattice_seconds: f64,
    /// Seconds spent building coefficients.
    pub coefficient_seconds: f64,
    /// Seconds spent in L-BFGS, thresholding and polish.
    pub solve_seconds: f64,
    /// Seconds spent refining (0 without refinement).
    pub refine_seconds: f64,
    /// Primitives the post-refinement existence check removed.
    pub refine_dropped: usize,
    /// Lattice passes run (2 when the lattice was re-aligned to a first refined fit).
    pub passes: usize,
    /// Primitives proposed by the coarse-to-fine gap filling (before merging).
    pub filled: usize,
}

/// The result of [`fit`].
#[derive(Debug, Clone)]
pub struct FitResult {
    /// Settings used.
    pub settings: Settings,
    /// The chosen primitives.
    pub primitives: Vec<Primitive>,
    /// The continuous existence probability of each chosen primitive.
    pub existence: Vec<f64>,
    /// Solver output over all candidates.
    pub solution: Solution,
    /// Sizes and timings.
    pub stats: FitStats,
    /// What the sampler did, for the `mcmc` method.
    pub mcmc: Option<McmcRun>,
}

impl FitResult {
    /// `result.json` (DESIGN §3); `metrics` is inserted as given.
    pub fn to_json(&self, metrics: Value) -> Value {
        let mut settings = self.settings.to_json();
        if let (Some(run), Some(Value::Object(m))) = (&self.mcmc, settings.get_mut("mcmc")) {
            let record = json!({
                "steps": run.steps,
                "burn_in": run.burn_in,
                "accepted": run.accepted,
                "polish_flips": run.polish_flips,
                "log_likelihood": run.log_likelihood,
                "log_posterior": run.log_posterior,
                "frames": run.frames,
                "skipped_points": run.skipped_points,
            });
            if let Value::Object(r) = record {
                m.extend(r);
            }
        }
        result_json(settings, metrics, &self.primitives, &self.existence)
    }

    /// All primitives as one mesh, with the primitive index of every face.
    pub fn mesh(&self) -> (TriMesh, Vec<i32>) {
        primitives_mesh(&self.primitives)
    }
}

/// The `result.json` document shared by `fit`, `synth --truth` and `register`.
pub fn result_json(
    settings: Value,
    metrics: Value,
    primitives: &[Primitive],
    existence: &[f64],
) -> Value {
    let list: Vec<Value> = primitives
        .iter()
        .zip(existence)
        .map(|(p, e)| {
            let mut v = p.to_json();
            v["existence"] = json!(e);
            v
        })
        .collect();
    json!({ "primfit": crate::VERSION, "settings": settings, "metrics": metrics, "primitives": list })
}

/// One triangle mesh of all `primitives`, and the index of the primitive of every face.
pub fn primitives_mesh(primitives: &[Primitive]) -> (TriMesh, Vec<i32>) {
    let mut mesh = TriMesh::default();
    let mut owner = Vec::new();
    for (k, p) in primitives.iter().enumerate() {
        let range = mesh.append(&p.triangulate());
        owner.extend(std::iter::repeat_n(k as i32, range.len()));
    }
    (mesh, owner)
}

/// The exact binary chamfer of a primitive set against `cloud` under `settings` (samples
/// at `settings.sample_spacing`, all primitives existing, no α/β truncation):
/// `w_prim Σ_i g_i + w_point Σ_y min_i d_i(y)`, or `d_cap` per point for an empty set.
/// Used to compare a fit with a ground truth on the fitter's own terms.
pub fn binary_chamfer(
    cloud: &PointCloud,
    primitives: &[Primitive],
    settings: &Settings,
) -> Result<LossValue> {
    let set = CandidateSet::from_primitives(primitives, settings.sample_spacing)?;
    let options = ChamferOptions {
        alpha: None,
        beta: None,
        ..settings.chamfer.clone()
    };
    let coeffs = Coefficients::build(&cloud.points, &set, &options, &Silent)?;
    Ok(Evaluator::new(&coeffs).binary_value(&vec![true; set.len()]))
}
