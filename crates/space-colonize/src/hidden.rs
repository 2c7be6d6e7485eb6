//! Wood the camera did not see. In a one-sided view a trunk or limb passes behind branches
//! in front of it, and colonization then draws its chain along what hides it, off the true
//! axis by several centimetres. With the camera known the view's points also say which
//! space the camera saw *through*: a model surface facing the camera where the camera saw
//! farther (or nothing at all) is not there. Such a stretch of a thick chain is replaced by
//! the straight line between two of its nodes, when that evidence does not refute the
//! line: the branch is continued through the stretch the camera could not see, and the
//! camera's rays are the evidence that it is hidden rather than absent.

use std::collections::HashMap;

use nalgebra::Vector3;

use crate::error::Result;
use crate::refine::Graph;
use crate::skeleton::{Skeleton, SkeletonNode};
use crate::view::{pixel, splat_nearest};

/// A model surface point within this distance of the nearest surface the camera saw in
/// its pixel is seen there, metres: five times a Kinect's 6 mm depth noise
/// ([`crate::KINECT_DEPTH_NOISE_M`]), so that a branch's near side is not refuted by the
/// noise of its own points.
const SEEN_MARGIN_M: f64 = 0.03;
/// Radius of the disc each seen point stands for, in point spacings: holes between a
/// view's points are not seen through.
const SPLAT_SPACINGS: f64 = 2.0;
/// Angles around the direction to the camera at which a branch's near surface is sampled,
/// degrees: the part of a circle a camera sees well (beyond ±60° the surface is seen at a
/// grazing angle and may fall out of the view).
const NEAR_SIDE_DEG: [f64; 5] = [-60.0, -30.0, 0.0, 30.0, 60.0];
/// Sampling step along a branch's axis, metres.
const SAMPLE_STEP_M: f64 = 0.01;
/// Only chains at least this thick are continued through what hides them, metres: a thin
/// twig's near surface is within the depth noise of its axis, and the evidence cannot tell
/// a twig's path from a chord.
const MIN_RADIUS_M: f64 = 0.015;
/// A path is refuted when at least this share of its near-surface samples lie where the
/// camera saw farther or nothing.
const REFUTED_SHARE: f64 = 0.15;
/// A straight line replaces a stretch only when at most this share of its own samples are
/// refuted (the true trunks of the synthetic views, hidden or not: under 1 %).
const CLEAN_SHARE: f64 = 0.03;
/// Longest stretch put on one line, metres along the chain (a trunk hidden behind a limb
/// for up to a metre, issue 22's synthetic views).
const MAX_STRETCH_M: f64 = 1.5;
/// Fewest refuted samples on a path worth replacing (four centimetres of a branch refuted
/// all round its near side).
const MIN_REFUTED_SAMPLES: usize = 20;
/// A line's upper end is looked for among ancestors past at least this share of the
/// refuted samples between the lower end and the farthest ancestor.
const COVER_SHARE: f64 = 0.9;
/// Lines tried per lower end, nearest upper ends first.
const MAX_LINES_PER_END: usize = 8;
/// Least distance a path must stray from its line to be replaced, metres.
const MIN_DEVIATION_M: f64 = 0.01;
/// Sharpest turn between a line and the chain entering or leaving it, degrees: a hidden
/// trunk continues the trunk below it; a line from a side branch back to the trunk does
/// not.
const MAX_KINK_DEG: f64 = 30.0;
/// Length of chain over which the entering and leaving directions are taken, metres.
const KINK_SPAN_M: f64 = 0.1;
/// A segment the camera saw on at least this share of its near-surface samples is kept
/// when the path it is on is replaced: a real branch the old path ran along.
const WELL_SEEN_SHARE: f64 = 0.6;
/// A seen node of a replaced path stays (as wood the path ran along) only when it is more
/// than this many radii of the line from it.
const BRANCH_OUT_RADII: f64 = 2.0;
/// Most nodes of one line (the longest line over the finest step).
const MAX_LINE_NODES: usize = 1_000;
/// Rounds of [`continue_hidden`].
const MAX_ROUNDS: usize = 3;

/// What the camera saw along each pixel's ray: the range of the nearest surface.
pub(crate) struct SeenSpace {
    nearest: HashMap<(i64, i64), f64>,
    camera: Vector3<f64>,
    pixel_rad: f64,
}

