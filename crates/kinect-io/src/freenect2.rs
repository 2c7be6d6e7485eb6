//! libfreenect2's depth-to-colour registration from the Kinect V2's factory parameters.
//!
//! The model (libfreenect2 `Registration`, whose behaviour this module reproduces; the code is
//! ours): every pixel `(x, y)` of an *undistorted* 512x424 depth grid samples the raw depth at
//! the nearest pixel of its distorted position (Brown–Conrady with the IR parameters). Its colour
//! pixel comes from a cubic polynomial in the depth pixel offsets scaled by `depth_q = 0.01`,
//! plus a disparity term `shift_m / z` (z in millimetres) along x:
//!
//! ```text
//! mx = (x - ir.cx) * depth_q, my = (y - ir.cy) * depth_q
//! wx = sum mx_xiyj * mx^i my^j, wy = sum my_xiyj * mx^i my^j   (i + j <= 3)
//! colour_x = (wx / (color.fx * color_q) - shift_m / shift_d + shift_m / z) * color.fx + color.cx
//! colour_y = wy / color_q + color.cy,      color_q = 0.002199
//! ```
//!
//! both rounded half up. The optional occlusion filter keeps, for each colour pixel, the nearest
//! depth over a 5x3 window and drops the colour of depth pixels more than 1 % behind it.
//! Arithmetic is in `f32` exactly as libfreenect2 does it, so that the registered image matches
//! libfreenect2's pixel for pixel.
//!
//! Two quirks of libfreenect2 are kept on purpose (they decide which colour a pixel gets):
//! the colour column is truncated toward zero after adding 0.5 (so columns just left of the
//! image clamp into column 0), and only the flat offset `x + 1920 y` is range-checked (so a
//! column past 1919 wraps into the next row). Memory accesses that libfreenect2 leaves
//! unchecked at the filter-map borders are bounds-checked here.

use image::RgbImage;
use serde::{Deserialize, Serialize};

use crate::camera::{
    CameraModel, Distortion, KINECT_V2_COLOR_HEIGHT_PX, KINECT_V2_COLOR_WIDTH_PX,
    KINECT_V2_DEPTH_HEIGHT_PX, KINECT_V2_DEPTH_WIDTH_PX,
};
use crate::error::{KinectError, Result};

/// Depth quantisation of the polynomial's inputs, hard-coded in the Kinect SDK and libfreenect2.
pub const FREENECT2_DEPTH_Q: f32 = 0.01;
/// Colour quantisation of the polynomial's outputs, hard-coded in the Kinect SDK and
/// libfreenect2.
pub const FREENECT2_COLOR_Q: f32 = 0.002199;
/// libfreenect2's occlusion filter: half-width of the window in colour pixels.
pub const FREENECT2_FILTER_HALF_WIDTH_PX: i32 = 2;
/// libfreenect2's occlusion filter: half-height of the window in colour pixels.
pub const FREENECT2_FILTER_HALF_HEIGHT_PX: i32 = 1;
/// libfreenect2's occlusion filter: relative depth tolerance.
pub const FREENECT2_FILTER_TOLERANCE: f32 = 0.01;

const W: usize = KINECT_V2_DEPTH_WIDTH_PX as usize;
const H: usize = KINECT_V2_DEPTH_HEIGHT_PX as usize;
const CW: usize = KINECT_V2_COLOR_WIDTH_PX as usize;
const CH: usize = KINECT_V2_COLOR_HEIGHT_PX as usize;

/// The IR (depth) camera's factory parameters (libfreenect2 `IrCameraParams`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct Freenect2IrParams {
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub k1: f32,
    pub k2: f32,
    pub k3: f32,
    pub p1: f32,
    pub p2: f32,
}

