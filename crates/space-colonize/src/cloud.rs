//! The attraction points: validation, spacing, trunk radius, outlier clusters and isolated
//! points, k-d tree.

use std::collections::HashMap;

use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use nalgebra::{Matrix3, Point3};

use crate::circle::fit_circle;
use crate::config::{
    ColonizeConfig, INFLUENCE_PER_KILL, KILL_PER_TRUNK_RADIUS, KILL_PER_TRUNK_RADIUS_ONE_SIDED,
    LEVEL_BIN_SPACINGS, MAX_GAP_INFLUENCES, MAX_PATCH_M, MIN_KILL_SPACINGS, MIN_LEVEL_BIN_M,
    MIN_STEP_PER_KILL, ONE_SIDED_COVERAGE, PATCH_BINS, Parameters, STEP_SPACINGS,
};
use crate::error::{ColonizeError, Result};
use crate::ground::{Ground, find_ground};
use crate::wood::{Leaves, MAX_OFF_AXIS_SHARE, classify};

/// Static k-d tree over points, items are indices.
pub(crate) type PointTree = ImmutableKdTree<f64, u32, 3, 32>;

/// Fewest points a reconstruction accepts.
pub const MIN_POINTS: usize = 10;
/// Spacing is measured on at most this many points (a deterministic stride), enough for a
/// median to three digits.
const SPACING_SAMPLE: usize = 20_000;
/// Copies of a point (at exactly its place) the spacing looks past for its nearest other
/// point.
const SPACING_COPIES: usize = 16;
/// Smallest principal standard deviation accepted, relative to the largest: a tree is
/// never flat to a thousandth of its size.
const MIN_RELATIVE_THICKNESS: f64 = 1e-3;
/// Smallest principal standard deviation accepted in absolute terms, metres.
const MIN_THICKNESS_M: f64 = 1e-6;

/// Neighbours a point needs within [`ISOLATED_SPACINGS`] median spacings to be part of the
/// tree: a twig's points have two or more along it at one to three spacings; a stray point,
/// or a pair, has none that near.
const ISOLATED_NEIGHBOURS: usize = 3;
/// Reach, in median spacings, of the neighbourhood of [`ISOLATED_NEIGHBOURS`]. Measured
/// (`docs/validation.md`, "Stray points"): at 10 the sparse leafy tree13 (5.4 cm median
/// spacing) loses 125 of its points, at 20 only 9, but stray points at 10 % of a cloud are
/// then too dense to be told apart; 15 sets aside 26 of tree13's, 7 of tree7's, none of
/// Paris' or the coffee tree's, and 94–97 % of uniform strays at 1–10 % of the coffee tree.
const ISOLATED_SPACINGS: f64 = 15.0;

/// Largest coordinate accepted, metres: 10,000 km, more than the Earth's radius, so any
/// georeferenced cloud fits, while a corrupt 1e300 (whose squares overflow the principal
/// axes into a "degenerate" cloud) is named as what it is.
pub const MAX_COORDINATE_M: f64 = 1e7;

/// A cloud ready for growth.
pub(crate) struct Prepared {
    pub pts: Vec<[f64; 3]>,
    pub tree: PointTree,
    /// Points of the main cluster that are not isolated (the rest are outliers: beyond the
    /// largest bridge, or without neighbours near them).
    pub main: Vec<bool>,
    /// Points of `pts` not in `main`.
    pub outliers: usize,
    /// The ground found under the tree; its points are not in `pts`.
    pub ground: Option<Ground>,
    /// The points taken for leaves ([`ColonizeConfig::separate_leaves`]); not in `pts`.
    pub leaves: Option<Leaves>,
    pub params: Parameters,
}

/// `k` as the neighbour count of a k-d tree query, at least 1.
pub(crate) fn at_least_one(k: usize) -> std::num::NonZeroUsize {
    std::num::NonZeroUsize::new(k).unwrap_or(std::num::NonZeroUsize::MIN)
}