/// Near-surface samples of a model branch: where the camera saw them (or in front of
/// them, hiding them), and where it saw farther or nothing.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Tally {
    pub seen: usize,
    pub hidden: usize,
    pub refuted: usize,
}

impl Tally {
    fn total(self) -> usize {
        self.seen + self.hidden + self.refuted
    }

    fn refuted_share(self) -> f64 {
        if self.total() == 0 {
            0.0
        } else {
            self.refuted as f64 / self.total() as f64
        }
    }

    fn add(&mut self, o: Tally) {
        self.seen += o.seen;
        self.hidden += o.hidden;
        self.refuted += o.refuted;
    }
}

impl SeenSpace {
    /// The z-buffer of `pts` (those `keep` marks) seen from `camera`: pixels of half the
    /// cloud's point spacing at its median range, each point a disc of one spacing. `None`
    /// when no point is away from the camera.
    pub(crate) fn new(
        pts: &[[f64; 3]],
        keep: &[bool],
        camera: [f64; 3],
        spacing_m: f64,
    ) -> Option<Self> {
        let camera = Vector3::from(camera);
        let rays: Vec<(Vector3<f64>, f64)> = pts
            .iter()
            .zip(keep)
            .filter(|(_, k)| **k)
            .map(|(p, _)| {
                let d = Vector3::from(*p) - camera;
                (d, d.norm())
            })
            .filter(|(_, r)| *r > 0.0 && r.is_finite())
            .collect();
        let mut ranges: Vec<f64> = rays.iter().map(|(_, r)| *r).collect();
        if ranges.is_empty() || !spacing_m.is_finite() || spacing_m <= 0.0 {
            return None;
        }
        let mid = ranges.len() / 2;
        let median = *ranges.select_nth_unstable_by(mid, f64::total_cmp).1;
        let pixel_rad = spacing_m / median;
        if !(pixel_rad.is_finite() && pixel_rad >= crate::view::MIN_PIXEL_RAD) {
            return None;
        }
        Some(Self {
            nearest: splat_nearest(&rays, pixel_rad, SPLAT_SPACINGS * spacing_m),
            camera,
            pixel_rad,
        })
    }

    /// Tally the near-surface samples of a cone from `a` (radius `ra`) to `b` (`rb`) into `t`.
    pub(crate) fn tally(
        &self,
        a: &Vector3<f64>,
        b: &Vector3<f64>,
        ra: f64,
        rb: f64,
        t: &mut Tally,
    ) {
        let u = b - a;
        let len = u.norm();
        if !len.is_finite() || len <= 0.0 {
            return;
        }
        let u = u / len;
        let steps = (len / SAMPLE_STEP_M).ceil().max(1.0) as usize;
        for k in 0..steps {
            let share = (k as f64 + 0.5) / steps as f64;
            let c = a + u * (share * len);
            let r = ra + (rb - ra) * share;
            let to = self.camera - c;
            let across = to - u * to.dot(&u);
            let Some(n) = across.try_normalize(1e-12) else {
                continue;
            };
            let side = u.cross(&n);
            for deg in NEAR_SIDE_DEG {
                let (s, co) = deg.to_radians().sin_cos();
                let q = c + (n * co + side * s) * r;
                let d = q - self.camera;
                let range = d.norm();
                match self.nearest.get(&pixel(&d, self.pixel_rad)) {
                    Some(&f) if f < range - SEEN_MARGIN_M => t.hidden += 1,
                    Some(&f) if f <= range + SEEN_MARGIN_M => t.seen += 1,
                    // Farther, or nothing at all: the camera saw through this place.
                    _ => t.refuted += 1,
                }
            }
        }
    }
}

