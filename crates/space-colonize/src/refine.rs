//! From the grown graph to a skeleton: tip completion, centring on the branch axis,
//! smoothing, pipe-model radii, and removal of growth artefacts.

use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use nalgebra::{Point3, Vector3};

use crate::circle::{centre_with_radius, fit_circle};
use crate::cloud::PointTree;
use crate::config::{ACROSS_RAY_MAX_RADIUS_M, ACROSS_RAY_RANGE_PER_RADIUS, Parameters};
use crate::error::Result;
use crate::skeleton::{Skeleton, SkeletonNode};

/// A circle fit moves a node only when it uses at least this many points.
const MIN_FIT_POINTS: usize = 6;
/// ... covers at least this share of the circle's 16 sectors (a one-sided view covers half).
const MIN_FIT_COVERAGE: f64 = 0.25;
/// ... and its RMS residual is below this share of its radius.
const MAX_FIT_RMS_PER_RADIUS: f64 = 0.35;
/// A fitted radius is trusted as a measurement with at least this many points,
const RELIABLE_FIT_POINTS: usize = 6;
/// ... covering at least this share of the circle (a one-sided view gives up to a half;
/// arcs of a quarter of the circle are where fits to points of two branches passed, with
/// radii up to 2.5 times the parent's on the leaf-off coffee tree),
const RELIABLE_FIT_COVERAGE: f64 = 0.4;
/// In a one-sided view, a fit covering at least this share of its circle (a ±45° arc) is
/// used too where the scan's noise is small against its radius
/// ([`SHORT_ARC_NOISE_PER_RADIUS`]). The pipeline's twin (a Kinect v2 rendered at 2.2 m,
/// silhouette pixels lost to flying pixels and the steady-pixel mask) sees its trunk over
/// ±45–50°: with fits only from 0.4 its radii came from the pipe model, 0.81 of the truth
/// on branches over 2 cm and 0.49–1.02 of the true volume over seeds 7–10.
const SHORT_ARC_COVERAGE: f64 = 0.25;
/// ... where the scan's noise (the median residual of the fits covering at least
/// [`RELIABLE_FIT_COVERAGE`]) is at most this share of the radius: the twin's 0.8 mm lets
/// branches from 11 mm in, the coffee views' 3.2–3.3 mm (6 mm of depth noise) keeps every
/// branch under 4.6 cm out (accepting their short arcs by their own residual, under 0.1 r,
/// put their volumes 1–6 points higher: a circle flattened by noise fits its arc closely;
/// 0.05 left the twin at ×0.88–1.15, 0.1 let the coffee views' trunks in, +0.1 to +1.3 L).
const SHORT_ARC_NOISE_PER_RADIUS: f64 = 0.07;
/// Fewest fits covering [`RELIABLE_FIT_COVERAGE`] for that noise to be known.
const SHORT_ARC_MIN_NOISE_FITS: usize = 10;
/// ... an RMS residual below this share of the radius,
const RELIABLE_FIT_RMS_PER_RADIUS: f64 = 0.35;
/// ... and a radius of at least this many point spacings (thinner ones are noise-bound).
const RELIABLE_FIT_SPACINGS: f64 = 0.5;
/// Fewest measured radii on a chain for a taper fit.
const MIN_TAPER_FITS: usize = 3;
/// Taubin smoothing: the shrinking step's weight λ and the inflating step's μ (Taubin 1995
/// suggests μ slightly beyond −λ; these pass-band values keep bends of a few nodes).
const TAUBIN_LAMBDA: f64 = 0.5;
/// See [`TAUBIN_LAMBDA`].
const TAUBIN_MU: f64 = -0.53;
/// Largest median ratio of fitted radii to the pure pipe model (or its inverse) for the
/// fits to be used: on the leaf-off coffee tree the median is 1.3; on the leafy
/// `adtree/tree13.xyz` 5.8 (circle fits to leaf clumps).
const MAX_FIT_PIPE_RATIO: f64 = 2.0;
/// With forks centred, a node's fitted radius is used only up to this many times the pipe
/// model's there scaled by the median ratio of fits to the pipe model; beyond, the node
/// takes its parent's ratio. A side branch's first nodes, once its fork sits on the
/// parent's axis, can fit circles through sparse points of several twigs around an empty
/// centre (on the coffee tree a 14 cm twig 1.7–2.7 cm thick on a 1.0 cm parent). Chosen
/// between 2, 3 and 4 on the coffee tree (volume +1 %, +1 %, +3 % against TreeQSM's, mean
/// point-to-surface 2.86, 2.76, 2.65 mm); at 4 the synthetic trees of the evaluation
/// are unchanged (axis error 7.60 → 7.65 mm, volume error 0.234 → 0.229).
pub(crate) const MAX_FIT_PER_PIPE_MEDIAN: f64 = 4.0;
/// Neighbouring forks passed on each side to find the chain nodes that set a fork's parent
/// axis. Stopping at the first (forks beside forks left as grown) gave the coffee tree
/// 2.65 mm and the synthetic evaluation trees 7.65 mm of axis error; passing up to 3,
/// 2.60 mm and 7.14 mm.
const FORK_WALK_STEPS: usize = 3;
/// In a one-sided view grown by colonization, a chain node is centred across the direction
/// from the node this many steps back to the one this many ahead (see [`Graph::tangent`]),
/// not from its parent to its child: nodes drawn to the seen half of a thick branch wander
/// sideways across it, and a cross-section taken across that wandering cuts the branch
/// lengthwise (on one coffee view a 35 mm limb was followed by a chain that turned sideways
/// for five nodes, measured 13–20 mm there, and the taper along it ran down to 8 mm). Chosen
/// among 1–4 on the coffee views and synthetic Kinect views (`docs/validation.md`). Full
/// scans keep 1 (at 3 the synthetic evaluation trees' axis error went 7.2 → 7.8 mm), and so
/// do level sets, whose nodes are patch centres (at 3 tree13 and Paris lost 0.2 points of
/// model near the cloud).
pub(crate) const ONE_SIDED_TANGENT_SPAN: usize = 3;
/// Loops of one-sided views (see [`Graph::straighten_loops`]): a chain drawn to the seen
/// half of a thick branch can swing across it and back, or over to a neighbouring branch
/// at a fork and back (on a synthetic 7 cm tree seen from one side, windows of 10 nodes on
/// branches over 1 cm whose path was more than 1.5 times their chord: 4–11 % of them; none
/// in the true skeletons). Nodes in a window.
const LOOP_WINDOW_NODES: usize = 6;
/// ... path length per chord above which a window is a loop (a real branch bending this much
/// over a few of its widths is rare).
const LOOP_PATH_PER_CHORD: f64 = 1.3;
/// ... and the least radius of the window's last node, metres: thin twigs are left to
/// centring and smoothing. The three were chosen among windows of 4–10 nodes and ratios
/// 1.2–1.5 on synthetic Kinect views of seeds 60–67 and checked on seeds 70–77, the coffee
/// views and the pipeline's twin (`docs/validation.md`). Full scans are not straightened:
/// there the synthetic evaluation trees' axis error went 7.2 → 8.3 mm.
const LOOP_MIN_RADIUS_M: f64 = 0.01;
/// Centring passes (the assignment of points to nodes is redone between them).
const CENTRING_PASSES: usize = 4;

