//! End-to-end: inputs are read as regular files of bounded size, model headers are checked field
//! by field, and training takes a lock on its output folder.

mod common;
use common::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn sample() -> PathBuf {
    workspace().join("assets/samples/apriltag-36h11-swarmathon.jpg")
}

/// A folder holding the sample photograph as `photo.jpg`.
fn with_photo() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(sample(), dir.path().join("photo.jpg")).unwrap();
    dir
}

/// Makes a FIFO at `path`; `false` where `mkfifo` is missing.
fn mkfifo(path: &Path) -> bool {
    let made = Command::new("mkfifo").arg(path).status();
    made.is_ok_and(|s| s.success())
}

/// A tiny training run's options, with `extra` before them.
fn tiny_train<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec!["train"];
    args.extend_from_slice(extra);
    args.extend([
        "--stage",
        "keypoints",
        "--batch",
        "2",
        "--width",
        "8",
        "--validation-patches",
        "2",
    ]);
    args
}

#[test]
fn fifos_as_family_model_checkpoint_or_image_are_refused_without_waiting() {
    let dir = with_photo();
    let d = dir.path();
    for name in ["pipe.json", "pipe.bin", "pipe.png"] {
        if !mkfifo(&d.join(name)) {
            eprintln!("no mkfifo here: skipped");
            return;
        }
    }
    std::fs::create_dir(d.join("run")).unwrap();
    assert!(mkfifo(&d.join("run/checkpoint.bin")));
    let shipped = ["--family", "apriltag-36h11"];
    let cases: Vec<(Vec<&str>, &[&str])> = vec![
        (vec!["validate", "pipe.json"], &["pipe.json", "FIFO"]),
        (
            vec!["detect", "photo.jpg", "--family", "pipe.json"],
            &["pipe.json", "FIFO"],
        ),
        (
            [
                &["detect", "photo.jpg"],
                &shipped[..],
                &["--model", "pipe.bin"],
            ]
            .concat(),
            &["pipe.bin", "FIFO"],
        ),
        (
            [
                &["detect", "photo.jpg"],
                &shipped[..],
                &["--stage1", "pipe.bin"],
            ]
            .concat(),
            &["pipe.bin", "FIFO"],
        ),
        (
            [&["detect", "pipe.png"], &shipped[..]].concat(),
            &["pipe.png", "FIFO"],
        ),
        (
            [&tiny_train(&["pipe.json"])[..], &["--out", "r"]].concat(),
            &["pipe.json", "FIFO"],
        ),
        (
            [
                &tiny_train(&["apriltag-16h5"])[..],
                &["--init", "pipe.bin", "--out", "r"],
            ]
            .concat(),
            &["--init pipe.bin", "FIFO"],
        ),
        (
            [
                &tiny_train(&["apriltag-16h5"])[..],
                &["--resume", "--out", "run"],
            ]
            .concat(),
            &["checkpoint.bin", "FIFO"],
        ),
        (
            vec!["studio", "--image", "pipe.png"],
            &["--image pipe.png", "FIFO"],
        ),
    ];
    for (args, names) in &cases {
        refused(d, args, names);
    }
}

#[cfg(unix)]
#[test]
fn a_device_as_family_or_model_is_refused_naming_it() {
    if !Path::new("/dev/zero").exists() {
        return;
    }
    let dir = with_photo();
    let d = dir.path();
    let shipped = ["--family", "apriltag-36h11"];
    let cases: Vec<Vec<&str>> = vec![
        vec!["validate", "/dev/zero"],
        vec!["detect", "photo.jpg", "--family", "/dev/zero"],
        [
            &["detect", "photo.jpg"],
            &shipped[..],
            &["--model", "/dev/zero"],
        ]
        .concat(),
        [
            &["detect", "photo.jpg"],
            &shipped[..],
            &["--stage1", "/dev/zero"],
        ]
        .concat(),
        [&["detect", "/dev/zero"], &shipped[..]].concat(),
        [
            &tiny_train(&["apriltag-16h5"])[..],
            &["--init", "/dev/zero", "--out", "r"],
        ]
        .concat(),
    ];
    for args in &cases {
        refused(d, args, &["/dev/zero", "device"]);
    }
}

