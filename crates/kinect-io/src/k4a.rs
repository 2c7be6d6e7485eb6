//! Azure Kinect and Orbbec Femto recordings: the Matroska layout `k4arecorder` (and Orbbec's
//! K4A wrapper) writes, read lazily.
//!
//! What is read (Microsoft's "Azure Kinect recording file format"):
//! - tracks found by their tags `K4A_COLOR_TRACK` / `K4A_DEPTH_TRACK` (the tag's target track
//!   UID, else its value), falling back to the track names `COLOR` / `DEPTH`, never by number;
//! - depth as `b16g` (16-bit big-endian millimetres, `V_MS/VFW/FOURCC`);
//! - colour as MJPEG (`V_MJPEG`, or `V_MS/VFW/FOURCC` with `MJPG`), `BGRA`, `NV12` or `YUY2`;
//! - block timestamps plus `K4A_START_OFFSET_NS` (the device timestamp of the file's zero);
//! - the `calibration.json` attachment (named by the `K4A_CALIBRATION_FILE` tag) converted
//!   to our [`Calibration`] for the recorded depth mode and colour resolution, as the SDK's
//!   `transformation_get_mode_specific_camera_calibration` does;
//! - colour and depth paired by time (depth time = colour time + `K4A_DEPTH_DELAY_NS`).
//!
//! The IR and IMU tracks are ignored. Laced blocks are refused (the recorder never laces).

use std::path::{Path, PathBuf};

use image::RgbImage;
use nalgebra::Isometry3;
use serde_json::Value;

use crate::calibration::{Calibration, Extrinsics, RegistrationModel};
use crate::camera::{CameraModel, Distortion};
use crate::depth::{DEPTH_UNIT_MM_M, DepthImage, decode_color_image};
use crate::ebml::{self, Child, FileReader, Header};
use crate::error::{KinectError, Result};
use crate::pixels::{RawColor, to_rgb};
use crate::recording::{Container, frame_at, pair_by_time};

const ID_EBML: u32 = 0x1A45_DFA3;
const ID_DOC_TYPE: u32 = 0x4282;
const ID_SEGMENT: u32 = 0x1853_8067;
const ID_INFO: u32 = 0x1549_A966;
const ID_TIMESTAMP_SCALE: u32 = 0x2A_D7B1;
const ID_TRACKS: u32 = 0x1654_AE6B;
const ID_TRACK_ENTRY: u32 = 0xAE;
const ID_TRACK_NUMBER: u32 = 0xD7;
const ID_TRACK_UID: u32 = 0x73C5;
const ID_CODEC_ID: u32 = 0x86;
const ID_CODEC_PRIVATE: u32 = 0x63A2;
const ID_NAME: u32 = 0x536E;
const ID_VIDEO: u32 = 0xE0;
const ID_PIXEL_WIDTH: u32 = 0xB0;
const ID_PIXEL_HEIGHT: u32 = 0xBA;
const ID_CLUSTER: u32 = 0x1F43_B675;
const ID_CLUSTER_TIMESTAMP: u32 = 0xE7;
const ID_SIMPLE_BLOCK: u32 = 0xA3;
const ID_BLOCK_GROUP: u32 = 0xA0;
const ID_BLOCK: u32 = 0xA1;
const ID_TAGS: u32 = 0x1254_C367;
const ID_TAG: u32 = 0x7373;
const ID_TARGETS: u32 = 0x63C0;
const ID_TAG_TRACK_UID: u32 = 0x63C5;
const ID_TAG_ATTACHMENT_UID: u32 = 0x63C6;
const ID_SIMPLE_TAG: u32 = 0x67C8;
const ID_TAG_NAME: u32 = 0x45A3;
const ID_TAG_STRING: u32 = 0x4487;
const ID_ATTACHMENTS: u32 = 0x1941_A469;
const ID_ATTACHED_FILE: u32 = 0x61A7;
const ID_FILE_NAME: u32 = 0x466E;
const ID_FILE_DATA: u32 = 0x465C;
const ID_FILE_UID: u32 = 0x46AE;
/// Elements a Cluster may hold (Matroska spec): an unknown-size cluster ends at any other ID.
const CLUSTER_CHILDREN: [u32; 9] = [
    ID_CLUSTER_TIMESTAMP,
    ID_SIMPLE_BLOCK,
    ID_BLOCK_GROUP,
    0xEC,   // Void
    0xBF,   // CRC-32
    0xA7,   // Position
    0xAB,   // PrevSize
    0x5854, // SilentTracks
    0xAF,   // EncryptedBlock
];

