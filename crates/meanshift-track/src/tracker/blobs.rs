//! Candidates from a frame: a marker's weights over a region, their blobs, the template's
//! matches, and what a blob says about the marker (width, colour, depth, holes).

use super::*;

/// Largest distance (windows) between a marker's prediction and its part of a blob split
/// from a look-alike touching it: a marker at rest, or in the first frame of its release
/// (a quarter window and more); a part farther off is not the marker's (the split gave its
/// pixels to the look-alike's side).
const OWN_PART_WINDOWS: f64 = 0.4;

/// Share of the pixels of `holds` whose colour changed since `previous` by more than
/// [`CHANGED_LEVEL`] in some channel: a marker that just arrived changed its pixels; a
/// static look-alike did not.
/// Without the previous frame over `holds`, everything changed.
pub(super) fn changed_share(frame: &RgbImage, previous: &PreviousFrame, holds: PixelRect) -> f64 {
    let r = holds.intersect(&image_rect(frame.width(), frame.height()));
    let Some((previous, [dx, dy])) = previous.covering_moved(r) else {
        return 1.0;
    };
    if r.is_empty() || previous.dimensions() != frame.dimensions() {
        return 1.0;
    }
    let (width, height) = (frame.width() as i32, frame.height() as i32);
    let (mut changed, mut all) = (0usize, 0usize);
    for y in r.y..r.bottom() as i32 {
        for x in r.x..r.right() as i32 {
            let (bx, by) = ((x - dx).clamp(0, width - 1), (y - dy).clamp(0, height - 1));
            let (a, b) = (
                frame.get_pixel(x as u32, y as u32).0,
                previous.get_pixel(bx as u32, by as u32).0,
            );
            all += 1;
            if a.iter()
                .zip(&b)
                .any(|(&p, &q)| p.abs_diff(q) > CHANGED_LEVEL)
            {
                changed += 1;
            }
        }
    }
    changed as f64 / all.max(1) as f64
}

/// Regions (a lost marker's gate) of more than this many marker windows may be weighed
/// sparsely: sampled first, and in full only about what was found (`region::Sparse`);
/// a 3x3-window quick region and a gate a few windows wide are weighed whole.
const SPARSE_MIN_WINDOWS: i64 = 36;
/// Least cell side of a sparse fill, pixels: past the sampling step and a blob's edge.
const SPARSE_MIN_CELL_PX: i32 = 4;
/// Frames for which a marker whose gate was found cluttered has it weighed whole (the
/// gate moves little from frame to frame, and a sampling pass cut short is wasted). Three
/// against ten before: a gate stays cluttered for fewer frames than ten, and the sampling
/// pass costs less than weighing the rest of the hold whole (`track_into` on the combined
/// stress condition, seeds 1000-1001: 866.7 M instructions with 10, 854.8 M with 3, 857.4 M
/// with 1; the same tracks, a sparse fill weighing what a full one does about every blob).
pub(super) const CLUTTER_HOLD_FRAMES: usize = 3;

/// The cells of a sparse fill for marker `m`: half a window (at least
/// [`SPARSE_MIN_CELL_PX`]), two of them about every hit (`region::Sparse`), so that the
/// window about a blob's centre and its box grown by a pixel are weighed.
fn sparse_cell(m: &MarkerState) -> (i32, i32) {
    let (w, h) = m.size;
    (
        (w / 2).max(SPARSE_MIN_CELL_PX),
        (h / 2).max(SPARSE_MIN_CELL_PX),
    )
}

/// The weights of marker `m`'s model over `rect`, with its mask, depth gate and the `masked`
/// rectangles, and its streak weights against the `previous` frame where it was kept over
/// `rect` (recovering tracker, colour models), with the marker's trail there (see
/// [`MarkerState::trail`]). With `sparse`, a region of more than
/// [`SPARSE_MIN_WINDOWS`] windows is weighed only about the blobs of the marker's look in it
/// (the same blobs and measurements as a full fill gives).
#[allow(clippy::too_many_arguments)]
pub(super) fn fill(
    region: &mut Region,
    config: &TrackerConfig,
    m: &MarkerState,
    frame: &RgbImage,
    previous: Option<&PreviousFrame>,
    depth: Option<&DepthView<'_>>,
    rect: PixelRect,
    masked: &[PixelRect],
    paler: &[(PixelRect, u8)],
    sparse: bool,
) {
    let gate = match (config.depth_gate_m, m.depth_m, depth) {
        (Some(g), Some(dm), Some(d)) => Some((g, dm, *d)),
        _ => None,
    };
    let colour_model = !matches!(config.model, AppearanceModel::Gray { .. });
    // Where the last frame was not kept over the region, no streak weights.
    let streak = previous
        .filter(|_| config.recovery && colour_model)
        .and_then(|p| p.covering_moved(rect))
        .map(|(previous, shift)| Streak {
            previous,
            shift,
            colour: m.colour,
            shade: m.shade,
            hue_share: m.hue_share,
            core: m.core_colour,
            // The trail was taken on the frame before; the camera's shift moves it here.
            trail: m.trail.map(|t| Trail {
                rect: t.rect.shifted(shift[0], shift[1]),
                ..t
            }),
        });
    let filter = PixelFilter {
        depth: gate,
        masked,
        paler,
        streak,
    };
    let (w, h) = m.size;
    let visible = rect.intersect(&image_rect(frame.width(), frame.height()));
    let sparse = (sparse
        && visible.area() as i64 > SPARSE_MIN_WINDOWS * i64::from(w) * i64::from(h))
    .then(|| Sparse {
        threshold: m.reference.threshold,
        cell: sparse_cell(m),
    });
    let model = &config.model;
    region.fill(model, &m.model, &m.lookup, frame, rect, &filter, sparse);
}

/// Where marker `m` is in `frame` (found there), and the median colour of a ring about its
/// window, half a window wide, sampled every [`TRAIL_RING_STEP_PX`] pixels (see [`Trail`]);
/// `None` when the marker was not found (or only on a weak measurement: a look-alike's place
/// is no trail), or the ring lies out of the frame or is not plain.
pub(super) fn trail(m: &MarkerState, frame: &RgbImage) -> Option<Trail> {
    if !m.last_status.found() || m.searching() > 0 {
        return None;
    }
    let (w, h) = m.size;
    let window = PixelRect::centered_at(m.last_center, w, h);
    let ring = window.grown(w / 2, h / 2);
    let inside = ring.intersect(&image_rect(frame.width(), frame.height()));
    if inside.is_empty() {
        return None;
    }
    let raw = frame.as_raw();
    let stride = 3 * frame.width() as usize;
    let mut pixels: Vec<[u8; 3]> = Vec::new();
    // Per channel, how many samples hold each level: the median from the counts.
    let mut counts = [[0u32; 256]; 3];
    for y in (inside.y..inside.bottom() as i32).step_by(TRAIL_RING_STEP_PX) {
        let row = &raw[y as usize * stride..(y as usize + 1) * stride];
        for x in (inside.x..inside.right() as i32).step_by(TRAIL_RING_STEP_PX) {
            if window.contains(x, y) {
                continue;
            }
            let p = [
                row[3 * x as usize],
                row[3 * x as usize + 1],
                row[3 * x as usize + 2],
            ];
            for (c, &v) in counts.iter_mut().zip(&p) {
                c[usize::from(v)] += 1;
            }
            pixels.push(p);
        }
    }
    let n = pixels.len();
    if n < TRAIL_MIN_RING_PX {
        return None;
    }
    let around = counts.map(|c| rank_level(&c, n / 2));
    // Only a plain surrounding (the sky, a wall) says what lay behind the marker: where it
    // sat on a limb, the limb uncovered as it leaves is no streak.
    let near = pixels
        .iter()
        .filter(|p| {
            (0..3)
                .map(|c| (f32::from(p[c]) - f32::from(around[c])).powi(2))
                .sum::<f32>()
                < STREAK_MIN_CONTRAST * STREAK_MIN_CONTRAST
        })
        .count();
    if (near as f64) < TRAIL_PLAIN_SHARE * n as f64 {
        return None;
    }
    Some(Trail {
        rect: window,
        around,
    })
}

