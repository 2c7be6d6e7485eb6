//! Exporters: glTF 2.0 binary (skinned tube mesh, a joint per segment, rotation channels on
//! one time track) here; BVH and CSV of per-branch angles and displacements in
//! [`crate::export_text`].
//!
//! The tree's frame is Z-up (the project's convention); glTF and BVH are Y-up, so both
//! exporters map (x, y, z) → (x, z, −y), a rotation of −90° about x, which keeps the
//! handedness. Lengths stay in metres.

use std::path::Path;

use gj::validation::{Checked::Valid, USize64};
use gltf_json as gj;
use nalgebra::{Point3, UnitQuaternion, Vector3};

use crate::error::{AnimError, Result};
use crate::sim::{Pose, Simulation};
use crate::tree::SEGMENTS;

/// Largest number of joints (segments) a glTF export can address: JOINTS_0 is written as
/// unsigned 16-bit integers.
pub const MAX_GLTF_JOINTS: usize = u16::MAX as usize + 1;

/// Options of the glTF export.
#[derive(Debug, Clone, PartialEq)]
pub struct GlbOptions {
    /// Vertices around each ring of the tube mesh (at least 3). Default 8.
    pub sides: usize,
    /// Bark colour, linear RGB in [0, 1]. Default a grey brown.
    pub bark_rgb: [f32; 3],
    /// Name of the animation clip. Default "wind".
    pub clip_name: String,
}

impl Default for GlbOptions {
    fn default() -> Self {
        Self {
            sides: 8,
            bark_rgb: [0.28, 0.2, 0.13],
            clip_name: "wind".into(),
        }
    }
}

/// Z-up → Y-up: (x, y, z) → (x, z, −y).
pub(crate) fn y_up(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.z, -v.y]
}

/// A rotation in the Y-up frame as (x, y, z, w).
pub(crate) fn y_up_quaternion(q: &UnitQuaternion<f64>) -> [f64; 4] {
    [q.i, q.k, -q.j, q.w]
}

/// Checks that `poses` belong to `sim` and are usable as a clip: at least one, the right
/// sizes, finite, times strictly increasing.
pub(crate) fn check_poses(sim: &Simulation, poses: &[Pose]) -> Result<()> {
    if poses.is_empty() {
        return Err(AnimError::param("poses", "no poses to export"));
    }
    let (segments, branches) = (sim.tree().segment_count(), sim.tree().branches().len());
    for (k, p) in poses.iter().enumerate() {
        if p.local.len() != segments
            || p.angle_rad.len() != branches
            || p.displacement_m.len() != branches
        {
            return Err(AnimError::param(
                "poses",
                format!(
                    "pose {k} is not a pose of this tree ({segments} segments, {branches} branches)"
                ),
            ));
        }
        let finite = p.time_s.is_finite()
            && p.local
                .iter()
                .all(|q| q.coords.iter().all(|c| c.is_finite()))
            && p.angle_rad.iter().all(|a| a.is_finite())
            && p.displacement_m.iter().flatten().all(|d| d.is_finite());
        if !finite {
            return Err(AnimError::param("poses", format!("pose {k} is not finite")));
        }
        if k > 0 && p.time_s <= poses[k - 1].time_s {
            return Err(AnimError::param(
                "poses",
                format!(
                    "pose {k} at {} s does not come after pose {} at {} s",
                    p.time_s,
                    k - 1,
                    poses[k - 1].time_s
                ),
            ));
        }
    }
    Ok(())
}

/// Rest start of every segment (tree frame), from the rest offsets.
fn rest_starts(sim: &Simulation) -> Vec<Point3<f64>> {
    let offsets = sim.rest_offsets();
    let parents = sim.parent_segments();
    let mut starts: Vec<Point3<f64>> = Vec::with_capacity(offsets.len());
    for (s, off) in offsets.iter().enumerate() {
        let base = parents[s].map_or_else(Point3::origin, |p| starts[p]);
        starts.push(base + off);
    }
    starts
}

/// The tube mesh: vertices, normals, (joint, weight) pairs, triangle indices.
struct Tube {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    joints: Vec<[u16; 4]>,
    weights: Vec<[f32; 4]>,
    indices: Vec<u32>,
}

