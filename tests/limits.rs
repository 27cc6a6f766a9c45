//! End-to-end: sizes and counts from the command line have documented ranges, and bad input
//! exits 2 with a message that names the option, file or field at fault.

mod common;
use common::*;
use serde_json::{json, Value};
use std::path::Path;

#[test]
fn out_of_range_sizes_are_refused_naming_the_option_and_its_range() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let train = |opt: &'static str, v: &'static str| {
        vec![
            "train",
            "apriltag-16h5",
            "--stage",
            "keypoints",
            opt,
            v,
            "--out",
            "r",
        ]
    };
    for (args, names) in [
        (train("--width", "100000"), ["--width", "8..=256"]),
        (train("--width", "4"), ["--width", "8..=256"]),
        (train("--batch", "100000"), ["--batch", "1..=256"]),
        (train("--steps", "0"), ["--steps", "1..=10000000"]),
        (
            train("--validation-patches", "0"),
            ["--validation-patches", "1..=10000"],
        ),
        (train("--workers", "0"), ["--workers", "1..="]),
        (train("--workers", "100000"), ["--workers", "1..="]),
        (
            train("--checkpoint-every", "0"),
            ["--checkpoint-every", "1.."],
        ),
        (train("--validate-every", "0"), ["--validate-every", "1.."]),
        (train("--learning-rate", "5"), ["--learning-rate", "(0, 1]"]),
        (
            vec![
                "detect",
                "x.png",
                "--family",
                "apriltag-16h5",
                "--roi",
                "0,0,1,0,1,1,0,1",
                "--iterations",
                "1000000",
            ],
            ["--iterations", "1..=10"],
        ),
        (
            vec!["detect-set", "set", "-o", "d.json", "--iterations", "0"],
            ["--iterations", "1..=10"],
        ),
        (
            vec!["synth", "apriltag-16h5", "-n", "2000000", "-o", "s"],
            ["--count", "1..=1000000"],
        ),
        (
            vec!["synth", "apriltag-16h5", "--width", "100000", "-o", "s"],
            ["--width", "16..=8192"],
        ),
        (
            vec![
                "render",
                "apriltag-16h5",
                "--id",
                "0",
                "--px",
                "100000",
                "-o",
                "m.png",
            ],
            ["--px", "1..=20000"],
        ),
        (
            vec![
                "render",
                "apriltag-16h5",
                "--id",
                "0",
                "--size-mm",
                "1e9",
                "-o",
                "m.svg",
            ],
            ["--size-mm", "[1, 2000]"],
        ),
        (
            vec![
                "sheet",
                "apriltag-16h5",
                "--ids",
                "0",
                "--size-mm",
                "0",
                "-o",
                "s.pdf",
            ],
            ["--size-mm", "[1, 2000]"],
        ),
        (
            vec![
                "codebook",
                "generate",
                "aruco-4x4_50",
                "--min-distance",
                "3",
                "--count",
                "0",
                "-o",
                "c.json",
            ],
            ["--count", "1..=100000"],
        ),
        (
            vec![
                "codebook",
                "generate",
                "aruco-4x4_50",
                "--min-distance",
                "3",
                "--max-candidates",
                "0",
                "-o",
                "c.json",
            ],
            ["--max-candidates", "1..="],
        ),
        (
            vec![
                "eval",
                "generate",
                "apriltag-16h5",
                "--per-cell",
                "4294967295",
                "-o",
                "set",
            ],
            ["--per-cell", "1..=100"],
        ),
        (
            vec![
                "eval",
                "generate",
                "apriltag-16h5",
                "--side-mm",
                "0",
                "-o",
                "set",
            ],
            ["--side-mm", "[1, 1000]"],
        ),
    ] {
        refused(d, &args, &names);
    }
    // Nothing was written, in particular no empty set folder.
    assert_eq!(std::fs::read_dir(d).unwrap().count(), 0);
}

