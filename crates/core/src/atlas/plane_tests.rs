//! Tests of the `plane` type (polygon geometry) and of outlines traced from points.
//! Ground truth: analytic areas of the synthetic regions, `geo`'s polygon distance,
//! dense samples, and the known pose of synthetic 3-D planes.

use nalgebra::{Point2, Point3, UnitQuaternion, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::tests::{l_plane, plane_distance_2d};
use super::{PlaneShape, Shape, fit_plane, fit_plane_primitive};
use crate::{Error, Primitive};

/// Point spacing of the synthetic scans (local units).
const SPACING: f64 = 0.01;
/// Occupancy cell handed to the outline: three point spacings.
const CELL: f64 = 3.0 * SPACING;

fn plane(shape: &Shape) -> &PlaneShape {
    match shape {
        Shape::Plane(p) => p,
        _ => panic!("not a plane"),
    }
}

/// Points on a grid of pitch [`SPACING`] over `[-half, half]²` where `inside`, each
/// jittered uniformly by up to ±0.3 of the pitch per axis, then rotated by `angle`
/// (radians) about the origin.
fn scan(half: f64, angle: f64, seed: u64, inside: impl Fn(f64, f64) -> bool) -> Vec<Point2<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = (2.0 * half / SPACING).round() as i64;
    let (c, s) = (angle.cos(), angle.sin());
    let mut out = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let x = -half + (i as f64 + 0.5) * SPACING;
            let y = -half + (j as f64 + 0.5) * SPACING;
            if !inside(x, y) {
                continue;
            }
            let jx = x + rng.random_range(-0.3..0.3) * SPACING;
            let jy = y + rng.random_range(-0.3..0.3) * SPACING;
            out.push(Point2::new(c * jx - s * jy, s * jx + c * jy));
        }
    }
    out
}

fn rectangle(x: f64, y: f64) -> bool {
    x.abs() <= 1.0 && y.abs() <= 0.6
}
fn l_shape(x: f64, y: f64) -> bool {
    !(x > 0.1 && y > 0.2)
}
fn holed(x: f64, y: f64) -> bool {
    rectangle(x, y) && !(x.abs() < 0.3 && y.abs() < 0.2)
}

/// What an outline traced from points is measured by.
struct Outcome {
    area_error: f64,
    outline_vertices: usize,
    holes: usize,
    /// Farthest point outside the polygon (local units).
    worst_outside: f64,
    /// Farthest outline vertex from its nearest point (local units).
    worst_overhang: f64,
}

