//! Validation of a family spec and derivation of the [`Family`].
//!
//! Every check reports the JSON path of the offending field. Checks run in dependency order and
//! stop before a stage that would only repeat an earlier problem (a codebook cannot be checked
//! against a layout that failed).

use super::geometry::{rotation_candidates, symmetries, Extent, Keypoint};
use super::spec::{FamilySpec, GridLayout, KeypointSet, Layout, RingsLayout, Role, FORMAT_VERSION};
use super::{Assignment, Family, FamilyError, Problem};
use crate::codebook::Codebook;
use crate::color::Rgb;
use crate::family::pattern::{parse_category, CategoryPattern};
use std::collections::HashMap;

// Limits on what a family may ask the renderers to draw and print. A fuzz campaign found that
// unbounded inputs made `validate`, `render` and `sheet` run for minutes or use gigabytes; each
// limit is far above what a real design needs (see the built-in families) and below what makes a
// command slow.

pub const MAX_GRID: u32 = 32;
pub const MAX_KEYPOINTS: usize = 4096;
const MAX_RINGS: usize = 16;
const MAX_SLOTS: u32 = 512;
/// The largest published table, AprilTag 52h13, has 48 714 codes; the minimum-distance check is
/// quadratic, and at this size it still takes seconds, not hours.
const MAX_CODES: usize = 100_000;
/// Coordinates beyond this many marker units are certainly a typo.
const MAX_COORD: f64 = 1000.0;
/// Bounds of `print.marker_side_mm`, in mm.
pub const MIN_MARKER_SIDE_MM: f64 = 1.0;
pub const MAX_MARKER_SIDE_MM: f64 = 2000.0;

/// Longest `title`, in characters: it is printed on one line of every sheet's header, where about
/// 100 characters of its 3.5 mm type fill the width of an A4 page (the PDF took seconds to lay out
/// a title of 100 000 characters).
pub const MAX_TITLE_CHARS: usize = 100;
/// Longest `description`, in characters: a few paragraphs, enough to describe any design.
pub const MAX_DESCRIPTION_CHARS: usize = 4000;
/// Longest `source` and `codebook.source`, in characters: a citation, a URL and a licence take a
/// few hundred.
pub const MAX_SOURCE_CHARS: usize = 1000;
/// Longest category name, in characters: names label categories in warnings, the studio and the
/// legend, like the family name, which has the same limit.
pub const MAX_CATEGORY_NAME_CHARS: usize = 64;
/// Most categories in a family. The detector classifies every keypoint into one of them (its
/// network has one class per category plus the background), and a category is only useful when it
/// looks unlike every other at a few pixels per cell: 64 is far beyond what can be told apart, and
/// keeps the pairwise look-alike check of [`crate::render::readback`] (4 turns each) instant.
pub const MAX_CATEGORIES: usize = 64;
/// Most path segments of all categories' primitives together (a dot or ring has 6 or 12): bounds
/// the cost of drawing every category, as the look-alike check and the studio's swatches do.
pub const MAX_FAMILY_SEGMENTS: usize = 8192;
/// Most primitives one marker draws (every keypoint's category's primitives, the heaviest symbol
/// category at each symbol keypoint): one vector node each in SVG and PDF output, and usvg, which
/// reads sheet pages, stops at 1 000 000 nodes; 8192 leaves room for a hundred markers a page,
/// while the largest layouts (4096 keypoints) still get two primitives per keypoint.
pub const MAX_MARKER_PRIMITIVES: usize = 8192;
/// Most path segments one marker draws: enough for a dot and a ring (16 segments) at each of the
/// 4096 keypoints of the largest layouts, while a marker stays a few MB of SVG path data and
/// rasterizes in well under a second even when every curve crosses every scanline (a 9 MB path
/// repeated over a marker needed gigabytes).
pub const MAX_MARKER_SEGMENTS: usize = 65_536;

