//! Growth along the wood: geodesic level sets over a neighbour graph of the points
//! (Verroust & Lazarus 2000; Xu, Gossett & Chen 2007, the idea behind TreeQSM's cover-set
//! segmentation), so every node is the centre of a patch of points and every edge joins two
//! patches that touch.
//!
//! 1. Each point is joined to its [`NEIGHBOURS`] nearest within [`EDGE_SPACINGS`] point
//!    spacings (both ways); each point of a small piece of the graph also gets a bridge to
//!    its nearest point outside the piece.
//! 2. Shortest paths through that graph from the points around the root (Dijkstra; a
//!    bridge costs [`BRIDGE_COST`] times its length). When the front still stalls with
//!    points left, the nearest unreached point is joined to the nearest reached one (at
//!    most the longest gap).
//! 3. The path length is cut into bins; points of one bin within [`LINK_BINS`] bins of
//!    each other form a patch. Path lengths through scattered points zigzag, so the level
//!    set around a thick branch is wavy and a thin slice of it can break into arcs: arcs of
//!    one bin that together make a ring are merged. A patch wider than the patch size that
//!    is not a ring around a branch (a circle fit across the direction the paths run) is
//!    split on a grid of that size: a band of a leafy crown becomes many small patches on
//!    the leaves, not one node in the air at its middle.
//! 4. One node per patch at its centroid; its parent is the patch holding the shortest
//!    path's predecessor of the patch's first-reached point. Bridges longer than a bin get
//!    intermediate nodes.
//!
//! Cost: k-nearest-neighbour and fixed-radius queries and Dijkstra, O(n log n); a stall
//! that the small-piece bridges did not prevent rebuilds a k-d tree of the reached points.

use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};

use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use nalgebra::{Matrix3, Vector3};

use crate::circle::fit_circle;
use crate::cloud::Prepared;
use crate::error::{ColonizeError, Result};
use crate::grow::Growth;

/// Neighbours per point in the graph.
pub const NEIGHBOURS: usize = 10;
/// Longest graph edge, in point spacings: neighbours farther than this are across a gap
/// (bridged only when nothing nearer is left).
pub const EDGE_SPACINGS: f64 = 4.0;
/// A patch is a ring around a branch (kept whole) when a circle fitted across it covers at
/// least this share of the circle (a one-sided view sees half),
const RING_COVERAGE: f64 = 0.4;
/// ... with an RMS residual below this share of its radius.
const RING_RMS_PER_RADIUS: f64 = 0.35;
/// ... holding at least this share of the patch's points.
const RING_INLIERS: f64 = 0.5;
/// Fewest points for the ring test.
const RING_POINTS: usize = 8;
const NONE: u32 = u32::MAX;
/// Points of one bin closer than this many bins are in one patch,
pub const LINK_BINS: f64 = 2.0;
/// ... among each point's this many nearest (so the cost per point stays bounded on
/// clouds much denser than the bin).
pub const LINK_NEIGHBOURS: usize = 32;

/// Sizes of the level sets.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Levels {
    /// Width of a bin of path length, metres.
    pub bin_m: f64,
    /// Largest patch that is not a ring, metres (grid cell of the split).
    pub patch_m: f64,
}

#[derive(PartialEq)]
struct Entry(f64, u32);
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        // Min-heap on distance, ties by index.
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

/// The neighbour graph in compressed rows. Bridges are edges across gaps (from a small
/// piece of the cloud to its nearest point outside it), stored with a negative length.
struct NeighbourGraph {
    start: Vec<usize>,
    to: Vec<u32>,
    len: Vec<f64>,
}

impl NeighbourGraph {
    /// Neighbours with the edge length and whether the edge is a bridge.
    fn of(&self, i: usize) -> impl Iterator<Item = (usize, f64, bool)> + '_ {
        let r = self.start[i]..self.start[i + 1];
        self.to[r.clone()]
            .iter()
            .zip(&self.len[r])
            .map(|(&j, &d)| (j as usize, d.abs(), d < 0.0))
    }
}

