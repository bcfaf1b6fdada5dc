//! `primfit fit`: scan in, primitives out.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use primfit_core::atlas::{MeshShape, ShapeKind};
use primfit_core::fit::FrameChoice;
use primfit_core::fit::{
    AUTO_TYPES, DEFAULT_FRAME, DEFAULT_MAX_ITERATIONS, DEFAULT_PRIOR, DEFAULT_SEARCH_POINTS,
    DEFAULT_SEED, FitOptions, McmcFitOptions, MethodOptions, fit_indexed, parse_types,
};
use primfit_core::io::{self, Encoding};
use primfit_core::metrics::evaluate_indexed;
use primfit_core::na::Point3;
use primfit_core::refine::RefineOptions;
use primfit_core::solve::{Parameterization, SolverOptions};
use primfit_core::tiles::fit_tiled;
use primfit_core::{Limit, MetricsOptions, PointIndex, Stopwatch, chamfer::PointModel as Model};

use super::sizes::SizeArgs;
use super::tiles::{TileArgs, hand_off};
use super::{Output, check_output, parse_limit, parse_pair, parse_point, read_scene};
use crate::progress::Bars;

/// Arguments of `primfit fit`. Every size defaults to a value derived from the cloud
/// (printed with `-v`, and written to the result's `settings`); every other default is
/// the library's ([`FitOptions::default`]).
#[derive(Debug, Args)]
#[command(
    mut_arg("size", |a| a.help(
        "Candidate main extent in scene units: square side, disk/sphere diameter, cylinder \
         length [default: bounding-box diagonal / 8, rounded down to 1, 2 or 5 × 10^k]"
    )),
    mut_arg("radius", |a| a.help("Tube radius of cylinders and elbows [default: size / 10]")),
    mut_arg("bend", |a| a.help("Elbow bend radius (centre line) [default: spacing]")),
)]
pub struct FitArgs {
    /// The scan: a PLY point cloud (ascii or binary; float or double coordinates).
    pub scene: PathBuf,
    /// Write the result JSON here.
    #[arg(short, long, value_name = "result.json")]
    pub output: Option<PathBuf>,
    /// Write all fitted primitives as one triangle mesh, in the format of the extension:
    /// `.ply` (per-face `primitive` index), `.obj` (one object per primitive) or `.glb`
    /// (glTF binary: one node per primitive, type and existence in its extras).
    #[arg(long, value_name = "fitted.ply|obj|glb")]
    pub mesh: Option<PathBuf>,
    /// Write a PLY mesh as ascii instead of binary little-endian.
    #[arg(long)]
    pub ascii: bool,
    /// Primitive types: `auto` (the compact model: planes with outlines, cylinders and
    /// spheres detected in the data, kept by the probabilistic chamfer with a
    /// description length per primitive; the lattice options below play no part), or a
    /// comma-separated lattice from square, disk, cylinder, elbow, sphere, mesh.
    #[arg(long, value_delimiter = ',', default_value = AUTO_TYPES)]
    pub types: Vec<String>,
    /// Candidate sizes.
    #[command(flatten)]
    pub sizes: SizeArgs,
    /// Lattice translation step [default: size / 2].
    #[arg(allow_hyphen_values = true, long)]
    pub spacing: Option<f64>,
    /// A lattice point, `x,y,z` [default: with `--frame axis` 0,0,0; otherwise chosen so
    /// that grid planes lie on the scan's main planes].
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    pub origin: Option<[f64; 3]>,
    /// Lattice frame: `auto` estimates the scan's dominant axes from local normals (PCA of
    /// 32 nearest neighbours) and puts the grid on the data; `axis` uses the scene axes
    /// and origin; a FILE is JSON `{"rotation": [w,x,y,z], "origin": [x,y,z]}` (origin
    /// optional) or an earlier result.json (its settings.frame and origin are reused).
    #[arg(long, default_value = DEFAULT_FRAME.name(), value_name = "auto|axis|FILE")]
    pub frame: String,
    /// Skip the continuous refinement of the chosen primitives' poses and sizes (and the
    /// existence re-check after it).
    #[arg(long)]
    pub no_refine: bool,
    /// Refinement rounds (point assignment + Levenberg–Marquardt per primitive).
    #[arg(allow_hyphen_values = true, long, default_value_t = RefineOptions::default().rounds)]
    pub refine_rounds: usize,
    /// Spacing of candidate surface samples [default: min(size/16, 2π·radius/12), at least
    /// the cloud's median point spacing].
    #[arg(allow_hyphen_values = true, long)]
    pub sample_spacing: Option<f64>,
    /// Point-term model.
    #[arg(long, default_value = Model::default().name(), value_parser = ["existence", "independent"])]
    pub model: String,
    /// α: samples per candidate and point (independent model); `inf` = all.
    #[arg(allow_hyphen_values = true, long, value_parser = parse_limit, default_value_t = FitOptions::default().alpha)]
    pub alpha: Limit,
    /// β: candidates per point; `inf` = all.
    #[arg(allow_hyphen_values = true, long, value_parser = parse_limit, default_value_t = FitOptions::default().beta)]
    pub beta: Limit,
    /// Distance whose square is the cost of an unexplained point [default: max(spacing,
    /// 5σ) with σ the scan's noise level, estimated from local plane fits].
    #[arg(allow_hyphen_values = true, long)]
    pub cap: Option<f64>,
    /// Weights of the primitive and point terms, `a,b` [default: 1,1].
    #[arg(long, value_parser = parse_pair, allow_hyphen_values = true)]
    pub weights: Option<[f64; 2]>,
    /// Inference method (mcmc needs sensor origins per point).
    #[arg(long, default_value = MethodOptions::default().name(), value_parser = ["chamfer", "mcmc"])]
    pub method: String,
    /// Existence parameterisation of L-BFGS.
    #[arg(long, default_value = Parameterization::default().name(), value_parser = ["box", "logit"])]
    pub parameterization: String,
    /// Maximum L-BFGS iterations.
    #[arg(allow_hyphen_values = true, long, default_value_t = DEFAULT_MAX_ITERATIONS)]
    pub max_iterations: usize,
    /// Larger clouds are solved in two phases: L-BFGS and the polish's search moves on
    /// about this many points (point term reweighted), then L-BFGS and single flips on
    /// every point. 0 = one phase on every point (slower on large clouds).
    #[arg(allow_hyphen_values = true, long, default_value_t = DEFAULT_SEARCH_POINTS.get().unwrap_or(0))]
    pub search_points: usize,
    /// Most estimated nearest-neighbour queries per point of a lattice pass; a fit over
    /// it is refused up front [default: 2000, 20× the default lattice fit's].
    #[arg(allow_hyphen_values = true, long)]
    pub work_budget: Option<f64>,
    /// Skip the discrete polish after thresholding.
    #[arg(long)]
    pub no_polish: bool,
    /// Charge each candidate for the rays that cross it in front of their points (needs
    /// sensor origins) [default: on when the scene has sensor_x/y/z].
    #[arg(long, overrides_with = "no_free_space")]
    pub free_space: bool,
    /// Do not charge free space, even when the scene has sensor origins.
    #[arg(long, overrides_with = "free_space")]
    pub no_free_space: bool,
    /// mcmc: Metropolis–Hastings proposals after burn-in [default: max(1000, 20 × candidates)].
    #[arg(allow_hyphen_values = true, long)]
    pub steps: Option<usize>,
    /// mcmc: proposals before existence frequencies count [default: steps / 5].
    #[arg(allow_hyphen_values = true, long)]
    pub burn_in: Option<usize>,
    /// mcmc: noise returns per unit length of ray [default: 1 / bounding-box diagonal].
    #[arg(allow_hyphen_values = true, long)]
    pub noise_rate: Option<f64>,
    /// mcmc: deviation of a primitive's points along its normal [default: spacing / 10].
    #[arg(allow_hyphen_values = true, long)]
    pub sigma: Option<f64>,
    /// mcmc: prior existence probability of a candidate with nearby points.
    #[arg(allow_hyphen_values = true, long, default_value_t = DEFAULT_PRIOR)]
    pub prior: f64,
    /// Triangle mesh (PLY with faces) used by the `mesh` type.
    #[arg(long, value_name = "object.ply")]
    pub mesh_model: Option<PathBuf>,
    /// Seed for every random choice.
    #[arg(allow_hyphen_values = true, long, default_value_t = DEFAULT_SEED)]
    pub seed: u64,
    /// Write the wall time of every stage (read, index, detection steps, existence,
    /// measures, output) as JSON here.
    #[arg(long, value_name = "timings.json")]
    pub timings: Option<PathBuf>,
    /// Tiled fitting of large surveys.
    #[command(flatten)]
    pub tiling: TileArgs,
}