/// Continue the refuted stretches of thick chains on straight lines between anchors the
/// camera's evidence does not refute (see the module docs). `radius_m` per node; new nodes
/// are `step_m` apart. Returns the number of stretches continued.
///
/// Every path from a node up to an ancestor at most [`MAX_STRETCH_M`] along the chain is a
/// candidate when both ends are at least [`MIN_RADIUS_M`] thick, the path's own surface
/// is refuted on at least [`REFUTED_SHARE`] of its samples (and [`MIN_REFUTED_SAMPLES`]),
/// it strays at least [`MIN_DEVIATION_M`] from the line, and the line turns at most
/// [`MAX_KINK_DEG`] from the chain entering it and leaving it; the line replaces the path
/// when at most [`CLEAN_SHARE`] of the line's samples are refuted. Each round takes, per
/// lower end, the line removing the most refuted samples, then the best of those that share
/// no node; at most [`MAX_ROUNDS`] rounds.
///
/// The line is new nodes from the upper end carrying the lower end's subtree; of the old
/// path, what nothing else hangs on and the camera did not see well is removed (a real
/// branch the old path ran along stays).
pub(crate) fn continue_hidden(
    graph: &mut Graph,
    radius_m: &[f64],
    seen: &SeenSpace,
    step_m: f64,
) -> usize {
    let mut radius: Vec<f64> = (0..graph.pos.len())
        .map(|v| radius_m.get(v).copied().unwrap_or(0.0))
        .collect();
    let mut moved = 0;
    for _ in 0..MAX_ROUNDS {
        let n = graph.pos.len();
        // Each node's segment from its parent.
        let segs: Vec<Tally> = (0..n)
            .map(|v| {
                let mut t = Tally::default();
                if let Some(p) = graph.parent[v] {
                    seen.tally(&graph.pos[p], &graph.pos[v], radius[p], radius[v], &mut t);
                }
                t
            })
            .collect();
        let children = graph.children();
        let mut found: Vec<(usize, usize, usize)> = Vec::new(); // (gain, a, b)
        for b in 0..n {
            if radius[b] < MIN_RADIUS_M || segs[b].refuted_share() > REFUTED_SHARE {
                continue;
            }
            if let Some(c) = best_line(graph, &children, b, &segs, &radius, seen) {
                found.push(c);
            }
        }
        found.sort_by_key(|c| std::cmp::Reverse(c.0));
        let mut taken = vec![false; n];
        let mut lines: Vec<Vec<usize>> = Vec::new();
        for (_, a, b) in found {
            let chain = chain_up(graph, b, a);
            if chain.iter().any(|&v| taken[v]) {
                continue;
            }
            chain.iter().for_each(|&v| taken[v] = true);
            lines.push(chain);
        }
        if lines.is_empty() {
            break;
        }
        let mut remove = vec![false; graph.pos.len()];
        for chain in &lines {
            replace_with_line(graph, &mut radius, chain, step_m, &segs, &mut remove);
        }
        moved += lines.len();
        remove.resize(graph.pos.len(), false);
        radius = compact(graph, &radius, &remove);
    }
    moved
}

/// Renumber `graph` parents first (the lines' new nodes carry older ones), without the
/// nodes `remove` marks and what hangs on them; returns `radius` renumbered alike.
fn compact(graph: &mut Graph, radius: &[f64], remove: &[bool]) -> Vec<f64> {
    let children = graph.children();
    let mut order: Vec<usize> = (0..graph.pos.len())
        .filter(|&v| graph.parent[v].is_none() && !remove[v])
        .collect();
    let mut k = 0;
    while k < order.len() {
        let v = order[k];
        order.extend(children[v].iter().copied().filter(|&c| !remove[c]));
        k += 1;
    }
    let mut map = vec![usize::MAX; graph.pos.len()];
    for (new, &old) in order.iter().enumerate() {
        map[old] = new;
    }
    let pos = order.iter().map(|&v| graph.pos[v]).collect();
    let parent = order
        .iter()
        .map(|&v| graph.parent[v].map(|p| map[p]))
        .collect();
    let bridge = order.iter().map(|&v| graph.bridge[v]).collect();
    graph.pos = pos;
    graph.parent = parent;
    graph.bridge = bridge;
    order.iter().map(|&v| radius[v]).collect()
}

