//! Reading images with bounded decoding: the size in the header is checked against [`Limits`]
//! before any pixel buffer exists, so a 60-byte file that claims 40000 × 40000 pixels costs
//! nothing.

use super::{luminance, GrayImage};
use ::image::{DynamicImage, ImageDecoder, ImageFormat, ImageReader};
use std::io::{BufRead, BufReader, Cursor, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// How large an image Tagsmith agrees to decode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Width × height, at most. The default, 64 megapixels, is above any camera's frame and keeps
    /// the worst-case decode (16-bit RGBA) within 512 MB.
    pub max_pixels: u64,
}

impl Limits {
    pub const DEFAULT_MAX_PIXELS: u64 = 64_000_000;
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_pixels: Self::DEFAULT_MAX_PIXELS,
        }
    }
}

/// Why an image could not be read; [`ImageError::path`] is the file, when there is one.
#[derive(Debug, thiserror::Error)]
#[error("{}{kind}", path.as_ref().map(|p| format!("{}: ", p.display())).unwrap_or_default())]
pub struct ImageError {
    pub path: Option<PathBuf>,
    pub kind: ImageErrorKind,
}

#[derive(Debug, thiserror::Error)]
pub enum ImageErrorKind {
    #[error("cannot read the file: {0}")]
    Io(#[from] std::io::Error),
    #[error("not an image in a format Tagsmith reads (PNG, JPEG, BMP, TIFF, WebP, PNM)")]
    UnknownFormat,
    #[error(
        "the image is {width}×{height} px ({:.1} megapixels), over the limit of {:.1} megapixels",
        *width as f64 * *height as f64 / 1e6,
        *limit as f64 / 1e6
    )]
    TooLarge { width: u32, height: u32, limit: u64 },
    #[error("the {format} data is corrupt or truncated ({message})")]
    Corrupt { format: String, message: String },
}

impl ImageErrorKind {
    /// Whether the input is at fault (a missing, corrupt, unknown or oversized image) rather than
    /// the system (a read that failed half-way, a full disk).
    pub fn is_bad_input(&self) -> bool {
        use std::io::ErrorKind as K;
        match self {
            Self::Io(e) => matches!(
                e.kind(),
                K::NotFound | K::PermissionDenied | K::IsADirectory
            ),
            _ => true,
        }
    }
}

/// Reads an image file as gray (colour by [`luminance`], alpha composited over white paper,
/// 16-bit and float scaled, palettes expanded, EXIF orientation applied as photo viewers and
/// OpenCV's `imread` do).
pub fn read(path: &Path, limits: &Limits) -> Result<GrayImage, ImageError> {
    let with_path = |kind| ImageError {
        path: Some(path.to_path_buf()),
        kind,
    };
    let file = std::fs::File::open(path).map_err(|e| with_path(e.into()))?;
    decode_from(BufReader::new(file), limits).map_err(with_path)
}

/// Decodes an image held in memory; see [`read`].
pub fn decode(bytes: &[u8], limits: &Limits) -> Result<GrayImage, ImageError> {
    decode_from(Cursor::new(bytes), limits).map_err(|kind| ImageError { path: None, kind })
}

fn decode_from(
    mut source: impl BufRead + Seek,
    limits: &Limits,
) -> Result<GrayImage, ImageErrorKind> {
    // The size from the header alone, before any decoder runs: some decoders read every chunk up
    // to the pixel data first, so a header-only file that claims a huge size would otherwise be
    // reported as truncated rather than as too large.
    if let Ok(size) = imagesize::reader_size(&mut source) {
        check_size(size.width as u64, size.height as u64, limits)?;
    }
    source.seek(SeekFrom::Start(0))?;
    let reader = ImageReader::new(source).with_guessed_format()?;
    let format = match reader.format() {
        Some(f) if is_supported(f) => f,
        _ => return Err(ImageErrorKind::UnknownFormat),
    };
    if format == ImageFormat::Jpeg {
        // JPEG decoders fill a cut-off file with gray and succeed; a photo that lost its end is
        // bad input, so it must end in an EOI marker after its scan data.
        let mut bytes = Vec::new();
        let cap = limits.max_pixels.saturating_mul(4).saturating_add(16 << 20);
        reader.into_inner().take(cap).read_to_end(&mut bytes)?;
        if !jpeg_is_complete(&bytes) {
            return Err(ImageErrorKind::Corrupt {
                format: "JPEG".into(),
                message: "the file ends before its end-of-image marker".into(),
            });
        }
        let reader = ImageReader::with_format(Cursor::new(bytes), format);
        return decode_with(reader, format, limits);
    }
    decode_with(reader, format, limits)
}

