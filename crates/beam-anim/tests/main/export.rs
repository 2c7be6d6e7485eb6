//! Exporters: the .glb re-read and skinned by hand must reproduce the simulation's own
//! deformed tree; BVH angles must give back the local rotations; CSV keeps the contract.

use beam_anim::export::zxy_euler_deg;
use beam_anim::{
    AnimConfig, AnimError, BeamTree, GlbOptions, PAPER_DYNAMICS, Pose, SEGMENTS, Simulation,
    angles_csv, bvh_string, displacement_csv, glb_bytes, procedural_tree,
};
use gltf_json as gj;
use nalgebra::{Matrix4, Point3, Quaternion, UnitQuaternion, Vector3, Vector4};
use proptest::prelude::*;

/// A windy run: the simulation and its poses (the rest pose first).
fn run(frames: usize) -> (Simulation, Vec<Pose>) {
    let sk = procedural_tree(13, 5).unwrap();
    let mut config = AnimConfig::default();
    config.wind.mean_speed_m_s = 15.0;
    let tree = BeamTree::new(&sk, &config).unwrap();
    let d = vec![PAPER_DYNAMICS; tree.branches().len()];
    let mut sim = Simulation::new(tree, &d, config, 1.0 / 30.0).unwrap();
    let mut wind = sim.wind_field().unwrap();
    let mut poses = vec![sim.pose().clone()];
    for _ in 0..frames {
        sim.step(&mut wind).unwrap();
        poses.push(sim.pose().clone());
    }
    (sim, poses)
}

fn y_up(v: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(v.x, v.z, -v.y)
}

fn y_up_q(q: &UnitQuaternion<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::new_normalize(Quaternion::new(q.w, q.i, q.k, -q.j))
}

struct Glb {
    root: gj::Root,
    bin: Vec<u8>,
}

fn split_glb(bytes: &[u8]) -> Glb {
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()) as usize;
    assert_eq!(&bytes[0..4], b"glTF");
    assert_eq!(u32_at(4), 2);
    assert_eq!(u32_at(8), bytes.len());
    let json_len = u32_at(12);
    assert_eq!(&bytes[16..20], b"JSON");
    assert_eq!(json_len % 4, 0);
    let root: gj::Root = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let b = 20 + json_len;
    let bin_len = u32_at(b);
    assert_eq!(&bytes[b + 4..b + 8], b"BIN\0");
    assert_eq!(bin_len % 4, 0);
    assert_eq!(b + 8 + bin_len, bytes.len());
    Glb {
        root,
        bin: bytes[b + 8..].to_vec(),
    }
}

impl Glb {
    /// The raw bytes of an accessor (tightly packed, as we write them).
    fn bytes(&self, a: gj::Index<gj::Accessor>, elem: usize) -> &[u8] {
        let acc = &self.root.accessors[a.value()];
        let view = &self.root.buffer_views[acc.buffer_view.unwrap().value()];
        let start = view.byte_offset.map_or(0, |o| o.0 as usize)
            + acc.byte_offset.map_or(0, |o| o.0 as usize);
        assert_eq!(start % 4, 0, "accessor data must be 4-byte aligned");
        &self.bin[start..start + acc.count.0 as usize * elem]
    }

    fn f32s(&self, a: gj::Index<gj::Accessor>, n: usize) -> Vec<Vec<f64>> {
        self.bytes(a, 4 * n)
            .chunks_exact(4 * n)
            .map(|c| {
                c.chunks_exact(4)
                    .map(|x| f32::from_le_bytes(x.try_into().unwrap()) as f64)
                    .collect()
            })
            .collect()
    }

    fn u16s(&self, a: gj::Index<gj::Accessor>) -> Vec<[usize; 4]> {
        self.bytes(a, 8)
            .chunks_exact(8)
            .map(|c| std::array::from_fn(|k| u16::from_le_bytes([c[2 * k], c[2 * k + 1]]) as usize))
            .collect()
    }
}