/// How [`Graph::centre`] treats nodes without a circle, forks, and the branch direction.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Centring {
    /// Where no circle fits, move the node to its cross-section's centroid.
    pub centroid_fallback: bool,
    /// Centre the nodes next to forks and put forks on their parent's axis.
    pub near_forks: bool,
    /// Chain nodes each way over which the branch direction is taken (1: parent to child).
    pub span: usize,
}

/// The working graph: parents always before children.
#[derive(Debug, Clone)]
pub(crate) struct Graph {
    pub pos: Vec<Vector3<f64>>,
    pub parent: Vec<Option<usize>>,
    /// Nodes of straight bridges across gaps (the rest were grown or extended).
    pub bridge: Vec<bool>,
}

impl Graph {
    pub(crate) fn children(&self) -> Vec<Vec<usize>> {
        let mut c = vec![Vec::new(); self.pos.len()];
        for (i, p) in self.parent.iter().enumerate() {
            if let Some(p) = p {
                c[*p].push(i);
            }
        }
        c
    }

    /// Each point's nearest node, as lists per node (CSR: `start[i]..start[i + 1]` in `items`).
    fn assign(&self, pts: &[[f64; 3]], keep: &[bool]) -> Assignment {
        let nodes: Vec<[f64; 3]> = self.pos.iter().map(|p| [p.x, p.y, p.z]).collect();
        let tree: ImmutableKdTree<f64, u32, 3, 32> = ImmutableKdTree::new_from_slice(&nodes);
        let owner: Vec<u32> = pts
            .iter()
            .zip(keep)
            .map(|(q, &k)| {
                if k {
                    tree.nearest_one::<SquaredEuclidean>(q).item
                } else {
                    u32::MAX
                }
            })
            .collect();
        let mut start = vec![0usize; self.pos.len() + 1];
        for &o in &owner {
            if o != u32::MAX {
                start[o as usize + 1] += 1;
            }
        }
        for i in 0..self.pos.len() {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; start[self.pos.len()]];
        for (i, &o) in owner.iter().enumerate() {
            if o != u32::MAX {
                items[fill[o as usize]] = i as u32;
                fill[o as usize] += 1;
            }
        }
        Assignment { start, items }
    }

    /// Unit direction of the branch at a node: at a chain node (one parent, one child) from
    /// the node `span` steps back to the one `span` steps ahead along the chain (fewer where
    /// the chain ends at a fork or tip; `span` 1: parent to child), else from its parent to
    /// it, else (the root) to its first child.
    fn tangent(&self, i: usize, children: &[Vec<usize>], span: usize) -> Option<Vector3<f64>> {
        let d = match (self.parent[i], children[i].as_slice()) {
            (Some(p), [c]) => {
                // Up to `span` nodes each way along the chain (not past a fork).
                let (mut back, mut ahead) = (p, *c);
                for _ in 1..span {
                    if let (Some(pp), [_]) = (self.parent[back], children[back].as_slice()) {
                        back = pp;
                    }
                    if let [cc] = children[ahead].as_slice() {
                        ahead = *cc;
                    }
                }
                self.pos[ahead] - self.pos[back]
            }
            (Some(p), _) => self.pos[i] - self.pos[p],
            (None, [c, ..]) => self.pos[*c] - self.pos[i],
            (None, []) => return None,
        };
        d.try_normalize(1e-12)
    }

    /// Extend each tip from index `from` on along its direction to the farthest point it owns.
    pub(crate) fn extend_tips(
        &mut self,
        pts: &[[f64; 3]],
        keep: &[bool],
        p: &Parameters,
        from: usize,
    ) {
        let a = self.assign(pts, keep);
        let children = self.children();
        let tips: Vec<usize> = (from..self.pos.len())
            .filter(|&i| children[i].is_empty() && self.parent[i].is_some())
            .collect();
        for t in tips {
            let Some(dir) = self.tangent(t, &children, 1) else {
                continue;
            };
            let base = self.pos[t];
            let mut reach = 0.0_f64;
            for &q in a.of(t) {
                let v = Vector3::from(pts[q as usize]) - base;
                let s = v.dot(&dir);
                if s > 0.0 && (v - s * dir).norm() < p.kill_distance_m {
                    reach = reach.max(s);
                }
            }
            if reach < 0.5 * p.step_m {
                continue;
            }
            let steps = (reach / p.step_m).ceil().max(1.0);
            let mut parent = t;
            for k in 1..=(steps as usize) {
                self.pos.push(base + dir * (reach * k as f64 / steps));
                self.parent.push(Some(parent));
                self.bridge.push(false);
                parent = self.pos.len() - 1;
            }
        }
    }

