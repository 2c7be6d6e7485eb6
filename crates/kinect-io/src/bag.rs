//! Intel RealSense recordings: ROS 1 bags (`.bag`, chunks uncompressed, lz4 or bz2) in the
//! layout librealsense's recorder writes, read lazily with the `rosbag` crate.
//!
//! What is read (the RealSense SDK's "ROS-bag file format"):
//! - depth and colour `sensor_msgs/Image` on `/device_0/sensor_N/Depth_0/image/data` and
//!   `/device_0/sensor_N/Color_0/image/data` (depth `16UC1`/`mono16`; colour `rgb8`, `bgr8`,
//!   `rgba8`, `bgra8`, `yuv422`/`uyvy` or `yuv422_yuy2`/`yuyv`); time from the image header;
//! - intrinsics from each stream's `info/camera_info` (`sensor_msgs/CameraInfo`: `K`, and `D`
//!   for the models "Brown Conrady" / `plumb_bob`; other models only with zero coefficients);
//! - each stream's `tf/0` (`geometry_msgs/Transform`, the stream's pose in the device's
//!   reference stream): depth-to-colour = colour⁻¹ · depth;
//! - the depth unit from `/device_0/sensor_N/option/Depth Units/value` (`std_msgs/Float32`;
//!   0.001 m when absent, the SDK's default);
//! - colour and depth paired by time within half the depth frame period.
//!
//! A bag recorded from a ROS driver instead (`realsense-ros` and others: `rosbag record` of
//! `.../aligned_depth_to_color/image_raw`, `.../color/image_raw` and the colour
//! `camera_info`) is read as depth already registered to colour, in millimetres.
//!
//! Not read: IMU, IR, pose streams, the bag's other options and metadata. A bag without an
//! index (a recording cut short) is refused: `rosbag reindex` repairs it.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use image::RgbImage;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use rosbag::{ChunkRecord, IndexRecord, MessageRecord, RosBag};

use crate::bag_chunk::check_chunk;
use crate::calibration::{Calibration, Extrinsics, RegistrationModel};
use crate::camera::{CameraModel, Distortion};
use crate::depth::{DEPTH_UNIT_MM_M, DepthImage};
use crate::error::{KinectError, Result};
use crate::pixels::{RawColor, to_rgb};
use crate::recording::{Container, frame_at, pair_by_time};

/// Most images indexed per topic: 24 hours at 60 fps is 5.2 million (40 bytes each).
const MAX_IMAGES: usize = 10_000_000;
/// The first bytes of a ROS 1 bag (format version 2.0).
const BAG_MAGIC: &[u8] = b"#ROSBAG V2.0\n";
/// Largest bag header record read to check the index position (the format pads it to 4 KiB).
const MAX_BAG_HEADER_BYTES: usize = 1 << 16;

/// Where one image message is: its chunk's file position and its place among the chunk's
/// records.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct MsgRef {
    chunk_pos: u64,
    record: usize,
}

/// An opened RealSense bag.
#[derive(Debug, Clone)]
pub(crate) struct BagRecording {
    frames: Vec<(MsgRef, MsgRef)>,
    times_ns: Vec<(u64, u64)>,
    unpaired_depth: usize,
    calibration: Calibration,
}

/// True when the file starts with the ROS bag 2.0 magic line.
pub(crate) fn is_rosbag(path: &Path) -> bool {
    let mut magic = [0u8; 13];
    std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic))
        .is_ok()
        && magic == BAG_MAGIC
}

/// Read the bag header record ourselves and check its index position, so that the `rosbag`
/// crate (which slices its memory map by it) is only handed a bag whose index is there.
fn check_bag_header(path: &Path) -> Result<()> {
    let bad = |what: String| KinectError::format(path, what);
    let len = std::fs::metadata(path)
        .map_err(|e| KinectError::io(path, e))?
        .len();
    let mut head = vec![0u8; MAX_BAG_HEADER_BYTES.min(usize::try_from(len).unwrap_or(0))];
    std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
        .map_err(|e| KinectError::io(path, e))?;
    let mut r = Reader::new(&head, path);
    if r.bytes(BAG_MAGIC.len())? != BAG_MAGIC {
        return Err(bad("not a ROS bag 2.0 (no #ROSBAG V2.0 line)".into()));
    }
    let header_len = r.u32()? as usize;
    let header = r.bytes(header_len)?;
    let data_len = u64::from(r.u32()?);
    let start = r.pos as u64 + data_len;
    let mut fields = Reader::new(header, path);
    let mut index_pos = None;
    while fields.left() > 0 {
        let n = fields.u32()? as usize;
        let field = fields.bytes(n)?;
        if let Some(v) = field.strip_prefix(b"index_pos=") {
            let v: [u8; 8] = v
                .try_into()
                .map_err(|_| bad("bag header: index_pos is not 8 bytes".into()))?;
            index_pos = Some(u64::from_le_bytes(v));
        }
    }
    match index_pos {
        None => Err(bad("bag header has no index_pos".into())),
        Some(0) => Err(bad(
            "the bag has no index (a recording cut short?); `rosbag reindex` repairs it".into(),
        )),
        Some(p) if p < start || p > len => Err(bad(format!(
            "the bag's index is at byte {p}, outside its {len} bytes (truncated? `rosbag \
             reindex` repairs it)"
        ))),
        Some(_) => Ok(()),
    }
}