fn neighbour_graph(prep: &Prepared) -> NeighbourGraph {
    let n = prep.pts.len();
    let max2 = (EDGE_SPACINGS * prep.params.spacing_m).powi(2);
    let k = crate::cloud::at_least_one(NEIGHBOURS + 1);
    let mut pairs: Vec<(u32, u32, f64)> = Vec::with_capacity(n * NEIGHBOURS);
    for (i, p) in prep.pts.iter().enumerate() {
        if !prep.main[i] {
            continue;
        }
        for nb in prep.tree.nearest_n::<SquaredEuclidean>(p, k) {
            let j = nb.item as usize;
            if j != i && prep.main[j] && nb.distance <= max2 {
                pairs.push((i as u32, nb.item, nb.distance.sqrt()));
            }
        }
    }
    bridge_small_pieces(prep, &mut pairs);
    let mut count = vec![0usize; n + 1];
    for &(i, j, _) in &pairs {
        count[i as usize] += 1;
        count[j as usize] += 1;
    }
    let mut start = vec![0usize; n + 1];
    for i in 0..n {
        start[i + 1] = start[i] + count[i];
    }
    let mut fill = start.clone();
    let mut to = vec![0u32; start[n]];
    let mut len = vec![0.0; start[n]];
    for &(i, j, d) in &pairs {
        for (a, b) in [(i, j), (j, i)] {
            let s = &mut fill[a as usize];
            to[*s] = b;
            len[*s] = d;
            *s += 1;
        }
    }
    NeighbourGraph { start, to, len }
}

/// Pieces of the graph up to this many points get a bridge from each of their points to
/// its nearest point outside the piece (found among the piece's size + 1 nearest), so the
/// shortest paths cross most gaps without stalling; larger pieces are joined at a stall.
const SMALL_PIECE: usize = 64;
/// A path pays this many times a bridge's length to cross it, so pieces are entered by
/// their shortest bridge and paths run through points where points allow. On tree13 and
/// Paris_Luxembourg_1 the model length near the cloud was 45.8 / 67.9 % at 1.5, 49.4 /
/// 70.1 % at 4, 50.3 / 70.6 % at 8, 50.8 / 71.0 % at 20 and 51.1 / 71.2 % at 100 (the
/// shares of points within 2 cm 0.1–0.4 points lower from 8 on).
pub const BRIDGE_COST: f64 = 20.0;

/// Add the bridges of the small pieces of the graph (see [`SMALL_PIECE`]), as edges with a
/// negative length, up to the longest gap.
fn bridge_small_pieces(prep: &Prepared, pairs: &mut Vec<(u32, u32, f64)>) {
    let n = prep.pts.len();
    let mut uf = UnionFind::new(n);
    for &(i, j, _) in pairs.iter() {
        uf.union(i as usize, j as usize);
    }
    let piece: Vec<usize> = (0..n).map(|i| uf.find(i)).collect();
    let mut size = vec![0usize; n];
    for i in (0..n).filter(|&i| prep.main[i]) {
        size[piece[i]] += 1;
    }
    let max = prep.params.max_gap_m;
    for i in (0..n).filter(|&i| prep.main[i] && size[piece[i]] <= SMALL_PIECE) {
        let k = crate::cloud::at_least_one(size[piece[i]] + 1);
        let out = prep
            .tree
            .nearest_n::<SquaredEuclidean>(&prep.pts[i], k)
            .into_iter()
            .find(|nb| prep.main[nb.item as usize] && piece[nb.item as usize] != piece[i]);
        if let Some(nb) = out
            && nb.distance.sqrt() <= max
        {
            pairs.push((
                i as u32,
                nb.item,
                -nb.distance.sqrt().max(f64::MIN_POSITIVE),
            ));
        }
    }
}

/// Shortest paths from the root's points: per point its path length, predecessor, the rank
/// in which it was reached, and whether it was reached by a bridge.
struct Paths {
    dist: Vec<f64>,
    pred: Vec<u32>,
    rank: Vec<u32>,
    bridged: Vec<bool>,
    bridges: usize,
    bridged_m: f64,
    unreached: usize,
}

