//! Ray casting for the synthetic camera: shapes moved into the camera frame with bounding
//! spheres, ray-shape intersections, and a tiled grid of ray cones that skips the shapes a
//! tile cannot see.

use super::*;

/// A shape moved into a camera frame, with a bounding sphere for quick rejection.
#[derive(Debug, Clone, Copy)]
pub(super) enum Local {
    Capsule {
        a: Vector3<f64>,
        b: Vector3<f64>,
        r: f64,
    },
    Sphere {
        c: Vector3<f64>,
        r: f64,
    },
    Disc {
        c: Vector3<f64>,
        n: Vector3<f64>,
        r: f64,
    },
    Plane {
        p: Vector3<f64>,
        n: Vector3<f64>,
    },
}

#[derive(Debug, Clone, Copy)]
pub(super) struct Object {
    shape: Local,
    rgb: [u8; 3],
    bound: Bound,
    marker: bool,
}

/// A bounding sphere: centre and radius.
type Bound = Option<(Vector3<f64>, f64)>;

pub(super) fn to_local(shape: &Shape, t: &Isometry3<f64>) -> Result<(Local, Bound)> {
    let finite = |v: f64, name: &'static str| {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(KinectError::param(
                name,
                format!("{v} m must be finite and positive"),
            ))
        }
    };
    Ok(match *shape {
        Shape::Capsule { a, b, radius_m } => {
            let r = finite(radius_m, "capsule radius")?;
            let (a, b) = ((t * a).coords, (t * b).coords);
            (
                Local::Capsule { a, b, r },
                Some(((a + b) * 0.5, (b - a).norm() * 0.5 + r)),
            )
        }
        Shape::Sphere { center, radius_m } => {
            let r = finite(radius_m, "sphere radius")?;
            let c = (t * center).coords;
            (Local::Sphere { c, r }, Some((c, r)))
        }
        Shape::Disc {
            center,
            normal,
            radius_m,
        } => {
            let r = finite(radius_m, "disc radius")?;
            let n = t * normal;
            let norm = n.norm();
            if !(norm.is_finite() && norm > 0.0) {
                return Err(KinectError::param(
                    "disc normal",
                    "must be a non-zero vector",
                ));
            }
            let c = (t * center).coords;
            (Local::Disc { c, n: n / norm, r }, Some((c, r)))
        }
    })
}

/// Distance along the unit ray `d` from the origin to the first hit, and the surface normal.
pub(super) fn intersect(shape: &Local, d: &Vector3<f64>) -> Option<(f64, Vector3<f64>)> {
    match *shape {
        Local::Sphere { c, r } => {
            let b = d.dot(&c);
            let h = b * b - (c.norm_squared() - r * r);
            if h < 0.0 {
                return None;
            }
            let t = b - h.sqrt();
            (t > 0.0).then(|| (t, (d * t - c) / r))
        }
        Local::Capsule { a, b, r } => {
            // Cylinder body then end caps (a standard capsule-ray intersection).
            let ba = b - a;
            let oa = -a;
            let baba = ba.dot(&ba);
            let bard = ba.dot(d);
            let baoa = ba.dot(&oa);
            let rdoa = d.dot(&oa);
            let oaoa = oa.dot(&oa);
            let qa = baba - bard * bard;
            let qb = baba * rdoa - baoa * bard;
            let qc = baba * oaoa - baoa * baoa - r * r * baba;
            let h = qb * qb - qa * qc;
            if h < 0.0 {
                return None;
            }
            let mut t = if qa.abs() > 1e-12 {
                (-qb - h.sqrt()) / qa
            } else {
                -1.0
            };
            let y = baoa + t * bard;
            if !(t > 0.0 && y > 0.0 && y < baba) {
                let oc = if y <= 0.0 { oa } else { -b };
                let cb = d.dot(&oc);
                let cc = oc.dot(&oc) - r * r;
                let ch = cb * cb - cc;
                if ch <= 0.0 {
                    return None;
                }
                t = -cb - ch.sqrt();
                if t <= 0.0 {
                    return None;
                }
            }
            let p = d * t;
            let s = ((p - a).dot(&ba) / baba).clamp(0.0, 1.0);
            Some((t, (p - a - ba * s) / r))
        }
        Local::Disc { c, n, r } => {
            let dn = d.dot(&n);
            if dn.abs() < 1e-12 {
                return None;
            }
            let t = c.dot(&n) / dn;
            (t > 0.0 && (d * t - c).norm_squared() <= r * r).then_some((t, n))
        }
        Local::Plane { p, n } => {
            let dn = d.dot(&n);
            if dn.abs() < 1e-12 {
                return None;
            }
            let t = p.dot(&n) / dn;
            (t > 0.0).then_some((t, n))
        }
    }
}