impl FitArgs {
    /// Translates the flags into library options.
    fn options(&self) -> Result<FitOptions> {
        let kinds = parse_types(&self.types).context("--types")?;
        let mesh = match (&self.mesh_model, kinds.contains(&ShapeKind::Mesh)) {
            (Some(path), _) => {
                let m = io::read_mesh(path)?;
                let shape = MeshShape::new(path.display().to_string(), m)
                    .with_context(|| format!("{}: unusable as a mesh model", path.display()))?;
                Some(shape)
            }
            (None, true) => bail!("--types mesh needs --mesh-model object.ply"),
            (None, false) => None,
        };
        let defaults = FitOptions::default();
        let [primitive_weight, point_weight] = self
            .weights
            .unwrap_or([defaults.primitive_weight, defaults.point_weight]);
        let frame = match self.frame.as_str() {
            "auto" | "axis" => FrameChoice::parse(&self.frame)?,
            file => {
                let text = std::fs::read_to_string(file)
                    .with_context(|| format!("reading --frame {file}"))?;
                let value: serde_json::Value = serde_json::from_str(&text)
                    .with_context(|| format!("parsing --frame {file} as JSON"))?;
                FrameChoice::from_json(&value).with_context(|| format!("--frame {file}"))?
            }
        };
        let refine = (!self.no_refine).then(|| RefineOptions {
            rounds: self.refine_rounds,
            ..defaults.refine.clone().unwrap_or_default()
        });
        let method = match MethodOptions::parse(&self.method)? {
            MethodOptions::Mcmc(_) => {
                let mcmc = self.mcmc_options();
                mcmc.validate()?;
                MethodOptions::Mcmc(mcmc)
            }
            chamfer => chamfer,
        };
        Ok(FitOptions {
            kinds,
            frame,
            refine,
            size: self.sizes.size,
            radius: self.sizes.radius,
            bend: self.sizes.bend,
            spacing: self.spacing,
            origin: self.origin.map(|[x, y, z]| Point3::new(x, y, z)),
            sample_spacing: self.sample_spacing,
            model: Model::parse(&self.model)?,
            alpha: self.alpha,
            beta: self.beta,
            cap: self.cap,
            primitive_weight,
            point_weight,
            mesh,
            solver: SolverOptions {
                parameterization: Parameterization::parse(&self.parameterization)?,
                max_iterations: self.max_iterations,
                search_points: match self.search_points {
                    0 => Limit::All,
                    n => Limit::At(n),
                },
                polish: !self.no_polish,
                ..defaults.solver
            },
            method,
            memory_budget: None,
            work_budget: self.work_budget,
            free_space: match (self.free_space, self.no_free_space) {
                (true, _) => Some(true),
                (_, true) => Some(false),
                _ => defaults.free_space,
            },
            seed: self.seed,
        })
    }

