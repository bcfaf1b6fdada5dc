//! Translation by voting: for a fixed rotation `R` and scale `s`, every pair of a scene
//! point `p_j` and a model sample `m_k` votes for the translation `t = p_j − s R m_k`.
//! The object's points all vote for (about) the true translation, one vote each per
//! nearby model sample, while the outliers' votes spread over the whole domain; the
//! peak of the vote histogram is the translation that puts the most model samples on
//! scene points. This turns the 6-D pose search into a search over rotations (and
//! scale): each rotation particle takes its translation from the vote peak.
//!
//! Cost: the scene points are counted in a uniform grid of cells ([`VoteIndex`]) and the
//! rotated model samples in the same cells, so the vote histogram (one bin per cell) is
//! the correlation of the two count grids: (occupied model cells) × (cells of the
//! translation domain) multiply-adds, independent of the number of points and samples.
//! A peak is then refined at point level ([`mean_shift`]), touching only the points near
//! `t + s R m_k`.

use nalgebra::{Point3, Vector3};

/// Scene points bucketed in a uniform grid of cubic cells (compressed rows: the points of
/// cell `c` are `points[start[c]..start[c + 1]]`, cells in x-fastest order), with the
/// count of every cell, for [`vote_translation`] and [`mean_shift`]. Non-finite points
/// are left out.
#[derive(Debug, Clone)]
pub struct VoteIndex {
    lo: Point3<f64>,
    cell: f64,
    dims: [usize; 3],
    start: Vec<u32>,
    count: Vec<f32>,
    points: Vec<[f64; 3]>,
}

/// Largest number of cells along one axis of a [`VoteIndex`].
const MAX_INDEX_CELLS: usize = 64;

impl VoteIndex {
    /// Buckets `points` in cells of side about `cell` (scene units; enlarged so that no
    /// axis has more than 64 cells).
    pub fn new(points: &[Point3<f64>], cell: f64) -> Self {
        let finite: Vec<[f64; 3]> = points
            .iter()
            .filter(|p| p.iter().all(|c| c.is_finite()))
            .map(|p| [p.x, p.y, p.z])
            .collect();
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in &finite {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        if finite.is_empty() {
            (lo, hi) = ([0.0; 3], [0.0; 3]);
        }
        let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        let mut cell = if cell.is_finite() && cell > 0.0 {
            cell
        } else {
            extent.max(1.0)
        };
        cell = cell
            .max(extent / MAX_INDEX_CELLS as f64)
            .max(f64::MIN_POSITIVE);
        let dims = [0, 1, 2].map(|a| (((hi[a] - lo[a]) / cell).floor() as usize + 1).max(1));
        let cell_of = |p: &[f64; 3]| {
            let c = [0, 1, 2].map(|a| (((p[a] - lo[a]) / cell) as usize).min(dims[a] - 1));
            c[0] + dims[0] * (c[1] + dims[1] * c[2])
        };
        let total = dims[0] * dims[1] * dims[2];
        let mut start = vec![0u32; total + 1];
        for p in &finite {
            start[cell_of(p) + 1] += 1;
        }
        for c in 0..total {
            start[c + 1] += start[c];
        }
        let mut fill = start.clone();
        let mut sorted = vec![[0.0; 3]; finite.len()];
        for p in &finite {
            let c = cell_of(p);
            sorted[fill[c] as usize] = *p;
            fill[c] += 1;
        }
        let count = start.windows(2).map(|w| (w[1] - w[0]) as f32).collect();
        VoteIndex {
            lo: Point3::from(lo),
            cell,
            dims,
            start,
            count,
            points: sorted,
        }
    }

    /// The cell side (scene units): the bin of [`vote_translation`].
    pub fn cell(&self) -> f64 {
        self.cell
    }

    /// Number of indexed points.
    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when no point is indexed.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Calls `f` on every indexed point of the cells that overlap the box `[lo, hi]`
    /// (a superset of the points inside it).
    #[inline]
    fn for_each_near(&self, lo: &Point3<f64>, hi: &Point3<f64>, mut f: impl FnMut(&[f64; 3])) {
        let mut range = [(0usize, 0usize); 3];
        for a in 0..3 {
            let l = (lo[a] - self.lo[a]) / self.cell;
            let h = (hi[a] - self.lo[a]) / self.cell;
            if !(h >= 0.0 && l < self.dims[a] as f64) {
                return;
            }
            range[a] = (l.max(0.0) as usize, (h as usize).min(self.dims[a] - 1));
        }
        let (nx, nxy) = (self.dims[0], self.dims[0] * self.dims[1]);
        for z in range[2].0..=range[2].1 {
            for y in range[1].0..=range[1].1 {
                let row = y * nx + z * nxy;
                let (a, b) = (
                    self.start[row + range[0].0] as usize,
                    self.start[row + range[0].1 + 1] as usize,
                );
                self.points[a..b].iter().for_each(&mut f);
            }
        }
    }
}

/// One peak of a translation vote.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VotePeak {
    /// The translation (scene units).
    pub translation: Vector3<f64>,
    /// The votes of its 3 × 3 × 3-cell window.
    pub votes: f64,
}

