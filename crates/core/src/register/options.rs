//! The settings of a registration ([`RegisterOptions`]): defaults, range checks and
//! their JSON record.

use nalgebra::Vector3;
use serde::Serialize;
use serde_json::Value;

use crate::Result;
use crate::check::{self, Interval};

/// Settings of [`register`](super::register). Fractions are of the model size (the diagonal of the mesh's
/// bounding box, scene units after the pose's scale).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RegisterOptions {
    /// Estimate the translation (default); `false`: rotation only, about the mesh's
    /// origin placed at [`RegisterOptions::fixed_translation`].
    pub translation: bool,
    /// The translation when it is not estimated (scene units).
    #[serde(skip)]
    pub fixed_translation: Vector3<f64>,
    /// Estimate a uniform scale within this range (`None` = scale 1).
    pub scale: Option<(f64, f64)>,
    /// Search for this many objects, one after another (those below
    /// [`RegisterOptions::min_confidence`] are searched for but not reported); `None` =
    /// as many as exist (at most `max_objects`).
    pub count: Option<usize>,
    /// Upper bound on the objects found automatically.
    pub max_objects: usize,
    /// Particles of the first round (drawn from the prior).
    pub initial_particles: usize,
    /// Prior draws screened for the first population (see
    /// [`RegisterOptions::initial_particles`]); `None` = `initial_particles`, or with
    /// translation search but no votes ([`RegisterOptions::vote_peaks`] = 0), 8 ×
    /// `initial_particles` (the 6-D prior is far larger). With votes, each draw is a
    /// rotation (and scale) that gets `vote_peaks` translations.
    #[serde(skip)]
    pub screen: Option<usize>,
    /// Cloud points (a stride subsample) of the screening proxy.
    pub screen_points: usize,
    /// With translation search: vote peaks kept per prior rotation of the first
    /// population (`vote.rs`; each becomes a particle with that
    /// translation); 0 = draw translations from the prior instead.
    pub vote_peaks: usize,
    /// With translation votes: the candidates (rotation, vote peak) with the most votes
    /// that form the first population, each translation refined at point level
    /// (`vote.rs`).
    pub vote_keep: usize,
    /// Bin (grid cell) of the translation vote, fraction of the model size.
    pub vote_bin: f64,
    /// Spacing of the model samples that vote, fraction of the model size.
    pub vote_spacing: f64,
    /// With translation search and no scale: pose hypotheses from point-pair features
    /// (`ppf.rs`) that join the filter's answer and its symmetry tries in the final
    /// choice (each settled by ICP); 0 = none.
    pub pair_hypotheses: usize,
    /// Existence (0‥1) at which the best point-pair hypothesis, settled by ICP, is
    /// accepted without the particle filter's search; above 1: always search. The
    /// default is [`min_confidence`](Self::min_confidence)'s: an answer that would be
    /// reported anyway is not searched further. On the calibration scenes this kept every
    /// right answer right and cut the median time from 1.6 to 0.45 s
    /// (docs/registration_confidence.md).
    pub accept_without_search: f64,
    /// Particles of later rounds.
    pub particles: usize,
    /// Round limit per object.
    pub max_rounds: usize,
    /// First kernel width, fraction of the model size.
    pub kernel_start: f64,
    /// Last kernel width, fraction of the model size.
    pub kernel_end: f64,
    /// Kernel factor per round (in (0, 1)).
    pub kernel_shrink: f64,
    /// Move spread (σ of the translation; rotation σ = spread / lever arm), as a multiple
    /// of the kernel width.
    pub spread: f64,
    /// Translation moves are `translation_spread` × the spread of surface points under
    /// the rotation moves (rotations and translations are searched at different rates:
    /// a wrong rotation can gain a little by sliding, which would drag the population).
    pub translation_spread: f64,
    /// Rounds with a stable best pose at the last kernel before stopping.
    pub settle_rounds: usize,
    /// The search gives up after this many rounds in a row in which no particle's
    /// point-term gain paid its primitive term (every score ≤ 0: nothing in the cloud
    /// explains [`RegisterOptions::search_support`] points beyond clutter); its best pose
    /// is still settled and measured. 0 = never give up.
    pub give_up_rounds: usize,
    /// Target effective sample size, as a share of the particles (in (0, 1]).
    pub ess: f64,
    /// β of the chamfer: candidates kept per point.
    pub beta: usize,
    /// Weight of the chamfer's primitive term (its point term has weight 1); `None` =
    /// calibrated every round so that a typical particle pays what uniform clutter around
    /// its surface would gain it plus [`RegisterOptions::min_support`] points.
    pub primitive_weight: Option<f64>,
    /// Points an object must explain beyond what clutter explains to exist (with the
    /// calibrated primitive weight): the final existence decision.
    pub min_support: f64,
    /// The same, for the primitive weight of the search's measurement (how strongly the
    /// primitive term — model samples far from any point — counts against a particle).
    pub search_support: f64,
    /// Leading particles moved downhill each round by trimmed-ICP steps at the kernel.
    pub local_moves: usize,
    /// Leading particles whose approximate symmetry flips ([`symmetry_flips`](super::symmetry_flips): turns by
    /// π about the model's principal axes) join the next round, each round: a jump
    /// between the basins a nearly symmetric object leaves in the measurement.
    pub flip_moves: usize,
    /// Share of the particles resampled within each other basin of the best particle
    /// (the basins of its symmetry flips), by the basin's own weights, each round.
    pub basin_share: f64,
    /// ICP steps of each such move.
    pub local_steps: usize,
    /// Most samples of the outlier primitive (not recorded in `result.json`).
    #[serde(skip)]
    pub max_outlier_samples: usize,
    /// Translation prior: the model, rotated and scaled, lies inside the scene's bounding
    /// box, its extents about its centre first multiplied by this (1 = wholly inside;
    /// less allows objects cut by the box).
    pub prior_margin: f64,
    /// Spacing of the particles' template samples, fraction of the model size.
    pub sample_spacing: f64,
    /// Refine each pose by trimmed ICP.
    pub icp: bool,
    /// Inlier distance: a cloud point within it of a found surface is that object's
    /// inlier (ICP's last correspondence distance); fraction of the model size.
    pub inlier_distance: f64,
    /// Existence threshold of the chamfer solves inside the search (polish).
    pub threshold: f64,
    /// Smallest calibrated existence of a reported object (0‥1): objects below it are
    /// not reported, and the search for more objects stops at the first one below it.
    pub min_confidence: f64,
    /// Seed of every random choice.
    pub seed: u64,
}

