//! From 3D marker trajectories to the relative rotation angle of every branch (paper,
//! section 5.3, eq. 1), ready for modal estimation.
//!
//! Place in the pipeline: kinect-io lifts the 2D marker tracks of meanshift-track to 3D
//! trajectories; this crate turns them into one angle series per branch; modal-estimate
//! takes those series ([`Series`]: timestamps, values with explicit gaps, and which samples
//! are measured) and finds each branch's frequency and damping.
//!
//! - [`Hierarchy`]: named markers (the paper's A..J), each with its parent, validated as one
//!   tree; the branch of a child marker is the segment from its parent marker to it.
//! - [`Trajectories`]: per marker, positions in metres at common timestamps in seconds, with
//!   explicit gaps; [`Trajectories::fill_gaps`] fills short ones ([`GapConfig`]: cubic
//!   Hermite up to 3 samples by default) and reports every gap.
//! - [`branch_angles`]: eq. (1), the angle between the parent branch and the child branch,
//!   computed as `atan2(|p x c|, p . c)` (exact near 0 and 180 degrees, where `acos` of a
//!   clamped ratio loses half the digits); the signed decomposition [`SignedAngles`] in a
//!   frame carried by the parent and referenced to the rest pose (the unsigned angle folds a
//!   swing through the rest direction and doubles its apparent frequency); each marker's
//!   absolute displacement. [`AngleConfig::paper`] is eq. (1) alone, without gap filling.
//! - [`drop_jumps`] takes out lifts that landed on another surface for a frame;
//!   [`relative_swing`] gives a child's swing as one coordinate (its displacement from its
//!   parent's marker along the direction it moves most), the signal modal fits need when a
//!   twig swings along its chord; [`Hierarchy::of_present`] keeps the markers whose parents
//!   are present.
//! - [`csv`]: trajectories (`t,id,x,y,z`) and angle tables (`t,<branch>...`, degrees).
//!
//! Units: metres, seconds, radians (degrees only in angle CSV files). Frames: any right-handed
//! frame; the children of the root are measured against [`AngleConfig::root_direction`]
//! (default +Z, up in the tree frame).
//!
//! ```
//! use branch_angles::{AngleConfig, branch_angles, synthetic};
//!
//! let tree = synthetic::two_level();
//! let config = AngleConfig { rest: tree.rest, ..AngleConfig::default() };
//! let set = branch_angles(&tree.hierarchy, &tree.trajectories, &config)?;
//! let d = &set.branches[1];
//! assert_eq!((d.child.as_str(), d.parent.as_str()), ("D", "C"));
//! let k = 200;
//! let err = (d.angle_rad.values[k].unwrap() - tree.truth[1].angle_rad[k]).abs();
//! assert!(err.to_degrees() < 1e-9);
//! # Ok::<(), branch_angles::AngleError>(())
//! ```

mod angles;
pub mod csv;
mod error;
mod hierarchy;
mod motion;
mod series;
pub mod synthetic;
mod trajectory;

pub use angles::{AngleConfig, AngleSet, BranchAngles, RestPose, SignedAngles, branch_angles};
pub use error::{AngleError, Result};
pub use hierarchy::{Branch, Hierarchy, MarkerNode, Pruned};
pub use motion::{DEFAULT_JUMP_M, STILL_PARENT_RATIO, drop_jumps, relative_swing};
pub use series::Series;
pub use trajectory::{
    Filled, Gap, GapConfig, Interpolation, MAX_COORDINATE_M, MarkerTrack, Trajectories,
};

/// The types most programs need.
pub mod prelude {
    pub use crate::{
        AngleConfig, AngleError, AngleSet, BranchAngles, GapConfig, Hierarchy, RestPose, Series,
        SignedAngles, Trajectories, branch_angles,
    };
}
