//! Geometry for other tools: a TreeQSM-style cylinder table and a generalized-cylinder mesh.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;

use nalgebra::{Point3, Rotation3, Vector3};

use crate::error::{ColonizeError, Result};
use crate::skeleton::Skeleton;

/// Sides of each ring of the mesh by default.
pub const DEFAULT_MESH_SIDES: usize = 12;

/// One cylinder per skeleton segment, as TreeQSM tabulates them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cylinder {
    /// Index in the table.
    pub id: usize,
    /// The cylinder it continues from (`None` at the root).
    pub parent: Option<usize>,
    /// Start of the axis, metres.
    pub start: Point3<f64>,
    /// Unit axis direction.
    pub axis: Vector3<f64>,
    /// Length, metres.
    pub length_m: f64,
    /// Radius, metres.
    pub radius_m: f64,
    /// The branch it belongs to (id of the branch's first node).
    pub branch: usize,
    /// The branch's order (0 trunk).
    pub order: usize,
}

/// Two unit vectors across unit direction `t` (the first horizontal where `t` is not
/// vertical), right-handed with it: the plane of a branch's cross-section.
pub(crate) fn across(t: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let u = t
        .cross(&Vector3::z())
        .try_normalize(1e-9)
        .unwrap_or_else(|| t.cross(&Vector3::x()).normalize());
    (u, t.cross(&u))
}

/// The cylinders of a skeleton: one per node with a parent. As in TreeQSM's tables, a
/// branch starts on its parent's surface: the part of its first segments inside the parent
/// ([`Skeleton::inside_parent_m`]) is left out, and segments wholly inside or of zero
/// length are skipped. Their lengths sum to the tree's wood length, their volumes to its
/// wood volume.
pub fn cylinders(skeleton: &Skeleton) -> Vec<Cylinder> {
    let nodes = skeleton.nodes();
    let inside = skeleton.inside_parent_m();
    let mut branch_of = vec![(0usize, 0usize); nodes.len()];
    for b in skeleton.branches() {
        for &v in &b.nodes {
            branch_of[v] = (b.id, b.order);
        }
    }
    let mut cyl_of = vec![None; nodes.len()];
    let mut out = Vec::new();
    for &v in skeleton.topological_order() {
        let Some(p) = nodes[v].parent else { continue };
        let d = nodes[v].position - nodes[p].position;
        let full_m = d.norm();
        let length_m = full_m - inside[v];
        if full_m <= 0.0 || length_m <= 1e-12 {
            cyl_of[v] = cyl_of[p];
            continue;
        }
        let axis = d / full_m;
        let id = out.len();
        out.push(Cylinder {
            id,
            parent: cyl_of[p],
            start: nodes[p].position + axis * inside[v],
            axis,
            length_m,
            radius_m: nodes[v].radius_m,
            branch: branch_of[v].0,
            order: branch_of[v].1,
        });
        cyl_of[v] = Some(id);
    }
    out
}

/// The cylinder table as CSV: `id,parent,start_x,start_y,start_z,axis_x,axis_y,axis_z,
/// length,radius,branch,order`; metres, an empty `parent` for the first cylinder.
pub fn cylinders_to_csv(cylinders: &[Cylinder]) -> String {
    let mut s = String::from(
        "id,parent,start_x,start_y,start_z,axis_x,axis_y,axis_z,length,radius,branch,order\n",
    );
    for c in cylinders {
        let parent = c.parent.map(|p| p.to_string()).unwrap_or_default();
        let _ = writeln!(
            s,
            "{},{parent},{},{},{},{},{},{},{},{},{},{}",
            c.id,
            c.start.x,
            c.start.y,
            c.start.z,
            c.axis.x,
            c.axis.y,
            c.axis.z,
            c.length_m,
            c.radius_m,
            c.branch,
            c.order
        );
    }
    s
}

/// A triangle mesh.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriangleMesh {
    /// Vertex positions, metres.
    pub vertices: Vec<Point3<f64>>,
    /// Counter-clockwise triangles seen from outside, indices into `vertices`.
    pub triangles: Vec<[u32; 3]>,
}

/// Most sides of a mesh ring (checked before allocating: a ring of a million sides on every
/// node of a skeleton would not fit in memory, and 1024 is smooth at any size on screen).
pub const MAX_MESH_SIDES: usize = 1024;

/// The tree as generalized cylinders: one tube per branch, a ring of `sides` vertices at
/// each node (frames carried along by parallel transport, so tubes do not twist), closed by
/// a cap at each end. A branch's tube starts at the centre of the fork it grows from, inside
/// its parent's tube, so joints show no gap; every tube is a closed, consistently oriented
/// surface (each edge shared by exactly two triangles).
///
/// # Errors
/// [`ColonizeError::InvalidParameter`] for fewer than 3 or more than [`MAX_MESH_SIDES`] sides.
pub fn tube_mesh(skeleton: &Skeleton, sides: usize) -> Result<TriangleMesh> {
    if !(3..=MAX_MESH_SIDES).contains(&sides) {
        return Err(ColonizeError::param(
            "sides",
            format!("{sides}; a ring needs 3 to {MAX_MESH_SIDES}"),
        ));
    }
    let nodes = skeleton.nodes();
    let mut mesh = TriangleMesh::default();
    for b in skeleton.branches() {
        // Centres and radii of the rings: the fork (with the first segment's radius), then
        // the branch's nodes; repeated positions are dropped.
        let mut rings: Vec<(Point3<f64>, f64)> = Vec::new();
        let first_r = nodes[b.nodes[0]].radius_m;
        if let Some(base) = b.base_node {
            rings.push((nodes[base].position, first_r));
        }
        for &v in &b.nodes {
            let p = nodes[v].position;
            let r = if rings.is_empty() && b.nodes.len() > 1 {
                nodes[b.nodes[1]].radius_m
            } else {
                nodes[v].radius_m
            };
            if rings.last().is_none_or(|(q, _)| (p - q).norm() > 0.0) {
                rings.push((p, r));
            }
        }
        if rings.len() < 2 {
            continue;
        }
        add_tube(&mut mesh, &rings, sides);
    }
    Ok(mesh)
}

