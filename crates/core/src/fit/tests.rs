//! Tests of the whole pipeline on small clouds.

use nalgebra::Point3;

use super::*;
use crate::ShapeKind;
use crate::chamfer::{ChamferOptions, PointModel};
use crate::error::{Remedy, Unit};
use crate::progress::Silent;

/// A floor patch 2 m × 2 m at z = 0 and a wall at x = 0, aligned with a 0.5 m lattice.
fn corner() -> PointCloud {
    let mut pts = Vec::new();
    for i in 0..40 {
        for j in 0..40 {
            let (a, b) = (i as f64 * 0.05 + 0.025, j as f64 * 0.05 + 0.025);
            pts.push(Point3::new(a, b, 0.0));
            pts.push(Point3::new(0.0, a, b));
        }
    }
    PointCloud::from_points(pts)
}

#[test]
fn fits_an_aligned_corner_with_squares() {
    let options = FitOptions {
        size: Some(1.0),
        ..FitOptions::lattice()
    };
    let result = fit(&corner(), &options, &Silent).unwrap();
    assert_eq!(result.settings.spacing, 0.5);
    // Every input point is on a chosen square (within the sample spacing).
    for p in corner().points.iter().step_by(7) {
        let d = result
            .primitives
            .iter()
            .map(|q| q.distance(p))
            .fold(f64::INFINITY, f64::min);
        assert!(d < 1e-9, "point {p:?} is {d} from the model");
    }
    // Two 2 m × 2 m faces need at least 4 squares each, and the polish leaves no
    // square that is off the data.
    assert!(result.primitives.len() >= 8, "{}", result.primitives.len());
    for q in &result.primitives {
        let c = q.center();
        assert!(
            c.z.abs() < 1e-12 || c.x.abs() < 1e-12,
            "stray square at {c:?}"
        );
    }
}

#[test]
fn bad_options_are_errors() {
    let c = corner();
    let bad = FitOptions {
        size: Some(-1.0),
        ..FitOptions::lattice()
    };
    assert!(fit(&c, &bad, &Silent).is_err());
    let bad = FitOptions {
        cap: Some(f64::NAN),
        ..FitOptions::lattice()
    };
    assert!(fit(&c, &bad, &Silent).is_err());
    assert!(fit(&PointCloud::default(), &FitOptions::lattice(), &Silent).is_err());
    let tiny = FitOptions {
        memory_budget: Some(10),
        ..FitOptions::lattice()
    };
    assert!(matches!(
        fit(&c, &tiny, &Silent),
        Err(Error::OverLimit {
            unit: Unit::Bytes,
            ..
        })
    ));
}

#[test]
fn faults_are_typed_and_name_the_option_by_its_field() {
    let c = corner();
    let negative = |e: Result<FitResult>, option: &str| match e {
        Err(Error::OutOfRange { name, .. }) => assert_eq!(name, option),
        other => panic!("{option}: {other:?}"),
    };
    for option in ["size", "spacing", "radius", "bend", "sample_spacing"] {
        let mut o = FitOptions::lattice();
        match option {
            "size" => o.size = Some(-1.0),
            "spacing" => o.spacing = Some(0.0),
            "radius" => o.radius = Some(f64::NAN),
            "bend" => o.bend = Some(-2.0),
            _ => o.sample_spacing = Some(f64::INFINITY),
        }
        negative(fit(&c, &o, &Silent), option);
    }
    let bad_cap = FitOptions {
        cap: Some(-1.0),
        ..FitOptions::lattice()
    };
    negative(fit(&c, &bad_cap, &Silent), "cap");
    assert!(matches!(
        fit(&PointCloud::default(), &FitOptions::lattice(), &Silent),
        Err(Error::EmptyCloud)
    ));
    let mut nan = c.clone();
    nan.points[7].y = f64::NAN;
    assert!(matches!(
        fit(&nan, &FitOptions::lattice(), &Silent),
        Err(Error::NonFinite { index: 7, .. })
    ));
    let mesh_without_mesh = FitOptions {
        kinds: vec![ShapeKind::Mesh],
        ..FitOptions::lattice()
    };
    assert!(matches!(
        fit(&c, &mesh_without_mesh, &Silent),
        Err(Error::Missing { .. })
    ));
    // The library names options by their fields, never by a CLI flag.
    let e = fit(
        &c,
        &FitOptions {
            size: Some(-1.0),
            ..FitOptions::lattice()
        },
        &Silent,
    );
    assert!(!e.unwrap_err().to_string().contains("--"));
}

