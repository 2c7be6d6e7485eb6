//! Recordings: timestamped colour + depth frames with a calibration, read lazily (one frame
//! in memory at a time) from a folder or a camera's container file, and written in our
//! native layout.
//!
//! Layouts (see `docs/recording-format.md`):
//! - **native**: `calibration.json`, `frames.csv` (`frame,timestamp_s,color,depth`), colour
//!   PNG/JPEG files and 16-bit depth PNG (or PGM) files in the calibration's depth unit;
//! - **TUM RGB-D**: `rgb.txt` and `depth.txt` (`timestamp filename` lines), depth in 1/5000 m,
//!   colour and depth associated by nearest timestamp as TUM's `associate.py` does; the
//!   calibration is `calibration.json` when present, else TUM's documented defaults;
//! - **Azure Kinect / Orbbec Femto `.mkv`** (`k4arecorder`'s Matroska layout): a file,
//!   calibration from its `calibration.json` attachment;
//! - **Intel RealSense `.bag`** (ROS 1, librealsense's topics): a file, calibration from its
//!   `camera_info`, `tf` and depth-unit messages;
//! - **Orbbec SDK v2 `.bag`** (ROS 1, the SDK recorder's `/cam/...` topics): a file,
//!   calibration from its stream-profile and property messages.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use image::RgbImage;

use crate::bag::{BagRecording, Flavour, is_rosbag};
use crate::calibration::Calibration;
use crate::depth::{DepthImage, read_color_image, read_depth_image, write_depth_png};
use crate::error::{KinectError, Result};
use crate::k4a::{K4aRecording, is_matroska};

/// Calibration file of a native recording (and optional in a TUM folder).
pub const CALIBRATION_FILE: &str = "calibration.json";
/// Frame index of a native recording.
pub const FRAMES_FILE: &str = "frames.csv";
/// Header line of `frames.csv`.
pub const FRAMES_HEADER: &str = "frame,timestamp_s,color,depth";
/// Largest colour-to-depth time difference accepted when associating TUM frames: 0.02 s, the
/// default `max_difference` of the TUM benchmark's `associate.py`.
pub const TUM_MAX_DIFFERENCE_S: f64 = 0.02;

/// Which layout a recording has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Layout {
    /// Our native layout (a folder).
    Native,
    /// TUM RGB-D benchmark layout (a folder).
    Tum,
    /// An Azure Kinect or Orbbec Femto Matroska recording (a `.mkv` file).
    AzureKinect,
    /// An Intel RealSense ROS 1 bag (a `.bag` file; also a ROS driver's aligned depth).
    RealSense,
    /// An Orbbec SDK v2 ROS 1 bag (a `.bag` file from OrbbecViewer or the SDK's recorder).
    Orbbec,
}

/// Where one frame's files are.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameEntry {
    /// Time of the frame in seconds (the depth image's timestamp).
    pub timestamp_s: f64,
    /// Time of the colour image in seconds (equal to `timestamp_s` in native recordings).
    pub color_timestamp_s: f64,
    /// The colour image file.
    pub color_path: PathBuf,
    /// The depth image file.
    pub depth_path: PathBuf,
}

/// One frame, loaded.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Position in the recording.
    pub index: usize,
    /// Time in seconds.
    pub timestamp_s: f64,
    /// Colour image.
    pub color: RgbImage,
    /// Depth image (raw units of the calibration).
    pub depth: DepthImage,
}

/// A camera's container file, indexed at open (Azure Kinect `.mkv`, RealSense or Orbbec
/// `.bag`).
pub(crate) trait Container: std::fmt::Debug + Send + Sync {
    /// The calibration the file records (or the one the caller gave).
    fn calibration(&self) -> &Calibration;
    /// Depth frames left out for want of a colour frame close enough in time.
    fn unpaired_depth(&self) -> usize;
    /// Depth and colour time of every paired frame, seconds.
    fn times_s(&self) -> Vec<(f64, f64)>;
    /// Read and decode frame `index` (in range), depth in `depth_unit_m` units.
    fn read(&self, path: &Path, index: usize, depth_unit_m: f64) -> Result<(RgbImage, DepthImage)>;
}

