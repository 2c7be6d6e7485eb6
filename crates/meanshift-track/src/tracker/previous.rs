//! The last frame, kept where the next frame will read it: the background of colour
//! markers' streaks and the test of a still look-alike.
//!
//! Copying a whole frame after every update cost more than tracking one marker in it (a
//! 512x424 frame is 651 kB; about 60 µs on the reference machine, against about 50 µs for
//! everything else one marker costs). Only the regions the next frame's passes can weigh
//! are kept ([`Tracker::next_regions`](super::Tracker)), or the whole frame when they cover
//! most of it; a read outside what was kept gets no previous frame (no streak weight, no
//! still test) rather than stale pixels.

use super::camera::{CameraPoints, MAX_CAMERA_SHIFT_PX};
use super::*;

/// Share of the frame above which the whole frame is copied in one go rather than region by
/// region (the regions overlap, and one copy is cheaper than many short ones).
const WHOLE_FRAME_SHARE: f64 = 0.5;
/// Frames after the camera last moved during which the regions kept are grown by the
/// largest shift looked for: a shake lasts a few frames, and the next frame reads the
/// previous one where the camera's shift puts it.
const SHAKE_HOLD_FRAMES: u32 = 5;

/// The pixels of the last frame that the next one can read.
#[derive(Debug, Clone)]
pub(super) struct PreviousFrame {
    /// Frame-sized; only `kept` holds the last frame's pixels.
    image: RgbImage,
    /// The rectangles (inside the frame) that hold the last frame.
    kept: Vec<PixelRect>,
    /// Edge points of the still scene (see [`camera`](super::camera)).
    camera: CameraPoints,
    /// The camera's shift from the frame kept to the one being tracked (zero until
    /// [`PreviousFrame::measure_shift`] is called with it).
    shift: [i32; 2],
    /// Frames since the camera last moved (saturating).
    since_shift: u32,
}

impl PreviousFrame {
    /// All of `frame`.
    pub(super) fn whole(frame: &RgbImage) -> Self {
        Self {
            image: frame.clone(),
            kept: vec![image_rect(frame.width(), frame.height())],
            camera: CameraPoints::default(),
            shift: [0, 0],
            since_shift: u32::MAX,
        }
    }

    /// All of the first frame, with the edge points of its still scene away from `markers`
    /// (their windows and surroundings) to measure the camera's shake by.
    pub(super) fn first(frame: &RgbImage, markers: &[PixelRect]) -> Self {
        Self {
            camera: CameraPoints::of(frame, markers),
            ..Self::whole(frame)
        }
    }

    /// Measure the camera's shift from the frame kept to `frame`, the next one.
    pub(super) fn measure_shift(&mut self, frame: &RgbImage) {
        self.shift = self.camera.shift_to(frame);
        self.since_shift = if self.shift == [0, 0] {
            self.since_shift.saturating_add(1)
        } else {
            0
        };
    }

    /// The camera's shift from the frame kept to the one being tracked (pixels).
    pub(super) fn shift(&self) -> Vector2<f64> {
        Vector2::new(f64::from(self.shift[0]), f64::from(self.shift[1]))
    }

    /// [`PreviousFrame::shift`]: a pixel at `(x, y)` now showed the still scene that was at
    /// `(x - dx, y - dy)` in the frame kept.
    pub(super) fn offset(&self) -> [i32; 2] {
        self.shift
    }

    /// All of `frame`, which the tracker may keep; the frame kept until now is handed back.
    pub(super) fn replace(&mut self, frame: RgbImage) -> RgbImage {
        self.kept.clear();
        self.kept.push(image_rect(frame.width(), frame.height()));
        std::mem::replace(&mut self.image, frame)
    }

    /// The last frame, if it was kept over all of `rect` (clipped to the frame; an empty
    /// `rect` needs nothing).
    pub(super) fn covering(&self, rect: PixelRect) -> Option<&RgbImage> {
        let r = rect.intersect(&image_rect(self.image.width(), self.image.height()));
        (r.is_empty() || self.kept.iter().any(|k| r.is_inside(k))).then_some(&self.image)
    }

    /// The last frame and the camera's whole-pixel shift since it ([`PreviousFrame::offset`]),
    /// if it was kept over all of `rect` moved back by the shift (what the pixels of `rect`
    /// showed there), or over `rect` itself with no shift.
    pub(super) fn covering_moved(&self, rect: PixelRect) -> Option<(&RgbImage, [i32; 2])> {
        let [dx, dy] = self.offset();
        let back = rect.shifted(-dx, -dy);
        match self.covering(back) {
            Some(image) => Some((image, [dx, dy])),
            None => self.covering(rect).map(|image| (image, [0, 0])),
        }
    }

