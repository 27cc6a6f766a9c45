//! Families: the built-ins and users' files, rendered as arrays and printed as sheets.

use crate::errors::{bad_input, no_panic, require_exists};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2};
use pyo3::prelude::*;
use std::path::{Path, PathBuf};
use tagsmith::render::raster::{gray_at, rasterize_width};
use tagsmith::render::scene::{marker_scene, SceneOptions};
use tagsmith::render::sheet::{layout_sheet, svg_page_name, PageSize, SheetParams, MAX_IDS};

/// A built-in family by name, or a family file by path (as `tagsmith --family`).
pub fn load_family(name_or_path: &str) -> PyResult<tagsmith::Family> {
    if let Some(found) = tagsmith::builtin::get(name_or_path) {
        return found.map_err(bad_input);
    }
    let path = Path::new(name_or_path);
    if path.exists() || name_or_path.ends_with(".json") || name_or_path.contains('/') {
        require_exists(path, "family file")?;
        return tagsmith::family::load_file(path).map_err(bad_input);
    }
    let names: Vec<_> = tagsmith::builtin::names().collect();
    Err(bad_input(format!(
        "no built-in family or file named {name_or_path:?}; built-in families: {}",
        names.join(", ")
    )))
}

/// The built-in families' names.
#[pyfunction]
pub fn families() -> Vec<&'static str> {
    tagsmith::builtin::names().collect()
}

/// The families whose stage-2 weights ship with Tagsmith (the detector's default).
#[pyfunction]
pub fn detectable_families() -> Vec<&'static str> {
    tagsmith::detect::stage2::shipped_families().collect()
}

/// A marker family: its layout, pattern categories, keypoints, ROI and codebook.
#[pyclass(frozen, module = "tagsmith")]
pub struct Family {
    inner: tagsmith::Family,
}

fn page_size(page: &str) -> PyResult<PageSize> {
    let (name, landscape) = match page.strip_suffix("-landscape") {
        Some(name) => (name, true),
        None => (page, false),
    };
    let size = PageSize::parse(name).map_err(bad_input)?;
    Ok(if landscape { size.landscape() } else { size })
}

#[pymethods]
impl Family {
    /// A built-in family's name or the path of a family JSON file.
    #[staticmethod]
    fn load(name_or_path: &str) -> PyResult<Self> {
        Ok(Self {
            inner: load_family(name_or_path)?,
        })
    }

    #[getter]
    fn name(&self) -> String {
        self.inner.name().to_string()
    }

    #[getter]
    fn title(&self) -> String {
        self.inner.title().to_string()
    }

    /// How many IDs the codebook holds.
    #[getter]
    fn size(&self) -> usize {
        self.inner.codebook().len()
    }

    #[getter]
    fn keypoint_count(&self) -> usize {
        self.inner.keypoints().len()
    }

    /// The printed marker's side (ROI corner to corner) the family is posed at by default, mm.
    #[getter]
    fn marker_side_mm(&self) -> f64 {
        self.inner.spec().print.marker_side_mm
    }

    /// Whether weights that read this family ship with Tagsmith: a built-in's own, or those of
    /// its layout.
    #[getter]
    fn has_shipped_weights(&self) -> bool {
        tagsmith::detect::stage2::shipped_model_for(&self.inner).is_some()
    }

    /// Marker `id` as a gray `uint8` array `px` wide (quiet zone included).
    #[pyo3(signature = (id, px = 256, quiet_zone = None))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        id: usize,
        px: u32,
        quiet_zone: Option<f64>,
    ) -> PyResult<Bound<'py, PyArray2<u8>>> {
        if !(1..=20_000).contains(&px) {
            return Err(bad_input(format!("px {px}: give 1 to 20000 pixels")));
        }
        let options = SceneOptions {
            side_mm: None,
            quiet_zone,
        };
        let scene = marker_scene(&self.inner, id, options).map_err(bad_input)?;
        let pixmap = no_panic("rendering", || rasterize_width(&scene, px))?.map_err(bad_input)?;
        let (w, h) = (pixmap.width(), pixmap.height());
        let gray = Array2::from_shape_fn((h as usize, w as usize), |(y, x)| {
            (gray_at(&pixmap, x as u32, y as u32) * 255.0)
                .round()
                .clamp(0.0, 255.0) as u8
        });
        Ok(gray.into_pyarray(py))
    }

    /// Lays `ids` out on printable pages at the exact physical size and writes them to `path`:
    /// a PDF (one file) or SVG (`STEM.svg`, or `STEM-1.svg`, … for several pages), each written
    /// whole or not at all. Returns the files written.
    #[pyo3(signature = (ids, path, page = "A4", marker_side_mm = None, spacing_mm = None,
                        margin_mm = None, labels = None, cut_marks = false))]
    #[allow(clippy::too_many_arguments)]
    fn sheet(
        &self,
        ids: Vec<usize>,
        path: PathBuf,
        page: &str,
        marker_side_mm: Option<f64>,
        spacing_mm: Option<f64>,
        margin_mm: Option<f64>,
        labels: Option<bool>,
        cut_marks: bool,
    ) -> PyResult<Vec<PathBuf>> {
        if ids.is_empty() || ids.len() > MAX_IDS {
            return Err(bad_input(format!(
                "ids: give 1 to {MAX_IDS} IDs, not {}",
                ids.len()
            )));
        }
        let mut params = SheetParams::new(&self.inner, ids);
        params.page = page_size(page)?;
        params.marker_side_mm = marker_side_mm.unwrap_or(params.marker_side_mm);
        params.spacing_mm = spacing_mm.unwrap_or(params.spacing_mm);
        params.margin_mm = margin_mm.unwrap_or(params.margin_mm);
        params.labels = labels.unwrap_or(params.labels);
        params.cut_marks = cut_marks;
        let sheet = layout_sheet(&self.inner, &params).map_err(bad_input)?;
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let write = |path: &Path, bytes: &[u8]| {
            tagsmith::io::write_atomic(path, bytes).map_err(|e| {
                pyo3::exceptions::PyOSError::new_err(format!(
                    "cannot write {}: {e}",
                    path.display()
                ))
            })
        };
        match extension.as_deref() {
            Some("pdf") => {
                let bytes = tagsmith::render::pdf::sheet_pdf(&sheet).map_err(bad_input)?;
                write(&path, &bytes)?;
                Ok(vec![path])
            }
            Some("svg") if sheet.pages.len() == 1 => {
                write(&path, sheet.pages[0].as_bytes())?;
                Ok(vec![path])
            }
            Some("svg") => {
                let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("sheet");
                let folder = path.parent().unwrap_or(Path::new(""));
                let mut written = Vec::new();
                for (i, page) in sheet.pages.iter().enumerate() {
                    let page_path = folder.join(svg_page_name(stem, i + 1));
                    write(&page_path, page.as_bytes())?;
                    written.push(page_path);
                }
                Ok(written)
            }
            _ => Err(bad_input(format!(
                "{}: name a .pdf or .svg file",
                path.display()
            ))),
        }
    }

    /// What the family's checks warn about (it loaded, so nothing is an error).
    fn validate(&self) -> Vec<String> {
        let mut warnings = self.inner.warnings();
        warnings.extend(tagsmith::render::readback::warnings(&self.inner));
        warnings
    }

    fn __repr__(&self) -> String {
        format!(
            "Family({:?}, {} IDs, {} keypoints)",
            self.inner.name(),
            self.size(),
            self.keypoint_count()
        )
    }
}
