//! Candidate blobs of a marker's appearance: the pixels of a weight map (back-projection) at or
//! above a threshold, grouped into 8-connected components, or components of pixels up to a gap
//! apart (two-pass labelling with union–find, Rosenfeld and Pfaltz 1966, over runs of pixels
//! along the rows rather than single pixels). Each blob's weighted centroid is a measurement:
//! for a marker smeared into a streak by motion blur it is the streak's centre.

use nalgebra::Point2;

use crate::rect::PixelRect;

/// One connected component of above-threshold pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Blob {
    /// Pixels in the component.
    pub(crate) pixels: usize,
    /// Sum of their weights.
    pub(crate) mass: f64,
    /// Weighted centroid (image coordinates).
    pub(crate) centroid: Point2<f64>,
    /// Bounding box (image coordinates).
    pub(crate) bounds: PixelRect,
    /// Weighted second central moments `[xx, xy, yy]` (pixels²).
    pub(crate) spread: [f64; 3],
    /// Its label in the labeler's last run (for [`Labeler::split`]).
    label: u32,
}

/// Add pixel `(x, y)` of weight `v` to a blob's sums (count, weight, first and second
/// moments) and bounds (min x, min y, max x, max y).
fn accumulate(s: &mut [f64; 7], b: &mut [i32; 4], x: i32, y: i32, v: f64) {
    let (xf, yf) = (f64::from(x), f64::from(y));
    s[0] += 1.0;
    s[1] += v;
    s[2] += v * xf;
    s[3] += v * yf;
    s[4] += v * xf * xf;
    s[5] += v * xf * yf;
    s[6] += v * yf * yf;
    b[0] = b[0].min(x);
    b[1] = b[1].min(y);
    b[2] = b[2].max(x);
    b[3] = b[3].max(y);
}

impl Blob {
    /// The blob of sums and bounds made by [`accumulate`] (positive weight).
    fn from_sums(s: &[f64; 7], b: &[i32; 4], label: u32) -> Self {
        let (cx, cy) = (s[2] / s[1], s[3] / s[1]);
        Blob {
            pixels: s[0] as usize,
            mass: s[1],
            centroid: Point2::new(cx, cy),
            bounds: PixelRect::new(b[0], b[1], b[2] - b[0] + 1, b[3] - b[1] + 1),
            spread: [
                s[4] / s[1] - cx * cx,
                s[5] / s[1] - cx * cy,
                s[6] / s[1] - cy * cy,
            ],
            label,
        }
    }

    /// The blob's weighted second moments `[xx, xy, yy]` about `c` (not divided by its mass):
    /// its central moments moved there (parallel axes).
    fn moments_about(&self, c: Point2<f64>) -> [f64; 3] {
        let d = self.centroid - c;
        [
            self.mass * (self.spread[0] + d.x * d.x),
            self.mass * (self.spread[1] + d.x * d.y),
            self.mass * (self.spread[2] + d.y * d.y),
        ]
    }

    /// The two blobs as one (pooled moments): the fragments of a marker split by a twig.
    pub(crate) fn merged(&self, other: &Blob) -> Blob {
        let m = self.mass + other.mass;
        if m <= 0.0 {
            return *self;
        }
        let c = Point2::from(
            (self.centroid.coords * self.mass + other.centroid.coords * other.mass) / m,
        );
        let (a, b) = (self.moments_about(c), other.moments_about(c));
        let (x0, y0) = (
            self.bounds.x.min(other.bounds.x),
            self.bounds.y.min(other.bounds.y),
        );
        let x1 = self.bounds.right().max(other.bounds.right()) as i32;
        let y1 = self.bounds.bottom().max(other.bounds.bottom()) as i32;
        Blob {
            pixels: self.pixels + other.pixels,
            mass: m,
            centroid: c,
            bounds: PixelRect::new(x0, y0, x1 - x0, y1 - y0),
            spread: [(a[0] + b[0]) / m, (a[1] + b[1]) / m, (a[2] + b[2]) / m],
            label: self.label,
        }
    }

    /// The blob without `part`, a part of its pixels (as [`Labeler::opened`] gives): the
    /// rest's count, mass, centroid and moments (bounds: the whole blob's). `None` when
    /// nothing of weight is left.
    pub(crate) fn without(&self, part: &Blob) -> Option<Blob> {
        let m = self.mass - part.mass;
        let pixels = self.pixels.checked_sub(part.pixels)?;
        if pixels == 0 || m <= 1e-9 * self.mass {
            return None;
        }
        let c =
            Point2::from((self.centroid.coords * self.mass - part.centroid.coords * part.mass) / m);
        // Second moments about the rest's centroid: the whole's less the part's.
        let (a, b) = (self.moments_about(c), part.moments_about(c));
        Some(Blob {
            pixels,
            mass: m,
            centroid: c,
            bounds: self.bounds,
            spread: [
                ((a[0] - b[0]) / m).max(0.0),
                (a[1] - b[1]) / m,
                ((a[2] - b[2]) / m).max(0.0),
            ],
            label: self.label,
        })
    }

    /// Length of the blob's major axis, four standard deviations (pixels): a disc of diameter
    /// `d` gives `d`, a streak its length.
    pub(crate) fn length_px(&self) -> f64 {
        let [a, b, c] = self.spread;
        let half = 0.5 * (a + c);
        let root = (0.25 * (a - c) * (a - c) + b * b).sqrt();
        4.0 * (half + root).max(0.0).sqrt()
    }

    /// Length of the minor axis, four standard deviations (pixels).
    pub(crate) fn width_px(&self) -> f64 {
        let [a, b, c] = self.spread;
        let half = 0.5 * (a + c);
        let root = (0.25 * (a - c) * (a - c) + b * b).sqrt();
        4.0 * (half - root).max(0.0).sqrt()
    }
}

