//! The camera's own motion from one frame to the next: a shake at a release moves the whole
//! scene by several pixels (issue 19's Kinect-style sequences blur the whole frame there).
//!
//! A marker's streak is told from its background by the previous frame's pixel at the same
//! place; when the camera moved, the same place held something else, and every edge of the
//! still scene (a limb's, a trunk's) looks like something that just arrived, which a limb of
//! a marker's hue turns into a streak of it. The shift is measured on edge points of the first
//! frame's scene, away from the markers (one per cell of [`POINT_CELL_PX`], where the
//! gradient is strongest, at most [`MAX_POINTS`], none at all when fewer than
//! [`MIN_POINTS`]): the shift whose points' colours in this
//! frame best match theirs in the frame before (a truncated L1 distance, so that a marker or
//! leaf passing over a few points does not decide it). Integral projections were tried
//! first and fail on a tree: a vertical trunk shows no vertical shift, diagonal limbs smear
//! into the row sums, and a Kinect's registered colour image has fixed holes (black where the
//! depth is missing) that hold the projections still.
//!
//! The search (every shift up to [`MAX_CAMERA_SHIFT_PX`] each way) runs only on frames whose
//! points differ from the frame before by clearly more than they usually do ([`SEARCH_RISE`]
//! over a running mean), after the points' levels are scaled to the frame before's (a
//! flicker of the light is not a shift), and a shift is taken only when it matches clearly
//! better than none ([`MIN_SHIFT_GAIN`], [`MIN_SHIFT_LEVELS`]).

use super::*;

/// Largest camera shift between two frames looked for, per axis (pixels): a shake of 5-12 px
/// at a release (issue 19's Kinect-style sequences), with a margin.
pub(super) const MAX_CAMERA_SHIFT_PX: i32 = 12;
/// Side of the cells of the first frame in each of which the strongest edge is a point.
const POINT_CELL_PX: u32 = 16;
/// Most points kept (the strongest edges).
const MAX_POINTS: usize = 192;
/// Fewest points for the camera's shift to be measured at all: a scene of a few objects on
/// a plain background (a rendered test scene) gives a handful, and a marker passing over
/// two of them would decide the shift.
const MIN_POINTS: usize = 32;
/// Least gradient (|gx| + |gy| of a 3x3 Sobel on the channels' sum, levels) of a point: an
/// edge of about 15 levels in each channel.
const MIN_POINT_GRADIENT: i32 = 180;
/// A point's distance (sum over channels of absolute differences, levels) counts at most
/// this much: a point a marker or leaf passed over is one bad point, not a vote.
const POINT_DISTANCE_CAP: f32 = 60.0;
/// A frame's points are searched for a shift when their mean distance to the frame before
/// exceeds the running mean of frames without a shift by this factor.
const SEARCH_RISE: f64 = 1.2;
/// A shift is taken when it brings the points' mean distance under this share of no shift's.
const MIN_SHIFT_GAIN: f64 = 0.85;
/// ... and by at least this much (mean levels per point): a scene without noise (a rendered
/// one) differs from one frame to the next by nothing where nothing moved, and a marker
/// passing over a few points is not a shake.
const MIN_SHIFT_LEVELS: f64 = 4.0;
/// Added to a shift's distance per pixel of its length (levels per point), so that of
/// shifts that match alike (an edge moved along itself, a repeated texture) the shortest is
/// taken.
const SHIFT_LENGTH_LEVELS: f64 = 0.01;
/// Least sum of a point's channels (levels) for its ratio to count toward the gain.
const GAIN_MIN_LEVEL: f32 = 60.0;
/// Rate of the running mean of the points' distance on still frames.
const STILL_RATE: f64 = 0.1;
/// Shifts per axis of the search: every one from `-MAX_CAMERA_SHIFT_PX` to
/// `MAX_CAMERA_SHIFT_PX`.
const SHIFTS: usize = 2 * MAX_CAMERA_SHIFT_PX as usize + 1;

