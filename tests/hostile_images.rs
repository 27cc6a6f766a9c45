//! End-to-end: images of any size and batches with bad members — no panic, per-image errors in
//! the detections file, outputs that never replace inputs, and bad ROIs, cameras and sizes refused
//! as bad input (exit 2) naming the option or file.

mod common;
use common::*;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// A gray PNG of `width` × `height`.
fn gray_png(path: &Path, width: u32, height: u32) {
    let file = std::fs::File::create(path).unwrap();
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().unwrap();
    let pixels: Vec<u8> = (0..width as usize * height as usize)
        .map(|i| (i * 37 % 251) as u8)
        .collect();
    writer.write_image_data(&pixels).unwrap();
}

fn sample() -> PathBuf {
    workspace().join("assets/samples/apriltag-36h11-swarmathon.jpg")
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// Images shorter than the network's receptive field used to panic in stage 1 (`clamp` with
/// min > max), and one such image in a batch cost every other image its result.
#[test]
fn images_of_any_size_are_detected_without_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let sizes = [
        (1, 1),
        (2, 2),
        (200, 79),
        (79, 200),
        (100_000, 1),
        (1, 50_000),
    ];
    let mut args = vec![
        "detect".to_string(),
        "--family".into(),
        "apriltag-36h11".into(),
    ];
    for (w, h) in sizes {
        let name = format!("{w}x{h}.png");
        gray_png(&dir.path().join(&name), w, h);
        args.push(name);
    }
    args.push(sample().to_str().unwrap().into());
    args.extend(["--json".into(), "found.json".into()]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let run = tagsmith_within(dir.path(), &args, Duration::from_secs(120));
    run.ok();
    assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    let found = json(&dir.path().join("found.json"));
    let images = found["images"].as_array().unwrap();
    assert_eq!(images.len(), sizes.len() + 1);
    let photo = images.last().unwrap();
    assert!(
        photo["detections"].as_array().unwrap().len() >= 10,
        "{photo}"
    );
}

/// A bad image in a batch is listed with its error in the detections file; the others keep
/// their detections, and the exit code says that some failed.
#[test]
fn a_batch_reports_each_failed_image_and_keeps_the_others() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("broken.png"), b"\x89PNG\r\n\x1a\nnothing").unwrap();
    let photo = sample();
    let run = tagsmith(
        dir.path(),
        &[
            "detect",
            "--family",
            "apriltag-36h11",
            "broken.png",
            photo.to_str().unwrap(),
            "missing.jpg",
            "--json",
            "found.json",
        ],
    );
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(
        run.stderr.contains("2 of 3 image(s) failed"),
        "{}",
        run.stderr
    );
    let found = json(&dir.path().join("found.json"));
    assert_eq!(found["images"].as_array().unwrap().len(), 1);
    let failed = found["failed"].as_array().unwrap();
    let files: Vec<&str> = failed.iter().map(|f| f["file"].as_str().unwrap()).collect();
    assert_eq!(files, ["broken.png", "missing.jpg"]);
    assert!(failed.iter().all(|f| f["exit_code"] == 2), "{failed:?}");
    assert!(failed[0]["error"].as_str().unwrap().contains("broken.png"));
}

#[test]
fn outputs_never_replace_the_runs_own_images() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("a")).unwrap();
    std::fs::copy(sample(), dir.path().join("v.jpg")).unwrap();
    let original = std::fs::read(dir.path().join("v.jpg")).unwrap();
    let args = ["detect", "v.jpg", "--family", "apriltag-36h11"];
    // The detections file given as the photograph itself, or through a second spelling.
    for json in ["v.jpg", "./v.jpg", "a/../v.jpg"] {
        let run = tagsmith(dir.path(), &[&args[..], &["--json", json]].concat());
        assert_eq!(run.code, 2, "{json}: {}", run.stderr);
        assert!(run.stderr.contains("--json"), "{}", run.stderr);
    }
    assert_eq!(std::fs::read(dir.path().join("v.jpg")).unwrap(), original);

    // An annotation folder that holds the input: its annotation takes another name.
    gray_png(&dir.path().join("a/x.png"), 64, 48);
    let input = std::fs::read(dir.path().join("a/x.png")).unwrap();
    tagsmith(
        dir.path(),
        &[
            "detect",
            "a/x.png",
            "--family",
            "apriltag-36h11",
            "--annotate",
            "a",
        ],
    )
    .ok();
    assert_eq!(std::fs::read(dir.path().join("a/x.png")).unwrap(), input);
    assert!(dir.path().join("a/x-2.png").is_file());
}

/// Two inputs of one name in different folders get an annotation each.
#[test]
fn annotations_of_images_with_one_name_do_not_collide() {
    let dir = tempfile::tempdir().unwrap();
    for sub in ["left", "right"] {
        std::fs::create_dir(dir.path().join(sub)).unwrap();
    }
    std::fs::copy(sample(), dir.path().join("left/x.jpg")).unwrap();
    gray_png(&dir.path().join("right/x.png"), 80, 60);
    let run = tagsmith(
        dir.path(),
        &[
            "detect",
            "left/x.jpg",
            "right/x.png",
            "--family",
            "apriltag-36h11",
            "--annotate",
            "out",
            "--json",
            "found.json",
        ],
    );
    run.ok();
    let (first, second) = (dir.path().join("out/x.png"), dir.path().join("out/x-2.png"));
    assert!(first.is_file() && second.is_file());
    // The photograph's annotation is the larger one: the order follows the command line.
    assert!(std::fs::metadata(&first).unwrap().len() > std::fs::metadata(&second).unwrap().len());
    let found = json(&dir.path().join("found.json"));
    let files: Vec<&str> = (found["images"].as_array().unwrap().iter())
        .map(|i| i["file"].as_str().unwrap())
        .collect();
    assert_eq!(files, ["left/x.jpg", "right/x.png"]);
}

