//! A ground under the tree, found and set aside before growth.
//!
//! A scan cut out of its scene often keeps a disc of ground around the trunk's foot; grown
//! as a tree it becomes hundreds of metres of branches along the ground (the coffee tree
//! with a 1.5 m disc of ground: 210–260 m of axis against 34.8 m, `docs/validation.md`).
//! The ground is the lowest surface that spreads sideways. On an x–y grid (cells of 4, 8
//! and 16 median spacings, for grounds sampled more sparsely than the tree; the width that
//! finds the most ground points is kept) each cell's
//! lowest points are a sample of it when the points within a band above them fill the cell
//! in two directions ([`MIN_FILL`]: the ring where a trunk cut out at one height meets a
//! plane is a line in each cell, not a surface). Then
//! - a seed: a plane through most of the filled cells (RANSAC, then least squares), near
//!   horizontal (Z up, at most [`MAX_TILT_DEG`] off), whose cells form one region of at
//!   least [`MIN_SURFACE_CELLS`] cells and [`MIN_WIDTH_CELLS`] across (a horizontal branch
//!   is one cell wide);
//! - grown over neighbouring filled cells whose ground level differs by at most
//!   [`MAX_SLOPE_DEG`] of slope, so undulating and sloping ground is followed;
//! - taken for the ground only if next to nothing lies below it ([`MAX_BELOW_SHARE`] of
//!   the points): a flat crown base with the trunk under it is not a ground;
//! - its thickness from the heights of its cells' points above the surface: up to where
//!   their density falls to [`DROP_SHARE`] of its peak (grass, litter, noise), at most
//!   [`MAX_THICKNESS_M`].
//!
//! Points within [`REACH_CELLS`] cells of the ground's cells, below its surface or less
//! than its thickness above it, are ground.

use std::collections::{HashMap, HashSet, VecDeque};

use nalgebra::{Matrix3, Vector3};
use rand_xoshiro::SplitMix64;
use rand_xoshiro::rand_core::{RngCore, SeedableRng};
use serde::Serialize;

/// Grid cell widths tried, in median point spacings: a ground sampled like the tree fills
/// cells of 4 spacings; one scanned from farther, more sparsely, needs wider cells.
const CELL_SPACINGS: [f64; 3] = [4.0, 8.0, 16.0];
/// Half-width of the band above a cell's lowest points that holds its ground points, and
/// of the band around the seed plane, in cell widths.
const BAND_CELLS: f64 = 0.5;
/// Steepest seed plane taken for a ground, degrees from horizontal (a 10° slope is steep
/// ground; 30° leaves a margin for tilted scans).
pub const MAX_TILT_DEG: f64 = 30.0;
/// Steepest step between neighbouring ground cells, degrees.
pub const MAX_SLOPE_DEG: f64 = 45.0;
/// Fewest filled cells in the seed region.
pub const MIN_SURFACE_CELLS: usize = 24;
/// A cell is filled when the points in its band spread across it this much (smaller
/// principal standard deviation over the cell width; a uniformly filled cell has 0.29, the
/// points of a wall crossing it next to none).
pub const MIN_FILL: f64 = 0.12;
/// Points a cell's band needs to be judged filled.
const MIN_CELL_POINTS: usize = 4;
/// The cell's lowest points: its band starts at the lowest but this many (one or two
/// stray returns under a ground do not move it).
const LOW_SKIP: usize = 2;
/// Narrowest seed accepted: smaller principal standard deviation of its cells' centres, in
/// cells.
pub const MIN_WIDTH_CELLS: f64 = 2.0;
/// Largest share of all points lower than the ground's lowest cell by more than
/// [`BELOW_BANDS`] bands.
pub const MAX_BELOW_SHARE: f64 = 0.002;
/// How far below the ground, in bands, a point counts as below it.
pub const BELOW_BANDS: f64 = 3.0;
/// Plane trials (three cells each), a fixed sequence: the result does not change from run
/// to run.
const TRIALS: usize = 300;
/// Least-squares refits of the best trial on its inliers.
const REFITS: usize = 3;
/// The surface reaches this many cells beyond the ground's filled cells (cells at its edge
/// and gaps in it, too sparse to be judged filled), interpolated from the filled cells
/// within that reach.
const REACH_CELLS: i64 = 2;
/// Seed of the trials.
const SEED: u64 = 0x6772_6f75_6e64;
/// The thickness ends where the density of heights above the surface falls below this
/// share of its peak.
pub const DROP_SHARE: f64 = 0.02;
/// Thinnest ground layer set aside, in median spacings (a surface sampled at the spacing,
/// with its noise).
const MIN_THICKNESS_SPACINGS: f64 = 2.0;
/// Thickest ground layer set aside, metres (tall grass and undergrowth are beyond what a
/// plane and a layer describe).
pub const MAX_THICKNESS_M: f64 = 0.3;

