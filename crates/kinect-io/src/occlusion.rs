//! The occlusion filter's test over the colour image: which of the points that project onto
//! it the colour camera sees, found by one sweep down the colour rows with a few rows of
//! nearest depths in cache, instead of maps of the whole image.

/// The nearest depth in a window around each of a set of sparse colour pixels, by a sweep
/// down the colour rows.
///
/// The points are ordered by colour row (a counting sort); then the rows are filled one by
/// one into a ring of `2 · half_height + 1` rows of nearest depth per column, and the
/// points of a row are tested once the rows below it within the window are in. Memory is
/// the sorted points and the ring (15 KB for 1280-pixel rows and the default 5x3 window),
/// where a map of the whole colour image (3.7 MB at 1280x720, 8 MB at 1920x1080) misses the
/// cache on every few points.
#[derive(Debug, Clone, Default)]
pub(crate) struct WindowSweep {
    /// The colour image's width and height, pixels.
    size: (usize, usize),
    /// The points as given: colour pixel (`v << 16 | u`; colour images are at most
    /// [`crate::camera::MAX_IMAGE_SIDE_PX`] < 2^16 a side), quantised depth, caller's id.
    points: Vec<[u32; 3]>,
    /// Points per colour row while they come in (row `v` at `v + 1`), then where each
    /// row's points start in `sorted` (one entry more than rows).
    row_start: Vec<u32>,
    /// The points ordered by colour row: column, quantised depth, id.
    sorted: Vec<[u32; 3]>,
    /// The ring: nearest quantised depth per column of the last rows ([`NONE`]: none).
    /// `f32` holds every 24-bit quantised depth exactly, and its `min` is one vector
    /// instruction on every x86-64 (the unsigned 32-bit one needs SSE4.1).
    ring: Vec<f32>,
    /// The nearest depth per column over the rows of the window of the row under test.
    column_min: Vec<f32>,
}

impl WindowSweep {
    /// Start a frame on a `width` x `height` colour image.
    pub(crate) fn begin(&mut self, width: usize, height: usize) {
        self.size = (width, height);
        self.points.clear();
        self.row_start.clear();
        self.row_start.resize(height + 1, 0);
    }

    /// A point at colour pixel `(u, v)` (inside the image; others are ignored) with
    /// quantised depth `q` (0.1 mm steps, `crate::zbuffer::quantise`) and an id for
    /// [`Self::hidden`].
    #[inline]
    pub(crate) fn push(&mut self, (u, v): (u32, u32), q: u32, id: u32) {
        if (u as usize) < self.size.0
            && let Some(count) = self.row_start.get_mut(v as usize + 1)
        {
            *count += 1;
            self.points.push([v << 16 | u, q, id]);
        }
    }

