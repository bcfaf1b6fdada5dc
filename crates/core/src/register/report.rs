//! What a registration found ([`Registration`], one [`FoundObject`] per object) and its
//! `result.json`.

use serde::Serialize;
use serde_json::Value;

use super::particle_filter::RoundStats;
use crate::fit::document::{PrimitiveEntry, ResultDoc};
use crate::{Pose, Primitive, StageTimes};

/// One object found by [`register`](super::register).
#[derive(Debug, Clone)]
pub struct FoundObject {
    /// The posed mesh.
    pub primitive: Primitive,
    /// The calibrated probability that it is there at this pose (0‥1, at most
    /// [`MAX_EXISTENCE`](super::confidence::MAX_EXISTENCE)).
    pub existence: f64,
    /// The margin by which its pose beats the outlier-only explanation around its
    /// surface: the signed root of a log-likelihood ratio, about N(0, 1) for clutter
    /// ([`margin`](super::confidence::margin)).
    pub margin: f64,
    /// The margin of the best other answer among the tries of the final choice (the
    /// pose turned by π about a principal axis, the point-pair hypotheses, refined): how
    /// nearly another pose explains the points as well (−∞ when there was none).
    pub runner_up_margin: f64,
    /// Share of all cloud points within the inlier distance of its surface (0‥1).
    pub inlier_share: f64,
    /// RMS surface distance of those inliers (scene units).
    pub rms: f64,
    /// The search's pose before ICP: the particle filter's answer, or the point-pair
    /// hypothesis accepted without the filter's search.
    pub filter_pose: Pose,
    /// Per-round statistics of the filter's search (empty when it did not run).
    pub rounds: Vec<RoundStats>,
}

/// The result of [`register`](super::register).
#[derive(Debug, Clone)]
pub struct Registration {
    /// Objects found, in the order found (the strongest first).
    pub objects: Vec<FoundObject>,
    /// Model size used for the relative settings (scene units, scale 1).
    pub model_size: f64,
    /// Wall time (seconds).
    pub seconds: f64,
    /// Wall time per stage (seconds): the model's distance grid and samples (`model`),
    /// the point-pair hypotheses and their polish, and per search the tries' measure,
    /// the particle filter and the settling of its answers (summed over searches).
    pub timings: StageTimes,
}

impl Registration {
    /// `result.json` (DESIGN §3): one `"type": "mesh"` entry per object found, with its
    /// pose, `existence`, `inlier_share` and `margin`.
    pub fn to_json(&self, settings: Value, metrics: Value) -> Value {
        /// One object's entry: the primitive's, with its `inlier_share`.
        #[derive(Serialize)]
        struct Entry<'a> {
            #[serde(flatten)]
            entry: PrimitiveEntry<'a>,
            inlier_share: f64,
            margin: f64,
        }
        let primitives = self
            .objects
            .iter()
            .map(|o| Entry {
                entry: PrimitiveEntry {
                    primitive: &o.primitive,
                    existence: o.existence,
                },
                inlier_share: o.inlier_share,
                margin: o.margin,
            })
            .collect();
        let doc = ResultDoc {
            primfit: crate::VERSION,
            settings,
            metrics,
            primitives,
        };
        serde_json::to_value(doc).unwrap_or(Value::Null)
    }
}
