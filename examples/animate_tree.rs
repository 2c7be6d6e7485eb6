//! A tree swaying in wind (or a branch released from a pull) with its measured dynamics,
//! exported to glTF 2.0 binary, BVH and CSV.
//!
//! ```text
//! cargo run --release --example animate_tree -- [--skeleton s.json] [--dynamics d.json] [--seconds 10] [--fps 30] [--wind-speed 5] [--out tree.glb] [--bvh tree.bvh] [--angles angles.csv] [--release BRANCH_ID:DEGREES] [--integrator exact|semi|euler]
//! ```
//!
//! - `--skeleton`: space-colonize's skeleton JSON (`reconstruct_tree --out-skeleton`); without
//!   it, the synthetic tree of `space_colonize::synthetic` (its known skeleton).
//! - `--dynamics`: `{"default": {"frequency_hz": 1.46, "damping_ratio": 0.086}, "branches":
//!   {"<branch id>": {...}}, "measured": [{"position": [x, y, z], "frequency_hz",
//!   "damping_ratio"}]}` (`branches` and `measured` optional); without it, the paper's 1.46 Hz
//!   and 0.086 for every branch. A branch is named by the id of its first skeleton node.
//! - `--out` (default `target/treemocap-demo/animate_tree/tree.glb`): the animated mesh; `--bvh`: the
//!   segment hierarchy as BVH; `--angles`: `t,<branch id>...`, each branch's bending angle
//!   in degrees per frame.
//! - `--release BRANCH_ID:DEGREES`: pull that branch to the angle and let go in still air
//!   (the release test) instead of wind; the summary then has the frequency and damping
//!   ratio measured back from the written angle series (modal-estimate).
//!
//! Prints one JSON summary on stdout; progress goes to stderr.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Parser;
use serde::Serialize;
use treemocap::beam_anim::{
    AnimConfig, BeamTree, DynamicsSource, DynamicsSpec, GlbOptions, Integrator, IntegratorReport,
    Pose, SMALL_ANGLE_LIMIT_RAD, Simulation, WindField, angles_csv, frame_count, read_skeleton,
    write_bvh, write_glb,
};
use treemocap::modal_estimate::{EstimateConfig, Signal, estimate};
use treemocap::space_colonize::synthetic::SyntheticConfig;

mod common;

/// Animate a tree (space-colonize skeleton JSON, or a synthetic tree) in turbulent wind with
/// one oscillator of the paper's eq. (7) per branch, and write the animation as glTF 2.0
/// binary, optionally BVH and a CSV of bending angles.
///
/// Prints one JSON summary on stdout; progress goes to stderr.
#[derive(Parser, Debug)]
#[command(name = "animate_tree", version, about, allow_negative_numbers = true)]
struct Cli {
    /// space-colonize's skeleton JSON (reconstruct_tree --out-skeleton) [default: the
    /// synthetic tree of space_colonize::synthetic]
    #[arg(long, value_name = "FILE")]
    skeleton: Option<PathBuf>,
    /// {"default": {"frequency_hz", "damping_ratio"}, "branches": {"<id>": {...}},
    /// "measured": [{"position", "frequency_hz", "damping_ratio"}]} [default: the paper's
    /// 1.46 Hz and 0.086 for every branch]
    #[arg(long, value_name = "FILE")]
    dynamics: Option<PathBuf>,
    /// Length of the animation, seconds
    #[arg(long, value_name = "S", default_value_t = 10.0, value_parser = positive)]
    seconds: f64,
    /// Frames per second
    #[arg(long, value_name = "HZ", default_value_t = 30.0, value_parser = positive)]
    fps: f64,
    /// Mean wind speed, m/s
    #[arg(long = "wind-speed", value_name = "M_S", default_value_t = 5.0, value_parser = not_negative)]
    wind_speed_m_s: f64,
    /// The animated mesh, glTF 2.0 binary [default: target/treemocap-demo/animate_tree/tree.glb]
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// The segment hierarchy and its motion as BVH
    #[arg(long, value_name = "FILE")]
    bvh: Option<PathBuf>,
    /// Each branch's bending angle per frame, degrees: t,<branch id>...
    #[arg(long, value_name = "FILE")]
    angles: Option<PathBuf>,
    /// Pull branch ID (its first skeleton node) to DEGREES and let go in still air instead
    /// of wind; the summary then has the frequency and damping measured back
    #[arg(long, value_name = "BRANCH_ID:DEGREES", value_parser = parse_release)]
    release: Option<(usize, f64)>,
    /// exact (zero-order hold), semi (semi-implicit Euler), euler (the paper's explicit
    /// Euler); the Euler ones are sub-stepped until stable
    #[arg(long, value_enum, default_value_t = IntegratorArg::Exact)]
    integrator: IntegratorArg,
}

