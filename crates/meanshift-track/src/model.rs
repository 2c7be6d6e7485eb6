//! Appearance models of the tracker: what a marker looks like, and how much each pixel of a
//! new frame looks like it.

use image::RgbImage;

use crate::backproject::BackProjector;
use crate::error::{Result, TrackError};
use crate::histogram::{Histogram, HistogramSpec};
use crate::hsv::{ChannelRange, rgb_to_gray, rgb_to_hsv};
use crate::rect::PixelRect;

/// What the tracker models a marker's appearance with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AppearanceModel {
    /// Hue histogram with OpenCV's back-projection (the paper's model; OpenCV's CamShift
    /// sample). Pixels outside [`crate::TrackerConfig::hsv_mask`] do not count.
    Hue {
        /// Bins over hue 0..180.
        bins: usize,
    },
    /// Hue–saturation histogram with back-projection; separates a saturated red marker from
    /// paler reddish bark better than hue alone.
    HueSaturation {
        /// Bins over hue 0..180.
        hue_bins: usize,
        /// Bins over saturation 0..256.
        saturation_bins: usize,
    },
    /// RGB histogram with kernel weighting and the Bhattacharyya coefficient (Comaniciu,
    /// Ramesh, Meer 2003, "Kernel-based object tracking", IEEE TPAMI 25(5)): the mean-shift
    /// weights are `sqrt(q_u / p_u)` of the target and candidate histograms. With
    /// [`crate::TrackerConfig::background_weighting`] the target histogram is background
    /// weighted (their section 6.2); holes (black in every channel, see
    /// `HOLE_LEVEL`) are no data; every colour of the marker weighs alike in the
    /// back-projection its blobs are measured on; and with recovery on, each frame is read
    /// as the first frame's light would have shown it (the light's change per channel
    /// measured on a sparse grid of the frame), since RGB bins, unlike a hue, move with it.
    Rgb {
        /// Bins per channel over 0..256.
        bins: usize,
    },
    /// Gray-level histogram with back-projection, for black/white targets where hue means
    /// nothing.
    Gray {
        /// Bins over 0..256.
        bins: usize,
    },
}

impl AppearanceModel {
    /// The paper's model: a hue histogram; 16 bins as OpenCV's CamShift sample.
    pub const PAPER: AppearanceModel = AppearanceModel::Hue { bins: 16 };

    /// The name used on command lines and in files: `hue`, `hs`, `rgb`, `gray`.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Hue { .. } => "hue",
            Self::HueSaturation { .. } => "hs",
            Self::Rgb { .. } => "rgb",
            Self::Gray { .. } => "gray",
        }
    }

    /// The model of a name (`hue`, `hs`, `rgb`, `gray`) with its default bins: 16 hue bins;
    /// 16x4 hue–saturation (coarse saturation bins keep blurred markers in the model); 16 per RGB channel (Comaniciu et al. use 16x16x16); 32 gray.
    ///
    /// # Errors
    /// [`TrackError::InvalidParameter`] for any other name.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "hue" => Ok(Self::PAPER),
            "hs" => Ok(Self::HueSaturation {
                hue_bins: 16,
                saturation_bins: 4,
            }),
            "rgb" => Ok(Self::Rgb { bins: 16 }),
            "gray" => Ok(Self::Gray { bins: 32 }),
            other => Err(TrackError::param(
                "appearance model",
                format!("{other:?}; expected hue, hs, rgb or gray"),
            )),
        }
    }

    /// The histogram layout of the model (over HSV for hue/hs, RGB for rgb, gray for gray).
    pub fn spec(&self) -> HistogramSpec {
        match *self {
            Self::Hue { bins } => HistogramSpec::hue(bins),
            Self::HueSaturation {
                hue_bins,
                saturation_bins,
            } => HistogramSpec::hue_saturation(hue_bins, saturation_bins),
            Self::Rgb { bins } => HistogramSpec::rgb(bins),
            Self::Gray { bins } => HistogramSpec::gray(bins),
        }
    }

    /// The colour values the model's histogram reads from an RGB pixel, and whether the pixel
    /// counts at all (the HSV mask).
    #[inline]
    pub(crate) fn features(&self, rgb: [u8; 3], mask: &ChannelRange) -> Option<[u8; 3]> {
        match self {
            Self::Hue { .. } | Self::HueSaturation { .. } => {
                let hsv = rgb_to_hsv(rgb);
                mask.contains(hsv).then_some(hsv)
            }
            Self::Rgb { .. } => Some(rgb),
            Self::Gray { .. } => Some([rgb_to_gray(rgb), 0, 0]),
        }
    }
}