/// Where a recording's frames come from.
#[derive(Debug, Clone)]
enum Source {
    /// One image file per frame and camera (native, TUM).
    Files(Vec<FrameEntry>),
    /// A camera's container file.
    Container(Arc<dyn Container>),
}

/// A recording, opened: the calibration and the frame list are read; images are loaded only
/// when a frame is asked for.
#[derive(Debug, Clone)]
pub struct Recording {
    path: PathBuf,
    layout: Layout,
    calibration: Calibration,
    /// Depth and colour time of every frame, seconds.
    times_s: Vec<(f64, f64)>,
    /// Depth frames left out because no colour frame was close enough in time.
    unpaired: usize,
    source: Source,
}

impl Recording {
    /// Open a recording, detecting its layout: a folder with `frames.csv` is native, one with
    /// `rgb.txt` + `depth.txt` is TUM; a Matroska file (by its magic number, whatever its
    /// name) is an Azure Kinect / Orbbec Femto recording, a ROS bag a RealSense one.
    ///
    /// # Errors
    /// [`KinectError::UnknownLayout`] when no layout is found; otherwise the errors of
    /// reading the calibration and the frame list (or indexing the container).
    pub fn open(path: &Path) -> Result<Self> {
        Self::open_with(path, None)
    }

    /// Open a recording with a given calibration (overrides the one in the recording).
    ///
    /// # Errors
    /// As [`Recording::open`], and [`KinectError::InvalidParameter`] for an invalid
    /// calibration.
    pub fn open_with_calibration(path: &Path, calibration: Calibration) -> Result<Self> {
        calibration.validate()?;
        Self::open_with(path, Some(calibration))
    }

    fn open_with(path: &Path, calibration: Option<Calibration>) -> Result<Self> {
        if path.is_file() {
            return Self::open_file(path, calibration);
        }
        if !path.is_dir() {
            return Err(KinectError::io(
                path,
                std::io::Error::new(std::io::ErrorKind::NotFound, "no such file or directory"),
            ));
        }
        let dir = path;
        let calibration_path = dir.join(CALIBRATION_FILE);
        let layout = if dir.join(FRAMES_FILE).is_file() {
            Layout::Native
        } else if dir.join("rgb.txt").is_file() && dir.join("depth.txt").is_file() {
            Layout::Tum
        } else {
            return Err(KinectError::UnknownLayout {
                path: dir.to_path_buf(),
                what: format!("no {FRAMES_FILE} (native) and no rgb.txt + depth.txt (TUM)"),
            });
        };
        let calibration = match (calibration, layout) {
            (Some(c), _) => c,
            (None, Layout::Tum) if !calibration_path.is_file() => Calibration::tum_default(),
            (None, _) => Calibration::read_json(&calibration_path)?,
        };
        let (entries, unpaired) = match layout {
            Layout::Tum => read_tum(dir)?,
            _ => (read_frames_csv(dir)?, 0),
        };
        Ok(Self {
            path: dir.to_path_buf(),
            layout,
            calibration,
            times_s: entries
                .iter()
                .map(|e| (e.timestamp_s, e.color_timestamp_s))
                .collect(),
            unpaired,
            source: Source::Files(entries),
        })
    }

    fn open_file(path: &Path, calibration: Option<Calibration>) -> Result<Self> {
        let (layout, container): (_, Arc<dyn Container>) = if is_matroska(path) {
            let k4a = K4aRecording::open(path, calibration)?;
            (Layout::AzureKinect, Arc::new(k4a))
        } else if is_rosbag(path) {
            let bag = BagRecording::open(path, calibration)?;
            let layout = match bag.flavour() {
                Flavour::RealSense { .. } => Layout::RealSense,
                Flavour::Orbbec(_) => Layout::Orbbec,
            };
            (layout, Arc::new(bag))
        } else {
            return Err(KinectError::UnknownLayout {
                path: path.to_path_buf(),
                what: "a file that is neither a Matroska (.mkv) recording nor a ROS bag \
                       (.bag); a folder recording is opened by its folder"
                    .into(),
            });
        };
        Ok(Self {
            path: path.to_path_buf(),
            layout,
            calibration: container.calibration().clone(),
            times_s: container.times_s(),
            unpaired: container.unpaired_depth(),
            source: Source::Container(container),
        })
    }

