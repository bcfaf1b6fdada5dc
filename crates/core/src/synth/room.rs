//! A furnished room (issue 14's synthetic scenes): floor, four walls and an optional
//! ceiling, box furniture standing on the floor, tubes (a pipe run, a pole), placed at
//! an arbitrary yaw and tilt; the truth is every **visible** face as a bounded `plane`
//! (a rectangle, with holes where something stands on it) and every tube as a cylinder.
//!
//! The room frame has the floor at z = 0 and the walls at x = 0, x = `size.x`, y = 0,
//! y = `size.y`; every face's normal points to the side it is seen from (into the room,
//! out of a box). Hidden faces are left out: the bottom of a box on the floor, a box top
//! covered by the box standing on it (a table's legs under its top). The floor has a
//! hole under every box standing on it and every tube that reaches it; the ceiling one
//! where a tube reaches it; a box bottom one where another box's top touches it.
//! How the surfaces are sampled (area-uniform, or as a depth sensor sees them, with
//! Kinect-type quantised depth) is [`super::room_view`].

use std::f64::consts::TAU;

use nalgebra::{Matrix3, Point2, Point3, Rotation3, UnitQuaternion, Vector3};

use crate::atlas::{PlaneShape, Shape};
use crate::check::{self, positive};
use crate::{Error, Pose, Primitive, Result};

/// Vertices of the polygon that stands in for a tube's circular footprint in a floor or
/// ceiling hole (inscribed, so the hole stays inside the tube).
const FOOTPRINT_VERTICES: usize = 24;

/// Two heights closer than this (metres) touch: a box standing on another, a tube end
/// on the floor.
const CONTACT: f64 = 1e-9;

/// An axis-aligned box standing in the room (room frame, metres).
#[derive(Debug, Clone, PartialEq)]
pub struct Furniture {
    /// The corner with the smallest x, y and z (z = 0: on the floor).
    pub min: Point3<f64>,
    /// Extent along x, y and z (each > 0).
    pub size: Vector3<f64>,
}

impl Furniture {
    /// A box with its lowest corner at `min` and extents `size`.
    pub fn new(min: Point3<f64>, size: Vector3<f64>) -> Self {
        Furniture { min, size }
    }

    /// A table: a top slab of `thickness` whose upper face is at `height`, over the
    /// floor rectangle from `(x, y)` of extent `(width, depth)`, on four square legs of
    /// side `leg` set in by `inset` from the top's corners (all metres).
    pub fn table(
        (x, y): (f64, f64),
        (width, depth, height): (f64, f64, f64),
        thickness: f64,
        leg: f64,
        inset: f64,
    ) -> Vec<Furniture> {
        let base = height - thickness;
        let mut out = vec![Furniture::new(
            Point3::new(x, y, base),
            Vector3::new(width, depth, thickness),
        )];
        for (fx, fy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            let lx = x + inset + fx * (width - 2.0 * inset - leg);
            let ly = y + inset + fy * (depth - 2.0 * inset - leg);
            out.push(Furniture::new(
                Point3::new(lx, ly, 0.0),
                Vector3::new(leg, leg, base),
            ));
        }
        out
    }

    fn max(&self) -> Point3<f64> {
        self.min + self.size
    }

    /// The floor-plan rectangle `(x₀, y₀, x₁, y₁)`.
    fn footprint(&self) -> [f64; 4] {
        let hi = self.max();
        [self.min.x, self.min.y, hi.x, hi.y]
    }
}

/// An open tube from `from` to `to` (its axis end points, room frame, metres) of
/// `radius` (metres): a pipe, a pole.
#[derive(Debug, Clone, PartialEq)]
pub struct Tube {
    /// One end of the axis.
    pub from: Point3<f64>,
    /// The other end.
    pub to: Point3<f64>,
    /// Radius (> 0).
    pub radius: f64,
}

/// The geometry of a room (room frame, metres); see the module docs.
#[derive(Debug, Clone, PartialEq)]
pub struct RoomGeometry {
    /// Extent along x, y and z (the height).
    pub size: Vector3<f64>,
    /// Whether there is a ceiling.
    pub ceiling: bool,
    /// Boxes (disjoint interiors, inside the room, off the walls).
    pub furniture: Vec<Furniture>,
    /// Tubes (inside the room).
    pub tubes: Vec<Tube>,
}