/// Largest number of histogram bins of one vote (larger votes give no peaks).
const MAX_BINS: usize = 1 << 21;

/// Votes for the translation of a model whose samples, rotated and scaled, are
/// `offsets` (`s R m_k`, scene units), given the scene points in `index`: the pair
/// `(p_j, m_k)` votes for `t = p_j − s R m_k`, for `t` in the domain `[lo, hi]` widened
/// by a cell.
///
/// The votes are counted per cell of the index's grid: a point in cell `v` and a sample
/// in cell `w` (cells of side `c` = [`VoteIndex::cell`]) vote for the bin `v − w`, whose
/// translations lie within one cell of `index.lo + (v − w) c`; the histogram is the
/// correlation of the scene's and the model's cell counts. A peak is the bin with the
/// most votes in its 3 × 3 × 3-bin window (which holds all of a bin's spread), at
/// least 3 bins from the peaks before it, placed at the vote-weighted mean of the
/// window's bins (above the window's least bin: the outliers' votes are about uniform
/// over a window), which is about one cell precise. With `steps` > 0 each peak's
/// translation is then refined with the point-level votes ([`refine_peak`]).
///
/// Returns up to `peaks` peaks, most votes first (ties: lowest bin first); none for an
/// empty domain or index, no finite offsets, or a histogram of more than 2²¹ bins.
pub fn vote_translation(
    index: &VoteIndex,
    offsets: &[Vector3<f64>],
    lo: &Point3<f64>,
    hi: &Point3<f64>,
    peaks: usize,
    steps: usize,
) -> Vec<VotePeak> {
    if peaks == 0
        || index.is_empty()
        || !lo.iter().chain(hi.iter()).all(|v| v.is_finite())
        || (0..3).any(|a| lo[a] > hi[a])
    {
        return Vec::new();
    }
    let model = model_cells(offsets, index.cell);
    if model.is_empty() {
        return Vec::new();
    }
    let Some(bins) = HistogramBins::new(index, &model, lo, hi) else {
        return Vec::new();
    };
    let hist = bins.accumulate(index, &model);
    let window = bins.window_sums(&hist);
    bins.pick_peaks(&window, peaks)
        .into_iter()
        .map(|(b, votes)| {
            let mut translation = index.lo.coords + bins.peak_mean(&hist, b) * index.cell;
            if steps > 0 {
                translation = refine_peak(index, offsets, translation, steps);
            }
            VotePeak {
                translation,
                votes: votes as f64,
            }
        })
        .collect()
}

