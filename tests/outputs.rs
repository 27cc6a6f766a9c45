//! End-to-end: what commands do to the paths given as outputs. A symlink stays a symlink, a
//! device or pipe is written through and never replaced, and a damaged training checkpoint is bad
//! input.

mod common;
use common::*;

#[cfg(unix)]
#[test]
fn a_symlink_given_as_output_is_still_a_symlink_afterwards() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("real")).unwrap();
    std::os::unix::fs::symlink("real/marker.svg", dir.path().join("marker.svg")).unwrap();
    tagsmith(
        dir.path(),
        &["render", "apriltag-36h11", "--id", "3", "-o", "marker.svg"],
    )
    .ok();
    let link = dir.path().join("marker.svg");
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    let svg = std::fs::read_to_string(dir.path().join("real/marker.svg")).unwrap();
    assert!(
        svg.starts_with("<svg") || svg.starts_with("<?xml"),
        "{svg:.80}"
    );
}

#[cfg(unix)]
#[test]
fn a_device_given_as_output_is_written_through_not_replaced() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tempfile::tempdir().unwrap();
    let photo = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/samples/apriltag-36h11-swarmathon.jpg");
    let detect = |annotate: &str| {
        tagsmith(
            dir.path(),
            &[
                "detect",
                photo.to_str().unwrap(),
                "--family",
                "apriltag-36h11",
                "--roi",
                "329.95,442.66,286.03,446.36,285.24,402.35,328.57,398.87",
                "--annotate",
                annotate,
            ],
        )
    };
    let null = std::path::Path::new("/dev/null");
    if null.exists() {
        detect("/dev/null").ok();
        assert!(std::fs::metadata(null)
            .unwrap()
            .file_type()
            .is_char_device());
    }
    let full = std::path::Path::new("/dev/full");
    if full.exists() {
        let run = detect("/dev/full");
        assert_eq!(run.code, 1, "{}", run.stderr);
        assert!(run.stderr.contains("/dev/full"), "{}", run.stderr);
        assert!(std::fs::metadata(full)
            .unwrap()
            .file_type()
            .is_char_device());
    }
}

#[test]
fn a_damaged_checkpoint_is_bad_input_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "train",
        "apriltag-16h5",
        "--stage",
        "keypoints",
        "--steps",
        "2",
        "--batch",
        "2",
        "--width",
        "8",
        "--checkpoint-every",
        "2",
        "--validate-every",
        "2",
        "--validation-patches",
        "2",
        "--out",
        "run",
    ];
    tagsmith(dir.path(), &args).ok();
    let checkpoint = dir.path().join("run/checkpoint.bin");
    let mut bytes = std::fs::read(&checkpoint).unwrap();
    bytes.extend_from_slice(b"trailing garbage");
    std::fs::write(&checkpoint, bytes).unwrap();
    let mut resume = args.to_vec();
    resume.push("--resume");
    let run = tagsmith(dir.path(), &resume);
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(run.stderr.contains("checkpoint.bin"), "{}", run.stderr);
}

/// An output folder that names an existing file (or lies under one) is the user's mistake:
/// exit 2 naming the option, and the file is left as it was.
#[test]
fn an_output_folder_that_is_a_file_is_bad_input_naming_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("taken"), "mine").unwrap();
    for args in [
        vec!["synth", "apriltag-16h5", "-n", "1", "-o", "taken"],
        vec!["synth", "apriltag-16h5", "-n", "1", "-o", "taken/sub"],
        vec!["eval", "generate", "apriltag-16h5", "-o", "taken"],
        vec!["eval", "generate", "apriltag-16h5", "-o", "taken/sub"],
    ] {
        let run = tagsmith(d, &args);
        assert_eq!(run.code, 2, "{args:?}: {}", run.stderr);
        assert!(
            run.stderr.contains("--output") && run.stderr.contains("taken"),
            "{args:?}: {}",
            run.stderr
        );
        assert!(run.stderr.contains("not a folder"), "{}", run.stderr);
    }
    assert_eq!(std::fs::read_to_string(d.join("taken")).unwrap(), "mine");
}