impl Default for RoomGeometry {
    /// A 5 × 4 × 2.5 m room without a ceiling, with a 1.2 × 0.8 × 0.75 m box table and
    /// a 0.6 × 0.5 × 1.2 m cabinet: 15 visible faces.
    fn default() -> Self {
        RoomGeometry {
            size: Vector3::new(5.0, 4.0, 2.5),
            ceiling: false,
            furniture: vec![
                Furniture::new(Point3::new(1.4, 1.2, 0.0), Vector3::new(1.2, 0.8, 0.75)),
                Furniture::new(Point3::new(3.6, 2.6, 0.0), Vector3::new(0.6, 0.5, 1.2)),
            ],
            tubes: Vec::new(),
        }
    }
}

impl RoomGeometry {
    /// This room with a pipe run (r = 5 cm) along the wall y = `size.y`, 10 cm off the
    /// floor and 15 cm off the wall, and a pole (r = 10 cm) from floor to ceiling height.
    pub fn with_pipe_and_pole(mut self) -> Self {
        let (l, w, h) = (self.size.x, self.size.y, self.size.z);
        let (r, z, y) = (0.05, 0.15, w - 0.2);
        self.tubes.push(Tube {
            from: Point3::new(0.3, y, z),
            to: Point3::new(l - 0.3, y, z),
            radius: r,
        });
        self.tubes.push(Tube {
            from: Point3::new(0.25 * l, 0.3 * w, 0.0),
            to: Point3::new(0.25 * l, 0.3 * w, h),
            radius: 0.1,
        });
        self
    }

    /// Checks sizes, that every box and tube is inside the room, that boxes stand off the
    /// walls and do not intersect.
    pub fn validate(&self) -> Result<()> {
        check::finite("size", self.size.as_slice())?;
        for (k, v) in ["size.x", "size.y", "size.z"].iter().zip(self.size.iter()) {
            positive(k, *v)?;
        }
        let inside =
            |p: &Point3<f64>| (0..3).all(|k| p[k] >= -CONTACT && p[k] <= self.size[k] + CONTACT);
        for (i, f) in self.furniture.iter().enumerate() {
            check::finite(&format!("furniture[{i}].min"), f.min.coords.as_slice())?;
            check::finite(&format!("furniture[{i}].size"), f.size.as_slice())?;
            for k in 0..3 {
                positive(&format!("furniture[{i}].size[{k}]"), f.size[k])?;
            }
            let [x0, y0, x1, y1] = f.footprint();
            let off_walls = x0 > 0.0 && y0 > 0.0 && x1 < self.size.x && y1 < self.size.y;
            if !(off_walls && inside(&f.min) && inside(&f.max())) {
                return Err(Error::invalid(format!(
                    "furniture[{i}] must stand inside the room, off its walls"
                )));
            }
            for (j, g) in self.furniture.iter().enumerate().take(i) {
                if (0..3).all(|k| f.min[k] < g.max()[k] && g.min[k] < f.max()[k]) {
                    return Err(Error::invalid(format!(
                        "furniture[{i}] and furniture[{j}] intersect"
                    )));
                }
            }
        }
        for (i, t) in self.tubes.iter().enumerate() {
            check::finite(&format!("tubes[{i}].from"), t.from.coords.as_slice())?;
            check::finite(&format!("tubes[{i}].to"), t.to.coords.as_slice())?;
            positive(&format!("tubes[{i}].radius"), t.radius)?;
            if (t.to - t.from).norm() <= 0.0 || !inside(&t.from) || !inside(&t.to) {
                return Err(Error::invalid(format!(
                    "tubes[{i}] must have two distinct ends inside the room"
                )));
            }
        }
        Ok(())
    }

    /// The visible surfaces (room frame, metres): the room's faces (floor, walls,
    /// ceiling), then each box's, then the tubes; see the module docs.
    pub fn surfaces(&self) -> Result<Vec<Primitive>> {
        self.validate()?;
        let s = self.size;
        let mut out = Vec::new();
        // Floor and ceiling with their holes.
        out.push(self.horizontal(0.0, 1.0, [0.0, 0.0, s.x, s.y])?);
        for (axis, sign, at) in [(0, 1.0, 0.0), (0, -1.0, s.x), (1, 1.0, 0.0), (1, -1.0, s.y)] {
            let (lo, hi) = (Vector3::zeros(), s);
            out.push(face(axis, sign, at, &lo, &hi, &[])?);
        }
        if self.ceiling {
            out.push(self.horizontal(s.z, -1.0, [0.0, 0.0, s.x, s.y])?);
        }
        for (i, f) in self.furniture.iter().enumerate() {
            let (lo, hi) = (f.min.coords, f.max().coords);
            let covered = self.furniture.iter().enumerate().any(|(j, g)| {
                j != i
                    && (g.min.z - hi.z).abs() < CONTACT
                    && contains(&g.footprint(), &f.footprint())
            });
            if !covered {
                out.push(face(2, 1.0, hi.z, &lo, &hi, &[])?);
            }
            if f.min.z > CONTACT {
                out.push(self.box_bottom(i)?);
            }
            for (axis, sign, at) in [
                (0, -1.0, lo.x),
                (0, 1.0, hi.x),
                (1, -1.0, lo.y),
                (1, 1.0, hi.y),
            ] {
                out.push(face(axis, sign, at, &lo, &hi, &[])?);
            }
        }
        out.extend(self.tubes.iter().map(tube_primitive));
        Ok(out)
    }

