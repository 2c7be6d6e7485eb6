//! The whole reconstruction: prepare, grow, refine.

use nalgebra::{Point3, Vector3};
use serde::Serialize;

use crate::cloud::{PointTree, Prepared, prepare};
use crate::config::{AUTO_NEAR_SHARE, ColonizeConfig, Growth, Parameters};
use crate::error::{ColonizeError, Result};
use crate::fidelity::model_near_cloud;
use crate::ground::Ground;
use crate::grow::{Pass, grow};
use crate::levels::{Levels, grow_levels};
use crate::metrics::NEAR_CLOUD_M;
use crate::refine::{
    Centring, Graph, ONE_SIDED_TANGENT_SPAN, far_tails, inside_parent_twigs, twig_stubs,
    unneeded_stubs,
};
use crate::skeleton::{Branch, Skeleton, SkeletonNode};
use crate::wood::Leaves;

/// Laplacian passes on the grown nodes before centring.
const PRE_CENTRING_PASSES: usize = 3;

/// The twig pass attracts only points at least this far from the first model's surface,
/// metres: closer ones are the first model's radius and centring error, not missing twigs
/// (the 2 cm fidelity bound).
const TWIG_PASS_MIN_DISTANCE_M: f64 = NEAR_CLOUD_M;

/// Rounds of cutting twigs that end in the air (the radii change after a cut, so a second
/// round can find more).
const FAR_TIP_ROUNDS: usize = 2;

/// A twig end counts as in the air beyond this many point spacings from every point, when
/// that is more than [`NEAR_CLOUD_M`] (sparse clouds: mid-segments are that far from the
/// nearest point along their own twig).
pub const FAR_TIP_SPACINGS: f64 = 2.0;

/// Stages reported to a progress callback, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[non_exhaustive]
pub enum Stage {
    /// Validation, spacing, trunk radius, outlier clusters, k-d tree.
    Prepare,
    /// Space colonization.
    Grow,
    /// Tips, centring, smoothing.
    Refine,
    /// Radii, pruning, branches.
    Radii,
}

/// What growth did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GrowthReport {
    /// Iterations of the growth loop.
    pub iterations: usize,
    /// Nodes grown (before refinement).
    pub grown_nodes: usize,
    /// Straight bridges across gaps.
    pub bridges: usize,
    /// Total length of the bridges, metres.
    pub bridged_length_m: f64,
    /// Points not modelled: in clusters beyond the largest bridge from the main cluster, or
    /// isolated (fewer than 3 other points within 15 median spacings: stray returns). Ground
    /// points are not counted here but in [`Reconstruction::ground`].
    pub outlier_points: usize,
    /// Points of the main cluster growth never reached.
    pub unreached_points: usize,
    /// Points given up because their node could not move toward them.
    pub abandoned_points: usize,
    /// Terminal stubs removed.
    pub pruned_twigs: usize,
    /// Twig ends cut because they ran more than [`NEAR_CLOUD_M`] (or
    /// [`FAR_TIP_SPACINGS`] point spacings, if more) from every point and no point needed
    /// them. Those points need, other than bridges, are moved onto their points.
    pub far_tips: usize,
    /// Whether the fitted radii were used (see [`ColonizeConfig::radius_fits`]); false when
    /// not asked for or when they disagree with the pipe model by more than a factor of 2
    /// at the median (leaf clumps, not wood).
    pub radius_fits_used: bool,
    /// Segments whose cylinder was fitted to their own points as the last stage
    /// ([`ColonizeConfig::cylinder_fits`]; 0 for one-sided views and when not asked for).
    pub fitted_segments: usize,
    /// Stretches of thick chains continued straight through what the camera could not see
    /// (one-sided views grown by colonization with the camera known,
    /// [`ColonizeConfig::hidden_wood`]; see `hidden.rs`).
    pub hidden_stretches: usize,
    /// With [`Growth::Auto`]: the "model near cloud" of the first space-colonization growth
    /// (before refinement, with pipe-model radii from the trunk radius: the share of its
    /// length within [`NEAR_CLOUD_M`] of a point beyond its surface, see [`crate::fidelity()`]);
    /// below [`AUTO_NEAR_SHARE`] the tree was grown by level sets instead. `None` when a
    /// method was asked for.
    pub colonization_near_cloud: Option<f64>,
}

