//! Every built-in family validates, renders every ID, reads back to its own ID, and the standard
//! ones match OpenCV's renderings cell for cell.

use rayon::prelude::*;
use std::path::PathBuf;
use tagsmith::codebook::import::{AprilTag3Table, OpenCvTable};
use tagsmith::family::decode;
use tagsmith::family::{designs, to_json_string, Family};
use tagsmith::render::readback::Reader;
use tagsmith::render::{marker_scene, raster, svg, SceneOptions};
use tiny_skia::Pixmap;

fn shared() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/codebooks")
}

fn all() -> Vec<Family> {
    tagsmith::builtin::names()
        .map(|n| {
            tagsmith::builtin::get(n)
                .unwrap()
                .unwrap_or_else(|e| panic!("{e}"))
        })
        .collect()
}

fn ambiguous(f: &Family) -> Vec<Vec<usize>> {
    f.ambiguous_rotations()
        .filter_map(|r| r.code_perm.clone())
        .collect()
}

#[test]
fn there_are_sixteen_and_each_declares_its_true_minimum_distance() {
    let families = all();
    assert_eq!(families.len(), 16);
    for f in &families {
        let computed = f.codebook().min_distance(&ambiguous(f));
        assert_eq!(f.spec().codebook.min_distance, computed, "{}", f.name());
        let warnings = tagsmith::render::readback::warnings(f);
        if f.name() == "artoolkitplus-bch" {
            // Corrects 2 errors as ARToolKitPlus does, though three pairs of IDs come within 2
            // bits of each other turned: the studio says so.
            assert_eq!(warnings.len(), 1, "{warnings:?}");
            assert!(warnings[0].contains("wrong ID"), "{warnings:?}");
        } else {
            assert!(warnings.is_empty(), "{}: {warnings:?}", f.name());
        }
    }
}

/// The family file's table is the code its definition gives, ID for ID (the file is what users
/// read and edit; the definition is what ARToolKitPlus prints).
#[test]
fn artoolkitplus_codes_are_its_bch_code() {
    use tagsmith::codebook::bch::{artoolkitplus_bch, ARTOOLKITPLUS_BCH_IDS};
    let f = tagsmith::builtin::get("artoolkitplus-bch")
        .unwrap()
        .unwrap();
    let codes = &f.spec().codebook.codes;
    assert_eq!(codes.len(), ARTOOLKITPLUS_BCH_IDS);
    for (id, hex) in codes.iter().enumerate() {
        let want = artoolkitplus_bch(id).unwrap();
        assert_eq!(u64::from_str_radix(hex, 16), Ok(want), "ID {id}");
    }
    assert_eq!(f.codebook().max_correction(), 2);
}

#[test]
fn every_id_of_every_family_renders_to_svg_and_png() {
    for f in all() {
        (0..f.codebook().len()).into_par_iter().for_each(|id| {
            let scene = marker_scene(&f, id, SceneOptions::default()).unwrap();
            let svg = svg::marker_svg(&scene);
            assert!(
                svg.contains("width=\"") && svg.contains("mm\""),
                "{} {id}",
                f.name()
            );
            let png = raster::encode_png(&raster::rasterize_width(&scene, 40).unwrap()).unwrap();
            assert!(png.starts_with(b"\x89PNG"));
        });
    }
}

fn sample_ids(n: usize) -> Vec<usize> {
    let mut ids: Vec<usize> = (0..10).map(|k| k * (n - 1) / 9).collect();
    ids.dedup();
    ids
}

/// Turns an image a quarter turn clockwise (y down).
fn quarter_turn(p: &Pixmap) -> Pixmap {
    let (w, h) = (p.width(), p.height());
    let mut out = Pixmap::new(h, w).unwrap();
    for y in 0..h {
        for x in 0..w {
            let px = p.pixel(x, y).unwrap();
            out.pixels_mut()[(x * h + (h - 1 - y)) as usize] = px;
        }
    }
    out
}

