//! `render` and `sheet`: markers to SVG, PNG and printable pages.

use super::common::{extension, load_family, write_output};
use super::error::{bad_input, Concerning, Result};
use clap::Args;
use std::path::PathBuf;
use tagsmith::render::sheet::{layout_sheet, parse_ids, PageSize, SheetParams};
use tagsmith::render::{marker_scene, pdf, raster, svg, SceneOptions};

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Built-in family name or path to a family JSON file.
    pub family: String,
    #[arg(long)]
    pub id: usize,
    /// Tag size in mm: the distance between ROI corners (the outer black square's side).
    #[arg(long)]
    pub size_mm: Option<f64>,
    /// PNG only: image width in pixels, quiet zone included [default: 512].
    #[arg(long)]
    pub px: Option<u32>,
    /// Quiet zone in cells (marker units) [default: the family's].
    #[arg(long)]
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
        let scene = marker_scene(&family, self.id, options)?;
        let bytes = match extension(&self.output).as_str() {
            "svg" => {
                if self.px.is_some() {
                    eprintln!("note: --px applies to PNG output only; the SVG is sized in mm");
                }
                svg::marker_svg(&scene).into_bytes()
            }
            "png" => {
                let pixmap = raster::rasterize_width(&scene, self.px.unwrap_or(512))?;
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

#[derive(Args, Debug)]
pub struct SheetArgs {
    /// Built-in family name or path to a family JSON file.
    pub family: String,
    /// IDs to print: ranges and lists, e.g. 0-47 or 1,5,9-12.
    #[arg(long)]
    pub ids: String,
    /// a4, a3, letter, or WIDTHxHEIGHT in mm.
    #[arg(long, default_value = "a4")]
    pub page: String,
    #[arg(long)]
    pub landscape: bool,
    /// Tag size in mm: the distance between ROI corners (the outer black square's side).
    #[arg(long)]
    pub size_mm: Option<f64>,
    #[arg(long, default_value_t = 10.0)]
    pub margin_mm: f64,
    /// Gap between neighbouring markers' quiet zones.
    #[arg(long, default_value_t = 6.0)]
    pub spacing_mm: f64,
    /// Print family, ID and size under each marker.
    #[arg(long)]
    pub labels: bool,
    #[arg(long)]
    pub cut_marks: bool,
    /// Quiet zone in cells (marker units) [default: the family's].
    #[arg(long)]
    pub quiet_zone: Option<f64>,
    /// Output: .pdf, or .svg (several pages are written as NAME-1.svg, NAME-2.svg, …).
    #[arg(short, long)]
    pub output: PathBuf,
}

impl SheetArgs {
    pub fn run(self) -> Result<()> {
        let family = load_family(&self.family)?;
        let ids = parse_ids(&self.ids).concerning("--ids")?;
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
        let sheet = layout_sheet(&family, &params)?;
        for w in &sheet.warnings {
            eprintln!("warning: {w}");
        }
        let written: Vec<PathBuf> = match extension(&self.output).as_str() {
            "pdf" => {
                let bytes = pdf::sheet_pdf(&sheet)?;
                write_output(&self.output, &bytes)?;
                vec![self.output.clone()]
            }
            "svg" if sheet.pages.len() == 1 => {
                write_output(&self.output, sheet.pages[0].as_bytes())?;
                vec![self.output.clone()]
            }
            "svg" => {
                let stem = self
                    .output
                    .file_stem()
                    .and_then(|s| s.to_str())
                    .unwrap_or("sheet");
                let mut out = Vec::new();
                for (i, page) in sheet.pages.iter().enumerate() {
                    let path = self.output.with_file_name(format!("{stem}-{}.svg", i + 1));
                    write_output(&path, page.as_bytes())?;
                    out.push(path);
                }
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