    /// The options of `--method mcmc`.
    fn mcmc_options(&self) -> McmcFitOptions {
        McmcFitOptions {
            rate: self.noise_rate,
            sigma: self.sigma,
            prior: self.prior,
            steps: self.steps,
            burn_in: self.burn_in,
            ..Default::default()
        }
    }
}

/// Runs `primfit fit`.
pub fn run(args: FitArgs, out: &Output) -> Result<()> {
    let mut clock = Stopwatch::start();
    let mut outputs = vec![];
    outputs.extend(args.output.as_deref());
    outputs.extend(args.mesh.as_deref());
    outputs.extend(args.timings.as_deref());
    let mut inputs = vec![args.scene.as_path()];
    inputs.extend(args.mesh_model.as_deref());
    for path in &outputs {
        check_output(path, &inputs)?;
    }
    if let Some(path) = &args.mesh {
        io::MeshFormat::from_path(path)?;
    }
    for (i, a) in outputs.iter().enumerate() {
        if outputs[..i].contains(a) {
            bail!(
                "{}: given as two outputs (-o, --mesh, --timings)",
                a.display()
            );
        }
    }
    let options = args.options()?;
    if let Some(address) = &args.tiling.scheduler {
        let (o, m) = (args.output.as_deref(), args.mesh.as_deref());
        return hand_off(&args.tiling, address, &args.scene, o, m, out.quiet);
    }
    let cloud = read_scene(&args.scene, out)?;
    clock.lap("read");
    if args.method == "mcmc" && cloud.sensors.is_none() {
        bail!(
            "{}: --method mcmc needs each point's sensor origin (PLY vertex properties \
             sensor_x, sensor_y, sensor_z); use --method chamfer for clouds without them",
            args.scene.display()
        );
    }
    let bars = Bars::new(out.quiet, out.verbose);
    // One kd-tree for the fit and the measures.
    let index = PointIndex::new(&cloud.points);
    clock.lap("index");
    let t = &args.tiling;
    let result = if t.tiles {
        fit_tiled(&cloud, &options, t.tile_size, t.halo, &bars)
    } else {
        fit_indexed(&cloud, &index, &options, &bars)
    }
    .with_context(|| format!("fitting {}", args.scene.display()))?;
    clock.lap("fit");
    clock.nest("fit", &result.stats.stages);
    let metrics = evaluate_indexed(
        &cloud.points,
        &index,
        &result.primitives,
        None,
        &MetricsOptions::default(),
    )?;
    clock.lap("measures");
    let encoding = if args.ascii {
        Encoding::Ascii
    } else {
        Encoding::BinaryLittleEndian
    };
    // Both outputs or neither: the JSON is staged, the mesh written, then the JSON
    // renamed into place (a failed mesh write drops the staged JSON).
    let staged = match &args.output {
        Some(path) => {
            let mut doc = result.to_json(metrics.to_json());
            doc["settings"]["scene"] = args.scene.display().to_string().into();
            Some(io::stage_json(path, &doc)?)
        }
        None => None,
    };
    if let Some(path) = &args.mesh {
        io::write_primitives_mesh(path, &result.primitives, Some(&result.existence), encoding)?;
    }
    if let Some(json) = staged {
        json.commit()?;
    }
    clock.lap("write");
    if let Some(path) = &args.timings {
        let doc = serde_json::json!({
            "scene": args.scene.display().to_string(),
            "points": cloud.len(),
            "threads": rayon::current_num_threads(),
            "stages": clock.times.to_json(),
        });
        io::write_json_atomic(path, &doc)?;
    }
    if !out.quiet {
        print_summary(&args, &result, &metrics, out.verbose);
        if out.verbose {
            println!("stages: {}", clock.times.summary());
        }
    }
    Ok(())
}

