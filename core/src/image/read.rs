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

/// The formats [`ImageErrorKind::UnknownFormat`] names.
#[cfg(not(target_arch = "wasm32"))]
const READ_FORMATS: &str = "PNG, JPEG, BMP, TIFF, WebP, PNM";
#[cfg(target_arch = "wasm32")]
const READ_FORMATS: &str = "PNG, JPEG, BMP, PNM; TIFF and WebP on the desktop";

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
    #[error("not an image in a format Tagsmith reads ({READ_FORMATS})")]
    UnknownFormat,
    #[error(
        "the image is {width}×{height} px ({:.1} megapixels), over the limit of {:.1} megapixels",
        *width as f64 * *height as f64 / 1e6,
        *limit as f64 / 1e6
    )]
    TooLarge { width: u32, height: u32, limit: u64 },
    #[error("the {format} data is corrupt or truncated ({message})")]
    Corrupt { format: String, message: String },
    /// A well-formed image of a kind the decoders do not read (a sample format, a size).
    #[error("unsupported {format} image ({message})")]
    Unsupported { format: String, message: String },
}

impl ImageErrorKind {
    /// Whether the input is at fault (a missing, corrupt, unknown, unsupported or oversized image,
    /// a FIFO, a device or a folder) rather than the system (a read that failed half-way).
    pub fn is_bad_input(&self) -> bool {
        match self {
            Self::Io(e) => crate::io::is_bad_input(e),
            _ => true,
        }
    }
}

/// The BMP decoder's own limit on either side (it refuses larger images as a guard against
/// memory exhaustion, whatever the pixel count).
const BMP_MAX_SIDE: u64 = 0xFFFF;

/// Reads an image file as gray (colour by [`luminance`], alpha composited over white paper,
/// 16-bit and float scaled, palettes expanded, EXIF orientation applied as photo viewers and
/// OpenCV's `imread` do). Only a regular file is read ([`crate::io::open_input`]): a FIFO would
/// block, a device never end, and a folder has no pixels.
pub fn read(path: &Path, limits: &Limits) -> Result<GrayImage, ImageError> {
    let with_path = |kind| ImageError {
        path: Some(path.to_path_buf()),
        kind,
    };
    let file = crate::io::open_input(path).map_err(|e| with_path(e.into()))?;
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
    let size = imagesize::reader_size(&mut source).ok();
    if let Some(size) = &size {
        check_size(size.width as u64, size.height as u64, limits)?;
    }
    source.seek(SeekFrom::Start(0))?;
    let reader = ImageReader::new(source).with_guessed_format()?;
    let format = match reader.format() {
        Some(f) if is_supported(f) => f,
        _ => return Err(ImageErrorKind::UnknownFormat),
    };
    match format {
        ImageFormat::Jpeg => {
            let mut bytes = Vec::new();
            let cap = limits.max_pixels.saturating_mul(4).saturating_add(16 << 20);
            reader.into_inner().take(cap).read_to_end(&mut bytes)?;
            decode_jpeg(bytes, limits)
        }
        ImageFormat::Bmp => {
            if let Some(size) = size.filter(|s| s.width.max(s.height) as u64 > BMP_MAX_SIDE) {
                return Err(ImageErrorKind::Unsupported {
                    format: "BMP".into(),
                    message: format!(
                        "it is {}×{} px; the BMP decoder reads at most {BMP_MAX_SIDE} px a side \
                         (convert it to PNG)",
                        size.width, size.height
                    ),
                });
            }
            decode_with(reader, format, limits)
        }
        #[cfg(not(target_arch = "wasm32"))]
        ImageFormat::Tiff => {
            let mut source = reader.into_inner();
            match decode_with(
                ImageReader::with_format(&mut source, format),
                format,
                limits,
            ) {
                Err(unsupported @ ImageErrorKind::Unsupported { .. }) => {
                    source.seek(SeekFrom::Start(0))?;
                    decode_tiff_samples(source, limits)?.ok_or(unsupported)
                }
                other => other,
            }
        }
        _ => decode_with(reader, format, limits),
    }
}