#[test]
fn rendered_markers_read_back_to_their_own_id() {
    for f in all() {
        let reader = Reader::new(&f);
        for id in sample_ids(f.codebook().len()) {
            let scene = marker_scene(&f, id, SceneOptions::default()).unwrap();
            let ppm = 14.0 / (scene.scale * f.cell_size()); // 14 px per cell
            let pixmap = raster::rasterize(&scene, ppm).unwrap();
            let labels = reader.read(&f, &scene, &pixmap, ppm);
            assert_eq!(
                labels,
                f.keypoint_categories(id)
                    .unwrap()
                    .into_iter()
                    .map(Some)
                    .collect::<Vec<_>>(),
                "{} {id}",
                f.name()
            );
            let d = decode(&f, &labels, None)
                .unwrap_or_else(|| panic!("{} {id} did not decode", f.name()));
            assert_eq!(
                (d.id, d.rotation, d.corrected_errors, d.fixed_mismatches),
                (id, 0, 0, 0),
                "{}",
                f.name()
            );

            // The same marker turned a quarter: square layouts decode it with rotation 90°.
            if f.rotations().len() == 4 && scene.width_mm == scene.height_mm {
                let turned = quarter_turn(&pixmap);
                let labels = reader.read(&f, &scene, &turned, ppm);
                let d = decode(&f, &labels, None)
                    .unwrap_or_else(|| panic!("{} {id} turned did not decode", f.name()));
                assert_eq!(
                    (d.id, f.rotations()[d.rotation].angle_deg),
                    (id, 90.0),
                    "{}",
                    f.name()
                );
            }
        }
    }
}

#[test]
fn decoding_corrects_errors_up_to_the_limit_and_no_further() {
    let f = tagsmith::builtin::get("apriltag-36h11").unwrap().unwrap();
    let id = 123;
    let truth: Vec<Option<usize>> = f
        .keypoint_categories(id)
        .unwrap()
        .into_iter()
        .map(Some)
        .collect();
    let flip = |labels: &mut Vec<Option<usize>>, n: usize| {
        for &kp in f.code_keypoints().iter().take(n) {
            labels[kp] = labels[kp].map(|c| 1 - c);
        }
    };
    let mut five = truth.clone();
    flip(&mut five, 5);
    let d = decode(&f, &five, None).unwrap();
    assert_eq!((d.id, d.corrected_errors), (id, 5));
    let mut six = truth.clone();
    flip(&mut six, 6);
    assert!(decode(&f, &six, None).is_none_or(|d| d.id != id || d.corrected_errors <= 5));
    // Unread keypoints count as errors.
    let mut unread = truth;
    for &kp in f.code_keypoints().iter().take(3) {
        unread[kp] = None;
    }
    assert_eq!(decode(&f, &unread, None).unwrap().corrected_errors, 3);
}

#[test]
fn the_quaternary_family_decodes_its_all_zero_code_in_every_orientation() {
    let f = tagsmith::builtin::get("quaternary-6x6").unwrap().unwrap();
    assert!(f.codebook().code(0).unwrap().iter().all(|&s| s == 0));
    assert_eq!(f.ambiguous_rotations().count(), 0);
    let truth = f.keypoint_categories(0).unwrap();
    for (r, rot) in f.rotations().iter().enumerate() {
        // What a camera sees of the marker turned by `rot`: keypoint i's label where perm[i] was.
        let mut seen = vec![None; truth.len()];
        for (i, &c) in truth.iter().enumerate() {
            seen[rot.keypoint_perm[i]] = Some(c);
        }
        let d = decode(&f, &seen, None).unwrap();
        assert_eq!((d.id, d.rotation), (0, r));
    }
}