/// A reconstructed tree.
#[derive(Debug, Clone)]
pub struct Reconstruction {
    /// Nodes, parents, radii.
    pub skeleton: Skeleton,
    /// Branches with orders and lengths ([`Skeleton::branches`]).
    pub branches: Vec<Branch>,
    /// The parameters used (derived where the config left them open).
    pub parameters: Parameters,
    /// What growth did.
    pub growth: GrowthReport,
    /// The ground plane found under the tree and set aside before growth
    /// ([`ColonizeConfig::remove_ground`]); `None` when there was none (or not asked for).
    pub ground: Option<Ground>,
    /// The points taken for leaves and set aside before growth
    /// ([`ColonizeConfig::separate_leaves`], [`crate::separate_wood`]); `None` when not
    /// asked for.
    pub leaves: Option<Leaves>,
    /// The cloud looked like a depth camera's own frame (y down, z forward), not Z up
    /// ([`crate::looks_like_camera_frame`]): the model was grown from the front of the tree
    /// upward along the view and cannot be trusted. Turn the cloud first
    /// ([`crate::UpAxis::MinusY`] for a level camera).
    pub camera_frame_suspected: bool,
    /// The scan's noise about the model's surface, metres: the robust spread of the points
    /// about the branches at least [`crate::NOISE_BRANCH_RADIUS_M`] thick (`None` with too
    /// few points on such branches). Above [`NOISY_SCAN_M`] the volume cannot be trusted
    /// ([`Self::volume_trusted`]).
    pub surface_noise_m: Option<f64>,
}

/// Scan noise above which a model's volume cannot be trusted, metres. Noise widens circle
/// fits to thin branches and grows parallel chains up thick ones: the leaf-off coffee tree
/// (its own noise 1.7 mm by [`Reconstruction::surface_noise_m`]) with 3, 5 and 10 mm of
/// Gaussian noise added measured 2.8, 4.2 and 7.0 mm, and its volume came out +36, +52 and
/// +82 %. One-sided views with their camera known ([`crate::ColonizeConfig::camera_m`])
/// measure thin branches across the rays and are held to [`NOISY_VIEW_M`] instead.
pub const NOISY_SCAN_M: f64 = 0.0025;
/// The same for a one-sided view whose camera is known, metres. Five views of the coffee
/// tree (`camera_view`) with 3, 6 and 9 mm of depth noise measured 2.4–2.7, 3.6–4.2 and
/// 4.8–5.6 mm; their volumes were within 10 % of TreeQSM's at 3 and 6 mm, and two of five
/// were +12 and +18 % at 9 mm. Chosen on those views.
pub const NOISY_VIEW_M: f64 = 0.0045;

impl Reconstruction {
    /// Whether the scan is quiet enough for the model's volume to be trusted (see
    /// [`NOISY_SCAN_M`]); true when no noise could be measured.
    pub fn volume_trusted(&self) -> bool {
        let limit = if self.parameters.camera_m.is_some() {
            NOISY_VIEW_M
        } else {
            NOISY_SCAN_M
        };
        self.surface_noise_m.is_none_or(|n| n <= limit)
    }

    /// Number of branches of each order, index = order.
    pub fn branches_by_order(&self) -> Vec<usize> {
        let max = self.branches.iter().map(|b| b.order).max().unwrap_or(0);
        let mut v = vec![0; max + 1];
        for b in &self.branches {
            v[b.order] += 1;
        }
        v
    }
}

/// Reconstruct a tree from its points (metres, Z up).
///
/// # Errors
/// Bad points or parameters ([`ColonizeError::NonFinitePoint`], [`ColonizeError::TooFewPoints`],
/// [`ColonizeError::Degenerate`], [`ColonizeError::InvalidParameter`]), growth bounds
/// ([`ColonizeError::IterationLimit`], [`ColonizeError::NodeLimit`]), or
/// [`ColonizeError::NoGrowth`] when nothing grew from the root.
pub fn reconstruct(points: &[Point3<f64>], config: &ColonizeConfig) -> Result<Reconstruction> {
    reconstruct_with_progress(points, config, &mut |_| {})
}

