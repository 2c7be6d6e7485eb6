//! # kinect-io: the capture data layer of treemocap
//!
//! From a Kinect V2 (or any calibrated RGB-D) recording to an organized textured point cloud,
//! its **projection image** and back: the devices of the paper's sections 4 and 5.2 (Hu, He,
//! He, *Motion Capture and Estimation of Dynamic Properties for Realistic Tree Animation*).
//! The paper tracks markers on an image made by projecting the textured cloud onto an image
//! plane, then reads the 3D position of a tracked pixel from the cloud; this crate builds that
//! image ([`project_cloud`]) and does the reading robustly ([`ProjectionImage::lift`]).
//!
//! Pipeline place: first stage. Everything downstream (tracking, angles, modal estimation,
//! reconstruction) reads what this crate produces.
//!
//! ## Units and frames
//! Metres, seconds. Raw depth stays in sensor units (`u16`, 0 = none) in [`DepthImage`] and
//! becomes metres only in [`CloudBuilder`]. Camera frame: OpenCV (x right, y down, z forward);
//! pixel centres at integer coordinates. World frame (optional, [`camera_to_world_z_up`]):
//! right-handed, Z up.
//!
//! ## Main entry points
//! - [`CameraModel`] (pinhole + Brown–Conrady, Kinect V2 presets), [`Calibration`] (our JSON,
//!   iai_kinect2 YAML, rigid / already-registered / libfreenect2 registration).
//! - [`Recording`] (native and TUM folders, Azure Kinect / Orbbec Femto `.mkv`, RealSense
//!   `.bag`; lazy) and
//!   [`RecordingWriter`].
//! - [`CloudBuilder`] → [`TexturedCloud`] → [`project_cloud`] → [`ProjectionImage`] →
//!   [`ProjectionImage::lift`].
//! - Point-cloud files: [`read_point_cloud`], [`read_ply`]/[`write_ply`],
//!   [`read_pcd`]/[`write_pcd`], [`read_xyz`]/[`write_xyz`].
//! - [`synth`]: Kinect-like frames of a scene of primitives with ground truth.
//!
//! ## Example
//! ```
//! use kinect_io::prelude::*;
//! use kinect_io::synth;
//!
//! // A synthetic Kinect V2 frame of a small tree with red markers (quarter-size colour
//! // camera to keep the example quick).
//! let mut config = synth::SynthConfig::kinect_v2(2.2, 1.1, 7);
//! config.calibration.color_camera = config.calibration.color_camera.scaled(0.25)?;
//! let frame = synth::render(&synth::demo_tree(7), &config)?;
//!
//! // Textured cloud in the depth camera frame, then its projection image on the depth plane.
//! let mut builder = CloudBuilder::new(&config.calibration, CloudConfig::default())?;
//! let cloud = builder.build(&frame.depth, &frame.color)?;
//! let camera = config.calibration.depth_camera;
//! let projection = project_cloud(&cloud, &camera, &Isometry3::identity(), &ProjectionConfig::default())?;
//!
//! // Lift the true pixel of a visible marker back to 3D.
//! let marker = frame.markers.iter().find(|m| m.visible).expect("a visible marker");
//! let pixel = camera.project(&marker.depth_camera_m).expect("in front");
//! let lifted = projection.lift(&cloud, &pixel, &LiftConfig::default()).expect("a point");
//! assert!((lifted - marker.depth_camera_m).norm() < 0.02);
//! # Ok::<(), kinect_io::KinectError>(())
//! ```

mod bag;
mod bag_chunk;
mod bag_msgs;
mod bag_orbbec;
mod calibration;
mod camera;
mod cloud;
mod depth;
mod ebml;
mod error;
mod freenect2;
mod k4a;
mod mjpeg;
mod occlusion;
mod opencv_yaml;
mod pcd;
mod pixels;
mod ply;
mod pointcloud;
mod projection;
mod recording;
mod ros_calibration;
mod scalar;
mod still;
pub mod synth;
mod zbuffer;

pub use calibration::{
    CALIBRATION_FORMAT, CALIBRATION_VERSION, Calibration, Extrinsics, KINECT_V2_BASELINE_M,
    RegistrationModel, TUM_DEFAULT_FOCAL_PX, camera_to_world_z_up,
};
pub use camera::{
    CameraModel, Distortion, KINECT_V2_COLOR_HEIGHT_PX, KINECT_V2_COLOR_WIDTH_PX,
    KINECT_V2_DEPTH_HEIGHT_PX, KINECT_V2_DEPTH_WIDTH_PX, MAX_DISTORTION_COEFFICIENT,
    MAX_FOCAL_SIDES, MAX_IMAGE_SIDE_PX,
};
pub use cloud::{
    CloudBuilder, CloudConfig, MAX_OCCLUSION_HALF_WINDOW_PX, OcclusionFilter, TexturedCloud,
    TexturedPoint,
};
pub use depth::{
    DEPTH_UNIT_MM_M, DEPTH_UNIT_TUM_M, DepthImage, decode_color_image, decode_depth_image,
    read_color_image, read_depth_image, write_depth_pgm, write_depth_png,
};
pub use error::{KinectError, Result};
pub use freenect2::{
    FREENECT2_COLOR_Q, FREENECT2_DEPTH_Q, Freenect2ColorParams, Freenect2Frame, Freenect2IrParams,
    Freenect2Registration,
};
pub use pcd::{PcdData, PcdPrecision, PcdWriteOptions, encode_pcd, parse_pcd, read_pcd, write_pcd};
pub use ply::{PlyFormat, encode_ply, parse_ply, read_ply, write_ply};
pub use pointcloud::{PointCloud, parse_xyz, read_point_cloud, read_xyz, write_xyz};
pub use projection::{
    LiftConfig, MAX_AUTO_SPLAT_RADIUS_PX, ProjectionConfig, ProjectionImage, Splat, project_cloud,
    register_to_color,
};
pub use recording::{
    CALIBRATION_FILE, ColorFormat, FRAMES_FILE, FRAMES_HEADER, Frame, FrameEntry, Layout,
    Recording, RecordingWriter, TUM_MAX_DIFFERENCE_S, associate,
};
pub use ros_calibration::{read_npy_transform, read_ros_camera_info};
pub use still::{STILL_SPREAD_M, StillCloud};

/// The types most programs need, plus nalgebra's `Isometry3`, `Point2`, `Point3`.
pub mod prelude {
    pub use crate::{
        Calibration, CameraModel, CloudBuilder, CloudConfig, DepthImage, KinectError, LiftConfig,
        PointCloud, ProjectionConfig, ProjectionImage, Recording, TexturedCloud, project_cloud,
    };
    pub use nalgebra::{Isometry3, Point2, Point3};
}
