//! Gray templates compared by zero-mean normalised cross-correlation (NCC): a marker's own
//! window, which locates black-and-white targets that a histogram cannot (a white square on a
//! white wall), and its surroundings, which tell look-alike markers apart (the branch they
//! sit on, a fork, the background).
//!
//! [`Template::search`] finds the best matches within a radius coarse to fine: an NCC map on
//! a grid two or four times coarser, its local maxima, each refined at full resolution and to
//! a sub-pixel centre by a parabola through the correlations of the neighbouring pixels.

use std::cell::OnceCell;

use image::RgbImage;
use nalgebra::{Point2, Vector2};

use crate::hsv::rgb_to_gray;

/// Fewest overlapping pixels for a meaningful correlation.
const MIN_PIXELS: usize = 16;
/// Least share of the template's pixels that must overlap the frame: a template mostly off
/// the frame correlates with anything.
const MIN_OVERLAP: f64 = 0.6;
/// Coarse grid cells must hold at least this many template pixels a side.
const MIN_COARSE_SIDE: usize = 8;
/// Coarse peaks refined at full resolution, at least (a fine target seen half a cell off
/// correlates less on the coarse grid than a look-alike aligned with it).
const MIN_REFINED: usize = 8;
/// A coarse local maximum below this correlation is not a candidate.
const MIN_PEAK_NCC: f64 = 0.3;

/// A gray patch centred on a marker, `NaN` where it fell outside the frame.
#[derive(Debug, Clone)]
pub(crate) struct Template {
    width: usize,
    height: usize,
    values: Vec<f32>,
    /// Where the marker's centre lies relative to the patch's centre pixel (sub-pixel).
    offset: Vector2<f64>,
    /// The template averaged over `scale` x `scale` cells, for the coarse search: made when
    /// a search first needs it after the template was learnt or blended (a surroundings
    /// template, blended every frame, is never searched).
    coarse: OnceCell<Vec<f32>>,
    scale: usize,
    /// Sum and sum of squares of `values` when none is unknown (see [`ncc_in`]).
    sums: Option<(f64, f64)>,
}

/// Reusable buffers of the template comparisons.
#[derive(Debug, Default)]
pub(crate) struct TemplateScratch {
    patch: Vec<f32>,
    /// The template and the patch widened to `f64`, and column sums, for a block of windows.
    template: Vec<f64>,
    wide: Vec<f64>,
    cols: Vec<f64>,
}

/// A match of a template: the marker's centre there and the correlation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Match {
    pub(crate) center: Point2<f64>,
    pub(crate) ncc: f64,
}

/// Pixel centre nearest to `center`, as integers.
fn anchor(center: Point2<f64>) -> (i64, i64) {
    let finite = |v: f64| if v.is_finite() { v.round() } else { 0.0 };
    (
        finite(center.x).clamp(-1e9, 1e9) as i64,
        finite(center.y).clamp(-1e9, 1e9) as i64,
    )
}

/// The gray values of the `width` x `height` patch centred on pixel `(cx, cy)`, `NaN`
/// outside the frame.
fn patch_at(
    frame: &RgbImage,
    (cx, cy): (i64, i64),
    width: usize,
    height: usize,
    out: &mut Vec<f32>,
) {
    out.clear();
    out.resize(width * height, f32::NAN);
    let x0 = cx - (width / 2) as i64;
    let y0 = cy - (height / 2) as i64;
    let (fw, fh) = (i64::from(frame.width()), i64::from(frame.height()));
    // The columns of the patch inside the frame, the same on every row.
    let (from, to) = (x0.clamp(0, fw), (x0 + width as i64).clamp(0, fw));
    if from >= to {
        return;
    }
    let raw = frame.as_raw();
    let skip = (from - x0) as usize;
    for (j, y) in (y0..y0 + height as i64).enumerate() {
        if !(0..fh).contains(&y) {
            continue;
        }
        let start = ((y * fw + from) * 3) as usize;
        let pixels = raw[start..start + (to - from) as usize * 3].chunks_exact(3);
        let dest = &mut out[j * width + skip..];
        for (d, p) in dest.iter_mut().zip(pixels) {
            *d = f32::from(rgb_to_gray([p[0], p[1], p[2]]));
        }
    }
}