/// The level of rank `rank` (0 the least) among samples counted per level in `counts`
/// (the level `select_nth_unstable(rank)` leaves there); 255 past the last sample.
fn rank_level(counts: &[u32; 256], rank: usize) -> u8 {
    let mut below = 0usize;
    for (level, &c) in counts.iter().enumerate() {
        below += c as usize;
        if below > rank {
            return level as u8;
        }
    }
    u8::MAX
}

impl Tracker {
    /// Whether no other marker's last place lies within [`TRAIL_APART_WINDOWS`] windows of
    /// marker `i`'s: its window then holds it alone, and the trail of [`Trail`] is its. Two
    /// markers passing each other (or one track sitting on the other's marker) share the
    /// window, and the other marker's pixels leaving it are no trail of this one.
    pub(super) fn alone(&self, i: usize) -> bool {
        let m = &self.markers[i];
        let side = window_px(m);
        self.markers.iter().enumerate().all(|(k, o)| {
            k == i
                || (o.last_center - m.last_center).norm()
                    > TRAIL_APART_WINDOWS * side.max(window_px(o))
        })
    }
}

/// See [`Tracker::alone`]: a marker's ring reaches a window out from its centre, so the
/// windows and rings of two markers this many windows apart do not meet.
const TRAIL_APART_WINDOWS: f64 = 2.0;

/// Least number of ring pixels sampled inside the frame for a trail's surroundings.
const TRAIL_MIN_RING_PX: usize = 12;
/// The ring is sampled every this many pixels along rows and between rows: a plain
/// surrounding needs no more, and it reads a quarter of the pixels (every pixel gave the
/// same figures on the tuning sets but for one crossing, `docs/validation.md`).
const TRAIL_RING_STEP_PX: usize = 2;
/// Least share of the ring within [`STREAK_MIN_CONTRAST`] of its median colour: a plain
/// surrounding.
const TRAIL_PLAIN_SHARE: f64 = 0.9;

/// The region's weights over the part of `window` inside it, row by row.
fn window_weights(region: &Region, window: PixelRect) -> impl Iterator<Item = f32> + '_ {
    let w = window.intersect(&region.rect);
    (w.y..w.bottom() as i32)
        .flat_map(move |y| (w.x..w.right() as i32).map(move |x| region.weights[region.index(x, y)]))
}

/// Learn the marker's blob in its first window: threshold, pixel count, width.
pub(super) fn learn_blob(
    m: &mut MarkerState,
    region: &Region,
    labeler: &mut Labeler,
    window: PixelRect,
) {
    // The marker's pixels: the heaviest tenth of the window sets the scale.
    let mut inside: Vec<f32> = window_weights(region, window)
        .filter(|&v| v > 0.0)
        .collect();
    if inside.is_empty() {
        return;
    }
    let k = inside.len() / 10;
    let top = *inside.select_nth_unstable_by(k, |a, b| b.total_cmp(a)).1;
    let threshold = (top * BLOB_THRESHOLD).max(1.0);
    let c = window.center();
    // The least gap that makes the marker's pixels in its window one blob.
    let mut best = None;
    for gap in 1..=MAX_GAP_PX {
        let blobs = labeler.blobs(&region.weights, region.rect, region.rect, threshold, 1, gap);
        let inside: Vec<(f64, &Blob)> = blobs
            .iter()
            .map(|b| {
                let part =
                    b.bounds.intersect(&window).area() as f64 / b.bounds.area().max(1) as f64;
                (b.mass * part, b)
            })
            .filter(|(w, _)| *w > 0.0)
            .collect();
        let total: f64 = inside.iter().map(|(w, _)| w).sum();
        let main = inside
            .iter()
            .min_by(|a, b| {
                (a.1.centroid - c)
                    .norm()
                    .total_cmp(&(b.1.centroid - c).norm())
            })
            .map(|(w, b)| (*w, **b));
        if let Some((w, b)) = main {
            best = Some((gap, b));
            if w >= ONE_BLOB_SHARE * total {
                break;
            }
        }
    }
    if let Some((gap, _)) = best {
        m.reference.gap = gap;
    }

    let best = best.map(|(_, b)| b);
    m.reference.threshold = threshold;
    if let Some(b) = best {
        m.reference.pixels = b.pixels as f64;
        m.reference.pixel_weight = b.mass / b.pixels as f64;
        m.reference.width_px = b.width_px().max(2.0);
    } else {
        m.reference.pixel_weight = f64::from(top);
    }
}

/// Learn the marker's blob from the pixels of its first window alone (at or above the
/// learnt threshold): where its blob in the frame runs on into something touching it, the
/// blob's count and weight are not the marker's.
pub(super) fn learn_blob_in_window(m: &mut MarkerState, region: &Region, window: PixelRect) {
    let threshold = m.reference.threshold;
    let (pixels, mass) = window_weights(region, window)
        .filter(|&v| v >= threshold)
        .fold((0usize, 0.0f64), |(n, s), v| (n + 1, s + f64::from(v)));
    if pixels > 0 {
        m.reference.pixels = pixels as f64;
        m.reference.pixel_weight = mass / pixels as f64;
    }
}

/// The gap a marker's blob must bridge where the image has holes (pixels with no data,
/// black, as a projection image where no point projected): around `window` (a window on
/// every side), more than [`HOLES_SPARSE`] holes need 2 pixels, more than [`HOLES_SPLATTED`]
/// need 3 (splats with holes between them).
pub(super) fn hole_gap(frame: &RgbImage, window: PixelRect) -> usize {
    let around = window
        .grown(window.width, window.height)
        .intersect(&image_rect(frame.width(), frame.height()));
    let (mut holes, mut all) = (0usize, 0usize);
    for y in around.y..around.bottom() as i32 {
        for x in around.x..around.right() as i32 {
            let p = frame.get_pixel(x as u32, y as u32).0;
            all += 1;
            if is_hole(p) {
                holes += 1;
            }
        }
    }
    let share = holes as f64 / all.max(1) as f64;
    if share > HOLES_SPLATTED {
        3
    } else if share > HOLES_SPARSE {
        2
    } else {
        1
    }
}

/// The pixels of `window` within `region`, each with whether its weight is at least
/// `threshold` (the marker's own), row by row.
fn window_pixels<'a>(
    frame: &'a RgbImage,
    region: &'a Region,
    window: PixelRect,
    threshold: f32,
) -> impl Iterator<Item = ([u8; 3], bool)> + 'a {
    let w = window.intersect(&region.rect);
    (w.y..w.bottom() as i32).flat_map(move |y| {
        (w.x..w.right() as i32).map(move |x| {
            let p = frame.get_pixel(x as u32, y as u32).0;
            (p, region.weights[region.index(x, y)] >= threshold)
        })
    })
}

/// The share of the marker's darkest pixels, taken at this quantile of its pixels on the
/// first frame (a shaded sphere's shadow side; a few pixels of noise lower).
const DARKEST_QUANTILE: f64 = 0.02;

