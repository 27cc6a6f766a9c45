//! End-to-end: the `tagsmith` command line, run as a user runs it.

mod common;
use common::*;

#[test]
fn every_command_has_help() {
    let dir = tempfile::tempdir().unwrap();
    for cmd in [
        vec!["--help"],
        vec!["families", "--help"],
        vec!["render", "--help"],
        vec!["sheet", "--help"],
        vec!["codebook", "--help"],
        vec!["codebook", "stats", "--help"],
        vec!["codebook", "generate", "--help"],
        vec!["validate", "--help"],
        vec!["export-opencv", "--help"],
        vec!["schema", "--help"],
    ] {
        let run = tagsmith(dir.path(), &cmd);
        run.ok();
        assert!(run.stdout.contains("Usage: tagsmith"), "{cmd:?}");
    }
}

#[test]
fn families_lists_every_builtin_with_stats() {
    let dir = tempfile::tempdir().unwrap();
    let run = tagsmith(dir.path(), &["families"]);
    run.ok();
    assert_eq!(run.stdout.lines().count(), 17, "{}", run.stdout);
    let cols = |name: &str| -> Vec<String> {
        let line = (run.stdout.lines())
            .find(|l| l.starts_with(&format!("{name} ")))
            .unwrap();
        line.split_whitespace().map(String::from).collect()
    };
    assert_eq!(
        &cols("apriltag-36h11")[1..7],
        ["grid", "64", "2", "587", "11", "default"]
    );
    // Which detect: by default, when named (shipped weights), or once trained.
    assert_eq!(cols("artoolkitplus-bch")[4..7], ["4096", "2", "named"]);
    assert_eq!(cols("aruco-mip-36h12")[6], "named");
    assert_eq!(cols("topotag-like")[6], "named");
    assert_eq!(cols("apriltag-standard41h12")[6], "named");
    assert_eq!(cols("apriltag-circle21h7")[6], "named");
    assert_eq!(cols("runetag")[6], "named");
    assert_eq!(cols("runetag-plus")[6], "train");
}

#[test]
fn render_svg_has_the_requested_physical_size() {
    let dir = tempfile::tempdir().unwrap();
    tagsmith(
        dir.path(),
        &[
            "render",
            "aruco-6x6_250",
            "--id",
            "23",
            "--size-mm",
            "37.5",
            "-o",
            "m.svg",
        ],
    )
    .ok();
    let svg = std::fs::read_to_string(dir.path().join("m.svg")).unwrap();
    // 8 cells of 37.5/8 mm plus one quiet-zone cell on each side.
    assert!(svg.contains("width=\"46.875mm\""), "{svg}");
    let black = black_paths_after(&svg, "<g class=\"marker\"");
    assert_eq!(
        black.len(),
        1,
        "cells of one colour are merged into one path"
    );
    let b = bbox(black[0]);
    assert!(
        (b[2] - b[0] - 37.5).abs() < 0.01 && (b[3] - b[1] - 37.5).abs() < 0.01,
        "{b:?}"
    );
}