/// [`reconstruct`], calling `progress` as each stage starts.
///
/// # Errors
/// As [`reconstruct`].
#[allow(clippy::too_many_lines)] // longer than 100 lines: the stages change with issue 22 (growth that follows wood); split then
pub fn reconstruct_with_progress(
    points: &[Point3<f64>],
    config: &ColonizeConfig,
    progress: &mut dyn FnMut(Stage),
) -> Result<Reconstruction> {
    progress(Stage::Prepare);
    let prep = prepare(points, config)?;
    progress(Stage::Grow);
    let colonize = |prep: &Prepared| {
        let p = prep.params;
        grow(
            prep,
            Pass {
                seeds: (&[], &[]),
                attract: prep.main.clone(),
                kill_m: p.kill_distance_m,
                influence_m: p.influence_m,
                step_m: p.step_m,
                bridges: true,
            },
        )
    };
    let by_levels = |prep: &Prepared| {
        let p = prep.params;
        grow_levels(
            prep,
            Levels {
                bin_m: p.bin_m,
                patch_m: p.patch_m,
            },
        )
    };
    let (g, levels, colonization_near_cloud) = match prep.params.growth {
        Growth::LevelSets => (by_levels(&prep)?, true, None),
        Growth::Colonization => (colonize(&prep)?, false, None),
        Growth::Auto => {
            let g = colonize(&prep)?;
            let p = prep.params;
            let near = near_share(
                &g.positions,
                &g.parents,
                &prep.tree,
                p.trunk_radius_m,
                p.pipe_exponent,
            );
            if near >= AUTO_NEAR_SHARE {
                (g, false, Some(near))
            } else {
                (by_levels(&prep)?, true, Some(near))
            }
        }
    };
    let p = Parameters {
        growth: if levels {
            Growth::LevelSets
        } else {
            Growth::Colonization
        },
        ..prep.params
    };
    if g.positions.len() < 2 {
        return Err(ColonizeError::NoGrowth {
            points: prep.main.iter().filter(|&&m| m).count(),
            kill_distance_m: p.kill_distance_m,
        });
    }
    progress(Stage::Refine);
    let mut graph = Graph {
        pos: g.positions.iter().map(|x| Vector3::from(*x)).collect(),
        parent: g.parents.clone(),
        bridge: g.bridge.clone(),
    };
    // Nodes by forks (by default) are centred in full scans grown by colonization, in
    // the first refinement only (in the twig pass's short twigs it drew model parts off
    // the cloud). Level-set nodes are already patch centres (centring them there cost
    // tree13 and Paris 2 points of model near the cloud), and in one-sided views the half
    // rings by a fork gave one coffee view 18 % more volume.
    let near_forks = config.centre_forks && !levels && !p.one_sided;
    // Cross-sections of a one-sided view's colonization chains are taken over a longer span.
    let one_sided_colonization = p.one_sided && !levels;
    let span = if one_sided_colonization {
        ONE_SIDED_TANGENT_SPAN
    } else {
        1
    };
    let refine = |graph: &mut Graph, from: usize| {
        // Level-set tips are already at the last points of their twig.
        if !(levels && from == 0) {
            graph.extend_tips(&prep.pts, &prep.main, &p, from);
        }
        // SC nodes zig-zag between the attractors of successive steps: straighten them
        // before centring, then remove the centring noise without shrinking bends.
        // Level-set nodes are patch centres on the points; smoothing would pull the
        // nodes of sparse twigs and leaves off their points.
        if !(levels && from == 0) {
            graph.smooth_from(PRE_CENTRING_PASSES, from, false);
        }
        // Where no circle fits, space colonization's nodes move to the centroid of their
        // cross-section; a level-set node already is a patch centre, and the centroid of
        // its neighbours' points would pull a sparse twig's node off its points.
        if config.centring {
            graph.centre(
                &prep.pts,
                &prep.main,
                &p,
                from,
                Centring {
                    centroid_fallback: !levels,
                    near_forks: near_forks && from == 0,
                    span,
                },
            );
        }
        if !(levels && from == 0) {
            graph.smooth_from(config.smoothing_iterations, from, true);
        }
    };
    refine(&mut graph, 0);
    let radii = |graph: &Graph| {
        let fits = config
            .radius_fits
            .then(|| graph.fit_radii(&prep.pts, &prep.main, &p));
        let (s, used) = graph.to_skeleton(
            p.pipe_exponent,
            p.trunk_radius_m,
            fits.as_deref(),
            near_forks.then_some(crate::refine::MAX_FIT_PER_PIPE_MEDIAN),
        )?;
        // A one-sided view's chain measured thin where the camera hardly saw it.
        let s = if p.one_sided {
            crate::hidden::no_thinner_than_its_continuation(&s, p.trunk_radius_m, p.pipe_exponent)?
        } else {
            s
        };
        Ok((s, used))
    };
    let (mut skeleton, mut fits_used) = radii(&graph)?;
    // What the camera saw through, when it is known (see `crate::hidden`).
    let hidden_space = if config.hidden_wood {
        p.camera_m
            .and_then(|c| crate::hidden::SeenSpace::new(&prep.pts, &prep.main, c, p.spacing_m))
    } else {
        None
    };
    if one_sided_colonization {
        // Chains that looped across a half-seen thick branch: onto their chords.
        let r: Vec<f64> = skeleton.nodes().iter().map(|n| n.radius_m).collect();
        if graph.straighten_loops(&r) > 0 {
            (skeleton, fits_used) = radii(&graph)?;
        }
    }
    // Twigs shorter than the kill distance were never grown: their points sit off the
    // model. Grow once more from the whole skeleton toward those, with a fine kill distance.
    let mut twig_growth = None;
    if p.twig_kill_distance_m < p.kill_distance_m {
        let d = crate::metrics::point_distances_among(
            &prep.pts,
            &skeleton,
            crate::metrics::TWIG_PASS_CANDIDATE_CYLINDERS,
        );
        let attract: Vec<bool> = d
            .iter()
            .zip(&prep.main)
            .map(|(&d, &m)| m && d > p.twig_kill_distance_m.max(TWIG_PASS_MIN_DISTANCE_M))
            .collect();
        if attract.iter().any(|&a| a) {
            let seeds: Vec<[f64; 3]> = graph.pos.iter().map(|v| [v.x, v.y, v.z]).collect();
            let g2 = grow(
                &prep,
                Pass {
                    seeds: (&seeds, &graph.parent),
                    attract,
                    kill_m: p.twig_kill_distance_m,
                    influence_m: p.influence_m,
                    step_m: p.step_m.min(0.5 * p.twig_kill_distance_m),
                    bridges: false,
                },
            )?;
            let from = graph.pos.len();
            if g2.positions.len() > from {
                graph.pos = g2.positions.iter().map(|x| Vector3::from(*x)).collect();
                graph.parent = g2.parents.clone();
                // The seeds keep their flags; this pass does not bridge.
                graph.bridge.resize(graph.pos.len(), false);
                refine(&mut graph, from);
                (skeleton, fits_used) = radii(&graph)?;
            }
            twig_growth = Some(g2);
        }
    }
    let radii_of = |graph: &Graph| radii(graph).map(|(s, _)| s);
    let mut pruned = 0;
    // Level sets give a chain to every patch, also parallel chains along the surface of a
    // thick branch: any terminal twig no point needs goes, not only the short stubs.
    let stub_m = if levels { f64::INFINITY } else { p.min_twig_m };
    for _ in 0..2 {
        let mut stubs = twig_stubs(&skeleton, stub_m);
        // Colonization also grows twigs along the inside of a thick branch's surface.
        if !levels {
            for c in inside_parent_twigs(&skeleton, p.min_twig_m) {
                if !stubs.contains(&c) {
                    stubs.push(c);
                }
            }
        }
        let removed = remove_unneeded(&mut graph, &skeleton, &stubs, &prep, &radii_of)?;
        if removed == 0 {
            break;
        }
        pruned += removed;
        (skeleton, fits_used) = radii(&graph)?;
    }
    if config.centring {
        // With the radii known, fit circles of those radii: thin branches of one-sided views
        // had only centroids.
        let r: Vec<f64> = skeleton.nodes().iter().map(|n| n.radius_m).collect();
        graph.centre_on_radius(&prep.pts, &prep.main, &r, span);
        if !levels {
            graph.smooth_from(config.smoothing_iterations, 0, true);
        }
        (skeleton, fits_used) = radii(&graph)?;
    }
    // Chains drawn along what hides them: through the hidden stretch instead.
    let mut hidden_stretches = 0;
    if one_sided_colonization && let Some(seen) = hidden_space.as_ref() {
        let r: Vec<f64> = skeleton.nodes().iter().map(|n| n.radius_m).collect();
        hidden_stretches = crate::hidden::continue_hidden(&mut graph, &r, seen, p.step_m);
        if hidden_stretches > 0 {
            (skeleton, fits_used) = radii(&graph)?;
        }
    }
    let mut far_tips = 0;
    let near_m = NEAR_CLOUD_M.max(FAR_TIP_SPACINGS * p.spacing_m);
    for _ in 0..FAR_TIP_ROUNDS {
        let tails = far_tails(&skeleton, &prep.tree, near_m);
        let removed = remove_unneeded(&mut graph, &skeleton, &tails, &prep, &radii_of)?;
        if removed == 0 {
            break;
        }
        far_tips += removed;
        (skeleton, fits_used) = radii(&graph)?;
    }
    // The twig ends points need (other than bridges): onto those points.
    let tails = far_tails(&skeleton, &prep.tree, near_m);
    if !tails.is_empty() {
        let r: Vec<f64> = skeleton.nodes().iter().map(|n| n.radius_m).collect();
        if graph.onto_cloud(&tails, &prep.tree, &prep.pts, &r) > 0 {
            (skeleton, fits_used) = radii(&graph)?;
        }
    }
    // The scan's noise about the smooth model: the fits below follow some of it.
    let surface_noise_m = crate::metrics::surface_noise(&prep.pts, &skeleton);
    // Each segment's cylinder onto its own points (full scans only: a one-sided view's
    // half rings cover too little of a circle for a free fit; not for the pure pipe model).
    let mut fitted_segments = 0;
    if config.cylinder_fits && config.radius_fits && !p.one_sided {
        (skeleton, fitted_segments) = crate::fit::fit_segments(
            &skeleton,
            &prep.pts,
            &prep.main,
            surface_noise_m.unwrap_or(0.0),
        )?;
    }
    let branches = skeleton.branches();
    Ok(Reconstruction {
        growth: GrowthReport {
            iterations: g.iterations + twig_growth.as_ref().map_or(0, |t| t.iterations),
            grown_nodes: twig_growth
                .as_ref()
                .map_or(g.positions.len(), |t| t.positions.len()),
            bridges: g.bridges,
            bridged_length_m: g.bridged_m,
            outlier_points: prep.outliers,
            unreached_points: g.unreached,
            abandoned_points: g.abandoned,
            pruned_twigs: pruned,
            far_tips,
            radius_fits_used: fits_used,
            fitted_segments,
            hidden_stretches,
            colonization_near_cloud,
        },
        skeleton,
        branches,
        parameters: p,
        ground: prep.ground.clone(),
        leaves: prep.leaves.clone(),
        camera_frame_suspected: crate::frame::looks_like_camera_frame(points),
        surface_noise_m,
    })
}