/// Little-endian ROS 1 serialisation, every read bounds-checked.
struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
    path: &'a Path,
}

impl<'a> Reader<'a> {
    fn new(data: &'a [u8], path: &'a Path) -> Self {
        Self { data, pos: 0, path }
    }

    fn left(&self) -> usize {
        self.data.len() - self.pos
    }

    fn bytes(&mut self, n: usize) -> Result<&'a [u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.data.len());
        let Some(end) = end else {
            return Err(KinectError::format(
                self.path,
                format!(
                    "a message is cut off: {n} bytes asked for at byte {} of {}",
                    self.pos,
                    self.data.len()
                ),
            ));
        };
        let out = &self.data[self.pos..end];
        self.pos = end;
        Ok(out)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N]> {
        let b = self.bytes(N)?;
        let mut out = [0u8; N];
        out.copy_from_slice(b);
        Ok(out)
    }

    fn u8(&mut self) -> Result<u8> {
        Ok(self.array::<1>()?[0])
    }

    fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_le_bytes(self.array()?))
    }

    fn f32(&mut self) -> Result<f32> {
        Ok(f32::from_le_bytes(self.array()?))
    }

    fn string(&mut self) -> Result<&'a str> {
        let n = self.u32()? as usize;
        let b = self.bytes(n)?;
        std::str::from_utf8(b)
            .map_err(|_| KinectError::format(self.path, "a message string is not UTF-8"))
    }

    fn f64s(&mut self, n: usize) -> Result<Vec<f64>> {
        (0..n).map(|_| self.f64()).collect()
    }

    /// `std_msgs/Header`: the stamp in nanoseconds.
    fn header(&mut self) -> Result<u64> {
        let _seq = self.u32()?;
        let sec = u64::from(self.u32()?);
        let nsec = u64::from(self.u32()?);
        let _frame = self.string()?;
        Ok(sec * 1_000_000_000 + nsec)
    }
}

/// A `sensor_msgs/Image`, borrowed.
struct ImageMsg<'a> {
    stamp_ns: u64,
    height: u32,
    width: u32,
    encoding: &'a str,
    big_endian: bool,
    step: u32,
    data: &'a [u8],
}

fn parse_image<'a>(bytes: &'a [u8], path: &'a Path) -> Result<ImageMsg<'a>> {
    let mut r = Reader::new(bytes, path);
    let stamp_ns = r.header()?;
    let height = r.u32()?;
    let width = r.u32()?;
    let encoding = r.string()?;
    let big_endian = r.u8()? != 0;
    let step = r.u32()?;
    let n = r.u32()? as usize;
    let data = r.bytes(n)?;
    Ok(ImageMsg {
        stamp_ns,
        height,
        width,
        encoding,
        big_endian,
        step,
        data,
    })
}

