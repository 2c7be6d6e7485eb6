//! Procedural trees of any size, for benchmarks and tests.

use nalgebra::{Point3, UnitQuaternion, Vector3};
use rand_xoshiro::SplitMix64;
use rand_xoshiro::rand_core::{RngCore, SeedableRng};
use space_colonize::{Skeleton, SkeletonNode};

use crate::error::{AnimError, Result};
use crate::tree::SEGMENTS;

/// A tree of `branches` branches, each of [`SEGMENTS`] skeleton segments: a 5 m trunk of
/// radius 15 cm, then each new branch on a node of an earlier one (breadth first, so orders
/// fill level by level), 40° off its parent, 0.7 of its parent's length and radius at the
/// base. Seeded; Z up.
///
/// # Errors
/// [`AnimError::InvalidParameter`] for zero branches.
pub fn procedural_tree(branches: usize, seed: u64) -> Result<Skeleton> {
    if branches == 0 {
        return Err(AnimError::param(
            "branches",
            "0; a tree has at least its trunk",
        ));
    }
    let mut rng = SplitMix64::seed_from_u64(seed);
    let mut uniform = move || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    let mut nodes: Vec<SkeletonNode> = Vec::with_capacity(branches * SEGMENTS + 1);
    // (first node, direction, length, base radius) per branch.
    let mut made: Vec<(usize, Vector3<f64>, f64, f64)> = Vec::with_capacity(branches);
    let grow = |nodes: &mut Vec<SkeletonNode>,
                base: Option<usize>,
                from: Point3<f64>,
                dir: Vector3<f64>,
                len: f64,
                r0: f64| {
        let first = nodes.len();
        let mut parent = base;
        for k in 0..=SEGMENTS {
            if k == 0 && base.is_some() {
                continue;
            }
            let id = nodes.len();
            let t = k as f64 / SEGMENTS as f64;
            nodes.push(SkeletonNode {
                id,
                parent,
                position: from + dir * (len * t),
                radius_m: r0 * (1.0 - 0.6 * t),
            });
            parent = Some(id);
        }
        first
    };
    let first = grow(&mut nodes, None, Point3::origin(), Vector3::z(), 5.0, 0.15);
    made.push((first, Vector3::z(), 5.0, 0.15));
    let mut next_parent = 0;
    while made.len() < branches {
        let (pfirst, pdir, plen, pr) = made[next_parent];
        // Each branch carries up to 3 children, then the next one takes over.
        if made.len() > 3 * (next_parent + 1) {
            next_parent += 1;
            continue;
        }
        let k = 1 + (uniform() * (SEGMENTS - 1) as f64) as usize;
        let base = pfirst + k - usize::from(pfirst == 0);
        let base = base.min(nodes.len() - 1);
        let side = pdir
            .cross(&Vector3::x())
            .try_normalize(1e-6)
            .unwrap_or_else(Vector3::y);
        let az = UnitQuaternion::from_axis_angle(
            &nalgebra::Unit::new_normalize(pdir),
            std::f64::consts::TAU * uniform(),
        );
        let axis = nalgebra::Unit::new_normalize(az * side);
        let dir = UnitQuaternion::from_axis_angle(&axis, 40f64.to_radians()) * pdir;
        let from = nodes[base].position;
        let r = pr * 0.7;
        let first = grow(&mut nodes, Some(base), from, dir, plen * 0.7, r);
        made.push((first, dir, plen * 0.7, r));
    }
    Skeleton::new(nodes).map_err(|e| AnimError::InvalidSkeleton {
        reason: e.to_string(),
    })
}
