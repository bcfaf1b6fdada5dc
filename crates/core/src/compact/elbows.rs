//! Elbows between pipe runs: two cylinders of the model whose axes meet at a right angle
//! near their ends are joined by an elbow (a quarter torus, [`Shape::Elbow`]) when it
//! lowers the loss by more than its description length.
//!
//! Detection finds planes, cylinders and spheres. The bend of a pipe between two runs is
//! none of them, so its points were left unexplained or taken by small patches (a chain of
//! 10 cm pipes at σ = 5 mm: point→model 9–13 mm with the runs alone).
//!
//! **Geometry.** The elbow between runs `p` and `q` is fixed by their axes up to its bend
//! radius `B`. With `X` the point where the axes meet (the middle of their closest
//! approach), `a` the direction of run `p` towards `X` and `b` that of run `q` away from
//! it, the elbow's centre line is the quarter circle tangent to `p` at `X − B a` and to
//! `q` at `X + B b`; its centre is `X − B a + B b`. Each run is cut back (or extended)
//! to end where the elbow starts.
//!
//! **Loss** (`elbow_loss.rs`): the existence decision's own (`model.rs`, `mdl.rs`). `B`
//! is the best of a geometric grid from [`MIN_BEND_RADII`] tube radii up to what both
//! runs can give up, refined by golden section. Junctions are taken greedily, largest
//! gain first, each run end at most once.
//!
//! **Runs refitted.** Detection grows a run into the start of its bends, whose points
//! pull the fitted axis, and `X` with it, towards the inside of the bend; a corner
//! moved inwards by `δ` gives `B` short by about `δ / (√2 − 1)` (docs/compact.md). So
//! the runs an elbow cut are refitted on their points between the cuts, a tube radius
//! clear of each, and the junctions decided again on the refitted runs.

use std::borrow::Cow;

use nalgebra::{Point3, UnitQuaternion, Vector3};
use rayon::prelude::*;

use super::elbow_loss::Judge;
use super::trim::{Cloud, Kept, Pricing};
use crate::atlas::elbow_rotation_between;
use crate::detect::{CylinderFit, refit_cylinder};
use crate::primitive::Pose;
use crate::{Primitive, Shape};

/// Largest departure of two runs' axes from a right angle (degrees): an elbow is a
/// quarter torus.
const RIGHT_ANGLE_TOLERANCE_DEG: f64 = 10.0;

/// Largest relative difference of the two runs' radii.
const RADIUS_TOLERANCE: f64 = 0.15;

/// Largest distance between the two axes at their closest approach, in tube radii.
const MAX_AXIS_GAP_RADII: f64 = 1.0;

/// How far a run may reach past the corner `X`, in tube radii (a cylinder fitted through
/// the outer wall of the bend).
const MAX_OVERSHOOT_RADII: f64 = 1.0;

/// Smallest bend radius, in tube radii (a torus needs `B > r`; short-radius elbows have
/// `B = 2r`).
const MIN_BEND_RADII: f64 = 1.25;

/// Largest bend radius searched beyond the runs' own gap to the corner, and the farthest
/// a run may end short of the corner, in tube radii (a 5D bend; common elbows have 2–3
/// radii).
const MAX_BEND_RADII: f64 = 10.0;

/// Shortest a run may become after its cut, in tube radii.
const MIN_RUN_RADII: f64 = 1.0;

/// How far from an elbow's start a run's points are left out of its refit, in tube
/// radii: the bend's start, which detection grew into the run, lies within it.
const REFIT_CLEARANCE_RADII: f64 = 1.0;

/// Fewest points a run is refitted on.
const MIN_REFIT_POINTS: usize = 30;

/// A cylinder of the model seen as a pipe run: its axis and extent (scene units).
#[derive(Debug, Clone, Copy)]
pub(super) struct Run {
    pub centre: Point3<f64>,
    /// Unit axis (the cylinder's local z).
    pub axis: Vector3<f64>,
    /// Half its length.
    pub half: f64,
    pub radius: f64,
    rotation: UnitQuaternion<f64>,
}

impl Run {
    fn of(p: &Primitive) -> Option<Run> {
        let Shape::Cylinder { length, radius } = p.shape else {
            return None;
        };
        let s = p.pose.scale;
        Some(Run {
            centre: p.center(),
            axis: p.pose.rotation * Vector3::z(),
            half: s * length / 2.0,
            radius: s * radius,
            rotation: p.pose.rotation,
        })
    }

    /// Its extent along the axis: `(−half, half)`.
    fn whole(&self) -> (f64, f64) {
        (-self.half, self.half)
    }