fn add_tube(mesh: &mut TriangleMesh, rings: &[(Point3<f64>, f64)], sides: usize) {
    let n = rings.len();
    let dir = |a: usize, b: usize| (rings[b].0 - rings[a].0).normalize();
    let tangents: Vec<Vector3<f64>> = (0..n)
        .map(|k| {
            let t = if k == 0 {
                dir(0, 1)
            } else if k == n - 1 {
                dir(n - 2, n - 1)
            } else {
                dir(k - 1, k) + dir(k, k + 1)
            };
            t.try_normalize(1e-12)
                .unwrap_or_else(|| dir(k.min(n - 2), k.min(n - 2) + 1))
        })
        .collect();
    let t0 = tangents[0];
    let helper = if t0.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let mut normal = t0.cross(&helper).normalize();
    let base = mesh.vertices.len() as u32;
    for k in 0..n {
        if k > 0 {
            // Parallel transport: rotate the normal by the rotation taking the previous
            // tangent to this one.
            if let Some(rot) = Rotation3::rotation_between(&tangents[k - 1], &tangents[k]) {
                normal = rot * normal;
            }
            normal = (normal - tangents[k] * normal.dot(&tangents[k]))
                .try_normalize(1e-12)
                .unwrap_or_else(|| tangents[k].cross(&helper).normalize());
        }
        let binormal = tangents[k].cross(&normal);
        let (c, r) = rings[k];
        for s in 0..sides {
            let a = std::f64::consts::TAU * s as f64 / sides as f64;
            mesh.vertices
                .push(c + (normal * a.cos() + binormal * a.sin()) * r);
        }
    }
    let ring = |k: usize, s: usize| base + (k * sides + s % sides) as u32;
    for k in 0..n - 1 {
        for s in 0..sides {
            let (a, b, c, d) = (
                ring(k, s),
                ring(k, s + 1),
                ring(k + 1, s),
                ring(k + 1, s + 1),
            );
            mesh.triangles.push([a, b, d]);
            mesh.triangles.push([a, d, c]);
        }
    }
    // Caps: a centre vertex at each end.
    let start = mesh.vertices.len() as u32;
    mesh.vertices.push(rings[0].0);
    let end = start + 1;
    mesh.vertices.push(rings[n - 1].0);
    for s in 0..sides {
        mesh.triangles.push([start, ring(0, s + 1), ring(0, s)]);
        mesh.triangles
            .push([end, ring(n - 1, s), ring(n - 1, s + 1)]);
    }
}

impl TriangleMesh {
    /// Wavefront OBJ text (`v x y z`, `f a b c` with 1-based indices), metres.
    pub fn to_obj(&self) -> String {
        let mut s = String::with_capacity(self.vertices.len() * 40 + self.triangles.len() * 24);
        s.push_str("# treemocap space-colonize tree mesh, metres, Z up\n");
        for v in &self.vertices {
            let _ = writeln!(s, "v {} {} {}", v.x, v.y, v.z);
        }
        for t in &self.triangles {
            let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        s
    }

    /// Binary little-endian PLY bytes (float64 vertices, uint32 triangle lists), metres.
    pub fn to_ply(&self) -> Vec<u8> {
        let mut out =
            Vec::with_capacity(200 + self.vertices.len() * 24 + self.triangles.len() * 13);
        let header = format!(
            "ply\nformat binary_little_endian 1.0\ncomment treemocap space-colonize tree mesh, metres, Z up\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nelement face {}\nproperty list uchar uint vertex_indices\nend_header\n",
            self.vertices.len(),
            self.triangles.len()
        );
        out.extend_from_slice(header.as_bytes());
        for v in &self.vertices {
            for c in [v.x, v.y, v.z] {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        for t in &self.triangles {
            out.push(3);
            for i in t {
                out.extend_from_slice(&i.to_le_bytes());
            }
        }
        out
    }

    /// Write OBJ or PLY, chosen by the extension (`.obj`, `.ply`).
    ///
    /// # Errors
    /// [`ColonizeError::InvalidParameter`] for another extension; [`ColonizeError::Io`].
    pub fn write(&self, path: &Path) -> Result<()> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let bytes = match ext.as_deref() {
            Some("obj") => self.to_obj().into_bytes(),
            Some("ply") => self.to_ply(),
            _ => {
                return Err(ColonizeError::param(
                    "mesh path",
                    format!("{}: the extension must be .obj or .ply", path.display()),
                ));
            }
        };
        let mut f = std::fs::File::create(path).map_err(|e| ColonizeError::io(path, e))?;
        f.write_all(&bytes).map_err(|e| ColonizeError::io(path, e))
    }

    /// Enclosed volume by the divergence theorem, cubic metres (for closed meshes; tubes
    /// that overlap at joints are counted each in full).
    pub fn volume_m3(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize].coords);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }
}