/// Matroska's default TimestampScale: 1 ms ticks.
const DEFAULT_TIMESTAMP_SCALE_NS: u64 = 1_000_000;
/// Largest metadata element (Tracks, Tags, Info, one attachment) held in memory.
const MAX_META_BYTES: u64 = 16 << 20;
/// Largest colour or depth block read (a 4096x3072 BGRA frame is 50 MB).
const MAX_FRAME_BYTES: u64 = 64 << 20;
/// Most video blocks indexed: 24 hours of colour, depth and IR at 30 fps is 7.8 million; the
/// index holds 40 bytes per block.
const MAX_BLOCKS: usize = 10_000_000;
/// A block header: track number (at most 8 bytes), 16-bit timestamp, flags.
const MAX_BLOCK_HEADER: usize = 11;

/// A raw depth frame's size per pixel: b16g, two bytes.
const B16G_BYTES: u64 = 2;

/// Where one frame's data is in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct BlockRef {
    offset: u64,
    len: u64,
    /// Block time, nanoseconds from the file's zero.
    time_ns: i64,
}

/// How a colour track stores its frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ColorCodec {
    Mjpeg,
    Raw(RawColor),
}

/// An opened Azure Kinect recording: track layout, calibration and where each frame is.
#[derive(Debug, Clone)]
pub(crate) struct K4aRecording {
    color_codec: ColorCodec,
    color_size: (u32, u32),
    depth_size: (u32, u32),
    frames: Vec<(BlockRef, BlockRef)>,
    start_offset_ns: i64,
    /// Depth frames with no colour frame within the pairing tolerance.
    unpaired_depth: usize,
    calibration: Calibration,
}

#[derive(Debug, Default)]
struct Track {
    number: u64,
    uid: u64,
    name: String,
    codec: String,
    private: Vec<u8>,
    width: u32,
    height: u32,
}

#[derive(Debug, Default)]
struct Tag {
    track_uids: Vec<u64>,
    attachment_uids: Vec<u64>,
    simple: Vec<(String, String)>,
}

#[derive(Debug)]
struct Attachment {
    uid: u64,
    name: String,
    data: Vec<u8>,
}

#[derive(Debug)]
struct RawBlock {
    track: u64,
    ticks: i64,
    laced: bool,
    offset: u64,
    len: u64,
}

/// Everything the walk over the file collects.
#[derive(Debug, Default)]
struct Walk {
    timestamp_scale_ns: Option<u64>,
    tracks: Vec<Track>,
    tags: Vec<Tag>,
    attachments: Vec<Attachment>,
    blocks: Vec<RawBlock>,
}

impl Walk {
    /// The first tag holding a simple tag `name`.
    fn tag(&self, name: &str) -> Option<&Tag> {
        self.tags
            .iter()
            .find(|t| t.simple.iter().any(|(n, _)| n == name))
    }

    /// The value of the first simple tag `name`.
    fn value(&self, name: &str) -> Option<&str> {
        self.tags
            .iter()
            .flat_map(|t| &t.simple)
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    /// The track a K4A tag names (by its target track UID, else its value), else the track
    /// called `name`.
    fn find_track(&self, tag: &str, name: &str, path: &Path) -> Result<&Track> {
        let by_tag = self.tag(tag).and_then(|t| {
            let uid = t.track_uids.first().copied().or_else(|| {
                t.simple
                    .iter()
                    .find(|(n, _)| n == tag)
                    .and_then(|(_, v)| v.trim().parse::<u64>().ok())
            })?;
            self.tracks.iter().find(|tr| tr.uid == uid)
        });
        by_tag
            .or_else(|| self.tracks.iter().find(|tr| tr.name == name))
            .ok_or_else(|| {
                KinectError::format(
                    path,
                    format!(
                        "no {name} track: no {tag} tag naming a track and no track named \
                         {name:?} (not an Azure Kinect recording, or recorded with that \
                         camera off); tracks: {:?}",
                        self.tracks
                            .iter()
                            .map(|t| (t.number, t.name.as_str(), t.codec.as_str()))
                            .collect::<Vec<_>>()
                    ),
                )
            })
    }

    /// The blocks of `track` sorted by time (time in ns as `f64` for pairing).
    fn blocks_of(&self, track: &Track, path: &Path) -> Result<Vec<(f64, BlockRef)>> {
        let scale = self
            .timestamp_scale_ns
            .unwrap_or(DEFAULT_TIMESTAMP_SCALE_NS);
        let mut out = Vec::new();
        for b in self.blocks.iter().filter(|b| b.track == track.number) {
            if b.laced {
                return Err(KinectError::Unsupported {
                    path: path.to_path_buf(),
                    what: format!(
                        "laced block at byte {} in the {} track (k4arecorder never laces)",
                        b.offset, track.name
                    ),
                });
            }
            let time_ns = i64::try_from(scale)
                .ok()
                .and_then(|s| b.ticks.checked_mul(s))
                .ok_or_else(|| {
                    KinectError::format(path, format!("block at byte {} overflows time", b.offset))
                })?;
            let r = BlockRef {
                offset: b.offset,
                len: b.len,
                time_ns,
            };
            out.push((time_ns as f64, r));
        }
        out.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(out)
    }
}

/// True when the file starts with the EBML magic number.
pub(crate) fn is_matroska(path: &Path) -> bool {
    let mut magic = [0u8; 4];
    std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic))
        .is_ok()
        && u32::from_be_bytes(magic) == ID_EBML
}