/// The ground found under a tree ([`crate::ColonizeConfig::remove_ground`]); its points
/// were set aside before growth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ground {
    /// Unit normal of the plane the ground was seeded from, pointing up (z > 0).
    pub normal: [f64; 3],
    /// That plane is normal · p = offset_m.
    pub offset_m: f64,
    /// Points less than this above the ground's surface (and all below it), within two
    /// cells of its cells, are ground, metres.
    pub thickness_m: f64,
    /// Points set aside as ground.
    pub points: usize,
    /// Grid cells of the ground.
    pub cells: usize,
    /// Width of a grid cell, metres.
    pub cell_m: f64,
    /// Indices (into the points given) of the ground's points, in order.
    #[serde(skip)]
    pub indices: Vec<usize>,
}

type Cell = (i64, i64);

fn cell_of(p: &[f64; 3], cell_m: f64) -> Cell {
    // `as` saturates: a far coordinate over a tiny cell cannot overflow.
    (
        (p[0] / cell_m).floor() as i64,
        (p[1] / cell_m).floor() as i64,
    )
}

fn height(n: &[f64; 3], offset_m: f64, p: &[f64; 3]) -> f64 {
    n[0] * p[0] + n[1] * p[1] + n[2] * p[2] - offset_m
}

/// A plane through three points, normal up; `None` when they are on a line or the plane
/// is steeper than [`MAX_TILT_DEG`].
fn plane3(a: &[f64; 3], b: &[f64; 3], c: &[f64; 3]) -> Option<([f64; 3], f64)> {
    let (a, b, c) = (Vector3::from(*a), Vector3::from(*b), Vector3::from(*c));
    let n = (b - a).cross(&(c - a));
    let len = n.norm();
    if !(len > 0.0 && len.is_finite()) {
        return None;
    }
    let mut n = n / len;
    if n.z < 0.0 {
        n = -n;
    }
    (n.z >= MAX_TILT_DEG.to_radians().cos()).then(|| ([n.x, n.y, n.z], n.dot(&a)))
}

/// Least-squares plane z = a·x + b·y + c through `pts`, as (unit normal up, offset).
fn plane_ls(pts: &[[f64; 3]]) -> Option<([f64; 3], f64)> {
    let n = pts.len() as f64;
    let m = pts
        .iter()
        .fold([0.0; 3], |s, p| [s[0] + p[0], s[1] + p[1], s[2] + p[2]]);
    let m = [m[0] / n, m[1] / n, m[2] / n];
    let mut ata = Matrix3::<f64>::zeros();
    let mut atb = Vector3::<f64>::zeros();
    for p in pts {
        let r = Vector3::new(p[0] - m[0], p[1] - m[1], 1.0);
        ata += r * r.transpose();
        atb += r * (p[2] - m[2]);
    }
    let s = ata.lu().solve(&atb)?;
    let normal = Vector3::new(-s.x, -s.y, 1.0).normalize();
    let at = Vector3::new(m[0], m[1], m[2] + s.z);
    if !normal.iter().all(|c| c.is_finite()) || normal.z < MAX_TILT_DEG.to_radians().cos() {
        return None;
    }
    Some(([normal.x, normal.y, normal.z], normal.dot(&at)))
}