#[test]
fn glb_skinned_by_hand_matches_the_simulated_tree() {
    let (sim, poses) = run(40);
    let bytes = glb_bytes(&sim, &poses, &GlbOptions::default()).unwrap();
    let glb = split_glb(&bytes);
    let root = &glb.root;
    let n = sim.tree().segment_count();
    assert_eq!(root.nodes.len(), 1 + n);
    let skin = &root.skins[0];
    assert_eq!(skin.joints.len(), n);
    let anim = &root.animations[0];
    assert_eq!(anim.channels.len(), n);
    // One time track shared by all samplers, with its bounds.
    let input = anim.samplers[0].input;
    assert!(anim.samplers.iter().all(|s| s.input == input));
    let times = glb.f32s(input, 1);
    assert_eq!(times.len(), poses.len());
    let acc = &root.accessors[input.value()];
    assert_eq!(
        acc.max.as_ref().unwrap()[0].as_f64().unwrap() as f32,
        times[times.len() - 1][0] as f32
    );
    // The pose at frame k from the file: node TRS with the animated rotations.
    let k = 40;
    let mut local = vec![UnitQuaternion::identity(); n];
    for ch in &anim.channels {
        let joint = ch.target.node.value() - 1;
        let out = glb.f32s(anim.samplers[ch.sampler.value()].output, 4);
        let [x, y, z, w] = [out[k][0], out[k][1], out[k][2], out[k][3]];
        local[joint] = UnitQuaternion::new_normalize(Quaternion::new(w, x, y, z));
    }
    let mut parent = vec![None; n];
    for (i, node) in root.nodes.iter().enumerate().skip(1) {
        for c in node.children.iter().flatten() {
            parent[c.value() - 1] = Some(i - 1);
        }
    }
    assert_eq!(parent, sim.parent_segments().to_vec());
    let mut world: Vec<Matrix4<f64>> = Vec::with_capacity(n);
    for s in 0..n {
        let t = root.nodes[1 + s].translation.unwrap();
        let m = Matrix4::new_translation(&Vector3::new(t[0] as f64, t[1] as f64, t[2] as f64))
            * local[s].to_homogeneous();
        world.push(parent[s].map_or(m, |p| world[p] * m));
    }
    let ibm = glb.f32s(skin.inverse_bind_matrices.unwrap(), 16);
    let prim = &root.meshes[0].primitives[0];
    let attr = |sem: gj::mesh::Semantic| prim.attributes[&gj::validation::Checked::Valid(sem)];
    let pos = glb.f32s(attr(gj::mesh::Semantic::Positions), 3);
    let joints = glb.u16s(attr(gj::mesh::Semantic::Joints(0)));
    let weights = glb.f32s(attr(gj::mesh::Semantic::Weights(0)), 4);
    // The simulation's own deformation of each vertex bound to a single joint.
    let frames = frames_at(&sim, &poses[k]);
    let rest = rest_starts(&sim);
    let mut checked = 0;
    for (v, ((p, j), w)) in pos.iter().zip(&joints).zip(&weights).enumerate() {
        let sum: f64 = w.iter().sum();
        assert!((sum - 1.0).abs() < 1e-6, "vertex {v}: weights sum to {sum}");
        let rest_v = Vector4::new(p[0], p[1], p[2], 1.0);
        let mut skinned = Vector4::zeros();
        for slot in 0..4 {
            if w[slot] > 0.0 {
                let b = Matrix4::from_column_slice(&ibm[j[slot]]);
                skinned += (world[j[slot]] * b * rest_v) * w[slot];
            }
        }
        if w[0] == 1.0 {
            // Rigidly attached: start + g (v − rest start), in Y-up.
            let s = j[0];
            let (g, start) = frames[s];
            let rest_z_up = Vector3::new(p[0], -p[2], p[1]);
            let expected = y_up(&(start.coords + g * (rest_z_up - rest[s].coords)));
            let got = skinned.xyz();
            assert!(
                (got - expected).norm() < 2e-5,
                "vertex {v} on joint {s}: {got:?} vs {expected:?}"
            );
            checked += 1;
        }
    }
    assert!(checked > pos.len() / 3);
}

/// Each segment's (global rotation, start) for a recorded pose: the locals composed.
fn frames_at(sim: &Simulation, pose: &Pose) -> Vec<(UnitQuaternion<f64>, Point3<f64>)> {
    let tree = sim.tree();
    let parents = sim.parent_segments();
    let offsets = sim.rest_offsets();
    let mut out: Vec<(UnitQuaternion<f64>, Point3<f64>)> = Vec::new();
    for s in 0..tree.segment_count() {
        let (pg, ps) =
            parents[s].map_or((UnitQuaternion::identity(), Point3::origin()), |p| out[p]);
        out.push((pg * pose.local[s], ps + pg * offsets[s]));
    }
    out
}

fn rest_starts(sim: &Simulation) -> Vec<Point3<f64>> {
    (0..sim.tree().segment_count())
        .map(|s| sim.tree().segment_start(s))
        .collect()
}

#[test]
fn frames_from_locals_match_the_simulation() {
    let (sim, poses) = run(20);
    let ours = frames_at(&sim, poses.last().unwrap());
    for (s, ((g, p), (g2, p2))) in ours.iter().zip(sim.segment_frames()).enumerate() {
        assert!(g.angle_to(&g2) < 1e-12, "segment {s}");
        assert!((p - p2).norm() < 1e-12, "segment {s}");
    }
}

