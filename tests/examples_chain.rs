//! The stage programs chain as the README says: `branch_angles` writes `t,<branch>...`, and
//! `estimate_modal --column <branch>` reads a branch's column of it by name; usage errors
//! exit 2 and every program knows `--version`. Runs the example programs `cargo test`
//! builds next to this test; skips with a message when they are not there.
#![allow(missing_docs, clippy::expect_used, clippy::unwrap_used, clippy::panic)]

use std::path::PathBuf;
use std::process::Command;

use treemocap::branch_angles::csv::trajectories_to_csv;
use treemocap::branch_angles::synthetic;

const PROGRAMS: [&str; 8] = [
    "pipeline",
    "capture_to_cloud",
    "cloud_timing",
    "track_markers",
    "branch_angles",
    "estimate_modal",
    "reconstruct_tree",
    "animate_tree",
];

/// What a test prints when the example programs are not there to run.
const SKIPPED: &str = "skipped: the example programs are not built (run `cargo test --workspace`)";

/// An empty scratch directory of this test process, `treemocap-<tag>-<pid>` in the temp dir.
fn fresh_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("treemocap-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn program(name: &str) -> Option<PathBuf> {
    let exe = std::env::current_exe().ok()?;
    let path = exe
        .parent()?
        .parent()?
        .join("examples")
        .join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    path.exists().then_some(path)
}