fn tube(sim: &Simulation, sides: usize) -> Tube {
    let mut t = Tube {
        positions: Vec::new(),
        normals: Vec::new(),
        joints: Vec::new(),
        weights: Vec::new(),
        indices: Vec::new(),
    };
    let f32s = |v: [f64; 3]| v.map(|c| c as f32);
    for (bi, b) in sim.tree().branches().iter().enumerate() {
        let dirs: [Vector3<f64>; SEGMENTS] =
            std::array::from_fn(|j| (b.points[j + 1] - b.points[j]).normalize());
        // A frame carried along the beam (parallel transport: no twist between rings).
        let mut normal = b.u;
        let first_vertex = t.positions.len() as u32;
        for k in 0..=SEGMENTS {
            let tangent = match k {
                0 => dirs[0],
                SEGMENTS => dirs[SEGMENTS - 1],
                _ => (dirs[k - 1] + dirs[k])
                    .try_normalize(1e-12)
                    .unwrap_or(dirs[k]),
            };
            normal = (normal - tangent * tangent.dot(&normal))
                .try_normalize(1e-9)
                .unwrap_or_else(|| tangent.cross(&Vector3::x()).normalize());
            let binormal = tangent.cross(&normal);
            let radius = match k {
                0 => b.radii_m[0],
                SEGMENTS => 0.5 * b.radii_m[SEGMENTS - 1],
                _ => 0.5 * (b.radii_m[k - 1] + b.radii_m[k]),
            };
            let (joints, weights) = match k {
                0 => ([bi * SEGMENTS; 2], [1.0, 0.0]),
                SEGMENTS => ([bi * SEGMENTS + SEGMENTS - 1; 2], [1.0, 0.0]),
                _ => ([bi * SEGMENTS + k - 1, bi * SEGMENTS + k], [0.5, 0.5]),
            };
            for i in 0..sides {
                let theta = std::f64::consts::TAU * i as f64 / sides as f64;
                let radial = normal * theta.cos() + binormal * theta.sin();
                t.positions
                    .push(f32s(y_up(&(b.points[k].coords + radial * radius))));
                t.normals.push(f32s(y_up(&radial)));
                t.joints.push([joints[0] as u16, joints[1] as u16, 0, 0]);
                t.weights.push([weights[0], weights[1], 0.0, 0.0]);
            }
        }
        // The tip cap's centre.
        let tip = first_vertex + ((SEGMENTS + 1) * sides) as u32;
        t.positions.push(f32s(y_up(&b.points[SEGMENTS].coords)));
        t.normals.push(f32s(y_up(&dirs[SEGMENTS - 1])));
        t.joints
            .push([(bi * SEGMENTS + SEGMENTS - 1) as u16, 0, 0, 0]);
        t.weights.push([1.0, 0.0, 0.0, 0.0]);
        let n = sides as u32;
        for k in 0..SEGMENTS as u32 {
            for i in 0..n {
                let a = first_vertex + k * n + i;
                let b = first_vertex + k * n + (i + 1) % n;
                let (c, d) = (a + n, b + n);
                t.indices.extend_from_slice(&[a, b, c, b, d, c]);
            }
        }
        let ring = first_vertex + SEGMENTS as u32 * n;
        for i in 0..n {
            t.indices
                .extend_from_slice(&[ring + i, ring + (i + 1) % n, tip]);
        }
    }
    // The second joint slot is only used with a non-zero weight; zero-weight slots name
    // joint 0 (the glTF validator flags repeated joints within one vertex).
    for (j, w) in t.joints.iter_mut().zip(&t.weights) {
        for slot in 1..4 {
            if w[slot] == 0.0 {
                j[slot] = 0;
            }
        }
    }
    t
}

/// Pads `data` with `byte` to a multiple of 4 bytes (glTF's alignment of chunks and views).
fn pad4(data: &mut Vec<u8>, byte: u8) {
    while !data.len().is_multiple_of(4) {
        data.push(byte);
    }
}

/// The binary chunk being built, with bufferViews 4-byte aligned.
struct Bin {
    data: Vec<u8>,
    views: Vec<gj::buffer::View>,
}

impl Bin {
    fn view(
        &mut self,
        bytes: &[u8],
        target: Option<gj::buffer::Target>,
    ) -> gj::Index<gj::buffer::View> {
        pad4(&mut self.data, 0);
        let offset = self.data.len();
        self.data.extend_from_slice(bytes);
        self.views.push(gj::buffer::View {
            buffer: gj::Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: Default::default(),
        });
        gj::Index::new(self.views.len() as u32 - 1)
    }
}