/// A `sensor_msgs/CameraInfo` as a camera model.
fn parse_camera_info(bytes: &[u8], path: &Path, what: &str) -> Result<CameraModel> {
    let bad = |w: String| KinectError::calibration(path, format!("{what} camera_info: {w}"));
    let mut r = Reader::new(bytes, path);
    r.header()?;
    let height = r.u32()?;
    let width = r.u32()?;
    let model = r.string()?.to_owned();
    let n = r.u32()? as usize;
    if n > r.left() / 8 {
        return Err(bad(format!(
            "{n} distortion coefficients in a short message"
        )));
    }
    let d = r.f64s(n)?;
    let k = r.f64s(9)?;
    let known = matches!(
        model.as_str(),
        "Brown Conrady" | "plumb_bob" | "rational_polynomial"
    );
    if !known && d.iter().any(|&c| c != 0.0) {
        return Err(KinectError::Unsupported {
            path: path.to_path_buf(),
            what: format!(
                "{what} camera_info: distortion model {model:?} with coefficients {d:?} (only \
                 Brown–Conrady / plumb_bob / rational_polynomial, or zero coefficients)"
            ),
        });
    }
    let distortion = if d.iter().all(|&c| c == 0.0) {
        Distortion::default()
    } else {
        let take = d.len().min(8);
        let list = if take > 5 && take < 8 {
            &d[..5]
        } else {
            &d[..take]
        };
        Distortion::from_opencv(list).map_err(|e| bad(e.to_string()))?
    };
    let camera = CameraModel {
        width,
        height,
        fx: k[0],
        fy: k[4],
        cx: k[2],
        cy: k[5],
        distortion,
    };
    camera.validate().map_err(|e| bad(e.to_string()))?;
    Ok(camera)
}

/// A `geometry_msgs/Transform` as an isometry.
fn parse_transform(bytes: &[u8], path: &Path, what: &str) -> Result<Isometry3<f64>> {
    let mut r = Reader::new(bytes, path);
    let v = r.f64s(7)?;
    let q = Quaternion::new(v[6], v[3], v[4], v[5]);
    let norm = q.norm();
    if !(v.iter().all(|x| x.is_finite()) && (norm - 1.0).abs() < 1e-3) {
        return Err(KinectError::calibration(
            path,
            format!("{what} tf: not a rigid transform: {v:?}"),
        ));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        UnitQuaternion::from_quaternion(q),
    ))
}

/// The topics of one RealSense stream (`Depth_0`, `Color_0`) in the bag.
#[derive(Debug, Default)]
struct Stream {
    image: Option<u32>,
    info: Option<u32>,
    tf: Option<u32>,
}

/// The camera stream a topic belongs to, and which of its topics it is.
fn classify(topic: &str) -> Option<(&'static str, &'static str)> {
    let mut parts = topic.trim_start_matches('/').split('/');
    let (device, sensor, stream) = (parts.next()?, parts.next()?, parts.next()?);
    if !device.starts_with("device_") || !sensor.starts_with("sensor_") {
        return None;
    }
    let kind = match stream {
        "Depth_0" => "depth",
        "Color_0" => "color",
        _ => return None,
    };
    let rest: Vec<&str> = parts.collect();
    let what = match rest.as_slice() {
        ["image", "data"] => "image",
        ["info", "camera_info"] => "info",
        ["tf", "0"] => "tf",
        _ => return None,
    };
    Some((kind, what))
}

impl BagRecording {
    /// Index a bag: its connections, calibration messages (unless a calibration is
    /// `given`) and where each image message is.
    pub fn open(path: &Path, given: Option<Calibration>) -> Result<Self> {
        check_bag_header(path)?;
        let bag = RosBag::new(path).map_err(|e| KinectError::io(path, e))?;
        let rosbag_error = |e: rosbag::Error| KinectError::format(path, format!("ROS bag: {e}"));
        let mut depth = Stream::default();
        let mut color = Stream::default();
        let mut units = None;
        let mut connections = Vec::new();
        let mut chunks = Vec::new();
        for record in bag.index_records() {
            match record.map_err(rosbag_error)? {
                IndexRecord::Connection(c) => {
                    connections.push((c.id, c.topic.to_owned(), c.tp.to_owned()));
                    if c.topic.ends_with("/option/Depth Units/value") {
                        units = Some(c.id);
                    }
                    if let Some((kind, what)) = classify(c.topic) {
                        let s = if kind == "depth" {
                            &mut depth
                        } else {
                            &mut color
                        };
                        let slot = match what {
                            "image" => &mut s.image,
                            "info" => &mut s.info,
                            _ => &mut s.tf,
                        };
                        slot.get_or_insert(c.id);
                    }
                }
                IndexRecord::ChunkInfo(info) => chunks.push(info.chunk_pos),
                IndexRecord::IndexData(_) => {}
            }
        }
        // Not the SDK's own layout: a ROS driver's aligned depth (realsense-ros and others).
        let aligned = if depth.image.is_none() || color.image.is_none() {
            let found = aligned_topics(&connections).ok_or_else(|| {
                KinectError::format(
                    path,
                    format!(
                        "no RealSense depth and colour image topics \
                         (/device_0/sensor_N/Depth_0/image/data, .../Color_0/image/data) and \
                         no ROS driver's .../aligned_depth_to_color/image_raw with its colour \
                         image and camera_info; topics: {:?}",
                        connections.iter().map(|c| &c.1).collect::<Vec<_>>()
                    ),
                )
            })?;
            depth.image = Some(found.0);
            color.image = Some(found.1);
            color.info = Some(found.2);
            true
        } else {
            false
        };
        let (Some(depth_image), Some(color_image)) = (depth.image, color.image) else {
            return Err(KinectError::format(
                path,
                "no depth or colour topic (internal)",
            ));
        };
        chunks.sort_unstable();
        let wanted = [depth.info, color.info, depth.tf, color.tf, units];
        let scan = scan_chunks(&bag, path, &chunks, (depth_image, color_image), &wanted)?;
        let (mut depth_msgs, mut color_msgs, small) = (scan.depth, scan.color, scan.small);
        let pairs = pair_by_time(&mut depth_msgs, &mut color_msgs);
        if pairs.is_empty() {
            return Err(KinectError::format(
                path,
                format!(
                    "no frame with both colour and depth ({} depth and {} colour images)",
                    depth_msgs.len(),
                    color_msgs.len()
                ),
            ));
        }
        let frames = pairs
            .iter()
            .map(|&(d, c)| (depth_msgs[d].1.0, color_msgs[c].1.0))
            .collect();
        let times_ns = pairs
            .iter()
            .map(|&(d, c)| (depth_msgs[d].1.1, color_msgs[c].1.1))
            .collect();
        let calibration = match given {
            Some(c) => c,
            None if aligned => aligned_calibration(path, &small, color.info)?,
            None => bag_calibration(path, &small, &depth, &color, units)?,
        };
        Ok(Self {
            frames,
            times_ns,
            unpaired_depth: depth_msgs.len() - pairs.len(),
            calibration,
        })
    }
}

