//! The branch model: each skeleton branch as a curved beam of four segments.

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};
use space_colonize::{Skeleton, SkeletonNode};

use crate::error::{AnimError, Result};

/// Segments per branch (the paper's curved beam P0..P4, fig. 13).
pub const SEGMENTS: usize = 4;
/// Density of green hardwood, kg/m³ (USDA Wood Handbook FPL-GTR-190, 2010: green specific
/// gravity about 0.5 plus moisture content near 60 % of dry weight gives 800).
pub const GREEN_WOOD_DENSITY_KG_M3: f64 = 800.0;

/// One branch as a beam of [`SEGMENTS`] equal-length segments, in the rest pose.
#[derive(Debug, Clone, PartialEq)]
pub struct BeamBranch {
    /// Id of its first skeleton node (the branch's name in files).
    pub id: usize,
    /// Index of the branch it grows from in [`BeamTree::branches`].
    pub parent: Option<usize>,
    /// Global index of the parent's segment it is attached to.
    pub parent_segment: Option<usize>,
    /// Branch order (the paper's level): 0 for the trunk.
    pub order: usize,
    /// P0..P4 at rest, metres.
    pub points: [Point3<f64>; SEGMENTS + 1],
    /// Radius of each segment, metres.
    pub radii_m: [f64; SEGMENTS],
    /// Length along the skeleton, metres.
    pub length_m: f64,
    /// Wood mass of the branch's own segments, kg.
    pub mass_kg: f64,
    /// Unit vector along the chord P0 → P4 (the beam's v axis).
    pub v: Vector3<f64>,
    /// Unit vector across the beam toward the reference direction (u axis).
    pub u: Vector3<f64>,
    /// v × u... the w axis (u, v, w right-handed: w = u × v).
    pub w: Vector3<f64>,
}