    /// The child of fork `i` that carries on its parent branch: the one whose direction from
    /// the fork is nearest the direction into it.
    fn continuation(&self, i: usize, children: &[Vec<usize>]) -> Option<usize> {
        let into = (self.pos[i] - self.pos[self.parent[i]?]).try_normalize(1e-12)?;
        let along = |c: usize| {
            (self.pos[c] - self.pos[i])
                .try_normalize(1e-12)
                .map_or(f64::NEG_INFINITY, |d| d.dot(&into))
        };
        children[i]
            .iter()
            .copied()
            .max_by(|&x, &y| along(x).total_cmp(&along(y)))
    }

    /// The points a node and its chain neighbours own, in the plane across the branch at
    /// the node (coordinates along `u` and `v`, origin at the node). With `skip_forks` a
    /// neighbour that is a fork gives none (its points belong to two branches).
    fn cross_section(
        &self,
        i: usize,
        (a, pts): (&Assignment, &[[f64; 3]]),
        children: &[Vec<usize>],
        plane: &mut Vec<[f64; 2]>,
        skip_forks: bool,
        span: usize,
    ) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let t = self.tangent(i, children, span)?;
        let (u, v) = crate::geometry::across(&t);
        plane.clear();
        let o = self.pos[i];
        let mut add = |n: usize| {
            for &q in a.of(n) {
                let d = Vector3::from(pts[q as usize]) - o;
                plane.push([d.dot(&u), d.dot(&v)]);
            }
        };
        let own = |n: usize| !(skip_forks && children[n].len() > 1);
        add(i);
        if let Some(par) = self.parent[i].filter(|&n| own(n)) {
            add(par);
        }
        for &c in children[i].iter().filter(|&&n| own(n)) {
            add(c);
        }
        Some((u, v))
    }

    /// Move nodes from index `from` on onto the branch axis: a circle fitted to the points a node and its
    /// neighbours own, in the plane across the branch (taken over `how.span` chain nodes each
    /// way, see [`Self::tangent`]); where no circle fits (thin branches), the centroid of those
    /// points if `how.centroid_fallback`, else the node stays.
    ///
    /// The root stays where it is: it is the centre of the circle fitted to the trunk's
    /// lowest points (or the user's root), and its cross-section, taken across the
    /// direction to its child, tilts as that child is centred. On a synthetic tree seen from
    /// one side the root so climbed 9 cm up the trunk in four passes, off the base, and the
    /// twig pass grew 1.5 m of twigs around the base it left bare.
    ///
    /// A fork's points belong to two branches. Without `how.near_forks`, forks and the nodes
    /// next to them stay where growth put them; with it, the nodes next to a fork are
    /// centred on their own points and their other neighbour's, and the fork is put on its
    /// parent branch's axis (see [`Self::forks_onto_axes`]).
    #[allow(clippy::needless_range_loop)] // `i` is also the node passed to the helpers
    pub(crate) fn centre(
        &mut self,
        pts: &[[f64; 3]],
        keep: &[bool],
        p: &Parameters,
        from: usize,
        how: Centring,
    ) {
        for _ in 0..CENTRING_PASSES {
            let a = self.assign(pts, keep);
            let children = self.children();
            let mut moved = self.pos.clone();
            let mut plane: Vec<[f64; 2]> = Vec::new();
            // The radius of each node's fitted circle this pass (0 where none was fitted).
            let mut axis_radius = vec![0.0; self.pos.len()];
            for i in from..self.pos.len() {
                if self.parent[i].is_none() {
                    continue; // the root stays on the trunk's fitted base
                }
                let by_fork = near_fork(i, &self.parent, &children);
                if by_fork && (!how.near_forks || children[i].len() > 1) {
                    continue; // forks mix the points of two branches
                }
                let Some((u, v)) =
                    self.cross_section(i, (&a, pts), &children, &mut plane, by_fork, how.span)
                else {
                    continue;
                };
                if plane.is_empty() {
                    continue;
                }
                let circle = fit_circle(&plane).filter(|c| usable(c, p));
                let centre = match circle {
                    Some(c) => c.centre,
                    None if !how.centroid_fallback => continue,
                    // Too few points or too thin for a circle: the centroid of the cross
                    // section, which is on the axis of a branch about a spacing thick.
                    None => {
                        let k = plane.len() as f64;
                        [
                            plane.iter().map(|q| q[0]).sum::<f64>() / k,
                            plane.iter().map(|q| q[1]).sum::<f64>() / k,
                        ]
                    }
                };
                let reach = circle.map_or(0.0, |c| c.radius_m);
                if by_fork && !no_farther(&plane, centre, reach) {
                    continue;
                }
                axis_radius[i] = reach;
                moved[i] += u * centre[0] + v * centre[1];
            }
            if how.near_forks {
                self.forks_onto_axes(&mut moved, &children, from, &a, pts, &axis_radius);
            }
            self.pos = moved;
        }
    }

    /// Each fork from index `from` on onto its parent branch's axis, the line through its
    /// nearest chain nodes before and after it along that branch (past at most
    /// [`FORK_WALK_STEPS`] neighbouring forks each way) as `moved` holds them: growth
    /// splits a branch late, so a fork sits beside the axis toward its side branch, and the
    /// parent's nodes on either side of it, once centred, kink toward it. TreeQSM likewise
    /// starts a side branch on its parent's axis.
    ///
    /// A fork is not moved farther from the points it and those neighbours own than it
    /// was, unless it stays within their fitted radius (`axis_radius`) of one: a late
    /// fork of twigs moved onto a line through two noisy nodes can land in the air.
    fn forks_onto_axes(
        &self,
        moved: &mut [Vector3<f64>],
        children: &[Vec<usize>],
        from: usize,
        a: &Assignment,
        pts: &[[f64; 3]],
        axis_radius: &[f64],
    ) {
        for i in from..self.pos.len() {
            if children[i].len() < 2 {
                continue;
            }
            let (Some(par), Some(c)) = (self.parent[i], self.continuation(i, children)) else {
                continue;
            };
            // Past neighbouring forks (a branch splitting into several at successive
            // nodes) to the nearest chain nodes on either side.
            let (mut par, mut c) = (par, c);
            for _ in 0..FORK_WALK_STEPS {
                if children[par].len() > 1 {
                    par = self.parent[par].unwrap_or(par);
                }
                if children[c].len() > 1 {
                    c = self.continuation(c, children).unwrap_or(c);
                }
            }
            if children[c].len() > 1 || children[par].len() > 1 {
                continue;
            }
            let start = moved[par];
            let Some(axis) = (moved[c] - start).try_normalize(1e-12) else {
                continue;
            };
            let onto = start + axis * (self.pos[i] - start).dot(&axis);
            let nearest = |x: Vector3<f64>| {
                [i, par, c]
                    .iter()
                    .flat_map(|&n| a.of(n))
                    .map(|&q| (Vector3::from(pts[q as usize]) - x).norm())
                    .fold(f64::INFINITY, f64::min)
            };
            let (before, after) = (nearest(self.pos[i]), nearest(onto));
            if after <= before.max(axis_radius[par].max(axis_radius[c])) {
                moved[i] = onto;
            }
        }
    }

    /// Move nodes (not the root, forks or their neighbours) onto the axis of a circle of the model's
    /// radius through their cross-section (a least-squares cylinder of known radius), in
    /// [`CENTRING_PASSES`] passes. After the radii are known this places thin branches
    /// of one-sided views, where [`Self::centre`] has only centroids.
    pub(crate) fn centre_on_radius(
        &mut self,
        pts: &[[f64; 3]],
        keep: &[bool],
        radius_m: &[f64],
        span: usize,
    ) {
        for _ in 0..CENTRING_PASSES {
            let a = self.assign(pts, keep);
            let children = self.children();
            let mut moved = self.pos.clone();
            let mut plane: Vec<[f64; 2]> = Vec::new();
            for (i, m) in moved.iter_mut().enumerate() {
                if self.parent[i].is_none() || near_fork(i, &self.parent, &children) {
                    continue;
                }
                let Some((u, v)) =
                    self.cross_section(i, (&a, pts), &children, &mut plane, false, span)
                else {
                    continue;
                };
                if let Some(c) = centre_with_radius(&plane, radius_m[i]) {
                    *m += u * c[0] + v * c[1];
                }
            }
            self.pos = moved;
        }
    }

    /// Radius measured at each node where a circle fits its cross-section well (see
    /// [`RELIABLE_FIT_POINTS`]), median-filtered along the branch; `None` elsewhere.
    pub(crate) fn fit_radii(
        &self,
        pts: &[[f64; 3]],
        keep: &[bool],
        p: &Parameters,
    ) -> Vec<Option<f64>> {
        let a = self.assign(pts, keep);
        let children = self.children();
        let mut plane: Vec<[f64; 2]> = Vec::new();
        // Each node's circle (before the coverage test) and its width across the ray.
        let measured: Vec<Option<(crate::circle::Circle, Option<f64>)>> = (0..self.pos.len())
            .map(|i| {
                if children[i].len() > 1 {
                    return None;
                }
                let (u, v) = self.cross_section(i, (&a, pts), &children, &mut plane, false, 1)?;
                let fit = fit_circle(&plane).filter(|c| usable(c, p)).filter(|c| {
                    c.points >= RELIABLE_FIT_POINTS
                        && c.rms_m < RELIABLE_FIT_RMS_PER_RADIUS * c.radius_m
                        && c.radius_m >= RELIABLE_FIT_SPACINGS * p.spacing_m
                        && c.centre[0].hypot(c.centre[1]) < 0.5 * c.radius_m
                })?;
                // With the camera known, a thin branch is also measured across the view
                // ray, where depth noise does not widen it as it widens the circle fit.
                let across = p
                    .camera_m
                    .filter(|_| fit.radius_m < ACROSS_RAY_MAX_RADIUS_M)
                    .and_then(|camera| {
                        across_ray_radius(
                            &plane,
                            self.pos[i],
                            u.cross(&v),
                            (u, v),
                            camera,
                            p.spacing_m,
                        )
                    });
                Some((fit, across))
            })
            .collect();
        // The scan's noise: the median residual of the circles that cover enough of their
        // branch. A one-sided view's short arcs (a camera whose silhouette pixels are lost
        // sees a branch over ±45°) measure a radius only where that noise is small against
        // it (an arc's sagitta is 0.29 r at ±45°).
        let mut full_rms: Vec<f64> = measured
            .iter()
            .flatten()
            .filter(|(c, _)| c.coverage >= RELIABLE_FIT_COVERAGE)
            .map(|(c, _)| c.rms_m)
            .collect();
        full_rms.sort_by(f64::total_cmp);
        let noise_m =
            (full_rms.len() >= SHORT_ARC_MIN_NOISE_FITS).then(|| full_rms[full_rms.len() / 2]);
        let raw: Vec<Option<f64>> = measured
            .iter()
            .map(|m| {
                let (c, across) = m.as_ref()?;
                let covered = c.coverage >= RELIABLE_FIT_COVERAGE
                    || (p.one_sided
                        && c.coverage >= SHORT_ARC_COVERAGE
                        && noise_m.is_some_and(|n| n <= SHORT_ARC_NOISE_PER_RADIUS * c.radius_m));
                covered.then(|| across.map_or(c.radius_m, |r| c.radius_m.min(r)))
            })
            .collect();
        self.taper_fit(&raw, &children)
    }

    /// Radii per chain (the nodes between two forks): a straight taper r(s) = a + b·s fitted
    /// to the chain's measured radii by least squares, once more without those beyond 2.5
    /// median absolute deviations, with b ≤ 0 (a branch does not thicken toward its tip; a
    /// rising fit becomes the median). Before the chain's first measured node and after its
    /// last the radius is held at the line's value there, not extrapolated (a chain measured
    /// only near its top could otherwise run to several times its width at its base). Chains
    /// with fewer than [`MIN_TAPER_FITS`] measurements stay unmeasured.
    fn taper_fit(&self, raw: &[Option<f64>], children: &[Vec<usize>]) -> Vec<Option<f64>> {
        let n = self.pos.len();
        let mut out = vec![None; n];
        for first in 0..n {
            let starts = self.parent[first].is_none_or(|p| children[p].len() != 1);
            if !starts {
                continue;
            }
            let mut chain = vec![first];
            let mut v = first;
            while let [c] = children[v].as_slice() {
                chain.push(*c);
                v = *c;
            }
            let mut s = 0.0;
            let mut samples: Vec<(f64, f64)> = Vec::new();
            for (k, &v) in chain.iter().enumerate() {
                if k > 0 {
                    s += (self.pos[v] - self.pos[chain[k - 1]]).norm();
                }
                if let Some(r) = raw[v] {
                    samples.push((s, r));
                }
            }
            if samples.len() < MIN_TAPER_FITS {
                continue;
            }
            let Some((a, b)) = robust_taper(&samples) else {
                continue;
            };
            let (first_s, last_s) = (samples[0].0, samples[samples.len() - 1].0);
            let mut s = 0.0;
            for (k, &v) in chain.iter().enumerate() {
                if k > 0 {
                    s += (self.pos[v] - self.pos[chain[k - 1]]).norm();
                }
                let r = a + b * s.clamp(first_s, last_s);
                if r > 0.0 {
                    out[v] = Some(r);
                }
            }
        }
        out
    }

    /// Smoothing of chain nodes (one parent, one child) from index `from` on. Plain
    /// Laplacian steps of weight λ with `taubin` false; with `taubin` true each is followed
    /// by one of weight μ < −λ, which removes zig-zag without the shrinking of plain
    /// Laplacian smoothing (Taubin 1995). Forks, tips and the root stay.
    pub(crate) fn smooth_from(&mut self, passes: usize, from: usize, taubin: bool) {
        let children = self.children();
        let weights: &[f64] = if taubin {
            &[TAUBIN_LAMBDA, TAUBIN_MU]
        } else {
            &[TAUBIN_LAMBDA]
        };
        for _ in 0..passes {
            for &w in weights {
                let mut next = self.pos.clone();
                for i in from..self.pos.len() {
                    if let (Some(par), [c]) = (self.parent[i], children[i].as_slice()) {
                        let mid = (self.pos[par] + self.pos[*c]) * 0.5;
                        next[i] = self.pos[i] + (mid - self.pos[i]) * w;
                    }
                }
                self.pos = next;
            }
        }
    }

    /// Straighten loops: where the path from a node [`LOOP_WINDOW_NODES`] steps up toward the
    /// root is more than [`LOOP_PATH_PER_CHORD`] times as long as the straight line between
    /// its ends, and the node is at least [`LOOP_MIN_RADIUS_M`] thick (`radius_m`, per node),
    /// the nodes between are put on that line at their share of the path (side branches
    /// stay attached to them). Returns the number of windows straightened.
    pub(crate) fn straighten_loops(&mut self, radius_m: &[f64]) -> usize {
        let (window, ratio, min_radius_m) =
            (LOOP_WINDOW_NODES, LOOP_PATH_PER_CHORD, LOOP_MIN_RADIUS_M);
        let mut count = 0;
        let mut path: Vec<usize> = Vec::with_capacity(window + 1);
        for j in 0..self.pos.len() {
            if radius_m.get(j).is_none_or(|&r| r < min_radius_m) {
                continue;
            }
            path.clear();
            path.push(j);
            let mut v = j;
            while path.len() <= window {
                let Some(p) = self.parent[v] else { break };
                path.push(p);
                v = p;
            }
            if path.len() <= window {
                continue;
            }
            let steps: Vec<f64> = path
                .windows(2)
                .map(|w| (self.pos[w[0]] - self.pos[w[1]]).norm())
                .collect();
            let length: f64 = steps.iter().sum();
            let (start, end) = (self.pos[v], self.pos[j]);
            if length <= ratio * (end - start).norm() || length <= 0.0 {
                continue;
            }
            // From the far end (the ancestor) toward `j`.
            let mut along = 0.0;
            for k in (1..path.len() - 1).rev() {
                along += steps[k];
                self.pos[path[k]] = start + (end - start) * (along / length);
            }
            count += 1;
        }
        count
    }

    /// Drop nodes whose `keep` is false (their subtrees must be dropped too), renumbering
    /// with the order kept.
    pub(crate) fn retain(&mut self, keep: &[bool]) {
        let mut map = vec![usize::MAX; self.pos.len()];
        let mut pos = Vec::new();
        let mut parent = Vec::new();
        let mut bridge = Vec::new();
        for i in 0..self.pos.len() {
            let ok = keep[i] && self.parent[i].is_none_or(|p| map[p] != usize::MAX);
            if ok {
                map[i] = pos.len();
                pos.push(self.pos[i]);
                parent.push(self.parent[i].map(|p| map[p]));
                bridge.push(self.bridge[i]);
            }
        }
        self.pos = pos;
        self.parent = parent;
        self.bridge = bridge;
    }

    /// The skeleton with pipe-model radii: each segment's radius^e is proportional to the
    /// length of tree it carries, so r_parent^e = Σ r_child^e at every fork, scaled so that
    /// the trunk segment at the base has `base_radius_m`. With `fits`, every node with a
    /// measured radius is an anchor too: it takes the measurement, and the nodes beyond it
    /// follow the pipe model scaled from the nearest anchor toward the root. Fits whose
    /// median departs from the pipe model by more than [`MAX_FIT_PIPE_RATIO`] are not
    /// used: they measure something else than wood (the leaf clumps of a crown in leaf).
    /// With `max_fit_per_pipe_median` k, a single fit more than k times that median ratio
    /// off the pipe model is not an anchor (see [`MAX_FIT_PER_PIPE_MEDIAN`]).
    /// Returns the skeleton and whether the fits were used.
    pub(crate) fn to_skeleton(
        &self,
        exponent: f64,
        base_radius_m: f64,
        fits: Option<&[Option<f64>]>,
        max_fit_per_pipe_median: Option<f64>,
    ) -> Result<(Skeleton, bool)> {
        let flat = Skeleton::new(
            self.pos
                .iter()
                .enumerate()
                .map(|(id, p)| SkeletonNode {
                    id,
                    parent: self.parent[id],
                    position: Point3::from(*p),
                    radius_m: 0.0,
                })
                .collect(),
        )?;
        let pipe = pipe_radii(&flat, base_radius_m, exponent);
        let mut radius = pipe.clone();
        // The median ratio of fitted radii to the pipe model's.
        let median = fits.and_then(|f| {
            let mut ratios: Vec<f64> = f
                .iter()
                .zip(&pipe)
                .filter_map(|(r, &q)| r.filter(|_| q > 0.0).map(|r| r / q))
                .collect();
            ratios.sort_by(f64::total_cmp);
            ratios.get(ratios.len() / 2).copied()
        });
        let fits = fits.filter(|_| {
            median.is_some_and(|m| (1.0 / MAX_FIT_PIPE_RATIO..=MAX_FIT_PIPE_RATIO).contains(&m))
        });
        let used = fits.is_some();
        if let Some(fits) = fits {
            let largest =
                max_fit_per_pipe_median.map_or(f64::INFINITY, |k| k * median.unwrap_or(1.0));
            let mut ratio = vec![1.0; pipe.len()];
            for &i in flat.topological_order() {
                let inherited = self.parent[i].map_or(1.0, |p| ratio[p]);
                ratio[i] = match fits.get(i).copied().flatten() {
                    Some(r) if pipe[i] > 0.0 && r / pipe[i] <= largest => r / pipe[i],
                    _ => inherited,
                };
                radius[i] = pipe[i] * ratio[i];
            }
        }
        let skeleton = Skeleton::new(
            flat.nodes()
                .iter()
                .map(|x| SkeletonNode {
                    radius_m: radius[x.id],
                    ..*x
                })
                .collect(),
        )?;
        Ok((skeleton, used))
    }
}