impl K4aRecording {
    /// Index a recording: read its tracks, tags, calibration (unless one is `given`) and
    /// block positions (not the frames themselves).
    pub fn open(path: &Path, given: Option<Calibration>) -> Result<Self> {
        let mut file = FileReader::open(path)?;
        let walk = walk(&mut file)?;
        let bad = |what: String| KinectError::format(path, what);
        let depth = walk.find_track("K4A_DEPTH_TRACK", "DEPTH", path)?;
        let color = walk.find_track("K4A_COLOR_TRACK", "COLOR", path)?;
        check_depth_codec(depth, path)?;
        let color_codec = color_codec(color, path)?;
        let number = |what: &str| -> Result<i64> {
            walk.value(what).map_or(Ok(0), |v| {
                v.trim()
                    .parse::<i64>()
                    .map_err(|_| bad(format!("tag {what} = {v:?} is not an integer")))
            })
        };
        let start_offset_ns = number("K4A_START_OFFSET_NS")?;
        let depth_delay_ns = number("K4A_DEPTH_DELAY_NS")?;
        let mut depth_blocks = walk.blocks_of(depth, path)?;
        let mut color_blocks = walk.blocks_of(color, path)?;
        for (t, _) in &mut color_blocks {
            *t += depth_delay_ns as f64;
        }
        let pairs = pair_by_time(&mut depth_blocks, &mut color_blocks);
        let frames: Vec<_> = pairs
            .iter()
            .map(|&(d, c)| (depth_blocks[d].1, color_blocks[c].1))
            .collect();
        if frames.is_empty() {
            return Err(bad(format!(
                "no frame with both colour and depth ({} depth and {} colour blocks)",
                depth_blocks.len(),
                color_blocks.len()
            )));
        }
        let calibration = match given {
            Some(c) => c,
            None => attached_calibration(path, &walk, (depth, color))?,
        };
        Ok(Self {
            color_codec,
            color_size: (color.width, color.height),
            depth_size: (depth.width, depth.height),
            unpaired_depth: depth_blocks.len() - frames.len(),
            frames,
            start_offset_ns,
            calibration,
        })
    }
}

impl Container for K4aRecording {
    fn calibration(&self) -> &Calibration {
        &self.calibration
    }

    fn unpaired_depth(&self) -> usize {
        self.unpaired_depth
    }

    /// Device timestamps: block time + `K4A_START_OFFSET_NS`.
    fn times_s(&self) -> Vec<(f64, f64)> {
        let s = |t: i64| (t.saturating_add(self.start_offset_ns)) as f64 * 1e-9;
        self.frames
            .iter()
            .map(|(d, c)| (s(d.time_ns), s(c.time_ns)))
            .collect()
    }

    /// Read and decode frame `i`: colour as RGB, depth in `depth_unit_m` units (the
    /// recorder's millimetres unless the caller's calibration says otherwise).
    fn read(&self, path: &Path, i: usize, depth_unit_m: f64) -> Result<(RgbImage, DepthImage)> {
        let (d, c) = frame_at(&self.frames, path, i)?;
        let mut file = FileReader::open(path)?;
        let label = |what: &str, b: &BlockRef| -> PathBuf {
            PathBuf::from(format!(
                "{} ({what} of frame {i}, block at byte {})",
                path.display(),
                b.offset
            ))
        };
        let color_bytes = file.read_vec(c.offset, c.len, MAX_FRAME_BYTES, "a colour block")?;
        let color_label = label("colour", &c);
        let (cw, ch) = self.color_size;
        let color = match self.color_codec {
            ColorCodec::Mjpeg => decode_color_image(&color_bytes, &color_label)?,
            ColorCodec::Raw(layout) => to_rgb(layout, cw, ch, None, &color_bytes, &color_label)?,
        };
        if (color.width(), color.height()) != (cw, ch) {
            return Err(KinectError::SizeMismatch {
                what: format!("{} vs. its track", color_label.display()),
                expected_width: cw,
                expected_height: ch,
                found_width: color.width(),
                found_height: color.height(),
            });
        }
        let depth_bytes = file.read_vec(d.offset, d.len, MAX_FRAME_BYTES, "a depth block")?;
        let (dw, dh) = self.depth_size;
        let need = u64::from(dw) * u64::from(dh) * B16G_BYTES;
        if depth_bytes.len() as u64 != need {
            return Err(KinectError::format(
                &label("depth", &d),
                format!(
                    "a b16g frame of {dw}x{dh} px has {need} bytes, this block {}",
                    depth_bytes.len()
                ),
            ));
        }
        let values = depth_bytes
            .chunks_exact(2)
            .map(|p| u16::from_be_bytes([p[0], p[1]]))
            .collect();
        let depth = DepthImage::new(dw, dh, depth_unit_m, values)?;
        Ok((color, depth))
    }
}