/// The first point that is not finite, as [`ColonizeError::NonFinitePoint`].
pub(crate) fn all_finite(points: &[Point3<f64>]) -> Result<()> {
    match points
        .iter()
        .enumerate()
        .find(|(_, p)| !p.iter().all(|c| c.is_finite()))
    {
        Some((index, p)) => Err(ColonizeError::NonFinitePoint {
            index,
            x: p.x,
            y: p.y,
            z: p.z,
        }),
        None => Ok(()),
    }
}

/// Every point finite and within [`MAX_COORDINATE_M`], at least [`MIN_POINTS`] of them and
/// no more than `u32` indices hold.
pub(crate) fn check_points(points: &[Point3<f64>]) -> Result<()> {
    all_finite(points)?;
    if let Some((index, p)) = points
        .iter()
        .enumerate()
        .find(|(_, p)| p.iter().any(|c| c.abs() > MAX_COORDINATE_M))
    {
        return Err(ColonizeError::PointOutOfRange {
            index,
            x: p.x,
            y: p.y,
            z: p.z,
            limit_m: MAX_COORDINATE_M,
        });
    }
    if points.len() < MIN_POINTS {
        return Err(ColonizeError::TooFewPoints {
            points: points.len(),
            needed: MIN_POINTS,
        });
    }
    if points.len() > u32::MAX as usize {
        return Err(ColonizeError::param(
            "points",
            format!("{} points; at most {} supported", points.len(), u32::MAX),
        ));
    }
    Ok(())
}

/// Validate the points and derive the parameters the config leaves open.
pub(crate) fn prepare(points: &[Point3<f64>], config: &ColonizeConfig) -> Result<Prepared> {
    config.validate()?;
    check_points(points)?;
    check_thickness(points)?;
    let mut pts: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
    let mut tree = PointTree::new_from_slice(&pts);
    let mut spacing_m = match config.spacing_m {
        Some(s) => s,
        None => median_spacing(&pts, &tree)?,
    };
    // A ground under the tree is set aside first; the rest is the tree, with its own
    // spacing.
    let ground = if config.remove_ground {
        find_ground(&pts, spacing_m)
    } else {
        None
    };
    // Indices into the points given of the points kept.
    let mut given: Vec<usize> = (0..pts.len()).collect();
    if let Some(g) = &ground {
        let mut on = vec![false; pts.len()];
        for &i in &g.indices {
            on[i] = true;
        }
        given.retain(|&i| !on[i]);
        pts = pts
            .iter()
            .zip(&on)
            .filter(|(_, g)| !**g)
            .map(|(p, _)| *p)
            .collect();
        if pts.len() < MIN_POINTS {
            return Err(ColonizeError::param(
                "points",
                format!(
                    "{} of {} points lie on a ground plane and {} above it, fewer than the \
                     {MIN_POINTS} a tree needs (set remove_ground to false to keep them)",
                    points.len() - pts.len(),
                    points.len(),
                    pts.len()
                ),
            ));
        }
        tree = PointTree::new_from_slice(&pts);
        if config.spacing_m.is_none() {
            spacing_m = median_spacing(&pts, &tree)?;
        }
    }
    let leaves = if config.separate_leaves {
        let (wood, leaves) = set_leaves_aside(&pts, &tree, &given, spacing_m)?;
        pts = wood;
        tree = PointTree::new_from_slice(&pts);
        if config.spacing_m.is_none() {
            spacing_m = median_spacing(&pts, &tree)?;
        }
        Some(leaves)
    } else {
        None
    };
    // Kill and influence need the trunk radius, the outlier clusters need the influence,
    // and the trunk fit needs the main cluster: fit on all points first, then refit on the
    // main cluster.
    let base_fit = trunk_fit(&pts, None, spacing_m);
    let first = derive(config, spacing_m, base_fit, &pts)?;
    let lone = isolated(&pts, &tree, spacing_m);
    let mut main = main_cluster(&pts, first.max_gap_m);
    for (m, l) in main.iter_mut().zip(&lone) {
        *m &= !l;
    }
    let outliers = main.iter().filter(|&&m| !m).count();
    let params = if outliers > 0 {
        derive(
            config,
            spacing_m,
            trunk_fit(&pts, Some(&main), spacing_m),
            &pts_in(&pts, &main),
        )?
    } else {
        first
    };
    params.validate()?;
    Ok(Prepared {
        pts,
        tree,
        main,
        outliers,
        ground,
        leaves,
        params,
    })
}