/// Cast one ray: nearest hit (depth along the optical axis, index of the object, normal).
pub(super) fn cast(objects: &[Object], d: &Vector3<f64>) -> Option<(f64, usize, Vector3<f64>)> {
    let mut best: Option<(f64, usize, Vector3<f64>)> = None;
    for (k, o) in objects.iter().enumerate() {
        if let Some((c, r)) = o.bound {
            let tc = d.dot(&c);
            if c.norm_squared() - tc * tc > r * r || tc < -r {
                continue;
            }
        }
        if let Some((t, n)) = intersect(&o.shape, d)
            && best.is_none_or(|b| t < b.0)
        {
            best = Some((t, k, n));
        }
    }
    best
}

pub(super) fn scene_objects(
    scene: &Scene,
    world_to_camera: &Isometry3<f64>,
) -> Result<Vec<Object>> {
    let mut objects = Vec::with_capacity(scene.primitives.len() + scene.markers.len() + 1);
    for p in &scene.primitives {
        let (shape, bound) = to_local(&p.shape, world_to_camera)?;
        objects.push(Object {
            shape,
            rgb: p.rgb,
            bound,
            marker: false,
        });
    }
    for m in &scene.markers {
        let (shape, bound) = to_local(
            &Shape::Disc {
                center: m.center_m,
                normal: m.normal,
                radius_m: m.radius_m,
            },
            world_to_camera,
        )?;
        objects.push(Object {
            shape,
            rgb: m.rgb,
            bound,
            marker: true,
        });
    }
    if let Some((height_m, rgb)) = scene.ground {
        if !height_m.is_finite() {
            return Err(KinectError::param("ground height", "is not finite"));
        }
        objects.push(Object {
            shape: Local::Plane {
                p: (world_to_camera * Point3::new(0.0, 0.0, height_m)).coords,
                n: world_to_camera * Vector3::z(),
            },
            rgb,
            bound: None,
            marker: false,
        });
    }
    Ok(objects)
}

/// Side of the square pixel tiles whose objects are culled together.
pub(super) const TILE_PX: u32 = 16;

/// A cone holding every ray of a tile: unit axis and half-angle (cos, sin).
#[derive(Debug, Clone, Copy)]
pub(super) struct Cone {
    axis: Vector3<f64>,
    cos: f64,
    sin: f64,
}

/// The rays of one camera, computed once: per pixel the unit ray (`None` where the
/// distortion cannot be inverted) and the factor from distance along the ray to depth along
/// the optical axis, and per tile a cone holding its rays.
#[derive(Debug, Clone)]
pub(super) struct RayGrid {
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) rays: Vec<Option<(Vector3<f64>, f64)>>,
    pub(super) tiles_x: u32,
    pub(super) cones: Vec<Option<Cone>>,
}

impl RayGrid {
    pub(super) fn new(camera: &CameraModel) -> Self {
        let (w, h) = (camera.width, camera.height);
        let mut rays = Vec::with_capacity(camera.pixel_count());
        for v in 0..h {
            for u in 0..w {
                rays.push(
                    camera
                        .unproject_normalized(&Point2::new(f64::from(u), f64::from(v)))
                        .map(|r| {
                            let d = Vector3::new(r.x, r.y, 1.0);
                            let len = d.norm();
                            (d / len, 1.0 / len)
                        }),
                );
            }
        }
        let tiles_x = w.div_ceil(TILE_PX);
        let tiles_y = h.div_ceil(TILE_PX);
        let mut cones = Vec::with_capacity((tiles_x * tiles_y) as usize);
        for ty in 0..tiles_y {
            for tx in 0..tiles_x {
                let tile_rays = || {
                    (ty * TILE_PX..((ty + 1) * TILE_PX).min(h)).flat_map(move |v| {
                        (tx * TILE_PX..((tx + 1) * TILE_PX).min(w))
                            .map(move |u| (v * w + u) as usize)
                    })
                };
                let sum: Vector3<f64> = tile_rays().filter_map(|i| rays[i].map(|r| r.0)).sum();
                let cone = sum.try_normalize(1e-12).map(|axis| {
                    let cos = tile_rays()
                        .filter_map(|i| rays[i].map(|r| r.0.dot(&axis)))
                        .fold(1.0f64, f64::min)
                        .clamp(-1.0, 1.0);
                    // Widen by a hair for rounding.
                    let angle = cos.acos() + 1e-9;
                    Cone {
                        axis,
                        cos: angle.cos(),
                        sin: angle.sin(),
                    }
                });
                cones.push(cone);
            }
        }
        Self {
            width: w,
            height: h,
            rays,
            tiles_x,
            cones,
        }
    }

