//! End-to-end: `tagsmith detect` on whole images — stage 1 finds the markers, stage 2 of each
//! requested family reads them — with the shipped weights.

mod common;
use common::*;
use tagsmith::synth::augment::AugmentRanges;
use tagsmith::synth::{synthesize_mixed, Mode, SynthConfig};

fn family(name: &str) -> tagsmith::family::Family {
    tagsmith::builtin::get(name).unwrap().unwrap()
}

/// A 960×720 camera image of three 80-mm markers, two AprilTag 36h11 and one ArUco 6×6, with
/// light blur and noise; returns its truth.
fn mixed_scene(dir: &std::path::Path) -> tagsmith::synth::Truth {
    let (a, b) = (family("apriltag-36h11"), family("aruco-6x6_250"));
    let mut config = SynthConfig::new(Mode::Camera);
    config.width = 960;
    config.height = 720;
    config.markers = [3, 3];
    config.side_m = [0.08, 0.08];
    config.distance_m = [0.35, 0.6];
    config.view_angle_deg = [0.0, 45.0];
    let mut augment = AugmentRanges::none();
    augment.marker_black = [20.0, 40.0];
    augment.marker_white = [200.0, 230.0];
    augment.blur_sigma = [0.6, 0.6];
    augment.noise_sigma = [3.0, 3.0];
    config.augment = augment;
    let sample = synthesize_mixed(&[&a, &b], &config, 11).unwrap();
    assert_eq!(
        sample.truth.markers.len(),
        3,
        "the scene holds three markers"
    );
    let png = tagsmith::image::encode_png(&sample.image).unwrap();
    std::fs::write(dir.join("scene.png"), png).unwrap();
    let camera = serde_json::to_string(sample.truth.camera.as_ref().unwrap()).unwrap();
    std::fs::write(dir.join("camera.json"), camera).unwrap();
    sample.truth
}

#[test]
fn the_shipped_detector_finds_three_markers_of_two_families_with_ids_corners_and_poses() {
    let dir = tempfile::tempdir().unwrap();
    let truth = mixed_scene(dir.path());
    let run = tagsmith(
        dir.path(),
        &[
            "detect",
            "scene.png",
            "--family",
            "apriltag-36h11",
            "--family",
            "aruco-6x6_250",
            "--camera",
            "camera.json",
            "--side-mm",
            "80",
            "--json",
            "out.json",
        ],
    );
    run.ok();
    assert!(
        run.stdout.contains("scene.png: 3 markers"),
        "{}",
        run.stdout
    );
    let out: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("out.json")).unwrap()).unwrap();
    let found = out["images"][0]["detections"].as_array().unwrap();
    assert_eq!(found.len(), 3, "{found:#?}");
    for m in &truth.markers {
        let name = m.family.as_deref().unwrap();
        let d = found
            .iter()
            .find(|d| d["family"] == name && d["id"] == m.id)
            .unwrap_or_else(|| panic!("{name} #{} not found", m.id));
        for (c, t) in d["corners"].as_array().unwrap().iter().zip(&m.roi) {
            let e = (c[0].as_f64().unwrap() - t[0]).hypot(c[1].as_f64().unwrap() - t[1]);
            assert!(e < 1.5, "{name} #{}: corner off by {e:.2} px", m.id);
        }
        let pose = &d["pose"];
        let want = &m.pose.as_ref().unwrap().pose;
        let t: Vec<f64> = (0..3)
            .map(|i| pose["translation_m"][i].as_f64().unwrap())
            .collect();
        let dist = (0..3)
            .map(|i| (t[i] - want.translation_m[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            dist < 0.003,
            "{name} #{}: position off by {dist:.4} m",
            m.id
        );
        // The angle of R_found · R_trueᵀ.
        let r = |i: usize, j: usize| pose["rotation"][i][j].as_f64().unwrap();
        let trace: f64 = (0..3)
            .map(|i| (0..3).map(|k| r(i, k) * want.rotation[i][k]).sum::<f64>())
            .sum();
        let angle = ((trace - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees();
        assert!(angle < 1.0, "{name} #{}: rotation off by {angle:.2}°", m.id);
        assert!(d["scores"]["roi"].as_f64().unwrap() > 0.0);
        assert!(!d["keypoints"].as_array().unwrap().is_empty());
    }
}

#[test]
fn an_image_without_markers_gives_none_and_a_corrupt_one_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let mut config = SynthConfig::new(Mode::Camera);
    config.width = 640;
    config.height = 480;
    config.markers = [0, 0];
    let sample = synthesize_mixed(&[&family("apriltag-36h11")], &config, 3).unwrap();
    let png = tagsmith::image::encode_png(&sample.image).unwrap();
    std::fs::write(dir.path().join("empty.png"), png).unwrap();
    let run = tagsmith(dir.path(), &["detect", "empty.png", "--json", "out.json"]);
    run.ok();
    assert!(
        run.stdout.contains("empty.png: 0 markers"),
        "{}",
        run.stdout
    );
    let out: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("out.json")).unwrap()).unwrap();
    assert_eq!(out["images"][0]["detections"], serde_json::json!([]));

    std::fs::write(
        dir.path().join("broken.jpg"),
        b"\xff\xd8\xff\xe0 not really",
    )
    .unwrap();
    let run = tagsmith(
        dir.path(),
        &["detect", "empty.png", "broken.jpg", "--json", "out2.json"],
    );
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(run.stderr.contains("broken.jpg"), "{}", run.stderr);
    // The readable image is still reported.
    let out: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("out2.json")).unwrap()).unwrap();
    assert_eq!(out["images"].as_array().unwrap().len(), 1);
}