/// The wood of `pts` (whose indices in the points given are `given`) and its leaves
/// ([`classify`]).
fn set_leaves_aside(
    pts: &[[f64; 3]],
    tree: &PointTree,
    given: &[usize],
    spacing_m: f64,
) -> Result<(Vec<[f64; 3]>, Leaves)> {
    let (wood, _) = classify(pts, tree, spacing_m, MAX_OFF_AXIS_SHARE);
    let indices: Vec<usize> = given
        .iter()
        .zip(&wood)
        .filter(|(_, w)| !**w)
        .map(|(&i, _)| i)
        .collect();
    let kept = pts.len() - indices.len();
    if kept < MIN_POINTS {
        return Err(ColonizeError::param(
            "separate_leaves",
            format!(
                "{} of {} points were taken for leaves and {kept} for wood, fewer than the \
                 {MIN_POINTS} a tree needs (a cloud without wood? set separate_leaves to \
                 false to keep them)",
                indices.len(),
                pts.len()
            ),
        ));
    }
    Ok((
        pts_in(pts, &wood),
        Leaves {
            points: indices.len(),
            indices,
        },
    ))
}

fn pts_in(pts: &[[f64; 3]], keep: &[bool]) -> Vec<[f64; 3]> {
    pts.iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|(p, _)| *p)
        .collect()
}

/// The trunk circle near the base: centre (x, y), radius, and whether it is a fit.
#[derive(Debug, Clone, Copy)]
struct TrunkFit {
    centre: [f64; 2],
    radius_m: f64,
    fitted: bool,
    z_min: f64,
    /// Share of the circle the fitted slice covers (1 for a full scan, 0.5–0.7 for a
    /// one-sided view); 1 when not fitted.
    coverage: f64,
}

fn derive(
    config: &ColonizeConfig,
    spacing_m: f64,
    fit: TrunkFit,
    pts: &[[f64; 3]],
) -> Result<Parameters> {
    let (trunk_radius_m, fitted) = match config.trunk_radius_m {
        Some(r) => (r, false),
        None => (fit.radius_m, fit.fitted),
    };
    // A one-sided view sees a half ring of each thick branch: a node drawn to its points
    // sits 2r/π in front of the axis, and the ring's silhouette edges are then 1.19 r from
    // it, beyond 1.2 r less any noise, and grew as a second, parallel chain.
    // A known camera says so itself (noise can scatter a view's trunk slice over more
    // sectors: the third coffee view with 9 mm of depth noise covered 0.75).
    let one_sided = config.camera_m.is_some() || (fit.fitted && fit.coverage < ONE_SIDED_COVERAGE);
    let kill_per_radius = if one_sided {
        KILL_PER_TRUNK_RADIUS_ONE_SIDED
    } else {
        KILL_PER_TRUNK_RADIUS
    };
    let kill_at = |per_radius: f64| {
        config
            .kill_distance_m
            .unwrap_or((per_radius * trunk_radius_m).max(MIN_KILL_SPACINGS * spacing_m))
    };
    let kill_distance_m = kill_at(kill_per_radius);
    // Step and influence as for a full scan: only the reach of a node grows.
    let full_scan_kill_m = kill_at(KILL_PER_TRUNK_RADIUS);
    let twig_kill_distance_m = config
        .twig_kill_distance_m
        .unwrap_or((MIN_KILL_SPACINGS * spacing_m).min(crate::config::MAX_TWIG_KILL_M));
    let step_m = config.step_m.unwrap_or(
        (STEP_SPACINGS * spacing_m)
            .max(MIN_STEP_PER_KILL * full_scan_kill_m)
            .min(0.5 * full_scan_kill_m),
    );
    let influence_m = config
        .influence_m
        .unwrap_or(INFLUENCE_PER_KILL * full_scan_kill_m);
    let max_gap_m = config.max_gap_m.unwrap_or(MAX_GAP_INFLUENCES * influence_m);
    let root_m = match config.root {
        Some(r) => [r.x, r.y, r.z],
        None => [fit.centre[0], fit.centre[1], fit.z_min],
    };
    let n = pts.len();
    let bin_m = config
        .bin_m
        .unwrap_or((LEVEL_BIN_SPACINGS * spacing_m).max(MIN_LEVEL_BIN_M));
    Ok(Parameters {
        growth: config.growth,
        bin_m,
        patch_m: config
            .patch_m
            .unwrap_or((PATCH_BINS * bin_m).min(MAX_PATCH_M)),
        spacing_m,
        trunk_radius_m,
        trunk_radius_fitted: fitted,
        trunk_coverage: fit.coverage,
        one_sided,
        kill_distance_m,
        twig_kill_distance_m,
        step_m,
        influence_m,
        max_gap_m,
        root_m,
        camera_m: config.camera_m.map(|c| [c.x, c.y, c.z]),
        pipe_exponent: config.pipe_exponent,
        min_twig_m: config.min_twig_m.unwrap_or(2.0 * spacing_m),
        max_iterations: config.max_iterations.unwrap_or(2 * n + 10_000),
        max_nodes: config.max_nodes.unwrap_or(2 * n + 10_000),
    })
}

