//! A ROS bag chunk's size, checked before the `rosbag` crate decompresses it.
//!
//! The crate reserves the chunk's declared uncompressed `size` (up to 4 GiB) before it
//! decompresses, and decompresses an lz4 chunk to its end whatever that size says. A chunk
//! that declares a huge size, or lz4 data that expands far beyond it, would make it allocate
//! without bound. Here the declared size is held to [`MAX_CHUNK_BYTES`], and an lz4 chunk's
//! frames are walked block by block (headers only, no decompression): each block expands to
//! at most the frame's block size, so the sum bounds the output.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use crate::error::{KinectError, Result};

/// Largest uncompressed chunk read, bytes. A chunk holds the messages of about 768 KiB of
/// recording (ROS's default chunk threshold) plus the one that crossed it: one raw image, at
/// most tens of MB for today's cameras (a 4K RGBA frame is 33 MB).
pub(crate) const MAX_CHUNK_BYTES: u64 = 1 << 29;

/// Largest chunk record header read (the format's headers are a few dozen bytes).
const MAX_RECORD_HEADER_BYTES: u32 = 1 << 16;

/// The op code of a chunk record.
const OP_CHUNK: u8 = 0x05;

/// LZ4 frame magic numbers (LZ4 frame format 1.6.x): a frame, and the range of skippable
/// frames.
const LZ4_FRAME_MAGIC: u32 = 0x184D_2204;
const LZ4_SKIPPABLE_MASK: u32 = 0xFFFF_FFF0;
const LZ4_SKIPPABLE_MAGIC: u32 = 0x184D_2A50;

/// Check the chunk record at `chunk_pos` of the bag at `path` before it is decompressed.
///
/// # Errors
/// [`KinectError::Format`] naming the file and the chunk when its record cannot be read, it
/// is not a chunk, its declared size is over [`MAX_CHUNK_BYTES`], or its lz4 data could
/// expand beyond that.
pub(crate) fn check_chunk(path: &Path, chunk_pos: u64) -> Result<()> {
    let bad =
        |what: String| KinectError::format(path, format!("chunk at byte {chunk_pos}: {what}"));
    let mut file = File::open(path).map_err(|e| KinectError::io(path, e))?;
    let len = file.metadata().map_err(|e| KinectError::io(path, e))?.len();
    let mut at = |pos: u64, buf: &mut [u8]| -> Result<()> {
        if pos
            .checked_add(buf.len() as u64)
            .is_none_or(|end| end > len)
        {
            return Err(bad(format!(
                "reaches past the end of the file ({len} bytes)"
            )));
        }
        file.seek(SeekFrom::Start(pos))
            .and_then(|_| file.read_exact(buf))
            .map_err(|e| KinectError::io(path, e))
    };
    let header_len = read_u32(&mut at, chunk_pos)?;
    if header_len > MAX_RECORD_HEADER_BYTES {
        return Err(bad(format!("a record header of {header_len} bytes")));
    }
    let mut header = vec![0u8; header_len as usize];
    at(chunk_pos + 4, &mut header)?;
    let fields = header_fields(&header).ok_or_else(|| bad("its header is cut short".into()))?;
    let field = |name: &[u8]| fields.iter().find(|(n, _)| *n == name).map(|(_, v)| *v);
    if field(b"op") != Some(&[OP_CHUNK][..]) {
        return Err(bad("not a chunk record".into()));
    }
    let size = field(b"size")
        .and_then(|v| <[u8; 4]>::try_from(v).ok())
        .map(u32::from_le_bytes)
        .ok_or_else(|| bad("no 4-byte size field".into()))?;
    if u64::from(size) > MAX_CHUNK_BYTES {
        return Err(bad(format!(
            "declares {size} bytes uncompressed; at most {MAX_CHUNK_BYTES} are read"
        )));
    }
    let data_pos = chunk_pos + 4 + u64::from(header_len);
    let data_len = read_u32(&mut at, data_pos)?;
    if field(b"compression") == Some(&b"lz4"[..]) {
        let bound = lz4_output_bound(u64::from(data_len), &mut |pos, buf| {
            at(data_pos + 4 + pos, buf)
        })
        .map_err(|what| bad(format!("lz4 data: {what}")))?;
        if bound > MAX_CHUNK_BYTES {
            return Err(bad(format!(
                "its lz4 data can expand to {bound} bytes; at most {MAX_CHUNK_BYTES} are read"
            )));
        }
    }
    Ok(())
}

fn read_u32(at: &mut impl FnMut(u64, &mut [u8]) -> Result<()>, pos: u64) -> Result<u32> {
    let mut b = [0u8; 4];
    at(pos, &mut b)?;
    Ok(u32::from_le_bytes(b))
}

/// The `name=value` fields of a record header; `None` when a field runs past its end.
fn header_fields(mut header: &[u8]) -> Option<Vec<(&[u8], &[u8])>> {
    let mut fields = Vec::new();
    while !header.is_empty() {
        let n = u32::from_le_bytes(header.get(..4)?.try_into().ok()?) as usize;
        let field = header.get(4..4usize.checked_add(n)?)?;
        header = &header[4 + n..];
        let eq = field.iter().position(|&b| b == b'=')?;
        fields.push((&field[..eq], &field[eq + 1..]));
    }
    Some(fields)
}

