//! Reconstruction parameters: what the user may set, and the values derived from the cloud.

use nalgebra::Point3;
use serde::Serialize;

use crate::error::{ColonizeError, Result};

/// Kill distance per trunk radius: the "at least about the trunk radius"; 1.2 kills
/// the trunk's own surface points from a node on its axis despite scan noise and a trunk
/// that is not round.
pub const KILL_PER_TRUNK_RADIUS: f64 = 1.2;
/// Kill distance per trunk radius for a one-sided view ([`ONE_SIDED_COVERAGE`]): a node
/// drawn to the points of a half-seen branch sits 2r/π in front of its axis, so the edges
/// of the half ring are 1.19 r from it and escaped a 1.2 r kill distance, to grow a second
/// chain up the branch beside the first (each then measured half as thick). 1.6 leaves a
/// margin for noise. Measured on Kinect views of synthetic trees (`docs/validation.md`):
/// 1.4 keeps some parallel chains, 1.8 gives the same as 1.6.
pub const KILL_PER_TRUNK_RADIUS_ONE_SIDED: f64 = 1.6;
/// The cloud is taken for a one-sided view when the circle fitted to the trunk's lowest
/// slice covers less than this share of its 16 sectors (full scans 1.0; Kinect views of
/// the coffee tree 0.50–0.69; the AdTree clouds, mobile and terrestrial scans from a few
/// sides, 0.44–0.69).
pub const ONE_SIDED_COVERAGE: f64 = 0.75;
/// Kill distance in point spacings at least, so thin clouds still grow.
pub const MIN_KILL_SPACINGS: f64 = 3.0;
/// Segment length in point spacings (Runions et al. use a step well below the kill distance;
/// 1.5 spacings keeps nodes on the data).
pub const STEP_SPACINGS: f64 = 1.5;
/// Shortest default step per kill distance: keeps the node count of a tree independent of
/// the scan density, so growth on a denser scan of the same tree costs O(n log n), not
/// O(n^1.5) (each node's influence query returns O(n) points).
pub const MIN_STEP_PER_KILL: f64 = 0.25;
/// Longest default kill distance of the twig pass, metres: a point is left up to the kill
/// distance from its node, and the coverage bound for sparse scans is 5 cm
/// (`adtree/tree13.xyz`, 5.3 cm spacing, where 3 spacings would leave leaf clumps 16 cm off).
pub const MAX_TWIG_KILL_M: f64 = 0.05;
/// Influence radius per kill distance (2.5–3 in the issue; Runions et al. 2007, fig. 5).
pub const INFLUENCE_PER_KILL: f64 = 2.75;
/// Largest gap growth bridges, in influence radii (an occluded trunk stretch of a sparse
/// scan, `adtree/tree13.xyz`, is about 2 influence radii).
pub const MAX_GAP_INFLUENCES: f64 = 8.0;
/// Level-set bin width in point spacings (see [`Growth::LevelSets`]): on the AdTree clouds
/// (tree7, tree13, Paris_Luxembourg_1) 1 spacing keeps 2–10 % more points within 2 cm of
/// the model than 1.5 and 2.5.
pub const LEVEL_BIN_SPACINGS: f64 = 1.0;
/// Narrowest level-set bin, metres: on the leaf-off coffee tree (9.7 mm spacing) bins of
/// one spacing split thin rings of dense scans into arcs that become parallel chains (the
/// length +80 %); 1.5 cm gives +9 %.
pub const MIN_LEVEL_BIN_M: f64 = 0.015;
/// Widest patch that is not a ring, in bins,
pub const PATCH_BINS: f64 = 2.0;
/// ... and in metres: a leaf patch wider than this leaves its points more than 2 cm (the
/// comparison's fidelity bound) from the node at its centre.
pub const MAX_PATCH_M: f64 = 0.03;