/// The pipe model's radius of each node of `skeleton` (its radii unused): r^e proportional
/// to the length the node carries, `base_m` at the root.
pub(crate) fn pipe_radii(skeleton: &Skeleton, base_m: f64, exponent: f64) -> Vec<f64> {
    let w = skeleton.carried_length_m();
    let root = skeleton.root();
    let scale = if w[root] > 0.0 {
        base_m.powf(exponent) / w[root]
    } else {
        0.0
    };
    w.iter()
        .map(|&w| (scale * w).powf(1.0 / exponent))
        .collect()
}

/// Line r = a + b·s through (s, r) samples, refitted without outliers, b ≤ 0.
fn robust_taper(samples: &[(f64, f64)]) -> Option<(f64, f64)> {
    let line = |pts: &[&(f64, f64)]| -> Option<(f64, f64)> {
        let n = pts.len() as f64;
        let ms = pts.iter().map(|p| p.0).sum::<f64>() / n;
        let mr = pts.iter().map(|p| p.1).sum::<f64>() / n;
        let sxx: f64 = pts.iter().map(|p| (p.0 - ms).powi(2)).sum();
        let sxy: f64 = pts.iter().map(|p| (p.0 - ms) * (p.1 - mr)).sum();
        let b = if sxx > 0.0 { (sxy / sxx).min(0.0) } else { 0.0 };
        if b == 0.0 {
            let mut r: Vec<f64> = pts.iter().map(|p| p.1).collect();
            r.sort_by(f64::total_cmp);
            return Some((r[r.len() / 2], 0.0));
        }
        Some((mr - b * ms, b))
    };
    let all: Vec<&(f64, f64)> = samples.iter().collect();
    let (a, b) = line(&all)?;
    let mut dev: Vec<f64> = samples.iter().map(|p| (p.1 - a - b * p.0).abs()).collect();
    dev.sort_by(f64::total_cmp);
    let limit = 2.5 * 1.4826 * dev[dev.len() / 2];
    let kept: Vec<&(f64, f64)> = samples
        .iter()
        .filter(|p| (p.1 - a - b * p.0).abs() <= limit)
        .collect();
    if kept.len() >= MIN_TAPER_FITS && kept.len() < samples.len() {
        line(&kept)
    } else {
        Some((a, b))
    }
}

