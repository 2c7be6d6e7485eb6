//! The occlusion filter's minimum-depth map over the colour image: which depth pixels the
//! colour camera sees, found without clearing a full-size map every frame.

use crate::zbuffer::DEPTH_BITS;

/// A minimum-depth map over the colour image that needs no clearing between frames. A cell is
/// `(age << 24) | depth` (depth quantised to 0.1 mm): cells from earlier frames have a larger
/// age, so one unsigned `min` both replaces stale cells and keeps the nearest depth of this
/// frame. Saves clearing the map (8 MB at 1920x1080) every frame; the update is branch-free.
#[derive(Debug, Clone, Default)]
pub(crate) struct MinDepthMap {
    /// Per colour pixel; only filled around contested points (see `CloudBuilder::build_into`).
    cells: Vec<u32>,
    width: usize,
    height: usize,
    /// A lower bound of the nearest depth over blocks of `2^COARSE_SHIFT` pixels square, in
    /// steps of `2^COARSE_DEPTH_SHIFT` quantised units ([`COARSE_EMPTY`] where no point
    /// fell): small enough to stay in cache (16 bits a cell, cleared every frame), it answers
    /// "nothing nearer anywhere near" for most points without the fine map.
    coarse: Vec<u16>,
    coarse_width: usize,
    /// Blocks whose fine cells a contested point needs, this frame.
    needed: Vec<bool>,
    age: u32,
}

/// Coarse blocks of the occlusion map are 2x2 colour pixels: finer blocks contest fewer points
/// on slanted surfaces (measured on the Azure Kinect and Kinect V2 frames of the
/// `kinect_io` bench: 8x8 blocks 20-30 % slower with the filter on).
const COARSE_SHIFT: u32 = 1;

/// The block level keeps depths in steps of 2^4 quantised units (1.6 mm), rounded down, so
/// that a cell is 16 bits (half the memory traffic of the fine cells' 32) and still a lower
/// bound: the block test can only contest more points, never clear an occluded one.
const COARSE_DEPTH_SHIFT: u32 = 4;

/// A block no point fell in this frame.
const COARSE_EMPTY: u16 = u16::MAX;

/// A quantised depth as a block cell: rounded down, saturating below [`COARSE_EMPTY`] (beyond
/// 104 m every depth is the same, still a lower bound).
#[inline]
fn coarse_cell(q: u32) -> u16 {
    (q >> COARSE_DEPTH_SHIFT).min(u32::from(COARSE_EMPTY - 1)) as u16
}

impl MinDepthMap {
    pub(crate) fn begin_frame(&mut self, width: usize, height: usize) {
        if (self.width, self.height) != (width, height) || self.age == 0 {
            self.cells.clear();
            self.cells.resize(width * height, u32::MAX);
            (self.width, self.height) = (width, height);
            self.coarse_width = width.div_ceil(1 << COARSE_SHIFT);
            let blocks = self.coarse_width * height.div_ceil(1 << COARSE_SHIFT);
            self.coarse.clear();
            self.coarse.resize(blocks, COARSE_EMPTY);
            self.needed.clear();
            self.needed.resize(blocks, false);
            self.age = (1 << (32 - DEPTH_BITS)) - 1;
        }
        self.age -= 1;
        self.coarse.fill(COARSE_EMPTY);
        self.needed.fill(false);
    }

    #[inline]
    pub(crate) fn key(&self, q: u32) -> u32 {
        (self.age << DEPTH_BITS) | q
    }

    #[inline]
    pub(crate) fn block(&self, x: usize, y: usize) -> usize {
        (y >> COARSE_SHIFT) * self.coarse_width + (x >> COARSE_SHIFT)
    }

    /// Record quantised depth `q` at pixel `(x, y)` in the block level.
    #[inline]
    pub(crate) fn lower_coarse(&mut self, (x, y): (usize, usize), q: u32) {
        let at = self.block(x, y);
        self.coarse[at] = self.coarse[at].min(coarse_cell(q));
    }

    /// Record quantised depth `q` at pixel `(x, y)` in the fine level, if a contested point
    /// needs its block.
    #[inline]
    pub(crate) fn lower_fine_if_needed(&mut self, (x, y): (usize, usize), q: u32) {
        if self.needed[self.block(x, y)] {
            let key = self.key(q);
            let cell = &mut self.cells[y * self.width + x];
            *cell = (*cell).min(key);
        }
    }

    /// The window of `(hw, hh)` pixels around `(x, y)`, clipped: `(x0, x1, y0, y1)`.
    #[inline]
    pub(crate) fn window(&self, (x, y): (usize, usize), (hw, hh): (usize, usize)) -> [usize; 4] {
        [
            x.saturating_sub(hw),
            (x + hw).min(self.width - 1),
            y.saturating_sub(hh),
            (y + hh).min(self.height - 1),
        ]
    }

    /// Is `m` a depth of this frame nearer than `limit` (quantised units)?
    #[inline]
    pub(crate) fn nearer(&self, m: u32, limit: f64) -> bool {
        m >> DEPTH_BITS == self.age && f64::from(m & ((1 << DEPTH_BITS) - 1)) < limit
    }

    /// Step 1 of the test: `false` when no depth of this frame in the blocks covering the
    /// window is nearer than `limit` (then the point is not occluded); `true` when the fine
    /// level must decide, in which case the blocks are marked as needed.
    #[inline]
    pub(crate) fn contested(
        &mut self,
        centre: (usize, usize),
        half: (usize, usize),
        limit: f64,
    ) -> bool {
        let [x0, x1, y0, y1] = self.window(centre, half);
        let (bx0, bx1) = (x0 >> COARSE_SHIFT, x1 >> COARSE_SHIFT);
        let mut m = COARSE_EMPTY;
        for by in (y0 >> COARSE_SHIFT)..=(y1 >> COARSE_SHIFT) {
            let start = by * self.coarse_width;
            for &block in &self.coarse[start + bx0..=start + bx1] {
                m = m.min(block);
            }
        }
        if m == COARSE_EMPTY || f64::from(u32::from(m) << COARSE_DEPTH_SHIFT) >= limit {
            return false;
        }
        for by in (y0 >> COARSE_SHIFT)..=(y1 >> COARSE_SHIFT) {
            let start = by * self.coarse_width;
            self.needed[start + bx0..=start + bx1].fill(true);
        }
        true
    }

    /// Step 2: is a depth of this frame nearer than `limit` within the window (fine level)?
    #[inline]
    pub(crate) fn occluded(
        &self,
        centre: (usize, usize),
        half: (usize, usize),
        limit: f64,
    ) -> bool {
        let [x0, x1, y0, y1] = self.window(centre, half);
        let mut m = u32::MAX;
        for row in y0..=y1 {
            let start = row * self.width;
            for &cell in &self.cells[start + x0..=start + x1] {
                m = m.min(cell);
            }
        }
        self.nearer(m, limit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_cells_are_lower_bounds_within_one_step() {
        let max = (1_u32 << DEPTH_BITS) - 1;
        for q in [
            0,
            1,
            15,
            16,
            17,
            40_000,
            1 << 20,
            (0xFFFE << 4) - 1,
            0xFFFE << 4,
            max,
        ] {
            let cell = coarse_cell(q);
            assert!(cell < COARSE_EMPTY, "{q}");
            let bound = u32::from(cell) << COARSE_DEPTH_SHIFT;
            assert!(bound <= q, "{q}: {bound}");
            if q < 0xFFFE << COARSE_DEPTH_SHIFT {
                assert!(q - bound < 1 << COARSE_DEPTH_SHIFT, "{q}: {bound}");
            }
        }
    }
}
