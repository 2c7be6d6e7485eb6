//! A static tree model (skeleton, radii, mesh, cylinders) from a point cloud, with its fidelity.
//!
//! ```text
//! cargo run --release --example reconstruct_tree -- <CLOUD> [--growth auto|colonization|levels] [--out-skeleton s.json] [--out-mesh tree.obj] [--out-cylinders c.csv] [--keep-ground] [--separate-leaves] [--out-leaves l.xyz] [--up AXIS] [--view-from X,Y,Z] [--camera-at X,Y,Z]
//! ```
//!
//! `CLOUD`: XYZ text, PLY or PCD (kinect-io's readers), metres, Z up; `--up AXIS` names
//! another up (`-y` for a cloud in a level depth camera's frame, as `capture_to_cloud`
//! writes it; `+y` for Y-up exports): the cloud is turned Z up for the reconstruction and
//! every output (skeleton, mesh, cylinders, `"ground"`) is turned back into the cloud's
//! frame, so it lies on the cloud. A cloud that looks like a camera's frame while Z is
//! taken as up gets a warning on stderr and in `"warnings"`. Prints one JSON object:
//! the metrics (`"mean_distance_m"`, `"median_distance_m"`, `"p95_distance_m"`,
//! `"max_distance_m"`, `"within_1cm"`, `"within_2cm"`, `"within_5cm"` as shares of points,
//! `"length_near_cloud"` as a share of model length, `"max_model_gap_m"`,
//! `"branches_by_order"`), `"nodes"`, `"branches"`, `"total_length_m"`, `"volume_l"` and
//! `"fidelity"` (issue 22's measure, the one the anchors AdTree and TreeQSM are compared by:
//! `"mean_distance_m"`, `"within_2cm"`, `"model_near_cloud"`, `"axis_length_m"`),
//! `"seconds"` (reconstruction time without file I/O or metrics), plus the `"parameters"` used,
//! what `"growth"` did, the `"up"` axis used and any `"warnings"`. Progress goes to stderr. A ground plane under the tree is set
//! aside before growth (`--keep-ground` keeps it) and reported as `"ground"` (the plane it
//! was seeded from, `normal`·p = `offset_m`; `thickness_m`, `points`, `cells`, `cell_m`),
//! with `"fidelity_above_ground"`. `--separate-leaves` sets the points of leaves aside
//! before growth (`space_colonize::separate_wood`), so a scan in leaf gives a wood
//! skeleton; `"leaves"` counts them and `"fidelity_to_wood"` measures the model against
//! the points it grew from (neither ground nor leaves); `--out-leaves` writes them as XYZ
//! text in the cloud's frame.
//!
//! With `--view-from X,Y,Z` the cloud is first reduced to what a Kinect v2 there would see
//! (`space_colonize::camera_view`: the near half of each branch, `--depth-noise-m` along the
//! rays), reconstructed with that camera known, and `"view"` measures the model against the
//! whole cloud (`"fidelity_to_whole_cloud"`, `"metrics_to_whole_cloud"`). `--camera-at
//! X,Y,Z` gives the camera of a one-sided cloud (`ColonizeConfig::camera_m`: thin branches
//! are measured across its rays, where depth noise does not widen them).
//!
//! With no arguments it reconstructs a synthetic tree sampled from a known skeleton and adds
//! `"truth"`: the error against that skeleton.

use std::path::PathBuf;
use std::time::Instant;

use clap::Parser;
use serde::Serialize;
use treemocap::kinect_io::read_point_cloud;
use treemocap::nalgebra::Point3;
use treemocap::space_colonize::synthetic::{SkeletonError, SyntheticConfig, skeleton_error};
use treemocap::space_colonize::{
    AUTO_NEAR_SHARE, ColonizeConfig, DEFAULT_MESH_SIDES, Fidelity, Ground, Growth, GrowthReport,
    KINECT_DEPTH_NOISE_M, Leaves, Metrics, Parameters, Reconstruction, Skeleton, Stage, UpAxis,
    ViewConfig, camera_view, cylinders, cylinders_to_csv, fidelity, looks_like_camera_frame,
    metrics, reconstruct_with_progress, tube_mesh,
};

mod common;

