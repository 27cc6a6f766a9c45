//! Helpers shared by the end-to-end tests: run the `tagsmith` binary in a temporary folder.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub struct Run {
    pub code: i32,
    pub stdout: String,
    pub stderr: String,
}

impl Run {
    pub fn ok(&self) -> &Self {
        assert_eq!(
            self.code, 0,
            "stdout: {}\nstderr: {}",
            self.stdout, self.stderr
        );
        self
    }
}

pub fn tagsmith(dir: &Path, args: &[&str]) -> Run {
    let Output {
        status,
        stdout,
        stderr,
    } = Command::new(env!("CARGO_BIN_EXE_tagsmith"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the tagsmith binary runs");
    Run {
        code: status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&stdout).into(),
        stderr: String::from_utf8_lossy(&stderr).into(),
    }
}

/// Runs `args` in `dir` like [`tagsmith`], but fails the test (killing the run) if it has not
/// ended within `limit`: a command that waits on a FIFO waits forever, and the issue's bound
/// for any input is 20 s.
pub fn tagsmith_within(dir: &Path, args: &[&str], limit: std::time::Duration) -> Run {
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_tagsmith"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the tagsmith binary runs");
    // Drained on threads, so a chatty run cannot block on a full pipe.
    let drain = |mut r: Box<dyn std::io::Read + Send>| {
        std::thread::spawn(move || {
            let mut text = Vec::new();
            let _ = r.read_to_end(&mut text);
            String::from_utf8_lossy(&text).into_owned()
        })
    };
    let out = drain(Box::new(child.stdout.take().unwrap()));
    let err = drain(Box::new(child.stderr.take().unwrap()));
    let started = std::time::Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if started.elapsed() >= limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{args:?} did not end within {limit:?}");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    Run {
        code: status.code().unwrap_or(-1),
        stdout: out.join().unwrap(),
        stderr: err.join().unwrap(),
    }
}

/// Runs `args` in `dir` and checks it is refused as bad input (exit 2, within 20 s, no panic)
/// with every one of `names` (the option, file, field or range) in the message.
pub fn refused(dir: &Path, args: &[&str], names: &[&str]) -> Run {
    let run = tagsmith_within(dir, args, std::time::Duration::from_secs(20));
    assert_eq!(run.code, 2, "{args:?}\nstderr: {}", run.stderr);
    assert!(!run.stderr.contains("panicked"), "{args:?}: {}", run.stderr);
    for name in names {
        assert!(
            run.stderr.contains(name),
            "{args:?}: {name:?} not in {}",
            run.stderr
        );
    }
    run
}

pub fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Bounding box (min x, min y, max x, max y) of the points of an SVG path's `d` of M/L/Z commands.
pub fn bbox(d: &str) -> [f64; 4] {
    let nums: Vec<f64> = d
        .split(|c: char| c.is_ascii_alphabetic() || c == ' ')
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    for p in nums.chunks(2) {
        b = [
            b[0].min(p[0]),
            b[1].min(p[1]),
            b[2].max(p[0]),
            b[3].max(p[1]),
        ];
    }
    b
}

/// The `d` of every black-filled path inside the element that starts at `start` in `svg`.
pub fn black_paths_after<'a>(svg: &'a str, start: &str) -> Vec<&'a str> {
    let from = svg
        .find(start)
        .unwrap_or_else(|| panic!("{start} not in the SVG"));
    let group = &svg[from..from + svg[from..].find("</g>").unwrap()];
    group
        .split("<path ")
        .skip(1)
        .filter(|p| p.contains("fill=\"#000000\""))
        .map(|p| {
            let s = p.find("d=\"").unwrap() + 3;
            &p[s..s + p[s..].find('"').unwrap()]
        })
        .collect()
}

/// Starts `tagsmith train ARGS --steps 100000 --checkpoint-every EVERY --out r`, kills it with
/// SIGKILL once its first checkpoint exists, then runs it again with `--steps STEPS --resume`;
/// returns the resumed run's `report.json`.
pub fn train_killed_then_resumed(
    dir: &Path,
    args: &[&str],
    every: u64,
    steps: u64,
) -> serde_json::Value {
    let with = |steps: String| -> Vec<String> {
        args.iter()
            .map(|s| s.to_string())
            .chain([
                "--steps".into(),
                steps,
                "--checkpoint-every".into(),
                every.to_string(),
                "--out".into(),
                "r".into(),
            ])
            .collect()
    };
    let mut child = Command::new(env!("CARGO_BIN_EXE_tagsmith"))
        .args(with("100000".into()))
        .current_dir(dir)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let checkpoint = dir.join("r/checkpoint.bin");
    let start = std::time::Instant::now();
    while !checkpoint.exists() {
        assert!(start.elapsed().as_secs() < 120, "no checkpoint written");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let mut again = with(steps.to_string());
    again.push("--resume".into());
    let again: Vec<&str> = again.iter().map(String::as_str).collect();
    tagsmith(dir, &again).ok();
    serde_json::from_slice(&std::fs::read(dir.join("r/report.json")).unwrap()).unwrap()
}