fn shortest_paths(prep: &Prepared, g: &NeighbourGraph) -> Paths {
    let p = &prep.params;
    let n = prep.pts.len();
    let root = Vector3::from(p.root_m);
    let mut dist = vec![f64::INFINITY; n];
    let mut heap = BinaryHeap::new();
    let reach = p.trunk_radius_m + p.step_m;
    let mut nearest = (f64::INFINITY, NONE);
    for (i, q) in prep.pts.iter().enumerate() {
        if !prep.main[i] {
            continue;
        }
        let d = (Vector3::from(*q) - root).norm();
        if d <= reach {
            dist[i] = (d - p.trunk_radius_m).max(0.0);
            heap.push(Entry(dist[i], i as u32));
        }
        if d < nearest.0 {
            nearest = (d, i as u32);
        }
    }
    if heap.is_empty() && nearest.1 != NONE {
        dist[nearest.1 as usize] = 0.0;
        heap.push(Entry(0.0, nearest.1));
    }
    let mut out = Paths {
        dist,
        pred: vec![NONE; n],
        rank: vec![NONE; n],
        bridged: vec![false; n],
        bridges: 0,
        bridged_m: 0.0,
        unreached: 0,
    };
    let mut settled: Vec<u32> = Vec::new();
    // Each round settles at least the bridged point, so at most n rounds.
    for _ in 0..=n {
        while let Some(Entry(d, i)) = heap.pop() {
            let iu = i as usize;
            if out.rank[iu] != NONE || d > out.dist[iu] {
                continue;
            }
            if out.bridged[iu] {
                out.bridges += 1;
                out.bridged_m += (Vector3::from(prep.pts[iu])
                    - Vector3::from(prep.pts[out.pred[iu] as usize]))
                .norm();
            }
            out.rank[iu] = settled.len() as u32;
            settled.push(i);
            for (j, len, bridge) in g.of(iu) {
                let nd = d + if bridge { BRIDGE_COST * len } else { len };
                if out.rank[j] == NONE && nd < out.dist[j] {
                    out.dist[j] = nd;
                    out.pred[j] = i;
                    out.bridged[j] = bridge;
                    heap.push(Entry(nd, j as u32));
                }
            }
        }
        // Stalled: bridge from the reached points to the nearest unreached one.
        let reached: Vec<[f64; 3]> = settled.iter().map(|&i| prep.pts[i as usize]).collect();
        if reached.is_empty() {
            break;
        }
        let tree: ImmutableKdTree<f64, u32, 3, 32> = ImmutableKdTree::new_from_slice(&reached);
        let mut best: Option<(f64, usize, u32)> = None;
        for (i, q) in prep.pts.iter().enumerate() {
            if prep.main[i] && out.rank[i] == NONE {
                let nb = tree.nearest_one::<SquaredEuclidean>(q);
                if best.is_none_or(|b| nb.distance < b.0) {
                    best = Some((nb.distance, i, settled[nb.item as usize]));
                }
            }
        }
        let Some((d2, target, from)) = best else {
            break;
        };
        let gap = d2.sqrt();
        if gap > p.max_gap_m {
            out.unreached = (0..n)
                .filter(|&i| prep.main[i] && out.rank[i] == NONE)
                .count();
            break;
        }
        out.dist[target] = out.dist[from as usize] + BRIDGE_COST * gap;
        out.pred[target] = from;
        out.bridged[target] = true;
        heap.push(Entry(out.dist[target], target as u32));
    }
    out
}

struct UnionFind(Vec<u32>);

impl UnionFind {
    fn new(n: usize) -> Self {
        Self((0..n as u32).collect())
    }
    fn find(&mut self, mut i: usize) -> usize {
        while self.0[i] as usize != i {
            let up = self.0[i] as usize;
            self.0[i] = self.0[up];
            i = up;
        }
        i
    }
    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.0[ra.max(rb)] = ra.min(rb) as u32;
        }
    }
}

/// Whether the points form a ring around a branch: a circle fitted in the plane across
/// `axis` (the branch direction, when known) or across their thinnest direction covers
/// [`RING_COVERAGE`] with a small residual, and holds most of the points (a branch
/// leaving the ring adds points off the circle, which the fit sets aside).
fn is_ring(pts: &[[f64; 3]], members: &[u32], axis: Option<Vector3<f64>>) -> bool {
    if members.len() < RING_POINTS {
        return false;
    }
    let n = members.len() as f64;
    let mean = members
        .iter()
        .fold(Vector3::zeros(), |a, &i| a + Vector3::from(pts[i as usize]))
        / n;
    let (u, v) = match axis.and_then(|a| a.try_normalize(1e-12)) {
        Some(t) => crate::geometry::across(&t),
        None => {
            let mut cov = Matrix3::zeros();
            for &i in members {
                let d = Vector3::from(pts[i as usize]) - mean;
                cov += d * d.transpose();
            }
            let eig = cov.symmetric_eigen();
            let mut order = [0usize, 1, 2];
            order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
            (
                eig.eigenvectors.column(order[0]).into_owned(),
                eig.eigenvectors.column(order[1]).into_owned(),
            )
        }
    };
    let plane: Vec<[f64; 2]> = members
        .iter()
        .map(|&i| {
            let d = Vector3::from(pts[i as usize]) - mean;
            [d.dot(&u), d.dot(&v)]
        })
        .collect();
    fit_circle(&plane).is_some_and(|c| {
        c.coverage >= RING_COVERAGE
            && c.rms_m < RING_RMS_PER_RADIUS * c.radius_m
            && c.points as f64 >= RING_INLIERS * n
    })
}