    /// The folder or file the recording was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The detected layout.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// The calibration in use.
    pub fn calibration(&self) -> &Calibration {
        &self.calibration
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.times_s.len()
    }

    /// True when there are no frames.
    pub fn is_empty(&self) -> bool {
        self.times_s.is_empty()
    }

    /// Time of every frame's depth image, seconds (the device's clock for an Azure Kinect
    /// recording: block time plus `K4A_START_OFFSET_NS`).
    pub fn timestamps_s(&self) -> impl ExactSizeIterator<Item = f64> + '_ {
        self.times_s.iter().map(|t| t.0)
    }

    /// Time of every frame's colour image, seconds.
    pub fn color_timestamps_s(&self) -> impl ExactSizeIterator<Item = f64> + '_ {
        self.times_s.iter().map(|t| t.1)
    }

    /// Depth frames the recording holds but that are not frames here, because no colour
    /// image was close enough in time (TUM: 0.02 s; Azure Kinect: half a frame period).
    pub fn unpaired_depth_frames(&self) -> usize {
        self.unpaired
    }

    /// Where each frame's files are, for a folder recording; `None` for a container file.
    pub fn entries(&self) -> Option<&[FrameEntry]> {
        match &self.source {
            Source::Files(entries) => Some(entries),
            Source::Container(_) => None,
        }
    }

    /// Load frame `index`, checking both images against the calibration's camera sizes.
    ///
    /// # Errors
    /// [`KinectError::FrameOutOfRange`]; the image readers' errors;
    /// [`KinectError::SizeMismatch`] naming the file whose size is wrong.
    pub fn frame(&self, index: usize) -> Result<Frame> {
        let Some(&(timestamp_s, _)) = self.times_s.get(index) else {
            return Err(KinectError::FrameOutOfRange {
                path: self.path.clone(),
                index,
                count: self.times_s.len(),
            });
        };
        // A calibration given by the caller sets the unit a container's raw depth is in.
        let unit_m = self.calibration.depth_unit_m;
        let (color, depth, (color_name, depth_name)) = match &self.source {
            Source::Files(entries) => {
                let entry = &entries[index.min(entries.len().saturating_sub(1))];
                let color = read_color_image(&entry.color_path)?;
                let depth = read_depth_image(&entry.depth_path, unit_m)?;
                let names = (
                    entry.color_path.display().to_string(),
                    entry.depth_path.display().to_string(),
                );
                (color, depth, names)
            }
            Source::Container(container) => {
                let (color, depth) = container.read(&self.path, index, unit_m)?;
                let name = format!("{} frame {index}", self.path.display());
                (
                    color,
                    depth,
                    (format!("{name} colour"), format!("{name} depth")),
                )
            }
        };
        let against = |name: &str| format!("{name} vs. the calibration");
        self.calibration.color_camera.check_image_size(
            &against(&color_name),
            color.width(),
            color.height(),
        )?;
        self.calibration.depth_camera.check_image_size(
            &against(&depth_name),
            depth.width(),
            depth.height(),
        )?;
        Ok(Frame {
            index,
            timestamp_s,
            color,
            depth,
        })
    }

    /// All frames in order, loaded one at a time as the iterator advances.
    pub fn frames(&self) -> impl Iterator<Item = Result<Frame>> + '_ {
        (0..self.len()).map(|i| self.frame(i))
    }
}

fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|e| KinectError::io(path, e))
}

