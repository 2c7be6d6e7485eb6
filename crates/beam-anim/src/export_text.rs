//! Text exporters: BVH (Biovision hierarchy) and CSV of per-branch angles and
//! displacements. Y-up like the glTF export (see [`crate::export`]); lengths in metres.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Rotation3, UnitQuaternion};

use crate::error::{AnimError, Result};
use crate::export::{check_poses, y_up, y_up_quaternion};
use crate::sim::{Pose, Simulation};
use crate::tree::SEGMENTS;

/// ZXY Euler angles (degrees) of a rotation, for BVH's `Zrotation Xrotation Yrotation`:
/// R = Rz(z) Rx(x) Ry(y).
pub fn zxy_euler_deg(q: &UnitQuaternion<f64>) -> [f64; 3] {
    let r = Rotation3::from(*q);
    let m = r.matrix();
    let x = m[(2, 1)].clamp(-1.0, 1.0).asin();
    let (y, z) = if m[(2, 1)].abs() < 1.0 - 1e-12 {
        ((-m[(2, 0)]).atan2(m[(2, 2)]), (-m[(0, 1)]).atan2(m[(1, 1)]))
    } else {
        // Gimbal lock (x = ±90°): only z ± y is defined; put it all in z.
        (0.0, m[(1, 0)].atan2(m[(0, 0)]))
    };
    [z.to_degrees(), x.to_degrees(), y.to_degrees()]
}

/// The animation as BVH (Biovision hierarchy): a joint per segment, Y-up, metres, rotation
/// channels `Zrotation Xrotation Yrotation` (the root also has positions); childless joints
/// end in an `End Site` at the segment's end. Frames at the poses' mean interval.
///
/// # Errors
/// [`AnimError::InvalidParameter`] for poses that are not of this tree, not finite or not in
/// time order.
pub fn bvh_string(sim: &Simulation, poses: &[Pose]) -> Result<String> {
    check_poses(sim, poses)?;
    let n = sim.tree().segment_count();
    let offsets = sim.rest_offsets();
    let parents = sim.parent_segments();
    let branches = sim.tree().branches();
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); n];
    let mut roots = Vec::new();
    for (s, p) in parents.iter().enumerate() {
        match p {
            Some(p) => children[*p].push(s),
            None => roots.push(s),
        }
    }
    let mut out = String::from("HIERARCHY\n");
    // Channel order = depth-first order of the hierarchy as written.
    let mut order = Vec::with_capacity(n);
    let name = |s: usize| format!("branch{}_seg{}", branches[s / SEGMENTS].id, s % SEGMENTS);
    let mut stack: Vec<(usize, usize, bool)> = roots.iter().rev().map(|&s| (s, 0, false)).collect();
    // (segment, depth, closing)
    while let Some((s, depth, closing)) = stack.pop() {
        let pad = "  ".repeat(depth);
        if closing {
            let _ = writeln!(out, "{pad}}}");
            continue;
        }
        let [x, y, z] = y_up(&offsets[s]);
        if parents[s].is_none() {
            let _ = writeln!(out, "{pad}ROOT {}\n{pad}{{", name(s));
            let _ = writeln!(out, "{pad}  OFFSET {x:.6} {y:.6} {z:.6}");
            let _ = writeln!(
                out,
                "{pad}  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"
            );
        } else {
            let _ = writeln!(out, "{pad}JOINT {}\n{pad}{{", name(s));
            let _ = writeln!(out, "{pad}  OFFSET {x:.6} {y:.6} {z:.6}");
            let _ = writeln!(out, "{pad}  CHANNELS 3 Zrotation Xrotation Yrotation");
        }
        order.push(s);
        stack.push((s, depth, true));
        if children[s].is_empty() {
            let b = &branches[s / SEGMENTS];
            let j = s % SEGMENTS;
            let [x, y, z] = y_up(&(b.points[j + 1] - b.points[j]));
            let _ = writeln!(
                out,
                "{pad}  End Site\n{pad}  {{\n{pad}    OFFSET {x:.6} {y:.6} {z:.6}\n{pad}  }}"
            );
        }
        for &c in children[s].iter().rev() {
            stack.push((c, depth + 1, false));
        }
    }
    let frame_time = if poses.len() > 1 {
        (poses[poses.len() - 1].time_s - poses[0].time_s) / (poses.len() - 1) as f64
    } else {
        sim.dt_s()
    };
    let _ = writeln!(
        out,
        "MOTION\nFrames: {}\nFrame Time: {frame_time:.9}",
        poses.len()
    );
    for p in poses {
        let mut line = String::with_capacity(order.len() * 30);
        for &s in &order {
            if parents[s].is_none() {
                let [x, y, z] = y_up(&offsets[s]);
                let _ = write!(line, "{x:.6} {y:.6} {z:.6} ");
            }
            let [qx, qy, qz, qw] = y_up_quaternion(&p.local[s]);
            let q = UnitQuaternion::new_normalize(nalgebra::Quaternion::new(qw, qx, qy, qz));
            let [z, x, y] = zxy_euler_deg(&q);
            let _ = write!(line, "{z:.6} {x:.6} {y:.6} ");
        }
        out.push_str(line.trim_end());
        out.push('\n');
    }
    Ok(out)
}

/// [`bvh_string`] written to `path`.
///
/// # Errors
/// As [`bvh_string`], and [`AnimError::Io`].
pub fn write_bvh(path: &Path, sim: &Simulation, poses: &[Pose]) -> Result<()> {
    let text = bvh_string(sim, poses)?;
    std::fs::write(path, text).map_err(|e| AnimError::io(path, e))
}

/// Per-branch bending angles as CSV: a header `t,<branch id>,...`, then one row per pose
/// with the time in seconds and each branch's angle in degrees (shortest round-trip
/// decimal: nothing is lost).
///
/// # Errors
/// [`AnimError::InvalidParameter`] for poses that are not of this tree, not finite or not
/// in time order.
pub fn angles_csv(sim: &Simulation, poses: &[Pose]) -> Result<String> {
    check_poses(sim, poses)?;
    let branches = sim.tree().branches();
    let mut out = String::from("t");
    for b in branches {
        let _ = write!(out, ",{}", b.id);
    }
    out.push('\n');
    for p in poses {
        let _ = write!(out, "{}", p.time_s);
        for a in &p.angle_rad {
            let _ = write!(out, ",{}", a.to_degrees());
        }
        out.push('\n');
    }
    Ok(out)
}

/// Per-branch displacements as CSV: a header `t,<id>_u,<id>_w,...`, then one row per pose
/// with the time in seconds and each branch's modal displacement along its u and w axes in
/// metres.
///
/// # Errors
/// As [`angles_csv`].
pub fn displacement_csv(sim: &Simulation, poses: &[Pose]) -> Result<String> {
    check_poses(sim, poses)?;
    let mut out = String::from("t");
    for b in sim.tree().branches() {
        let _ = write!(out, ",{0}_u,{0}_w", b.id);
    }
    out.push('\n');
    for p in poses {
        let _ = write!(out, "{}", p.time_s);
        for [u, w] in &p.displacement_m {
            let _ = write!(out, ",{u},{w}");
        }
        out.push('\n');
    }
    Ok(out)
}

/// `text` written to `path`.
///
/// # Errors
/// [`AnimError::Io`].
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|e| AnimError::io(path, e))
}