pub(super) fn build(spec: FamilySpec) -> Result<Family, FamilyError> {
    let mut problems = Vec::new();
    if spec.format != FORMAT_VERSION {
        return Err(FamilyError::single(
            "format",
            format!(
                "unsupported format {} (this build reads format {FORMAT_VERSION})",
                spec.format
            ),
        ));
    }
    check_name(&spec.name, &mut problems);
    check_text("title", &spec.title, MAX_TITLE_CHARS, &mut problems);
    check_text(
        "description",
        &spec.description,
        MAX_DESCRIPTION_CHARS,
        &mut problems,
    );
    check_text("source", &spec.source, MAX_SOURCE_CHARS, &mut problems);
    check_text(
        "codebook.source",
        &spec.codebook.source,
        MAX_SOURCE_CHARS,
        &mut problems,
    );
    let background = Rgb::parse(&spec.background)
        .map_err(|e| problems.push(Problem::new("background", e.to_string())))
        .ok();
    let categories = check_categories(&spec, &mut problems);
    let symbol_categories = symbol_categories(&spec, &mut problems);
    if !problems.is_empty() {
        return Err(FamilyError::new(problems));
    }
    let names: HashMap<&str, usize> = spec
        .categories
        .iter()
        .enumerate()
        .map(|(i, c)| (c.name.as_str(), i))
        .collect();

    let (keypoints, extent, quiet_zone) = layout_keypoints(&spec, &names, &mut problems);
    check_print(&spec, &mut problems);
    if problems.is_empty() {
        check_marker_size(&spec, &categories, &keypoints, &mut problems);
    }
    if !problems.is_empty() {
        return Err(FamilyError::new(problems));
    }
    check_keypoint_set(&spec, keypoints.len(), &mut problems);
    check_roi(&spec, &mut problems);
    if !problems.is_empty() {
        return Err(FamilyError::new(problems));
    }

    let mut code_keypoints = Vec::new();
    for (i, k) in keypoints.iter().enumerate() {
        if let Assignment::Symbol(n) = k.assignment {
            debug_assert_eq!(n, code_keypoints.len());
            code_keypoints.push(i);
        }
    }
    if code_keypoints.is_empty() {
        return Err(FamilyError::single(
            "layout",
            "no keypoint carries a code symbol",
        ));
    }
    let (centre, angles) = rotation_candidates(&spec.layout);
    let rotations = symmetries(&keypoints, centre, &angles);
    let ambiguous: Vec<Vec<usize>> = rotations
        .iter()
        .skip(1)
        .filter(|r| r.preserves_fixed)
        .filter_map(|r| r.code_perm.clone())
        .collect();
    if spec.codebook.codes.len() > MAX_CODES {
        return Err(FamilyError::single(
            "codebook.codes",
            format!(
                "{} codes is over the limit of {MAX_CODES}",
                spec.codebook.codes.len()
            ),
        ));
    }
    let codebook = Codebook::parse(
        &spec.codebook,
        symbol_categories.len(),
        code_keypoints.len(),
        &ambiguous,
    )
    .map_err(FamilyError::new)?;

    Ok(Family {
        background: background.expect("checked above"),
        categories,
        symbol_categories,
        keypoints,
        code_keypoints,
        rotations,
        extent,
        quiet_zone,
        codebook,
        spec,
    })
}

fn check_name(name: &str, problems: &mut Vec<Problem>) {
    if let Some(why) = name_problem(name) {
        problems.push(Problem::new("name", why));
    }
}

/// What is wrong with a family name, if anything. Names become file names (`NAME.json`,
/// `runs/NAME-keypoints`), so besides the characters allowed, a leading '.' is refused: `.` and
/// `..` are folders and `.NAME` a hidden file.
pub fn name_problem(name: &str) -> Option<String> {
    let ok = !name.is_empty()
        && name.len() <= 64
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c));
    (!ok).then(|| {
        format!(
            "{} must be 1–64 letters, digits, '-', '_' or '.', not starting with '.'",
            quoted(name)
        )
    })
}

fn check_text(path: &str, text: &str, max: usize, problems: &mut Vec<Problem>) {
    // Bytes bound characters from above: most texts are short and need no count.
    if text.len() > max {
        let n = text.chars().count();
        if n > max {
            problems.push(Problem::new(
                path,
                format!("{n} characters is over the limit of {max}"),
            ));
        }
    }
}

/// A text quoted for a message, cut short so that a huge value does not make a huge message.
fn quoted(text: &str) -> String {
    const SHOWN: usize = 40;
    match text.char_indices().nth(SHOWN) {
        Some((end, _)) => format!("{:?}…", &text[..end]),
        None => format!("{text:?}"),
    }
}