#[test]
fn help_documents_the_ranges() {
    let dir = tempfile::tempdir().unwrap();
    for (cmd, ranges) in [
        (
            vec!["train", "--help"],
            vec!["8..=256", "1..=256", "1..=10000000", "1..=10000"],
        ),
        (vec!["detect", "--help"], vec!["1..=10"]),
        (vec!["detect-set", "--help"], vec!["1..=10"]),
        (
            vec!["eval", "generate", "--help"],
            vec!["1..=100", "[1, 1000]"],
        ),
        (vec!["synth", "--help"], vec!["1..=1000000", "16..=8192"]),
        (vec!["render", "--help"], vec!["1..=20000", "[1, 2000]"]),
        (vec!["sheet", "--help"], vec!["10000", "[1, 2000]"]),
        (vec!["codebook", "generate", "--help"], vec!["1..=100000"]),
    ] {
        let run = tagsmith(dir.path(), &cmd);
        run.ok();
        for r in ranges {
            assert!(run.stdout.contains(r), "{cmd:?}: {r} not in {}", run.stdout);
        }
    }
}

#[test]
fn a_huge_id_list_is_refused_before_it_is_expanded() {
    let dir = tempfile::tempdir().unwrap();
    let ids = vec!["0-586"; 2000].join(",");
    let started = std::time::Instant::now();
    refused(
        dir.path(),
        &["sheet", "apriltag-36h11", "--ids", &ids, "-o", "s.pdf"],
        &["--ids", "10000"],
    );
    assert!(started.elapsed().as_secs() < 10, "{:?}", started.elapsed());
    assert!(!dir.path().join("s.pdf").exists());
}

#[test]
fn codebook_generate_names_its_bad_options() {
    let dir = tempfile::tempdir().unwrap();
    let generate = |name: &str, expected: &[&str]| {
        refused(
            dir.path(),
            &[
                "codebook",
                "generate",
                "aruco-4x4_50",
                "--min-distance",
                "3",
                "--max-candidates",
                "1000",
                "--name",
                name,
                "-o",
                "c.json",
            ],
            expected,
        )
    };
    let run = generate("../../evil", &["--name", "../../evil"]);
    assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    assert!(!dir.path().join("c.json").exists());
    for name in ["..", ".hidden"] {
        generate(name, &["--name"]);
    }
}

#[test]
fn out_of_range_ids_and_sizes_name_their_option() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    refused(
        d,
        &["render", "apriltag-16h5", "--id", "30", "-o", "x.svg"],
        &["--id", "ID 30"],
    );
    refused(
        d,
        &["sheet", "apriltag-16h5", "--ids", "0,31", "-o", "x.pdf"],
        &["--ids", "ID 31"],
    );
    refused(
        d,
        &[
            "sheet",
            "apriltag-16h5",
            "--ids",
            "0",
            "--size-mm",
            "1000",
            "-o",
            "x.pdf",
        ],
        &["--size-mm", "does not fit"],
    );
}

#[test]
fn a_tiny_marker_side_in_a_family_file_names_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(workspace().join("families/apriltag-16h5.json")).unwrap();
    let mut f: Value = serde_json::from_str(&text).unwrap();
    f["print"]["marker_side_mm"] = json!(5e-324);
    std::fs::write(dir.path().join("f.json"), f.to_string()).unwrap();
    for args in [
        vec!["render", "f.json", "--id", "0", "-o", "m.png"],
        vec!["validate", "f.json"],
    ] {
        let run = refused(dir.path(), &args, &["print.marker_side_mm", "2000"]);
        assert!(!run.stderr.contains("NaN"), "{}", run.stderr);
    }
}

/// A one-image benchmark set (from `synth --mode camera`) and its oracle detections, as JSON.
fn small_set(dir: &Path) -> (Value, Value) {
    small_set_of(dir, "apriltag-16h5")
}