/// The most particles of a round (first or later): 50× the default first round, far
/// past where more particles stop helping, and still minutes of work at most.
pub const MAX_PARTICLES: usize = 100_000;

/// The most filter rounds per object (the default is 40; the filter settles in 10–30).
pub const MAX_ROUNDS: usize = 10_000;

/// The most point-pair hypotheses (the default is 8): each is one ICP refinement.
pub const MAX_PAIR_HYPOTHESES: usize = 1_000;

impl Default for RegisterOptions {
    fn default() -> Self {
        RegisterOptions {
            translation: true,
            fixed_translation: Vector3::zeros(),
            scale: None,
            count: None,
            max_objects: 8,
            initial_particles: 2000,
            screen: None,
            screen_points: 500,
            vote_peaks: 2,
            vote_keep: 400,
            vote_bin: 0.08,
            vote_spacing: 0.04,
            pair_hypotheses: 8,
            accept_without_search: 0.5,
            particles: 200,
            max_rounds: 40,
            kernel_start: 0.08,
            kernel_end: 0.02,
            kernel_shrink: 0.85,
            spread: 0.5,
            translation_spread: 0.25,
            settle_rounds: 2,
            give_up_rounds: 3,
            ess: 0.1,
            beta: 8,
            primitive_weight: None,
            min_support: 50.0,
            search_support: 30.0,
            local_moves: 8,
            local_steps: 3,
            flip_moves: 2,
            basin_share: 0.1,
            max_outlier_samples: 200_000,
            prior_margin: 1.0,
            sample_spacing: 1.0 / 15.0,
            icp: true,
            inlier_distance: 0.01,
            threshold: 0.5,
            min_confidence: 0.5,
            seed: 0,
        }
    }
}