/// Edge points of the still scene and what the camera saw at them in the last frame.
#[derive(Debug, Clone, Default)]
pub(super) struct CameraPoints {
    /// Pixel coordinates, at least [`MAX_CAMERA_SHIFT_PX`] + 1 inside the frame.
    points: Vec<(u32, u32)>,
    /// The last frame's colour at each point.
    last: Vec<[u8; 3]>,
    /// Running mean of the points' distance between consecutive frames without a shift.
    still: Option<f64>,
    /// The size of the frame the points were found on.
    size: (u32, u32),
    /// Frames searched for a shift so far (what the search costs, for the tests).
    #[cfg(test)]
    searches: usize,
}

impl CameraPoints {
    /// The edge points of `frame` (the first), away from the rectangles `away` (the markers'
    /// windows and their surroundings).
    pub(super) fn of(frame: &RgbImage, away: &[PixelRect]) -> Self {
        let (width, height) = frame.dimensions();
        let mut found = strongest_per_cell(frame, away);
        found.sort_by_key(|b| std::cmp::Reverse(b.0));
        found.truncate(MAX_POINTS);
        if found.len() < MIN_POINTS {
            found.clear();
        }
        let points: Vec<(u32, u32)> = found.iter().map(|&(_, x, y)| (x, y)).collect();
        let last = points
            .iter()
            .map(|&(x, y)| frame.get_pixel(x, y).0)
            .collect();
        Self {
            points,
            last,
            still: None,
            size: (width, height),
            #[cfg(test)]
            searches: 0,
        }
    }

    /// The camera's shift from the last frame to `frame` (whole pixels; a point of the still
    /// scene at `p` then is at `p + shift` now), zero when none matches clearly better than
    /// none; `frame`'s colours are kept for the next call.
    pub(super) fn shift_to(&mut self, frame: &RgbImage) -> [i32; 2] {
        if self.points.is_empty() || frame.dimensions() != self.size {
            return [0, 0];
        }
        let gain = self.gain(frame);
        let still = self.distance(frame, [0, 0], gain);
        let searched = self
            .still
            .is_some_and(|s| still > SEARCH_RISE * s && still > s + MIN_SHIFT_LEVELS);
        let mut shift = [0, 0];
        if searched {
            #[cfg(test)]
            {
                self.searches += 1;
            }
            let reach = MAX_CAMERA_SHIFT_PX;
            let mut best = (still, [0, 0]);
            let mut sums = [[0.0f32; SHIFTS]; SHIFTS];
            self.all_distances(frame, gain, &mut sums);
            for (dy, row) in (-reach..=reach).zip(&sums) {
                for (dx, &sum) in (-reach..=reach).zip(row) {
                    let d = f64::from(sum) / self.points.len() as f64
                        + SHIFT_LENGTH_LEVELS * f64::from(dx.abs() + dy.abs());
                    if d < best.0 {
                        best = (d, [dx, dy]);
                    }
                }
            }
            if best.0 < MIN_SHIFT_GAIN * still && best.0 <= still - MIN_SHIFT_LEVELS {
                shift = best.1;
            }
        }
        if shift == [0, 0] {
            self.still = Some(match self.still {
                Some(s) => s + STILL_RATE * (still - s),
                None => still,
            });
        }
        for (v, &(x, y)) in self.last.iter_mut().zip(&self.points) {
            *v = frame.get_pixel(x, y).0;
        }
        shift
    }

    /// Mean capped distance of the points' last colours to `frame`'s at the points moved by
    /// `shift`, the frame's levels scaled by `gain` (inside the frame: points lie
    /// [`MAX_CAMERA_SHIFT_PX`] + 1 inside it, and `frame` is the first frame's size).
    fn distance(&self, frame: &RgbImage, shift: [i32; 2], gain: f32) -> f64 {
        let raw = frame.as_raw();
        let stride = 3 * frame.width() as usize;
        let sum: f32 = self
            .points
            .iter()
            .zip(&self.last)
            .map(|(&(x, y), last)| {
                let at =
                    (y as i32 + shift[1]) as usize * stride + 3 * (x as i32 + shift[0]) as usize;
                let d: f32 = raw[at..at + 3]
                    .iter()
                    .zip(last)
                    .map(|(&a, &b)| (gain * f32::from(a) - f32::from(b)).abs())
                    .sum();
                d.min(POINT_DISTANCE_CAP)
            })
            .sum();
        f64::from(sum) / self.points.len() as f64
    }

