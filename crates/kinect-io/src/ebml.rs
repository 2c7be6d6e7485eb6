//! A small EBML reader (the container layer of Matroska, RFC 8794): element headers read from
//! a file with every size checked against its parent and the file, and masters small enough
//! to hold parsed from memory. Only what the Azure Kinect reader needs; nothing here panics
//! on bad bytes, and every loop advances by at least one byte per element.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use crate::error::{KinectError, Result};

/// Largest element ID length in bytes (RFC 8794 §5: `EBMLMaxIDLength` defaults to 4).
const MAX_ID_BYTES: usize = 4;
/// Largest element data size length in bytes (RFC 8794 §6: `EBMLMaxSizeLength` defaults to 8).
const MAX_SIZE_BYTES: usize = 8;

/// One element header: its ID (with the length marker, as Matroska's tables write IDs), where
/// its data starts and its data size (`None`: unknown size, allowed for Segment and Cluster).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Header {
    pub id: u32,
    pub data_start: u64,
    pub size: Option<u64>,
}

impl Header {
    /// Offset just past the element, when its size is known.
    pub fn end(&self) -> Option<u64> {
        self.size.map(|s| self.data_start.saturating_add(s))
    }
}

/// Reads element headers and element data from a file, positioned by absolute offsets.
pub(crate) struct FileReader {
    path: PathBuf,
    reader: BufReader<File>,
    len: u64,
    pos: u64,
}

impl FileReader {
    /// Open `path` for reading.
    pub fn open(path: &Path) -> Result<Self> {
        let file = File::open(path).map_err(|e| KinectError::io(path, e))?;
        let len = file.metadata().map_err(|e| KinectError::io(path, e))?.len();
        Ok(Self {
            path: path.to_path_buf(),
            reader: BufReader::with_capacity(1 << 16, file),
            len,
            pos: 0,
        })
    }