/// Scratch of the labelling, kept between calls so that no call allocates once warm.
#[derive(Debug, Default, Clone)]
pub(crate) struct Labeler {
    /// The area labelled in the last run (image coordinates).
    area: PixelRect,
    /// Per pixel of the area (row-major, its width), the label of its run; `NONE` off runs.
    labels: Vec<u32>,
    /// The foreground of the row being labelled, a bit per pixel.
    bits: Vec<u64>,
    parent: Vec<u32>,
    sums: Vec<[f64; 7]>,
    bounds: Vec<[i32; 4]>,
    /// The runs of foreground of the last run, row by row, and where each row's begin.
    runs: Vec<Run>,
    row_runs: Vec<usize>,
    cursors: Vec<usize>,
    /// A blob's pixels in its box, and the box eroded (scratch of [`Labeler::opened`]).
    mask: Vec<u8>,
    eroded: Vec<u8>,
    opened: Vec<u8>,
    rows: Vec<u8>,
}

/// Foreground pixels `x0..x1` of a row, and the label they were given.
#[derive(Debug, Clone, Copy)]
struct Run {
    x0: usize,
    x1: usize,
    label: u32,
}

const NONE: u32 = u32::MAX;

/// The first pixel at or after `from` whose bit in `bits` is `set` (a row's foreground, a
/// bit per pixel, 0 past the row's end), or `w`, the row's length.
fn next_bit(bits: &[u64], from: usize, w: usize, set: bool) -> usize {
    let word = |k: usize| if set { bits[k] } else { !bits[k] };
    let mut k = from / 64;
    if k >= bits.len() {
        return w;
    }
    let mut m = word(k) & (!0u64 << (from % 64));
    loop {
        if m != 0 {
            return (k * 64 + m.trailing_zeros() as usize).min(w);
        }
        k += 1;
        if k >= bits.len() {
            return w;
        }
        m = word(k);
    }
}

/// Whether a weight counts as foreground: at or above the threshold, or NaN (not known to be
/// below it).
fn is_foreground(v: f32, threshold: f32) -> bool {
    v.partial_cmp(&threshold) != Some(std::cmp::Ordering::Less)
}

fn find(parent: &mut [u32], mut a: u32) -> u32 {
    // Path halving; the loop ends because parents point to smaller or equal labels.
    while parent[a as usize] != a {
        let p = parent[a as usize];
        parent[a as usize] = parent[p as usize];
        a = p;
    }
    a
}

/// Erosion (`all`) or dilation of the 0/1 image `src` (`w` x `h`, row-major) by a square of
/// side `2 * k + 1`, into `dst`, with `rows` as scratch: a pixel is set when every (erosion)
/// or some (dilation) pixel of the square about it is; for erosion, pixels off the image
/// count as set when `outside_set`, else as unset. Separable (along the rows, then along the
/// columns), each pass a running count of the set pixels under the square's side.
fn square_filter(
    src: &[u8],
    dst: &mut Vec<u8>,
    rows: &mut Vec<u8>,
    (w, h): (usize, usize),
    k: usize,
    (all, outside_set): (bool, bool),
) {
    let off = usize::from(all && outside_set);
    rows.clear();
    rows.resize(w * h, 0);
    for y in 0..h {
        line_filter(src, (y * w, 1, w), rows, y * w, k, (all, off));
    }
    dst.clear();
    dst.resize(w * h, 0);
    for x in 0..w {
        line_filter(rows, (x, w, h), dst, x, k, (all, off));
    }
}

/// One pass of [`square_filter`] along a line of `n` pixels of `src` from `start`, `stride`
/// apart, into the same places of `dst` from `dst_start`: a running count of the set pixels
/// within `k` of each, pixels off the line counting `off` (0 or 1).
fn line_filter(
    src: &[u8],
    (start, stride, n): (usize, usize, usize),
    dst: &mut [u8],
    dst_start: usize,
    k: usize,
    (all, off): (bool, usize),
) {
    let at = |j: isize| {
        if j < 0 || j as usize >= n {
            off
        } else {
            usize::from(src[start + j as usize * stride])
        }
    };
    let k = k as isize;
    let mut count: usize = (-k..=k).map(at).sum();
    for i in 0..n as isize {
        if i > 0 {
            count = count + at(i + k) - at(i - k - 1);
        }
        let set = if all {
            count as isize == 2 * k + 1
        } else {
            count > 0
        };
        dst[dst_start + i as usize * stride] = u8::from(set);
    }
}

fn union(parent: &mut [u32], a: u32, b: u32) -> u32 {
    let (ra, rb) = (find(parent, a), find(parent, b));
    let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
    parent[hi as usize] = lo;
    lo
}

