//! Wood and leaves told apart by the shape of the points around each point.
//!
//! The surface normals of wood share an axis: a trunk or branch is a cylinder, whose
//! normals all lie across its axis; a twig thinner than the point spacing is a line of
//! points, whose fitted normals lie across the line too. Leaves hang at every angle, so
//! the normals in a clump of leaves (or in a crown a scanner resolves as a cloud of
//! returns) point every way. For each point, the normals of its neighbours (within
//! [`COHERENCE_SPACINGS`] spacings and at least [`MIN_COHERENCE_RADIUS_M`], the nearest
//! [`COHERENCE_NEIGHBOURS`]) are fitted with the axis they are most nearly across, and
//! the point's *off-axis share* is the share of them more than [`AXIS_TOLERANCE_DEG`] out
//! of the plane across that axis (the axis is refitted to the normals within it, so that a
//! few leaves beside a twig do not turn it): near 0 on wood, about 2/3 where normals point
//! every way. Normals are fitted at two scales ([`NORMAL_SCALES`]) and the lower share
//! kept: a twig about as thick as the finer neighbourhood is neither a surface nor a line
//! there, but a line at the coarser one. After a median over each point's nearest
//! neighbours, wood is a share of at most [`WoodConfig::max_off_axis_share`], together
//! with the points linked to it whose share is at most [`WEAK_PER_STRONG`] times that
//! (hysteresis: the points of a fork, whose normals have two axes).
//!
//! What a neighbourhood cannot tell, a component can: a flat leaf seen alone has parallel
//! normals, like a patch of thick bark, so wood components less than
//! [`MIN_WOOD_EXTENT_M`] across are leaves unless they are linear (a piece of twig,
//! [`MAX_TWIG_WIDTH_RATIO`]).
//!
//! This is the idea of geometric wood/leaf separation (Brodu & Lague 2012, CANUPO; Vicari
//! et al. 2019, TLSeparation; Wang et al. 2020, LeWoS), with one feature chosen because it
//! separates the two without a trained classifier. What it costs and misses is measured
//! in `docs/validation.md` ("Wood and leaves"): twigs inside foliage are taken with the
//! leaves.

use kiddo::SquaredEuclidean;
use nalgebra::{Matrix3, Point3, Vector3};
use serde::Serialize;

use crate::cloud::{PointTree, at_least_one, check_points, median_spacing};
use crate::error::{ColonizeError, Result};

/// Nearest points a normal is fitted to (the point itself included): the fewest that fix a
/// plane through noise at one spacing.
pub const NORMAL_NEIGHBOURS: usize = 12;
/// The neighbourhoods normals are fitted to, points: [`NORMAL_NEIGHBOURS`], and one wide
/// enough that a twig as thick as the first is a line in it.
pub const NORMAL_SCALES: [usize; 2] = [NORMAL_NEIGHBOURS, 36];
/// Radius of the neighbourhood whose normals are compared, in median point spacings.
pub const COHERENCE_SPACINGS: f64 = 6.0;
/// ... and at least this, metres: wider than one leaf (synthetic leaves are 3 cm discs,
/// a broad leaf is 5–10 cm long), so a leaf is seen with its neighbours. Without it the
/// synthetic leafy trees of the tuning set (3.7 mm spacing) kept model lengths of 1.62
/// times the truth instead of 1.25.
pub const MIN_COHERENCE_RADIUS_M: f64 = 0.05;
/// Most neighbours the share is taken over (the nearest within the radius). Tuning set:
/// 48 kept 1.39 times the true length, 96 1.25, 160 1.02 but found 67 % of the true
/// length instead of 73 %, at 1.6 times the cost.
pub const COHERENCE_NEIGHBOURS: usize = 96;
/// Fewest neighbours (the point included) within the radius for a share to be measured;
/// a point with fewer is a stray return and counted with the leaves.
pub const MIN_COHERENCE_NEIGHBOURS: usize = 6;
/// A normal more than this out of the plane across the axis is off the axis, degrees
/// (|n · axis| > sin 20° = 0.34). 15° (0.25) took more twigs with the leaves: 64 % of the
/// tuning set's true length found against 73 %.
pub const AXIS_TOLERANCE_DEG: f64 = 20.0;
/// Default largest off-axis share of wood. Chosen on the tuning set (synthetic leafy
/// trees, seeds 0–2): 0.06 found 64.8 % of the true length at 1.24 times its length,
/// 0.12 72.6 % at 1.25, 0.14 90.2 % at 2.08 (more leaves kept).
pub const MAX_OFF_AXIS_SHARE: f64 = 0.12;
/// Points with a share up to this many times [`WoodConfig::max_off_axis_share`] join a
/// wood component that holds a point below it.
pub const WEAK_PER_STRONG: f64 = 2.0;
/// Link distance of wood components, in spacings.
pub const LINK_SPACINGS: f64 = 2.5;
/// Smallest extent of a wood component, metres: a leaf is at most about 15 cm long.
/// Smaller components are wood only when they are linear (a twig cut off from its branch
/// where the fork's normals spread) and [`MIN_WOOD_EXTENT_SPACINGS`] across.
pub const MIN_WOOD_EXTENT_M: f64 = 0.15;
/// Smallest extent of a linear wood component, in spacings.
pub const MIN_WOOD_EXTENT_SPACINGS: f64 = 10.0;
/// Largest ratio of a small linear component's spread across its axis to its spread
/// along it (standard deviations): a twig of 5 mm radius and 8 cm is 0.15; a leaf, an
/// ellipse of aspect 0.35–1, its aspect.
pub const MAX_TWIG_WIDTH_RATIO: f64 = 0.3;
/// Refits of a neighbourhood's axis to the normals across it.
const AXIS_REFITS: usize = 2;
/// A leaf point whose [`NORMAL_NEIGHBOURS`] are at least this share wood is wood.
pub const FILL_SHARE: f64 = 0.75;

