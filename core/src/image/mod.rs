//! The gray image every stage works on, and the only way pixels enter or leave Tagsmith: reading
//! users' files (PNG, JPEG, BMP, TIFF, WebP, PNM) with bounded decoding, writing PNG, the one
//! luminance conversion and the one bilinear sampler.
//!
//! Conventions: 8-bit gray, row-major; pixel centres at integer coordinates (as OpenCV's warps).

mod pixels;
mod read;
mod write;

pub use pixels::{Lent, Pixels};
pub use read::{decode, read, ImageError, ImageErrorKind, Limits};
pub use write::encode_png;

/// The largest `Limits::max_pixels` the commands accept: at 8 bytes a pixel for the widest
/// decoded layout (16-bit RGBA), 2 GB, within any machine that runs the detector.
pub const MAX_PIXELS_CEILING: u64 = 256_000_000;

/// File-name extensions of the formats the reader decodes (lower case).
#[cfg(not(target_arch = "wasm32"))]
pub const EXTENSIONS: &[&str] = &[
    "png", "jpg", "jpeg", "bmp", "tif", "tiff", "webp", "pgm", "pnm", "ppm",
];
/// The browser build reads neither TIFF nor WebP (core/Cargo.toml says why).
#[cfg(target_arch = "wasm32")]
pub const EXTENSIONS: &[&str] = &["png", "jpg", "jpeg", "bmp", "pgm", "pnm", "ppm"];

