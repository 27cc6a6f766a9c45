//! NumPy images in, the detector's gray image out.
//!
//! A C-contiguous gray array is read where it lies: the detector's image borrows its bytes and
//! keeps the array alive. Any other layout (a slice with a step, a transposed or a Fortran-order
//! array) is copied once into a row-major image, and a colour array is converted to gray (the
//! file reader's luminance), which is a copy by nature. The caller must not write to an array
//! while a detector reads it, as with OpenCV's functions.

use crate::errors::bad_input;
use numpy::prelude::*;
use numpy::{PyArrayDyn, PyUntypedArray};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use std::sync::Arc;
use tagsmith::image::{gray_of_rgb8, luminance, GrayImage};

/// A NumPy array's bytes, lent to the detector: the array is held, so its memory stays.
struct LentArray {
    _owner: Py<PyAny>,
    start: *const u8,
    len: usize,
}

// SAFETY: the bytes are only read, and the array they belong to outlives this value (it is
// held); NumPy does not move an array's data while another reference to it exists.
unsafe impl Send for LentArray {}
unsafe impl Sync for LentArray {}

impl AsRef<[u8]> for LentArray {
    fn as_ref(&self) -> &[u8] {
        // SAFETY: `start` and `len` describe the held array's contiguous data.
        unsafe { std::slice::from_raw_parts(self.start, self.len) }
    }
}

/// The channel order of a colour image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channels {
    Rgb,
    Bgr,
}

impl Channels {
    pub fn parse(text: &str) -> PyResult<Self> {
        match text.to_ascii_uppercase().as_str() {
            "RGB" | "RGBA" => Ok(Self::Rgb),
            "BGR" | "BGRA" => Ok(Self::Bgr),
            _ => Err(bad_input(format!(
                "channels={text:?}: give \"RGB\" or \"BGR\" (the order of a colour image's last axis)"
            ))),
        }
    }
}

/// `image`: `uint8`, H×W (gray), H×W×1, H×W×3 or H×W×4 (colour in `channels` order; alpha is
/// composited over white paper, as the file reader does).
pub fn gray_image(image: &Bound<'_, PyAny>, channels: Channels) -> PyResult<GrayImage> {
    let untyped = image.cast::<PyUntypedArray>().map_err(|_| {
        PyTypeError::new_err(format!(
            "image: expected a numpy.ndarray of uint8, got {}",
            image
                .get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_else(|_| "an object".into())
        ))
    })?;
    let dtype = untyped.dtype();
    let typed = image.cast::<PyArrayDyn<u8>>().map_err(|_| {
        bad_input(format!(
            "image: dtype {dtype} is not uint8 (convert with image.astype(numpy.uint8), scaling \
             floats to 0–255 first)"
        ))
    })?;
    let readonly = typed
        .try_readonly()
        .map_err(|e| bad_input(format!("image: cannot read the array: {e}")))?;
    let view = readonly.as_array();
    let shape = view.shape().to_vec();
    let (height, width, depth) = match shape[..] {
        [h, w] => (h, w, 1),
        [h, w, c @ (1 | 3 | 4)] => (h, w, c),
        _ => {
            return Err(bad_input(format!(
                "image: shape {shape:?} is not H×W (gray) nor H×W×3 or H×W×4 (colour)"
            )))
        }
    };
    if height == 0 || width == 0 {
        return Err(bad_input(format!("image: shape {shape:?} has no pixels")));
    }
    let limit = tagsmith::image::Limits::default().max_pixels;
    if (height as u64) * (width as u64) > limit {
        return Err(bad_input(format!(
            "image: {width}×{height} is larger than the detector's limit of {limit} pixels"
        )));
    }
    let (width32, height32) = (width as u32, height as u32);
    if let (1, Some(contiguous)) = (depth, view.as_slice()) {
        let lent = LentArray {
            _owner: image.clone().unbind(),
            start: contiguous.as_ptr(),
            len: contiguous.len(),
        };
        return Ok(GrayImage::lent(width32, height32, Arc::new(lent)));
    }
    let pixels: Vec<u8> = match (depth, view.as_slice()) {
        (1, None) => view.iter().copied().collect(),
        _ => {
            let standard = view.as_standard_layout();
            let flat = standard
                .as_slice()
                .expect("a standard-layout array is contiguous");
            flat.chunks_exact(depth)
                .map(|p| {
                    let (r, g, b) = match channels {
                        Channels::Rgb => (p[0], p[1], p[2]),
                        Channels::Bgr => (p[2], p[1], p[0]),
                    };
                    if depth == 4 {
                        over_white(r, g, b, p[3])
                    } else {
                        gray_of_rgb8(r, g, b)
                    }
                })
                .collect()
        }
    };
    Ok(GrayImage::from_vec(width32, height32, pixels))
}

/// As the file reader composites RGBA: transparent areas show the paper behind them.
fn over_white(r: u8, g: u8, b: u8, alpha: u8) -> u8 {
    let a = alpha as f32 / 255.0;
    let v = luminance(r as f32, g as f32, b as f32) / 255.0 * a + (1.0 - a);
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// The gray image the detector sees for `image` (see `Detector.detect`).
#[pyfunction]
#[pyo3(signature = (image, channels = "RGB"))]
pub fn to_gray<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    channels: &str,
) -> PyResult<Bound<'py, numpy::PyArray2<u8>>> {
    let gray = gray_image(image, Channels::parse(channels)?)?;
    Ok(numpy::ndarray::Array2::from_shape_vec(
        (gray.height as usize, gray.width as usize),
        gray.pixels.into_vec(),
    )
    .expect("the pixels fill the shape")
    .into_pyarray(py))
}

/// An image file as the command line reads it: gray `uint8` H×W (colour by Rec. 709 luminance,
/// alpha over white), within the same decoding limits.
#[pyfunction]
pub fn imread<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
) -> PyResult<Bound<'py, numpy::PyArray2<u8>>> {
    crate::errors::require_exists(&path, "image")?;
    let gray =
        tagsmith::image::read(&path, &tagsmith::image::Limits::default()).map_err(bad_input)?;
    Ok(numpy::ndarray::Array2::from_shape_vec(
        (gray.height as usize, gray.width as usize),
        gray.pixels.into_vec(),
    )
    .expect("the pixels fill the shape")
    .into_pyarray(py))
}
