//! The marker hierarchy: named markers, each with its parent, validated as one tree.

use serde::{Deserialize, Serialize};

use crate::error::{AngleError, Result};

/// One marker of a hierarchy and its parent (`None` for the root).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkerNode {
    /// The marker's id (the paper's A..J).
    pub id: String,
    /// The parent marker's id; `None` for the root.
    pub parent: Option<String>,
}

/// The hierarchy file: `{"markers": [{"id": "A", "parent": null}, ...]}`.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct HierarchyFile {
    markers: Vec<MarkerNode>,
}

/// A validated tree of markers: one root, no cycles, no unknown parents, no duplicate ids.
/// The branch of a child marker is the segment from its parent marker to it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Hierarchy {
    nodes: Vec<MarkerNode>,
    /// Index of each node's parent.
    parents: Vec<Option<usize>>,
    root: usize,
}

/// True when `id` can be a CSV column name and a JSON string without escaping surprises.
pub(crate) fn valid_id(id: &str) -> bool {
    !id.is_empty() && id.trim() == id && !id.contains([',', '"', '\n', '\r'])
}

impl Hierarchy {
    /// Validate `nodes` as one tree. The order is kept (it is the column order of the
    /// outputs).
    ///
    /// # Errors
    /// [`AngleError::EmptyHierarchy`], [`AngleError::InvalidId`], [`AngleError::DuplicateId`],
    /// [`AngleError::UnknownParent`], [`AngleError::NoRoot`], [`AngleError::SeveralRoots`],
    /// [`AngleError::Cycle`].
    pub fn new(nodes: Vec<MarkerNode>) -> Result<Self> {
        if nodes.is_empty() {
            return Err(AngleError::EmptyHierarchy);
        }
        for (k, n) in nodes.iter().enumerate() {
            if !valid_id(&n.id) {
                return Err(AngleError::InvalidId { id: n.id.clone() });
            }
            if nodes[..k].iter().any(|m| m.id == n.id) {
                return Err(AngleError::DuplicateId { id: n.id.clone() });
            }
        }
        let index = |id: &str| nodes.iter().position(|n| n.id == id);
        let mut parents = Vec::with_capacity(nodes.len());
        for n in &nodes {
            parents.push(match &n.parent {
                None => None,
                Some(p) => Some(index(p).ok_or_else(|| AngleError::UnknownParent {
                    id: n.id.clone(),
                    parent: p.clone(),
                })?),
            });
        }
        // A marker that is its own parent is a cycle of one.
        for (k, p) in parents.iter().enumerate() {
            if *p == Some(k) {
                return Err(AngleError::Cycle {
                    ids: vec![nodes[k].id.clone()],
                });
            }
        }
        // Walk up from every marker: a walk longer than the number of markers has a cycle.
        for start in 0..nodes.len() {
            let mut seen = vec![false; nodes.len()];
            let mut at = start;
            while let Some(p) = parents[at] {
                if seen[at] {
                    // Collect the cycle from `at`.
                    let mut ids = vec![nodes[at].id.clone()];
                    let mut k = parents[at].unwrap_or(at);
                    while k != at {
                        ids.push(nodes[k].id.clone());
                        k = parents[k].unwrap_or(at);
                    }
                    return Err(AngleError::Cycle { ids });
                }
                seen[at] = true;
                at = p;
            }
        }
        let roots: Vec<usize> = (0..nodes.len()).filter(|&k| parents[k].is_none()).collect();
        let root = match roots.as_slice() {
            [] => return Err(AngleError::NoRoot),
            [r] => *r,
            many => {
                return Err(AngleError::SeveralRoots {
                    ids: many.iter().map(|&k| nodes[k].id.clone()).collect(),
                });
            }
        };
        Ok(Self {
            nodes,
            parents,
            root,
        })
    }

    /// Parse and validate `{"markers": [{"id": "A", "parent": null}, ...]}`.
    ///
    /// # Errors
    /// [`AngleError::Json`] for malformed JSON or another shape; then as [`Hierarchy::new`].
    pub fn from_json(text: &str) -> Result<Self> {
        let file: HierarchyFile = serde_json::from_str(text)?;
        Self::new(file.markers)
    }

    /// The hierarchy as the JSON [`Hierarchy::from_json`] reads.
    pub fn to_json(&self) -> String {
        let file = HierarchyFile {
            markers: self.nodes.clone(),
        };
        // Serialising plain strings and options cannot fail.
        serde_json::to_string_pretty(&file).unwrap_or_default()
    }

    /// The hierarchy of the markers of `nodes` that are `present` (tracked, say), leaving out
    /// also every marker whose parent in `nodes` is not kept (its branch has no angle), in
    /// the order given, with what was left out and why.
    ///
    /// # Errors
    /// As [`Hierarchy::new`] on the kept markers (for instance [`AngleError::NoRoot`] when
    /// the root is not present).
    pub fn of_present(nodes: &[MarkerNode], present: &[String]) -> Result<Pruned> {
        let mut kept: Vec<&MarkerNode> = nodes.iter().filter(|m| present.contains(&m.id)).collect();
        let mut orphans = Vec::new();
        // Each pass removes one orphan; at most one pass per marker.
        for _ in 0..nodes.len() {
            let ids: Vec<&str> = kept.iter().map(|m| m.id.as_str()).collect();
            let orphan = kept.iter().position(|m| {
                m.parent
                    .as_deref()
                    .is_some_and(|p| !ids.contains(&p) && nodes.iter().any(|q| q.id == p))
            });
            let Some(i) = orphan else { break };
            let m = kept.remove(i);
            orphans.push((m.id.clone(), m.parent.clone().unwrap_or_default()));
        }
        Ok(Pruned {
            hierarchy: Self::new(kept.into_iter().cloned().collect())?,
            orphans,
        })
    }