fn le_f32(values: impl IntoIterator<Item = f32>) -> Vec<u8> {
    values.into_iter().flat_map(f32::to_le_bytes).collect()
}

fn accessor(
    view: gj::Index<gj::buffer::View>,
    offset: usize,
    count: usize,
    component: gj::accessor::ComponentType,
    type_: gj::accessor::Type,
    bounds: Option<(Vec<f32>, Vec<f32>)>,
) -> gj::Accessor {
    let (min, max) = match bounds {
        Some((lo, hi)) => (
            Some(gj::serialize::to_value(lo).ok()).flatten(),
            Some(gj::serialize::to_value(hi).ok()).flatten(),
        ),
        None => (None, None),
    };
    gj::Accessor {
        buffer_view: Some(view),
        byte_offset: (offset > 0).then(|| USize64::from(offset)),
        count: USize64::from(count),
        component_type: Valid(gj::accessor::GenericComponentType(component)),
        extensions: None,
        extras: Default::default(),
        type_: Valid(type_),
        min,
        max,
        name: None,
        normalized: false,
        sparse: None,
    }
}

/// Component-wise bounds of 3-vectors.
fn bounds3(values: &[[f32; 3]]) -> (Vec<f32>, Vec<f32>) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for v in values {
        for c in 0..3 {
            lo[c] = lo[c].min(v[c]);
            hi[c] = hi[c].max(v[c]);
        }
    }
    (lo.to_vec(), hi.to_vec())
}

/// The animation of `poses` on the tree of `sim` as a glTF 2.0 binary (`.glb`).
///
/// One skinned tube mesh (rings at P0..P4 of each branch, blended between neighbouring
/// segments), one node per segment (a joint; its translation is the rest offset from its
/// parent segment's start), one animation with a rotation channel per joint on a single
/// time track (linear interpolation, i.e. slerp). Y-up, metres.
///
/// # Errors
/// [`AnimError::TooManyJoints`], [`AnimError::InvalidParameter`] for poses that are not of
/// this tree, not finite or not in time order, or fewer than 3 sides.
pub fn glb_bytes(sim: &Simulation, poses: &[Pose], options: &GlbOptions) -> Result<Vec<u8>> {
    check_poses(sim, poses)?;
    if options.sides < 3 {
        return Err(AnimError::param(
            "sides",
            format!("{}; a tube needs at least 3", options.sides),
        ));
    }
    let n_joints = sim.tree().segment_count();
    if n_joints > MAX_GLTF_JOINTS {
        return Err(AnimError::TooManyJoints {
            joints: n_joints,
            max: MAX_GLTF_JOINTS,
        });
    }
    let mesh = tube(sim, options.sides);
    let mut root = gj::Root {
        asset: gj::Asset {
            generator: Some(format!("treemocap beam-anim {}", env!("CARGO_PKG_VERSION"))),
            ..Default::default()
        },
        ..Default::default()
    };
    let mut bin = Bin {
        data: Vec::new(),
        views: Vec::new(),
    };
    let mesh_index = push_mesh(&mut root, &mut bin, &mesh, options);
    let joint_nodes = push_skeleton(&mut root, &mut bin, sim, mesh_index);
    push_clip(&mut root, &mut bin, poses, &joint_nodes, &options.clip_name);
    container(root, bin)
}