fn check_categories(spec: &FamilySpec, problems: &mut Vec<Problem>) -> Vec<CategoryPattern> {
    if spec.categories.is_empty() {
        problems.push(Problem::new(
            "categories",
            "a family needs at least two categories",
        ));
    }
    if spec.categories.len() > MAX_CATEGORIES {
        problems.push(Problem::new(
            "categories",
            format!(
                "{} categories is over the limit of {MAX_CATEGORIES}",
                spec.categories.len()
            ),
        ));
        return Vec::new();
    }
    let mut seen: HashMap<&str, usize> = HashMap::new();
    let mut out = Vec::new();
    for (i, cat) in spec.categories.iter().enumerate() {
        let path = format!("categories[{i}]");
        if cat.name.chars().count() > MAX_CATEGORY_NAME_CHARS {
            problems.push(Problem::new(
                format!("{path}.name"),
                format!(
                    "{} is over the limit of {MAX_CATEGORY_NAME_CHARS} characters",
                    quoted(&cat.name)
                ),
            ));
        } else if cat.name.is_empty() || cat.name == "." {
            problems.push(Problem::new(
                format!("{path}.name"),
                "a category needs a name other than \".\"",
            ));
        } else if let Some(first) = seen.insert(cat.name.as_str(), i) {
            problems.push(Problem::new(
                format!("{path}.name"),
                format!(
                    "category {} is already defined at categories[{first}]",
                    quoted(&cat.name)
                ),
            ));
        }
        match parse_category(cat, &path) {
            Ok(p) => out.push(p),
            Err(mut p) => problems.append(&mut p),
        }
    }
    let segments: usize = out.iter().map(segment_count).sum();
    if segments > MAX_FAMILY_SEGMENTS {
        problems.push(Problem::new(
            "categories",
            format!(
                "the categories' primitives have {segments} path segments in all, over the limit \
                 of {MAX_FAMILY_SEGMENTS}"
            ),
        ));
    }
    out
}

fn segment_count(pattern: &CategoryPattern) -> usize {
    pattern.items.iter().map(|it| it.path.0.len()).sum()
}

/// What one marker draws at most must stay within [`MAX_MARKER_PRIMITIVES`] and
/// [`MAX_MARKER_SEGMENTS`]; the problem names the category that draws the most.
fn check_marker_size(
    spec: &FamilySpec,
    categories: &[CategoryPattern],
    keypoints: &[Keypoint],
    problems: &mut Vec<Problem>,
) {
    let costs: Vec<[usize; 2]> = categories
        .iter()
        .map(|c| [c.items.len(), segment_count(c)])
        .collect();
    let limits = [
        (MAX_MARKER_PRIMITIVES, "primitives"),
        (MAX_MARKER_SEGMENTS, "path segments"),
    ];
    for (m, (limit, what)) in limits.into_iter().enumerate() {
        // A symbol keypoint may show any symbol category: count the heaviest.
        let heaviest = (0..categories.len())
            .filter(|&c| matches!(spec.categories[c].role, Role::Symbol(_)))
            .max_by_key(|&c| costs[c][m]);
        let mut uses = vec![0usize; categories.len()];
        for k in keypoints {
            let c = match k.assignment {
                Assignment::Fixed(c) => Some(c),
                Assignment::Symbol(_) => heaviest,
            };
            if let Some(c) = c {
                uses[c] += 1;
            }
        }
        let drawn = |c: usize| uses[c] * costs[c][m];
        let total: usize = (0..categories.len()).map(drawn).sum();
        if total > limit {
            let c = (0..categories.len())
                .max_by_key(|&c| drawn(c))
                .expect("a marker over the limit draws some category");
            problems.push(Problem::new(
                format!("categories[{c}].primitives"),
                format!(
                    "a marker draws up to {total} {what}, over the limit of {limit}; most are \
                     this category's {}, drawn at {} keypoints",
                    costs[c][m], uses[c]
                ),
            ));
            return;
        }
    }
}

/// Symbol value → category; values must be exactly 0..q.
fn symbol_categories(spec: &FamilySpec, problems: &mut Vec<Problem>) -> Vec<usize> {
    let symbols: Vec<(usize, u8)> = spec
        .categories
        .iter()
        .enumerate()
        .filter_map(|(i, c)| match c.role {
            Role::Symbol(s) => Some((i, s)),
            Role::Fixed => None,
        })
        .collect();
    let q = symbols.len();
    if q < 2 {
        problems.push(Problem::new(
            "categories",
            format!("a family needs at least two symbol categories (role {{\"symbol\": k}}), it has {q}"),
        ));
        return Vec::new();
    }
    let mut by_value = vec![None; q];
    for &(i, s) in &symbols {
        let path = format!("categories[{i}].role.symbol");
        if s as usize >= q {
            problems.push(Problem::new(
                path,
                format!(
                    "symbol value {s} is ≥ the number of symbol categories ({q}); use 0 to {}",
                    q - 1
                ),
            ));
        } else if let Some(first) = by_value[s as usize].replace(i) {
            problems.push(Problem::new(
                path,
                format!("symbol value {s} is already used by categories[{first}]"),
            ));
        }
    }
    by_value.into_iter().map(|c| c.unwrap_or(0)).collect()
}