/// Running sums of 2D points: count, Σx, Σy, Σxx, Σxy, Σyy.
#[derive(Default, Clone, Copy)]
struct Spread([f64; 6]);

impl Spread {
    fn add(&mut self, x: f64, y: f64) {
        let s = &mut self.0;
        s[0] += 1.0;
        s[1] += x;
        s[2] += y;
        s[3] += x * x;
        s[4] += x * y;
        s[5] += y * y;
    }

    /// Smaller principal standard deviation.
    fn minor_std(&self) -> f64 {
        let s = &self.0;
        let n = s[0];
        if n < 2.0 {
            return 0.0;
        }
        let (mx, my) = (s[1] / n, s[2] / n);
        let sxx = (s[3] / n - mx * mx).max(0.0);
        let sxy = s[4] / n - mx * my;
        let syy = (s[5] / n - my * my).max(0.0);
        let half_trace = 0.5 * (sxx + syy);
        let det = sxx * syy - sxy * sxy;
        (half_trace - (half_trace * half_trace - det).max(0.0).sqrt())
            .max(0.0)
            .sqrt()
    }
}

/// A filled cell: where its ground lies.
#[derive(Clone, Copy)]
struct Sample {
    /// Centroid of the band's points: x, y, and their median z.
    at: [f64; 3],
    /// The lowest point but [`LOW_SKIP`].
    low_m: f64,
}

/// The ground under a tree (Z up), `None` when there is none.
pub(crate) fn find_ground(pts: &[[f64; 3]], spacing_m: f64) -> Option<Ground> {
    // Every cell width, the one that finds the most: too fine a grid leaves a sparse
    // ground's cells unfilled, with its points between them.
    CELL_SPACINGS
        .iter()
        .filter_map(|k| ground_at(pts, spacing_m, k * spacing_m))
        .max_by_key(|g| g.points)
}

/// The filled cells of a grid of `cell_m`.
fn samples(pts: &[[f64; 3]], cell_m: f64, band_m: f64) -> HashMap<Cell, Sample> {
    let mut members: HashMap<Cell, Vec<usize>> = HashMap::new();
    for (i, p) in pts.iter().enumerate() {
        members.entry(cell_of(p, cell_m)).or_default().push(i);
    }
    let mut out = HashMap::new();
    let mut z: Vec<f64> = Vec::new();
    for (cell, idx) in members {
        if idx.len() < MIN_CELL_POINTS {
            continue;
        }
        z.clear();
        z.extend(idx.iter().map(|&i| pts[i][2]));
        let (_, &mut low_m, _) = z.select_nth_unstable_by(LOW_SKIP, f64::total_cmp);
        let mut spread = Spread::default();
        let mut band: Vec<f64> = Vec::new();
        for &i in &idx {
            let p = &pts[i];
            if (p[2] - low_m).abs() <= band_m {
                spread.add(p[0], p[1]);
                band.push(p[2]);
            }
        }
        if band.len() < MIN_CELL_POINTS || spread.minor_std() < MIN_FILL * cell_m {
            continue;
        }
        let mid = band.len() / 2;
        let (_, &mut z_m, _) = band.select_nth_unstable_by(mid, f64::total_cmp);
        let n = spread.0[0];
        out.insert(
            cell,
            Sample {
                at: [spread.0[1] / n, spread.0[2] / n, z_m],
                low_m,
            },
        );
    }
    out
}

