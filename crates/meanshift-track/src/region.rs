//! A marker's weights over a region of a frame, and mean-shift on them: the histogram models'
//! back-projection (OpenCV's arithmetic per window, sub-pixel centroid at the end) and the
//! kernel model's Bhattacharyya mean-shift (Comaniciu, Ramesh, Meer 2003).

use image::RgbImage;
use nalgebra::Point2;

use crate::histogram::Histogram;
use crate::hsv::{ChannelRange, rgb_to_gray, rgb_to_hsv};
use crate::meanshift::{Moments, TermCriteria, moments_from_f64_sums};
use crate::model::{AppearanceModel, MarkerModel, holes_are_no_data, is_hole};
use crate::rect::PixelRect;
use crate::tracker::DepthView;

/// No bin (masked out, gated, claimed or outside the histogram's range).
pub(crate) const NO_BIN: u32 = u32::MAX;
/// Shift in pixels below which the kernel (Bhattacharyya) mean-shift has converged
/// (Comaniciu et al. 2003 stop below one pixel; sub-pixel centres need a finer stop, since
/// on a uniform blob each step covers only part of the remaining distance).
const KERNEL_EPSILON_PX: f64 = 0.05;
/// Iteration limit of the kernel mean-shift.
const KERNEL_MAX_ITERATIONS: usize = 30;
/// Border of CamShift's size estimate around the converged window (OpenCV's `TOLERANCE`).
const ADAPTIVE_BORDER_PX: i32 = 10;

/// Least distance (8-bit RGB levels) between the marker's colour and the background for a
/// streak to be told from it.
pub(crate) const STREAK_MIN_CONTRAST: f32 = 40.0;
/// Least coverage of a streak pixel: the share of the exposure the marker spent on it.
const STREAK_MIN_COVERAGE: f32 = 0.15;
/// Coverage at and above which a streak pixel weighs as much as the marker's own colour.
const STREAK_FULL_COVERAGE: f32 = 0.5;
/// Largest distance (8-bit levels) of a streak pixel from the line between background and
/// marker colour, and as a share of the coverage times the contrast (colour noise, JPEG).
pub(crate) const STREAK_RESIDUAL: [f32; 2] = [15.0, 0.3];
/// The least brightness a streak pixel may imply for what covered it, as a share of the
/// marker's mean colour, unless the marker's own darkest pixels on the first frame are
/// darker (see `Tracker` `darkest_shade`): a streak pixel is a mean of the marker's surface
/// along its path, never darker than its darkest part, while a dark twig's or branch's smear
/// blended with the sky lies on the same mixing line at about half the marker's brightness
/// (the third generator's bark twigs imply 0.53 of a red marker's colour; its shaded
/// spheres' darkest pixels 0.56-0.64, `docs/validation.md`).
pub(crate) const STREAK_MIN_SHADE: f32 = 0.6;
/// Largest distance of a streak pixel off the plane of its background and the marker's core
/// colour toward gray's side of it, as a share of the coverage times the contrast, for a
/// marker whose rim on the first frame blends with its background in that plane (see
/// `Tracker` `rim_hue_share`). The plane holds every blend of the background with every
/// shade of the marker; a twig or branch smeared over the sky implies a grayer colour, off
/// it toward gray (a green marker's twig on the third generator's seed 8: 0.15-0.2 of the
/// contrast), while a compressed frame's blends at an edge leave it either way (luma kept
/// per pixel, chroma shared by blocks), so only gray's side is held. Chosen on the third
/// generator's tuning seeds (`docs/validation.md`).
pub(crate) const STREAK_MIN_HUE_SHARE: f32 = 0.1;
/// Largest distance off the plane of background and core colour toward gray, as a share of
/// coverage times contrast, of a neighbourhood of streak pixels taken together (see
/// `Region::grayer_streaks`). Chosen on the third generator's tuning seeds: their
/// twigs' smears lie at 0.08-0.13, their markers' streaks at 0-0.04.
pub(crate) const STREAK_LOCAL_HUE_SHARE: f32 = 0.05;
/// Half the side of the neighbourhood of [`STREAK_LOCAL_HUE_SHARE`] (a 5x5 square: about
/// a third of the smallest marker's width, so that a streak's rim is judged with its core).
const STREAK_LOCAL_RADIUS_PX: usize = 2;
/// Pixel step of the sampling pass of a sparse [`Region::fill`], along rows and between rows: a
/// blob three pixels across in both directions holds a sampled pixel (the smallest marker,
/// 12 px, and its streak are several times that; a sliver of a marker under three pixels
/// wide, at an occluder's edge, may be missed, as one under two was before). Three against
/// two before: a ninth of a gate weighed in the sampling pass, not a quarter (`track_into`
/// on the combined stress condition, seed 1000: 854.8 M instructions with 2, 738.3 M with
/// 3, 675.3 M with 4; see `docs/validation.md` for the tracks).
const SPARSE_STEP_PX: usize = 3;
/// Cells about each cell with a sampled hit that a sparse [`Region::fill`] weighs in full (a
/// cell is half a marker window): a blob, its edge and the window about its centre.
const SPARSE_REACH_CELLS: usize = 2;
/// Share of a sparse fill's cells holding a hit past which the sampling stops and the region
/// is weighed whole: each hit brings up to `(2 SPARSE_REACH_CELLS + 1)^2` cells with it, so
/// past this most of a cluttered region would be weighed after the sampling pass anyway.
const SPARSE_MAX_HIT_SHARE: f64 = 0.04;
/// Pixels weighed together by [`Region::fill_rows`]: long enough that the vector loops'
/// remainders are rare, short enough that the block and its feature planes stay in the
/// first-level cache.
const BLOCK_PX: usize = 1024;
/// Pixels of a row whose streak weights are computed together, in vector registers.
const STREAK_CHUNK_PX: usize = 16;

/// What a moving marker leaves: a streak whose pixels mix the marker's colour with the
/// background in proportion to the time it covered them (`p = a m + (1 - a) b`). The
/// background of a pixel is taken from the previous frame, which a marker fast enough to blur
/// has left; a static or slow marker gives no streak weight (its colour does the work).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Streak<'a> {
    /// The previous frame (same size as the frame).
    pub(crate) previous: &'a RgbImage,
    /// The camera's shift since the previous frame (whole pixels): a pixel's background at
    /// `(x, y)` is the previous frame's at `(x - shift[0], y - shift[1])`, clamped into it.
    pub(crate) shift: [i32; 2],
    /// The marker's mean colour (RGB).
    pub(crate) colour: [f32; 3],
    /// The least brightness, as a share of `colour` (its projection on it), of the colour a
    /// streak pixel implies for what covered it (see [`Streak::raise_row`]).
    pub(crate) shade: f32,
    /// The largest distance of a streak pixel off the plane of its background and `core`
    /// toward gray, as a share of coverage times contrast: from [`STREAK_MIN_HUE_SHARE`]
    /// (a rim blending in the plane) up to the general residual's share
    /// (`STREAK_RESIDUAL[1]`: a marker whose rim is paled toward gray, by a camera's chroma
    /// denoising for one, whose streaks are paled as much).
    pub(crate) hue_share: f32,
    /// The marker's core colour (RGB; its hue, see `Tracker` `core_colour`).
    pub(crate) core: [f32; 3],
    /// Where the marker was in the previous frame, and the background around it there.
    pub(crate) trail: Option<Trail>,
}

/// Where streak weights raised a pixel's weight, as two planes of one length: the pixel's
/// distance off the plane of its background and the marker's core colour toward gray
/// (`off`, 8-bit levels, negative on the other side), and the coverage times the contrast
/// that the distance is measured against (`scale`); both zero where the streak raised
/// nothing.
#[derive(Debug, Default)]
struct Lifts {
    off: Vec<f32>,
    scale: Vec<f32>,
}

impl Lifts {
    fn resize(&mut self, n: usize) {
        self.off.resize(n, 0.0);
        self.scale.resize(n, 0.0);
    }

    /// The `n` entries from `at` on, to be written.
    fn slice(&mut self, at: usize, n: usize) -> LiftsMut<'_> {
        LiftsMut {
            off: &mut self.off[at..at + n],
            scale: &mut self.scale[at..at + n],
        }
    }

    /// Copy `n` entries of `from`, from `at` on, to `to` on.
    fn copy_from(&mut self, to: usize, from: &Lifts, at: usize, n: usize) {
        self.off[to..to + n].copy_from_slice(&from.off[at..at + n]);
        self.scale[to..to + n].copy_from_slice(&from.scale[at..at + n]);
    }
}

/// A run of [`Lifts`] to write.
struct LiftsMut<'a> {
    off: &'a mut [f32],
    scale: &'a mut [f32],
}

/// The marker's window in the previous frame (in this frame's pixels, the camera's shift
/// applied) and the colour around it there. Inside it the previous frame shows the marker,
/// not what lies behind it: a streak's trailing end, where the marker was, would have its own
/// colour for background and no streak weight, so the measurement ran ahead along the motion
/// (by half the jump on a release frame drawn twice). There, a pixel of the previous frame
/// nearer the marker's colour than the surroundings' is replaced by the surroundings'.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Trail {
    pub(crate) rect: PixelRect,
    pub(crate) around: [u8; 3],
}

impl Trail {
    /// Replace, in `background` (the previous frame's RGB pixels under `row`, this frame's,
    /// of row `y` at columns `x`, `x + step`, ...), the pixels inside the trail that are
    /// nearer `marker` than the surroundings and that changed since (the marker left them,
    /// at least in part: a marker or a look-alike that stays keeps its pixels, and its own
    /// colour is what weighs it).
    fn patch(
        &self,
        marker: [f32; 3],
        (x, y): (i32, i32),
        step: usize,
        row: &[u8],
        background: &mut [u8],
    ) {
        let r = self.rect;
        if y < r.y || y >= r.bottom() as i32 {
            return;
        }
        let around = self.around.map(f32::from);
        for (k, (px, now)) in background
            .chunks_exact_mut(3)
            .zip(row.chunks_exact(3))
            .enumerate()
        {
            let xk = i64::from(x) + (k * step) as i64;
            if xk < i64::from(r.x) || xk >= r.right() {
                continue;
            }
            let changed = px
                .iter()
                .zip(now)
                .any(|(&b, &p)| b.abs_diff(p) > TRAIL_CHANGED_LEVEL);
            let b = [f32::from(px[0]), f32::from(px[1]), f32::from(px[2])];
            let to = |c: [f32; 3]| (0..3).map(|i| (b[i] - c[i]).powi(2)).sum::<f32>();
            if changed && to(marker) < to(around) {
                px.copy_from_slice(&self.around);
            }
        }
    }
}

/// A pixel whose colour moved this much (8-bit levels, in some channel) since the previous
/// frame has changed (colour noise and JPEG stay below it; the tracker's `CHANGED_LEVEL`).
const TRAIL_CHANGED_LEVEL: u8 = 30;