/// A tree model (space colonization, centring, pipe-model radii anchored to fitted ones)
/// from a point cloud (XYZ text, PLY or PCD; metres, Z up), with its fidelity to the cloud,
/// its size and the time taken, as one JSON object.
///
/// With no arguments: a synthetic tree with a known skeleton, and the error against it.
#[derive(Parser, Debug)]
#[command(name = "reconstruct_tree", version, about)]
struct Args {
    /// The point cloud: XYZ text, PLY or PCD (metres, Z up)
    #[arg(value_name = "CLOUD")]
    cloud: Option<PathBuf>,
    /// The skeleton as JSON: {"nodes": [{"id", "parent", "position", "radius"}]}
    #[arg(long = "out-skeleton", value_name = "FILE")]
    skeleton: Option<PathBuf>,
    /// The generalized-cylinder mesh, .obj or .ply
    #[arg(long = "out-mesh", value_name = "FILE", value_parser = mesh_path)]
    mesh: Option<PathBuf>,
    /// The cylinder table, CSV (id,parent,start_x..z,axis_x..z,length,radius,branch,order)
    #[arg(long = "out-cylinders", value_name = "FILE")]
    cylinders: Option<PathBuf>,
    /// How the skeleton is grown: `auto` (the default: space colonization, unless less than
    /// 80 % of what it grows lies within 2 cm of the points, as in a leafy crown; then level
    /// sets), `colonization` (space colonization) or `levels` (geodesic level sets:
    /// follows the points, better on leafy and sparse scans). `"parameters"` `"growth"`
    /// says which was used, `"growth"` `"colonization_near_cloud"` the share `auto` measured
    #[arg(long, value_name = "METHOD", default_value = "auto", value_parser = growth_method)]
    growth: Growth,
    /// Reconstruct from what a Kinect v2 at X,Y,Z (metres, the cloud's frame) would see of
    /// the cloud (the near half of each branch, depth noise along the rays), and measure
    /// the model against the whole cloud too (`"view"` in the output)
    #[arg(long = "view-from", value_name = "X,Y,Z", value_parser = point3)]
    view_from: Option<Point3<f64>>,
    /// Depth noise of that view, metres (standard deviation along the ray)
    #[arg(long = "depth-noise-m", value_name = "M", default_value_t = KINECT_DEPTH_NOISE_M)]
    depth_noise_m: f64,
    /// Grow from every point, even those on a ground plane found under the tree (by
    /// default they are set aside and reported as `"ground"`)
    #[arg(long = "keep-ground")]
    keep_ground: bool,
    /// Set aside the points of leaves before growth, so a scan in leaf gives a wood
    /// skeleton (twigs inside foliage go with the leaves); reported as `"leaves"`
    #[arg(long = "separate-leaves")]
    separate_leaves: bool,
    /// Write the points taken for leaves as XYZ text (metres, the cloud's frame); needs
    /// --separate-leaves
    #[arg(long = "out-leaves", value_name = "FILE", requires = "separate_leaves")]
    leaves: Option<PathBuf>,
    /// Leave forks and the nodes next to them where growth put them (by default, in full
    /// scans grown by colonization, they are centred and forks put on their parent's axis)
    #[arg(long = "forks-as-grown")]
    forks_as_grown: bool,
    /// Keep the smooth radii and chains (by default, in full scans, each segment's cylinder
    /// is fitted to its own points as the last stage; `"growth"` `"fitted_segments"` counts
    /// them)
    #[arg(long = "no-cylinder-fits")]
    no_cylinder_fits: bool,
    /// The cloud's up axis: `z` (the default: the tree frame), `-y` (a level depth
    /// camera's own frame, y down, as `capture_to_cloud` writes it), `y` (Y-up exports),
    /// `x`, `-x` or `-z`. The outputs are turned back into the cloud's frame
    #[arg(long, value_name = "AXIS", value_parser = up_axis, allow_hyphen_values = true)]
    up: Option<UpAxis>,
    /// Where the cloud was seen from, for a one-sided view (a depth camera's position,
    /// metres, the cloud's frame: 0,0,0 for a cloud in the camera's own frame): branches
    /// under 1.5 cm are then measured across its rays too, where depth noise does not
    /// widen them, and a thick branch drawn along what hid it from the camera is continued
    /// straight through the hidden stretch (`"growth"` `"hidden_stretches"` counts them).
    /// `--view-from` sets it to the view's camera
    #[arg(long = "camera-at", value_name = "X,Y,Z", value_parser = point3, allow_hyphen_values = true)]
    camera_at: Option<Point3<f64>>,
    /// With the camera known, leave hidden stretches as grown (along what hid them)
    #[arg(long = "no-hidden-wood")]
    no_hidden_wood: bool,
}