/// [`Growth::Auto`] keeps space colonization when at least this share of its grown
/// skeleton (before any refinement, sampled every centimetre, with pipe-model radii from the
/// trunk radius) lies within [`crate::metrics::NEAR_CLOUD_M`] (2 cm, the fidelity
/// bound) of a point: the "model near cloud" on the raw growth. Measured
/// (`docs/validation.md`): the leaf-off coffee tree 0.996, its three one-sided Kinect views
/// 0.90–0.95, the pipeline's one-sided twin 0.99, synthetic trees with and without leaf
/// clumps 0.86–1.00, against 0.68 (tree7), 0.16 (tree13) and 0.28 (Paris_Luxembourg_1),
/// where colonization runs through the air between leaf clumps. 0.8 lies between the
/// two groups; it was chosen on those clouds.
pub const AUTO_NEAR_SHARE: f64 = 0.8;

/// How the skeleton graph is grown.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[non_exhaustive]
pub enum Growth {
    /// The default: grow by space colonization, measure how much of what grew lies near
    /// the points, and when less than [`AUTO_NEAR_SHARE`] does (a leafy or sparse crown,
    /// where colonization draws branches through the air), grow again by level sets.
    /// Colonization's first growth is a small part of its time (2–7 % on the real clouds),
    /// so the choice costs little. [`Parameters::growth`] and
    /// [`crate::GrowthReport::colonization_near_cloud`] say which was used and why.
    Auto,
    /// Geodesic level sets over a neighbour graph of the points (Xu, Gossett & Chen 2007):
    /// every node is the centre of a patch of points and every edge joins two patches that
    /// touch, so the model follows the points and ends in leaf clumps instead of crossing
    /// crowns. Better on leafy and sparse scans: on the AdTree clouds (tree7, tree13,
    /// Paris_Luxembourg_1) it beats AdTree on mean point-to-surface, points within 2 cm
    /// and model near the cloud (`docs/validation.md`). Not the default yet: on the
    /// leaf-off coffee tree it keeps short twigs TreeQSM does not (length +15 %), and on
    /// the pipeline's one-sided Kinect twin its axes are 12.6 mm from the truth
    /// (colonization 7.4 mm: the patch centres of half-seen branches sit on their near
    /// surface). [`Growth::Auto`] picks it where colonization runs through the air.
    LevelSets,
    /// Space colonization (Runions et al. 2007), the paper's method: the nodes grow toward
    /// the mean direction of their attractors, which in a leafy crown runs through the air.
    /// [`Growth::Auto`] keeps it on wood (leaf-off scans, one-sided views of branches).
    Colonization,
}

/// Pipe-model exponent (the issue: on real scans 2.5 matched TreeQSM's volume within 5 %,
/// 2 gave −21 % and 3 gave +33 %).
pub const PIPE_EXPONENT: f64 = 2.5;
/// Branches whose fitted radius is under this are also measured across the view ray when
/// the camera is known ([`ColonizeConfig::camera_m`]), metres. Depth noise (a Kinect's 5–8
/// mm along the ray) lengthens a thin branch's half ring along the ray and a circle fitted
/// to it comes out wide: on three one-sided views of the coffee tree, branches TreeQSM
/// measures under 1 cm came out 1.13–1.19 times as thick. Under 1 cm no fit was narrowed
/// (a thin branch's noisy fit is wider than that), 1.5 and 2 cm gave the same volumes.
pub const ACROSS_RAY_MAX_RADIUS_M: f64 = 0.015;
/// The central 90 % of a half ring's coordinates across the view ray spans this many radii
/// (1.8 when the ring is sampled evenly across the image, a camera's pixels; 1.98 when
/// evenly around it, a laser scan's points kept by a view; midway).
pub const ACROSS_RAY_RANGE_PER_RADIUS: f64 = 1.9;