impl Streak<'_> {
    /// Raise the weights of a row of pixels (`row`, RGB) to their streak weights over the
    /// same pixels of the previous frame (`background`): per pixel the greater of the two.
    /// The streak weight (0..255) of colour `p` over background `b` is 255 times the
    /// coverage up to [`STREAK_FULL_COVERAGE`], 0 off the mixing line, below
    /// [`STREAK_MIN_COVERAGE`] or where the background is within [`STREAK_MIN_CONTRAST`] of
    /// the marker's colour. Computed without branches, [`STREAK_CHUNK_PX`] pixels at a
    /// time: their channels split into small arrays and the arithmetic over those, which the
    /// compiler keeps in vector registers (splitting whole rows into planes in memory first
    /// cost about 3 % more of the tracker's time on the combined stress condition).
    fn raise_row(
        &self,
        weights: &mut [f32],
        row: &[u8],
        background: &[u8],
        lifts: LiftsMut<'_>,
    ) -> bool {
        let n = weights
            .len()
            .min(row.len() / 3)
            .min(background.len() / 3)
            .min(lifts.scale.len());
        let weights = &mut weights[..n];
        let (off, scale) = (&mut lifts.off[..n], &mut lifts.scale[..n]);
        let c = STREAK_CHUNK_PX;
        let mut chunks = weights.chunks_exact_mut(c);
        let (mut offs, mut scales) = (off.chunks_exact_mut(c), scale.chunks_exact_mut(c));
        let mut at = 0;
        let mut any = false;
        for ((out, o0), s0) in (&mut chunks).zip(&mut offs).zip(&mut scales) {
            let (p, b) = (&row[3 * at..][..3 * c], &background[3 * at..][..3 * c]);
            if let (Ok(out), Ok(o0), Ok(s0)) = (
                <&mut [f32; STREAK_CHUNK_PX]>::try_from(out),
                <&mut [f32; STREAK_CHUNK_PX]>::try_from(o0),
                <&mut [f32; STREAK_CHUNK_PX]>::try_from(s0),
            ) {
                any |= self.raise_chunk(out, p, b, [o0, s0]);
            }
            at += c;
        }
        let rest = chunks
            .into_remainder()
            .iter_mut()
            .zip(offs.into_remainder())
            .zip(scales.into_remainder());
        for (k, ((w, o0), s0)) in rest.enumerate() {
            let (p, b) = (&row[3 * (at + k)..][..3], &background[3 * (at + k)..][..3]);
            let mut one = [*w];
            let (mut lo, mut ls) = ([0.0], [0.0]);
            any |= self.raise_chunk::<1>(&mut one, p, b, [&mut lo, &mut ls]);
            (*w, *o0, *s0) = (one[0], lo[0], ls[0]);
        }
        any
    }

    /// [`Streak::raise_row`] over `N` pixels, their channels split into arrays the compiler
    /// keeps in vector registers.
    #[inline(always)]
    fn raise_chunk<const N: usize>(
        &self,
        weights: &mut [f32; N],
        row: &[u8],
        background: &[u8],
        [off, scales]: [&mut [f32; N]; 2],
    ) -> bool {
        let mut p = [[0.0f32; N]; 3];
        let mut b = [[0.0f32; N]; 3];
        for i in 0..N {
            for c in 0..3 {
                p[c][i] = f32::from(row[3 * i + c]);
                b[c][i] = f32::from(background[3 * i + c]);
            }
        }
        let m = self.colour;
        let mm = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];
        let shade = self.shade;
        let k = self.core;
        let mut any = false;
        for i in 0..N {
            let d = [m[0] - b[0][i], m[1] - b[1][i], m[2] - b[2][i]];
            let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let e = [p[0][i] - b[0][i], p[1][i] - b[1][i], p[2][i] - b[2][i]];
            let ed = e[0] * d[0] + e[1] * d[1] + e[2] * d[2];
            let a = ed / dd;
            // The colour the pixel implies for what covered it, `b + e / a`, at least
            // `shade` of the marker's colour along it: (b + e / a) . m >= shade m . m.
            let em = e[0] * m[0] + e[1] * m[1] + e[2] * m[2];
            let bm = b[0][i] * m[0] + b[1][i] * m[1] + b[2][i] * m[2];
            let bright = em >= a * (shade * mm - bm);
            let r = [e[0] - a * d[0], e[1] - a * d[1], e[2] - a * d[2]];
            let rr = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
            let scale = a.min(1.0) * dd.sqrt();
            let limit = STREAK_RESIDUAL[0].max(STREAK_RESIDUAL[1] * scale);
            // Off the plane of the background and the marker's core colour, which holds
            // every blend of the background with every shade of the marker, toward gray:
            // `e . n` over `|n|`, `n = core x b`, of the sign of `(1, 1, 1) . n` (no test
            // where the two are parallel: `n` is zero).
            let n = [
                k[1] * b[2][i] - k[2] * b[1][i],
                k[2] * b[0][i] - k[0] * b[2][i],
                k[0] * b[1][i] - k[1] * b[0][i],
            ];
            let en = e[0] * n[0] + e[1] * n[1] + e[2] * n[2];
            let nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
            let hue_limit = STREAK_RESIDUAL[0].max(self.hue_share * scale);
            let on_line = dd >= STREAK_MIN_CONTRAST * STREAK_MIN_CONTRAST
                && ed >= STREAK_MIN_COVERAGE * dd
                && rr <= limit * limit
                && (en * (n[0] + n[1] + n[2]) <= 0.0 || en * en <= hue_limit * hue_limit * nn)
                && bright;
            let streak = if on_line {
                255.0 * (a / STREAK_FULL_COVERAGE).min(1.0)
            } else {
                0.0
            };
            // Where the streak raised the weight, for the neighbourhood's test
            // (`grayer_streaks`): the distance toward gray off the plane, its scale.
            let raised = streak > weights[i];
            let toward_gray = if n[0] + n[1] + n[2] > 0.0 { en } else { -en };
            let kept = if raised { 1.0 } else { 0.0 };
            off[i] = kept * toward_gray * inverse_sqrt(nn);
            scales[i] = kept * scale;
            any |= raised;
            weights[i] = weights[i].max(streak);
        }
        any
    }
}

/// Side of the neighbourhood [`Region::grayer_streaks`] sums (pixels).
const LOCAL_SIDE_PX: usize = 2 * STREAK_LOCAL_RADIUS_PX + 1;

/// Add to `off` and `scale`, in order, the `offs` and `scales` of the pixels whose weight
/// (`weights`) is positive.
#[inline(always)]
fn add_weighed<W, L>(weights: W, offs: L, scales: L, off: &mut f32, scale: &mut f32)
where
    W: IntoIterator<Item = f32>,
    L: IntoIterator<Item = f32>,
{
    for ((wt, o), s) in weights.into_iter().zip(offs).zip(scales) {
        let weighs = if wt > 0.0 { 1.0 } else { 0.0 };
        *off += weighs * o;
        *scale += weighs * s;
    }
}

/// `1 / sqrt(x)` to about 0.2 % (one Newton step from the bit-level estimate), 0 for `x`
/// of 0 or less: without a square root or a division, so that the streak loop stays cheap
/// where it only keeps the distance for [`Region::grayer_streaks`]'s sums.
#[inline(always)]
fn inverse_sqrt(x: f32) -> f32 {
    let guess = f32::from_bits(0x5f37_59df_u32.wrapping_sub(x.to_bits() >> 1));
    let y = guess * (1.5 - 0.5 * x * guess * guess);
    if x > 0.0 { y } else { 0.0 }
}

/// Per pixel of a row given as three feature planes, its entry of `table` (a weight or a
/// bin), `missing` where the lookup rejects it: by the one-channel form (`one`: the form and
/// its table by the first channel) when there is one, else by the general three-table
/// lookup. Planes, not interleaved pixels, so that the one-channel loop runs in vector lanes
/// (a gathered read and four range tests per pixel).
#[inline(always)]
fn look_up_row<T: Copy>(
    out: &mut [T],
    [c0, c1, c2]: [&[u8]; 3],
    missing: T,
    one: Option<(&OneChannel, &[T; 256])>,
    table: &[T],
    tables: &[[u32; 256]; 3],
) {
    let n = out.len().min(c0.len()).min(c1.len()).min(c2.len());
    let (out, c0, c1, c2) = (&mut out[..n], &c0[..n], &c1[..n], &c2[..n]);
    if let Some((one, by_first)) = one {
        let ([lo1, lo2], [hi1, hi2]) = (one.lower, one.upper);
        for i in 0..n {
            let pass = (c1[i] >= lo1) & (c1[i] <= hi1) & (c2[i] >= lo2) & (c2[i] <= hi2);
            let v = by_first[usize::from(c0[i])];
            out[i] = if pass { v } else { missing };
        }
    } else {
        let [t0, t1, t2] = tables;
        for i in 0..n {
            let entry = t0[usize::from(c0[i])] + t1[usize::from(c1[i])] + t2[usize::from(c2[i])];
            out[i] = table.get(entry as usize).copied().unwrap_or(missing);
        }
    }
}

/// The features of a row of RGB pixels as three planes in `planes` (each `row.len() / 3`
/// long): with `HSV` the pixels converted to HSV and then `features` applied, else
/// `features` of the RGB pixels.
#[inline(always)]
fn feature_planes<'p, const HSV: bool>(
    row: &[u8],
    features: &impl Fn([u8; 3]) -> [u8; 3],
    planes: &'p mut Vec<u8>,
) -> [&'p [u8]; 3] {
    let n = row.len() / 3;
    // Every value of the planes is written below: grow the scratch, never clear it.
    if planes.len() < 3 * n {
        planes.resize(3 * n, 0);
    }
    let (p0, rest) = planes[..3 * n].split_at_mut(n);
    let (p1, p2) = rest.split_at_mut(n);
    for (((p, x0), x1), x2) in row
        .chunks_exact(3)
        .zip(p0.iter_mut())
        .zip(p1.iter_mut())
        .zip(p2.iter_mut())
    {
        let rgb = [p[0], p[1], p[2]];
        let f = features(if HSV { rgb_to_hsv(rgb) } else { rgb });
        (*x0, *x1, *x2) = (f[0], f[1], f[2]);
    }
    [&*p0, &*p1, &*p2]
}

/// The weights (and with `bins_out` the bins) of one row of RGB pixels: the lookup of each
/// pixel's features, raised to its streak weight over `background` where there is one.
#[inline(always)]
fn weigh_row<const HSV: bool>(
    lookup: &Lookup,
    features: &impl Fn([u8; 3]) -> [u8; 3],
    row: &[u8],
    background: Option<(Streak<'_>, &[u8], LiftsMut<'_>)>,
    feature_rows: &mut Vec<u8>,
    out: &mut [f32],
    bins_out: Option<&mut [u32]>,
) -> bool {
    let Lookup {
        tables,
        values,
        bins,
        one_channel,
        holes,
    } = lookup;
    let planes = feature_planes::<HSV>(row, features, feature_rows);
    let one = one_channel.as_deref().map(|o| (o, &o.weight));
    look_up_row(out, planes, 0.0, one, values, tables);
    let raised =
        background.is_some_and(|(s, background, lifts)| s.raise_row(out, row, background, lifts));
    let mut bins_out = bins_out;
    if let Some(out) = bins_out.as_deref_mut() {
        let one = one_channel.as_deref().map(|o| (o, &o.bin));
        look_up_row(out, planes, NO_BIN, one, bins, tables);
    }
    if *holes {
        no_data_in_holes(row, out, bins_out);
    }
    raised
}

/// Weight 0 and no bin for every hole (see [`is_hole`]) of a row of RGB pixels.
fn no_data_in_holes(row: &[u8], weights: &mut [f32], mut bins: Option<&mut [u32]>) {
    for (k, (p, w)) in row.chunks_exact(3).zip(weights.iter_mut()).enumerate() {
        if is_hole([p[0], p[1], p[2]]) {
            *w = 0.0;
            if let Some(b) = bins.as_deref_mut().and_then(|b| b.get_mut(k)) {
                *b = NO_BIN;
            }
        }
    }
}

/// Mark in `rows` the rows of `scales` (`width` entries a row, see [`Lifts`]) that hold a
/// pixel a streak raised.
fn mark_raised_rows(rows: &mut [bool], scales: &[f32], width: usize) {
    for (mark, row) in rows.iter_mut().zip(scales.chunks(width.max(1))) {
        *mark |= row.iter().any(|&v| v > 0.0);
    }
}

/// Every [`SPARSE_STEP_PX`]-th pixel of a row of RGB pixels (the first among them) into
/// `out`.
fn gather(row: &[u8], out: &mut Vec<u8>) {
    let n = (row.len() / 3).div_ceil(SPARSE_STEP_PX);
    out.resize(3 * n, 0);
    for (o, p) in out.chunks_exact_mut(3).zip(row.chunks(3 * SPARSE_STEP_PX)) {
        o.copy_from_slice(&p[..3]);
    }
}

/// The streak of `filter` with the previous frame's pixels, where the previous frame is the
/// frame's size.
fn streak_background<'a>(
    filter: &PixelFilter<'a>,
    frame: &RgbImage,
) -> Option<(Streak<'a>, &'a [u8])> {
    filter
        .streak
        .filter(|s| s.previous.dimensions() == frame.dimensions())
        .map(|s| (s, s.previous.as_raw().as_slice()))
}

/// Append to `out` the background of the `len` pixels of row `y` from column `x` on (all
/// inside the frame): the previous frame's pixels (`previous`, RGB bytes, `width` x
/// `height`) where the camera's `shift` puts them, clamped into that frame.
fn extend_background(
    previous: &[u8],
    (width, height): (u32, u32),
    (x, y): (i32, i32),
    len: usize,
    shift: [i32; 2],
    out: &mut Vec<u8>,
) {
    let (width, height) = (width as i32, height as i32);
    let stride = 3 * width as usize;
    let sy = (y - shift[1]).clamp(0, height - 1) as usize;
    let sx = x - shift[0];
    let row = &previous[sy * stride..(sy + 1) * stride];
    if sx >= 0 && sx as usize + len <= width as usize {
        out.extend_from_slice(&row[3 * sx as usize..3 * (sx as usize + len)]);
    } else {
        for k in 0..len as i32 {
            let c = 3 * (sx + k).clamp(0, width - 1) as usize;
            out.extend_from_slice(&row[c..c + 3]);
        }
    }
}

/// What a pixel must pass to count, besides the model and its mask (in the [`Lookup`]): a
/// depth gate, and rectangles other markers hold.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PixelFilter<'a> {
    /// `(gate, marker depth, depth map)`: pixels farther than the gate from the marker's
    /// depth do not count.
    pub(crate) depth: Option<(f64, f64, DepthView<'a>)>,
    pub(crate) masked: &'a [PixelRect],
    /// Rectangles in which only pixels at least this saturated count (8-bit levels): a
    /// paler look-alike of a marker that the marker may be passing over.
    pub(crate) paler: &'a [(PixelRect, u8)],
    /// Streak weights for a moving marker (colour models), the greater of the two counts.
    pub(crate) streak: Option<Streak<'a>>,
}