/// The calibration attached to the recording (named by the `K4A_CALIBRATION_FILE` tag).
fn attached_calibration(
    path: &Path,
    walk: &Walk,
    (depth, color): (&Track, &Track),
) -> Result<Calibration> {
    let calibration_name = walk
        .value("K4A_CALIBRATION_FILE")
        .unwrap_or("calibration.json");
    let attachment = walk
        .attachments
        .iter()
        .find(|a| a.name == calibration_name)
        .or_else(|| {
            let uid = walk.tag("K4A_CALIBRATION_FILE")?.attachment_uids.first()?;
            walk.attachments.iter().find(|a| a.uid == *uid)
        })
        .ok_or_else(|| {
            KinectError::calibration(
                path,
                format!(
                    "no attachment {calibration_name:?} (attachments: {:?})",
                    walk.attachments
                        .iter()
                        .map(|a| a.name.as_str())
                        .collect::<Vec<_>>()
                ),
            )
        })?;
    let text = std::str::from_utf8(&attachment.data).map_err(|_| {
        KinectError::calibration(
            path,
            format!("attachment {:?} is not UTF-8", attachment.name),
        )
    })?;
    let calibration = Calibration::from_azure_kinect_json(
        text,
        (depth.width, depth.height),
        (color.width, color.height),
    )
    .map_err(|e| match e {
        KinectError::Calibration { what, .. } => {
            KinectError::calibration(path, format!("attachment {:?}: {what}", attachment.name))
        }
        other => other,
    })?;
    Ok(calibration)
}

/// The FourCC of a `V_MS/VFW/FOURCC` track (BITMAPINFOHEADER's `biCompression`, bytes 16..20).
fn fourcc(track: &Track) -> Option<[u8; 4]> {
    (track.codec == "V_MS/VFW/FOURCC")
        .then(|| track.private.get(16..20)?.try_into().ok())
        .flatten()
}

fn check_depth_codec(track: &Track, path: &Path) -> Result<()> {
    if fourcc(track) == Some(*b"b16g") && track.width > 0 && track.height > 0 {
        return Ok(());
    }
    Err(KinectError::Unsupported {
        path: path.to_path_buf(),
        what: format!(
            "depth track {} is {:?} {:?} {}x{}, expected V_MS/VFW/FOURCC b16g (16-bit \
             big-endian) with a size",
            track.number,
            track.codec,
            fourcc(track).map(|f| String::from_utf8_lossy(&f).into_owned()),
            track.width,
            track.height
        ),
    })
}

fn color_codec(track: &Track, path: &Path) -> Result<ColorCodec> {
    let codec = match (track.codec.as_str(), fourcc(track).as_ref()) {
        ("V_MJPEG", _) | (_, Some(b"MJPG")) => Some(ColorCodec::Mjpeg),
        (_, Some(b"BGRA")) => Some(ColorCodec::Raw(RawColor::Bgra8)),
        (_, Some(b"NV12")) => Some(ColorCodec::Raw(RawColor::Nv12)),
        (_, Some(b"YUY2")) => Some(ColorCodec::Raw(RawColor::Yuy2)),
        _ => None,
    };
    match codec {
        Some(c) if track.width > 0 && track.height > 0 => Ok(c),
        _ => Err(KinectError::Unsupported {
            path: path.to_path_buf(),
            what: format!(
                "colour track {} is {:?} {:?} {}x{}, expected MJPEG, BGRA, NV12 or YUY2 \
                 with a size",
                track.number,
                track.codec,
                fourcc(track).map(|f| String::from_utf8_lossy(&f).into_owned()),
                track.width,
                track.height
            ),
        }),
    }
}