/// An up axis by name.
fn up_axis(text: &str) -> Result<UpAxis, String> {
    text.parse().map_err(|e| format!("{e}"))
}

/// A point as X,Y,Z.
fn point3(text: &str) -> Result<Point3<f64>, String> {
    let v: Vec<f64> = text
        .split(',')
        .map(|c| c.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{text}: {e}"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Point3::new(*x, *y, *z)),
        _ => Err(format!("{text}: must be three finite numbers X,Y,Z")),
    }
}

/// A growth method by name.
fn growth_method(text: &str) -> Result<Growth, String> {
    match text {
        "auto" => Ok(Growth::Auto),
        "colonization" => Ok(Growth::Colonization),
        "levels" => Ok(Growth::LevelSets),
        _ => Err(format!(
            "{text}: must be `auto`, `colonization` or `levels`"
        )),
    }
}

/// A mesh file name: .obj or .ply.
fn mesh_path(text: &str) -> Result<PathBuf, String> {
    let path = PathBuf::from(text);
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    if ext.eq_ignore_ascii_case("obj") || ext.eq_ignore_ascii_case("ply") {
        Ok(path)
    } else {
        Err(format!("{text}: the extension must be .obj or .ply"))
    }
}

#[derive(Serialize)]
struct Report {
    cloud: String,
    nodes: usize,
    branches: usize,
    cylinders: usize,
    branches_by_order: Vec<usize>,
    #[serde(flatten)]
    metrics: Metrics,
    fidelity: Fidelity,
    seconds: f64,
    parameters: Parameters,
    growth: GrowthReport,
    /// The ground plane set aside before growth, if one was found.
    #[serde(skip_serializing_if = "Option::is_none")]
    ground: Option<Ground>,
    /// `"fidelity"` without the ground's points, which the model rightly does not reach.
    #[serde(skip_serializing_if = "Option::is_none")]
    fidelity_above_ground: Option<Fidelity>,
    /// The points taken for leaves and set aside before growth (`--separate-leaves`).
    #[serde(skip_serializing_if = "Option::is_none")]
    leaves: Option<Leaves>,
    /// `"fidelity"` against the points the model grew from (neither ground nor leaves),
    /// with `--separate-leaves`.
    #[serde(skip_serializing_if = "Option::is_none")]
    fidelity_to_wood: Option<Fidelity>,
    #[serde(skip_serializing_if = "Option::is_none")]
    truth: Option<SkeletonError>,
    #[serde(skip_serializing_if = "Option::is_none")]
    view: Option<ViewReport>,
    /// The cloud's up axis the reconstruction used (`--up`; `+z` by default).
    up: UpAxis,
    /// The scan's noise about the model's surface (branches of 2 cm or more), metres.
    surface_noise_m: Option<f64>,
    /// Whether that noise leaves the volume trustworthy.
    volume_trusted: bool,
    /// What the user should know before trusting the model.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    warnings: Vec<String>,
}

/// The model of a one-sided view against the whole cloud.
#[derive(Serialize)]
struct ViewReport {
    camera_m: [f64; 3],
    depth_noise_m: f64,
    points_seen: usize,
    points_in_cloud: usize,
    fidelity_to_whole_cloud: Fidelity,
    metrics_to_whole_cloud: Metrics,
}

fn run(
    points: &[Point3<f64>],
    args: &Args,
    camera_m: Option<Point3<f64>>,
) -> Result<(Reconstruction, f64), Box<dyn std::error::Error>> {
    let t = Instant::now();
    let mut progress = |s: Stage| {
        eprintln!(
            "[{:6.2} s] {}",
            t.elapsed().as_secs_f64(),
            match s {
                Stage::Prepare => "preparing the cloud (spacing, trunk radius, outliers)",
                Stage::Grow => "growing the skeleton",
                Stage::Refine => "refining (tips, centring, smoothing)",
                Stage::Radii => "radii, twig pass, pruning",
                _ => "working",
            }
        );
    };
    let config = ColonizeConfig {
        growth: args.growth,
        remove_ground: !args.keep_ground,
        separate_leaves: args.separate_leaves,
        centre_forks: !args.forks_as_grown,
        cylinder_fits: !args.no_cylinder_fits,
        hidden_wood: !args.no_hidden_wood,
        camera_m,
        ..ColonizeConfig::default()
    };
    let model = reconstruct_with_progress(points, &config, &mut progress)?;
    let seconds = t.elapsed().as_secs_f64();
    if let Some(g) = &model.ground {
        eprintln!(
            "[{seconds:6.2} s] set aside {} points of a ground under the tree ({} cells of \
             {:.0} cm, {:.1}° from horizontal, {:.1} cm thick); --keep-ground grows from them \
             too",
            g.points,
            g.cells,
            100.0 * g.cell_m,
            g.normal[2].clamp(-1.0, 1.0).acos().to_degrees(),
            100.0 * g.thickness_m
        );
    }
    if let Some(l) = &model.leaves {
        eprintln!(
            "[{seconds:6.2} s] set aside {} of {} points as leaves",
            l.points,
            points.len()
        );
    }
    if let Some(share) = model.growth.colonization_near_cloud {
        eprintln!(
            "[{seconds:6.2} s] grown by {}: {:.0} % of space colonization's growth lay within \
             2 cm of the points (level sets below {:.0} %)",
            if model.parameters.growth == Growth::LevelSets {
                "level sets"
            } else {
                "space colonization"
            },
            100.0 * share,
            100.0 * AUTO_NEAR_SHARE
        );
    }
    eprintln!("[{seconds:6.2} s] done; measuring the model against the cloud");
    Ok((model, seconds))
}