fn measure(shape: &PlaneShape, points: &[Point2<f64>], true_area: f64) -> Outcome {
    let worst_outside = points
        .iter()
        .map(|p| plane_distance_2d(shape, p.x, p.y))
        .fold(0.0, f64::max);
    let worst_overhang = std::iter::once(shape.outline())
        .chain(shape.holes().iter().map(Vec::as_slice))
        .flatten()
        .map(|v| {
            points
                .iter()
                .map(|p| (p - v).norm())
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max);
    Outcome {
        area_error: shape.area() / true_area - 1.0,
        outline_vertices: shape.outline().len(),
        holes: shape.holes().len(),
        worst_outside,
        worst_overhang,
    }
}

fn check_outline(
    what: &str,
    shape: &PlaneShape,
    points: &[Point2<f64>],
    area: f64,
    max_vertices: usize,
    holes: usize,
) {
    let m = measure(shape, points, area);
    eprintln!(
        "{what}: outline {:?}",
        shape
            .outline()
            .iter()
            .map(|v| (v.x, v.y))
            .collect::<Vec<_>>()
    );
    eprintln!(
        "{what}: area error {:+.2} %, {} outline vertices, {} holes, worst point outside {:.4}, worst vertex overhang {:.4} (cell {CELL})",
        100.0 * m.area_error,
        m.outline_vertices,
        m.holes,
        m.worst_outside,
        m.worst_overhang
    );
    assert!(
        m.area_error.abs() < 0.03,
        "{what}: area off by {:.2} %",
        100.0 * m.area_error
    );
    assert!(
        m.outline_vertices <= max_vertices,
        "{what}: {} vertices",
        m.outline_vertices
    );
    assert_eq!(m.holes, holes, "{what}: holes");
    assert!(
        m.worst_outside <= CELL,
        "{what}: a point {} outside",
        m.worst_outside
    );
    assert!(
        m.worst_overhang <= CELL,
        "{what}: outline {} beyond the points",
        m.worst_overhang
    );
    let mesh_area = shape.mesh().area();
    assert!(
        (mesh_area - shape.area()).abs() <= 1e-9 * shape.area(),
        "{what}: mesh area {mesh_area}"
    );
}

#[test]
fn outline_of_a_rectangle_is_a_rectangle() {
    let points = scan(1.1, 0.0, 1, rectangle);
    let shape = PlaneShape::from_points(&points, CELL).unwrap();
    check_outline("rectangle", &shape, &points, 2.4, 6, 0);
}

#[test]
fn outline_of_an_l_is_an_l() {
    let points = scan(1.0, 0.0, 2, l_shape);
    let shape = PlaneShape::from_points(&points, CELL).unwrap();
    check_outline("L", &shape, &points, 4.0 - 0.9 * 0.8, 9, 0);
    // The notch is not filled: its centre is well outside.
    assert!(plane_distance_2d(&shape, 0.55, 0.6) > 0.3);
}

#[test]
fn outline_keeps_a_hole() {
    let points = scan(1.1, 0.0, 3, holed);
    let shape = PlaneShape::from_points(&points, CELL).unwrap();
    check_outline("holed", &shape, &points, 2.4 - 0.6 * 0.4, 6, 1);
    assert!(!shape.contains(0.0, 0.0) && shape.contains(0.6, 0.0));
    assert!(shape.holes()[0].len() <= 6, "{:?}", shape.holes());
}

#[test]
fn outline_of_a_rectangle_turned_37_degrees_in_its_own_coordinates() {
    // No re-alignment here (`from_points` keeps the points' frame): the grid's staircase
    // along the tilted edges is simplified away to within half a cell.
    let points = scan(1.3, 37f64.to_radians(), 4, rectangle);
    let shape = PlaneShape::from_points(&points, CELL).unwrap();
    check_outline("rectangle at 37° (own frame)", &shape, &points, 2.4, 16, 0);
}

#[test]
fn outline_of_a_disk_follows_the_rim_with_few_vertices() {
    let points = scan(0.9, 0.0, 11, |x, y| x.hypot(y) <= 0.8);
    let shape = PlaneShape::from_points(&points, CELL).unwrap();
    check_outline("disk", &shape, &points, std::f64::consts::PI * 0.64, 40, 0);
    // Every vertex near the rim.
    let worst = shape
        .outline()
        .iter()
        .map(|v| (v.coords.norm() - 0.8).abs())
        .fold(0.0, f64::max);
    assert!(worst < CELL / 2.0, "vertex {worst} off the rim");
}

#[test]
fn small_components_and_holes_are_cleaned_up() {
    let mut points = scan(1.1, 0.0, 5, |x, y| {
        rectangle(x, y) && (x - 0.5).hypot(y) > 0.012
    });
    // A stray pair of points far away.
    points.extend([Point2::new(3.0, 3.0), Point2::new(3.001, 3.0)]);
    let parts = PlaneShape::parts_from_points(&points, CELL).unwrap();
    assert_eq!(parts.len(), 1, "the stray points make no part");
    assert!(parts[0].holes().is_empty(), "a one-point gap is no hole");
    // Two separate rectangles are two parts, largest first.
    let mut two = scan(1.1, 0.0, 6, |x, y| rectangle(x, y) && x < -0.2);
    two.extend(scan(1.1, 0.0, 7, |x, y| rectangle(x, y) && x > 0.4));
    let parts = PlaneShape::parts_from_points(&two, CELL).unwrap();
    assert_eq!(parts.len(), 2);
    assert!(parts[0].area() > parts[1].area());
    assert!(
        (parts[0].area() / (0.8 * 1.2) - 1.0).abs() < 0.04,
        "{}",
        parts[0].area()
    );
}

#[test]
fn a_cell_finer_than_the_points_is_coarsened_until_the_outline_is_simple() {
    // Uniform random points, mean spacing 0.01, traced at a cell of 0.006: the occupancy
    // is speckled with holes until the cell is doubled.
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let points: Vec<Point2<f64>> = (0..40_000)
        .map(|_| Point2::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)))
        .collect();
    let shape = PlaneShape::from_points(&points, 0.006).unwrap();
    eprintln!(
        "speckled: area {:.4}, {} vertices, {} holes",
        shape.area(),
        shape.vertex_count(),
        shape.holes().len()
    );
    assert!(shape.vertex_count() <= super::outline::MAX_CHECKED_VERTICES);
    assert!((shape.area() / 4.0 - 1.0).abs() < 0.05, "{}", shape.area());
}

