//! What a fit returns: [`FitResult`] with its [`FitStats`], the `result.json` document,
//! the primitives as one mesh, and the binary chamfer a result is judged by.

use serde::Serialize;
use serde_json::Value;

use super::document::{PrimitiveEntry, ResultDoc, SettingsDoc};
use super::{McmcRun, Settings};
use crate::atlas::{MeshShape, TriMesh};
use crate::chamfer::{ChamferOptions, Coefficients, Evaluator, LossValue};
use crate::lattice::CandidateSet;
use crate::metrics::Metrics;
use crate::progress::Silent;
use crate::solve::{Solution, StopReason};
use crate::{Error, PointCloud, Primitive, Result, StageTimes};

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
    /// The peak estimate checked against the memory budget ([`super::estimate_bytes`]).
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
    /// Wall time of every stage, in order (`detect.normals`, `existence.solve`, …; a
    /// lattice fit: `pass.lattice`, `gaps`, `realigned_pass.solve`, …).
    pub stages: StageTimes,
}

/// The result of [`super::fit`].
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
        let settings = SettingsDoc::new(&self.settings, self.mcmc.as_ref());
        document(settings, metrics, &self.primitives, &self.existence)
    }

    /// Reads back a `result.json` of a fit (as [`FitResult::to_json`] writes it): the
    /// settings, the primitives with their existence, the mcmc run, and the measures.
    /// `load` gives the mesh of a mesh source (the fit's `mesh_model`, mesh primitives).
    /// What the document does not hold is empty: the solver's [`Solution`] (no
    /// candidates), the [`FitStats`] but `points` (from the measures) and `passes` (1).
    pub fn from_json(
        doc: &Value,
        load: &dyn Fn(&str) -> Result<MeshShape>,
    ) -> Result<(FitResult, Metrics)> {
        let part = |key: &'static str| doc.get(key).cloned().unwrap_or(Value::Null);
        let settings: SettingsDoc = serde_json::from_value(part("settings"))
            .map_err(|e| Error::json("settings", e.to_string()))?;
        let metrics: Metrics = serde_json::from_value(part("metrics"))
            .map_err(|e| Error::json("metrics", e.to_string()))?;
        let (settings, mcmc) = settings.to_settings(load)?;
        let entries = doc
            .get("primitives")
            .and_then(Value::as_array)
            .ok_or_else(|| Error::json("primitives", "an array of primitives"))?;
        let mut primitives = Vec::with_capacity(entries.len());
        let mut existence = Vec::with_capacity(entries.len());
        for (k, entry) in entries.iter().enumerate() {
            primitives
                .push(Primitive::from_json(entry, load).map_err(|e| e.in_item("primitive", k))?);
            let p = entry
                .get("existence")
                .and_then(Value::as_f64)
                .ok_or_else(|| {
                    Error::json(format!("primitives[{k}].existence"), "a probability")
                })?;
            existence.push(p);
        }
        let stats = FitStats {
            points: metrics.points,
            passes: 1,
            ..FitStats::default()
        };
        let result = FitResult {
            settings,
            primitives,
            existence,
            solution: unrecorded_solution(),
            stats,
            mcmc,
        };
        Ok((result, metrics))
    }

    /// All primitives as one mesh, with the primitive index of every face.
    pub fn mesh(&self) -> (TriMesh, Vec<i32>) {
        primitives_mesh(&self.primitives)
    }
}

/// The solution of a result read from JSON, which records none: no candidates.
fn unrecorded_solution() -> Solution {
    Solution {
        probability: Vec::new(),
        exists: Vec::new(),
        history: Vec::new(),
        iterations: 0,
        evaluations: 0,
        stop: StopReason::Iterations,
        thresholded: LossValue::default(),
        binary: LossValue::default(),
        flips: 0,
    }
}

/// The `result.json` document shared by `fit`, `synth --truth` and `register`
/// (`document.rs`): their own `settings` and `metrics`, and the primitives.
pub fn result_json(
    settings: Value,
    metrics: Value,
    primitives: &[Primitive],
    existence: &[f64],
) -> Value {
    document(settings, metrics, primitives, existence)
}

/// [`ResultDoc`] as JSON.
fn document(
    settings: impl Serialize,
    metrics: impl Serialize,
    primitives: &[Primitive],
    existence: &[f64],
) -> Value {
    let doc = ResultDoc {
        primfit: crate::VERSION,
        settings,
        metrics,
        primitives: primitives
            .iter()
            .zip(existence)
            .map(|(primitive, &existence)| PrimitiveEntry {
                primitive,
                existence,
            })
            .collect(),
    };
    serde_json::to_value(doc).unwrap_or(Value::Null)
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
    let index = crate::PointIndex::new(&cloud.points);
    binary_chamfer_indexed(cloud, &index, primitives, settings)
}

/// [`binary_chamfer`] with `index`, a kd-tree over exactly `cloud.points`.
pub(super) fn binary_chamfer_indexed(
    cloud: &PointCloud,
    index: &crate::PointIndex,
    primitives: &[Primitive],
    settings: &Settings,
) -> Result<LossValue> {
    let set = CandidateSet::from_primitives(primitives, settings.sample_spacing)?;
    let options = ChamferOptions {
        alpha: None,
        beta: None,
        ..settings.chamfer.clone()
    }
    .for_all_existing();
    let coeffs = Coefficients::build_indexed(&cloud.points, index, &set, &options, &Silent)?;
    Ok(Evaluator::new(&coeffs).binary_value(&vec![true; set.len()]))
}