/// The colour camera's factory parameters (libfreenect2 `ColorCameraParams`): intrinsics,
/// disparity shift, and the cubic polynomial coefficients of the depth-to-colour map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct Freenect2ColorParams {
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub shift_d: f32,
    pub shift_m: f32,
    pub mx_x3y0: f32,
    pub mx_x0y3: f32,
    pub mx_x2y1: f32,
    pub mx_x1y2: f32,
    pub mx_x2y0: f32,
    pub mx_x0y2: f32,
    pub mx_x1y1: f32,
    pub mx_x1y0: f32,
    pub mx_x0y1: f32,
    pub mx_x0y0: f32,
    pub my_x3y0: f32,
    pub my_x0y3: f32,
    pub my_x2y1: f32,
    pub my_x1y2: f32,
    pub my_x2y0: f32,
    pub my_x0y2: f32,
    pub my_x1y1: f32,
    pub my_x1y0: f32,
    pub my_x0y1: f32,
    pub my_x0y0: f32,
}

impl Freenect2IrParams {
    /// Typical Kinect V2 IR factory parameters, the values of [`CameraModel::kinect_v2_depth`]
    /// (a real device's differ by about 1 %: read them from the device for measurement work).
    pub fn kinect_v2_typical() -> Self {
        let c = CameraModel::kinect_v2_depth();
        let d = c.distortion;
        Self {
            fx: c.fx as f32,
            fy: c.fy as f32,
            cx: c.cx as f32,
            cy: c.cy as f32,
            k1: d.k1 as f32,
            k2: d.k2 as f32,
            k3: d.k3 as f32,
            p1: d.p1 as f32,
            p2: d.p2 as f32,
        }
    }

    /// The depth camera as a [`CameraModel`] (512x424).
    pub fn camera(&self) -> CameraModel {
        CameraModel {
            width: KINECT_V2_DEPTH_WIDTH_PX,
            height: KINECT_V2_DEPTH_HEIGHT_PX,
            fx: f64::from(self.fx),
            fy: f64::from(self.fy),
            cx: f64::from(self.cx),
            cy: f64::from(self.cy),
            distortion: Distortion {
                k1: f64::from(self.k1),
                k2: f64::from(self.k2),
                k3: f64::from(self.k3),
                p1: f64::from(self.p1),
                p2: f64::from(self.p2),
                ..Distortion::default()
            },
        }
    }

    fn values(&self) -> [f32; 9] {
        [
            self.fx, self.fy, self.cx, self.cy, self.k1, self.k2, self.k3, self.p1, self.p2,
        ]
    }
}

impl Freenect2ColorParams {
    /// The colour camera as a [`CameraModel`] (1920x1080, no distortion: the polynomial holds
    /// it).
    pub fn camera(&self) -> CameraModel {
        CameraModel {
            width: KINECT_V2_COLOR_WIDTH_PX,
            height: KINECT_V2_COLOR_HEIGHT_PX,
            fx: f64::from(self.fx),
            fy: f64::from(self.fy),
            cx: f64::from(self.cx),
            cy: f64::from(self.cy),
            distortion: Distortion::default(),
        }
    }

    /// Colour parameters that make the polynomial model equal a pinhole colour camera
    /// (focal length `color_f_px`, principal point `(color_cx_px, color_cy_px)`) displaced by
    /// `baseline_mm` along the depth camera's x axis, with no rotation and no distortion.
    /// For tests and for users who only know such a simple model.
    pub fn from_pinhole_baseline(
        ir: &Freenect2IrParams,
        color_f_px: f32,
        color_cx_px: f32,
        color_cy_px: f32,
        baseline_mm: f32,
    ) -> Self {
        let zero = 0.0;
        Self {
            fx: color_f_px,
            fy: color_f_px,
            cx: color_cx_px,
            cy: color_cy_px,
            shift_d: 1.0e30,
            shift_m: baseline_mm,
            mx_x3y0: zero,
            mx_x0y3: zero,
            mx_x2y1: zero,
            mx_x1y2: zero,
            mx_x2y0: zero,
            mx_x0y2: zero,
            mx_x1y1: zero,
            mx_x1y0: color_f_px * FREENECT2_COLOR_Q / (ir.fx * FREENECT2_DEPTH_Q),
            mx_x0y1: zero,
            mx_x0y0: zero,
            my_x3y0: zero,
            my_x0y3: zero,
            my_x2y1: zero,
            my_x1y2: zero,
            my_x2y0: zero,
            my_x0y2: zero,
            my_x1y1: zero,
            my_x1y0: zero,
            my_x0y1: color_f_px * FREENECT2_COLOR_Q / (ir.fy * FREENECT2_DEPTH_Q),
            my_x0y0: zero,
        }
    }

