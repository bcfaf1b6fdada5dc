//! Detection on synthetic scenes made here, against their ground truth.

use std::f64::consts::PI;

use nalgebra::{Point3, Unit, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::*;

/// A labelled synthetic cloud: points and the true surface each came from.
struct Labelled {
    points: Vec<Point3<f64>>,
    label: Vec<usize>,
}

impl Labelled {
    fn new() -> Self {
        Labelled {
            points: Vec::new(),
            label: Vec::new(),
        }
    }

    /// `density` points per m² uniformly on the parallelogram `corner + a u + b v`,
    /// `a, b ∈ [0, 1]`, skipping those `keep` rejects, with N(0, σ²) offsets along its
    /// normal.
    fn rect(
        &mut self,
        rng: &mut ChaCha8Rng,
        (corner, u, v): (Point3<f64>, Vector3<f64>, Vector3<f64>),
        density: f64,
        sigma: f64,
        keep: &dyn Fn(&Point3<f64>) -> bool,
        label: usize,
    ) {
        let n = u.cross(&v);
        let count = (n.norm() * density).round() as usize;
        let n = n.normalize();
        for _ in 0..count {
            let p = corner + u * rng.random::<f64>() + v * rng.random::<f64>();
            if keep(&p) {
                self.push(p + n * (sigma * gauss(rng)), label);
            }
        }
    }

    fn push(&mut self, p: Point3<f64>, label: usize) {
        self.points.push(p);
        self.label.push(label);
    }

    /// Applies the rigid motion `rotation`, then `+ shift`, to every point.
    fn moved(mut self, rotation: &UnitQuaternion<f64>, shift: Vector3<f64>) -> Self {
        for p in &mut self.points {
            *p = Point3::from(rotation * p.coords + shift);
        }
        self
    }

    fn detect(&self, options: &DetectOptions) -> Detection {
        let index = PointIndex::new(&self.points);
        detect(&self.points, &index, options).unwrap()
    }

    /// The true label most of `segment`'s points carry, and that share.
    fn majority(&self, segment: &[usize]) -> (usize, f64) {
        let mut counts = std::collections::BTreeMap::new();
        for &i in segment {
            *counts.entry(self.label[i]).or_insert(0usize) += 1;
        }
        let (label, n) = counts
            .into_iter()
            .max_by_key(|(l, n)| (*n, usize::MAX - l))
            .unwrap();
        (label, n as f64 / segment.len() as f64)
    }
}

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample::<f64, _>(StandardNormal)
}

fn angle_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    a.normalize()
        .dot(&b.normalize())
        .abs()
        .min(1.0)
        .acos()
        .to_degrees()
}

/// A 5 × 4 × 2.5 m room (floor, four walls) with a 1 × 0.6 × 0.75 m box table, seen from
/// inside: 10 true faces, labels 0–9, with their normals (in the room's own frame).
fn room(density: f64, sigma: f64, seed: u64) -> (Labelled, Vec<Vector3<f64>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut scene = Labelled::new();
    let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
    let o = Point3::origin();
    let (tx, ty, tw, td, th) = (2.0, 1.5, 1.0, 0.6, 0.75);
    let off_table =
        move |p: &Point3<f64>| !(p.x > tx && p.x < tx + tw && p.y > ty && p.y < ty + td);
    let all = |_: &Point3<f64>| true;
    let faces = [
        ((o, x * 5.0, y * 4.0), z),
        ((o, x * 5.0, z * 2.5), y),
        ((o + y * 4.0, x * 5.0, z * 2.5), y),
        ((o, y * 4.0, z * 2.5), x),
        ((o + x * 5.0, y * 4.0, z * 2.5), x),
        ((Point3::new(tx, ty, th), x * tw, y * td), z),
        ((Point3::new(tx, ty, 0.0), x * tw, z * th), y),
        ((Point3::new(tx, ty + td, 0.0), x * tw, z * th), y),
        ((Point3::new(tx, ty, 0.0), y * td, z * th), x),
        ((Point3::new(tx + tw, ty, 0.0), y * td, z * th), x),
    ];
    for (label, (rect, _)) in faces.iter().enumerate() {
        let keep: &dyn Fn(&Point3<f64>) -> bool = if label == 0 { &off_table } else { &all };
        scene.rect(&mut rng, *rect, density, sigma, keep, label);
    }
    (scene, faces.iter().map(|f| f.1).collect())
}