fn print_summary(
    args: &FitArgs,
    r: &primfit_core::fit::FitResult,
    m: &primfit_core::metrics::Metrics,
    verbose: bool,
) {
    println!("{}", summary_line(args, r));
    println!(
        "point→model mean {:.4}, p95 {:.4}, max {:.4}; model→point mean {:.4}; coverage@{:.4} {:.1} %",
        m.point_to_model_mean,
        m.point_to_model_p95,
        m.point_to_model_max,
        m.model_to_point_mean,
        m.coverage_tau,
        100.0 * m.coverage
    );
    if verbose {
        for line in verbose_lines(r) {
            println!("{line}");
        }
    }
    for (flag, path) in [("result", &args.output), ("mesh", &args.mesh)] {
        if let Some(p) = path {
            println!("wrote {flag} {}", p.display());
        }
    }
}

/// `SCENE: J points → K primitives (by type) from N candidates`, with the candidates the
/// solver saw when dominance set some aside.
fn summary_line(args: &FitArgs, r: &primfit_core::fit::FitResult) -> String {
    let mut counts = std::collections::BTreeMap::new();
    for p in &r.primitives {
        *counts.entry(p.shape.kind().name()).or_insert(0usize) += 1;
    }
    let kinds: Vec<String> = counts.iter().map(|(k, n)| format!("{n} {k}")).collect();
    let s = &r.stats;
    let candidates = if s.lattice_candidates > s.candidates {
        format!(
            "{} candidates ({} not dominated)",
            s.lattice_candidates, s.candidates
        )
    } else {
        format!("{} candidates", s.candidates)
    };
    format!(
        "{}: {} points → {} primitives ({}) from {candidates}",
        args.scene.display(),
        s.points,
        r.primitives.len(),
        if kinds.is_empty() {
            "none".into()
        } else {
            kinds.join(", ")
        },
    )
}

