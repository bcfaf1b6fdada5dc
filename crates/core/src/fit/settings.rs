//! [`FitOptions`] (what a user may set), [`Settings`] (every value a fit uses) and
//! [`Settings::resolve`], which derives the defaults from the cloud.

use nalgebra::{Point3, UnitQuaternion};
use serde_json::{Value, json};

use super::budget::physical_memory;
use crate::atlas::{MeshShape, Shape, ShapeKind};
use crate::chamfer::{ChamferOptions, PointModel};
use crate::frame::{FrameChoice, FrameEstimate, estimate_frame, grid_origin};
use crate::lattice::LatticeSpec;
use crate::refine::RefineOptions;
use crate::solve::SolverOptions;
use crate::spatial::{PointIndex, median_spacing};
use crate::surface::{
    DEFAULT_MAX_POINTS, DEFAULT_NEIGHBOURS, NOISE_MAX_POINTS, local_planes, noise_level,
};
use crate::{Error, PointCloud, Result};

/// User-facing options of [`fit`]; `None` means "derive from the cloud".
#[derive(Debug, Clone, Default)]
pub struct FitOptions {
    /// Primitive types to use (default: square).
    pub kinds: Vec<ShapeKind>,
    /// Main extent: square side, disk/sphere diameter, cylinder length.
    pub size: Option<f64>,
    /// Tube radius of cylinders and elbows.
    pub radius: Option<f64>,
    /// Elbow bend radius (centre line).
    pub bend: Option<f64>,
    /// Lattice translation step.
    pub spacing: Option<f64>,
    /// A lattice point.
    pub origin: Option<Point3<f64>>,
    /// How the lattice frame is chosen (default: the scene axes).
    pub frame: FrameChoice,
    /// Continuous refinement after the existence decision (default: none).
    pub refine: Option<RefineOptions>,
    /// Spacing of candidate surface samples.
    pub sample_spacing: Option<f64>,
    /// Point-term model.
    pub model: PointModel,
    /// α; `Some(usize::MAX)` = unlimited.
    pub alpha: Option<usize>,
    /// β; `Some(usize::MAX)` = unlimited.
    pub beta: Option<usize>,
    /// The distance whose square is `d_cap`.
    pub cap: Option<f64>,
    /// Weight of the primitive term (default 1).
    pub primitive_weight: Option<f64>,
    /// Weight of the point term (default 1).
    pub point_weight: Option<f64>,
    /// The mesh used by the `mesh` type.
    pub mesh: Option<MeshShape>,
    /// Solver settings.
    pub solver: SolverOptions,
    /// Upper bound on the estimated peak memory of the fit ([`estimate_bytes`]), bytes
    /// (default: half the machine's memory).
    pub memory_budget: Option<u64>,
    /// Seed for every random choice (the chamfer fit itself is deterministic).
    pub seed: u64,
}

/// The inference method of a fit (`--method`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// Probabilistic chamfer + L-BFGS over existence (thesis ch. 6).
    #[default]
    Chamfer,
    /// Ray likelihood + Metropolis–Hastings over existence (thesis ch. 4, [`crate::ray`]).
    Mcmc,
}

impl Method {
    /// The CLI/JSON name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Chamfer => "chamfer",
            Method::Mcmc => "mcmc",
        }
    }
}

/// Every setting of a fit, defaults resolved.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Primitive types.
    pub kinds: Vec<ShapeKind>,
    /// See [`FitOptions::size`].
    pub size: f64,
    /// See [`FitOptions::radius`].
    pub radius: f64,
    /// See [`FitOptions::bend`].
    pub bend: f64,
    /// See [`FitOptions::spacing`].
    pub spacing: f64,
    /// See [`FitOptions::origin`].
    pub origin: Point3<f64>,
    /// Lattice frame → scene.
    pub frame: UnitQuaternion<f64>,
    /// How the frame was chosen: `axis`, `auto` or `given`.
    pub frame_source: &'static str,
    /// Share of flat normals within ≈ 14° of a frame axis (estimated frames only).
    pub frame_support: Option<f64>,
    /// The cloud's estimated noise σ (scene units; see the module docs), 0 if unknown.
    pub noise: f64,
    /// Refinement options, if refinement runs.
    pub refine: Option<RefineOptions>,
    /// See [`FitOptions::sample_spacing`].
    pub sample_spacing: f64,
    /// The cloud's median nearest-neighbour distance.
    pub point_spacing: f64,
    /// The distance whose square is `d_cap`.
    pub cap: f64,
    /// Loss options.
    pub chamfer: ChamferOptions,
    /// Solver options.
    pub solver: SolverOptions,
    /// Seed.
    pub seed: u64,
    /// Budget for the estimated peak memory of a fit, bytes ([`estimate_bytes`]).
    pub memory_budget: u64,
    /// Mesh source, if the mesh type is used.
    pub mesh: Option<MeshShape>,
    /// The inference method.
    pub method: Method,
    /// Settings specific to the method, merged into [`Settings::to_json`] (e.g. the ray
    /// model and sampler of `mcmc`).
    pub method_settings: serde_json::Map<String, Value>,
}