    fn values(&self) -> [f32; 26] {
        [
            self.fx,
            self.fy,
            self.cx,
            self.cy,
            self.shift_d,
            self.shift_m,
            self.mx_x3y0,
            self.mx_x0y3,
            self.mx_x2y1,
            self.mx_x1y2,
            self.mx_x2y0,
            self.mx_x0y2,
            self.mx_x1y1,
            self.mx_x1y0,
            self.mx_x0y1,
            self.mx_x0y0,
            self.my_x3y0,
            self.my_x0y3,
            self.my_x2y1,
            self.my_x1y2,
            self.my_x2y0,
            self.my_x0y2,
            self.my_x1y1,
            self.my_x1y0,
            self.my_x0y1,
            self.my_x0y0,
        ]
    }
}

/// The precomputed maps of libfreenect2's registration.
#[derive(Debug, Clone)]
pub struct Freenect2Registration {
    ir: Freenect2IrParams,
    color: Freenect2ColorParams,
    /// Flat index of the distorted depth pixel each undistorted pixel samples, or -1.
    distort_map: Vec<i32>,
    /// Colour x before the disparity term, per undistorted depth pixel.
    map_x: Vec<f32>,
    /// Rounded colour row per undistorted depth pixel.
    map_yi: Vec<i32>,
    filter_map: Vec<f32>,
    color_offsets: Vec<i32>,
}

/// What [`Freenect2Registration::apply`] produces: libfreenect2's `undistorted` and
/// `registered` frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Freenect2Frame {
    /// Depth in millimetres on the undistorted 512x424 grid; 0 where there is none.
    pub undistorted_mm: Vec<f32>,
    /// Colour of each undistorted depth pixel; `None` where libfreenect2 writes 0 (no depth,
    /// outside the colour image, or occluded).
    pub registered: Vec<Option<[u8; 3]>>,
}

impl Freenect2Registration {
    /// Precompute the maps from the factory parameters.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] when a parameter is not finite or a focal length,
    /// `shift_d` is zero.
    pub fn new(ir: Freenect2IrParams, color: Freenect2ColorParams) -> Result<Self> {
        if ir
            .values()
            .iter()
            .chain(color.values().iter())
            .any(|v| !v.is_finite())
        {
            return Err(KinectError::param(
                "libfreenect2 parameters",
                "every IR and colour parameter must be finite",
            ));
        }
        for (name, v) in [
            ("libfreenect2 ir.fx", ir.fx),
            ("libfreenect2 ir.fy", ir.fy),
            ("libfreenect2 color.fx", color.fx),
            ("libfreenect2 color.shift_d", color.shift_d),
        ] {
            if v == 0.0 {
                return Err(KinectError::param(name, "must not be zero"));
            }
        }
        let mut reg = Self {
            ir,
            color,
            distort_map: Vec::with_capacity(W * H),
            map_x: Vec::with_capacity(W * H),
            map_yi: Vec::with_capacity(W * H),
            filter_map: Vec::new(),
            color_offsets: vec![-1; W * H],
        };
        for y in 0..H {
            for x in 0..W {
                let (mx, my) = reg.distort(x as f32, y as f32);
                let ix = (mx + 0.5) as i32;
                let iy = (my + 0.5) as i32;
                let index = if ix < 0 || ix >= W as i32 || iy < 0 || iy >= H as i32 {
                    -1
                } else {
                    iy * W as i32 + ix
                };
                reg.distort_map.push(index);
                let (rx, ry) = reg.depth_to_color(x as f32, y as f32);
                reg.map_x.push(rx);
                reg.map_yi.push((ry + 0.5) as i32);
            }
        }
        Ok(reg)
    }