/// Hang the subtree of `chain`'s last node on new nodes along the straight line from its
/// first node, about `step_m` apart, with radii from the first's to the last's. Of the old
/// inner nodes, those whose segment the camera saw well ([`WELL_SEEN_SHARE`]: real wood
/// the old path ran along) outside the line's tube ([`BRANCH_OUT_RADII`]) stay; the rest
/// are marked in `remove`, and what hung on them is hung on the nearest node of the line.
fn replace_with_line(
    graph: &mut Graph,
    radius: &mut Vec<f64>,
    chain: &[usize],
    step_m: f64,
    segs: &[Tally],
    remove: &mut Vec<bool>,
) {
    let (Some(&a), Some(&b)) = (chain.first(), chain.last()) else {
        return;
    };
    let (pa, pb) = (graph.pos[a], graph.pos[b]);
    let len = (pb - pa).norm();
    let inner = ((len / step_m.max(1e-3)).ceil() as usize)
        .saturating_sub(1)
        .min(MAX_LINE_NODES);
    let mut line = vec![a];
    for k in 1..=inner {
        let t = k as f64 / (inner + 1) as f64;
        graph.pos.push(pa + (pb - pa) * t);
        graph.parent.push(line.last().copied());
        // Like a bridge, the line is not moved onto points afterwards.
        graph.bridge.push(true);
        radius.push(radius[a] + (radius[b] - radius[a]) * t);
        line.push(graph.pos.len() - 1);
    }
    graph.parent[b] = line.last().copied();
    remove.resize(graph.pos.len(), false);
    let old = &chain[1..chain.len() - 1];
    let u = (pb - pa).try_normalize(1e-12).unwrap_or_else(Vector3::z);
    let tube = BRANCH_OUT_RADII * radius[a].max(radius[b]);
    let gone: Vec<usize> = old
        .iter()
        .copied()
        .filter(|&v| {
            let t = segs[v];
            let well_seen = t.total() > 0 && t.seen as f64 >= WELL_SEEN_SHARE * t.total() as f64;
            let d = graph.pos[v] - pa;
            !(well_seen && (d - u * d.dot(&u)).norm() > tube)
        })
        .collect();
    gone.iter().for_each(|&v| remove[v] = true);
    let children = graph.children();
    for &q in &gone {
        for &c in &children[q] {
            if remove[c] || c == b {
                continue;
            }
            let at = graph.pos[c];
            let nearest = line
                .iter()
                .copied()
                .min_by(|&x, &y| {
                    (graph.pos[x] - at)
                        .norm_squared()
                        .total_cmp(&(graph.pos[y] - at).norm_squared())
                })
                .unwrap_or(a);
            graph.parent[c] = Some(nearest);
        }
    }
}

/// Radii of a one-sided view where the camera saw a chain poorly: each node at least as
/// thick as the child carrying the most length beyond it (a branch does not thicken as it
/// goes out), but never thicker than the pipe model gives it from the trunk's base radius
/// `base_m` and exponent `exponent`. A trunk hidden behind branches is measured there on
/// the few points of what hid it (a third of its radius on the first set's seed 63), while
/// the trunk above and below is measured well.
pub(crate) fn no_thinner_than_its_continuation(
    skeleton: &Skeleton,
    base_m: f64,
    exponent: f64,
) -> Result<Skeleton> {
    let w = skeleton.carried_length_m();
    let pipe = crate::refine::pipe_radii(skeleton, base_m, exponent);
    let mut r: Vec<f64> = skeleton.nodes().iter().map(|n| n.radius_m).collect();
    for &v in skeleton.topological_order().iter().rev() {
        let heavier = skeleton
            .children(v)
            .iter()
            .copied()
            .max_by(|&x, &y| w[x].total_cmp(&w[y]));
        if let Some(h) = heavier {
            r[v] = r[v].max(r[h].min(pipe[v]));
        }
    }
    Skeleton::new(
        skeleton
            .nodes()
            .iter()
            .map(|n| SkeletonNode {
                radius_m: r[n.id],
                ..*n
            })
            .collect(),
    )
}

/// Nodes from ancestor `a` down to `b`.
fn chain_up(graph: &Graph, b: usize, a: usize) -> Vec<usize> {
    let mut chain = vec![b];
    let mut v = b;
    while v != a {
        let Some(p) = graph.parent[v] else { break };
        chain.push(p);
        v = p;
    }
    chain.reverse();
    chain
}