/// [`small_set`] of `family`.
fn small_set_of(dir: &Path, family: &str) -> (Value, Value) {
    tagsmith(
        dir,
        &["synth", family, "-n", "1", "--mode", "camera", "-o", "s"],
    )
    .ok();
    let truth: Value =
        serde_json::from_slice(&std::fs::read(dir.join("s/000000.json")).unwrap()).unwrap();
    std::fs::create_dir_all(dir.join("set/images")).unwrap();
    std::fs::copy(dir.join("s/000000.png"), dir.join("set/images/000000.png")).unwrap();
    let set = json!({
        "family": family,
        "side_m": truth["markers"][0]["pose"]["side_m"].as_f64().unwrap_or(0.05),
        "camera": truth["camera"],
        "seed": 0,
        "images": [{
            "file": "images/000000.png",
            "group": {"kind": "protocol", "distance_cm": 30, "angle_deg": 0, "normal": true},
            "truth": truth,
        }],
    });
    std::fs::write(dir.join("set/set.json"), set.to_string()).unwrap();
    tagsmith(dir, &["eval", "oracle", "set", "-o", "d.json"]).ok();
    let detections: Value =
        serde_json::from_slice(&std::fs::read(dir.join("d.json")).unwrap()).unwrap();
    (set, detections)
}

/// Damages one field of a JSON file.
type Breaks = fn(&mut Value);

#[test]
fn eval_score_refuses_sets_and_detections_that_cannot_be_scored() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (set, detections) = small_set(d);
    tagsmith(d, &["eval", "score", "set", "d.json", "-o", "report"]).ok();

    let write_set = |s: &Value| std::fs::write(d.join("set/set.json"), s.to_string()).unwrap();
    let broken_sets: [(&str, Breaks); 5] = [
        ("family", |s| s["family"] = json!("no-such-family")),
        ("side_m", |s| s["side_m"] = json!(0.0)),
        ("side_m", |s| s["side_m"] = json!(-0.05)),
        ("camera", |s| s["camera"]["fx"] = json!(0.0)),
        ("images[1].file", |s| {
            let first = s["images"][0].clone();
            s["images"].as_array_mut().unwrap().push(first);
        }),
    ];
    for (field, breaks) in broken_sets {
        let mut s = set.clone();
        breaks(&mut s);
        write_set(&s);
        refused(d, &["eval", "score", "set", "d.json"], &["set.json", field]);
    }
    write_set(&set);

    let broken_detections: [(&str, Breaks); 2] = [
        ("rotation", |f| {
            f["images"][0]["detections"][0]["pose"]["rotation"] =
                json!([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]);
        }),
        ("images[1].file", |f| {
            let first = f["images"][0].clone();
            f["images"].as_array_mut().unwrap().push(first);
        }),
    ];
    for (field, breaks) in broken_detections {
        let mut f = detections.clone();
        breaks(&mut f);
        std::fs::write(d.join("bad.json"), f.to_string()).unwrap();
        refused(
            d,
            &["eval", "score", "set", "bad.json"],
            &["bad.json", field],
        );
    }
}