/// A branch's polyline (points and radii, with the arc length at each) resampled at
/// `SEGMENTS` equal steps: segment end points, and radii at the segment midpoints.
fn resample(
    poly: &[(Point3<f64>, f64)],
    s_at: &[f64],
    length_m: f64,
) -> ([Point3<f64>; SEGMENTS + 1], [f64; SEGMENTS]) {
    let at = |target: f64| -> (Point3<f64>, f64) {
        let k = s_at
            .partition_point(|&x| x < target)
            .clamp(1, poly.len() - 1);
        let (s0, s1) = (s_at[k - 1], s_at[k]);
        let t = if s1 > s0 {
            ((target - s0) / (s1 - s0)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (lerp_point(&poly[k - 1].0, &poly[k].0, t), poly[k].1)
    };
    let seg = length_m / SEGMENTS as f64;
    (
        std::array::from_fn(|k| at(k as f64 * seg).0),
        std::array::from_fn(|k| at((k as f64 + 0.5) * seg).1),
    )
}

/// A branch's axis `v` (base to tip) and its bending axis `u` toward `reference` (or any
/// perpendicular when the branch points along it); `None` for a branch without length.
fn axes(
    points: &[Point3<f64>; SEGMENTS + 1],
    reference: &Vector3<f64>,
) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let v = (points[SEGMENTS] - points[0]).try_normalize(1e-12)?;
    let u = (reference - v * reference.dot(&v))
        .try_normalize(1e-6)
        .or_else(|| Vector3::z().cross(&v).try_normalize(1e-6))
        .unwrap_or_else(|| Vector3::x().cross(&v).normalize());
    Some((v, u))
}

/// A tree of beams, parents before children.
#[derive(Debug, Clone, PartialEq)]
pub struct BeamTree {
    branches: Vec<BeamBranch>,
    by_id: HashMap<usize, usize>,
}

/// Parse space-colonize's skeleton JSON with space-colonize's own reader
/// ([`space_colonize::skeleton_nodes_from_json`]) and check it with [`validate_nodes`]
/// (this crate's typed errors, ranges and segment rules); `path` names the text in errors.
///
/// # Errors
/// [`AnimError::Format`] for JSON that is not a skeleton, then as [`validate_nodes`].
pub fn skeleton_from_json(text: &str, path: &std::path::Path) -> Result<Skeleton> {
    let nodes = space_colonize::skeleton_nodes_from_json(text, path).map_err(|e| match e {
        space_colonize::ColonizeError::Format { reason, .. } => AnimError::format(path, reason),
        other => AnimError::format(path, other.to_string()),
    })?;
    validate_nodes(&nodes)
}

/// Read a skeleton JSON file (space-colonize's `--out-skeleton`).
///
/// # Errors
/// [`AnimError::Io`], then as [`skeleton_from_json`].
pub fn read_skeleton(path: &std::path::Path) -> Result<Skeleton> {
    let text = std::fs::read_to_string(path).map_err(|e| AnimError::io(path, e))?;
    skeleton_from_json(&text, path)
}

/// Largest coordinate of a skeleton node, metres: 10,000 km (any georeferenced frame fits;
/// a corrupt 1e300 does not).
pub const MAX_POSITION_M: f64 = 1e7;

/// Largest radius of a skeleton node, metres (the thickest trees measure about 6 m across
/// their trunk's radius at the base: the Árbol del Tule).
pub const MAX_RADIUS_M: f64 = 20.0;

/// Validate raw skeleton nodes (ids 0..n in any order) with this crate's errors.
///
/// # Errors
/// [`AnimError::InvalidSkeleton`] (no nodes, duplicate or out-of-range ids, no root, a
/// parent that does not exist, a non-finite position, a radius that is negative or not
/// finite), [`AnimError::Cycle`],
/// [`AnimError::Disconnected`] (a second root's nodes), [`AnimError::ZeroLengthSegment`].
pub fn validate_nodes(nodes: &[SkeletonNode]) -> Result<Skeleton> {
    let n = nodes.len();
    let bad = |reason: String| AnimError::InvalidSkeleton { reason };
    if n == 0 {
        return Err(bad("no nodes".into()));
    }
    let mut at = vec![usize::MAX; n];
    for (k, node) in nodes.iter().enumerate() {
        if node.id >= n || at[node.id] != usize::MAX {
            return Err(bad(format!(
                "node id {} is out of range or repeated",
                node.id
            )));
        }
        if !node.position.coords.iter().all(|c| c.is_finite()) {
            return Err(bad(format!(
                "node {} has position {:?}, which is not finite",
                node.id,
                [node.position.x, node.position.y, node.position.z]
            )));
        }
        if let Some(far) = node
            .position
            .coords
            .iter()
            .find(|c| c.abs() > MAX_POSITION_M)
        {
            return Err(bad(format!(
                "node {} has coordinate {far:e} m, beyond {MAX_POSITION_M:e} m (further than any point on Earth from any origin)",
                node.id
            )));
        }
        if !node.radius_m.is_finite() {
            return Err(bad(format!(
                "node {} has radius {} m, which is not finite",
                node.id, node.radius_m
            )));
        }
        if node.radius_m < 0.0 {
            return Err(bad(format!(
                "node {} has radius {} m; a radius cannot be negative",
                node.id, node.radius_m
            )));
        }
        if node.radius_m > MAX_RADIUS_M {
            return Err(bad(format!(
                "node {} has radius {:e} m; no tree is thicker than {MAX_RADIUS_M} m",
                node.id, node.radius_m
            )));
        }
        at[node.id] = k;
    }
    let parent = |id: usize| nodes[at[id]].parent;
    for node in nodes {
        if let Some(p) = node.parent
            && p >= n
        {
            return Err(bad(format!(
                "node {} has parent {p}, which does not exist",
                node.id
            )));
        }
    }
    let roots: Vec<usize> = (0..n).filter(|&i| parent(i).is_none()).collect();
    // 0 = unseen, 1 = on the current walk, 2 = reaches a root.
    let mut state = vec![0u8; n];
    for start in 0..n {
        let mut walk = Vec::new();
        let mut v = start;
        while state[v] == 0 {
            state[v] = 1;
            walk.push(v);
            match parent(v) {
                Some(p) => v = p,
                None => break,
            }
        }
        if state[v] == 1 && parent(v).is_some() {
            return Err(AnimError::Cycle { node: v });
        }
        for w in walk {
            state[w] = 2;
        }
    }
    if roots.is_empty() {
        return Err(bad("no root (every node has a parent)".into()));
    }
    if let Some(&second) = roots.get(1) {
        return Err(AnimError::Disconnected { node: second });
    }
    for node in nodes {
        if let Some(p) = node.parent
            && (nodes[at[p]].position - node.position).norm() <= 0.0
        {
            return Err(AnimError::ZeroLengthSegment { node: node.id });
        }
    }
    Skeleton::new(nodes.to_vec()).map_err(|e| bad(e.to_string()))
}

/// Branches (sorted so that parents come first) in depth-first pre-order.
fn depth_first(raw: Vec<space_colonize::Branch>) -> Vec<space_colonize::Branch> {
    let index: HashMap<usize, usize> = raw.iter().enumerate().map(|(k, b)| (b.id, k)).collect();
    let mut children = vec![Vec::new(); raw.len()];
    let mut roots = Vec::new();
    for (k, b) in raw.iter().enumerate() {
        match b.parent.and_then(|p| index.get(&p)) {
            Some(&pi) => children[pi].push(k),
            None => roots.push(k),
        }
    }
    let mut order = Vec::with_capacity(raw.len());
    let mut stack: Vec<usize> = roots.into_iter().rev().collect();
    while let Some(k) = stack.pop() {
        order.push(k);
        stack.extend(children[k].iter().rev());
    }
    let mut slots: Vec<Option<space_colonize::Branch>> = raw.into_iter().map(Some).collect();
    order.into_iter().filter_map(|k| slots[k].take()).collect()
}

fn lerp_point(a: &Point3<f64>, b: &Point3<f64>, t: f64) -> Point3<f64> {
    a + (b - a) * t
}

impl BeamTree {
    /// Beams from a skeleton for an animation configured by `config`: its wood density, and
    /// u axes toward its wind's direction.
    ///
    /// # Errors
    /// As [`BeamTree::with_density`].
    pub fn new(skeleton: &Skeleton, config: &crate::AnimConfig) -> Result<Self> {
        Self::with_density(skeleton, config.wood_density_kg_m3, &config.wind.direction)
    }

    /// Beams from a skeleton, with u axes toward `reference_direction` (the wind's).
    ///
    /// # Errors
    /// [`AnimError::ZeroLengthSegment`] for a segment without length,
    /// [`AnimError::InvalidParameter`] for a density that is not positive or a reference
    /// direction that is not finite.
    pub fn with_density(
        skeleton: &Skeleton,
        wood_density_kg_m3: f64,
        reference_direction: &Vector3<f64>,
    ) -> Result<Self> {
        if !(wood_density_kg_m3.is_finite() && wood_density_kg_m3 > 0.0) {
            return Err(AnimError::param(
                "wood_density_kg_m3",
                format!("{wood_density_kg_m3}; must be positive"),
            ));
        }
        let reference = reference_direction.try_normalize(1e-12).ok_or_else(|| {
            AnimError::param(
                "reference_direction",
                format!("{reference_direction:?}; must be a non-zero finite vector"),
            )
        })?;
        let nodes = skeleton.nodes();
        for node in nodes {
            if node.parent.is_some() && skeleton.segment_length_m(node.id) <= 0.0 {
                return Err(AnimError::ZeroLengthSegment { node: node.id });
            }
        }
        let mut raw = skeleton.branches();
        // Parents before children: branches sorted by the topological rank of their base.
        let mut rank = vec![0usize; nodes.len()];
        for (k, &v) in skeleton.topological_order().iter().enumerate() {
            rank[v] = k;
        }
        raw.sort_by_key(|b| b.base_node.map_or(0, |n| rank[n] + 1));
        // Then depth first (pre-order), children in the order they leave their parent, so
        // that a branch's descendants follow it closely (locality for the frame loop).
        let raw = depth_first(raw);
        let by_id: HashMap<usize, usize> = raw.iter().enumerate().map(|(k, b)| (b.id, k)).collect();
        // Arc length of every node along its branch's polyline (from the branch base).
        let mut arc = vec![0.0; nodes.len()];
        let mut branches: Vec<BeamBranch> = Vec::with_capacity(raw.len());
        for b in &raw {
            let mut poly: Vec<(Point3<f64>, f64)> = Vec::with_capacity(b.nodes.len() + 1);
            let start = b.base_node.unwrap_or(b.nodes[0]);
            poly.push((nodes[start].position, nodes[b.nodes[0]].radius_m));
            let mut s = 0.0;
            let mut s_at = Vec::with_capacity(b.nodes.len() + 1);
            s_at.push(0.0);
            let own = if b.base_node.is_some() {
                &b.nodes[..]
            } else {
                &b.nodes[1..]
            };
            for &v in own {
                let p = nodes[v].position;
                let last = poly.last().map_or(p, |q| q.0);
                s += (p - last).norm();
                poly.push((p, nodes[v].radius_m));
                s_at.push(s);
                arc[v] = s;
            }
            let length_m = s;
            if poly.len() < 2 || length_m <= 0.0 {
                return Err(AnimError::ZeroLengthSegment { node: b.id });
            }
            let (points, radii_m) = resample(&poly, &s_at, length_m);
            let mut mass_kg = 0.0;
            for k in 0..SEGMENTS {
                let l = (points[k + 1] - points[k]).norm();
                if l <= 0.0 {
                    return Err(AnimError::ZeroLengthSegment { node: b.id });
                }
                mass_kg += wood_density_kg_m3 * std::f64::consts::PI * radii_m[k].powi(2) * l;
            }
            let (v, u) =
                axes(&points, &reference).ok_or(AnimError::ZeroLengthSegment { node: b.id })?;
            let parent = b.parent.and_then(|p| by_id.get(&p).copied());
            let parent_segment = match (parent, b.base_node) {
                (Some(pi), Some(base)) => {
                    let pl = branches[pi].length_m;
                    let k =
                        ((arc[base] / (pl / SEGMENTS as f64)).floor() as usize).min(SEGMENTS - 1);
                    Some(pi * SEGMENTS + k)
                }
                _ => None,
            };
            branches.push(BeamBranch {
                id: b.id,
                parent,
                parent_segment,
                order: b.order,
                points,
                radii_m,
                length_m,
                mass_kg,
                v,
                u,
                w: u.cross(&v),
            });
        }
        Ok(Self { branches, by_id })
    }

    /// The branches, parents before children.
    pub fn branches(&self) -> &[BeamBranch] {
        &self.branches
    }

    /// Index of the branch named `id` (its first skeleton node).
    ///
    /// # Errors
    /// [`AnimError::UnknownBranch`].
    pub fn index_of(&self, id: usize) -> Result<usize> {
        self.by_id
            .get(&id)
            .copied()
            .ok_or(AnimError::UnknownBranch { id })
    }

    /// Number of segments ([`SEGMENTS`] per branch).
    pub fn segment_count(&self) -> usize {
        self.branches.len() * SEGMENTS
    }

    /// Rest position of the start of global segment `s` (branch `s / 4`, segment `s % 4`).
    pub fn segment_start(&self, s: usize) -> Point3<f64> {
        self.branches[s / SEGMENTS].points[s % SEGMENTS]
    }

    /// Extent of the tree along `direction`: (min, max) of the rest points' projections.
    pub fn extent_along(&self, direction: &Vector3<f64>) -> (f64, f64) {
        self.branches
            .iter()
            .flat_map(|b| b.points.iter())
            .map(|p| p.coords.dot(direction))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            })
    }
}