/// The skinned tube: its vertex attributes, indices and bark material.
fn push_mesh(
    root: &mut gj::Root,
    bin: &mut Bin,
    mesh: &Tube,
    options: &GlbOptions,
) -> gj::Index<gj::Mesh> {
    use gj::accessor::{ComponentType as C, Type as T};
    use gj::buffer::Target;
    let v = bin.view(
        &le_f32(mesh.positions.iter().flatten().copied()),
        Some(Target::ArrayBuffer),
    );
    let positions = root.push(accessor(
        v,
        0,
        mesh.positions.len(),
        C::F32,
        T::Vec3,
        Some(bounds3(&mesh.positions)),
    ));
    let v = bin.view(
        &le_f32(mesh.normals.iter().flatten().copied()),
        Some(Target::ArrayBuffer),
    );
    let normals = root.push(accessor(v, 0, mesh.normals.len(), C::F32, T::Vec3, None));
    let joint_bytes: Vec<u8> = mesh
        .joints
        .iter()
        .flatten()
        .flat_map(|j| j.to_le_bytes())
        .collect();
    let v = bin.view(&joint_bytes, Some(Target::ArrayBuffer));
    let joints = root.push(accessor(v, 0, mesh.joints.len(), C::U16, T::Vec4, None));
    let v = bin.view(
        &le_f32(mesh.weights.iter().flatten().copied()),
        Some(Target::ArrayBuffer),
    );
    let weights = root.push(accessor(v, 0, mesh.weights.len(), C::F32, T::Vec4, None));
    let index_bytes: Vec<u8> = mesh.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
    let v = bin.view(&index_bytes, Some(Target::ElementArrayBuffer));
    let indices = root.push(accessor(v, 0, mesh.indices.len(), C::U32, T::Scalar, None));
    let [r, g, b] = options.bark_rgb;
    let material = root.push(gj::Material {
        name: Some("bark".into()),
        pbr_metallic_roughness: gj::material::PbrMetallicRoughness {
            base_color_factor: gj::material::PbrBaseColorFactor([r, g, b, 1.0]),
            metallic_factor: gj::material::StrengthFactor(0.0),
            roughness_factor: gj::material::StrengthFactor(0.9),
            ..Default::default()
        },
        ..Default::default()
    });
    let mut attributes = std::collections::BTreeMap::new();
    attributes.insert(Valid(gj::mesh::Semantic::Positions), positions);
    attributes.insert(Valid(gj::mesh::Semantic::Normals), normals);
    attributes.insert(Valid(gj::mesh::Semantic::Joints(0)), joints);
    attributes.insert(Valid(gj::mesh::Semantic::Weights(0)), weights);
    root.push(gj::Mesh {
        extensions: None,
        extras: Default::default(),
        name: Some("tree".into()),
        primitives: vec![gj::mesh::Primitive {
            attributes,
            extensions: None,
            extras: Default::default(),
            indices: Some(indices),
            material: Some(material),
            mode: Valid(gj::mesh::Mode::Triangles),
            targets: None,
        }],
        weights: None,
    })
}

/// One joint node per segment (node 1 + s; node 0 carries the mesh), the skin with its
/// inverse bind matrices, and the scene; the joint nodes.
fn push_skeleton(
    root: &mut gj::Root,
    bin: &mut Bin,
    sim: &Simulation,
    mesh_index: gj::Index<gj::Mesh>,
) -> Vec<gj::Index<gj::Node>> {
    use gj::accessor::{ComponentType as C, Type as T};
    let n_joints = sim.tree().segment_count();
    let offsets = sim.rest_offsets();
    let parents = sim.parent_segments();
    let mut children: Vec<Vec<gj::Index<gj::Node>>> = vec![Vec::new(); n_joints];
    for (s, p) in parents.iter().enumerate() {
        if let Some(p) = p {
            children[*p].push(gj::Index::new(1 + s as u32));
        }
    }
    let mesh_node = root.push(gj::Node {
        mesh: Some(mesh_index),
        name: Some("tree".into()),
        ..Default::default()
    });
    let branches = sim.tree().branches();
    for (s, kids) in children.into_iter().enumerate() {
        let off = y_up(&offsets[s]).map(|c| c as f32);
        root.push(gj::Node {
            name: Some(format!(
                "branch{}_seg{}",
                branches[s / SEGMENTS].id,
                s % SEGMENTS
            )),
            translation: Some(off),
            children: (!kids.is_empty()).then_some(kids),
            ..Default::default()
        });
    }
    let joint_nodes: Vec<gj::Index<gj::Node>> = (0..n_joints)
        .map(|s| gj::Index::new(1 + s as u32))
        .collect();
    let ibm: Vec<f32> = rest_starts(sim)
        .iter()
        .flat_map(|p| {
            let [x, y, z] = y_up(&p.coords).map(|c| c as f32);
            [
                1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -x, -y, -z, 1.0,
            ]
        })
        .collect();
    let v = bin.view(&le_f32(ibm), None);
    let ibm = root.push(accessor(v, 0, n_joints, C::F32, T::Mat4, None));
    let root_joints: Vec<gj::Index<gj::Node>> = (0..n_joints)
        .filter(|&s| parents[s].is_none())
        .map(|s| joint_nodes[s])
        .collect();
    let skin = root.push(gj::Skin {
        extensions: None,
        extras: Default::default(),
        inverse_bind_matrices: Some(ibm),
        joints: joint_nodes.clone(),
        name: Some("segments".into()),
        skeleton: root_joints.first().copied(),
    });
    root.nodes[mesh_node.value()].skin = Some(skin);
    let mut scene_nodes = vec![mesh_node];
    scene_nodes.extend(root_joints);
    let scene = root.push(gj::Scene {
        extensions: None,
        extras: Default::default(),
        name: Some("tree".into()),
        nodes: scene_nodes,
    });
    root.scene = Some(scene);
    joint_nodes
}