/// `bytes` of a model file (magic line, u32 header length, JSON header, weights) with
/// `net.FIELD` of its header set to `value`; the weights and their checksum untouched.
fn with_net_field(bytes: &[u8], field: &str, value: serde_json::Value) -> Vec<u8> {
    let magic = bytes.iter().position(|&b| b == b'\n').unwrap() + 1;
    let len = u32::from_le_bytes(bytes[magic..magic + 4].try_into().unwrap()) as usize;
    let start = magic + 4;
    let mut header: serde_json::Value = serde_json::from_slice(&bytes[start..start + len]).unwrap();
    header["net"][field] = value;
    let json = serde_json::to_vec(&header).unwrap();
    let mut out = bytes[..magic].to_vec();
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(&bytes[start + len..]);
    out
}

/// A header that says `"width": 0` (weights and checksum untouched) used to panic inside burn.
#[test]
fn a_model_header_out_of_range_is_refused_naming_the_field() {
    let dir = with_photo();
    let d = dir.path();
    let models = workspace().join("assets/models");
    let stage2 = std::fs::read(models.join("apriltag-36h11.stage2.bin")).unwrap();
    let stage1 = std::fs::read(models.join("square.stage1.bin")).unwrap();
    let cases: [(&str, &Vec<u8>, &str, serde_json::Value, &str); 8] = [
        ("--model", &stage2, "width", 0.into(), "expected 8 to 256"),
        (
            "--model",
            &stage2,
            "width",
            100_000.into(),
            "expected 8 to 256",
        ),
        ("--model", &stage2, "patch", 0.into(), "expected 8 to 512"),
        ("--model", &stage2, "patch", 100.into(), "power of two"),
        (
            "--model",
            &stage2,
            "patch",
            256.into(),
            "patch side of family",
        ),
        ("--model", &stage2, "width", 16.into(), "the weights are"),
        ("--stage1", &stage1, "width", 0.into(), "expected 8 to 256"),
        ("--stage1", &stage1, "width", 64.into(), "the weights are"),
    ];
    for (option, bytes, field, value, says) in cases {
        std::fs::write(d.join("m.bin"), with_net_field(bytes, field, value.clone())).unwrap();
        let args = [
            "detect",
            "photo.jpg",
            "--family",
            "apriltag-36h11",
            option,
            "m.bin",
        ];
        let run = refused(d, &args, &["m.bin", says]);
        if !says.starts_with("the weights") {
            let named = format!("header field \"net.{field}\" is {value}");
            assert!(run.stderr.contains(&named), "{named} not in {}", run.stderr);
        }
    }
}