/// Walk the file: EBML header, then the first Segment's children.
fn walk(file: &mut FileReader) -> Result<Walk> {
    let len = file.len();
    let ebml = file
        .header(0, len)?
        .filter(|h| h.id == ID_EBML)
        .ok_or_else(|| file.error(0, "no EBML header: not a Matroska file"))?;
    let ebml_end = ebml
        .end()
        .ok_or_else(|| file.error(0, "the EBML header has an unknown size"))?;
    let data = file.read_vec(
        ebml.data_start,
        ebml_end - ebml.data_start,
        4096,
        "EBML header",
    )?;
    let path = file.path().to_path_buf();
    let doc_type = ebml::children(&data, ebml.data_start, &path)?
        .iter()
        .find(|c| c.id == ID_DOC_TYPE)
        .map(|c| ebml::string(c, &path))
        .transpose()?;
    if !matches!(doc_type.as_deref(), Some("matroska" | "webm")) {
        return Err(file.error(0, format!("DocType {doc_type:?}, expected \"matroska\"")));
    }
    let mut at = ebml_end;
    let segment = loop {
        let h = file
            .header(at, len)?
            .ok_or_else(|| file.error(at, "no Segment element"))?;
        if h.id == ID_SEGMENT {
            break h;
        }
        at = h
            .end()
            .ok_or_else(|| file.error(at, "a top-level element has an unknown size"))?;
    };
    let segment_end = segment.end().unwrap_or(len);
    let mut out = Walk::default();
    let mut at = segment.data_start;
    while let Some(h) = file.header(at, segment_end)? {
        at = match h.id {
            ID_CLUSTER => {
                let video: Vec<u64> = out
                    .tracks
                    .iter()
                    .filter(|t| t.codec.starts_with("V_"))
                    .map(|t| t.number)
                    .collect();
                walk_cluster(file, &h, segment_end, &mut out.blocks, &video)?
            }
            ID_ATTACHMENTS => {
                walk_attachments(file, &h, &mut out.attachments)?;
                known_end(file, &h, at)?
            }
            ID_INFO | ID_TRACKS | ID_TAGS => {
                let end = known_end(file, &h, at)?;
                let data =
                    file.read_vec(h.data_start, end - h.data_start, MAX_META_BYTES, "metadata")?;
                let kids = ebml::children(&data, h.data_start, &path)?;
                match h.id {
                    ID_INFO => {
                        if let Some(c) = kids.iter().find(|c| c.id == ID_TIMESTAMP_SCALE) {
                            let scale = ebml::uint(c, &path)?;
                            if scale == 0 {
                                return Err(file.error(c.offset, "TimestampScale is 0"));
                            }
                            out.timestamp_scale_ns = Some(scale);
                        }
                    }
                    ID_TRACKS => {
                        for c in kids.iter().filter(|c| c.id == ID_TRACK_ENTRY) {
                            out.tracks.push(track(c, &path)?);
                        }
                    }
                    _ => {
                        for c in kids.iter().filter(|c| c.id == ID_TAG) {
                            out.tags.push(tag(c, &path)?);
                        }
                    }
                }
                end
            }
            _ => known_end(file, &h, at)?,
        };
    }
    Ok(out)
}

fn known_end(file: &FileReader, h: &Header, at: u64) -> Result<u64> {
    h.end().ok_or_else(|| {
        file.error(
            at,
            format!(
                "element 0x{:X} has an unknown size (only Segment and Cluster may)",
                h.id
            ),
        )
    })
}

/// Keep a block if it belongs to a video track (all blocks while the tracks are not known
/// yet), refusing more than [`MAX_BLOCKS`].
fn keep(file: &FileReader, blocks: &mut Vec<RawBlock>, b: RawBlock, video: &[u64]) -> Result<()> {
    if !video.is_empty() && !video.contains(&b.track) {
        return Ok(());
    }
    if blocks.len() >= MAX_BLOCKS {
        return Err(file.error(
            b.offset,
            format!("more than {MAX_BLOCKS} video blocks: not read (split the recording)"),
        ));
    }
    blocks.push(b);
    Ok(())
}

/// Index the blocks of one cluster; returns where the next segment child starts. Only blocks
/// of `video` tracks are kept once the tracks are known (the IMU track's many small blocks
/// are not).
fn walk_cluster(
    file: &mut FileReader,
    cluster: &Header,
    segment_end: u64,
    blocks: &mut Vec<RawBlock>,
    video: &[u64],
) -> Result<u64> {
    let end = cluster.end().unwrap_or(segment_end);
    let mut timestamp: Option<u64> = None;
    let mut at = cluster.data_start;
    while let Some(h) = file.header(at, end)? {
        if cluster.size.is_none() && !CLUSTER_CHILDREN.contains(&h.id) {
            // An unknown-size cluster ends where a non-cluster element starts.
            return Ok(at);
        }
        let next = known_end(file, &h, at)?;
        match h.id {
            ID_CLUSTER_TIMESTAMP => {
                let data =
                    file.read_vec(h.data_start, next - h.data_start, 8, "a cluster timestamp")?;
                timestamp = Some(ebml::be_uint(&data));
            }
            ID_SIMPLE_BLOCK => {
                let found = block(file, &h, next, timestamp)?;
                keep(file, blocks, found, video)?;
            }
            ID_BLOCK_GROUP => {
                let mut inner = h.data_start;
                while let Some(b) = file.header(inner, next)? {
                    let b_end = known_end(file, &b, inner)?;
                    if b.id == ID_BLOCK {
                        let found = block(file, &b, b_end, timestamp)?;
                        keep(file, blocks, found, video)?;
                    }
                    inner = b_end;
                }
            }
            _ => {}
        }
        at = next;
    }
    Ok(end)
}