fn ground_at(pts: &[[f64; 3]], spacing_m: f64, cell_m: f64) -> Option<Ground> {
    let band_m = BAND_CELLS * cell_m;
    if !(cell_m > 0.0 && cell_m.is_finite() && spacing_m > 0.0) {
        return None;
    }
    let filled = samples(pts, cell_m, band_m);
    if filled.len() < MIN_SURFACE_CELLS {
        return None;
    }
    let (n, d, seed) = seed_plane(&filled, band_m)?;
    let mut centres = Spread::default();
    for c in &seed {
        centres.add(c.0 as f64, c.1 as f64);
    }
    if seed.len() < MIN_SURFACE_CELLS || centres.minor_std() < MIN_WIDTH_CELLS {
        return None;
    }
    let ground = grow_region(seed, &filled, band_m);
    // Next to nothing below it.
    let lowest = ground
        .iter()
        .map(|c| filled[c].low_m)
        .fold(f64::INFINITY, f64::min);
    let below = pts
        .iter()
        .filter(|p| p[2] < lowest - BELOW_BANDS * band_m)
        .count();
    if below as f64 > MAX_BELOW_SHARE * pts.len() as f64 {
        return None;
    }
    // Heights above the surface of the points in the ground's cells.
    let slope = [-n[0] / n[2], -n[1] / n[2]];
    let surface = |p: &[f64; 3]| {
        let c = cell_of(p, cell_m);
        let reach = REACH_CELLS as f64 * cell_m;
        let (mut sum, mut weight) = (0.0, 0.0);
        for dx in -REACH_CELLS..=REACH_CELLS {
            for dy in -REACH_CELLS..=REACH_CELLS {
                let k = (c.0.saturating_add(dx), c.1.saturating_add(dy));
                if !ground.contains(&k) {
                    continue;
                }
                let s = filled[&k].at;
                let w = ((1.0 - (p[0] - s[0]).abs() / reach).max(0.0)
                    * (1.0 - (p[1] - s[1]).abs() / reach).max(0.0))
                .max(1e-9);
                sum += w * (s[2] + slope[0] * (p[0] - s[0]) + slope[1] * (p[1] - s[1]));
                weight += w;
            }
        }
        (weight > 0.0).then(|| p[2] - sum / weight)
    };
    // Points higher than any ground cell's level could reach are not looked at (the crown:
    // most of a tree).
    let top_m = ground
        .iter()
        .map(|c| filled[c].at[2])
        .fold(f64::NEG_INFINITY, f64::max)
        + (slope[0].hypot(slope[1]) + 1.0) * (REACH_CELLS + 1) as f64 * cell_m
        + MAX_THICKNESS_M;
    let heights: Vec<Option<f64>> = pts
        .iter()
        .map(|p| if p[2] > top_m { None } else { surface(p) })
        .collect();
    let thickness_m = thickness(&heights, spacing_m, band_m);
    let indices: Vec<usize> = heights
        .iter()
        .enumerate()
        .filter(|(_, h)| h.is_some_and(|h| h < thickness_m))
        .map(|(i, _)| i)
        .collect();
    Some(Ground {
        normal: n,
        offset_m: d,
        thickness_m,
        points: indices.len(),
        cells: ground.len(),
        cell_m,
        indices,
    })
}

/// The seed: a plane through most filled cells (RANSAC over the lower half, least-squares
/// refits) and the largest connected region of cells on it.
fn seed_plane(filled: &HashMap<Cell, Sample>, band_m: f64) -> Option<([f64; 3], f64, Vec<Cell>)> {
    let mut cells: Vec<(Cell, Sample)> = filled.iter().map(|(c, s)| (*c, *s)).collect();
    cells.sort_by(|a, b| a.1.at[2].total_cmp(&b.1.at[2]).then(a.0.cmp(&b.0)));
    // The seed plane: trials draw from the lower half of the cells (a ground's are the
    // lowest), inliers are counted over all.
    let pool = (cells.len() / 2).max(MIN_SURFACE_CELLS).min(cells.len());
    let mut rng = SplitMix64::seed_from_u64(SEED);
    let mut draw = || (rng.next_u64() % pool as u64) as usize;
    let on = |n: [f64; 3], d: f64| {
        cells
            .iter()
            .filter(move |(_, s)| height(&n, d, &s.at).abs() <= band_m)
    };
    let mut best: Option<([f64; 3], f64, usize)> = None;
    for _ in 0..TRIALS {
        let (a, b, c) = (draw(), draw(), draw());
        if a == b || b == c || a == c {
            continue;
        }
        let Some((n, d)) = plane3(&cells[a].1.at, &cells[b].1.at, &cells[c].1.at) else {
            continue;
        };
        let count = on(n, d).count();
        if best.is_none_or(|(_, _, k)| count > k) {
            best = Some((n, d, count));
        }
    }
    let (mut n, mut d, _) = best?;
    for _ in 0..REFITS {
        let at: Vec<[f64; 3]> = on(n, d).map(|(_, s)| s.at).collect();
        if at.len() < 3 {
            return None;
        }
        (n, d) = plane_ls(&at)?;
    }
    let seed = largest_region(&on(n, d).map(|(c, _)| *c).collect());
    Some((n, d, seed))
}