/// A gray float TIFF, written by hand: one strip of little-endian f32 samples.
fn float_tiff(width: u32, height: u32, samples: &[f32]) -> Vec<u8> {
    assert_eq!(samples.len(), (width * height) as usize);
    let entries: [(u16, u16, u32); 10] = [
        (256, 4, width),               // ImageWidth, LONG
        (257, 4, height),              // ImageLength
        (258, 3, 32),                  // BitsPerSample, SHORT
        (259, 3, 1),                   // Compression: none
        (262, 3, 1),                   // PhotometricInterpretation: BlackIsZero
        (273, 4, 8 + 2 + 10 * 12 + 4), // StripOffsets: right after the IFD
        (277, 3, 1),                   // SamplesPerPixel
        (278, 4, height),              // RowsPerStrip
        (279, 4, 4 * width * height),  // StripByteCounts
        (339, 3, 3),                   // SampleFormat: IEEE float
    ];
    let mut out = b"II*\0".to_vec();
    out.extend_from_slice(&8u32.to_le_bytes());
    out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, kind, value) in entries {
        out.extend_from_slice(&tag.to_le_bytes());
        out.extend_from_slice(&kind.to_le_bytes());
        out.extend_from_slice(&1u32.to_le_bytes());
        out.extend_from_slice(&value.to_le_bytes()); // a SHORT sits in the first two bytes
    }
    out.extend_from_slice(&0u32.to_le_bytes());
    for v in samples {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// A valid float32 TIFF was called "corrupt or truncated": the photograph as float gray levels
/// finds its markers.
#[test]
fn a_float_tiff_reads() {
    let dir = tempfile::tempdir().unwrap();
    let gray = tagsmith::image::read(&sample(), &tagsmith::image::Limits::default()).unwrap();
    let samples: Vec<f32> = gray.pixels.iter().map(|&v| v as f32 / 255.0).collect();
    let tiff = float_tiff(gray.width, gray.height, &samples);
    std::fs::write(dir.path().join("photo.tif"), tiff).unwrap();
    let run = tagsmith_within(
        dir.path(),
        &["detect", "photo.tif", "--family", "apriltag-36h11"],
        Duration::from_secs(120),
    );
    run.ok();
    let markers: usize = run
        .stdout
        .split_whitespace()
        .nth(1)
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no marker count in {}", run.stdout));
    assert!(markers >= 10, "{}", run.stdout);
}

/// Half a JPEG with an end-of-image marker appended used to decode as gray, exit 0.
#[test]
fn half_a_jpeg_with_an_end_marker_is_corrupt() {
    let dir = tempfile::tempdir().unwrap();
    let jpeg = std::fs::read(sample()).unwrap();
    let mut half = jpeg[..jpeg.len() / 2].to_vec();
    half.extend_from_slice(&[0xFF, 0xD9]);
    std::fs::write(dir.path().join("half.jpg"), half).unwrap();
    refused(
        dir.path(),
        &["detect", "half.jpg", "--family", "apriltag-36h11"],
        &["half.jpg", "corrupt"],
    );
}

/// Two runs into one folder both reported success, and the folder held one arbitrary run. A
/// run now holds the folder's lock: the second stops at once, naming the folder and the lock.
#[test]
fn a_second_training_run_into_a_folder_in_use_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("r")).unwrap();
    let lock = d.join("r").join(tagsmith::train::LOCK_FILE);
    let held = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock)
        .unwrap();
    held.try_lock().unwrap();
    let args = [
        &tiny_train(&["apriltag-16h5"])[..],
        &["--steps", "2", "--out", "r"],
    ]
    .concat();
    let run = refused(
        d,
        &args,
        &[
            "r is in use by another training run",
            tagsmith::train::LOCK_FILE,
        ],
    );
    assert!(run.stderr.contains(&lock.display().to_string()) || run.stderr.contains("r/"));
    assert!(!d.join("r/checkpoint.bin").exists());
    // Released (as when its run ends or is killed), the folder takes a run again.
    drop(held);
    tagsmith_within(d, &args, Duration::from_secs(120)).ok();
    assert!(d.join("r/model.bin").exists());
}

/// A real run holding the folder: the second run stops; once the first is killed (its lock
/// goes with it), the second resumes from the first's checkpoint.
#[test]
fn a_killed_runs_lock_does_not_block_the_resumed_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = |steps: &'static str| {
        [
            &tiny_train(&["apriltag-16h5"])[..],
            &[
                "--steps",
                steps,
                "--checkpoint-every",
                "1",
                "--validate-every",
                "1000000",
                "--out",
                "r",
            ],
        ]
        .concat()
    };
    let mut first = Command::new(env!("CARGO_BIN_EXE_tagsmith"))
        .args(args("100000"))
        .current_dir(d)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let clock = Instant::now();
    while !d.join("r/checkpoint.bin").exists() {
        assert!(clock.elapsed().as_secs() < 120, "no checkpoint written");
        std::thread::sleep(Duration::from_millis(20));
    }
    let second = tagsmith_within(d, &args("3"), Duration::from_secs(20));
    first.kill().unwrap(); // SIGKILL: the lock file stays, its lock does not
    first.wait().unwrap();
    assert_eq!(second.code, 2, "{}", second.stderr);
    assert!(
        second.stderr.contains("in use by another training run"),
        "{}",
        second.stderr
    );
    let mut resume = args("100000");
    let steps = resume.iter().position(|a| *a == "100000").unwrap();
    resume[steps] = "1";
    resume.push("--resume");
    let resumed = tagsmith_within(d, &resume, Duration::from_secs(120));
    resumed.ok();
    assert!(
        resumed.stderr.contains("resumed at step"),
        "{}",
        resumed.stderr
    );
}

/// `--out` naming a file used to fail with exit 1 (as if the disk had).
#[test]
fn a_training_output_that_is_a_file_is_bad_input_naming_the_option() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("notes.txt"), b"mine").unwrap();
    for out in ["notes.txt", "notes.txt/run"] {
        let args = [
            &tiny_train(&["apriltag-16h5"])[..],
            &["--steps", "2", "--out", out],
        ]
        .concat();
        refused(dir.path(), &args, &["--out", "notes.txt"]);
    }
    assert_eq!(
        std::fs::read(dir.path().join("notes.txt")).unwrap(),
        b"mine"
    );
}
