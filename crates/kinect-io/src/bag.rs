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
//! Orbbec SDK v2's recorder writes ROS 1 bags too: they are indexed here and their layout
//! (topics, profile and property messages) is read by `bag_orbbec.rs`.
//!
//! Not read: IMU, IR, pose streams, the bag's other options and metadata. A bag without an
//! index (a recording cut short) is refused: `rosbag reindex` repairs it.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use image::RgbImage;
use rosbag::{ChunkRecord, IndexRecord, MessageRecord, RosBag};

use crate::bag_chunk::check_chunk;
use crate::bag_msgs::{ImageMsg, Reader, parse_camera_info, parse_image, parse_transform};
use crate::bag_orbbec::{self, ColorCodec};
use crate::calibration::{Calibration, Extrinsics, RegistrationModel};
use crate::depth::decode_color_image;
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

/// An opened RealSense or Orbbec bag.
#[derive(Debug, Clone)]
pub(crate) struct BagRecording {
    frames: Vec<(MsgRef, MsgRef)>,
    times_ns: Vec<(u64, u64)>,
    unpaired_depth: usize,
    calibration: Calibration,
    flavour: Flavour,
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

/// Which recorder's layout a bag has, with what that layout needs to read its frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Flavour {
    /// librealsense's recorder, or a ROS driver's aligned depth (`aligned`).
    RealSense { aligned: bool },
    /// Orbbec SDK v2's recorder; colour decoded as its profile says (by the image's
    /// encoding name when the profile is missing).
    Orbbec(Option<ColorCodec>),
}

/// The image connections of a bag and the connections whose messages its calibration needs.
struct BagLayout {
    flavour: Flavour,
    images: (u32, u32),
    depth: Stream,
    color: Stream,
    units: Option<u32>,
    orbbec: Option<bag_orbbec::Topics>,
}

/// Find the layout among a bag's `(id, topic, type)` connections.
fn find_layout(path: &Path, connections: &[(u32, String, String)]) -> Result<BagLayout> {
    let mut depth = Stream::default();
    let mut color = Stream::default();
    let mut units = None;
    for (id, topic, _) in connections {
        if topic.ends_with("/option/Depth Units/value") {
            units = Some(*id);
        }
        if let Some((kind, what)) = classify(topic) {
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
            slot.get_or_insert(*id);
        }
    }
    if let (Some(d), Some(c)) = (depth.image, color.image) {
        return Ok(BagLayout {
            flavour: Flavour::RealSense { aligned: false },
            images: (d, c),
            depth,
            color,
            units,
            orbbec: None,
        });
    }
    if let Some(t) = bag_orbbec::topics(connections) {
        return Ok(BagLayout {
            flavour: Flavour::Orbbec(None),
            images: (t.depth_image, t.color_image),
            depth,
            color,
            units,
            orbbec: Some(t),
        });
    }
    // Not a recorder's own layout: a ROS driver's aligned depth (realsense-ros and others).
    let found = aligned_topics(connections).ok_or_else(|| {
        KinectError::format(
            path,
            format!(
                "no RealSense depth and colour image topics (/device_0/sensor_N/Depth_0/image/\
                 data, .../Color_0/image/data), no Orbbec SDK v2 ones ({}, {}) and no ROS \
                 driver's .../aligned_depth_to_color/image_raw with its colour image and \
                 camera_info; topics: {:?}",
                bag_orbbec::DEPTH_TOPIC,
                bag_orbbec::COLOR_TOPIC,
                connections.iter().map(|c| &c.1).collect::<Vec<_>>()
            ),
        )
    })?;
    color.info = Some(found.2);
    Ok(BagLayout {
        flavour: Flavour::RealSense { aligned: true },
        images: (found.0, found.1),
        depth,
        color,
        units,
        orbbec: None,
    })
}