impl PixelFilter<'_> {
    /// Whether the pixel at `(x, y)` is rejected: in a masked rectangle, or beyond the depth
    /// gate.
    fn rejects(&self, x: i32, y: i32) -> bool {
        let in_mask = self.masked.iter().any(|m| m.contains(x, y));
        in_mask
            || self
                .depth
                .is_some_and(|(g, dm, d)| d.at(x, y).is_some_and(|v| (v - dm).abs() > g))
    }

    /// Weight 0 and no bin for the pixels of row `y` of `sub` (`weights`, `bins`: that row;
    /// `pixels`: its RGB) that the filter rejects: those in a masked rectangle, those under
    /// the saturation floor of a paler look-alike's rectangle, and those beyond the depth
    /// gate. (The sparse sampler's [`PixelFilter::rejects`] leaves the paler rectangles to
    /// this: a sample it keeps only has its cells weighed in full.)
    fn reject_in_row(
        &self,
        sub: PixelRect,
        y: i32,
        pixels: &[u8],
        weights: &mut [f32],
        mut bins: Option<&mut [u32]>,
    ) {
        let width = sub.width as usize;
        let mut reject = |from: usize, to: usize| {
            weights[from..to].fill(0.0);
            if let Some(b) = bins.as_deref_mut() {
                b[from..to].fill(NO_BIN);
            }
        };
        for m in self.masked {
            if i64::from(y) < i64::from(m.y) || i64::from(y) >= m.bottom() {
                continue;
            }
            let from = (i64::from(m.x) - i64::from(sub.x)).clamp(0, width as i64) as usize;
            let to = (m.right() - i64::from(sub.x)).clamp(0, width as i64) as usize;
            if from < to {
                reject(from, to);
            }
        }
        for &(m, floor) in self.paler {
            if i64::from(y) < i64::from(m.y) || i64::from(y) >= m.bottom() {
                continue;
            }
            let from = (i64::from(m.x) - i64::from(sub.x)).clamp(0, width as i64) as usize;
            let to = (m.right() - i64::from(sub.x)).clamp(0, width as i64) as usize;
            for i in from..to {
                let p = &pixels[3 * i..3 * i + 3];
                if crate::hsv::rgb_to_hsv([p[0], p[1], p[2]])[1] < floor {
                    reject(i, i + 1);
                }
            }
        }
        if let Some((g, dm, d)) = self.depth {
            for i in 0..width {
                let x = sub.x + i as i32;
                if d.at(x, y).is_some_and(|v| (v - dm).abs() > g) {
                    reject(i, i + 1);
                }
            }
        }
    }
}

/// The model's weights over a region of the frame.
#[derive(Debug, Default)]
pub(crate) struct Region {
    pub(crate) rect: PixelRect,
    /// Per-pixel weight: the back-projection (histogram models) or the target histogram's
    /// value scaled to 0..255 (kernel model).
    pub(crate) weights: Vec<f32>,
    /// Histogram bins (kernel model), [`NO_BIN`] where the pixel does not count.
    pub(crate) bins: Vec<u32>,
    /// Candidate histogram scratch (kernel model), all zero between kernel steps.
    p: Vec<f64>,
    /// The bins of `p` a kernel step set.
    touched: Vec<u32>,
    /// Pixel scratch of a kernel step.
    pixels: Vec<(i32, i32, u32, f64)>,
    /// One row of the region's features (HSV, RGB or gray) as three planes, converted a row
    /// at a time so that the conversion and the lookups each run in vector lanes.
    feature_rows: Vec<u8>,
    /// Scratch of the sampling pass of a sparse [`Region::fill`].
    scratch: SparseScratch,
    /// Scratch of [`Region::fill_rows`].
    block: BlockScratch,
    /// What streak weights raised, per pixel (see [`Lifts`]); current only where a pixel
    /// of this fill weighs more than 0.
    lifts: Lifts,
    /// Per row of the region, whether a streak weight of this fill raised a pixel in it.
    raised_rows: Vec<bool>,
    /// Pixels whose streak weight [`Region::grayer_streaks`] takes back (scratch).
    grayer: Vec<usize>,
    /// Whether the last sparse [`Region::fill`] found the region cluttered and weighed it
    /// whole.
    pub(crate) cluttered: bool,
    /// Whether [`Region::locate`] measures the moments of its window and a border (only an
    /// adaptive window size reads them; each costs a sum over about twice the window).
    pub(crate) moments_wanted: bool,
}

/// A block of rows of a region copied out of the frame (and the previous frame), and its
/// weights and bins where the rows do not lie one after the other in the region's buffers.
#[derive(Debug, Default)]
struct BlockScratch {
    pixels: Vec<u8>,
    background: Vec<u8>,
    weights: Vec<f32>,
    bins: Vec<u32>,
    lifts: Lifts,
}

impl BlockScratch {
    /// Copy rows `rows` of `sub` out of `frame`, and with a streak their background out of
    /// the previous frame (where the camera's shift puts it, the trail patched in).
    fn load(
        &mut self,
        frame: &RgbImage,
        previous: Option<(Streak<'_>, &[u8])>,
        sub: PixelRect,
        rows: std::ops::Range<i32>,
    ) {
        let raw = frame.as_raw();
        let stride = frame.width() as usize * 3;
        let width = sub.width as usize;
        self.pixels.clear();
        self.background.clear();
        for y in rows {
            let start = y as usize * stride + sub.x as usize * 3;
            self.pixels
                .extend_from_slice(&raw[start..start + width * 3]);
            let Some((s, prev)) = previous else {
                continue;
            };
            let from = self.background.len();
            if s.shift == [0, 0] {
                self.background
                    .extend_from_slice(&prev[start..start + width * 3]);
            } else {
                let size = frame.dimensions();
                extend_background(prev, size, (sub.x, y), width, s.shift, &mut self.background);
            }
            if let Some(t) = &s.trail {
                let now = &self.pixels[from..];
                t.patch(s.colour, (sub.x, y), 1, now, &mut self.background[from..]);
            }
        }
    }
}

/// The sampled pixels of a row, their background and their weights.
#[derive(Debug, Default)]
struct SparseScratch {
    gathered: Vec<u8>,
    background: Vec<u8>,
    lifts: Lifts,
    /// A row of the previous frame read where the camera's shift puts it.
    shifted: Vec<u8>,
    weights: Vec<f32>,
    /// Per cell of the region, whether a sampled pixel in it reached the threshold.
    hit: Vec<bool>,
}

/// A model and a mask as table lookups: per feature channel and value, the histogram bin's
/// offset (0 for a channel the histogram does not read), or at least `total` when the value
/// is outside the histogram's range or the mask. The three offsets of a pixel are summed:
/// any sum of `total` or more reads the padding of `values` (weight 0, no bin), so a pixel is
/// weighed without a branch.
#[derive(Debug, Clone)]
pub(crate) struct Lookup {
    tables: Box<[[u32; 256]; 3]>,
    /// Weight per bin, padded with zeros to `3 total + 1` entries.
    values: Vec<f32>,
    /// Bin per entry of `values` ([`NO_BIN`] in the padding).
    bins: Vec<u32>,
    /// The same lookup when only the first channel selects a bin and the other two only
    /// pass or reject (a hue histogram under a saturation/value mask, a gray histogram).
    one_channel: Option<Box<OneChannel>>,
    /// Holes are no data (weight 0, no bin) whatever the tables say (see
    /// `holes_are_no_data`).
    holes: bool,
}

/// A [`Lookup`] whose second and third channels only pass or reject, each over one interval
/// of values: a pixel's weight is one read by its first channel and two range tests, which
/// vectorise, instead of four dependent reads.
#[derive(Debug, Clone)]
struct OneChannel {
    /// Weight by the first channel's value (0 where it is outside the histogram or mask).
    weight: [f32; 256],
    /// Bin by the first channel's value ([`NO_BIN`] where outside).
    bin: [u32; 256],
    /// Inclusive intervals of the second and third channels that pass (`lower > upper`:
    /// none does).
    lower: [u8; 2],
    upper: [u8; 2],
}

impl OneChannel {
    /// The one-channel form of `tables` / `values` / `bins`, when there is one.
    fn of(tables: &[[u32; 256]; 3], values: &[f32], bins: &[u32], outside: u32) -> Option<Self> {
        let mut lower = [0u8; 2];
        let mut upper = [0u8; 2];
        for c in 0..2 {
            let table = &tables[c + 1];
            if table.iter().any(|&t| t != 0 && t < outside) {
                return None;
            }
            let pass: Vec<usize> = (0..256).filter(|&v| table[v] == 0).collect();
            match (pass.first(), pass.last()) {
                (Some(&lo), Some(&hi)) if hi - lo + 1 == pass.len() => {
                    (lower[c], upper[c]) = (lo as u8, hi as u8);
                }
                (None, None) => (lower[c], upper[c]) = (1, 0),
                _ => return None,
            }
        }
        let mut weight = [0.0f32; 256];
        let mut bin = [NO_BIN; 256];
        for (v, &t) in tables[0].iter().enumerate() {
            weight[v] = values.get(t as usize).copied().unwrap_or(0.0);
            bin[v] = bins.get(t as usize).copied().unwrap_or(NO_BIN);
        }
        Some(Self {
            weight,
            bin,
            lower,
            upper,
        })
    }
}

impl Default for Lookup {
    fn default() -> Self {
        Self {
            tables: Box::new([[0; 256]; 3]),
            values: Vec::new(),
            bins: Vec::new(),
            one_channel: None,
            holes: false,
        }
    }
}

impl Lookup {
    /// The lookup of a marker's model and mask (the mask applies to the HSV models only);
    /// both are fixed once the marker is learned, so it is built once per marker.
    pub(crate) fn new(
        appearance: &AppearanceModel,
        model: &MarkerModel,
        mask: &ChannelRange,
    ) -> Self {
        let hsv = matches!(
            appearance,
            AppearanceModel::Hue { .. } | AppearanceModel::HueSaturation { .. }
        );
        let mut lookup = Self::default();
        lookup.build(model, hsv.then_some(mask));
        lookup.holes = holes_are_no_data(appearance);
        lookup
    }

    /// The per-channel tables as they are now (see [`Lookup::rescale`]).
    pub(crate) fn tables(&self) -> [[u32; 256]; 3] {
        *self.tables
    }

    /// Read channel `c` of every pixel as its level times `gains[c]` (rounded, at most 255)
    /// through `learnt`, the tables as built: a frame whose light changed by `1 / gains`
    /// per channel is weighed as the first frame's light would have shown it. For lookups
    /// whose every channel selects a bin (the kernel model's); a one-channel form is left
    /// as it is.
    pub(crate) fn rescale(&mut self, learnt: &[[u32; 256]; 3], gains: [f32; 3]) {
        if self.one_channel.is_some() {
            return;
        }
        for ((table, learnt), gain) in self.tables.iter_mut().zip(learnt).zip(gains) {
            for (v, entry) in table.iter_mut().enumerate() {
                let scaled = ((v as f32 * gain).round() as usize).min(255);
                *entry = learnt[scaled];
            }
        }
    }

    fn build(&mut self, model: &MarkerModel, mask: Option<&ChannelRange>) {
        let (hist, weights): (&Histogram, &mut dyn Iterator<Item = f32>) = match model {
            MarkerModel::Projected { projector } => (
                projector.histogram(),
                &mut projector.bin_values().iter().map(|&v| f32::from(v)),
            ),
            MarkerModel::Kernel { hist, weight, .. } => (hist, &mut weight.iter().copied()),
        };
        // At most 2^24 bins (the histogram's limit): 3 total + 1 fits in u32.
        let total = hist.values().len();
        let outside = total as u32;
        *self.tables = [[0; 256]; 3];
        for (c, t) in hist.offset_tables(outside) {
            if let Some(table) = self.tables.get_mut(c) {
                for (d, s) in table.iter_mut().zip(t) {
                    *d = (*d + s).min(outside);
                }
            }
        }
        if let Some(mask) = mask {
            for (c, table) in self.tables.iter_mut().enumerate() {
                for (v, d) in table.iter_mut().enumerate() {
                    if !(usize::from(mask.lower[c])..=usize::from(mask.upper[c])).contains(&v) {
                        *d = outside;
                    }
                }
            }
        }
        self.values.clear();
        self.values.extend(weights);
        self.values.resize(3 * total + 1, 0.0);
        self.bins.clear();
        self.bins.extend(0..total as u32);
        self.bins.resize(3 * total + 1, NO_BIN);
        self.one_channel =
            OneChannel::of(&self.tables, &self.values, &self.bins, outside).map(Box::new);
    }
}

/// The result of a mean-shift from one start.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Mode {
    pub(crate) center: Point2<f64>,
    pub(crate) window: PixelRect,
    /// Back-projection mass in the window relative to the reference (histogram models), or
    /// the Bhattacharyya coefficient (kernel model), capped to 0..=1.
    pub(crate) confidence: f64,
    /// Moments of the converged window and a border (histogram models), for the adaptive size.
    pub(crate) moments: Option<Moments>,
}