/// Zero-mean NCC of two equally sized patches over the pixels known in both; 0 when either
/// has no contrast there, or fewer than [`MIN_PIXELS`] or [`MIN_OVERLAP`] of them overlap.
fn ncc(a: &[f32], b: &[f32]) -> f64 {
    ncc_in(a, a.len().max(1), b, a.len().max(1), None)
}

/// The quick path's sums, known when neither the template nor the frame's patch has an
/// unknown pixel: the template's sum and sum of squares.
#[derive(Debug, Clone, Copy)]
struct Quick {
    template: (f64, f64),
}

/// [`ncc`] of the patch `a` (rows of `width`) against the equally sized window of `b` (rows of
/// `b_stride`, from its start), by the quick path when `quick` is given.
fn ncc_in(a: &[f32], width: usize, b: &[f32], b_stride: usize, quick: Option<Quick>) -> f64 {
    let rows = a.len() / width;
    let row = |j: usize| &b[j * b_stride..j * b_stride + width];
    let (n, sa, sb, saa, sbb, sab);
    if let Some(Quick {
        template: (a_sum, a_squares),
    }) = quick
    {
        // Gray levels are integers, so the window's sums (below 2^53) are exact in any order
        // (as `window_sums` takes them); the products are summed in four lanes, which the
        // compiler vectorises (another order than the slow path's, within 1e-15).
        let (s1, s2) = (0..rows).flat_map(row).fold((0.0, 0.0), |(s, q), &y| {
            let y = f64::from(y);
            (s + y, q + y * y)
        });
        let mut p4 = [0.0f64; 4];
        for j in 0..rows {
            let (a_row, b_row) = (&a[j * width..(j + 1) * width], row(j));
            let (a4, b4) = (a_row.chunks_exact(4), b_row.chunks_exact(4));
            let tail = a4.remainder().iter().zip(b4.remainder());
            for (x, y) in a4.zip(b4) {
                for k in 0..4 {
                    p4[k] += f64::from(x[k]) * f64::from(y[k]);
                }
            }
            for (&x, &y) in tail {
                p4[0] += f64::from(x) * f64::from(y);
            }
        }
        let sp = (p4[0] + p4[1]) + (p4[2] + p4[3]);
        (n, sa, sb, saa, sbb, sab) = (a.len(), a_sum, s1, a_squares, s2, sp);
    } else {
        let (mut n1, mut s1, mut s2, mut s11, mut s22, mut s12) = (0usize, 0.0, 0.0, 0.0, 0.0, 0.0);
        for j in 0..rows {
            for (&x, &y) in a[j * width..(j + 1) * width].iter().zip(row(j)) {
                if x.is_nan() || y.is_nan() {
                    continue;
                }
                let (x, y) = (f64::from(x), f64::from(y));
                n1 += 1;
                s1 += x;
                s2 += y;
                s11 += x * x;
                s22 += y * y;
                s12 += x * y;
            }
        }
        (n, sa, sb, saa, sbb, sab) = (n1, s1, s2, s11, s22, s12);
    }
    ncc_of(n, a.len(), [sa, sb, saa, sbb, sab])
}

/// The correlation of `n` pixel pairs of patches of `len` pixels from their sums `[Σa, Σb,
/// Σa², Σb², Σab]`; 0 without contrast or enough overlap.
fn ncc_of(n: usize, len: usize, [sa, sb, saa, sbb, sab]: [f64; 5]) -> f64 {
    if n < MIN_PIXELS || (n as f64) < MIN_OVERLAP * len as f64 {
        return 0.0;
    }
    let nf = n as f64;
    let va = saa - sa * sa / nf;
    let vb = sbb - sb * sb / nf;
    if va <= 1e-9 || vb <= 1e-9 {
        return 0.0;
    }
    ((sab - sa * sb / nf) / (va * vb).sqrt()).clamp(-1.0, 1.0)
}