fn layout_keypoints(
    spec: &FamilySpec,
    names: &HashMap<&str, usize>,
    problems: &mut Vec<Problem>,
) -> (Vec<Keypoint>, Extent, f64) {
    let mut keypoints = Vec::new();
    let mut next_symbol = 0;
    let mut symbol = || {
        next_symbol += 1;
        Assignment::Symbol(next_symbol - 1)
    };
    let empty = Extent {
        min: [0.0; 2],
        max: [0.0; 2],
    };
    let (mut extent, quiet_zone) = match &spec.layout {
        Layout::Grid(GridLayout {
            size,
            cells,
            legend,
            quiet_zone,
        }) => {
            let n = *size;
            if n == 0 || n > MAX_GRID {
                problems.push(Problem::new(
                    "layout.size",
                    format!("a grid of {n}×{n} cells is outside 1×1 to {MAX_GRID}×{MAX_GRID}"),
                ));
                return (keypoints, empty, 0.0);
            }
            let mut fixed: HashMap<char, usize> = HashMap::new();
            for (key, name) in legend {
                let path = format!("layout.legend.{key}");
                let mut chars = key.chars();
                match (chars.next(), chars.next()) {
                    (Some(c), None) if c != '.' && c != '-' => match names.get(name.as_str()) {
                        Some(&cat) => {
                            fixed.insert(c, cat);
                        }
                        None => problems.push(Problem::new(
                            path,
                            format!("unknown category {}", quoted(name)),
                        )),
                    },
                    _ => problems.push(Problem::new(
                        path,
                        "legend keys are single characters other than '.' and '-'",
                    )),
                }
            }
            if cells.len() != n as usize {
                problems.push(Problem::new(
                    "layout.cells",
                    format!("{} rows for a grid of size {n}", cells.len()),
                ));
                return (keypoints, empty, 0.0);
            }
            for (row, line) in cells.iter().enumerate() {
                let path = format!("layout.cells[{row}]");
                if line.chars().count() != n as usize {
                    problems.push(Problem::new(
                        path,
                        format!(
                            "{} cells in a row of a grid of size {n}",
                            line.chars().count()
                        ),
                    ));
                    continue;
                }
                for (col, c) in line.chars().enumerate() {
                    let assignment = match c {
                        '-' => continue,
                        '.' => symbol(),
                        c => match fixed.get(&c) {
                            Some(&cat) => Assignment::Fixed(cat),
                            None => {
                                problems.push(Problem::new(
                                    path.clone(),
                                    format!("{c:?} in column {col} is not '.', '-' or a key of layout.legend"),
                                ));
                                continue;
                            }
                        },
                    };
                    keypoints.push(Keypoint {
                        pos: [col as f64 + 0.5, row as f64 + 0.5],
                        size: 1.0,
                        assignment,
                    });
                }
            }
            let qz = check_quiet_zone("layout.quiet_zone", *quiet_zone, n as f64, problems);
            (
                Extent {
                    min: [0.0; 2],
                    max: [n as f64; 2],
                },
                qz,
            )
        }
        Layout::Rings(RingsLayout {
            radii,
            slots,
            dot_radius_ratio,
            start_angle_deg,
            quiet_zone,
        }) => {
            let ok = check_rings(radii, *slots, *dot_radius_ratio, *start_angle_deg, problems);
            if !ok {
                return (keypoints, empty, 0.0);
            }
            let step = std::f64::consts::TAU / *slots as f64;
            for slot in 0..*slots {
                let angle = start_angle_deg.to_radians() + slot as f64 * step;
                let (s, c) = angle.sin_cos();
                for r in radii {
                    keypoints.push(Keypoint {
                        pos: [r * c, r * s],
                        size: 2.0 * r * dot_radius_ratio,
                        assignment: symbol(),
                    });
                }
            }
            let reach = radii
                .iter()
                .map(|r| r * (1.0 + dot_radius_ratio))
                .fold(0.0, f64::max);
            let qz = check_quiet_zone("layout.quiet_zone", *quiet_zone, reach, problems);
            (
                Extent {
                    min: [-reach; 2],
                    max: [reach; 2],
                },
                qz,
            )
        }
    };
    let first_extra = keypoints.len();
    for (i, e) in spec.extra.iter().enumerate() {
        let path = format!("extra[{i}]");
        let finite = |v: f64| v.is_finite() && v.abs() <= MAX_COORD;
        if !finite(e.x) || !finite(e.y) {
            problems.push(Problem::new(
                path.clone(),
                format!("position must be within ±{MAX_COORD}"),
            ));
            continue;
        }
        if !(e.size.is_finite() && e.size > 0.0 && e.size <= MAX_COORD) {
            problems.push(Problem::new(
                format!("{path}.size"),
                "must be a positive number",
            ));
            continue;
        }
        let assignment = if e.category == "." {
            symbol()
        } else if let Some(&cat) = names.get(e.category.as_str()) {
            Assignment::Fixed(cat)
        } else {
            problems.push(Problem::new(
                format!("{path}.category"),
                format!("unknown category {}", quoted(&e.category)),
            ));
            continue;
        };
        let h = e.size / 2.0;
        extent.min = [extent.min[0].min(e.x - h), extent.min[1].min(e.y - h)];
        extent.max = [extent.max[0].max(e.x + h), extent.max[1].max(e.y + h)];
        keypoints.push(Keypoint {
            pos: [e.x, e.y],
            size: e.size,
            assignment,
        });
    }
    if keypoints.len() > MAX_KEYPOINTS {
        problems.push(Problem::new(
            "layout",
            format!(
                "{} keypoints is over the limit of {MAX_KEYPOINTS}",
                keypoints.len()
            ),
        ));
    } else {
        // Only now: it compares every pair of keypoints, hours of work for a million extras.
        check_overlaps(&keypoints, first_extra, problems);
    }
    (keypoints, extent, quiet_zone)
}

