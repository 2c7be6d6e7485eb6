//! The comparison measure of issue 22, the same for our models and the anchors' (AdTree,
//! TreeQSM): each skeleton edge is a truncated cone between its two nodes' radii.
//!
//! - A point's distance to the model is |distance to the edge's axis segment − the cone's
//!   radius there|, the least over the [`CANDIDATE_EDGES`] edges with the nearest midpoints.
//! - "Model near cloud" is the share of the model's axis length, sampled every
//!   [`MODEL_SAMPLE_M`], whose nearest cloud point lies within the local radius +
//!   [`NEAR_CLOUD_M`].
//!
//! Unlike [`crate::metrics`] (the surface of the cylinder table, a branch's radius constant
//! along each segment), this measure needs nothing but nodes and radii, so any tool's model
//! converted to a [`Skeleton`] is measured exactly like ours.

use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use nalgebra::{Point3, Vector3};
use serde::Serialize;

use crate::metrics::NEAR_CLOUD_M;
use crate::skeleton::Skeleton;

/// Edges examined per point, nearest by midpoint (issue 22's definition).
pub const CANDIDATE_EDGES: usize = 16;
/// Spacing of the samples along the model's axis for "model near cloud", metres (issue 22).
pub const MODEL_SAMPLE_M: f64 = 0.01;
/// Most samples along one edge: a 10 km edge of a corrupt model is measured with a coarser
/// step rather than allocating a million samples.
const MAX_SAMPLES_PER_EDGE: usize = 100_000;

/// Fidelity of a model to its cloud by issue 22's measure.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Fidelity {
    /// Points measured.
    pub points: usize,
    /// Mean point-to-surface distance, metres (infinite for a model without edges).
    pub mean_distance_m: f64,
    /// Share of points within [`NEAR_CLOUD_M`] of the surface.
    pub within_2cm: f64,
    /// Share of the model's axis length near the cloud (see the module docs).
    pub model_near_cloud: f64,
    /// Axis length of the model (sum of its edges), metres.
    pub axis_length_m: f64,
}

/// One edge: a truncated cone from `a` (radius `ra`) along unit `u` for `len` to radius `rb`.
struct Cone {
    a: Vector3<f64>,
    u: Vector3<f64>,
    len: f64,
    ra: f64,
    rb: f64,
}

impl Cone {
    fn radius_at(&self, t: f64) -> f64 {
        self.ra + (self.rb - self.ra) * (t / self.len)
    }

    /// |distance to the axis segment − local radius|.
    fn distance(&self, q: &Vector3<f64>) -> f64 {
        let t = (q - self.a).dot(&self.u).clamp(0.0, self.len);
        let axis = (q - (self.a + self.u * t)).norm();
        (axis - self.radius_at(t)).abs()
    }
}

fn cones(skeleton: &Skeleton) -> Vec<Cone> {
    let nodes = skeleton.nodes();
    nodes
        .iter()
        .filter_map(|x| {
            let p = &nodes[x.parent?];
            let d = x.position.coords - p.position.coords;
            let len = d.norm();
            (len > 0.0).then(|| Cone {
                a: p.position.coords,
                u: d / len,
                len,
                ra: p.radius_m,
                rb: x.radius_m,
            })
        })
        .collect()
}

/// Measure a model against its cloud by issue 22's measure (see the module docs).
pub fn fidelity(points: &[Point3<f64>], skeleton: &Skeleton) -> Fidelity {
    let cones = cones(skeleton);
    let axis_length_m = cones.iter().map(|c| c.len).sum();
    if cones.is_empty() || points.is_empty() {
        return Fidelity {
            points: points.len(),
            mean_distance_m: if points.is_empty() {
                0.0
            } else {
                f64::INFINITY
            },
            within_2cm: 0.0,
            model_near_cloud: 0.0,
            axis_length_m,
        };
    }
    let mids: Vec<[f64; 3]> = cones
        .iter()
        .map(|c| {
            let m = c.a + c.u * (0.5 * c.len);
            [m.x, m.y, m.z]
        })
        .collect();
    let edges: ImmutableKdTree<f64, u32, 3, 32> = ImmutableKdTree::new_from_slice(&mids);
    let k = crate::cloud::at_least_one(CANDIDATE_EDGES.min(cones.len()));
    let (mut sum, mut within) = (0.0, 0usize);
    for p in points {
        let d = edges
            .nearest_n::<SquaredEuclidean>(&[p.x, p.y, p.z], k)
            .iter()
            .map(|nb| cones[nb.item as usize].distance(&p.coords))
            .fold(f64::INFINITY, f64::min);
        sum += d;
        within += usize::from(d <= NEAR_CLOUD_M);
    }
    let pts: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
    let cloud: ImmutableKdTree<f64, u32, 3, 32> = ImmutableKdTree::new_from_slice(&pts);
    Fidelity {
        points: points.len(),
        mean_distance_m: sum / points.len() as f64,
        within_2cm: within as f64 / points.len() as f64,
        model_near_cloud: near_length(&cones, &cloud) / axis_length_m,
        axis_length_m,
    }
}