/// The model's cell counts: cell `w` (of side `c`) holds the offsets in
/// `[w c, (w + 1) c)`; sorted by cell, non-finite or huge offsets left out.
fn model_cells(offsets: &[Vector3<f64>], c: f64) -> Vec<([i64; 3], f32)> {
    let mut cells: Vec<[i64; 3]> = offsets
        .iter()
        .filter(|o| o.iter().all(|v| v.is_finite() && v.abs() < 1e15 * c))
        .map(|o| [0, 1, 2].map(|a| floor_to_i64(o[a] / c)))
        .collect();
    cells.sort_unstable();
    let mut model: Vec<([i64; 3], f32)> = Vec::new();
    for w in cells {
        match model.last_mut() {
            Some((last, n)) if *last == w => *n += 1.0,
            _ => model.push((w, 1.0)),
        }
    }
    model
}

/// `⌊v⌋` for a finite `v` of magnitude below 2⁶³, without a call to `floor` (which
/// baseline x86-64 does not inline): truncation, one less for a negative non-integer.
#[inline]
fn floor_to_i64(v: f64) -> i64 {
    let t = v as i64;
    t - ((t as f64) > v) as i64
}

/// The translation histogram's bins: bin `u` (translation ≈ `index.lo + (ulo + u) c`)
/// for `u` in `0..dims`, row-major with x fastest.
struct HistogramBins {
    /// The first bin's cell offset from the index's corner.
    ulo: [i64; 3],
    /// Bins along each axis.
    dims: [usize; 3],
}

impl HistogramBins {
    /// The bins of the domain `[lo, hi]`, one spare on each side, and only those some
    /// (scene cell, model cell) pair reaches; `None` when there are none or more than
    /// [`MAX_BINS`].
    fn new(
        index: &VoteIndex,
        model: &[([i64; 3], f32)],
        lo: &Point3<f64>,
        hi: &Point3<f64>,
    ) -> Option<Self> {
        let c = index.cell;
        let (wlo, whi) = model
            .iter()
            .fold(([i64::MAX; 3], [i64::MIN; 3]), |(l, h), (w, _)| {
                (
                    [0, 1, 2].map(|a| l[a].min(w[a])),
                    [0, 1, 2].map(|a| h[a].max(w[a])),
                )
            });
        let mut ulo = [0i64; 3];
        let mut dims = [0usize; 3];
        for a in 0..3 {
            let from = ((lo[a] - index.lo[a]) / c).floor().max(-1e15) as i64 - 1;
            let to = ((hi[a] - index.lo[a]) / c).ceil().min(1e15) as i64 + 1;
            let (from, to) = (from.max(-whi[a]), to.min(index.dims[a] as i64 - 1 - wlo[a]));
            if from > to {
                return None;
            }
            ulo[a] = from;
            dims[a] = (to - from + 1) as usize;
        }
        if dims
            .iter()
            .try_fold(1usize, |p, &d| p.checked_mul(d))
            .is_none_or(|n| n > MAX_BINS)
        {
            return None;
        }
        Some(HistogramBins { ulo, dims })
    }

    /// Bins of one z layer and of one xy row.
    fn strides(&self) -> (usize, usize) {
        (self.dims[0], self.dims[0] * self.dims[1])
    }