    /// Keep `frame` (the size of the first) over `regions`, or whole when they cover more than
    /// [`WHOLE_FRAME_SHARE`] of it.
    pub(super) fn keep(&mut self, frame: &RgbImage, regions: &[PixelRect]) {
        let whole = image_rect(frame.width(), frame.height());
        if frame.dimensions() != self.image.dimensions() {
            *self = Self::whole(frame);
            return;
        }
        let grow = if self.since_shift <= SHAKE_HOLD_FRAMES {
            MAX_CAMERA_SHIFT_PX
        } else {
            0
        };
        self.kept.clear();
        self.kept.extend(
            regions
                .iter()
                .map(|r| r.grown(grow, grow).intersect(&whole))
                .filter(|r| !r.is_empty()),
        );
        let area: u64 = self.kept.iter().map(PixelRect::area).sum();
        if area as f64 > WHOLE_FRAME_SHARE * whole.area() as f64 {
            self.image.copy_from_slice(frame);
            self.kept.clear();
            self.kept.push(whole);
            return;
        }
        let stride = frame.width() as usize * 3;
        let (from, to) = (frame.as_raw(), &mut *self.image);
        for r in &self.kept {
            let (x, width) = (r.x as usize * 3, r.width as usize * 3);
            for y in r.y as usize..r.bottom() as usize {
                let start = y * stride + x;
                to[start..start + width].copy_from_slice(&from[start..start + width]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(level: u8) -> RgbImage {
        RgbImage::from_fn(40, 30, |x, y| image::Rgb([level, x as u8, y as u8]))
    }

    #[test]
    fn kept_regions_hold_the_last_frame_and_nothing_else_is_offered() {
        let mut p = PreviousFrame::whole(&frame(1));
        let region = PixelRect::new(5, 6, 10, 8);
        p.keep(&frame(2), &[region, PixelRect::new(-5, -5, 8, 8)]);
        let image = p.covering(region).expect("kept");
        assert_eq!(image.get_pixel(5, 6).0, [2, 5, 6]);
        assert_eq!(image.get_pixel(14, 13).0, [2, 14, 13]);
        // Clipped to the frame, the second region is kept too.
        assert!(p.covering(PixelRect::new(-2, -2, 4, 4)).is_some());
        // A rectangle reaching past what was kept gets no previous frame, not stale pixels.
        assert!(p.covering(region.grown(1, 0)).is_none());
        assert!(p.covering(PixelRect::new(20, 20, 3, 3)).is_none());
        // Nothing needed, nothing missing.
        assert!(p.covering(PixelRect::new(100, 100, 3, 3)).is_some());
    }

    #[test]
    fn regions_over_most_of_the_frame_keep_it_whole() {
        let mut p = PreviousFrame::whole(&frame(1));
        p.keep(&frame(3), &[PixelRect::new(0, 0, 40, 16)]);
        let image = p.covering(PixelRect::new(0, 0, 40, 30)).expect("whole");
        assert_eq!(image.get_pixel(39, 29).0, [3, 39, 29]);
        p.keep(&frame(4), &[]);
        assert!(p.covering(PixelRect::new(0, 0, 1, 1)).is_none());
    }

    /// Kept regions or the whole frame given: the same tracks, bit for bit, on a sequence
    /// with jumps of 2–5 windows (detection in wide gates) where the kept regions are a
    /// small part of the frame.
    #[test]
    fn tracks_from_kept_regions_are_those_from_whole_frames() -> Result<()> {
        use crate::stress::{Condition, StressConfig, StressScene};
        let scene = StressScene::new(&StressConfig::condition(Condition::Jumps, 2))?;
        let inits = &scene.inits()[..2];
        let first = scene.frame(0)?;
        let mut kept = Tracker::new(TrackerConfig::default(), &first, None, inits)?;
        let mut owned = Tracker::new(TrackerConfig::default(), &first, None, inits)?;
        let whole = image_rect(first.width(), first.height()).area();
        let mut partial = 0;
        for f in 1..scene.frames().min(70) {
            let frame = scene.frame(f)?;
            kept.update(&frame, None)?;
            let spare = owned.update_owned(frame, None)?;
            assert_eq!(
                spare,
                scene.frame(f - 1)?,
                "the frame before is handed back"
            );
            let p = kept.previous.as_ref().expect("colour model");
            if p.kept.iter().map(PixelRect::area).sum::<u64>() < whole / 2 {
                partial += 1;
            }
        }
        assert!(partial > 30, "{partial}");
        let recovered = |t: &Tracker| {
            t.tracks()
                .iter()
                .flat_map(|t| &t.observations)
                .filter(|o| o.status == TrackStatus::Recovered)
                .count()
        };
        assert!(recovered(&kept) > 0);
        assert_eq!(
            format!("{:?}", kept.tracks()),
            format!("{:?}", owned.tracks())
        );
        Ok(())
    }
}
