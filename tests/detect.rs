//! End-to-end: `tagsmith detect` with the shipped weights, its errors, and a short `tagsmith train`.

mod common;
use common::*;

/// A camera image of one marker and its ground truth, from `tagsmith synth`.
fn scene(dir: &std::path::Path) -> serde_json::Value {
    tagsmith(
        dir,
        &[
            "synth",
            "apriltag-36h11",
            "-n",
            "1",
            "--mode",
            "camera",
            "--seed",
            "4",
            "-o",
            "s",
        ],
    )
    .ok();
    serde_json::from_slice(&std::fs::read(dir.join("s/000000.json")).unwrap()).unwrap()
}

fn roi_arg(truth: &serde_json::Value) -> String {
    truth["markers"][0]["roi"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|p| [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()])
        .map(|v| format!("{v:.2}"))
        .collect::<Vec<_>>()
        .join(",")
}

#[test]
fn the_learned_detector_commands_have_help() {
    let dir = tempfile::tempdir().unwrap();
    for cmd in ["train", "detect", "detect-set"] {
        let run = tagsmith(dir.path(), &[cmd, "--help"]);
        run.ok();
        assert!(run.stdout.contains("Usage: tagsmith"), "{cmd}");
    }
}

#[test]
fn detect_prints_the_id_keypoints_and_pose_and_annotates() {
    let dir = tempfile::tempdir().unwrap();
    let truth = scene(dir.path());
    let roi = roi_arg(&truth);
    let run = tagsmith(
        dir.path(),
        &[
            "detect",
            "s/000000.png",
            "--family",
            "apriltag-36h11",
            "--roi",
            &roi,
            "--annotate",
            "a.png",
        ],
    );
    run.ok();
    let out: serde_json::Value = serde_json::from_str(&run.stdout).unwrap();
    assert_eq!(out["decoded"], true);
    assert_eq!(out["id"], truth["markers"][0]["id"]);
    assert!(
        out["keypoints"].as_array().unwrap().len() >= 56,
        "{}",
        run.stdout
    );
    assert!(out["pose"]["translation_m"][2].as_f64().unwrap() > 0.0);
    assert!(std::fs::read(dir.path().join("a.png"))
        .unwrap()
        .starts_with(b"\x89PNG"));
}

#[test]
fn detect_rejects_bad_rois_and_models_with_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let truth = scene(dir.path());
    let roi = roi_arg(&truth);
    let img = "s/000000.png";

    let run = tagsmith(
        dir.path(),
        &[
            "detect",
            img,
            "--family",
            "apriltag-36h11",
            "--roi",
            "1,2,3",
        ],
    );
    assert_eq!(run.code, 2);
    assert!(
        run.stderr.contains("--roi") && run.stderr.contains("8 finite numbers"),
        "{}",
        run.stderr
    );

    std::fs::write(dir.path().join("junk.bin"), b"not a model").unwrap();
    let run = tagsmith(
        dir.path(),
        &[
            "detect",
            img,
            "--family",
            "apriltag-36h11",
            "--roi",
            &roi,
            "--model",
            "junk.bin",
        ],
    );
    assert_eq!(run.code, 2);
    assert!(
        run.stderr
            .contains("junk.bin: not a Tagsmith stage-2 model"),
        "{}",
        run.stderr
    );

    let run = tagsmith(
        dir.path(),
        &["detect", img, "--family", "aruco-4x4_50", "--roi", &roi],
    );
    assert_eq!(run.code, 2);
    assert!(
        run.stderr
            .contains("no weights are shipped for family \"aruco-4x4_50\""),
        "{}",
        run.stderr
    );
}

#[test]
fn train_writes_a_model_that_loads_for_its_family_only() {
    let dir = tempfile::tempdir().unwrap();
    let run = tagsmith(
        dir.path(),
        &[
            "train",
            "apriltag-16h5",
            "--stage",
            "keypoints",
            "--steps",
            "3",
            "--batch",
            "2",
            "--width",
            "8",
            "--validate-every",
            "3",
            "--validation-patches",
            "2",
            "--out",
            "r",
        ],
    );
    run.ok();
    assert!(run.stdout.contains("3 steps"), "{}", run.stdout);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("r/report.json")).unwrap()).unwrap();
    assert_eq!(report["steps"], 3);
    assert_eq!(report["family"], "apriltag-16h5");

    let truth = scene(dir.path());
    let roi = roi_arg(&truth);
    let run = tagsmith(
        dir.path(),
        &[
            "detect",
            "s/000000.png",
            "--family",
            "apriltag-36h11",
            "--roi",
            &roi,
            "--model",
            "r/model.bin",
        ],
    );
    assert_eq!(run.code, 2);
    assert!(
        run.stderr
            .contains("trained for family \"apriltag-16h5\", not \"apriltag-36h11\""),
        "{}",
        run.stderr
    );

    let run = tagsmith(
        dir.path(),
        &[
            "train",
            "apriltag-16h5",
            "--stage",
            "keypoints",
            "--steps",
            "0",
            "--out",
            "r",
        ],
    );
    assert_eq!(run.code, 2);
}

/// `kill -9` in the middle of training loses at most one checkpoint interval: `--resume` goes on
/// from the last checkpoint.
#[test]
fn training_resumes_after_kill_9() {
    let dir = tempfile::tempdir().unwrap();
    let args = |steps: &str| -> Vec<String> {
        [
            "train",
            "apriltag-16h5",
            "--stage",
            "keypoints",
            "--steps",
            steps,
            "--batch",
            "2",
            "--width",
            "8",
            "--checkpoint-every",
            "5",
            "--validate-every",
            "1000",
            "--validation-patches",
            "2",
            "--out",
            "r",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    };
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_tagsmith"))
        .args(args("100000"))
        .current_dir(dir.path())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let checkpoint = dir.path().join("r/checkpoint.bin");
    let start = std::time::Instant::now();
    while !checkpoint.exists() {
        assert!(start.elapsed().as_secs() < 120, "no checkpoint written");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let steps = "60";
    let run = tagsmith(
        dir.path(),
        &[
            args(steps).iter().map(String::as_str).collect::<Vec<_>>(),
            vec!["--resume"],
        ]
        .concat(),
    );
    run.ok();
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("r/report.json")).unwrap()).unwrap();
    let from = report["resumed_from"].as_u64().expect("resumed");
    assert!(
        from >= 5 && from.is_multiple_of(5) && from <= 60,
        "resumed from {from}"
    );
    assert_eq!(report["steps"], 60);
}