fn block(file: &mut FileReader, h: &Header, end: u64, cluster_ts: Option<u64>) -> Result<RawBlock> {
    let offset = h.data_start;
    let cluster_ts = cluster_ts
        .ok_or_else(|| file.error(offset, "a block comes before its cluster's Timestamp"))?;
    let avail = (end - offset).min(MAX_BLOCK_HEADER as u64) as usize;
    let mut head = [0u8; MAX_BLOCK_HEADER];
    file.read_at(offset, &mut head[..avail])?;
    let (track, n) = ebml::parse_vint(&head[..avail])
        .ok_or_else(|| file.error(offset, "a block's track number is cut off or invalid"))?;
    let (Some(&t0), Some(&t1), Some(&flags)) = (head.get(n), head.get(n + 1), head.get(n + 2))
    else {
        return Err(file.error(offset, "a block header is cut off"));
    };
    if n + 3 > avail {
        return Err(file.error(offset, "a block header is cut off"));
    }
    let relative = i64::from(i16::from_be_bytes([t0, t1]));
    let ticks = i64::try_from(cluster_ts)
        .ok()
        .and_then(|c| c.checked_add(relative))
        .ok_or_else(|| file.error(offset, "the cluster timestamp overflows"))?;
    let payload = offset + (n + 3) as u64;
    Ok(RawBlock {
        track,
        ticks,
        laced: flags & 0x06 != 0,
        offset: payload,
        len: end - payload,
    })
}

fn walk_attachments(file: &mut FileReader, h: &Header, out: &mut Vec<Attachment>) -> Result<()> {
    let end = known_end(file, h, h.data_start)?;
    let path = file.path().to_path_buf();
    let mut at = h.data_start;
    while let Some(f) = file.header(at, end)? {
        let f_end = known_end(file, &f, at)?;
        // Attachments larger than the metadata limit cannot be a calibration: skipped.
        if f.id == ID_ATTACHED_FILE && f_end - f.data_start <= MAX_META_BYTES {
            let data = file.read_vec(
                f.data_start,
                f_end - f.data_start,
                MAX_META_BYTES,
                "an attachment",
            )?;
            let kids = ebml::children(&data, f.data_start, &path)?;
            let mut a = Attachment {
                uid: 0,
                name: String::new(),
                data: Vec::new(),
            };
            for c in &kids {
                match c.id {
                    ID_FILE_NAME => a.name = ebml::string(c, &path)?,
                    ID_FILE_UID => a.uid = ebml::uint(c, &path)?,
                    ID_FILE_DATA => a.data = c.data.to_vec(),
                    _ => {}
                }
            }
            out.push(a);
        }
        at = f_end;
    }
    Ok(())
}

fn track(entry: &Child<'_>, path: &Path) -> Result<Track> {
    let mut t = Track::default();
    for c in ebml::children(entry.data, entry.offset, path)? {
        match c.id {
            ID_TRACK_NUMBER => t.number = ebml::uint(&c, path)?,
            ID_TRACK_UID => t.uid = ebml::uint(&c, path)?,
            ID_NAME => t.name = ebml::string(&c, path)?,
            ID_CODEC_ID => t.codec = ebml::string(&c, path)?,
            ID_CODEC_PRIVATE => t.private = c.data.to_vec(),
            ID_VIDEO => {
                for v in ebml::children(c.data, c.offset, path)? {
                    let dim = || -> Result<u32> {
                        u32::try_from(ebml::uint(&v, path)?).map_err(|_| {
                            KinectError::format(path, format!("byte {}: video size", v.offset))
                        })
                    };
                    match v.id {
                        ID_PIXEL_WIDTH => t.width = dim()?,
                        ID_PIXEL_HEIGHT => t.height = dim()?,
                        _ => {}
                    }
                }
            }
            _ => {}
        }
    }
    Ok(t)
}