fn check_quiet_zone(path: &str, qz: f64, scale: f64, problems: &mut Vec<Problem>) -> f64 {
    if qz.is_finite() && qz >= 0.0 && qz <= 10.0 * scale {
        qz
    } else {
        problems.push(Problem::new(
            path,
            format!("{qz} must be between 0 and {}", 10.0 * scale),
        ));
        0.0
    }
}

fn check_rings(
    radii: &[f64],
    slots: u32,
    ratio: f64,
    start: f64,
    problems: &mut Vec<Problem>,
) -> bool {
    let before = problems.len();
    if radii.is_empty() || radii.len() > MAX_RINGS {
        problems.push(Problem::new(
            "layout.radii",
            format!("1 to {MAX_RINGS} rings, got {}", radii.len()),
        ));
    }
    for (i, r) in radii.iter().enumerate() {
        if !(r.is_finite() && *r > 0.0 && *r <= MAX_COORD) {
            problems.push(Problem::new(
                format!("layout.radii[{i}]"),
                format!("{r} must be a positive number"),
            ));
        } else if i > 0 && *r <= radii[i - 1] {
            problems.push(Problem::new(
                format!("layout.radii[{i}]"),
                "radii must increase from the inner ring outwards",
            ));
        }
    }
    if slots == 0 || slots > MAX_SLOTS {
        problems.push(Problem::new(
            "layout.slots",
            format!("{slots} slots: must be 1 to {MAX_SLOTS}"),
        ));
    }
    if !(ratio.is_finite() && ratio > 0.0 && ratio < 0.5) {
        problems.push(Problem::new(
            "layout.dot_radius_ratio",
            format!("{ratio} must be in (0, 0.5)"),
        ));
    }
    if !start.is_finite() {
        problems.push(Problem::new(
            "layout.start_angle_deg",
            "must be a finite number",
        ));
    }
    if problems.len() > before {
        return false;
    }
    let spacing = |r: f64| 2.0 * r * (std::f64::consts::PI / slots as f64).sin();
    for (i, r) in radii.iter().enumerate() {
        if slots > 1 && spacing(*r) < 2.0 * r * ratio {
            problems.push(Problem::new(
                format!("layout.radii[{i}]"),
                format!("the {slots} dots of this ring overlap: fewer slots or a smaller dot_radius_ratio"),
            ));
        }
        if i > 0 && r - radii[i - 1] < (r + radii[i - 1]) * ratio {
            problems.push(Problem::new(
                format!("layout.radii[{i}]"),
                "the dots of this ring overlap those of the ring inside it",
            ));
        }
    }
    problems.len() == before
}