#[test]
fn outline_inputs_are_checked() {
    let ok = [Point2::new(0.0, 0.0)];
    assert!(matches!(
        PlaneShape::from_points(&[], CELL),
        Err(Error::EmptyCloud)
    ));
    let nan = [Point2::new(0.0, f64::NAN)];
    assert!(matches!(
        PlaneShape::from_points(&nan, CELL),
        Err(Error::NonFinite { index: 0, .. })
    ));
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(
            matches!(
                PlaneShape::from_points(&ok, bad),
                Err(Error::OutOfRange { .. })
            ),
            "{bad}"
        );
    }
    // Scattered points far apart at a fine cell: nothing connected enough.
    let sparse: Vec<_> = (0..20)
        .map(|k| Point2::new(k as f64, (k * k) as f64))
        .collect();
    assert!(PlaneShape::from_points(&sparse, 0.01).is_err());
    // An absurdly fine cell is coarsened to the grid cap, not allocated: this returns at
    // once (here with no part, as the points are sparse at the coarsened cell).
    let square = scan(0.2, 0.0, 8, |_, _| true);
    assert!(matches!(
        PlaneShape::from_points(&square, 1e-9),
        Err(Error::InvalidArgument(_))
    ));
}

/// The truth of a synthetic 3-D plane: a 2 × 1.2 rectangle with a 0.6 × 0.4 hole, long
/// side along `x_axis`, normal `normal`, centred at `centre`.
struct Truth {
    rotation: UnitQuaternion<f64>,
    centre: Vector3<f64>,
}

impl Truth {
    fn new() -> Truth {
        let tilt = UnitQuaternion::from_euler_angles(0.3, -0.5, 0.2);
        let spin = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 37f64.to_radians());
        Truth {
            rotation: tilt * spin,
            centre: Vector3::new(3.0, -1.0, 2.0),
        }
    }
    fn points(&self, noise: f64) -> Vec<Point3<f64>> {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        scan(1.1, 0.0, 10, holed)
            .iter()
            .map(|p| {
                let z = noise * (rng.random::<f64>() - 0.5) * 12f64.sqrt();
                Point3::from(self.rotation * Vector3::new(p.x, p.y, z) + self.centre)
            })
            .collect()
    }
}

#[test]
fn fit_plane_recovers_a_tilted_turned_holed_rectangle() {
    let truth = Truth::new();
    let noise = 0.002;
    let points = truth.points(noise);
    let prim = fit_plane_primitive(&points, None, CELL).unwrap();
    let shape = plane(&prim.shape);
    let (n_true, x_true) = (truth.rotation * Vector3::z(), truth.rotation * Vector3::x());
    let (n, x) = (
        prim.pose.rotation * Vector3::z(),
        prim.pose.rotation * Vector3::x(),
    );
    let normal_deg = n.dot(&n_true).abs().min(1.0).acos().to_degrees();
    let axis_deg = x.dot(&x_true).abs().min(1.0).acos().to_degrees();
    let local: Vec<Point2<f64>> = points
        .iter()
        .map(|p| {
            let q = prim.pose.to_local(p);
            Point2::new(q.x, q.y)
        })
        .collect();
    let mean_distance = points.iter().map(|p| prim.distance(p)).sum::<f64>() / points.len() as f64;
    eprintln!(
        "3-D fit: normal off by {normal_deg:.3}°, x axis off by {axis_deg:.3}°, mean point distance {mean_distance:.5} (noise σ {noise})"
    );
    assert!(normal_deg < 0.2, "normal off by {normal_deg}°");
    assert!(axis_deg < 1.0, "in-plane axis off by {axis_deg}°");
    assert!(mean_distance < noise, "{mean_distance}");
    assert!((prim.pose.translation - truth.centre).norm() < 0.01);
    check_outline(
        "3-D holed rectangle at 37°",
        shape,
        &local,
        2.4 - 0.24,
        6,
        1,
    );
    // A given normal is used as given (sign included).
    let hint = -(n_true + Vector3::new(0.0, 0.0, 1e-3)).normalize();
    let (pose, _) = fit_plane(&points, Some(hint), CELL).unwrap();
    assert!((pose.rotation * Vector3::z() - hint).norm() < 1e-9);
    assert!(fit_plane(&points, Some(Vector3::zeros()), CELL).is_err());
}