#[test]
fn render_png_at_the_requested_width_and_reject_bad_requests() {
    let dir = tempfile::tempdir().unwrap();
    tagsmith(
        dir.path(),
        &[
            "render",
            "runetag-plus",
            "--id",
            "7",
            "--px",
            "321",
            "-o",
            "m.png",
        ],
    )
    .ok();
    let png = std::fs::read(dir.path().join("m.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    assert_eq!(u32::from_be_bytes(png[16..20].try_into().unwrap()), 321);

    let run = tagsmith(
        dir.path(),
        &["render", "apriltag-16h5", "--id", "30", "-o", "x.svg"],
    );
    assert_eq!(run.code, 2);
    assert!(
        run.stderr
            .contains("ID 30 does not exist: apriltag-16h5 has IDs 0 to 29"),
        "{}",
        run.stderr
    );
    assert!(!dir.path().join("x.svg").exists());

    let run = tagsmith(
        dir.path(),
        &["render", "no-such-family", "--id", "0", "-o", "x.svg"],
    );
    assert_eq!(run.code, 2);
    assert!(
        run.stderr.contains("built-in families: apriltag-16h5"),
        "{}",
        run.stderr
    );
}

#[test]
fn a_bad_family_file_is_rejected_naming_file_and_field_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(workspace().join("families/apriltag-16h5.json")).unwrap();
    let bad = good.replace("\"b\": \"black\"", "\"b\": \"blakc\"");
    std::fs::write(dir.path().join("mine.json"), bad).unwrap();
    std::fs::write(dir.path().join("out.svg"), "previous content").unwrap();

    let run = tagsmith(dir.path(), &["validate", "mine.json"]);
    assert_eq!(run.code, 2);
    assert!(
        run.stderr
            .contains("mine.json: layout.legend.b: unknown category \"blakc\""),
        "{}",
        run.stderr
    );

    let run = tagsmith(
        dir.path(),
        &["render", "mine.json", "--id", "0", "-o", "out.svg"],
    );
    assert_eq!(run.code, 2);
    assert_eq!(
        std::fs::read_to_string(dir.path().join("out.svg")).unwrap(),
        "previous content"
    );

    std::fs::write(dir.path().join("ok.json"), good).unwrap();
    let run = tagsmith(dir.path(), &["validate", "ok.json"]);
    run.ok();
    assert!(
        run.stdout.contains("valid — 36 keypoints"),
        "{}",
        run.stdout
    );
}

#[test]
fn an_unwritable_output_fails_without_leaving_a_partial_file() {
    let dir = tempfile::tempdir().unwrap();
    let run = tagsmith(
        dir.path(),
        &[
            "render",
            "apriltag-36h11",
            "--id",
            "1",
            "-o",
            "missing/dir/out.svg",
        ],
    );
    assert_eq!(run.code, 1);
    assert!(
        run.stderr.contains("cannot write missing/dir/out.svg"),
        "{}",
        run.stderr
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn codebook_stats_computes_distance_and_correction_limit() {
    let dir = tempfile::tempdir().unwrap();
    let run = tagsmith(dir.path(), &["codebook", "stats", "apriltag-36h11"]);
    run.ok();
    for expected in [
        "codes:             587",
        "code length:       36",
        "q (symbols):       2",
        "minimum distance:  11 (computed)",
        "correction limit:  5",
    ] {
        assert!(
            run.stdout.contains(expected),
            "{expected:?} in {}",
            run.stdout
        );
    }
    let run = tagsmith(dir.path(), &["codebook", "stats", "quaternary-6x6"]);
    run.ok();
    assert!(
        run.stdout.contains("q (symbols):       4") && run.stdout.contains("minimum distance:  14"),
        "{}",
        run.stdout
    );
}

#[test]
fn codebook_generate_writes_a_valid_family_that_is_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "codebook",
        "generate",
        "aruco-5x5_100",
        "--min-distance",
        "7",
        "--count",
        "40",
        "--seed",
        "4",
        "--max-candidates",
        "2000000",
        "--name",
        "my-5x5",
    ];
    let mut a = args.to_vec();
    a.extend(["-o", "a.json"]);
    let run = tagsmith(dir.path(), &a);
    run.ok();
    assert!(run.stdout.contains("40 codes"), "{}", run.stdout);
    let mut b = args.to_vec();
    b.extend(["-o", "b.json"]);
    tagsmith(dir.path(), &b).ok();
    let (fa, fb) = (
        std::fs::read(dir.path().join("a.json")).unwrap(),
        std::fs::read(dir.path().join("b.json")).unwrap(),
    );
    assert_eq!(fa, fb);
    let run = tagsmith(dir.path(), &["validate", "a.json"]);
    run.ok();
    let family = tagsmith::family::load_file(&dir.path().join("a.json")).unwrap();
    assert_eq!(family.name(), "my-5x5");
    assert!(family.spec().codebook.min_distance.unwrap() >= 7);
    // It prints like any family.
    tagsmith(
        dir.path(),
        &["render", "a.json", "--id", "39", "-o", "m.svg"],
    )
    .ok();
}

#[test]
fn export_opencv_writes_a_readable_dictionary() {
    let dir = tempfile::tempdir().unwrap();
    tagsmith(
        dir.path(),
        &["export-opencv", "apriltag-36h11", "-o", "dict.yml"],
    )
    .ok();
    let yml = std::fs::read_to_string(dir.path().join("dict.yml")).unwrap();
    let lines: Vec<&str> = yml.lines().collect();
    assert_eq!(
        &lines[..5],
        [
            "%YAML:1.0",
            "---",
            "nmarkers: 587",
            "markersize: 6",
            "maxCorrectionBits: 5"
        ]
    );
    assert_eq!(lines.len(), 5 + 587);
    let family = tagsmith::builtin::get("apriltag-36h11").unwrap().unwrap();
    for (id, line) in lines[5..].iter().enumerate() {
        let bits: String = family
            .codebook()
            .code(id)
            .unwrap()
            .iter()
            .map(|b| char::from(b'0' + b))
            .collect();
        assert_eq!(*line, format!("marker_{id}: \"{bits}\""));
    }
    // OpenCV reads black and white cells only.
    for family in ["apriltag-xo-36h11", "runetag", "quaternary-6x6"] {
        let run = tagsmith(dir.path(), &["export-opencv", family, "-o", "no.yml"]);
        assert_eq!(run.code, 2, "{family}");
        assert!(
            run.stderr.contains("cannot be read by OpenCV"),
            "{}",
            run.stderr
        );
    }
    assert!(!dir.path().join("no.yml").exists());
}

#[test]
fn schema_command_prints_the_committed_schema() {
    let dir = tempfile::tempdir().unwrap();
    let run = tagsmith(dir.path(), &["schema"]);
    run.ok();
    assert_eq!(
        run.stdout,
        std::fs::read_to_string(workspace().join("families/schema.json")).unwrap()
    );
}

#[test]
fn without_a_display_the_studio_says_to_use_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tagsmith"))
        .current_dir(dir.path())
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("WAYLAND_SOCKET")
        // Keep the studio's persistence out of the user's real data folder.
        .env("XDG_DATA_HOME", dir.path())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("studio window could not open") && stderr.contains("tagsmith --help"),
        "{stderr}"
    );
}

