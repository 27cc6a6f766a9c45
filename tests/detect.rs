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

/// `tagsmith detect` on the scene's image with the family, its true ROI and `extra` arguments.
fn detect_scene(dir: &std::path::Path, roi: &str, extra: &[&str]) -> Run {
    let mut args = vec![
        "detect",
        "s/000000.png",
        "--family",
        "apriltag-36h11",
        "--roi",
        roi,
    ];
    args.extend_from_slice(extra);
    tagsmith(dir, &args)
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
    let run = detect_scene(dir.path(), &roi, &["--annotate", "a.png"]);
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

/// Position (mm) and rotation (°) error of a `detect` report's pose against the scene's truth.
fn pose_error(report: &serde_json::Value, truth: &serde_json::Value) -> (f64, f64) {
    let t = &truth["markers"][0]["pose"];
    let vec3 = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let mat = |v: &serde_json::Value| -> Vec<Vec<f64>> {
        v.as_array().unwrap().iter().map(vec3).collect()
    };
    let (p, q) = (
        vec3(&report["pose"]["translation_m"]),
        vec3(&t["translation_m"]),
    );
    let position = (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt() * 1000.0;
    let (a, b) = (mat(&report["pose"]["rotation"]), mat(&t["rotation"]));
    // trace(Aᵀ B) = 1 + 2 cos θ
    let trace: f64 = (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .map(|(i, j)| a[i][j] * b[i][j])
        .sum();
    let rotation = ((trace - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees();
    (position, rotation)
}

#[test]
fn refining_against_the_rendering_tightens_the_pose_and_reports_how() {
    let dir = tempfile::tempdir().unwrap();
    let truth = scene(dir.path());
    let roi = roi_arg(&truth);
    std::fs::write(
        dir.path().join("camera.json"),
        serde_json::to_string(&truth["camera"]).unwrap(),
    )
    .unwrap();
    let side_mm = format!(
        "{}",
        truth["markers"][0]["pose"]["side_m"].as_f64().unwrap() * 1000.0
    );
    let detect = |refine: &str| -> serde_json::Value {
        let run = detect_scene(
            dir.path(),
            &roi,
            &[
                "--camera",
                "camera.json",
                "--side-mm",
                &side_mm,
                "--refine",
                refine,
            ],
        );
        run.ok();
        serde_json::from_str(&run.stdout).unwrap()
    };
    let (none, full) = (detect("none"), detect("full"));
    assert!(none.get("refinement").is_none(), "{none}");
    assert_eq!(full["refinement"]["refined"], true, "{full}");
    assert!(
        full["refinement"]["residual"].as_f64().unwrap()
            < full["refinement"]["start_residual"].as_f64().unwrap()
    );
    let uncertainty = &full["pose"]["uncertainty"];
    assert!(
        uncertainty["position_mm"][2].as_f64().unwrap() > 0.0,
        "{full}"
    );
    let (p_none, r_none) = pose_error(&none, &truth);
    let (p_full, r_full) = pose_error(&full, &truth);
    // Stage 2 alone is within millimetres; aligned with the rendering, within a tenth of that.
    assert!(p_none < 5.0 && r_none < 2.0, "{p_none:.3} mm, {r_none:.3}°");
    assert!(
        p_full < 0.5 && r_full < 0.2 && p_full < p_none,
        "refined {p_full:.3} mm, {r_full:.3}° (stage 2: {p_none:.3} mm, {r_none:.3}°)"
    );
    let run = detect_scene(dir.path(), &roi, &["--refine", "best"]);
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(
        run.stderr.contains("none") && run.stderr.contains("full"),
        "{}",
        run.stderr
    );
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
        &["detect", img, "--family", "runetag-plus", "--roi", &roi],
    );
    assert_eq!(run.code, 2);
    assert!(
        run.stderr
            .contains("no weights are shipped for family \"runetag-plus\""),
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

/// `--init shipped` fine-tunes a family's shipped stage 2: after two steps at a tiny rate the
/// model still reads the validation patches (fresh weights read none), and the report names
/// where it started and its share of camera-cut patches. A family without shipped weights, or
/// a share outside [0, 1], is refused before anything runs.
#[test]
fn stage_2_fine_tunes_from_the_shipped_weights() {
    let dir = tempfile::tempdir().unwrap();
    let args = |family: &'static str, extra: &[&'static str]| {
        let mut a = vec![
            "train",
            family,
            "--stage",
            "keypoints",
            "--steps",
            "2",
            "--batch",
            "2",
            "--learning-rate",
            "0.000001",
            "--validate-every",
            "2",
            "--validation-patches",
            "10",
            "--out",
            "ft",
        ];
        a.extend_from_slice(extra);
        a
    };
    tagsmith(
        dir.path(),
        &args(
            "aruco-6x6_250",
            &["--init", "shipped", "--camera-patches", "0.5"],
        ),
    )
    .ok();
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("ft/report.json")).unwrap()).unwrap();
    assert_eq!(
        report["started_from"],
        "shipped aruco-6x6_250 stage-2 model"
    );
    assert_eq!(report["camera_share"], 0.5);
    let id_accuracy = report["validation"][0][1]["id_accuracy"].as_f64().unwrap();
    assert!(id_accuracy >= 0.9, "ID accuracy {id_accuracy}");

    let run = tagsmith(dir.path(), &args("runetag-plus", &["--init", "shipped"]));
    assert_eq!(run.code, 2);
    assert!(
        run.stderr
            .contains("no stage-2 model is shipped for runetag-plus"),
        "{}",
        run.stderr
    );
    // A grid of another size starts from the shipped 8 × 8 grid model (the same network: two
    // categories); a family of other categories from its trunk with a class head of its own; a
    // family whose patch is another size (rings) cannot.
    let grid = workspace().join("assets/models/grid-8-bw.stage2.bin");
    let grid: &'static str = grid.to_str().unwrap().to_string().leak();
    tagsmith(dir.path(), &args("apriltag-16h5", &["--init", grid])).ok();
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("ft/report.json")).unwrap()).unwrap();
    assert_eq!(report["started_from"], grid);
    tagsmith(dir.path(), &args("quaternary-6x6", &["--init", grid])).ok();
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("ft/report.json")).unwrap()).unwrap();
    assert_eq!(report["started_from"], grid);
    assert_eq!(report["net"]["classes"], 6, "{report}");
    let run = tagsmith(dir.path(), &args("runetag", &["--init", grid]));
    assert_eq!(run.code, 2);
    assert!(run.stderr.contains("net.patch"), "{}", run.stderr);
    let run = tagsmith(
        dir.path(),
        &args("aruco-6x6_250", &["--camera-patches", "1.5"]),
    );
    assert_eq!(run.code, 2);
    assert!(run.stderr.contains("--camera-patches"), "{}", run.stderr);
}