/// Share of `skeleton`'s axis length near the points of `cloud` (the module docs' "model
/// near cloud"); 0 for a skeleton without length.
pub(crate) fn model_near_cloud(
    skeleton: &Skeleton,
    cloud: &ImmutableKdTree<f64, u32, 3, 32>,
) -> f64 {
    let cones = cones(skeleton);
    let length: f64 = cones.iter().map(|c| c.len).sum();
    if length > 0.0 {
        near_length(&cones, cloud) / length
    } else {
        0.0
    }
}

/// Axis length of `cones`, sampled every [`MODEL_SAMPLE_M`], whose nearest point in `cloud`
/// lies within the local radius + [`NEAR_CLOUD_M`], metres.
fn near_length(cones: &[Cone], cloud: &ImmutableKdTree<f64, u32, 3, 32>) -> f64 {
    let mut near = 0.0;
    for c in cones {
        let n = ((c.len / MODEL_SAMPLE_M).ceil() as usize).clamp(1, MAX_SAMPLES_PER_EDGE);
        let piece = c.len / n as f64;
        for s in 0..n {
            let t = (s as f64 + 0.5) * piece;
            let q = c.a + c.u * t;
            let d = cloud
                .nearest_one::<SquaredEuclidean>(&[q.x, q.y, q.z])
                .distance
                .sqrt();
            if d <= c.radius_at(t) + NEAR_CLOUD_M {
                near += piece;
            }
        }
    }
    near
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skeleton::SkeletonNode;

    fn node(id: usize, parent: Option<usize>, p: [f64; 3], r: f64) -> SkeletonNode {
        SkeletonNode {
            id,
            parent,
            position: Point3::from(p),
            radius_m: r,
        }
    }

    /// A cone from radius 0.10 to 0.02 over 1 m, and points on its surface, on its axis and
    /// beside it: each distance is known.
    #[test]
    fn cone_distances_and_support_are_exact() {
        let s = Skeleton::new(vec![
            node(0, None, [0.0, 0.0, 0.0], 0.10),
            node(1, Some(0), [0.0, 0.0, 1.0], 0.02),
        ])
        .unwrap_or_else(|e| panic!("{e}"));
        // On the surface at z = 0.5 (radius 0.06): distance 0.
        // On the axis at z = 0.25 (radius 0.08): distance 0.08.
        // Beyond the top, 0.1 m above the tip on the axis: |0.1 - 0.02| = 0.08.
        let pts = [
            Point3::new(0.06, 0.0, 0.5),
            Point3::new(0.0, 0.0, 0.25),
            Point3::new(0.0, 0.0, 1.1),
        ];
        let f = fidelity(&pts, &s);
        approx::assert_relative_eq!(
            f.mean_distance_m,
            (0.0 + 0.08 + 0.08) / 3.0,
            epsilon = 1e-12
        );
        approx::assert_relative_eq!(f.within_2cm, 1.0 / 3.0, epsilon = 1e-12);
        // Samples near a point within radius + 2 cm: z in [0.25 - 0.10, 0.25 + ...] etc.
        // Check against a brute-force sum over the same 100 samples.
        let mut near = 0.0;
        for k in 0..100 {
            let z = (k as f64 + 0.5) * 0.01;
            let r = 0.10 - 0.08 * z;
            let d = pts
                .iter()
                .map(|p| (p.coords - Vector3::new(0.0, 0.0, z)).norm())
                .fold(f64::INFINITY, f64::min);
            if d <= r + 0.02 {
                near += 0.01;
            }
        }
        approx::assert_relative_eq!(f.model_near_cloud, near, epsilon = 1e-9);
        assert!(
            f.model_near_cloud > 0.1 && f.model_near_cloud < 0.9,
            "{f:?}"
        );
    }

    #[test]
    fn a_model_without_edges_is_infinitely_far() {
        let s = Skeleton::new(vec![node(0, None, [0.0; 3], 0.1)]).unwrap_or_else(|e| panic!("{e}"));
        let f = fidelity(&[Point3::new(1.0, 0.0, 0.0)], &s);
        assert!(f.mean_distance_m.is_infinite());
        assert_eq!(f.model_near_cloud, 0.0);
    }
}