    /// The summed capped distances of [`CameraPoints::distance`] for every shift up to
    /// [`MAX_CAMERA_SHIFT_PX`] each way (`sums[dy + reach][dx + reach]`): per point and `dy`
    /// the row of pixels all the `dx` read, scaled by `gain` and compared with the point's
    /// last colour in one pass (which vectorises), then each shift's three channels summed.
    /// The same sums, bit for bit, as one shift at a time: each shift's terms are the same
    /// products and differences, added in the same order (point by point).
    fn all_distances(&self, frame: &RgbImage, gain: f32, sums: &mut [[f32; SHIFTS]; SHIFTS]) {
        let raw = frame.as_raw();
        let stride = 3 * frame.width() as usize;
        let reach = MAX_CAMERA_SHIFT_PX;
        let mut differences = [0.0f32; 3 * SHIFTS];
        let mut lasts = [0.0f32; 3 * SHIFTS];
        sums.iter_mut().for_each(|row| row.fill(0.0));
        for (&(x, y), last) in self.points.iter().zip(&self.last) {
            for (l, c) in lasts
                .chunks_exact_mut(3)
                .flat_map(|l| l.iter_mut().zip(last))
            {
                *l = f32::from(*c);
            }
            for (row_sums, dy) in sums.iter_mut().zip(-reach..=reach) {
                let (row, first) = ((y as i32 + dy) as usize, (x as i32 - reach) as usize);
                let at = row * stride + 3 * first;
                // Points lie MAX_CAMERA_SHIFT_PX + 1 inside the frame, which is the first
                // frame's size: every row read is inside it.
                let Some(pixels) = raw.get(at..at + 3 * SHIFTS) else {
                    row_sums.iter_mut().for_each(|s| *s += POINT_DISTANCE_CAP);
                    continue;
                };
                for ((d, &p), &l) in differences.iter_mut().zip(pixels).zip(&lasts) {
                    *d = (gain * f32::from(p) - l).abs();
                }
                for (s, d) in row_sums.iter_mut().zip(differences.chunks_exact(3)) {
                    *s += (d[0] + d[1] + d[2]).min(POINT_DISTANCE_CAP);
                }
            }
        }
    }

    /// The factor that brings `frame`'s levels at the points to the last frame's (a flicker
    /// of the light changes them all alike): the median of the points' ratios (the sums of
    /// their channels), 1 where too few points are lit in both.
    fn gain(&self, frame: &RgbImage) -> f32 {
        let level = |p: [u8; 3]| p.iter().map(|&v| f32::from(v)).sum::<f32>();
        let mut ratios: Vec<f32> = self
            .points
            .iter()
            .zip(&self.last)
            .map(|(&(x, y), &last)| (level(frame.get_pixel(x, y).0), level(last)))
            .filter(|&(now, last)| now >= GAIN_MIN_LEVEL && last >= GAIN_MIN_LEVEL)
            .map(|(now, last)| last / now)
            .collect();
        if ratios.len() < self.points.len() / 2 || ratios.is_empty() {
            return 1.0;
        }
        let mid = ratios.len() / 2;
        *ratios.select_nth_unstable_by(mid, f32::total_cmp).1
    }
}

