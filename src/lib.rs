#![doc = include_str!("../README.md")]

#[cfg(feature = "kinect-io")]
pub use kinect_io;

pub use image;
pub use nalgebra;

/// The preludes of every enabled crate.
pub mod prelude {
    #[cfg(feature = "kinect-io")]
    pub use kinect_io::prelude::*;
}