/// `Σ a·b` of the template `a` (rows of `width`) against `N` windows of `b` (row stride
/// `b_stride`) that start at columns `0..N` of its first row, each summed exactly as
/// [`ncc_in`]'s quick path sums one (four lanes in column order, a row's remainder into the
/// first lane), the `N` windows side by side so that their sums run in parallel. Both are
/// `f32` values widened to `f64` beforehand, so every product is the same.
fn products_side_by_side<const N: usize>(
    a: &[f64],
    width: usize,
    b: &[f64],
    b_stride: usize,
) -> [f64; N] {
    let rows = a.len() / width;
    let mut p = [[0.0f64; 4]; N];
    let chunks = width / 4;
    for j in 0..rows {
        let a_row = &a[j * width..(j + 1) * width];
        let b_row = &b[j * b_stride..j * b_stride + width + N - 1];
        // Window by window (each lane's sum runs in the same order as when the windows
        // took turns per chunk), over whole 4-lane arrays, which vectorises.
        for (u, lanes) in p.iter_mut().enumerate() {
            let b_u = &b_row[u..u + width];
            for (x, y) in a_row.chunks_exact(4).zip(b_u.chunks_exact(4)) {
                for k in 0..4 {
                    lanes[k] += x[k] * y[k];
                }
            }
            for t in 4 * chunks..width {
                lanes[0] += a_row[t] * b_u[t];
            }
        }
    }
    p.map(|l| (l[0] + l[1]) + (l[2] + l[3]))
}

/// Sum and sum of squares of each of the `N x N` windows (`width` x `height`) of `b` (row
/// stride `stride`, whole gray levels), row-major: from column sums slid down a row at a
/// time and window sums along them. Whole numbers far below 2^53, so every sum is exact,
/// the same as summing each window in any order.
fn window_sums<const N: usize>(
    b: &[f64],
    stride: usize,
    (width, height): (usize, usize),
    cols: &mut Vec<f64>,
) -> [[(f64, f64); N]; N] {
    cols.clear();
    cols.resize(2 * stride, 0.0);
    let (sums, squares) = cols.split_at_mut(stride);
    for row in b.chunks_exact(stride).take(height) {
        for ((s, q), &v) in sums.iter_mut().zip(squares.iter_mut()).zip(row) {
            *s += v;
            *q += v * v;
        }
    }
    let mut out = [[(0.0, 0.0); N]; N];
    for (v, out_row) in out.iter_mut().enumerate() {
        if v > 0 {
            let (gone, new) = (
                &b[(v - 1) * stride..v * stride],
                &b[(v + height - 1) * stride..],
            );
            for (((s, q), &g), &n) in sums.iter_mut().zip(squares.iter_mut()).zip(gone).zip(new) {
                *s += n - g;
                *q += n * n - g * g;
            }
        }
        for (u, o) in out_row.iter_mut().enumerate() {
            let (s, q) = (&sums[u..u + width], &squares[u..u + width]);
            *o = (s.iter().sum(), q.iter().sum());
        }
    }
    out
}

/// Sum and sum of squares of `values` in order (f64), or `None` when one is unknown.
fn known_sums(values: &[f32]) -> Option<(f64, f64)> {
    let (mut s, mut ss) = (0.0, 0.0);
    for &v in values {
        if v.is_nan() {
            return None;
        }
        let v = f64::from(v);
        s += v;
        ss += v * v;
    }
    Some((s, ss))
}

/// `values` (`width` x `height`) averaged over `scale` x `scale` cells (NaN if any is).
fn coarsen(values: &[f32], width: usize, height: usize, scale: usize) -> Vec<f32> {
    let (cw, ch) = (width / scale, height / scale);
    let mut out = Vec::with_capacity(cw * ch);
    for j in 0..ch {
        for i in 0..cw {
            let mut s = 0.0f32;
            for y in j * scale..(j + 1) * scale {
                for x in i * scale..(i + 1) * scale {
                    s += values[y * width + x];
                }
            }
            out.push(s / (scale * scale) as f32);
        }
    }
    out
}