/// The branch direction at a patch: the sum of the unit directions in which the shortest
/// paths reach its points (up the surface of a branch, whatever happened below).
fn path_axis(prep: &Prepared, paths: &Paths, members: &[u32]) -> Vector3<f64> {
    members
        .iter()
        .filter(|&&i| paths.pred[i as usize] != NONE)
        .filter_map(|&i| {
            (Vector3::from(prep.pts[i as usize])
                - Vector3::from(prep.pts[paths.pred[i as usize] as usize]))
            .try_normalize(1e-12)
        })
        .sum()
}

/// Patches of one bin with the same parent patch whose points together form a ring are
/// arcs of one branch's cross-section (a level set around a thick branch is wavy, so a
/// thin slice of it can break): merge them, bin by bin from the root.
fn merge_arcs(prep: &Prepared, paths: &Paths, uf: &mut UnionFind, bin: &dyn Fn(usize) -> i64) {
    let n = prep.pts.len();
    let mut members: HashMap<usize, Vec<u32>> = HashMap::new();
    let mut order: Vec<u32> = (0..n as u32)
        .filter(|&i| paths.rank[i as usize] != NONE)
        .collect();
    order.sort_by_key(|&i| paths.rank[i as usize]);
    // Patches by their first-reached point, in reach order (so by bin).
    let mut entries: Vec<u32> = Vec::new();
    for &i in &order {
        let r = uf.find(i as usize);
        let m = members.entry(r).or_default();
        if m.is_empty() {
            entries.push(i);
        }
        m.push(i);
    }
    let mut start = 0;
    while start < entries.len() {
        let b = bin(entries[start] as usize);
        let end = start
            + entries[start..]
                .iter()
                .take_while(|&&e| bin(e as usize) == b)
                .count();
        // Largest first: each smaller patch joins the nearest larger one when together
        // they are a ring.
        let mut group: Vec<(usize, Vector3<f64>)> = entries[start..end]
            .iter()
            .map(|&e| {
                let r = uf.find(e as usize);
                let m = &members[&r];
                let c = m.iter().fold(Vector3::zeros(), |a, &i| {
                    a + Vector3::from(prep.pts[i as usize])
                }) / m.len() as f64;
                (r, c)
            })
            .collect();
        group.sort_by_key(|(r, _)| std::cmp::Reverse(members[r].len()));
        for k in 1..group.len() {
            let (r, c) = group[k];
            let Some(&(q, _)) = group[..k]
                .iter()
                .min_by(|a, b| (a.1 - c).norm().total_cmp(&(b.1 - c).norm()))
            else {
                continue;
            };
            let (rq, rr) = (uf.find(q), uf.find(r));
            if rq == rr {
                continue;
            }
            let all: Vec<u32> = members[&rq].iter().chain(&members[&rr]).copied().collect();
            if is_ring(&prep.pts, &all, None) {
                uf.union(rq, rr);
                let keep = uf.find(rq);
                members.insert(keep, all);
            }
        }
        start = end.max(start + 1);
    }
}