    /// The floor (`sign` = +1, at `z` = 0) or the ceiling (`sign` = −1) over `rect`,
    /// with a hole under every box standing on it and every tube that reaches it.
    fn horizontal(&self, z: f64, sign: f64, rect: [f64; 4]) -> Result<Primitive> {
        let mut holes: Vec<Vec<Point2<f64>>> = Vec::new();
        if sign > 0.0 {
            holes.extend(
                self.furniture
                    .iter()
                    .filter(|f| f.min.z.abs() < CONTACT)
                    .map(|f| rectangle(&f.footprint())),
            );
        }
        for t in &self.tubes {
            for end in [t.from, t.to] {
                if (end.z - z).abs() < CONTACT {
                    holes.push(circle(Point2::new(end.x, end.y), t.radius));
                }
            }
        }
        let lo = Vector3::new(rect[0], rect[1], z);
        let hi = Vector3::new(rect[2], rect[3], z);
        face(2, sign, z, &lo, &hi, &holes)
    }

    /// The bottom of box `i` (not on the floor), with a hole where a box's top touches it.
    fn box_bottom(&self, i: usize) -> Result<Primitive> {
        let f = &self.furniture[i];
        let holes: Vec<Vec<Point2<f64>>> = self
            .furniture
            .iter()
            .enumerate()
            .filter(|(j, g)| {
                *j != i
                    && (g.max().z - f.min.z).abs() < CONTACT
                    && contains(&f.footprint(), &g.footprint())
            })
            .map(|(_, g)| rectangle(&g.footprint()))
            .collect();
        face(2, -1.0, f.min.z, &f.min.coords, &f.max().coords, &holes)
    }
}

/// Whether the floor-plan rectangle `outer` contains `inner` (closed).
fn contains(outer: &[f64; 4], inner: &[f64; 4]) -> bool {
    outer[0] <= inner[0] + CONTACT
        && outer[1] <= inner[1] + CONTACT
        && inner[2] <= outer[2] + CONTACT
        && inner[3] <= outer[3] + CONTACT
}

/// The corners of a floor-plan rectangle `(x₀, y₀, x₁, y₁)` (room x, y).
fn rectangle(r: &[f64; 4]) -> Vec<Point2<f64>> {
    vec![
        Point2::new(r[0], r[1]),
        Point2::new(r[2], r[1]),
        Point2::new(r[2], r[3]),
        Point2::new(r[0], r[3]),
    ]
}

/// A polygon inscribed in the circle of `radius` about `centre` (room x, y).
fn circle(centre: Point2<f64>, radius: f64) -> Vec<Point2<f64>> {
    (0..FOOTPRINT_VERTICES)
        .map(|k| {
            let a = TAU * k as f64 / FOOTPRINT_VERTICES as f64;
            centre + nalgebra::Vector2::new(a.cos(), a.sin()) * radius
        })
        .collect()
}

/// The axis-aligned rectangle at coordinate `at` on `axis` (0 = x, 1 = y, 2 = z) over
/// the box `[lo, hi]` in the other two axes, facing `sign · e_axis`, as a `plane` whose
/// local x and y are the next two axes in the order that makes `sign · e_axis` its +z.
/// `holes` are rings in room coordinates of those two axes, in cyclic axis order
/// (for the floor and ceiling: room (x, y)).
pub(crate) fn face(
    axis: usize,
    sign: f64,
    at: f64,
    lo: &Vector3<f64>,
    hi: &Vector3<f64>,
    holes: &[Vec<Point2<f64>>],
) -> Result<Primitive> {
    let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
    let (u, v) = if sign > 0.0 { (a, b) } else { (b, a) };
    let mut centre = (lo + hi) / 2.0;
    centre[axis] = at;
    // Room coordinates (along a, along b) → local (x, y).
    let local = |pa: f64, pb: f64| {
        let (da, db) = (pa - centre[a], pb - centre[b]);
        if u == a {
            Point2::new(da, db)
        } else {
            Point2::new(db, da)
        }
    };
    let outline = vec![
        local(lo[a], lo[b]),
        local(hi[a], lo[b]),
        local(hi[a], hi[b]),
        local(lo[a], hi[b]),
    ];
    let holes: Vec<Vec<Point2<f64>>> = holes
        .iter()
        .map(|ring| ring.iter().map(|p| local(p.x, p.y)).collect())
        .collect();
    let shape = PlaneShape::new(outline, holes)?;
    let n = Vector3::ith(axis, sign);
    let m = Matrix3::from_columns(&[Vector3::ith(u, 1.0), Vector3::ith(v, 1.0), n]);
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
    Ok(Primitive::new(
        Shape::Plane(shape),
        Pose::new(rotation, centre),
    ))
}