/// Decodes a JPEG that must be whole. JPEG decoders fill what a cut-off file lacks with gray and
/// succeed; a photo that lost its end is bad input. So the file must end its last scan with an
/// end-of-image marker ([`jpeg_end`]), and that marker must come after the scan's last block:
/// a file cut short with an end marker appended still has an end marker, but there the decoder
/// makes up the missing blocks from nothing. Decoded a second time with filler bytes before
/// the end marker, a whole file gives the same pixels (the filler comes after the data the decoder
/// reads), a cut-off one other pixels (the filler becomes the missing blocks).
fn decode_jpeg(bytes: Vec<u8>, limits: &Limits) -> Result<GrayImage, ImageErrorKind> {
    let truncated = || ImageErrorKind::Corrupt {
        format: "JPEG".into(),
        message: "the file ends before its last scan does".into(),
    };
    let Some(end) = jpeg_end(&bytes) else {
        return Err(ImageErrorKind::Corrupt {
            format: "JPEG".into(),
            message: "the file ends before its end-of-image marker".into(),
        });
    };
    let mut filled = Vec::with_capacity(bytes.len() + JPEG_FILLER.len());
    filled.extend_from_slice(&bytes[..end]);
    filled.extend_from_slice(&JPEG_FILLER);
    filled.extend_from_slice(&bytes[end..]);
    let jpeg = |bytes: Vec<u8>| {
        decode_with(
            ImageReader::with_format(Cursor::new(bytes), ImageFormat::Jpeg),
            ImageFormat::Jpeg,
            limits,
        )
    };
    let image = jpeg(bytes)?;
    match jpeg(filled) {
        Ok(again) if again == image => Ok(image),
        _ => Err(truncated()),
    }
}

/// Bytes that are no marker (no 0xFF) and decode to other coefficients than the zero bits a JPEG
/// decoder makes up past the data.
const JPEG_FILLER: [u8; 64] = [0xA5; 64];

/// Where the end-of-image marker of a JPEG's main image is: its marker segments are followed by
/// their lengths (an EXIF thumbnail inside APP1, with its own start, scan and end, is skipped as
/// a whole), each scan's entropy-coded data up to the next marker that is not a restart or a
/// stuffed byte. `None` when the data ends first.
fn jpeg_end(bytes: &[u8]) -> Option<usize> {
    if !bytes.starts_with(&[0xFF, 0xD8]) {
        return None;
    }
    let mut at = 2;
    loop {
        // Decoders skip stray bytes between segments, and fill bytes (0xFF runs) before a marker.
        at += bytes.get(at..)?.iter().position(|&b| b == 0xFF)?;
        let first = at;
        while bytes.get(at + 1) == Some(&0xFF) {
            at += 1;
        }
        let marker = *bytes.get(at + 1)?;
        match marker {
            // Before its fill bytes: the filler [`decode_jpeg`] puts there must not follow one.
            0xD9 => return Some(first),
            // Standalone markers: restarts, start of image, TEM, and a stuffed zero outside a scan.
            0xD0..=0xD8 | 0x01 | 0x00 => at += 2,
            _ => {
                let length = u16::from_be_bytes([*bytes.get(at + 2)?, *bytes.get(at + 3)?]);
                at += 2 + length as usize;
                if marker == 0xDA {
                    // Entropy-coded data up to the next marker: 0xFF 0x00 is a stuffed 0xFF,
                    // 0xFF 0xD0–D7 a restart.
                    loop {
                        at += bytes.get(at..)?.iter().position(|&b| b == 0xFF)?;
                        match *bytes.get(at + 1)? {
                            0x00 | 0xD0..=0xD7 => at += 2,
                            _ => break,
                        }
                    }
                }
            }
        }
    }
}

