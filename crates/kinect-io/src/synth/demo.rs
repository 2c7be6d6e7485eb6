//! The demo scene: a small tree of capsules with red markers, for examples and tests.

use super::*;

/// Bark colour of the demo tree.
const BARK_RGB: [u8; 3] = [112, 82, 58];
/// Marker red of the demo tree (the paper's red markers).
pub const MARKER_RGB: [u8; 3] = [215, 25, 30];
/// Marker radius of the demo tree: the paper's markers are about 3 cm wide.
pub const MARKER_RADIUS_M: f64 = 0.015;

/// A small leafless tree (about 2 m tall) standing at the world origin on grass, with a red
/// marker on the trunk and on every branch of the first two levels (ids `A`, `B`, ... in
/// depth-first order), each facing a camera on the -y side. Branch angles vary with `seed`.
pub fn demo_tree(seed: u64) -> Scene {
    let mut rng = SplitMix64::new(seed ^ 0x7472_6565); // "tree"
    let mut primitives = Vec::new();
    let mut markers = Vec::new();
    let trunk_top = Point3::new(0.0, 0.0, 1.0);
    primitives.push(Primitive {
        shape: Shape::Capsule {
            a: Point3::new(0.0, 0.0, -0.05),
            b: trunk_top,
            radius_m: 0.04,
        },
        rgb: BARK_RGB,
    });
    add_marker(&mut markers, Point3::new(0.0, 0.0, 0.6), Vector3::z(), 0.04);
    // (start, direction, length, radius, level)
    let mut stack = vec![(trunk_top, Vector3::z(), 0.0_f64, 0.03_f64, 0usize)];
    while let Some((start, dir, _, radius, level)) = stack.pop() {
        if level >= 3 {
            continue;
        }
        let children = if level == 0 { 3 } else { 2 };
        for k in 0..children {
            let spread = if level == 0 { 0.9 } else { 0.6 };
            let side = if children == 3 {
                k as f64 - 1.0
            } else {
                k as f64 * 2.0 - 1.0
            };
            let angle = side * spread + 0.15 * (rng.uniform() - 0.5);
            // Branches fan out mostly in the x–z plane (facing the camera on -y), a little in y.
            let depth_tilt = 0.25 * (rng.uniform() - 0.5);
            let rot = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), angle)
                * nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), depth_tilt);
            let child_dir = (rot * dir).normalize();
            let length = [0.55, 0.38, 0.24][level] * (0.9 + 0.2 * rng.uniform());
            let child_radius = radius * 0.62;
            let end = start + child_dir * length;
            primitives.push(Primitive {
                shape: Shape::Capsule {
                    a: start,
                    b: end,
                    radius_m: child_radius,
                },
                rgb: BARK_RGB,
            });
            if level < 2 {
                add_marker(
                    &mut markers,
                    start + child_dir * (length * 0.6),
                    child_dir,
                    child_radius,
                );
            }
            stack.push((end, child_dir, length, child_radius, level + 1));
        }
    }
    Scene {
        primitives,
        markers,
        ground: Some((0.0, [86, 118, 62])),
        sky_rgb: [172, 200, 232],
        light_direction: Vector3::new(0.3, -0.6, 1.0),
    }
}

/// A marker on the camera-facing (-y) side of a branch at `at` with axis `axis`.
pub(super) fn add_marker(
    markers: &mut Vec<Marker>,
    at: Point3<f64>,
    axis: Vector3<f64>,
    radius_m: f64,
) {
    let toward = -Vector3::y();
    let axis = axis.normalize();
    let facing = (toward - axis * toward.dot(&axis))
        .try_normalize(1e-9)
        .unwrap_or(toward);
    let id = marker_id(markers.len());
    markers.push(Marker {
        id,
        center_m: at + facing * (radius_m + 0.002),
        normal: facing,
        radius_m: MARKER_RADIUS_M,
        rgb: MARKER_RGB,
    });
}

pub(super) fn marker_id(k: usize) -> String {
    let letters = b"ABCDEFGHIJKLMNOPQRSTUVWXYZ";
    if k < letters.len() {
        char::from(letters[k]).to_string()
    } else {
        format!("M{k}")
    }
}