/// A marker's learned appearance.
#[derive(Debug, Clone)]
pub(crate) enum MarkerModel {
    /// Back-projection of a normalised histogram (hue, hue–saturation, gray).
    Projected { projector: BackProjector },
    /// Kernel-weighted target histogram `q` (sums to 1; with the tracker's
    /// `background_weighting` each bin times the share of its pixels about the window that
    /// lie inside it, `h / (h + o)`, Comaniciu et al.'s section 6.2 as Ning et al. 2012
    /// correct it: the target only) for Bhattacharyya tracking, and per bin a weight 0..255
    /// for the back-projection that blobs are found and measured on: 255 times
    /// `min(1, q / (KERNEL_FULL_WEIGHT_SHARE top))` times that share again, so that every
    /// colour of the marker weighs alike and the background's colours, spread thin over many
    /// bins by noise, stay near 0.
    Kernel {
        hist: Histogram,
        q: Vec<f64>,
        weight: Vec<f32>,
    },
}

/// Feature bytes of every pixel of `rect` (inside the image), row-major, 3 per pixel, with
/// `None` for masked-out pixels.
fn features_in(
    frame: &RgbImage,
    rect: PixelRect,
    model: &AppearanceModel,
    mask: &ChannelRange,
) -> Vec<Option<[u8; 3]>> {
    let mut out = Vec::with_capacity(rect.area() as usize);
    for y in rect.y..rect.bottom() as i32 {
        for x in rect.x..rect.right() as i32 {
            let p = frame.get_pixel(x as u32, y as u32).0;
            out.push(model.features(p, mask));
        }
    }
    out
}

impl MarkerModel {
    /// Learn from the pixels of `window` (inside the frame).
    pub(crate) fn learn(
        id: &str,
        frame: &RgbImage,
        window: PixelRect,
        model: &AppearanceModel,
        mask: &ChannelRange,
        background_weighting: bool,
    ) -> Result<Self> {
        let features = features_in(frame, window, model, mask);
        let mut hist = Histogram::new(model.spec())?;
        let (w, h) = (window.width as usize, window.height as usize);
        let mut used = 0usize;
        let mut q = vec![0.0; hist.values().len()];
        let holes = holes_are_no_data(model);
        for (k, f) in features.iter().enumerate() {
            let Some(f) = f.filter(|f| !(holes && is_hole(*f))) else {
                continue;
            };
            let Some(bin) = hist.bin_of(&f) else { continue };
            used += 1;
            hist.values_mut()[bin] += 1.0;
            // Epanechnikov kernel profile over the window's inscribed ellipse.
            let (i, j) = ((k % w) as f64, (k / w) as f64);
            let r2 = kernel_r2(i, j, w, h);
            if r2 < 1.0 {
                q[bin] += 1.0 - r2;
            }
        }
        if used == 0 {
            let what = if holes {
                "has data (black is a hole for it)"
            } else {
                "passes its mask"
            };
            return Err(TrackError::EmptyModel {
                id: id.to_string(),
                reason: format!(
                    "none of its {} pixels {what} under the {} model",
                    window.area(),
                    model.name()
                ),
            });
        }
        match model {
            AppearanceModel::Rgb { .. } => {
                let total: f64 = q.iter().sum();
                if total <= 0.0 {
                    return Err(TrackError::EmptyModel {
                        id: id.to_string(),
                        reason: "the window is too small for a kernel".into(),
                    });
                }
                q.iter_mut().for_each(|v| *v /= total);
                // Per bin, the share of its pixels about the window that lie in it (1 where
                // the tracker does not weigh by the background).
                let mut inside = vec![1.0f64; q.len()];
                if background_weighting {
                    let ring = ring_counts(&hist, frame, window, model, mask);
                    for ((share, &h), &o) in inside.iter_mut().zip(hist.values()).zip(&ring) {
                        let h = f64::from(h);
                        if h > 0.0 {
                            *share = h / (h + o);
                        }
                    }
                    q.iter_mut().zip(&inside).for_each(|(v, s)| *v *= s);
                    let kept: f64 = q.iter().sum();
                    if kept > 0.0 {
                        q.iter_mut().for_each(|v| *v /= kept);
                    }
                }
                let top = q.iter().copied().fold(0.0, f64::max);
                let full = KERNEL_FULL_WEIGHT_SHARE * top;
                let weight = q
                    .iter()
                    .zip(&inside)
                    .map(|(&v, &share)| (255.0 * (v / full).min(1.0) * share) as f32)
                    .collect();
                Ok(Self::Kernel { hist, q, weight })
            }
            _ => {
                if background_weighting {
                    weigh_by_background(&mut hist, frame, window, model, mask);
                }
                hist.normalize_min_max(0.0, 255.0)?;
                // A histogram with every bin equal normalises to all zero: keep the counts.
                if hist.values().iter().all(|&v| v == 0.0) {
                    hist.values_mut().iter_mut().for_each(|v| *v = 255.0);
                }
                Ok(Self::Projected {
                    projector: BackProjector::new(hist, 1.0)?,
                })
            }
        }
    }
}

