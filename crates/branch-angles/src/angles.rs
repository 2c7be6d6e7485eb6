//! The relative rotation angle of every branch (eq. 1 of the paper), its signed
//! decomposition in a frame attached to the parent, and each marker's displacement.

use nalgebra::{Point3, Rotation3, Unit, Vector3};

use crate::error::{AngleError, Result};
use crate::hierarchy::Hierarchy;
use crate::series::Series;
use crate::trajectory::{Gap, GapConfig, Trajectories};

/// Which samples define the rest pose that the signed angles and the displacements are
/// referenced to.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum RestPose {
    /// The mean over every known sample (directions: the normalised mean of unit vectors).
    /// Suits a swing about the rest pose; a long held pull shifts it (the modal fit absorbs a
    /// constant offset).
    #[default]
    Mean,
    /// The first sample where the quantity is known.
    FirstSample,
    /// The mean over the samples in `start_s..=end_s` (e.g. the still tree before the pull,
    /// or the settled tail).
    Interval {
        /// Start, seconds.
        start_s: f64,
        /// End, seconds (inclusive).
        end_s: f64,
    },
}

/// Settings of [`branch_angles`].
#[derive(Debug, Clone, PartialEq)]
pub struct AngleConfig {
    /// Gap filling of the trajectories before the angles. Default: [`GapConfig::default`]
    /// (cubic Hermite, up to 3 samples).
    pub gaps: GapConfig,
    /// The direction the branches of the root's children are measured against, in the
    /// trajectories' frame (the trunk is taken as still; the root has no parent branch).
    /// Default +Z, up in the tree frame of `docs/conventions.md`; pass -Y for trajectories
    /// in the camera frame with a level camera.
    pub root_direction: Vector3<f64>,
    /// Rest pose for the signed angles and the displacements. Default [`RestPose::Mean`].
    pub rest: RestPose,
    /// Segments shorter than this give no angle at that sample (a gap): a direction from
    /// nearly coincident markers is noise (Kinect V2 position noise of about 1.5 mm over 1 cm
    /// is 9 degrees). Metres, default 0.01.
    pub min_segment_m: f64,
    /// Compute the signed decomposition. Default true.
    pub signed: bool,
}

impl Default for AngleConfig {
    fn default() -> Self {
        Self {
            gaps: GapConfig::default(),
            root_direction: Vector3::z(),
            rest: RestPose::Mean,
            min_segment_m: DEFAULT_MIN_SEGMENT_M,
            signed: true,
        }
    }
}

/// Default shortest segment (m).
const DEFAULT_MIN_SEGMENT_M: f64 = 0.01;
/// Below this sine of the angle between the rest child and parent directions, the fork plane
/// is undefined and the signed frame takes the child's main swing direction instead
/// (radians; sin(1 degree)).
const ALIGNED_SIN: f64 = 0.017_452_406_437_283_51;

impl AngleConfig {
    /// The paper's computation: eq. (1) only, no gap filling (the paper re-seeded lost
    /// markers by hand), no signed decomposition.
    pub fn paper() -> Self {
        Self {
            gaps: GapConfig::NONE,
            signed: false,
            ..Self::default()
        }
    }

    /// Check the fields.
    ///
    /// # Errors
    /// [`AngleError::InvalidParameter`] for a root direction that is zero or not finite, a
    /// minimum segment that is negative or not finite, a rest interval that is empty or not
    /// finite; as [`GapConfig::validate`].
    pub fn validate(&self) -> Result<()> {
        self.gaps.validate()?;
        let n = self.root_direction.norm();
        if !(n.is_finite() && n > 0.0) {
            return Err(AngleError::param(
                "root_direction",
                format!("{:?} is not a finite non-zero vector", self.root_direction),
            ));
        }
        if !(self.min_segment_m.is_finite() && self.min_segment_m >= 0.0) {
            return Err(AngleError::param(
                "min_segment_m",
                format!("{} must be finite and not negative", self.min_segment_m),
            ));
        }
        if let RestPose::Interval { start_s, end_s } = self.rest
            && !(start_s.is_finite() && end_s.is_finite() && start_s <= end_s)
        {
            return Err(AngleError::param(
                "rest",
                format!("interval {start_s}..={end_s} s is empty or not finite"),
            ));
        }
        Ok(())
    }
}

