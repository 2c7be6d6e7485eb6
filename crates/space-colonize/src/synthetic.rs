//! Synthetic trees with a known skeleton, and the error of a reconstruction against it.
//!
//! [`SyntheticConfig::generate`] grows a seeded procedural tree (a bending trunk, side
//! branches to a chosen order, pipe-model radii), samples its cylinder surfaces like a scan
//! (uniform density, Gaussian noise, optionally seen from one side only or with a stretch
//! of trunk occluded) and returns both. [`skeleton_error`] compares a reconstructed skeleton
//! with the truth.

use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use nalgebra::{Point3, Vector3};
use rand_xoshiro::SplitMix64;
use rand_xoshiro::rand_core::{RngCore, SeedableRng};
use serde::Serialize;

use crate::error::{ColonizeError, Result};
use crate::skeleton::{Skeleton, SkeletonNode};

/// Node spacing of the generated skeletons, metres.
const TRUTH_STEP_M: f64 = 0.02;
/// Most points a synthetic cloud may hold (checked before allocating; a terrestrial laser
/// scan of a whole tree holds tens of millions).
pub const MAX_SYNTHETIC_POINTS: usize = 100_000_000;

/// Thinnest generated twig, metres (thinner ones would get almost no points).
const MIN_TWIG_RADIUS_M: f64 = 0.004;
/// Sampling step of skeletons in [`skeleton_error`], metres.
const ERROR_SAMPLE_M: f64 = 0.002;

/// What synthetic tree to make.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticConfig {
    /// Seed of all randomness.
    pub seed: u64,
    /// Trunk length, metres. Default 3.
    pub height_m: f64,
    /// Trunk radius at the base, metres. Default 0.05.
    pub base_radius_m: f64,
    /// Highest branch order. Default 3.
    pub max_order: usize,
    /// Points to sample (about). Default 20,000.
    pub points: usize,
    /// Standard deviation of the Gaussian noise added to each point, metres. Default 1 mm.
    pub noise_m: f64,
    /// Keep only surfaces facing a viewer looking along this direction (a single Kinect
    /// view). Default `None` (all around).
    pub view_direction: Option<Vector3<f64>>,
    /// Remove points with z in this range, metres (an occluded stretch). Default `None`.
    pub gap_z_m: Option<(f64, f64)>,
    /// Points on leaves, added after the wood's (about; 0, the default, is a leaf-off
    /// tree). Leaves are flat discs of [`LEAF_RADIUS_M`], [`LEAF_POINTS`] points each,
    /// turned at random and held by a stalk of up to [`LEAF_STALK_M`] from a random node of
    /// a twig thinner than [`LEAF_TWIG_RADIUS_M`]: a leafy crown to test that growth
    /// follows the wood. They get the same noise and no view or gap.
    pub leaf_points: usize,
}

/// Radius of a synthetic leaf, metres (a broad-leaved tree's leaf is 5–10 cm long).
pub const LEAF_RADIUS_M: f64 = 0.03;
/// Points per synthetic leaf.
pub const LEAF_POINTS: usize = 30;
/// Longest stalk between a twig and a synthetic leaf's centre, metres.
pub const LEAF_STALK_M: f64 = 0.06;
/// Leaves hang from twigs thinner than this, metres.
pub const LEAF_TWIG_RADIUS_M: f64 = 0.01;

impl Default for SyntheticConfig {
    fn default() -> Self {
        Self {
            seed: 7,
            height_m: 3.0,
            base_radius_m: 0.05,
            max_order: 3,
            points: 20_000,
            noise_m: 0.001,
            view_direction: None,
            gap_z_m: None,
            leaf_points: 0,
        }
    }
}

/// A synthetic tree: the true skeleton and the sampled points.
#[derive(Debug, Clone)]
pub struct SyntheticTree {
    /// The skeleton the points were sampled from.
    pub skeleton: Skeleton,
    /// The points, metres: first the wood's, then the leaves'.
    pub points: Vec<Point3<f64>>,
    /// How many of [`Self::points`] are on wood (the first ones); the rest are on leaves.
    pub wood_points: usize,
}

/// SplitMix64 (Steele, Lea, Flood 2014; `rand_xoshiro`'s, the workspace's one generator):
/// small, seedable, good enough for test data.
pub(crate) struct Rng(SplitMix64);