/// What the user may set. `None` means "derive from the cloud" (see [`Parameters`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ColonizeConfig {
    /// How the skeleton graph is grown. Default [`Growth::Auto`].
    pub growth: Growth,
    /// Level-set bin width (path length from the root per bin), metres. Default:
    /// [`LEVEL_BIN_SPACINGS`] × spacing, at least [`MIN_LEVEL_BIN_M`].
    pub bin_m: Option<f64>,
    /// Largest level-set patch that is not a ring around a branch, metres. Default:
    /// [`PATCH_BINS`] × bin, at most [`MAX_PATCH_M`].
    pub patch_m: Option<f64>,
    /// Median distance between neighbouring points, metres. Default: measured.
    pub spacing_m: Option<f64>,
    /// Trunk radius near the base, metres. Default: a circle fitted to a slice of the
    /// lowest points (see [`Parameters::trunk_radius_m`]).
    pub trunk_radius_m: Option<f64>,
    /// Attraction points closer than this to a node are reached and removed, metres.
    /// Default: max([`KILL_PER_TRUNK_RADIUS`] × trunk radius, [`MIN_KILL_SPACINGS`] ×
    /// spacing), with [`KILL_PER_TRUNK_RADIUS_ONE_SIDED`] for a one-sided view.
    pub kill_distance_m: Option<f64>,
    /// Kill distance of the second pass, which grows the twigs the first pass (with its
    /// trunk-sized kill distance) never reached, from the whole first skeleton toward the
    /// points more than this from its surface, metres. Default: [`MIN_KILL_SPACINGS`] ×
    /// spacing, at most [`MAX_TWIG_KILL_M`]; equal to the kill distance or above turns the
    /// pass off. The pass keeps the first pass's influence radius (points the first model
    /// missed, such as the leaf clumps of a sparse crown, can be far from it) and steps at
    /// most half its kill distance.
    pub twig_kill_distance_m: Option<f64>,
    /// Segment length, metres. Default: [`STEP_SPACINGS`] × spacing, at least
    /// [`MIN_STEP_PER_KILL`] and at most half the kill distance (a full scan's: 1.2 trunk
    /// radii also for a one-sided view).
    pub step_m: Option<f64>,
    /// A node is attracted by points within this radius, metres. Default:
    /// [`INFLUENCE_PER_KILL`] × kill distance (a full scan's, as for the step).
    pub influence_m: Option<f64>,
    /// Longest straight bridge across a gap in the cloud, metres; points farther than this
    /// from the rest (as clusters) are outliers. Default: [`MAX_GAP_INFLUENCES`] × influence.
    pub max_gap_m: Option<f64>,
    /// Root of the tree. Default: the lowest points, at the centre of the fitted trunk circle.
    pub root: Option<Point3<f64>>,
    /// Where the cloud was seen from, for a one-sided view (a depth camera's position in the
    /// cloud's frame, known in a capture). The cloud is then taken for a one-sided view
    /// whatever its trunk slice covers ([`Parameters::one_sided`]), and radii under
    /// [`ACROSS_RAY_MAX_RADIUS_M`] are
    /// measured across the view ray too, where depth noise does not widen a branch, and the
    /// smaller of that and the circle fit is kept. A capture whose silhouette pixels were
    /// dropped (flying-pixel filters, steady-pixel masks: the pipeline's twin sees its trunk
    /// over ±45° only) measures widths short, so the pipeline does not pass its camera.
    /// Default `None`: circle fits only.
    pub camera_m: Option<Point3<f64>>,
    /// Pipe-model exponent e in r_parent^e = Σ r_child^e. Default [`PIPE_EXPONENT`].
    pub pipe_exponent: f64,
    /// Anchor the pipe model to every radius a circle fit measures reliably (thick
    /// branches), not only to the trunk base. Default true; false is the paper's pure pipe
    /// model.
    pub radius_fits: bool,
    /// Move nodes to the branch axis with local circle fits. Default true.
    pub centring: bool,
    /// Also centre the nodes next to forks (on their own side's points) and put each fork
    /// on its parent branch's axis, in full scans grown by colonization (with
    /// [`Self::centring`]); a single radius fit far off the pipe model is then not an
    /// anchor. Growth splits branches late, so without it a fork sits beside the axis
    /// toward its side branch and the parts by it kink toward it. On the leaf-off coffee
    /// tree 2.60 mm mean point-to-surface against 2.97 mm without, length +2.3 % and
    /// volume +2.5 % against TreeQSM's (+0.7 % and +3.4 % without); on synthetic trees the
    /// axes 7.1 mm from the truth against 9.4 mm (`docs/validation.md`, "Centring by
    /// forks"). Default true; false gives the model as before.
    pub centre_forks: bool,
    /// In a full scan, fit each segment's cylinder to its own points as the last stage
    /// (the circle of least mean distance, where the points go round at least half of it),
    /// as TreeQSM fits its cylinders; the nodes move by the mean shift of their segments'
    /// axes and take their own segment's radius. Only with [`Self::radius_fits`] (the pure
    /// pipe model stays pure). Default true; false leaves the smooth pipe-model radii and
    /// centred chains.
    pub cylinder_fits: bool,
    /// In a one-sided view grown by colonization with its camera known
    /// ([`Self::camera_m`]), continue a thick chain straight through a stretch the camera
    /// could not see, where the camera saw through the chain's own surface (it was drawn
    /// along what hides it) but not through the straight line. Default true.
    pub hidden_wood: bool,
    /// Look for a ground plane under the tree (the lowest surface that spreads sideways,
    /// see [`crate::Ground`]) and set its points aside before growth. Default true; the
    /// plane and its points are reported in [`crate::Reconstruction::ground`].
    pub remove_ground: bool,
    /// Set aside the points of leaves before growth ([`crate::separate_wood`] with its
    /// defaults, after the ground), so that a scan in leaf gives a wood skeleton; they are
    /// reported in [`crate::Reconstruction::leaves`]. Default false: every point is wood
    /// (leaf-off scans, one-sided views; a leafy crown is then followed to its leaves).
    pub separate_leaves: bool,
    /// Taubin smoothing passes along branch chains after centring. Default 3.
    pub smoothing_iterations: usize,
    /// Terminal twigs that reach less than this beyond their parent's surface are removed
    /// as growth artefacts, metres. Default: 2 × spacing.
    pub min_twig_m: Option<f64>,
    /// Growth iteration bound. Default: 2 × points + 10,000 (each iteration adds a node or
    /// retires a point, so a finished growth never needs more).
    pub max_iterations: Option<usize>,
    /// Node bound. Default: 2 × points + 10,000.
    pub max_nodes: Option<usize>,
}

