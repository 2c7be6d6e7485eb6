#![doc = include_str!("../README.md")]

#[cfg(feature = "beam-anim")]
pub use beam_anim;
#[cfg(feature = "branch-angles")]
pub use branch_angles;
#[cfg(feature = "kinect-io")]
pub use kinect_io;
#[cfg(feature = "meanshift-track")]
pub use meanshift_track;
#[cfg(feature = "mocap-pipeline")]
pub use mocap_pipeline;
#[cfg(feature = "modal-estimate")]
pub use modal_estimate;
#[cfg(feature = "space-colonize")]
pub use space_colonize;

pub use image;
pub use nalgebra;

/// The preludes of every enabled crate.
pub mod prelude {
    #[cfg(feature = "beam-anim")]
    pub use beam_anim::prelude::*;
    #[cfg(feature = "branch-angles")]
    pub use branch_angles::prelude::*;
    #[cfg(feature = "kinect-io")]
    pub use kinect_io::prelude::*;
    #[cfg(feature = "meanshift-track")]
    pub use meanshift_track::prelude::*;
    #[cfg(feature = "modal-estimate")]
    pub use modal_estimate::prelude::*;
    #[cfg(feature = "space-colonize")]
    pub use space_colonize::prelude::*;
}