/// For lower end `b`: the nearest ancestor `a` past its refuted stretch whose line is
/// clean (see [`continue_hidden`]), as (samples removed, a, b).
fn best_line(
    graph: &Graph,
    children: &[Vec<usize>],
    b: usize,
    segs: &[Tally],
    radius: &[f64],
    seen: &SeenSpace,
) -> Option<(usize, usize, usize)> {
    // Candidates up the chain, nearest first.
    let mut cands: Vec<(usize, usize)> = Vec::new();
    let (mut chain, mut arc, mut v) = (Tally::default(), 0.0, b);
    while let Some(p) = graph.parent[v] {
        chain.add(segs[v]);
        arc += (graph.pos[v] - graph.pos[p]).norm();
        if arc > MAX_STRETCH_M {
            break;
        }
        v = p;
        if radius[v] >= MIN_RADIUS_M
            && segs[v].refuted_share() <= REFUTED_SHARE
            && chain.refuted >= MIN_REFUTED_SAMPLES
            && chain.refuted_share() >= REFUTED_SHARE
        {
            cands.push((chain.refuted, v));
        }
    }
    // The nearest ancestors past (nearly) all of the refuted stretch first: a line from
    // farther up would cut across the bends of the seen chain above it.
    let most = cands.iter().map(|c| c.0).max().unwrap_or(0);
    let past = cands
        .into_iter()
        .filter(|c| c.0 as f64 >= COVER_SHARE * most as f64)
        .filter(|&(_, a)| {
            let (pa, pb) = (graph.pos[a], graph.pos[b]);
            let line = pb - pa;
            let entering = up_from(graph, a).map(|u| pa - u);
            let leaving = down_from(graph, children, b).map(|d| d - pb);
            let turn_ok = |d: Option<Vector3<f64>>| {
                d.is_none_or(|d| d.angle(&line) <= MAX_KINK_DEG.to_radians())
            };
            turn_ok(entering) && turn_ok(leaving) && strays(graph, a, b) >= MIN_DEVIATION_M
        });
    for (refuted, a) in past.take(MAX_LINES_PER_END) {
        let mut line = Tally::default();
        seen.tally(
            &graph.pos[a],
            &graph.pos[b],
            radius[a],
            radius[b],
            &mut line,
        );
        if line.refuted_share() <= CLEAN_SHARE {
            return Some((refuted.saturating_sub(line.refuted), a, b));
        }
    }
    None
}

/// The position [`KINK_SPAN_M`] up the chain from `v` (or the root), `None` at the root.
fn up_from(graph: &Graph, v: usize) -> Option<Vector3<f64>> {
    let mut u = graph.parent[v]?;
    while (graph.pos[v] - graph.pos[u]).norm() < KINK_SPAN_M {
        match graph.parent[u] {
            Some(p) => u = p,
            None => break,
        }
    }
    Some(graph.pos[u])
}

/// The position [`KINK_SPAN_M`] down the chain from `v`, always into the child carrying
/// the most nodes below it within that span; `None` at a tip.
fn down_from(graph: &Graph, children: &[Vec<usize>], v: usize) -> Option<Vector3<f64>> {
    let mut d = *children[v].first()?;
    let mut guard = 0;
    while (graph.pos[d] - graph.pos[v]).norm() < KINK_SPAN_M && guard < graph.pos.len() {
        guard += 1;
        match children[d].iter().max_by_key(|&&c| children[c].len()) {
            Some(&c) => d = c,
            None => break,
        }
    }
    Some(graph.pos[d])
}

