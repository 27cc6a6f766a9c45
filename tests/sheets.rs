//! End-to-end: printable sheets at an exact physical size, as SVG pages and one vector PDF.

mod common;
use common::*;

const A4_PT: (f64, f64) = (595.2756, 841.8898);

fn pdf_pages(pdf: &[u8]) -> usize {
    let text = String::from_utf8_lossy(pdf);
    text.matches("/Type /Page").count() - text.matches("/Type /Pages").count()
}

fn media_boxes(pdf: &[u8]) -> Vec<[f64; 4]> {
    let text = String::from_utf8_lossy(pdf);
    text.match_indices("/MediaBox [")
        .map(|(i, m)| {
            let rest = &text[i + m.len()..];
            let nums: Vec<f64> = rest[..rest.find(']').unwrap()]
                .split_whitespace()
                .map(|n| n.parse().unwrap())
                .collect();
            [nums[0], nums[1], nums[2], nums[3]]
        })
        .collect()
}

#[test]
fn pdf_sheet_is_a4_to_a_hundredth_of_a_point_with_one_page_per_twelve_markers() {
    let dir = tempfile::tempdir().unwrap();
    let run = tagsmith(
        dir.path(),
        &[
            "sheet",
            "apriltag-36h11",
            "--ids",
            "0-47",
            "--page",
            "a4",
            "--size-mm",
            "40",
            "--labels",
            "--cut-marks",
            "-o",
            "sheet.pdf",
        ],
    );
    run.ok();
    assert!(
        run.stdout.contains("48 markers, 12 per page, 4 page(s)"),
        "{}",
        run.stdout
    );
    let pdf = std::fs::read(dir.path().join("sheet.pdf")).unwrap();
    assert!(pdf.starts_with(b"%PDF-"));
    assert_eq!(pdf_pages(&pdf), 4);
    let boxes = media_boxes(&pdf);
    assert_eq!(boxes.len(), 4);
    for b in boxes {
        assert!(
            (b[2] - A4_PT.0).abs() < 0.01 && (b[3] - A4_PT.1).abs() < 0.01,
            "{b:?}"
        );
    }
    // The page's SVG is drawn onto the page at exactly the page size (1 mm = 72/25.4 pt).
    assert!(String::from_utf8_lossy(&pdf).contains("595.2756 0 0 841.8898 0 0 cm"));
}

#[test]
fn svg_sheet_markers_measure_the_requested_side_and_carry_size_scale_and_labels() {
    let dir = tempfile::tempdir().unwrap();
    tagsmith(
        dir.path(),
        &[
            "sheet",
            "apriltag-36h11",
            "--ids",
            "3,5,8-9",
            "--size-mm",
            "40",
            "--labels",
            "--cut-marks",
            "-o",
            "sheet.svg",
        ],
    )
    .ok();
    let svg = std::fs::read_to_string(dir.path().join("sheet.svg")).unwrap();
    assert!(
        svg.contains("width=\"210mm\"")
            && svg.contains("height=\"297mm\"")
            && svg.contains("viewBox=\"0 0 210 297\"")
    );
    for id in [3, 5, 8, 9] {
        let black = black_paths_after(&svg, &format!("id=\"marker-{id}\""));
        let b = bbox(black[0]);
        assert!(
            (b[2] - b[0] - 40.0).abs() < 0.01 && (b[3] - b[1] - 40.0).abs() < 0.01,
            "ID {id}: {b:?}"
        );
        assert!(svg.contains(&format!("apriltag-36h11 · ID {id} · 40.0 mm")));
    }
    assert!(svg.contains("tag size 40.0 mm, corner to corner"));
    assert!(svg.contains("class=\"cut-marks\""));
    // The scale bar is 100 mm long.
    let bar = &svg[svg.find("class=\"scale-bar\"").unwrap()..];
    assert!(bar.contains("width=\"100\""), "{}", &bar[..300]);
}