/// Level sets grow on a cloud no denser than cubes of this many bins hold one point each
/// (1 cm at the bin's floor: the coffee tree's spacing, where level sets do well; half a
/// bin gave 11.9 mm axis error on the 10k synthetic tree against 8.9 mm).
pub const LEVEL_VOXEL_BINS: f64 = 2.0 / 3.0;
/// Clouds whose spacing is below this share of that cube are thinned (each cube's points
/// replaced by their centroid) before level-set growth; refinement and radii use every
/// point. None of the real clouds is (the densest, the coffee tree, has 0.97 of a 1 cm
/// cube), nor the 10k synthetic tree (0.49); the 100k one (0.19) is. It is for cost; on the
/// synthetic tree the axis error thinned / not is 13.4 / 13.5 mm at 100k points, 14.2 /
/// 15.4 mm at 300k and 16.4 / 18.9 mm at 1M (`docs/benchmarks.md`).
pub const THIN_BELOW_VOXEL: f64 = 1.0 / 3.0;

/// Grow the skeleton graph by geodesic level sets (see the module docs), on the cloud
/// thinned to [`LEVEL_VOXEL_BINS`] when it is much denser than that: the patches' ring
/// tests and link queries grow with the points per bin, so without it a denser scan of
/// the same tree cost more than n log n (1M synthetic points: growth 10.6 s of 38.1 s and
/// 500 MB; thinned 0.12 s of 23.8 s and 104 MB). The growth report's unreached points
/// then count cube centroids.
pub(crate) fn grow_levels(prep: &Prepared, levels: Levels) -> Result<Growth> {
    let voxel = LEVEL_VOXEL_BINS * levels.bin_m;
    if prep.params.spacing_m < THIN_BELOW_VOXEL * voxel {
        let thin = thinned(prep, voxel)?;
        return grow_levels_on(&thin, levels);
    }
    grow_levels_on(prep, levels)
}

/// The main cluster's points as the centroids of the points in each cube of `voxel_m`,
/// ready for growth (the spacing measured again).
fn thinned(prep: &Prepared, voxel_m: f64) -> Result<Prepared> {
    let mut cells: HashMap<[i64; 3], (Vector3<f64>, usize)> = HashMap::new();
    for (q, _) in prep.pts.iter().zip(&prep.main).filter(|(_, m)| **m) {
        let key = q.map(|c| (c / voxel_m).floor() as i64);
        let e = cells.entry(key).or_insert((Vector3::zeros(), 0));
        e.0 += Vector3::from(*q);
        e.1 += 1;
    }
    let mut keyed: Vec<([i64; 3], [f64; 3])> = cells
        .into_iter()
        .map(|(k, (s, c))| {
            let m = s / c as f64;
            (k, [m.x, m.y, m.z])
        })
        .collect();
    // A fixed order, whatever the hash map's.
    keyed.sort_unstable_by_key(|(k, _)| *k);
    let pts: Vec<[f64; 3]> = keyed.into_iter().map(|(_, p)| p).collect();
    let tree: crate::cloud::PointTree = ImmutableKdTree::new_from_slice(&pts);
    let spacing_m = crate::cloud::median_spacing(&pts, &tree)?;
    Ok(Prepared {
        main: vec![true; pts.len()],
        pts,
        tree,
        outliers: 0,
        ground: prep.ground.clone(),
        leaves: prep.leaves.clone(),
        params: crate::config::Parameters {
            spacing_m,
            ..prep.params
        },
    })
}

/// [`grow_levels`] on the cloud as given.
fn grow_levels_on(prep: &Prepared, levels: Levels) -> Result<Growth> {
    let graph = neighbour_graph(prep);
    let paths = shortest_paths(prep, &graph);
    let (patch_of, entry) = patches(prep, &paths, levels);
    nodes(prep, &paths, levels, &patch_of, &entry)
}