#[test]
fn synth_writes_images_ground_truth_and_a_contact_sheet_reproducibly() {
    let dir = tempfile::tempdir().unwrap();
    for out in ["a", "b"] {
        tagsmith(
            dir.path(),
            &[
                "synth",
                "apriltag-16h5",
                "-n",
                "5",
                "--mode",
                "patch",
                "--seed",
                "9",
                "-o",
                out,
            ],
        )
        .ok();
    }
    for i in 0..5 {
        let name = format!("{i:06}");
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        assert_eq!(
            std::fs::read(a.join(format!("{name}.png"))).unwrap(),
            std::fs::read(b.join(format!("{name}.png"))).unwrap()
        );
        let truth: serde_json::Value =
            serde_json::from_slice(&std::fs::read(a.join(format!("{name}.json"))).unwrap())
                .unwrap();
        assert_eq!(truth["family"], "apriltag-16h5");
        assert_eq!(truth["width"], 128);
        let kps = truth["markers"][0]["keypoints"].as_array().unwrap();
        assert_eq!(kps.len(), 36);
        assert!(kps.iter().all(|k| k["visible"] == true));
    }
    assert!(dir.path().join("a/contact.png").exists());
    let run = tagsmith(
        dir.path(),
        &["synth", "apriltag-16h5", "-n", "0", "-o", "c"],
    );
    assert_eq!(run.code, 2);
}