#[test]
fn branch_angles_output_feeds_estimate_modal_by_column_name() {
    let (Some(angles), Some(modal)) = (program("branch_angles"), program("estimate_modal")) else {
        eprintln!("{SKIPPED}");
        return;
    };
    let dir = fresh_dir("chain");
    let tree = synthetic::two_level();
    std::fs::write(
        dir.join("trajectories.csv"),
        trajectories_to_csv(&tree.trajectories),
    )
    .unwrap();
    std::fs::write(dir.join("hierarchy.json"), tree.hierarchy.to_json()).unwrap();
    let out = Command::new(&angles)
        .arg(dir.join("trajectories.csv"))
        .arg(dir.join("hierarchy.json"))
        .arg("--out")
        .arg(dir.join("angles.csv"))
        // The signed tilts: the unsigned angle folds a swing through the rest direction
        // and doubles its apparent frequency.
        .arg("--signed")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for truth in &tree.truth {
        let spread = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let column = if spread(&truth.u_rad) >= spread(&truth.w_rad) {
            format!("{}_u", truth.child)
        } else {
            format!("{}_w", truth.child)
        };
        let out = Command::new(&modal)
            .arg(dir.join("angles.csv"))
            .args(["--column", &column])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}: {}",
            truth.child,
            String::from_utf8_lossy(&out.stderr)
        );
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let f = json["modes"][0]["frequency_hz"].as_f64().unwrap();
        assert!(
            (f - truth.frequency_hz).abs() < 0.02 * truth.frequency_hz,
            "{}: {f} Hz, true {} Hz",
            truth.child,
            truth.frequency_hz
        );
    }
    // A name that is not a column is an error naming it.
    let out = Command::new(&modal)
        .arg(dir.join("angles.csv"))
        .args(["--column", "nope"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("\"nope\""));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn every_program_knows_version_and_exits_2_on_a_usage_error() {
    for name in PROGRAMS {
        let Some(path) = program(name) else {
            eprintln!("skipped: {name} is not built");
            continue;
        };
        let out = Command::new(&path).arg("--version").output().unwrap();
        assert!(out.status.success(), "{name} --version");
        assert!(
            String::from_utf8_lossy(&out.stdout).starts_with(name),
            "{name}"
        );
        let out = Command::new(&path)
            .arg("--no-such-option")
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{name}");
        assert!(
            String::from_utf8_lossy(&out.stderr).starts_with("error: "),
            "{name}"
        );
    }
}

#[test]
fn reconstruct_tree_flags_a_cloud_in_a_cameras_frame_and_turns_it_with_up() {
    use treemocap::nalgebra::Vector3;
    use treemocap::space_colonize::UpAxis;
    use treemocap::space_colonize::synthetic::SyntheticConfig;
    let Some(program) = program("reconstruct_tree") else {
        eprintln!("{SKIPPED}");
        return;
    };
    let dir = fresh_dir("up");
    // A tree 3 m in front of a level camera 1.2 m above its base, in the camera's frame
    // (x right, y down, z forward), as capture_to_cloud writes a capture.
    let tree = SyntheticConfig {
        points: 4_000,
        max_order: 2,
        seed: 9,
        ..Default::default()
    }
    .generate()
    .unwrap();
    let camera = Vector3::new(0.0, -3.0, 1.2);
    let text: String = tree
        .points
        .iter()
        .map(|p| {
            let c = UpAxis::MinusY.from_z_up(&(p - camera));
            format!("{} {} {}\n", c.x, c.y, c.z)
        })
        .collect();
    let cloud = dir.join("capture.xyz");
    std::fs::write(&cloud, text).unwrap();
    let skeleton = dir.join("skeleton.json");
    let json = |args: &[&str]| -> serde_json::Value {
        let out = Command::new(&program).args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let cloud_arg = cloud.to_str().unwrap();
    let read_z_up = json(&[cloud_arg]);
    assert_eq!(read_z_up["up"], "+z");
    assert!(
        read_z_up["warnings"][0]
            .as_str()
            .is_some_and(|w| w.contains("--up -y")),
        "{read_z_up}"
    );
    let turned = json(&[
        cloud_arg,
        "--up",
        "-y",
        "--out-skeleton",
        skeleton.to_str().unwrap(),
    ]);
    assert_eq!(turned["up"], "-y");
    assert!(turned.get("warnings").is_none(), "{turned}");
    assert!(turned["fidelity"]["within_2cm"].as_f64().unwrap() > 0.95);
    // The skeleton is written in the cloud's frame: its root at the trunk's base, 1.2 m
    // below the camera (+y) and 3 m in front of it.
    let nodes: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&skeleton).unwrap()).unwrap();
    let root = &nodes["nodes"][0]["position"];
    let (y, z) = (root[1].as_f64().unwrap(), root[2].as_f64().unwrap());
    assert!((y - 1.2).abs() < 0.1 && (z - 3.0).abs() < 0.2, "{root}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn reconstruct_tree_sets_leaves_aside_and_writes_them() {
    use treemocap::space_colonize::synthetic::SyntheticConfig;
    let Some(program) = program("reconstruct_tree") else {
        eprintln!("{SKIPPED}");
        return;
    };
    let dir = fresh_dir("leaves");
    let tree = SyntheticConfig {
        points: 8_000,
        leaf_points: 4_000,
        seed: 11,
        ..Default::default()
    }
    .generate()
    .unwrap();
    let text: String = tree
        .points
        .iter()
        .map(|p| format!("{} {} {}\n", p.x, p.y, p.z))
        .collect();
    let cloud = dir.join("leafy.xyz");
    std::fs::write(&cloud, text).unwrap();
    let leaves = dir.join("leaves.xyz");
    let run = |args: &[&str]| Command::new(&program).args(args).output().unwrap();
    let cloud_arg = cloud.to_str().unwrap();
    let out = run(&[
        cloud_arg,
        "--separate-leaves",
        "--out-leaves",
        leaves.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let n = json["leaves"]["points"].as_u64().unwrap() as usize;
    let written = std::fs::read_to_string(&leaves).unwrap();
    assert_eq!(written.lines().count(), n);
    // Most of the leaves, and some of the wood: a fifth to a third of so small a cloud's
    // wood (twigs among the leaves, forks) goes with them.
    assert!(n > 3_000 && n < 7_500, "{n}");
    let to_wood = &json["fidelity_to_wood"];
    assert!(
        to_wood["model_near_cloud"].as_f64().unwrap() > 0.9,
        "{to_wood}"
    );
    assert_eq!(
        to_wood["points"].as_u64().unwrap() as usize,
        tree.points.len() - n
    );
    // Without separation: no "leaves", and --out-leaves alone is a usage error.
    let plain: serde_json::Value = serde_json::from_slice(&run(&[cloud_arg]).stdout).unwrap();
    assert!(plain.get("leaves").is_none() && plain.get("fidelity_to_wood").is_none());
    let usage = run(&[cloud_arg, "--out-leaves", leaves.to_str().unwrap()]);
    assert_eq!(usage.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `track_markers` with a colour model warns about a window without colour (a
/// black-and-white target, for which `--model gray` is meant), and not about a coloured
/// marker or under the gray model.
#[test]
fn track_markers_warns_of_a_colour_model_on_a_target_without_colour() {
    let Some(track) = program("track_markers") else {
        eprintln!("{SKIPPED}");
        return;
    };
    let dir = fresh_dir("colourless");
    for k in 0..3u32 {
        let frame = treemocap::image::RgbImage::from_fn(96, 48, |x, y| {
            let (dx, dy) = (x as i32 - 24 - k as i32, y as i32 - 24);
            let (rx, ry) = (x as i32 - 70 - k as i32, y as i32 - 24);
            treemocap::image::Rgb(if dx.abs() <= 7 && dy.abs() <= 7 {
                if dx * dx + dy * dy <= 9 {
                    [20, 20, 20]
                } else {
                    [235, 235, 230]
                }
            } else if rx * rx + ry * ry <= 36 {
                [215, 25, 30]
            } else {
                [110, 115, 105]
            })
        });
        frame.save(dir.join(format!("f{k:04}.png"))).unwrap();
    }
    let init = dir.join("init.json");
    std::fs::write(
        &init,
        r#"[{"id": "white", "x": 14, "y": 14, "w": 21, "h": 21},
            {"id": "red", "x": 62, "y": 16, "w": 17, "h": 17}]"#,
    )
    .unwrap();
    let run = |model: &str| {
        let out = Command::new(&track)
            .arg(&dir)
            .arg(&init)
            .args(["--model", model, "--out"])
            .arg(dir.join(format!("{model}.json")))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        (out.status.success(), stderr)
    };
    // The RGB model runs on the white target; the hue model cannot (none of its pixels
    // passes the hue mask: an error), and the advice comes before it.
    for (model, runs) in [("rgb", true), ("hue", false)] {
        let (ok, stderr) = run(model);
        assert_eq!(ok, runs, "{model}: {stderr}");
        let warnings: Vec<&str> = stderr
            .lines()
            .filter(|l| l.starts_with("warning"))
            .collect();
        assert_eq!(warnings.len(), 1, "{model}: {stderr}");
        assert!(
            warnings[0].contains("marker white") && warnings[0].contains("--model gray"),
            "{model}: {stderr}"
        );
        assert!(runs || stderr.contains("no usable pixels"), "{stderr}");
    }
    let (ok, stderr) = run("gray");
    assert!(ok && !stderr.contains("warning"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}