/// Whether moving a node from the origin of its cross-section's plane to `to` (among the
/// points `plane`) leaves it no farther from its nearest point than it was, or within
/// `reach` of one (the radius of a fitted circle: an axis is a radius from its points).
fn no_farther(plane: &[[f64; 2]], to: [f64; 2], reach: f64) -> bool {
    let nearest = |c: [f64; 2]| {
        plane
            .iter()
            .map(|q| (q[0] - c[0]).hypot(q[1] - c[1]))
            .fold(f64::INFINITY, f64::min)
    };
    nearest(to) <= nearest([0.0, 0.0]).max(reach)
}

/// True for a fork and for the nodes next to one: their cross-sections mix branches.
fn near_fork(i: usize, parent: &[Option<usize>], children: &[Vec<usize>]) -> bool {
    children[i].len() > 1
        || parent[i].is_some_and(|p| children[p].len() > 1)
        || children[i].iter().any(|&c| children[c].len() > 1)
}

/// The radius of a branch from its cross-section's spread across the view ray from
/// `camera` (perpendicular to the ray and to the branch direction `t`; `plane` holds the
/// points in the basis `uv` at `node`): the central 90 % span over
/// [`ACROSS_RAY_RANGE_PER_RADIUS`]. Depth noise lies along the ray and does not widen it.
/// `None` with fewer than [`MIN_FIT_POINTS`] points, a ray along the branch, or no spread.
fn across_ray_radius(
    plane: &[[f64; 2]],
    node: Vector3<f64>,
    t: Vector3<f64>,
    (u, v): (Vector3<f64>, Vector3<f64>),
    camera: [f64; 3],
    spacing_m: f64,
) -> Option<f64> {
    if plane.len() < MIN_FIT_POINTS {
        return None;
    }
    let ray = node - Vector3::from(camera);
    let across = t.cross(&(ray - t * ray.dot(&t))).try_normalize(1e-9)?;
    let (au, av) = (across.dot(&u), across.dot(&v));
    let mut lateral: Vec<f64> = plane.iter().map(|q| q[0] * au + q[1] * av).collect();
    lateral.sort_by(f64::total_cmp);
    let last = (lateral.len() - 1) as f64;
    let at = |share: f64| lateral[((share * last).round() as usize).min(lateral.len() - 1)];
    // A camera samples a branch in columns of pixels, whose points share their lateral
    // position: the outermost columns' centres lie half a column inside the branch's edges,
    // so one column's step is added back. Laser points kept by a view are scattered across
    // instead (few neighbours at one lateral position) and need nothing added.
    let gaps: Vec<f64> = lateral.windows(2).map(|w| w[1] - w[0]).collect();
    let tiny = 0.05 * spacing_m;
    let shared = gaps.iter().filter(|&&g| g <= tiny).count();
    let step = if 2 * shared > gaps.len() {
        let mut wide: Vec<f64> = gaps.into_iter().filter(|&g| g > tiny).collect();
        wide.sort_by(f64::total_cmp);
        wide.get(wide.len() / 2).copied().unwrap_or(0.0)
    } else {
        0.0
    };
    let r = (at(0.95) - at(0.05) + step) / ACROSS_RAY_RANGE_PER_RADIUS;
    (r > 0.0).then_some(r)
}

