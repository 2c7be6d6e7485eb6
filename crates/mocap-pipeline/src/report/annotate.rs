//! Marker windows and names drawn on the projection image, with a small bitmap font (no
//! font files, no dependency): `projection.png` shows which marker is which.

use image::{Rgb, RgbImage};
use nalgebra::Point2;

/// Glyph width and height, pixels (before scaling).
const GLYPH_W: u32 = 5;
const GLYPH_H: u32 = 7;
/// Outline and label colours: yellow on a black halo reads on bark, sky and grass.
const INK: Rgb<u8> = Rgb([255, 230, 0]);
const HALO: Rgb<u8> = Rgb([0, 0, 0]);

/// 5x7 glyphs, one row per byte (bit 4 is the left column), for `0-9`, `A-Z`, `-`, `_`,
/// `.`; lowercase letters are drawn as capitals, anything else as `?`.
fn glyph(c: char) -> [u8; 7] {
    match c.to_ascii_uppercase() {
        '0' => [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        '1' => [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
        '2' => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
        '3' => [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
        '4' => [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
        '5' => [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
        '6' => [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
        '7' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
        '9' => [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
        'A' => [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'B' => [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E],
        'C' => [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E],
        'D' => [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C],
        'E' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F],
        'F' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10],
        'G' => [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F],
        'H' => [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'I' => [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'J' => [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C],
        'K' => [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F],
        'M' => [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11],
        'N' => [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
        'O' => [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'P' => [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10],
        'Q' => [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D],
        'R' => [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11],
        'S' => [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E],
        'T' => [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'V' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'W' => [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A],
        'X' => [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11],
        'Y' => [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04],
        'Z' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F],
        '-' => [0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00],
        '_' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1F],
        '.' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C],
        _ => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x00, 0x04],
    }
}

fn put(image: &mut RgbImage, x: i64, y: i64, colour: Rgb<u8>) {
    if x >= 0 && y >= 0 && x < i64::from(image.width()) && y < i64::from(image.height()) {
        image.put_pixel(x as u32, y as u32, colour);
    }
}

/// `text` at `(x, y)` (top-left), each glyph pixel a `scale`-pixel square, on a halo.
fn text(image: &mut RgbImage, x: i64, y: i64, text: &str, scale: u32) {
    let s = i64::from(scale);
    for pass in [HALO, INK] {
        let grow = i64::from(pass == HALO);
        for (k, c) in text.chars().enumerate() {
            let x0 = x + k as i64 * (i64::from(GLYPH_W) + 1) * s;
            for (row, bits) in glyph(c).iter().enumerate() {
                for col in 0..GLYPH_W {
                    if bits & (0x10 >> col) == 0 {
                        continue;
                    }
                    let (px, py) = (x0 + i64::from(col) * s, y + row as i64 * s);
                    for dy in -grow..s + grow {
                        for dx in -grow..s + grow {
                            put(image, px + dx, py + dy, pass);
                        }
                    }
                }
            }
        }
    }
}

/// Draw each marker's window (centre, side in pixels) as a square outline with its name
/// above it, the text scaled with the image (readable at 960 px and 1920 px wide).
pub fn annotate(image: &mut RgbImage, marks: &[(String, Point2<f64>, i32)]) {
    let scale = (image.width() / 480).clamp(1, 4);
    for (id, c, side) in marks {
        if !(c.x.is_finite() && c.y.is_finite()) {
            continue;
        }
        let half = i64::from((*side).max(3)) / 2 + 2;
        let (cx, cy) = (c.x.round() as i64, c.y.round() as i64);
        for d in -half..=half {
            for (x, y) in [
                (cx + d, cy - half),
                (cx + d, cy + half),
                (cx - half, cy + d),
                (cx + half, cy + d),
            ] {
                put(image, x, y, INK);
            }
        }
        let label_h = i64::from(GLYPH_H * scale);
        text(image, cx - half, cy - half - label_h - 3, id, scale);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_and_names_are_drawn_inside_the_image_only() {
        let mut image = RgbImage::new(100, 60);
        annotate(
            &mut image,
            &[
                ("A1".into(), Point2::new(30.0, 30.0), 10),
                ("edge".into(), Point2::new(99.0, 0.0), 10),
                ("nan".into(), Point2::new(f64::NAN, 0.0), 10),
            ],
        );
        // The outline's left edge and a pixel of the label above it are ink.
        assert_eq!(*image.get_pixel(23, 30), INK);
        let inked = (0..100)
            .flat_map(|x| (0..16).map(move |y| (x, y)))
            .filter(|&(x, y)| *image.get_pixel(x, y) == INK)
            .count();
        assert!(inked > 20, "label pixels {inked}");
        // The window's inside is untouched.
        assert_eq!(*image.get_pixel(30, 30), Rgb([0, 0, 0]));
    }

    #[test]
    fn every_glyph_is_five_columns_wide() {
        for c in "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ-_.?".chars() {
            assert!(glyph(c).iter().all(|row| *row < 0x20), "{c}");
        }
        assert_eq!(glyph('a'), glyph('A'));
    }
}