impl RegisterOptions {
    /// Checks ranges.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("kernel_start", self.kernel_start),
            ("kernel_end", self.kernel_end),
            ("spread", self.spread),
            ("translation_spread", self.translation_spread),
            ("sample_spacing", self.sample_spacing),
            ("vote_bin", self.vote_bin),
            ("vote_spacing", self.vote_spacing),
            ("inlier_distance", self.inlier_distance),
        ] {
            check::positive(name, v)?;
        }
        check::in_interval(
            "kernel_shrink",
            self.kernel_shrink,
            Interval::open(0.0, 1.0),
        )?;
        check::in_interval("basin_share", self.basin_share, Interval::closed(0.0, 0.3))?;
        check::in_interval("ess", self.ess, Interval::open_closed(0.0, 1.0))?;
        check::in_interval("threshold", self.threshold, Interval::UNIT)?;
        check::in_interval("min_confidence", self.min_confidence, Interval::UNIT)?;
        if let Some(w) = self.primitive_weight {
            check::non_negative("primitive_weight", w)?;
        }
        check::non_negative("min_support", self.min_support)?;
        check::non_negative("search_support", self.search_support)?;
        check::non_negative("prior_margin", self.prior_margin)?;
        check::non_negative("accept_without_search", self.accept_without_search)?;
        check::at_most("pair_hypotheses", self.pair_hypotheses, MAX_PAIR_HYPOTHESES)?;
        for (name, k) in [
            ("initial_particles", self.initial_particles),
            ("particles", self.particles),
            ("max_rounds", self.max_rounds),
            ("vote_keep", self.vote_keep),
            ("beta", self.beta),
        ] {
            check::at_least(name, k, 1)?;
        }
        check::at_most("initial_particles", self.initial_particles, MAX_PARTICLES)?;
        check::at_most("particles", self.particles, MAX_PARTICLES)?;
        check::at_most("max_rounds", self.max_rounds, MAX_ROUNDS)?;
        if let Some(k) = self.count {
            check::at_least("count", k, 1)?;
        }
        if let Some(range) = self.scale {
            check::positive_range("scale", range)?;
        }
        check::finite("fixed_translation", self.fixed_translation.as_slice())
    }

    /// Prior draws screened for the first population (resolves `screen: None`).
    pub fn screen_draws(&self) -> usize {
        self.screen
            .unwrap_or(if self.translation && self.vote_peaks == 0 {
                8 * self.initial_particles
            } else {
                self.initial_particles
            })
    }

    /// The options as JSON (the `settings` of `result.json`: every option, the screen
    /// resolved, and `"method": "particle_filter"`).
    pub fn to_json(&self) -> Value {
        let t = &self.fixed_translation;
        let doc = SettingsDoc {
            method: "particle_filter",
            fixed_translation: (!self.translation).then_some([t.x, t.y, t.z]),
            screen: self.screen_draws(),
            options: self,
        };
        serde_json::to_value(doc).unwrap_or(Value::Null)
    }
}

/// The `settings` of a registration's `result.json`: every option (the screen resolved,
/// the fixed translation only when the translation is not estimated) and the method.
#[derive(Serialize)]
struct SettingsDoc<'a> {
    method: &'static str,
    fixed_translation: Option<[f64; 3]>,
    screen: usize,
    #[serde(flatten)]
    options: &'a RegisterOptions,
}