    /// The cylinder from axis parameter `lo` to `hi` (scene units along the axis from
    /// the centre), with this run's axis and radius.
    fn cylinder(&self, (lo, hi): (f64, f64)) -> Primitive {
        let centre = self.centre + self.axis * ((lo + hi) / 2.0);
        let shape = Shape::Cylinder {
            length: hi - lo,
            radius: self.radius,
        };
        Primitive::new(shape, Pose::new(self.rotation, centre.coords))
    }
}

/// Two run ends that an elbow could join.
#[derive(Debug, Clone)]
pub(super) struct Junction {
    /// The two runs' indices in the model, and the runs.
    pub ids: [usize; 2],
    pub runs: [Run; 2],
    /// For each run, the sign (along its axis) of the end at the corner.
    pub ends: [f64; 2],
    /// Where the axes meet.
    pub corner: Point3<f64>,
    /// Unit direction of the first run towards the corner.
    into: Vector3<f64>,
    /// Unit direction of the second run away from the corner, orthogonal to `into`.
    out: Vector3<f64>,
    pub radius: f64,
    /// Distance along each axis from the corner to the run's far end.
    pub reach: [f64; 2],
    /// Distance along each axis from the corner back to the run's near end (negative
    /// where the run reaches past the corner).
    gap: [f64; 2],
}

impl Junction {
    /// The runs `ids` (`p`, `q`) as a junction, or `None` where their axes do not meet
    /// at a right angle beyond one end of each.
    pub(super) fn of(ids: [usize; 2], p: &Run, q: &Run) -> Option<Junction> {
        let r = p.radius.max(q.radius);
        let max_cos = RIGHT_ANGLE_TOLERANCE_DEG.to_radians().sin();
        let cos = p.axis.dot(&q.axis);
        if (p.radius - q.radius).abs() > RADIUS_TOLERANCE * r || cos.abs() > max_cos {
            return None;
        }
        // Closest approach of the lines c_p + s u_p and c_q + t u_q.
        let w = p.centre - q.centre;
        let (d, e) = (p.axis.dot(&w), q.axis.dot(&w));
        let denom = 1.0 - cos * cos;
        let s = (cos * e - d) / denom;
        let t = (e - cos * d) / denom;
        let (on_p, on_q) = (p.centre + p.axis * s, q.centre + q.axis * t);
        if (on_p - on_q).norm() > MAX_AXIS_GAP_RADII * r {
            return None;
        }
        // Each run ends near the corner: at most a radius past it, at most the largest
        // bend radius short of it.
        let gap = [s.abs() - p.half, t.abs() - q.half];
        if (gap.iter()).any(|&g| g < -MAX_OVERSHOOT_RADII * r || g > MAX_BEND_RADII * r) {
            return None;
        }
        let into = p.axis * s.signum();
        let out = -q.axis * t.signum();
        Some(Junction {
            ids,
            runs: [*p, *q],
            ends: [s.signum(), t.signum()],
            corner: nalgebra::center(&on_p, &on_q),
            into,
            out: (out - into * into.dot(&out)).normalize(),
            radius: (p.radius + q.radius) / 2.0,
            reach: [s.abs() + p.half, t.abs() + q.half],
            gap,
        })
    }

    /// The elbow of bend radius `bend`, tangent to the first run at `X − B a` and to the
    /// second at `X + B b` (`atlas/elbow.rs`'s local frame).
    pub(super) fn elbow(&self, bend: f64) -> Primitive {
        let centre = self.corner + (self.out - self.into) * bend;
        let shape = Shape::Elbow {
            bend,
            radius: self.radius,
        };
        let rotation = elbow_rotation_between(&self.into, &self.out);
        Primitive::new(shape, Pose::new(rotation, centre.coords))
    }

    /// Where run `k` ends when the elbow of bend radius `bend` starts: its axis
    /// parameter (scene units from the run's centre) at the elbow's tangent point.
    fn cut(&self, k: usize, bend: f64) -> f64 {
        let tangent = if k == 0 {
            self.corner - self.into * bend
        } else {
            self.corner + self.out * bend
        };
        let run = &self.runs[k];
        (tangent - run.centre).dot(&run.axis)
    }

    /// Run `k` cut (or extended) to meet the elbow of bend radius `bend`, its far end
    /// where it was.
    pub(super) fn cut_run(&self, k: usize, bend: f64) -> Primitive {
        let run = &self.runs[k];
        let (at, far) = (self.cut(k, bend), -self.ends[k] * run.half);
        run.cylinder((far.min(at), far.max(at)))
    }

    /// The range of bend radii to search: from [`MIN_BEND_RADII`] radii to what both
    /// runs can give up, and no farther than [`MAX_BEND_RADII`] radii or twice the
    /// larger gap between a run's end and the corner, whichever is more.
    pub(super) fn bend_range(&self) -> Option<(f64, f64)> {
        let lo = MIN_BEND_RADII * self.radius;
        let keep = MIN_RUN_RADII * self.radius;
        let gap = self.gap[0].max(self.gap[1]);
        let hi = (self.reach[0] - keep)
            .min(self.reach[1] - keep)
            .min((2.0 * gap + self.radius).max(MAX_BEND_RADII * self.radius));
        (hi > lo).then_some((lo, hi))
    }