impl Template {
    /// The `width` x `height` patch centred at `center`.
    pub(crate) fn learn(
        frame: &RgbImage,
        center: Point2<f64>,
        width: usize,
        height: usize,
    ) -> Self {
        let (width, height) = (width.max(1), height.max(1));
        let a = anchor(center);
        let mut values = Vec::with_capacity(width * height);
        patch_at(frame, a, width, height, &mut values);
        let scale = if width.min(height) >= 4 * MIN_COARSE_SIDE {
            4
        } else if width.min(height) >= 2 * MIN_COARSE_SIDE {
            2
        } else {
            1
        };
        Self {
            width,
            height,
            offset: Vector2::new(center.x - a.0 as f64, center.y - a.1 as f64),
            sums: known_sums(&values),
            values,
            coarse: OnceCell::new(),
            scale,
        }
    }

    /// NCC (-1..=1) between the template and the patch at `center`, over the pixels inside
    /// the frame in both (0 without contrast or overlap).
    #[cfg(test)]
    fn ncc(&self, frame: &RgbImage, center: Point2<f64>, scratch: &mut TemplateScratch) -> f64 {
        patch_at(
            frame,
            anchor(center - self.offset),
            self.width,
            self.height,
            &mut scratch.patch,
        );
        ncc(&self.values, &scratch.patch)
    }

    /// The best NCC within one pixel of `center` (a centre a pixel off loses much of a small
    /// target's correlation).
    pub(crate) fn ncc_near(
        &self,
        frame: &RgbImage,
        center: Point2<f64>,
        scratch: &mut TemplateScratch,
    ) -> f64 {
        let mut block = [0.0; 9];
        self.ncc_block(frame, anchor(center - self.offset), 1, scratch, &mut block);
        block.into_iter().fold(f64::NEG_INFINITY, f64::max)
    }

    /// The NCC of the template anchored at every pixel of the `(2 reach + 1)`² block around
    /// `(cx, cy)` into `out` (row-major), from one gray patch of the frame that holds them all.
    fn ncc_block(
        &self,
        frame: &RgbImage,
        (cx, cy): (i64, i64),
        reach: usize,
        scratch: &mut TemplateScratch,
        out: &mut [f64],
    ) {
        let side = 2 * reach + 1;
        let stride = self.width + 2 * reach;
        // The wide patch's first column is `cx - width / 2 - reach`: that of the template
        // anchored `reach` pixels to the left.
        let rows = self.height + 2 * reach;
        patch_at(frame, (cx, cy), stride, rows, &mut scratch.patch);
        let sums = self.quick_sums(&scratch.patch);
        if let Some(template) = sums {
            match side {
                3 => return self.quick_block::<3>(template, scratch, stride, out),
                5 => return self.quick_block::<5>(template, scratch, stride, out),
                9 => return self.quick_block::<9>(template, scratch, stride, out),
                _ => {}
            }
        }
        // Other block sizes (none the tracker asks for), and patches with unknown pixels.
        let quick = sums.map(|template| Quick { template });
        for (k, o) in out.iter_mut().enumerate().take(side * side) {
            let (u, v) = (k % side, k / side);
            *o = ncc_in(
                &self.values,
                self.width,
                &scratch.patch[v * stride + u..],
                stride,
                quick,
            );
        }
    }