/// A pixel no brighter than this in every channel is a hole: a depth camera's colour image
/// is black where it has no colour for a pixel (a Kinect's holes, often in strips beside
/// edges), exactly 0 in every channel as registered frames leave them; 2 allows for a
/// codec's rounding.
pub(crate) const HOLE_LEVEL: u8 = 2;

/// Whether `rgb` is a hole (see [`HOLE_LEVEL`]).
#[inline(always)]
pub(crate) fn is_hole(rgb: [u8; 3]) -> bool {
    rgb.iter().all(|&c| c <= HOLE_LEVEL)
}

/// Whether the model counts holes as no data: the kernel (RGB) model, where black is a
/// colour like any other. The histogram models leave holes out by the HSV mask's value
/// floor; the gray model keeps them (a black dot on a white target is what it tracks, and
/// a real camera's black reaches 0).
pub(crate) fn holes_are_no_data(model: &AppearanceModel) -> bool {
    matches!(model, AppearanceModel::Rgb { .. })
}

/// Share of the kernel model's top bin (of `q`) from which a bin weighs fully in its
/// back-projection (times the share of its pixels about the window that lie inside it),
/// below it in proportion. A shaded marker spreads over many RGB bins, its lit side in the
/// fullest ones; weights in proportion to `q` pulled a blob's centroid 2-3 px toward the
/// light (the third generator's shaded spheres), where every colour of the marker weighing
/// alike centres it as a hue does. Chosen on the third generator's tuning seeds 1-39
/// (`docs/validation.md`: 1/8, 1/16 and 1/32 within 0.1 point of each other, 1/2 a point
/// and a half lower, every bin of the window alike 20 points lower).
pub(crate) const KERNEL_FULL_WEIGHT_SHARE: f64 = 1.0 / 16.0;