    /// The IR parameters.
    pub fn ir(&self) -> &Freenect2IrParams {
        &self.ir
    }

    /// The colour parameters.
    pub fn color(&self) -> &Freenect2ColorParams {
        &self.color
    }

    fn distort(&self, mx: f32, my: f32) -> (f32, f32) {
        let d = &self.ir;
        let dx = (mx - d.cx) / d.fx;
        let dy = (my - d.cy) / d.fy;
        let dx2 = dx * dx;
        let dy2 = dy * dy;
        let r2 = dx2 + dy2;
        let dxdy2 = 2.0 * dx * dy;
        let kr = 1.0 + ((d.k3 * r2 + d.k2) * r2 + d.k1) * r2;
        let x = d.fx * (dx * kr + d.p2 * (r2 + 2.0 * dx2) + d.p1 * dxdy2) + d.cx;
        let y = d.fy * (dy * kr + d.p1 * (r2 + 2.0 * dy2) + d.p2 * dxdy2) + d.cy;
        (x, y)
    }

    fn depth_to_color(&self, mx: f32, my: f32) -> (f32, f32) {
        let c = &self.color;
        let mx = (mx - self.ir.cx) * FREENECT2_DEPTH_Q;
        let my = (my - self.ir.cy) * FREENECT2_DEPTH_Q;
        let wx = cubic(
            [
                c.mx_x3y0, c.mx_x0y3, c.mx_x2y1, c.mx_x1y2, c.mx_x2y0, c.mx_x0y2, c.mx_x1y1,
                c.mx_x1y0, c.mx_x0y1, c.mx_x0y0,
            ],
            mx,
            my,
        );
        let wy = cubic(
            [
                c.my_x3y0, c.my_x0y3, c.my_x2y1, c.my_x1y2, c.my_x2y0, c.my_x0y2, c.my_x1y1,
                c.my_x1y0, c.my_x0y1, c.my_x0y0,
            ],
            mx,
            my,
        );
        let rx = (wx / (c.fx * FREENECT2_COLOR_Q)) - (c.shift_m / c.shift_d);
        let ry = (wy / FREENECT2_COLOR_Q) + c.cy;
        (rx, ry)
    }

    /// Sub-pixel colour position of undistorted depth pixel `(x, y)` at depth `z_mm`
    /// (libfreenect2 `Registration::apply(dx, dy, dz, cx, cy)`); `None` outside the depth grid.
    pub fn color_position(&self, x: u32, y: u32, z_mm: f32) -> Option<(f32, f32)> {
        if x as usize >= W || y as usize >= H {
            return None;
        }
        let (rx, ry) = self.depth_to_color(x as f32, y as f32);
        let rx = rx + self.color.shift_m / z_mm;
        Some((rx * self.color.fx + self.color.cx, ry))
    }

    /// Register one frame: depth in millimetres (512x424 raw, distorted grid, `f32` as
    /// libfreenect2's depth frames are), colour 1920x1080. With `filter`, colours that the
    /// colour camera cannot see (occluded) are dropped, as libfreenect2's `enable_filter`.
    ///
    /// # Errors
    /// [`KinectError::SizeMismatch`] when the depth or colour size is not the Kinect V2's.
    pub fn apply(
        &mut self,
        depth_mm: &[f32],
        color: &RgbImage,
        filter: bool,
    ) -> Result<Freenect2Frame> {
        let mut out = Freenect2Frame {
            undistorted_mm: vec![0.0; W * H],
            registered: vec![None; W * H],
        };
        self.apply_into(depth_mm, color, filter, &mut out)?;
        Ok(out)
    }