/// The integrators, as named on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum IntegratorArg {
    /// Zero-order hold, exact for the linear oscillator
    Exact,
    /// Semi-implicit Euler
    Semi,
    /// The paper's explicit Euler
    Euler,
}

/// A finite number from an option's value.
fn finite(text: &str) -> Result<f64, String> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|x| x.is_finite())
        .ok_or_else(|| format!("{text}: not a number"))
}

fn positive(text: &str) -> Result<f64, String> {
    let v = finite(text)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{text}: must be positive"))
    }
}

fn not_negative(text: &str) -> Result<f64, String> {
    let v = finite(text)?;
    if v >= 0.0 {
        Ok(v)
    } else {
        Err(format!("{text}: must not be negative"))
    }
}

fn parse_release(text: &str) -> Result<(usize, f64), String> {
    let (id, deg) = text
        .split_once(':')
        .ok_or_else(|| format!("{text}: expected BRANCH_ID:DEGREES"))?;
    let id = id
        .trim()
        .parse::<usize>()
        .map_err(|_| format!("{text}: {id:?} is not a branch id"))?;
    Ok((id, finite(deg)?))
}

struct Args {
    skeleton: Option<PathBuf>,
    dynamics: Option<PathBuf>,
    seconds: f64,
    fps: f64,
    wind_speed_m_s: f64,
    out: PathBuf,
    bvh: Option<PathBuf>,
    angles: Option<PathBuf>,
    release: Option<(usize, f64)>,
    integrator: Integrator,
}

impl From<Cli> for Args {
    fn from(c: Cli) -> Self {
        Self {
            skeleton: c.skeleton,
            dynamics: c.dynamics,
            seconds: c.seconds,
            fps: c.fps,
            wind_speed_m_s: c.wind_speed_m_s,
            out: c
                .out
                .unwrap_or_else(|| common::demo_dir("animate_tree").join("tree.glb")),
            bvh: c.bvh,
            angles: c.angles,
            release: c.release,
            integrator: match c.integrator {
                IntegratorArg::Exact => Integrator::ExactZoh,
                IntegratorArg::Semi => Integrator::SemiImplicitEuler,
                IntegratorArg::Euler => Integrator::ExplicitEuler,
            },
        }
    }
}

#[derive(Serialize)]
struct Release {
    branch: usize,
    degrees: f64,
    configured_frequency_hz: f64,
    configured_damping_ratio: f64,
    /// From the written angle series by modal-estimate (None if it found no mode).
    measured_frequency_hz: Option<f64>,
    measured_damping_ratio: Option<f64>,
}

#[derive(Serialize)]
struct Sources {
    explicit: usize,
    measured: usize,
    level: usize,
    default: usize,
}

#[derive(Serialize)]
struct Summary {
    skeleton: String,
    mode: &'static str,
    branches: usize,
    segments: usize,
    frames: usize,
    fps: f64,
    seconds: f64,
    wind_speed_m_s: f64,
    integrator: IntegratorReport,
    dynamics_sources: Sources,
    max_angle_deg: f64,
    /// What the user must know about the result (an empty list when nothing).
    warnings: Vec<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    release: Option<Release>,
    simulation_ms_per_frame: f64,
    outputs: Vec<String>,
}

fn ensure_parent(path: &Path) -> Result<(), String> {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => {
            std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))
        }
        _ => Ok(()),
    }
}

fn main() -> std::process::ExitCode {
    let args = Args::from(Cli::parse());
    common::run("animate_tree", || run_main(&args))
}