impl Rng {
    /// The generator seeded with `seed`.
    pub(crate) fn new(seed: u64) -> Self {
        Self(SplitMix64::seed_from_u64(seed))
    }
    fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }
    pub(crate) fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
    pub(crate) fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

fn unit_perpendicular(d: &Vector3<f64>) -> Vector3<f64> {
    let h = if d.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    d.cross(&h).normalize()
}

impl SyntheticConfig {
    /// Grow the tree and sample it.
    ///
    /// # Errors
    /// [`ColonizeError::InvalidParameter`] for a non-positive height, radius, point count, a
    /// negative noise, or more than [`MAX_SYNTHETIC_POINTS`] points or leaf points.
    pub fn generate(&self) -> Result<SyntheticTree> {
        self.check()?;
        let mut rng = Rng::new(self.seed);
        let mut positions: Vec<Point3<f64>> = vec![Point3::origin()];
        let mut parents: Vec<Option<usize>> = vec![None];
        // (start node, direction, length, order)
        let mut todo = vec![(0usize, Vector3::z(), self.height_m, 0usize)];
        while let Some((start, dir0, length, order)) = todo.pop() {
            let steps = (length / TRUTH_STEP_M).ceil().max(1.0) as usize;
            let mut dir = dir0;
            let mut at = start;
            let bend = unit_perpendicular(&dir0) * rng.range(-1.0, 1.0)
                + dir0.cross(&unit_perpendicular(&dir0)) * rng.range(-1.0, 1.0);
            let mut chain = Vec::with_capacity(steps);
            for k in 0..steps {
                // A gentle bend, and side branches tending upward.
                let curl = if order == 0 { 0.04 } else { 0.12 };
                dir = (dir + bend * (curl * TRUTH_STEP_M) + Vector3::z() * (0.02 * TRUTH_STEP_M))
                    .normalize();
                let p = positions[at] + dir * (length / steps as f64);
                positions.push(p);
                parents.push(Some(at));
                at = positions.len() - 1;
                chain.push((at, dir, k));
            }
            if order >= self.max_order {
                continue;
            }
            // Side branches: from 35 % of the trunk (15 % of a branch) on, every 12–25 % of
            // the length, rotating by the golden angle.
            let first = if order == 0 { 0.35 } else { 0.15 };
            let mut s = first + rng.range(0.0, 0.1);
            let mut azimuth = rng.range(0.0, std::f64::consts::TAU);
            while s < 0.9 {
                let k = ((s * steps as f64) as usize).min(steps - 1);
                let (node, d, _) = chain[k];
                let u = unit_perpendicular(&d);
                let v = d.cross(&u);
                let side = u * azimuth.cos() + v * azimuth.sin();
                let angle = rng.range(35.0_f64, 60.0).to_radians();
                let child_dir = (d * angle.cos() + side * angle.sin()).normalize();
                let remaining = length * (1.0 - s);
                let child_len =
                    remaining * rng.range(0.45, 0.7) * if order == 0 { 1.0 } else { 0.8 };
                if child_len > 4.0 * TRUTH_STEP_M {
                    todo.push((node, child_dir, child_len, order + 1));
                }
                azimuth += 2.399_963_229_728_653; // golden angle, rad
                s += rng.range(0.12, 0.25);
            }
        }
        // Pipe-model radii by carried length, exponent 2.5, floored at a thin twig.
        let flat = Skeleton::new(
            positions
                .iter()
                .enumerate()
                .map(|(id, p)| SkeletonNode {
                    id,
                    parent: parents[id],
                    position: *p,
                    radius_m: 0.0,
                })
                .collect(),
        )?;
        let w = flat.carried_length_m();
        let root = flat.root();
        let skeleton = Skeleton::new(
            flat.nodes()
                .iter()
                .map(|x| SkeletonNode {
                    radius_m: (self.base_radius_m * (w[x.id] / w[root]).powf(1.0 / 2.5))
                        .max(MIN_TWIG_RADIUS_M),
                    ..*x
                })
                .collect(),
        )?;
        let mut points = self.sample(&skeleton, &mut rng);
        let wood_points = points.len();
        points.extend(self.leaves(&skeleton, &mut rng));
        Ok(SyntheticTree {
            skeleton,
            points,
            wood_points,
        })
    }

