//! How well trees are rebuilt from one depth camera's view, on synthetic trees with a known
//! skeleton: the evaluation behind the one-sided rows of `docs/validation.md` (issue 22).
//!
//! ```text
//! cargo run --release --example one_sided_views -- [--set first|second|third] [--seeds A..B] [--distance-m D]
//! ```
//!
//! Each tree (`space_colonize::synthetic`, two sizes per set) is seen by a Kinect v2
//! (`space_colonize::camera_view`: the near half of each branch, 6 mm of depth noise along
//! the rays) from three sides, `--distance-m` from the trunk and 0.45 of the tree's height
//! up, and rebuilt from that view with the camera known. Per view and on average it prints
//! the share of the *whole* cloud within 2 cm of the model (issue 22's measure), the
//! model's volume against the true skeleton's, and the mean distance from the model's axis
//! to the true axis, and whether the reconstruction flagged the volume as untrusted
//! (`Reconstruction::volume_trusted`: a scan too noisy for its radii). The `first` and `second` sets (seeds 60..68) were used to choose the
//! one-sided rules; `third` (seeds 70..78) was not until 5 December 2026, when seed 71's
//! views shaped the rule that continues hidden trunks (`ColonizeConfig::hidden_wood`);
//! `--set third --seeds 90..98` and `--set third --distance-m 3.5` were not.

use std::ops::Range;

use clap::{Parser, ValueEnum};
use treemocap::nalgebra::Point3;
use treemocap::space_colonize::synthetic::{SyntheticConfig, skeleton_error};
use treemocap::space_colonize::{ColonizeConfig, ViewConfig, camera_view, fidelity, reconstruct};

mod common;

/// Camera azimuths around the trunk, radians.
const AZIMUTHS_RAD: [f64; 3] = [0.3, 2.4, 4.5];
/// Camera height as a share of the tree's height.
const CAMERA_HEIGHT_SHARE: f64 = 0.45;
/// A view's volume counts as off when it is more than this share from the truth's (issue
/// 22's 10 %).
const VOLUME_TOLERANCE: f64 = 0.1;

/// Trees of one set: (noise in metres, trunk radius in metres, height in metres, points).
#[derive(Debug, Clone, Copy, ValueEnum)]
enum Set {
    /// 4 cm trunks with 1 mm of noise, 7 cm trunks with 2 mm (tuning, seeds 60..68).
    First,
    /// 7 cm trunks with 1 mm of noise, 4 cm trunks with 2 mm (tuning, seeds 60..68).
    Second,
    /// 5 cm trunks with 1.5 mm of noise, 6 cm trunks with 3 mm (evaluation, seeds 70..78).
    Third,
}

impl Set {
    fn trees(self) -> [(f64, f64, f64, usize); 2] {
        match self {
            Self::First => [(0.001, 0.04, 3.5, 20_000), (0.002, 0.07, 4.0, 30_000)],
            Self::Second => [(0.001, 0.07, 4.0, 30_000), (0.002, 0.04, 3.5, 20_000)],
            Self::Third => [(0.0015, 0.05, 3.8, 25_000), (0.003, 0.06, 4.5, 35_000)],
        }
    }

    fn seeds(self) -> Range<u64> {
        match self {
            Self::First | Self::Second => 60..68,
            Self::Third => 70..78,
        }
    }
}

/// Synthetic trees rebuilt from one camera's view, measured against their truth.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// Which trees (see the program's documentation).
    #[arg(long, value_enum, default_value = "third")]
    set: Set,
    /// Seeds as `A..B` (B excluded); default the set's.
    #[arg(long, value_parser = parse_range)]
    seeds: Option<Range<u64>>,
    /// Camera distance from the trunk, metres.
    #[arg(long, default_value_t = 2.5)]
    distance_m: f64,
}

fn parse_range(s: &str) -> Result<Range<u64>, String> {
    let (a, b) = s
        .split_once("..")
        .ok_or_else(|| format!("{s:?}: expected A..B"))?;
    let parse = |x: &str| x.trim().parse::<u64>().map_err(|e| format!("{x:?}: {e}"));
    let (a, b) = (parse(a)?, parse(b)?);
    if a >= b {
        return Err(format!("{s:?}: the range is empty"));
    }
    Ok(a..b)
}

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    common::run("one_sided_views", || run_main(&args))
}

fn run_main(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    if !(args.distance_m.is_finite() && args.distance_m > 0.0) {
        return Err(format!("--distance-m {}: must be positive", args.distance_m).into());
    }
    let (mut within, mut volume_error, mut axis_m, mut views) = (0.0, 0.0, 0.0, 0);
    // Views whose volume is off by more than the tolerance, and those of them whose volume
    // the reconstruction said could be trusted (`Reconstruction::volume_trusted`).
    let (mut off, mut off_trusted) = (0, 0);
    for seed in args.seeds.clone().unwrap_or_else(|| args.set.seeds()) {
        for (noise_m, base_radius_m, height_m, points) in args.set.trees() {
            let tree = SyntheticConfig {
                seed,
                noise_m,
                base_radius_m,
                height_m,
                points,
                ..Default::default()
            }
            .generate()?;
            let root = tree.skeleton.nodes()[tree.skeleton.root()].position;
            for azimuth in AZIMUTHS_RAD {
                let camera = Point3::new(
                    root.x + args.distance_m * azimuth.cos(),
                    root.y + args.distance_m * azimuth.sin(),
                    root.z + CAMERA_HEIGHT_SHARE * height_m,
                );
                let seen = camera_view(
                    &tree.points,
                    &ViewConfig {
                        seed,
                        ..ViewConfig::kinect(camera)
                    },
                )?;
                let config = ColonizeConfig {
                    camera_m: Some(camera),
                    ..Default::default()
                };
                let model = match reconstruct(&seen, &config) {
                    Ok(m) => m,
                    Err(e) => {
                        println!("seed {seed} trunk {base_radius_m} m azimuth {azimuth}: {e}");
                        continue;
                    }
                };
                let f = fidelity(&tree.points, &model.skeleton);
                let e = skeleton_error(&model.skeleton, &tree.skeleton);
                let ratio = model.skeleton.volume_m3() / tree.skeleton.volume_m3();
                let trusted = model.volume_trusted();
                println!(
                    "seed {seed} trunk {base_radius_m} m noise {noise_m} m azimuth {azimuth} rad: \
                     whole cloud within 2 cm {:.2} %, volume x{ratio:.3}{}, axis error {:.2} mm",
                    100.0 * f.within_2cm,
                    if trusted { "" } else { " (flagged untrusted)" },
                    1e3 * e.mean_skeleton_error_m
                );
                within += f.within_2cm;
                volume_error += (ratio - 1.0).abs();
                axis_m += e.mean_skeleton_error_m;
                let is_off = (ratio - 1.0).abs() > VOLUME_TOLERANCE;
                off += usize::from(is_off);
                off_trusted += usize::from(is_off && trusted);
                views += 1;
            }
        }
    }
    let n = f64::from(u32::try_from(views.max(1))?);
    println!(
        "mean over {views} views: whole cloud within 2 cm {:.2} %, |volume ratio - 1| {:.3}, \
         axis error {:.2} mm; volume off by more than 10 %: {off} ({off_trusted} of them \
         not flagged untrusted)",
        100.0 * within / n,
        volume_error / n,
        1e3 * axis_m / n
    );
    Ok(())
}