impl Default for ColonizeConfig {
    fn default() -> Self {
        Self {
            growth: Growth::Auto,
            bin_m: None,
            patch_m: None,
            spacing_m: None,
            trunk_radius_m: None,
            kill_distance_m: None,
            twig_kill_distance_m: None,
            step_m: None,
            influence_m: None,
            max_gap_m: None,
            root: None,
            camera_m: None,
            pipe_exponent: PIPE_EXPONENT,
            radius_fits: true,
            centring: true,
            centre_forks: true,
            cylinder_fits: true,
            hidden_wood: true,
            remove_ground: true,
            separate_leaves: false,
            smoothing_iterations: 3,
            min_twig_m: None,
            max_iterations: None,
            max_nodes: None,
        }
    }
}

fn positive(name: &'static str, v: Option<f64>) -> Result<()> {
    match v {
        Some(x) if !(x.is_finite() && x > 0.0) => Err(ColonizeError::param(
            name,
            format!("{x} m; must be positive and finite"),
        )),
        _ => Ok(()),
    }
}

impl ColonizeConfig {
    /// Check each field on its own and the set fields against each other.
    ///
    /// # Errors
    /// [`ColonizeError::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<()> {
        positive("spacing_m", self.spacing_m)?;
        positive("trunk_radius_m", self.trunk_radius_m)?;
        positive("kill_distance_m", self.kill_distance_m)?;
        positive("twig_kill_distance_m", self.twig_kill_distance_m)?;
        positive("step_m", self.step_m)?;
        positive("influence_m", self.influence_m)?;
        positive("max_gap_m", self.max_gap_m)?;
        positive("bin_m", self.bin_m)?;
        positive("patch_m", self.patch_m)?;
        if let Some(m) = self.min_twig_m
            && !(m.is_finite() && m >= 0.0)
        {
            return Err(ColonizeError::param(
                "min_twig_m",
                format!("{m} m; must be zero or positive"),
            ));
        }
        if !(self.pipe_exponent.is_finite() && (1.0..=4.0).contains(&self.pipe_exponent)) {
            return Err(ColonizeError::param(
                "pipe_exponent",
                format!("{}; must be in [1, 4]", self.pipe_exponent),
            ));
        }
        if let Some(r) = self.root
            && !r.iter().all(|c| c.is_finite())
        {
            return Err(ColonizeError::param("root", format!("{r:?} is not finite")));
        }
        if let Some(c) = self.camera_m
            && !c.iter().all(|c| c.is_finite())
        {
            return Err(ColonizeError::param(
                "camera_m",
                format!("{c:?} is not finite"),
            ));
        }
        if self.max_iterations == Some(0) {
            return Err(ColonizeError::param("max_iterations", "must be at least 1"));
        }
        if matches!(self.max_nodes, Some(n) if n < 2) {
            return Err(ColonizeError::param("max_nodes", "must be at least 2"));
        }
        Ok(())
    }
}