/// The most bytes the LZ4 frames in `len` bytes (read through `read(offset, buf)`) can
/// decompress to: per block its stored size when stored uncompressed, else the frame's
/// block size. Only headers are read.
///
/// # Errors
/// What is wrong, when the data is not a sequence of LZ4 frames (or skippable frames).
pub(crate) fn lz4_output_bound(
    len: u64,
    read: &mut impl FnMut(u64, &mut [u8]) -> Result<()>,
) -> std::result::Result<u64, String> {
    let mut word = |pos: u64| -> std::result::Result<u32, String> {
        if pos + 4 > len {
            return Err(format!("cut short at byte {pos} of {len}"));
        }
        let mut b = [0u8; 4];
        read(pos, &mut b).map_err(|e| e.to_string())?;
        Ok(u32::from_le_bytes(b))
    };
    let mut pos = 0u64;
    let mut bound = 0u64;
    while pos < len {
        let magic = word(pos)?;
        if magic & LZ4_SKIPPABLE_MASK == LZ4_SKIPPABLE_MAGIC {
            pos += 8 + u64::from(word(pos + 4)?);
            continue;
        }
        if magic != LZ4_FRAME_MAGIC {
            return Err(format!("no LZ4 frame at byte {pos} (magic {magic:#010x})"));
        }
        // FLG and BD (descriptor bytes 1-2), as the low bytes of the word after the magic.
        let [flg, bd, ..] = word(pos + 4)?.to_le_bytes();
        if flg >> 6 != 1 {
            return Err(format!("LZ4 frame version {} at byte {pos}", flg >> 6));
        }
        let block_checksum = flg & 0x10 != 0;
        let content_checksum = flg & 0x04 != 0;
        let block_max: u64 = match (bd >> 4) & 0x7 {
            4 => 64 << 10,
            5 => 256 << 10,
            6 => 1 << 20,
            7 => 4 << 20,
            other => return Err(format!("LZ4 block size code {other} at byte {pos}")),
        };
        // Magic, FLG, BD, optional content size and dictionary id, header checksum.
        pos +=
            4 + 2 + if flg & 0x08 != 0 { 8 } else { 0 } + if flg & 0x01 != 0 { 4 } else { 0 } + 1;
        loop {
            let block = word(pos)?;
            pos += 4;
            if block == 0 {
                pos += if content_checksum { 4 } else { 0 };
                break;
            }
            let stored = u64::from(block & 0x7FFF_FFFF);
            bound += if block >> 31 == 1 { stored } else { block_max };
            pos += stored + if block_checksum { 4 } else { 0 };
            if bound > MAX_CHUNK_BYTES || pos > len {
                // Enough to refuse (or cut short); no need to walk further.
                return if pos > len {
                    Err(format!("a block runs past the data's {len} bytes"))
                } else {
                    Ok(bound)
                };
            }
        }
    }
    Ok(bound)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An LZ4 frame (no checksums, no content size, 64 KiB blocks) of `blocks` blocks, each
    /// a compressed block of `stored` bytes (contents irrelevant to the bound).
    fn frame(blocks: usize, stored: u32, uncompressed_flag: bool) -> Vec<u8> {
        let mut f = LZ4_FRAME_MAGIC.to_le_bytes().to_vec();
        f.extend([0x40, 0x40, 0x00]); // FLG: version 1; BD: 64 KiB; header checksum
        for _ in 0..blocks {
            let word = stored | if uncompressed_flag { 1 << 31 } else { 0 };
            f.extend(word.to_le_bytes());
            f.extend(std::iter::repeat_n(0u8, stored as usize));
        }
        f.extend(0u32.to_le_bytes());
        f
    }

    fn bound_of(data: &[u8]) -> std::result::Result<u64, String> {
        lz4_output_bound(data.len() as u64, &mut |pos, buf| {
            let pos = pos as usize;
            buf.copy_from_slice(&data[pos..pos + buf.len()]);
            Ok(())
        })
    }

    #[test]
    fn the_bound_counts_each_block_at_its_most() {
        assert_eq!(bound_of(&frame(3, 100, false)), Ok(3 * 65_536));
        assert_eq!(bound_of(&frame(3, 100, true)), Ok(300));
        // Two frames in a row, and a skippable frame between them.
        let mut two = frame(2, 10, false);
        two.extend(0x184D_2A5Au32.to_le_bytes());
        two.extend(3u32.to_le_bytes());
        two.extend([1, 2, 3]);
        two.extend(frame(1, 10, false));
        assert_eq!(bound_of(&two), Ok(3 * 65_536));
    }

    #[test]
    fn a_frame_that_could_expand_past_the_limit_is_reported_without_walking_it_all() {
        // 9000 blocks of 64 KiB: 590 MB from 45 kB of data (a decompression bomb's shape).
        let bomb = frame(9000, 1, false);
        let bound = bound_of(&bomb).expect("a frame");
        assert!(bound > MAX_CHUNK_BYTES, "{bound}");
    }

    #[test]
    fn damaged_frames_are_errors_not_panics() {
        let good = frame(2, 50, false);
        for cut in [0, 3, 5, 8, 20, good.len() - 1] {
            assert!(bound_of(&good[..cut.max(1)]).is_err(), "cut at {cut}");
        }
        let mut wrong_magic = good.clone();
        wrong_magic[0] ^= 0xFF;
        assert!(bound_of(&wrong_magic).unwrap_err().contains("no LZ4 frame"));
        let mut wrong_version = good.clone();
        wrong_version[4] = 0x80;
        assert!(bound_of(&wrong_version).unwrap_err().contains("version"));
        let mut wrong_block_size = good;
        wrong_block_size[5] = 0x10;
        assert!(
            bound_of(&wrong_block_size)
                .unwrap_err()
                .contains("block size")
        );
    }
}