/// `kill -9` in the middle of stage-1 training loses at most one checkpoint interval.
#[test]
fn stage1_training_resumes_after_kill_9() {
    let dir = tempfile::tempdir().unwrap();
    let report = train_killed_then_resumed(
        dir.path(),
        &[
            "train",
            "--stage",
            "roi",
            "--batch",
            "1",
            "--width",
            "8",
            "--validate-every",
            "1000",
            "--validation-patches",
            "1",
        ],
        3,
        12,
    );
    let from = report["resumed_from"].as_u64().expect("resumed");
    assert!(
        from >= 3 && from.is_multiple_of(3) && from <= 12,
        "resumed from {from}"
    );
    assert_eq!(report["steps"], 12);
    assert_eq!(report["family"], "square markers");
    // The model it wrote is a stage-1 model `detect` can use.
    tagsmith(
        dir.path(),
        &["synth", "apriltag-36h11", "-n", "1", "-o", "s"],
    )
    .ok();
    tagsmith(
        dir.path(),
        &["detect", "s/000000.png", "--stage1", "r/model.bin"],
    )
    .ok();
}

/// The AprilTag swarmathon photograph with 25 tags of 13–20 px on cubes side by side (AprilTag's
/// own regression image; its detector's corners are the reference, `../shared/realimages`). The
/// tiny-marker search (`--upsample`) finds nearly all of them and the default search, through
/// the quads traced around dark blobs, most of them — each where AprilTag finds it, reading
/// nothing else.
#[test]
fn tiny_tags_side_by_side_on_a_photograph_are_found_with_upsample() {
    let folder = workspace().join("../shared/realimages/apriltag_swarmathon");
    let image = folder.join("34085369442_304b6bafd9_c.jpg");
    let reference: Vec<[[f64; 2]; 4]> = std::fs::read_to_string(image.with_extension("txt"))
        .unwrap()
        .lines()
        .map(|line| {
            let v: Vec<f64> = line
                .split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
                .filter(|s| !s.is_empty())
                .map(|s| s.parse().unwrap())
                .collect();
            // AprilTag puts pixel centres at +0.5.
            std::array::from_fn(|i| [v[1 + 2 * i] - 0.5, v[2 + 2 * i] - 0.5])
        })
        .collect();
    assert_eq!(reference.len(), 25);
    let dir = tempfile::tempdir().unwrap();
    let found = |extra: &[&str]| -> usize {
        let mut args = vec![
            "detect",
            image.to_str().unwrap(),
            "--family",
            "apriltag-36h11",
            "--json",
            "out.json",
        ];
        args.extend(extra);
        tagsmith(dir.path(), &args).ok();
        let out: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("out.json")).unwrap()).unwrap();
        let detections = out["images"][0]["detections"].as_array().unwrap().clone();
        let corners = |d: &serde_json::Value| -> [[f64; 2]; 4] {
            std::array::from_fn(|i| {
                [
                    d["corners"][i][0].as_f64().unwrap(),
                    d["corners"][i][1].as_f64().unwrap(),
                ]
            })
        };
        // Any starting corner, either winding (AprilTag lists its corners anticlockwise).
        let same = |a: &[[f64; 2]; 4], b: &[[f64; 2]; 4]| {
            (0..4).any(|k| {
                (0..4).all(|i| {
                    let (p, q) = (a[(i + k) % 4], b[i]);
                    (p[0] - q[0]).hypot(p[1] - q[1]) < 3.0
                }) || (0..4).all(|i| {
                    let (p, q) = (a[(k + 4 - i) % 4], b[i]);
                    (p[0] - q[0]).hypot(p[1] - q[1]) < 3.0
                })
            })
        };
        for d in &detections {
            assert_eq!(d["id"], 0, "every tag on the cubes is ID 0: {d}");
        }
        reference
            .iter()
            .filter(|r| detections.iter().any(|d| same(&corners(d), r)))
            .count()
    };
    let (default, upsampled) = (found(&[]), found(&["--upsample"]));
    assert!(
        upsampled >= default && upsampled >= 20 && default >= 12,
        "of 25 tags: {default} found by default, {upsampled} with --upsample"
    );
}

