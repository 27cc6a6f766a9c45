//! Printable sheets: markers at an exact physical size laid out on pages, with labels, cut marks
//! and a 100 mm scale bar to check that the print came out at 100 %.

use super::scene::{marker_scene, RenderError, SceneOptions};
use super::svg::{marker_group, num};
use crate::family::Family;
use svg::node::element::{Group, Line, Rectangle, Text};
use svg::Document;

/// A page size or ID list that cannot be read; each names the text that failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SheetError {
    #[error("page {text:?}: use a4, a3, letter or WIDTHxHEIGHT in mm")]
    PageName { text: String },
    #[error("page {text:?}: width and height must be 10 to 5000 mm")]
    PageSize { text: String },
    #[error("{id:?} in {text:?} is not an ID")]
    NotAnId { id: String, text: String },
    #[error("range {range:?} runs backwards")]
    Backwards { range: String },
    #[error("range {range:?} is too long")]
    TooLong { range: String },
    #[error("more than {max} IDs; print them in several sheets")]
    TooMany { max: usize },
    #[error("no IDs given")]
    NoIds,
}

/// Page size in mm (portrait).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PageSize {
    pub width_mm: f64,
    pub height_mm: f64,
}

impl PageSize {
    pub const A4: PageSize = PageSize {
        width_mm: 210.0,
        height_mm: 297.0,
    };
    pub const A3: PageSize = PageSize {
        width_mm: 297.0,
        height_mm: 420.0,
    };
    pub const LETTER: PageSize = PageSize {
        width_mm: 215.9,
        height_mm: 279.4,
    };

    /// `a4`, `a3`, `letter`, or `WIDTHxHEIGHT` in mm (e.g. `100x150`).
    pub fn parse(text: &str) -> Result<Self, SheetError> {
        match text.to_ascii_lowercase().as_str() {
            "a4" => Ok(Self::A4),
            "a3" => Ok(Self::A3),
            "letter" => Ok(Self::LETTER),
            other => {
                let (w, h) = other
                    .split_once('x')
                    .ok_or_else(|| SheetError::PageName { text: text.into() })?;
                let parse = |s: &str| {
                    s.trim()
                        .parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite() && *v >= 10.0 && *v <= 5000.0)
                };
                match (parse(w), parse(h)) {
                    (Some(w), Some(h)) => Ok(Self {
                        width_mm: w,
                        height_mm: h,
                    }),
                    _ => Err(SheetError::PageSize { text: text.into() }),
                }
            }
        }
    }

    pub fn landscape(self) -> Self {
        Self {
            width_mm: self.height_mm.max(self.width_mm),
            height_mm: self.height_mm.min(self.width_mm),
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct SheetParams {
    pub page: PageSize,
    pub margin_mm: f64,
    /// Marker size: distance between ROI corners (square tags: outer black square side).
    pub marker_side_mm: f64,
    /// Gap between neighbouring markers' quiet zones.
    pub spacing_mm: f64,
    pub ids: Vec<usize>,
    pub labels: bool,
    pub cut_marks: bool,
    /// Quiet zone in marker units; default: the family's.
    pub quiet_zone: Option<f64>,
}

impl SheetParams {
    pub fn new(family: &Family, ids: Vec<usize>) -> Self {
        Self {
            page: PageSize::A4,
            margin_mm: 10.0,
            marker_side_mm: family.spec().print.marker_side_mm,
            spacing_mm: 6.0,
            ids,
            labels: family.spec().print.labels,
            cut_marks: false,
            quiet_zone: None,
        }
    }
}

/// A laid-out sheet: one SVG document per page.
#[derive(Debug, Clone)]
pub struct Sheet {
    pub pages: Vec<String>,
    pub page: PageSize,
    pub markers_per_page: usize,
    pub warnings: Vec<String>,
}

const HEADER_MM: f64 = 9.0;
const FOOTER_MM: f64 = 14.0;
const LABEL_MM: f64 = 4.5;
const FONT: &str = "DejaVu Sans";
const SCALE_BAR_MM: f64 = 100.0;

/// The most markers one sheet command lays out: every built-in family fits, and laying out more
/// (2000 copies of `0-586` took minutes) is a typing mistake rather than a print job.
pub const MAX_IDS: usize = 10_000;

/// Parses `0-47`, `3,5,9-12` into IDs, at most `max` of them; a list that would exceed `max` is
/// refused as soon as a range would pass it, before the range is expanded.
pub fn parse_ids(text: &str, max: usize) -> Result<Vec<usize>, SheetError> {
    let mut ids = Vec::new();
    for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let num = |s: &str| {
            s.trim().parse::<usize>().map_err(|_| SheetError::NotAnId {
                id: s.into(),
                text: text.into(),
            })
        };
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b) = (num(a)?, num(b)?);
                let range = || part.to_string();
                if a > b {
                    return Err(SheetError::Backwards { range: range() });
                }
                if b - a > 1_000_000 {
                    return Err(SheetError::TooLong { range: range() });
                }
                if ids.len() + (b - a) >= max {
                    return Err(SheetError::TooMany { max });
                }
                ids.extend(a..=b);
            }
            None => {
                if ids.len() >= max {
                    return Err(SheetError::TooMany { max });
                }
                ids.push(num(part)?)
            }
        }
    }
    if ids.is_empty() {
        return Err(SheetError::NoIds);
    }
    Ok(ids)
}

