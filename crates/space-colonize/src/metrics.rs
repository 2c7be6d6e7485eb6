//! How close a model is to its cloud: point-to-surface distances, model parts near the cloud,
//! length, volume, branches by order.

use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use nalgebra::{Point3, Vector3};
use serde::Serialize;

use crate::skeleton::Skeleton;

/// A model part is "near the cloud" when its surface is within this of a point, metres
/// (the 2 cm).
pub const NEAR_CLOUD_M: f64 = 0.02;
/// Cylinders examined per point (nearest by midpoint); the nearest surface is among them
/// for segments no longer than the spacing of the nodes.
pub(crate) const CANDIDATE_CYLINDERS: usize = 8;

/// Cylinders (nearest by midpoint) among which a point's distance to the model is sought
/// when choosing what the twig pass grows toward. With the metrics' 8, a point on a thick
/// branch beside a cluster of short twig segments could miss the branch's own cylinder and
/// look 2–4 cm off the model, and the twig pass grew twigs along the branch's surface. 16
/// (the fidelity measure's count) and 32 gave the same models (synthetic evaluation trees,
/// seeds 40–51: axis error 7.17 → 6.79 mm), 16 in less time.
pub(crate) const TWIG_PASS_CANDIDATE_CYLINDERS: usize = 16;

/// Fidelity of a model to a cloud.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metrics {
    /// Points measured.
    pub points: usize,
    /// Mean distance from a point to the model surface, metres.
    pub mean_distance_m: f64,
    /// Median of it, metres.
    pub median_distance_m: f64,
    /// 95th percentile, metres.
    pub p95_distance_m: f64,
    /// Largest, metres.
    pub max_distance_m: f64,
    /// Share of points within 1 cm of the surface.
    pub within_1cm: f64,
    /// Share within 2 cm.
    pub within_2cm: f64,
    /// Share within 5 cm.
    pub within_5cm: f64,
    /// Share of the skeleton's length whose surface is within [`NEAR_CLOUD_M`] of a point.
    pub length_near_cloud: f64,
    /// Largest distance from a model part (a segment's mid-axis, less its radius) to the
    /// nearest point, metres.
    pub max_model_gap_m: f64,
    /// Wood length, metres: the cylinders of [`crate::cylinders`], each branch from its
    /// parent's surface as TreeQSM counts it.
    pub total_length_m: f64,
    /// Sum of the skeleton's segment lengths, metres: [`Self::total_length_m`] plus the
    /// stretches of branches inside their parents, from the fork node to the surface.
    pub skeleton_length_m: f64,
    /// Wood volume of the same cylinders, litres (the unit tree-modelling tools report).
    pub volume_l: f64,
}

/// Distance from `q` to the lateral surface of a cylinder (start `a`, unit axis `u`, length
/// `len`, radius `r`); beyond an end, the distance to its rim.
pub(crate) fn surface_distance(
    q: &Vector3<f64>,
    a: &Vector3<f64>,
    u: &Vector3<f64>,
    len: f64,
    r: f64,
) -> f64 {
    let v = q - a;
    let t = v.dot(u);
    let radial = (v - u * t).norm();
    let axial = if t < 0.0 {
        -t
    } else if t > len {
        t - len
    } else {
        0.0
    };
    (radial - r).hypot(axial)
}

/// Distance from each point to the nearest cylinder surface of a skeleton, metres
/// (infinite when the skeleton has no segment).
pub(crate) fn point_distances(pts: &[[f64; 3]], skeleton: &Skeleton) -> Vec<f64> {
    point_distances_among(pts, skeleton, CANDIDATE_CYLINDERS)
}

/// [`point_distances`] over the `candidates` cylinders with the nearest midpoints.
pub(crate) fn point_distances_among(
    pts: &[[f64; 3]],
    skeleton: &Skeleton,
    candidates: usize,
) -> Vec<f64> {
    let cyls = cylinders(skeleton);
    distances(pts.iter().map(|p| Vector3::from(*p)), &cyls, candidates)
}

/// A skeleton segment as a cylinder: from its parent's position `a` along unit `u` for
/// `len`, radius `r`; `node` is the node it ends at.
pub(crate) struct Cyl {
    pub node: usize,
    pub a: Vector3<f64>,
    pub u: Vector3<f64>,
    pub len: f64,
    pub r: f64,
}

