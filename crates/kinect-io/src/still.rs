//! The still tree from several frames: each depth pixel averaged over the frames where it is
//! valid, kept when it is seen in most of them and steady (a surface), dropped when it comes
//! and goes (a dropout) or wanders (a flying pixel mixing a branch with the background, which
//! lands anywhere between them from frame to frame).

use nalgebra::{Point3, Vector3};

use crate::cloud::TexturedCloud;
use crate::error::{KinectError, Result};

/// Spread (standard deviation of the distance from the camera) above which a pixel of the
/// still frames is not one surface, metres (about 5 sigma of the Kinect V2's depth noise at
/// 2 m).
pub const STILL_SPREAD_M: f64 = 0.01;

/// One depth pixel over the still frames: sums of its positions and distances.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Pixel {
    sum: Vector3<f64>,
    sum_r_m: f64,
    sum_sq_m2: f64,
    count: u32,
}

/// Accumulates the clouds of a still tree, pixel by pixel.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StillCloud {
    pixels: Vec<Pixel>,
    frames: u32,
}

impl StillCloud {
    /// An empty accumulator.
    pub fn new() -> Self {
        Self::default()
    }

    /// Add one frame's organized cloud.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] when the cloud's depth camera has another pixel
    /// count than the clouds added before (nothing is added then).
    pub fn add(&mut self, cloud: &TexturedCloud) -> Result<()> {
        let n = cloud.source_camera().pixel_count();
        if self.pixels.is_empty() && self.frames == 0 {
            self.pixels = vec![Pixel::default(); n];
        }
        if self.pixels.len() != n {
            return Err(KinectError::param(
                "still cloud frame",
                format!(
                    "{n} depth pixels; the frames before had {}",
                    self.pixels.len()
                ),
            ));
        }
        for (i, p) in cloud.iter_valid() {
            let r = p.position_m.coords.norm();
            let px = &mut self.pixels[i];
            px.sum += p.position_m.coords;
            px.sum_r_m += r;
            px.sum_sq_m2 += r * r;
            px.count += 1;
        }
        self.frames += 1;
        Ok(())
    }

    /// Frames added.
    pub fn frames(&self) -> u32 {
        self.frames
    }

    /// The still points: per depth pixel valid in at least half of the frames (rounded up)
    /// and steady within [`STILL_SPREAD_M`], its mean position (the clouds' frame, metres).
    pub fn points(&self) -> Vec<Point3<f64>> {
        let needed = self.frames.div_ceil(2).max(1);
        self.pixels
            .iter()
            .filter(|p| p.count >= needed)
            .filter_map(|p| {
                let n = f64::from(p.count);
                let mean_r = p.sum_r_m / n;
                let var = (p.sum_sq_m2 / n - mean_r * mean_r).max(0.0);
                (var.sqrt() <= STILL_SPREAD_M).then(|| Point3::from(p.sum / n))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Calibration, CloudBuilder, CloudConfig, DepthImage};
    use image::RgbImage;

    fn cloud(depth_mm: impl Fn(u32, u32) -> u16) -> TexturedCloud {
        let calibration = Calibration::tum_default();
        let (w, h) = (
            calibration.depth_camera.width,
            calibration.depth_camera.height,
        );
        let values = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| depth_mm(x, y))
            .collect();
        let depth = DepthImage::new(w, h, 1e-3, values).unwrap();
        let color = RgbImage::new(
            calibration.color_camera.width,
            calibration.color_camera.height,
        );
        CloudBuilder::new(&calibration, CloudConfig::default())
            .unwrap()
            .build(&depth, &color)
            .unwrap()
    }

    #[test]
    fn steady_pixels_stay_flickering_and_wandering_ones_go() {
        let mut still = StillCloud::new();
        for k in 0..5u16 {
            still
                .add(&cloud(|x, y| match (x, y) {
                    // Steady surface.
                    (10, 10) => 2000,
                    // Seen in 2 of 5 frames: a dropout pixel.
                    (20, 10) if k < 2 => 2000,
                    // Wandering by 10 cm: a flying pixel.
                    (30, 10) => 2000 + 100 * k,
                    _ => 0,
                }))
                .unwrap();
        }
        assert_eq!(still.frames(), 5);
        let points = still.points();
        assert_eq!(points.len(), 1, "{points:?}");
        assert!((points[0].z - 2.0).abs() < 1e-3);
    }
}