/// Two detectors side by side: the one that misses the set's marker is counted against, and a
/// detections file that cannot be scored is named.
#[test]
fn eval_compare_counts_the_markers_one_detector_reads_alone() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (set, detections) = small_set(d);
    let markers = set["images"][0]["truth"]["markers"]
        .as_array()
        .unwrap()
        .len();
    let mut missed = detections.clone();
    missed["detector"] = json!("misses it");
    missed["images"][0]["detections"] = json!([]);
    std::fs::write(d.join("missed.json"), missed.to_string()).unwrap();
    let run = tagsmith(
        d,
        &[
            "eval",
            "compare",
            "set",
            "d.json",
            "missed.json",
            "--json",
            "c.json",
        ],
    );
    run.ok();
    let row = format!(
        "| normal (≤ 50 cm, ≤ 60°) | {markers} | 100.0 % | 0.0 % | {markers} | 0 | +100.0 |"
    );
    assert!(run.stdout.contains(&row), "{}", run.stdout);
    assert!(run.stdout.contains("B: misses it."), "{}", run.stdout);
    let written: Value = serde_json::from_slice(&std::fs::read(d.join("c.json")).unwrap()).unwrap();
    assert_eq!(
        written["rows"][0]["only_a_markers"][0][0],
        "images/000000.png"
    );
    // The other way round, the same markers count for B.
    let run = tagsmith(d, &["eval", "compare", "set", "missed.json", "d.json"]);
    run.ok();
    let row = format!(
        "| normal (≤ 50 cm, ≤ 60°) | {markers} | 0.0 % | 100.0 % | 0 | {markers} | -100.0 |"
    );
    assert!(run.stdout.contains(&row), "{}", run.stdout);

    let mut elsewhere = detections.clone();
    elsewhere["images"][0]["file"] = json!("images/999999.png");
    std::fs::write(d.join("elsewhere.json"), elsewhere.to_string()).unwrap();
    refused(
        d,
        &["eval", "compare", "set", "d.json", "elsewhere.json"],
        &["elsewhere.json", "999999"],
    );
}

/// A set of a design that is no built-in carries its family file, so it still scores.
#[test]
fn eval_score_reads_the_family_kept_with_the_set() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (mut set, _) = small_set(d);
    let mut spec = tagsmith::builtin::get("apriltag-16h5")
        .unwrap()
        .unwrap()
        .spec()
        .clone();
    spec.name = "my-design".into();
    std::fs::write(
        d.join("set/family.json"),
        tagsmith::family::to_json_string(&spec),
    )
    .unwrap();
    set["family"] = json!("my-design");
    std::fs::write(d.join("set/set.json"), set.to_string()).unwrap();
    tagsmith(d, &["eval", "score", "set", "d.json", "-o", "report"]).ok();
    // A kept family that is not the set's is refused.
    set["family"] = json!("other-design");
    std::fs::write(d.join("set/set.json"), set.to_string()).unwrap();
    refused(
        d,
        &["eval", "score", "set", "d.json"],
        &["family.json", "my-design"],
    );
}

#[test]
fn codebook_generate_names_an_impossible_distance_and_its_range() {
    let dir = tempfile::tempdir().unwrap();
    let generate = |distance: &str, transitions: &str, expected: &[&str]| {
        refused(
            dir.path(),
            &[
                "codebook",
                "generate",
                "aruco-4x4_50",
                "--min-distance",
                distance,
                "--min-transitions",
                transitions,
                "-o",
                "c.json",
            ],
            expected,
        );
    };
    // aruco-4x4_50 has 16 symbols.
    generate("1000000000", "0", &["--min-distance", "0..=16"]);
    generate("17", "0", &["--min-distance", "0..=16"]);
    generate("3", "16", &["--min-transitions", "0..=15"]);
    generate("3", "4000000000", &["--min-transitions", "0..=15"]);
    assert!(!dir.path().join("c.json").exists());
}

#[test]
fn a_set_whose_image_paths_leave_its_folder_is_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (set, _) = small_set(d);
    let absolute = d.join("set/images/000000.png");
    let absolute = absolute.to_str().unwrap();
    for (file, why) in [
        (absolute, "absolute"),
        ("../set/images/000000.png", "leaves the set folder"),
        (
            "images/../../set/images/000000.png",
            "leaves the set folder",
        ),
        ("", "empty"),
    ] {
        let mut s = set.clone();
        s["images"][0]["file"] = json!(file);
        std::fs::write(d.join("set/set.json"), s.to_string()).unwrap();
        for args in [
            vec!["eval", "score", "set", "d.json"],
            vec!["eval", "oracle", "set", "-o", "o.json"],
            vec!["detect-set", "set", "-o", "o.json"],
        ] {
            refused(d, &args, &["set.json", "images[0].file", why]);
        }
    }
    // Inside the folder, however spelled, is fine.
    let mut s = set.clone();
    s["images"][0]["file"] = json!("./images//000000.png");
    std::fs::write(d.join("set/set.json"), s.to_string()).unwrap();
    tagsmith(d, &["eval", "score", "set", "d.json", "-o", "report"]).ok();
    assert!(!d.join("o.json").exists());
}