/// The parameters a reconstruction ran with, derived where the config left them open.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Parameters {
    /// How the skeleton graph was grown: never [`Growth::Auto`], which resolves to the
    /// method it chose.
    pub growth: Growth,
    /// Level-set bin width, metres.
    pub bin_m: f64,
    /// Largest level-set patch that is not a ring, metres.
    pub patch_m: f64,
    /// Median nearest-neighbour distance, metres.
    pub spacing_m: f64,
    /// Trunk radius near the base, metres.
    pub trunk_radius_m: f64,
    /// True when the trunk radius came from a circle fit (false: given, or the fallback).
    pub trunk_radius_fitted: bool,
    /// Share of the trunk circle the lowest slice's points cover (1 when not fitted).
    pub trunk_coverage: f64,
    /// Whether the cloud was taken for a one-sided view (a fitted trunk covered less than
    /// [`ONE_SIDED_COVERAGE`], or the camera was given, [`ColonizeConfig::camera_m`]): the
    /// kill distance is then
    /// [`KILL_PER_TRUNK_RADIUS_ONE_SIDED`] trunk radii.
    pub one_sided: bool,
    /// Kill distance, metres.
    pub kill_distance_m: f64,
    /// Kill distance of the twig pass, metres.
    pub twig_kill_distance_m: f64,
    /// Segment length, metres.
    pub step_m: f64,
    /// Influence radius, metres.
    pub influence_m: f64,
    /// Longest bridge, metres.
    pub max_gap_m: f64,
    /// Root position, metres.
    pub root_m: [f64; 3],
    /// The camera a one-sided view was seen from ([`ColonizeConfig::camera_m`]), metres.
    pub camera_m: Option<[f64; 3]>,
    /// Pipe-model exponent.
    pub pipe_exponent: f64,
    /// Shortest twig kept beyond its parent's surface, metres.
    pub min_twig_m: f64,
    /// Growth iteration bound.
    pub max_iterations: usize,
    /// Node bound.
    pub max_nodes: usize,
}

impl Parameters {
    /// Check the resolved set: kill < influence, step < kill.
    ///
    /// # Errors
    /// [`ColonizeError::InvalidParameter`] naming the pair that cannot work.
    pub fn validate(&self) -> Result<()> {
        if self.kill_distance_m >= self.influence_m {
            return Err(ColonizeError::param(
                "kill_distance_m",
                format!(
                    "{} m is not below the influence radius {} m: no point could attract a node before being removed",
                    self.kill_distance_m, self.influence_m
                ),
            ));
        }
        if self.step_m >= self.kill_distance_m {
            return Err(ColonizeError::param(
                "step_m",
                format!(
                    "{} m is not below the kill distance {} m: nodes would jump over points",
                    self.step_m, self.kill_distance_m
                ),
            ));
        }
        if self.max_gap_m < self.influence_m {
            return Err(ColonizeError::param(
                "max_gap_m",
                format!(
                    "{} m is below the influence radius {} m",
                    self.max_gap_m, self.influence_m
                ),
            ));
        }
        Ok(())
    }
}