/// The file name of page `page` (from 1) of a sheet of several SVG pages written as
/// `STEM.svg`: `STEM-1.svg`, `STEM-2.svg`, …
pub fn svg_page_name(stem: &str, page: usize) -> String {
    format!("{stem}-{page}.svg")
}

/// The page files in `dir` that a sheet of `pages` numbered SVG pages named `stem` does not
/// write, but a longer one of the same name did: `STEM-N.svg` with N > `pages`, exactly that
/// pattern (N decimal, no leading zero), regular files only. A sheet written as a single
/// `STEM.svg` has no numbered pages: `pages` is 0 and every `STEM-N.svg` is stale.
pub fn stale_svg_pages(
    dir: &std::path::Path,
    stem: &str,
    pages: usize,
) -> std::io::Result<Vec<std::path::PathBuf>> {
    let dir = if dir.as_os_str().is_empty() {
        std::path::Path::new(".")
    } else {
        dir
    };
    let mut stale = Vec::new();
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let name = entry.file_name();
        let Some(n) = name.to_str().and_then(|n| {
            n.strip_prefix(stem)?
                .strip_prefix('-')?
                .strip_suffix(".svg")
        }) else {
            continue;
        };
        let numbered =
            !n.is_empty() && !n.starts_with('0') && n.bytes().all(|b| b.is_ascii_digit());
        // A number too long for usize is past any page count.
        if numbered
            && n.parse::<usize>().map_or(true, |n| n > pages)
            && entry.file_type()?.is_file()
        {
            stale.push(entry.path());
        }
    }
    stale.sort();
    Ok(stale)
}