/// The simulation of `args`: the skeleton read, dynamics assigned, wind or release set up.
struct Setup {
    /// The skeleton's name for messages and the summary.
    name: String,
    sim: Simulation,
    /// The wind field, or `None` for a release in still air.
    wind: Option<WindField>,
    sources: Sources,
    frames: usize,
    /// The released branch's configured frequency and damping ratio, when one is released.
    released: Option<(usize, f64, f64)>,
}

fn run_main(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    let Setup {
        name,
        mut sim,
        mut wind,
        sources,
        frames,
        released,
    } = set_up(args)?;
    let (branches, segments) = (sim.tree().branches().len(), sim.tree().segment_count());
    eprintln!(
        "{branches} branches ({segments} segments), {frames} frames at {} fps, {}",
        args.fps,
        match args.release {
            Some((id, deg)) => format!("release of branch {id} from {deg}°"),
            None => format!("wind {} m/s", args.wind_speed_m_s),
        }
    );
    let (poses, sim_s) = simulate(&mut sim, wind.as_mut(), frames)?;
    let max_angle_deg = poses
        .iter()
        .flat_map(|p| p.angle_rad.iter())
        .fold(0.0f64, |m, a| m.max(a.abs()))
        .to_degrees();
    let mut warnings = Vec::new();
    if max_angle_deg > SMALL_ANGLE_LIMIT_RAD.to_degrees() {
        warnings.push(format!(
            "branches bend up to {max_angle_deg:.1}°, beyond the small-angle beam model ({:.0}°): the shapes are not physical",
            SMALL_ANGLE_LIMIT_RAD.to_degrees()
        ));
    }
    let release = match (args.release, released) {
        (Some((id, degrees)), Some((i, frequency_hz, damping_ratio))) => {
            let series: Vec<Option<f64>> = poses.iter().map(|p| Some(p.angle_rad[i])).collect();
            let fit = Signal::uniform(args.fps, series)
                .and_then(|s| estimate(&s, &EstimateConfig::default()))
                .ok();
            let mode = fit.as_ref().and_then(|e| e.modes.first().copied());
            Some(Release {
                branch: id,
                degrees,
                configured_frequency_hz: frequency_hz,
                configured_damping_ratio: damping_ratio,
                measured_frequency_hz: mode.map(|m| m.frequency_hz),
                measured_damping_ratio: mode.map(|m| m.damping_ratio),
            })
        }
        _ => None,
    };
    let outputs = write_outputs(args, &sim, &poses)?;
    let released_mode = args.release.is_some();
    let summary = Summary {
        skeleton: name,
        mode: if released_mode { "release" } else { "wind" },
        branches,
        segments,
        frames,
        fps: args.fps,
        seconds: frames as f64 / args.fps,
        wind_speed_m_s: if released_mode {
            0.0
        } else {
            args.wind_speed_m_s
        },
        integrator: sim.integrator_report(),
        dynamics_sources: sources,
        max_angle_deg,
        warnings,
        release,
        simulation_ms_per_frame: sim_s / frames as f64 * 1e3,
        outputs,
    };
    println!("{}", serde_json::to_string_pretty(&summary)?);
    Ok(())
}