/// How to separate wood from leaves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WoodConfig {
    /// Median distance between neighbouring points, metres. Default `None`: measured.
    pub spacing_m: Option<f64>,
    /// Largest off-axis share of wood (see the module documentation), 0 to 1. Default
    /// [`MAX_OFF_AXIS_SHARE`]; lower keeps less of the leaves and of the twigs among them.
    pub max_off_axis_share: f64,
}

impl Default for WoodConfig {
    fn default() -> Self {
        Self {
            spacing_m: None,
            max_off_axis_share: MAX_OFF_AXIS_SHARE,
        }
    }
}

/// The points a reconstruction took for leaves and set aside
/// ([`crate::ColonizeConfig::separate_leaves`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Leaves {
    /// Points set aside as leaves.
    pub points: usize,
    /// Indices (into the points given) of the leaves' points, in order.
    #[serde(skip)]
    pub indices: Vec<usize>,
}

/// Which points are wood.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WoodSplit {
    /// One flag per point given, in order: true for wood.
    pub wood: Vec<bool>,
    /// Each point's off-axis share after the median over its neighbours (0 to 1; `NaN`
    /// for a point with fewer than [`MIN_COHERENCE_NEIGHBOURS`] neighbours).
    pub off_axis_share: Vec<f64>,
    /// The spacing used, metres.
    pub spacing_m: f64,
}

impl WoodSplit {
    /// Points taken for wood.
    pub fn wood_points(&self) -> usize {
        self.wood.iter().filter(|&&w| w).count()
    }
    /// Points taken for leaves (or stray returns).
    pub fn leaf_points(&self) -> usize {
        self.wood.len() - self.wood_points()
    }
}

/// Tell wood from leaves (see the module documentation).
///
/// ```
/// use space_colonize::synthetic::SyntheticConfig;
/// use space_colonize::{WoodConfig, separate_wood};
///
/// let tree = SyntheticConfig { points: 8_000, leaf_points: 3_000, ..Default::default() }
///     .generate()?;
/// let split = separate_wood(&tree.points, &WoodConfig::default())?;
/// let (wood, leaves) = split.wood.split_at(tree.wood_points);
/// let kept = wood.iter().filter(|&&w| w).count() as f64 / wood.len() as f64;
/// let dropped = leaves.iter().filter(|&&w| !w).count() as f64 / leaves.len() as f64;
/// assert!(kept > 0.6 && dropped > 0.9, "{kept} {dropped}");
/// # Ok::<(), space_colonize::ColonizeError>(())
/// ```
///
/// # Errors
/// [`ColonizeError::NonFinitePoint`], [`ColonizeError::PointOutOfRange`],
/// [`ColonizeError::TooFewPoints`] (fewer than [`crate::MIN_POINTS`]), and [`ColonizeError::InvalidParameter`] for a spacing that is not
/// positive, a share outside (0, 1), or more points than indices hold.
pub fn separate_wood(points: &[Point3<f64>], config: &WoodConfig) -> Result<WoodSplit> {
    config.validate()?;
    check_points(points)?;
    let pts: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
    let tree = PointTree::new_from_slice(&pts);
    let spacing_m = match config.spacing_m {
        Some(s) => s,
        None => median_spacing(&pts, &tree)?,
    };
    let (wood, off_axis_share) = classify(&pts, &tree, spacing_m, config.max_off_axis_share);
    Ok(WoodSplit {
        wood,
        off_axis_share,
        spacing_m,
    })
}