/// How dark the marker's own colour gets on the first frame, as a share of its mean colour
/// `colour` (the projection of each pixel at or above `threshold` in `window` on `colour`,
/// over `colour`'s own): the [`DARKEST_QUANTILE`] of its pixels. `None` without pixels.
pub(super) fn darkest_shade(
    frame: &RgbImage,
    region: &Region,
    window: PixelRect,
    threshold: f32,
    colour: [f32; 3],
) -> Option<f32> {
    let mm: f32 = colour.iter().map(|c| c * c).sum();
    if mm <= 0.0 {
        return None;
    }
    let mut shades: Vec<f32> = window_pixels(frame, region, window, threshold)
        .filter(|(_, own)| *own)
        .map(|(p, _)| (0..3).map(|c| f32::from(p[c]) * colour[c]).sum::<f32>() / mm)
        .collect();
    if shades.is_empty() {
        return None;
    }
    let k = ((shades.len() - 1) as f64 * DARKEST_QUANTILE).round() as usize;
    Some(*shades.select_nth_unstable_by(k, |a, b| a.total_cmp(b)).1)
}

/// Rays cast from a marker's centre to find its rim on the first frame: enough to meet a
/// sharp rim (one pixel of blend) through a Kinect's holes (32 left green markers of the
/// third generator without a learnt share, at the widest).
const RIM_RAYS: usize = 64;
/// Least coverage times contrast (8-bit levels) of a rim pixel that counts: below it the
/// sensor's noise would decide its share.
const RIM_MIN_SIGNAL: f32 = 40.0;
/// Coverages of the rim pixels that count: a blend of the marker and its background.
const RIM_COVERAGE: [f32; 2] = [0.2, 0.8];
/// Least rim pixels for a share to be learnt.
const RIM_MIN_PIXELS: usize = 12;
/// The share learnt is this many times the rim pixels' median share.
const RIM_MARGIN: f32 = 2.0;

/// How far the marker's rim on the first frame lies off the plane of its background and its
/// core colour `core` (every blend of the background with every shade of the marker) toward
/// gray's side, as a share of coverage (against its mean colour `colour`) times contrast:
/// twice the median over the rim pixels met by [`RIM_RAYS`] rays from `center` (a pixel on
/// the other side counts as none), each measured against the background two pixels beyond
/// the rim on its ray, between [`STREAK_MIN_HUE_SHARE`] and the general residual share. A
/// rim drawn or filmed plainly blends in the plane (noise alone leaves it; a JPEG of quality
/// 30 about 0.05); a camera that pales edges toward gray (chroma denoising) pales its
/// streaks as much, and more is allowed. `None` where too few rim pixels are found (a
/// marker on a background of its colour, or at the frame's edge).
pub(super) fn rim_hue_share(
    frame: &RgbImage,
    center: Point2<f64>,
    width_px: f64,
    [colour, core]: [[f32; 3]; 2],
) -> Option<f32> {
    let mm: f32 = colour.iter().map(|c| c * c).sum();
    if mm <= 0.0 || !(width_px.is_finite() && width_px > 0.0) {
        return None;
    }
    let far = |p: [f32; 3]| {
        let d: f32 = (0..3).map(|c| (p[c] - colour[c]).powi(2)).sum();
        d >= STREAK_MIN_CONTRAST * STREAK_MIN_CONTRAST
    };
    let (w, h) = (f64::from(frame.width()), f64::from(frame.height()));
    let mut shares = Vec::new();
    for k in 0..RIM_RAYS {
        let (sin, cos) = (std::f64::consts::TAU * k as f64 / RIM_RAYS as f64).sin_cos();
        // A pixel on the ray `t` pixels out; none outside the frame or in a hole.
        let at = |t: f64| {
            let (x, y) = ((center.x + t * cos).round(), (center.y + t * sin).round());
            (x >= 0.0 && y >= 0.0 && x < w && y < h)
                .then(|| frame.get_pixel(x as u32, y as u32).0)
                .filter(|p| *p != [0, 0, 0])
                .map(|p| p.map(f32::from))
        };
        let steps = (1.5 * width_px).ceil() as usize + 3;
        let first = (0.3 * width_px).floor() as usize;
        let Some(edge) = (first..steps).find(|&t| {
            matches!((at(t as f64), at(t as f64 + 1.0)), (Some(p), Some(q)) if far(p) && far(q))
        }) else {
            continue;
        };
        let Some(b) = at(edge as f64 + 2.0).filter(|b| far(*b)) else {
            continue;
        };
        let d = [0, 1, 2].map(|c| colour[c] - b[c]);
        let dd: f32 = d.iter().map(|v| v * v).sum();
        let n = [
            core[1] * b[2] - core[2] * b[1],
            core[2] * b[0] - core[0] * b[2],
            core[0] * b[1] - core[1] * b[0],
        ];
        let nn: f32 = n.iter().map(|v| v * v).sum();
        if nn <= 0.0 {
            continue;
        }
        for t in edge.saturating_sub(3)..=edge {
            let Some(p) = at(t as f64) else { continue };
            let e = [0, 1, 2].map(|c| p[c] - b[c]);
            let a = (0..3).map(|c| e[c] * d[c]).sum::<f32>() / dd;
            let signal = a * dd.sqrt();
            if !(RIM_COVERAGE[0]..=RIM_COVERAGE[1]).contains(&a) || signal < RIM_MIN_SIGNAL {
                continue;
            }
            let en: f32 = (0..3).map(|c| e[c] * n[c]).sum();
            let toward_gray = en * (n[0] + n[1] + n[2]) > 0.0;
            shares.push(if toward_gray {
                en.abs() / nn.sqrt() / signal
            } else {
                0.0
            });
        }
    }
    if shares.len() < RIM_MIN_PIXELS {
        return None;
    }
    let mid = shares.len() / 2;
    let median = *shares.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
    Some((RIM_MARGIN * median).clamp(STREAK_MIN_HUE_SHARE, STREAK_RESIDUAL[1]))
}

/// Mean RGB of the pixels of the central half of `window` (half its width and height) whose
/// weight is at least `threshold`: the marker's own colour, without the blends of its rim
/// with the background that [`mean_colour`] takes in. The mean colour if none is.
pub(super) fn core_colour(
    frame: &RgbImage,
    region: &Region,
    window: PixelRect,
    threshold: f32,
) -> [f32; 3] {
    let core = PixelRect::centered_at(
        window.center(),
        (window.width / 2).max(1),
        (window.height / 2).max(1),
    );
    let (mut sum, mut n) = ([0.0f64; 3], 0.0f64);
    for (p, _) in window_pixels(frame, region, core, threshold).filter(|(_, own)| *own) {
        for c in 0..3 {
            sum[c] += f64::from(p[c]);
        }
        n += 1.0;
    }
    if n == 0.0 {
        return mean_colour(frame, region, window, threshold);
    }
    sum.map(|v| (v / n) as f32)
}

/// Mean RGB of the pixels of `window` whose weight is at least `threshold` (the marker's
/// own), or of the whole window if none is.
pub(super) fn mean_colour(
    frame: &RgbImage,
    region: &Region,
    window: PixelRect,
    threshold: f32,
) -> [f32; 3] {
    let (mut sum, mut all, mut n, mut n_all) = ([0.0f64; 3], [0.0f64; 3], 0.0f64, 0.0f64);
    for (p, own) in window_pixels(frame, region, window, threshold) {
        for c in 0..3 {
            all[c] += f64::from(p[c]);
            if own {
                sum[c] += f64::from(p[c]);
            }
        }
        n_all += 1.0;
        if own {
            n += 1.0;
        }
    }
    let (s, k) = if n > 0.0 {
        (sum, n)
    } else {
        (all, n_all.max(1.0))
    };
    [(s[0] / k) as f32, (s[1] / k) as f32, (s[2] / k) as f32]
}

/// The saturation (0..255) of an RGB pixel, as OpenCV's `COLOR_RGB2HSV` gives it.
pub(super) fn saturation(p: [u8; 3]) -> u8 {
    crate::hsv::rgb_to_hsv(p)[1]
}