/// The cylinder of a tube: local z along its axis, centred at the axis midpoint.
fn tube_primitive(t: &Tube) -> Primitive {
    let axis = t.to - t.from;
    let rotation = UnitQuaternion::rotation_between(&Vector3::z(), &axis).unwrap_or_else(|| {
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
    });
    let centre = t.from + axis / 2.0;
    Primitive::new(
        Shape::Cylinder {
            length: axis.norm(),
            radius: t.radius,
        },
        Pose::new(rotation, centre.coords),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn normal(p: &Primitive) -> Vector3<f64> {
        p.pose.rotation * Vector3::z()
    }

    #[test]
    fn the_default_room_has_fifteen_faces_facing_their_viewers() {
        let g = RoomGeometry::default();
        let faces = g.surfaces().unwrap();
        assert_eq!(faces.len(), 15);
        let centre = Point3::from(g.size / 2.0);
        // Room faces look into the room; box faces away from their box.
        for f in &faces[..5] {
            assert!(normal(f).dot(&(centre - f.center())) > 0.0);
        }
        for (k, f) in faces[5..].iter().enumerate() {
            let b = &g.furniture[k / 5];
            let mid = b.min + b.size / 2.0;
            assert!(normal(f).dot(&(f.center() - mid)) > 0.0, "face {k}");
        }
        // The floor has two holes: its area is the room's less the two footprints.
        let floor = faces[0].area();
        assert!(
            (floor - (20.0 - 1.2 * 0.8 - 0.6 * 0.5)).abs() < 1e-9,
            "{floor}"
        );
        // Every corner of the table top's face lies on the table top.
        let top = &faces[5];
        assert!((top.area() - 1.2 * 0.8).abs() < 1e-9);
        assert!(top.distance(&Point3::new(2.6, 2.0, 0.75)) < 1e-12);
        assert!(top.distance(&Point3::new(2.6, 2.0, 0.7)) > 0.049);
    }

    #[test]
    fn a_table_hides_its_leg_tops_and_tubes_are_cut_into_floor_and_ceiling() {
        let mut g = RoomGeometry {
            ceiling: true,
            furniture: Furniture::table((1.0, 1.0), (1.2, 0.8, 0.75), 0.05, 0.06, 0.04),
            ..Default::default()
        }
        .with_pipe_and_pole();
        let faces = g.surfaces().unwrap();
        // 6 room faces, top slab 6 (bottom included), legs 4 sides each, 2 tubes.
        assert_eq!(faces.len(), 6 + 6 + 16 + 2);
        let slab_bottom = &faces[7];
        assert!((slab_bottom.area() - (1.2 * 0.8 - 4.0 * 0.06 * 0.06)).abs() < 1e-9);
        let pole_cut = std::f64::consts::PI * 0.01; // ≈ the 24-gon's area
        let floor = 20.0 - 4.0 * 0.06 * 0.06 - pole_cut;
        assert!(
            (faces[0].area() - floor).abs() < 2e-3,
            "{}",
            faces[0].area()
        );
        assert!(matches!(faces[29].shape, Shape::Cylinder { radius, .. } if radius == 0.1));
        // Bad geometry is refused.
        g.furniture.push(Furniture::new(
            Point3::new(1.1, 1.1, 0.0),
            Vector3::new(0.2, 0.2, 0.2),
        ));
        assert!(g.surfaces().is_err(), "intersecting boxes");
        let against_wall = RoomGeometry {
            furniture: vec![Furniture::new(
                Point3::origin(),
                Vector3::new(1.0, 1.0, 1.0),
            )],
            ..Default::default()
        };
        assert!(against_wall.validate().is_err());
    }
}