fn check_size(width: u64, height: u64, limits: &Limits) -> Result<(), ImageErrorKind> {
    if width.saturating_mul(height) > limits.max_pixels {
        return Err(ImageErrorKind::TooLarge {
            width: width.min(u32::MAX as u64) as u32,
            height: height.min(u32::MAX as u64) as u32,
            limit: limits.max_pixels,
        });
    }
    Ok(())
}

/// Whether JPEG data has an end-of-image marker after its first start-of-scan. Scan data stuffs
/// every 0xFF byte, so an unstuffed 0xFF 0xD9 there can only be the real end.
fn jpeg_is_complete(bytes: &[u8]) -> bool {
    let Some(scan) = bytes.windows(2).position(|w| w == [0xFF, 0xDA]) else {
        return false;
    };
    bytes[scan..].windows(2).any(|w| w == [0xFF, 0xD9])
}

fn decode_with<R: BufRead + Seek>(
    mut reader: ImageReader<R>,
    format: ImageFormat,
    limits: &Limits,
) -> Result<GrayImage, ImageErrorKind> {
    let name = format!("{format:?}").to_uppercase();
    let corrupt = |e: ::image::ImageError| match e {
        ::image::ImageError::IoError(io) if io.kind() != std::io::ErrorKind::UnexpectedEof => {
            ImageErrorKind::Io(io)
        }
        other => ImageErrorKind::Corrupt {
            format: name.clone(),
            message: other.to_string(),
        },
    };
    let mut decoder_limits = ::image::Limits::default();
    // The pixel count is checked below; this bounds what the decoders allocate besides (at most
    // 8 bytes a pixel for 16-bit RGBA, plus headroom for metadata).
    decoder_limits.max_alloc = Some(limits.max_pixels.saturating_mul(8).saturating_add(64 << 20));
    reader.limits(decoder_limits);
    let mut decoder = reader.into_decoder().map_err(corrupt)?;
    let (width, height) = decoder.dimensions();
    check_size(width as u64, height as u64, limits)?;
    let orientation = decoder.orientation().ok();
    let mut image = DynamicImage::from_decoder(decoder).map_err(corrupt)?;
    if let Some(o) = orientation {
        image.apply_orientation(o);
    }
    Ok(to_gray(image))
}

fn is_supported(format: ImageFormat) -> bool {
    matches!(
        format,
        ImageFormat::Png
            | ImageFormat::Jpeg
            | ImageFormat::Bmp
            | ImageFormat::Tiff
            | ImageFormat::WebP
            | ImageFormat::Pnm
    )
}

