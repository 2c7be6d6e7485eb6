//! A static tree model from a point cloud (paper, section 6.1): space colonization
//! (Runions, Lane, Prusinkiewicz 2007) grows the skeleton from the cloud, branches form a
//! hierarchy with orders (the paper's levels), radii follow the pipe model, and the geometry
//! is generalized cylinders. The model measures its own fidelity to the cloud.
//!
//! Place in the pipeline: kinect-io gives the point cloud (one frame or several merged);
//! this crate gives the [`Skeleton`] that beam-anim animates.
//!
//! - [`reconstruct`] with [`ColonizeConfig`] (every parameter derived from the cloud unless
//!   set, see [`Parameters`]):
//!   1. validation, median point spacing, a ground plane under the tree set aside
//!      ([`Ground`]: the lowest near-horizontal surface that fills a wide area, with next
//!      to nothing below it), optionally the points of leaves
//!      ([`ColonizeConfig::separate_leaves`], [`separate_wood`]: normals that do not share
//!      an axis; a scan in leaf then gives a wood skeleton), trunk radius from a circle
//!      fitted to the lowest slice,
//!      clusters beyond the largest bridge and isolated points (fewer than 3 others
//!      within 15 spacings: stray returns) set aside as outliers;
//!   2. growth, by default [`Growth::Auto`]: space colonization, kept unless less than
//!      [`AUTO_NEAR_SHARE`] of it lies within 2 cm of the points (a leafy crown it crosses
//!      through the air), then geodesic level sets ([`Growth::LevelSets`]).
//!      Space colonization with k-d trees (kiddo): kill distance ≈ 1.2 trunk radii (1.6
//!      when the trunk's lowest slice shows a one-sided view, [`ONE_SIDED_COVERAGE`]), step
//!      1.5 spacings, influence 2.75 kill distances; only points near new nodes are
//!      revisited, so growth costs O(n log n); gaps (occlusions, one-sided views) are
//!      crossed by the shortest straight bridge, never by growth toward nothing; a step
//!      that would leave the cloud (the mean attraction between two diverging twigs) goes
//!      toward the nearest attractor instead; an iteration and a node bound end it with
//!      an error if ever hit;
//!   3. tips extended to the last points they reached, nodes moved onto the branch axis
//!      (circle fits across the branch; centroids where a branch is too thin), smoothed;
//!   4. a second, fine pass grows the twigs shorter than the first kill distance toward the
//!      points still more than 2 cm off the model;
//!   5. radii: the pipe model r_parent^e = Σ r_child^e (e = 2.5) anchored at the fitted trunk
//!      base and, by default, at every radius a circle fit measures along a branch (a
//!      straight taper fitted per chain; in a one-sided view no node thinner than the
//!      child carrying the most beyond it, up to the pipe model: a stretch the camera
//!      hardly saw is otherwise measured on what hid it); stubs that do not reach beyond their parent's
//!      surface, and twig ends more than 2 cm from every point, are removed unless a
//!      point needs them; in a one-sided view whose camera is known
//!      ([`ColonizeConfig::camera_m`], [`ColonizeConfig::hidden_wood`]), a thick chain
//!      drawn along the branches that hid its wood (the camera saw through the chain's
//!      own surface, but not through the straight line past them) is continued on that
//!      line ([`GrowthReport::hidden_stretches`]);
//!   6. in a full scan, each segment's cylinder fitted to its own points (least mean
//!      distance, where they go round at least half of it; [`ColonizeConfig::cylinder_fits`]),
//!      as TreeQSM fits its cylinders.
//! - [`Skeleton`]: nodes with parents and radii, [`Branch`]es (chains continuing through each
//!   fork along the child carrying the most tree), orders, lengths, JSON files.
//! - [`metrics`]: point-to-surface distances (mean, median, p95, shares within 1/2/5 cm),
//!   the share of model length near the cloud, length and volume of the wood (each branch
//!   from its parent's surface, as TreeQSM counts it: [`Skeleton::inside_parent_m`]).
//! - [`fidelity`]: the measure models of other tools are compared by (edges as truncated
//!   cones between their nodes' radii; needs nothing but nodes and radii).
//! - [`cylinders`] (TreeQSM-style table, [`cylinders_to_csv`]) and [`tube_mesh`] (OBJ, PLY).
//! - [`synthetic`] trees with a known skeleton, and [`synthetic::skeleton_error`];
//!   [`camera_view`]: what one depth camera sees of a full scan (the near half of each
//!   branch, noise along the rays), to judge a reconstruction from a one-sided view
//!   against the full cloud.
//!
//! - [`UpAxis`] turns a cloud whose up is another axis (a depth camera's frame: y down;
//!   Y-up exports) into the tree frame and the model back;
//!   [`Reconstruction::camera_frame_suspected`] flags a cloud that still looks like a
//!   camera's frame ([`looks_like_camera_frame`]).
//!
//! Units: metres; the tree frame is right-handed with Z up. Nothing here panics on input:
//! bad clouds and parameters are [`ColonizeError`]s.
//!
//! ```
//! use space_colonize::synthetic::{SyntheticConfig, skeleton_error};
//! use space_colonize::{ColonizeConfig, metrics, reconstruct};
//!
//! let truth = SyntheticConfig { points: 8_000, max_order: 2, ..Default::default() }.generate()?;
//! let model = reconstruct(&truth.points, &ColonizeConfig::default())?;
//! let m = metrics(&truth.points, &model.skeleton);
//! assert!(m.within_2cm > 0.97, "{m:?}");
//! let e = skeleton_error(&model.skeleton, &truth.skeleton);
//! assert!(e.mean_skeleton_error_m < 0.02, "{e:?}");
//! # Ok::<(), space_colonize::ColonizeError>(())
//! ```