/// A circle that may move a node.
fn usable(c: &crate::circle::Circle, p: &Parameters) -> bool {
    c.points >= MIN_FIT_POINTS
        && c.coverage >= MIN_FIT_COVERAGE
        && c.rms_m < MAX_FIT_RMS_PER_RADIUS * c.radius_m
        && c.radius_m < p.influence_m
        && c.radius_m > 0.3 * p.spacing_m
        && c.centre[0].hypot(c.centre[1]) <= c.radius_m.max(p.step_m)
}

/// Points per node.
struct Assignment {
    start: Vec<usize>,
    items: Vec<u32>,
}

impl Assignment {
    fn of(&self, node: usize) -> &[u32] {
        &self.items[self.start[node]..self.start[node + 1]]
    }
}

/// Whether no branch grows from `b` (nor from its tip).
fn is_terminal(skeleton: &Skeleton, b: &crate::skeleton::Branch) -> bool {
    b.nodes.iter().all(|&v| skeleton.children(v).len() <= 1)
        && b.nodes
            .last()
            .is_some_and(|&tip| skeleton.children(tip).is_empty())
}

/// Terminal branches that reach less than `min_twig_m` beyond the surface of the branch
/// they grow from: candidates for removal as the stubs space colonization grows toward the
/// near side of a thick branch. Each stub is its list of nodes.
pub(crate) fn twig_stubs(skeleton: &Skeleton, min_twig_m: f64) -> Vec<Vec<usize>> {
    let nodes = skeleton.nodes();
    skeleton
        .branches()
        .into_iter()
        .filter(|b| {
            let (Some(base), Some(&tip)) = (b.base_node, b.nodes.last()) else {
                return false;
            };
            is_terminal(skeleton, b)
                && (nodes[tip].position - nodes[base].position).norm()
                    < nodes[base].radius_m + min_twig_m
        })
        .map(|b| b.nodes)
        .collect()
}