/// Two file names that differ only in bytes that are not UTF-8 stay two names in the detections
/// file and two annotations.
#[cfg(target_os = "linux")]
#[test]
fn names_that_are_not_utf8_stay_apart() {
    use std::ffi::OsStr;
    use std::os::unix::ffi::OsStrExt;
    let dir = tempfile::tempdir().unwrap();
    let names = [
        OsStr::from_bytes(b"\xff.png"),
        OsStr::from_bytes(b"\xfe.png"),
    ];
    for name in names {
        gray_png(&dir.path().join(name), 40, 30);
    }
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_tagsmith"))
        .current_dir(dir.path())
        .args(["detect", "--family", "apriltag-36h11", "--annotate", "out"])
        .args(names)
        .args(["--json", "found.json"])
        .output()
        .unwrap();
    assert!(status.status.success(), "{status:?}");
    let found = json(&dir.path().join("found.json"));
    let files: Vec<&str> = (found["images"].as_array().unwrap().iter())
        .map(|i| i["file"].as_str().unwrap())
        .collect();
    assert_eq!(files, ["\\xFF.png", "\\xFE.png"]);
    assert_eq!(
        std::fs::read_dir(dir.path().join("out")).unwrap().count(),
        2
    );
}

#[test]
fn outputs_of_the_wrong_kind_are_bad_input_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("note.txt"), b"keep me").unwrap();
    std::fs::create_dir(dir.path().join("folder")).unwrap();
    let photo = sample();
    let photo = photo.to_str().unwrap();
    for (option, path) in [("--annotate", "note.txt"), ("--json", "folder")] {
        refused(
            dir.path(),
            &["detect", photo, "--family", "apriltag-36h11", option, path],
            &[option],
        );
    }
    assert_eq!(
        std::fs::read(dir.path().join("note.txt")).unwrap(),
        b"keep me"
    );
}

/// Degenerate ROIs are the user's input (exit 2, `--roi` named), and subnormal coordinates no
/// longer spin in the homography's solver.
#[test]
fn degenerate_rois_are_refused_quickly() {
    let dir = tempfile::tempdir().unwrap();
    let photo = sample();
    for roi in [
        "0,0,5e-324,0,5e-324,5e-324,0,5e-324",
        "10,10,20,20,30,30,40,40",
        "10,10,50,50,50,10,10,50",
        "10,10,10,10,10,10,10,10",
    ] {
        refused(
            dir.path(),
            &[
                "detect",
                photo.to_str().unwrap(),
                "--family",
                "apriltag-36h11",
                &format!("--roi={roi}"),
            ],
            &["--roi"],
        );
    }
}

#[test]
fn a_camera_for_another_image_size_or_an_infinite_side_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let photo = sample();
    let photo = photo.to_str().unwrap();
    std::fs::write(
        dir.path().join("camera.json"),
        r#"{"width": 1280, "height": 960, "fx": 900, "fy": 900, "cx": 640, "cy": 480}"#,
    )
    .unwrap();
    refused(
        dir.path(),
        &[
            "detect",
            photo,
            "--family",
            "apriltag-36h11",
            "--camera",
            "camera.json",
        ],
        &["camera.json", "width"],
    );
    // A camera file that is no camera at all is said once, not once per image.
    std::fs::write(dir.path().join("bad.json"), b"{\"fx\": 1}").unwrap();
    let run = refused(
        dir.path(),
        &[
            "detect",
            photo,
            photo,
            "--family",
            "apriltag-36h11",
            "--camera",
            "bad.json",
        ],
        &[],
    );
    assert_eq!(run.stderr.matches("bad.json").count(), 1, "{}", run.stderr);
    assert!(!run.stderr.contains("could not be read"), "{}", run.stderr);

    refused(
        dir.path(),
        &[
            "detect",
            photo,
            "--family",
            "apriltag-36h11",
            "--side-mm",
            "inf",
        ],
        &["--side-mm"],
    );
}

/// `--upsample` counts the doubled image against `--max-pixels`, and `--max-pixels` has a
/// ceiling, so that neither reaches the allocator's abort.
#[test]
fn upsampling_and_the_pixel_limit_are_bounded() {
    let dir = tempfile::tempdir().unwrap();
    gray_png(&dir.path().join("wide.png"), 2000, 1000);
    refused(
        dir.path(),
        &[
            "detect",
            "wide.png",
            "--family",
            "apriltag-36h11",
            "--upsample",
            "--max-pixels",
            "4000000",
        ],
        &["--upsample"],
    );
    refused(
        dir.path(),
        &["detect", "wide.png", "--max-pixels", "100000000000"],
        &["--max-pixels"],
    );
}