mod circle;
mod cloud;
mod config;
mod error;
mod fidelity;
mod fit;
mod frame;
mod geometry;
mod ground;
mod grow;
mod hidden;
mod levels;
mod metrics;
mod reconstruct;
mod refine;
mod skeleton;
pub mod synthetic;
mod view;
mod wood;

pub use cloud::{MAX_COORDINATE_M, MIN_POINTS};
pub use config::{
    ACROSS_RAY_MAX_RADIUS_M, ACROSS_RAY_RANGE_PER_RADIUS, AUTO_NEAR_SHARE, ColonizeConfig, Growth,
    INFLUENCE_PER_KILL, KILL_PER_TRUNK_RADIUS, KILL_PER_TRUNK_RADIUS_ONE_SIDED, LEVEL_BIN_SPACINGS,
    MAX_GAP_INFLUENCES, MAX_PATCH_M, MAX_TWIG_KILL_M, MIN_KILL_SPACINGS, MIN_LEVEL_BIN_M,
    MIN_STEP_PER_KILL, ONE_SIDED_COVERAGE, PATCH_BINS, PIPE_EXPONENT, Parameters, STEP_SPACINGS,
};
pub use error::{ColonizeError, Result};
pub use reconstruct::{
    FAR_TIP_SPACINGS, GrowthReport, NOISY_SCAN_M, NOISY_VIEW_M, Reconstruction, Stage, reconstruct,
    reconstruct_with_progress,
};
pub use skeleton::{Branch, MAX_INSIDE_RADII, Skeleton, SkeletonNode, skeleton_nodes_from_json};

pub use fidelity::{CANDIDATE_EDGES, Fidelity, MODEL_SAMPLE_M, fidelity};
pub use frame::{
    CAMERA_FRUSTUM_SHARE, CAMERA_MAX_DEPTH_M, CAMERA_MAX_TAN, CAMERA_MIN_DEPTH_M, UpAxis,
    looks_like_camera_frame,
};
pub use geometry::{
    Cylinder, DEFAULT_MESH_SIDES, MAX_MESH_SIDES, TriangleMesh, cylinders, cylinders_to_csv,
    tube_mesh,
};
pub use ground::{
    BELOW_BANDS, DROP_SHARE, Ground, MAX_BELOW_SHARE, MAX_SLOPE_DEG, MAX_THICKNESS_M, MAX_TILT_DEG,
    MIN_FILL, MIN_SURFACE_CELLS, MIN_WIDTH_CELLS,
};
pub use levels::{
    BRIDGE_COST, EDGE_SPACINGS, LEVEL_VOXEL_BINS, LINK_BINS, NEIGHBOURS, THIN_BELOW_VOXEL,
};
pub use metrics::{Metrics, NEAR_CLOUD_M, NOISE_BRANCH_RADIUS_M, metrics};
pub use view::{KINECT_DEPTH_NOISE_M, KINECT_V2_PIXEL_RAD, MIN_PIXEL_RAD, ViewConfig, camera_view};
pub use wood::{
    AXIS_TOLERANCE_DEG, COHERENCE_NEIGHBOURS, COHERENCE_SPACINGS, FILL_SHARE, LINK_SPACINGS,
    Leaves, MAX_OFF_AXIS_SHARE, MAX_TWIG_WIDTH_RATIO, MIN_COHERENCE_NEIGHBOURS,
    MIN_COHERENCE_RADIUS_M, MIN_WOOD_EXTENT_M, MIN_WOOD_EXTENT_SPACINGS, NORMAL_NEIGHBOURS,
    NORMAL_SCALES, WEAK_PER_STRONG, WoodConfig, WoodSplit, separate_wood,
};

/// The types most programs need.
pub mod prelude {
    pub use crate::{
        Branch, ColonizeConfig, ColonizeError, Metrics, Reconstruction, Skeleton, SkeletonNode,
        metrics, reconstruct,
    };
}