    /// The votes of every bin: each (scene cell, model cell) pair adds the scene cell's
    /// points × the model cell's samples to the bin of their difference.
    fn accumulate(&self, index: &VoteIndex, model: &[([i64; 3], f32)]) -> Vec<f32> {
        let (ulo, dims) = (self.ulo, self.dims);
        let (nx, nxy) = self.strides();
        let mut hist = vec![0.0f32; nxy * dims[2]];
        let (sx, sxy) = (index.dims[0], index.dims[0] * index.dims[1]);
        for (w, m) in model {
            // Scene cells v = u + w for the bins u of the histogram.
            let range = |a: usize| {
                let from = (ulo[a] + w[a]).max(0);
                let to = (ulo[a] + dims[a] as i64 - 1 + w[a]).min(index.dims[a] as i64 - 1);
                (from, to)
            };
            let (x, y, z) = (range(0), range(1), range(2));
            if x.0 > x.1 || y.0 > y.1 || z.0 > z.1 {
                continue;
            }
            let len = (x.1 - x.0 + 1) as usize;
            for vz in z.0..=z.1 {
                for vy in y.0..=y.1 {
                    let src = x.0 as usize + sx * vy as usize + sxy * vz as usize;
                    let dst = (x.0 - w[0] - ulo[0]) as usize
                        + nx * (vy - w[1] - ulo[1]) as usize
                        + nxy * (vz - w[2] - ulo[2]) as usize;
                    for (h, n) in hist[dst..dst + len]
                        .iter_mut()
                        .zip(&index.count[src..src + len])
                    {
                        *h += n * m;
                    }
                }
            }
        }
        hist
    }

    /// 3 × 3 × 3 window sums of `hist` (separable box filter: three passes of a 3-bin
    /// sum along x, y and z, each bin's neighbours outside the grid counting 0).
    fn window_sums(&self, hist: &[f32]) -> Vec<f32> {
        let (nx, nxy) = self.strides();
        let mut window = hist.to_vec();
        let mut src = vec![0.0f32; window.len()];
        for (axis, stride) in [(0, 1), (1, nx), (2, nxy)] {
            src.copy_from_slice(&window);
            let n = self.dims[axis];
            // Bins k = outer · (n · stride) + i · stride + inner, i along the axis.
            for (out_block, src_block) in window
                .chunks_exact_mut(n * stride)
                .zip(src.chunks_exact(n * stride))
            {
                for i in 0..n {
                    let row = &mut out_block[i * stride..(i + 1) * stride];
                    if i > 0 {
                        let before = &src_block[(i - 1) * stride..i * stride];
                        row.iter_mut().zip(before).for_each(|(o, b)| *o += b);
                    }
                    if i + 1 < n {
                        let after = &src_block[(i + 1) * stride..(i + 2) * stride];
                        row.iter_mut().zip(after).for_each(|(o, a)| *o += a);
                    }
                }
            }
        }
        window
    }

    /// Up to `peaks` bins with the most window votes (ties: lowest bin first), each at
    /// least 3 bins along some axis from those picked before, with their window votes.
    fn pick_peaks(&self, window: &[f32], peaks: usize) -> Vec<([i64; 3], f32)> {
        let (nx, nxy) = self.strides();
        let mut order: Vec<(f32, usize)> = window
            .iter()
            .enumerate()
            .filter(|(_, v)| **v > 0.0)
            .map(|(k, v)| (*v, k))
            .collect();
        let keep = (64 * peaks).max(64);
        let by_votes = |a: &(f32, usize), b: &(f32, usize)| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1));
        if order.len() > keep {
            order.select_nth_unstable_by(keep - 1, by_votes);
            order.truncate(keep);
        }
        order.sort_unstable_by(by_votes);
        let bin_of = |k: usize| [k % nx, (k / nx) % self.dims[1], k / nxy].map(|v| v as i64);
        let mut picked: Vec<([i64; 3], f32)> = Vec::with_capacity(peaks);
        for &(v, k) in &order {
            if picked.len() == peaks {
                break;
            }
            let b = bin_of(k);
            if picked
                .iter()
                .all(|(p, _)| (0..3).any(|a| (p[a] - b[a]).abs() >= 3))
            {
                picked.push((b, v));
            }
        }
        picked
    }

    /// The mean cell offset (from the index's corner, in cells) of the 3 × 3 × 3 window
    /// about bin `b`, its bins weighted by their votes above the window's least (the
    /// outliers' votes are about uniform over a window; left in, they would pull the
    /// mean to the peak bin's centre); bin `b` itself when the window is flat.
    fn peak_mean(&self, hist: &[f32], b: [i64; 3]) -> Vector3<f64> {
        let (ulo, dims) = (self.ulo, self.dims);
        let (nx, nxy) = self.strides();
        let mut bins = Vec::with_capacity(27);
        for dz in -1..=1i64 {
            for dy in -1..=1i64 {
                for dx in -1..=1i64 {
                    let q = [b[0] + dx, b[1] + dy, b[2] + dz];
                    if (0..3).all(|a| q[a] >= 0 && q[a] < dims[a] as i64) {
                        let h = hist[q[0] as usize + nx * q[1] as usize + nxy * q[2] as usize];
                        bins.push((q, h as f64));
                    }
                }
            }
        }
        let floor = bins.iter().map(|q| q.1).fold(f64::INFINITY, f64::min);

        let (mut sum, mut weight) = (Vector3::zeros(), 0.0);
        for (q, h) in &bins {
            let u = Vector3::new(
                (q[0] + ulo[0]) as f64,
                (q[1] + ulo[1]) as f64,
                (q[2] + ulo[2]) as f64,
            );
            sum += u * (h - floor);
            weight += h - floor;
        }
        if weight <= 0.0 {
            sum = Vector3::new(
                (b[0] + ulo[0]) as f64,
                (b[1] + ulo[1]) as f64,
                (b[2] + ulo[2]) as f64,
            );
            weight = 1.0;
        }
        sum / weight
    }
}