/// `x` rounded down to 1, 2 or 5 × 10^k.
fn nice_floor(x: f64) -> f64 {
    let e = 10f64.powf(x.log10().floor());
    let m = x / e;
    e * if m >= 5.0 {
        5.0
    } else if m >= 2.0 {
        2.0
    } else {
        1.0
    }
}

fn limit(v: Option<usize>, default: usize) -> Option<usize> {
    match v {
        None => Some(default),
        Some(usize::MAX) => None,
        Some(n) => Some(n),
    }
}

fn positive(name: &str, v: f64) -> Result<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(Error::invalid(format!(
            "--{name} must be a positive length, got {v}"
        )))
    }
}

/// The lattice frame, the frame estimate's support and the grid origin of `o.frame`:
/// given values as they are, otherwise estimated from local planes of the cloud.
fn resolve_frame(
    cloud: &PointCloud,
    index: &PointIndex,
    o: &FitOptions,
    spacing: f64,
    size: f64,
) -> (UnitQuaternion<f64>, Option<f64>, Point3<f64>) {
    let given_origin = match &o.frame {
        FrameChoice::Given {
            origin: Some(p), ..
        } => Some(*p),
        _ => o.origin,
    };
    // The frame and the grid origin need more neighbourhoods than the noise level;
    // they are estimated only when not given.
    let estimated = matches!(o.frame, FrameChoice::Auto)
        || (given_origin.is_none() && !matches!(o.frame, FrameChoice::Axis));
    let planes = if estimated {
        local_planes(&cloud.points, index, DEFAULT_NEIGHBOURS, DEFAULT_MAX_POINTS)
    } else {
        Vec::new()
    };
    let (frame, frame_support) = match &o.frame {
        FrameChoice::Axis => (UnitQuaternion::identity(), None),
        FrameChoice::Given { rotation, .. } => (*rotation, None),
        FrameChoice::Auto => match estimate_frame(&planes, o.seed) {
            Some(FrameEstimate { rotation, support }) => (rotation, Some(support)),
            None => (UnitQuaternion::identity(), None),
        },
    };
    let origin = match (given_origin, &o.frame) {
        (Some(p), _) => p,
        (None, FrameChoice::Axis) => Point3::origin(),
        (None, _) => grid_origin(&planes, &cloud.points, &frame, spacing, size),
    };
    (frame, frame_support, origin)
}

impl Settings {
    /// Resolves every default from the cloud (see the module docs) and validates.
    pub fn resolve(cloud: &PointCloud, index: &PointIndex, o: &FitOptions) -> Result<Settings> {
        let (lo, hi) = cloud
            .bounds()
            .ok_or_else(|| Error::invalid("the cloud is empty"))?;
        let diagonal = (hi - lo).norm();
        if diagonal.is_nan() || diagonal <= 0.0 {
            return Err(Error::invalid(
                "the cloud has no extent (all points coincide)",
            ));
        }
        let point_spacing = median_spacing(&cloud.points, index, 2000).unwrap_or(diagonal / 100.0);
        let noise = noise_level(&local_planes(
            &cloud.points,
            index,
            DEFAULT_NEIGHBOURS,
            NOISE_MAX_POINTS,
        ))
        .unwrap_or(0.0);

        let kinds = if o.kinds.is_empty() {
            vec![ShapeKind::Square]
        } else {
            o.kinds.clone()
        };
        let size = positive("size", o.size.unwrap_or_else(|| nice_floor(diagonal / 8.0)))?;
        let default_spacing = match &o.mesh {
            Some(m) if kinds.iter().all(|k| *k == ShapeKind::Mesh) => m.bounding_radius(),
            _ => size / 2.0,
        };
        let spacing = positive("spacing", o.spacing.unwrap_or(default_spacing))?;
        let radius = positive("radius", o.radius.unwrap_or(size / 10.0))?;
        let bend = positive("bend", o.bend.unwrap_or(spacing))?;
        let cap = o.cap.unwrap_or(spacing.max(5.0 * noise));
        if !(cap.is_finite() && cap >= 0.0) {
            return Err(Error::invalid(format!(
                "--cap must be a finite distance ≥ 0, got {cap}"
            )));
        }
        let tubes = kinds
            .iter()
            .any(|k| matches!(k, ShapeKind::Cylinder | ShapeKind::Elbow));
        let mut sample_spacing = size / 16.0;
        if tubes {
            sample_spacing = sample_spacing.min(std::f64::consts::TAU * radius / 12.0);
        }
        let sample_spacing = positive(
            "sample-spacing",
            o.sample_spacing
                .unwrap_or(sample_spacing.max(point_spacing)),
        )?;
        if kinds.contains(&ShapeKind::Mesh) && o.mesh.is_none() {
            return Err(Error::invalid(
                "the mesh type needs a mesh (--mesh-model FILE.ply)",
            ));
        }
        let chamfer = ChamferOptions {
            model: o.model,
            alpha: match o.model {
                PointModel::Independent => limit(o.alpha, 10),
                PointModel::Existence => None,
            },
            beta: limit(o.beta, 32),
            cap: cap * cap,
            surface_distance: o.model == PointModel::Existence,
            primitive_weight: o.primitive_weight.unwrap_or(1.0),
            point_weight: o.point_weight.unwrap_or(1.0),
        };
        chamfer.validate()?;
        if let Some(r) = &o.refine {
            r.validate()?;
        }
        let (frame, frame_support, origin) = resolve_frame(cloud, index, o, spacing, size);
        Ok(Settings {
            kinds,
            size,
            radius,
            bend,
            spacing,
            origin,
            frame,
            frame_source: o.frame.name(),
            frame_support,
            noise,
            refine: o.refine.clone(),
            sample_spacing,
            point_spacing,
            cap,
            chamfer,
            solver: o.solver.clone(),
            seed: o.seed,
            memory_budget: o.memory_budget.unwrap_or(physical_memory() / 2),
            mesh: o.mesh.clone(),
            method: Method::Chamfer,
            method_settings: serde_json::Map::new(),
        })
    }

