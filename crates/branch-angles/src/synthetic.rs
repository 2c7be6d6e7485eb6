//! Generated marker trajectories of a tree whose branches swing by known angles: for tests,
//! benches and the `branch_angles` example.
//!
//! Each branch has a rest direction (tilted from its parent's by `rest_tilt_rad` towards an
//! azimuth in the parent's frame) and swings by `(u, w)` tilts in the frame that
//! [`crate::SignedAngles`] documents, carried by its parent's motion. The tree is at rest until
//! `release_s`, then every branch swings as a decaying sine, so [`RestPose::Interval`] over
//! the still part recovers the rest pose exactly.

use nalgebra::{Point3, Vector3};

use crate::angles::{RestPose, shortest_arc};
use crate::error::{AngleError, Result};
use crate::hierarchy::{Hierarchy, MarkerNode};
use crate::trajectory::{MarkerTrack, Trajectories};

/// One branch of a generated tree.
#[derive(Debug, Clone, PartialEq)]
pub struct BranchSpec {
    /// The child marker.
    pub id: String,
    /// The parent marker (the root is `"A"`, at the origin).
    pub parent: String,
    /// Length from the parent marker, metres.
    pub length_m: f64,
    /// Angle between the rest direction and the parent branch's (radians).
    pub rest_tilt_rad: f64,
    /// Direction of that tilt around the parent branch (radians; 0 along the parent's u, or
    /// +X for the children of the root).
    pub azimuth_rad: f64,
    /// Peak tilt towards u, radians.
    pub u_amplitude_rad: f64,
    /// Peak tilt towards w, radians.
    pub w_amplitude_rad: f64,
    /// Swing frequency, hertz.
    pub frequency_hz: f64,
    /// Phase of the w swing relative to the u swing, radians.
    pub w_phase_rad: f64,
    /// Exponential decay rate of the swing, 1/s.
    pub decay_per_s: f64,
}

/// True angles of one generated branch per sample, radians.
#[derive(Debug, Clone, PartialEq)]
pub struct BranchTruth {
    /// The child marker.
    pub child: String,
    /// Eq. (1).
    pub angle_rad: Vec<f64>,
    /// Signed tilt towards u.
    pub u_rad: Vec<f64>,
    /// Signed tilt towards w.
    pub w_rad: Vec<f64>,
    /// Swing frequency, hertz.
    pub frequency_hz: f64,
}

/// A generated tree: hierarchy, trajectories and the true angles.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticTree {
    /// Root `"A"` and the branches' markers.
    pub hierarchy: Hierarchy,
    /// Noise-free positions, metres, +Z up.
    pub trajectories: Trajectories,
    /// True angles per branch, in the order of the specs.
    pub truth: Vec<BranchTruth>,
    /// The rest pose that recovers the true reference (the still part before the release).
    pub rest: RestPose,
}

/// Rest frame of a branch: parent direction `a`, child rest direction `v`, and `u`, `w`.
#[derive(Debug, Clone, Copy)]
struct Frame {
    a: Vector3<f64>,
    v: Vector3<f64>,
    u: Vector3<f64>,
    w: Vector3<f64>,
}

/// The sample rate of the paper's recordings (Kinect V2), hertz.
pub const PAPER_RATE_HZ: f64 = 30.0;
/// The paper's record length (Fig. 6), samples.
pub const PAPER_SAMPLES: usize = 409;

/// A two-level tree: the root A, C on A (tilted 35 degrees), D on C (40 degrees off C), and
/// E on C aligned with it (the case where eq. (1) folds a swing), 409 samples at 30 Hz,
/// released at 0.5 s.
pub fn two_level() -> SyntheticTree {
    let deg = f64::to_radians;
    let spec =
        |id: &str, parent: &str, length_m, tilt, azimuth, u, w, f, phase, decay| BranchSpec {
            id: id.into(),
            parent: parent.into(),
            length_m,
            rest_tilt_rad: deg(tilt),
            azimuth_rad: deg(azimuth),
            u_amplitude_rad: deg(u),
            w_amplitude_rad: deg(w),
            frequency_hz: f,
            w_phase_rad: phase,
            decay_per_s: decay,
        };
    let specs = [
        spec("C", "A", 0.8, 35.0, 0.0, 4.0, 3.0, 1.4, 0.9, 0.15),
        spec("D", "C", 0.5, 40.0, 90.0, 5.0, 2.5, 2.3, 1.7, 0.3),
        spec("E", "C", 0.4, 0.0, 0.0, 5.0, 0.0, 2.0, 0.0, 0.0),
    ];
    let times: Vec<f64> = (0..PAPER_SAMPLES)
        .map(|k| k as f64 / PAPER_RATE_HZ)
        .collect();
    // The specs are valid by construction.
    generate(&specs, &times, 0.5).unwrap_or_else(|e| unreachable!("{e}"))
}