    /// The markers, in the order given.
    pub fn markers(&self) -> &[MarkerNode] {
        &self.nodes
    }

    /// The root marker's id.
    pub fn root(&self) -> &str {
        &self.nodes[self.root].id
    }

    /// Index of `id` in [`Hierarchy::markers`].
    pub fn index_of(&self, id: &str) -> Option<usize> {
        self.nodes.iter().position(|n| n.id == id)
    }

    /// The parent of `id` (`None` for the root or an unknown id).
    pub fn parent_of(&self, id: &str) -> Option<&str> {
        let k = self.index_of(id)?;
        self.parents[k].map(|p| self.nodes[p].id.as_str())
    }

    /// The children of `id`, in the order given.
    pub fn children_of(&self, id: &str) -> Vec<&str> {
        let Some(k) = self.index_of(id) else {
            return Vec::new();
        };
        (0..self.nodes.len())
            .filter(|&c| self.parents[c] == Some(k))
            .map(|c| self.nodes[c].id.as_str())
            .collect()
    }

    /// The level of a branch in the paper's sense: 1 for the branch of a child of the root,
    /// 2 for the branch of a grandchild, and so on; 0 for the root (which has no branch).
    pub fn level_of(&self, id: &str) -> Option<usize> {
        let mut k = self.index_of(id)?;
        let mut level = 0;
        while let Some(p) = self.parents[k] {
            level += 1;
            k = p;
        }
        Some(level)
    }

    /// Every branch: each marker with a parent, in the order given.
    pub fn branches(&self) -> Vec<Branch<'_>> {
        (0..self.nodes.len())
            .filter_map(|c| {
                let p = self.parents[c]?;
                Some(Branch {
                    child: &self.nodes[c].id,
                    parent: &self.nodes[p].id,
                    grandparent: self.parents[p].map(|g| self.nodes[g].id.as_str()),
                })
            })
            .collect()
    }
}

/// The branch of a child marker: the segment from its parent marker to it. Its parent branch
/// runs from the grandparent to the parent (none for the children of the root).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Branch<'a> {
    /// The child marker (names the branch).
    pub child: &'a str,
    /// The parent marker.
    pub parent: &'a str,
    /// The parent's parent, start of the parent branch.
    pub grandparent: Option<&'a str>,
}

/// A hierarchy of the markers present, and the markers left out because their parent was
/// not (see [`Hierarchy::of_present`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Pruned {
    /// The kept markers' hierarchy.
    pub hierarchy: Hierarchy,
    /// `(marker, its missing parent)`, in the order they were left out.
    pub orphans: Vec<(String, String)>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(id: &str, parent: Option<&str>) -> MarkerNode {
        MarkerNode {
            id: id.into(),
            parent: parent.map(Into::into),
        }
    }

    #[test]
    fn a_valid_tree_gives_branches_levels_and_children() {
        let h = Hierarchy::from_json(
            r#"{"markers": [{"id": "A", "parent": null}, {"id": "C", "parent": "A"},
                {"id": "D", "parent": "C"}, {"id": "E", "parent": "C"}]}"#,
        )
        .expect("valid");
        assert_eq!(h.root(), "A");
        assert_eq!(h.children_of("C"), vec!["D", "E"]);
        assert_eq!(h.level_of("D"), Some(2));
        assert_eq!(h.level_of("A"), Some(0));
        let b = h.branches();
        assert_eq!(b.len(), 3);
        assert_eq!(
            b[1],
            Branch {
                child: "D",
                parent: "C",
                grandparent: Some("A")
            }
        );
        assert_eq!(b[0].grandparent, None);
        assert_eq!(Hierarchy::from_json(&h.to_json()).expect("round trip"), h);
    }

    #[test]
    fn every_kind_of_bad_tree_is_named() {
        assert!(matches!(
            Hierarchy::new(vec![]),
            Err(AngleError::EmptyHierarchy)
        ));
        assert!(matches!(
            Hierarchy::new(vec![node("A", None), node("A", Some("A"))]),
            Err(AngleError::DuplicateId { .. })
        ));
        assert!(matches!(
            Hierarchy::new(vec![node("A", None), node("B", Some("Z"))]),
            Err(AngleError::UnknownParent { .. })
        ));
        assert!(matches!(
            Hierarchy::new(vec![node("A", None), node("B", None)]),
            Err(AngleError::SeveralRoots { .. })
        ));
        match Hierarchy::new(vec![
            node("R", None),
            node("A", Some("C")),
            node("B", Some("A")),
            node("C", Some("B")),
        ]) {
            Err(AngleError::Cycle { ids }) => assert_eq!(ids.len(), 3),
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            Hierarchy::new(vec![node("A", Some("B")), node("B", Some("A"))]),
            Err(AngleError::Cycle { .. })
        ));
        assert!(matches!(
            Hierarchy::new(vec![node("R", None), node("A", Some("A"))]),
            Err(AngleError::Cycle { .. })
        ));
        assert!(matches!(
            Hierarchy::new(vec![node("a,b", None)]),
            Err(AngleError::InvalidId { .. })
        ));
        assert!(matches!(
            Hierarchy::from_json(r#"{"markers": [{"id": "A", "parnet": null}]}"#),
            Err(AngleError::Json { .. })
        ));
        assert!(matches!(
            Hierarchy::from_json("{"),
            Err(AngleError::Json { .. })
        ));
    }
}
