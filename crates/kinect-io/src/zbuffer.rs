//! Depth as the z-buffers of this crate store it: 24-bit steps of 0.1 mm, so that a depth, a
//! frame stamp and (in the projection image) a point index pack into one integer whose
//! unsigned `min` is the z-test. Positive depths keep their order; 0.1 mm is far below any
//! tolerance the tests use (1 % of depth, 2 cm) and 24 bits reach 1.6 km.

/// Bits of a quantised depth.
pub(crate) const DEPTH_BITS: u32 = 24;
/// Size of one step in metres.
const STEP_M: f64 = 1e-4;
/// Steps per metre, so that the hot path multiplies.
const STEPS_PER_M: f64 = 1.0 / STEP_M;
/// Largest quantised depth.
const MAX_STEPS: u32 = (1 << DEPTH_BITS) - 1;

/// Quantise a depth `z_m >= 0` (rounded half up; saturates at 1.6 km).
#[inline]
pub(crate) fn quantise(z_m: f64) -> u32 {
    // Truncating after adding 0.5 rounds half up for non-negative values.
    (z_m * STEPS_PER_M + 0.5).min(f64::from(MAX_STEPS)) as u32
}

/// The depth in metres of a quantised depth (the low 24 bits of `q`).
#[inline]
pub(crate) fn dequantise(q: u32) -> f64 {
    f64::from(q & MAX_STEPS) * STEP_M
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantisation_keeps_order_and_a_tenth_of_a_millimetre() {
        assert_eq!(quantise(0.0), 0);
        assert_eq!(quantise(2.0), 20_000);
        assert!(quantise(1.00004) < quantise(1.00006));
        assert!((dequantise(quantise(2.71234)) - 2.71234).abs() <= 0.5e-4);
        assert_eq!(quantise(1e6), MAX_STEPS);
    }
}
