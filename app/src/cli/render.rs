//! `render` and `sheet`: markers to SVG, PNG and printable pages.

use super::common::{extension, f64_in, load_family, write_output};
use super::error::{bad_input, failure, Classify, CliError, Concerning, Result};
use anyhow::Context;
use clap::Args;
use std::path::{Path, PathBuf};
use tagsmith::render::sheet::{
    layout_sheet, parse_ids, stale_svg_pages, svg_page_name, PageSize, SheetParams, MAX_IDS,
};
use tagsmith::render::{marker_scene, pdf, raster, svg, RenderError, SceneOptions};

/// The marker sizes a family file may declare (`print.marker_side_mm`): 1 mm to 2 m.
const SIDE_MM: (f64, f64) = (1.0, 2000.0);
/// A quiet zone wider than 100 cells only makes the page or image empty.
const QUIET_ZONE: (f64, f64) = (0.0, 100.0);
/// Margins and spacing beyond 1 m leave no room on any page.
const GAP_MM: (f64, f64) = (0.0, 1000.0);

/// Names the option a rendering error is about: the ID (`--id`, `--ids`) or the size options
/// (a marker that does not fit, a raster that cannot be made).
fn naming_options(e: RenderError, ids: &str, sizes: &str) -> CliError {
    let what = match e {
        RenderError::NoSuchId { .. } => ids,
        // Encoding fails for want of memory or space, not for an option.
        RenderError::Encode(_) => return e.into(),
        _ => sizes,
    };
    CliError::from(e).concerning(what)
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Built-in family name or path to a family JSON file.
    pub family: String,
    #[arg(long)]
    pub id: usize,
    /// Tag size in mm: the distance between ROI corners (the outer black square's side)
    /// [range: [1, 2000]].
    #[arg(long, value_parser = f64_in(SIDE_MM.0, SIDE_MM.1))]
    pub size_mm: Option<f64>,
    /// PNG only: image width in pixels, quiet zone included [range: 1..=20000] [default: 512].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=20_000))]
    pub px: Option<u32>,
    /// Quiet zone in cells (marker units) [range: [0, 100]] [default: the family's].
    #[arg(long, value_parser = f64_in(QUIET_ZONE.0, QUIET_ZONE.1))]
    pub quiet_zone: Option<f64>,
    /// Output file: .svg or .png.
    #[arg(short, long)]
    pub output: PathBuf,
}

impl RenderArgs {
    pub fn run(self) -> Result<()> {
        let family = load_family(&self.family)?;
        let options = SceneOptions {
            side_mm: self.size_mm,
            quiet_zone: self.quiet_zone,
        };
        let scene = marker_scene(&family, self.id, options)
            .map_err(|e| naming_options(e, "--id", "--size-mm, --quiet-zone"))?;
        let bytes = match extension(&self.output).as_str() {
            "svg" => {
                if self.px.is_some() {
                    eprintln!("note: --px applies to PNG output only; the SVG is sized in mm");
                }
                svg::marker_svg(&scene).into_bytes()
            }
            "png" => {
                let pixmap = raster::rasterize_width(&scene, self.px.unwrap_or(512))
                    .map_err(|e| naming_options(e, "--id", "--px"))?;
                raster::encode_png(&pixmap)?
            }
            other => {
                return Err(bad_input!(
                    "output {:?}: use .svg or .png, not {other:?}",
                    self.output
                ))
            }
        };
        for w in tagsmith::render::readback::warnings(&family) {
            eprintln!("warning: {w}");
        }
        write_output(&self.output, &bytes)?;
        println!(
            "wrote {} ({} ID {}, tag size {:.1} mm corner to corner, {:.1} × {:.1} mm with quiet zone)",
            self.output.display(),
            family.name(),
            self.id,
            scene.scale * family.roi_side(),
            scene.width_mm,
            scene.height_mm
        );
        Ok(())
    }
}

