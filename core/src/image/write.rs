//! Writing gray images: PNG, the format of every image Tagsmith produces.

use super::GrayImage;
use ::image::{codecs::png::PngEncoder, ExtendedColorType, ImageEncoder};

/// An 8-bit grayscale PNG.
pub fn encode_png(image: &GrayImage) -> Result<Vec<u8>, ::image::ImageError> {
    let mut out = Vec::new();
    PngEncoder::new(&mut out).write_image(
        &image.pixels,
        image.width,
        image.height,
        ExtendedColorType::L8,
    )?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::{decode, Limits};
    use super::*;

    #[test]
    fn png_round_trips() {
        let image = GrayImage {
            width: 3,
            height: 2,
            pixels: vec![0, 1, 2, 253, 254, 255].into(),
        };
        let back = decode(&encode_png(&image).unwrap(), &Limits::default()).unwrap();
        assert_eq!(back, image);
    }
}