impl Container for BagRecording {
    fn calibration(&self) -> &Calibration {
        &self.calibration
    }

    fn unpaired_depth(&self) -> usize {
        self.unpaired_depth
    }

    fn times_s(&self) -> Vec<(f64, f64)> {
        self.times_ns
            .iter()
            .map(|&(d, c)| (d as f64 * 1e-9, c as f64 * 1e-9))
            .collect()
    }

    /// Read and decode frame `i` (depth in `depth_unit_m` units).
    fn read(&self, path: &Path, i: usize, depth_unit_m: f64) -> Result<(RgbImage, DepthImage)> {
        let (d, c) = frame_at(&self.frames, path, i)?;
        let bag = RosBag::new(path).map_err(|e| KinectError::io(path, e))?;
        let label = |what: &str| PathBuf::from(format!("{} ({what} of frame {i})", path.display()));
        let (color_label, depth_label) = (label("colour"), label("depth"));
        let color = with_message(&bag, path, c, &color_label, |bytes| {
            let m = parse_image(bytes, &color_label)?;
            let layout = color_layout(m.encoding).ok_or_else(|| KinectError::Unsupported {
                path: color_label.clone(),
                what: format!("colour encoding {:?}", m.encoding),
            })?;
            to_rgb(
                layout,
                m.width,
                m.height,
                Some(m.step as usize),
                m.data,
                &color_label,
            )
        })?;
        let depth = with_message(&bag, path, d, &depth_label, |bytes| {
            let m = parse_image(bytes, &depth_label)?;
            if !matches!(m.encoding.to_ascii_lowercase().as_str(), "16uc1" | "mono16") {
                return Err(KinectError::Unsupported {
                    path: depth_label.clone(),
                    what: format!("depth encoding {:?} (16UC1 or mono16 are read)", m.encoding),
                });
            }
            let (w, h) = (m.width as usize, m.height as usize);
            let step = m.step as usize;
            let rows_fit = step >= 2 * w && h.checked_mul(step) == Some(m.data.len());
            if !rows_fit {
                return Err(KinectError::format(
                    &depth_label,
                    format!(
                        "{}x{} px with a {step}-byte step does not fit {} bytes",
                        m.width,
                        m.height,
                        m.data.len()
                    ),
                ));
            }
            let mut values = Vec::with_capacity(w * h);
            for row in m.data.chunks_exact(step) {
                values.extend(row[..2 * w].chunks_exact(2).map(|p| {
                    if m.big_endian {
                        u16::from_be_bytes([p[0], p[1]])
                    } else {
                        u16::from_le_bytes([p[0], p[1]])
                    }
                }));
            }
            DepthImage::new(m.width, m.height, depth_unit_m, values)
        })?;
        Ok((color, depth))
    }
}

