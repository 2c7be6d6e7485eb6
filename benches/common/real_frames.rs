//! The real frames the textured-cloud timings use (issue 23), read from
//! `../shared/data/kinect` by path: the TUM frame (already registered) and the Azure Kinect
//! frame (WFOV 2x2 binned depth, 720p colour, rational distortion on both cameras, rigid
//! registration). Shared by the `kinect_io` bench and the `cloud_timing` example, so that
//! both time the same frames as `crates/kinect-io/fixtures/open3d_cloud_timing.py`.

use std::path::{Path, PathBuf};

use treemocap::image::RgbImage;
use treemocap::kinect_io::{
    Calibration, CameraModel, CloudBuilder, CloudConfig, DEPTH_UNIT_MM_M, DEPTH_UNIT_TUM_M,
    DepthImage, Distortion, Extrinsics, ProjectionConfig, RegistrationModel, project_cloud,
    read_color_image, read_depth_image,
};

/// One frame and the calibration it needs.
pub struct Frame {
    pub calibration: Calibration,
    pub depth: DepthImage,
    pub color: RgbImage,
}

/// `../shared/data/kinect` next to the workspace, if it is there.
pub fn shared_kinect_data() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kinect");
    dir.is_dir().then_some(dir)
}

/// The TUM frame (`slambook_ch7_tum/1.png`, `1_depth.png`, 640x480, depth registered to
/// colour) with TUM's default calibration.
pub fn tum(data: &Path) -> Result<Frame, String> {
    let dir = data.join("slambook_ch7_tum");
    Ok(Frame {
        calibration: Calibration::tum_default(),
        depth: read_depth_image(&dir.join("1_depth.png"), DEPTH_UNIT_TUM_M)
            .map_err(|e| e.to_string())?,
        color: read_color_image(&dir.join("1.png")).map_err(|e| e.to_string())?,
    })
}

/// The Azure Kinect frame (`cameramodels_azure_kinect/`) with its ROS camera infos and
/// depth-to-colour transform.
pub fn azure(data: &Path) -> Result<Frame, String> {
    let dir = data.join("cameramodels_azure_kinect");
    Ok(Frame {
        calibration: Calibration {
            depth_camera: ros_camera(&dir.join("k4a_depth_camera_info.yaml"))?,
            color_camera: ros_camera(&dir.join("k4a_rgb_camera_info.yaml"))?,
            registration: RegistrationModel::Rigid(npy_transform(
                &dir.join("depth_to_rgb_transformation.npy"),
            )?),
            depth_unit_m: DEPTH_UNIT_MM_M,
            depth_offset_m: 0.0,
        },
        depth: read_depth_image(&dir.join("k4a_depth_image_raw.png"), DEPTH_UNIT_MM_M)
            .map_err(|e| e.to_string())?,
        color: read_color_image(&dir.join("k4a_rgb_image_raw.jpg")).map_err(|e| e.to_string())?,
    })
}

/// The Azure Kinect frame registered to its colour camera, as the Azure Kinect SDK's
/// `k4a_transformation_depth_image_to_color_camera` gives it and as Open3D takes it: a
/// 1280x720 depth image on the colour camera's pixels (millimetres) beside the colour image,
/// with a calibration that says so (`AlreadyRegistered`, the colour camera for both). The
/// depth is made here from the raw frame: its two-camera cloud splatted onto the colour
/// camera (`project_cloud`, nearest point per pixel).
pub fn azure_registered(data: &Path) -> Result<Frame, String> {
    let raw = azure(data)?;
    let mut builder =
        CloudBuilder::new(&raw.calibration, CloudConfig::default()).map_err(|e| e.to_string())?;
    let cloud = builder
        .build(&raw.depth, &raw.color)
        .map_err(|e| e.to_string())?;
    let camera = raw.calibration.color_camera;
    let depth_to_color = raw
        .calibration
        .depth_to_color()
        .map_err(|e| e.to_string())?
        .ok_or("the Azure calibration is not rigid")?;
    let image = project_cloud(
        &cloud,
        &camera,
        &depth_to_color,
        &ProjectionConfig::default(),
    )
    .map_err(|e| e.to_string())?;
    let mm: Vec<u16> = (0..camera.height)
        .flat_map(|v| (0..camera.width).map(move |u| (u, v)))
        .map(|(u, v)| {
            image.depth_m(u, v).map_or(0, |z| {
                (z / DEPTH_UNIT_MM_M).round().clamp(0.0, 65_535.0) as u16
            })
        })
        .collect();
    Ok(Frame {
        calibration: Calibration {
            depth_camera: camera,
            color_camera: camera,
            registration: RegistrationModel::AlreadyRegistered,
            depth_unit_m: DEPTH_UNIT_MM_M,
            depth_offset_m: 0.0,
        },
        depth: DepthImage::new(camera.width, camera.height, DEPTH_UNIT_MM_M, mm)
            .map_err(|e| e.to_string())?,
        color: raw.color,
    })
}