/// The `--verbose` details of the fit's method: sizes, times and settings.
fn verbose_lines(r: &primfit_core::fit::FitResult) -> Vec<String> {
    use primfit_core::fit::MethodSettings;
    let (s, st) = (&r.stats, &r.settings);
    match &st.method {
        MethodSettings::Mcmc(_) => vec![format!(
            "{} ({} proposals, {} accepted)",
            sizes_and_times(s, "crossings", "ray table", "sampling"),
            r.solution.iterations,
            r.solution.flips
        )],
        MethodSettings::Compact(c) => vec![format!(
            "compact model: {} segments → {} candidates; noise σ {:.5}, point spacing {:.5}, cap {:.5}, sample spacing {:.5}; existence: {} iterations, {} evaluations, {} polish flips",
            c.segments,
            c.proposed,
            st.noise,
            st.point_spacing,
            st.cap,
            st.sample_spacing,
            r.solution.iterations,
            r.solution.evaluations,
            r.solution.flips
        )],
        MethodSettings::Chamfer => {
            let q = st.frame.quaternion();
            vec![
                format!(
                    "{} ({} iterations, {} evaluations, {} polish flips), refine {:.2} s ({} dropped)",
                    sizes_and_times(s, "entries", "coefficients", "solve"),
                    r.solution.iterations,
                    r.solution.evaluations,
                    r.solution.flips,
                    s.refine_seconds,
                    s.refine_dropped
                ),
                format!(
                    "frame {} [w x y z] = [{:.4} {:.4} {:.4} {:.4}] (support {}), origin [{:.4} {:.4} {:.4}], noise σ {:.4}, size {}, spacing {}, cap {:.4}",
                    st.frame_source,
                    q.w,
                    q.i,
                    q.j,
                    q.k,
                    st.frame_support
                        .map_or("n/a".to_string(), |s| format!("{:.0} %", 100.0 * s)),
                    st.origin.x,
                    st.origin.y,
                    st.origin.z,
                    st.noise,
                    st.size,
                    st.spacing,
                    st.cap
                ),
            ]
        }
    }
}

/// `N <what> × B B = M MiB; lattice … s, <coefficients> … s, <solve> … s`: the sizes
/// and stage times a lattice method reports.
fn sizes_and_times(
    s: &primfit_core::fit::FitStats,
    what: &str,
    coefficients: &str,
    solve: &str,
) -> String {
    format!(
        "{} {what} × {} B = {:.1} MiB; lattice {:.2} s, {coefficients} {:.2} s, {solve} {:.2} s",
        s.entries,
        s.bytes_per_entry,
        s.coefficient_bytes as f64 / (1 << 20) as f64,
        s.lattice_seconds,
        s.coefficient_seconds,
        s.solve_seconds
    )
}