/// `kill -9` in the middle of training loses at most one checkpoint interval: `--resume` goes on
/// from the last checkpoint.
#[test]
fn training_resumes_after_kill_9() {
    let dir = tempfile::tempdir().unwrap();
    let report = train_killed_then_resumed(
        dir.path(),
        &[
            "train",
            "apriltag-16h5",
            "--stage",
            "keypoints",
            "--batch",
            "2",
            "--width",
            "8",
            "--validate-every",
            "1000",
            "--validation-patches",
            "2",
        ],
        5,
        60,
    );
    let from = report["resumed_from"].as_u64().expect("resumed");
    assert!(
        from >= 5 && from.is_multiple_of(5) && from <= 60,
        "resumed from {from}"
    );
    assert_eq!(report["steps"], 60);
}

/// One marker of the sample photograph (see assets/samples/README.md), clockwise.
const SWARMATHON_ROI: &str = "329.95,442.66,286.03,446.36,285.24,402.35,328.57,398.87";

/// `detect IMAGE` with the sample tag's family and ROI, then `extra`.
fn detect_swarmathon_tag<'a>(image: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![
        "detect",
        image,
        "--family",
        "apriltag-36h11",
        "--roi",
        SWARMATHON_ROI,
    ];
    args.extend_from_slice(extra);
    args
}

fn sample(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/samples")
        .join(name)
}

/// The ArUco tutorial photograph: OpenCV's corners for the six markers (`ArucoDetector`,
/// DICT_6X6_250, no sub-pixel step; clockwise from the marker's top-left), each ROI read by the
/// shipped ArUco weights and refined.
#[test]
fn the_aruco_photograph_reads_every_marker_with_opencvs_id() {
    let dir = tempfile::tempdir().unwrap();
    let image = sample("aruco-6x6_250-tutorial.jpg");
    let markers = [
        (40, "359,310,404,310,410,350,362,350"),
        (98, "427,255,469,256,477,289,434,288"),
        (62, "233,273,190,273,196,241,237,241"),
        (23, "298,185,334,186,335,212,297,211"),
        (124, "425,163,430,186,394,186,390,162"),
        (203, "195,155,230,155,227,178,190,178"),
    ];
    for (id, roi) in markers {
        let run = tagsmith(
            dir.path(),
            &[
                "detect",
                image.to_str().unwrap(),
                "--family",
                "aruco-6x6_250",
                "--roi",
                roi,
            ],
        );
        run.ok();
        let out: serde_json::Value = serde_json::from_str(&run.stdout).unwrap();
        assert_eq!(out["id"], id, "{roi}: {}", run.stdout);
        assert!(
            out["pose"]["reprojection_rms_px"].as_f64().unwrap() < 0.5,
            "{}",
            run.stdout
        );
    }
}