    /// [`Template::ncc_block`]'s quick path for a block `N` windows a side: each row of
    /// windows summed side by side (the same sums, in the same order, as one at a time).
    fn quick_block<const N: usize>(
        &self,
        (a_sum, a_squares): (f64, f64),
        scratch: &mut TemplateScratch,
        stride: usize,
        out: &mut [f64],
    ) {
        let TemplateScratch {
            patch,
            template,
            wide,
            cols,
        } = scratch;
        template.clear();
        template.extend(self.values.iter().map(|&v| f64::from(v)));
        wide.clear();
        wide.extend(patch.iter().map(|&v| f64::from(v)));
        let sums = window_sums::<N>(wide, stride, (self.width, self.height), cols);
        let n = self.values.len();
        for (v, (row, sums)) in out.chunks_mut(N).zip(sums).enumerate() {
            let products =
                products_side_by_side::<N>(template, self.width, &wide[v * stride..], stride);
            for ((o, sab), (sb, sbb)) in row.iter_mut().zip(products).zip(sums) {
                *o = ncc_of(n, n, [a_sum, sb, a_squares, sbb, sab]);
            }
        }
    }

    /// The template's sums for [`ncc_in`]'s quick path against windows of `patch`, when
    /// neither has an unknown pixel.
    fn quick_sums(&self, patch: &[f32]) -> Option<(f64, f64)> {
        // A branch-free test over the whole patch, which vectorises.
        self.sums
            .filter(|_| patch.iter().fold(true, |known, v| known & !v.is_nan()))
    }

    /// Blend the patch at `center` into the template: `t <- (1 - rate) t + rate p`, so that
    /// slow changes (a branch turning, the light) are followed. Pixels known in only one of
    /// the two take the known value.
    pub(crate) fn update(
        &mut self,
        frame: &RgbImage,
        center: Point2<f64>,
        rate: f32,
        scratch: &mut TemplateScratch,
    ) {
        let patch = &mut scratch.patch;
        patch_at(
            frame,
            anchor(center - self.offset),
            self.width,
            self.height,
            patch,
        );
        // The blend, and the sums of the blended values in order (as `known_sums`).
        let (mut sum, mut squares, mut known) = (0.0, 0.0, true);
        for (t, &p) in self.values.iter_mut().zip(patch.iter()) {
            *t = match (t.is_nan(), p.is_nan()) {
                (false, false) => *t + rate * (p - *t),
                (true, _) => p,
                (false, true) => *t,
            };
            let v = f64::from(*t);
            known &= !t.is_nan();
            sum += v;
            squares += v * v;
        }
        self.coarse = OnceCell::new();
        self.sums = known.then_some((sum, squares));
    }

    /// The best matches (at most `max`, best first) whose centres lie within `radius_px` of
    /// `center`: local maxima of a coarse NCC map, each refined at full resolution to a
    /// sub-pixel centre.
    pub(crate) fn search(
        &self,
        frame: &RgbImage,
        center: Point2<f64>,
        radius_px: f64,
        max: usize,
        scratch: &mut TemplateScratch,
    ) -> Vec<Match> {
        // A search closer than two coarse cells is done at full resolution.
        let s = if radius_px < 2.0 * self.scale as f64 {
            1
        } else {
            self.scale
        };
        let (c0x, c0y) = anchor(center - self.offset);
        let r = (radius_px.max(0.0) / s as f64).ceil().min(4096.0) as i64;
        let mut coarse_peaks: Vec<(f64, i64, i64)> = self
            .coarse_peaks(frame, (c0x, c0y), r, s)
            .into_iter()
            .map(|(m, u, v)| {
                (
                    m,
                    c0x + (u as i64 - r) * s as i64,
                    c0y + (v as i64 - r) * s as i64,
                )
            })
            .collect();
        coarse_peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
        coarse_peaks.truncate((max * 2).max(MIN_REFINED));
        let mut out: Vec<Match> = Vec::new();
        for &(_, px, py) in &coarse_peaks {
            let Some(m) = self.refine(frame, (px, py), s, scratch) else {
                continue;
            };
            if (m.center - center).norm() > radius_px + 1.5 {
                continue;
            }
            if out
                .iter()
                .all(|o| (o.center - m.center).norm() > 0.5 * self.width.min(self.height) as f64)
            {
                out.push(m);
            }
        }
        out.sort_by(|a, b| b.ncc.total_cmp(&a.ncc));
        out.truncate(max);
        out
    }