/// The seed grown over neighbouring filled cells along the ground's own slope (at most
/// [`MAX_SLOPE_DEG`] between cells).
fn grow_region(seed: Vec<Cell>, filled: &HashMap<Cell, Sample>, band_m: f64) -> HashSet<Cell> {
    let max_step = MAX_SLOPE_DEG.to_radians().tan();
    let mut ground: HashSet<Cell> = seed.iter().copied().collect();
    let mut queue: VecDeque<Cell> = seed.into_iter().collect();
    while let Some(c) = queue.pop_front() {
        let here = filled[&c].at;
        for (dx, dy) in NEIGHBOURS {
            let next = (c.0.saturating_add(dx), c.1.saturating_add(dy));
            if ground.contains(&next) {
                continue;
            }
            if let Some(s) = filled.get(&next) {
                let run = (s.at[0] - here[0]).hypot(s.at[1] - here[1]);
                if (s.at[2] - here[2]).abs() <= max_step * run + band_m {
                    ground.insert(next);
                    queue.push_back(next);
                }
            }
        }
    }
    ground
}

const NEIGHBOURS: [(i64, i64); 8] = [
    (-1, -1),
    (-1, 0),
    (-1, 1),
    (0, -1),
    (0, 1),
    (1, -1),
    (1, 0),
    (1, 1),
];

/// Where the density of heights above the surface falls below [`DROP_SHARE`] of its peak
/// (bins of half a spacing), one bin of margin, at least [`MIN_THICKNESS_SPACINGS`]
/// spacings and at most [`MAX_THICKNESS_M`] (which wins where the two cross).
fn thickness(heights: &[Option<f64>], spacing_m: f64, band_m: f64) -> f64 {
    let bin = (0.5 * spacing_m).max(1e-3);
    let bins = ((MAX_THICKNESS_M + band_m) / bin).ceil() as usize + 1;
    let mut count = vec![0usize; bins];
    for h in heights.iter().flatten() {
        let k = (h + band_m) / bin;
        if k >= 0.0 && (k as usize) < bins {
            count[k as usize] += 1;
        }
    }
    let (peak, &top) = count
        .iter()
        .enumerate()
        .max_by_key(|(i, c)| (**c, std::cmp::Reverse(*i)))
        .unwrap_or((0, &0));
    let end = (peak..bins)
        .find(|&k| (count[k] as f64) < DROP_SHARE * top as f64)
        .unwrap_or(bins);
    // Top edge of the last dense bin, plus one bin.
    let t = (end + 1) as f64 * bin - band_m;
    // Not `clamp`: in a cloud sparser than 15 cm the floor is above the cap (the cap wins).
    t.max(MIN_THICKNESS_SPACINGS * spacing_m)
        .min(MAX_THICKNESS_M)
}

/// The largest 8-connected set of cells.
fn largest_region(cells: &HashSet<Cell>) -> Vec<Cell> {
    let mut seen: HashSet<Cell> = HashSet::with_capacity(cells.len());
    let mut best: Vec<Cell> = Vec::new();
    let mut start: Vec<&Cell> = cells.iter().collect();
    start.sort();
    for &s in start {
        if !seen.insert(s) {
            continue;
        }
        let mut region = vec![s];
        let mut queue = VecDeque::from([s]);
        while let Some((x, y)) = queue.pop_front() {
            for (dx, dy) in NEIGHBOURS {
                let c = (x.saturating_add(dx), y.saturating_add(dy));
                if cells.contains(&c) && seen.insert(c) {
                    region.push(c);
                    queue.push_back(c);
                }
            }
        }
        if region.len() > best.len() {
            best = region;
        }
    }
    best
}