impl BagRecording {
    /// Index a bag: its connections, calibration messages (unless a calibration is
    /// `given`) and where each image message is.
    pub fn open(path: &Path, given: Option<Calibration>) -> Result<Self> {
        check_bag_header(path)?;
        let bag = RosBag::new(path).map_err(|e| KinectError::io(path, e))?;
        let rosbag_error = |e: rosbag::Error| KinectError::format(path, format!("ROS bag: {e}"));
        let mut connections = Vec::new();
        let mut chunks = Vec::new();
        for record in bag.index_records() {
            match record.map_err(rosbag_error)? {
                IndexRecord::Connection(c) => {
                    connections.push((c.id, c.topic.to_owned(), c.tp.to_owned()));
                }
                IndexRecord::ChunkInfo(info) => chunks.push(info.chunk_pos),
                IndexRecord::IndexData(_) => {}
            }
        }
        let mut layout = find_layout(path, &connections)?;
        chunks.sort_unstable();
        let (depth, color) = (&layout.depth, &layout.color);
        let orbbec = layout.orbbec;
        let wanted = [
            depth.info,
            color.info,
            depth.tf,
            color.tf,
            layout.units,
            orbbec.and_then(|t| t.depth_profile),
            orbbec.and_then(|t| t.color_profile),
        ];
        let every = orbbec.and_then(|t| t.property);
        let scan = scan_chunks(&bag, path, &chunks, layout.images, &wanted, every)?;
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
        let calibration = match (layout.flavour, orbbec) {
            (Flavour::Orbbec(_), Some(t)) => {
                let message = |id: Option<u32>| id.and_then(|id| small.get(&id)).map(Vec::as_slice);
                let decoded = bag_orbbec::decode(
                    path,
                    message(t.depth_profile),
                    message(t.color_profile),
                    &scan.every,
                    given,
                )?;
                layout.flavour = Flavour::Orbbec(decoded.color);
                decoded.calibration
            }
            _ => match given {
                Some(c) => c,
                None if layout.flavour == (Flavour::RealSense { aligned: true }) => {
                    aligned_calibration(path, &small, color.info)?
                }
                None => bag_calibration(path, &small, depth, color, layout.units)?,
            },
        };
        Ok(Self {
            frames,
            times_ns,
            unpaired_depth: depth_msgs.len() - pairs.len(),
            calibration,
            flavour: layout.flavour,
        })
    }

    /// Which recorder's layout the bag has.
    pub fn flavour(&self) -> Flavour {
        self.flavour
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
            self.decode_color(&parse_image(bytes, &color_label)?, &color_label)
        })?;
        let depth = with_message(&bag, path, d, &depth_label, |bytes| {
            let m = parse_image(bytes, &depth_label)?;
            self.decode_depth(&m, &depth_label, depth_unit_m)
        })?;
        Ok((color, depth))
    }
}

impl BagRecording {
    /// A colour image: by its encoding name (RealSense, ROS), or as the Orbbec profile says.
    fn decode_color(&self, m: &ImageMsg<'_>, label: &Path) -> Result<RgbImage> {
        let codec = match self.flavour {
            Flavour::RealSense { .. } => color_layout(m.encoding).map(ColorCodec::Raw),
            Flavour::Orbbec(Some(codec)) => Some(codec),
            Flavour::Orbbec(None) => bag_orbbec::color_codec_by_encoding(m.encoding),
        };
        match codec {
            Some(ColorCodec::Raw(layout)) => to_rgb(
                layout,
                m.width,
                m.height,
                // A step of 0 (not ROS's rule, but written by some recorders): packed rows.
                (m.step > 0).then_some(m.step as usize),
                m.data,
                label,
            ),
            Some(ColorCodec::Jpeg) => {
                let image = decode_color_image(m.data, label)?;
                if image.dimensions() != (m.width, m.height) {
                    return Err(KinectError::format(
                        label,
                        format!(
                            "the JPEG is {:?} px, the message says {}x{}",
                            image.dimensions(),
                            m.width,
                            m.height
                        ),
                    ));
                }
                Ok(image)
            }
            None => Err(KinectError::Unsupported {
                path: label.to_path_buf(),
                what: format!("colour encoding {:?}", m.encoding),
            }),
        }
    }