    /// The shape of each selected type at the configured sizes.
    pub fn shapes(&self) -> Vec<Shape> {
        self.kinds
            .iter()
            .filter_map(|k| {
                Some(match k {
                    ShapeKind::Square => Shape::Square { side: self.size },
                    ShapeKind::Disk => Shape::Disk {
                        diameter: self.size,
                    },
                    ShapeKind::Sphere => Shape::Sphere {
                        diameter: self.size,
                    },
                    ShapeKind::Cylinder => Shape::Cylinder {
                        length: self.size,
                        radius: self.radius,
                    },
                    ShapeKind::Elbow => Shape::Elbow {
                        bend: self.bend,
                        radius: self.radius,
                    },
                    ShapeKind::Mesh => Shape::Mesh(self.mesh.clone()?),
                    ShapeKind::Plane => return None,
                })
            })
            .collect()
    }

    /// The lattice these settings describe.
    pub fn lattice(&self) -> LatticeSpec {
        LatticeSpec {
            shapes: self.shapes(),
            spacing: self.spacing,
            origin: self.origin,
            frame: self.frame,
            sample_spacing: self.sample_spacing,
        }
    }

    /// Every setting as JSON (`result.json`'s `"settings"`).
    pub fn to_json(&self) -> Value {
        let lim = |v: Option<usize>| v.map_or(Value::from("inf"), Value::from);
        let frame = FrameEstimate {
            rotation: self.frame,
            support: self.frame_support.unwrap_or(f64::NAN),
        }
        .to_json(self.frame_source);
        let refine = self.refine.as_ref().map(|r| {
            json!({ "rounds": r.rounds, "iterations": r.iterations, "trim": r.trim.unwrap_or(self.cap),
                    "max_growth": r.max_growth, "recheck": r.recheck, "merge": r.merge, "fill": r.fill,
                    "retype": r.retype })
        });
        let mut doc = json!({
            "types": self.kinds.iter().map(|k| k.name()).collect::<Vec<_>>(),
            "size": self.size,
            "radius": self.radius,
            "bend": self.bend,
            "spacing": self.spacing,
            "origin": [self.origin.x, self.origin.y, self.origin.z],
            "frame": frame,
            "noise": self.noise,
            "refine": refine,
            "sample_spacing": self.sample_spacing,
            "point_spacing": self.point_spacing,
            "model": self.chamfer.model.name(),
            "alpha": lim(self.chamfer.alpha),
            "beta": lim(self.chamfer.beta),
            "cap": self.cap,
            "weights": [self.chamfer.primitive_weight, self.chamfer.point_weight],
            "parameterization": self.solver.parameterization.name(),
            "max_iterations": self.solver.max_iterations,
            "search_points": self.solver.search_points,
            "threshold": self.solver.threshold,
            "polish": self.solver.polish,
            "method": self.method.name(),
            "seed": self.seed,
            "mesh_model": self.mesh.as_ref().map(|m| m.source.clone()),
        });
        if let Value::Object(m) = &mut doc {
            if self.method != Method::Chamfer {
                // The chamfer loss and its solver play no part in other methods.
                for key in [
                    "model",
                    "alpha",
                    "beta",
                    "cap",
                    "weights",
                    "parameterization",
                    "max_iterations",
                    "search_points",
                    "threshold",
                    "polish",
                ] {
                    m.remove(key);
                }
            }
            m.extend(self.method_settings.clone());
        }
        doc
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_floor_rounds_down_to_1_2_5() {
        assert_eq!(nice_floor(1.3), 1.0);
        assert_eq!(nice_floor(0.31), 0.2);
        assert_eq!(nice_floor(7.0), 5.0);
        assert!((nice_floor(0.05) - 0.05).abs() < 1e-15);
    }
}