/// Terminal branches that run inside the branch they grow from: every node within
/// `min_twig_m` of that branch's surface or inside it. Candidates for removal, like
/// [`twig_stubs`], but of any length: in a one-sided view chains can run along the inside
/// of a thick branch's seen half for tens of centimetres.
pub(crate) fn inside_parent_twigs(skeleton: &Skeleton, min_twig_m: f64) -> Vec<Vec<usize>> {
    let nodes = skeleton.nodes();
    let branches = skeleton.branches();
    let index: std::collections::HashMap<usize, usize> = branches
        .iter()
        .enumerate()
        .map(|(k, b)| (b.id, k))
        .collect();
    branches
        .iter()
        .filter(|b| {
            let Some(parent) = b.parent.filter(|_| is_terminal(skeleton, b)) else {
                return false;
            };
            let Some(pb) = index.get(&parent).map(|&k| &branches[k]) else {
                return false;
            };
            // The parent branch's segments: (start, end, radius of the end node).
            let segs: Vec<(Vector3<f64>, Vector3<f64>, f64)> = pb
                .nodes
                .iter()
                .filter_map(|&v| {
                    let p = nodes[v].parent?;
                    Some((
                        nodes[p].position.coords,
                        nodes[v].position.coords,
                        nodes[v].radius_m,
                    ))
                })
                .collect();
            !segs.is_empty()
                && b.nodes.iter().all(|&v| {
                    let q = nodes[v].position.coords;
                    segs.iter().any(|(a, e, r)| {
                        let d = e - a;
                        let len2 = d.norm_squared();
                        let t = if len2 > 0.0 {
                            ((q - a).dot(&d) / len2).clamp(0.0, 1.0)
                        } else {
                            0.0
                        };
                        (q - (a + d * t)).norm() <= r + min_twig_m
                    })
                })
        })
        .map(|b| b.nodes.clone())
        .collect()
}