/// The signed decomposition of a branch's direction in a frame attached to its parent
/// branch, referenced to the rest pose, radians. The frame (u, v, w) is the paper's: v along
/// the child branch at rest, u in the plane of the fork pointing towards the parent's axis
/// (or, for a child aligned with its parent, along the child's main swing), w = u x v.
/// `u_rad` is the tilt towards u, `atan2(l.u, l.v)`, and `w_rad` the tilt towards w, where l
/// is the child's direction carried back to the parent's rest pose by the shortest rotation.
/// Both are 0 at rest and change sign when the branch swings through its rest direction, so
/// they keep the swing's frequency where the unsigned angle folds it to twice that.
#[derive(Debug, Clone, PartialEq)]
pub struct SignedAngles {
    /// Tilt towards u, radians.
    pub u_rad: Series,
    /// Tilt towards w, radians.
    pub w_rad: Series,
}

/// The angles of one branch.
#[derive(Debug, Clone, PartialEq)]
pub struct BranchAngles {
    /// The child marker (names the branch).
    pub child: String,
    /// The parent marker.
    pub parent: String,
    /// The parent's parent (`None` for a branch of a child of the root, measured against
    /// [`AngleConfig::root_direction`]).
    pub grandparent: Option<String>,
    /// Branch level: 1 for the children of the root.
    pub level: usize,
    /// Eq. (1): the angle between the parent branch's direction and this branch's, radians,
    /// as `atan2(|p x c|, p . c)`.
    pub angle_rad: Series,
    /// The signed decomposition, with [`AngleConfig::signed`].
    pub signed: Option<SignedAngles>,
    /// Samples where every marker was known but a segment was shorter than
    /// [`AngleConfig::min_segment_m`] (gaps in the output).
    pub degenerate_samples: usize,
}

/// Everything [`branch_angles`] computes.
#[derive(Debug, Clone, PartialEq)]
pub struct AngleSet {
    /// The time base, seconds.
    pub times_s: Vec<f64>,
    /// One entry per branch (per marker with a parent), in the hierarchy's order.
    pub branches: Vec<BranchAngles>,
    /// Per marker of the trajectories: distance from its rest position, metres (the absolute
    /// motion the paper argues against using: it includes every parent's motion).
    pub displacements_m: Vec<Series>,
    /// Every gap of the trajectories, filled or not.
    pub gaps: Vec<Gap>,
}

/// A unit vector from `from` to `to`, or `None` when shorter than `min_m`.
fn direction(from: Point3<f64>, to: Point3<f64>, min_m: f64) -> Option<Vector3<f64>> {
    let d = to - from;
    let n = d.norm();
    (n > min_m && n > 0.0).then(|| d / n)
}

/// The rotation taking unit `from` to unit `to` by the shortest arc, with the angle as
/// `atan2(|from x to|, from . to)` (nalgebra's `rotation_between` takes `acos` of the dot
/// product, which is NaN when rounding lifts it above 1); a half turn about a perpendicular
/// axis when they are opposite.
pub(crate) fn shortest_arc(from: &Vector3<f64>, to: &Vector3<f64>) -> Rotation3<f64> {
    let axis = from.cross(to);
    let s = axis.norm();
    let c = from.dot(to);
    if s > 0.0 {
        Rotation3::from_axis_angle(&Unit::new_unchecked(axis / s), s.atan2(c))
    } else if c >= 0.0 {
        Rotation3::identity()
    } else {
        Rotation3::from_axis_angle(&any_perpendicular(from), std::f64::consts::PI)
    }
}

/// A unit vector perpendicular to unit `v`.
fn any_perpendicular(v: &Vector3<f64>) -> Unit<Vector3<f64>> {
    let k = v.iamin();
    let mut e = Vector3::zeros();
    e[k] = 1.0;
    Unit::new_normalize(v.cross(&e))
}

/// The indices of `times_s` the rest pose averages over, among `known` samples.
fn rest_samples(rest: RestPose, times_s: &[f64], known: &[bool]) -> Vec<usize> {
    let mut idx = (0..times_s.len()).filter(|&k| known[k]);
    match rest {
        RestPose::Mean => idx.collect(),
        RestPose::FirstSample => idx.next().into_iter().collect(),
        RestPose::Interval { start_s, end_s } => idx
            .filter(|&k| (start_s..=end_s).contains(&times_s[k]))
            .collect(),
    }
}

/// Normalised mean of unit vectors at `idx` (None when they cancel or there are none).
fn mean_direction(vectors: &[Option<Vector3<f64>>], idx: &[usize]) -> Option<Vector3<f64>> {
    let sum: Vector3<f64> = idx.iter().filter_map(|&k| vectors[k]).sum();
    let n = sum.norm();
    (n > 1e-12).then(|| sum / n)
}