#[test]
fn a_rotated_room_gives_one_plane_per_face() {
    let (scene, normals) = room(1500.0, 0.003, 1);
    let rotation = UnitQuaternion::from_axis_angle(
        &Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8)),
        37f64.to_radians(),
    );
    let scene = scene.moved(&rotation, Vector3::new(10.0, -3.0, 2.0));
    let detection = scene.detect(&DetectOptions::default());
    let planes: Vec<&Segment> = detection
        .segments
        .iter()
        .filter(|s| matches!(s.model, SurfaceModel::Plane { .. }))
        .collect();
    assert_eq!(
        planes.len(),
        detection.segments.len(),
        "only planes in a room"
    );
    // Count within 20 % of the 10 true faces.
    assert!((8..=12).contains(&planes.len()), "{} planes", planes.len());
    let mut seen = [false; 10];
    for s in &planes {
        let (face, share) = scene.majority(&s.points);
        let SurfaceModel::Plane { normal, .. } = s.model else {
            unreachable!()
        };
        let tilt = angle_deg(&normal, &(rotation * normals[face]));
        assert!(
            share > 0.95 && tilt < 2.0,
            "face {face}: share {share}, tilt {tilt}°"
        );
        seen[face] = true;
    }
    assert!(seen.iter().all(|s| *s), "every face found: {seen:?}");
    let explained: usize = planes.iter().map(|s| s.points.len()).sum();
    assert!(
        explained as f64 > 0.9 * scene.points.len() as f64,
        "{explained}"
    );
    // σ = 3 mm, or the floor of the random sampling's spacing where that is larger.
    let expected = 0.003f64.max(crate::surface::noise_floor(detection.spacing));
    assert!(
        (detection.noise / expected - 1.0).abs() < 0.2,
        "σ = {} for {expected}",
        detection.noise
    );
}

#[test]
fn a_coarsely_subsampled_room_judges_models_at_the_sensor_noise_not_the_layout() {
    // Subsampled to voxels many point spacings wide, a coarse grid 4 voxels wide would
    // span the room's corners (σ of the layout, tens of cm); the fine scale already
    // spans the sensor's correlated noise, so models are judged at it.
    let (scene, _) = room(1500.0, 0.003, 3);
    let options = DetectOptions {
        max_samples: Some(2_000),
        ..Default::default()
    };
    let detection = scene.detect(&options);
    let voxel = detection.voxel.expect("subsampled");
    assert!(
        voxel >= noise::COARSE_FACTOR * detection.spacing,
        "voxel {voxel}"
    );
    assert_eq!(detection.model_noise, detection.noise);
    assert!(detection.model_noise < 0.02, "σ {}", detection.model_noise);
    // The floor and the four walls (the small table faces fall below 2 000 samples).
    let planes = detection.segments.len();
    assert!((5..=7).contains(&planes), "{planes} segments");
}

#[test]
fn detection_does_not_depend_on_the_thread_count() {
    let (scene, _) = room(400.0, 0.003, 2);
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    };
    let one = pool(1).install(|| scene.detect(&DetectOptions::default()));
    let three = pool(3).install(|| scene.detect(&DetectOptions::default()));
    assert_eq!(one, three);
}

#[test]
fn detection_does_not_depend_on_where_the_scan_lies() {
    // The voxel subsample and the noise map's cells are grids fixed to the cloud, not to
    // the origin: moving the scan moves them with it, and the same points form the same
    // segments. (Fixed to the origin, this shift puts different points in each voxel
    // and cell, and the segments change.) The room is subsampled (voxels) and large
    // enough for many noise cells.
    let (scene, _) = room(400.0, 0.003, 2);
    let shift = Vector3::new(0.37, -1.13, 2.9);
    let moved = Labelled {
        points: scene.points.iter().map(|p| p + shift).collect(),
        label: scene.label.clone(),
    };
    let options = DetectOptions {
        max_samples: Some(4_000),
        ..Default::default()
    };
    let (here, there) = (scene.detect(&options), moved.detect(&options));
    assert!(here.voxel.is_some(), "not subsampled: the test proves less");
    let members = |d: &Detection| -> Vec<Vec<usize>> {
        d.segments.iter().map(|s| s.points.clone()).collect()
    };
    assert_eq!(
        members(&here),
        members(&there),
        "{} vs {}",
        summary(&here),
        summary(&there)
    );
    assert!((here.noise - there.noise).abs() <= 1e-9 * here.noise);
}

