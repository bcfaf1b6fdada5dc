//! Tiling with ground truth: partition and ownership, seam merging, de-duplication, the
//! LAS/LAZ tile reader, and a tiled fit against one fit of the same floor.

use nalgebra::{Point2, Point3, UnitQuaternion, Vector3};

use super::*;
use crate::atlas::{PlaneShape, Shape};
use crate::metrics::double_cover_share;
use crate::synth::{SurveyParams, survey};
use crate::{Pose, Primitive, Silent};

const TOL: MergeTolerance = MergeTolerance {
    distance: 0.02,
    noise: 0.003,
    points: 100_000,
};

/// The wall y = `y`, x from `x0` to `x1`, z from 0 to 3, as a plane (normal −y).
fn wall(x0: f64, x1: f64, y: f64) -> Primitive {
    let outline = vec![
        Point2::new(0.0, 0.0),
        Point2::new(x1 - x0, 0.0),
        Point2::new(x1 - x0, 3.0),
        Point2::new(0.0, 3.0),
    ];
    let r = UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(
        nalgebra::Matrix3::from_columns(&[Vector3::x(), Vector3::z(), -Vector3::y()]),
    ));
    let shape = PlaneShape::new(outline, Vec::new()).unwrap();
    Primitive::new(Shape::Plane(shape), Pose::new(r, Vector3::new(x0, y, 0.0)))
}

/// A cylinder of radius 0.08 along x from `x0` to `x1` at y = 2, z = 2.6.
fn pipe(x0: f64, x1: f64) -> Primitive {
    let r = crate::synth::axis_rotation(0);
    let shape = Shape::Cylinder {
        length: x1 - x0,
        radius: 0.08,
    };
    Primitive::new(shape, Pose::new(r, Vector3::new(0.5 * (x0 + x1), 2.0, 2.6)))
}

fn pieces(prims: Vec<Primitive>) -> Vec<Piece> {
    prims
        .into_iter()
        .enumerate()
        .map(|(t, primitive)| Piece {
            primitive,
            existence: 1.0,
            tiles: vec![t],
        })
        .collect()
}

#[test]
fn a_wall_across_three_tiles_is_one_plane() {
    let merged = merge_pieces(
        pieces(vec![
            wall(0.0, 12.0, 0.0),
            wall(8.0, 22.0, 0.0),
            wall(18.0, 30.0, 0.001),
        ]),
        &TOL,
    );
    assert_eq!(merged.len(), 1);
    assert!(
        (merged[0].primitive.area() - 90.0).abs() < 0.5,
        "{}",
        merged[0].primitive.area()
    );
    assert_eq!(merged[0].tiles.len(), 3);
}

#[test]
fn parallel_walls_apart_and_pieces_of_one_tile_stay_apart() {
    let apart = merge_pieces(
        pieces(vec![wall(0.0, 12.0, 0.0), wall(8.0, 22.0, 1.0)]),
        &TOL,
    );
    assert_eq!(apart.len(), 2);
    let mut same_tile = pieces(vec![wall(0.0, 12.0, 0.0), wall(8.0, 22.0, 0.0)]);
    same_tile[1].tiles = vec![0];
    assert_eq!(merge_pieces(same_tile, &TOL).len(), 2);
}

#[test]
fn a_pipe_across_a_seam_is_one_cylinder() {
    let merged = merge_pieces(
        pieces(vec![pipe(0.0, 12.0), pipe(8.0, 22.0), pipe(21.9, 30.0)]),
        &TOL,
    );
    assert_eq!(merged.len(), 1);
    let Shape::Cylinder { length, radius } = merged[0].primitive.shape else {
        panic!("not a cylinder");
    };
    assert!((length - 30.0).abs() < 1e-9 && (radius - 0.08).abs() < 1e-12);
    assert!((merged[0].primitive.center().x - 15.0).abs() < 1e-9);
    // A thinner pipe beside it does not join.
    let other = Primitive::new(
        Shape::Cylinder {
            length: 10.0,
            radius: 0.03,
        },
        Pose::new(crate::synth::axis_rotation(0), Vector3::new(15.0, 2.0, 2.6)),
    );
    assert_eq!(
        merge_pieces(pieces(vec![pipe(0.0, 12.0), other]), &TOL).len(),
        2
    );
}

#[test]
fn a_duplicate_on_a_seam_is_dropped_by_the_re_check() {
    // A small piece of the wall, 5 mm off it, from another tile, left by the merge.
    let big = wall(0.0, 20.0, 0.0);
    let small = wall(9.0, 11.0, 0.005);
    let far = wall(30.0, 32.0, 4.0);
    let seam: Vec<Point3<f64>> = (0..400)
        .map(|k| Point3::new(9.0 + 0.005 * k as f64, 0.0, 0.1 + 0.002 * k as f64))
        .collect();
    let kept = dedup_on_seams(pieces(vec![big, small, far]), &seam, &TOL).unwrap();
    assert_eq!(kept.len(), 2);
    assert!((kept[0].primitive.area() - 60.0).abs() < 1e-9);
}