/// `start` (about one cell of `index` from a peak of the votes, as [`vote_translation`]
/// places it) moved to the peak at point level: [`fine_peak`] within 1.5 cells (bins of
/// a quarter cell), then `steps` [`mean_shift`] steps of radius a quarter cell.
pub fn refine_peak(
    index: &VoteIndex,
    offsets: &[Vector3<f64>],
    start: Vector3<f64>,
    steps: usize,
) -> Vector3<f64> {
    let c = index.cell();
    let t = fine_peak(index, offsets, start, 1.5 * c, 0.25 * c);
    mean_shift(index, offsets, t, 0.25 * c, steps).translation
}

/// The peak of the point-level votes within `half` (scene units, per axis) of `centre`:
/// the votes are counted in cubic bins of side `bin`, and the result is the mean of the
/// votes of the best 3 × 3 × 3-bin window, each bin weighted by its votes above the
/// window's least bin (the outliers' votes, about uniform over a window, would pull the
/// mean to the window's centre); `centre` where there are no votes.
pub fn fine_peak(
    index: &VoteIndex,
    offsets: &[Vector3<f64>],
    centre: Vector3<f64>,
    half: f64,
    bin: f64,
) -> Vector3<f64> {
    let valid = bin.is_finite() && bin > 0.0 && half.is_finite() && half > 0.0;
    if !(valid && centre.iter().all(|v| v.is_finite())) {
        return centre;
    }
    let n = ((2.0 * half / bin).ceil() as usize).clamp(3, 64);
    let bin = 2.0 * half / n as f64;
    let origin = centre - Vector3::repeat(half);
    let (lo, hi) = (
        Point3::from(origin),
        Point3::from(centre + Vector3::repeat(half)),
    );
    let mut count = vec![0u32; n * n * n];
    let mut sum = vec![Vector3::zeros(); n * n * n];
    for o in offsets.iter().filter(|o| o.iter().all(|v| v.is_finite())) {
        index.for_each_near(&(lo + o), &(hi + o), |p| {
            let t = Vector3::new(p[0] - o.x, p[1] - o.y, p[2] - o.z);
            let u = (t - origin) / bin;
            if u.iter().all(|&v| v >= 0.0 && v < n as f64) {
                let k = u.x as usize + n * (u.y as usize + n * u.z as usize);
                count[k] += 1;
                sum[k] += t;
            }
        });
    }
    let windows = forward_window_sums(&count, n);
    let mut best = (0u32, [0usize; 3]);
    for z in 0..n - 2 {
        for y in 0..n - 2 {
            for x in 0..n - 2 {
                let c = windows[x + n * (y + n * z)];
                if c > best.0 {
                    best = (c, [x, y, z]);
                }
            }
        }
    }
    if best.0 == 0 {
        return centre;
    }
    let [x, y, z] = best.1;
    let window: Vec<usize> = (0..27)
        .map(|d| (x + d % 3) + n * ((y + (d / 3) % 3) + n * (z + d / 9)))
        .collect();
    let floor = window.iter().map(|&k| count[k]).min().unwrap_or(0) as f64;
    let (mut s, mut w) = (Vector3::zeros(), 0.0);
    for &k in &window {
        if count[k] > 0 {
            let excess = count[k] as f64 - floor;
            s += sum[k] / count[k] as f64 * excess;
            w += excess;
        }
    }
    if w > 0.0 { s / w } else { centre }
}