/// Generate the trajectories of `specs` (each parent before its children; the root `"A"`)
/// at `times_s`, still until `release_s`.
///
/// # Errors
/// As [`Hierarchy::new`] and [`Trajectories::new`]; [`AngleError::InvalidParameter`] for a
/// length that is not positive or a tilt of 90 degrees or more (a swing would pass the
/// singular direction).
pub fn generate(specs: &[BranchSpec], times_s: &[f64], release_s: f64) -> Result<SyntheticTree> {
    let mut nodes = vec![MarkerNode {
        id: "A".into(),
        parent: None,
    }];
    nodes.extend(specs.iter().map(|s| MarkerNode {
        id: s.id.clone(),
        parent: Some(s.parent.clone()),
    }));
    let hierarchy = Hierarchy::new(nodes)?;
    check_specs(specs)?;
    let frames = rest_frames(specs);
    let n = times_s.len();
    let mut positions: Vec<Vec<Option<Point3<f64>>>> = vec![vec![Some(Point3::origin()); n]];
    let mut directions: Vec<Vec<Vector3<f64>>> = Vec::new();
    let mut truth = Vec::new();
    for (s, (_, f)) in specs.iter().zip(&frames) {
        let parent_idx = hierarchy.index_of(&s.parent).unwrap_or(0);
        let (mut pos, mut dirs) = (Vec::with_capacity(n), Vec::with_capacity(n));
        let (mut angle, mut us, mut ws) = (Vec::new(), Vec::new(), Vec::new());
        for (k, &t) in times_s.iter().enumerate() {
            let tau = t - release_s;
            let (tu, tw) = if tau <= 0.0 {
                (0.0, 0.0)
            } else {
                let env = (-s.decay_per_s * tau).exp();
                let ph = 2.0 * std::f64::consts::PI * s.frequency_hz * tau;
                (
                    s.u_amplitude_rad * env * ph.sin(),
                    s.w_amplitude_rad * env * ((ph + s.w_phase_rad).sin() - s.w_phase_rad.sin()),
                )
            };
            let l = (f.u * tu.tan() + f.v + f.w * tw.tan()).normalize();
            let (e, origin) = if parent_idx == 0 {
                (Vector3::z(), Point3::origin())
            } else {
                let pd: &Vec<Vector3<f64>> = &directions[parent_idx - 1];
                let pp = positions[parent_idx][k].unwrap_or_else(Point3::origin);
                (pd[k], pp)
            };
            let carry = shortest_arc(&f.a, &e);
            let d = carry * l;
            dirs.push(d);
            pos.push(Some(origin + d * s.length_m));
            angle.push(f.a.cross(&l).norm().atan2(f.a.dot(&l)));
            us.push(tu);
            ws.push(tw);
        }
        positions.push(pos);
        directions.push(dirs);
        truth.push(BranchTruth {
            child: s.id.clone(),
            angle_rad: angle,
            u_rad: us,
            w_rad: ws,
            frequency_hz: s.frequency_hz,
        });
    }
    let markers = hierarchy
        .markers()
        .iter()
        .zip(positions)
        .map(|(m, p)| MarkerTrack {
            id: m.id.clone(),
            positions_m: p,
        })
        .collect();
    let trajectories = Trajectories::new(times_s.to_vec(), markers)?;
    let rest = RestPose::Interval {
        start_s: times_s.first().copied().unwrap_or(0.0),
        end_s: release_s,
    };
    Ok(SyntheticTree {
        hierarchy,
        trajectories,
        truth,
        rest,
    })
}

/// A length that is not positive or a tilt of 90 degrees or more is an error.
fn check_specs(specs: &[BranchSpec]) -> Result<()> {
    for s in specs {
        if !(s.length_m.is_finite() && s.length_m > 0.0) {
            return Err(AngleError::param(
                "length_m",
                format!("{} for {}", s.length_m, s.id),
            ));
        }
        if s.rest_tilt_rad.is_nan() || s.rest_tilt_rad.abs() >= std::f64::consts::FRAC_PI_2 {
            return Err(AngleError::param(
                "rest_tilt_rad",
                format!("{} for {}", s.rest_tilt_rad, s.id),
            ));
        }
    }
    Ok(())
}

/// Each branch's rest frame, parents first (a branch's parent comes before it in `specs`).
fn rest_frames(specs: &[BranchSpec]) -> Vec<(String, Frame)> {
    let mut frames: Vec<(String, Frame)> = Vec::new();
    for s in specs {
        let parent = frames.iter().find(|(id, _)| *id == s.parent).map(|f| f.1);
        let (a, side) = match parent {
            None => (
                Vector3::z(),
                Vector3::new(s.azimuth_rad.cos(), s.azimuth_rad.sin(), 0.0),
            ),
            Some(p) => (p.v, p.u * s.azimuth_rad.cos() + p.w * s.azimuth_rad.sin()),
        };
        let side = (side - a * side.dot(&a)).normalize();
        let v = a * s.rest_tilt_rad.cos() + side * s.rest_tilt_rad.sin();
        let toward = a - v * a.dot(&v);
        let u = if toward.norm() > 1e-9 {
            toward.normalize()
        } else {
            side
        };
        let w = u.cross(&v);
        frames.push((s.id.clone(), Frame { a, v, u, w }));
    }
    frames
}
