//! Motion-JPEG frames without Huffman tables. A UVC camera's MJPEG frames (webcams, and the
//! colour streams of RGB-D cameras recorded as MJPG) often leave out the DHT segment and rely
//! on the standard tables of ITU-T T.81 Annex K.3 (Microsoft's AVI1 "MJPG" convention);
//! libjpeg puts those tables in when a scan starts without any. The `image` crate's decoder
//! does not, so they are inserted here before the first scan of such a frame.

/// One Huffman table of T.81 Annex K: its class and id byte (`Tc << 4 | Th`), the number of
/// codes of each length 1..16, and the values in code order.
struct HuffmanTable {
    class_id: u8,
    counts: [u8; 16],
    values: &'static [u8],
}

/// Table K.3: class 0, id 0.
const DC_LUMINANCE: HuffmanTable = HuffmanTable {
    class_id: 0x00,
    counts: [0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0],
    values: &[
        0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08, 0x09, 0x0a, 0x0b,
    ],
};

/// Table K.5: class 1, id 0.
const AC_LUMINANCE: HuffmanTable = HuffmanTable {
    class_id: 0x10,
    counts: [0, 2, 1, 3, 3, 2, 4, 3, 5, 5, 4, 4, 0, 0, 1, 125],
    values: &[
        0x01, 0x02, 0x03, 0x00, 0x04, 0x11, 0x05, 0x12, 0x21, 0x31, 0x41, 0x06, 0x13, 0x51, 0x61,
        0x07, 0x22, 0x71, 0x14, 0x32, 0x81, 0x91, 0xa1, 0x08, 0x23, 0x42, 0xb1, 0xc1, 0x15, 0x52,
        0xd1, 0xf0, 0x24, 0x33, 0x62, 0x72, 0x82, 0x09, 0x0a, 0x16, 0x17, 0x18, 0x19, 0x1a, 0x25,
        0x26, 0x27, 0x28, 0x29, 0x2a, 0x34, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44, 0x45,
        0x46, 0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63, 0x64,
        0x65, 0x66, 0x67, 0x68, 0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x83,
        0x84, 0x85, 0x86, 0x87, 0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99,
        0x9a, 0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6,
        0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3, 0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3,
        0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda, 0xe1, 0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8,
        0xe9, 0xea, 0xf1, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9, 0xfa,
    ],
};

/// Table K.4: class 0, id 1.
const DC_CHROMINANCE: HuffmanTable = HuffmanTable {
    class_id: 0x01,
    counts: [0, 3, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0],
    values: &[
        0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08, 0x09, 0x0a, 0x0b,
    ],
};

/// Table K.6: class 1, id 1.
const AC_CHROMINANCE: HuffmanTable = HuffmanTable {
    class_id: 0x11,
    counts: [0, 2, 1, 2, 4, 4, 3, 4, 7, 5, 4, 4, 0, 1, 2, 119],
    values: &[
        0x00, 0x01, 0x02, 0x03, 0x11, 0x04, 0x05, 0x21, 0x31, 0x06, 0x12, 0x41, 0x51, 0x07, 0x61,
        0x71, 0x13, 0x22, 0x32, 0x81, 0x08, 0x14, 0x42, 0x91, 0xa1, 0xb1, 0xc1, 0x09, 0x23, 0x33,
        0x52, 0xf0, 0x15, 0x62, 0x72, 0xd1, 0x0a, 0x16, 0x24, 0x34, 0xe1, 0x25, 0xf1, 0x17, 0x18,
        0x19, 0x1a, 0x26, 0x27, 0x28, 0x29, 0x2a, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44,
        0x45, 0x46, 0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63,
        0x64, 0x65, 0x66, 0x67, 0x68, 0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a,
        0x82, 0x83, 0x84, 0x85, 0x86, 0x87, 0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97,
        0x98, 0x99, 0x9a, 0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4,
        0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3, 0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca,
        0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda, 0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7,
        0xe8, 0xe9, 0xea, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9, 0xfa,
    ],
};
/// The four tables in the order libjpeg writes them.
const STANDARD_TABLES: [HuffmanTable; 4] =
    [DC_LUMINANCE, AC_LUMINANCE, DC_CHROMINANCE, AC_CHROMINANCE];

/// Where the first scan (SOS) of a JPEG starts, when no DHT segment comes before it; `None`
/// when the JPEG has its tables, or its segments cannot be walked (the decoder then says
/// what is wrong).
fn first_scan_without_tables(bytes: &[u8]) -> Option<usize> {
    if !bytes.starts_with(&[0xFF, 0xD8]) {
        return None;
    }
    let mut i = 2;
    loop {
        // Fill bytes before a marker.
        while bytes.get(i) == Some(&0xFF) && bytes.get(i + 1) == Some(&0xFF) {
            i += 1;
        }
        if bytes.get(i) != Some(&0xFF) {
            return None;
        }
        let marker = *bytes.get(i + 1)?;
        match marker {
            0xC4 => return None,
            0xDA => return Some(i),
            0xD8 | 0xD9 | 0x01 | 0xD0..=0xD7 => return None,
            _ => {}
        }
        let length = bytes.get(i + 2..i + 4)?;
        let length = usize::from(u16::from_be_bytes([length[0], length[1]]));
        if length < 2 {
            return None;
        }
        i += 2 + length;
    }
}