#[test]
fn many_svg_pages_are_numbered_files() {
    let dir = tempfile::tempdir().unwrap();
    let run = tagsmith(
        dir.path(),
        &[
            "sheet",
            "aruco-4x4_50",
            "--ids",
            "0-49",
            "--size-mm",
            "50",
            "-o",
            "p.svg",
        ],
    );
    run.ok();
    let pages: Vec<_> = (1..)
        .map(|i| dir.path().join(format!("p-{i}.svg")))
        .take_while(|p| p.exists())
        .collect();
    assert!(pages.len() >= 5, "{}", run.stdout);
    assert!(std::fs::read_to_string(&pages[0])
        .unwrap()
        .contains("page 1 / "));
}

/// A shorter sheet written over a longer one of the same name: the old pages past the new count
/// are removed (they would print with the new sheet), and nothing else is.
#[test]
fn a_shorter_svg_sheet_removes_the_stale_pages_of_a_longer_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sheet = |ids: &str| {
        tagsmith(
            d,
            &[
                "sheet",
                "aruco-4x4_50",
                "--ids",
                ids,
                "--size-mm",
                "50",
                "-o",
                "p.svg",
            ],
        )
        .ok();
    };
    let pages = || -> Vec<usize> {
        let mut n: Vec<usize> = std::fs::read_dir(d)
            .unwrap()
            .filter_map(|e| {
                let name = e.unwrap().file_name().into_string().unwrap();
                let n = name.strip_prefix("p-")?.strip_suffix(".svg")?;
                n.parse().ok().filter(|_| !n.starts_with('0'))
            })
            .collect();
        n.sort_unstable();
        n
    };
    sheet("0-49");
    let long = pages();
    assert!(long.len() >= 5, "{long:?}");
    // Files that only look alike are not pages of the sheet.
    for other in ["p-01.svg", "p-x.svg", "p-3.png", "q-9.svg", "notes.txt"] {
        std::fs::write(d.join(other), "keep").unwrap();
    }
    sheet("0-9");
    let short = pages();
    assert!(short.len() >= 2 && short.len() < long.len(), "{short:?}");
    assert_eq!(short, (1..=short.len()).collect::<Vec<_>>());
    let last = std::fs::read_to_string(d.join(format!("p-{}.svg", short.len()))).unwrap();
    assert!(
        last.contains(&format!("page {} / {}", short.len(), short.len())),
        "{last:.300}"
    );
    // One page is written as p.svg itself: no numbered page is left.
    sheet("0");
    assert!(pages().is_empty(), "{:?}", pages());
    assert!(d.join("p.svg").exists());
    for other in ["p-01.svg", "p-x.svg", "p-3.png", "q-9.svg", "notes.txt"] {
        assert_eq!(std::fs::read_to_string(d.join(other)).unwrap(), "keep");
    }
}

#[test]
fn a_sheet_that_cannot_fit_one_marker_or_names_a_missing_id_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let run = tagsmith(
        dir.path(),
        &[
            "sheet",
            "apriltag-36h11",
            "--ids",
            "0",
            "--size-mm",
            "400",
            "-o",
            "s.pdf",
        ],
    );
    assert_eq!(run.code, 2);
    assert!(run.stderr.contains("does not fit"), "{}", run.stderr);
    let run = tagsmith(
        dir.path(),
        &["sheet", "apriltag-36h11", "--ids", "585-590", "-o", "s.pdf"],
    );
    assert_eq!(run.code, 2);
    assert!(
        run.stderr.contains("ID 587 does not exist"),
        "{}",
        run.stderr
    );
    let run = tagsmith(
        dir.path(),
        &["sheet", "apriltag-36h11", "--ids", "9-3", "-o", "s.pdf"],
    );
    assert_eq!(run.code, 2);
    assert!(!dir.path().join("s.pdf").exists());
}

#[test]
fn a_thin_quiet_zone_is_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let run = tagsmith(
        dir.path(),
        &[
            "sheet",
            "apriltag-36h11",
            "--ids",
            "0-3",
            "--quiet-zone",
            "0.5",
            "-o",
            "s.svg",
        ],
    );
    run.ok();
    assert!(
        run.stderr.contains("thinner than one cell"),
        "{}",
        run.stderr
    );
}