fn tag(entry: &Child<'_>, path: &Path) -> Result<Tag> {
    let mut t = Tag::default();
    for c in ebml::children(entry.data, entry.offset, path)? {
        match c.id {
            ID_TARGETS => {
                for g in ebml::children(c.data, c.offset, path)? {
                    match g.id {
                        ID_TAG_TRACK_UID => t.track_uids.push(ebml::uint(&g, path)?),
                        ID_TAG_ATTACHMENT_UID => t.attachment_uids.push(ebml::uint(&g, path)?),
                        _ => {}
                    }
                }
            }
            ID_SIMPLE_TAG => {
                let (mut name, mut value) = (String::new(), String::new());
                for s in ebml::children(c.data, c.offset, path)? {
                    match s.id {
                        ID_TAG_NAME => name = ebml::string(&s, path)?,
                        ID_TAG_STRING => value = ebml::string(&s, path)?,
                        _ => {}
                    }
                }
                t.simple.push((name, value));
            }
            _ => {}
        }
    }
    Ok(t)
}

/// How the SDK turns a raw (normalised, corner-origin) calibration into one recording mode:
/// `(binned width, binned height, crop x, crop y)` of `k4a_camera_calibration_mode_info_t`.
type ModeInfo = (f64, f64, f64, f64);

/// Depth modes by output size (Azure Kinect SDK `transformation_get_mode_specific_depth_camera_calibration`).
fn depth_mode(size: (u32, u32)) -> Option<ModeInfo> {
    Some(match size {
        (320, 288) => (512.0, 512.0, 96.0, 90.0), // NFOV_2X2BINNED
        (640, 576) => (1024.0, 1024.0, 192.0, 180.0), // NFOV_UNBINNED
        (512, 512) => (512.0, 512.0, 0.0, 0.0),   // WFOV_2X2BINNED
        (1024, 1024) => (1024.0, 1024.0, 0.0, 0.0), // WFOV_UNBINNED, PASSIVE_IR
        _ => return None,
    })
}

/// Colour resolutions by output size (the SDK's `..._color_camera_calibration`).
fn color_mode(size: (u32, u32)) -> Option<ModeInfo> {
    Some(match size {
        (1280, 720) => (1280.0, 960.0, 0.0, 120.0),
        (1920, 1080) => (1920.0, 1440.0, 0.0, 180.0),
        (2560, 1440) => (2560.0, 1920.0, 0.0, 240.0),
        (2048, 1536) => (2048.0, 1536.0, 0.0, 0.0),
        (3840, 2160) => (3840.0, 2880.0, 0.0, 360.0),
        (4096, 3072) => (4096.0, 3072.0, 0.0, 0.0),
        _ => return None,
    })
}

/// Number of intrinsic parameters of the SDK's Brown–Conrady model: cx, cy, fx, fy, k1..k6,
/// codx, cody, p2, p1 (then the metric radius, unused here).
const K4A_INTRINSICS: usize = 14;

impl Calibration {
    /// An Azure Kinect / Orbbec Femto factory calibration (`calibration.json` as the
    /// recorder attaches it, or as `k4a_device_get_raw_calibration` returns it) for one
    /// recording mode, given by the depth and colour image sizes (for example 640x576 for
    /// `NFOV_UNBINNED`, 1280x720 for `720P`). Intrinsics are scaled and cropped to the mode
    /// and moved to pixel-centre coordinates exactly as the SDK does; the depth-to-colour
    /// transform is the colour camera's `Rt` times the inverse of the depth camera's; depth
    /// in millimetres.
    ///
    /// Not used: the IMU, the metric radius (the SDK's limit of valid distortion; our
    /// undistortion marks pixels it cannot invert instead).
    ///
    /// # Errors
    /// [`KinectError::Calibration`] for JSON that is not such a calibration, a camera
    /// missing, a lens model other than Brown–Conrady, a nonzero distortion centre, a mode
    /// size the device does not have, or values the camera model refuses.
    pub fn from_azure_kinect_json(
        text: &str,
        depth_size: (u32, u32),
        color_size: (u32, u32),
    ) -> Result<Self> {
        let label = Path::new(crate::error::MEMORY_LABEL);
        let bad = |what: String| KinectError::calibration(label, what);
        let root: Value = serde_json::from_str(text).map_err(|e| bad(format!("not JSON: {e}")))?;
        let cameras = root
            .pointer("/CalibrationInformation/Cameras")
            .and_then(Value::as_array)
            .ok_or_else(|| bad("no CalibrationInformation.Cameras array".into()))?;
        let camera = |location: &str| -> Result<&Value> {
            cameras
                .iter()
                .find(|c| c.get("Location").and_then(Value::as_str) == Some(location))
                .ok_or_else(|| bad(format!("no camera with Location {location:?}")))
        };
        let depth_raw = camera("CALIBRATION_CameraLocationD0")?;
        let color_raw = camera("CALIBRATION_CameraLocationPV0")?;
        let depth_mode = depth_mode(depth_size).ok_or_else(|| {
            bad(format!(
                "depth images of {}x{} px are no Azure Kinect depth mode",
                depth_size.0, depth_size.1
            ))
        })?;
        let color_mode = color_mode(color_size).ok_or_else(|| {
            bad(format!(
                "colour images of {}x{} px are no Azure Kinect colour resolution",
                color_size.0, color_size.1
            ))
        })?;
        let (depth_camera, world_to_depth) =
            k4a_camera(depth_raw, depth_size, depth_mode, "depth", &bad)?;
        let (color_camera, world_to_color) =
            k4a_camera(color_raw, color_size, color_mode, "colour", &bad)?;
        let depth_to_color = world_to_color * world_to_depth.inverse();
        let calibration = Self {
            depth_camera,
            color_camera,
            registration: RegistrationModel::Rigid(Extrinsics::from_isometry(&depth_to_color)),
            depth_unit_m: DEPTH_UNIT_MM_M,
            depth_offset_m: 0.0,
        };
        calibration.validate()?;
        Ok(calibration)
    }
}