/// A half cylinder (180° visible, as a mug seen from one side) of radius `r` and
/// height `h` standing on a 0.4 m square floor at z = 0: labels 0 (floor), 1 (cylinder).
fn mug_on_a_table(r: f64, h: f64, sigma: f64, density: f64, seed: u64) -> Labelled {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut scene = Labelled::new();
    let floor = (
        Point3::new(-0.2, -0.2, 0.0),
        Vector3::x() * 0.4,
        Vector3::y() * 0.4,
    );
    let outside = move |p: &Point3<f64>| p.x.hypot(p.y) > r;
    scene.rect(&mut rng, floor, density, sigma, &outside, 0);
    let count = (PI * r * h * density).round() as usize;
    for _ in 0..count {
        let phi = (rng.random::<f64>() - 0.5) * PI;
        let z = rng.random::<f64>() * h;
        let radial = Vector3::new(phi.cos(), phi.sin(), 0.0);
        scene.push(
            Point3::from(radial * (r + sigma * gauss(&mut rng)) + Vector3::z() * z),
            1,
        );
    }
    scene
}

#[test]
fn a_mug_seen_from_one_side_is_one_cylinder_on_a_separate_plane() {
    let (r, h) = (0.04, 0.1);
    let tilt =
        UnitQuaternion::from_axis_angle(&Unit::new_normalize(Vector3::new(1.0, 2.0, 0.0)), 0.4);
    let scene = mug_on_a_table(r, h, 0.001, 250_000.0, 3).moved(&tilt, Vector3::new(0.3, 0.1, 0.8));
    let detection = scene.detect(&DetectOptions::default());
    let cylinders: Vec<&Segment> = detection
        .segments
        .iter()
        .filter(|s| s.model.name() == "cylinder")
        .collect();
    assert_eq!(cylinders.len(), 1, "{}", summary(&detection));
    let SurfaceModel::Cylinder {
        axis,
        radius,
        length,
        ..
    } = cylinders[0].model
    else {
        unreachable!()
    };
    assert!((radius - r).abs() < 0.03 * r, "r = {radius}");
    assert!(
        angle_deg(&axis, &(tilt * Vector3::z())) < 3.0,
        "axis {axis}"
    );
    assert!((length - h).abs() < 0.1 * h, "length {length}");
    let (label, share) = scene.majority(&cylinders[0].points);
    assert!(label == 1 && share > 0.95);
    let floor = &detection.segments[0];
    let SurfaceModel::Plane { normal, .. } = floor.model else {
        panic!("{}", summary(&detection))
    };
    assert!(angle_deg(&normal, &(tilt * Vector3::z())) < 1.0);
    assert_eq!(scene.majority(&floor.points).0, 0);
    // The cylinder's primitive: z along the axis, centred at the axial midpoint.
    let prim = cylinders[0].primitive().unwrap();
    assert!(angle_deg(&(prim.pose.rotation * Vector3::z()), &axis) < 1e-9);
    let mid = tilt * Vector3::new(0.0, 0.0, h / 2.0) + Vector3::new(0.3, 0.1, 0.8);
    assert!(
        (prim.pose.translation - mid).norm() < 0.01,
        "{}",
        prim.pose.translation
    );
}