#[test]
fn tiles_of_las_and_laz_files_are_read_in_batches() {
    let dir = std::env::temp_dir().join(format!("primfit-tiles-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let points: Vec<Point3<f64>> = (0..5000)
        .map(|k| Point3::new((k % 100) as f64 * 0.3, (k / 100) as f64 * 0.3, 1.0))
        .collect();
    for name in ["t.las", "t.laz"] {
        let path = dir.join(name);
        crate::io::write_las(&path, &points, 0.001).unwrap();
        let (lo, hi, n) = survey_bounds(&path).unwrap();
        assert_eq!(n, 5000);
        let grid = TileGrid::new(&lo, &hi, 10.0, 1.0).unwrap();
        for t in 0..grid.len() {
            let got = read_tile(&path, &grid, t).unwrap();
            let want = points
                .iter()
                .filter(|p| grid.in_haloed(t, p.x, p.y))
                .count();
            assert_eq!(got.len(), want, "{name} tile {t}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_split_in_parts_gives_each_tile_the_points_a_direct_read_gives() {
    let dir = std::env::temp_dir().join(format!("primfit-split-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // 70 000 points: more than one LAZ chunk (50 000), so a part seeks into the file.
    let points: Vec<Point3<f64>> = (0..70_000)
        .map(|k| {
            Point3::new(
                (k % 250) as f64 * 0.1,
                (k / 250) as f64 * 0.1,
                0.001 * k as f64,
            )
        })
        .collect();
    let path = dir.join("s.laz");
    crate::io::write_las(&path, &points, 0.001).unwrap();
    let (lo, hi, n) = survey_bounds(&path).unwrap();
    let grid = TileGrid::new(&lo, &hi, 10.0, 1.0).unwrap();
    let parts = [(0, 30_000), (30_000, 25_000), (55_000, u64::MAX)];
    let mut received = vec![0u64; grid.len()];
    for (part, &(first, count)) in parts.iter().enumerate() {
        let counts = split_survey(&path, &grid, first, count, &dir, part).unwrap();
        received.iter_mut().zip(counts).for_each(|(r, c)| *r += c);
    }
    assert_eq!(n, 70_000);
    for (t, &count) in received.iter().enumerate() {
        let mut want = read_tile(&path, &grid, t).unwrap();
        let mut got = read_spilled_tile(&dir, t, parts.len()).unwrap();
        assert_eq!(got.len() as u64, count, "tile {t}");
        let key = |p: &Point3<f64>| (p.z * 1e6).round() as i64;
        want.sort_by_key(key);
        got.sort_by_key(key);
        assert_eq!(got.len(), want.len(), "tile {t}");
        assert!(got == want, "tile {t}: the points differ");
    }
    // A second split of the same part replaces its files instead of appending.
    split_survey(&path, &grid, 0, 30_000, &dir, 0).unwrap();
    let total: usize = (0..grid.len())
        .map(|t| read_spilled_tile(&dir, t, parts.len()).unwrap().len())
        .sum();
    assert_eq!(total as u64, received.iter().sum::<u64>());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_tiles_are_one_clear_error() {
    let cloud = crate::PointCloud::from_points(vec![Point3::origin(), Point3::new(1.0, 1.0, 1.0)]);
    let grid = TileGrid::new(&Point3::origin(), &Point3::new(1.0, 1.0, 1.0), 1.0, 0.1).unwrap();
    let options = FitOptions::default();
    assert!(fit_tile(&cloud.points, &grid, 99, &options, &Silent).is_err());
    let err = fit_tiled(&cloud, &options, Some(0.5), None, &Silent).unwrap_err();
    assert!(err.to_string().contains("tile size"), "{err}");
    assert!(fit_tiled(&cloud, &options, Some(-1.0), None, &Silent).is_err());
}

#[test]
fn a_tiled_floor_matches_one_fit() {
    let scene = survey(&SurveyParams {
        points: 60_000,
        ..Default::default()
    })
    .unwrap();
    let options = FitOptions::default();
    let single = crate::fit(&scene.cloud, &options, &Silent).unwrap();
    // 3 × 2 tiles of 15 m: every wall along x, the floor and the pipe cross seams.
    let tiled = fit_tiled(&scene.cloud, &options, Some(15.0), None, &Silent).unwrap();
    let (a, b) = (
        single.primitives.len() as f64,
        tiled.primitives.len() as f64,
    );
    assert!(
        (a - b).abs() <= (0.02 * a).max(1.0),
        "single {a}, tiled {b}"
    );
    let h = 3.0 * tiled.settings.point_spacing;
    let twice = double_cover_share(&tiled.primitives, h, h).unwrap();
    assert!(twice < 0.01, "covered twice {twice}");
    let pipes = tiled
        .primitives
        .iter()
        .filter(|p| matches!(p.shape, Shape::Cylinder { .. }));
    assert_eq!(pipes.count(), 1);
}