/// One camera of an Azure Kinect calibration in one mode, and its `Rt` (world to camera).
fn k4a_camera(
    raw: &Value,
    size: (u32, u32),
    mode: ModeInfo,
    what: &str,
    bad: &dyn Fn(String) -> KinectError,
) -> Result<(CameraModel, Isometry3<f64>)> {
    let floats = |v: Option<&Value>, key: &str, n: usize| -> Result<Vec<f64>> {
        let list = v
            .and_then(Value::as_array)
            .ok_or_else(|| bad(format!("{what} camera: no {key} array")))?;
        let out: Vec<f64> = list.iter().filter_map(Value::as_f64).collect();
        if out.len() < n || out.len() != list.len() || out.iter().any(|x| !x.is_finite()) {
            return Err(bad(format!(
                "{what} camera: {key} must hold at least {n} finite numbers, found {list:?}"
            )));
        }
        Ok(out)
    };
    let intrinsics = raw.get("Intrinsics");
    let model = intrinsics
        .and_then(|i| i.get("ModelType"))
        .and_then(Value::as_str)
        .unwrap_or("");
    if model != "CALIBRATION_LensDistortionModelBrownConrady" {
        return Err(bad(format!(
            "{what} camera: lens model {model:?}, only CALIBRATION_LensDistortionModelBrownConrady is read"
        )));
    }
    let p = floats(
        intrinsics.and_then(|i| i.get("ModelParameters")),
        "ModelParameters",
        K4A_INTRINSICS,
    )?;
    let sensor = |key: &str| raw.get(key).and_then(Value::as_f64).unwrap_or(0.0);
    let (sensor_w, sensor_h) = (sensor("SensorWidth"), sensor("SensorHeight"));
    // Legacy colour calibrations are 16:9: the SDK first maps them onto the 4:3 sensor
    // (binned 4096x2304, crop (0, -384), output 4096x3072), normalised.
    let (mut cx, mut cy, fx, mut fy) = (p[0], p[1], p[2], p[3]);
    if what == "colour" && (sensor_w * 9.0 / 16.0 - sensor_h).abs() < 1.0 {
        cy = (cy * 2304.0 + 384.0) / 3072.0;
        fy = fy * 2304.0 / 3072.0;
    } else if what == "depth" && (sensor_w, sensor_h) != (1024.0, 1024.0) {
        return Err(bad(format!(
            "depth camera: sensor {sensor_w}x{sensor_h} px, the SDK expects 1024x1024"
        )));
    }
    let (bw, bh, crop_x, crop_y) = mode;
    cx = cx * bw - crop_x - 0.5;
    cy = cy * bh - crop_y - 0.5;
    if p[10] != 0.0 || p[11] != 0.0 {
        return Err(bad(format!(
            "{what} camera: distortion centre ({}, {}) is not zero; not read",
            p[10], p[11]
        )));
    }
    let camera = CameraModel {
        width: size.0,
        height: size.1,
        fx: fx * bw,
        fy: fy * bh,
        cx,
        cy,
        distortion: Distortion {
            k1: p[4],
            k2: p[5],
            k3: p[6],
            k4: p[7],
            k5: p[8],
            k6: p[9],
            p2: p[12],
            p1: p[13],
        },
    };
    camera
        .validate()
        .map_err(|e| bad(format!("{what} camera: {e}")))?;
    let rt = raw.get("Rt");
    let r = floats(rt.and_then(|v| v.get("Rotation")), "Rt.Rotation", 9)?;
    let t = floats(rt.and_then(|v| v.get("Translation")), "Rt.Translation", 3)?;
    let checked = Extrinsics {
        rotation: [[r[0], r[1], r[2]], [r[3], r[4], r[5]], [r[6], r[7], r[8]]],
        translation_m: [t[0], t[1], t[2]],
    };
    let iso = checked
        .to_isometry()
        .map_err(|e| bad(format!("{what} camera Rt: {e}")))?;
    Ok((camera, iso))
}
