//! `Detector` and `Tracker`: the command line's detector, built once, on NumPy images.

use crate::arrays::{gray_image, Channels};
use crate::detection::Detection;
use crate::errors::{bad_input, no_panic, require_exists};
use crate::family::load_family;
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use tagsmith::detect::detector::FamilyReader;
use tagsmith::detect::refine::RefineMode;
use tagsmith::detect::stage1::Stage1;
use tagsmith::detect::stage2::{Stage2, DEFAULT_FAMILIES};
use tagsmith::detect::{Found, Timings, TrackParams};
use tagsmith::family::Family;
use tagsmith::geometry::Camera;
use tagsmith::image::GrayImage;

/// Finds and reads markers of the given families in images.
#[pyclass(frozen, module = "tagsmith")]
pub struct Detector {
    inner: tagsmith::detect::Detector,
    /// The marker side each family is posed at unless `tag_size` is given (metres).
    sides: HashMap<String, f64>,
    camera: Option<[f64; 4]>,
    channels: Channels,
}

fn load_stage2(family: &Family, model: Option<&PathBuf>) -> PyResult<Stage2> {
    match model {
        Some(path) => {
            require_exists(path, &format!("stage-2 model of {}", family.name()))?;
            Stage2::load(path, family).map_err(bad_input)
        }
        None => {
            let shipped = Stage2::shipped(family).ok_or_else(|| {
                bad_input(format!(
                    "no weights are shipped for family {:?}; train them with `tagsmith train {} \
                     --stage keypoints` and pass models={{{:?}: \"path/to/model\"}}",
                    family.name(),
                    family.name(),
                    family.name()
                ))
            })?;
            shipped.map_err(bad_input)
        }
    }
}

fn check_camera(camera: [f64; 4]) -> PyResult<[f64; 4]> {
    let [fx, fy, cx, cy] = camera;
    if camera.iter().all(|v| v.is_finite()) && fx > 0.0 && fy > 0.0 {
        Ok(camera)
    } else {
        Err(bad_input(format!(
            "camera_params ({fx}, {fy}, {cx}, {cy}): fx and fy must be positive and all four finite"
        )))
    }
}

impl Detector {
    fn camera_for(&self, image: &GrayImage, given: Option<[f64; 4]>) -> PyResult<Option<Camera>> {
        let Some(camera) = given.or(self.camera) else {
            return Ok(None);
        };
        let [fx, fy, cx, cy] = check_camera(camera)?;
        Ok(Some(Camera {
            width: image.width,
            height: image.height,
            fx,
            fy,
            cx,
            cy,
            distortion: [0.0; 5],
        }))
    }

    fn scale(&self, found: &Found, tag_size: Option<f64>) -> f64 {
        match (tag_size, self.sides.get(&found.family)) {
            (Some(size), Some(side)) => size / side,
            _ => 1.0,
        }
    }

    fn wrap(&self, found: &[Found], timings: &Timings, tag_size: Option<f64>) -> Vec<Detection> {
        let timings = Arc::new(serde_json::to_string(timings).expect("timings serialise"));
        found
            .iter()
            .map(|f| Detection::new(f, self.scale(f, tag_size), timings.clone()))
            .collect()
    }

    /// The gray image and camera one call detects with, its arguments checked.
    fn prepare(
        &self,
        image: &Bound<'_, PyAny>,
        camera_params: Option<[f64; 4]>,
        tag_size: Option<f64>,
        channels: Option<&str>,
    ) -> PyResult<(GrayImage, Option<Camera>)> {
        let channels = channels.map(Channels::parse).transpose()?;
        let gray = gray_image(image, channels.unwrap_or(self.channels))?;
        let camera = self.camera_for(&gray, camera_params)?;
        check_tag_size(tag_size)?;
        Ok((gray, camera))
    }

    /// Converts, then detects with the GIL released.
    fn run(
        &self,
        py: Python<'_>,
        image: &Bound<'_, PyAny>,
        camera_params: Option<[f64; 4]>,
        tag_size: Option<f64>,
        channels: Option<&str>,
    ) -> PyResult<Vec<Detection>> {
        let (gray, camera) = self.prepare(image, camera_params, tag_size, channels)?;
        let (found, timings) = py.detach(|| {
            no_panic("detecting", || {
                self.inner.detect_with(&gray, camera.as_ref())
            })
        })?;
        Ok(self.wrap(&found, &timings, tag_size))
    }
}

fn check_tag_size(tag_size: Option<f64>) -> PyResult<()> {
    match tag_size {
        Some(size) if !(size.is_finite() && size > 0.0) => Err(bad_input(format!(
            "tag_size {size}: the marker side must be a positive, finite length in metres"
        ))),
        _ => Ok(()),
    }
}