    /// The local maxima (NCC, column, row) of the NCC map of the template at cell size `s`
    /// over the disc of radius `r` cells around the anchor `(c0x, c0y)`.
    fn coarse_peaks(
        &self,
        frame: &RgbImage,
        (c0x, c0y): (i64, i64),
        r: i64,
        s: usize,
    ) -> Vec<(f64, usize, usize)> {
        // The frame's gray cells under every coarse position of the template.
        let (cw, ch) = (self.width / s, self.height / s);
        let coarse: &[f32] = if s == self.scale {
            self.coarse
                .get_or_init(|| coarsen(&self.values, self.width, self.height, self.scale))
        } else {
            &self.values
        };
        let span = 2 * r as usize + 1;
        let (gw, gh) = (span + cw, span + ch);
        let gx0 = c0x - (self.width / 2) as i64 - r * s as i64;
        let gy0 = c0y - (self.height / 2) as i64 - r * s as i64;
        let grid = gray_cells(frame, (gx0, gy0), (gw, gh), s);
        let mut map = vec![f64::NEG_INFINITY; span * span];
        let mut cell = Vec::with_capacity(cw * ch);
        for v in 0..span {
            for u in 0..span {
                let (du, dv) = (u as i64 - r, v as i64 - r);
                if ((du * du + dv * dv) as f64) > (r as f64 + 0.5).powi(2) {
                    continue;
                }
                cell.clear();
                for j in 0..ch {
                    cell.extend_from_slice(&grid[(v + j) * gw + u..(v + j) * gw + u + cw]);
                }
                map[v * span + u] = ncc(coarse, &cell);
            }
        }
        local_maxima(&map, span, MIN_PEAK_NCC)
    }

    /// The best full-resolution position within a coarse cell of `(px, py)`, refined to a
    /// sub-pixel centre by a parabola through its neighbours; `None` when no position there
    /// can be compared.
    fn refine(
        &self,
        frame: &RgbImage,
        (px, py): (i64, i64),
        s: usize,
        scratch: &mut TemplateScratch,
    ) -> Option<Match> {
        let reach = s as i64;
        let side = 2 * s + 1;
        let mut block = vec![0.0; side * side];
        self.ncc_block(frame, (px, py), s, scratch, &mut block);
        let mut best = (f64::NEG_INFINITY, px, py);
        for (k, &v) in block.iter().enumerate() {
            if v > best.0 {
                best = (
                    v,
                    px + (k % side) as i64 - reach,
                    py + (k / side) as i64 - reach,
                );
            }
        }
        let (v, bx, by) = best;
        if !v.is_finite() {
            return None;
        }
        let mut at = |x: i64, y: i64| {
            let (u, w) = (x - px + reach, y - py + reach);
            if (0..side as i64).contains(&u) && (0..side as i64).contains(&w) {
                return block[w as usize * side + u as usize];
            }
            let patch = &mut scratch.patch;
            patch_at(frame, (x, y), self.width, self.height, patch);
            let quick = self.quick_sums(patch).map(|template| Quick { template });
            ncc_in(&self.values, self.width, patch, self.width, quick)
        };
        let sub = |l: f64, c: f64, r: f64| {
            let d = l - 2.0 * c + r;
            if d < -1e-12 {
                (0.5 * (l - r) / d).clamp(-0.5, 0.5)
            } else {
                0.0
            }
        };
        let (l, rr) = (at(bx - 1, by), at(bx + 1, by));
        let (u, d) = (at(bx, by - 1), at(bx, by + 1));
        let center = Point2::new(bx as f64 + sub(l, v, rr), by as f64 + sub(u, v, d)) + self.offset;
        Some(Match { center, ncc: v })
    }
}