#[test]
fn plane_area_and_samples_match_the_polygon() {
    let shape = l_plane();
    let p = plane(&shape);
    assert!((p.area() - 3.12).abs() < 1e-12, "{}", p.area());
    assert!(
        (p.mesh().area() - 3.12).abs() < 1e-12,
        "{}",
        p.mesh().area()
    );
    let spacing = 0.01;
    let samples = shape.sample_surface(spacing);
    let sampled_area = samples.len() as f64 * spacing * spacing;
    assert!((sampled_area / 3.12 - 1.0).abs() < 0.005, "{sampled_area}");
    assert!(samples.iter().all(|s| s.z == 0.0 && p.contains(s.x, s.y)));
    assert!(
        samples
            .iter()
            .all(|s| plane_distance_2d(p, s.x, s.y) == 0.0)
    );
    // Halves: x < 0 holds 2 − 0.16 of the area, x > 0 holds 2 − 0.72; y < 0 holds 2 −
    // 0.16, y > 0 holds 2 − 0.72 as well.
    for (axis, expected_low) in [(0, 1.84 / 3.12), (1, 1.84 / 3.12)] {
        let low = samples.iter().filter(|s| s[axis] < 0.0).count() as f64 / samples.len() as f64;
        assert!(
            (low / expected_low - 1.0).abs() < 0.01,
            "axis {axis}: {low} vs {expected_low}"
        );
    }
}

/// A concave star with edges at many angles (area by the shoelace formula).
fn star() -> PlaneShape {
    let ring: Vec<Point2<f64>> = (0..14)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 14.0 + 0.1;
            let r = if k % 2 == 0 { 1.0 } else { 0.45 };
            Point2::new(r * a.cos() + 0.2, r * a.sin() - 0.1)
        })
        .collect();
    PlaneShape::new(ring, Vec::new()).unwrap()
}

#[test]
fn star_samples_closest_points_and_mesh_agree_with_brute_force() {
    let p = star();
    let shoelace: f64 = (0..p.outline().len())
        .map(|i| {
            let (a, b) = (p.outline()[i], p.outline()[(i + 1) % p.outline().len()]);
            (a.x * b.y - b.x * a.y) / 2.0
        })
        .sum();
    assert!(
        (p.area() - shoelace).abs() < 1e-12 && shoelace > 0.0,
        "counter-clockwise outline"
    );
    assert!((p.mesh().area() - p.area()).abs() < 1e-12);
    let shape = Shape::Plane(p.clone());
    let dense_spacing = 0.005;
    let dense = shape.sample_surface(dense_spacing);
    let sampled_area = dense.len() as f64 * dense_spacing * dense_spacing;
    assert!(
        (sampled_area / p.area() - 1.0).abs() < 0.01,
        "{sampled_area} vs {}",
        p.area()
    );
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    for _ in 0..200 {
        let q = Point3::new(
            rng.random_range(-1.5..1.5),
            rng.random_range(-1.5..1.5),
            rng.random_range(-0.5..0.5),
        );
        let c = shape.closest_point(&q);
        let exact = (q - c).norm();
        let in_plane = plane_distance_2d(&p, q.x, q.y);
        assert!(
            (exact - q.z.hypot(in_plane)).abs() < 1e-12,
            "{q}: {exact} vs geo {in_plane}"
        );
        let brute = dense
            .iter()
            .map(|s| (q - s).norm())
            .fold(f64::INFINITY, f64::min);
        // Grid samples reach into the star's sharp tips only to within a few spacings.
        assert!(
            brute >= exact - 1e-12 && brute <= exact + 4.0 * dense_spacing,
            "{q}: {brute} vs {exact}"
        );
    }
}

#[test]
fn rays_hit_the_material_and_pass_through_holes() {
    let shape = l_plane();
    let down = Vector3::new(0.0, 0.0, -2.0);
    let hit = |o: [f64; 3], d: &Vector3<f64>| shape.ray_intersect(&Point3::from(o), d);
    assert_eq!(hit([0.5, -0.5, 2.0], &down), Some(1.0)); // t in units of d
    assert_eq!(hit([-0.5, -0.5, 2.0], &down), None); // through the hole
    assert_eq!(hit([0.5, 0.6, 2.0], &down), None); // through the notch
    assert_eq!(hit([0.5, -0.5, -2.0], &down), None); // pointing away
    // In the plane: entering at the outline, leaving the hole, starting inside.
    assert_eq!(hit([-3.0, 0.0, 0.0], &Vector3::x()), Some(2.0));
    let from_hole = hit([-0.5, -0.5, 0.0], &Vector3::x()).unwrap();
    assert!((from_hole - 0.2).abs() < 1e-12, "{from_hole}");
    assert_eq!(hit([0.5, -0.5, 0.0], &Vector3::y()), Some(0.0));
    assert_eq!(hit([0.5, 0.6, 0.0], &Vector3::y()), None); // in the notch, away from it
    // Oblique, through a rotated placement: depth in scene units.
    let pose = crate::Pose::new(
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2),
        Vector3::new(5.0, 0.0, 0.0),
    );
    let prim = Primitive::new(shape.clone(), pose);
    let h = prim
        .first_hit(&Point3::new(0.0, 0.5, 0.0), &Vector3::x())
        .unwrap();
    assert!((h.depth - 5.0).abs() < 1e-12 && (h.normal + Vector3::x()).norm() < 1e-12);
}