/// `train FAMILY --stage roi` fine-tunes the shipped stage 1 (`--init shipped` is its default):
/// two steps at a small learning rate still find the six markers of the ArUco photograph, as the
/// shipped model does, and the report says where the run started; from fresh weights
/// (`--init none`) two steps find nothing. Both are asked for the network's own proposals
/// (`--no-outline`): the image searches find these six markers by the image alone once the
/// mask says "marker" — and an untrained mask says 0.5 everywhere. A model of the other stage is
/// refused by name.
#[test]
fn a_familys_stage_1_is_fine_tuned_from_the_shipped_weights() {
    let dir = tempfile::tempdir().unwrap();
    let train = |out: &str, extra: &[&str]| {
        let mut args = vec![
            "train",
            "aruco-6x6_250",
            "--stage",
            "roi",
            "--steps",
            "2",
            "--batch",
            "2",
            "--validation-patches",
            "2",
            "--learning-rate",
            "0.00001",
            "--out",
            out,
        ];
        args.extend(extra);
        tagsmith(dir.path(), &args).ok();
    };
    let sample = workspace().join("assets/samples/aruco-6x6_250-tutorial.jpg");
    let found = |model: &str| -> usize {
        let args = [
            "detect",
            sample.to_str().unwrap(),
            "--family",
            "aruco-6x6_250",
            "--stage1",
            model,
            "--no-outline",
            "--json",
            "out.json",
        ];
        tagsmith(dir.path(), &args).ok();
        let out: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("out.json")).unwrap()).unwrap();
        out["images"][0]["detections"].as_array().unwrap().len()
    };
    train("tuned", &[]);
    assert_eq!(found("tuned/model.bin"), 6);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("tuned/report.json")).unwrap())
            .unwrap();
    assert_eq!(report["started_from"], "shipped stage-1 model");
    train("fresh", &["--init", "none"]);
    assert_eq!(found("fresh/model.bin"), 0);

    let stage2 = workspace().join("assets/models/aruco-6x6_250.stage2.bin");
    let run = tagsmith(
        dir.path(),
        &[
            "train",
            "--stage",
            "roi",
            "--init",
            stage2.to_str().unwrap(),
        ],
    );
    assert_eq!(run.code, 2);
    assert!(
        run.stderr.contains("aruco-6x6_250.stage2.bin") && run.stderr.contains("stage-1"),
        "{}",
        run.stderr
    );
}

/// Markers seen nearly edge-on (65–75° at 10–35 cm, the paper's Difficult views): the network's
/// grouping misses many of them, the quads the image outlines find more (`--no-outline` turns
/// them off), and every marker reported carries its own ID.
#[test]
fn steep_views_are_found_through_their_outlines() {
    let f = family("apriltag-36h11");
    let dir = tempfile::tempdir().unwrap();
    let mut images = Vec::new();
    let mut ids = Vec::new();
    for seed in 0..16 {
        let mut config = SynthConfig::new(Mode::Camera);
        config.markers = [1, 1];
        config.side_m = [0.05, 0.05];
        config.distance_m = [0.1, 0.35];
        config.view_angle_deg = [65.0, 75.0];
        let mut augment = AugmentRanges::none();
        augment.marker_black = [20.0, 40.0];
        augment.marker_white = [200.0, 235.0];
        augment.noise_sigma = [2.0, 2.0];
        config.augment = augment;
        let sample = tagsmith::synth::synthesize(&f, &config, 100 + seed).unwrap();
        let name = format!("steep{seed}.png");
        let png = tagsmith::image::encode_png(&sample.image).unwrap();
        std::fs::write(dir.path().join(&name), png).unwrap();
        images.push(name);
        ids.push(sample.truth.markers[0].id as u64);
    }
    let found = |extra: &[&str]| -> usize {
        let mut args = vec!["detect", "--family", "apriltag-36h11", "--json", "out.json"];
        args.extend(images.iter().map(String::as_str));
        args.extend(extra);
        tagsmith(dir.path(), &args).ok();
        let out: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("out.json")).unwrap()).unwrap();
        let mut found = 0;
        for image in out["images"].as_array().unwrap() {
            let file = image["file"].as_str().unwrap();
            let k = images
                .iter()
                .position(|i| file.ends_with(i.as_str()))
                .unwrap();
            for d in image["detections"].as_array().unwrap() {
                assert_eq!(d["id"].as_u64(), Some(ids[k]), "{file}: {d}");
            }
            found += usize::from(!image["detections"].as_array().unwrap().is_empty());
        }
        found
    };
    let (with, without) = (found(&[]), found(&["--no-outline"]));
    assert!(
        with >= without + 2,
        "of 16 steep views: {with} found, {without} without the outlined quads"
    );
}