/// Compute every branch's angles (and each marker's displacement) from `trajectories`.
///
/// Every marker of `hierarchy` must have a trajectory. Short gaps are filled first
/// ([`AngleConfig::gaps`]); a sample where a marker is still missing, or a segment is shorter
/// than [`AngleConfig::min_segment_m`], is a gap (`None`) in the output, never a NaN.
///
/// # Errors
/// As [`AngleConfig::validate`]; [`AngleError::UnknownMarker`] for a hierarchy marker
/// without a trajectory; [`AngleError::NotInHierarchy`] for a trajectory the hierarchy does
/// not name; [`AngleError::InvalidParameter`] when a rest interval holds no known
/// sample of a branch or marker.
pub fn branch_angles(
    hierarchy: &Hierarchy,
    trajectories: &Trajectories,
    config: &AngleConfig,
) -> Result<AngleSet> {
    config.validate()?;
    let index = trajectory_index(hierarchy, trajectories)?;
    let filled = trajectories.fill_gaps(&config.gaps)?;
    let times = filled.trajectories.times_s();
    let n = times.len();
    let pos = |id: &str| -> (&[Option<Point3<f64>>], &[bool]) {
        let k = index[hierarchy.index_of(id).unwrap_or(0)];
        (
            &filled.trajectories.markers()[k].positions_m,
            &filled.measured[k],
        )
    };
    let root_dir = config.root_direction.normalize();
    let mut branches = Vec::new();
    for b in hierarchy.branches() {
        let (pc, mc) = pos(b.child);
        let (pp, mp) = pos(b.parent);
        let grand = b.grandparent.map(&pos);
        let mut parent_dirs = vec![None; n];
        let mut child_dirs = vec![None; n];
        let mut measured = vec![false; n];
        let mut degenerate = 0;
        for k in 0..n {
            let parent_dir = match grand {
                None => pp[k].map(|_| Some(root_dir)),
                Some((pg, _)) => match (pg[k], pp[k]) {
                    (Some(g), Some(p)) => Some(direction(g, p, config.min_segment_m)),
                    _ => None,
                },
            };
            let child_dir = match (pp[k], pc[k]) {
                (Some(p), Some(c)) => Some(direction(p, c, config.min_segment_m)),
                _ => None,
            };
            match (parent_dir, child_dir) {
                (Some(Some(e)), Some(Some(d))) => {
                    parent_dirs[k] = Some(e);
                    child_dirs[k] = Some(d);
                    measured[k] = mc[k] && mp[k] && grand.is_none_or(|(_, mg)| mg[k]);
                }
                (Some(_), Some(_)) => degenerate += 1,
                _ => {}
            }
        }
        let angle: Vec<Option<f64>> = parent_dirs
            .iter()
            .zip(&child_dirs)
            .map(|(e, d)| match (e, d) {
                (Some(e), Some(d)) => Some(e.cross(d).norm().atan2(e.dot(d))),
                _ => None,
            })
            .collect();
        let signed = if config.signed {
            Some(signed_angles(
                b.child,
                times,
                &parent_dirs,
                &child_dirs,
                &measured,
                config.rest,
            )?)
        } else {
            None
        };
        branches.push(BranchAngles {
            child: b.child.to_string(),
            parent: b.parent.to_string(),
            grandparent: b.grandparent.map(str::to_string),
            level: hierarchy.level_of(b.child).unwrap_or(0),
            angle_rad: Series {
                name: b.child.to_string(),
                times_s: times.to_vec(),
                values: angle,
                measured,
            },
            signed,
            degenerate_samples: degenerate,
        });
    }
    let displacements_m = filled
        .trajectories
        .markers()
        .iter()
        .zip(&filled.measured)
        .map(|(m, real)| displacement(&m.id, times, &m.positions_m, real, config.rest))
        .collect::<Result<_>>()?;
    Ok(AngleSet {
        times_s: times.to_vec(),
        branches,
        displacements_m,
        gaps: filled.gaps,
    })
}

/// For each marker of the hierarchy, the index of its trajectory.
///
/// # Errors
/// [`AngleError::UnknownMarker`] for a hierarchy marker without a trajectory,
/// [`AngleError::NotInHierarchy`] for a trajectory of a marker the hierarchy does not name.
fn trajectory_index(hierarchy: &Hierarchy, trajectories: &Trajectories) -> Result<Vec<usize>> {
    let index: Vec<usize> = hierarchy
        .markers()
        .iter()
        .map(|m| {
            trajectories
                .markers()
                .iter()
                .position(|t| t.id == m.id)
                .ok_or_else(|| AngleError::UnknownMarker { id: m.id.clone() })
        })
        .collect::<Result<_>>()?;
    if let Some(extra) = trajectories
        .markers()
        .iter()
        .find(|t| hierarchy.index_of(&t.id).is_none())
    {
        return Err(AngleError::NotInHierarchy {
            id: extra.id.clone(),
        });
    }
    Ok(index)
}