    /// The radius of the ball about the corner that holds every surface a cut or an
    /// elbow with a bend radius up to `bend_hi` changes.
    pub(super) fn reach_of_changes(&self, bend_hi: f64) -> f64 {
        bend_hi.max(self.gap[0]).max(self.gap[1]) + self.radius
    }
}

/// A junction worth its elbow: the gain (loss before − after, squared scene units), the
/// bend radius, and the primitives (model indices) the elbow replaces.
#[derive(Debug, Clone)]
pub(super) struct Scored {
    pub gain: f64,
    pub junction: Junction,
    pub bend: f64,
    pub replaced: Vec<usize>,
}

/// `kept` (with their `existence`) with elbows added between the runs they join, the
/// runs refitted on their straight parts and cut to meet them, and the patches an elbow
/// replaces dropped (module docs). An
/// elbow's members are the points within the cap of it, its existence the lower of its
/// two runs'. `sample_spacing` is the existence decision's (scene units).
pub fn join_runs<'a>(
    cloud: Cloud,
    kept: Vec<Kept<'a>>,
    existence: Vec<f64>,
    pricing: Pricing,
    sample_spacing: f64,
) -> (Vec<Kept<'a>>, Vec<f64>) {
    let mut primitives: Vec<Primitive> = kept.iter().map(|k| k.primitive.clone()).collect();
    let mut runs: Vec<Option<Run>> = primitives.iter().map(Run::of).collect();
    let mut accepted = decide(cloud, &primitives, &runs, pricing, sample_spacing);
    // Detection grows a run into the start of its bends, and the points there pull its
    // fitted axis towards the inside of the bend, and the corner with it: the bend
    // radius then comes out short by about 2.4 times the corner's shift (docs/compact.md).
    // The runs an elbow joins are refitted on their straight part and decided again.
    let refitted = refit_joined(cloud, &kept, &runs, &accepted.extent);
    if refitted.iter().any(Option::is_some) {
        for (i, run) in refitted.into_iter().enumerate() {
            if let Some(run) = run {
                primitives[i] = run.cylinder(run.whole());
                runs[i] = Some(run);
            }
        }
        accepted = decide(cloud, &primitives, &runs, pricing, sample_spacing);
    }
    let elbows: Vec<(Kept<'a>, f64)> = (accepted.elbows.iter())
        .map(|(elbow, [i, j])| {
            let members = Cow::Owned(members_of(cloud, elbow, pricing.cap));
            let primitive = elbow.clone();
            (
                Kept { primitive, members },
                existence[*i].min(existence[*j]),
            )
        })
        .collect();
    let mut model = Vec::with_capacity(kept.len() + elbows.len());
    for (i, ((k, p), primitive)) in kept.into_iter().zip(existence).zip(primitives).enumerate() {
        if accepted.dropped[i] {
            continue;
        }
        let primitive = match &runs[i] {
            Some(run) if accepted.extent[i] != run.whole() => run.cylinder(accepted.extent[i]),
            _ => primitive,
        };
        model.push((Kept { primitive, ..k }, p));
    }
    model.extend(elbows);
    model.into_iter().unzip()
}

/// The junctions of `runs` (the cylinders among `primitives`) worth an elbow, taken
/// greedily ([`accept`]).
fn decide(
    cloud: Cloud,
    primitives: &[Primitive],
    runs: &[Option<Run>],
    pricing: Pricing,
    sample_spacing: f64,
) -> Accepted {
    let pairs: Vec<[usize; 2]> = (0..runs.len())
        .flat_map(|i| (i + 1..runs.len()).map(move |j| [i, j]))
        .filter(|&[i, j]| runs[i].is_some() && runs[j].is_some())
        .collect();
    let judge = Judge {
        cloud,
        primitives,
        pricing,
        spacing: sample_spacing,
    };
    // Pairs in parallel, collected in order: the same model on any number of threads.
    let mut scored: Vec<Scored> = pairs
        .par_iter()
        .filter_map(|&[i, j]| {
            let junction = Junction::of([i, j], runs[i].as_ref()?, runs[j].as_ref()?)?;
            judge.best_elbow(junction).filter(|s| s.gain > 0.0)
        })
        .collect();
    scored.sort_by(|a, b| (b.gain.total_cmp(&a.gain)).then(a.junction.ids.cmp(&b.junction.ids)));
    accept(runs, scored)
}

/// Each run cut by an elbow (its `extent` not its whole), refitted on its members that
/// lie within the extent and at least a tube radius clear of each cut end; `None` for
/// the others and where too few points remain or the fit fails. The refitted run keeps
/// its length, centred on the foot of its old centre on the new axis.
fn refit_joined(
    cloud: Cloud,
    kept: &[Kept],
    runs: &[Option<Run>],
    extent: &[(f64, f64)],
) -> Vec<Option<Run>> {
    (0..runs.len())
        .into_par_iter()
        .map(|i| {
            let run = runs[i].as_ref()?;
            let (lo, hi) = extent[i];
            let whole = run.whole();
            if (lo, hi) == whole {
                return None;
            }
            let clear = REFIT_CLEARANCE_RADII * run.radius;
            let lo = if lo > whole.0 { lo + clear } else { lo };
            let hi = if hi < whole.1 { hi - clear } else { hi };
            let straight: Vec<Point3<f64>> = (kept[i].members.iter())
                .map(|&j| cloud.points[j])
                .filter(|p| (lo..=hi).contains(&(p - run.centre).dot(&run.axis)))
                .collect();
            if straight.len() < MIN_REFIT_POINTS {
                return None;
            }
            let start = CylinderFit {
                point: run.centre,
                axis: run.axis,
                radius: run.radius,
                length: 2.0 * run.half,
                rms: 0.0,
            };
            // A refit that leaves the run's tube (its radius off by more than two joined
            // runs' may differ) fitted something else: the run stays as it was.
            let fit = refit_cylinder(&straight, &start)
                .filter(|f| (f.radius - run.radius).abs() <= RADIUS_TOLERANCE * run.radius)?;
            let axis = if fit.axis.dot(&run.axis) < 0.0 {
                -fit.axis
            } else {
                fit.axis
            };
            let tilt = UnitQuaternion::rotation_between(&run.axis, &axis)?;
            let centre = fit.point + axis * (run.centre - fit.point).dot(&axis);
            let shape = Shape::Cylinder {
                length: 2.0 * run.half,
                radius: fit.radius,
            };
            Run::of(&Primitive::new(
                shape,
                Pose::new(tilt * run.rotation, centre.coords),
            ))
        })
        .collect()
}

/// What [`accept`] decided: each run's extent along its axis, which primitives an elbow
/// replaced, and the elbows with the two runs each joins.
struct Accepted {
    extent: Vec<(f64, f64)>,
    dropped: Vec<bool>,
    elbows: Vec<(Primitive, [usize; 2])>,
}

/// The scored junctions taken, the largest gains first: each run end and each replaced
/// patch at most once, each run left at least [`MIN_RUN_RADII`] long.
fn accept(runs: &[Option<Run>], scored: Vec<Scored>) -> Accepted {
    let mut extent: Vec<(f64, f64)> = (runs.iter())
        .map(|r| r.map_or((0.0, 0.0), |r| r.whole()))
        .collect();
    let mut end_taken = vec![[false; 2]; runs.len()];
    let mut dropped = vec![false; runs.len()];
    let mut elbows = Vec::new();
    for Scored {
        junction: j,
        bend,
        replaced,
        ..
    } in scored
    {
        let side = |k: usize| usize::from(j.ends[k] > 0.0);
        let cuts = [0, 1].map(|k| {
            let (lo, hi) = extent[j.ids[k]];
            let at = j.cut(k, bend);
            if j.ends[k] > 0.0 { (lo, at) } else { (at, hi) }
        });
        let fits = (0..2).all(|k| {
            let id = j.ids[k];
            !end_taken[id][side(k)]
                && !dropped[id]
                && cuts[k].1 - cuts[k].0 >= MIN_RUN_RADII * j.runs[k].radius
        });
        // A patch already dropped, or a run an accepted elbow joins, is not replaced.
        let taken = |k: usize| dropped[k] || end_taken[k].contains(&true);
        if !fits || replaced.iter().any(|&k| taken(k)) {
            continue;
        }
        for k in 0..2 {
            extent[j.ids[k]] = cuts[k];
            end_taken[j.ids[k]][side(k)] = true;
        }
        for &k in &replaced {
            dropped[k] = true;
        }
        elbows.push((j.elbow(bend), j.ids));
    }
    Accepted {
        extent,
        dropped,
        elbows,
    }
}

/// The points within `cap` of `elbow`, ascending.
fn members_of(cloud: Cloud, elbow: &Primitive, cap: f64) -> Vec<usize> {
    let reach = elbow.bounding_radius() + cap;
    let mut members: Vec<usize> = (cloud.index)
        .within(&elbow.center(), reach * reach)
        .into_iter()
        .map(|(j, _)| j as usize)
        .filter(|&j| elbow.distance(&cloud.points[j]) <= cap)
        .collect();
    members.sort_unstable();
    members
}

#[cfg(test)]
#[path = "elbows_tests.rs"]
mod tests;
