//! The light's change since the first frame, per colour channel, for the RGB kernel model.
//!
//! A hue does not change when the light brightens or dims, and hardly when its colour
//! shifts; a pixel's RGB does, in proportion per channel (a flicker of the light: our
//! generator's `flicker` condition, 1 ± 0.35 in gain and ± 8 % in the red and blue
//! channels' balance). The kernel model's bins are 16 levels wide, so a marker of the first
//! frame's colour falls in other bins, and weighs nothing, once the light has changed by a
//! tenth. The probe reads the frame on a sparse grid of the first frame's pixels and gives,
//! per channel, the factor that brings this frame's levels back to the first's; the kernel
//! model's lookup then reads every pixel scaled by it (see `Lookup::rescale`).

use super::*;

/// Step of the probe's grid (pixels, both directions): about 3,400 samples on a 512x424
/// frame, enough that a marker or a swinging limb passing over some of them moves the sums
/// by little, few enough to cost a few microseconds a frame.
const LIGHT_STEP_PX: u32 = 8;
/// Least and greatest level (8-bit) of a sample's channel for it to count in that
/// channel: a dark sample is mostly noise, a saturated one has lost its ratio.
const LIGHT_LEVELS: [u8; 2] = [24, 245];
/// Fewest samples a channel's factor is measured on; below it the factor is 1.
const LIGHT_MIN_SAMPLES: usize = 64;
/// A factor within this of 1 is taken as 1 (the lookup is left as learnt).
const LIGHT_TOLERANCE: f32 = 0.01;
/// The factors are held within these bounds: a change of the light by more than a factor
/// of two is a new scene, not a flicker.
const LIGHT_BOUNDS: [f32; 2] = [0.5, 2.0];

/// The first frame's levels on a sparse grid.
#[derive(Debug, Clone)]
pub(super) struct LightProbe {
    /// Byte offsets of the samples' pixels in the frame's raw RGB data.
    at: Vec<usize>,
    /// The first frame's levels at the samples.
    first: Vec<[u8; 3]>,
    /// The size of the first frame.
    size: (u32, u32),
}

impl LightProbe {
    /// The probe of `frame` (the first), skipping holes.
    pub(super) fn of(frame: &RgbImage) -> Self {
        let (width, height) = frame.dimensions();
        let raw = frame.as_raw();
        let mut at = Vec::new();
        let mut first = Vec::new();
        for y in (LIGHT_STEP_PX / 2..height).step_by(LIGHT_STEP_PX as usize) {
            for x in (LIGHT_STEP_PX / 2..width).step_by(LIGHT_STEP_PX as usize) {
                let k = 3 * (y as usize * width as usize + x as usize);
                let p = [raw[k], raw[k + 1], raw[k + 2]];
                if !is_hole(p) {
                    at.push(k);
                    first.push(p);
                }
            }
        }
        Self {
            at,
            first,
            size: (width, height),
        }
    }

    /// Per channel, the factor that brings `frame`'s levels to the first frame's: the ratio
    /// of the first frame's sum to this one's over the samples that are neither dark nor
    /// saturated in both, 1 when fewer than [`LIGHT_MIN_SAMPLES`] are or the factor is
    /// within [`LIGHT_TOLERANCE`] of 1, held within [`LIGHT_BOUNDS`].
    pub(super) fn gains(&self, frame: &RgbImage) -> [f32; 3] {
        if frame.dimensions() != self.size {
            return [1.0; 3];
        }
        let raw = frame.as_raw();
        let lit = |v: u8| (LIGHT_LEVELS[0]..=LIGHT_LEVELS[1]).contains(&v);
        let mut sums = [[0u64; 2]; 3];
        let mut counts = [0usize; 3];
        for (&k, was) in self.at.iter().zip(&self.first) {
            let Some(now) = raw.get(k..k + 3) else {
                continue;
            };
            for c in 0..3 {
                if lit(now[c]) && lit(was[c]) {
                    sums[c][0] += u64::from(was[c]);
                    sums[c][1] += u64::from(now[c]);
                    counts[c] += 1;
                }
            }
        }
        let mut gains = [1.0f32; 3];
        for c in 0..3 {
            if counts[c] >= LIGHT_MIN_SAMPLES && sums[c][1] > 0 {
                let g = (sums[c][0] as f64 / sums[c][1] as f64) as f32;
                if (g - 1.0).abs() > LIGHT_TOLERANCE {
                    gains[c] = g.clamp(LIGHT_BOUNDS[0], LIGHT_BOUNDS[1]);
                }
            }
        }
        gains
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn scene(gain: [f64; 3], seed: u64) -> RgbImage {
        let mut rng = Rng::new(seed);
        RgbImage::from_fn(160, 120, |x, y| {
            let base = if (x / 20 + y / 30) % 2 == 0 {
                [150.0, 120.0, 90.0]
            } else {
                [90.0, 140.0, 200.0]
            };
            let mut p = [0u8; 3];
            for c in 0..3 {
                p[c] = (base[c] * gain[c] + 3.0 * rng.normal()).clamp(0.0, 255.0) as u8;
            }
            if x % 13 == 0 && y % 7 == 0 {
                p = [0, 0, 0];
            }
            image::Rgb(p)
        })
    }

    #[test]
    fn a_change_of_the_light_is_measured_per_channel() {
        let probe = LightProbe::of(&scene([1.0; 3], 1));
        let g = probe.gains(&scene([0.7, 0.75, 0.65], 2));
        for (c, want) in [1.0 / 0.7, 1.0 / 0.75, 1.0 / 0.65].into_iter().enumerate() {
            assert!((f64::from(g[c]) - want).abs() < 0.02 * want, "{g:?}");
        }
        // The same light, other noise: no change.
        assert_eq!(probe.gains(&scene([1.0; 3], 3)), [1.0; 3]);
        // Another size, or a black frame: no measurement.
        assert_eq!(probe.gains(&RgbImage::new(10, 10)), [1.0; 3]);
        assert_eq!(probe.gains(&RgbImage::new(160, 120)), [1.0; 3]);
    }
}
