//! Tests of the atlas geometry. Every check compares against something computed
//! independently: the implicit surface equations, dense samples, brute force over all
//! faces, or sphere tracing along rays. Meshes are built procedurally (no files).

use std::f64::consts::{FRAC_1_SQRT_2, PI};

use nalgebra::{Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::bvh::closest_on_triangle;
use super::numeric::{apportion, poly_roots_in};
use super::{MeshShape, PlaneShape, Shape, ShapeKind, TriMesh};

// ---------------------------------------------------------------------------------------
// Fixtures
// ---------------------------------------------------------------------------------------

/// A box `[-a, a] × [-b, b] × [-c, c]`, each face a grid with its own resolution so that
/// triangle sizes differ a lot between faces. Outward, counter-clockwise faces.
fn box_mesh(a: f64, b: f64, c: f64) -> TriMesh {
    // (corner, first edge, second edge, cells along the first, cells along the second)
    type Side = ([f64; 3], [f64; 3], [f64; 3], u32, u32);
    let sides: [Side; 6] = [
        ([a, -b, -c], [0.0, 2.0 * b, 0.0], [0.0, 0.0, 2.0 * c], 1, 1),
        ([-a, -b, -c], [0.0, 0.0, 2.0 * c], [0.0, 2.0 * b, 0.0], 3, 2),
        ([-a, b, -c], [0.0, 0.0, 2.0 * c], [2.0 * a, 0.0, 0.0], 1, 5),
        ([-a, -b, -c], [2.0 * a, 0.0, 0.0], [0.0, 0.0, 2.0 * c], 7, 1),
        ([-a, -b, c], [2.0 * a, 0.0, 0.0], [0.0, 2.0 * b, 0.0], 2, 2),
        ([-a, -b, -c], [0.0, 2.0 * b, 0.0], [2.0 * a, 0.0, 0.0], 4, 9),
    ];
    let mut mesh = TriMesh::default();
    for (origin, u, v, nu, nv) in sides {
        let (origin, u, v) = (Point3::from(origin), Vector3::from(u), Vector3::from(v));
        let mut side = TriMesh::default();
        for j in 0..=nv {
            for i in 0..=nu {
                side.vertices
                    .push(origin + u * (i as f64 / nu as f64) + v * (j as f64 / nv as f64));
            }
        }
        let at = |i: u32, j: u32| j * (nu + 1) + i;
        for j in 0..nv {
            for i in 0..nu {
                side.faces.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                side.faces.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        mesh.append(&side);
    }
    mesh
}

/// An icosphere of the given radius: an icosahedron whose faces are split in four
/// `levels` times, with vertices pushed onto the sphere (20 · 4^levels faces).
fn icosphere(radius: f64, levels: u32) -> TriMesh {
    let mut mesh = TriMesh::unit_icosphere(levels);
    mesh.vertices
        .iter_mut()
        .for_each(|v| *v = Point3::from(v.coords * radius));
    mesh
}

/// An L-shaped plane with a square hole: non-convex, axis-aligned edges, area 3.12.
pub(super) fn l_plane() -> Shape {
    let p = |x: f64, y: f64| nalgebra::Point2::new(x, y);
    let outline = vec![
        p(-1.0, -1.0),
        p(1.0, -1.0),
        p(1.0, 0.2),
        p(0.1, 0.2),
        p(0.1, 1.0),
        p(-1.0, 1.0),
    ];
    let hole = vec![p(-0.7, -0.7), p(-0.7, -0.3), p(-0.3, -0.3), p(-0.3, -0.7)];
    Shape::Plane(PlaneShape::new(outline, vec![hole]).expect("valid L"))
}

fn box_shape() -> Shape {
    Shape::from_mesh("procedural:box", box_mesh(1.0, 0.5, 0.25)).expect("valid box")
}

/// One shape of each type, at sizes that make the types' quirks visible (a fat elbow, …).
fn all_shapes() -> Vec<Shape> {
    let shapes = vec![
        Shape::Disk { diameter: 2.0 },
        Shape::Square { side: 1.5 },
        Shape::Cylinder {
            length: 2.0,
            radius: 0.5,
        },
        Shape::Elbow {
            bend: 1.0,
            radius: 0.4,
        },
        Shape::Sphere { diameter: 2.0 },
        box_shape(),
        l_plane(),
    ];
    let kinds: Vec<ShapeKind> = shapes.iter().map(Shape::kind).collect();
    assert_eq!(kinds, ShapeKind::ALL);
    shapes
        .iter()
        .for_each(|s| s.validate().expect("fixture is valid"));
    shapes
}

fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

fn random_point(rng: &mut ChaCha8Rng, half: f64) -> Point3<f64> {
    Point3::new(
        rng.random_range(-half..half),
        rng.random_range(-half..half),
        rng.random_range(-half..half),
    )
}

// ---------------------------------------------------------------------------------------
// Independent surface membership: the implicit equations of each type
// ---------------------------------------------------------------------------------------

/// How far `p` is from satisfying the surface's defining equations (0 on the surface).
/// Written from the conventions table in `atlas/mod.rs`, not from the implementation.
fn residual(shape: &Shape, p: &Point3<f64>) -> f64 {
    let rho = p.x.hypot(p.y);
    match shape {
        Shape::Disk { diameter } => p.z.abs() + (rho - diameter / 2.0).max(0.0),
        Shape::Square { side } => {
            p.z.abs() + (p.x.abs() - side / 2.0).max(0.0) + (p.y.abs() - side / 2.0).max(0.0)
        }
        Shape::Cylinder { length, radius } => {
            (rho - radius).abs() + (p.z.abs() - length / 2.0).max(0.0)
        }
        Shape::Elbow { bend, radius } => {
            ((rho - bend).hypot(p.z) - radius).abs() + (-p.x).max(0.0) + (-p.y).max(0.0)
        }
        Shape::Sphere { diameter } => (p.coords.norm() - diameter / 2.0).abs(),
        Shape::Mesh(m) => mesh_residual(&m.mesh, p),
        Shape::Plane(plane) => p.z.abs() + plane_distance_2d(plane, p.x, p.y),
    }
}

/// In-plane distance from `(x, y)` to a plane's polygon (0 inside), by `geo`.
pub(super) fn plane_distance_2d(plane: &PlaneShape, x: f64, y: f64) -> f64 {
    use geo::{Distance, Euclidean};
    let ring = |r: &[nalgebra::Point2<f64>]| {
        geo::LineString::from(r.iter().map(|v| (v.x, v.y)).collect::<Vec<_>>())
    };
    let polygon = geo::Polygon::new(
        ring(plane.outline()),
        plane.holes().iter().map(|h| ring(h)).collect(),
    );
    Euclidean.distance(&geo::Point::new(x, y), &polygon)
}

/// Distance from `p` to the plane of the nearest face whose triangle contains `p`'s
/// projection (barycentric coordinates ≥ −1e-9); infinity if there is none.
fn mesh_residual(mesh: &TriMesh, p: &Point3<f64>) -> f64 {
    let mut best = f64::INFINITY;
    for f in &mesh.faces {
        let [a, b, c] = f.map(|i| mesh.vertices[i as usize]);
        let n = (b - a).cross(&(c - a));
        let area2 = n.norm_squared();
        if area2 == 0.0 {
            continue;
        }
        let (l1, l2) = (
            (c - b).cross(&(p - b)).dot(&n) / area2,
            (a - c).cross(&(p - c)).dot(&n) / area2,
        );
        let l3 = 1.0 - l1 - l2;
        if l1 >= -1e-9 && l2 >= -1e-9 && l3 >= -1e-9 {
            best = best.min((p - a).dot(&n).abs() / area2.sqrt());
        }
    }
    best
}

/// Brute-force distance to a mesh: the point-triangle distance to every face.
fn mesh_brute_distance(mesh: &TriMesh, p: &Point3<f64>) -> f64 {
    mesh.faces
        .iter()
        .map(|f| (closest_on_triangle(p, &f.map(|i| mesh.vertices[i as usize])) - p).norm())
        .fold(f64::INFINITY, f64::min)
}

// ---------------------------------------------------------------------------------------
// (a) samples on the surface, (b) counts and area-uniformity, (f) determinism
// ---------------------------------------------------------------------------------------

#[test]
fn samples_lie_on_the_surface() {
    for shape in all_shapes() {
        for spacing in [0.5, 0.05] {
            let samples = shape.sample_surface(spacing);
            let worst = samples
                .iter()
                .map(|p| residual(&shape, p))
                .fold(0.0, f64::max);
            assert!(
                worst < 1e-9,
                "{}: sample off the surface by {worst}",
                shape.kind()
            );
            let worst = samples
                .iter()
                .map(|p| shape.distance(p))
                .fold(0.0, f64::max);
            assert!(
                worst < 1e-9,
                "{}: distance() of a sample is {worst}",
                shape.kind()
            );
        }
    }
}

#[test]
fn sample_count_is_area_over_spacing_squared() {
    for shape in all_shapes() {
        for spacing in [0.1, 0.04, 0.013] {
            let expected = shape.area() / (spacing * spacing);
            let n = shape.sample_surface(spacing).len() as f64;
            assert!(
                (n - expected).abs() <= 0.15 * expected,
                "{} at spacing {spacing}: {n} samples, expected about {expected:.0}",
                shape.kind()
            );
        }
    }
}

#[test]
fn at_least_one_sample_even_for_huge_spacing() {
    for shape in all_shapes() {
        let samples = shape.sample_surface(1e6);
        assert!(!samples.is_empty(), "{}", shape.kind());
        assert!(residual(&shape, &samples[0]) < 1e-9, "{}", shape.kind());
    }
}

#[test]
fn sampling_is_deterministic() {
    for shape in all_shapes() {
        let (a, b) = (shape.sample_surface(0.03), shape.sample_surface(0.03));
        assert_eq!(a, b, "{}", shape.kind());
        let cloned = shape.clone().sample_surface(0.03);
        assert_eq!(a, cloned, "{}", shape.kind());
    }
}

/// Asserts that the counts of samples in regions are proportional to the regions' areas
/// (relative error of each share at most `tol`).
fn assert_proportional(what: &str, counts: &[usize], areas: &[f64], tol: f64) {
    let (n, total_area) = (
        counts.iter().sum::<usize>() as f64,
        areas.iter().sum::<f64>(),
    );
    for (k, (&c, &a)) in counts.iter().zip(areas).enumerate() {
        let (share, expected) = (c as f64 / n, a / total_area);
        assert!(
            (share - expected).abs() <= tol * expected,
            "{what}: region {k} holds {share:.4} of the samples but {expected:.4} of the area ({counts:?})"
        );
    }
}

/// Counts samples of `shape` at `spacing` per region (`region` returns the region index).
fn region_counts(
    shape: &Shape,
    spacing: f64,
    regions: usize,
    region: impl Fn(&Point3<f64>) -> usize,
) -> Vec<usize> {
    let mut counts = vec![0; regions];
    shape
        .sample_surface(spacing)
        .iter()
        .for_each(|p| counts[region(p)] += 1);
    counts
}

#[test]
fn disk_samples_are_area_uniform() {
    // The disk of radius R/√2 and the ring outside it have equal areas; so do the halves.
    let shape = Shape::Disk { diameter: 2.0 };
    let rings = region_counts(&shape, 0.02, 2, |p| {
        usize::from(p.x.hypot(p.y) > FRAC_1_SQRT_2)
    });
    assert_proportional("disk inner/outer", &rings, &[1.0, 1.0], 0.02);
    let halves = region_counts(&shape, 0.02, 2, |p| usize::from(p.x > 0.0));
    assert_proportional("disk halves", &halves, &[1.0, 1.0], 0.02);
}

#[test]
fn square_samples_are_area_uniform() {
    // The centred square of side s/√2 holds half the area.
    let shape = Shape::Square { side: 1.5 };
    let inner = 0.75 * FRAC_1_SQRT_2;
    let counts = region_counts(&shape, 0.01, 2, |p| {
        usize::from(p.x.abs().max(p.y.abs()) > inner)
    });
    assert_proportional("square inner/outer", &counts, &[1.0, 1.0], 0.03);
}

#[test]
fn cylinder_samples_are_area_uniform() {
    // Quadrants of (upper/lower half) × (x > 0 / x < 0) have equal areas.
    let shape = Shape::Cylinder {
        length: 2.0,
        radius: 0.5,
    };
    let counts = region_counts(&shape, 0.02, 4, |p| {
        usize::from(p.z > 0.0) * 2 + usize::from(p.x > 0.0)
    });
    assert_proportional("cylinder quadrants", &counts, &[1.0; 4], 0.02);
}

#[test]
fn elbow_samples_follow_area_inner_vs_outer() {
    // Pappus: the inner half of the tube (cos φ < 0, i.e. ρ < B) has area
    // (π/2) r (πB − 2r) and the outer half (π/2) r (πB + 2r). A sampler that is uniform
    // in (ψ, φ) would put equal counts in both and fail this.
    let (bend, radius) = (1.0, 0.6);
    let shape = Shape::Elbow { bend, radius };
    let inner_outer = region_counts(&shape, 0.015, 2, |p| usize::from(p.x.hypot(p.y) > bend));
    let areas = [PI * bend - 2.0 * radius, PI * bend + 2.0 * radius];
    assert_proportional("elbow inner/outer", &inner_outer, &areas, 0.02);
    // The first and second halves of the arc are congruent.
    let arc_halves = region_counts(&shape, 0.015, 2, |p| usize::from(p.y > p.x));
    assert_proportional("elbow arc halves", &arc_halves, &[1.0, 1.0], 0.02);
    // Upper and lower halves of the tube are mirror images.
    let up_down = region_counts(&shape, 0.015, 2, |p| usize::from(p.z > 0.0));
    assert_proportional("elbow upper/lower", &up_down, &[1.0, 1.0], 0.02);
}

#[test]
fn sphere_samples_are_area_uniform_in_z_bands() {
    // Archimedes: bands of equal height have equal area.
    let shape = Shape::Sphere { diameter: 2.0 };
    let bands = region_counts(&shape, 0.02, 5, |p| {
        (((p.z + 1.0) / 2.0 * 5.0) as usize).min(4)
    });
    assert_proportional("sphere z bands", &bands, &[1.0; 5], 0.01);
    let halves = region_counts(&shape, 0.02, 2, |p| usize::from(p.x > 0.0));
    assert_proportional("sphere x halves", &halves, &[1.0, 1.0], 0.02);
}

#[test]
fn mesh_samples_follow_face_areas() {
    // The box's six sides have very different triangle sizes; counts must follow area.
    let (a, b, c) = (1.0, 0.5, 0.25);
    let shape = Shape::from_mesh("box", box_mesh(a, b, c)).unwrap();
    let side = |p: &Point3<f64>| {
        let scaled = [p.x / a, p.y / b, p.z / c];
        let axis = (0..3)
            .max_by(|&i, &j| scaled[i].abs().total_cmp(&scaled[j].abs()))
            .unwrap();
        2 * axis + usize::from(scaled[axis] > 0.0)
    };
    let counts = region_counts(&shape, 0.02, 6, side);
    let (yz, xz, xy) = (4.0 * b * c, 4.0 * a * c, 4.0 * a * b);
    assert_proportional("box sides", &counts, &[yz, yz, xz, xz, xy, xy], 0.01);
}

// ---------------------------------------------------------------------------------------
// (c) closest point vs brute force
// ---------------------------------------------------------------------------------------

/// Query points: random ones around the shape plus the awkward ones (axes, centre, rims).
fn query_points(shape: &Shape, seed: u64, n: usize) -> Vec<Point3<f64>> {
    let half = 1.5 * shape.bounding_radius();
    let mut r = rng(seed);
    let mut points: Vec<Point3<f64>> = (0..n).map(|_| random_point(&mut r, half)).collect();
    points.extend([
        Point3::origin(),
        Point3::new(0.0, 0.0, 0.7),
        Point3::new(0.0, 0.0, -3.0),
        Point3::new(-1.0, -1.0, 0.0),
        Point3::new(1.0, -0.5, 0.1),
        Point3::new(-0.5, 1.0, -0.1),
    ]);
    points
}

#[test]
fn closest_point_matches_dense_brute_force() {
    for shape in all_shapes() {
        let dense_spacing = 0.01;
        let dense = shape.sample_surface(dense_spacing);
        for q in query_points(&shape, 7, 150) {
            let c = shape.closest_point(&q);
            let exact = (q - c).norm();
            assert!(
                residual(&shape, &c) < 1e-9,
                "{}: closest point {c} of {q} is off the surface",
                shape.kind()
            );
            assert!(
                (shape.distance(&q) - exact).abs() <= 1e-15 * (1.0 + exact),
                "{}",
                shape.kind()
            );
            let brute = dense
                .iter()
                .map(|s| (q - s).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(
                brute >= exact - 1e-12,
                "{}: a sample at {brute} beats the exact {exact} for {q}",
                shape.kind()
            );
            assert!(
                brute <= exact + dense_spacing,
                "{}: the exact distance {exact} is too small (dense samples say {brute}) for {q}",
                shape.kind()
            );
        }
    }
}

#[test]
fn closest_point_in_known_configurations() {
    let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
    let (length, radius) = (2.0, 0.5);
    let cyl = Shape::Cylinder { length, radius };
    assert!(
        close(cyl.distance(&Point3::new(0.0, 0.0, 0.3)), radius),
        "point on the axis"
    );
    assert!(
        close(
            cyl.distance(&Point3::new(0.0, 0.0, 2.0)),
            (radius * radius + 1.0f64).sqrt()
        ),
        "axis beyond the rim"
    );
    assert!(
        close(cyl.distance(&Point3::new(2.0, 0.0, 1.5)), 1.5f64.hypot(0.5)),
        "off the rim"
    );

    let (bend, r) = (1.0, 0.4);
    let elbow = Shape::Elbow { bend, radius: r };
    for z in [0.0, 0.5, -2.0] {
        let expected = bend.hypot(z) - r; // every tube circle is equally far from the z axis
        assert!(
            close(elbow.distance(&Point3::new(0.0, 0.0, z)), expected),
            "z axis at {z}"
        );
    }
    let on_centre_line = Point3::new(bend * 0.3f64.cos(), bend * 0.3f64.sin(), 0.0);
    assert!(
        close(elbow.distance(&on_centre_line), r),
        "on the centre line"
    );
    // Beyond the ψ = 0 end, straight below the end circle's centre: distance to the rim.
    assert!(
        close(
            elbow.distance(&Point3::new(bend, -1.0, 0.0)),
            1.0f64.hypot(r)
        ),
        "past the start rim"
    );
    // The missing three quarters of the torus are not part of the surface: from the far
    // side (−B − r, 0, 0) the nearest point is the inner point (0, B − r, 0) of the ψ = π/2 rim.
    let far_side = elbow.closest_point(&Point3::new(-bend - r, 0.0, 0.0));
    assert!(
        (far_side - Point3::new(0.0, bend - r, 0.0)).norm() < 1e-12,
        "opposite side: {far_side}"
    );

    let sphere = Shape::Sphere { diameter: 2.0 };
    assert!(
        close(sphere.distance(&Point3::origin()), 1.0),
        "sphere centre"
    );
    let disk = Shape::Disk { diameter: 2.0 };
    assert!(
        close(
            disk.distance(&Point3::new(3.0, 0.0, 4.0)),
            2.0f64.hypot(4.0)
        ),
        "above beyond the rim"
    );
    assert!(
        close(disk.distance(&Point3::new(0.3, -0.2, -0.7)), 0.7),
        "below the disk"
    );
}

#[test]
fn mesh_closest_point_matches_brute_force_over_faces() {
    for (mesh, seed) in [(box_mesh(1.0, 0.5, 0.25), 1), (icosphere(1.3, 3), 2)] {
        let shape = Shape::from_mesh("procedural", mesh.clone()).unwrap();
        for q in query_points(&shape, seed, 500) {
            let exact = shape.distance(&q);
            let brute = mesh_brute_distance(&mesh, &q);
            assert!(
                (exact - brute).abs() <= 1e-12,
                "{q}: index says {exact}, brute force {brute}"
            );
            assert!(mesh_residual(&mesh, &shape.closest_point(&q)) < 1e-9);
        }
    }
}

#[test]
fn closest_on_triangle_matches_dense_sampling() {
    let tri = [
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.2, 0.0),
        Point3::new(0.3, 0.9, 0.4),
    ];
    let n = 400;
    let mut dense = Vec::new();
    for i in 0..=n {
        for j in 0..=(n - i) {
            let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
            dense.push(tri[0] + (tri[1] - tri[0]) * u + (tri[2] - tri[0]) * v);
        }
    }
    let mut r = rng(3);
    for _ in 0..200 {
        let q = random_point(&mut r, 2.0);
        let exact = (closest_on_triangle(&q, &tri) - q).norm();
        let brute = dense
            .iter()
            .map(|s| (q - s).norm())
            .fold(f64::INFINITY, f64::min);
        assert!(
            brute >= exact - 1e-12 && brute <= exact + 2.0 / n as f64,
            "{q}: {exact} vs {brute}"
        );
    }
    // A degenerate (collinear) triangle acts as a segment.
    let flat = [
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(2.0, 0.0, 0.0),
    ];
    let c = closest_on_triangle(&Point3::new(1.5, 1.0, 0.0), &flat);
    assert!((c - Point3::new(1.5, 0.0, 0.0)).norm() < 1e-15);
}

#[test]
fn mesh_index_matches_brute_force_on_a_large_mesh() {
    // Speed of this query is measured in benches/, never asserted here.
    let mesh = icosphere(1.0, 6); // 81 920 faces
    assert_eq!(mesh.faces.len(), 81_920);
    let shape = Shape::from_mesh("icosphere-6", mesh.clone()).unwrap();
    let queries = query_points(&shape, 11, 400);
    for q in queries.iter().step_by(20) {
        assert!((shape.distance(q) - mesh_brute_distance(&mesh, q)).abs() <= 1e-12);
    }
}

// ---------------------------------------------------------------------------------------
// (d) triangulation
// ---------------------------------------------------------------------------------------

/// An outward direction of the surface near `p`, from the type's geometry.
fn outward(shape: &Shape, p: &Point3<f64>) -> Vector3<f64> {
    match shape {
        Shape::Disk { .. } | Shape::Square { .. } | Shape::Plane(_) => Vector3::z(),
        Shape::Cylinder { .. } => Vector3::new(p.x, p.y, 0.0),
        Shape::Elbow { bend, .. } => {
            let rho = p.x.hypot(p.y);
            p.coords - Vector3::new(p.x, p.y, 0.0) * (bend / rho)
        }
        Shape::Sphere { .. } | Shape::Mesh(_) => p.coords,
    }
}

#[test]
fn triangulation_is_close_to_the_surface_and_faces_outward() {
    for shape in all_shapes() {
        let mesh = shape.triangulate();
        let kind = shape.kind();
        let size = shape.bounding_radius();
        assert!(!mesh.faces.is_empty(), "{kind}");
        assert!(
            mesh.faces
                .iter()
                .flatten()
                .all(|&i| (i as usize) < mesh.vertices.len()),
            "{kind}"
        );
        let worst = mesh
            .vertices
            .iter()
            .map(|v| residual(&shape, v))
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "{kind}: vertex off the surface by {worst}");
        for f in &mesh.faces {
            let [a, b, c] = f.map(|i| mesh.vertices[i as usize]);
            let centroid = Point3::from((a.coords + b.coords + c.coords) / 3.0);
            let deviation = shape.distance(&centroid);
            assert!(
                deviation < 0.01 * size,
                "{kind}: face centroid {deviation} off the surface"
            );
            let normal = (b - a).cross(&(c - a));
            assert!(normal.norm() > 0.0, "{kind}: degenerate face");
            assert!(
                normal.dot(&outward(&shape, &centroid)) > 0.0,
                "{kind}: face {f:?} points inward"
            );
        }
        let ratio = mesh.area() / shape.area();
        assert!(
            (ratio - 1.0).abs() < 0.02,
            "{kind}: mesh area is {ratio} of the surface's"
        );
    }
}

#[test]
fn mesh_triangulation_is_the_mesh_itself() {
    let mesh = box_mesh(1.0, 0.5, 0.25);
    let shape = Shape::from_mesh("box", mesh.clone()).unwrap();
    assert_eq!(shape.triangulate(), mesh);
}

// ---------------------------------------------------------------------------------------
// (e) rays
// ---------------------------------------------------------------------------------------

/// What sphere tracing along a ray finds.
enum Trace {
    Hit(f64),
    Miss,
    /// Too many steps (a ray grazing the surface); inconclusive.
    Undecided,
}

/// Brute-force first hit: march along the ray by the exact distance to the surface, a
/// step that can never jump over it, until the distance vanishes or the ray has left the
/// bounding ball for good.
fn sphere_trace(shape: &Shape, o: &Point3<f64>, d: &Vector3<f64>) -> Trace {
    let speed = d.norm();
    let r = shape.bounding_radius();
    let mut t = 0.0;
    for _ in 0..200_000 {
        let p = o + d * t;
        let dist = shape.distance(&p);
        if dist < 1e-12 {
            return Trace::Hit(t);
        }
        let leaving = p.coords.norm() > r && p.coords.dot(d) > 0.0;
        if leaving {
            return Trace::Miss;
        }
        t += dist / speed;
    }
    Trace::Undecided
}

#[test]
fn ray_intersect_agrees_with_sphere_tracing() {
    for shape in all_shapes() {
        let kind = shape.kind();
        let r = shape.bounding_radius();
        let targets = shape.sample_surface(0.05);
        let mut rng = rng(5);
        let (mut hits, mut misses, mut undecided) = (0, 0, 0);
        for k in 0..400 {
            let origin = if k % 4 == 0 {
                random_point(&mut rng, r) // often inside the bounding ball, even inside the surface
            } else {
                Point3::from(
                    Vector3::from([0.0; 3])
                        .map(|_| rng.random_range(-1.0..1.0))
                        .normalize()
                        * 2.5
                        * r,
                )
            };
            let target = targets[rng.random_range(0..targets.len())]
                + Vector3::from([0.0; 3]).map(|_| rng.random_range(-0.2..0.2));
            let dir = (target - origin) * rng.random_range(0.1..10.0);
            let got = shape.ray_intersect(&origin, &dir);
            match (sphere_trace(&shape, &origin, &dir), got) {
                (Trace::Hit(tb), Some(t)) => {
                    hits += 1;
                    let p = origin + dir * t;
                    assert!(
                        shape.distance(&p) < 1e-9,
                        "{kind}: hit point {p} is off the surface"
                    );
                    assert!(
                        ((t - tb) * dir.norm()).abs() < 1e-7,
                        "{kind}: first hit at {t}, tracing says {tb}"
                    );
                }
                (Trace::Miss, None) => misses += 1,
                (Trace::Undecided, _) => undecided += 1,
                (Trace::Hit(tb), None) => {
                    panic!("{kind}: ray {origin} + t {dir} hits at {tb} but got None")
                }
                (Trace::Miss, Some(t)) => {
                    panic!("{kind}: ray {origin} + t {dir} misses but got {t}")
                }
            }
        }
        assert!(
            hits > 100 && misses > 20 && undecided < 5,
            "{kind}: {hits} hits, {misses} misses, {undecided} undecided"
        );
    }
}

#[test]
fn rays_that_miss_return_none() {
    let down = Vector3::new(0.0, 0.0, -1.0);
    let above = Point3::new(0.0, 0.0, 5.0);
    // Down the axis: through the tube, and through the torus' hole.
    assert_eq!(
        Shape::Cylinder {
            length: 2.0,
            radius: 0.5
        }
        .ray_intersect(&above, &down),
        None
    );
    assert_eq!(
        Shape::Elbow {
            bend: 1.0,
            radius: 0.4
        }
        .ray_intersect(&above, &down),
        None
    );
    // Through the three missing quarters of the torus (x = −B, from y = −5 to +5).
    let elbow = Shape::Elbow {
        bend: 1.0,
        radius: 0.4,
    };
    assert_eq!(
        elbow.ray_intersect(&Point3::new(-1.0, -5.0, 0.0), &Vector3::y()),
        None
    );
    // …while the same ray shifted to x = +B enters the full torus at y = −√0.96 (outside
    // the quarter), passes through the open ψ = 0 end and leaves through the outer wall at
    // y = +√0.96, where √(B² + y²) = B + r.
    let t = elbow.ray_intersect(&Point3::new(1.0, -5.0, 0.0), &Vector3::y());
    assert!(
        t.is_some_and(|t| (t - (5.0 + 0.96f64.sqrt())).abs() < 1e-12),
        "{t:?}"
    );
    // Pointing away, and parallel beside.
    for shape in all_shapes() {
        let kind = shape.kind();
        let far = Point3::new(0.0, 0.0, 3.0 * shape.bounding_radius());
        assert_eq!(
            shape.ray_intersect(&far, &Vector3::z()),
            None,
            "{kind}: pointing away"
        );
        assert_eq!(
            shape.ray_intersect(&far, &Vector3::x()),
            None,
            "{kind}: passing above"
        );
    }
    // Parallel to a flat shape, just above it.
    assert_eq!(
        Shape::Disk { diameter: 2.0 }.ray_intersect(&Point3::new(-5.0, 0.0, 1e-9), &Vector3::x()),
        None
    );
    assert_eq!(
        Shape::Square { side: 1.0 }.ray_intersect(&Point3::new(-5.0, 0.0, 1e-9), &Vector3::x()),
        None
    );
}

#[test]
fn ray_intersect_in_known_configurations() {
    let close = |got: Option<f64>, want: f64| got.is_some_and(|t| (t - want).abs() < 1e-12);
    let sphere = Shape::Sphere { diameter: 2.0 };
    assert!(
        close(
            sphere.ray_intersect(&Point3::new(0.0, 0.0, -5.0), &(Vector3::z() * 2.0)),
            2.0
        ),
        "t in units of dir"
    );
    assert!(
        close(sphere.ray_intersect(&Point3::origin(), &Vector3::x()), 1.0),
        "from inside"
    );
    assert!(
        close(
            sphere.ray_intersect(&Point3::new(1.0, 0.0, 0.0), &Vector3::x()),
            0.0
        ),
        "origin on the surface"
    );
    // The elbow entered from below at its centre line: first the lower wall.
    let elbow = Shape::Elbow {
        bend: 1.0,
        radius: 0.4,
    };
    let (c, s) = (0.5f64.cos(), 0.5f64.sin());
    assert!(
        close(
            elbow.ray_intersect(&Point3::new(c, s, -2.0), &Vector3::z()),
            1.6
        ),
        "lower wall"
    );
    // From the start of the centre line along its tangent: inside the tube until the
    // centre line bends away and the ray leaves through the outer wall, √(B² + y²) = B + r.
    let t = elbow.ray_intersect(&Point3::new(1.0, 0.0, 0.0), &Vector3::y());
    assert!(
        close(t, 0.96f64.sqrt()),
        "exit through the outer wall: {t:?}"
    );
    // Disk and square: in-plane rays and oblique ones.
    let disk = Shape::Disk { diameter: 2.0 };
    assert!(
        close(
            disk.ray_intersect(&Point3::new(-3.0, 0.0, 0.0), &Vector3::x()),
            2.0
        ),
        "in the disk's plane"
    );
    assert!(close(
        disk.ray_intersect(&Point3::new(0.5, 0.0, 2.0), &Vector3::new(0.0, 0.0, -4.0)),
        0.5
    ));
    let square = Shape::Square { side: 1.0 };
    assert!(
        close(
            square.ray_intersect(&Point3::new(0.0, -2.0, 0.0), &Vector3::y()),
            1.5
        ),
        "in the square's plane"
    );
    // Cylinder: along the wall, and from inside.
    let cyl = Shape::Cylinder {
        length: 2.0,
        radius: 0.5,
    };
    assert!(
        close(
            cyl.ray_intersect(&Point3::new(0.5, 0.0, -3.0), &Vector3::z()),
            2.0
        ),
        "along the wall"
    );
    assert!(
        close(cyl.ray_intersect(&Point3::origin(), &Vector3::x()), 0.5),
        "from the axis"
    );
    // Zero direction: a hit only on the surface.
    assert_eq!(
        cyl.ray_intersect(&Point3::new(0.5, 0.0, 0.0), &Vector3::zeros()),
        Some(0.0)
    );
    assert_eq!(
        cyl.ray_intersect(&Point3::origin(), &Vector3::zeros()),
        None
    );
}

// ---------------------------------------------------------------------------------------
// Mesh shape construction (procedural meshes only: nothing is read from disk)
// ---------------------------------------------------------------------------------------

#[test]
fn mesh_shape_from_a_procedural_box_needs_no_files() {
    let shape = box_shape();
    let Shape::Mesh(m) = &shape else {
        unreachable!()
    };
    assert_eq!(m.source, "procedural:box");
    assert!((shape.area() - 8.0 * (0.5 + 0.25 + 0.125)).abs() < 1e-12);
    assert_eq!(
        shape.sizes_json(),
        serde_json::json!({ "source": "procedural:box" })
    );
    assert!(format!("{m:?}").contains("faces"));
}

#[test]
fn mesh_shape_new_rejects_broken_meshes() {
    let tri = |vertices: Vec<Point3<f64>>, faces: Vec<[u32; 3]>| {
        MeshShape::new("t", TriMesh { vertices, faces })
    };
    let v = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(0.0, 1.0, 0.0),
    ];
    assert!(tri(v.clone(), vec![[0, 1, 2]]).is_ok());
    assert!(tri(v.clone(), vec![]).is_err(), "no faces");
    assert!(
        tri(v.clone(), vec![[0, 1, 3]]).is_err(),
        "index out of range"
    );
    assert!(tri(v.clone(), vec![[0, 1, 1]]).is_err(), "no area");
    let mut bad = v.clone();
    bad[1].x = f64::NAN;
    assert!(tri(bad, vec![[0, 1, 2]]).is_err(), "non-finite vertex");
    // A zero-area face next to a good one is fine and gets no samples.
    let shape = tri(v, vec![[0, 1, 1], [0, 1, 2]]).unwrap();
    let samples = Shape::Mesh(shape).sample_surface(0.05);
    assert_eq!(samples.len(), 200);
}

// ---------------------------------------------------------------------------------------
// Numeric helpers
// ---------------------------------------------------------------------------------------

#[test]
fn poly_roots_finds_simple_double_and_no_roots() {
    // (t − 1)(t − 2)(t + 3)(t − 0.5) = t⁴ − 0.5t³ − 7t² + 9.5t − 3
    let roots = poly_roots_in(&[-3.0, 9.5, -7.0, -0.5, 1.0], -10.0, 10.0);
    let want = [-3.0, 0.5, 1.0, 2.0];
    assert_eq!(roots.len(), 4, "{roots:?}");
    roots
        .iter()
        .zip(want)
        .for_each(|(r, w)| assert!((r - w).abs() < 1e-12, "{roots:?}"));
    // (t − 1)² (t² + 1) = t⁴ − 2t³ + 2t² − 2t + 1: one double root, no sign change.
    let roots = poly_roots_in(&[1.0, -2.0, 2.0, -2.0, 1.0], -10.0, 10.0);
    assert!(
        roots.len() == 1 && (roots[0] - 1.0).abs() < 1e-7,
        "{roots:?}"
    );
    // t⁴ + 1 has no real roots; the interval restricts roots.
    assert!(poly_roots_in(&[1.0, 0.0, 0.0, 0.0, 1.0], -10.0, 10.0).is_empty());
    assert_eq!(
        poly_roots_in(&[-3.0, 9.5, -7.0, -0.5, 1.0], 0.75, 1.5).len(),
        1
    );
}

#[test]
fn apportion_sums_to_total_and_follows_weights() {
    let parts = apportion(&[1.0, 2.0, 3.0, 0.0], 10);
    assert_eq!(parts.iter().sum::<usize>(), 10);
    assert_eq!(parts, vec![2, 3, 5, 0]);
    assert_eq!(apportion(&[0.0, 0.0], 5), vec![0, 0]);
    assert_eq!(apportion(&[], 5), Vec::<usize>::new());
}

#[test]
fn elbow_quarter_is_where_the_conventions_say() {
    // From (B, 0, 0) with tangent +y to (0, B, 0) with tangent −x.
    let elbow = Shape::Elbow {
        bend: 2.0,
        radius: 0.5,
    };
    for p in [
        Point3::new(2.5, 0.0, 0.0),
        Point3::new(0.0, 2.5, 0.0),
        Point3::new(2.0, 0.0, 0.5),
    ] {
        assert!(elbow.distance(&p) < 1e-15, "{p}");
    }
    assert!(elbow.distance(&Point3::new(-2.5, 0.0, 0.0)) > 1.0);
    assert!(elbow.distance(&Point3::new(0.0, -2.5, 0.0)) > 1.0);
}

#[test]
fn hostile_spacings_never_explode() {
    for shape in [
        Shape::Square { side: 1.0 },
        Shape::Sphere { diameter: 1.0 },
        l_plane(),
    ] {
        for spacing in [0.0, -1.0, f64::NAN, 1e-12] {
            let n = shape.sample_surface(spacing).len();
            assert!(
                n >= 1 && (n as f64) <= 1.2 * Shape::MAX_SAMPLES,
                "{} at {spacing}: {n}",
                shape.kind()
            );
        }
    }
}

/// The closed-form distances equal the distance to the closest point, everywhere
/// (inside the bend's quarter and outside it, on the axes, far and near).
#[test]
fn distance_equals_the_distance_to_the_closest_point() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for shape in all_shapes() {
        let r = shape.bounding_radius();
        let mut probes: Vec<Point3<f64>> = (0..2000)
            .map(|_| {
                Point3::new(
                    rng.random_range(-2.0 * r..2.0 * r),
                    rng.random_range(-2.0 * r..2.0 * r),
                    rng.random_range(-2.0 * r..2.0 * r),
                )
            })
            .collect();
        probes.extend([
            Point3::origin(),
            Point3::new(0.0, 0.3 * r, 0.1),
            Point3::new(0.3 * r, 0.0, -0.1),
            Point3::new(-0.0, 0.2, 0.0),
        ]);
        for p in &probes {
            let via_point = (p - shape.closest_point(p)).norm();
            let d = shape.distance(p);
            assert!(
                (d - via_point).abs() <= 1e-12 * (1.0 + via_point),
                "{shape:?} at {p:?}: {d} vs {via_point}"
            );
        }
    }
}