/// The skeleton's segments of positive length, node to node.
pub(crate) fn cylinders(skeleton: &Skeleton) -> Vec<Cyl> {
    let nodes = skeleton.nodes();
    nodes
        .iter()
        .filter_map(|x| {
            let p = nodes[x.parent?].position.coords;
            let d = x.position.coords - p;
            let len = d.norm();
            (len > 0.0).then(|| Cyl {
                node: x.id,
                a: p,
                u: d / len,
                len,
                r: x.radius_m,
            })
        })
        .collect()
}

fn midpoints(cyls: &[Cyl]) -> Vec<[f64; 3]> {
    cyls.iter()
        .map(|c| {
            let m = c.a + c.u * (0.5 * c.len);
            [m.x, m.y, m.z]
        })
        .collect()
}

fn distances(
    points: impl Iterator<Item = Vector3<f64>>,
    cyls: &[Cyl],
    candidates: usize,
) -> Vec<f64> {
    nearest_cylinders(points, cyls, candidates)
        .into_iter()
        .map(|n| n.map_or(f64::INFINITY, |(_, d)| d))
        .collect()
}

/// Each point's nearest cylinder by surface distance among the `candidates` with the
/// nearest midpoints: its index in `cyls` and the distance (`None` without cylinders).
pub(crate) fn nearest_cylinders(
    points: impl Iterator<Item = Vector3<f64>>,
    cyls: &[Cyl],
    candidates: usize,
) -> Vec<Option<(usize, f64)>> {
    if cyls.is_empty() {
        return points.map(|_| None).collect();
    }
    let tree: ImmutableKdTree<f64, u32, 3, 32> = ImmutableKdTree::new_from_slice(&midpoints(cyls));
    let k = crate::cloud::at_least_one(candidates.min(cyls.len()));
    points
        .map(|q| {
            tree.nearest_n::<SquaredEuclidean>(&[q.x, q.y, q.z], k)
                .iter()
                .map(|nb| {
                    let i = nb.item as usize;
                    let c = &cyls[i];
                    (i, surface_distance(&q, &c.a, &c.u, c.len, c.r))
                })
                .min_by(|x, y| x.1.total_cmp(&y.1))
        })
        .collect()
}

/// Branches at least this thick measure the scan's noise: their surface is smooth on the
/// scale of millimetres, so the points' spread about it is noise (bark and fit error
/// included), metres.
pub const NOISE_BRANCH_RADIUS_M: f64 = 0.02;
/// Points measured at most for the noise (evenly strided through the cloud).
const NOISE_SAMPLE: usize = 50_000;
/// Fewest points on such branches for an estimate.
const NOISE_MIN_POINTS: usize = 100;

/// The scan's noise about the model's surface, metres: the robust spread (1.4826 times the
/// median absolute deviation) of the signed distances of points to the lateral surface of
/// the nearest cylinder at least [`NOISE_BRANCH_RADIUS_M`] thick, for points lying along it
/// (not beyond its ends). `None` with fewer than 100 such points.
pub(crate) fn surface_noise(pts: &[[f64; 3]], skeleton: &Skeleton) -> Option<f64> {
    let cyls = cylinders(skeleton);
    if cyls.is_empty() {
        return None;
    }
    let tree: ImmutableKdTree<f64, u32, 3, 32> = ImmutableKdTree::new_from_slice(&midpoints(&cyls));
    let k = crate::cloud::at_least_one(CANDIDATE_CYLINDERS.min(cyls.len()));
    let stride = pts.len().div_ceil(NOISE_SAMPLE).max(1);
    let mut signed: Vec<f64> = pts
        .iter()
        .step_by(stride)
        .filter_map(|p| {
            let q = Vector3::from(*p);
            let nearest = tree
                .nearest_n::<SquaredEuclidean>(p, k)
                .iter()
                .map(|nb| &cyls[nb.item as usize])
                .min_by(|a, b| {
                    surface_distance(&q, &a.a, &a.u, a.len, a.r)
                        .total_cmp(&surface_distance(&q, &b.a, &b.u, b.len, b.r))
                })?;
            let v = q - nearest.a;
            let t = v.dot(&nearest.u);
            (nearest.r >= NOISE_BRANCH_RADIUS_M && (0.0..=nearest.len).contains(&t))
                .then(|| (v - nearest.u * t).norm() - nearest.r)
        })
        .collect();
    if signed.len() < NOISE_MIN_POINTS {
        return None;
    }
    signed.sort_by(f64::total_cmp);
    let median = signed[signed.len() / 2];
    let mut dev: Vec<f64> = signed.iter().map(|d| (d - median).abs()).collect();
    dev.sort_by(f64::total_cmp);
    Some(1.4826 * dev[dev.len() / 2])
}