/// The "model near cloud" ([`crate::fidelity()`]) of a grown graph (`positions`,
/// `parents`) given pipe-model radii anchored to `trunk_radius_m` at the root (exponent
/// `pipe_exponent`), since a node on the axis of a thick branch is a radius from its
/// points. 0 for a graph without length or that is not one tree.
fn near_share(
    positions: &[[f64; 3]],
    parents: &[Option<usize>],
    tree: &PointTree,
    trunk_radius_m: f64,
    pipe_exponent: f64,
) -> f64 {
    let node = |id: usize, radius_m: f64| SkeletonNode {
        id,
        parent: parents[id],
        position: Point3::from(positions[id]),
        radius_m,
    };
    let Ok(flat) = Skeleton::new((0..positions.len()).map(|id| node(id, 0.0)).collect()) else {
        return 0.0;
    };
    let w = flat.carried_length_m();
    let w_root = w[flat.root()];
    if w_root <= 0.0 {
        return 0.0;
    }
    let radius = |id: usize| trunk_radius_m * (w[id] / w_root).powf(1.0 / pipe_exponent);
    match Skeleton::new(
        (0..positions.len())
            .map(|id| node(id, radius(id)))
            .collect(),
    ) {
        Ok(piped) => model_near_cloud(&piped, tree),
        Err(_) => 0.0,
    }
}