/// Patches of touching points of one bin, wide ones that are not rings split on a grid:
/// per point its patch (`NONE` if unreached) and per patch its first-reached point, in
/// the order they were reached (parents before children).
fn patches(prep: &Prepared, paths: &Paths, levels: Levels) -> (Vec<u32>, Vec<u32>) {
    let n = prep.pts.len();
    let bin = |i: usize| (paths.dist[i] / levels.bin_m).floor() as i64;
    let reached = |i: usize| paths.rank[i] != NONE;
    // Patches: points of one bin within the link distance of each other. Graph edges
    // alone would break the thin slice of a thick branch into arcs (a point's nearest
    // neighbours are mostly in the bins above and below).
    let link_m = LINK_BINS * levels.bin_m;
    let link_k = crate::cloud::at_least_one(LINK_NEIGHBOURS);
    // The reached points near point `i` that come after it (each pair once).
    let linked = |i: usize| {
        prep.tree
            .nearest_n_within::<SquaredEuclidean>(&prep.pts[i], link_m * link_m, link_k, false)
            .into_iter()
            .map(|nb| nb.item as usize)
            .filter(move |&j| j > i && reached(j))
    };
    let mut uf = UnionFind::new(n);
    for i in (0..n).filter(|&i| reached(i)) {
        for j in linked(i) {
            if bin(i) == bin(j) {
                uf.union(i, j);
            }
        }
    }
    merge_arcs(prep, paths, &mut uf, &bin);
    let mut members: HashMap<usize, Vec<u32>> = HashMap::new();
    for i in (0..n).filter(|&i| reached(i)) {
        members.entry(uf.find(i)).or_default().push(i as u32);
    }
    // Split the wide patches that are not rings on a grid. The ring is tested across the
    // direction from the parent patch (the patch of the path's predecessor of its first
    // point): a junction's patch, a ring with the base of a branch, has a tilted
    // principal plane but is a ring across the branch it continues.
    let centroid = |m: &[u32]| {
        m.iter().fold(Vector3::zeros(), |a, &i| {
            a + Vector3::from(prep.pts[i as usize])
        }) / m.len() as f64
    };
    let centres: HashMap<usize, Vector3<f64>> =
        members.iter().map(|(r, m)| (*r, centroid(m))).collect();
    // Per patch: wide (beyond half the patch size) and a ring, or neither.
    let mut wide: HashMap<usize, bool> = HashMap::new();
    let mut ring: HashMap<usize, bool> = HashMap::new();
    for (root, m) in &members {
        let c = centres[root];
        let extent = m
            .iter()
            .map(|&i| (Vector3::from(prep.pts[i as usize]) - c).norm())
            .fold(0.0, f64::max);
        let is_wide = extent > 0.5 * levels.patch_m;
        wide.insert(*root, is_wide);
        ring.insert(
            *root,
            is_wide
                && is_ring(
                    &prep.pts,
                    m,
                    Some(path_axis(prep, paths, m)).filter(|a| a.norm() > 0.0),
                ),
        );
    }
    let mut split = vec![false; n];
    for root in members.keys() {
        split[*root] = wide[root] && !ring[root];
    }
    let cell = |i: usize| {
        let q = prep.pts[i];
        [
            (q[0] / levels.patch_m).floor() as i64,
            (q[1] / levels.patch_m).floor() as i64,
            (q[2] / levels.patch_m).floor() as i64,
        ]
    };
    let first = (0..n).map(|i| uf.find(i)).collect::<Vec<_>>();
    // Patches that stay whole keep their points; split ones are cut into grid cells, each
    // cell's points joined as the patch's were.
    let mut uf = UnionFind::new(n);
    for i in (0..n).filter(|&i| reached(i)) {
        if !split[first[i]] {
            uf.union(i, first[i]);
            continue;
        }
        for j in linked(i) {
            if first[i] == first[j] && cell(i) == cell(j) {
                uf.union(i, j);
            }
        }
    }
    // Patches in the order their first point was reached: parents before children.
    let mut patch_of = vec![NONE; n];
    let mut entry: Vec<u32> = Vec::new();
    let mut by_rank: Vec<u32> = (0..n as u32).filter(|&i| reached(i as usize)).collect();
    by_rank.sort_by_key(|&i| paths.rank[i as usize]);
    let mut root_patch: Vec<u32> = vec![NONE; n];
    for &i in &by_rank {
        let r = uf.find(i as usize);
        if root_patch[r] == NONE {
            root_patch[r] = entry.len() as u32;
            entry.push(i);
        }
        patch_of[i as usize] = root_patch[r];
    }
    (patch_of, entry)
}