impl Labeler {
    /// The components of `weights` (row-major over `rect`) at or above `threshold` whose
    /// pixels lie inside `within` (image coordinates), with at least `min_pixels` pixels,
    /// heaviest first. Pixels up to `gap` pixels apart (Chebyshev distance; 1 is plain
    /// 8-connectivity) belong to one component: a marker in a projection image is a cluster
    /// of splats with holes between them.
    pub(crate) fn blobs(
        &mut self,
        weights: &[f32],
        rect: PixelRect,
        within: PixelRect,
        threshold: f32,
        min_pixels: usize,
        gap: usize,
    ) -> Vec<Blob> {
        let area = within.intersect(&rect);
        if area.is_empty() || weights.len() != rect.area() as usize {
            return Vec::new();
        }
        // The labels hold `NONE` everywhere but on the last run's runs: those are cleared,
        // not the whole buffer (most of a gate is background).
        let last_w = self.area.width as usize;
        for (y, &start) in self.row_runs.iter().enumerate() {
            let end = self.row_runs.get(y + 1).copied().unwrap_or(self.runs.len());
            for r in &self.runs[start..end] {
                self.labels[y * last_w + r.x0..y * last_w + r.x1].fill(NONE);
            }
        }
        self.area = area;
        let (w, h) = (area.width as usize, area.height as usize);
        let stride = rect.width as usize;
        let offset = (area.y - rect.y) as usize * stride + (area.x - rect.x) as usize;
        let at = |x: usize, y: usize| weights[offset + y * stride + x];
        if self.labels.len() < w * h {
            self.labels.resize(w * h, NONE);
        }
        self.parent.clear();
        self.runs.clear();
        self.row_runs.clear();
        let g = gap.max(1);
        // Runs of foreground along each row, each joined to the run before it in the row
        // when at most `g` pixels apart, and to the runs of the `g` rows above whose pixels
        // come within `g` columns of its own: the components of pixels at most `g` apart, as
        // pixel by pixel, with far fewer lookups. A component's first label is made by its
        // first run in raster order, and a union keeps the smaller label, so a component's
        // root is its first label, in raster order of components as pixel by pixel.
        self.label_runs(weights, offset, stride, (w, h), threshold, g);
        let n = self.parent.len();
        self.sums.clear();
        self.sums.resize(n, [0.0; 7]);
        self.bounds.clear();
        self.bounds
            .resize(n, [i32::MAX, i32::MAX, i32::MIN, i32::MIN]);
        // Run by run in raster order: every pixel in the order a pixel-by-pixel pass takes.
        for (y, rows) in self.row_runs.iter().enumerate() {
            let end = self.row_runs.get(y + 1).copied().unwrap_or(self.runs.len());
            for r in &self.runs[*rows..end] {
                let root = find(&mut self.parent, r.label) as usize;
                for x in r.x0..r.x1 {
                    let v = f64::from(at(x, y));
                    let (xi, yi) = (area.x + x as i32, area.y + y as i32);
                    accumulate(&mut self.sums[root], &mut self.bounds[root], xi, yi, v);
                }
            }
        }
        let mut out = Vec::new();
        for (root, (s, b)) in self.sums.iter().zip(&self.bounds).enumerate() {
            if self.parent[root] != root as u32
                || (s[0] as usize) < min_pixels.max(1)
                || s[1] <= 0.0
            {
                continue;
            }
            out.push(Blob::from_sums(s, b, root as u32));
        }
        out.sort_by(|a, b| b.mass.total_cmp(&a.mass));
        out
    }

    /// The labelling pass of [`Labeler::blobs`] over the `w x h` area at `offset` of
    /// `weights` (row stride `stride`): runs, labels and the foreground, row by row.
    fn label_runs(
        &mut self,
        weights: &[f32],
        offset: usize,
        stride: usize,
        (w, h): (usize, usize),
        threshold: f32,
        g: usize,
    ) {
        // Per row above within the gap, the first run that can still touch a run of this row
        // (kept in the labeler, so that a warm call does not allocate).
        let mut cursors = std::mem::take(&mut self.cursors);
        cursors.clear();
        cursors.resize(g.min(h), 0);
        for y in 0..h {
            let row_start = self.runs.len();
            self.row_runs.push(row_start);
            for (dy, c) in cursors.iter_mut().enumerate() {
                *c = if y > dy { self.row_runs[y - dy - 1] } else { 0 };
            }
            let row = &weights[offset + y * stride..offset + y * stride + w];
            // The row's foreground as bits (a branch-free test per pixel, which vectorises),
            // then its runs found a word at a time: most of a gate is background.
            self.bits.clear();
            self.bits.extend(row.chunks(64).map(|chunk| {
                chunk.iter().enumerate().fold(0u64, |m, (i, &v)| {
                    m | (u64::from(is_foreground(v, threshold)) << i)
                })
            }));
            let mut x = next_bit(&self.bits, 0, w, true);
            while x < w {
                let x0 = x;
                let x1 = next_bit(&self.bits, x0, w, false);
                x = next_bit(&self.bits, x1, w, true);
                let mut label = NONE;
                let parent = &mut self.parent;
                let mut join = |l: u32| {
                    label = if label == NONE {
                        find(parent, l)
                    } else {
                        union(parent, label, l)
                    };
                };
                if let Some(last) = self.runs[row_start..].last()
                    && x0 - (last.x1 - 1) <= g
                {
                    join(last.label);
                }
                for (dy, cursor) in cursors.iter_mut().enumerate() {
                    if y <= dy {
                        break;
                    }
                    let end = self.row_runs[y - dy];
                    // Runs ending more than `g` left of this run are behind every later run
                    // of this row too.
                    while *cursor < end && self.runs[*cursor].x1 - 1 + g < x0 {
                        *cursor += 1;
                    }
                    for r in &self.runs[*cursor..end] {
                        if r.x0 > x1 - 1 + g {
                            break;
                        }
                        join(r.label);
                    }
                }
                if label == NONE {
                    label = self.parent.len() as u32;
                    self.parent.push(label);
                }
                self.runs.push(Run { x0, x1, label });
                self.labels[y * w + x0..y * w + x1].fill(label);
            }
        }
        self.cursors = cursors;
    }