/// Background weighting in the spirit of Comaniciu, Ramesh, Meer (2003), section 6.2: each
/// bin `h_u` becomes `h_u² / (h_u + o_u)`, where `o_u` counts the bin in a ring one window
/// wide around the window (eight times the window's area), so colours common around the
/// marker (the background also inside its window) stop attracting the window. Their
/// `min(o*/o_u, 1)` leaves a uniform background at full weight (one non-zero bin is its own
/// minimum); the ratio `h_u / (h_u + o_u)` does not.
fn weigh_by_background(
    hist: &mut Histogram,
    frame: &RgbImage,
    window: PixelRect,
    model: &AppearanceModel,
    mask: &ChannelRange,
) {
    let background = ring_counts(hist, frame, window, model, mask);
    for (v, &o) in hist.values_mut().iter_mut().zip(&background) {
        let h = f64::from(*v);
        if h > 0.0 {
            *v = (h * h / (h + o)) as f32;
        }
    }
}

/// Per bin of `hist`, the pixels of the ring one window wide around `window` (inside the
/// frame) that fall in it.
fn ring_counts(
    hist: &Histogram,
    frame: &RgbImage,
    window: PixelRect,
    model: &AppearanceModel,
    mask: &ChannelRange,
) -> Vec<f64> {
    let ring = window
        .grown(window.width, window.height)
        .intersect(&PixelRect::image(frame.width(), frame.height()));
    let mut background = vec![0.0f64; hist.values().len()];
    for y in ring.y..ring.bottom() as i32 {
        for x in ring.x..ring.right() as i32 {
            let inside = x >= window.x
                && y >= window.y
                && i64::from(x) < window.right()
                && i64::from(y) < window.bottom();
            if inside {
                continue;
            }
            let p = frame.get_pixel(x as u32, y as u32).0;
            if let Some(bin) = model.features(p, mask).and_then(|f| hist.bin_of(&f)) {
                background[bin] += 1.0;
            }
        }
    }
    background
}

/// Squared normalised distance of pixel `(i, j)` of a `w` x `h` window from its centre, in
/// units of the half-sizes (1 on the inscribed ellipse).
#[inline]
pub(crate) fn kernel_r2(i: f64, j: f64, w: usize, h: usize) -> f64 {
    let hx = (w as f64 * 0.5).max(0.5);
    let hy = (h as f64 * 0.5).max(0.5);
    let dx = (i - (w as f64 - 1.0) * 0.5) / hx;
    let dy = (j - (h as f64 - 1.0) * 0.5) / hy;
    dx * dx + dy * dy
}

/// Lowest saturation a marker's own limits may go down to: below it, a pixel is gray and its
/// hue is noise (8-bit levels; a grey wall with colour noise stays under about 20).
const SATURATION_FLOOR: u8 = 24;
/// Lowest value a marker's own limits may go down to (8-bit levels).
const VALUE_FLOOR: u8 = 16;
/// A marker's limits keep this share of the saturation and value of its palest tenth of
/// pixels: a marker blurred into a streak two and a half times its width is covered at most
/// about 0.4 of the exposure at its ends, and loses saturation in proportion.
const MASK_MARGIN: f64 = 0.5;

/// The HSV limits of the marker in `window`: as `mask`, with the saturation and value floors
/// lowered to half of what the marker's palest tenth shows (never below a gray's), so that a
/// blurred, paler marker still counts. For the models that read RGB or gray, `mask` as is.
pub(crate) fn marker_mask(
    frame: &RgbImage,
    window: PixelRect,
    model: &AppearanceModel,
    mask: &ChannelRange,
) -> ChannelRange {
    if !matches!(
        model,
        AppearanceModel::Hue { .. } | AppearanceModel::HueSaturation { .. }
    ) {
        return *mask;
    }
    let (w, h) = (window.width.max(1) as usize, window.height.max(1) as usize);
    let mut s = Vec::new();
    let mut v = Vec::new();
    for (k, f) in features_in(frame, window, model, mask).iter().enumerate() {
        let Some(hsv) = f else { continue };
        if kernel_r2((k % w) as f64, (k / w) as f64, w, h) < 0.5 {
            s.push(hsv[1]);
            v.push(hsv[2]);
        }
    }
    if s.is_empty() {
        return *mask;
    }
    let tenth = |values: &mut Vec<u8>| {
        let i = values.len() / 10;
        *values.select_nth_unstable(i).1
    };
    let (s10, v10) = (tenth(&mut s), tenth(&mut v));
    let lower = |floor: u8, own: u8, given: u8| {
        ((f64::from(own) * MASK_MARGIN).round() as u8)
            .max(floor)
            .min(given)
    };
    ChannelRange {
        lower: [
            mask.lower[0],
            lower(SATURATION_FLOOR, s10, mask.lower[1]),
            lower(VALUE_FLOOR, v10, mask.lower[2]),
        ],
        upper: mask.upper,
    }
}

