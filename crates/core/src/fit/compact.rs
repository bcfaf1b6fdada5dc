//! The default pipeline (`types` auto): the compact model of [`crate::compact`] as a
//! [`FitResult`], with its settings.

use nalgebra::{Point3, UnitQuaternion};

use super::options::FitOptions;
use super::settings::{CompactSettings, MethodSettings, resolve_free_space};
use super::{FitResult, FitStats, Settings};
use crate::chamfer::ChamferOptions;
use crate::compact::{CompactModel, CompactOptions, EXISTENCE_BETA, compact_model};
use crate::progress::Progress;
use crate::ray::Rays;
use crate::spatial::PointIndex;
use crate::{Error, PointCloud, Result, check};

/// The compact model of `cloud` under `options` (its `cap`, `sample_spacing`, `solver`,
/// `seed` and `memory_budget` apply; the lattice options play no part).
pub(super) fn fit_compact(
    cloud: &PointCloud,
    index: &PointIndex,
    options: &FitOptions,
    progress: &dyn Progress,
) -> Result<FitResult> {
    check_lattice_options_unset(options)?;
    if let Some(cap) = options.cap {
        check::non_negative("cap", cap)?;
    }
    if let Some(s) = options.sample_spacing {
        check::positive("sample_spacing", s)?;
    }
    let compact = CompactOptions {
        cap: options.cap,
        sample_spacing: options.sample_spacing,
        weights: Some([options.primitive_weight, options.point_weight]),
        solver: options.solver.clone(),
        free_space: match resolve_free_space(options.free_space, cloud)? {
            true => Some(Rays::from_cloud(cloud)?),
            false => None,
        },
        ..Default::default()
    };
    let free_space = compact.free_space.is_some();
    let model = compact_model(&cloud.points, index, &compact, progress)?;
    let settings = compact_settings(options, &model, free_space);
    let stats = FitStats {
        points: cloud.len(),
        lattice_candidates: model.proposed,
        candidates: model.proposed,
        lattice_seconds: model.detect_seconds,
        solve_seconds: model.existence_seconds,
        passes: 1,
        stages: model.times.clone(),
        ..Default::default()
    };
    Ok(FitResult {
        settings,
        primitives: model.primitives,
        existence: model.existence,
        solution: model.solution,
        stats,
        mcmc: None,
    })
}

/// The lattice's own options have no meaning when the types come from the data: a value
/// given for one is refused rather than silently ignored.
fn check_lattice_options_unset(options: &FitOptions) -> Result<()> {
    let expected = "unset: with the types detected from the data (auto) the sizes and \
                    positions come from the data; name lattice types to set it";
    let lengths = [
        ("size", options.size),
        ("radius", options.radius),
        ("bend", options.bend),
        ("spacing", options.spacing),
    ];
    if let Some((name, Some(v))) = lengths.iter().find(|(_, v)| v.is_some()) {
        return Err(Error::out_of_range(*name, v, expected));
    }
    if let Some(o) = options.origin {
        return Err(Error::out_of_range(
            "origin",
            format!("{:?}", o.coords.as_slice()),
            expected,
        ));
    }
    Ok(())
}

/// The settings a compact model was made with (`free_space`: whether rays charged
/// the candidates).
fn compact_settings(options: &FitOptions, model: &CompactModel, free_space: bool) -> Settings {
    let detection = &model.detection;
    let chamfer = ChamferOptions {
        cap: model.cap * model.cap,
        surface_distance: true,
        beta: Some(EXISTENCE_BETA),
        primitive_weight: options.primitive_weight,
        point_weight: options.point_weight,
        ..Default::default()
    };
    Settings {
        kinds: Vec::new(),
        size: 0.0,
        radius: 0.0,
        bend: 0.0,
        spacing: 0.0,
        origin: Point3::origin(),
        frame: UnitQuaternion::identity(),
        frame_source: "auto",
        frame_support: None,
        noise: detection.model_noise,
        refine: None,
        sample_spacing: model.sample_spacing,
        point_spacing: detection.spacing,
        cap: model.cap,
        chamfer,
        solver: options.solver.clone(),
        seed: options.seed,
        memory_budget: options
            .memory_budget
            .unwrap_or_else(crate::budget::default_memory_budget),
        work_budget: options.work_budget.unwrap_or(super::DEFAULT_WORK_PER_POINT),
        mesh: None,
        free_space,
        method: MethodSettings::Compact(CompactSettings {
            segments: detection.segments.len(),
            proposed: model.proposed,
            growing_noise: detection.noise,
            angle_degrees: detection.angle.to_degrees(),
            voxel: detection.voxel,
        }),
    }
}