/// Farthest distance of the path from `b` up to `a` from the line between them, metres.
fn strays(graph: &Graph, a: usize, b: usize) -> f64 {
    let (pa, pb) = (graph.pos[a], graph.pos[b]);
    let Some(u) = (pb - pa).try_normalize(1e-12) else {
        return 0.0;
    };
    chain_up(graph, b, a)
        .iter()
        .map(|&v| {
            let d = graph.pos[v] - pa;
            (d - u * d.dot(&u)).norm()
        })
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SPACING_M: f64 = 0.005;

    /// Points every [`SPACING_M`] on the near half (facing +x) of a vertical cylinder of
    /// radius `r` about (`x`, `y`) from `z0` to `z1`.
    fn near_half(x: f64, y: f64, r: f64, (z0, z1): (f64, f64)) -> Vec<[f64; 3]> {
        let rings = ((z1 - z0) / SPACING_M).round() as usize;
        let around = (std::f64::consts::PI * r / SPACING_M).round() as usize;
        let mut pts = Vec::new();
        for i in 0..=rings {
            for j in 0..=around {
                let a =
                    -0.5 * std::f64::consts::PI + std::f64::consts::PI * j as f64 / around as f64;
                pts.push([x + r * a.cos(), y + r * a.sin(), z0 + SPACING_M * i as f64]);
            }
        }
        pts
    }

    /// A plate facing +x at `x`, across `y0..y1` and `z0..z1`.
    fn plate(x: f64, (y0, y1): (f64, f64), (z0, z1): (f64, f64)) -> Vec<[f64; 3]> {
        let (ny, nz) = (
            ((y1 - y0) / SPACING_M) as usize,
            ((z1 - z0) / SPACING_M) as usize,
        );
        (0..=ny)
            .flat_map(|i| {
                (0..=nz).map(move |k| [x, y0 + SPACING_M * i as f64, z0 + SPACING_M * k as f64])
            })
            .collect()
    }

    fn space(pts: &[[f64; 3]], camera: [f64; 3]) -> SeenSpace {
        SeenSpace::new(pts, &vec![true; pts.len()], camera, SPACING_M)
            .unwrap_or_else(|| panic!("no space"))
    }

    fn tally(s: &SeenSpace, x: f64, y: f64, r: f64) -> Tally {
        let mut t = Tally::default();
        s.tally(
            &Vector3::new(x, y, -0.1),
            &Vector3::new(x, y, 0.1),
            r,
            r,
            &mut t,
        );
        t
    }

    #[test]
    fn a_chain_is_no_thinner_than_its_continuation_up_to_the_pipe_model() {
        // A 1 m trunk (radius 6 cm at the base by the pipe model, nodes every 10 cm)
        // measured 1 cm thick in its middle, 4 cm elsewhere, with a 3 cm twig off its
        // middle (a light child).
        let mut nodes: Vec<SkeletonNode> = (0..=10)
            .map(|k| SkeletonNode {
                id: k,
                parent: k.checked_sub(1),
                position: nalgebra::Point3::new(0.0, 0.0, 0.1 * k as f64),
                radius_m: if (4..=6).contains(&k) { 0.01 } else { 0.04 },
            })
            .collect();
        nodes.push(SkeletonNode {
            id: 11,
            parent: Some(5),
            position: nalgebra::Point3::new(0.05, 0.0, 0.5),
            radius_m: 0.03,
        });
        let s = Skeleton::new(nodes).unwrap_or_else(|e| panic!("{e}"));
        let out = no_thinner_than_its_continuation(&s, 0.06, 2.5).unwrap_or_else(|e| panic!("{e}"));
        let r = |k: usize| out.nodes()[k].radius_m;
        for k in 4..=6 {
            assert!((r(k) - 0.04).abs() < 1e-12, "{k}: {}", r(k));
        }
        // The twig keeps its radius, and the thin top keeps its own.
        assert_eq!(r(11), 0.03);
        assert_eq!(r(10), 0.04);
        // Under the pipe model's radius: a trunk whose base is 1 cm carries at most that.
        let thin_base =
            no_thinner_than_its_continuation(&s, 0.01, 2.5).unwrap_or_else(|e| panic!("{e}"));
        assert!(thin_base.nodes()[5].radius_m <= 0.01 + 1e-12);
    }

    #[test]
    fn a_surface_is_seen_hidden_or_seen_through() {
        // A wall 2 m in front of the camera.
        let s = space(&plate(2.0, (-0.3, 0.3), (-0.3, 0.3)), [0.0, 0.0, 0.0]);
        // On the wall: a branch whose near side is the wall.
        let on = tally(&s, 2.03, 0.0, 0.03);
        assert!(on.seen as f64 > 0.9 * on.total() as f64, "{on:?}");
        // Behind it.
        let behind = tally(&s, 2.5, 0.0, 0.03);
        assert_eq!(behind.hidden, behind.total(), "{behind:?}");
        // In front of it (the camera saw the wall through it) and off to the side (the
        // camera saw nothing there).
        for (x, y) in [(1.5, 0.0), (2.0, 1.0)] {
            let t = tally(&s, x, y, 0.03);
            assert_eq!(t.refuted, t.total(), "{x} {y}: {t:?}");
        }
    }

    /// A trunk of radius 5 cm on the z axis seen from `camera`, its near half, with `plate`
    /// points too; the chain of nodes every 2 cm runs out to `detour_x` between z 0.6 and
    /// 0.9 (straight ramps from 0.5 and to 1.0).
    fn trunk_case(
        trunk: &[(f64, f64)],
        extra: Vec<[f64; 3]>,
        detour_x: f64,
    ) -> (Graph, Vec<f64>, SeenSpace) {
        let mut pts: Vec<[f64; 3]> = trunk
            .iter()
            .flat_map(|&z| near_half(0.0, 0.0, 0.05, z))
            .collect();
        pts.extend(extra);
        let seen = space(&pts, [3.0, 0.0, 0.75]);
        let mut graph = Graph {
            pos: Vec::new(),
            parent: Vec::new(),
            bridge: Vec::new(),
        };
        for k in 0..=75_u32 {
            let z = 0.02 * f64::from(k);
            let x =
                detour_x * ((z - 0.5) / 0.1).clamp(0.0, 1.0) * ((1.0 - z) / 0.1).clamp(0.0, 1.0);
            graph.pos.push(Vector3::new(x, 0.0, z));
            graph.parent.push(k.checked_sub(1).map(|p| p as usize));
            graph.bridge.push(false);
        }
        let radius = vec![0.05; graph.pos.len()];
        (graph, radius, seen)
    }

    /// Largest distance from the z axis of the nodes between z 0.6 and 0.9.
    fn off_axis(graph: &Graph) -> f64 {
        graph
            .pos
            .iter()
            .filter(|p| (0.6..=0.9).contains(&p.z))
            .map(|p| p.x.hypot(p.y))
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_trunk_drawn_along_a_branch_in_front_is_continued_behind_it() {
        // A limb 40 cm in front of the trunk hides it from z 0.55 to 0.95; the chain was
        // drawn along the limb (its near side 0.35 m out, where the camera saw the limb).
        let limb = plate(0.4, (-0.15, 0.15), (0.55, 0.95));
        let (mut graph, radius, seen) = trunk_case(&[(0.0, 0.55), (0.95, 1.5)], limb, 0.35);
        let top = graph.pos.len() - 1;
        assert!(off_axis(&graph) > 0.3);
        let n = continue_hidden(&mut graph, &radius, &seen, 0.02);
        assert!(n >= 1);
        // The path from the top down to the root now stays on the trunk's axis...
        let top = graph
            .pos
            .iter()
            .position(|p| (p - Vector3::new(0.0, 0.0, 1.5)).norm() < 1e-9)
            .unwrap_or(top);
        let path = chain_up(&graph, top, 0);
        assert_eq!(path.first(), Some(&0));
        let worst = path
            .iter()
            .map(|&v| graph.pos[v].x.hypot(graph.pos[v].y))
            .fold(0.0, f64::max);
        assert!(worst < 0.01, "{worst}");
        // ...and the part of the old chain the camera saw on the limb is kept beside it.
        assert!(graph.pos.iter().any(|p| p.x > 0.3));
    }

    #[test]
    fn a_trunk_the_camera_saw_bend_keeps_its_bend_and_a_seen_gap_is_not_bridged() {
        // The trunk really bends 35 cm toward the camera and is seen there: its chain is
        // seen, not refuted, and stays.
        let bend: Vec<[f64; 3]> = (0..=15)
            .flat_map(|k| {
                let z = 0.6 + 0.02 * f64::from(k);
                near_half(0.35, 0.0, 0.05, (z, z + 0.02))
            })
            .collect();
        let (mut graph, radius, seen) = trunk_case(&[(0.0, 0.5), (1.0, 1.5)], bend, 0.35);
        let before = graph.pos.clone();
        assert_eq!(continue_hidden(&mut graph, &radius, &seen, 0.02), 0);
        assert_eq!(graph.pos, before);
        // A chain drawn out into the air where the camera saw nothing in front of the
        // trunk's place but the wall behind it: the straight line is refuted too (the
        // camera saw through it to the wall), so nothing is made up.
        let wall = plate(-1.0, (-0.5, 0.5), (0.0, 1.5));
        let (mut graph, radius, seen) = trunk_case(&[(0.0, 0.5), (1.0, 1.5)], wall, 0.35);
        assert_eq!(continue_hidden(&mut graph, &radius, &seen, 0.02), 0);
    }
}