/// The median saturation (HSV, 0..255) of the pixels of the middle of `window` (its
/// inscribed ellipse shrunk by 1/sqrt(2), where a window drawn about a marker holds the
/// marker) that lie inside `frame`, holes (black: every channel at most 2, no data) left
/// out; `None` when none is left. A colour model tells a marker from gray surroundings by its colour: a window whose median is under the HSV
/// mask's saturation floor ([`crate::TrackerConfig::hsv_mask`], 60 by default) holds a
/// black-and-white target, or one paled by the light, which the gray model is for (the real
/// vibration frames' white targets: 21-43, against 160 and more for the third generator's
/// coloured markers).
///
/// # Examples
/// ```
/// use meanshift_track::{PixelRect, window_saturation};
/// let frame = image::RgbImage::from_fn(40, 40, |x, _| {
///     image::Rgb(if x < 20 { [220, 30, 30] } else { [200, 200, 200] })
/// });
/// assert!(window_saturation(&frame, PixelRect::new(0, 0, 20, 40)).unwrap() > 200);
/// assert_eq!(window_saturation(&frame, PixelRect::new(20, 0, 20, 40)), Some(0));
/// ```
pub fn window_saturation(frame: &RgbImage, window: PixelRect) -> Option<u8> {
    let inside = window.intersect(&PixelRect::image(frame.width(), frame.height()));
    let (w, h) = (window.width.max(1) as usize, window.height.max(1) as usize);
    let mut saturations: Vec<u8> = Vec::with_capacity(inside.area() as usize);
    for y in inside.y..inside.bottom() as i32 {
        for x in inside.x..inside.right() as i32 {
            let (i, j) = (f64::from(x - window.x), f64::from(y - window.y));
            let p = frame.get_pixel(x as u32, y as u32).0;
            if kernel_r2(i, j, w, h) < 0.5 && !is_hole(p) {
                saturations.push(rgb_to_hsv(p)[1]);
            }
        }
    }
    if saturations.is_empty() {
        return None;
    }
    let mid = saturations.len() / 2;
    Some(*saturations.select_nth_unstable(mid).1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_s_saturation_leaves_out_holes_and_the_outside() {
        let frame = RgbImage::from_fn(30, 20, |x, _| {
            image::Rgb(match x {
                0..10 => [0, 0, 0],
                10..20 => [40, 200, 60],
                _ => [128, 128, 128],
            })
        });
        // Holes and the part outside the frame do not count: only the green remains.
        let green = window_saturation(&frame, PixelRect::new(-5, -5, 30, 50));
        assert_eq!(green, Some(rgb_to_hsv([40, 200, 60])[1]));
        // The middle of the window decides: a red disc filling it, in a gray corner.
        let disc = RgbImage::from_fn(20, 20, |x, y| {
            let r2 = (x as i32 - 10).pow(2) + (y as i32 - 10).pow(2);
            image::Rgb(if r2 <= 36 {
                [215, 25, 30]
            } else {
                [110, 115, 105]
            })
        });
        let red = window_saturation(&disc, PixelRect::new(2, 2, 17, 17));
        assert_eq!(red, Some(rgb_to_hsv([215, 25, 30])[1]));
        assert_eq!(
            window_saturation(&frame, PixelRect::new(0, 0, 10, 20)),
            None
        );
        assert_eq!(window_saturation(&frame, PixelRect::new(40, 0, 5, 5)), None);
        assert_eq!(
            window_saturation(&frame, PixelRect::new(20, 0, 10, 20)),
            Some(0)
        );
    }
}