/// The TIFFs the `image` crate refuses but whose samples are plain gray levels: one channel of
/// 32- or 64-bit floats (scientific and HDR cameras; 0–1, as for the float colour TIFFs the
/// crate reads), 16-bit floats, or 32- and 64-bit unsigned integers (scaled from their range).
/// `None` for other layouts, which stay unsupported.
#[cfg(not(target_arch = "wasm32"))]
fn decode_tiff_samples(
    source: impl BufRead + Seek,
    limits: &Limits,
) -> Result<Option<GrayImage>, ImageErrorKind> {
    use tiff::decoder::{Decoder, DecodingResult};
    let corrupt = |e: tiff::TiffError| match e {
        tiff::TiffError::IoError(io) if io.kind() != std::io::ErrorKind::UnexpectedEof => {
            ImageErrorKind::Io(io)
        }
        other => ImageErrorKind::Corrupt {
            format: "TIFF".into(),
            message: other.to_string(),
        },
    };
    let mut decoder = Decoder::new(source).map_err(corrupt)?;
    let mut tiff_limits = tiff::decoder::Limits::default();
    tiff_limits.decoding_buffer_size =
        usize::try_from(limits.max_pixels.saturating_mul(8)).unwrap_or(usize::MAX);
    decoder = decoder.with_limits(tiff_limits);
    if !matches!(
        decoder.colortype().map_err(corrupt)?,
        tiff::ColorType::Gray(_)
    ) {
        return Ok(None);
    }
    let (width, height) = decoder.dimensions().map_err(corrupt)?;
    check_size(width as u64, height as u64, limits)?;
    let orientation = decoder
        .find_tag_unsigned::<u8>(tiff::tags::Tag::Orientation)
        .ok()
        .flatten()
        .and_then(::image::metadata::Orientation::from_exif);
    let quantise = |v: f64| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    let pixels: Vec<u8> = match decoder.read_image().map_err(corrupt)? {
        DecodingResult::F32(v) => v.into_iter().map(|x| quantise(x as f64)).collect(),
        DecodingResult::F64(v) => v.into_iter().map(quantise).collect(),
        DecodingResult::F16(v) => v.into_iter().map(|x| quantise(x.to_f64())).collect(),
        DecodingResult::U32(v) => (v.into_iter())
            .map(|x| quantise(x as f64 / u32::MAX as f64))
            .collect(),
        DecodingResult::U64(v) => (v.into_iter())
            .map(|x| quantise(x as f64 / u64::MAX as f64))
            .collect(),
        _ => return Ok(None),
    };
    if pixels.len() as u64 != width as u64 * height as u64 {
        return Err(ImageErrorKind::Corrupt {
            format: "TIFF".into(),
            message: format!("{} samples for {width}×{height} pixels", pixels.len()),
        });
    }
    let buffer =
        ::image::GrayImage::from_raw(width, height, pixels).expect("the sample count was checked");
    let mut image = DynamicImage::ImageLuma8(buffer);
    if let Some(o) = orientation {
        image.apply_orientation(o);
    }
    Ok(Some(to_gray(image)))
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
        ::image::ImageError::Unsupported(e) => ImageErrorKind::Unsupported {
            format: name.clone(),
            message: e.to_string(),
        },
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
    // A format built out (TIFF and WebP in the browser) is refused as unknown, with the list.
    format.reading_enabled()
        && matches!(
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
    let quantise = super::quantise_unit;
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
        DynamicImage::ImageRgb8(b) => {
            convert(b.as_raw(), 3, |p| super::gray_of_rgb8(p[0], p[1], p[2]))
        }
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
    GrayImage::from_vec(width, height, pixels)
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
        decode(bytes, &Limits::default()).unwrap().pixels.into_vec()
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

    /// A 64 × 48 gray JPEG with detail everywhere, so every block has coefficients to lose.
    fn detailed_jpeg() -> Vec<u8> {
        let data: Vec<u8> = (0..64 * 48)
            .map(|i| ((i % 64) * 7 + (i / 64) * 13 + (i * i) % 31) as u8)
            .collect();
        encode(ImageFormat::Jpeg, 64, 48, &data, ExtendedColorType::L8)
    }

    #[test]
    fn a_cut_off_jpeg_with_an_end_marker_appended_is_corrupt() {
        let rgb: Vec<u8> = (0..64 * 48 * 3).map(|i| (i * 37 % 251) as u8).collect();
        let colour = encode(ImageFormat::Jpeg, 64, 48, &rgb, ExtendedColorType::Rgb8);
        for jpeg in [detailed_jpeg(), colour] {
            assert!(decode(&jpeg, &Limits::default()).is_ok());
            let scan = jpeg.windows(2).position(|w| w == [0xFF, 0xDA]).unwrap();
            // Cut anywhere in the scan data (not in the last few bytes, which may be padding).
            for cut in [scan + 20, (scan + jpeg.len()) / 2, jpeg.len() - 40] {
                let mut half = jpeg[..cut].to_vec();
                half.extend_from_slice(&[0xFF, 0xD9]);
                let err = decode(&half, &Limits::default()).unwrap_err();
                assert!(
                    matches!(err.kind, ImageErrorKind::Corrupt { .. }),
                    "cut at {cut} of {}: {err}",
                    jpeg.len()
                );
            }
        }
    }

    #[test]
    fn a_whole_jpeg_reads_with_fill_bytes_or_trailing_data_around_its_end() {
        let jpeg = detailed_jpeg();
        let want = decode(&jpeg, &Limits::default()).unwrap();
        let end = jpeg.len() - 2;
        assert_eq!(jpeg[end..], [0xFF, 0xD9]);
        // 0xFF fill bytes before the end marker.
        let mut filled = jpeg[..end].to_vec();
        filled.extend_from_slice(&[0xFF, 0xFF, 0xFF, 0xD9]);
        assert_eq!(decode(&filled, &Limits::default()).unwrap(), want);
        // Bytes after the end (a second image, a camera's trailer).
        let mut trailed = jpeg.clone();
        trailed.extend_from_slice(&jpeg);
        trailed.extend_from_slice(b"trailer");
        assert_eq!(decode(&trailed, &Limits::default()).unwrap(), want);
    }

    #[test]
    fn a_thumbnail_in_the_exif_segment_does_not_end_a_cut_off_jpeg() {
        let thumbnail = encode(ImageFormat::Jpeg, 8, 8, &[90; 64], ExtendedColorType::L8);
        let main = detailed_jpeg();
        let mut app1 = b"Exif\0\0".to_vec();
        app1.extend_from_slice(&thumbnail);
        let mut jpeg = vec![0xFF, 0xD8, 0xFF, 0xE1];
        jpeg.extend_from_slice(&((app1.len() + 2) as u16).to_be_bytes());
        jpeg.extend_from_slice(&app1);
        jpeg.extend_from_slice(&main[2..]);
        assert_eq!(
            decode(&jpeg, &Limits::default()).unwrap(),
            decode(&main, &Limits::default()).unwrap()
        );
        let cut = jpeg.len() - main.len() / 2;
        let err = decode(&jpeg[..cut], &Limits::default()).unwrap_err();
        assert!(matches!(err.kind, ImageErrorKind::Corrupt { .. }), "{err}");
    }

    #[test]
    fn float_tiffs_read_gray_or_colour() {
        let mut gray = Vec::new();
        {
            let mut tiff = tiff::encoder::TiffEncoder::new(Cursor::new(&mut gray)).unwrap();
            tiff.write_image::<tiff::encoder::colortype::Gray32Float>(4, 1, &[0.0, 0.5, 1.0, 2.0])
                .unwrap();
        }
        assert_eq!(gray_of(&gray), [0, 128, 255, 255]);
        let mut gray64 = Vec::new();
        {
            let mut tiff = tiff::encoder::TiffEncoder::new(Cursor::new(&mut gray64)).unwrap();
            tiff.write_image::<tiff::encoder::colortype::Gray64Float>(2, 1, &[0.25, 1.0])
                .unwrap();
        }
        assert_eq!(gray_of(&gray64), [64, 255]);
        let rgb: Vec<u8> = [1.0f32, 1.0, 1.0, 0.0, 0.0, 0.0]
            .iter()
            .flat_map(|v| v.to_ne_bytes())
            .collect();
        let colour = encode(ImageFormat::Tiff, 2, 1, &rgb, ExtendedColorType::Rgb32F);
        assert_eq!(gray_of(&colour), [255, 0]);
    }

    #[test]
    fn a_bmp_longer_than_its_decoder_reads_is_unsupported_not_corrupt() {
        let bmp = encode(
            ImageFormat::Bmp,
            1,
            100_000,
            &vec![128; 300_000],
            ExtendedColorType::Rgb8,
        );
        let err = decode(&bmp, &Limits::default()).unwrap_err();
        assert!(
            matches!(err.kind, ImageErrorKind::Unsupported { .. }),
            "{err}"
        );
        let text = err.to_string();
        assert!(
            text.contains("1×100000") && text.contains("65535"),
            "{text}"
        );
        assert!(err.kind.is_bad_input());
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_a_device_or_a_folder_is_refused_as_bad_input_without_waiting() {
        let dir = tempfile::tempdir().unwrap();
        let mut paths = vec![dir.path().to_path_buf()];
        if Path::new("/dev/zero").exists() {
            paths.push("/dev/zero".into());
        }
        let fifo = dir.path().join("photo.png");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            paths.push(fifo);
        }
        for path in paths {
            let err = read(&path, &Limits::default()).unwrap_err();
            assert!(err.kind.is_bad_input(), "{err}");
            assert!(
                err.to_string().starts_with(&path.display().to_string()),
                "{err}"
            );
        }
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