/// The subnormal ROI that spun in the homography's SVD forever, as a set's ground truth: refused
/// when the set is read, naming set.json, the field and the image.
#[test]
fn a_subnormal_truth_roi_is_bad_input_not_a_hang() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A family with shipped weights, so that detect-set would reach stage 2 with the ROI.
    let (set, _) = small_set_of(d, "apriltag-36h11");
    let tiny = json!([[0.0, 0.0], [5e-324, 0.0], [5e-324, 5e-324], [0.0, 5e-324]]);
    let bow_tie = json!([[0.0, 0.0], [100.0, 100.0], [100.0, 0.0], [0.0, 100.0]]);
    for (roi, why) in [
        (tiny, "subnormal"),
        (bow_tie, "bow-tie"),
        (json!([[0.0, 0.0], [1.0, 0.0]]), "2 points"),
    ] {
        let mut s = set.clone();
        s["images"][0]["truth"]["markers"][0]["roi"] = roi;
        std::fs::write(d.join("set/set.json"), s.to_string()).unwrap();
        for args in [
            vec!["detect-set", "set", "-o", "o.json"],
            vec!["eval", "score", "set", "d.json"],
        ] {
            refused(
                d,
                &args,
                &[
                    "set.json",
                    "images[0].truth.markers[0].roi",
                    "images/000000.png",
                    why,
                ],
            );
        }
    }
    assert!(!d.join("o.json").exists());
}

/// The same image under two spellings of its path: the later list silently replaced the earlier.
#[test]
fn eval_score_refuses_one_image_listed_under_two_spellings() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (_, detections) = small_set(d);
    let through_the_set = d.join("set/images/000000.png");
    for other in [
        "./images/000000.png",
        "images//000000.png",
        "images/./000000.png",
        "x/../images/000000.png",
        through_the_set.to_str().unwrap(),
    ] {
        let mut f = detections.clone();
        let mut second = f["images"][0].clone();
        second["file"] = json!(other);
        second["detections"] = json!([]);
        f["images"].as_array_mut().unwrap().push(second);
        std::fs::write(d.join("twice.json"), f.to_string()).unwrap();
        for args in [
            vec!["eval", "score", "set", "twice.json"],
            vec!["eval", "compare", "set", "d.json", "twice.json"],
        ] {
            refused(
                d,
                &args,
                &[
                    "twice.json",
                    "images[1].file",
                    "\"images/000000.png\"",
                    &format!("{other:?}"),
                ],
            );
        }
    }
    assert!(!d.join("set/report-ground-truth").exists());
}

/// Set and detections files are read as regular files of a bounded size: a FIFO is not waited
/// on, a device not read forever.
#[cfg(unix)]
#[test]
fn eval_reads_no_fifo_or_device_as_set_or_detections() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    small_set(d);
    let fifo = |path: &Path| {
        let made = std::process::Command::new("mkfifo")
            .arg(path)
            .status()
            .unwrap();
        assert!(made.success());
    };
    fifo(&d.join("pipe.json"));
    for (detections, why) in [("pipe.json", "FIFO"), ("/dev/zero", "device")] {
        if !Path::new(detections).is_absolute() || Path::new(detections).exists() {
            refused(d, &["eval", "score", "set", detections], &[detections, why]);
            refused(
                d,
                &["eval", "compare", "set", "d.json", detections],
                &[detections, why],
            );
        }
    }
    // A FIFO in place of set.json.
    std::fs::rename(d.join("set/set.json"), d.join("set.json.kept")).unwrap();
    fifo(&d.join("set/set.json"));
    for args in [
        vec!["eval", "score", "set", "d.json"],
        vec!["eval", "oracle", "set", "-o", "o.json"],
        vec!["detect-set", "set", "-o", "o.json"],
    ] {
        refused(d, &args, &["set.json", "FIFO"]);
    }
    // And a folder.
    std::fs::remove_file(d.join("set/set.json")).unwrap();
    std::fs::create_dir(d.join("set/set.json")).unwrap();
    refused(
        d,
        &["eval", "score", "set", "d.json"],
        &["set.json", "folder"],
    );
}