pub fn layout_sheet(family: &Family, params: &SheetParams) -> Result<Sheet, RenderError> {
    let page = params.page;
    let bad = |m: String| RenderError::Layout(m);
    let non_negative = |v: f64| v.is_finite() && v >= 0.0;
    if !non_negative(params.margin_mm) || !non_negative(params.spacing_mm) {
        return Err(bad("margins and spacing must be ≥ 0 mm".into()));
    }
    if params.ids.is_empty() {
        return Err(bad("no IDs to print".into()));
    }
    let last = family.codebook().len();
    if let Some(&id) = params.ids.iter().find(|&&id| id >= last) {
        return Err(RenderError::NoSuchId {
            family: family.name().into(),
            id,
            last: last.saturating_sub(1),
        });
    }
    let options = SceneOptions {
        side_mm: Some(params.marker_side_mm),
        quiet_zone: params.quiet_zone,
    };
    let probe = marker_scene(family, params.ids[0], options)?;
    let tile_w = probe.width_mm;
    let tile_h = probe.height_mm + if params.labels { LABEL_MM } else { 0.0 };
    let usable_w = page.width_mm - 2.0 * params.margin_mm;
    let usable_h = page.height_mm - 2.0 * params.margin_mm - HEADER_MM - FOOTER_MM;
    let fit = |usable: f64, tile: f64| {
        ((usable + params.spacing_mm) / (tile + params.spacing_mm) + 1e-9)
            .floor()
            .max(0.0) as usize
    };
    let (cols, rows) = (fit(usable_w, tile_w), fit(usable_h, tile_h));
    if cols == 0 || rows == 0 {
        return Err(bad(format!(
            "a {:.1} × {:.1} mm marker (quiet zone{} included) does not fit the {:.1} × {:.1} mm \
             printable area of a {} × {} mm page with {} mm margins",
            tile_w,
            tile_h,
            if params.labels { " and label" } else { "" },
            usable_w.max(0.0),
            usable_h.max(0.0),
            page.width_mm,
            page.height_mm,
            params.margin_mm
        )));
    }

    let mut warnings = Vec::new();
    let qz = params.quiet_zone.unwrap_or(family.quiet_zone());
    if family.quiet_zone_is_thin(qz) {
        warnings.push(format!(
            "the quiet zone ({:.2} mm) is thinner than one cell ({:.2} mm): detectors need a light margin",
            qz * probe.scale,
            family.cell_size() * probe.scale
        ));
    }
    let mut cut_marks = params.cut_marks;
    if cut_marks && params.spacing_mm < 2.0 {
        warnings.push(format!(
            "no cut marks: they need at least 2 mm between markers (spacing is {} mm)",
            params.spacing_mm
        ));
        cut_marks = false;
    }
    if usable_w < SCALE_BAR_MM {
        warnings.push(format!(
            "the page is too narrow for the {SCALE_BAR_MM} mm scale bar; it is shortened"
        ));
    }

    let per_page = cols * rows;
    let page_count = params.ids.len().div_ceil(per_page);
    // Centre the block of markers horizontally.
    let block_w = cols as f64 * tile_w + (cols - 1) as f64 * params.spacing_mm;
    let x0 = params.margin_mm + (usable_w - block_w) / 2.0;
    let y0 = params.margin_mm + HEADER_MM;

    let mut pages = Vec::with_capacity(page_count);
    for (p, ids) in params.ids.chunks(per_page).enumerate() {
        let mut doc = Document::new()
            .set("width", format!("{}mm", num(page.width_mm)))
            .set("height", format!("{}mm", num(page.height_mm)))
            .set(
                "viewBox",
                format!("0 0 {} {}", num(page.width_mm), num(page.height_mm)),
            )
            .add(
                Rectangle::new()
                    .set("width", num(page.width_mm))
                    .set("height", num(page.height_mm))
                    .set("fill", "#ffffff"),
            )
            .add(header(family, params, p, page_count));
        for (n, &id) in ids.iter().enumerate() {
            let (col, row) = (n % cols, n / cols);
            let x = x0 + col as f64 * (tile_w + params.spacing_mm);
            let y = y0 + row as f64 * (tile_h + params.spacing_mm);
            let scene = marker_scene(family, id, options)?;
            let mut g = marker_group(&scene, x, y)
                .set("class", "marker")
                .set("id", format!("marker-{id}"));
            if params.labels {
                g = g.add(label(
                    family,
                    id,
                    params.marker_side_mm,
                    x,
                    y + scene.height_mm,
                    tile_w,
                ));
            }
            if cut_marks {
                // Around the marker and its label, so a cut-out marker keeps its ID.
                g = g.add(cut_mark_group(tile_w, tile_h, x, y, params.spacing_mm));
            }
            doc = doc.add(g);
        }
        doc = doc.add(scale_bar(
            params.margin_mm,
            page.height_mm - params.margin_mm - 6.0,
            usable_w,
        ));
        pages.push(doc.to_string());
    }
    Ok(Sheet {
        pages,
        page,
        markers_per_page: per_page,
        warnings,
    })
}

fn text(x: f64, y: f64, size: f64, content: impl Into<String>) -> Text {
    Text::new(content.into())
        .set("x", num(x))
        .set("y", num(y))
        .set("font-family", FONT)
        .set("font-size", num(size))
        .set("fill", "#000000")
}

fn header(family: &Family, params: &SheetParams, page: usize, pages: usize) -> Group {
    let m = params.margin_mm;
    Group::new()
        .set("class", "header")
        .add(text(
            m,
            m + 4.0,
            3.5,
            format!(
                "{} — tag size {:.1} mm, corner to corner",
                family.title(),
                params.marker_side_mm
            ),
        ))
        .add(
            text(params.page.width_mm - m, m + 4.0, 3.0, format!("page {} / {}", page + 1, pages))
                .set("text-anchor", "end"),
        )
        .add(text(
            m,
            m + 7.5,
            2.3,
            "Tag size = distance between the ROI corners (square tags: the side of the outer black square).",
        ))
}

fn label(family: &Family, id: usize, side: f64, x: f64, y: f64, width: f64) -> Text {
    text(
        x + width / 2.0,
        y + 3.2,
        2.6,
        format!("{} · ID {id} · {side:.1} mm", family.name()),
    )
    .set("text-anchor", "middle")
    .set("class", "label")
}

/// Corner marks in the gap around a tile (marker, quiet zone and label), never over it.
fn cut_mark_group(w: f64, h: f64, x: f64, y: f64, spacing: f64) -> Group {
    let gap = 0.5;
    let len = (spacing / 2.0 - gap).clamp(0.5, 4.0);
    let mut g = Group::new()
        .set("class", "cut-marks")
        .set("stroke", "#808080")
        .set("stroke-width", "0.15");
    for (cx, cy, sx, sy) in [
        (x, y, -1.0, -1.0),
        (x + w, y, 1.0, -1.0),
        (x + w, y + h, 1.0, 1.0),
        (x, y + h, -1.0, 1.0),
    ] {
        // One horizontal and one vertical tick, each continuing a side of the marker outward.
        g = g
            .add(line(cx + sx * gap, cy, cx + sx * (gap + len), cy))
            .add(line(cx, cy + sy * gap, cx, cy + sy * (gap + len)));
    }
    g
}