#[pymethods]
impl Detector {
    #[new]
    #[pyo3(signature = (
        families = None,
        models = None,
        stage1 = None,
        camera = None,
        channels = "RGB",
        iterations = 2,
        refine = "full",
        corner_threshold = None,
        verifier_threshold = None,
        upsample = false,
        image_searches = true,
        cell_reads = true,
        edge_fits = true,
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        families: Option<Vec<String>>,
        models: Option<HashMap<String, PathBuf>>,
        stage1: Option<PathBuf>,
        camera: Option<[f64; 4]>,
        channels: &str,
        iterations: usize,
        refine: &str,
        corner_threshold: Option<f32>,
        verifier_threshold: Option<f32>,
        upsample: bool,
        image_searches: bool,
        cell_reads: bool,
        edge_fits: bool,
    ) -> PyResult<Self> {
        let names: Vec<String> = match families {
            Some(names) if names.is_empty() => {
                return Err(bad_input("families: give at least one family"))
            }
            Some(names) => names,
            None => DEFAULT_FAMILIES.iter().map(|f| f.to_string()).collect(),
        };
        let mut models = models.unwrap_or_default();
        let mut readers = Vec::new();
        let mut sides = HashMap::new();
        for name in &names {
            let family = load_family(name)?;
            let model = models.remove(name).or_else(|| models.remove(family.name()));
            let stage2 = load_stage2(&family, model.as_ref())?;
            let side_m = family.spec().print.marker_side_mm / 1000.0;
            sides.insert(family.name().to_string(), side_m);
            let mut reader = FamilyReader::new(family, stage2);
            reader.side_m = side_m;
            readers.push(reader);
        }
        if let Some(unused) = models.keys().next() {
            return Err(bad_input(format!(
                "models: {unused:?} is none of the families to detect ({})",
                names.join(", ")
            )));
        }
        let stage1 = match &stage1 {
            Some(path) => {
                require_exists(path, "stage-1 model")?;
                Stage1::load(path).map_err(bad_input)?
            }
            None => Stage1::shipped().map_err(bad_input)?,
        };
        let mut inner = tagsmith::detect::Detector::new(stage1, readers).map_err(bad_input)?;
        if !(1..=10).contains(&iterations) {
            return Err(bad_input(format!(
                "iterations {iterations}: give 1 to 10 stage-2 passes"
            )));
        }
        let options = &mut inner.options;
        options.read.iterations = iterations;
        options.read.refine = refine.parse::<RefineMode>().map_err(|_| {
            bad_input(format!(
                "refine={refine:?}: give one of {}",
                RefineMode::NAMES.join(", ")
            ))
        })?;
        if let Some(threshold) = corner_threshold {
            if !(threshold > 0.0 && threshold < 1.0) {
                return Err(bad_input(format!(
                    "corner_threshold {threshold}: give a value in (0, 1)"
                )));
            }
            options.propose.group.corner = threshold;
        }
        if let Some(threshold) = verifier_threshold {
            if !(0.0..1.0).contains(&threshold) {
                return Err(bad_input(format!(
                    "verifier_threshold {threshold}: give a value in [0, 1) (0 sends every quad \
                     to stage 2)"
                )));
            }
            options.verifier.min_score = threshold;
        }
        options.propose.upsample = upsample;
        options.propose.set_image_searches(image_searches);
        options.cell_reads = cell_reads;
        options.edge_fits = edge_fits;
        Ok(Self {
            inner,
            sides,
            camera: camera.map(check_camera).transpose()?,
            channels: Channels::parse(channels)?,
        })
    }

    /// The families this detector reads.
    #[getter]
    fn families(&self) -> Vec<String> {
        (self.inner.readers.iter())
            .map(|r| r.family.name().to_string())
            .collect()
    }

    #[pyo3(signature = (image, camera_params = None, tag_size = None, channels = None))]
    fn detect(
        &self,
        py: Python<'_>,
        image: &Bound<'_, PyAny>,
        camera_params: Option<[f64; 4]>,
        tag_size: Option<f64>,
        channels: Option<&str>,
    ) -> PyResult<Vec<Detection>> {
        self.run(py, image, camera_params, tag_size, channels)
    }

    #[pyo3(signature = (images, camera_params = None, tag_size = None, channels = None))]
    fn detect_batch(
        &self,
        py: Python<'_>,
        images: &Bound<'_, PyAny>,
        camera_params: Option<[f64; 4]>,
        tag_size: Option<f64>,
        channels: Option<&str>,
    ) -> PyResult<Vec<Vec<Detection>>> {
        let channels = channels.map(Channels::parse).transpose()?;
        check_tag_size(tag_size)?;
        let mut grays = Vec::new();
        for (i, image) in images.try_iter()?.enumerate() {
            let gray = gray_image(&image?, channels.unwrap_or(self.channels))
                .map_err(|e| prefix(py, e, &format!("images[{i}]")))?;
            let camera = self.camera_for(&gray, camera_params)?;
            grays.push((gray, camera));
        }
        let results = py.detach(|| {
            use rayon::prelude::*;
            no_panic("detecting a batch", || {
                grays
                    .par_iter()
                    .with_max_len(1)
                    .map(|(gray, camera)| self.inner.detect_with(gray, camera.as_ref()))
                    .collect::<Vec<_>>()
            })
        })?;
        Ok(results
            .iter()
            .map(|(found, timings)| self.wrap(found, timings, tag_size))
            .collect())
    }

    /// The detections of one image as arrays: `ids` (N,) int64, `families` list of N names,
    /// `corners` (N, 4, 2), `poses` (N, 7): translation x, y, z (metres) then the rotation's
    /// quaternion x, y, z, w (NaN without a pose), `hamming` (N,) int64.
    #[pyo3(signature = (image, camera_params = None, tag_size = None, channels = None))]
    fn detect_arrays<'py>(
        &self,
        py: Python<'py>,
        image: &Bound<'py, PyAny>,
        camera_params: Option<[f64; 4]>,
        tag_size: Option<f64>,
        channels: Option<&str>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let found = self.run(py, image, camera_params, tag_size, channels)?;
        let n = found.len();
        let records: Vec<_> = found.iter().map(Detection::record).collect();
        let ids = Array1::from_iter(records.iter().map(|r| r.id as i64));
        let corners = Array3::from_shape_fn((n, 4, 2), |(i, k, j)| records[i].corners[k][j]);
        let poses = Array2::from_shape_fn((n, 7), |(i, j)| match &records[i].pose {
            None => f64::NAN,
            Some(p) if j < 3 => p.translation_m[j],
            Some(p) => {
                let m = nalgebra::Matrix3::from_fn(|r, c| p.rotation[r][c]);
                let rotation = nalgebra::Rotation3::from_matrix(&m);
                let q = nalgebra::UnitQuaternion::from_rotation_matrix(&rotation);
                [q.i, q.j, q.k, q.w][j - 3]
            }
        });
        let hamming = Array1::from_iter(
            records
                .iter()
                .map(|r| r.scores.as_ref().map_or(0, |s| s.corrected_errors) as i64),
        );
        let dict = PyDict::new(py);
        dict.set_item("ids", ids.into_pyarray(py))?;
        let families: Vec<String> = records
            .iter()
            .map(|r| r.family.clone().unwrap_or_default())
            .collect();
        dict.set_item("families", PyList::new(py, families)?)?;
        dict.set_item("corners", corners.into_pyarray(py))?;
        dict.set_item("poses", poses.into_pyarray(py))?;
        dict.set_item("hamming", hamming.into_pyarray(py))?;
        Ok(dict)
    }

    fn __repr__(&self) -> String {
        format!("Detector(families={:?})", self.families())
    }
}