/// Measure a skeleton's cylinders against the points.
pub fn metrics(points: &[Point3<f64>], skeleton: &Skeleton) -> Metrics {
    let cyls = cylinders(skeleton);
    let skeleton_length_m: f64 = cyls.iter().map(|c| c.len).sum();
    let wood = crate::geometry::cylinders(skeleton);
    let total_length_m: f64 = wood.iter().map(|c| c.length_m).sum();
    let volume_l = wood
        .iter()
        .map(|c| std::f64::consts::PI * c.radius_m * c.radius_m * c.length_m)
        .sum::<f64>()
        * 1000.0;
    let mids = midpoints(&cyls);
    let mut dist = if cyls.is_empty() {
        Vec::new()
    } else {
        distances(points.iter().map(|p| p.coords), &cyls, CANDIDATE_CYLINDERS)
    };
    let (mut length_near, mut max_gap) = (0.0, 0.0_f64);
    if !points.is_empty() {
        let pts: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
        let tree: ImmutableKdTree<f64, u32, 3, 32> = ImmutableKdTree::new_from_slice(&pts);
        for (c, m) in cyls.iter().zip(&mids) {
            let d = tree.nearest_one::<SquaredEuclidean>(m).distance.sqrt();
            let gap = (d - c.r).max(0.0);
            max_gap = max_gap.max(gap);
            if gap <= NEAR_CLOUD_M {
                length_near += c.len;
            }
        }
    }
    let n = dist.len().max(1) as f64;
    let share = |lim: f64| dist.iter().filter(|&&d| d <= lim).count() as f64 / n;
    let mean = dist.iter().sum::<f64>() / n;
    let (w1, w2, w5) = (share(0.01), share(0.02), share(0.05));
    dist.sort_by(f64::total_cmp);
    let pick = |q: f64| {
        if dist.is_empty() {
            f64::NAN
        } else {
            dist[((q * (dist.len() - 1) as f64).round() as usize).min(dist.len() - 1)]
        }
    };
    Metrics {
        points: points.len(),
        mean_distance_m: mean,
        median_distance_m: pick(0.5),
        p95_distance_m: pick(0.95),
        max_distance_m: dist.last().copied().unwrap_or(f64::NAN),
        within_1cm: w1,
        within_2cm: w2,
        within_5cm: w5,
        length_near_cloud: if skeleton_length_m > 0.0 {
            length_near / skeleton_length_m
        } else {
            0.0
        },
        max_model_gap_m: max_gap,
        total_length_m,
        skeleton_length_m,
        volume_l,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::SkeletonNode;

    #[test]
    fn a_point_on_a_thick_branch_beside_a_cluster_of_twig_segments_finds_the_branch() {
        // A 7 cm trunk segment 20 cm long, and a twig of 12 short segments 5 cm beside the
        // point, all with midpoints nearer the point than the trunk's.
        let node = |id: usize, parent: Option<usize>, p: [f64; 3], r: f64| SkeletonNode {
            id,
            parent,
            position: Point3::from(p),
            radius_m: r,
        };
        let mut nodes = vec![
            node(0, None, [0.0, 0.0, 0.0], 0.07),
            node(1, Some(0), [0.0, 0.0, 0.2], 0.07),
        ];
        for k in 0..12 {
            let x = 0.02 + 0.005 * k as f64;
            nodes.push(node(2 + k, Some(1 + k), [x, 0.05, 0.2], 0.002));
        }
        let skeleton = Skeleton::new(nodes).unwrap();
        let on_trunk = [[0.07, 0.0, 0.19]];
        // Among the metrics' 8 nearest midpoints only twig segments: 4-5 cm off.
        assert!(point_distances(&on_trunk, &skeleton)[0] > 0.03);
        let d = point_distances_among(&on_trunk, &skeleton, TWIG_PASS_CANDIDATE_CYLINDERS)[0];
        assert!(d < 1e-9, "{d}");
    }
}
