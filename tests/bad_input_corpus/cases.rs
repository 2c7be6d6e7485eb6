//! The corpus: every mutation of every input file, and every extreme option, as a case of
//! the program that reads it.

use super::*;

/// Every file mutation of `file` (relative to `base`), each as a case of `program` whose
/// arguments `args` builds from the case directory.
/// The arguments (and the output files) of a run on a case directory.
pub(super) type ArgsFor<'a> = &'a dyn Fn(&Path) -> (Vec<OsString>, Vec<PathBuf>);

pub(super) fn file_cases(
    corpus: &mut Corpus,
    program: &'static str,
    base: &Path,
    file: &str,
    make_args: ArgsFor<'_>,
    flips: usize,
    places: usize,
) {
    let mut rng = Mix(Rng::new(corpus.count as u64));
    let rng = &mut rng;
    let bytes = std::fs::read(base.join(file)).unwrap();
    let text = String::from_utf8(bytes.clone()).ok();
    let mut variants: Vec<(String, Vec<u8>)> = byte_mutations(&bytes, rng, flips);
    if let Some(text) = &text {
        variants.extend(
            value_mutations(text, rng, places)
                .into_iter()
                .map(|(l, t)| (l, t.into_bytes())),
        );
        if let Ok(json) = serde_json::from_str::<serde_json::Value>(text) {
            variants.extend(
                json_mutations(&json)
                    .into_iter()
                    .map(|(l, t)| (l, t.into_bytes())),
            );
        }
    }
    let name = Path::new(file)
        .file_name()
        .unwrap()
        .to_string_lossy()
        .into_owned();
    // The unbroken inputs first: what the program says of them.
    let dir = corpus.fresh(base);
    let (args, outputs) = make_args(&dir);
    let baseline = corpus.cases.len();
    corpus.cases.push(Case {
        program,
        args,
        label: format!("{file}: unchanged"),
        names: vec![name.clone()],
        dir,
        baseline: None,
        outputs,
    });
    corpus.baselines.push(baseline);
    let push = |corpus: &mut Corpus, label: String, dir: PathBuf| {
        let (args, outputs) = make_args(&dir);
        corpus.cases.push(Case {
            program,
            args,
            label: format!("{file}: {label}"),
            names: vec![name.clone()],
            dir,
            baseline: Some(baseline),
            outputs,
        });
    };
    for (label, content) in variants {
        let dir = corpus.fresh(base);
        std::fs::write(dir.join(file), content).unwrap();
        push(corpus, label, dir);
    }
    // A directory where the file should be.
    let dir = corpus.fresh(base);
    std::fs::remove_file(dir.join(file)).unwrap();
    std::fs::create_dir_all(dir.join(file)).unwrap();
    push(corpus, "a directory".into(), dir);
    // The file missing.
    let dir = corpus.fresh(base);
    std::fs::remove_file(dir.join(file)).unwrap();
    push(corpus, "missing".into(), dir);
}

/// Cases of extreme option values on valid inputs.
pub(super) fn option_cases(corpus: &mut Corpus, b: &Bases) {
    // Per program: its base inputs, the arguments before the options, the options (each
    // with a bad value) and the output file, if it writes one.
    type Leading = fn(&Path) -> Vec<OsString>;
    type Row<'a> = (
        &'static str,
        &'a Path,
        Leading,
        &'a [(&'a str, &'a str)],
        &'a str,
    );
    let table: [Row<'_>; 4] = [
        (
            "estimate_modal",
            &b.signal,
            |d| os(&[&d.join("signal.csv")]),
            &[
                ("--band", "5:1"),
                ("--band", "0:1000000000"),
                ("--band", "nan:1"),
                ("--column", "99"),
                ("--column", "0"),
                ("--rate", "0"),
                ("--rate", "-5"),
                ("--modes", "0"),
                ("--modes", "1000000"),
                ("--method", "magic"),
            ],
            "",
        ),
        (
            "animate_tree",
            &b.animation,
            |d| {
                os(&[
                    &"--skeleton",
                    &d.join("skeleton.json"),
                    &"--seconds",
                    &"0.5",
                ])
            },
            &[
                ("--seconds", "1e9"),
                ("--seconds", "0"),
                ("--seconds", "nan"),
                ("--seconds", "100000"),
                ("--fps", "1e9"),
                ("--fps", "-30"),
                ("--fps", "0.1"),
                ("--wind-speed", "1e6"),
                ("--wind-speed", "-1"),
                ("--release", "0:1000"),
                ("--release", "999999:10"),
                ("--release", "x:10"),
                ("--integrator", "rk4"),
            ],
            "t.glb",
        ),
        (
            "capture_to_cloud",
            &b.recording,
            |d| os(&[&d.join("rec")]),
            &[("--frame", "99999"), ("--frame", "-1"), ("--frame", "x")],
            "c.ply",
        ),
        (
            "track_markers",
            &b.frames,
            |d| os(&[&d.join("frames"), &d.join("init.json")]),
            &[("--model", "infrared"), ("--window", "huge")],
            "tracks.json",
        ),
    ];
    for (program, base, leading, options, out) in table {
        for &(opt, value) in options {
            let dir = corpus.fresh(base);
            let mut args = leading(&dir);
            args.extend([OsString::from(opt), OsString::from(value)]);
            let mut outputs = Vec::new();
            if !out.is_empty() {
                args.extend([OsString::from("--out"), dir.join(out).into_os_string()]);
                outputs.push(dir.join(out));
            }
            corpus.cases.push(Case {
                program,
                label: format!("{program} {opt} {value}"),
                args,
                names: vec![opt.to_owned(), value.to_owned()],
                dir,
                baseline: None,
                outputs,
            });
        }
    }
}

