//! Writes the built-in family files `families/*.json` from the standard tables in
//! `../shared/codebooks/` and the designs in `tagsmith::family::designs`.
//!
//! `cargo run --release -p tagsmith --example build_families -- ../shared/codebooks families`

use std::path::{Path, PathBuf};
use tagsmith::codebook::import::{AprilTag3Table, OpenCvTable};
use tagsmith::family::designs::*;
use tagsmith::family::{spec::FamilySpec, to_json_string, Family};

// Printed with Display: `main` returning the error would print its Debug form.
fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let tables = PathBuf::from(args.get(1).map_or("../shared/codebooks", |s| s.as_str()));
    let out = PathBuf::from(args.get(2).map_or("families", |s| s.as_str()));
    let read = |p: &Path| std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()));
    let opencv = |file: &str| -> Result<_, Box<dyn std::error::Error>> {
        Ok(OpenCvTable::parse(&read(&tables.join(file))?)?)
    };
    let april = |file: &str| -> Result<_, Box<dyn std::error::Error>> {
        Ok(AprilTag3Table::parse(&read(
            &tables.join("apriltag3").join(file),
        )?)?)
    };

    let mut specs: Vec<FamilySpec> = vec![
        opencv_family(
            "apriltag-16h5",
            "AprilTag 16h5",
            &opencv("apriltag_16h5.json")?,
        )?,
        opencv_family(
            "apriltag-25h9",
            "AprilTag 25h9",
            &opencv("apriltag_25h9.json")?,
        )?,
        opencv_family(
            "apriltag-36h11",
            "AprilTag 36h11",
            &opencv("apriltag_36h11.json")?,
        )?,
        opencv_family("aruco-4x4_50", "ArUco 4x4_50", &opencv("4x4_50.json")?)?,
        opencv_family("aruco-5x5_100", "ArUco 5x5_100", &opencv("5x5_100.json")?)?,
        opencv_family("aruco-6x6_250", "ArUco 6x6_250", &opencv("6x6_250.json")?)?,
        opencv_family(
            "aruco-mip-36h12",
            "ARUCO_MIP_36h12",
            &opencv("aruco_mip_36h12.json")?,
        )?,
        apriltag3_family(
            "apriltag-standard41h12",
            "AprilTag tagStandard41h12",
            &april("tagStandard41h12.json")?,
        )?,
        apriltag3_family(
            "apriltag-circle21h7",
            "AprilTag tagCircle21h7",
            &april("tagCircle21h7.json")?,
        )?,
    ];
    let t36 = opencv("apriltag_36h11.json")?;
    specs.push(shaped_36h11(
        "apriltag-xo-36h11",
        "AprilTag-XO 36h11",
        &t36,
        ("x", cross()),
        ("o", ring()),
    )?);
    specs.push(shaped_36h11(
        "apriltag-xa-36h11",
        "AprilTag-XA 36h11",
        &t36,
        ("x", cross()),
        ("a", triangle()),
    )?);
    specs.push(quaternary_6x6()?);
    let rune = runetag()?;
    specs.push(runetag_plus(&rune)?);
    specs.push(rune);
    specs.push(topotag_like()?);

    for spec in specs {
        let family = Family::from_spec(spec.clone())?;
        let path = out.join(format!("{}.json", spec.name));
        tagsmith::io::write_atomic(&path, to_json_string(&spec).as_bytes())
            .map_err(|e| format!("{}: {e}", path.display()))?;
        println!(
            "{:<24} {:>5} codes  {:>3} keypoints  q={}  d={:?}",
            spec.name,
            family.codebook().len(),
            family.keypoints().len(),
            family.q(),
            spec.codebook.min_distance
        );
    }
    Ok(())
}