fn read_frames_csv(dir: &Path) -> Result<Vec<FrameEntry>> {
    let path = dir.join(FRAMES_FILE);
    let text = read_text(&path)?;
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim() == FRAMES_HEADER => {}
        other => {
            return Err(KinectError::format(
                &path,
                format!(
                    "line 1 must be {FRAMES_HEADER:?}, found {:?}",
                    other.map(|(_, l)| l).unwrap_or("")
                ),
            ));
        }
    }
    let mut entries = Vec::new();
    for (k, line) in lines {
        let lineno = k + 1;
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let [frame, t, color, depth] = fields.as_slice() else {
            return Err(KinectError::format(
                &path,
                format!("line {lineno}: {} fields, expected 4", fields.len()),
            ));
        };
        if frame.parse::<usize>().ok() != Some(entries.len()) {
            return Err(KinectError::format(
                &path,
                format!("line {lineno}: frame {frame:?}, expected {}", entries.len()),
            ));
        }
        let t = parse_time(t, &path, lineno)?;
        if let Some(prev) = entries.last().map(|e: &FrameEntry| e.timestamp_s)
            && t <= prev
        {
            return Err(KinectError::format(
                &path,
                format!("line {lineno}: timestamp {t} s is not after the previous {prev} s"),
            ));
        }
        // A cut or edited line names a file that is not there: said here, with the line,
        // rather than later as an unreadable image.
        for (what, file) in [("colour", color), ("depth", depth)] {
            if file.is_empty() || !dir.join(file).is_file() {
                return Err(KinectError::format(
                    &path,
                    format!(
                        "line {lineno}: the {what} image {file:?} is not a file in {}",
                        dir.display()
                    ),
                ));
            }
        }
        entries.push(FrameEntry {
            timestamp_s: t,
            color_timestamp_s: t,
            color_path: dir.join(color),
            depth_path: dir.join(depth),
        });
    }
    Ok(entries)
}

fn parse_time(s: &str, path: &Path, lineno: usize) -> Result<f64> {
    s.parse::<f64>()
        .ok()
        .filter(|t| t.is_finite())
        .ok_or_else(|| {
            KinectError::format(
                path,
                format!("line {lineno}: timestamp {s:?} is not a number"),
            )
        })
}