#[test]
fn planes_reject_broken_rings() {
    let p = |x: f64, y: f64| Point2::new(x, y);
    let square = vec![p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)];
    let bowtie = vec![p(0.0, 0.0), p(1.0, 1.0), p(1.0, 0.0), p(0.0, 1.0)];
    let outside = vec![p(2.0, 2.0), p(3.0, 2.0), p(3.0, 3.0)];
    assert!(PlaneShape::new(bowtie, Vec::new()).is_err());
    assert!(PlaneShape::new(square.clone(), vec![outside]).is_err());
    assert!(PlaneShape::new(square[..2].to_vec(), Vec::new()).is_err());
    assert!(PlaneShape::new(vec![p(0.0, 0.0), p(1.0, 0.0), p(2.0, 0.0)], Vec::new()).is_err());
    let nan = vec![p(0.0, 0.0), p(f64::NAN, 0.0), p(1.0, 1.0)];
    assert!(matches!(
        PlaneShape::new(nan, Vec::new()),
        Err(Error::NonFinite { index: 1, .. })
    ));
    // A closed ring (first vertex repeated) and a clockwise one are accepted, stored open
    // and counter-clockwise.
    let mut closed: Vec<_> = square.iter().rev().copied().collect();
    closed.push(closed[0]);
    let shape = PlaneShape::new(closed, Vec::new()).unwrap();
    assert_eq!(shape.outline().len(), 4);
    assert!((shape.area() - 1.0).abs() < 1e-15);
    let turn = |r: &[Point2<f64>]| {
        let (a, b, c) = (r[0], r[1], r[2]);
        let (u, v): (Vector2<f64>, Vector2<f64>) = (b - a, c - b);
        u.x * v.y - u.y * v.x
    };
    assert!(turn(shape.outline()) > 0.0);
}

#[test]
fn plane_primitives_export_a_mesh_and_keep_their_own_templates() {
    let pose = crate::Pose {
        rotation: UnitQuaternion::from_euler_angles(0.2, 0.4, -1.0),
        translation: Vector3::new(1.0, 2.0, 3.0),
        scale: 1.5,
    };
    let prim = Primitive::new(l_plane(), pose);
    let (mesh, owner) = crate::fit::primitives_mesh(std::slice::from_ref(&prim));
    assert!((mesh.area() - 3.12 * 2.25).abs() < 1e-9, "{}", mesh.area());
    assert_eq!(owner.len(), mesh.faces.len());
    assert!(mesh.vertices.iter().all(|v| prim.distance(v) < 1e-12));
    // Two planes of equal area but different outlines are not one template.
    let p = |x: f64, y: f64| Point2::new(x, y);
    let wide = PlaneShape::new(
        vec![p(0.0, 0.0), p(2.0, 0.0), p(2.0, 0.5), p(0.0, 0.5)],
        vec![],
    );
    let square = PlaneShape::new(
        vec![p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)],
        vec![],
    );
    let planes = [wide.unwrap(), square.unwrap()]
        .map(|s| Primitive::new(Shape::Plane(s), crate::Pose::identity()));
    let set = crate::lattice::CandidateSet::from_primitives(&planes, 0.05).unwrap();
    assert_eq!(set.templates.len(), 2);
    let again = crate::lattice::CandidateSet::from_primitives(
        &[planes[0].clone(), planes[0].clone()],
        0.05,
    );
    assert_eq!(again.unwrap().templates.len(), 1);
}

/// An axis-aligned square ring `[x0, x0 + side] × [y0, y0 + side]`.
fn square_ring(x0: f64, y0: f64, side: f64) -> Vec<Point2<f64>> {
    [(0.0, 0.0), (side, 0.0), (side, side), (0.0, side)]
        .iter()
        .map(|(dx, dy)| Point2::new(x0 + dx, y0 + dy))
        .collect()
}