    /// The centroid of `blob` (from the last [`Labeler::blobs`] run on the same `weights` and
    /// `rect`) over every weight in its box grown by a pixel and in `window` that belongs to
    /// it, to no component, or to a piece of fewer than `pieces` pixels: the pixels just under
    /// the threshold at its edge and the small pieces around it count too, which steadies
    /// the centre of a marker whose outline flickers and breaks up (a splatted projection
    /// image). The blob's own centroid if there is nothing to weigh.
    pub(crate) fn edge_centroid(
        &mut self,
        weights: &[f32],
        rect: PixelRect,
        blob: &Blob,
        window: PixelRect,
        pieces: usize,
    ) -> Point2<f64> {
        let area = self.area;
        let b = blob.bounds.grown(1, 1);
        let (x0, y0) = (b.x.min(window.x), b.y.min(window.y));
        let x1 = b.right().max(window.right()) as i32;
        let y1 = b.bottom().max(window.bottom()) as i32;
        let box_ = PixelRect::new(x0, y0, x1 - x0, y1 - y0).intersect(&area);
        if box_.is_empty() || weights.len() != rect.area() as usize {
            return blob.centroid;
        }
        let stride = rect.width as usize;
        let w = area.width as usize;
        let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
        for y in box_.y..box_.bottom() as i32 {
            for x in box_.x..box_.right() as i32 {
                let in_blob_box =
                    x >= b.x && y >= b.y && i64::from(x) < b.right() && i64::from(y) < b.bottom();
                let in_window = x >= window.x
                    && y >= window.y
                    && i64::from(x) < window.right()
                    && i64::from(y) < window.bottom();
                let l = self.labels[(y - area.y) as usize * w + (x - area.x) as usize];
                let keep = if l == NONE {
                    in_blob_box
                } else {
                    let root = find(&mut self.parent, l);
                    root == blob.label
                        || (in_window && (self.sums[root as usize][0] as usize) < pieces)
                };
                if !keep {
                    continue;
                }
                let v = f64::from(weights[(y - rect.y) as usize * stride + (x - rect.x) as usize]);
                sw += v;
                sx += v * f64::from(x);
                sy += v * f64::from(y);
            }
        }
        if sw <= 0.0 {
            return blob.centroid;
        }
        Point2::new(sx / sw, sy / sw)
    }

    /// The part of `blob` (from the last [`Labeler::blobs`] run on the same `weights` and
    /// `rect`) that a square of side `2 * k + 1` fits in (its morphological opening): the
    /// blob without the lines thinner than the square that run out of it, such as a twig
    /// of its colour that a marker hangs from. `None` when nothing of it is left.
    pub(crate) fn opened(
        &mut self,
        weights: &[f32],
        rect: PixelRect,
        blob: &Blob,
        k: usize,
    ) -> Option<Blob> {
        let area = self.area;
        let box_ = blob.bounds.intersect(&area);
        if box_.is_empty() || weights.len() != rect.area() as usize || k == 0 {
            return None;
        }
        let (bw, bh) = (box_.width as usize, box_.height as usize);
        let w = area.width as usize;
        let mut mask = std::mem::take(&mut self.mask);
        mask.clear();
        for y in box_.y..box_.bottom() as i32 {
            for x in box_.x..box_.right() as i32 {
                let l = self.labels[(y - area.y) as usize * w + (x - area.x) as usize];
                mask.push(u8::from(
                    l != NONE && find(&mut self.parent, l) == blob.label,
                ));
            }
        }
        // Holes of up to two pixels closed first (a 3x3 square's dilation, then its
        // erosion with off-box pixels counting as set), so that the blob's holes (pixels with
        // no data in a registered colour image) do not open it up; then erosion by the
        // square (every pixel within `k` along both axes set; none off the box is), then
        // dilation of that by the square, kept to the blob's own pixels.
        let mut eroded = std::mem::take(&mut self.eroded);
        let mut opened = std::mem::take(&mut self.opened);
        let mut rows = std::mem::take(&mut self.rows);
        square_filter(&mask, &mut opened, &mut rows, (bw, bh), 1, (false, false));
        square_filter(&opened, &mut eroded, &mut rows, (bw, bh), 1, (true, true));
        std::mem::swap(&mut opened, &mut eroded);
        square_filter(&opened, &mut eroded, &mut rows, (bw, bh), k, (true, false));
        square_filter(&eroded, &mut opened, &mut rows, (bw, bh), k, (false, false));
        self.rows = rows;
        let stride = rect.width as usize;
        let mut sums = [0.0f64; 7];
        let mut bounds = [i32::MAX, i32::MAX, i32::MIN, i32::MIN];
        for y in 0..bh {
            for x in 0..bw {
                if opened[y * bw + x] == 1 && mask[y * bw + x] == 1 {
                    let (ix, iy) = (box_.x + x as i32, box_.y + y as i32);
                    let v = f64::from(
                        weights[(iy - rect.y) as usize * stride + (ix - rect.x) as usize],
                    );
                    accumulate(&mut sums, &mut bounds, ix, iy, v);
                }
            }
        }
        self.mask = mask;
        self.eroded = eroded;
        self.opened = opened;
        (sums[1] > 0.0).then(|| Blob::from_sums(&sums, &bounds, blob.label))
    }