/// A sparse [`Region::fill`]: the weights where they can reach `threshold`, 0 (no bin)
/// elsewhere. A large region (a lost marker's gate) is first
/// weighed at every [`SPARSE_STEP_PX`]-th pixel of every [`SPARSE_STEP_PX`]-th row; the
/// cells (`cell` pixels) holding a sampled pixel at or above `threshold` that the filter
/// keeps, and the cells within [`SPARSE_REACH_CELLS`] of them, are then weighed in full,
/// exactly as a full fill weighs them. A blob at or above `threshold` is weighed
/// whole, with the pixels about it, when its pixels lie within the reach of its sampled
/// ones: a marker's blob (a few pixels across at the least) does; a component no sampled
/// pixel falls on (a line one pixel thin, a speck) may be left at 0. A cluttered region
/// (more than [`SPARSE_MAX_HIT_SHARE`] of its cells hit) is weighed whole, and
/// [`Region::cluttered`] says so.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sparse {
    /// The marker's blob threshold.
    pub(crate) threshold: f32,
    /// Cell size (pixels, x and y).
    pub(crate) cell: (i32, i32),
}

impl Region {
    /// An empty region whose [`Region::locate`] measures its window's moments only when
    /// `moments_wanted`.
    pub(crate) fn new(moments_wanted: bool) -> Self {
        Self {
            moments_wanted,
            ..Self::default()
        }
    }