    /// A 16-bit depth image. RealSense and ROS name it `16UC1`/`mono16`; an Orbbec depth
    /// stream's format was checked against its profile at open, and its rows must hold
    /// 2 bytes per pixel.
    fn decode_depth(
        &self,
        m: &ImageMsg<'_>,
        label: &Path,
        depth_unit_m: f64,
    ) -> Result<DepthImage> {
        let named = matches!(m.encoding.to_ascii_lowercase().as_str(), "16uc1" | "mono16");
        if !named && matches!(self.flavour, Flavour::RealSense { .. }) {
            return Err(KinectError::Unsupported {
                path: label.to_path_buf(),
                what: format!("depth encoding {:?} (16UC1 or mono16 are read)", m.encoding),
            });
        }
        let (w, h) = (m.width as usize, m.height as usize);
        // A step of 0 (not ROS's rule, but written by some recorders): packed rows.
        let step = if m.step == 0 { 2 * w } else { m.step as usize };
        let rows_fit = step >= 2 * w && h.checked_mul(step) == Some(m.data.len());
        if !rows_fit {
            return Err(KinectError::format(
                label,
                format!(
                    "{}x{} px with a {step}-byte step does not fit {} bytes (16-bit depth)",
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
    }
}

/// The pixel layout of a colour image's ROS encoding. ROS names UYVY `yuv422` and YUYV
/// `yuv422_yuy2`; librealsense writes its UYVY as `yuv422` and its YUYV as `YUYV` (the
/// format's own name), so names are compared without case.
pub(crate) fn color_layout(encoding: &str) -> Option<RawColor> {
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
/// as `f64` for pairing, where, time in ns), the first message of each wanted connection and
/// every message of one more (Orbbec's properties).
struct Scan {
    depth: Vec<(f64, (MsgRef, u64))>,
    color: Vec<(f64, (MsgRef, u64))>,
    small: HashMap<u32, Vec<u8>>,
    every: Vec<Vec<u8>>,
}

/// Most messages kept from the connection read in full (Orbbec's recorder writes a few dozen
/// properties, each a few bytes to a few KiB).
const MAX_EVERY_MESSAGES: usize = 10_000;

fn scan_chunks(
    bag: &RosBag,
    path: &Path,
    chunks: &[u64],
    (depth_image, color_image): (u32, u32),
    wanted: &[Option<u32>],
    every: Option<u32>,
) -> Result<Scan> {
    let rosbag_error = |e: rosbag::Error| KinectError::format(path, format!("ROS bag: {e}"));
    let mut scan = Scan {
        depth: Vec::new(),
        color: Vec::new(),
        small: HashMap::new(),
        every: Vec::new(),
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
            } else if every == Some(m.conn_id) {
                if scan.every.len() >= MAX_EVERY_MESSAGES {
                    return Err(KinectError::format(
                        path,
                        format!("more than {MAX_EVERY_MESSAGES} property messages"),
                    ));
                }
                scan.every.push(m.data.to_vec());
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

    fn orbbec() -> BagRecording {
        BagRecording {
            frames: Vec::new(),
            times_ns: Vec::new(),
            unpaired_depth: 0,
            calibration: Calibration::tum_default(),
            flavour: Flavour::Orbbec(Some(ColorCodec::Raw(RawColor::Rgb8))),
        }
    }

    fn message<'a>(encoding: &'a str, step: u32, data: &'a [u8]) -> ImageMsg<'a> {
        ImageMsg {
            stamp_ns: 0,
            height: 2,
            width: 3,
            encoding,
            big_endian: false,
            step,
            data,
        }
    }

    #[test]
    fn images_with_a_zero_step_are_packed_rows() {
        let label = Path::new("x.bag");
        let depth: Vec<u8> = (1..=6u16).flat_map(u16::to_le_bytes).collect();
        let d = orbbec()
            .decode_depth(&message("Z16", 0, &depth), label, 0.001)
            .expect("packed depth");
        assert_eq!(d.values(), &[1, 2, 3, 4, 5, 6]);
        let rgb: Vec<u8> = (0..18).collect();
        let c = orbbec()
            .decode_color(&message("RGB", 0, &rgb), label)
            .expect("packed colour");
        assert_eq!(c.as_raw(), &rgb);
        // Padded rows are still read by their step; a step that does not fit is an error.
        let padded: Vec<u8> = [&depth[..6], &[9, 9], &depth[6..], &[9, 9]].concat();
        let d = orbbec()
            .decode_depth(&message("Z16", 8, &padded), label, 0.001)
            .expect("padded depth");
        assert_eq!(d.values(), &[1, 2, 3, 4, 5, 6]);
        assert!(
            orbbec()
                .decode_depth(&message("Z16", 4, &depth), label, 0.001)
                .is_err()
        );
    }

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