/// OpenCV's reference images: 10 px per cell, one-cell border, no quiet zone.
#[test]
fn standard_families_match_opencv_renderings_cell_for_cell() {
    let cases = [
        ("4x4_50", "aruco-4x4_50"),
        ("5x5_100", "aruco-5x5_100"),
        ("6x6_250", "aruco-6x6_250"),
        ("aruco_mip_36h12", "aruco-mip-36h12"),
        ("apriltag_16h5", "apriltag-16h5"),
        ("apriltag_25h9", "apriltag-25h9"),
        ("apriltag_36h11", "apriltag-36h11"),
    ];
    let mut compared = 0;
    for entry in std::fs::read_dir(shared().join("reference")).expect("shared/codebooks/reference")
    {
        let path = entry.unwrap().path();
        let stem = path.file_stem().unwrap().to_str().unwrap().to_string();
        let (table, id) = stem.rsplit_once("_id").unwrap();
        let Some((_, name)) = cases.iter().find(|(t, _)| *t == table) else {
            continue;
        };
        let f = tagsmith::builtin::get(name).unwrap().unwrap();
        let id: usize = id.parse().unwrap();
        let reference = Pixmap::load_png(&path).unwrap();
        let n = f.extent().width() as u32;
        assert_eq!(reference.width(), n * 10, "{stem}");
        let scene = marker_scene(
            &f,
            id,
            SceneOptions {
                side_mm: Some(n as f64),
                quiet_zone: Some(0.0),
            },
        )
        .unwrap();
        let ours = raster::rasterize(&scene, 10.0).unwrap();
        for row in 0..n {
            for col in 0..n {
                let (x, y) = (col * 10 + 5, row * 10 + 5);
                let (a, b) = (
                    raster::gray_at(&reference, x, y),
                    raster::gray_at(&ours, x, y),
                );
                assert_eq!(a > 127.0, b > 127.0, "{stem}: cell row {row} col {col}");
            }
        }
        compared += 1;
    }
    assert_eq!(
        compared, 28,
        "every reference image of a built-in family was compared"
    );
}

/// The AprilTag library's own tables, turned 180° on import, give OpenCV's codes: the same
/// conversion makes tagStandard41h12 and tagCircle21h7 consistent with the other families.
#[test]
fn apriltag3_tables_turned_half_way_equal_opencv_tables() {
    for (april, opencv) in [
        ("tag16h5", "apriltag_16h5"),
        ("tag25h9", "apriltag_25h9"),
        ("tag36h11", "apriltag_36h11"),
    ] {
        let a = AprilTag3Table::parse(
            &std::fs::read_to_string(shared().join(format!("apriltag3/{april}.json"))).unwrap(),
        )
        .unwrap();
        let o = OpenCvTable::parse(
            &std::fs::read_to_string(shared().join(format!("{opencv}.json"))).unwrap(),
        )
        .unwrap();
        assert_eq!(a.to_grid().unwrap().codes, o.bits().unwrap(), "{april}");
    }
}

/// The committed files are exactly what the builder writes (tables from shared/, seeded generator).
#[test]
fn family_files_match_their_builder() {
    let read = |p: PathBuf| std::fs::read_to_string(p).unwrap();
    let table = |f: &str| OpenCvTable::parse(&read(shared().join(f))).unwrap();
    let check = |spec: tagsmith::family::spec::FamilySpec| {
        let (_, committed) = tagsmith::builtin::SOURCES
            .iter()
            .find(|(n, _)| *n == spec.name)
            .unwrap();
        assert!(
            to_json_string(&spec) == *committed,
            "families/{}.json differs from its builder; run build_families",
            spec.name
        );
    };
    check(
        designs::opencv_family("aruco-6x6_250", "ArUco 6x6_250", &table("6x6_250.json")).unwrap(),
    );
    let t41 =
        AprilTag3Table::parse(&read(shared().join("apriltag3/tagStandard41h12.json"))).unwrap();
    check(
        designs::apriltag3_family("apriltag-standard41h12", "AprilTag tagStandard41h12", &t41)
            .unwrap(),
    );
    check(
        designs::shaped_36h11(
            "apriltag-xo-36h11",
            "AprilTag-XO 36h11",
            &table("apriltag_36h11.json"),
            ("x", designs::cross()),
            ("o", designs::ring()),
        )
        .unwrap(),
    );
    check(designs::quaternary_6x6().unwrap());
    let rune = designs::runetag().unwrap();
    check(designs::runetag_plus(&rune).unwrap());
    check(rune);
    check(designs::topotag_like().unwrap());
}

#[test]
fn schema_file_is_in_sync_with_the_types() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../families/schema.json");
    let generated = tagsmith::family::schema_json();
    if std::env::var_os("TAGSMITH_BLESS").is_some() {
        std::fs::write(&path, &generated).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(committed == generated, "families/schema.json is stale: run `TAGSMITH_BLESS=1 cargo test -p tagsmith --test builtin_families schema`");
}
