//! A reconstructed tree swaying in wind with its measured dynamics (paper section 6.2).
//!
//! Each branch of a [`space_colonize::Skeleton`] becomes a curved beam of four segments
//! ([`BeamTree`]); the wind's drag on its segments drives one oscillator of eq. (7) per branch
//! (two with [`Forcing::Components`]); the displacement bends the beam as a chain of
//! rotational springs (moments at segment midpoints, exact for a tip load); children ride on
//! their parent's deformed frame. [`Integrator::ExactZoh`] is exact at any frame rate.
//!
//! ```
//! use beam_anim::{AnimConfig, BeamTree, PAPER_DYNAMICS, Simulation};
//! use space_colonize::synthetic::SyntheticConfig;
//!
//! let skeleton = SyntheticConfig { points: 2_000, ..Default::default() }.generate()?.skeleton;
//! let config = AnimConfig::default();
//! let tree = BeamTree::new(&skeleton, &config)?;
//! let dynamics = vec![PAPER_DYNAMICS; tree.branches().len()];
//! let mut sim = Simulation::new(tree, &dynamics, config, 1.0 / 30.0)?;
//! let mut wind = sim.wind_field()?;
//! for _ in 0..30 {
//!     sim.step(&mut wind)?;
//! }
//! assert!(sim.pose().angle_rad.iter().all(|a| a.is_finite()));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod assign;
mod error;
pub mod export;
pub mod export_text;
mod oscillator;
mod procedural;
mod rotation;
mod sim;
mod tree;
pub mod wind;

pub use assign::{Assignment, DynamicsSource, DynamicsSpec, MeasuredDynamics};
pub use error::{AnimError, Result};
pub use export::{GlbOptions, MAX_GLTF_JOINTS, glb_bytes, write_glb};
pub use export_text::{angles_csv, bvh_string, displacement_csv, write_bvh};
pub use oscillator::{
    Dynamics, EULER_TOLERANCE, Integrator, MAX_FREQUENCY_HZ, MAX_SUBSTEPS, PAPER_DYNAMICS,
    free_response, gain,
};
pub use procedural::procedural_tree;
pub use sim::{
    AnimConfig, Forcing, IntegratorReport, MAX_FRAMES, MAX_POSE_BYTES, MAX_PULL_RAD, Pose,
    SMALL_ANGLE_LIMIT_RAD, Simulation, frame_count,
};
pub use tree::{
    BeamBranch, BeamTree, GREEN_WOOD_DENSITY_KG_M3, MAX_POSITION_M, MAX_RADIUS_M, SEGMENTS,
    read_skeleton, skeleton_from_json, validate_nodes,
};
pub use wind::{MAX_WIND_SPEED_M_S, Spectrum, WindConfig, WindField};

/// The types most programs need.
pub mod prelude {
    pub use crate::{
        AnimConfig, AnimError, BeamTree, Dynamics, Integrator, Pose, Simulation, WindConfig,
        WindField,
    };
}