    /// Share the pixels of `blob` (from the last [`Labeler::blobs`] run on the same
    /// `weights` and `rect`) among `centres` by weighted 2-means (Lloyd's iterations started
    /// at the centres): two markers of one colour that touch or overlap make one blob, and
    /// each gets the part nearer to it. One part per centre, possibly empty (no pixels).
    pub(crate) fn split(
        &mut self,
        weights: &[f32],
        rect: PixelRect,
        blob: &Blob,
        centres: &[Point2<f64>],
    ) -> Vec<Blob> {
        /// Lloyd's iterations; a few settle two discs.
        const ROUNDS: usize = 4;
        let area = self.area;
        let box_ = blob.bounds.intersect(&area);
        let mut means: Vec<Point2<f64>> = centres.to_vec();
        let mut parts = vec![[0.0f64; 7]; centres.len()];
        let mut bounds = vec![[i32::MAX, i32::MAX, i32::MIN, i32::MIN]; centres.len()];
        if box_.is_empty() || centres.is_empty() || weights.len() != rect.area() as usize {
            return Vec::new();
        }
        let stride = rect.width as usize;
        let w = area.width as usize;
        for round in 0..ROUNDS {
            parts.iter_mut().for_each(|p| *p = [0.0; 7]);
            bounds
                .iter_mut()
                .for_each(|b| *b = [i32::MAX, i32::MAX, i32::MIN, i32::MIN]);
            for y in box_.y..box_.bottom() as i32 {
                for x in box_.x..box_.right() as i32 {
                    let l = self.labels[(y - area.y) as usize * w + (x - area.x) as usize];
                    if l == NONE || find(&mut self.parent, l) != blob.label {
                        continue;
                    }
                    let v =
                        f64::from(weights[(y - rect.y) as usize * stride + (x - rect.x) as usize]);
                    let p = Point2::new(f64::from(x), f64::from(y));
                    let k = means
                        .iter()
                        .enumerate()
                        .min_by(|a, b| {
                            (a.1 - p)
                                .norm_squared()
                                .total_cmp(&(b.1 - p).norm_squared())
                        })
                        .map_or(0, |(k, _)| k);
                    accumulate(&mut parts[k], &mut bounds[k], x, y, v);
                }
            }
            if round + 1 < ROUNDS {
                for (m, s) in means.iter_mut().zip(&parts) {
                    if s[1] > 0.0 {
                        *m = Point2::new(s[2] / s[1], s[3] / s[1]);
                    }
                }
            }
        }
        parts
            .iter()
            .zip(&bounds)
            .map(|(s, b)| {
                if s[1] <= 0.0 {
                    return Blob {
                        pixels: 0,
                        mass: 0.0,
                        centroid: blob.centroid,
                        bounds: PixelRect::default(),
                        spread: [0.0; 3],
                        label: blob.label,
                    };
                }
                Blob::from_sums(s, b, blob.label)
            })
            .collect()
    }