/// Removes the `STEM-N.svg` pages beside `output` past the `pages` just written (0 when the
/// sheet was one `STEM.svg`).
fn remove_stale_pages(output: &Path, stem: &str, pages: usize) -> Result<()> {
    let dir = output.parent().unwrap_or(Path::new(""));
    let stale = stale_svg_pages(dir, stem, pages)
        .with_context(|| format!("cannot list the old pages beside {}", output.display()))
        .failure()?;
    for path in stale {
        match std::fs::remove_file(&path) {
            Ok(()) => eprintln!("removed {}, a page of an earlier sheet", path.display()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => {
                return Err(failure!(
                    "cannot remove {}, a page of an earlier sheet: {e}",
                    path.display()
                ))
            }
        }
    }
    Ok(())
}

#[derive(Args, Debug)]
pub struct SheetArgs {
    /// Built-in family name or path to a family JSON file.
    pub family: String,
    /// IDs to print: ranges and lists, e.g. 0-47 or 1,5,9-12; at most 10000 markers.
    #[arg(long)]
    pub ids: String,
    /// a4, a3, letter, or WIDTHxHEIGHT in mm.
    #[arg(long, default_value = "a4")]
    pub page: String,
    #[arg(long)]
    pub landscape: bool,
    /// Tag size in mm: the distance between ROI corners (the outer black square's side)
    /// [range: [1, 2000]].
    #[arg(long, value_parser = f64_in(SIDE_MM.0, SIDE_MM.1))]
    pub size_mm: Option<f64>,
    /// Page margin in mm [range: [0, 1000]].
    #[arg(long, default_value_t = 10.0, value_parser = f64_in(GAP_MM.0, GAP_MM.1))]
    pub margin_mm: f64,
    /// Gap between neighbouring markers' quiet zones in mm [range: [0, 1000]].
    #[arg(long, default_value_t = 6.0, value_parser = f64_in(GAP_MM.0, GAP_MM.1))]
    pub spacing_mm: f64,
    /// Print family, ID and size under each marker.
    #[arg(long)]
    pub labels: bool,
    #[arg(long)]
    pub cut_marks: bool,
    /// Quiet zone in cells (marker units) [range: [0, 100]] [default: the family's].
    #[arg(long, value_parser = f64_in(QUIET_ZONE.0, QUIET_ZONE.1))]
    pub quiet_zone: Option<f64>,
    /// Output: .pdf, or .svg (several pages are written as NAME-1.svg, NAME-2.svg, …).
    #[arg(short, long)]
    pub output: PathBuf,
}

impl SheetArgs {
    pub fn run(self) -> Result<()> {
        let family = load_family(&self.family)?;
        let ids = parse_ids(&self.ids, MAX_IDS).concerning("--ids")?;
        let mut page = PageSize::parse(&self.page).concerning("--page")?;
        if self.landscape {
            page = page.landscape();
        }
        let mut params = SheetParams::new(&family, ids);
        params.page = page;
        params.margin_mm = self.margin_mm;
        params.spacing_mm = self.spacing_mm;
        params.labels = self.labels;
        params.cut_marks = self.cut_marks;
        params.quiet_zone = self.quiet_zone;
        if let Some(s) = self.size_mm {
            params.marker_side_mm = s;
        }
        let sheet = layout_sheet(&family, &params).map_err(|e| {
            naming_options(
                e,
                "--ids",
                "--size-mm, --page, --margin-mm, --spacing-mm, --quiet-zone",
            )
        })?;
        for w in &sheet.warnings {
            eprintln!("warning: {w}");
        }
        let written: Vec<PathBuf> = match extension(&self.output).as_str() {
            "pdf" => {
                let bytes = pdf::sheet_pdf(&sheet)?;
                write_output(&self.output, &bytes)?;
                vec![self.output.clone()]
            }
            "svg" => {
                let stem = self
                    .output
                    .file_stem()
                    .and_then(|s| s.to_str())
                    .unwrap_or("sheet");
                let out = if sheet.pages.len() == 1 {
                    write_output(&self.output, sheet.pages[0].as_bytes())?;
                    vec![self.output.clone()]
                } else {
                    let mut out = Vec::new();
                    for (i, page) in sheet.pages.iter().enumerate() {
                        let path = self.output.with_file_name(svg_page_name(stem, i + 1));
                        write_output(&path, page.as_bytes())?;
                        out.push(path);
                    }
                    out
                };
                // Only once every new page is written: the pages of an earlier, longer sheet of
                // the same name would otherwise print with this one.
                let numbered = if sheet.pages.len() == 1 {
                    0
                } else {
                    sheet.pages.len()
                };
                remove_stale_pages(&self.output, stem, numbered)?;
                out
            }
            other => {
                return Err(bad_input!(
                    "output {:?}: use .pdf or .svg, not {other:?}",
                    self.output
                ))
            }
        };
        let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
        println!(
            "wrote {} ({} markers, {} per page, {} page(s), tag size {:.1} mm corner to corner)",
            names.join(", "),
            params.ids.len(),
            sheet.markers_per_page,
            sheet.pages.len(),
            params.marker_side_mm
        );
        Ok(())
    }
}