/// The report of `model`, whose skeleton turned back into the cloud's frame is `skeleton`,
/// measured against `points` (the cloud's frame).
fn report(
    cloud: String,
    points: &[Point3<f64>],
    model: &Reconstruction,
    skeleton: &Skeleton,
    seconds: f64,
    truth: Option<SkeletonError>,
) -> Report {
    Report {
        cloud,
        nodes: skeleton.nodes().len(),
        branches: model.branches.len(),
        cylinders: cylinders(skeleton).len(),
        branches_by_order: model.branches_by_order(),
        metrics: metrics(points, skeleton),
        fidelity: fidelity(points, skeleton),
        seconds,
        parameters: model.parameters,
        growth: model.growth,
        ground: model.ground.clone(),
        fidelity_above_ground: model
            .ground
            .as_ref()
            .map(|g| fidelity(&without(points, &[&g.indices]), skeleton)),
        leaves: model.leaves.clone(),
        fidelity_to_wood: model.leaves.as_ref().map(|l| {
            let ground = model.ground.as_ref().map_or(&[][..], |g| &g.indices[..]);
            fidelity(&without(points, &[ground, &l.indices]), skeleton)
        }),
        truth,
        view: None,
        up: UpAxis::PlusZ,
        surface_noise_m: model.surface_noise_m,
        volume_trusted: model.volume_trusted(),
        warnings: Vec::new(),
    }
}

/// `points` without those at any of the `indices`.
fn without(points: &[Point3<f64>], indices: &[&[usize]]) -> Vec<Point3<f64>> {
    let mut out = vec![false; points.len()];
    for &i in indices.iter().flat_map(|ix| ix.iter()) {
        if let Some(o) = out.get_mut(i) {
            *o = true;
        }
    }
    points
        .iter()
        .zip(&out)
        .filter(|(_, o)| !**o)
        .map(|(p, _)| *p)
        .collect()
}

/// The warning for a cloud that looks like a depth camera's frame but is read Z up.
fn camera_frame_warning(name: &str) -> String {
    format!(
        "{name} looks like a cloud in a depth camera's own frame (x right, y down, z \
         forward: every point in front of the origin along +z, inside a camera's field of \
         view), but is read Z up: the model grows from the front of the tree along the view \
         and cannot be trusted. For a level camera pass --up -y (or write the cloud in a Z-up \
         world frame, kinect_io::camera_to_world_z_up); --up z keeps Z up and silences this"
    )
}

/// The warning for a scan too noisy for its model's volume to be trusted.
fn noise_warning(model: &Reconstruction, volume_l: f64) -> String {
    format!(
        "the scan's noise about the model's surface is {:.1} mm (branches of 2 cm or more): \
         noise widens thin branches and doubles chains up thick ones, so the volume ({volume_l:.1} \
         L) may run high (the coffee tree with 3, 5 and 10 mm of noise added: +36, +52, +82 \
         %){}",
        1e3 * model.surface_noise_m.unwrap_or(f64::NAN),
        if model.parameters.camera_m.is_none() {
            "; for a one-sided view, --camera-at gives the camera"
        } else {
            ""
        }
    )
}

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    common::run("reconstruct_tree", || run_main(&args))
}