    /// Indices of the objects some ray of `tile` may hit: those without a bound, those whose
    /// bounding sphere holds the camera, and those whose sphere's cone of view meets the
    /// tile's cone.
    pub(super) fn candidates(&self, tile: usize, objects: &[Object], out: &mut Vec<usize>) {
        out.clear();
        let Some(cone) = self.cones[tile] else {
            return;
        };
        for (k, o) in objects.iter().enumerate() {
            let Some((c, r)) = o.bound else {
                out.push(k);
                continue;
            };
            let dist = c.norm();
            if dist <= r {
                out.push(k);
                continue;
            }
            // Angle between the axis and the centre at most the cone's half-angle plus the
            // sphere's angular radius: cos(angle) >= cos(alpha + beta).
            let (sin_b, cos_b) = (r / dist, (1.0 - (r / dist).powi(2)).sqrt());
            let cos_sum = cone.cos * cos_b - cone.sin * sin_b;
            let sin_sum = cone.sin * cos_b + cone.cos * sin_b;
            // (alpha + beta beyond a half turn: sin_sum < 0; every direction is inside.)
            if sin_sum < 0.0 || cone.axis.dot(&c) >= cos_sum * dist {
                out.push(k);
            }
        }
    }
}

/// Ray-cast one camera: per pixel the depth along the optical axis (`None` for no hit) and,
/// optionally, the shaded colour.
pub(super) fn raycast(
    grid: &RayGrid,
    objects: &[Object],
    light_camera: &Vector3<f64>,
    sky: [u8; 3],
    mut color: Option<&mut RgbImage>,
) -> Vec<Option<f64>> {
    let (w, h) = (grid.width, grid.height);
    let mut depth = vec![None; grid.rays.len()];
    let mut candidates = Vec::with_capacity(objects.len());
    let mut local = Vec::with_capacity(objects.len());
    if let Some(img) = color.as_deref_mut() {
        for p in img.pixels_mut() {
            *p = image::Rgb(sky);
        }
    }
    for (tile, _) in grid.cones.iter().enumerate() {
        grid.candidates(tile, objects, &mut candidates);
        if candidates.is_empty() {
            continue;
        }
        local.clear();
        local.extend(candidates.iter().map(|&k| objects[k]));
        let (tx, ty) = (tile as u32 % grid.tiles_x, tile as u32 / grid.tiles_x);
        for v in ty * TILE_PX..((ty + 1) * TILE_PX).min(h) {
            for u in tx * TILE_PX..((tx + 1) * TILE_PX).min(w) {
                let i = (v * w + u) as usize;
                let Some((d, scale)) = grid.rays[i] else {
                    continue;
                };
                let Some((t, k, n)) = cast(&local, &d) else {
                    continue;
                };
                depth[i] = Some(t * scale);
                if let Some(img) = color.as_deref_mut() {
                    let n = if n.dot(&d) > 0.0 { -n } else { n };
                    let lambert = n.dot(light_camera).max(0.0);
                    let shade = if local[k].marker {
                        0.8 + 0.2 * lambert
                    } else {
                        AMBIENT + (1.0 - AMBIENT) * lambert
                    };
                    let rgb = local[k].rgb.map(|c| to_u8(f64::from(c) * shade));
                    img.put_pixel(u, v, image::Rgb(rgb));
                }
            }
        }
    }
    depth
}