#[test]
fn a_jpeg_photograph_decodes_as_the_png_of_the_same_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let jpeg = sample("apriltag-36h11-swarmathon.jpg");
    let gray = tagsmith::image::read(&jpeg, &Default::default()).unwrap();
    assert_eq!((gray.width, gray.height), (799, 533));
    std::fs::write(
        dir.path().join("same.png"),
        tagsmith::image::encode_png(&gray).unwrap(),
    )
    .unwrap();
    let detect = |image: &str| {
        let run = tagsmith(dir.path(), &detect_swarmathon_tag(image, &[]));
        run.ok();
        let mut report = serde_json::from_str::<serde_json::Value>(&run.stdout).unwrap();
        // Wall times differ from run to run; everything else must not.
        let refinement = report["refinement"].as_object_mut().expect("refined");
        refinement.remove("time_ms");
        refinement.remove("render_ms");
        report
    };
    let from_jpeg = detect(jpeg.to_str().unwrap());
    assert_eq!(from_jpeg["id"], 0, "{from_jpeg}");
    assert_eq!(from_jpeg, detect("same.png"));
}

/// Runs `tagsmith` under GNU time (where the machine has it) and returns the run with its peak
/// resident memory in MB.
fn tagsmith_measured(dir: &std::path::Path, args: &[&str]) -> (Run, Option<f64>) {
    let time = std::path::Path::new("/usr/bin/time");
    if !time.exists() {
        return (tagsmith(dir, args), None);
    }
    let out = std::process::Command::new(time)
        .args(["-f", "peak-kb %M"])
        .arg(env!("CARGO_BIN_EXE_tagsmith"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    let peak = stderr
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix("peak-kb "))
        .and_then(|v| v.trim().parse::<f64>().ok())
        .map(|kb| kb / 1024.0);
    let run = Run {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into(),
        stderr,
    };
    (run, peak)
}

/// A PNG signature and IHDR chunk (CRC included) claiming `width` × `height` 8-bit gray, and
/// nothing else.
fn png_header(width: u32, height: u32) -> Vec<u8> {
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend(width.to_be_bytes());
    ihdr.extend(height.to_be_bytes());
    ihdr.extend([8, 0, 0, 0, 0]);
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    out.extend(13u32.to_be_bytes());
    out.extend(&ihdr);
    out.extend(crc32(&ihdr).to_be_bytes());
    out
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

#[test]
fn oversized_images_are_refused_before_decoding_in_bounded_time_and_memory() {
    let dir = tempfile::tempdir().unwrap();
    let claimed = png_header(40_000, 40_000);
    assert!(claimed.len() <= 60);
    std::fs::write(dir.path().join("claims.png"), &claimed).unwrap();
    // A real, complete 20000 × 20000 PNG (black; it compresses to about 400 KB).
    {
        let file = std::fs::File::create(dir.path().join("huge.png")).unwrap();
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), 20_000, 20_000);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_compression(png::Compression::Fast);
        let mut writer = enc.write_header().unwrap();
        let mut stream = writer.stream_writer().unwrap();
        let row = vec![0u8; 20_000];
        for _ in 0..20_000 {
            std::io::Write::write_all(&mut stream, &row).unwrap();
        }
        stream.finish().unwrap();
    }
    for (file, size) in [("claims.png", "40000×40000"), ("huge.png", "20000×20000")] {
        let started = std::time::Instant::now();
        let (run, peak_mb) = tagsmith_measured(dir.path(), &detect_swarmathon_tag(file, &[]));
        let seconds = started.elapsed().as_secs_f64();
        assert_eq!(run.code, 2, "{file}: {}", run.stderr);
        assert!(run.stderr.contains(size), "{file}: {}", run.stderr);
        assert!(
            run.stderr.contains("64.0 megapixels"),
            "{file}: {}",
            run.stderr
        );
        assert_eq!(run.stderr.matches(file).count(), 1, "{}", run.stderr);
        assert!(seconds < 5.0, "{file}: {seconds:.1} s");
        if let Some(mb) = peak_mb {
            assert!(mb < 512.0, "{file}: peak {mb:.0} MB");
        }
    }
    // The limit can be raised up to its ceiling: then a header-only file is refused as
    // truncated instead.
    std::fs::write(
        dir.path().join("claims-144.png"),
        png_header(12_000, 12_000),
    )
    .unwrap();
    let run = tagsmith(
        dir.path(),
        &detect_swarmathon_tag("claims-144.png", &["--max-pixels", "256000000"]),
    );
    assert_eq!(run.code, 2, "{}", run.stderr);
    assert!(
        run.stderr.contains("corrupt or truncated"),
        "{}",
        run.stderr
    );
}

#[test]
fn a_truncated_or_non_image_file_is_bad_input_named_once() {
    let dir = tempfile::tempdir().unwrap();
    let jpeg = std::fs::read(sample("apriltag-36h11-swarmathon.jpg")).unwrap();
    std::fs::write(dir.path().join("cut.jpg"), &jpeg[..jpeg.len() / 3]).unwrap();
    std::fs::write(dir.path().join("notes.png"), b"not an image at all").unwrap();
    for file in ["cut.jpg", "notes.png"] {
        let run = tagsmith(dir.path(), &detect_swarmathon_tag(file, &[]));
        assert_eq!(run.code, 2, "{file}: {}", run.stderr);
        assert_eq!(run.stderr.matches(file).count(), 1, "{}", run.stderr);
    }
}