/// One node per patch at its centroid, each patch's parent the patch holding the path's
/// predecessor of its first point; bridges get intermediate nodes.
fn nodes(
    prep: &Prepared,
    paths: &Paths,
    levels: Levels,
    patch_of: &[u32],
    entry: &[u32],
) -> Result<Growth> {
    let patches = entry.len();
    // Each patch is one step of growth.
    if patches > prep.params.max_iterations {
        return Err(ColonizeError::IterationLimit {
            iterations: prep.params.max_iterations,
            nodes: 0,
            unreached: paths.unreached,
        });
    }
    if patches + 1 > prep.params.max_nodes {
        return Err(ColonizeError::NodeLimit {
            nodes: prep.params.max_nodes,
            unreached: paths.unreached,
        });
    }
    let mut sum = vec![Vector3::zeros(); patches];
    let mut count = vec![0usize; patches];
    for (i, &k) in patch_of.iter().enumerate().filter(|(_, k)| **k != NONE) {
        let (i, k) = (i as u32, k as usize);
        sum[k] += Vector3::from(prep.pts[i as usize]);
        count[k] += 1;
    }
    let centroid: Vec<Vector3<f64>> = sum.iter().zip(&count).map(|(s, &c)| s / c as f64).collect();
    let mut positions: Vec<[f64; 3]> = vec![prep.params.root_m];
    let mut parents: Vec<Option<usize>> = vec![None];
    let mut bridge = vec![false];
    let mut node_of = vec![0usize; patches];
    for (k, &e) in entry.iter().enumerate() {
        let c = centroid[k];
        let pred = paths.pred[e as usize];
        let parent = if pred == NONE {
            0
        } else {
            node_of[patch_of[pred as usize] as usize]
        };
        let mut parent = parent;
        if paths.bridged[e as usize] {
            // Intermediate nodes along a bridge longer than a bin.
            let a = Vector3::from(positions[parent]);
            let steps = ((c - a).norm() / levels.bin_m).floor();
            // Checked before adding: a long bridge with a tiny bin would otherwise fill
            // memory before the node bound is looked at.
            if positions.len() as f64 + steps >= prep.params.max_nodes as f64 {
                return Err(ColonizeError::NodeLimit {
                    nodes: prep.params.max_nodes,
                    unreached: paths.unreached,
                });
            }
            let steps = steps as usize;
            for s in 1..steps {
                let q = a + (c - a) * (s as f64 / steps as f64);
                positions.push([q.x, q.y, q.z]);
                parents.push(Some(parent));
                bridge.push(true);
                parent = positions.len() - 1;
            }
        }
        if positions.len() >= prep.params.max_nodes {
            return Err(ColonizeError::NodeLimit {
                nodes: positions.len(),
                unreached: paths.unreached,
            });
        }
        positions.push([c.x, c.y, c.z]);
        parents.push(Some(parent));
        bridge.push(false);
        node_of[k] = positions.len() - 1;
    }
    Ok(Growth {
        positions,
        parents,
        iterations: patches,
        bridges: paths.bridges,
        bridged_m: paths.bridged_m,
        unreached: paths.unreached,
        abandoned: 0,
        bridge,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::prepare;
    use crate::config::ColonizeConfig;
    use crate::synthetic::SyntheticConfig;

    #[test]
    fn thinning_keeps_one_centroid_per_cube_of_the_main_cluster() {
        let truth = SyntheticConfig {
            points: 20_000,
            ..Default::default()
        }
        .generate()
        .unwrap();
        let prep = prepare(&truth.points, &ColonizeConfig::default()).unwrap();
        let voxel = 0.01;
        let thin = thinned(&prep, voxel).unwrap();
        let key = |q: &[f64; 3]| q.map(|c| (c / voxel).floor() as i64);
        let mut cubes: Vec<[i64; 3]> = prep
            .pts
            .iter()
            .zip(&prep.main)
            .filter(|(_, m)| **m)
            .map(|(q, _)| key(q))
            .collect();
        cubes.sort_unstable();
        cubes.dedup();
        assert_eq!(thin.pts.len(), cubes.len());
        assert!(thin.pts.len() < prep.pts.len() / 2, "{}", thin.pts.len());
        // Each centroid lies in its own cube, one per cube.
        let mut own: Vec<[i64; 3]> = thin.pts.iter().map(key).collect();
        own.sort_unstable();
        own.dedup();
        assert_eq!(own, cubes);
        assert!(thin.main.iter().all(|&m| m));
        // The spacing is measured again: about the cube, well above the cloud's.
        assert!(
            thin.params.spacing_m > 1.5 * prep.params.spacing_m,
            "{} {}",
            thin.params.spacing_m,
            prep.params.spacing_m
        );
        assert!(
            thin.params.spacing_m < 2.0 * voxel,
            "{}",
            thin.params.spacing_m
        );
        assert_eq!(thin.params.bin_m, prep.params.bin_m);
    }
}