    /// Compute the weights of `model` over `rect` (clipped to the frame): every pixel, or
    /// with `sparse` only where they can reach its threshold (see [`Sparse`]).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn fill(
        &mut self,
        appearance: &AppearanceModel,
        model: &MarkerModel,
        lookup: &Lookup,
        frame: &RgbImage,
        rect: PixelRect,
        filter: &PixelFilter<'_>,
        sparse: Option<Sparse>,
    ) {
        let sparse = sparse.map(|s| (s.threshold, s.cell));
        let rect = rect.intersect(&PixelRect::image(frame.width(), frame.height()));
        self.rect = rect;
        self.cluttered = false;
        let area = rect.area() as usize;
        let kernel = matches!(model, MarkerModel::Kernel { .. });
        // A full fill writes every weight and bin, so what the buffers held stays only until
        // it is overwritten; a sparse one leaves 0 (no bin) where it does not weigh.
        self.weights.resize(area, 0.0);
        // Read only where this fill weighs (see `Region::grayer_streaks`): never shrunk, so
        // that regions of changing size do not zero it again and again.
        if self.lifts.scale.len() < area {
            self.lifts.resize(area);
        }
        self.raised_rows.clear();
        self.raised_rows.resize(rect.height.max(0) as usize, false);
        if kernel {
            self.bins.resize(area, NO_BIN);
        } else {
            self.bins.clear();
        }
        if sparse.is_some() {
            self.weights.fill(0.0);
            self.bins.fill(NO_BIN);
        }
        match appearance {
            AppearanceModel::Hue { .. } | AppearanceModel::HueSaturation { .. } => {
                self.fill_in::<true>(lookup, frame, filter, kernel, sparse, |p| p);
            }
            AppearanceModel::Rgb { .. } => {
                self.fill_in::<false>(lookup, frame, filter, kernel, sparse, |p| p);
            }
            AppearanceModel::Gray { .. } => {
                self.fill_in::<false>(lookup, frame, filter, kernel, sparse, |p| {
                    [rgb_to_gray(p), 0, 0]
                });
            }
        }
    }

    /// Take back the streak weight of every pixel whose neighbourhood's streak pixels lie,
    /// together, off the plane of their backgrounds and the marker's core colour toward
    /// gray by more than [`STREAK_LOCAL_HUE_SHARE`] (or half of `hue_share`, the rim's own
    /// median share for a marker whose rim is paled toward gray) of their coverage times
    /// contrast. One pixel cannot tell: at a fifth of coverage over the sky a streak pixel
    /// of a dark marker differs from the background by about 40 levels, and colour noise
    /// moves it off the plane by 5-10 of them. A neighbourhood of streak pixels averages
    /// the noise out, and a twig's or branch's smear across the sky (bark blended with the
    /// sky, a colour of its own) stays 8-13 % of its contrast off the plane toward gray,
    /// where a marker's streak is 0-4 % off (the third generator's seeds 8 and 17, green
    /// markers taking a twig's smear for their streak, `docs/validation.md`).
    fn grayer_streaks(&mut self, hue_share: f32) {
        let limit = (0.5 * hue_share).max(STREAK_LOCAL_HUE_SHARE);
        let (w, h) = (self.rect.width as usize, self.rect.height as usize);
        let r = STREAK_LOCAL_RADIUS_PX;
        let Region {
            weights,
            lifts,
            raised_rows,
            grayer,
            ..
        } = self;
        grayer.clear();
        // Runs of this many pixels are skipped whole where the streak raised none of them
        // (a few dozen raised pixels in a region of thousands is usual).
        const RUN_PX: usize = 16;
        for y in (0..h).filter(|&y| raised_rows[y]) {
            let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
            let scales = &lifts.scale[y * w..(y + 1) * w];
            let runs = scales.chunks(RUN_PX).enumerate();
            let raised = runs.filter(|(_, run)| run.iter().any(|&v| v > 0.0));
            for x in raised.flat_map(|(j, run)| j * RUN_PX..j * RUN_PX + run.len()) {
                let k = y * w + x;
                if lifts.scale[k] <= 0.0 || weights[k] <= 0.0 {
                    continue;
                }
                // What the streak raised about the pixel, where the pixels weigh (one the
                // filter rejected, or a sparse fill did not weigh, holds nothing of this
                // fill).
                let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
                let (mut off, mut scale) = (0.0f32, 0.0f32);
                for ny in y0..y1 {
                    let run = ny * w + x0..ny * w + x1;
                    let rows = [
                        &weights[run.clone()],
                        &lifts.off[run.clone()],
                        &lifts.scale[run],
                    ];
                    // A whole neighbourhood's row as fixed arrays (a loop the compiler
                    // unrolls), else the clipped row; the same sums in the same order.
                    match rows.map(<&[f32; LOCAL_SIDE_PX]>::try_from) {
                        [Ok(wt), Ok(o), Ok(s)] => add_weighed(*wt, *o, *s, &mut off, &mut scale),
                        _ => {
                            let [wt, o, s] = rows.map(|r| r.iter().copied());
                            add_weighed(wt, o, s, &mut off, &mut scale);
                        }
                    }
                }
                if off > limit * scale {
                    grayer.push(k);
                }
            }
        }
    }

    /// One copy per feature conversion (`HSV`: rows converted to HSV first, `features`
    /// applies to the converted pixels): the whole region, or with `sparse` the parts found
    /// by [`Region::sparse_parts`].
    #[inline(always)]
    fn fill_in<const HSV: bool>(
        &mut self,
        lookup: &Lookup,
        frame: &RgbImage,
        filter: &PixelFilter<'_>,
        kernel: bool,
        sparse: Option<(f32, (i32, i32))>,
        features: impl Fn([u8; 3]) -> [u8; 3],
    ) {
        let rect = self.rect;
        let parts = sparse.and_then(|(threshold, (cw, ch))| {
            let cell = (cw.max(1), ch.max(1));
            self.sparse_parts::<HSV>(lookup, frame, filter, threshold, cell, &features)
        });
        match parts {
            Some(parts) => {
                for sub in parts {
                    self.fill_rows::<HSV>(lookup, frame, sub, filter, kernel, &features);
                }
            }
            None => {
                self.cluttered = sparse.is_some();
                self.fill_rows::<HSV>(lookup, frame, rect, filter, kernel, &features);
            }
        }
        // Streak weights a neighbourhood turns down (see `Region::grayer_streaks`) go back
        // to the pixel's own weight (the filter's rejections stay).
        let Some((streak, _)) = streak_background(filter, frame) else {
            return;
        };
        self.grayer_streaks(streak.hue_share);
        let mut grayer = std::mem::take(&mut self.grayer);
        for &k in &grayer {
            let (x, y) = (k % rect.width as usize, k / rect.width as usize);
            let p = frame
                .get_pixel(rect.x as u32 + x as u32, rect.y as u32 + y as u32)
                .0;
            let mut own = [0.0f32];
            let rows = &mut self.feature_rows;
            weigh_row::<HSV>(lookup, &features, &p, None, rows, &mut own, None);
            self.weights[k] = self.weights[k].min(own[0]);
        }
        grayer.clear();
        self.grayer = grayer;
    }

    /// The parts of the region to weigh in full (see [`Sparse`]): runs of cells
    /// along each row of cells, as rectangles inside the region; `None` as soon as more than
    /// [`SPARSE_MAX_HIT_SHARE`] of the cells hold a hit.
    #[inline(always)]
    fn sparse_parts<const HSV: bool>(
        &mut self,
        lookup: &Lookup,
        frame: &RgbImage,
        filter: &PixelFilter<'_>,
        threshold: f32,
        (cw, ch): (i32, i32),
        features: &impl Fn([u8; 3]) -> [u8; 3],
    ) -> Option<Vec<PixelRect>> {
        let rect = self.rect;
        if rect.is_empty() {
            return Some(Vec::new());
        }
        let raw = frame.as_raw();
        let stride = frame.width() as usize * 3;
        let previous = streak_background(filter, frame);
        let (nx, ny) = (
            (rect.width + cw - 1) as usize / cw as usize,
            (rect.height + ch - 1) as usize / ch as usize,
        );
        let most = (nx * ny) as f64 * SPARSE_MAX_HIT_SHARE;
        let mut hits = 0usize;
        let samples = (rect.width as usize).div_ceil(SPARSE_STEP_PX);
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.hit.clear();
        scratch.hit.resize(nx * ny, false);
        for y in (rect.y..rect.bottom() as i32).step_by(SPARSE_STEP_PX) {
            let start = y as usize * stride + rect.x as usize * 3;
            let row = &raw[start..start + rect.width as usize * 3];
            gather(row, &mut scratch.gathered);
            let background = previous.map(|(s, prev)| {
                if s.shift == [0, 0] {
                    gather(&prev[start..start + row.len()], &mut scratch.background);
                } else {
                    scratch.shifted.clear();
                    let size = frame.dimensions();
                    let len = rect.width as usize;
                    extend_background(prev, size, (rect.x, y), len, s.shift, &mut scratch.shifted);
                    gather(&scratch.shifted, &mut scratch.background);
                }
                if let Some(t) = &s.trail {
                    let (now, under) = (&scratch.gathered, &mut scratch.background);
                    t.patch(s.colour, (rect.x, y), SPARSE_STEP_PX, now, under);
                }
                s
            });
            scratch.weights.clear();
            scratch.weights.resize(samples, 0.0);
            scratch.lifts.resize(samples);
            let lifts = scratch.lifts.slice(0, samples);
            let background = background.map(|s| (s, &scratch.background[..], lifts));
            weigh_row::<HSV>(
                lookup,
                features,
                &scratch.gathered,
                background,
                &mut self.feature_rows,
                &mut scratch.weights,
                None,
            );
            let cy = (y - rect.y) as usize / ch as usize;
            for (k, &v) in scratch.weights.iter().enumerate() {
                let x = rect.x + (k * SPARSE_STEP_PX) as i32;
                if v >= threshold && !filter.rejects(x, y) {
                    let cell = &mut scratch.hit[cy * nx + (x - rect.x) as usize / cw as usize];
                    hits += usize::from(!*cell);
                    *cell = true;
                }
            }
            if hits as f64 > most {
                self.scratch = scratch;
                return None;
            }
        }
        // Each hit cell and the cells within the reach of it, as runs along the cell rows.
        let reach = SPARSE_REACH_CELLS;
        let hit = &scratch.hit;
        let near_hit = |cx: usize, cy: usize| {
            (cy.saturating_sub(reach)..(cy + reach + 1).min(ny)).any(|r| {
                hit[r * nx + cx.saturating_sub(reach)..r * nx + (cx + reach + 1).min(nx)]
                    .contains(&true)
            })
        };
        let mut parts = Vec::new();
        for cy in 0..ny {
            let mut run: Option<usize> = None;
            for cx in 0..=nx {
                match (cx < nx && near_hit(cx, cy), run) {
                    (true, None) => run = Some(cx),
                    (false, Some(from)) => {
                        let part = PixelRect::new(
                            rect.x + from as i32 * cw,
                            rect.y + cy as i32 * ch,
                            (cx - from) as i32 * cw,
                            ch,
                        );
                        parts.push(part.intersect(&rect));
                        run = None;
                    }
                    _ => {}
                }
            }
        }
        self.scratch = scratch;
        Some(parts)
    }

    /// Weigh the rows of `sub` (inside the region) into the region's buffers: every pixel
    /// weighed without a branch on the filter, then the pixels the filter rejects set to
    /// weight 0 (no bin). Rows are weighed together, a block of about [`BLOCK_PX`] pixels
    /// copied out of the frame at a time, so that the vector loops run long (a region's rows
    /// are a few dozen pixels, and each loop's scalar remainder cost as much as its lanes).
    #[inline(always)]
    fn fill_rows<const HSV: bool>(
        &mut self,
        lookup: &Lookup,
        frame: &RgbImage,
        sub: PixelRect,
        filter: &PixelFilter<'_>,
        kernel: bool,
        features: &impl Fn([u8; 3]) -> [u8; 3],
    ) {
        if sub.is_empty() {
            return;
        }
        let previous = streak_background(filter, frame);
        let Region {
            rect,
            weights,
            bins,
            lifts,
            raised_rows,
            feature_rows,
            block,
            ..
        } = self;
        let width = sub.width as usize;
        // The sub's rows lie one after the other in the region's buffers when it spans them.
        let contiguous = sub.x == rect.x && sub.width == rect.width;
        let rows_per_block = (BLOCK_PX / width).max(1);
        let bottom = sub.bottom() as i32;
        let mut y0 = sub.y;
        while y0 < bottom {
            let y1 = (y0 + rows_per_block as i32).min(bottom);
            let n = (y1 - y0) as usize * width;
            block.load(frame, previous, sub, y0..y1);
            let at = (y0 - rect.y) as usize * rect.width as usize + (sub.x - rect.x) as usize;
            // Rows that lie one after the other in the region are weighed in place; a
            // narrower part's rows through the block's buffers, then copied out.
            let (out, bins_out, lifted) = if contiguous {
                (
                    &mut weights[at..at + n],
                    kernel.then(|| &mut bins[at..at + n]),
                    lifts.slice(at, n),
                )
            } else {
                block.weights.resize(n, 0.0);
                block.bins.resize(if kernel { n } else { 0 }, NO_BIN);
                block.lifts.resize(n);
                (
                    &mut block.weights[..],
                    kernel.then_some(&mut block.bins[..]),
                    block.lifts.slice(0, n),
                )
            };
            let background = previous.map(|(s, _)| (s, &block.background[..], lifted));
            let pixels = &block.pixels;
            if weigh_row::<HSV>(
                lookup,
                features,
                pixels,
                background,
                feature_rows,
                out,
                bins_out,
            ) {
                let scales = if contiguous {
                    &lifts.scale[at..at + n]
                } else {
                    &block.lifts.scale[..n]
                };
                mark_raised_rows(&mut raised_rows[(y0 - rect.y) as usize..], scales, width);
            }
            if !contiguous {
                for (j, w) in block.weights.chunks_exact(width).enumerate() {
                    let to = at + j * rect.width as usize;
                    weights[to..to + width].copy_from_slice(w);
                    lifts.copy_from(to, &block.lifts, j * width, width);
                    if kernel {
                        bins[to..to + width].copy_from_slice(&block.bins[j * width..][..width]);
                    }
                }
            }
            for y in y0..y1 {
                let at = (y - rect.y) as usize * rect.width as usize + (sub.x - rect.x) as usize;
                let out = &mut weights[at..at + width];
                let bins_out = kernel.then(|| &mut bins[at..at + width]);
                let row = (y - y0) as usize * width * 3;
                let pixels = &block.pixels[row..row + width * 3];
                filter.reject_in_row(sub, y, pixels, out, bins_out);
            }
            y0 = y1;
        }
    }

    pub(crate) fn index(&self, x: i32, y: i32) -> usize {
        (y - self.rect.y) as usize * self.rect.width as usize + (x - self.rect.x) as usize
    }

    /// Sums of weight, weight·x, weight·y and second orders over `window ∩ region`
    /// (absolute pixel coordinates).
    pub(crate) fn sums(&self, window: PixelRect) -> [f64; 6] {
        let w = window.intersect(&self.rect);
        let mut s = [0.0; 6];
        if w.is_empty() {
            return s;
        }
        for y in w.y..w.bottom() as i32 {
            let start = self.index(w.x, y);
            let row = &self.weights[start..start + w.width as usize];
            let (mut r0, mut rx, mut rxx) = (0.0f64, 0.0f64, 0.0f64);
            // Column numbers are integers: counting them up is exact.
            let mut x = f64::from(w.x);
            for &v in row {
                let v = f64::from(v);
                r0 += v;
                rx += v * x;
                rxx += v * x * x;
                x += 1.0;
            }
            let yf = f64::from(y);
            s[0] += r0;
            s[1] += rx;
            s[2] += r0 * yf;
            s[3] += rxx;
            s[4] += rx * yf;
            s[5] += r0 * yf * yf;
        }
        s
    }

    /// Sum of the weights in `window`.
    pub(crate) fn mass(&self, window: PixelRect) -> f64 {
        self.sums(window)[0]
    }

    /// Mean-shift from `start` with a window of `size`, then the weighted centroid and the
    /// confidence of the converged window (`reference_mass`: the mass of the marker's own
    /// window on the first frame).
    pub(crate) fn locate(
        &mut self,
        model: &MarkerModel,
        criteria: &TermCriteria,
        reference_mass: f64,
        start: Point2<f64>,
        size: (i32, i32),
    ) -> Mode {
        match model {
            MarkerModel::Projected { .. } => {
                self.weights_locate(criteria, reference_mass, start, size)
            }
            MarkerModel::Kernel { q, .. } => self.kernel_locate(q, start, size),
        }
    }

    /// OpenCV's mean-shift over the region's weights (the histogram models' `locate`; for
    /// the kernel model, mean-shift over its back-projection instead of the Bhattacharyya
    /// coefficient), then the weighted centroid and the confidence of the converged window.
    pub(crate) fn weights_locate(
        &mut self,
        criteria: &TermCriteria,
        reference_mass: f64,
        start: Point2<f64>,
        size: (i32, i32),
    ) -> Mode {
        let max_iter = criteria.max_iterations.unwrap_or(100).max(1);
        let eps = criteria.epsilon_px.unwrap_or(1.0).max(0.0);
        let mut window = PixelRect::centered_at(start, size.0, size.1);
        let mut center = start;
        // The sums of the window the loop ended on, when it ended without moving it.
        let mut last = None;
        for _ in 0..max_iter {
            let s = self.sums(window);
            if s[0] <= 0.0 {
                last = Some(s);
                break;
            }
            let c = Point2::new(s[1] / s[0], s[2] / s[0]);
            let next = PixelRect::centered_at(c, size.0, size.1);
            let moved = (c - center).norm();
            center = c;
            if next == window {
                last = Some(s);
                break;
            }
            window = next;
            if moved < eps {
                break;
            }
        }
        let s = last.unwrap_or_else(|| self.sums(window));
        if s[0] > 0.0 {
            center = Point2::new(s[1] / s[0], s[2] / s[0]);
        }
        let moments = self
            .moments_wanted
            .then(|| {
                let grown = window.grown(ADAPTIVE_BORDER_PX, ADAPTIVE_BORDER_PX);
                let g = self.sums(grown);
                // Central moments do not depend on the origin of the coordinates.
                (g[0] > 0.0).then(|| moments_from_f64_sums(g))
            })
            .flatten();
        Mode {
            center,
            window,
            confidence: (s[0] / reference_mass.max(1.0)).min(1.0),
            moments,
        }
    }

    /// Comaniciu–Ramesh–Meer mean-shift with the Epanechnikov kernel over the window's
    /// inscribed ellipse; the confidence is the Bhattacharyya coefficient at the end.
    fn kernel_locate(&mut self, q: &[f64], start: Point2<f64>, size: (i32, i32)) -> Mode {
        let (w, h) = (size.0.max(1) as usize, size.1.max(1) as usize);
        let mut y0 = start;
        let mut rho = 0.0;
        for _ in 0..KERNEL_MAX_ITERATIONS {
            let (next, r) = self.kernel_step(q, y0, w, h);
            rho = r;
            let Some(next) = next else { break };
            let moved = (next - y0).norm();
            y0 = next;
            if moved < KERNEL_EPSILON_PX {
                rho = self.kernel_step(q, y0, w, h).1;
                break;
            }
        }
        Mode {
            center: y0,
            window: PixelRect::centered_at(y0, size.0, size.1),
            confidence: rho.clamp(0.0, 1.0),
            moments: None,
        }
    }

    /// The Bhattacharyya coefficient of the kernel histogram at `center` with `q`.
    pub(crate) fn bhattacharyya(
        &mut self,
        q: &[f64],
        center: Point2<f64>,
        size: (i32, i32),
    ) -> f64 {
        let (w, h) = (size.0.max(1) as usize, size.1.max(1) as usize);
        self.kernel_step(q, center, w, h).1
    }

    /// One kernel mean-shift step at `y0`: the new position (None when the kernel holds no
    /// counted pixel) and the Bhattacharyya coefficient at `y0`.
    fn kernel_step(
        &mut self,
        q: &[f64],
        y0: Point2<f64>,
        w: usize,
        h: usize,
    ) -> (Option<Point2<f64>>, f64) {
        let window = PixelRect::centered_at(y0, w as i32, h as i32).intersect(&self.rect);
        if window.is_empty() || self.bins.len() != self.rect.area() as usize {
            return (None, 0.0);
        }
        let hx = (w as f64 * 0.5).max(0.5);
        let hy = (h as f64 * 0.5).max(0.5);
        // `p` is all zero between calls: only the bins this window touches are set, summed
        // (in bin order, as over the whole histogram) and cleared again, not the 4,096 bins
        // of a 16-per-channel RGB histogram at every step.
        if self.p.len() != q.len() {
            self.p.clear();
            self.p.resize(q.len(), 0.0);
        }
        self.touched.clear();
        self.pixels.clear();
        let mut total = 0.0;
        for y in window.y..window.bottom() as i32 {
            for x in window.x..window.right() as i32 {
                let bin = self.bins[self.index(x, y)];
                if bin == NO_BIN {
                    continue;
                }
                let dx = (f64::from(x) - y0.x) / hx;
                let dy = (f64::from(y) - y0.y) / hy;
                let r2 = dx * dx + dy * dy;
                if r2 >= 1.0 {
                    continue;
                }
                let p = &mut self.p[bin as usize];
                if *p == 0.0 {
                    self.touched.push(bin);
                }
                *p += 1.0 - r2;
                total += 1.0 - r2;
                self.pixels.push((x, y, bin, 1.0 - r2));
            }
        }
        if total <= 0.0 {
            return (None, 0.0);
        }
        let mut rho = 0.0;
        self.touched.sort_unstable();
        for &bin in &self.touched {
            let (p, qv) = (self.p[bin as usize], q[bin as usize]);
            if p > 0.0 && qv > 0.0 {
                rho += (p / total * qv).sqrt();
            }
        }
        // sqrt(q/p) times the kernel profile: the spatially weighted mean converges to the
        // Bhattacharyya maximum on uniform blobs, where the flat mean stalls short of it.
        // The bin's factor once per bin, kept in `p` until it is cleared below.
        for &bin in &self.touched {
            let p = self.p[bin as usize] / total;
            self.p[bin as usize] = (q[bin as usize] / p).sqrt();
        }
        let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
        for &(x, y, bin, k) in &self.pixels {
            let weight = self.p[bin as usize] * k;
            sw += weight;
            sx += weight * f64::from(x);
            sy += weight * f64::from(y);
        }
        for &bin in &self.touched {
            self.p[bin as usize] = 0.0;
        }
        if sw <= 0.0 {
            return (None, rho);
        }
        (Some(Point2::new(sx / sw, sy / sw)), rho)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::Labeler;
    use crate::tracker::DepthView;

    /// Every pixel the filter rejects weighs 0 and has no bin; every other pixel is as
    /// without the filter (the masks and the depth gate are applied after the row is weighed).
    #[test]
    fn masked_rectangles_and_the_depth_gate_reject_exactly_their_pixels() {
        let (fw, fh) = (60u32, 40u32);
        let frame = RgbImage::from_fn(fw, fh, |x, y| {
            let red = (20..30).contains(&x) && (10..22).contains(&y);
            let v = ((x * 31 + y * 17) % 97) as u8;
            if red {
                image::Rgb([200, 30 + v / 8, 20])
            } else {
                image::Rgb([v, 120 + v / 2, 90])
            }
        });
        let previous = RgbImage::from_fn(fw, fh, |x, y| {
            image::Rgb([((x * 7 + y) % 255) as u8, 120, 90])
        });
        let depth: Vec<Option<f64>> = (0..fw * fh)
            .map(|k| (k % 7 != 0).then_some(1.0 + f64::from(k % 5) * 0.1))
            .collect();
        let depth = DepthView::new(fw, fh, &depth).expect("sized");
        let mask = ChannelRange::CAMSHIFT_DEMO;
        let window = PixelRect::new(20, 10, 10, 12);
        let mut kernels = 0;
        for appearance in [
            AppearanceModel::Hue { bins: 16 },
            AppearanceModel::HueSaturation {
                hue_bins: 8,
                saturation_bins: 4,
            },
            AppearanceModel::Rgb { bins: 8 },
        ] {
            for background in [false, true] {
                let model = MarkerModel::learn("m", &frame, window, &appearance, &mask, background)
                    .expect("learns");
                let lookup = Lookup::new(&appearance, &model, &mask);
                let rect = PixelRect::new(-5, 4, 50, 30);
                let masked = [PixelRect::new(-10, 0, 18, 8), PixelRect::new(24, 15, 3, 40)];
                let streak = Streak {
                    previous: &previous,
                    shift: [0, 0],
                    colour: [200.0, 35.0, 20.0],
                    shade: STREAK_MIN_SHADE,
                    hue_share: STREAK_RESIDUAL[1],
                    core: [200.0, 35.0, 20.0],
                    trail: None,
                };
                let open = PixelFilter {
                    depth: None,
                    masked: &[],
                    paler: &[],
                    streak: Some(streak),
                };
                let gated = PixelFilter {
                    depth: Some((0.15, 1.1, depth)),
                    masked: &masked,
                    paler: &[],
                    streak: Some(streak),
                };
                let (mut all, mut some) = (Region::default(), Region::default());
                all.fill(&appearance, &model, &lookup, &frame, rect, &open, None);
                some.fill(&appearance, &model, &lookup, &frame, rect, &gated, None);
                assert_eq!(some.rect, PixelRect::new(0, 4, 45, 30));
                let (mut rejected, mut weighed) = (0, 0);
                for y in some.rect.y..some.rect.bottom() as i32 {
                    for x in some.rect.x..some.rect.right() as i32 {
                        let k = some.index(x, y);
                        let in_mask = masked.iter().any(|r| {
                            x >= r.x
                                && y >= r.y
                                && i64::from(x) < r.right()
                                && i64::from(y) < r.bottom()
                        });
                        let beyond = depth.at(x, y).is_some_and(|v| (v - 1.1).abs() > 0.15);
                        if in_mask || beyond {
                            rejected += 1;
                            assert_eq!(some.weights[k], 0.0, "({x}, {y})");
                        } else {
                            weighed += usize::from(all.weights[k] > 0.0);
                            assert_eq!(some.weights[k], all.weights[k], "({x}, {y})");
                        }
                        let kernel = matches!(model, MarkerModel::Kernel { .. });
                        if kernel {
                            let bin = if in_mask || beyond {
                                NO_BIN
                            } else {
                                all.bins[k]
                            };
                            assert_eq!(some.bins[k], bin, "({x}, {y})");
                        } else {
                            assert!(some.bins.is_empty());
                        }
                    }
                }
                assert!(rejected > 100 && weighed > 50, "{rejected} {weighed}");
                kernels += usize::from(matches!(model, MarkerModel::Kernel { .. }));
            }
        }
        assert_eq!(kernels, 2, "the kernel (RGB) model's bins were checked");
    }

    /// The streak weight of one pixel as its definition reads, for the plane loop to be
    /// checked against.
    fn streak_of(
        [m, k]: [[f32; 3]; 2],
        [shade, hue_share]: [f32; 2],
        p: [f32; 3],
        b: [f32; 3],
    ) -> f32 {
        let d = [m[0] - b[0], m[1] - b[1], m[2] - b[2]];
        let e = [p[0] - b[0], p[1] - b[1], p[2] - b[2]];
        let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        if dd < STREAK_MIN_CONTRAST * STREAK_MIN_CONTRAST {
            return 0.0;
        }
        let ed = e[0] * d[0] + e[1] * d[1] + e[2] * d[2];
        if ed < STREAK_MIN_COVERAGE * dd {
            return 0.0;
        }
        let a = ed / dd;
        let r = [e[0] - a * d[0], e[1] - a * d[1], e[2] - a * d[2]];
        let rr = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
        let limit = STREAK_RESIDUAL[0].max(STREAK_RESIDUAL[1] * a.min(1.0) * dd.sqrt());
        if rr > limit * limit {
            return 0.0;
        }
        let mm = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];
        // The distance of `e` from the plane of the core colour and the background.
        let n = [
            k[1] * b[2] - k[2] * b[1],
            k[2] * b[0] - k[0] * b[2],
            k[0] * b[1] - k[1] * b[0],
        ];
        let nn: f32 = n.iter().map(|v| v * v).sum();
        let en: f32 = (0..3).map(|c| e[c] * n[c]).sum();
        let hue_limit = STREAK_RESIDUAL[0].max(hue_share * a.min(1.0) * dd.sqrt());
        let toward_gray = en * (n[0] + n[1] + n[2]) > 0.0;
        if toward_gray && en * en > hue_limit * hue_limit * nn {
            return 0.0;
        }
        let em = e[0] * m[0] + e[1] * m[1] + e[2] * m[2];
        let bm = b[0] * m[0] + b[1] * m[1] + b[2] * m[2];
        if em < a * (shade * mm - bm) {
            return 0.0;
        }
        255.0 * (a / STREAK_FULL_COVERAGE).min(1.0)
    }

    #[test]
    fn streak_weights_of_a_row_are_each_pixels_own() {
        let previous = RgbImage::new(1, 1);
        // Rows of many lengths (vector blocks and remainders), pixels on and off the line
        // between each background and the marker's colour, under the general residual and
        // under the least share across the marker's colour.
        for (n, hue_share) in [0usize, 1, 7, 8, 9, 15, 16, 17, 31, 32, 45]
            .into_iter()
            .flat_map(|n| [(n, STREAK_RESIDUAL[1]), (n, STREAK_MIN_HUE_SHARE)])
        {
            let streak = Streak {
                previous: &previous,
                shift: [0, 0],
                colour: [210.0, 30.0, 25.0],
                shade: STREAK_MIN_SHADE,
                hue_share,
                core: [200.0, 40.0, 30.0],
                trail: None,
            };
            let background: Vec<u8> = (0..3 * n).map(|k| ((k * 53 + 11) % 200) as u8).collect();
            let row: Vec<u8> = (0..3 * n)
                .map(|k| {
                    let (px, c) = (k / 3, k % 3);
                    let b = f32::from(background[k]);
                    let share = [0.1f32, 0.3, 0.6, 0.9][px % 4];
                    let mixed = share * streak.colour[c] + (1.0 - share) * b;
                    let noise = if px % 5 == 0 { 40.0 } else { 0.0 };
                    (mixed + noise).clamp(0.0, 255.0) as u8
                })
                .collect();
            let mut weights: Vec<f32> = (0..n).map(|i| (i % 3) as f32 * 60.0).collect();
            let before = weights.clone();
            let mut lifts = Lifts::default();
            lifts.resize(n);
            lifts.off.fill(-1.0);
            streak.raise_row(&mut weights, &row, &background, lifts.slice(0, n));
            let mut raised = 0;
            for i in 0..n {
                let f = |v: &[u8]| [v[3 * i], v[3 * i + 1], v[3 * i + 2]].map(f32::from);
                let params = [streak.shade, streak.hue_share];
                let colours = [streak.colour, streak.core];
                let s = streak_of(colours, params, f(&row), f(&background));
                assert_eq!(weights[i], before[i].max(s), "length {n}, pixel {i}");
                // Where the streak raised the weight, its scale is kept; elsewhere nothing.
                if s > before[i] {
                    assert!(lifts.scale[i] > 0.0, "length {n}, pixel {i}");
                } else {
                    assert_eq!(
                        [lifts.off[i], lifts.scale[i]],
                        [0.0; 2],
                        "length {n}, pixel {i}"
                    );
                }
                raised += usize::from(s > before[i]);
            }
            if n >= 8 {
                assert!(raised > 0, "length {n}: no pixel on a streak");
            }
        }
    }

    /// Over a sky, a dark brown twig's smear lies near the line from the sky to a red
    /// marker's colour (both darken green and blue the most) and would pass as a streak of
    /// it; the colour it implies for what covered it is about half the marker's brightness,
    /// darker than the marker's own shading, and it is turned down. The marker's streak,
    /// and the streak of its darkest shade, are not.
    #[test]
    fn a_dark_twigs_smear_is_not_a_streak_of_a_red_marker() {
        let sky = [130.0f32, 185.0, 225.0];
        let red = [129.0f32, 28.0, 30.0];
        let twig = [62.0f32, 39.0, 22.0];
        let blend =
            |c: [f32; 3], a: f32| [0, 1, 2].map(|k| (a * c[k] + (1.0 - a) * sky[k]).round());
        for a in [0.2f32, 0.35, 0.5, 0.8] {
            // Without the shade test the twig's smear is on the line: the test is what
            // turns it down.
            let general = STREAK_RESIDUAL[1];
            let red = [red, red];
            assert!(
                streak_of(red, [0.0, general], blend(twig, a), sky) > 0.0,
                "coverage {a}"
            );
            let params = [STREAK_MIN_SHADE, general];
            assert_eq!(streak_of(red, params, blend(twig, a), sky), 0.0);
            assert!(streak_of(red, params, blend(red[0], a), sky) > 0.0);
            let darkest = red[0].map(|v| 0.65 * v);
            assert!(streak_of(red, params, blend(darkest, a), sky) > 0.0);
        }
    }

    /// A twig smeared over the sky by a green marker it carries (the third generator's seed
    /// 8): its pixels imply a gray as bright as the marker's mean colour (which took in
    /// some sky), and pass the line's general residual and the shade test, so the marker's
    /// blob ran on along the twig and its centre was measured 5 px toward it. They lie off
    /// the plane of the sky and the marker's core colour, which holds every blend of the
    /// sky with every shade of the marker, and the least share off it turns them down; the
    /// marker's own streak, lit or shaded, lies in the plane.
    #[test]
    fn a_twigs_gray_smear_is_not_a_streak_of_a_green_marker() {
        let sky = [155.0f32, 210.0, 245.0];
        let (mean, core) = ([55.0f32, 119.0, 79.0], [40.0f32, 145.0, 52.0]);
        let gray = [88.0f32, 76.0, 83.0];
        let blend =
            |c: [f32; 3], a: f32| [0, 1, 2].map(|k| (a * c[k] + (1.0 - a) * sky[k]).round());
        let general = [STREAK_MIN_SHADE, STREAK_RESIDUAL[1]];
        let least = [STREAK_MIN_SHADE, STREAK_MIN_HUE_SHARE];
        for a in [0.55f32, 0.65, 0.8] {
            assert!(
                streak_of([mean, core], general, blend(gray, a), sky) > 0.0,
                "coverage {a}"
            );
            assert_eq!(streak_of([mean, core], least, blend(gray, a), sky), 0.0);
            for shade in [0.7f32, 1.0, 1.15] {
                let marker = core.map(|v| shade * v);
                assert!(streak_of([mean, core], least, blend(marker, a), sky) > 0.0);
            }
            // As far off the plane as the gray smear but on the other side (a compressed
            // frame's blend at an edge leaves it either way): kept.
            let n = [
                core[1] * sky[2] - core[2] * sky[1],
                core[2] * sky[0] - core[0] * sky[2],
                core[0] * sky[1] - core[1] * sky[0],
            ];
            let norm = n.iter().map(|v| v * v).sum::<f32>().sqrt();
            let away = -(n[0] + n[1] + n[2]).signum() * 25.0 / norm;
            let on = blend(core, a);
            let pushed = [0, 1, 2].map(|c| (on[c] + away * n[c]).round());
            assert!(
                streak_of([mean, core], least, pushed, sky) > 0.0,
                "{pushed:?}"
            );
            let toward = [0, 1, 2].map(|c| (on[c] - away * n[c]).round());
            assert_eq!(streak_of([mean, core], least, toward, sky), 0.0);
        }
    }

    #[test]
    fn the_inverse_square_root_is_within_a_fifth_of_a_percent() {
        for x in [1e-6f32, 0.01, 1.0, 2.0, 3.0, 1234.5, 6.5e4, 1e9] {
            let exact = 1.0 / x.sqrt();
            assert!((inverse_sqrt(x) / exact - 1.0).abs() < 2e-3, "{x}");
        }
        assert_eq!(inverse_sqrt(0.0), 0.0);
        assert_eq!(inverse_sqrt(-1.0), 0.0);
    }

    /// A twig smeared across the sky beside a green marker (the third generator's seed 17:
    /// bark blended with the sky at a fifth to a third of coverage) and a faint streak of
    /// the marker, both under colour noise of 4 levels: one pixel at a time most of the
    /// twig's pass as a streak of the marker (the residual's floor, 15 levels, is as large
    /// as what a fifth of coverage leaves off the line), but taken together their
    /// neighbourhoods lie off the plane of the sky and the marker's core toward gray, and
    /// they are turned down; the marker's streak keeps its weights, on the full and the
    /// sparse path.
    #[test]
    fn a_twigs_smear_is_told_from_a_faint_streak_by_its_neighbourhood() {
        let (w, h) = (120u32, 60u32);
        let sky = [164.0f32, 190.0, 210.0];
        let (mean, core) = ([34.0f32, 104.0, 41.0], [35.0f32, 112.0, 44.0]);
        let bark = [100.0f32, 90.0, 80.0];
        // Seeded noise of -4..=4 levels per channel.
        let noise = |x: u32, y: u32, c: u32, salt: u32| {
            let v = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663))
                ^ (c + 3 * salt).wrapping_mul(83_492_791);
            (v.wrapping_mul(2_654_435_761) >> 16) % 9
        };
        let paint = |x: u32, y: u32, colour: [f32; 3], a: f32, salt: u32| {
            image::Rgb(std::array::from_fn(|c| {
                let v = a * colour[c] + (1.0 - a) * sky[c] + noise(x, y, c as u32, salt) as f32;
                (v - 4.0).round().clamp(0.0, 255.0) as u8
            }))
        };
        let twig = |x: u32, y: u32| (10..50).contains(&x) && (24..36).contains(&y);
        let streak = |x: u32, y: u32| (70..100).contains(&x) && (24..36).contains(&y);
        // The twig's coverage runs from a fifth to a third along it; the streak's is a
        // quarter to a third.
        let frame = RgbImage::from_fn(w, h, |x, y| {
            if twig(x, y) {
                paint(x, y, bark, 0.2 + 0.13 * (x - 10) as f32 / 40.0, 0)
            } else if streak(x, y) {
                paint(x, y, core, 0.25 + 0.08 * (x % 3) as f32 / 2.0, 0)
            } else {
                paint(x, y, sky, 0.0, 0)
            }
        });
        let previous = RgbImage::from_fn(w, h, |x, y| paint(x, y, sky, 0.0, 1));
        let solid = RgbImage::from_fn(w, h, |x, y| {
            let (dx, dy) = (f64::from(x) - 60.0, f64::from(y) - 30.0);
            if dx * dx + dy * dy <= 49.0 {
                image::Rgb(core.map(|v| v as u8))
            } else {
                paint(x, y, sky, 0.0, 0)
            }
        });
        let appearance = AppearanceModel::Hue { bins: 16 };
        let mask = ChannelRange::CAMSHIFT_DEMO;
        let window = PixelRect::new(56, 26, 8, 8);
        let model =
            MarkerModel::learn("m", &solid, window, &appearance, &mask, false).expect("learns");
        let lookup = Lookup::new(&appearance, &model, &mask);
        let filter = PixelFilter {
            depth: None,
            masked: &[],
            paler: &[],
            streak: Some(Streak {
                previous: &previous,
                shift: [0, 0],
                colour: mean,
                shade: STREAK_MIN_SHADE,
                hue_share: STREAK_MIN_HUE_SHARE,
                core,
                trail: None,
            }),
        };
        let params = [STREAK_MIN_SHADE, STREAK_MIN_HUE_SHARE];
        let px = |image: &RgbImage, x: u32, y: u32| image.get_pixel(x, y).0.map(f32::from);
        let count = |inside: &dyn Fn(u32, u32) -> bool, weighs: &dyn Fn(u32, u32) -> bool| {
            let (mut n, mut yes) = (0, 0);
            for y in 0..h {
                for x in 0..w {
                    if inside(x, y) {
                        n += 1;
                        yes += usize::from(weighs(x, y));
                    }
                }
            }
            yes as f64 / n as f64
        };
        let one_by_one = count(&twig, &|x, y| {
            streak_of([mean, core], params, px(&frame, x, y), px(&previous, x, y)) >= 64.0
        });
        assert!(one_by_one > 0.5, "twig pixels passing alone: {one_by_one}");
        let rect = PixelRect::new(0, 0, w as i32, h as i32);
        for sparse in [
            None,
            Some(Sparse {
                threshold: 64.0,
                cell: (6, 6),
            }),
        ] {
            let mut region = Region::default();
            region.fill(&appearance, &model, &lookup, &frame, rect, &filter, sparse);
            let weighs = |x: u32, y: u32| region.weights[region.index(x as i32, y as i32)] >= 64.0;
            let kept_twig = count(&twig, &weighs);
            let kept_streak = count(&streak, &weighs);
            assert!(kept_twig < 0.05, "{sparse:?}: twig pixels kept {kept_twig}");
            assert!(
                kept_streak > 0.9,
                "{sparse:?}: streak pixels kept {kept_streak}"
            );
        }
    }

    /// A filter that lets every pixel through and raises none to a streak weight.
    fn no_filter() -> PixelFilter<'static> {
        PixelFilter {
            depth: None,
            masked: &[],
            paler: &[],
            streak: None,
        }
    }

    /// The one-channel lookup (hue under a saturation/value mask, gray) weighs every pixel
    /// as the general three-table lookup does, and is used where it applies.
    #[test]
    fn the_one_channel_lookup_equals_the_general_one() {
        let frame = RgbImage::from_fn(64, 48, |x, y| {
            let v = ((x * 37 + y * 11 + x * y) % 256) as u8;
            image::Rgb([v, v.wrapping_mul(7), 255 - v / 2])
        });
        let window = PixelRect::new(20, 10, 12, 12);
        // A mask narrow enough that both its saturation and value bounds reject pixels.
        let mask = ChannelRange {
            lower: [0, 40, 30],
            upper: [180, 250, 240],
        };
        let filter = no_filter();
        let rect = PixelRect::new(0, 0, 64, 48);
        for (appearance, one) in [
            (AppearanceModel::Hue { bins: 16 }, true),
            (AppearanceModel::Gray { bins: 32 }, true),
            (
                AppearanceModel::HueSaturation {
                    hue_bins: 8,
                    saturation_bins: 4,
                },
                false,
            ),
        ] {
            let model =
                MarkerModel::learn("m", &frame, window, &appearance, &mask, false).expect("learns");
            let fast = Lookup::new(&appearance, &model, &mask);
            assert_eq!(fast.one_channel.is_some(), one, "{appearance:?}");
            let general = Lookup {
                one_channel: None,
                ..fast.clone()
            };
            let (mut a, mut b) = (Region::default(), Region::default());
            a.fill(&appearance, &model, &fast, &frame, rect, &filter, None);
            b.fill(&appearance, &model, &general, &frame, rect, &filter, None);
            assert_eq!(a.weights, b.weights, "{appearance:?}");
            let zero = a.weights.iter().filter(|&&w| w == 0.0).count();
            assert!(zero > 0 && zero < a.weights.len(), "{appearance:?}: {zero}");
        }
    }

    /// The kernel model's lookup, rescaled by the light's change per channel, weighs a frame
    /// under a dimmer, bluer light as the first (to the rounding of one level), where the
    /// lookup as learnt puts the marker in other bins; holes stay no data either way.
    #[test]
    fn a_rescaled_lookup_weighs_a_frame_under_another_light_as_the_first() {
        let disc = |x: u32, y: u32| (x as i32 - 16).pow(2) + (y as i32 - 12).pow(2) <= 36;
        let frame = RgbImage::from_fn(32, 24, |x, y| {
            image::Rgb(match (disc(x, y), x == 3) {
                (_, true) => [0, 0, 0],
                (true, _) => [200, 40 + (x % 3) as u8 * 20, 60],
                (false, _) => [90, 140, 200],
            })
        });
        let light = [0.7f32, 0.8, 1.1];
        let dimmed = RgbImage::from_fn(32, 24, |x, y| {
            let p = frame.get_pixel(x, y).0;
            image::Rgb([0, 1, 2].map(|c| (f32::from(p[c]) * light[c]).round() as u8))
        });
        let appearance = AppearanceModel::Rgb { bins: 16 };
        let mask = ChannelRange {
            lower: [0, 0, 0],
            upper: [255, 255, 255],
        };
        let window = PixelRect::new(9, 5, 15, 15);
        let model =
            MarkerModel::learn("m", &frame, window, &appearance, &mask, true).expect("learns");
        let filter = no_filter();
        let rect = PixelRect::new(0, 0, 32, 24);
        let mut lookup = Lookup::new(&appearance, &model, &mask);
        let learnt = lookup.tables();
        let weigh = |lookup: &Lookup, image: &RgbImage| {
            let mut r = Region::default();
            r.fill(&appearance, &model, lookup, image, rect, &filter, None);
            (r.weights, r.bins)
        };
        let (first, first_bins) = weigh(&lookup, &frame);
        let on_disc = |w: &[f32]| {
            (0..w.len())
                .filter(|&k| disc((k % 32) as u32, (k / 32) as u32) && w[k] > 0.0)
                .count()
        };
        assert!(on_disc(&first) > 100, "{}", on_disc(&first));
        let (unscaled, _) = weigh(&lookup, &dimmed);
        assert!(
            on_disc(&unscaled) < on_disc(&first) / 4,
            "{}",
            on_disc(&unscaled)
        );
        lookup.rescale(&learnt, light.map(|g| 1.0 / g));
        let (scaled, scaled_bins) = weigh(&lookup, &dimmed);
        assert_eq!(scaled, first);
        assert_eq!(scaled_bins, first_bins);
        // The column of holes: no weight, no bin.
        for y in 0..24 {
            assert_eq!(scaled[y * 32 + 3], 0.0);
            assert_eq!(scaled_bins[y * 32 + 3], NO_BIN);
        }
    }

    /// A grey background (`previous`) and the frame of the sparse-fill test: red discs of 3 to
    /// 12 px (one with a faint halo, one cut by the region's edge, one half in a mask), a
    /// streak (red mixed half and half with the background along 30 px) and a faint streak
    /// far from everything (a sixth of an exposure), both under the threshold.
    fn sparse_scene() -> (RgbImage, RgbImage) {
        let (fw, fh) = (320u32, 240u32);
        let previous = RgbImage::from_fn(fw, fh, grey_at);
        let discs = [
            (40.0, 40.0, 6.0),
            (200.0, 60.0, 1.6),
            (120.0, 180.0, 3.0),
            (317.0, 120.0, 5.0),
            (60.0, 200.0, 5.0),
        ];
        let frame = RgbImage::from_fn(fw, fh, |x, y| {
            let (xf, yf) = (f64::from(x), f64::from(y));
            let disc = discs
                .iter()
                .any(|&(cx, cy, r)| (xf - cx).hypot(yf - cy) <= r);
            let streak = (250..280).contains(&x) && (150..157).contains(&y);
            // A faint streak far from everything (a sixth of an exposure): weighs under the
            // threshold.
            let faint = (150..160).contains(&x) && (20..30).contains(&y);
            let g = grey_at(x, y);
            let mix = |a: f64| {
                let m = |c: u8, r: f64| (a * r + (1.0 - a) * f64::from(c)).round() as u8;
                image::Rgb([m(g[0], 210.0), m(g[1], 30.0), m(g[2], 25.0)])
            };
            // A faint halo about the first disc (under the threshold, next to a blob).
            let halo = (6.0..=12.0).contains(&(xf - 40.0).hypot(yf - 40.0));
            if faint || halo {
                mix(0.16)
            } else if disc {
                image::Rgb([210, 30, 25])
            } else if streak {
                mix(0.5)
            } else {
                g
            }
        });
        (frame, previous)
    }

    fn grey_at(x: u32, y: u32) -> image::Rgb<u8> {
        let v = 90 + ((x * 7 + y * 13) % 23) as u8;
        image::Rgb([v, v + 5, v + 10])
    }

    /// Blob threshold of the sparse-fill tests (the tracker's `BLOB_THRESHOLD` of 255).
    const TEST_THRESHOLD: f32 = 255.0 * 0.35;

    /// The hue model of a red marker learnt in `window` of `frame`, and its lookup.
    fn red_marker(frame: &RgbImage, window: PixelRect) -> Option<(MarkerModel, Lookup)> {
        let appearance = AppearanceModel::Hue { bins: 16 };
        let mask = ChannelRange::CAMSHIFT_DEMO;
        let model = MarkerModel::learn("m", frame, window, &appearance, &mask, false).ok()?;
        let lookup = Lookup::new(&appearance, &model, &mask);
        Some((model, lookup))
    }

    /// A full and a sparse fill (cells of 6 px) of `marker` over `rect` of `frame`, the red
    /// streak over `previous` counting and `masked` rejected.
    fn full_and_sparse(
        (model, lookup): &(MarkerModel, Lookup),
        frame: &RgbImage,
        previous: &RgbImage,
        masked: &[PixelRect],
        rect: PixelRect,
    ) -> (Region, Region) {
        let appearance = AppearanceModel::Hue { bins: 16 };
        let filter = red_filter(previous, [0, 0], masked, None);
        let (mut full, mut sparse) = (Region::default(), Region::default());
        full.fill(&appearance, model, lookup, frame, rect, &filter, None);
        let (threshold, cell) = (TEST_THRESHOLD, (6, 6));
        let at = Sparse { threshold, cell };
        sparse.fill(&appearance, model, lookup, frame, rect, &filter, Some(at));
        (full, sparse)
    }

    /// A still scene shaken by the camera: a pale-red stripe (the marker's colour half
    /// blended with the sky, as a streak of the marker would be) moved 7 px up. Read where
    /// the camera's shift puts it, the frame before gives no streak weight anywhere, as when
    /// nothing moved; read in place, the stripe's edges look newly covered, like a streak.
    #[test]
    fn a_shaken_scene_read_where_the_camera_moved_it_gives_no_streak() {
        let (sky, red) = ([170u8, 200, 235], [210u8, 30, 25]);
        let stripe: [u8; 3] =
            std::array::from_fn(|c| ((u16::from(sky[c]) + u16::from(red[c])) / 2) as u8);
        let scene = |up: i32| {
            RgbImage::from_fn(120, 100, move |x, y| {
                let along = x as i32 + y as i32 + up;
                image::Rgb(if (60..72).contains(&along) {
                    stripe
                } else {
                    sky
                })
            })
        };
        let first = RgbImage::from_fn(120, 100, |x, y| {
            let (dx, dy) = (f64::from(x) - 20.0, f64::from(y) - 20.0);
            image::Rgb(if dx * dx + dy * dy <= 36.0 { red } else { sky })
        });
        let (model, lookup) = red_marker(&first, PixelRect::new(13, 13, 15, 15)).expect("learns");
        let appearance = AppearanceModel::Hue { bins: 16 };
        let weigh = |frame: &RgbImage, previous: &RgbImage, shift: [i32; 2], sparse: bool| -> f64 {
            let filter = red_filter(previous, shift, &[], None);
            let mut region = Region::default();
            let rect = PixelRect::new(10, 15, 100, 70);
            let at = sparse.then_some(Sparse {
                threshold: TEST_THRESHOLD,
                cell: (6, 6),
            });
            region.fill(&appearance, &model, &lookup, frame, rect, &filter, at);
            region.weights.iter().map(|&w| f64::from(w)).sum()
        };
        let (still, shaken) = (scene(0), scene(7));
        for sparse in [false, true] {
            let unchanged = weigh(&shaken, &shaken, [0, 0], sparse);
            assert_eq!(weigh(&shaken, &still, [0, -7], sparse), unchanged);
            let in_place = weigh(&shaken, &still, [0, 0], sparse);
            assert!(
                in_place > unchanged + 255.0 * 20.0,
                "{sparse}: {in_place} against {unchanged}"
            );
        }
    }

    /// The filter of a red marker (210, 30, 25) with streaks over `previous` moved by the
    /// camera's `shift`, the `masked` rectangles and the `trail`.
    fn red_filter<'a>(
        previous: &'a RgbImage,
        shift: [i32; 2],
        masked: &'a [PixelRect],
        trail: Option<Trail>,
    ) -> PixelFilter<'a> {
        PixelFilter {
            depth: None,
            masked,
            paler: &[],
            streak: Some(Streak {
                previous,
                shift,
                colour: [210.0, 30.0, 25.0],
                shade: STREAK_MIN_SHADE,
                hue_share: STREAK_RESIDUAL[1],
                core: [210.0, 30.0, 25.0],
                trail,
            }),
        }
    }

    /// A release filmed within one exposure: half of it the marker rests where it was in the
    /// frame before, half of it it is 12 px on, so the frame holds two half-tone copies and
    /// its truth is their midpoint. Without the trail only the copy that moved weighs (the
    /// one at rest has the marker's own colour behind it in the frame before); with it both
    /// do, on the sparse path as on the full one. What stays where the marker was weighs by
    /// its own colour, with or without the trail.
    #[test]
    fn a_trail_weighs_the_half_of_a_release_drawn_where_the_marker_was() {
        let (sky, red) = ([170u8, 200, 235], [210u8, 30, 25]);
        let half: [u8; 3] =
            std::array::from_fn(|c| ((u16::from(sky[c]) + u16::from(red[c])) / 2) as u8);
        let disc = |cx: f64, cy: f64, x: u32, y: u32| {
            let (dx, dy) = (f64::from(x) - cx, f64::from(y) - cy);
            dx * dx + dy * dy <= 36.0
        };
        let previous = RgbImage::from_fn(120, 100, |x, y| {
            image::Rgb(if disc(40.0, 50.0, x, y) { red } else { sky })
        });
        let frame = RgbImage::from_fn(120, 100, |x, y| {
            image::Rgb(if disc(40.0, 50.0, x, y) || disc(52.0, 50.0, x, y) {
                half
            } else {
                sky
            })
        });
        // Learnt inside the disc: the sky does not weigh.
        let (model, lookup) = red_marker(&previous, PixelRect::new(36, 46, 8, 8)).expect("learns");
        let appearance = AppearanceModel::Hue { bins: 16 };
        let trail = Trail {
            rect: PixelRect::new(33, 43, 15, 15),
            around: sky,
        };
        let weigh = |frame: &RgbImage, previous: &RgbImage, trail: Option<Trail>, sparse: bool| {
            let filter = red_filter(previous, [0, 0], &[], trail);
            let mut region = Region::default();
            let rect = PixelRect::new(10, 20, 100, 60);
            let at = sparse.then_some(Sparse {
                threshold: TEST_THRESHOLD,
                cell: (6, 6),
            });
            region.fill(&appearance, &model, &lookup, frame, rect, &filter, at);
            let (mut sw, mut sx) = (0.0, 0.0);
            for y in rect.y..rect.bottom() as i32 {
                for x in rect.x..rect.right() as i32 {
                    let w = f64::from(region.weights[region.index(x, y)]);
                    sw += w;
                    sx += w * f64::from(x);
                }
            }
            (sw, sx / sw)
        };
        // A paler look-alike (0.6 of the marker over the sky) that stays in both frames.
        let pale: [u8; 3] =
            std::array::from_fn(|c| ((3 * u16::from(red[c]) + 2 * u16::from(sky[c])) / 5) as u8);
        let look_alike = RgbImage::from_fn(120, 100, |x, y| {
            image::Rgb(if disc(40.0, 50.0, x, y) { pale } else { sky })
        });
        for sparse in [false, true] {
            let (_, ahead) = weigh(&frame, &previous, None, sparse);
            assert!(ahead > 50.0, "{sparse}: {ahead}");
            let (_, both) = weigh(&frame, &previous, Some(trail), sparse);
            assert!((both - 46.0).abs() < 0.5, "{sparse}: {both}");
            // What stays where the marker was (the marker at rest, or a look-alike the
            // track sits on): as without the trail.
            for still in [&previous, &look_alike] {
                let (plain, _) = weigh(still, still, None, sparse);
                let (with, _) = weigh(still, still, Some(trail), sparse);
                assert_eq!(plain, with, "{sparse}");
            }
        }
    }

    /// A sparse fill weighs every blob at or above its threshold, the pixels about it and the
    /// window about its centre exactly as a full fill does, and leaves the rest at 0; a
    /// cluttered region is weighed whole.
    #[test]
    fn a_sparse_fill_weighs_every_blob_as_a_full_fill_does() {
        let (fw, fh) = (320u32, 240u32);
        let (frame, previous) = sparse_scene();
        let marker = red_marker(&frame, PixelRect::new(34, 34, 12, 12)).expect("learns");
        let masked = [PixelRect::new(58, 190, 20, 20)];
        let rect = PixelRect::new(0, 0, 360, 240);
        let threshold = TEST_THRESHOLD;
        let (full, sparse) = full_and_sparse(&marker, &frame, &previous, &masked, rect);
        assert!(!sparse.cluttered);
        assert_eq!(sparse.rect, full.rect);
        let r = full.rect;
        let at = |x: i32, y: i32| full.index(x, y);
        let (mut blob_pixels, mut skipped) = (0, 0);
        for y in r.y..r.bottom() as i32 {
            for x in r.x..r.right() as i32 {
                let k = at(x, y);
                skipped += usize::from(sparse.weights[k] != full.weights[k]);
                if full.weights[k] < threshold {
                    continue;
                }
                blob_pixels += 1;
                // The blob pixel, its ring and a 12 px window about it: as in the full fill.
                for yy in (y - 6).max(r.y)..(y + 7).min(r.bottom() as i32) {
                    for xx in (x - 6).max(r.x)..(x + 7).min(r.right() as i32) {
                        let j = at(xx, yy);
                        assert_eq!(sparse.weights[j], full.weights[j], "({xx}, {yy})");
                    }
                }
            }
        }
        // The smallest disc (1.6 px) and the streak count too.
        assert!(full.weights[at(200, 60)] >= threshold);
        assert!(full.weights[at(265, 153)] >= threshold);
        assert!(blob_pixels > 300, "{blob_pixels}");
        // The disc cut by the mask: weighed outside it, 0 inside it.
        assert!(full.weights[at(56, 200)] >= threshold);
        assert_eq!(sparse.weights[at(62, 200)], 0.0);
        // Most of the region was not weighed: where the full fill has weights under the
        // threshold far from any blob (the streak's faint edges, colour noise), the sparse
        // one has 0.
        let weighed = sparse.weights.iter().filter(|&&w| w > 0.0).count();
        let nonzero = full.weights.iter().filter(|&&w| w > 0.0).count();
        assert!(weighed > 0 && weighed <= nonzero, "{weighed} {nonzero}");
        assert!(full.weights[at(40, 50)] > 0.0 && full.weights[at(40, 50)] < threshold);
        let faint = full.weights[at(155, 25)];
        assert!(faint > 0.0 && faint < threshold, "{faint}");
        assert_eq!(sparse.weights[at(155, 25)], 0.0);
        assert!(skipped > 0);

        // Red everywhere: the region is cluttered and weighed whole.
        let cluttered = RgbImage::from_fn(fw, fh, |x, y| {
            if (x / 4 + y / 4) % 3 == 0 {
                image::Rgb([210, 30, 25])
            } else {
                grey_at(x, y)
            }
        });
        let (full, whole) = full_and_sparse(&marker, &cluttered, &previous, &masked, rect);
        assert!(whole.cluttered);
        assert_eq!(whole.weights, full.weights);
    }

    /// A random scene for the sparse-fill test: discs of 2–9 px radius in two reds (centre
    /// x, y, radius, red level), a streak at any angle, noise.
    #[allow(clippy::type_complexity)]
    fn random_scene(rng: &mut crate::rng::Rng) -> (RgbImage, Vec<(f64, f64, f64, u8)>) {
        let discs: Vec<(f64, f64, f64, u8)> = (0..rng.int(1, 9))
            .map(|_| {
                let c = (rng.range([0.0, 320.0]), rng.range([0.0, 240.0]));
                (
                    c.0,
                    c.1,
                    rng.range([2.0, 9.0]),
                    if rng.uniform() < 0.5 { 200 } else { 150 },
                )
            })
            .collect();
        let streak = (
            (rng.range([40.0, 280.0]), rng.range([40.0, 200.0])),
            rng.range([0.0, std::f64::consts::PI]),
            rng.range([0.3, 0.7]),
        );
        let noise = rng.next();
        let frame = RgbImage::from_fn(320, 240, |x, y| {
            let (xf, yf) = (f64::from(x), f64::from(y));
            let g = grey_at(x, y);
            let jitter = ((noise ^ u64::from(x * 131 + y * 977)) % 7) as u8;
            if let Some(&(_, _, _, red)) = discs.iter().find(|d| (xf - d.0).hypot(yf - d.1) <= d.2)
            {
                return image::Rgb([red + jitter, 30, 25]);
            }
            let ((sx, sy), angle, a) = streak;
            let (dx, dy) = (xf - sx, yf - sy);
            let along = dx * angle.cos() + dy * angle.sin();
            let across = -dx * angle.sin() + dy * angle.cos();
            if along.abs() < 20.0 && across.abs() < 4.0 {
                let m = |c: u8, r: f64| (a * r + (1.0 - a) * f64::from(c)).round() as u8;
                return image::Rgb([m(g[0], 210.0), m(g[1], 30.0), m(g[2], 25.0)]);
            }
            g
        });
        (frame, discs)
    }

    /// Over random scenes (discs of 2–9 px radius in two reds, streaks at any angle, masks,
    /// noise), the blobs of a sparse fill and their steadied centres are those of a full fill.
    #[test]
    fn sparse_and_full_fills_give_the_same_blobs_on_random_scenes() {
        let mut rng = crate::rng::Rng::new(31);
        let mut compared = 0;
        for scene in 0..24 {
            let (frame, discs) = random_scene(&mut rng);
            let (_, previous) = sparse_scene();
            let window = discs
                .iter()
                .find(|d| {
                    d.2 >= 4.0
                        && d.3 == 200
                        && (8.0..312.0).contains(&d.0)
                        && (8.0..232.0).contains(&d.1)
                })
                .map(|d| PixelRect::centered_at(Point2::new(d.0, d.1), 12, 12));
            let Some(window) = window else {
                continue;
            };
            let Some(marker) = red_marker(&frame, window) else {
                continue;
            };
            let masked = [PixelRect::new(
                rng.int(0, 300) as i32,
                rng.int(0, 220) as i32,
                30,
                20,
            )];
            let rect = PixelRect::new(-20, -10, 360, 260);
            let threshold = TEST_THRESHOLD;
            let (full, sparse) = full_and_sparse(&marker, &frame, &previous, &masked, rect);
            let (mut a, mut b) = (Labeler::default(), Labeler::default());
            for gap in 1..=3 {
                let blobs = a.blobs(&full.weights, full.rect, full.rect, threshold, 3, gap);
                let same = b.blobs(&sparse.weights, sparse.rect, sparse.rect, threshold, 3, gap);
                assert_eq!(blobs, same, "scene {scene} gap {gap}");
                for blob in &blobs {
                    let w = PixelRect::centered_at(blob.centroid, 12, 12);
                    let (p, q) = (
                        a.edge_centroid(&full.weights, full.rect, blob, w, 6),
                        b.edge_centroid(&sparse.weights, sparse.rect, blob, w, 6),
                    );
                    assert_eq!(p, q, "scene {scene} gap {gap}");
                    compared += 1;
                }
            }
        }
        assert!(compared > 100, "{compared}");
    }
}