#[test]
fn a_plane_of_two_parts_is_one_surface_with_both_areas() {
    // A 2 × 2 square with a 0.5 × 0.5 hole, and beside it (a gap of 1) a 1 × 1 square.
    let big = (
        square_ring(0.0, 0.0, 2.0),
        vec![square_ring(0.75, 0.75, 0.5)],
    );
    let small = (square_ring(3.0, 0.0, 1.0), Vec::new());
    let shape = PlaneShape::from_parts(vec![small, big]).expect("two disjoint parts");
    assert_eq!(shape.parts().len(), 2);
    assert!((shape.area() - (4.0 - 0.25 + 1.0)).abs() < 1e-12);
    assert!((shape.mesh().area() - shape.area()).abs() < 1e-9);
    // Largest part first: outline() and holes() are the big square's.
    assert_eq!(shape.holes().len(), 1);
    for (x, y, inside) in [
        (0.1, 0.1, true),
        (1.0, 1.0, false), // the hole
        (2.5, 0.5, false), // the gap
        (3.5, 0.5, true),  // the second part
        (4.5, 0.5, false),
    ] {
        assert_eq!(shape.contains(x, y), inside, "({x}, {y})");
    }
    // The gap's middle is closest to the big part's edge x = 2 (0.5 away, as to x = 3).
    let c = shape.closest_point(&Point3::new(2.4, 0.5, 0.3));
    assert!((c - Point3::new(2.0, 0.5, 0.0)).norm() < 1e-12, "{c}");
    // Samples of both parts, area-uniform.
    let samples = shape.sample(0.05);
    let right = samples.iter().filter(|p| p.x > 2.5).count() as f64;
    let share = right / samples.len() as f64;
    assert!((share - 1.0 / 4.75).abs() < 0.02, "{share}");
    // JSON: the largest part as outline/holes, the other under more_parts, read back.
    let primitive = Primitive::new(Shape::Plane(shape.clone()), crate::Pose::identity());
    let json = primitive.to_json();
    assert_eq!(json["more_parts"].as_array().map(Vec::len), Some(1));
    let back = Primitive::from_json(&json, &|_| unreachable!()).expect("reads back");
    assert_eq!(plane(&back.shape).parts(), shape.parts());
    // A plane of one part writes no more_parts.
    let one = Primitive::new(
        Shape::Plane(PlaneShape::new(square_ring(0.0, 0.0, 1.0), Vec::new()).unwrap()),
        crate::Pose::identity(),
    );
    assert!(one.to_json().get("more_parts").is_none());
}

#[test]
fn overlapping_parts_and_broken_more_parts_are_refused() {
    let a = (square_ring(0.0, 0.0, 2.0), Vec::new());
    let b = (square_ring(1.0, 1.0, 2.0), Vec::new());
    assert!(matches!(
        PlaneShape::from_parts(vec![a.clone(), b]),
        Err(Error::InvalidArgument(_))
    ));
    assert!(PlaneShape::from_parts(Vec::new()).is_err());
    let outline = serde_json::json!([[0, 0], [1, 0], [1, 1]]);
    for (more, field) in [
        (serde_json::json!(3), "more_parts"),
        (serde_json::json!([{"holes": []}]), "more_parts[0].outline"),
        (
            serde_json::json!([{"outline": [[5, 0], [6, 0], [6, 1]], "holes": 1}]),
            "more_parts[0].holes",
        ),
    ] {
        let err = PlaneShape::from_rings_json(Some(&outline), None, Some(&more)).unwrap_err();
        assert!(err.to_string().contains(field), "{err}");
    }
}

#[test]
fn whole_from_points_keeps_every_part_of_a_scan_cut_in_two() {
    // A rectangle scan with a 0.2-wide band missing across it (an occlusion shadow).
    let points = scan(0.6, 0.0, 7, |x, y| {
        rectangle(x, y) && !(-0.1..0.1).contains(&x)
    });
    let whole = PlaneShape::whole_from_points(&points, CELL).expect("outline");
    let parts = PlaneShape::parts_from_points(&points, CELL).expect("outline");
    assert_eq!(whole.parts().len(), 2);
    assert_eq!(parts.len(), 2);
    let sum: f64 = parts.iter().map(PlaneShape::area).sum();
    assert!((whole.area() - sum).abs() < 1e-9 * sum);
    assert!(!whole.contains(0.0, 0.0));
}