/// The pixel layout of a colour image's ROS encoding. ROS names UYVY `yuv422` and YUYV
/// `yuv422_yuy2`; librealsense writes its UYVY as `yuv422` and its YUYV as `YUYV` (the
/// format's own name), so names are compared without case.
fn color_layout(encoding: &str) -> Option<RawColor> {
    Some(match encoding.to_ascii_lowercase().as_str() {
        "rgb8" => RawColor::Rgb8,
        "bgr8" => RawColor::Bgr8,
        "rgba8" => RawColor::Rgba8,
        "bgra8" => RawColor::Bgra8,
        "yuv422" | "uyvy" => RawColor::Uyvy,
        "yuv422_yuy2" | "yuyv" | "yuy2" => RawColor::Yuy2,
        _ => return None,
    })
}

/// Run `f` on the bytes of the message at `at`.
fn with_message<T>(
    bag: &RosBag,
    path: &Path,
    at: MsgRef,
    label: &Path,
    f: impl FnOnce(&[u8]) -> Result<T>,
) -> Result<T> {
    let bad = |what: String| KinectError::format(label, what);
    check_chunk(path, at.chunk_pos)?;
    let mut iter = bag.chunk_records();
    iter.seek(at.chunk_pos)
        .map_err(|e| bad(format!("ROS bag: {e}")))?;
    let Some(Ok(ChunkRecord::Chunk(chunk))) = iter.next() else {
        return Err(bad(format!("no chunk at byte {} any more", at.chunk_pos)));
    };
    match chunk.messages().nth(at.record) {
        Some(Ok(MessageRecord::MessageData(m))) => f(m.data),
        _ => Err(bad(format!(
            "record {} of the chunk at byte {} is no longer a message",
            at.record, at.chunk_pos
        ))),
    }
}

/// What one pass over a bag's chunks finds: the depth and colour image messages (time in ns
/// as `f64` for pairing, where, time in ns) and the first message of each wanted connection.
struct Scan {
    depth: Vec<(f64, (MsgRef, u64))>,
    color: Vec<(f64, (MsgRef, u64))>,
    small: HashMap<u32, Vec<u8>>,
}

fn scan_chunks(
    bag: &RosBag,
    path: &Path,
    chunks: &[u64],
    (depth_image, color_image): (u32, u32),
    wanted: &[Option<u32>],
) -> Result<Scan> {
    let rosbag_error = |e: rosbag::Error| KinectError::format(path, format!("ROS bag: {e}"));
    let mut scan = Scan {
        depth: Vec::new(),
        color: Vec::new(),
        small: HashMap::new(),
    };
    let mut iter = bag.chunk_records();
    for &chunk_pos in chunks {
        check_chunk(path, chunk_pos)?;
        iter.seek(chunk_pos).map_err(rosbag_error)?;
        let Some(Ok(ChunkRecord::Chunk(chunk))) = iter.next() else {
            return Err(KinectError::format(
                path,
                format!("the index names a chunk at byte {chunk_pos} that is not one"),
            ));
        };
        for (record, msg) in chunk.messages().enumerate() {
            let MessageRecord::MessageData(m) = msg.map_err(rosbag_error)? else {
                continue;
            };
            let at = MsgRef { chunk_pos, record };
            if m.conn_id == depth_image || m.conn_id == color_image {
                let image = parse_image(m.data, path)?;
                let t = if image.stamp_ns > 0 {
                    image.stamp_ns
                } else {
                    m.time
                };
                let list = if m.conn_id == depth_image {
                    &mut scan.depth
                } else {
                    &mut scan.color
                };
                if list.len() >= MAX_IMAGES {
                    return Err(KinectError::format(
                        path,
                        format!(
                            "more than {MAX_IMAGES} images on one topic: not read (split the bag)"
                        ),
                    ));
                }
                list.push((t as f64, (at, t)));
            } else if wanted.contains(&Some(m.conn_id)) {
                scan.small
                    .entry(m.conn_id)
                    .or_insert_with(|| m.data.to_vec());
            }
        }
    }
    Ok(scan)
}