/// The icosphere is closed, on the unit sphere, outward-facing, with the expected counts.
#[test]
fn unit_icosphere_is_a_closed_outward_unit_sphere() {
    for levels in 0..3u32 {
        let m = TriMesh::unit_icosphere(levels);
        let four = 4usize.pow(levels);
        assert_eq!(m.faces.len(), 20 * four);
        assert_eq!(m.vertices.len(), 12 + 10 * (four - 1));
        assert!(
            m.vertices
                .iter()
                .all(|v| (v.coords.norm() - 1.0).abs() < 1e-12)
        );
        let mut edges = std::collections::HashMap::new();
        for f in &m.faces {
            let [a, b, c] = f.map(|i| m.vertices[i as usize].coords);
            assert!(
                (b - a).cross(&(c - a)).dot(&(a + b + c)) > 0.0,
                "{f:?} faces inward"
            );
            for (p, q) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
                *edges.entry((p, q)).or_insert(0) += 1;
            }
        }
        // Closed and consistently wound: every directed edge once, its reverse once.
        assert!(
            edges
                .iter()
                .all(|(&(p, q), &n)| n == 1 && edges.get(&(q, p)) == Some(&1))
        );
    }
}

#[test]
fn closest_point_from_a_hint_is_the_exact_distance() {
    // A lumpy icosphere (uneven faces), queried along a line as the distance grid does:
    // each query starts from the previous answer, or from a far-off surface point.
    let mut mesh = icosphere(1.0, 3);
    for (k, v) in mesh.vertices.iter_mut().enumerate() {
        *v = Point3::from(v.coords * (1.0 + 0.2 * ((k * 7919) % 13) as f64 / 13.0));
    }
    let shape = MeshShape::new("lumpy", mesh.clone()).unwrap();
    let mut r = rng(5);
    for _ in 0..40 {
        let (a, b) = (random_point(&mut r, 2.0), random_point(&mut r, 2.0));
        let mut previous = shape.closest_point(&a);
        for t in 0..25 {
            let p = a + (b - a) * (t as f64 / 24.0);
            let brute = mesh_brute_distance(&mesh, &p);
            for hint in [previous, mesh.vertices[t * 17 % mesh.vertices.len()]] {
                let c = shape.closest_point_near(&p, &hint);
                assert!((((p - c).norm()) - brute).abs() < 1e-12, "{p}: {c}");
                assert!(mesh_residual(&mesh, &c) < 1e-9);
            }
            previous = shape.closest_point_near(&p, &previous);
        }
    }
}