/// Extra keypoints must not sit on another keypoint: two patterns at one place cannot both be read.
fn check_overlaps(keypoints: &[Keypoint], first_extra: usize, problems: &mut Vec<Problem>) {
    for i in first_extra..keypoints.len() {
        let a = &keypoints[i];
        if let Some(b) = keypoints[..i]
            .iter()
            .find(|b| (a.pos[0] - b.pos[0]).hypot(a.pos[1] - b.pos[1]) < 0.25 * a.size.min(b.size))
        {
            problems.push(Problem::new(
                format!("extra[{}]", i - first_extra),
                format!(
                    "sits on another keypoint at ({:.3}, {:.3}); each keypoint needs its own place",
                    b.pos[0], b.pos[1]
                ),
            ));
        }
    }
}

fn check_print(spec: &FamilySpec, problems: &mut Vec<Problem>) {
    // A printable marker: below 1 mm no printer draws the cells, and a denormal side (5e-324)
    // turned into a NaN-sized image further on; above 2 m is no sheet or print job.
    let s = spec.print.marker_side_mm;
    if !(s.is_finite() && (MIN_MARKER_SIDE_MM..=MAX_MARKER_SIDE_MM).contains(&s)) {
        problems.push(Problem::new(
            "print.marker_side_mm",
            format!("{s} must be in [{MIN_MARKER_SIDE_MM}, {MAX_MARKER_SIDE_MM}] mm"),
        ));
    }
}

fn check_keypoint_set(spec: &FamilySpec, n: usize, problems: &mut Vec<Problem>) {
    match &spec.keypoint_set {
        KeypointSet::Custom(list) => {
            let mut seen = vec![false; n];
            for (i, &k) in list.iter().enumerate() {
                let path = format!("keypoint_set.custom[{i}]");
                match seen.get_mut(k as usize) {
                    None => problems.push(Problem::new(
                        path,
                        format!("keypoint {k} does not exist (the family has {n})"),
                    )),
                    Some(s) if *s => {
                        problems.push(Problem::new(path, format!("keypoint {k} is listed twice")))
                    }
                    Some(s) => *s = true,
                }
            }
            if list.is_empty() {
                problems.push(Problem::new("keypoint_set.custom", "the list is empty"));
            }
        }
        KeypointSet::Corners if !matches!(spec.layout, Layout::Grid(_)) => {
            problems.push(Problem::new(
                "keypoint_set",
                "\"corners\" needs a grid layout",
            ));
        }
        _ => {}
    }
}

fn check_roi(spec: &FamilySpec, problems: &mut Vec<Problem>) {
    let pts = &spec.roi.points;
    if pts.len() < 4 {
        problems.push(Problem::new(
            "roi.points",
            format!(
                "needs at least 4 points to fix a homography, got {}",
                pts.len()
            ),
        ));
        return;
    }
    for (i, p) in pts.iter().enumerate() {
        if !p.iter().all(|v| v.is_finite() && v.abs() <= MAX_COORD) {
            problems.push(Problem::new(
                format!("roi.points[{i}]"),
                format!("coordinates must be within ±{MAX_COORD}"),
            ));
            return;
        }
    }
    let q = &pts[..4];
    let scale = q
        .iter()
        .flat_map(|a| q.iter().map(move |b| (a[0] - b[0]).hypot(a[1] - b[1])))
        .fold(0.0, f64::max);
    let cross = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    for (i, j, k) in [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)] {
        if cross(q[i], q[j], q[k]).abs() <= 1e-6 * scale * scale {
            problems.push(Problem::new(
                "roi.points",
                format!("points {i}, {j} and {k} are collinear (or coincide): they cannot fix a homography"),
            ));
            return;
        }
    }
    // With y down, a clockwise TL→TR→BR→BL quadrilateral turns the same way at every corner.
    let turns: Vec<f64> = (0..4)
        .map(|i| cross(q[i], q[(i + 1) % 4], q[(i + 2) % 4]))
        .collect();
    if !turns.iter().all(|&t| t > 0.0) {
        let why = if turns.iter().all(|&t| t < 0.0) {
            "they run counter-clockwise"
        } else {
            "they do not form a convex quadrilateral"
        };
        problems.push(Problem::new(
            "roi.points",
            format!("the first four points must be the corners TL, TR, BR, BL in clockwise order; {why}"),
        ));
    }
    let a = spec.roi.margin;
    if !(a.is_finite() && (0.0..0.45).contains(&a)) {
        problems.push(Problem::new(
            "roi.margin",
            format!("{a} must be in [0, 0.45)"),
        ));
    }
}