/// Per cell of [`POINT_CELL_PX`] (the cells tile the frame from [`MAX_CAMERA_SHIFT_PX`] + 1
/// inside it), its strongest edge as `(gradient, x, y)`: the first pixel in row order whose
/// gradient (|gx| + |gy| of a 3x3 Sobel on the channels' sum, levels) is the cell's greatest
/// and at least [`MIN_POINT_GRADIENT`], pixels inside `away` and black ones (a Kinect's
/// holes) left out. Cells in row order. The gradients are computed a row at a time over a
/// plane of the channels' sums, so that the loop runs in vector lanes.
fn strongest_per_cell(frame: &RgbImage, away: &[PixelRect]) -> Vec<(i32, u32, u32)> {
    let (width, height) = frame.dimensions();
    let margin = MAX_CAMERA_SHIFT_PX as usize + 1;
    let (w, h) = (width as usize, height as usize);
    if w <= 2 * margin || h <= 2 * margin {
        return Vec::new();
    }
    let levels: Vec<i32> = frame
        .as_raw()
        .chunks_exact(3)
        .map(|p| i32::from(p[0]) + i32::from(p[1]) + i32::from(p[2]))
        .collect();
    let cell = POINT_CELL_PX as usize;
    let n = w - 2 * margin;
    let columns = n.div_ceil(cell);
    let mut found = Vec::new();
    let mut gradient = vec![0i32; n];
    let mut band: Vec<Option<(i32, u32, u32)>> = vec![None; columns];
    for y in margin..h - margin {
        let row = |dy: usize| &levels[(y + dy - 1) * w + margin - 1..][..n + 2];
        let (up, mid, down) = (row(0), row(1), row(2));
        for (i, g) in gradient.iter_mut().enumerate() {
            let gx = up[i + 2] + 2 * mid[i + 2] + down[i + 2] - up[i] - 2 * mid[i] - down[i];
            let gy = down[i] + 2 * down[i + 1] + down[i + 2] - up[i] - 2 * up[i + 1] - up[i + 2];
            // A black pixel (a hole) is no point.
            *g = if mid[i + 1] == 0 {
                -1
            } else {
                gx.abs() + gy.abs()
            };
        }
        for a in away.iter().filter(|a| a.contains(a.x, y as i32)) {
            let from = (i64::from(a.x) - margin as i64).clamp(0, n as i64) as usize;
            let to = (a.right() - margin as i64).clamp(0, n as i64) as usize;
            gradient[from..to].fill(-1);
        }
        for (c, best) in band.iter_mut().enumerate() {
            let run = c * cell..((c + 1) * cell).min(n);
            for i in run {
                let g = gradient[i];
                if g >= MIN_POINT_GRADIENT && best.is_none_or(|b| g > b.0) {
                    *best = Some((g, (i + margin) as u32, y as u32));
                }
            }
        }
        if (y - margin + 1).is_multiple_of(cell) || y + 1 == h - margin {
            found.extend(band.iter_mut().filter_map(Option::take));
        }
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// A still scene of trunks and limbs (some diagonal) under a sky, shifted by whole
    /// pixels, with noise.
    fn scene(seed: u64, shift: (i32, i32), noise: u64) -> RgbImage {
        let mut rng = Rng::new(seed);
        let bars: Vec<(f64, f64, f64, [u8; 3])> = (0..14)
            .map(|_| {
                let level = |rng: &mut Rng| rng.range([40.0, 140.0]) as u8;
                (
                    rng.range([0.0, std::f64::consts::PI]),
                    rng.range([0.0, 300.0]),
                    rng.range([3.0, 12.0]),
                    [level(&mut rng), level(&mut rng), level(&mut rng)],
                )
            })
            .collect();
        let mut noise_rng = Rng::new(noise);
        RgbImage::from_fn(320, 240, |x, y| {
            let (x, y) = (f64::from(x as i32 - shift.0), f64::from(y as i32 - shift.1));
            let mut c = [170u8, 200, 235];
            for &(angle, at, width, colour) in &bars {
                let across = x * angle.cos() + y * angle.sin() - at;
                if (0.0..width).contains(&across) {
                    c = colour;
                }
            }
            let n = (noise_rng.normal() * 3.0) as i32;
            image::Rgb(c.map(|v| (i32::from(v) + n).clamp(0, 255) as u8))
        })
    }

    /// The cells' strongest edges as the plain per-pixel search finds them: the first pixel
    /// in row order of a cell's greatest gradient, away rectangles and holes left out.
    fn strongest_pixel_by_pixel(frame: &RgbImage, away: &[PixelRect]) -> Vec<(i32, u32, u32)> {
        let (width, height) = frame.dimensions();
        let margin = MAX_CAMERA_SHIFT_PX as u32 + 1;
        let level = |x: i32, y: i32| -> i32 {
            let p = frame.get_pixel(x as u32, y as u32).0;
            p.iter().map(|&v| i32::from(v)).sum()
        };
        let mut found = Vec::new();
        for cy in (margin..height - margin).step_by(POINT_CELL_PX as usize) {
            for cx in (margin..width - margin).step_by(POINT_CELL_PX as usize) {
                let mut best: Option<(i32, u32, u32)> = None;
                for y in cy..(cy + POINT_CELL_PX).min(height - margin) {
                    for x in cx..(cx + POINT_CELL_PX).min(width - margin) {
                        let (xi, yi) = (x as i32, y as i32);
                        if away.iter().any(|a| a.contains(xi, yi)) || level(xi, yi) == 0 {
                            continue;
                        }
                        let l = |dx: i32, dy: i32| level(xi + dx, yi + dy);
                        let gx =
                            l(1, -1) + 2 * l(1, 0) + l(1, 1) - l(-1, -1) - 2 * l(-1, 0) - l(-1, 1);
                        let gy =
                            l(-1, 1) + 2 * l(0, 1) + l(1, 1) - l(-1, -1) - 2 * l(0, -1) - l(1, -1);
                        let g = gx.abs() + gy.abs();
                        if g >= MIN_POINT_GRADIENT && best.is_none_or(|b| g > b.0) {
                            best = Some((g, x, y));
                        }
                    }
                }
                found.extend(best);
            }
        }
        found
    }

    /// The row-at-a-time search finds each cell's point where the pixel-by-pixel one does,
    /// with rectangles to stay away from (one reaching out of the frame, one empty) and
    /// holes, on frames whose sizes do and do not divide into whole cells.
    #[test]
    fn the_cells_strongest_edges_are_found_row_by_row_as_pixel_by_pixel() {
        let away = [
            PixelRect::new(40, 30, 25, 18),
            PixelRect::new(-10, 100, 60, 300),
            PixelRect::new(200, 50, 0, 40),
            PixelRect::new(300, 220, 40, 40),
        ];
        for (seed, (w, h)) in [(3, (320, 240)), (4, (317, 203)), (5, (61, 45))] {
            let mut frame =
                image::imageops::crop_imm(&scene(seed, (0, 0), seed), 0, 0, w, h).to_image();
            for (x, y) in [(50, 80), (51, 80), (120, 33), (29, 29)] {
                if x < w && y < h {
                    frame.put_pixel(x, y, image::Rgb([0, 0, 0]));
                }
            }
            let expected = strongest_pixel_by_pixel(&frame, &away);
            assert!(expected.len() >= 4, "{}", expected.len());
            assert_eq!(strongest_per_cell(&frame, &away), expected, "seed {seed}");
        }
        let tiny = RgbImage::new(2 * MAX_CAMERA_SHIFT_PX as u32 + 2, 100);
        assert!(strongest_per_cell(&tiny, &[]).is_empty());
    }

    #[test]
    fn a_shaken_camera_is_measured_and_a_still_one_is_not_moved() {
        let first = scene(3, (0, 0), 1);
        let mut points = CameraPoints::of(&first, &[]);
        assert!(points.points.len() > 40, "{}", points.points.len());
        // Still frames with new noise learn what no shift looks like.
        for k in 0..5 {
            assert_eq!(points.shift_to(&scene(3, (0, 0), 10 + k)), [0, 0]);
        }
        let mut at = (0, 0);
        for (k, (dx, dy)) in [(7, -4), (-12, 9), (3, 0), (0, -5)].into_iter().enumerate() {
            let next = (at.0 + dx, at.1 + dy);
            let s = points.shift_to(&scene(3, next, 20 + k as u64));
            assert_eq!(s, [dx, dy], "({dx}, {dy})");
            at = next;
        }
        assert_eq!(points.shift_to(&scene(3, at, 40)), [0, 0]);
        // A flicker of the light is not a shift, and does not hide one.
        let dimmed = |image: RgbImage, gain: f64| {
            let mut image = image;
            image
                .pixels_mut()
                .for_each(|p| p.0 = p.0.map(|v| (f64::from(v) * gain) as u8));
            image
        };
        assert_eq!(points.shift_to(&dimmed(scene(3, at, 41), 0.8)), [0, 0]);
        assert_eq!(points.shift_to(&scene(3, at, 42)), [0, 0]);
        let next = (at.0 - 6, at.1 + 5);
        assert_eq!(points.shift_to(&dimmed(scene(3, next, 43), 0.85)), [-6, 5]);
        assert!(points.searches <= 6, "{}", points.searches);
    }

    /// The search's rows of sums are each shift's distance, to the bit.
    #[test]
    fn all_shifts_at_once_are_each_shift_alone() {
        let first = scene(7, (0, 0), 1);
        let mut points = CameraPoints::of(&first, &[]);
        assert!(points.points.len() >= MIN_POINTS);
        points.shift_to(&scene(7, (0, 0), 2));
        let shaken = scene(7, (5, -3), 3);
        let mut sums = [[0.0f32; SHIFTS]; SHIFTS];
        for gain in [1.0, 0.87] {
            points.all_distances(&shaken, gain, &mut sums);
            let n = points.points.len() as f64;
            let reach = MAX_CAMERA_SHIFT_PX;
            for (dy, row) in (-reach..=reach).zip(&sums) {
                for (dx, &sum) in (-reach..=reach).zip(row) {
                    let alone = points.distance(&shaken, [dx, dy], gain);
                    assert_eq!(f64::from(sum) / n, alone, "({dx}, {dy}) at gain {gain}");
                }
            }
            // The shake is the nearest shift.
            let best = (0..SHIFTS * SHIFTS).min_by(|&a, &b| {
                sums[a / SHIFTS][a % SHIFTS].total_cmp(&sums[b / SHIFTS][b % SHIFTS])
            });
            let b = best.unwrap_or(0);
            let found = [
                b as i32 % SHIFTS as i32 - reach,
                b as i32 / SHIFTS as i32 - reach,
            ];
            if gain == 1.0 {
                assert_eq!(found, [5, -3]);
            }
        }
    }

    #[test]
    fn markers_moving_over_a_still_scene_do_not_move_it() {
        let first = scene(5, (0, 0), 1);
        let mut points = CameraPoints::of(&first, &[]);
        for k in 0..5 {
            points.shift_to(&scene(5, (0, 0), 10 + k));
        }
        // Eight marker-sized red discs appear.
        let mut moved = scene(5, (0, 0), 30);
        for k in 0..8u32 {
            let (cx, cy) = (30 + 35 * k, 40 + 20 * k);
            for y in cy - 8..cy + 8 {
                for x in cx - 8..cx + 8 {
                    if (x as i32 - cx as i32).pow(2) + (y as i32 - cy as i32).pow(2) < 64 {
                        moved.put_pixel(x, y, image::Rgb([210, 30, 30]));
                    }
                }
            }
        }
        assert_eq!(points.shift_to(&moved), [0, 0]);
        // Another size, or a frame too small for points: no shift, not a panic.
        assert_eq!(points.shift_to(&RgbImage::new(10, 10)), [0, 0]);
        let mut none = CameraPoints::of(&RgbImage::new(20, 20), &[]);
        assert_eq!(none.shift_to(&RgbImage::new(20, 20)), [0, 0]);
    }
}