/// Read a TUM list file (`timestamp filename` per line, `#` comments).
fn read_tum_list(dir: &Path, name: &str) -> Result<Vec<(f64, PathBuf)>> {
    let path = dir.join(name);
    let text = read_text(&path)?;
    let mut out = Vec::new();
    for (k, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut words = line.split_whitespace();
        let (Some(t), Some(file)) = (words.next(), words.next()) else {
            return Err(KinectError::format(
                &path,
                format!("line {}: expected `timestamp filename`", k + 1),
            ));
        };
        out.push((parse_time(t, &path, k + 1)?, dir.join(file)));
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(out)
}

/// The associated frames and the number of depth images left without a colour image.
fn read_tum(dir: &Path) -> Result<(Vec<FrameEntry>, usize)> {
    let rgb = read_tum_list(dir, "rgb.txt")?;
    let depth = read_tum_list(dir, "depth.txt")?;
    let pairs = associate(&depth, &rgb, TUM_MAX_DIFFERENCE_S);
    let unpaired = depth.len() - pairs.len();
    let entries = pairs
        .into_iter()
        .map(|(d, c)| FrameEntry {
            timestamp_s: depth[d].0,
            color_timestamp_s: rgb[c].0,
            color_path: rgb[c].1.clone(),
            depth_path: depth[d].1.clone(),
        })
        .collect();
    Ok((entries, unpaired))
}

/// Associate two sorted timestamp lists one-to-one: every pair closer than `max_difference_s`
/// is a candidate, candidates are taken closest first, each item used once (TUM
/// `associate.py`). Returns index pairs `(first, second)` sorted by the first list's time.
pub fn associate<T, U>(
    first: &[(f64, T)],
    second: &[(f64, U)],
    max_difference_s: f64,
) -> Vec<(usize, usize)> {
    let mut candidates = Vec::new();
    for (i, (t, _)) in first.iter().enumerate() {
        let start = second.partition_point(|(s, _)| *s < t - max_difference_s);
        for (j, (s, _)) in second.iter().enumerate().skip(start) {
            if *s > t + max_difference_s {
                break;
            }
            if (s - t).abs() < max_difference_s {
                candidates.push(((s - t).abs(), i, j));
            }
        }
    }
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut used_first = vec![false; first.len()];
    let mut used_second = vec![false; second.len()];
    let mut pairs = Vec::new();
    for (_, i, j) in candidates {
        if !used_first[i] && !used_second[j] {
            used_first[i] = true;
            used_second[j] = true;
            pairs.push((i, j));
        }
    }
    pairs.sort_unstable();
    pairs
}

/// Item `index` of a container's frame list, or the out-of-range error naming the file.
pub(crate) fn frame_at<T: Copy>(frames: &[T], path: &Path, index: usize) -> Result<T> {
    frames
        .get(index)
        .copied()
        .ok_or_else(|| KinectError::FrameOutOfRange {
            path: path.to_path_buf(),
            index,
            count: frames.len(),
        })
}

/// Default pairing tolerance of a camera container with a single depth frame: half a 30 fps
/// frame period, in nanoseconds.
const SINGLE_FRAME_TOLERANCE_NS: f64 = 1e9 / 60.0;

/// Pair a container's depth and colour images by time (nanoseconds): both lists are sorted,
/// then associated one-to-one within half the median depth frame period ([`associate`]).
/// Returns the pairs as indices into the sorted lists.
pub(crate) fn pair_by_time<T, U>(
    depth: &mut [(f64, T)],
    color: &mut [(f64, U)],
) -> Vec<(usize, usize)> {
    depth.sort_by(|a, b| a.0.total_cmp(&b.0));
    color.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut steps: Vec<f64> = depth
        .windows(2)
        .map(|w| w[1].0 - w[0].0)
        .filter(|&s| s > 0.0)
        .collect();
    steps.sort_by(f64::total_cmp);
    let tolerance = steps
        .get(steps.len() / 2)
        .map_or(SINGLE_FRAME_TOLERANCE_NS, |s| s / 2.0);
    associate(depth, color, tolerance)
}

/// How the writer stores colour images.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ColorFormat {
    /// Lossless PNG (the default).
    #[default]
    Png,
    /// JPEG with a quality of 1..=100 (smaller, lossy; what the Kinect V2 itself delivers).
    Jpeg {
        /// JPEG quality, 1..=100.
        quality: u8,
    },
}

/// Writes a recording in the native layout, frame by frame. The frame list is flushed after
/// every frame, so a recording cut short is still readable up to its last complete frame.
pub struct RecordingWriter {
    dir: PathBuf,
    calibration: Calibration,
    color_format: ColorFormat,
    frames: BufWriter<File>,
    count: usize,
    last_timestamp_s: Option<f64>,
}