#[test]
fn memory_budget_covers_the_peak_and_names_the_settings() {
    let existence = ChamferOptions {
        beta: Some(32),
        ..Default::default()
    };
    // 12 B per entry + 8 B offset, plus the polish transpose (17 B per candidate).
    let base = BYTES_PER_POINT;
    assert_eq!(
        estimate_bytes(1, 5000, 256, &existence),
        32 * 12 + 8 + 32 * 17 + base
    );
    let independent = ChamferOptions {
        model: PointModel::Independent,
        alpha: Some(10),
        ..existence.clone()
    };
    // 320 entries: the build's copy of them (and where each row lies) outweighs the
    // transpose.
    assert_eq!(
        estimate_bytes(1, 5000, 256, &independent),
        320 * 12 + 8 + (320 * 12 + 16) + base
    );
    // Fewer candidates than β: every candidate is an entry.
    assert_eq!(
        estimate_bytes(2, 3, 256, &existence),
        2 * (3 * 12 + 8 + (3 * 12 + 16) + base)
    );

    let c = corner();
    let fitted = fit(&c, &FitOptions::lattice(), &Silent).unwrap();
    let need = fitted.stats.estimated_bytes;
    assert!(need >= fitted.stats.coefficient_bytes as u64);
    let just_under = FitOptions {
        memory_budget: Some(need - 1),
        ..FitOptions::lattice()
    };
    let Err(Error::OverLimit {
        need: got,
        limit,
        unit,
        remedies,
        ..
    }) = fit(&c, &just_under, &Silent)
    else {
        panic!("a budget below the estimate must refuse");
    };
    assert_eq!(
        (got, limit, unit),
        (need as f64, (need - 1) as f64, Unit::Bytes)
    );
    assert_eq!(
        remedies,
        [
            Remedy::Lower("beta"),
            Remedy::Raise("spacing"),
            Remedy::Subsample,
            Remedy::Raise("memory_budget"),
        ]
    );
    let exact = FitOptions {
        memory_budget: Some(need),
        ..FitOptions::lattice()
    };
    assert!(fit(&c, &exact, &Silent).is_ok());
}

#[test]
fn result_json_reads_back_to_the_same_result() {
    use crate::metrics::{MetricsOptions, evaluate};
    let c = corner();
    let no_meshes = |_: &str| -> Result<crate::atlas::MeshShape> { unreachable!("no meshes") };
    for options in [
        // The default: the compact model (types auto).
        FitOptions::default(),
        // A refined lattice of squares.
        FitOptions {
            kinds: vec![ShapeKind::Square],
            size: Some(1.0),
            ..FitOptions::default()
        },
        FitOptions {
            size: Some(1.0),
            model: PointModel::Independent,
            beta: crate::Limit::All,
            solver: crate::solve::SolverOptions {
                search_points: crate::Limit::All,
                ..Default::default()
            },
            ..FitOptions::lattice()
        },
    ] {
        let fitted = fit(&c, &options, &Silent).unwrap();
        let metrics = evaluate(
            &c.points,
            &fitted.primitives,
            None,
            &MetricsOptions::default(),
        )
        .unwrap();
        let doc = fitted.to_json(metrics.to_json());
        let (back, back_metrics) = FitResult::from_json(&doc, &no_meshes).unwrap();
        // The same document, key for key and number for number.
        assert_eq!(back.to_json(back_metrics.to_json()), doc);
        assert_eq!(back_metrics, metrics);
        assert_eq!(back.existence, fitted.existence);
        assert_eq!(back.primitives.len(), fitted.primitives.len());
        for (a, b) in back.primitives.iter().zip(&fitted.primitives) {
            assert_eq!(a.pose, b.pose);
            assert_eq!(a.shape.sizes_json(), b.shape.sizes_json());
        }
        let (s, t) = (&back.settings, &fitted.settings);
        assert_eq!(
            (s.size, s.spacing, s.origin, s.frame),
            (t.size, t.spacing, t.origin, t.frame)
        );
        assert_eq!(
            (&s.chamfer, &s.refine, &s.method),
            (&t.chamfer, &t.refine, &t.method)
        );
        assert_eq!(s.solver.search_points, t.solver.search_points);
    }
    let auto = fit(&c, &FitOptions::default(), &Silent).unwrap();
    assert!(matches!(auto.settings.method, MethodSettings::Compact(_)));
    // What is not a fit's result is refused, naming the part.
    let bad = serde_json::json!({"settings": {}, "metrics": {}, "primitives": []});
    let e = FitResult::from_json(&bad, &no_meshes).unwrap_err();
    assert!(
        matches!(&e, Error::Json { field, .. } if field == "settings"),
        "{e}"
    );
}

#[test]
fn the_realigned_lattice_shift_counts_rotation_at_the_cloud_edge_and_grid_phase() {
    let c = corner();
    let index = PointIndex::new(&c.points);
    let options = FitOptions {
        size: Some(1.0),
        ..FitOptions::default()
    };
    let options = FitOptions {
        kinds: vec![ShapeKind::Square],
        ..options
    };
    let s = Settings::resolve(&c, &index, &options).unwrap();
    let spacing = s.spacing;
    // A whole number of lattice steps along every axis is the same lattice.
    let same = s.origin + s.frame * nalgebra::Vector3::new(spacing, -2.0 * spacing, 3.0 * spacing);
    assert!(lattice_shift(&s, &s.frame, &same, 10.0) < 1e-12);
    // A quarter step along one axis moves every candidate by a quarter step.
    let quarter = s.origin + s.frame * nalgebra::Vector3::new(0.25 * spacing, 0.0, 0.0);
    let moved = lattice_shift(&s, &s.frame, &quarter, 10.0);
    assert!((moved - 0.25 * spacing).abs() < 1e-12, "{moved}");
    // A rotation of θ moves a candidate at the reach (extent + size) by θ times it.
    let theta = 1e-3;
    let turned = nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, theta) * s.frame;
    let moved = lattice_shift(&s, &turned, &s.origin, 10.0);
    assert!((moved - theta * (10.0 + s.size)).abs() < 1e-9, "{moved}");
}