#[test]
fn letter_and_custom_pages() {
    let dir = tempfile::tempdir().unwrap();
    tagsmith(
        dir.path(),
        &[
            "sheet", "runetag", "--ids", "0-3", "--page", "letter", "-o", "l.pdf",
        ],
    )
    .ok();
    let b = media_boxes(&std::fs::read(dir.path().join("l.pdf")).unwrap())[0];
    assert!(
        (b[2] - 612.0).abs() < 0.01 && (b[3] - 792.0).abs() < 0.01,
        "{b:?}"
    );
    tagsmith(
        dir.path(),
        &[
            "sheet",
            "topotag-like",
            "--ids",
            "0-1",
            "--page",
            "150x100",
            "--size-mm",
            "30",
            "-o",
            "c.pdf",
        ],
    )
    .ok();
    let b = media_boxes(&std::fs::read(dir.path().join("c.pdf")).unwrap())[0];
    assert!(
        (b[2] - 150.0 * 72.0 / 25.4).abs() < 0.01 && (b[3] - 100.0 * 72.0 / 25.4).abs() < 0.01,
        "{b:?}"
    );
}

/// Reads a binary PGM (P5, 8-bit) as written by `pdftoppm -gray`.
fn read_pgm(bytes: &[u8]) -> (usize, usize, Vec<u8>) {
    let mut fields = Vec::new();
    let mut i = 0;
    while fields.len() < 4 {
        while bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        let start = i;
        while !bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        fields.push(String::from_utf8_lossy(&bytes[start..i]).to_string());
    }
    assert_eq!(fields[0], "P5");
    let (w, h) = (fields[1].parse().unwrap(), fields[2].parse().unwrap());
    (w, h, bytes[i + 1..].to_vec())
}

/// The PDF itself, rasterised by an independent renderer (poppler) at 50 px/mm: the marker's top
/// border row, integrated over its anti-aliased edges, is 40 mm long.
#[test]
fn pdf_marker_measures_the_requested_side_when_rasterised_by_poppler() {
    if std::process::Command::new("pdftoppm")
        .arg("-v")
        .output()
        .is_err()
    {
        eprintln!("pdftoppm (Debian poppler-utils) is not installed: PDF raster check skipped");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for out in ["one.pdf", "one.svg"] {
        tagsmith(
            dir.path(),
            &[
                "sheet",
                "apriltag-36h11",
                "--ids",
                "0",
                "--size-mm",
                "40",
                "-o",
                out,
            ],
        )
        .ok();
    }
    let svg = std::fs::read_to_string(dir.path().join("one.svg")).unwrap();
    let b = bbox(black_paths_after(&svg, "id=\"marker-0\"")[0]);
    const PX_PER_MM: f64 = 50.0;
    let (x0, y0) = ((b[0] - 2.0) * PX_PER_MM, (b[1] - 2.0) * PX_PER_MM);
    let size = 44.0 * PX_PER_MM;
    let status = std::process::Command::new("pdftoppm")
        .args([
            "-r",
            "1270",
            "-gray",
            "-f",
            "1",
            "-l",
            "1",
            "-x",
            &format!("{}", x0 as i64),
            "-y",
            &format!("{}", y0 as i64),
        ])
        .args([
            "-W",
            &format!("{}", size as i64),
            "-H",
            &format!("{}", size as i64),
            "one.pdf",
            "crop",
        ])
        .current_dir(dir.path())
        .status()
        .unwrap();
    assert!(status.success());
    let (w, _, pixels) = read_pgm(&std::fs::read(dir.path().join("crop-1.pgm")).unwrap());
    // The middle of the top border row (cells are 5 mm), in the crop's pixel rows.
    let row = ((b[1] + 2.5) * PX_PER_MM - (y0 as i64) as f64) as usize;
    let darkness: f64 = pixels[row * w..(row + 1) * w]
        .iter()
        .map(|&v| (255 - v) as f64 / 255.0)
        .sum();
    let measured = darkness / PX_PER_MM;
    assert!(
        (measured - 40.0).abs() < 0.01,
        "the border row measures {measured} mm"
    );
}