    /// [`Freenect2Registration::apply`] into existing buffers (no allocation per frame once
    /// the buffers have their size).
    ///
    /// # Errors
    /// As [`Freenect2Registration::apply`].
    pub fn apply_into(
        &mut self,
        depth_mm: &[f32],
        color: &RgbImage,
        filter: bool,
        out: &mut Freenect2Frame,
    ) -> Result<()> {
        if depth_mm.len() != W * H {
            return Err(KinectError::SizeMismatch {
                what: "libfreenect2 depth frame".into(),
                expected_width: W as u32,
                expected_height: H as u32,
                found_width: depth_mm.len() as u32,
                found_height: 1,
            });
        }
        if color.dimensions() != (CW as u32, CH as u32) {
            return Err(KinectError::SizeMismatch {
                what: "libfreenect2 colour frame".into(),
                expected_width: CW as u32,
                expected_height: CH as u32,
                found_width: color.width(),
                found_height: color.height(),
            });
        }
        out.undistorted_mm.resize(W * H, 0.0);
        out.registered.resize(W * H, None);
        let half_h = FREENECT2_FILTER_HALF_HEIGHT_PX;
        let half_w = FREENECT2_FILTER_HALF_WIDTH_PX;
        let offset_filter = CW as i64 * i64::from(half_h);
        if filter {
            self.filter_map.clear();
            self.filter_map
                .resize(CW * CH + CW * 2 * half_h as usize, 65536.0);
        }
        let color_cx = self.color.cx + 0.5;
        let size_color = (CW * CH) as i64;
        for i in 0..W * H {
            self.color_offsets[i] = -1;
            let index = self.distort_map[i];
            if index < 0 {
                out.undistorted_mm[i] = 0.0;
                continue;
            }
            let z = depth_mm[index as usize];
            out.undistorted_mm[i] = z;
            if z.is_nan() || z <= 0.0 {
                // libfreenect2 tests `z <= 0`; a NaN depth is treated as missing here too.
                out.undistorted_mm[i] = if z.is_nan() { 0.0 } else { z };
                continue;
            }
            let rx = (self.map_x[i] + (self.color.shift_m / z)) * self.color.fx + color_cx;
            let cx = rx as i32;
            let cy = self.map_yi[i];
            let c_off = i64::from(cx) + i64::from(cy) * CW as i64;
            if c_off < 0 || c_off >= size_color {
                continue;
            }
            self.color_offsets[i] = c_off as i32;
            if filter {
                for r in -half_h..=half_h {
                    let row_start =
                        offset_filter + (i64::from(cy) + i64::from(r)) * CW as i64 + i64::from(cx)
                            - i64::from(half_w);
                    for c in 0..=(2 * half_w) {
                        let at = row_start + i64::from(c);
                        if let Some(slot) = usize::try_from(at)
                            .ok()
                            .and_then(|at| self.filter_map.get_mut(at))
                            && z < *slot
                        {
                            *slot = z;
                        }
                    }
                }
            }
        }
        let raw = color.as_raw();
        for i in 0..W * H {
            let c_off = self.color_offsets[i];
            out.registered[i] = if c_off < 0 {
                None
            } else {
                let c = c_off as usize;
                if filter {
                    let min_z = self.filter_map[offset_filter as usize + c];
                    let z = out.undistorted_mm[i];
                    if (z - min_z) / z > FREENECT2_FILTER_TOLERANCE {
                        None
                    } else {
                        Some([raw[3 * c], raw[3 * c + 1], raw[3 * c + 2]])
                    }
                } else {
                    Some([raw[3 * c], raw[3 * c + 1], raw[3 * c + 2]])
                }
            };
        }
        Ok(())
    }
}