    /// The file's length in bytes.
    pub fn len(&self) -> u64 {
        self.len
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A format error at `offset`.
    pub fn error(&self, offset: u64, what: impl std::fmt::Display) -> KinectError {
        KinectError::format(&self.path, format!("byte {offset}: {what}"))
    }

    fn goto(&mut self, offset: u64) -> Result<()> {
        if offset == self.pos {
            return Ok(());
        }
        let delta = i64::try_from(offset).ok().zip(i64::try_from(self.pos).ok());
        let moved = match delta {
            Some((to, from)) => self.reader.seek_relative(to - from),
            None => self.reader.seek(SeekFrom::Start(offset)).map(|_| ()),
        };
        moved.map_err(|e| KinectError::io(&self.path, e))?;
        self.pos = offset;
        Ok(())
    }

    /// Read exactly `buf.len()` bytes at `offset`; a read past the end is a format error.
    pub fn read_at(&mut self, offset: u64, buf: &mut [u8]) -> Result<()> {
        let end = offset.checked_add(buf.len() as u64);
        if end.is_none_or(|e| e > self.len) {
            return Err(self.error(
                offset,
                format!(
                    "{} bytes asked for, the file ends at byte {} (truncated?)",
                    buf.len(),
                    self.len
                ),
            ));
        }
        self.goto(offset)?;
        self.reader
            .read_exact(buf)
            .map_err(|e| KinectError::io(&self.path, e))?;
        self.pos = offset + buf.len() as u64;
        Ok(())
    }

    /// Read `size` bytes at `offset` into a new buffer, refusing more than `limit` bytes
    /// (`what` names the element in the error).
    pub fn read_vec(&mut self, offset: u64, size: u64, limit: u64, what: &str) -> Result<Vec<u8>> {
        if size > limit {
            return Err(self.error(
                offset,
                format!("{what} of {size} bytes is larger than the {limit} bytes allowed"),
            ));
        }
        let mut buf = vec![
            0u8;
            usize::try_from(size)
                .unwrap_or(usize::MAX)
                .min(limit as usize)
        ];
        self.read_at(offset, &mut buf)?;
        Ok(buf)
    }

    /// The element header at `offset`, with its data checked to end by `parent_end` (the
    /// file's end for top-level elements). `None` when `offset` is at or past `parent_end`.
    pub fn header(&mut self, offset: u64, parent_end: u64) -> Result<Option<Header>> {
        if offset >= parent_end {
            return Ok(None);
        }
        let avail = (parent_end - offset).min((MAX_ID_BYTES + MAX_SIZE_BYTES) as u64) as usize;
        let mut buf = [0u8; MAX_ID_BYTES + MAX_SIZE_BYTES];
        self.read_at(offset, &mut buf[..avail])?;
        let header = parse_header(&buf[..avail])
            .map_err(|what| self.error(offset, what))?
            .ok_or_else(|| self.error(offset, "an element header is cut off"))?;
        let (id, size, used) = header;
        let data_start = offset + used as u64;
        if let Some(s) = size
            && data_start.checked_add(s).is_none_or(|e| e > parent_end)
        {
            let whom = if parent_end == self.len {
                "the file (truncated?)"
            } else {
                "its parent element"
            };
            return Err(self.error(
                offset,
                format!("element 0x{id:X} of {s} bytes runs past the end of {whom}"),
            ));
        }
        Ok(Some(Header {
            id,
            data_start,
            size,
        }))
    }
}

/// Parse an element header from the start of `bytes`: `(id, size, header length)`, `Ok(None)`
/// when `bytes` is too short to hold it.
fn parse_header(bytes: &[u8]) -> std::result::Result<Option<(u32, Option<u64>, usize)>, String> {
    let Some(&first) = bytes.first() else {
        return Ok(None);
    };
    let id_len = first.leading_zeros() as usize + 1;
    if id_len > MAX_ID_BYTES {
        return Err(format!("byte 0x{first:02X} does not start an element ID"));
    }
    let Some(id_bytes) = bytes.get(..id_len) else {
        return Ok(None);
    };
    let id = id_bytes.iter().fold(0u32, |a, &b| (a << 8) | u32::from(b));
    let Some(&size_first) = bytes.get(id_len) else {
        return Ok(None);
    };
    let size_len = size_first.leading_zeros() as usize + 1;
    if size_len > MAX_SIZE_BYTES {
        return Err(format!(
            "element 0x{id:X}: byte 0x{size_first:02X} does not start a data size"
        ));
    }
    let Some(size_bytes) = bytes.get(id_len..id_len + size_len) else {
        return Ok(None);
    };
    let marker_cleared = u64::from(size_first) & (0xFF >> size_len);
    let value = size_bytes[1..]
        .iter()
        .fold(marker_cleared, |a, &b| (a << 8) | u64::from(b));
    let all_ones = (1u64 << (7 * size_len)) - 1;
    let size = (value != all_ones).then_some(value);
    Ok(Some((id, size, id_len + size_len)))
}

/// A variable-length integer with its marker removed (Matroska block track numbers):
/// `(value, length)`.
pub(crate) fn parse_vint(bytes: &[u8]) -> Option<(u64, usize)> {
    let &first = bytes.first()?;
    let len = first.leading_zeros() as usize + 1;
    if len > MAX_SIZE_BYTES {
        return None;
    }
    let rest = bytes.get(1..len)?;
    let value = rest.iter().fold(u64::from(first) & (0xFF >> len), |a, &b| {
        (a << 8) | u64::from(b)
    });
    Some((value, len))
}

/// One child element of a master held in memory.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Child<'a> {
    pub id: u32,
    /// Offset of the element in the file (for errors).
    pub offset: u64,
    pub data: &'a [u8],
}