/// A ROS driver's aligned-depth topics: `(depth image, colour image, colour camera_info)`.
/// The depth topic is the `sensor_msgs/Image` whose name holds `aligned_depth_to_color` and
/// ends in `image_raw`; the colour image is the one image topic under a `color` namespace
/// ending in `image_raw` or `image_rect_color`; its `camera_info` is its sibling.
fn aligned_topics(connections: &[(u32, String, String)]) -> Option<(u32, u32, u32)> {
    let images = || connections.iter().filter(|c| c.2 == "sensor_msgs/Image");
    let depth =
        images().find(|c| c.1.contains("aligned_depth_to_color") && c.1.ends_with("/image_raw"))?;
    let color = images().find(|c| {
        c.1.contains("/color/")
            && !c.1.contains("aligned_depth")
            && (c.1.ends_with("/image_raw") || c.1.ends_with("/image_rect_color"))
    })?;
    let parent = &color.1[..color.1.rfind('/')?];
    let info = connections
        .iter()
        .find(|c| c.1 == format!("{parent}/camera_info") && c.2 == "sensor_msgs/CameraInfo")?;
    Some((depth.0, color.0, info.0))
}

/// The calibration of aligned depth: both images in the colour camera, depth in millimetres
/// (ROS REP 118: `16UC1` depth images are millimetres).
fn aligned_calibration(
    path: &Path,
    small: &HashMap<u32, Vec<u8>>,
    color_info: Option<u32>,
) -> Result<Calibration> {
    let info = color_info.and_then(|id| small.get(&id)).ok_or_else(|| {
        KinectError::calibration(path, "no colour camera_info message in the bag")
    })?;
    let camera = parse_camera_info(info, path, "colour")?;
    let calibration = Calibration {
        depth_camera: camera,
        color_camera: camera,
        registration: RegistrationModel::AlreadyRegistered,
        depth_unit_m: DEPTH_UNIT_MM_M,
        depth_offset_m: 0.0,
    };
    calibration
        .validate()
        .map_err(|e| KinectError::calibration(path, e.to_string()))?;
    Ok(calibration)
}

/// The calibration a RealSense bag records.
fn bag_calibration(
    path: &Path,
    small: &HashMap<u32, Vec<u8>>,
    depth: &Stream,
    color: &Stream,
    units: Option<u32>,
) -> Result<Calibration> {
    let message = |id: Option<u32>, what: &str| -> Result<&Vec<u8>> {
        id.and_then(|id| small.get(&id))
            .ok_or_else(|| KinectError::calibration(path, format!("no {what} message in the bag")))
    };
    let depth_camera = parse_camera_info(message(depth.info, "depth camera_info")?, path, "depth")?;
    let color_camera =
        parse_camera_info(message(color.info, "colour camera_info")?, path, "colour")?;
    let depth_pose = parse_transform(message(depth.tf, "depth tf/0")?, path, "depth")?;
    let color_pose = parse_transform(message(color.tf, "colour tf/0")?, path, "colour")?;
    let depth_unit_m = match units.and_then(|id| small.get(&id)) {
        None => DEPTH_UNIT_MM_M,
        Some(bytes) => {
            let v = Reader::new(bytes, path).f32()?;
            // The SDK stores the unit as a 32-bit float: read back its shortest decimal
            // (0.00025 rather than 0.000250000011874).
            v.to_string().parse::<f64>().unwrap_or(f64::from(v))
        }
    };
    let calibration = Calibration {
        depth_camera,
        color_camera,
        registration: RegistrationModel::Rigid(Extrinsics::from_isometry(
            &(color_pose.inverse() * depth_pose),
        )),
        depth_unit_m,
        depth_offset_m: 0.0,
    };
    calibration
        .validate()
        .map_err(|e| KinectError::calibration(path, e.to_string()))?;
    Ok(calibration)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn realsense_topics_are_classified() {
        assert_eq!(
            classify("/device_0/sensor_0/Depth_0/image/data"),
            Some(("depth", "image"))
        );
        assert_eq!(
            classify("/device_0/sensor_1/Color_0/info/camera_info"),
            Some(("color", "info"))
        );
        assert_eq!(
            classify("/device_0/sensor_1/Color_0/tf/0"),
            Some(("color", "tf"))
        );
        assert_eq!(classify("/device_0/sensor_0/Infrared_1/image/data"), None);
        assert_eq!(classify("/camera/depth/image_raw"), None);
    }

    #[test]
    fn ros_and_librealsense_colour_encodings() {
        assert_eq!(color_layout("rgb8"), Some(RawColor::Rgb8));
        assert_eq!(color_layout("yuv422"), Some(RawColor::Uyvy));
        assert_eq!(color_layout("YUYV"), Some(RawColor::Yuy2));
        assert_eq!(color_layout("yuv422_yuy2"), Some(RawColor::Yuy2));
        assert_eq!(color_layout("bayer_rggb8"), None);
    }
}