/// `(type, points, rms)` of each segment, the clutter sizes, the unassigned count and
/// σ, for failure messages.
fn summary(d: &Detection) -> String {
    let segments: Vec<(&'static str, usize, f64)> = d
        .segments
        .iter()
        .map(|s| (s.model.name(), s.points.len(), s.rms))
        .collect();
    let clutter: Vec<usize> = d.clutter.iter().map(Vec::len).collect();
    format!(
        "segments {segments:?}, clutter {clutter:?}, {} unassigned, σ {} / {}",
        d.unassigned.len(),
        d.noise,
        d.model_noise
    )
}

#[test]
fn a_sparse_pole_on_the_ground_is_a_cylinder() {
    // LiDAR-like: rings every 5 cm, 24 points per ring, σ = 3 mm, on sparse ground.
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let (r, sigma) = (0.1, 0.003);
    let mut scene = Labelled::new();
    let ground = (
        Point3::new(-2.0, -2.0, 0.0),
        Vector3::x() * 4.0,
        Vector3::y() * 4.0,
    );
    let outside = move |p: &Point3<f64>| p.x.hypot(p.y) > r;
    scene.rect(&mut rng, ground, 400.0, sigma, &outside, 0);
    for ring in 0..60 {
        for k in 0..24 {
            let phi = (k as f64 + 0.3 * rng.random::<f64>()) * 2.0 * PI / 24.0;
            let z = 0.05 * (ring as f64 + 0.5);
            let radial = Vector3::new(phi.cos(), phi.sin(), 0.0);
            scene.push(
                Point3::from(radial * (r + sigma * gauss(&mut rng)) + Vector3::z() * z),
                1,
            );
        }
    }
    let detection = scene.detect(&DetectOptions::default());
    let cylinders: Vec<&Segment> = detection
        .segments
        .iter()
        .filter(|s| s.model.name() == "cylinder")
        .collect();
    assert_eq!(cylinders.len(), 1, "{}", summary(&detection));
    let SurfaceModel::Cylinder { axis, radius, .. } = cylinders[0].model else {
        unreachable!()
    };
    assert!((radius - r).abs() < 0.05 * r, "r = {radius}");
    assert!(angle_deg(&axis, &Vector3::z()) < 3.0);
    assert!(cylinders[0].points.len() > 1300, "{}", summary(&detection));
    assert_eq!(scene.majority(&cylinders[0].points), (1, 1.0));
}

#[test]
fn quantised_depth_has_a_noise_floor_and_stays_one_plane() {
    // z = 1 + 0.05 x + 0.02 y on a 5 mm grid, rounded to 2 mm depth steps: terraces
    // whose neighbourhoods are exactly planar.
    let mut scene = Labelled::new();
    for i in 0..200 {
        for j in 0..200 {
            let (x, y) = (i as f64 * 0.005, j as f64 * 0.005);
            let z = ((1.0 + 0.05 * x + 0.02 * y) / 0.002).round() * 0.002;
            scene.push(Point3::new(x, y, z), 0);
        }
    }
    let detection = scene.detect(&DetectOptions::default());
    assert!(
        detection.noise >= crate::surface::noise_floor(0.005) - 1e-12,
        "σ = {}",
        detection.noise
    );
    assert_eq!(detection.segments.len(), 1, "{}", summary(&detection));
    let plane = &detection.segments[0];
    let SurfaceModel::Plane { normal, .. } = plane.model else {
        panic!()
    };
    assert!(angle_deg(&normal, &Vector3::new(-0.05, -0.02, 1.0)) < 0.5);
    assert!(
        plane.points.len() as f64 > 0.98 * scene.points.len() as f64,
        "{}",
        plane.points.len()
    );
}

#[test]
fn a_ball_is_a_sphere_and_bad_input_is_an_error() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut scene = Labelled::new();
    for _ in 0..6000 {
        let v = Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)).normalize();
        if v.z > -0.3 {
            scene.push(
                Point3::new(1.0, 2.0, 3.0) + v * (0.25 + 0.001 * gauss(&mut rng)),
                0,
            );
        }
    }
    let detection = scene.detect(&DetectOptions::default());
    assert_eq!(detection.segments.len(), 1, "{}", summary(&detection));
    let SurfaceModel::Sphere { centre, radius } = detection.segments[0].model else {
        panic!()
    };
    assert!((radius - 0.25).abs() < 0.005 && (centre - Point3::new(1.0, 2.0, 3.0)).norm() < 0.005);
    let index = PointIndex::new(&[]);
    assert!(matches!(
        detect(&[], &index, &DetectOptions::default()),
        Err(Error::EmptyCloud)
    ));
    let bad = DetectOptions {
        tolerance: Some(-1.0),
        ..Default::default()
    };
    let pts = [Point3::origin()];
    assert!(detect(&pts, &PointIndex::new(&pts), &bad).is_err());
    let nan = [Point3::new(f64::NAN, 0.0, 0.0)];
    assert!(matches!(
        detect(&nan, &PointIndex::new(&pts), &DetectOptions::default()),
        Err(Error::NonFinite { .. })
    ));
}