impl RecordingWriter {
    /// Create the directory structure (`color/`, `depth/`), the calibration and the frame list.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] for an invalid calibration or JPEG quality;
    /// [`KinectError::Io`] when files cannot be created; a directory that already holds a
    /// recording is not overwritten ([`KinectError::Io`] with kind `AlreadyExists`).
    pub fn create(
        dir: &Path,
        calibration: &Calibration,
        color_format: ColorFormat,
    ) -> Result<Self> {
        calibration.validate()?;
        if let ColorFormat::Jpeg { quality } = color_format
            && !(1..=100).contains(&quality)
        {
            return Err(KinectError::param(
                "JPEG quality",
                format!("{quality} is not in 1..=100"),
            ));
        }
        let frames_path = dir.join(FRAMES_FILE);
        if frames_path.exists() {
            return Err(KinectError::io(
                &frames_path,
                std::io::Error::new(
                    std::io::ErrorKind::AlreadyExists,
                    "a recording is already there",
                ),
            ));
        }
        for sub in ["color", "depth"] {
            let p = dir.join(sub);
            std::fs::create_dir_all(&p).map_err(|e| KinectError::io(&p, e))?;
        }
        calibration.write_json(&dir.join(CALIBRATION_FILE))?;
        let file = File::create(&frames_path).map_err(|e| KinectError::io(&frames_path, e))?;
        let mut frames = BufWriter::new(file);
        writeln!(frames, "{FRAMES_HEADER}").map_err(|e| KinectError::io(&frames_path, e))?;
        frames
            .flush()
            .map_err(|e| KinectError::io(&frames_path, e))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            calibration: calibration.clone(),
            color_format,
            frames,
            count: 0,
            last_timestamp_s: None,
        })
    }

    /// Append one frame; returns its index.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] for a timestamp that is not finite or not after the
    /// previous one, or a depth image in another unit than the calibration's;
    /// [`KinectError::SizeMismatch`] for images of the wrong size; I/O and codec errors.
    pub fn write_frame(
        &mut self,
        timestamp_s: f64,
        color: &RgbImage,
        depth: &DepthImage,
    ) -> Result<usize> {
        if !timestamp_s.is_finite() || self.last_timestamp_s.is_some_and(|t| timestamp_s <= t) {
            return Err(KinectError::param(
                "timestamp_s",
                format!(
                    "{timestamp_s} s must be finite and after the previous frame's {:?} s",
                    self.last_timestamp_s
                ),
            ));
        }
        if depth.unit_m() != self.calibration.depth_unit_m {
            return Err(KinectError::param(
                "depth unit",
                format!(
                    "{} m per unit, the calibration says {} m",
                    depth.unit_m(),
                    self.calibration.depth_unit_m
                ),
            ));
        }
        let cal = &self.calibration;
        cal.color_camera.check_image_size(
            "colour frame vs. the calibration",
            color.width(),
            color.height(),
        )?;
        cal.depth_camera.check_image_size(
            "depth frame vs. the calibration",
            depth.width(),
            depth.height(),
        )?;
        let index = self.count;
        let color_name = match self.color_format {
            ColorFormat::Png => format!("color/{index:06}.png"),
            ColorFormat::Jpeg { .. } => format!("color/{index:06}.jpg"),
        };
        let depth_name = format!("depth/{index:06}.png");
        let color_path = self.dir.join(&color_name);
        match self.color_format {
            ColorFormat::Png => color
                .save_with_format(&color_path, image::ImageFormat::Png)
                .map_err(|e| crate::depth::image_error(&color_path, e))?,
            ColorFormat::Jpeg { quality } => {
                let file =
                    File::create(&color_path).map_err(|e| KinectError::io(&color_path, e))?;
                let mut w = BufWriter::new(file);
                image::codecs::jpeg::JpegEncoder::new_with_quality(&mut w, quality)
                    .encode_image(color)
                    .map_err(|e| crate::depth::image_error(&color_path, e))?;
            }
        }
        write_depth_png(depth, &self.dir.join(&depth_name))?;
        let frames_path = self.dir.join(FRAMES_FILE);
        writeln!(
            self.frames,
            "{index},{timestamp_s},{color_name},{depth_name}"
        )
        .and_then(|()| self.frames.flush())
        .map_err(|e| KinectError::io(&frames_path, e))?;
        self.count += 1;
        self.last_timestamp_s = Some(timestamp_s);
        Ok(index)
    }

    /// Number of frames written.
    pub fn len(&self) -> usize {
        self.count
    }

    /// True when no frame was written yet.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn association_is_one_to_one_and_closest_first() {
        let depth = [(1.000, ()), (1.033, ()), (1.066, ())];
        let rgb = [(1.010, ()), (1.030, ()), (1.200, ())];
        let pairs = associate(&depth, &rgb, TUM_MAX_DIFFERENCE_S);
        // 1.033 takes 1.030 (0.003 s); 1.000 then takes 1.010; 1.066 has nothing within 0.02 s.
        assert_eq!(pairs, vec![(0, 0), (1, 1)]);
    }
}