/// The cubic of libfreenect2's depth-to-colour map, coefficients in the order
/// `x3y0 x0y3 x2y1 x1y2 x2y0 x0y2 x1y1 x1y0 x0y1 x0y0`, summed in libfreenect2's order (which
/// matters in `f32`).
#[inline]
fn cubic(c: [f32; 10], mx: f32, my: f32) -> f32 {
    (mx * mx * mx * c[0])
        + (my * my * my * c[1])
        + (mx * mx * my * c[2])
        + (my * my * mx * c[3])
        + (mx * mx * c[4])
        + (my * my * c[5])
        + (mx * my * c[6])
        + (mx * c[7])
        + (my * c[8])
        + c[9]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distortion-free IR parameters, so that pinhole comparisons are exact.
    fn ir() -> Freenect2IrParams {
        Freenect2IrParams {
            k1: 0.0,
            k2: 0.0,
            k3: 0.0,
            ..Freenect2IrParams::kinect_v2_typical()
        }
    }

    #[test]
    fn pinhole_baseline_parameters_give_the_pinhole_projection() {
        let ir = ir();
        let color = Freenect2ColorParams::from_pinhole_baseline(&ir, 1081.37, 959.5, 539.5, 52.0);
        let reg = Freenect2Registration::new(ir, color).expect("valid");
        // A point at depth 2000 mm seen at depth pixel (300, 100).
        let (x, y, z_mm) = (300.0_f64, 100.0_f64, 2000.0_f64);
        let x_m = (x - 256.0) / 365.5 * z_mm;
        let y_m = (y - 207.0) / 365.5 * z_mm;
        let expected_x = 1081.37 * (x_m + 52.0) / z_mm + 959.5;
        let expected_y = 1081.37 * y_m / z_mm + 539.5;
        let (cx, cy) = reg.color_position(300, 100, 2000.0).expect("inside");
        assert!(
            (f64::from(cx) - expected_x).abs() < 0.01,
            "{cx} vs {expected_x}"
        );
        assert!(
            (f64::from(cy) - expected_y).abs() < 0.01,
            "{cy} vs {expected_y}"
        );
    }

    #[test]
    fn the_filter_drops_colours_behind_a_nearer_surface() {
        let ir = ir();
        let color = Freenect2ColorParams::from_pinhole_baseline(&ir, 1081.37, 959.5, 539.5, 52.0);
        let mut reg = Freenect2Registration::new(ir, color).expect("valid");
        let mut depth = vec![2000.0_f32; W * H];
        // A near object (1 m) on a strip of columns: the colour camera, 52 mm to the side,
        // sees it in front of background pixels next to it.
        for y in 0..H {
            for x in 200..230 {
                depth[y * W + x] = 1000.0;
            }
        }
        let colour = RgbImage::from_pixel(CW as u32, CH as u32, image::Rgb([9, 8, 7]));
        let unfiltered = reg.apply(&depth, &colour, false).expect("sizes");
        let filtered = reg.apply(&depth, &colour, true).expect("sizes");
        let count = |f: &Freenect2Frame| f.registered.iter().filter(|c| c.is_some()).count();
        assert!(count(&filtered) < count(&unfiltered));
        // Near pixels always keep their colour.
        assert!(filtered.registered[207 * W + 215].is_some());
        assert_eq!(unfiltered.undistorted_mm[207 * W + 215], 1000.0);
    }

    #[test]
    fn nan_and_zero_depth_give_no_point_and_no_colour() {
        let ir = ir();
        let color = Freenect2ColorParams::from_pinhole_baseline(&ir, 1081.37, 959.5, 539.5, 52.0);
        let mut reg = Freenect2Registration::new(ir, color).expect("valid");
        let mut depth = vec![f32::NAN; W * H];
        depth[..W].fill(0.0);
        let colour = RgbImage::from_pixel(CW as u32, CH as u32, image::Rgb([1, 2, 3]));
        let frame = reg.apply(&depth, &colour, true).expect("sizes");
        assert!(frame.undistorted_mm.iter().all(|&z| z == 0.0));
        assert!(frame.registered.iter().all(Option::is_none));
    }

    #[test]
    fn wrong_sizes_are_errors() {
        let ir = ir();
        let color = Freenect2ColorParams::from_pinhole_baseline(&ir, 1081.37, 959.5, 539.5, 52.0);
        let mut reg = Freenect2Registration::new(ir, color).expect("valid");
        let colour = RgbImage::new(640, 480);
        assert!(reg.apply(&vec![0.0; W * H], &colour, true).is_err());
        let colour = RgbImage::new(CW as u32, CH as u32);
        assert!(reg.apply(&[0.0; 10], &colour, true).is_err());
    }
}