#[test]
fn bvh_angles_give_back_the_local_rotations() {
    let (sim, poses) = run(30);
    let text = bvh_string(&sim, &poses).unwrap();
    let n = sim.tree().segment_count();
    // Joint names in channel order.
    let names: Vec<&str> = text
        .lines()
        .filter_map(|l| {
            let l = l.trim();
            l.strip_prefix("ROOT ").or_else(|| l.strip_prefix("JOINT "))
        })
        .collect();
    assert_eq!(names.len(), n);
    assert_eq!(text.matches("{").count(), text.matches("}").count());
    let motion: Vec<&str> = text.split("MOTION\n").nth(1).unwrap().lines().collect();
    assert_eq!(motion[0], format!("Frames: {}", poses.len()));
    let row: Vec<f64> = motion[2 + 30]
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    assert_eq!(row.len(), 3 + 3 * n);
    let branches = sim.tree().branches();
    let mut worst = 0.0f64;
    for (k, name) in names.iter().enumerate() {
        let (b, j) = name
            .trim_start_matches("branch")
            .split_once("_seg")
            .unwrap();
        let (b, j): (usize, usize) = (b.parse().unwrap(), j.parse().unwrap());
        let s = sim.tree().index_of(b).unwrap() * SEGMENTS + j;
        assert_eq!(branches[s / SEGMENTS].id, b);
        let [z, x, y] = [row[3 + 3 * k], row[4 + 3 * k], row[5 + 3 * k]].map(f64::to_radians);
        let r = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), z)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), x)
            * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), y);
        worst = worst.max(r.angle_to(&y_up_q(&poses[30].local[s])));
    }
    // Six decimals of a degree.
    assert!(worst < 1e-7, "worst {worst} rad");
}

#[test]
fn angles_csv_has_the_contracted_header_and_degrees() {
    let (sim, poses) = run(5);
    let text = angles_csv(&sim, &poses).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut expected = vec!["t".to_string()];
    expected.extend(sim.tree().branches().iter().map(|b| b.id.to_string()));
    assert_eq!(header, expected);
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), poses.len());
    for (row, p) in rows.iter().zip(&poses) {
        assert_eq!(row[0], p.time_s);
        for (v, a) in row[1..].iter().zip(&p.angle_rad) {
            assert_eq!(*v, a.to_degrees());
        }
    }
    let disp = displacement_csv(&sim, &poses).unwrap();
    let head = disp.lines().next().unwrap();
    assert!(head.starts_with(&format!("t,{0}_u,{0}_w", sim.tree().branches()[0].id)));
    assert_eq!(disp.lines().count(), poses.len() + 1);
}

#[test]
fn exporters_refuse_poses_that_do_not_fit() {
    let (sim, mut poses) = run(3);
    assert!(matches!(
        glb_bytes(&sim, &[], &GlbOptions::default()),
        Err(AnimError::InvalidParameter { .. })
    ));
    let mut short = poses.clone();
    short[1].local.pop();
    assert!(matches!(
        bvh_string(&sim, &short),
        Err(AnimError::InvalidParameter { .. })
    ));
    let mut back = poses.clone();
    back[2].time_s = back[1].time_s;
    assert!(matches!(
        angles_csv(&sim, &back),
        Err(AnimError::InvalidParameter { .. })
    ));
    poses[1].angle_rad[0] = f64::NAN;
    assert!(matches!(
        glb_bytes(&sim, &poses, &GlbOptions::default()),
        Err(AnimError::InvalidParameter { .. })
    ));
    let bad_sides = GlbOptions {
        sides: 2,
        ..GlbOptions::default()
    };
    poses[1].angle_rad[0] = 0.0;
    assert!(matches!(
        glb_bytes(&sim, &poses, &bad_sides),
        Err(AnimError::InvalidParameter { .. })
    ));
}

proptest! {
    #[test]
    fn zxy_euler_round_trips(ax in -1.0f64..1.0, ay in -1.0f64..1.0, az in -1.0f64..1.0, angle in 0.0f64..3.0) {
        let axis = Vector3::new(ax, ay, az);
        prop_assume!(axis.norm() > 1e-3);
        let q = UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle);
        let [z, x, y] = zxy_euler_deg(&q).map(f64::to_radians);
        prop_assume!(x.abs() < 1.5);
        let r = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), z)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), x)
            * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), y);
        prop_assert!(r.angle_to(&q) < 1e-9);
    }
}