/// Read the skeleton and the dynamics, check the options, and set up the simulation. Every
/// error names the input it is about: the skeleton file, the dynamics file or the option.
fn set_up(args: &Args) -> Result<Setup, Box<dyn std::error::Error>> {
    let (name, skeleton) = match &args.skeleton {
        Some(p) => (
            p.display().to_string(),
            read_skeleton(p).map_err(|e| common::naming(p, e))?,
        ),
        None => {
            eprintln!("no skeleton given: the synthetic tree of space_colonize::synthetic");
            (
                "synthetic".to_string(),
                SyntheticConfig::default().generate()?.skeleton,
            )
        }
    };
    let mut config = AnimConfig {
        integrator: args.integrator,
        ..AnimConfig::default()
    };
    config.wind.mean_speed_m_s = args.wind_speed_m_s;
    let tree = BeamTree::new(&skeleton, &config).map_err(|e| format!("{name}: {e}"))?;
    let (dynamics_name, spec) = match &args.dynamics {
        Some(p) => (
            p.display().to_string(),
            DynamicsSpec::read(p).map_err(|e| common::naming(p, e))?,
        ),
        None => ("the default dynamics".to_string(), DynamicsSpec::default()),
    };
    let assignment = spec
        .assign(&tree)
        .map_err(|e| format!("{dynamics_name}: {e}"))?;
    let count = |f: fn(&DynamicsSource) -> bool| assignment.source.iter().filter(|s| f(s)).count();
    let sources = Sources {
        explicit: count(|s| matches!(s, DynamicsSource::Explicit)),
        measured: count(|s| matches!(s, DynamicsSource::Measured(_))),
        level: count(|s| matches!(s, DynamicsSource::Level(_))),
        default: count(|s| matches!(s, DynamicsSource::Default)),
    };
    let released = match args.release {
        Some((id, deg)) => {
            let i = tree
                .index_of(id)
                .map_err(|e| format!("--release {id}:{deg}: {e}"))?;
            let d = &assignment.dynamics[i];
            Some((i, d.frequency_hz, d.damping_ratio))
        }
        None => None,
    };
    let frames = frame_count(
        args.seconds,
        args.fps,
        tree.segment_count(),
        tree.branches().len(),
    )
    .map_err(|e| format!("--seconds {} --fps {}: {e}", args.seconds, args.fps))?;
    config
        .wind
        .validate()
        .map_err(|e| format!("--wind-speed {}: {e}", args.wind_speed_m_s))?;
    let mut sim = Simulation::new(tree, &assignment.dynamics, config, 1.0 / args.fps)
        .map_err(|e| format!("{dynamics_name} at --fps {}: {e}", args.fps))?;
    let wind = match args.release {
        Some((id, deg)) => {
            sim.pull(id, deg.to_radians())
                .map_err(|e| format!("--release {id}:{deg}: {e}"))?;
            None
        }
        None => Some(sim.wind_field()?),
    };
    Ok(Setup {
        name,
        sim,
        wind,
        sources,
        frames,
        released,
    })
}

/// Run `frames` steps (in `wind`, or free after a release) with progress on stderr: the
/// poses from the start, and the seconds spent stepping.
fn simulate(
    sim: &mut Simulation,
    mut wind: Option<&mut WindField>,
    frames: usize,
) -> Result<(Vec<Pose>, f64), Box<dyn std::error::Error>> {
    let mut poses: Vec<Pose> = Vec::with_capacity(frames + 1);
    poses.push(sim.pose().clone());
    let t = Instant::now();
    let mut sim_s = 0.0;
    let mut next_report = 0.1;
    for k in 0..frames {
        let t_frame = Instant::now();
        match wind.as_deref_mut() {
            Some(w) => sim.step(w)?,
            None => sim.step_free(),
        }
        sim_s += t_frame.elapsed().as_secs_f64();
        poses.push(sim.pose().clone());
        let done = (k + 1) as f64 / frames as f64;
        if done >= next_report {
            eprintln!(
                "[{:6.2} s] simulated {:3.0} % ({} of {frames} frames)",
                t.elapsed().as_secs_f64(),
                done * 100.0,
                k + 1
            );
            next_report += 0.1;
        }
    }
    Ok((poses, sim_s))
}

/// Write the glTF, and the BVH and angle CSV when asked; the paths written.
fn write_outputs(
    args: &Args,
    sim: &Simulation,
    poses: &[Pose],
) -> Result<Vec<String>, Box<dyn std::error::Error>> {
    let mut outputs = Vec::new();
    ensure_parent(&args.out)?;
    write_glb(&args.out, sim, poses, &GlbOptions::default())?;
    eprintln!("wrote {}", args.out.display());
    outputs.push(args.out.display().to_string());
    if let Some(p) = &args.bvh {
        ensure_parent(p)?;
        write_bvh(p, sim, poses)?;
        eprintln!("wrote {}", p.display());
        outputs.push(p.display().to_string());
    }
    if let Some(p) = &args.angles {
        ensure_parent(p)?;
        std::fs::write(p, angles_csv(sim, poses)?).map_err(|e| format!("{}: {e}", p.display()))?;
        eprintln!("wrote {}", p.display());
        outputs.push(p.display().to_string());
    }
    Ok(outputs)
}