    /// [`SyntheticConfig::leaf_points`] points on leaves (none when the tree has no twig
    /// thinner than [`LEAF_TWIG_RADIUS_M`]).
    fn leaves(&self, skeleton: &Skeleton, rng: &mut Rng) -> Vec<Point3<f64>> {
        let twigs: Vec<Point3<f64>> = skeleton
            .nodes()
            .iter()
            .filter(|x| x.parent.is_some() && x.radius_m < LEAF_TWIG_RADIUS_M)
            .map(|x| x.position)
            .collect();
        let count = self.leaf_points.div_ceil(LEAF_POINTS);
        if twigs.is_empty() || count == 0 {
            return Vec::new();
        }
        let mut out = Vec::with_capacity(count * LEAF_POINTS);
        let unit = |rng: &mut Rng| {
            loop {
                let v = Vector3::new(rng.normal(), rng.normal(), rng.normal());
                if let Some(u) = v.try_normalize(1e-6) {
                    break u;
                }
            }
        };
        for _ in 0..count {
            let at = twigs[(rng.next_u64() % twigs.len() as u64) as usize];
            let centre = at + unit(rng) * rng.range(LEAF_RADIUS_M, LEAF_STALK_M);
            let normal = unit(rng);
            let u = unit_perpendicular(&normal);
            let v = normal.cross(&u);
            for _ in 0..LEAF_POINTS {
                // Uniform on the disc.
                let r = LEAF_RADIUS_M * rng.uniform().sqrt();
                let phi = rng.range(0.0, std::f64::consts::TAU);
                let noise = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * self.noise_m;
                out.push(centre + (u * phi.cos() + v * phi.sin()) * r + noise);
            }
        }
        out
    }

    /// The config's values on their own ([`SyntheticConfig::generate`]'s errors).
    fn check(&self) -> Result<()> {
        let pos = |name: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(ColonizeError::param(name, format!("{v}; must be positive")))
            }
        };
        pos("height_m", self.height_m)?;
        pos("base_radius_m", self.base_radius_m)?;
        if self.points == 0 || self.points > MAX_SYNTHETIC_POINTS {
            return Err(ColonizeError::param(
                "points",
                format!("{}; must be 1 to {MAX_SYNTHETIC_POINTS}", self.points),
            ));
        }
        if self.leaf_points > MAX_SYNTHETIC_POINTS {
            return Err(ColonizeError::param(
                "leaf_points",
                format!(
                    "{}; must be at most {MAX_SYNTHETIC_POINTS}",
                    self.leaf_points
                ),
            ));
        }
        if !(self.noise_m.is_finite() && self.noise_m >= 0.0) {
            return Err(ColonizeError::param(
                "noise_m",
                format!("{}; must be zero or positive", self.noise_m),
            ));
        }
        Ok(())
    }

    fn sample(&self, skeleton: &Skeleton, rng: &mut Rng) -> Vec<Point3<f64>> {
        let nodes = skeleton.nodes();
        let area: f64 = nodes
            .iter()
            .map(|x| std::f64::consts::TAU * x.radius_m * skeleton.segment_length_m(x.id))
            .sum();
        // A one-sided view sees half the surface; sample twice as densely to keep the count.
        let visible = if self.view_direction.is_some() {
            0.5
        } else {
            1.0
        };
        let density = self.points as f64 / (area * visible);
        let view = self.view_direction.and_then(|v| v.try_normalize(1e-12));
        let mut out = Vec::with_capacity(self.points + self.points / 10);
        let mut carry = 0.0;
        for x in nodes {
            let Some(p) = x.parent else { continue };
            let a = nodes[p].position;
            let d = x.position - a;
            let len = d.norm();
            if len <= 0.0 {
                continue;
            }
            let axis = d / len;
            let u = unit_perpendicular(&axis);
            let v = axis.cross(&u);
            carry += density * std::f64::consts::TAU * x.radius_m * len;
            while carry >= 1.0 {
                carry -= 1.0;
                let t = rng.uniform() * len;
                let phi = rng.range(0.0, std::f64::consts::TAU);
                let normal = u * phi.cos() + v * phi.sin();
                if let Some(view) = view
                    && normal.dot(&view) >= 0.0
                {
                    continue;
                }
                let q = a + axis * t + normal * x.radius_m;
                let noise = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * self.noise_m;
                let q = q + noise;
                if let Some((z0, z1)) = self.gap_z_m
                    && q.z >= z0
                    && q.z <= z1
                {
                    continue;
                }
                out.push(q);
            }
        }
        out
    }
}