/// `detect --track`: frames of one scene moving 3 px right and 2 px down each; stage 2 alone
/// follows the three markers, and the whole detector runs on the first frame and every
/// `--redetect-every` frames.
#[test]
fn tracking_follows_the_markers_of_a_moving_scene_with_stage_2_alone() {
    let dir = tempfile::tempdir().unwrap();
    mixed_scene(dir.path());
    let scene = tagsmith::image::decode(
        &std::fs::read(dir.path().join("scene.png")).unwrap(),
        &Default::default(),
    )
    .unwrap();
    let mut frames = Vec::new();
    for k in 0..5u32 {
        let (dx, dy) = (3 * k, 2 * k);
        let mut frame = tagsmith::image::GrayImage::new(scene.width, scene.height, 128);
        for y in dy..scene.height {
            for x in dx..scene.width {
                frame.pixels[(y * scene.width + x) as usize] = scene.get(x - dx, y - dy);
            }
        }
        let name = format!("frame-{k}.png");
        let png = tagsmith::image::encode_png(&frame).unwrap();
        std::fs::write(dir.path().join(&name), &png).unwrap();
        // The same frames as a folder of a video's frames, beside a file that is no image.
        std::fs::create_dir_all(dir.path().join("video")).unwrap();
        std::fs::write(dir.path().join("video").join(&name), &png).unwrap();
        frames.push(name);
    }
    std::fs::write(dir.path().join("video/notes.txt"), "not a frame").unwrap();
    let frame_args: Vec<&str> = frames.iter().map(String::as_str).collect();
    for (every, want, inputs) in [
        ("10", [false, true, true, true, true], frame_args.clone()),
        ("2", [false, true, false, true, false], frame_args.clone()),
        ("10", [false, true, true, true, true], vec!["video"]),
    ] {
        let mut args = vec![
            "detect",
            "--track",
            "--redetect-every",
            every,
            "--family",
            "apriltag-36h11",
            "--family",
            "aruco-6x6_250",
            "--json",
            "out.json",
        ];
        args.extend(&inputs);
        let run = tagsmith(dir.path(), &args);
        run.ok();
        assert!(run.stdout.contains("(tracked: "), "{}", run.stdout);
        let out: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("out.json")).unwrap()).unwrap();
        let images = out["images"].as_array().unwrap();
        let tracked: Vec<bool> = images
            .iter()
            .map(|i| i["timings"]["tracked"].as_bool().unwrap())
            .collect();
        assert_eq!(tracked, want, "--redetect-every {every} on {inputs:?}");
        for (k, image) in images.iter().enumerate() {
            assert_eq!(
                image["detections"].as_array().unwrap().len(),
                3,
                "frame {k}"
            );
        }
        // The markers move with the frames.
        let corner = |k: usize| {
            let c = &images[k]["detections"][0]["corners"][0];
            [c[0].as_f64().unwrap(), c[1].as_f64().unwrap()]
        };
        let (first, last) = (corner(0), corner(4));
        assert!(
            ((last[0] - first[0]) - 12.0).abs() < 1.0,
            "{first:?} → {last:?}"
        );
        assert!(
            ((last[1] - first[1]) - 8.0).abs() < 1.0,
            "{first:?} → {last:?}"
        );
    }
}

/// A folder with no image in it is refused, named, with the formats that count.
#[test]
fn a_folder_without_images_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("empty")).unwrap();
    std::fs::write(dir.path().join("empty/readme.txt"), "no frames").unwrap();
    refused(
        dir.path(),
        &["detect", "--track", "empty"],
        &["empty", "holds no image", "png"],
    );
}

/// `--redetect-every` means nothing without `--track`, and is refused.
#[test]
fn redetect_every_without_track_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    refused(
        dir.path(),
        &["detect", "x.png", "--redetect-every", "3"],
        &["--track"],
    );
}
