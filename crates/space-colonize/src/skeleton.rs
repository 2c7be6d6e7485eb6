//! The tree skeleton: nodes with parent links and radii, branches, orders, JSON files.

use std::path::Path;

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use crate::error::{ColonizeError, Result};

/// One skeleton node. The segment from its parent to it is a cylinder of radius `radius_m`
/// (the root's radius is the trunk's at its base).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkeletonNode {
    /// Index in [`Skeleton::nodes`].
    pub id: usize,
    /// Parent node, `None` for the root.
    pub parent: Option<usize>,
    /// Position, metres, tree frame (Z up).
    pub position: Point3<f64>,
    /// Radius of the segment ending here, metres.
    pub radius_m: f64,
}

/// A branch: a chain of nodes that continues through each fork along the child carrying the
/// most tree beyond it (TreeQSM's convention); the other children start branches one order
/// higher. Named by its first node: the root for the trunk, otherwise the first node after
/// the fork it grows from.
#[derive(Debug, Clone, PartialEq)]
pub struct Branch {
    /// Id of its first node.
    pub id: usize,
    /// Branch it grows from (`None` for the trunk).
    pub parent: Option<usize>,
    /// The fork node on the parent branch it starts at (`None` for the trunk).
    pub base_node: Option<usize>,
    /// Its nodes, base to tip (the fork node not included).
    pub nodes: Vec<usize>,
    /// 0 for the trunk, 1 for branches on the trunk, and so on (the paper's levels).
    pub order: usize,
    /// Length from the fork (or root) to the tip, metres.
    pub length_m: f64,
}

/// Most of a branch counted as inside its parent, in parent radii (a branch leaving at 15°
/// crosses its parent's surface 3.9 radii from the fork).
pub const MAX_INSIDE_RADII: f64 = 4.0;

