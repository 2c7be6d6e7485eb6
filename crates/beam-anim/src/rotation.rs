//! Rotations for bending, two branches at a time: unit quaternions of rotation vectors by
//! short Taylor series for the small angles of bending, and the quaternion products the
//! frame loop needs, in pairs of `f64` lanes that the compiler keeps in one SSE2 register.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// Taylor coefficients in h² = |φ|²/4 of sin(|φ|/2)/|φ| and cos(|φ|/2), as many terms as
/// the angle needs for a truncation error below 2e-16: the short ones for |φ|² below
/// [`SHORT_SERIES_BELOW`] (|φ| < 0.02, where the angles of bending mostly are), the long ones
/// below [`SERIES_BELOW`] (|φ| < 0.25); beyond, `sin_cos`.
const SIN_HALF_SHORT: [f64; 3] = [0.5, -1.0 / 12.0, 1.0 / 240.0];
const COS_HALF_SHORT: [f64; 4] = [1.0, -0.5, 1.0 / 24.0, -1.0 / 720.0];
const SIN_HALF_LONG: [f64; 5] = [
    0.5,
    -1.0 / 12.0,
    1.0 / 240.0,
    -1.0 / 10_080.0,
    1.0 / 725_760.0,
];
const COS_HALF_LONG: [f64; 6] = [
    1.0,
    -0.5,
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40_320.0,
    -1.0 / 3_628_800.0,
];
const SHORT_SERIES_BELOW: f64 = 4e-4;
const SERIES_BELOW: f64 = 0.0625;

/// Σ c[k] h2^k by Horner's rule (unrolled: the length is a constant).
#[inline(always)]
pub(crate) fn horner<const N: usize>(c: &[f64; N], h2: f64) -> f64 {
    let mut acc = c[N - 1];
    for k in (0..N - 1).rev() {
        acc = c[k] + h2 * acc;
    }
    acc
}

/// Two lanes of f64 (two branches side by side).
pub(crate) type Lanes = [f64; 2];

#[inline(always)]
pub(crate) fn mul2(a: Lanes, b: Lanes) -> Lanes {
    [a[0] * b[0], a[1] * b[1]]
}

#[inline(always)]
pub(crate) fn add2(a: Lanes, b: Lanes) -> Lanes {
    [a[0] + b[0], a[1] + b[1]]
}

#[inline(always)]
pub(crate) fn sub2(a: Lanes, b: Lanes) -> Lanes {
    [a[0] - b[0], a[1] - b[1]]
}

#[inline(always)]
pub(crate) fn cross2(a: &[Lanes; 3], b: &[Lanes; 3]) -> [Lanes; 3] {
    [
        sub2(mul2(a[1], b[2]), mul2(a[2], b[1])),
        sub2(mul2(a[2], b[0]), mul2(a[0], b[2])),
        sub2(mul2(a[0], b[1]), mul2(a[1], b[0])),
    ]
}

/// Hamilton product g q, quaternions as (w, i, j, k) lanes.
#[inline(always)]
pub(crate) fn qmul2(g: &[Lanes; 4], q: &[Lanes; 4]) -> [Lanes; 4] {
    let [gw, gx, gy, gz] = *g;
    let [qw, qx, qy, qz] = *q;
    [
        sub2(
            sub2(mul2(gw, qw), mul2(gx, qx)),
            add2(mul2(gy, qy), mul2(gz, qz)),
        ),
        add2(
            add2(mul2(gw, qx), mul2(gx, qw)),
            sub2(mul2(gy, qz), mul2(gz, qy)),
        ),
        add2(
            sub2(mul2(gw, qy), mul2(gx, qz)),
            add2(mul2(gy, qw), mul2(gz, qx)),
        ),
        add2(
            add2(mul2(gw, qz), mul2(gx, qy)),
            sub2(mul2(gz, qw), mul2(gy, qx)),
        ),
    ]
}

/// g v for unit quaternions g: v + w t + g⃗ × t with t = 2 g⃗ × v.
#[inline(always)]
pub(crate) fn rotate2(g: &[Lanes; 4], v: &[Lanes; 3]) -> [Lanes; 3] {
    let gv = [g[1], g[2], g[3]];
    let t = cross2(&gv, v).map(|c| add2(c, c));
    let u = cross2(&gv, &t);
    [0, 1, 2].map(|c| add2(add2(v[c], mul2(g[0], t[c])), u[c]))
}

/// [`rotation`] on two lanes: the same series (the longer one if either lane needs it),
/// the exact form lane by lane beyond 0.25 rad.
#[inline(always)]
pub(crate) fn rotation2(phi: &[Lanes; 3]) -> [Lanes; 4] {
    let a2 = add2(
        add2(mul2(phi[0], phi[0]), mul2(phi[1], phi[1])),
        mul2(phi[2], phi[2]),
    );
    let big = a2[0].max(a2[1]);
    if big >= SERIES_BELOW {
        let q = [0, 1].map(|l| rotation(&Vector3::new(phi[0][l], phi[1][l], phi[2][l])));
        return [
            [q[0].w, q[1].w],
            [q[0].i, q[1].i],
            [q[0].j, q[1].j],
            [q[0].k, q[1].k],
        ];
    }
    let h2 = mul2(a2, [0.25; 2]);
    let horner = |coefficients: &[f64]| {
        let mut acc = [coefficients[coefficients.len() - 1]; 2];
        for &c in coefficients[..coefficients.len() - 1].iter().rev() {
            acc = add2([c; 2], mul2(h2, acc));
        }
        acc
    };
    let (s, c) = if big < SHORT_SERIES_BELOW {
        (horner(&SIN_HALF_SHORT), horner(&COS_HALF_SHORT))
    } else {
        (horner(&SIN_HALF_LONG), horner(&COS_HALF_LONG))
    };
    [c, mul2(phi[0], s), mul2(phi[1], s), mul2(phi[2], s)]
}

/// The unit quaternion of rotation vector `phi` (axis × angle, radians), with short series
/// for the small angles of bending.
#[inline]
pub(crate) fn rotation(phi: &Vector3<f64>) -> UnitQuaternion<f64> {
    let a2 = phi.norm_squared();
    let h2 = 0.25 * a2;
    let (s_over, c) = if a2 < SHORT_SERIES_BELOW {
        (horner(&SIN_HALF_SHORT, h2), horner(&COS_HALF_SHORT, h2))
    } else if a2 < SERIES_BELOW {
        (horner(&SIN_HALF_LONG, h2), horner(&COS_HALF_LONG, h2))
    } else {
        let a = a2.sqrt();
        let (s, c) = (0.5 * a).sin_cos();
        (s / a, c)
    };
    UnitQuaternion::new_unchecked(Quaternion::new(
        c,
        phi.x * s_over,
        phi.y * s_over,
        phi.z * s_over,
    ))
}