    /// Points pushed this frame.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.points.len()
    }

    /// Call `hidden(id)` for each point that has another point within `half` = (half
    /// width, half height) pixels whose depth is below `q · (1 − tolerance)`:
    /// libfreenect2's test, which spreads each point's depth over the window around it and
    /// asks each point's own pixel, the same as gathering over the window when the window
    /// is symmetric.
    ///
    /// Cost: the sort, the rows of the ring over the span of each row's points, and
    /// `2 · half width + 1` reads per point; `CloudConfig::validate` bounds the window.
    pub(crate) fn hidden(
        &mut self,
        (hw, hh): (usize, usize),
        tolerance: f64,
        mut hidden: impl FnMut(u32),
    ) {
        let (width, height) = self.size;
        if width == 0 || height == 0 || self.points.is_empty() {
            return;
        }
        // Counting sort by row: prefix sums of the counts, then each point to its row.
        for r in 1..=height {
            self.row_start[r] += self.row_start[r - 1];
        }
        self.sorted.clear();
        self.sorted.resize(self.points.len(), [0; 3]);
        // Fill pointers: the start of each row, advanced as its points are placed.
        let mut next = self.row_start.clone();
        for &[px, q, id] in &self.points {
            if let Some(at) = next.get_mut((px >> 16) as usize)
                && let Some(slot) = self.sorted.get_mut(*at as usize)
            {
                *slot = [px & 0xffff, q, id];
                *at += 1;
            }
        }
        let ring_rows = (2 * hh + 1).min(height);
        self.ring.clear();
        self.ring.resize(ring_rows * width, NONE);
        self.column_min.clear();
        self.column_min.resize(width, NONE);
        let (starts, sorted) = (&self.row_start, &self.sorted);
        let (ring, column_min) = (&mut self.ring, &mut self.column_min);
        let row = |r: usize| &sorted[starts[r] as usize..starts[r + 1] as usize];
        let keep = 1.0 - tolerance;
        let mut bases: Vec<usize> = Vec::with_capacity(ring_rows);
        for fill in 0..height + hh {
            if fill < height {
                let base = (fill % ring_rows) * width;
                // The row this slot held leaves the ring: its cells back to "none".
                if fill >= ring_rows {
                    for &[u, _, _] in row(fill - ring_rows) {
                        ring[base + u as usize] = NONE;
                    }
                }
                for &[u, q, _] in row(fill) {
                    let cell = &mut ring[base + u as usize];
                    *cell = nearer(*cell, q as f32);
                }
            }
            // Row `fill − hh` has every row of its window in the ring now.
            let Some(r) = fill.checked_sub(hh) else {
                continue;
            };
            let points = row(r);
            let (Some(lo), Some(hi)) = (
                points.iter().map(|p| p[0]).min(),
                points.iter().map(|p| p[0]).max(),
            ) else {
                continue;
            };
            // The nearest depth per column over the window's rows, across the columns the
            // row's windows cover (separable: rows first, in one vectorised pass).
            let (x_lo, x_hi) = (
                (lo as usize).saturating_sub(hw),
                (hi as usize + hw).min(width - 1),
            );
            let (r0, r1) = (r.saturating_sub(hh), (r + hh).min(height - 1));
            bases.clear();
            bases.extend((r0..=r1).map(|rr| (rr % ring_rows) * width));
            let span = &mut column_min[x_lo..=x_hi];
            let cells = |base: usize| &ring[base + x_lo..=base + x_hi];
            match bases.as_slice() {
                // The default window (three rows): one pass, no stores between rows.
                &[a, b, c] => {
                    for (m, ((&a, &b), &c)) in span
                        .iter_mut()
                        .zip(cells(a).iter().zip(cells(b)).zip(cells(c)))
                    {
                        *m = nearer(nearer(a, b), c);
                    }
                }
                rows => {
                    span.fill(NONE);
                    for &base in rows {
                        for (m, &c) in span.iter_mut().zip(cells(base)) {
                            *m = nearer(*m, c);
                        }
                    }
                }
            }
            for &[u, q, id] in points {
                let u = u as usize;
                let (x0, x1) = (u.saturating_sub(hw), (u + hw).min(width - 1));
                let m = column_min[x0..=x1].iter().fold(NONE, |m, &c| nearer(m, c));
                if f64::from(m) < f64::from(q) * keep {
                    hidden(id);
                }
            }
        }
    }
}

/// No depth in a cell.
const NONE: f32 = f32::INFINITY;

/// The nearer of two depths, as a select the compiler turns into one vector `min`.
#[inline(always)]
fn nearer(a: f32, b: f32) -> f32 {
    if b < a { b } else { a }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against a brute force over every pair, on random points with clusters at two depths,
    /// for several windows, including windows taller than the image.
    #[test]
    fn sweep_matches_every_pair() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut rnd = |n: u32| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % u64::from(n)) as u32
        };
        let (w, h) = (40_usize, 23_usize);
        let points: Vec<[u32; 3]> = (0..300)
            .map(|_| {
                let q = if rnd(4) == 0 {
                    10_000
                } else {
                    20_000 + rnd(400)
                };
                [rnd(w as u32), rnd(h as u32), q]
            })
            .collect();
        let mut sweep = WindowSweep::default();
        for (hw, hh, tolerance) in [(2, 1, 0.01), (0, 0, 0.0), (3, 5, 0.005), (1, 40, 0.01)] {
            sweep.begin(w, h);
            for (k, &[u, v, q]) in points.iter().enumerate() {
                sweep.push((u, v), q, k as u32);
            }
            // Outside the image: not taken.
            sweep.push((w as u32, 0), 1, 999);
            sweep.push((0, h as u32), 1, 999);
            assert_eq!(sweep.len(), points.len());
            let mut got = vec![false; points.len()];
            sweep.hidden((hw, hh), tolerance, |k| got[k as usize] = true);
            let expected: Vec<bool> = points
                .iter()
                .map(|p| {
                    points.iter().any(|o| {
                        o[0].abs_diff(p[0]) as usize <= hw
                            && o[1].abs_diff(p[1]) as usize <= hh
                            && f64::from(o[2]) < f64::from(p[2]) * (1.0 - tolerance)
                    })
                })
                .collect();
            assert_eq!(got, expected, "window {hw}x{hh}");
            assert!(
                got.iter().any(|&g| g) && !got.iter().all(|&g| g),
                "{hw}x{hh}"
            );
        }
    }
}