/// The median saturation of the square about `center` whose half-side is [`CORE_WINDOWS`]
/// of a window of side `window_px` (at least a pixel): the middle of a marker. `None` when
/// the square lies outside the frame.
pub(super) fn core_saturation(
    frame: &RgbImage,
    center: Point2<f64>,
    window_px: f64,
) -> Option<f64> {
    let half = (CORE_WINDOWS * window_px).round().max(1.0) as i32;
    let side = 2 * half + 1;
    let square = PixelRect::centered_at(center, side, side)
        .intersect(&image_rect(frame.width(), frame.height()));
    let mut values: Vec<u8> = Vec::with_capacity(square.area() as usize);
    for y in square.y..square.bottom() as i32 {
        for x in square.x..square.right() as i32 {
            values.push(saturation(frame.get_pixel(x as u32, y as u32).0));
        }
    }
    if values.is_empty() {
        return None;
    }
    let mid = values.len() / 2;
    Some(f64::from(*values.select_nth_unstable(mid).1))
}

/// A paler look-alike touching a colour marker, learnt as one blob with it on the first
/// frame (a reddish-brown knot beside a red marker): the median saturation of the pixels
/// of `blob` (its box in `region`, weights at or above `threshold`) that are more than
/// [`TOUCHING_PALER_LEVELS`] under the marker's core saturation `core`, when they are at least
/// [`PALER_SHARE`] of the others (the marker's own) and centred at least
/// [`PALER_OFFSET_WINDOWS`] of a window (`window_px`) off them: a marker's rim, blended with
/// the background, is paler too, but a few pixels all round it.
pub(super) fn paler_part(
    frame: &RgbImage,
    region: &Region,
    threshold: f32,
    blob: PixelRect,
    core: f64,
    window_px: f64,
) -> Option<f64> {
    let b = blob.intersect(&region.rect);
    let limit = core - TOUCHING_PALER_LEVELS;
    let (mut own, mut paler) = ((0.0, 0.0, 0usize), (0.0, 0.0, Vec::new()));
    for y in b.y..b.bottom() as i32 {
        for x in b.x..b.right() as i32 {
            if region.weights[region.index(x, y)] < threshold {
                continue;
            }
            let s = saturation(frame.get_pixel(x as u32, y as u32).0);
            if f64::from(s) < limit {
                paler.0 += f64::from(x);
                paler.1 += f64::from(y);
                paler.2.push(s);
            } else {
                own.0 += f64::from(x);
                own.1 += f64::from(y);
                own.2 += 1;
            }
        }
    }
    let n_paler = paler.2.len();
    if own.2 < FRAGMENT_MIN_PIXELS || (n_paler as f64) < PALER_SHARE * own.2 as f64 {
        return None;
    }
    let (n_own, n_pal) = (own.2 as f64, n_paler as f64);
    let offset = Vector2::new(
        paler.0 / n_pal - own.0 / n_own,
        paler.1 / n_pal - own.1 / n_own,
    );
    if offset.norm() < PALER_OFFSET_WINDOWS * window_px {
        return None;
    }
    let mid = n_paler / 2;
    Some(f64::from(*paler.2.select_nth_unstable(mid).1))
}

/// True when a blob could be the marker: wide as the marker (blur makes a streak longer, not
/// wider), not longer than a streak can be, with enough of its pixels.
pub(super) fn plausible(blob: &Blob, r: &Reference) -> bool {
    let width = blob.width_px() / r.width_px;
    let length = blob.length_px() / r.width_px;
    (BLOB_WIDTH_RANGE[0]..=BLOB_WIDTH_RANGE[1]).contains(&width)
        && length <= BLOB_MAX_LENGTH
        && blob.pixels as f64 >= BLOB_MIN_PIXELS * r.pixels
}

/// How much a blob looks like the marker, 0..=1 (see [`Observation::confidence`]): its
/// colour (mean weight against the marker's), its width (a wider blob is another object; a
/// narrower one may be the marker partly covered) and the share of the marker's pixels it
/// holds.
pub(super) fn blob_confidence(blob: &Blob, r: &Reference) -> f64 {
    let colour = (blob.mass / blob.pixels as f64 / r.pixel_weight).min(1.0);
    let held = (blob.pixels as f64 / (0.6 * r.pixels)).min(1.0);
    colour * width_fit(blob, r) * held
}

/// The places of `near.others` that share `blob` (`sharing(p)`), and whether the blob holds
/// at most [`ONE_MARKER_PIXELS`] times one of their markers' pixels (it may be that marker
/// alone).
fn sharing_blob(
    blob: &Blob,
    near: &Near<'_>,
    sharing: impl Fn(&Point2<f64>) -> bool,
) -> (Vec<Point2<f64>>, bool) {
    let mut places = Vec::new();
    let mut one_other = false;
    for (j, p) in near.others.iter().enumerate().filter(|(_, p)| sharing(p)) {
        places.push(*p);
        one_other |= near
            .others_pixels
            .get(j)
            .is_some_and(|&n| blob.pixels as f64 <= ONE_MARKER_PIXELS * n);
    }
    (places, one_other)
}

/// [`blob_confidence`]'s width term, 0..=1: 1 for a blob no wider than the marker, falling
/// off as the blob grows wider (a wider blob is another object).
fn width_fit(blob: &Blob, r: &Reference) -> f64 {
    let wider = (blob.width_px() / r.width_px).ln().max(0.0);
    (-0.5 * (wider / 0.35).powi(2)).exp()
}

/// What a marker's candidates are weighed against: where it and the markers about it are.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Near<'a> {
    /// Where the marker is predicted (the quick pass), or the centre of its gate
    /// (detection); `None` on the first frame.
    pub(super) own: Option<Point2<f64>>,
    /// Predictions of the other markers found in the last frame
    /// ([`sharing_predictions`]).
    pub(super) others: &'a [Point2<f64>],
    /// The pixels of each of `others`' markers ([`Reference::pixels`], the same order);
    /// a point without one is a marker of unknown size.
    pub(super) others_pixels: &'a [f64],
    /// The marker's static look-alikes a blob may hold beside it.
    pub(super) look_alikes: &'a [Point2<f64>],
    /// Where the markers of its look close to it were found last and are predicted
    /// ([`partners_of`]).
    pub(super) partners: &'a [Point2<f64>],
    /// Those of `others` (the same points) whose markers the joint assignment decides
    /// together with this one: every part of a blob shared with them is a candidate.
    pub(super) contested: &'a [Point2<f64>],
}