/// Gray from any decoded layout, each channel normalised to 0–1 first.
fn to_gray(image: DynamicImage) -> GrayImage {
    let (width, height) = (image.width(), image.height());
    let quantise = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    // Transparent areas show the paper behind them: white.
    let over_white = |v: f32, alpha: f32| v * alpha + (1.0 - alpha);
    fn convert<P: Copy>(pixels: &[P], channels: usize, f: impl Fn(&[P]) -> u8) -> Vec<u8> {
        pixels.chunks_exact(channels).map(f).collect()
    }
    const U8: f32 = 255.0;
    const U16: f32 = 65535.0;
    let pixels = match image {
        DynamicImage::ImageLuma8(b) => b.into_raw(),
        DynamicImage::ImageLumaA8(b) => convert(b.as_raw(), 2, |p| {
            quantise(over_white(p[0] as f32 / U8, p[1] as f32 / U8))
        }),
        DynamicImage::ImageRgb8(b) => convert(b.as_raw(), 3, |p| {
            quantise(luminance(p[0] as f32, p[1] as f32, p[2] as f32) / U8)
        }),
        DynamicImage::ImageRgba8(b) => convert(b.as_raw(), 4, |p| {
            let l = luminance(p[0] as f32, p[1] as f32, p[2] as f32) / U8;
            quantise(over_white(l, p[3] as f32 / U8))
        }),
        DynamicImage::ImageLuma16(b) => convert(b.as_raw(), 1, |p| quantise(p[0] as f32 / U16)),
        DynamicImage::ImageLumaA16(b) => convert(b.as_raw(), 2, |p| {
            quantise(over_white(p[0] as f32 / U16, p[1] as f32 / U16))
        }),
        DynamicImage::ImageRgb16(b) => convert(b.as_raw(), 3, |p| {
            quantise(luminance(p[0] as f32, p[1] as f32, p[2] as f32) / U16)
        }),
        DynamicImage::ImageRgba16(b) => convert(b.as_raw(), 4, |p| {
            let l = luminance(p[0] as f32, p[1] as f32, p[2] as f32) / U16;
            quantise(over_white(l, p[3] as f32 / U16))
        }),
        DynamicImage::ImageRgb32F(b) => {
            convert(b.as_raw(), 3, |p| quantise(luminance(p[0], p[1], p[2])))
        }
        DynamicImage::ImageRgba32F(b) => convert(b.as_raw(), 4, |p| {
            quantise(over_white(
                luminance(p[0], p[1], p[2]),
                p[3].clamp(0.0, 1.0),
            ))
        }),
        other => convert(other.to_rgba8().as_raw(), 4, |p| {
            let l = luminance(p[0] as f32, p[1] as f32, p[2] as f32) / U8;
            quantise(over_white(l, p[3] as f32 / U8))
        }),
    };
    GrayImage {
        width,
        height,
        pixels,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ::image::{ExtendedColorType, ImageEncoder};

    fn encode(
        format: ImageFormat,
        width: u32,
        height: u32,
        data: &[u8],
        color: ExtendedColorType,
    ) -> Vec<u8> {
        let mut out = Vec::new();
        ::image::write_buffer_with_format(
            &mut Cursor::new(&mut out),
            data,
            width,
            height,
            color,
            format,
        )
        .unwrap();
        out
    }

    /// A 4 × 1 ramp in every format and layout reads as the same gray levels.
    const GRAY: [u8; 4] = [0, 85, 170, 255];

    fn gray_of(bytes: &[u8]) -> Vec<u8> {
        decode(bytes, &Limits::default()).unwrap().pixels
    }

    #[test]
    fn gray_reads_identically_from_every_lossless_format() {
        for format in [
            ImageFormat::Png,
            ImageFormat::Bmp,
            ImageFormat::Tiff,
            ImageFormat::Pnm,
        ] {
            let color = if format == ImageFormat::Bmp {
                ExtendedColorType::Rgb8 // BMP has no 8-bit gray without a palette
            } else {
                ExtendedColorType::L8
            };
            let data: Vec<u8> = if color == ExtendedColorType::Rgb8 {
                GRAY.iter().flat_map(|&g| [g, g, g]).collect()
            } else {
                GRAY.to_vec()
            };
            assert_eq!(
                gray_of(&encode(format, 4, 1, &data, color)),
                GRAY,
                "{format:?}"
            );
        }
    }

    #[test]
    fn webp_reads() {
        let mut out = Vec::new();
        ::image::codecs::webp::WebPEncoder::new_lossless(&mut out)
            .write_image(&[0, 0, 0, 255, 255, 255], 2, 1, ExtendedColorType::Rgb8)
            .unwrap();
        assert_eq!(gray_of(&out), [0, 255]);
    }

    #[test]
    fn jpeg_reads_close_to_its_source() {
        let data: Vec<u8> = (0..64 * 64)
            .map(|i| if (i % 64) < 32 { 20 } else { 230 })
            .collect();
        let jpeg = encode(ImageFormat::Jpeg, 64, 64, &data, ExtendedColorType::L8);
        let gray = gray_of(&jpeg);
        assert_eq!(gray.len(), 64 * 64);
        assert!((gray[64 * 10 + 5] as i32 - 20).abs() <= 3);
        assert!((gray[64 * 10 + 60] as i32 - 230).abs() <= 3);
    }

    #[test]
    fn a_cut_off_jpeg_is_corrupt_not_gray_filled() {
        let data: Vec<u8> = (0..64 * 64).map(|i| (i % 251) as u8).collect();
        let jpeg = encode(ImageFormat::Jpeg, 64, 64, &data, ExtendedColorType::L8);
        let err = decode(&jpeg[..jpeg.len() - 40], &Limits::default()).unwrap_err();
        assert!(matches!(err.kind, ImageErrorKind::Corrupt { .. }), "{err}");
    }

    #[test]
    fn a_header_alone_is_judged_by_the_size_it_claims() {
        let png = black_png_300x200();
        // Signature + IHDR only: 33 bytes.
        let err = decode(&png[..33], &Limits { max_pixels: 1000 }).unwrap_err();
        assert_too_large_300x200(&err);
        let err = decode(&png[..33], &Limits::default()).unwrap_err();
        assert!(matches!(err.kind, ImageErrorKind::Corrupt { .. }), "{err}");
    }

    #[test]
    fn colour_uses_the_rec709_weights() {
        let png = encode(
            ImageFormat::Png,
            3,
            1,
            &[255, 0, 0, 0, 255, 0, 0, 0, 255],
            ExtendedColorType::Rgb8,
        );
        assert_eq!(gray_of(&png), [54, 182, 18]); // 0.2126, 0.7152, 0.0722 of 255, rounded
    }

    #[test]
    fn alpha_composites_over_white_paper() {
        // Opaque black, transparent black, half-transparent black.
        let png = encode(
            ImageFormat::Png,
            3,
            1,
            &[0, 0, 0, 255, 0, 0, 0, 0, 0, 0, 0, 128],
            ExtendedColorType::Rgba8,
        );
        assert_eq!(gray_of(&png), [0, 255, 127]);
        let la = encode(
            ImageFormat::Png,
            2,
            1,
            &[0, 255, 0, 0],
            ExtendedColorType::La8,
        );
        assert_eq!(gray_of(&la), [0, 255]);
    }

    #[test]
    fn sixteen_bit_scales_to_eight() {
        // The PNG encoder takes 16-bit samples in native order.
        let native: Vec<u8> = [0u16, 0x8080, 0xffff]
            .iter()
            .flat_map(|v| v.to_ne_bytes())
            .collect();
        let png = encode(ImageFormat::Png, 3, 1, &native, ExtendedColorType::L16);
        assert_eq!(gray_of(&png), [0, 128, 255]);
        let rgb16: Vec<u8> = [0xffffu16, 0xffff, 0xffff, 0, 0, 0]
            .iter()
            .flat_map(|v| v.to_ne_bytes())
            .collect();
        let png = encode(ImageFormat::Png, 2, 1, &rgb16, ExtendedColorType::Rgb16);
        assert_eq!(gray_of(&png), [255, 0]);
    }

    #[test]
    fn palette_png_expands() {
        // A hand-made 2-colour palette PNG (red, blue), written with the png crate's encoder.
        let mut out = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut out, 2, 1);
            enc.set_color(png::ColorType::Indexed);
            enc.set_depth(png::BitDepth::Eight);
            enc.set_palette(vec![255, 0, 0, 0, 0, 255]);
            enc.write_header()
                .unwrap()
                .write_image_data(&[0, 1])
                .unwrap();
        }
        assert_eq!(gray_of(&out), [54, 18]);
    }

    fn black_png_300x200() -> Vec<u8> {
        encode(
            ImageFormat::Png,
            300,
            200,
            &vec![0; 300 * 200],
            ExtendedColorType::L8,
        )
    }

    fn assert_too_large_300x200(err: &ImageError) {
        let is_it = matches!(
            err.kind,
            ImageErrorKind::TooLarge {
                width: 300,
                height: 200,
                ..
            }
        );
        assert!(is_it, "{err}");
    }

    #[test]
    fn an_oversized_header_is_refused_before_decoding() {
        let png = black_png_300x200();
        let err = decode(&png, &Limits { max_pixels: 59_999 }).unwrap_err();
        assert_too_large_300x200(&err);
        assert!(err.to_string().contains("300×200"), "{err}");
        assert!(decode(&png, &Limits { max_pixels: 60_000 }).is_ok());
    }

    #[test]
    fn garbage_and_truncated_files_are_bad_input_named_once() {
        let dir = tempfile::tempdir().unwrap();
        let text = dir.path().join("notes.png");
        std::fs::write(&text, b"this is not an image").unwrap();
        let err = read(&text, &Limits::default()).unwrap_err();
        assert!(matches!(err.kind, ImageErrorKind::UnknownFormat), "{err}");
        assert!(err.kind.is_bad_input());
        let shown = err.to_string();
        assert_eq!(shown.matches("notes.png").count(), 1, "{shown}");

        let png = encode(
            ImageFormat::Png,
            64,
            64,
            &vec![7; 64 * 64],
            ExtendedColorType::L8,
        );
        let cut = dir.path().join("cut.png");
        std::fs::write(&cut, &png[..png.len() / 2]).unwrap();
        let err = read(&cut, &Limits::default()).unwrap_err();
        assert!(err.kind.is_bad_input(), "{err:?}");
        assert_eq!(err.to_string().matches("cut.png").count(), 1, "{err}");

        let missing = read(&dir.path().join("missing.png"), &Limits::default()).unwrap_err();
        assert!(missing.kind.is_bad_input());
        assert_eq!(
            missing.to_string().matches("missing.png").count(),
            1,
            "{missing}"
        );
    }
}