fn run_main(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    let (name, points, truth) = match &args.cloud {
        Some(path) => {
            let cloud = read_point_cloud(path)?;
            let points: Vec<Point3<f64>> = cloud.valid_points().map(|(p, _)| p).collect();
            (path.display().to_string(), points, None)
        }
        None => {
            if args.up.is_some() {
                return Err("--up applies to a CLOUD; the synthetic tree is Z up".into());
            }
            let config = SyntheticConfig::default();
            eprintln!(
                "no cloud given: a synthetic tree ({} m, base radius {} m, orders up to {}, about {} points, {} mm noise)",
                config.height_m,
                config.base_radius_m,
                config.max_order,
                config.points,
                config.noise_m * 1e3
            );
            let tree = config.generate()?;
            ("synthetic".to_string(), tree.points, Some(tree.skeleton))
        }
    };
    let up = args.up.unwrap_or_default();
    let mut warnings: Vec<String> = Vec::new();
    if args.up.is_none() && looks_like_camera_frame(&points) {
        // Before the reconstruction, which such a cloud makes long.
        warnings.push(camera_frame_warning(&name));
        eprintln!("warning: {}", warnings[0]);
    }
    // The reconstruction works Z up; the outputs are turned back into the cloud's frame.
    let whole = points;
    let whole_z_up: Vec<Point3<f64>> = whole.iter().map(|p| up.to_z_up(p)).collect();
    let (points, points_z_up) = match args.view_from {
        Some(camera_m) => {
            let view = ViewConfig {
                depth_noise_m: args.depth_noise_m,
                ..ViewConfig::kinect(up.to_z_up(&camera_m))
            };
            let seen = camera_view(&whole_z_up, &view)?;
            eprintln!(
                "a Kinect v2 at {camera_m:?} sees {} of the {} points",
                seen.len(),
                whole.len()
            );
            (seen.iter().map(|p| up.from_z_up(p)).collect(), seen)
        }
        None => (whole.clone(), whole_z_up),
    };
    let camera_m = args.view_from.or(args.camera_at).map(|c| up.to_z_up(&c));
    let (model, seconds) = run(&points_z_up, args, camera_m).map_err(|e| format!("{name}: {e}"))?;
    let skeleton = up.skeleton_from_z_up(&model.skeleton)?;
    let error = truth.as_ref().map(|t| skeleton_error(&skeleton, t));
    if let Some(p) = &args.skeleton {
        skeleton.write_json(p)?;
        eprintln!("wrote {}", p.display());
    }
    if let Some(p) = &args.mesh {
        tube_mesh(&skeleton, DEFAULT_MESH_SIDES)?.write(p)?;
        eprintln!("wrote {}", p.display());
    }
    if let Some(p) = &args.cylinders {
        std::fs::write(p, cylinders_to_csv(&cylinders(&skeleton)))
            .map_err(|e| format!("{}: {e}", p.display()))?;
        eprintln!("wrote {}", p.display());
    }
    if let (Some(p), Some(l)) = (&args.leaves, &model.leaves) {
        let text: String = l
            .indices
            .iter()
            .map(|&i| format!("{} {} {}\n", points[i].x, points[i].y, points[i].z))
            .collect();
        std::fs::write(p, text).map_err(|e| format!("{}: {e}", p.display()))?;
        eprintln!("wrote {}", p.display());
    }
    let mut r = report(name, &points, &model, &skeleton, seconds, error);
    if let Some(g) = &mut r.ground {
        // A rotation keeps the plane's offset along its (turned) normal.
        let n = up.from_z_up(&Point3::from(g.normal));
        g.normal = [n.x, n.y, n.z];
    }
    // The parameters' places in the cloud's frame too.
    let back = |p: [f64; 3]| -> [f64; 3] { up.from_z_up(&Point3::from(p)).coords.into() };
    r.parameters.camera_m = r.parameters.camera_m.map(back);
    r.parameters.root_m = back(r.parameters.root_m);
    if !model.volume_trusted() {
        let w = noise_warning(&model, r.metrics.volume_l);
        eprintln!("warning: {w}");
        warnings.push(w);
    }
    r.up = up;
    r.warnings = warnings;
    r.view = args.view_from.map(|c| ViewReport {
        camera_m: [c.x, c.y, c.z],
        depth_noise_m: args.depth_noise_m,
        points_seen: points.len(),
        points_in_cloud: whole.len(),
        fidelity_to_whole_cloud: fidelity(&whole, &skeleton),
        metrics_to_whole_cloud: metrics(&whole, &skeleton),
    });
    println!("{}", serde_json::to_string_pretty(&r)?);
    Ok(())
}