impl WoodConfig {
    /// Check the fields.
    ///
    /// # Errors
    /// [`ColonizeError::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<()> {
        if let Some(s) = self.spacing_m
            && !(s.is_finite() && s > 0.0)
        {
            return Err(ColonizeError::param(
                "spacing_m",
                format!("{s} m; must be positive and finite"),
            ));
        }
        if !(self.max_off_axis_share > 0.0 && self.max_off_axis_share < 1.0) {
            return Err(ColonizeError::param(
                "max_off_axis_share",
                format!(
                    "{}; must be above 0 and below 1 (a share of the neighbours)",
                    self.max_off_axis_share
                ),
            ));
        }
        Ok(())
    }
}

/// The unit normals of a point's nearest points at each of [`NORMAL_SCALES`] (the
/// direction of least spread).
fn normals_at(pts: &[[f64; 3]], tree: &PointTree, p: &[f64; 3]) -> [Vector3<f64>; 2] {
    // Nearest first, so each scale is a prefix of one query.
    let nb = tree.nearest_n::<SquaredEuclidean>(p, at_least_one(NORMAL_SCALES[1]));
    NORMAL_SCALES.map(|k| {
        let nb = &nb[..k.min(nb.len())];
        let n = nb.len() as f64;
        let mean = nb.iter().fold(Vector3::zeros(), |a, q| {
            a + Vector3::from(pts[q.item as usize])
        }) / n;
        let mut cov = Matrix3::zeros();
        for q in nb {
            let d = Vector3::from(pts[q.item as usize]) - mean;
            cov += d * d.transpose();
        }
        smallest_eigenvector(&cov)
    })
}

fn smallest_eigenvector(m: &Matrix3<f64>) -> Vector3<f64> {
    let e = m.symmetric_eigen();
    let k = e.eigenvalues.imin();
    e.eigenvectors.column(k).into_owned()
}