/// The numbers of the flow list after `key` in a ROS `camera_info` YAML file
/// (`data: [a, b, ...]`, possibly over several lines).
fn yaml_list(text: &str, key: &str, path: &Path) -> Result<Vec<f64>, String> {
    let missing = || format!("{}: no list after {key}", path.display());
    let rest = &text[text.find(key).ok_or_else(missing)?..];
    let open = rest.find('[').ok_or_else(missing)?;
    let close = rest.find(']').ok_or_else(missing)?;
    rest[open + 1..close]
        .split(',')
        .map(|v| {
            v.trim()
                .parse()
                .map_err(|e| format!("{}: {key}: {e}", path.display()))
        })
        .collect()
}

/// A camera from a ROS `camera_info` YAML file.
fn ros_camera(path: &Path) -> Result<CameraModel, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let k = yaml_list(&text, "camera_matrix", path)?;
    let d = yaml_list(&text, "distortion_coefficients", path)?;
    let size = |key: &str| -> Result<u32, String> {
        text.lines()
            .find_map(|l| l.strip_prefix(key))
            .and_then(|v| v.trim().parse().ok())
            .ok_or_else(|| format!("{}: no {key}", path.display()))
    };
    let [fx, _, cx, _, fy, cy, ..] = k[..] else {
        return Err(format!(
            "{}: camera_matrix has {} numbers",
            path.display(),
            k.len()
        ));
    };
    Ok(CameraModel {
        width: size("image_width:")?,
        height: size("image_height:")?,
        fx,
        fy,
        cx,
        cy,
        distortion: Distortion::from_opencv(&d).map_err(|e| format!("{}: {e}", path.display()))?,
    })
}

/// A 4x4 little-endian f64 `.npy` matrix (NumPy format 1.0, C order) as a rigid transform,
/// inverted: the file named `depth_to_rgb_transformation.npy` maps colour to depth. Checked
/// on its frame: with the inverse, the depth edges (jumps over 3 cm) project onto colour
/// edges (mean Sobel magnitude 36.7 at no shift, best within 8 px) and not with the matrix
/// as given (26.7, best at the 16 px edge of the search).
fn npy_transform(path: &Path) -> Result<Extrinsics, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let bad = || format!("{}: not a 4x4 f64 .npy", path.display());
    let header = usize::from(u16::from_le_bytes([
        *bytes.get(8).ok_or_else(bad)?,
        *bytes.get(9).ok_or_else(bad)?,
    ]));
    let m: Vec<f64> = bytes
        .get(10 + header..)
        .ok_or_else(bad)?
        .chunks_exact(8)
        .filter_map(|b| b.try_into().ok().map(f64::from_le_bytes))
        .collect();
    if m.len() != 16 {
        return Err(bad());
    }
    let as_given = Extrinsics {
        rotation: [[m[0], m[1], m[2]], [m[4], m[5], m[6]], [m[8], m[9], m[10]]],
        translation_m: [m[3], m[7], m[11]],
    };
    let isometry = as_given
        .to_isometry()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(Extrinsics::from_isometry(&isometry.inverse()))
}