/// The marker-like blobs of the region's weights as measurements (heaviest first), with the
/// pairs of nearby fragments that make one marker together (a marker cut by a twig). A blob
/// on which another marker (`near.others`: predictions of markers found in the last frame)
/// is predicted as well as this one (`near.own`) is shared: this marker's candidate is the
/// part nearer to it, and, where the other marker is undecided as well
/// (`near.contested`), that marker's part too, for the joint assignment to choose between
/// them: a marker half behind another of its look that turns while they overlap is
/// predicted on the other's side, and the split by predictions gives each the other's
/// part (crossing seed 14007, `docs/validation.md`). A part of a shared blob that holds
/// no more than [`ONE_MARKER_PIXELS`] times one sharing marker's pixels and is wider than
/// this marker carries a [`Measured::misfit`]: it may be that bigger marker alone, which
/// both predictions fall on (a small marker turning beside a big one of its colour took
/// the big one's disc, third generator's seed 27). So is a blob that no other marker
/// shares and that holds one of the marker's static look-alikes away from `own`
/// (`near.look_alikes`, see [`MarkerState::look_alikes_away`]), when the part nearer to
/// `own` lies within [`OWN_PART_WINDOWS`] windows of it: a marker at rest beside a
/// look-alike of its colour makes one blob with it when the two touch, and its candidate is
/// its own part, not the pair's centroid. A blob that may be the marker and another of its
/// look touching (`near.partners`: where those were found last and are predicted) also
/// gives the marker's disc within it from `own` ([`pair_part`]).
pub(super) fn candidates_in(
    region: &mut Region,
    labeler: &mut Labeler,
    m: &MarkerState,
    near: &Near<'_>,
) -> Vec<Measured> {
    let Near {
        own,
        look_alikes,
        partners,
        contested,
        ..
    } = *near;
    let blobs = labeler.blobs(
        &region.weights,
        region.rect,
        region.rect,
        m.reference.threshold,
        FRAGMENT_MIN_PIXELS,
        m.reference.gap,
    );

    let (w, h) = m.size;
    let on = |p: &Point2<f64>, r: PixelRect| {
        p.x >= f64::from(r.x)
            && p.y >= f64::from(r.y)
            && p.x < r.right() as f64
            && p.y < r.bottom() as f64
    };
    let mut out = Vec::new();
    for (k, b) in blobs.iter().enumerate() {
        if out.len() >= MAX_CANDIDATES {
            break;
        }
        let (sharing, one_other) = sharing_blob(b, near, |p| on(p, b.bounds.grown(w / 2, h / 2)));
        // `own` near the blob, and the places it shares the blob's pixels with.
        let beside_own =
            |with: &[Point2<f64>]| own.filter(|p| !with.is_empty() && on(p, b.bounds.grown(w, h)));
        if let Some(own) = beside_own(&sharing) {
            let mut centres = vec![own];
            centres.extend_from_slice(&sharing);
            let parts = labeler.split(&region.weights, region.rect, b, &centres);
            for (k, (part, centre)) in parts.iter().zip(&centres).enumerate() {
                let offered = part.pixels > 0
                    && plausible(part, &m.reference)
                    && (k == 0 || contested.contains(centre));
                if offered {
                    // A part of a blob that is one other marker's worth of pixels and wider
                    // than this marker may be a piece of that marker, which both
                    // predictions fall on, not this marker beside it.
                    let misfit = if one_other {
                        -width_fit(b, &m.reference).max(1e-3).ln()
                    } else {
                        0.0
                    };
                    out.push(Measured {
                        split: true,
                        misfit,
                        ..measured_at(region, m, part)
                    });
                }
            }
            continue;
        }
        // A marker at rest and a look-alike touching it: its own part, where the split
        // finds that near its prediction (a marker at rest is about where it is predicted,
        // at most a release's first step off); else the blob as it is.
        let beside: Vec<Point2<f64>> = look_alikes
            .iter()
            .filter(|p| on(p, b.bounds))
            .copied()
            .collect();
        if let Some(own) = beside_own(&beside) {
            let reach = OWN_PART_WINDOWS * window_px(m);
            if let Some(part) = own_part(labeler, region, m, b, own, &beside)
                .filter(|p| (p.centroid - own).norm() <= reach)
            {
                out.push(measured_at(region, m, &part));
                continue;
            }
        }
        if plausible(b, &m.reference) {
            let mut steady = *b;
            let window = PixelRect::centered_at(b.centroid, m.size.0, m.size.1);
            let pieces = (m.reference.pixels * BLOB_MIN_PIXELS).ceil() as usize;
            steady.centroid =
                labeler.edge_centroid(&region.weights, region.rect, b, window, pieces);
            let steady = without_tail(labeler, region, b, &m.reference)
                .filter(|part| plausible(part, &m.reference))
                .unwrap_or(steady);
            out.push(measured_at(region, m, &steady));
            if let Some(part) = own.and_then(|p| pair_part(labeler, region, m, b, p, partners)) {
                out.push(measured_at(region, m, &part));
            }
        }
        // Fragments closer than the marker's width whose union is a whole marker.
        for c in &blobs[k + 1..] {
            if (b.centroid - c.centroid).norm() < m.reference.width_px {
                let u = b.merged(c);
                if plausible(&u, &m.reference) {
                    out.push(measured_at(region, m, &u));
                }
            }
        }
    }
    out
}

/// A blob at least this many times as long as it is wide may be a marker with a tail ...
const TAIL_MIN_ELONGATION: f64 = 1.2;
/// ... a line of its colour at most this share of the marker's width wide running out of it
/// (a twig it hangs from: 2-4 px wide against markers of 8-20 px), which an opening by a
/// square that wide removes ...
const TAIL_MAX_WIDTH: f64 = 0.35;
/// ... when the opening keeps at least this share of the marker's pixels (or of the blob's,
/// if fewer: a marker broken up by holes is not opened away) ...
const TAIL_KEPT_SHARE: f64 = 0.5;
/// ... and moves its centroid at least this far (pixels) ...
const TAIL_MIN_SHIFT_PX: f64 = 0.5;
/// The least half-side (pixels) of the opening's square: a marker under about 9 px across
/// (the square 3 px wide) is not opened, since its own rim and the splats of a projection
/// image are as thin as a twig there (the pipeline's 7 px markers: the worst within 3 px
/// 98.0 -> 90.4 % when they were).
const TAIL_MIN_HALF_SIDE_PX: usize = 2;
/// ... whose dropped pixels make a line: their minor axis (four standard deviations) at most
/// this share of the marker's width (the rim of a ragged marker the opening trims all round
/// is as wide as the marker) ...
const TAIL_REST_WIDTH: f64 = 0.5;
/// ... at least this many marker widths long (a crumb of a ragged rim is not a line) ...
const TAIL_REST_LENGTH: f64 = 0.8;
/// ... lying off to one side: their centroid at least this many marker widths from the
/// disc's (crumbs trimmed off both ends of a ragged marker balance about its centre) ...
const TAIL_REST_OFFSET: f64 = 0.6;
/// ... and leaves a disc: at most this many times the marker's width long. A motion streak
/// the opening trims (its trailing end lies where the marker was in the frame before, where
/// it has no streak weight, so it is thinner and paler there) stays a streak, and is measured
/// as it is.
const TAIL_DISC_LENGTH: f64 = 1.4;

/// The marker's part of `blob` (from the last labelling of `region`) without a thin tail of
/// its colour running out of it, when it has one: a marker hangs from a twig, and bark's
/// hue is a red marker's neighbour, so its blob runs on along the twig and the blob's
/// centroid is pulled toward it by a few pixels (3-5 px on the third generator's
/// sequences, `docs/validation.md`). The blob's opening by a square [`TAIL_MAX_WIDTH`] of
/// the marker's width wide ([`Labeler::opened`]) keeps a disc, a streak and a marker partly
/// covered about as they are, and drops lines thinner than that. `None` when the blob has
/// no such tail, or when what is left is not a disc.
fn without_tail(
    labeler: &mut Labeler,
    region: &Region,
    blob: &Blob,
    reference: &Reference,
) -> Option<Blob> {
    let width_px = reference.width_px;
    if blob.length_px() < TAIL_MIN_ELONGATION * blob.width_px().max(1.0) {
        return None;
    }
    let k = (0.5 * TAIL_MAX_WIDTH * width_px).round() as usize;
    if k < TAIL_MIN_HALF_SIDE_PX {
        return None;
    }
    let part = labeler.opened(&region.weights, region.rect, blob, k)?;
    let rest = blob.without(&part)?;
    (part.pixels as f64 >= TAIL_KEPT_SHARE * reference.pixels.min(blob.pixels as f64)
        && (part.centroid - blob.centroid).norm() >= TAIL_MIN_SHIFT_PX
        && part.length_px() <= TAIL_DISC_LENGTH * width_px
        && rest.width_px() <= TAIL_REST_WIDTH * width_px
        && rest.length_px() >= TAIL_REST_LENGTH * width_px.max(rest.width_px())
        && (rest.centroid - part.centroid).norm() >= TAIL_REST_OFFSET * width_px)
        .then_some(part)
}