/// The off-axis share of every point's neighbourhood, the lower of the two scales' normals.
fn off_axis_shares(
    pts: &[[f64; 3]],
    tree: &PointTree,
    normals: &[[Vector3<f64>; 2]],
    radius_m: f64,
) -> Vec<f64> {
    let radius2 = radius_m * radius_m;
    let mut near: Vec<usize> = Vec::with_capacity(COHERENCE_NEIGHBOURS);
    pts.iter()
        .map(|p| {
            near.clear();
            near.extend(
                tree.nearest_n_within::<SquaredEuclidean>(
                    p,
                    radius2,
                    at_least_one(COHERENCE_NEIGHBOURS),
                    false,
                )
                .iter()
                .map(|q| q.item as usize),
            );
            if near.len() < MIN_COHERENCE_NEIGHBOURS {
                return f64::NAN;
            }
            (0..NORMAL_SCALES.len())
                .map(|k| off_axis_share(&near, |i| normals[i][k]))
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

/// The share of the normals of `near` (at least one) more than [`AXIS_TOLERANCE_DEG`] out
/// of the plane across the axis they are most nearly across.
fn off_axis_share(near: &[usize], normal: impl Fn(usize) -> Vector3<f64>) -> f64 {
    let sin_tol = AXIS_TOLERANCE_DEG.to_radians().sin();
    let across = |axis: Vector3<f64>| {
        near.iter()
            .map(|&i| normal(i))
            .filter(move |n| n.dot(&axis).abs() < sin_tol)
    };
    let scatter = |ns: &mut dyn Iterator<Item = Vector3<f64>>| {
        ns.fold(Matrix3::zeros(), |m, n| m + n * n.transpose())
    };
    // The axis most normals are across, then refitted to those within the tolerance.
    let mut axis = smallest_eigenvector(&scatter(&mut near.iter().map(|&i| normal(i))));
    let mut best = across(axis).count();
    for _ in 0..AXIS_REFITS {
        if best < 3 {
            break;
        }
        let refit = smallest_eigenvector(&scatter(&mut across(axis)));
        let count = across(refit).count();
        if count <= best {
            break;
        }
        (axis, best) = (refit, count);
    }
    1.0 - best as f64 / near.len() as f64
}

/// Wood flags and the smoothed off-axis share of every point.
pub(crate) fn classify(
    pts: &[[f64; 3]],
    tree: &PointTree,
    spacing_m: f64,
    max_share: f64,
) -> (Vec<bool>, Vec<f64>) {
    let radius_m = (COHERENCE_SPACINGS * spacing_m).max(MIN_COHERENCE_RADIUS_M);
    // Normals at two scales: a twig about as thick as the finer neighbourhood is neither a
    // surface nor a line there, but a line at the coarser one.
    let normals: Vec<[Vector3<f64>; 2]> = pts.iter().map(|p| normals_at(pts, tree, p)).collect();
    let raw = off_axis_shares(pts, tree, &normals, radius_m);
    // Median over the nearest neighbours: one odd normal does not flip a point.
    let share: Vec<f64> = pts
        .iter()
        .map(|p| {
            let mut v: Vec<f64> = tree
                .nearest_n::<SquaredEuclidean>(p, at_least_one(NORMAL_NEIGHBOURS))
                .iter()
                .map(|q| raw[q.item as usize])
                .filter(|s| !s.is_nan())
                .collect();
            if v.len() * 2 < NORMAL_NEIGHBOURS {
                return f64::NAN;
            }
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        })
        .collect();
    let strong: Vec<bool> = share.iter().map(|&s| s <= max_share).collect();
    let weak: Vec<bool> = share
        .iter()
        .map(|&s| s <= WEAK_PER_STRONG * max_share)
        .collect();
    let mut wood = grow_components(pts, tree, spacing_m, &strong, &weak);
    fill_forks(pts, tree, &share, &mut wood);
    (wood, share)
}

/// Leaf points among mostly wood neighbours are wood (forks).
fn fill_forks(pts: &[[f64; 3]], tree: &PointTree, share: &[f64], wood: &mut [bool]) {
    let fill: Vec<usize> = pts
        .iter()
        .enumerate()
        .filter(|(i, _)| !wood[*i] && !share[*i].is_nan())
        .filter(|(_, p)| {
            let nb = tree.nearest_n::<SquaredEuclidean>(p, at_least_one(NORMAL_NEIGHBOURS));
            let w = nb.iter().filter(|q| wood[q.item as usize]).count();
            w as f64 >= FILL_SHARE * nb.len() as f64
        })
        .map(|(i, _)| i)
        .collect();
    for i in fill {
        wood[i] = true;
    }
}

/// Whether the points' spread across their main axis is at most [`MAX_TWIG_WIDTH_RATIO`]
/// of their spread along it (a piece of twig, not a leaf).
fn is_linear(pts: &[[f64; 3]], members: &[usize]) -> bool {
    let n = members.len() as f64;
    let mean = members
        .iter()
        .fold(Vector3::zeros(), |a, &i| a + Vector3::from(pts[i]))
        / n;
    let mut cov = Matrix3::zeros();
    for &i in members {
        let d = Vector3::from(pts[i]) - mean;
        cov += d * d.transpose();
    }
    let mut e: Vec<f64> = cov
        .symmetric_eigenvalues()
        .iter()
        .map(|v| v.max(0.0))
        .collect();
    e.sort_by(|a, b| b.total_cmp(a));
    e[1] <= MAX_TWIG_WIDTH_RATIO.powi(2) * e[0]
}

/// Components of `weak` points (linked within [`LINK_SPACINGS`]) that hold a `strong`
/// point and are at least [`MIN_WOOD_EXTENT_SPACINGS`] spacings (and
/// [`MIN_WOOD_EXTENT_M`]) across are wood.
fn grow_components(
    pts: &[[f64; 3]],
    tree: &PointTree,
    spacing_m: f64,
    strong: &[bool],
    weak: &[bool],
) -> Vec<bool> {
    let link2 = (LINK_SPACINGS * spacing_m).powi(2);
    let small_extent = MIN_WOOD_EXTENT_SPACINGS * spacing_m;
    let min_extent = small_extent.max(MIN_WOOD_EXTENT_M);
    let mut wood = vec![false; pts.len()];
    let mut seen = vec![false; pts.len()];
    let mut stack = Vec::new();
    let mut members = Vec::new();
    for start in 0..pts.len() {
        if seen[start] || !strong[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        members.clear();
        let (mut lo, mut hi) = (pts[start], pts[start]);
        while let Some(i) = stack.pop() {
            members.push(i);
            for k in 0..3 {
                lo[k] = lo[k].min(pts[i][k]);
                hi[k] = hi[k].max(pts[i][k]);
            }
            for q in tree.within_unsorted::<SquaredEuclidean>(&pts[i], link2) {
                let j = q.item as usize;
                if weak[j] && !seen[j] {
                    seen[j] = true;
                    stack.push(j);
                }
            }
        }
        let extent =
            ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt();
        if extent >= min_extent || (extent >= small_extent && is_linear(pts, &members)) {
            for &i in &members {
                wood[i] = true;
            }
        }
    }
    wood
}