/// Twig ends in the air: in each terminal chain (the nodes beyond the last fork), the
/// first segment whose surface is more than `near_m` from every point of `tree`, measured
/// from its mid-axis, and the nodes beyond it. Twigs extended or grown past the end of
/// their points, or across a hollow trunk base, end so; a bridge across an occlusion to
/// a leaf clump does too, which is why these are only candidates for removal.
pub(crate) fn far_tails(skeleton: &Skeleton, tree: &PointTree, near_m: f64) -> Vec<Vec<usize>> {
    let nodes = skeleton.nodes();
    let mut fork_below = vec![false; nodes.len()];
    for &v in skeleton.topological_order().iter().rev() {
        let kids = skeleton.children(v);
        fork_below[v] = kids.len() > 1 || kids.iter().any(|&c| fork_below[c]);
    }
    let mut tails = Vec::new();
    let mut in_tail = vec![false; nodes.len()];
    for &v in skeleton.topological_order() {
        let Some(p) = nodes[v].parent else { continue };
        // Only the first far segment of a chain starts a tail; later ones are in it.
        if fork_below[v] || in_tail[v] {
            continue;
        }
        let mid = (nodes[p].position.coords + nodes[v].position.coords) * 0.5;
        let d = tree
            .nearest_one::<SquaredEuclidean>(&[mid.x, mid.y, mid.z])
            .distance
            .sqrt();
        if d - nodes[v].radius_m > near_m {
            let mut tail = vec![v];
            let mut u = v;
            while let [c] = skeleton.children(u) {
                tail.push(*c);
                u = *c;
            }
            tail.iter().for_each(|&t| in_tail[t] = true);
            tails.push(tail);
        }
    }
    tails
}

impl Graph {
    /// Move the nodes of `tails` (twig ends in the air that points need, see [`far_tails`])
    /// onto the cloud: a node farther than its radius from its nearest point goes to that
    /// distance from it, along the line from the point, where the twig's axis is when the
    /// point is on its surface. Bridge nodes stay: they cross a gap on purpose. Returns how
    /// many nodes moved.
    pub(crate) fn onto_cloud(
        &mut self,
        tails: &[Vec<usize>],
        tree: &PointTree,
        pts: &[[f64; 3]],
        radius_m: &[f64],
    ) -> usize {
        let mut moved = 0;
        for &v in tails.iter().flatten().filter(|&&v| !self.bridge[v]) {
            let p = self.pos[v];
            let nb = tree.nearest_one::<SquaredEuclidean>(&[p.x, p.y, p.z]);
            let q = Vector3::from(pts[nb.item as usize]);
            let d = nb.distance.sqrt();
            if d > radius_m[v] && d > 0.0 {
                self.pos[v] = q + (p - q) * (radius_m[v] / d);
                moved += 1;
            }
        }
        moved
    }
}

/// Which `stubs` are artefacts: those no point needs. A stub is needed when a point that is
/// farther than `near_m` from the model without the stubs (`pruned_distance`, per point) is
/// nearer to one of the stub's nodes than to that model: a short twig into a leaf clump of
/// a sparse crown, not a stub toward the surface of its own parent. Returns one flag per
/// stub, true = remove.
pub(crate) fn unneeded_stubs(
    pts: &[[f64; 3]],
    main: &[bool],
    skeleton: &Skeleton,
    stubs: &[Vec<usize>],
    pruned_distance: &[f64],
    near_m: f64,
) -> Vec<bool> {
    let mut remove = vec![true; stubs.len()];
    let mut owner = Vec::new();
    let mut positions = Vec::new();
    for (s, stub) in stubs.iter().enumerate() {
        for &v in stub {
            let p = skeleton.nodes()[v].position;
            owner.push(s);
            positions.push([p.x, p.y, p.z]);
        }
    }
    if positions.is_empty() {
        return remove;
    }
    let tree: ImmutableKdTree<f64, u32, 3, 32> = ImmutableKdTree::new_from_slice(&positions);
    for ((q, &m), &d) in pts.iter().zip(main).zip(pruned_distance) {
        if !m || d <= near_m {
            continue;
        }
        let nb = tree.nearest_one::<SquaredEuclidean>(q);
        if nb.distance.sqrt() < d {
            remove[owner[nb.item as usize]] = false;
        }
    }
    remove
}

#[cfg(test)]
mod tests;