fn check_thickness(points: &[Point3<f64>]) -> Result<()> {
    let n = points.len() as f64;
    let mean = points
        .iter()
        .fold(nalgebra::Vector3::zeros(), |a, p| a + p.coords)
        / n;
    let mut cov = Matrix3::<f64>::zeros();
    for p in points {
        let d = p.coords - mean;
        cov += d * d.transpose();
    }
    cov /= n;
    let mut ev: Vec<f64> = cov
        .symmetric_eigenvalues()
        .iter()
        .map(|v| v.max(0.0).sqrt())
        .collect();
    ev.sort_by(|a, b| b.total_cmp(a));
    let min_m = (MIN_RELATIVE_THICKNESS * ev[0]).max(MIN_THICKNESS_M);
    if ev[2] < min_m || !ev[0].is_finite() {
        return Err(ColonizeError::Degenerate {
            extents_m: [ev[0], ev[1], ev[2]],
            min_m,
        });
    }
    Ok(())
}

pub(crate) fn median_spacing(pts: &[[f64; 3]], tree: &PointTree) -> Result<f64> {
    let stride = pts.len().div_ceil(SPACING_SAMPLE).max(1);
    // The point itself and its copies come first: a cloud merged or exported twice holds
    // every point more than once, and its spacing is that of the distinct points.
    let k = std::num::NonZeroUsize::MIN.saturating_add(SPACING_COPIES);
    let mut d: Vec<f64> = pts
        .iter()
        .step_by(stride)
        .filter_map(|p| {
            tree.nearest_n::<SquaredEuclidean>(p, k)
                .iter()
                .map(|nb| nb.distance)
                .find(|&d2| d2 > 0.0)
                .map(f64::sqrt)
        })
        .collect();
    if d.is_empty() {
        return Err(ColonizeError::param(
            "points",
            format!(
                "every sampled point has more than {SPACING_COPIES} copies at its place: \
                 remove duplicate points"
            ),
        ));
    }
    d.sort_by(f64::total_cmp);
    Ok(d[d.len() / 2])
}

/// Points whose [`ISOLATED_NEIGHBOURS`]-th nearest other point lies more than
/// [`ISOLATED_SPACINGS`] median spacings away: stray returns (a bird, dust, a mixed pixel far
/// from any surface) that growth would otherwise reach with a branch through the air.
fn isolated(pts: &[[f64; 3]], tree: &PointTree, spacing_m: f64) -> Vec<bool> {
    let limit2 = (ISOLATED_SPACINGS * spacing_m).powi(2);
    // The point itself comes first (duplicates too: a doubled stray point is still alone).
    let k = std::num::NonZeroUsize::MIN.saturating_add(ISOLATED_NEIGHBOURS);
    pts.iter()
        .map(|p| {
            tree.nearest_n::<SquaredEuclidean>(p, k)
                .last()
                .is_none_or(|nb| nb.distance > limit2)
        })
        .collect()
}