/// The children of a master element whose data (`data`, starting at file offset `base`) is in
/// memory. Unknown sizes are not allowed here.
pub(crate) fn children<'a>(data: &'a [u8], base: u64, path: &Path) -> Result<Vec<Child<'a>>> {
    let mut out = Vec::new();
    let mut at = 0usize;
    while at < data.len() {
        let offset = base + at as u64;
        let bad = |what: String| KinectError::format(path, format!("byte {offset}: {what}"));
        let (id, size, used) = parse_header(&data[at..])
            .map_err(bad)?
            .ok_or_else(|| bad("an element header is cut off".into()))?;
        let size = size.ok_or_else(|| bad(format!("element 0x{id:X} has an unknown size")))?;
        let start = at + used;
        let end = usize::try_from(size)
            .ok()
            .and_then(|s| start.checked_add(s))
            .filter(|&e| e <= data.len())
            .ok_or_else(|| {
                bad(format!(
                    "element 0x{id:X} of {size} bytes runs past the end of its parent"
                ))
            })?;
        out.push(Child {
            id,
            offset,
            data: &data[start..end],
        });
        at = end;
    }
    Ok(out)
}

/// An unsigned integer element (0 to 8 bytes, big-endian).
pub(crate) fn uint(child: &Child<'_>, path: &Path) -> Result<u64> {
    if child.data.len() > 8 {
        return Err(KinectError::format(
            path,
            format!(
                "byte {}: integer element 0x{:X} has {} bytes (at most 8)",
                child.offset,
                child.id,
                child.data.len()
            ),
        ));
    }
    Ok(be_uint(child.data))
}

/// A big-endian unsigned integer of at most 8 bytes.
pub(crate) fn be_uint(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0u64, |a, &b| (a << 8) | u64::from(b))
}

/// A string element (ASCII or UTF-8; trailing NULs removed). Invalid UTF-8 is a format error.
pub(crate) fn string(child: &Child<'_>, path: &Path) -> Result<String> {
    let trimmed = child
        .data
        .iter()
        .rposition(|&b| b != 0)
        .map_or(&child.data[..0], |last| &child.data[..=last]);
    std::str::from_utf8(trimmed)
        .map(str::to_owned)
        .map_err(|_| {
            KinectError::format(
                path,
                format!(
                    "byte {}: string element 0x{:X} is not UTF-8",
                    child.offset, child.id
                ),
            )
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_parse_ids_sizes_and_unknown_sizes() {
        // Segment ID, 8-byte unknown size.
        let seg = [
            0x18, 0x53, 0x80, 0x67, 0x01, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF,
        ];
        assert_eq!(parse_header(&seg), Ok(Some((0x1853_8067, None, 12))));
        // SimpleBlock, 2-byte size 0x123.
        assert_eq!(
            parse_header(&[0xA3, 0x41, 0x23]),
            Ok(Some((0xA3, Some(0x123), 3)))
        );
        // 1-byte unknown size is 0xFF.
        assert_eq!(parse_header(&[0xEC, 0xFF]), Ok(Some((0xEC, None, 2))));
        assert_eq!(parse_header(&[0x1A, 0x45]), Ok(None));
        assert!(parse_header(&[0x00, 0x81]).is_err());
        assert!(parse_header(&[0xEC, 0x00]).is_err());
        assert_eq!(parse_vint(&[0x81]), Some((1, 1)));
        assert_eq!(parse_vint(&[0x40, 0x02]), Some((2, 2)));
        assert_eq!(parse_vint(&[0x40]), None);
    }

    #[test]
    fn children_refuse_overruns() {
        let path = Path::new("<test>");
        let ok = [0xD7, 0x81, 0x05, 0x86, 0x82, b'A', b'B'];
        let kids = children(&ok, 100, path).unwrap();
        assert_eq!(kids.len(), 2);
        assert_eq!(uint(&kids[0], path).unwrap(), 5);
        assert_eq!(string(&kids[1], path).unwrap(), "AB");
        assert_eq!(kids[1].offset, 103);
        let overrun = [0xD7, 0x85, 0x05];
        let err = children(&overrun, 0, path).unwrap_err().to_string();
        assert!(err.contains("runs past"), "{err}");
    }
}