/// How far a reconstructed skeleton is from the true one.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SkeletonError {
    /// Mean distance from the model's axes to the true axes, metres (sampled every 2 mm).
    pub mean_skeleton_error_m: f64,
    /// 95th percentile of it, metres.
    pub p95_skeleton_error_m: f64,
    /// Mean distance from the true axes to the model's, metres.
    pub mean_truth_to_model_m: f64,
    /// Share of the true length within 2 cm of the model's axes.
    pub truth_length_found: f64,
    /// Model length / true length.
    pub length_ratio: f64,
    /// Model volume / true volume.
    pub volume_ratio: f64,
    /// Model radius at the base / true radius at the base.
    pub base_radius_ratio: f64,
}

fn axis_samples(s: &Skeleton) -> Vec<[f64; 3]> {
    let nodes = s.nodes();
    let mut out = Vec::new();
    for x in nodes {
        let Some(p) = x.parent else {
            out.push([x.position.x, x.position.y, x.position.z]);
            continue;
        };
        let a = nodes[p].position;
        let d = x.position - a;
        let k = (d.norm() / ERROR_SAMPLE_M).ceil().max(1.0) as usize;
        for i in 1..=k {
            let q = a + d * (i as f64 / k as f64);
            out.push([q.x, q.y, q.z]);
        }
    }
    out
}

fn base_radius(s: &Skeleton) -> f64 {
    let root = s.root();
    s.children(root)
        .iter()
        .map(|&c| s.nodes()[c].radius_m)
        .fold(0.0, f64::max)
}

/// Compare a reconstructed skeleton with the truth.
pub fn skeleton_error(model: &Skeleton, truth: &Skeleton) -> SkeletonError {
    let m = axis_samples(model);
    let t = axis_samples(truth);
    let nearest = |from: &[[f64; 3]], to: &[[f64; 3]]| -> Vec<f64> {
        let tree: ImmutableKdTree<f64, u32, 3, 32> = ImmutableKdTree::new_from_slice(to);
        from.iter()
            .map(|q| tree.nearest_one::<SquaredEuclidean>(q).distance.sqrt())
            .collect()
    };
    let mut mt = nearest(&m, &t);
    let tm = nearest(&t, &m);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let mean_m = mean(&mt);
    mt.sort_by(f64::total_cmp);
    let p95 = mt
        .get(((mt.len() as f64 - 1.0) * 0.95).round() as usize)
        .copied()
        .unwrap_or(f64::NAN);
    SkeletonError {
        mean_skeleton_error_m: mean_m,
        p95_skeleton_error_m: p95,
        mean_truth_to_model_m: mean(&tm),
        truth_length_found: tm.iter().filter(|&&d| d <= 0.02).count() as f64
            / tm.len().max(1) as f64,
        length_ratio: model.total_length_m() / truth.total_length_m(),
        volume_ratio: model.volume_m3() / truth.volume_m3(),
        base_radius_ratio: base_radius(model) / base_radius(truth),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leaves_hang_from_thin_twigs_after_the_same_wood() {
        let bare = SyntheticConfig {
            points: 3_000,
            ..Default::default()
        };
        let leafy = SyntheticConfig {
            leaf_points: 600,
            ..bare.clone()
        };
        let (b, l) = (bare.generate().unwrap(), leafy.generate().unwrap());
        // The wood is drawn first, so it is the same; then whole leaves.
        assert_eq!(l.points[..b.points.len()], b.points[..]);
        let leaves = &l.points[b.points.len()..];
        assert_eq!(leaves.len(), 600_usize.div_ceil(LEAF_POINTS) * LEAF_POINTS);
        // Every leaf point within stalk + leaf radius (+ noise) of a thin twig's node.
        let twigs: Vec<Point3<f64>> = l
            .skeleton
            .nodes()
            .iter()
            .filter(|x| x.parent.is_some() && x.radius_m < LEAF_TWIG_RADIUS_M)
            .map(|x| x.position)
            .collect();
        for q in leaves {
            let d = twigs
                .iter()
                .map(|t| (t - q).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(d < LEAF_STALK_M + LEAF_RADIUS_M + 0.01, "{d}");
        }
        let too_many = SyntheticConfig {
            leaf_points: MAX_SYNTHETIC_POINTS + 1,
            ..bare
        };
        assert!(matches!(
            too_many.generate(),
            Err(ColonizeError::InvalidParameter {
                name: "leaf_points",
                ..
            })
        ));
    }
}