/// A validated tree of nodes: one root, every other node's parent exists, no cycles.
#[derive(Debug, Clone, PartialEq)]
pub struct Skeleton {
    nodes: Vec<SkeletonNode>,
    children: Vec<Vec<usize>>,
    /// Nodes with every parent before its children.
    order: Vec<usize>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonNode {
    id: usize,
    parent: Option<usize>,
    position: [f64; 3],
    radius: f64,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonSkeleton {
    nodes: Vec<JsonNode>,
}

impl Skeleton {
    /// Validate nodes into a skeleton. Ids must be 0..n in any order (they are sorted).
    ///
    /// # Errors
    /// [`ColonizeError::InvalidSkeleton`] naming the node: duplicate or out-of-range id, no
    /// root or two, a parent that does not exist, a cycle or a node not connected to the
    /// root, a position that is not finite, a radius that is negative or not finite.
    pub fn new(mut nodes: Vec<SkeletonNode>) -> Result<Self> {
        let n = nodes.len();
        if n == 0 {
            return Err(ColonizeError::skeleton("no nodes"));
        }
        nodes.sort_by_key(|node| node.id);
        for (i, node) in nodes.iter().enumerate() {
            if node.id != i {
                return Err(ColonizeError::skeleton(format!(
                    "node ids must be 0..{n} once each; id {} is {}",
                    node.id,
                    if node.id < i {
                        "repeated"
                    } else {
                        "out of range or leaves a gap"
                    }
                )));
            }
            if !node.position.iter().all(|c| c.is_finite()) {
                return Err(ColonizeError::skeleton(format!(
                    "node {i} has position {:?}, which is not finite",
                    node.position.coords.as_slice()
                )));
            }
            if !(node.radius_m.is_finite() && node.radius_m >= 0.0) {
                return Err(ColonizeError::skeleton(format!(
                    "node {i} has radius {} m; must be finite and not negative",
                    node.radius_m
                )));
            }
            if let Some(p) = node.parent
                && (p >= n || p == i)
            {
                return Err(ColonizeError::skeleton(format!(
                    "node {i} has parent {p}, which {}",
                    if p == i {
                        "is itself"
                    } else {
                        "does not exist"
                    }
                )));
            }
        }
        let roots: Vec<usize> = nodes
            .iter()
            .filter(|x| x.parent.is_none())
            .map(|x| x.id)
            .collect();
        if roots.len() != 1 {
            return Err(ColonizeError::skeleton(format!(
                "{} roots ({:?}); a tree has exactly one node without a parent",
                roots.len(),
                &roots[..roots.len().min(5)]
            )));
        }
        let mut children = vec![Vec::new(); n];
        for node in &nodes {
            if let Some(p) = node.parent {
                children[p].push(node.id);
            }
        }
        let mut order = Vec::with_capacity(n);
        order.push(roots[0]);
        let mut k = 0;
        while k < order.len() {
            let v = order[k];
            order.extend_from_slice(&children[v]);
            k += 1;
        }
        if order.len() != n {
            let mut seen = vec![false; n];
            for &v in &order {
                seen[v] = true;
            }
            let lost = seen.iter().position(|s| !s).unwrap_or(0);
            return Err(ColonizeError::skeleton(format!(
                "node {lost} is not connected to the root {} (its parents form a cycle)",
                roots[0]
            )));
        }
        Ok(Self {
            nodes,
            children,
            order,
        })
    }

    /// The same skeleton with every node moved by `f` (ids, parents and radii kept): a
    /// skeleton turned or shifted into another frame.
    ///
    /// # Errors
    /// [`ColonizeError::InvalidSkeleton`] when `f` gives a position that is not finite.
    pub fn map_positions(&self, f: impl Fn(&Point3<f64>) -> Point3<f64>) -> Result<Self> {
        Self::new(
            self.nodes
                .iter()
                .map(|n| SkeletonNode {
                    position: f(&n.position),
                    ..*n
                })
                .collect(),
        )
    }

    /// The nodes, indexed by id.
    pub fn nodes(&self) -> &[SkeletonNode] {
        &self.nodes
    }

    /// Children of a node.
    pub fn children(&self, id: usize) -> &[usize] {
        self.children.get(id).map_or(&[], Vec::as_slice)
    }

    /// The root node's id.
    pub fn root(&self) -> usize {
        self.order[0]
    }

    /// Node ids with every parent before its children (breadth first from the root).
    pub fn topological_order(&self) -> &[usize] {
        &self.order
    }

    /// Length of the segment from a node's parent to it, metres (0 for the root).
    pub fn segment_length_m(&self, id: usize) -> f64 {
        let node = &self.nodes[id];
        node.parent
            .map_or(0.0, |p| (node.position - self.nodes[p].position).norm())
    }

    /// Sum of all segment lengths, metres.
    pub fn total_length_m(&self) -> f64 {
        (0..self.nodes.len())
            .map(|i| self.segment_length_m(i))
            .sum()
    }

    /// Volume of the segments as cylinders, cubic metres.
    pub fn volume_m3(&self) -> f64 {
        self.nodes
            .iter()
            .map(|x| std::f64::consts::PI * x.radius_m.powi(2) * self.segment_length_m(x.id))
            .sum()
    }

    /// Length of each node's segment that lies inside the branch its branch grows from,
    /// metres: a branch's first segments start at the fork node on its parent's axis, and
    /// run inside the parent until they cross its surface, a cylinder of the fork node's
    /// radius about the parent's axis there (through the fork's parent and the next node of
    /// the parent branch). That part is the parent's wood. TreeQSM starts a branch's first
    /// cylinder on its parent's surface, so lengths and volumes compare only without it
    /// ([`crate::cylinders`] leaves it out). At most [`MAX_INSIDE_RADII`] parent radii of a
    /// branch count (a child nearly parallel to its parent).
    pub fn inside_parent_m(&self) -> Vec<f64> {
        let mut inside = vec![0.0; self.nodes.len()];
        let pos = |i: usize| self.nodes[i].position.coords;
        let branches = self.branches();
        let mut branch_of = vec![0; self.nodes.len()];
        for (k, b) in branches.iter().enumerate() {
            b.nodes.iter().for_each(|&v| branch_of[v] = k);
        }
        for b in &branches {
            let Some(f) = b.base_node else { continue };
            let r = self.nodes[f].radius_m;
            // The parent branch's node after the fork.
            let next = self.children[f]
                .iter()
                .copied()
                .find(|&c| branch_of[c] == branch_of[f]);
            let axis = match (self.nodes[f].parent, next) {
                (Some(p), Some(n)) => pos(n) - pos(p),
                (Some(p), None) => pos(f) - pos(p),
                (None, Some(n)) => pos(n) - pos(f),
                (None, None) => continue,
            };
            let Some(axis) = axis.try_normalize(1e-12) else {
                continue;
            };
            let perp = |v: nalgebra::Vector3<f64>| v - axis * v.dot(&axis);
            let (mut prev, mut total) = (pos(f), 0.0);
            for &v in &b.nodes {
                let seg = pos(v) - prev;
                let len = seg.norm();
                let (w0, w1) = (perp(prev - pos(f)), perp(seg));
                let (qa, qb, qc) = (
                    w1.norm_squared(),
                    2.0 * w0.dot(&w1),
                    w0.norm_squared() - r * r,
                );
                if qc >= 0.0 {
                    break;
                }
                // Share of the segment before it crosses the surface (all of it when it runs
                // parallel to the axis).
                let t = if qa > 0.0 {
                    ((-qb + (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa)).min(1.0)
                } else {
                    1.0
                };
                let part = (t * len).min(MAX_INSIDE_RADII * r - total).max(0.0);
                inside[v] = part;
                total += part;
                if t < 1.0 || total >= MAX_INSIDE_RADII * r {
                    break;
                }
                prev = pos(v);
            }
        }
        inside
    }

    /// Length of tree carried by each segment: its own length plus everything beyond it,
    /// metres (the pipe model's weight).
    pub fn carried_length_m(&self) -> Vec<f64> {
        let mut w: Vec<f64> = (0..self.nodes.len())
            .map(|i| self.segment_length_m(i))
            .collect();
        for &v in self.order.iter().rev() {
            if let Some(p) = self.nodes[v].parent
                && self.nodes[p].parent.is_some()
            {
                w[p] += w[v];
            }
        }
        // The root carries its children.
        let root = self.root();
        w[root] = self.children[root].iter().map(|&c| w[c]).sum();
        w
    }

    /// The branches, trunk first, then in the order their first nodes are met breadth
    /// first. At a fork the branch continues into the child carrying the most length.
    pub fn branches(&self) -> Vec<Branch> {
        let carried = self.carried_length_m();
        let mut out: Vec<Branch> = Vec::new();
        // (first node, parent branch index, fork node, order)
        let mut queue: std::collections::VecDeque<(usize, Option<usize>, Option<usize>, usize)> =
            std::collections::VecDeque::new();
        queue.push_back((self.root(), None, None, 0));
        while let Some((first, parent_idx, base, order)) = queue.pop_front() {
            let idx = out.len();
            let mut nodes = vec![first];
            let mut length_m = self.segment_length_m(first);
            let mut v = first;
            loop {
                let kids = &self.children[v];
                let Some(&main) = kids
                    .iter()
                    .max_by(|&&a, &&b| carried[a].total_cmp(&carried[b]).then(b.cmp(&a)))
                else {
                    break;
                };
                for &k in kids {
                    if k != main {
                        queue.push_back((k, Some(idx), Some(v), order + 1));
                    }
                }
                nodes.push(main);
                length_m += self.segment_length_m(main);
                v = main;
            }
            out.push(Branch {
                id: first,
                parent: parent_idx.map(|p: usize| out[p].id),
                base_node: base,
                nodes,
                order,
                length_m,
            });
        }
        out
    }

    /// The skeleton as JSON: `{"nodes": [{"id", "parent", "position": [x, y, z],
    /// "radius"}]}`, metres.
    ///
    /// # Errors
    /// Never in practice (serialisation of finite numbers); kept for the signature.
    pub fn to_json(&self) -> Result<String> {
        let doc = JsonSkeleton {
            nodes: self
                .nodes
                .iter()
                .map(|x| JsonNode {
                    id: x.id,
                    parent: x.parent,
                    position: [x.position.x, x.position.y, x.position.z],
                    radius: x.radius_m,
                })
                .collect(),
        };
        serde_json::to_string_pretty(&doc).map_err(|e| ColonizeError::Format {
            path: "skeleton JSON".into(),
            reason: e.to_string(),
        })
    }

    /// Parse the JSON of [`Skeleton::to_json`]; `path` only names it in errors.
    ///
    /// # Errors
    /// [`ColonizeError::Format`] for JSON that does not match, then as [`Skeleton::new`].
    pub fn from_json(text: &str, path: &Path) -> Result<Self> {
        Self::new(skeleton_nodes_from_json(text, path)?)
    }

    /// Read a skeleton JSON file.
    ///
    /// # Errors
    /// [`ColonizeError::Io`], then as [`Skeleton::from_json`].
    pub fn read_json(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| ColonizeError::io(path, e))?;
        Self::from_json(&text, path)
    }

    /// Write [`Skeleton::to_json`] to a file.
    ///
    /// # Errors
    /// [`ColonizeError::Io`].
    pub fn write_json(&self, path: &Path) -> Result<()> {
        std::fs::write(path, self.to_json()?).map_err(|e| ColonizeError::io(path, e))
    }
}

/// The nodes of a skeleton JSON (`{"nodes": [{"id", "parent", "position": [x, y, z],
/// "radius"}]}`, unknown fields refused), not yet checked as a tree: the one reader of the
/// format, for [`Skeleton::from_json`] and for crates that check skeletons with rules and
/// errors of their own (beam-anim). `path` only names the text in errors.
///
/// # Errors
/// [`ColonizeError::Format`] for JSON that does not match the format.
pub fn skeleton_nodes_from_json(text: &str, path: &Path) -> Result<Vec<SkeletonNode>> {
    let doc: JsonSkeleton = serde_json::from_str(text).map_err(|e| ColonizeError::Format {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    Ok(doc
        .nodes
        .into_iter()
        .map(|x| SkeletonNode {
            id: x.id,
            parent: x.parent,
            position: Point3::from(x.position),
            radius_m: x.radius,
        })
        .collect())
}