/// The mean gray level of the `s`x`s` cells of a `gw`x`gh` grid starting at pixel
/// `(gx0, gy0)`; NaN for a cell not entirely inside the frame.
fn gray_cells(
    frame: &RgbImage,
    (gx0, gy0): (i64, i64),
    (gw, gh): (usize, usize),
    s: usize,
) -> Vec<f32> {
    let (fw, fh) = (i64::from(frame.width()), i64::from(frame.height()));
    let raw = frame.as_raw();
    let mut grid = vec![f32::NAN; gw * gh];
    for j in 0..gh {
        for i in 0..gw {
            let (x0, y0) = (gx0 + (i * s) as i64, gy0 + (j * s) as i64);
            if x0 < 0 || y0 < 0 || x0 + s as i64 > fw || y0 + s as i64 > fh {
                continue;
            }
            let mut sum = 0.0f32;
            for y in y0..y0 + s as i64 {
                for x in x0..x0 + s as i64 {
                    let k = ((y * fw + x) * 3) as usize;
                    sum += f32::from(rgb_to_gray([raw[k], raw[k + 1], raw[k + 2]]));
                }
            }
            grid[j * gw + i] = sum / (s * s) as f32;
        }
    }
    grid
}

/// The cells (value, column, row) of a `span`x`span` map that are at least `min` and no
/// smaller than any of their eight neighbours.
fn local_maxima(map: &[f64], span: usize, min: f64) -> Vec<(f64, usize, usize)> {
    let mut out = Vec::new();
    for v in 0..span {
        for u in 0..span {
            let m = map[v * span + u];
            if m < min {
                continue;
            }
            let mut peak = true;
            'n: for dv in -1i64..=1 {
                for du in -1i64..=1 {
                    let (uu, vv) = (u as i64 + du, v as i64 + dv);
                    if (du, dv) == (0, 0)
                        || uu < 0
                        || vv < 0
                        || uu >= span as i64
                        || vv >= span as i64
                    {
                        continue;
                    }
                    if map[vv as usize * span + uu as usize] > m {
                        peak = false;
                        break 'n;
                    }
                }
            }
            if peak {
                out.push((m, u, v));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(offset: u32) -> RgbImage {
        // A bright square with a dark bar on its left at `offset`, and a plain bright square
        // 30 px to the right.
        RgbImage::from_fn(100, 40, |x, y| {
            let in_a = (offset..offset + 8).contains(&x) && (16..24).contains(&y);
            let bar = (offset.saturating_sub(6)..offset.saturating_sub(2)).contains(&x)
                && (10..30).contains(&y);
            let in_b = (offset + 30..offset + 38).contains(&x) && (16..24).contains(&y);
            let v = if in_a || in_b {
                230
            } else if bar {
                20
            } else {
                90
            };
            image::Rgb([v, v, v])
        })
    }

    #[test]
    fn correlation_tells_look_alike_markers_apart_by_their_surroundings() {
        let frame = scene(20);
        let t = Template::learn(&frame, Point2::new(23.5, 19.5), 24, 24);
        let mut s = TemplateScratch::default();
        let own = t.ncc(&frame, Point2::new(23.5, 19.5), &mut s);
        let other = t.ncc(&frame, Point2::new(53.5, 19.5), &mut s);
        assert!((own - 1.0).abs() < 1e-9, "{own}");
        assert!(other < 0.9, "{other}");
        // The same scene shifted: the marker is found where it moved.
        let moved = scene(40);
        assert!((t.ncc(&moved, Point2::new(43.5, 19.5), &mut s) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn search_finds_the_target_coarse_to_fine_with_a_sub_pixel_centre() {
        // A textured 36 px target (its template is searched on a 4x coarser grid).
        let target = |dx: f64, dy: f64| {
            RgbImage::from_fn(200, 120, move |x, y| {
                let (u, v) = (f64::from(x) - 60.0 - dx, f64::from(y) - 50.0 - dy);
                let inside = u.abs() < 18.0 && v.abs() < 18.0;
                let g = if inside {
                    let r2 = u * u + v * v;
                    180.0 + 60.0 * (-r2 / 40.0).exp() - 120.0 * (-(u - 8.0).powi(2) / 20.0).exp()
                } else {
                    // Faint hashed texture.
                    90.0 + f64::from((x * 7 + y * 13) % 11)
                };
                let g = g.clamp(0.0, 255.0) as u8;
                image::Rgb([g, g, g])
            })
        };
        let t = Template::learn(&target(0.0, 0.0), Point2::new(60.0, 50.0), 36, 36);
        assert_eq!(t.scale, 4);
        let mut s = TemplateScratch::default();
        let moved = target(37.4, -12.6);
        let found = t.search(&moved, Point2::new(60.0, 50.0), 60.0, 3, &mut s);
        assert!(!found.is_empty());
        let best = found[0];
        assert!(
            (best.center - Point2::new(97.4, 37.4)).norm() < 0.6,
            "{found:?}"
        );
        assert!(best.ncc > 0.95, "{found:?}");
        // Outside the radius it is not found.
        let near = t.search(&moved, Point2::new(60.0, 50.0), 10.0, 3, &mut s);
        assert!(
            near.iter()
                .all(|m| (m.center - Point2::new(60.0, 50.0)).norm() <= 11.5)
        );
    }

    #[test]
    fn patches_past_the_border_and_flat_patches_are_handled() {
        let frame = scene(20);
        let mut t = Template::learn(&frame, Point2::new(2.0, 2.0), 24, 24);
        let mut s = TemplateScratch::default();
        let v = t.ncc(&frame, Point2::new(2.0, 2.0), &mut s);
        assert!(v.is_finite());
        let flat = RgbImage::from_pixel(100, 40, image::Rgb([50, 50, 50]));
        assert_eq!(t.ncc(&flat, Point2::new(50.0, 20.0), &mut s), 0.0);
        // Far outside: no overlap.
        assert_eq!(t.ncc(&frame, Point2::new(-500.0, -500.0), &mut s), 0.0);
        assert!(
            t.search(&frame, Point2::new(-5000.0, 1e12), 30.0, 2, &mut s)
                .is_empty()
        );
        // Updating from a patch inside fills the unknown pixels.
        t.update(&frame, Point2::new(50.0, 20.0), 0.5, &mut s);
        assert!(t.values.iter().all(|v| !v.is_nan()));
    }

    #[test]
    fn the_quick_correlation_and_the_block_agree_with_one_patch_at_a_time() {
        // A noisy textured frame, a template blended once (non-integer values).
        let frame = RgbImage::from_fn(80, 60, |x, y| {
            let g = ((x * 37 + y * 91 + x * y * 7) % 251) as u8;
            image::Rgb([g, g.wrapping_mul(3), 255 - g])
        });
        let mut t = Template::learn(&frame, Point2::new(40.0, 30.0), 13, 11);
        let mut s = TemplateScratch::default();
        t.update(&frame, Point2::new(41.0, 29.0), 0.3, &mut s);
        assert!(t.sums.is_some());
        // Inside the frame (quick path) and over its corner (slow path, unknown pixels).
        for (cx, cy) in [(40, 30), (3, 2)] {
            let mut block = [0.0; 25];
            t.ncc_block(&frame, (cx, cy), 2, &mut s, &mut block);
            for (k, &b) in block.iter().enumerate() {
                let at = (cx + (k % 5) as i64 - 2, cy + (k / 5) as i64 - 2);
                let mut one = Vec::new();
                patch_at(&frame, at, t.width, t.height, &mut one);
                // The slow path, the order the sums were always taken in.
                let slow = ncc(&t.values, &one);
                assert!((b - slow).abs() < 1e-12, "{at:?}: {b} against {slow}");
                assert_eq!(t.quick_sums(&one).is_some(), cx == 40);
            }
            // Not a flat block, which would prove nothing: the template's own place is in it.
            if cx == 40 {
                assert!(block.iter().any(|&v| v > 0.9), "{block:?}");
            }
        }
    }
}