/// A scenario file is checked before anything renders: a value out of range names the file and
/// the field, a family without weights is named, and nothing is written.
#[test]
fn a_bad_scenario_or_a_design_without_weights_is_refused_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    tagsmith(d, &["eval", "scenario", "-o", "scene.json"]).ok();
    let mut scene: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("scene.json")).unwrap()).unwrap();
    let designs = ["apriltag-36h11", "apriltag-xo-36h11"];
    let compare = |file: &str, families: &[&str]| -> Vec<String> {
        let mut args = vec!["eval".to_string(), "compare-designs".into(), file.into()];
        args.extend(families.iter().map(|f| f.to_string()));
        args.extend(["-o".into(), "out".into()]);
        args
    };
    let run = |args: &[String], names: &[&str]| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        refused(d, &args, names);
        assert!(!d.join("out").exists(), "{args:?} wrote its output folder");
    };
    scene["distance_m"] = json!([2.0, 1.0]);
    std::fs::write(d.join("far.json"), scene.to_string()).unwrap();
    run(&compare("far.json", &designs), &["far.json", "distance_m"]);
    let generate = [
        "eval",
        "generate",
        "apriltag-36h11",
        "--scenario",
        "far.json",
        "-o",
        "out",
    ];
    run(&generate.map(String::from), &["far.json", "distance_m"]);
    scene["distance_m"] = json!([0.3, 0.3]);
    scene["sweeps"][0]["condition"] = json!("zoom");
    std::fs::write(d.join("zoom.json"), scene.to_string()).unwrap();
    run(
        &compare("zoom.json", &designs),
        &["zoom.json", "sweeps[0].condition"],
    );
    run(
        &compare("scene.json", &["apriltag-36h11", "runetag-plus"]),
        &["runetag-plus", "no weights"],
    );
    run(&compare("scene.json", &["apriltag-36h11"]), &["FAMILIES"]);
}

/// `eval generate --scenario` renders the scenario's scenes as a set, which scores per swept
/// value like the protocol's subsets.
#[test]
fn a_scenario_renders_as_a_set_scored_per_swept_value() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    tagsmith(d, &["eval", "scenario", "-o", "scene.json"]).ok();
    let mut scene: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("scene.json")).unwrap()).unwrap();
    scene["camera"] = json!({"width": 320, "height": 240, "fov_deg": 70.0});
    scene["sweeps"] = json!([{"condition": "noise", "values": [0.0, 40.0]}]);
    scene["scenes"] = json!(3);
    std::fs::write(d.join("scene.json"), scene.to_string()).unwrap();
    let args = [
        "eval",
        "generate",
        "apriltag-36h11",
        "--scenario",
        "scene.json",
        "-o",
        "set",
    ];
    tagsmith(d, &args).ok();
    let set: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("set/set.json")).unwrap()).unwrap();
    let images = set["images"].as_array().unwrap();
    assert_eq!(images.len(), 6);
    assert_eq!(
        images[5]["group"],
        json!({"kind": "scenario", "condition": "noise", "value": 40.0})
    );
    assert_eq!(set["camera"]["width"], 320);
    tagsmith(d, &["eval", "oracle", "set", "-o", "truth.json"]).ok();
    let scored = tagsmith(d, &["eval", "score", "set", "truth.json", "-o", "report"]);
    scored.ok();
    assert!(
        scored.stdout.contains("| scenario | 6 | 6 | 100.0 %"),
        "{}",
        scored.stdout
    );
    assert!(
        scored.stdout.contains("recall and error vs noise"),
        "{}",
        scored.stdout
    );
}