/// The JPEG with the standard Huffman tables inserted before its first scan, when it has
/// none; `None` when it needs nothing.
pub(crate) fn with_standard_tables(bytes: &[u8]) -> Option<Vec<u8>> {
    let at = first_scan_without_tables(bytes)?;
    let body: usize = STANDARD_TABLES
        .iter()
        .map(|t| 1 + t.counts.len() + t.values.len())
        .sum();
    let mut out = Vec::with_capacity(bytes.len() + body + 4);
    out.extend_from_slice(&bytes[..at]);
    out.extend_from_slice(&[0xFF, 0xC4]);
    out.extend_from_slice(&u16::try_from(body + 2).unwrap_or(u16::MAX).to_be_bytes());
    for t in &STANDARD_TABLES {
        out.push(t.class_id);
        out.extend_from_slice(&t.counts);
        out.extend_from_slice(t.values);
    }
    out.extend_from_slice(&bytes[at..]);
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_are_complete_and_counted() {
        for t in &STANDARD_TABLES {
            let n: usize = t.counts.iter().map(|&c| usize::from(c)).sum();
            assert_eq!(n, t.values.len(), "{:#04x}", t.class_id);
        }
        // Kraft: a complete prefix code of at most 16 bits leaves no code unused but the
        // all-ones one (T.81 reserves it).
        for t in &STANDARD_TABLES {
            let used: u32 = t
                .counts
                .iter()
                .enumerate()
                .map(|(len, &c)| u32::from(c) << (15 - len))
                .sum();
            assert!(used < 1 << 16, "{:#04x}: {used}", t.class_id);
        }
    }

    /// Remove every DHT segment before the first scan, as a UVC camera sends its frames.
    fn strip_tables(jpeg: &[u8]) -> Vec<u8> {
        let mut out = jpeg[..2].to_vec();
        let mut i = 2;
        while jpeg[i + 1] != 0xDA {
            let len = usize::from(u16::from_be_bytes([jpeg[i + 2], jpeg[i + 3]]));
            if jpeg[i + 1] != 0xC4 {
                out.extend_from_slice(&jpeg[i..i + 2 + len]);
            }
            i += 2 + len;
        }
        out.extend_from_slice(&jpeg[i..]);
        out
    }

    #[test]
    fn a_frame_without_tables_decodes_as_with_them() {
        // A colour gradient with a red disc, encoded by the `image` crate (standard tables).
        let image = image::RgbImage::from_fn(64, 48, |x, y| {
            let red = (x as i32 - 30).pow(2) + (y as i32 - 20).pow(2) < 100;
            image::Rgb(if red {
                [220, 30, 30]
            } else {
                [x as u8 * 4, y as u8 * 5, 90]
            })
        });
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 85)
            .encode_image(&image)
            .expect("encode");
        let bare = strip_tables(&jpeg);
        assert!(
            bare.len() < jpeg.len() - 400,
            "{} -> {}",
            jpeg.len(),
            bare.len()
        );
        let path = std::path::Path::new("frame.jpg");
        let whole = crate::depth::decode_color_image(&jpeg, path).expect("with tables");
        let fixed = crate::depth::decode_color_image(&bare, path).expect("without tables");
        assert_eq!(whole.as_raw(), fixed.as_raw());
        // Without the fix the decoder refuses it.
        assert!(image::load_from_memory(&bare).is_err());
    }

    #[test]
    fn tables_go_before_the_first_scan_only_when_missing() {
        // SOI, an APP0 of 4 bytes, SOS, data, EOI.
        let bare = [
            0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x04, 1, 2, 0xFF, 0xDA, 0x00, 0x02, 7, 0xFF, 0xD9,
        ];
        let fixed = with_standard_tables(&bare).expect("inserted");
        assert_eq!(&fixed[..8], &bare[..8]);
        assert_eq!(&fixed[8..10], &[0xFF, 0xC4]);
        assert_eq!(u16::from_be_bytes([fixed[10], fixed[11]]), 418);
        assert_eq!(&fixed[8 + 420..], &bare[8..]);
        // Already has tables: nothing to do; and not a JPEG.
        assert_eq!(with_standard_tables(&fixed), None);
        assert_eq!(with_standard_tables(b"not a jpeg"), None);
        assert_eq!(with_standard_tables(&bare[..7]), None);
    }
}