fn no_rest_sample(what: &str, rest: RestPose) -> AngleError {
    AngleError::param("rest", format!("{rest:?} holds no known sample of {what}"))
}

fn signed_angles(
    child: &str,
    times: &[f64],
    parent_dirs: &[Option<Vector3<f64>>],
    child_dirs: &[Option<Vector3<f64>>],
    measured: &[bool],
    rest: RestPose,
) -> Result<SignedAngles> {
    let n = times.len();
    let known: Vec<bool> = child_dirs.iter().map(Option::is_some).collect();
    let series = |suffix: &str, values: Vec<Option<f64>>| Series {
        name: format!("{child}_{suffix}"),
        times_s: times.to_vec(),
        values,
        measured: measured.to_vec(),
    };
    if !known.iter().any(|&k| k) {
        return Ok(SignedAngles {
            u_rad: series("u", vec![None; n]),
            w_rad: series("w", vec![None; n]),
        });
    }
    let idx = rest_samples(rest, times, &known);
    let Some(a) = mean_direction(parent_dirs, &idx) else {
        return Err(no_rest_sample(&format!("branch {child:?}"), rest));
    };
    // The child's direction carried back to the parent's rest pose.
    let local: Vec<Option<Vector3<f64>>> = parent_dirs
        .iter()
        .zip(child_dirs)
        .map(|(e, d)| match (e, d) {
            (Some(e), Some(d)) => Some(shortest_arc(e, &a) * d),
            _ => None,
        })
        .collect();
    let Some(v) = mean_direction(&local, &idx) else {
        return Err(no_rest_sample(&format!("branch {child:?}"), rest));
    };
    let toward_parent = a - v * a.dot(&v);
    let u = if toward_parent.norm() > ALIGNED_SIN {
        toward_parent.normalize()
    } else {
        main_swing(&local, &v)
    };
    let w = u.cross(&v);
    let (mut us, mut ws) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for l in &local {
        match l {
            Some(l) => {
                let lv = l.dot(&v);
                us.push(Some(l.dot(&u).atan2(lv)));
                ws.push(Some(l.dot(&w).atan2(lv)));
            }
            None => {
                us.push(None);
                ws.push(None);
            }
        }
    }
    Ok(SignedAngles {
        u_rad: series("u", us),
        w_rad: series("w", ws),
    })
}

/// The direction perpendicular to `v` along which the local directions spread most (the
/// principal axis of their components across `v`); any perpendicular when they do not move.
/// Its sign makes the first clearly non-zero projection positive, so that the swing starts
/// positive.
fn main_swing(local: &[Option<Vector3<f64>>], v: &Vector3<f64>) -> Vector3<f64> {
    let mut cov = nalgebra::Matrix3::zeros();
    for l in local.iter().flatten() {
        let p = l - v * l.dot(v);
        cov += p * p.transpose();
    }
    // Bounded: a 3x3 matrix of finite entries converges in a few sweeps.
    let Some(eig) = nalgebra::SymmetricEigen::try_new(cov, f64::EPSILON, 1000) else {
        return any_perpendicular(v).into_inner();
    };
    let k = eig.eigenvalues.imax();
    let axis = eig.eigenvectors.column(k).into_owned();
    let axis = axis - v * axis.dot(v);
    if eig.eigenvalues[k] <= 1e-18 || axis.norm() < 1e-9 {
        return any_perpendicular(v).into_inner();
    }
    let axis = axis.normalize();
    let first = local
        .iter()
        .flatten()
        .map(|l| l.dot(&axis))
        .find(|p| p.abs() > 1e-9);
    match first {
        Some(p) if p < 0.0 => -axis,
        _ => axis,
    }
}

fn displacement(
    id: &str,
    times: &[f64],
    positions: &[Option<Point3<f64>>],
    measured: &[bool],
    rest: RestPose,
) -> Result<Series> {
    let known: Vec<bool> = positions.iter().map(Option::is_some).collect();
    let idx = rest_samples(rest, times, &known);
    let values = if known.iter().any(|&k| k) {
        if idx.is_empty() {
            return Err(no_rest_sample(&format!("marker {id:?}"), rest));
        }
        let sum: Vector3<f64> = idx
            .iter()
            .filter_map(|&k| positions[k])
            .map(|p| p.coords)
            .sum();
        let rest_pos = sum / idx.len() as f64;
        positions
            .iter()
            .map(|p| p.map(|p| (p.coords - rest_pos).norm()))
            .collect()
    } else {
        vec![None; times.len()]
    };
    Ok(Series {
        name: id.to_string(),
        times_s: times.to_vec(),
        values,
        measured: measured.to_vec(),
    })
}