/// The part of `blob` nearer to `own` than to any of `others` (weighted 2-means from those
/// places, [`Labeler::split`]), when it could be the marker.
fn own_part(
    labeler: &mut Labeler,
    region: &Region,
    m: &MarkerState,
    blob: &Blob,
    own: Point2<f64>,
    others: &[Point2<f64>],
) -> Option<Blob> {
    let mut centres = vec![own];
    centres.extend_from_slice(others);
    let parts = labeler.split(&region.weights, region.rect, blob, &centres);
    parts
        .into_iter()
        .next()
        .filter(|p| p.pixels > 0 && plausible(p, &m.reference))
}

/// A blob holds two markers of one look, touching or overlapping, rather than one marker's
/// motion streak, when it has at least this many times the marker's pixels ...
const PAIR_MIN_PIXELS: f64 = 1.4;
/// ... no wider than a marker (two discs side by side are one disc wide; a larger
/// look-alike is wider) ...
const PAIR_MAX_WIDTH: f64 = 1.25;
/// ... at its full colour: mean weight at least this share of the marker's (a streak is
/// paler, its colour spread over the path).
const PAIR_MIN_COLOUR: f64 = 0.8;

/// Where `blob` may be two markers of one look that touch or overlap (more pixels than one
/// marker, at its full colour), the marker's disc within it from its prediction `own`
/// ([`Labeler::disc_part`]), when that is plausibly the marker and not the whole blob.
fn pair_part(
    labeler: &mut Labeler,
    region: &Region,
    m: &MarkerState,
    blob: &Blob,
    own: Point2<f64>,
    partners: &[Point2<f64>],
) -> Option<Blob> {
    let r = &m.reference;
    if partners.is_empty() {
        return None;
    }
    let pair = blob.pixels as f64 >= PAIR_MIN_PIXELS * r.pixels
        && blob.width_px() <= PAIR_MAX_WIDTH * r.width_px
        && blob.mass / blob.pixels as f64 >= PAIR_MIN_COLOUR * r.pixel_weight;
    if !pair {
        return None;
    }
    let part = labeler.disc_part(&region.weights, region.rect, blob, own, 0.5 * r.width_px)?;
    // The rest of the blob is the other marker: near where one was found or is predicted
    // (the marker leaving a look-alike it touched leaves a blob with no partner). The disc
    // is the marker's from near its prediction (not a look-alike the disc slid onto).
    let rest_mass = blob.mass - part.mass;
    if rest_mass <= 0.0 || (part.centroid - own).norm() > PAIR_MAX_SHIFT_WINDOWS * window_px(m) {
        return None;
    }
    let rest = Point2::from(
        (blob.centroid.coords * blob.mass - part.centroid.coords * part.mass) / rest_mass,
    );
    let reach = PAIR_PARTNER_WINDOWS * window_px(m);
    let partnered = partners.iter().any(|p| (p - rest).norm() <= reach);
    (partnered
        && (part.centroid - blob.centroid).norm() >= PAIR_MIN_SHIFT_PX
        && plausible(&part, r))
    .then_some(part)
}

/// The rest of a blob of two markers lies within this many windows of where the other
/// marker was found last or is predicted.
const PAIR_PARTNER_WINDOWS: f64 = 2.0;

/// The disc settles at most this many windows from the marker's prediction.
const PAIR_MAX_SHIFT_WINDOWS: f64 = 0.5;

/// Least distance from the blob's centroid for the disc's part to be a candidate of its own.
const PAIR_MIN_SHIFT_PX: f64 = 1.0;

/// A measurement at a blob: its centroid, the window there and its confidence.
pub(super) fn measured_at(region: &mut Region, m: &MarkerState, blob: &Blob) -> Measured {
    let window = PixelRect::centered_at(blob.centroid, m.size.0, m.size.1);
    let confidence = match &m.model {
        // The kernel model's colour evidence is the Bhattacharyya coefficient, or the
        // blob's weight share where that is higher: a blurred marker's streak pixels blend
        // it with the background into bins its histogram does not hold (their streak
        // weights count them), and its coefficient fell to 0.2-0.3 at a release, so the
        // marker was held `predicted` and lost (the third generator's tuning seeds: 81 →
        // 90 % within 3 px with the other kernel rules of this change, `validation.md`).
        MarkerModel::Kernel { q, .. } => {
            let colour =
                (blob.mass / blob.pixels as f64 / m.reference.pixel_weight).clamp(1e-9, 1.0);
            let rho = region.bhattacharyya(q, blob.centroid, m.size);
            rho.max(colour) * blob_confidence(blob, &m.reference) / colour
        }
        MarkerModel::Projected { .. } => blob_confidence(blob, &m.reference),
    };
    Measured {
        center: blob.centroid,
        window,
        holds: blob.bounds.grown(1, 1),
        confidence: confidence.clamp(0.0, 1.0),
        moments: moments_of(region, window),
        cut: false,
        split: false,
        misfit: 0.0,
        spread: Some(blob.spread),
    }
}

/// The gray target's template matches within `radius` of `center` as measurements; the
/// confidence is the correlation (negative counts as 0).
pub(super) fn template_candidates(
    t: &Template,
    m: &MarkerState,
    frame: &RgbImage,
    center: Point2<f64>,
    radius: f64,
    max: usize,
    scratch: &mut TemplateScratch,
) -> Vec<Measured> {
    let (w, h) = m.size;
    t.search(frame, center, radius, max, scratch)
        .into_iter()
        .map(|found| {
            let window = PixelRect::centered_at(found.center, w, h);
            Measured {
                center: found.center,
                window,
                holds: window,
                confidence: found.ncc.max(0.0),
                moments: None,
                cut: false,
                split: false,
                misfit: 0.0,
                spread: None,
            }
        })
        .collect()
}

/// Moments of `window` and a 10-pixel border (CamShift's size estimate), where the region's
/// moments are wanted (an adaptive window).
pub(super) fn moments_of(region: &Region, window: PixelRect) -> Option<Moments> {
    if !region.moments_wanted {
        return None;
    }
    let g = region.sums(window.grown(ADAPTIVE_BORDER_PX, ADAPTIVE_BORDER_PX));
    (g[0] > 0.0).then(|| moments_from_f64_sums(g))
}

/// The mode as the measurement (plain mean-shift).
pub(super) fn plain(region: &Region, mode: Mode) -> Measured {
    Measured {
        center: mode.center,
        window: mode.window,
        holds: mode.window,
        confidence: mode.confidence,
        moments: mode.moments.or_else(|| moments_of(region, mode.window)),
        cut: false,
        split: false,
        misfit: 0.0,
        spread: None,
    }
}

/// The predictions of the markers of `i`'s look ([`same_look`]) other than `i` that were
/// found in the last frame, and their pixels ([`Reference::pixels`]): where a blob must be
/// shared. A marker of another colour puts no weight in `i`'s blob, so its place does not
/// cut the blob (a marker passing in front of another of a different colour was measured on
/// the part away from it: 3-5 px off on the third generator's sequences,
/// `docs/validation.md`).
pub(super) fn sharing_predictions(
    markers: &[MarkerState],
    i: usize,
    predictions: &[Point2<f64>],
) -> (Vec<Point2<f64>>, Vec<f64>) {
    markers
        .iter()
        .zip(predictions)
        .enumerate()
        .filter(|(j, (m, _))| *j != i && m.misses == 0 && same_look(&markers[i], m))
        .map(|(_, (m, p))| (*p, m.reference.pixels))
        .unzip()
}

/// True when `at` is on another marker's predicted place: nearer to that marker's prediction
/// than to marker `i`'s, and within that marker's window size of it. Only markers found in
/// the last frame claim their prediction: a coasting marker's is a guess.
pub(super) fn nearer_to_other(
    markers: &[MarkerState],
    i: usize,
    at: Point2<f64>,
    predictions: &[Point2<f64>],
) -> bool {
    let own = (at - predictions[i]).norm();
    predictions.iter().enumerate().any(|(j, p)| {
        let d = (at - p).norm();
        j != i && markers[j].last_status.found() && d < own && d < window_px(&markers[j])
    })
}