/// The sums of `count` (an `n`³ grid, x fastest) over the 3 × 3 × 3 windows starting
/// at each bin (valid where the window fits, the first `n − 2` bins along each axis):
/// three passes of a forward 3-bin sum, 3 × 3 additions a bin instead of 27.
fn forward_window_sums(count: &[u32], n: usize) -> Vec<u32> {
    let mut sums = count.to_vec();
    for stride in [1, n, n * n] {
        let src = sums.clone();
        for (k, out) in sums.iter_mut().enumerate() {
            // Along this axis the bin is at (k / stride) % n; the window must fit.
            if (k / stride) % n + 2 < n {
                *out = src[k] + src[k + stride] + src[k + 2 * stride];
            }
        }
    }
    sums
}

/// The votes (count, sum) in the box `[lo, hi]`, and within `ball = (centre, radius)`
/// when given.
fn votes_in(
    index: &VoteIndex,
    offsets: &[Vector3<f64>],
    lo: &Point3<f64>,
    hi: &Point3<f64>,
    ball: Option<(Vector3<f64>, f64)>,
) -> (usize, Vector3<f64>) {
    let mut n = 0usize;
    let mut s = Vector3::zeros();
    let (centre, r2) = ball.map_or((Vector3::zeros(), f64::INFINITY), |(c, r)| (c, r * r));
    for o in offsets.iter().filter(|o| o.iter().all(|c| c.is_finite())) {
        let (qlo, qhi) = (lo + o, hi + o);
        index.for_each_near(&qlo, &qhi, |p| {
            let v = Vector3::new(p[0] - o.x, p[1] - o.y, p[2] - o.z);
            if (0..3).all(|a| v[a] >= lo[a] && v[a] <= hi[a]) && (v - centre).norm_squared() <= r2 {
                n += 1;
                s += v;
            }
        });
    }
    (n, s)
}

/// Moves `start` to the local mode of the votes (see [`vote_translation`]): `steps`
/// times, the mean of the votes within `radius` of the current translation (a flat
/// kernel); stops early where no vote is that close. Returns the translation and the
/// votes within `radius` of it.
pub fn mean_shift(
    index: &VoteIndex,
    offsets: &[Vector3<f64>],
    start: Vector3<f64>,
    radius: f64,
    steps: usize,
) -> VotePeak {
    let ball = |t: &Vector3<f64>| {
        let r = Vector3::repeat(radius);
        votes_in(
            index,
            offsets,
            &Point3::from(t - r),
            &Point3::from(t + r),
            Some((*t, radius)),
        )
    };
    let mut t = start;
    let (mut n, mut s) = ball(&t);
    for _ in 0..steps {
        if n == 0 || !(radius.is_finite() && radius > 0.0) {
            break;
        }
        t = s / n as f64;
        (n, s) = ball(&t);
    }
    VotePeak {
        translation: t,
        votes: n as f64,
    }
}

#[cfg(test)]
mod tests;