#[test]
fn a_tube_two_samples_wide_is_a_cylinder_not_a_strip() {
    // A 12 × 6 m floor of rooms (3 mm jitter) with an 8 cm pipe along x through the
    // walls, subsampled to 24 000 samples: voxels of 12 cm, so the pipe is under two
    // samples across, and its sample segment passed as a plane through its axis
    // (4 540 points at 57 mm RMS, beside a cylinder piece of 602) before the strip check.
    use crate::synth::{SurveyParams, survey};
    let scene = survey(&SurveyParams {
        points: 186_000,
        extent: [12.0, 6.0],
        ..Default::default()
    })
    .unwrap();
    let points = &scene.cloud.points;
    let index = PointIndex::new(points);
    let options = DetectOptions {
        max_samples: Some(24_000),
        ..Default::default()
    };
    let d = detect(points, &index, &options).unwrap();
    assert!(d.voxel.is_some_and(|v| v > 0.08), "{:?}", d.voxel);
    let summary: Vec<_> = d
        .segments
        .iter()
        .map(|s| (s.points.len(), s.model.name(), s.rms))
        .collect();
    assert_eq!(d.segments.len(), scene.truth.len(), "{summary:?}");
    let tubes: Vec<&Segment> = d
        .segments
        .iter()
        .filter(|s| s.model.name() == "cylinder")
        .collect();
    assert_eq!(tubes.len(), 1, "{summary:?}");
    let SurfaceModel::Cylinder { radius, .. } = tubes[0].model else {
        unreachable!()
    };
    assert!((radius - 0.08).abs() < 0.008, "r = {radius}");
    assert!(d.segments.iter().all(|s| s.rms < 0.01), "{summary:?}");
}

#[test]
fn points_at_a_junction_join_their_own_surface_when_the_nearest_sample_is_the_others() {
    // A floor and a wall meeting at a right angle, subsampled to voxels far wider than
    // the point spacing: along the junction a point's nearest sample is often on the
    // other surface, yet the point lies on its own and must join it (no gap a voxel
    // wide along every junction).
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut scene = Labelled::new();
    let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
    let all = |_: &Point3<f64>| true;
    let o = Point3::origin();
    scene.rect(&mut rng, (o, x * 4.0, y * 3.0), 4000.0, 0.002, &all, 0);
    scene.rect(&mut rng, (o, x * 4.0, z * 2.0), 4000.0, 0.002, &all, 1);
    let options = DetectOptions {
        max_samples: Some(1_500),
        ..Default::default()
    };
    let detection = scene.detect(&options);
    let voxel = detection.voxel.expect("subsampled");
    assert_eq!(detection.segments.len(), 2, "{}", summary(&detection));
    let mut own = vec![None; scene.points.len()];
    for s in &detection.segments {
        let (face, _) = scene.majority(&s.points);
        for &i in &s.points {
            own[i] = Some(face);
        }
    }
    // Points within one voxel of the junction (y = 0 on the floor, z = 0 on the wall).
    let near: Vec<usize> = (0..scene.points.len())
        .filter(|&i| scene.points[i].y.max(scene.points[i].z) < voxel)
        .collect();
    let joined = near
        .iter()
        .filter(|&&i| own[i] == Some(scene.label[i]))
        .count();
    let left_out = near.iter().filter(|&&i| own[i].is_none()).count();
    // Points within t σ of both planes (a band a few mm wide) may join either.
    assert!(
        left_out * 50 < near.len() && joined * 100 > 95 * near.len(),
        "of {} points near the junction {joined} joined their own surface, {left_out} none \
         (voxel {voxel})",
        near.len()
    );
}