/// Whether a file's name says it is an image the reader decodes.
pub fn has_image_name(path: &std::path::Path) -> bool {
    (path.extension().and_then(|e| e.to_str()))
        .is_some_and(|e| EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// An 8-bit grayscale image, row-major.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GrayImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Pixels,
}

impl GrayImage {
    pub fn new(width: u32, height: u32, fill: u8) -> Self {
        Self::from_vec(width, height, vec![fill; width as usize * height as usize])
    }

    /// `pixels` row-major, `width` × `height` of them.
    pub fn from_vec(width: u32, height: u32, pixels: Vec<u8>) -> Self {
        debug_assert_eq!(pixels.len(), width as usize * height as usize);
        Self {
            width,
            height,
            pixels: Pixels::Owned(pixels),
        }
    }

    /// An image over bytes a caller owns (`width` × `height`, row-major), read in place.
    ///
    /// # Panics
    /// If the bytes are not exactly `width` × `height`.
    pub fn lent(width: u32, height: u32, pixels: Lent) -> Self {
        assert_eq!((*pixels).as_ref().len(), width as usize * height as usize);
        Self {
            width,
            height,
            pixels: Pixels::Lent(pixels),
        }
    }

    /// The negative: light for dark.
    pub fn inverted(&self) -> Self {
        let pixels = self.pixels.iter().map(|&p| 255 - p).collect();
        Self::from_vec(self.width, self.height, pixels)
    }

    pub fn get(&self, x: u32, y: u32) -> u8 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// The pixels of `width` × `height` from (`x`, `y`), which must lie inside the image.
    pub fn crop(&self, x: u32, y: u32, width: u32, height: u32) -> Self {
        let mut pixels = Vec::with_capacity(width as usize * height as usize);
        for row in y..y + height {
            let start = row as usize * self.width as usize + x as usize;
            pixels.extend_from_slice(&self.pixels[start..start + width as usize]);
        }
        Self::from_vec(width, height, pixels)
    }

    /// Bilinear sample (see [`bilinear`]), in gray levels 0–255.
    ///
    /// The bytes are borrowed once, not through [`Pixels`] at each of the four reads: the image
    /// searches and the frame fit take millions of samples an image.
    pub fn sample(&self, x: f32, y: f32) -> f32 {
        let pixels: &[u8] = &self.pixels;
        bilinear(self.width, self.height, x, y, |i| pixels[i] as f32)
    }
}

/// Relative luminance weights of Rec. 709 / sRGB, applied to the encoded (gamma) values. The
/// synthesiser converts rendered colours with them, so a photograph read here looks to the
/// detector as its training images did; they are also the `image` crate's and the web's weights.
pub const LUMA_WEIGHTS: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// Luminance of an encoded RGB colour, each channel in any common unit (0–1 or 0–255): the result
/// is in the same unit.
#[inline]
pub fn luminance(r: f32, g: f32, b: f32) -> f32 {
    LUMA_WEIGHTS[0] * r + LUMA_WEIGHTS[1] * g + LUMA_WEIGHTS[2] * b
}

/// The 8-bit gray of an 8-bit encoded RGB colour: the conversion every decoded colour photograph
/// goes through, so that pixels handed over by a caller (the Python package's arrays) read as
/// the same file read from disk.
#[inline]
pub fn gray_of_rgb8(r: u8, g: u8, b: u8) -> u8 {
    quantise_unit(luminance(r as f32, g as f32, b as f32) / 255.0)
}

/// A 0–1 level as 8 bits, rounded.
#[inline]
pub(crate) fn quantise_unit(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// Interpolates the four pixels around a point: `top_left`, `top_right`, `bottom_left`,
/// `bottom_right`, with `fx`, `fy` its fractional position between them.
#[inline]
pub fn mix(
    top_left: f32,
    top_right: f32,
    bottom_left: f32,
    bottom_right: f32,
    fx: f32,
    fy: f32,
) -> f32 {
    let top = top_left * (1.0 - fx) + top_right * fx;
    let bottom = bottom_left * (1.0 - fx) + bottom_right * fx;
    top * (1.0 - fy) + bottom * fy
}

/// The bilinear sampler: the value at (`x`, `y`) of a `width` × `height` grid whose value at
/// row-major index `i` is `at(i)`. Positions outside the grid take the nearest edge (the point is
/// clamped first), so a sample never reads out of bounds.
#[inline]
pub fn bilinear(width: u32, height: u32, x: f32, y: f32, at: impl Fn(usize) -> f32) -> f32 {
    let (last_x, last_y) = (width.saturating_sub(1), height.saturating_sub(1));
    let (x, y) = (x.clamp(0.0, last_x as f32), y.clamp(0.0, last_y as f32));
    // Truncation is the floor here, as both are clamped to ≥ 0, and it compiles to one
    // instruction where `floor` is a libm call on baseline x86-64 (no SSE4.1); the neighbours'
    // indices stay integers: this runs for every sample of every frame fit.
    let (x0, y0) = (x as u32, y as u32);
    let (x1, y1) = ((x0 + 1).min(last_x), (y0 + 1).min(last_y));
    let stride = width as usize;
    let idx = |xx: u32, yy: u32| yy as usize * stride + xx as usize;
    mix(
        at(idx(x0, y0)),
        at(idx(x1, y0)),
        at(idx(x0, y1)),
        at(idx(x1, y1)),
        x - x0 as f32,
        y - y0 as f32,
    )
}

/// [`bilinear`] over a gray image's bytes (`stride` a row) where (`x`, `y`) lies in
/// [0, width − 2] × [0, height − 2]: no clamp, no neighbour at the edge, the same value. For
/// callers that check a whole region against the image once (the frame fit).
#[inline]
pub fn bilinear_inside(pixels: &[u8], stride: usize, x: f32, y: f32) -> f32 {
    let (x0, y0) = (x as usize, y as usize);
    let i = y0 * stride + x0;
    let at = |i: usize| pixels[i] as f32;
    mix(
        at(i),
        at(i + 1),
        at(i + stride),
        at(i + stride + 1),
        x - x0 as f32,
        y - y0 as f32,
    )
}

/// An image crosses a message boundary (a page and its worker) as its size and row-major bytes.
impl serde::Serialize for GrayImage {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut fields = s.serialize_struct("GrayImage", 3)?;
        fields.serialize_field("width", &self.width)?;
        fields.serialize_field("height", &self.height)?;
        fields.serialize_field("pixels", &*self.pixels)?;
        fields.end()
    }
}

impl<'de> serde::Deserialize<'de> for GrayImage {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(serde::Deserialize)]
        struct Raw {
            width: u32,
            height: u32,
            pixels: Vec<u8>,
        }
        let raw = Raw::deserialize(d)?;
        if raw.pixels.len() as u64 != u64::from(raw.width) * u64::from(raw.height) {
            return Err(serde::de::Error::custom(format!(
                "{} bytes for a {}×{} image",
                raw.pixels.len(),
                raw.width,
                raw.height
            )));
        }
        Ok(Self::from_vec(raw.width, raw.height, raw.pixels))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_interpolates_inside_and_clamps_outside() {
        // 3 × 2 grid: 0 10 20 / 30 40 50
        let grid = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0];
        let at = |i: usize| grid[i];
        assert_eq!(bilinear(3, 2, 1.0, 1.0, at), 40.0);
        assert_eq!(bilinear(3, 2, 0.5, 0.5, at), 20.0);
        assert_eq!(bilinear(3, 2, 1.5, 0.0, at), 15.0);
        assert_eq!(bilinear(3, 2, -4.0, -1.0, at), 0.0);
        assert_eq!(bilinear(3, 2, 9.0, 9.0, at), 50.0);
    }

    #[test]
    fn an_image_samples_as_the_generic_bilinear_does_inside_at_the_edges_and_beyond() {
        let image = GrayImage::from_vec(3, 2, vec![0, 10, 20, 30, 40, 250]);
        let generic = |x: f32, y: f32| bilinear(3, 2, x, y, |i| image.pixels[i] as f32);
        for (x, y) in [
            (1.0, 1.0),
            (0.5, 0.5),
            (1.5, 0.0),
            (1.7, 0.9),
            (2.0, 1.0),
            (-4.0, -1.0),
            (9.0, 9.0),
            (1.999, 0.999),
        ] {
            assert_eq!(image.sample(x, y), generic(x, y), "at ({x}, {y})");
        }
        assert_eq!(image.sample(1.5, 0.5), 80.0);
        // Inside [0, width − 2] × [0, height − 2] the unchecked sampler agrees.
        for (x, y) in [(0.0, 0.0), (0.5, 0.5), (1.0, 0.0), (0.25, 0.75)] {
            assert_eq!(bilinear_inside(&image.pixels, 3, x, y), image.sample(x, y));
        }
        let pixel = GrayImage::new(1, 1, 7);
        assert_eq!(pixel.sample(0.3, 5.0), 7.0);
    }

    #[test]
    fn luminance_weights_sum_to_one_and_green_weighs_most() {
        assert!((luminance(1.0, 1.0, 1.0) - 1.0).abs() < 1e-6);
        assert!(luminance(0.0, 1.0, 0.0) > luminance(1.0, 0.0, 0.0));
        assert!(luminance(1.0, 0.0, 0.0) > luminance(0.0, 0.0, 1.0));
    }

    #[test]
    fn an_image_round_trips_through_json_and_a_wrong_size_is_refused() {
        let image = GrayImage::from_vec(3, 2, vec![0, 1, 2, 253, 254, 255]);
        let json = serde_json::to_string(&image).unwrap();
        assert_eq!(serde_json::from_str::<GrayImage>(&json).unwrap(), image);
        let short = r#"{"width":3,"height":2,"pixels":[0,1,2]}"#;
        let e = serde_json::from_str::<GrayImage>(short)
            .unwrap_err()
            .to_string();
        assert!(e.contains("3 bytes for a 3×2 image"), "{e}");
    }
}