/// True when `at` is on a place another marker took this frame.
pub(super) fn taken(
    markers: &[MarkerState],
    i: usize,
    at: Point2<f64>,
    claimed: &[(usize, PixelRect, Point2<f64>)],
) -> bool {
    claimed
        .iter()
        .any(|&(j, _, c)| j != i && closer_than(markers, i, j, c - at, EXCLUSION_FRACTION))
}

/// Whether two places of markers `i` and `j`, `apart`, are closer than `fraction` of their
/// mean window size.
fn closer_than(
    markers: &[MarkerState],
    i: usize,
    j: usize,
    apart: Vector2<f64>,
    fraction: f64,
) -> bool {
    apart.norm() < fraction * 0.5 * (window_px(&markers[i]) + window_px(&markers[j]))
}

/// [`taken`] for a quick-pass measurement: two parts of one blob that the split gave to two
/// markers (both [`Measured::split`]) are two markers' places when their centres are
/// [`SPLIT_EXCLUSION_FRACTION`] of a window apart; a marker partly behind another of its
/// look is that close to it while the two cross. Only between markers both reported found
/// in the last frame and moving at most [`SPLIT_MAX_WINDOWS_PER_FRAME`]: a marker that was
/// an estimate, or a fast pair, may be split the wrong way round (two markers pulled through
/// each other from rest, or one marker's streak that both predictions fall on).
pub(super) fn taken_part(
    markers: &[MarkerState],
    i: usize,
    at: Measured,
    claimed: &[(usize, PixelRect, Point2<f64>)],
    quick: &[Option<Scored>],
) -> bool {
    claimed.iter().any(|&(j, _, c)| {
        let both_split = at.split
            && quick[j].is_some_and(|q| q.measured.split)
            && [i, j].iter().all(|&k| {
                let m = &markers[k];
                m.last_status.found()
                    && m.filter.velocity.norm() <= SPLIT_MAX_WINDOWS_PER_FRAME * window_px(m)
            });
        let fraction = if both_split {
            SPLIT_EXCLUSION_FRACTION
        } else {
            EXCLUSION_FRACTION
        };
        j != i && closer_than(markers, i, j, c - at.center, fraction)
    })
}