/// Circle fitted in x–y to a slice of the lowest points: from 2 spacings above the lowest
/// point, 12 spacings or 4 % of the height thick, whichever is more.
fn trunk_fit(pts: &[[f64; 3]], keep: Option<&[bool]>, spacing_m: f64) -> TrunkFit {
    let kept = |i: usize| keep.is_none_or(|k| k[i]);
    let (mut z_min, mut z_max) = (f64::INFINITY, f64::NEG_INFINITY);
    for (i, p) in pts.iter().enumerate() {
        if kept(i) {
            z_min = z_min.min(p[2]);
            z_max = z_max.max(p[2]);
        }
    }
    let lo = z_min + 2.0 * spacing_m;
    let hi = lo + (12.0 * spacing_m).max(0.04 * (z_max - z_min));
    let mut slice: Vec<[f64; 2]> = pts
        .iter()
        .enumerate()
        .filter(|(i, p)| kept(*i) && p[2] >= lo && p[2] <= hi)
        .map(|(_, p)| [p[0], p[1]])
        .collect();
    if slice.len() < 5 {
        // Too thin a slice: take the lowest points up to `hi`.
        slice = pts
            .iter()
            .enumerate()
            .filter(|(i, p)| kept(*i) && p[2] <= hi)
            .map(|(_, p)| [p[0], p[1]])
            .collect();
    }
    let n = slice.len().max(1) as f64;
    let cx = slice.iter().map(|p| p[0]).sum::<f64>() / n;
    let cy = slice.iter().map(|p| p[1]).sum::<f64>() / n;
    let spread = slice
        .iter()
        .map(|p| (p[0] - cx).hypot(p[1] - cy))
        .sum::<f64>()
        / n;
    if let Some(c) = fit_circle(&slice)
        && c.radius_m < 4.0 * spread.max(spacing_m)
        && c.rms_m < 0.5 * c.radius_m
        && c.coverage >= 0.25
        && c.radius_m >= 0.5 * spacing_m
    {
        return TrunkFit {
            centre: c.centre,
            radius_m: c.radius_m,
            fitted: true,
            z_min,
            coverage: c.coverage,
        };
    }
    // Fallback: the mean distance to the centroid (the radius for a full ring).
    TrunkFit {
        centre: [cx, cy],
        radius_m: spread.max(spacing_m),
        fitted: false,
        z_min,
        coverage: 1.0,
    }
}

/// Points of the largest cluster, clusters linked when within about `gap_m` (occupied
/// cells of a grid of that size, joined with their 26 neighbours). O(n).
fn main_cluster(pts: &[[f64; 3]], gap_m: f64) -> Vec<bool> {
    let key = |p: &[f64; 3]| {
        (
            (p[0] / gap_m).floor() as i64,
            (p[1] / gap_m).floor() as i64,
            (p[2] / gap_m).floor() as i64,
        )
    };
    let mut cells: HashMap<(i64, i64, i64), usize> = HashMap::new();
    let mut cell_of = Vec::with_capacity(pts.len());
    let mut counts: Vec<usize> = Vec::new();
    for p in pts {
        let next = cells.len();
        let c = *cells.entry(key(p)).or_insert(next);
        if c == counts.len() {
            counts.push(0);
        }
        counts[c] += 1;
        cell_of.push(c);
    }
    let mut parent: Vec<usize> = (0..cells.len()).collect();
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for (&(x, y, z), &c) in &cells {
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let near = (
                        x.saturating_add(dx),
                        y.saturating_add(dy),
                        z.saturating_add(dz),
                    );
                    if let Some(&o) = cells.get(&near) {
                        let (a, b) = (find(&mut parent, c), find(&mut parent, o));
                        if a != b {
                            parent[a] = b;
                        }
                    }
                }
            }
        }
    }
    let mut size = vec![0usize; cells.len()];
    for (c, &count) in counts.iter().enumerate() {
        let r = find(&mut parent, c);
        size[r] += count;
    }
    let best = (0..cells.len()).max_by_key(|&r| size[r]).unwrap_or(0);
    cell_of
        .iter()
        .map(|&c| find(&mut parent, c) == best)
        .collect()
}