#[test]
fn closest_point_from_a_face_is_exact_within_reach_and_a_bound_beyond() {
    // The same lumpy icosphere swept along lines, each query starting from the previous
    // answer's face: within `reach` of the surface the exact distance, beyond it a
    // surface point no closer than the exact one (and farther than `reach`).
    let mut mesh = icosphere(1.0, 3);
    for (k, v) in mesh.vertices.iter_mut().enumerate() {
        *v = Point3::from(v.coords * (1.0 + 0.2 * ((k * 7919) % 13) as f64 / 13.0));
    }
    let shape = MeshShape::new("lumpy", mesh.clone()).unwrap();
    let reach = 0.3;
    let mut r = rng(6);
    let (mut exact, mut bounded) = (0, 0);
    for _ in 0..40 {
        let (a, b) = (random_point(&mut r, 2.5), random_point(&mut r, 2.5));
        let mut face = None;
        for t in 0..25 {
            let p = a + (b - a) * (t as f64 / 24.0);
            let brute = mesh_brute_distance(&mesh, &p);
            let (c, f) = shape.closest_point_from_face(&p, face, reach);
            face = Some(f);
            assert!(mesh_residual(&mesh, &c) < 1e-9, "{c} is off the surface");
            let d = (p - c).norm();
            if brute <= reach {
                assert!((d - brute).abs() < 1e-12, "{p}: {d} against {brute}");
                exact += 1;
            } else {
                assert!(d >= brute - 1e-12 && d > reach, "{p}: {d} against {brute}");
                bounded += 1;
            }
        }
    }
    assert!(
        exact > 100 && bounded > 100,
        "{exact} exact, {bounded} bounded"
    );
}