/// The same error type, its message prefixed with where in the input it arose.
fn prefix(py: Python<'_>, error: PyErr, at: &str) -> PyErr {
    let message = error.value(py).to_string();
    let kind = error.get_type(py);
    match kind.call1((format!("{at}: {message}"),)) {
        Ok(value) => PyErr::from_value(value),
        Err(_) => error,
    }
}

/// Follows markers through the frames of one video: each marker of the last frame is read
/// again from where its motion puts it, by its family's stage 2 alone; the whole detector runs
/// on the first frame, every `redetect_every` frames and whenever a marker is lost.
#[pyclass(module = "tagsmith")]
pub struct Tracker {
    detector: Py<Detector>,
    state: Mutex<tagsmith::detect::Tracker>,
    last_full: bool,
}

#[pymethods]
impl Tracker {
    #[new]
    #[pyo3(signature = (detector, redetect_every = 10))]
    fn new(detector: Py<Detector>, redetect_every: usize) -> PyResult<Self> {
        if redetect_every == 0 {
            return Err(bad_input("redetect_every 0: give at least 1 frame"));
        }
        Ok(Self {
            detector,
            state: Mutex::new(tagsmith::detect::Tracker::new(TrackParams {
                redetect_every,
                ..TrackParams::default()
            })),
            last_full: false,
        })
    }

    /// The markers of the next frame.
    #[pyo3(signature = (image, camera_params = None, tag_size = None, channels = None))]
    fn track(
        &mut self,
        py: Python<'_>,
        image: &Bound<'_, PyAny>,
        camera_params: Option<[f64; 4]>,
        tag_size: Option<f64>,
        channels: Option<&str>,
    ) -> PyResult<Vec<Detection>> {
        let detector = self.detector.get();
        let (gray, camera) = detector.prepare(image, camera_params, tag_size, channels)?;
        let state = &self.state;
        let frame = py.detach(|| {
            no_panic("tracking", || {
                let mut state = state.lock().unwrap_or_else(|e| e.into_inner());
                state.next(&detector.inner, &gray, camera.as_ref())
            })
        })?;
        self.last_full = frame.full;
        Ok(detector.wrap(&frame.found, &frame.timings, tag_size))
    }

    /// Whether the last frame ran the whole detector (rather than following its markers).
    #[getter]
    fn last_full(&self) -> bool {
        self.last_full
    }
}