    /// The part of `blob` (from the last [`Labeler::blobs`] run on the same `weights` and
    /// `rect`) under a disc of `radius_px`, placed by mean-shift with a flat disc kernel from
    /// `start`: the disc moves to the weighted centroid of the blob's pixels within it until it
    /// settles. Two markers of one look that touch or overlap make one blob, the union of
    /// their discs, and each disc's centre is a fixed point of this (its disc holds its own
    /// pixels, all of them): from a start near one marker, the part is that marker whole,
    /// with no need to know where the other is (as [`Labeler::split`] does). From outward of
    /// the marker one step comes back; toward the other disc each step keeps the share of
    /// the offset that the other covers of the rim ahead (about 0.9 for discs overlapping by
    /// a third), so the disc stops short of the centre by up to a pixel or two, at a place
    /// where its rim's pixels balance, or where it started when the two overlap by more
    /// than half (there the blob barely tells where the nearer one is). `None` when the disc
    /// holds none of the blob's pixels.
    pub(crate) fn disc_part(
        &mut self,
        weights: &[f32],
        rect: PixelRect,
        blob: &Blob,
        start: Point2<f64>,
        radius_px: f64,
    ) -> Option<Blob> {
        /// Most rounds (each moves the disc at least [`SETTLED_PX`], or is the last).
        const ROUNDS: usize = 24;
        const SETTLED_PX: f64 = 0.02;
        let area = self.area;
        if weights.len() != rect.area() as usize
            || !(radius_px.is_finite()
                && radius_px > 0.0
                && start.x.is_finite()
                && start.y.is_finite())
        {
            return None;
        }
        let stride = rect.width as usize;
        let w = area.width as usize;
        let r2 = radius_px * radius_px;
        let reach = radius_px.ceil() as i32 + 1;
        let mut c = start;
        for round in 0..ROUNDS {
            let disc = PixelRect::new(
                c.x.floor() as i32 - reach,
                c.y.floor() as i32 - reach,
                2 * reach + 1,
                2 * reach + 1,
            );
            let box_ = blob.bounds.intersect(&area).intersect(&disc);
            let mut sums = [0.0f64; 7];
            let mut bounds = [i32::MAX, i32::MAX, i32::MIN, i32::MIN];
            for y in box_.y..box_.bottom() as i32 {
                let dy = f64::from(y) - c.y;
                for x in box_.x..box_.right() as i32 {
                    let dx = f64::from(x) - c.x;
                    if dx * dx + dy * dy > r2 {
                        continue;
                    }
                    let l = self.labels[(y - area.y) as usize * w + (x - area.x) as usize];
                    if l == NONE || find(&mut self.parent, l) != blob.label {
                        continue;
                    }
                    let v =
                        f64::from(weights[(y - rect.y) as usize * stride + (x - rect.x) as usize]);
                    accumulate(&mut sums, &mut bounds, x, y, v);
                }
            }
            if sums[1] <= 0.0 {
                return None;
            }
            let part = Blob::from_sums(&sums, &bounds, blob.label);
            let step = part.centroid - c;
            if step.norm() < SETTLED_PX || round + 1 == ROUNDS {
                return Some(part);
            }
            c = part.centroid;
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_components_with_their_centroids_and_shapes() {
        let rect = PixelRect::new(10, 20, 40, 20);
        let mut weights = vec![0.0f32; 800];
        let mut put = |x: i32, y: i32, v: f32| {
            weights[((y - 20) * 40 + (x - 10)) as usize] = v;
        };
        // A 4x4 square at (12..16, 22..26), a diagonal streak of 10 pixels, a single pixel.
        for y in 22..26 {
            for x in 12..16 {
                put(x, y, 200.0);
            }
        }
        for k in 0..10 {
            put(25 + k, 25 + k / 2, 100.0);
        }
        put(45, 38, 255.0);
        let mut l = Labeler::default();
        let blobs = l.blobs(&weights, rect, rect, 50.0, 2, 1);
        assert_eq!(blobs.len(), 2, "{blobs:?}");
        let square = blobs[0];
        assert_eq!(square.pixels, 16);
        assert!((square.centroid - Point2::new(13.5, 23.5)).norm() < 1e-9);
        assert_eq!(square.bounds, PixelRect::new(12, 22, 4, 4));
        let streak = blobs[1];
        assert_eq!(streak.pixels, 10);
        assert!(streak.length_px() > 3.0 * streak.width_px(), "{streak:?}");
        // Restricted to a part of the region.
        let part = l.blobs(&weights, rect, PixelRect::new(10, 20, 10, 10), 50.0, 1, 1);
        assert_eq!(part.len(), 1);
        assert_eq!(part[0].pixels, 16);
        // Merging pools the moments: two halves make the whole square.
        let halves = l.blobs(&weights, rect, PixelRect::new(10, 20, 4, 10), 50.0, 1, 1)[0]
            .merged(&l.blobs(&weights, rect, PixelRect::new(14, 20, 6, 10), 50.0, 1, 1)[0]);
        assert!((halves.centroid - square.centroid).norm() < 1e-9);
        assert!((halves.spread[0] - square.spread[0]).abs() < 1e-9);
        assert_eq!(halves.bounds, square.bounds);
        // Two touching squares make one blob; split by their centres, each gets its own.
        let mut two = vec![0.0f32; 200];
        for y in 2..8 {
            for x in 2..14 {
                two[y * 20 + x] = 1.0;
            }
        }
        let r2 = PixelRect::new(0, 0, 20, 10);
        let one = l.blobs(&two, r2, r2, 0.5, 1, 1);
        assert_eq!(one.len(), 1);
        let parts = l.split(
            &two,
            r2,
            &one[0],
            &[Point2::new(4.0, 5.0), Point2::new(12.0, 4.0)],
        );
        assert!(
            (parts[0].centroid - Point2::new(4.5, 4.5)).norm() < 1e-9,
            "{parts:?}"
        );
        assert!(
            (parts[1].centroid - Point2::new(10.5, 4.5)).norm() < 1e-9,
            "{parts:?}"
        );
        assert_eq!(parts[0].pixels + parts[1].pixels, 72);
        // A U shape is one component (labels merged from both arms).
        let mut u = vec![0.0f32; 100];
        for y in 0..10 {
            u[y * 10 + 2] = 1.0;
            u[y * 10 + 7] = 1.0;
        }
        for x in 2..8 {
            u[90 + x] = 1.0;
        }
        let r = PixelRect::new(0, 0, 10, 10);
        assert_eq!(l.blobs(&u, r, r, 0.5, 1, 1).len(), 1);
        assert!(
            l.blobs(&u, r, PixelRect::new(50, 50, 3, 3), 0.5, 1, 1)
                .is_empty()
        );
        // Two squares 2 px apart are one blob with a gap of 2, two with plain connectivity.
        let mut pair = vec![0.0f32; 100];
        for y in 3..6 {
            for x in [1usize, 2, 3, 6, 7, 8] {
                pair[y * 10 + x] = 1.0;
            }
        }
        assert_eq!(l.blobs(&pair, r, r, 0.5, 1, 1).len(), 2);
        assert_eq!(l.blobs(&pair, r, r, 0.5, 1, 3).len(), 1);
    }

    /// Components by breadth-first search (pixels at or above `threshold`, Chebyshev
    /// distance up to `gap`), as `(pixels, mass)` sorted by mass, for the labelling to be
    /// checked against.
    fn components(
        weights: &[f32],
        w: usize,
        h: usize,
        threshold: f32,
        gap: usize,
    ) -> Vec<(usize, f64)> {
        let on = |k: usize| weights[k] >= threshold || weights[k].is_nan();
        let mut seen = vec![false; w * h];
        let mut out = Vec::new();
        for start in 0..w * h {
            if seen[start] || !on(start) {
                continue;
            }
            seen[start] = true;
            let (mut queue, mut pixels, mut mass) = (vec![start], 0, 0.0);
            while let Some(k) = queue.pop() {
                pixels += 1;
                mass += f64::from(weights[k]);
                let (x, y) = ((k % w) as i64, (k / w) as i64);
                let g = gap as i64;
                for yy in (y - g).max(0)..(y + g + 1).min(h as i64) {
                    for xx in (x - g).max(0)..(x + g + 1).min(w as i64) {
                        let n = yy as usize * w + xx as usize;
                        if !seen[n] && on(n) {
                            seen[n] = true;
                            queue.push(n);
                        }
                    }
                }
            }
            out.push((pixels, mass));
        }
        out.sort_by(|a, b| b.1.total_cmp(&a.1));
        out
    }

    #[test]
    fn square_filters_equal_a_pixel_by_pixel_check_on_random_masks() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let (mut out, mut rows) = (Vec::new(), Vec::new());
        for _ in 0..40 {
            let (w, h) = (1 + (next() % 23) as usize, 1 + (next() % 17) as usize);
            let src: Vec<u8> = (0..w * h).map(|_| u8::from(next() % 3 != 0)).collect();
            for k in 1..=3usize {
                for mode in [(true, true), (true, false), (false, false)] {
                    square_filter(&src, &mut out, &mut rows, (w, h), k, mode);
                    for y in 0..h {
                        for x in 0..w {
                            let (mut all, mut any) = (true, false);
                            for dy in -(k as isize)..=k as isize {
                                for dx in -(k as isize)..=k as isize {
                                    let (xx, yy) = (x as isize + dx, y as isize + dy);
                                    let v =
                                        if xx < 0 || yy < 0 || xx >= w as isize || yy >= h as isize
                                        {
                                            mode.1
                                        } else {
                                            src[yy as usize * w + xx as usize] == 1
                                        };
                                    all &= v;
                                    any |= v;
                                }
                            }
                            let want = if mode.0 { all } else { any };
                            assert_eq!(
                                out[y * w + x] == 1,
                                want,
                                "{w}x{h} k {k} {mode:?} at {x},{y}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn opening_drops_a_thin_tail_and_keeps_discs_and_streaks_whole() {
        // A disc of radius 7 px with a twig 2 px wide and 24 px long running out of it, a
        // streak 14 px wide and 40 long, a disc alone, and a disc with a hole in it.
        let rect = PixelRect::new(0, 0, 160, 60);
        let disc = Point2::new(20.0, 20.0);
        let alone = Point2::new(130.0, 20.0);
        let holed = Point2::new(130.0, 45.0);
        let mut weights = vec![0.0f32; rect.area() as usize];
        for y in 0..60 {
            for x in 0..160 {
                let p = Point2::new(f64::from(x), f64::from(y));
                let twig = (26..50).contains(&x) && (19..21).contains(&y);
                let streak = (60..100).contains(&x) && (13..27).contains(&y);
                let hole = x == 131 && y == 45;
                if ((p - disc).norm() <= 7.0 || twig || streak || (p - alone).norm() <= 7.0)
                    || ((p - holed).norm() <= 7.0 && !hole)
                {
                    weights[(y * 160 + x) as usize] = 200.0;
                }
            }
        }
        let mut l = Labeler::default();
        let blobs = l.blobs(&weights, rect, rect, 50.0, 2, 1);
        assert_eq!(blobs.len(), 4, "{blobs:?}");
        let near = |c: Point2<f64>| {
            *blobs
                .iter()
                .min_by(|a, b| (a.centroid - c).norm().total_cmp(&(b.centroid - c).norm()))
                .unwrap()
        };
        let tailed = near(disc);
        assert!((tailed.centroid - disc).norm() > 4.0, "{tailed:?}");
        let part = l.opened(&weights, rect, &tailed, 2).unwrap();
        assert!((part.centroid - disc).norm() < 0.3, "{part:?}");
        assert!(part.pixels < tailed.pixels && part.pixels > 140, "{part:?}");
        // A streak, a disc and a disc with a hole keep their centres (the hole's disc within a
        // few hundredths of a pixel of its centre less the hole).
        for (c, tolerance) in [(Point2::new(79.5, 19.5), 1e-9), (alone, 1e-9), (holed, 0.1)] {
            let b = near(c);
            let part = l.opened(&weights, rect, &b, 2).unwrap();
            assert!(
                (part.centroid - b.centroid).norm() < tolerance,
                "{b:?} {part:?}"
            );
        }
        // No square, no part.
        assert!(l.opened(&weights, rect, &tailed, 0).is_none());
    }

    #[test]
    fn a_disc_in_a_blob_of_two_overlapping_discs_settles_on_either_whole_disc() {
        // Two discs of radius 7 px whose centres are 10 px apart make one blob, whose
        // centroid lies between them; the disc kernel's parts are the discs themselves.
        let rect = PixelRect::new(0, 0, 48, 40);
        let (a, b) = (Point2::new(18.0, 20.0), Point2::new(26.0, 14.0));
        let radius = 7.0;
        let mut weights = vec![0.0f32; rect.area() as usize];
        for y in 0..40 {
            for x in 0..48 {
                let p = Point2::new(f64::from(x), f64::from(y));
                if (p - a).norm() <= radius || (p - b).norm() <= radius {
                    weights[(y * 48 + x) as usize] = 200.0;
                }
            }
        }
        let mut l = Labeler::default();
        let blobs = l.blobs(&weights, rect, rect, 50.0, 2, 1);
        assert_eq!(blobs.len(), 1, "{blobs:?}");
        let between = (blobs[0].centroid - a).norm();
        assert!(
            between > 3.0,
            "the blob's centroid lies {between} px from a"
        );
        // From outward of either disc, back onto it; from a start toward the other disc, the
        // pull back is weaker but the disc does not slide onto the other.
        for (centre, start, within) in [
            (a, Point2::new(16.4, 21.2), 0.3),
            (b, Point2::new(27.6, 12.8), 0.3),
            (a, Point2::new(19.2, 19.1), 1.5),
            (b, Point2::new(24.8, 14.9), 1.5),
        ] {
            let part = l
                .disc_part(&weights, rect, &blobs[0], start, radius)
                .unwrap();
            let off = (part.centroid - centre).norm();
            assert!(
                off < within,
                "disc from {start:?}: {:?}, {off} px off",
                part.centroid
            );
            // The whole disc, every pixel of it: about pi r^2.
            let disc_pixels = std::f64::consts::PI * radius * radius;
            assert!(
                (part.pixels as f64 - disc_pixels).abs() < 0.1 * disc_pixels,
                "{part:?}"
            );
        }
        // Nothing of the blob under the disc, or a radius that is no radius: no part.
        assert!(
            l.disc_part(&weights, rect, &blobs[0], Point2::new(45.0, 37.0), 2.0)
                .is_none()
        );
        assert!(
            l.disc_part(&weights, rect, &blobs[0], a, f64::NAN)
                .is_none()
        );
        assert!(l.disc_part(&weights, rect, &blobs[0], a, 0.0).is_none());
    }

    #[test]
    fn labelling_of_random_fields_equals_a_breadth_first_search() {
        // Random fields from nearly empty to nearly full, where runs of foreground join
        // components through the rows above in every way (U shapes, diagonals, gaps).
        let (w, h) = (70usize, 40usize);
        let rect = PixelRect::new(2, -4, w as i32, h as i32);
        let mut rng = crate::rng::Rng::new(17);
        let mut l = Labeler::default();
        for density in [0.05, 0.2, 0.4, 0.6, 0.9] {
            let weights: Vec<f32> = (0..w * h)
                .map(|_| {
                    if rng.uniform() < density {
                        50.0 + 100.0 * rng.uniform() as f32
                    } else {
                        10.0
                    }
                })
                .collect();
            for gap in 1..=4 {
                let found = l.blobs(&weights, rect, rect, 50.0, 1, gap);
                let expected = components(&weights, w, h, 50.0, gap);
                assert_eq!(found.len(), expected.len(), "density {density} gap {gap}");
                for (b, (pixels, mass)) in found.iter().zip(&expected) {
                    assert_eq!(b.pixels, *pixels, "density {density} gap {gap}");
                    assert!((b.mass - mass).abs() < 1e-6 * mass, "density {density}");
                }
            }
        }
    }

    /// A labeler used before on areas of other sizes (its labels cleared run by run, not
    /// whole) finds, centres and splits blobs as a fresh one does.
    #[test]
    fn a_reused_labeler_answers_as_a_fresh_one() {
        let mut rng = crate::rng::Rng::new(29);
        let mut reused = Labeler::default();
        for (w, h, within) in [
            (70, 40, None),
            (23, 61, None),
            (90, 12, Some(PixelRect::new(10, 2, 40, 8))),
            (41, 41, None),
            (8, 5, None),
            (64, 30, None),
        ] {
            let rect = PixelRect::new(-3, 5, w, h);
            let weights: Vec<f32> = (0..w * h)
                .map(|_| {
                    if rng.uniform() < 0.35 {
                        60.0 + 100.0 * rng.uniform() as f32
                    } else {
                        20.0 * rng.uniform() as f32
                    }
                })
                .collect();
            let within = within.map_or(rect, |r| r.shifted(rect.x, rect.y));
            let mut fresh = Labeler::default();
            let a = reused.blobs(&weights, rect, within, 50.0, 2, 1);
            let b = fresh.blobs(&weights, rect, within, 50.0, 2, 1);
            assert_eq!(format!("{a:?}"), format!("{b:?}"), "{w}x{h}");
            assert!(!a.is_empty(), "{w}x{h}: no blob to compare");
            for blob in a.iter().take(3) {
                let window = blob.bounds.grown(4, 4);
                let ca = reused.edge_centroid(&weights, rect, blob, window, 3);
                let cb = fresh.edge_centroid(&weights, rect, blob, window, 3);
                assert_eq!(ca, cb, "{w}x{h}");
                let centres = [
                    Point2::new(f64::from(blob.bounds.x), f64::from(blob.bounds.y)),
                    Point2::new(blob.bounds.right() as f64, blob.bounds.bottom() as f64),
                ];
                let sa = reused.split(&weights, rect, blob, &centres);
                let sb = fresh.split(&weights, rect, blob, &centres);
                assert_eq!(format!("{sa:?}"), format!("{sb:?}"), "{w}x{h}");
            }
        }
    }

    /// Blobs of equal mass come in raster order of their first pixels, whatever their
    /// shapes (a U whose arms meet only at its foot, labelled from its right arm first).
    #[test]
    fn blobs_of_equal_mass_come_in_raster_order() {
        let (w, h) = (30usize, 12usize);
        let mut weights = vec![0.0f32; w * h];
        let mut put = |x: usize, y: usize| weights[y * w + x] = 100.0;
        // A U of 12 pixels starting at row 2, column 20 (its left arm starts a row lower).
        for y in 3..7 {
            put(16, y);
        }
        for y in 2..7 {
            put(20, y);
        }
        for x in 17..20 {
            put(x, 6);
        }
        // A bar of 12 pixels starting at row 4, column 2.
        for x in 2..14 {
            put(x, 4);
        }
        let rect = PixelRect::new(0, 0, w as i32, h as i32);
        let mut l = Labeler::default();
        for gap in 1..=2 {
            let found = l.blobs(&weights, rect, rect, 50.0, 1, gap);
            assert_eq!(found.len(), 2, "gap {gap}");
            assert_eq!(found[0].pixels, 12);
            assert_eq!(found[0].bounds, PixelRect::new(16, 2, 5, 5), "gap {gap}");
            assert_eq!(found[1].bounds, PixelRect::new(2, 4, 12, 1), "gap {gap}");
        }
    }

    #[test]
    fn wide_rows_skip_background_and_find_every_component() {
        // 100 x 30: blobs across the 32-pixel chunk edges, single pixels, a diagonal, a
        // pair one gap apart, and a view (`within`) that starts mid-row.
        let (w, h) = (100usize, 30usize);
        let mut weights = vec![0.0f32; w * h];
        let mut put = |x: usize, y: usize, v: f32| weights[y * w + x] = v;
        for y in 4..9 {
            for x in 29..36 {
                put(x, y, 100.0 + (x * y) as f32);
            }
        }
        for k in 0..10 {
            put(60 + k, 12 + k, 80.0);
        }
        put(63, 2, 90.0);
        put(64, 2, 91.0);
        put(95, 28, 70.0);
        put(10, 20, 60.0);
        put(12, 20, 65.0);
        for y in 15..25 {
            put(31, y, 55.0);
            put(32, y, 57.0);
        }
        let rect = PixelRect::new(-3, 5, w as i32, h as i32);
        let mut l = Labeler::default();
        for gap in [1, 2] {
            let found = l.blobs(&weights, rect, rect, 50.0, 1, gap);
            let expected = components(&weights, w, h, 50.0, gap);
            assert_eq!(found.len(), expected.len(), "gap {gap}");
            for (b, (pixels, mass)) in found.iter().zip(&expected) {
                assert_eq!(b.pixels, *pixels, "gap {gap}");
                assert!((b.mass - mass).abs() < 1e-9, "gap {gap}");
            }
        }
        // The pair at (10, 20) and (12, 20) is one blob with a gap of 2, two without.
        assert_eq!(
            l.blobs(&weights, rect, rect, 50.0, 1, 2).len() + 1,
            l.blobs(&weights, rect, rect, 50.0, 1, 1).len()
        );
        // A view that starts inside a chunk sees only its part of the first square.
        let within = PixelRect::new(30, 5, 40, 30);
        let part = l.blobs(&weights, rect, within, 50.0, 1, 1);
        let square = part
            .iter()
            .find(|b| b.bounds.y == 9)
            .expect("the first square");
        assert_eq!(square.pixels, 5 * 3, "{part:?}");
    }
}