fn line(x1: f64, y1: f64, x2: f64, y2: f64) -> Line {
    Line::new()
        .set("x1", num(x1))
        .set("y1", num(y1))
        .set("x2", num(x2))
        .set("y2", num(y2))
}

fn scale_bar(x: f64, y: f64, usable_w: f64) -> Group {
    let length = if usable_w >= SCALE_BAR_MM {
        SCALE_BAR_MM
    } else {
        (usable_w / 10.0).floor() * 10.0
    };
    let mut g = Group::new().set("class", "scale-bar").add(
        Rectangle::new()
            .set("x", num(x))
            .set("y", num(y - 1.0))
            .set("width", num(length))
            .set("height", "1")
            .set("fill", "#000000"),
    );
    let ticks = (length / 10.0).round() as usize;
    let mut ticks_group = Group::new()
        .set("stroke", "#000000")
        .set("stroke-width", "0.2");
    for i in 0..=ticks {
        let tx = x + i as f64 * 10.0;
        ticks_group = ticks_group.add(line(tx, y - 3.0, tx, y - 1.0));
    }
    g = g
        .add(ticks_group)
        .add(text(x + length + 2.0, y, 2.5, format!("{length:.0} mm")))
        .add(text(
            x,
            y + 4.0,
            2.3,
            format!("Print at 100 % (no \"fit to page\") and check that this bar measures {length:.0} mm."),
        ));
    g
}

#[cfg(test)]
mod tests {
    #[test]
    fn stale_svg_pages_are_exactly_the_numbered_pages_past_the_count() {
        let dir = tempfile::tempdir().unwrap();
        for name in [
            "p-1.svg",
            "p-2.svg",
            "p-3.svg",
            "p-10.svg",
            "p-03.svg",
            "p-x.svg",
            "p-.svg",
            "p.svg",
            "p-4.png",
            "q-4.svg",
            "p-2-1.svg",
            "pp-4.svg",
        ] {
            std::fs::write(dir.path().join(name), "x").unwrap();
        }
        std::fs::create_dir(dir.path().join("p-7.svg")).unwrap();
        let names = |pages| -> Vec<String> {
            super::stale_svg_pages(dir.path(), "p", pages)
                .unwrap()
                .iter()
                .map(|p| p.file_name().unwrap().to_str().unwrap().to_string())
                .collect()
        };
        assert_eq!(names(2), ["p-10.svg", "p-3.svg"]);
        assert_eq!(names(0), ["p-1.svg", "p-10.svg", "p-2.svg", "p-3.svg"]);
        assert!(names(10).is_empty());
        assert_eq!(super::svg_page_name("p", 3), "p-3.svg");
    }

    use super::*;

    #[test]
    fn id_lists_and_ranges() {
        assert_eq!(
            parse_ids("0-3,7, 9", MAX_IDS).unwrap(),
            vec![0, 1, 2, 3, 7, 9]
        );
        assert_eq!(
            parse_ids("1, 5-2", MAX_IDS),
            Err(SheetError::Backwards {
                range: "5-2".into()
            })
        );
        assert_eq!(
            parse_ids("x", MAX_IDS).unwrap_err().to_string(),
            r#""x" in "x" is not an ID"#
        );
        assert_eq!(parse_ids("", MAX_IDS), Err(SheetError::NoIds));
        // The bound counts every ID a range stands for, and is reached exactly.
        assert_eq!(parse_ids("0-4", 5).unwrap().len(), 5);
        assert_eq!(parse_ids("0-5", 5), Err(SheetError::TooMany { max: 5 }));
        assert_eq!(parse_ids("0-4,7", 5), Err(SheetError::TooMany { max: 5 }));
        let huge = vec!["0-586"; 2000].join(",");
        assert_eq!(
            parse_ids(&huge, MAX_IDS),
            Err(SheetError::TooMany { max: MAX_IDS })
        );
    }

    #[test]
    fn page_sizes() {
        assert_eq!(PageSize::parse("A4").unwrap(), PageSize::A4);
        assert_eq!(
            PageSize::parse("100x150").unwrap(),
            PageSize {
                width_mm: 100.0,
                height_mm: 150.0
            }
        );
        assert_eq!(
            PageSize::parse("1x1"),
            Err(SheetError::PageSize { text: "1x1".into() })
        );
        assert!(matches!(
            PageSize::parse("a5"),
            Err(SheetError::PageName { .. })
        ));
        assert_eq!(PageSize::A4.landscape().width_mm, 297.0);
    }
}