/// Remove the `candidates` (lists of nodes, each with its subtree) that no point needs
/// ([`unneeded_stubs`]): a point more than [`NEAR_CLOUD_M`] from the model without them
/// that is nearer to one of a candidate's nodes keeps that candidate. Returns how many
/// went.
fn remove_unneeded(
    graph: &mut Graph,
    skeleton: &Skeleton,
    candidates: &[Vec<usize>],
    prep: &Prepared,
    radii: &dyn Fn(&Graph) -> Result<Skeleton>,
) -> Result<usize> {
    if candidates.is_empty() {
        return Ok(0);
    }
    let mut keep = vec![true; graph.pos.len()];
    candidates.iter().flatten().for_each(|&v| keep[v] = false);
    let mut trial = graph.clone();
    trial.retain(&keep);
    let d = crate::metrics::point_distances(&prep.pts, &radii(&trial)?);
    let remove = unneeded_stubs(
        &prep.pts,
        &prep.main,
        skeleton,
        candidates,
        &d,
        NEAR_CLOUD_M,
    );
    for (c, _) in candidates.iter().zip(&remove).filter(|(_, r)| !**r) {
        c.iter().for_each(|&v| keep[v] = true);
    }
    let removed = remove.iter().filter(|&&r| r).count();
    if removed > 0 {
        graph.retain(&keep);
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rings of 12 points around the z axis every centimetre from 0 to 1 m, tapering from
    /// `radius_m` as a pipe model of exponent 2.5 over a 1 m chain does (at height z the
    /// chain above carries 1 - z metres).
    fn tube(radius_m: f64) -> Vec<[f64; 3]> {
        let mut pts = Vec::new();
        for k in 0..100 {
            let z = 0.01 * f64::from(k);
            let r = radius_m * (1.0 - z).powf(1.0 / 2.5);
            for a in 0..12 {
                let phi = f64::from(a) * std::f64::consts::TAU / 12.0;
                pts.push([r * phi.cos(), r * phi.sin(), z]);
            }
        }
        pts
    }

    #[test]
    fn near_share_measures_against_the_pipe_surface() {
        let pts = tube(0.05);
        let tree = PointTree::new_from_slice(&pts);
        // A chain up the axis: a radius from the points, inside a pipe that tapers the same.
        let axis: Vec<[f64; 3]> = (0..=10).map(|k| [0.0, 0.0, 0.1 * f64::from(k)]).collect();
        let parents: Vec<Option<usize>> = (0..=10usize).map(|k| k.checked_sub(1)).collect();
        let on_axis = near_share(&axis, &parents, &tree, 0.05, 2.5);
        assert!((on_axis - 1.0).abs() < 1e-12, "{on_axis}");
        // Thought 1 cm thick at its base, the chain is far from the thick part's points.
        let thin = near_share(&axis, &parents, &tree, 0.01, 2.5);
        assert!(thin < 0.5, "{thin}");
        // Half of it beyond the tube's top: half near.
        let over: Vec<[f64; 3]> = (0..=10)
            .map(|k| [0.0, 0.0, 0.5 + 0.1 * f64::from(k)])
            .collect();
        let half = near_share(&over, &parents, &tree, 0.05, 2.5);
        assert!((half - 0.5).abs() < 0.1, "{half}");
        // No length, nothing near.
        assert_eq!(near_share(&axis[..1], &parents[..1], &tree, 0.05, 2.5), 0.0);
    }
}