/// Median depth of the pixels of `window` with depth (the marker's depth for gating).
pub(super) fn window_depth(depth: &DepthView<'_>, window: PixelRect) -> Option<f64> {
    let w = window.intersect(&PixelRect::image(depth.width, depth.height));
    let mut values: Vec<f64> = Vec::with_capacity(w.area() as usize);
    for y in w.y..w.bottom() as i32 {
        for x in w.x..w.right() as i32 {
            if let Some(d) = depth.at(x, y) {
                values.push(d);
            }
        }
    }
    if values.is_empty() {
        return None;
    }
    let mid = values.len() / 2;
    values.select_nth_unstable_by(mid, f64::total_cmp);
    Some(values[mid])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_level_of_rank_from_counts_is_the_one_selection_leaves_there() {
        let mut rng = crate::rng::Rng::new(17);
        for n in [1usize, 2, 7, 12, 675] {
            let mut values: Vec<u8> = (0..n).map(|_| rng.range([0.0, 256.0]) as u8).collect();
            // Runs of one level, as a plain sky gives.
            values.extend(std::iter::repeat_n(values[0], n / 3));
            let mut counts = [0u32; 256];
            values.iter().for_each(|&v| counts[usize::from(v)] += 1);
            for rank in [0, values.len() / 2, values.len() - 1] {
                let mut sorted = values.clone();
                let selected = *sorted.select_nth_unstable(rank).1;
                assert_eq!(rank_level(&counts, rank), selected, "n {n}, rank {rank}");
            }
        }
        assert_eq!(rank_level(&[0; 256], 0), u8::MAX);
    }

    /// Marker A's weights over `rect` of `frame` into the tracker's region (no streak, no
    /// masks, every pixel weighed).
    fn fill_marker_a(t: &mut Tracker, frame: &RgbImage, rect: PixelRect) {
        let m = &t.markers[0];
        fill(
            &mut t.region,
            &t.config,
            m,
            frame,
            None,
            None,
            rect,
            &[],
            &[],
            false,
        );
    }

    /// Marker A (a red square 9 px wide) predicted, together with another marker of its
    /// colour, on a red square 15 px wide, its own square beside it: the part of the wide
    /// square that the split gives A is priced for the square being the other marker's
    /// worth of pixels and wider than A, and A's own square is its best candidate; the
    /// part is not priced where the other marker's size is unknown or the blob holds more
    /// than it.
    #[test]
    fn a_part_of_a_wider_marker_that_both_are_predicted_on_is_priced() -> Result<()> {
        let mut t = crate::tracker::two_red_markers()?;
        let frame = RgbImage::from_fn(192, 64, |x, y| {
            let wide = x.abs_diff(60) <= 7 && y.abs_diff(30) <= 7;
            let own = x.abs_diff(90) <= 4 && y.abs_diff(30) <= 4;
            if wide || own {
                image::Rgb([215, 25, 30])
            } else {
                image::Rgb([100, 110, 95])
            }
        });
        fill_marker_a(&mut t, &frame, PixelRect::new(40, 10, 70, 40));
        let m = &t.markers[0];
        let others = [Point2::new(59.0, 30.0)];
        let mut near = Near {
            own: Some(Point2::new(61.0, 30.0)),
            others: &others,
            others_pixels: &[225.0],
            ..Near::default()
        };
        let found = candidates_in(&mut t.region, &mut t.labeler, m, &near);
        let part = found
            .iter()
            .find(|c| c.split)
            .expect("the wide square's part");
        let beside = found
            .iter()
            .find(|c| (c.center - Point2::new(90.0, 30.0)).norm() < 1.0)
            .expect("A's own square");
        assert!(part.misfit > 0.5 && beside.misfit == 0.0, "{found:?}");
        let with_context: Vec<(Measured, Option<f64>)> = found.iter().map(|&c| (c, None)).collect();
        let scored = m.score(&with_context, 1e4, false);
        let best = scored.iter().min_by(|a, b| a.cost.total_cmp(&b.cost));
        assert_eq!(best.map(|b| b.measured.center), Some(beside.center));
        for pixels in [&[][..], &[100.0][..]] {
            near.others_pixels = pixels;
            let found = candidates_in(&mut t.region, &mut t.labeler, m, &near);
            assert!(
                found.iter().all(|c| c.misfit == 0.0),
                "{pixels:?}: {found:?}"
            );
        }
        Ok(())
    }

    /// Two red squares overlapping in one blob, marker A predicted on the left one and
    /// another marker on the right one: A's candidate is its own part, and the other's part
    /// as well only where that marker is contested (undecided in the same assignment).
    #[test]
    fn a_shared_blob_offers_the_other_markers_part_only_when_it_is_contested() -> Result<()> {
        let mut t = crate::tracker::two_red_markers()?;
        let frame = crate::tracker::red_squares([60, 67]);
        fill_marker_a(&mut t, &frame, PixelRect::new(30, 10, 70, 40));
        let m = &t.markers[0];
        let (own, other) = (Point2::new(59.0, 30.0), Point2::new(68.0, 30.0));
        let others = [other];
        let mut near = Near {
            own: Some(own),
            others: &others,
            ..Near::default()
        };
        let alone = candidates_in(&mut t.region, &mut t.labeler, m, &near);
        assert_eq!(alone.len(), 1, "{alone:?}");
        assert!(alone[0].split && alone[0].center.x < 63.5, "{alone:?}");
        near.contested = &others;
        let both = candidates_in(&mut t.region, &mut t.labeler, m, &near);
        assert_eq!(both.len(), 2, "{both:?}");
        assert_eq!(both[0].center, alone[0].center);
        assert!(both[1].split && both[1].center.x > 63.5, "{both:?}");
        Ok(())
    }

    #[test]
    fn a_trail_is_kept_where_the_marker_was_over_a_plain_surrounding_only() -> Result<()> {
        let mut t = crate::tracker::two_red_markers()?;
        let m = &mut t.markers[0];
        m.last_center = Point2::new(20.0, 30.0);
        m.last_status = TrackStatus::Tracked;
        let (w, h) = m.size;
        let window = PixelRect::centered_at(m.last_center, w, h);
        // Over the first frame's gray: the trail is the window.
        let plain = crate::tracker::red_squares([20, 150]);
        let left = trail(m, &plain).expect("a plain surrounding");
        assert_eq!(left.rect, window);
        assert_eq!(left.around, [100, 110, 95]);
        // A limb of bark across the ring (a fifth of it): what lay behind is not known.
        let limb = RgbImage::from_fn(192, 64, |x, y| {
            if y.abs_diff(30) <= 4 && x.abs_diff(20) <= 4 {
                image::Rgb([215, 25, 30])
            } else if y.abs_diff(30) <= 3 {
                image::Rgb([120, 70, 40])
            } else {
                image::Rgb([100, 110, 95])
            }
        });
        assert_eq!(trail(m, &limb), None);
        // Not found in the frame before, or only weakly: no trail.
        m.weak_run = 1;
        assert_eq!(trail(m, &plain), None);
        m.weak_run = 0;
        m.last_status = TrackStatus::Predicted;
        assert_eq!(trail(m, &plain), None);
        Ok(())
    }

    #[test]
    fn a_marker_is_alone_with_no_other_marker_within_two_windows() -> Result<()> {
        let mut t = crate::tracker::two_red_markers()?;
        t.markers[0].last_center = Point2::new(20.0, 30.0);
        t.markers[1].last_center = Point2::new(150.0, 30.0);
        assert!(t.alone(0) && t.alone(1));
        // B's window (11 px) passing over A's ring: neither is alone.
        t.markers[1].last_center = Point2::new(38.0, 30.0);
        assert!(!t.alone(0) && !t.alone(1));
        Ok(())
    }

    /// A green disc of radius 8 px over a sky, its rim anti-aliased (each rim pixel the blend
    /// of disc and sky by the share of it the disc covers), and then moved `gray` of the way
    /// to the gray of its own brightness (a camera's chroma denoising pales edges so).
    fn disc_over_sky(gray: f64) -> RgbImage {
        let (green, sky) = ([40.0f64, 150.0, 55.0], [130.0f64, 185.0, 225.0]);
        RgbImage::from_fn(48, 48, |x, y| {
            let (dx, dy) = (f64::from(x) - 24.0, f64::from(y) - 24.0);
            // The covered share of the pixel, by a 4x4 grid of samples.
            let inside = (0..16)
                .filter(|k| {
                    let sx = dx + (f64::from(k % 4) + 0.5) / 4.0 - 0.5;
                    let sy = dy + (f64::from(k / 4) + 0.5) / 4.0 - 0.5;
                    sx * sx + sy * sy <= 64.0
                })
                .count();
            let a = inside as f64 / 16.0;
            let p = [0, 1, 2].map(|c| a * green[c] + (1.0 - a) * sky[c]);
            let rim = if inside > 0 && inside < 16 { gray } else { 0.0 };
            let luma = (p[0] + p[1] + p[2]) / 3.0;
            image::Rgb(p.map(|v| ((1.0 - rim) * v + rim * luma).round() as u8))
        })
    }

    /// A clean rim blends the marker with its background in the plane of the two: the
    /// least share is learnt (a JPEG of quality 30 of the same disc about that: its rim
    /// stays within about 0.05 of the plane). A rim paled toward gray (by a camera's chroma
    /// denoising, whose streaks are paled too) leaves the plane on gray's side, and a larger
    /// share is learnt; a rim that is nowhere (a marker on its own colour) gives none.
    #[test]
    fn a_clean_rim_learns_the_least_share_off_the_plane_and_a_paled_one_more() {
        let clean = disc_over_sky(0.0);
        let colours = [[49.0f32, 153.0, 72.0], [40.0, 150.0, 55.0]];
        let center = Point2::new(24.0, 24.0);
        assert_eq!(
            rim_hue_share(&clean, center, 16.0, colours),
            Some(STREAK_MIN_HUE_SHARE)
        );
        let mut bytes = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 30)
            .encode_image(&clean)
            .expect("encodes");
        let compressed = image::load_from_memory(&bytes).expect("decodes").to_rgb8();
        let jpeg = rim_hue_share(&compressed, center, 16.0, colours).unwrap_or(1.0);
        assert!(jpeg <= 1.2 * STREAK_MIN_HUE_SHARE, "{jpeg}");
        let paled = disc_over_sky(0.3);
        let wider = rim_hue_share(&paled, center, 16.0, colours).unwrap_or(0.0);
        assert!(wider > 2.0 * STREAK_MIN_HUE_SHARE, "{wider}");
        let flat = RgbImage::from_pixel(48, 48, image::Rgb([40, 150, 55]));
        assert_eq!(rim_hue_share(&flat, center, 16.0, colours), None);
        // A Kinect's registered colour image, black where the depth is missing: with three
        // pixels in ten of the rim and its surroundings holes, enough rim is still met to
        // learn from (32 rays met too little; a marker whose share is not learnt keeps the
        // widest).
        let mut rng = crate::rng::Rng::new(7);
        let mut holed = clean.clone();
        for p in holed.pixels_mut() {
            if rng.uniform() < 0.3 {
                *p = image::Rgb([0, 0, 0]);
            }
        }
        for (x, y, p) in holed.enumerate_pixels_mut() {
            let r = (f64::from(x) - 24.0).hypot(f64::from(y) - 24.0);
            if r < 6.0 {
                *p = *clean.get_pixel(x, y);
            }
        }
        assert_eq!(
            rim_hue_share(&holed, center, 16.0, colours),
            Some(STREAK_MIN_HUE_SHARE)
        );
    }

    /// A marker whose left half is lit and right half in shadow at half the brightness:
    /// its mean colour is three quarters of the lit one, so its darkest shade is 2/3 of the
    /// mean; pixels under the blob threshold (the background) do not count.
    #[test]
    fn the_darkest_shade_is_that_of_the_markers_shadow_side_against_its_mean() {
        let lit = [200u8, 40, 30];
        let frame = RgbImage::from_fn(20, 20, |x, y| {
            let inside = (5..15).contains(&x) && (5..15).contains(&y);
            match (inside, x < 10) {
                (true, true) => image::Rgb(lit),
                (true, false) => image::Rgb(lit.map(|v| v / 2)),
                (false, _) => image::Rgb([10, 10, 10]),
            }
        });
        let rect = PixelRect::new(0, 0, 20, 20);
        let mut region = Region::default();
        region.rect = rect;
        region.weights = (0..400)
            .map(|k| {
                let (x, y) = (k % 20, k / 20);
                if (5..15).contains(&x) && (5..15).contains(&y) {
                    255.0
                } else {
                    0.0
                }
            })
            .collect();
        let colour = mean_colour(&frame, &region, rect, 100.0);
        let darkest = darkest_shade(&frame, &region, rect, 100.0, colour).unwrap_or(0.0);
        assert!(
            (darkest - 2.0 / 3.0).abs() < 0.01,
            "{darkest} of {colour:?}"
        );
        let mut empty = Region::default();
        empty.rect = rect;
        empty.weights = vec![0.0; 400];
        assert_eq!(darkest_shade(&frame, &empty, rect, 100.0, colour), None);
    }
}