pub(super) fn build_corpus(root: &Path) -> Corpus {
    let b = make_bases(root);
    let mut corpus = Corpus {
        root: root.join("cases"),
        count: 0,
        cases: Vec::new(),
        baselines: Vec::new(),
    };
    file_cases(
        &mut corpus,
        "estimate_modal",
        &b.signal,
        "signal.csv",
        &|d| (os(&[&d.join("signal.csv")]), vec![]),
        8,
        4,
    );
    for file in ["trajectories.csv", "hierarchy.json"] {
        file_cases(
            &mut corpus,
            "branch_angles",
            &b.angles,
            file,
            &angles_args,
            6,
            3,
        );
    }
    for file in ["init.json", "frames/f000.jpg", "frames/f003.jpg"] {
        file_cases(
            &mut corpus,
            "track_markers",
            &b.frames,
            file,
            &track_args,
            4,
            0,
        );
    }
    for file in [
        "rec/calibration.json",
        "rec/frames.csv",
        "rec/color/000001.jpg",
        "rec/depth/000001.png",
    ] {
        file_cases(
            &mut corpus,
            "capture_to_cloud",
            &b.recording,
            file,
            &cloud_args,
            3,
            1,
        );
    }
    reconstruct_cases(&mut corpus, &b);
    for (file, flips, places) in [("skeleton.json", 3, 1), ("dynamics.json", 4, 2)] {
        file_cases(
            &mut corpus,
            "animate_tree",
            &b.animation,
            file,
            &anim_args,
            flips,
            places,
        );
    }
    for file in ["markers.json", "rec/color/000000.jpg"] {
        file_cases(
            &mut corpus,
            "pipeline",
            &b.recording,
            file,
            &pipeline_args,
            2,
            0,
        );
    }
    size_cases(&mut corpus, &b);
    option_cases(&mut corpus, &b);
    corpus
}

/// reconstruct_tree on each format of the cloud base.
fn reconstruct_cases(corpus: &mut Corpus, b: &Bases) {
    for (file, flips, places) in [
        ("tree.xyz", 4, 2),
        ("tree.ply", 4, 2),
        ("tree_binary.ply", 6, 0),
        ("tree.pcd", 4, 1),
    ] {
        let f = file.to_owned();
        file_cases(
            corpus,
            "reconstruct_tree",
            &b.clouds,
            file,
            &move |d: &Path| {
                (
                    os(&[&d.join(&f), &"--out-skeleton", &d.join("s.json")]),
                    vec![d.join("s.json")],
                )
            },
            flips,
            places,
        );
    }
}

/// Frames of changing size: one colour frame of a recording and one tracked frame.
fn size_cases(corpus: &mut Corpus, b: &Bases) {
    let dir = corpus.fresh(&b.recording);
    let small = RgbImage::from_pixel(17, 11, Rgb([1, 2, 3]));
    small.save(dir.join("rec/color/000001.jpg")).unwrap();
    let (args, outputs) = cloud_args(&dir);
    corpus.cases.push(Case {
        program: "capture_to_cloud",
        args,
        label: "a colour frame of another size".into(),
        names: vec!["000001.jpg".into()],
        dir,
        baseline: None,
        outputs,
    });
    let dir = corpus.fresh(&b.frames);
    small.save(dir.join("frames/f002.jpg")).unwrap();
    let (args, outputs) = track_args(&dir);
    corpus.cases.push(Case {
        program: "track_markers",
        args,
        label: "a frame of another size".into(),
        names: vec!["f002.jpg".into()],
        dir,
        baseline: None,
        outputs,
    });
}

/// branch_angles on a case directory: the trajectories and hierarchy, the angles written.
fn angles_args(d: &Path) -> (Vec<OsString>, Vec<PathBuf>) {
    (
        os(&[
            &d.join("trajectories.csv"),
            &d.join("hierarchy.json"),
            &"--out",
            &d.join("angles.csv"),
        ]),
        vec![d.join("angles.csv")],
    )
}

/// track_markers on a case directory: the frames and windows, the tracks written.
fn track_args(d: &Path) -> (Vec<OsString>, Vec<PathBuf>) {
    (
        os(&[
            &d.join("frames"),
            &d.join("init.json"),
            &"--out",
            &d.join("tracks.json"),
        ]),
        vec![d.join("tracks.json")],
    )
}

/// capture_to_cloud on a case directory: frame 1 of the recording, the cloud written.
fn cloud_args(d: &Path) -> (Vec<OsString>, Vec<PathBuf>) {
    (
        os(&[
            &d.join("rec"),
            &"--frame",
            &"1",
            &"--out",
            &d.join("cloud.ply"),
        ]),
        vec![d.join("cloud.ply")],
    )
}

/// animate_tree on a case directory: the skeleton and dynamics, half a second, glTF and BVH written.
fn anim_args(d: &Path) -> (Vec<OsString>, Vec<PathBuf>) {
    (
        os(&[
            &"--skeleton",
            &d.join("skeleton.json"),
            &"--dynamics",
            &d.join("dynamics.json"),
            &"--seconds",
            &"0.5",
            &"--out",
            &d.join("tree.glb"),
            &"--bvh",
            &d.join("tree.bvh"),
        ]),
        vec![d.join("tree.glb"), d.join("tree.bvh")],
    )
}

/// pipeline on a case directory: the recording and its markers, the report folder.
fn pipeline_args(d: &Path) -> (Vec<OsString>, Vec<PathBuf>) {
    (
        os(&[
            &"--recording",
            &d.join("rec"),
            &"--markers",
            &d.join("markers.json"),
            &"--out-dir",
            &d.join("report"),
        ]),
        vec![],
    )
}