/// The clip: one time track, one rotation track per joint.
fn push_clip(
    root: &mut gj::Root,
    bin: &mut Bin,
    poses: &[Pose],
    joint_nodes: &[gj::Index<gj::Node>],
    clip_name: &str,
) {
    use gj::accessor::{ComponentType as C, Type as T};
    let n_joints = joint_nodes.len();
    let t0 = poses[0].time_s;
    let times: Vec<f32> = poses.iter().map(|p| (p.time_s - t0) as f32).collect();
    let (t_lo, t_hi) = (times[0], times[times.len() - 1]);
    let v = bin.view(&le_f32(times.iter().copied()), None);
    let time = root.push(accessor(
        v,
        0,
        poses.len(),
        C::F32,
        T::Scalar,
        Some((vec![t_lo], vec![t_hi])),
    ));
    let rotations = le_f32((0..n_joints).flat_map(|s| {
        poses
            .iter()
            .flat_map(move |p| y_up_quaternion(&p.local[s]).map(|c| c as f32))
    }));
    let v = bin.view(&rotations, None);
    let mut samplers = Vec::with_capacity(n_joints);
    let mut channels = Vec::with_capacity(n_joints);
    for (s, node) in joint_nodes.iter().enumerate() {
        let output = root.push(accessor(
            v,
            s * poses.len() * 16,
            poses.len(),
            C::F32,
            T::Vec4,
            None,
        ));
        samplers.push(gj::animation::Sampler {
            extensions: None,
            extras: Default::default(),
            input: time,
            interpolation: Valid(gj::animation::Interpolation::Linear),
            output,
        });
        channels.push(gj::animation::Channel {
            sampler: gj::Index::new(s as u32),
            target: gj::animation::Target {
                extensions: None,
                extras: Default::default(),
                node: *node,
                path: Valid(gj::animation::Property::Rotation),
            },
            extensions: None,
            extras: Default::default(),
        });
    }
    root.push(gj::Animation {
        extensions: None,
        extras: Default::default(),
        channels,
        name: Some(clip_name.to_string()),
        samplers,
    });
}

/// The `.glb` container: header, JSON chunk, binary chunk.
fn container(mut root: gj::Root, mut bin: Bin) -> Result<Vec<u8>> {
    pad4(&mut bin.data, 0);
    root.buffer_views = bin.views;
    root.push(gj::Buffer {
        byte_length: USize64::from(bin.data.len()),
        name: None,
        uri: None,
        extensions: None,
        extras: Default::default(),
    });
    let mut json = root
        .to_vec()
        .map_err(|e| AnimError::param("glTF", format!("JSON serialisation failed: {e}")))?;
    pad4(&mut json, b' ');
    let total = 12 + 8 + json.len() + 8 + bin.data.len();
    let total = u32::try_from(total).map_err(|_| {
        AnimError::param(
            "poses",
            format!("{total} bytes exceed the 4 GiB a .glb can hold"),
        )
    })?;
    let mut out = Vec::with_capacity(total as usize);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.data.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin.data);
    Ok(out)
}

/// [`glb_bytes`] written to `path`.
///
/// # Errors
/// As [`glb_bytes`], and [`AnimError::Io`].
pub fn write_glb(
    path: &Path,
    sim: &Simulation,
    poses: &[Pose],
    options: &GlbOptions,
) -> Result<()> {
    let bytes = glb_bytes(sim, poses, options)?;
    std::fs::write(path, bytes).map_err(|e| AnimError::io(path, e))
}

// The text exporters moved to `export_text`; their old paths stay valid.
pub use crate::export_text::{
    angles_csv, bvh_string, displacement_csv, write_bvh, write_text, zxy_euler_deg,
};
