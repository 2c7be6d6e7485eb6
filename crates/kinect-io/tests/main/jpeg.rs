//! JPEG structure checks: a cut file is an error naming it, real files pass.

use super::*;

/// A JPEG of a textured scene (so the compressed data is long enough to cut anywhere).
fn textured_jpeg() -> Vec<u8> {
    let image = RgbImage::from_fn(160, 120, |x, y| {
        image::Rgb([
            (x * 7 % 256) as u8,
            (y * 13 % 256) as u8,
            ((x ^ y) % 256) as u8,
        ])
    });
    let mut bytes = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 90)
        .encode_image(&image)
        .unwrap();
    bytes
}

/// Issue 20: a colour JPEG cut to a quarter or a tenth decoded as grey without a word.
#[test]
fn a_truncated_jpeg_is_an_error_naming_the_file_not_grey_pixels() {
    let whole = textured_jpeg();
    let path = Path::new("frame_0007.jpg");
    assert!(decode_color_image(&whole, path).is_ok());
    // Data after the end-of-image marker (some cameras append metadata) is allowed.
    let mut appended = whole.clone();
    appended.extend_from_slice(b"trailing metadata");
    assert!(decode_color_image(&appended, path).is_ok());
    let n = whole.len();
    let mut cuts: Vec<usize> = (1..20).map(|k| n * k / 20).collect();
    cuts.extend([2, 3, 4, n - 2, n - 1]);
    for cut in cuts {
        let e = decode_color_image(&whole[..cut], path)
            .err()
            .unwrap_or_else(|| panic!("cut at {cut} of {n} bytes decoded"));
        assert!(e.to_string().contains("frame_0007.jpg"), "{e}");
    }
}

/// The structure check accepts every real JPEG in `../shared/data` (different encoders:
/// phones, Kinect v2 and Azure Kinect), when present.
#[test]
fn real_jpegs_pass_the_structure_check() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if !root.exists() {
        eprintln!("skipped: {} is not there", root.display());
        return;
    }
    let mut stack = vec![root];
    let mut checked = 0;
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let p = entry.path();
            if p.is_dir() {
                stack.push(p);
            } else if p
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("jpg") || e.eq_ignore_ascii_case("jpeg"))
            {
                let bytes = std::fs::read(&p).unwrap();
                if let Err(e) = decode_color_image(&bytes, &p) {
                    assert!(
                        !e.to_string().contains("corrupt JPEG"),
                        "{}: {e}",
                        p.display()
                    );
                }
                checked += 1;
            }
        }
    }
    eprintln!("{checked} real JPEGs checked");
}
