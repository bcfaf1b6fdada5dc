//! Scenes shared by the criterion benches (`crates/core/benches/*.rs`) and the benchmark
//! table (`crates/core/examples/bench_table.rs`, which includes this file with `#[path]`).
//!
//! Every scene is deterministic (seeded) and has an exact point count
//! ([`Density::Total`]); its fit options are the fitter's defaults plus the lattice the
//! scene lives on.
#![allow(dead_code)] // each bench target uses a different subset

use primfit_core::PointIndex;
use primfit_core::Silent;
use primfit_core::chamfer::{Coefficients, PointModel};
use primfit_core::fit::{FitOptions, Settings};
use primfit_core::lattice::CandidateSet;
use primfit_core::synth::{Density, HallwayParams, PipeParams, hallway, pipe};
use primfit_core::{PointCloud, ShapeKind};

/// Which synthetic scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// The thesis's pipe (§6.3.1): 4 runs with elbows; cylinders of length 1, radius 0.1,
    /// elbows of bend 0.5, lattice spacing 0.5.
    Pipe,
    /// The thesis's hallway (§6.3.2): 10 m × 2 m × 2.5 m (floor and two walls), 1 m
    /// squares on a 0.5 m lattice.
    Hallway,
}

/// A benchmark scene: a generator, a point count and a point model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BenchScene {
    /// Generator.
    pub kind: Kind,
    /// Exact number of input points.
    pub points: usize,
    /// Point-term model of the fit.
    pub model: PointModel,
    /// How much of the discrete polish the fit runs.
    pub polish: Polish,
}

/// How much of the discrete polish a bench fit runs after thresholding.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Polish {
    /// The fitter's default: the polish's sweeps.
    Sweeps,
    /// `-nosweeps`: no sweeps, but the polish state, and so the memory peak of a default
    /// fit, is still built (the 10M memory check).
    StateOnly,
    /// `-nopolish`: threshold at 0.5 and stop, as the NumPy reference does (its work,
    /// like for like).
    Off,
}

impl Polish {
    /// The scene-name suffix.
    const fn suffix(self) -> &'static str {
        match self {
            Polish::Sweeps => "",
            Polish::StateOnly => "-nosweeps",
            Polish::Off => "-nopolish",
        }
    }
}

impl BenchScene {
    /// A scene.
    pub const fn new(kind: Kind, points: usize, model: PointModel) -> Self {
        BenchScene {
            kind,
            points,
            model,
            polish: Polish::Sweeps,
        }
    }

    /// `pipe-20k`, `hallway-1m`, … (with `-indep` for the independent model).
    pub fn name(&self) -> String {
        let kind = match self.kind {
            Kind::Pipe => "pipe",
            Kind::Hallway => "hallway",
        };
        let model = match self.model {
            PointModel::Existence => "",
            PointModel::Independent => "-indep",
        };
        let polish = self.polish.suffix();
        format!("{kind}-{}{model}{polish}", count_label(self.points))
    }

    /// Parses a [`BenchScene::name`].
    pub fn parse(name: &str) -> Option<Self> {
        let (name, polish) = [Polish::StateOnly, Polish::Off]
            .into_iter()
            .find_map(|p| Some((name.strip_suffix(p.suffix())?, p)))
            .unwrap_or((name, Polish::Sweeps));
        let (rest, model) = match name.strip_suffix("-indep") {
            Some(r) => (r, PointModel::Independent),
            None => (name, PointModel::Existence),
        };
        let (kind, count) = rest.split_once('-')?;
        let kind = match kind {
            "pipe" => Kind::Pipe,
            "hallway" => Kind::Hallway,
            _ => return None,
        };
        let scene = BenchScene::new(kind, parse_count(count)?, model);
        Some(BenchScene { polish, ..scene })
    }

    /// The input cloud (seed 0).
    pub fn cloud(&self) -> PointCloud {
        let density = Density::Total(self.points);
        let scene = match self.kind {
            Kind::Pipe => pipe(&PipeParams {
                density,
                ..Default::default()
            }),
            Kind::Hallway => hallway(&HallwayParams {
                length: 10.0,
                width: 2.0,
                height: 2.5,
                side: 1.0,
                density,
                ..Default::default()
            }),
        };
        scene.expect("benchmark scene parameters are valid").cloud
    }

    /// The fitter's default options with this scene's lattice flags.
    pub fn options(&self) -> FitOptions {
        let mut base = FitOptions {
            model: self.model,
            size: Some(1.0),
            spacing: Some(0.5),
            ..FitOptions::lattice()
        };
        match self.polish {
            Polish::Sweeps => {}
            Polish::StateOnly => base.solver.max_polish_sweeps = 0,
            Polish::Off => base.solver.polish = false,
        }
        match self.kind {
            // `--types cylinder,elbow --size 1 --radius 0.1 --bend 0.5 --spacing 0.5`
            Kind::Pipe => FitOptions {
                kinds: vec![ShapeKind::Cylinder, ShapeKind::Elbow],
                radius: Some(0.1),
                bend: Some(0.5),
                ..base
            },
            // `--types square --size 1 --spacing 0.5`
            Kind::Hallway => FitOptions {
                kinds: vec![ShapeKind::Square],
                ..base
            },
        }
    }

    /// Resolved settings and the candidate set, as [`primfit_core::fit::fit`] builds them (before
    /// the exact dominance reduction of `Coefficients::build_reduced`).
    pub fn prepare(&self, cloud: &PointCloud) -> (Settings, CandidateSet) {
        let index = PointIndex::new(&cloud.points);
        let settings = Settings::resolve(cloud, &index, &self.options()).expect("valid settings");
        let mut candidates = CandidateSet::build(&settings.lattice(), cloud).expect("lattice");
        // The fitter's occupancy prior (`fit_pass`): candidates with no point near them.
        let keep = candidates.near_data(&cloud.points, settings.cap + settings.sample_spacing);
        candidates.retain(&keep);
        (settings, candidates)
    }

    /// Everything up to the solver: settings, candidates and coefficients.
    pub fn coefficients(&self, cloud: &PointCloud) -> (Settings, CandidateSet, Coefficients) {
        let (settings, candidates) = self.prepare(cloud);
        let coeffs = Coefficients::build(&cloud.points, &candidates, &settings.chamfer, &Silent)
            .expect("coefficients");
        (settings, candidates, coeffs)
    }
}

/// `20k`, `1m`, `10m`, or the plain number.
pub fn count_label(n: usize) -> String {
    if n >= 1_000_000 && n.is_multiple_of(1_000_000) {
        format!("{}m", n / 1_000_000)
    } else if n >= 1000 && n.is_multiple_of(1000) {
        format!("{}k", n / 1000)
    } else {
        n.to_string()
    }
}

/// Inverse of [`count_label`].
pub fn parse_count(s: &str) -> Option<usize> {
    let s = s.to_ascii_lowercase();
    let (digits, scale) = match s.as_bytes().last()? {
        b'k' => (&s[..s.len() - 1], 1000),
        b'm' => (&s[..s.len() - 1], 1_000_000),
        _ => (&s[..], 1),
    };
    digits.parse::<usize>().ok().map(|n| n * scale)
}

/// The benchmark sizes of issue 4.
pub const SIZES: [usize; 3] = [20_000, 100_000, 1_000_000];
