//! The data files the library reads at run time, by their path under the repository's `assets/`:
//! the label font (sheets; the browser studio's text too), the synthesis backgrounds, the
//! sample photographs the studio opens and the detector's shipped weights. Native
//! builds embed them. The browser build does not: the page and its worker fetch them from beside
//! the module (`scripts/build-web.sh` copies them into the site) and hand them over with
//! [`provide`] before anything renders, which keeps 2.5 MB of data out of the wasm module that
//! every visit compiles (BENCHMARKS.md, "Studio, browser and CLI"), and lets a family's weights
//! ship without growing it.

/// The asset paths, once: the constants, and on native builds the embedded bytes.
macro_rules! assets {
    (
        font: $font:literal,
        backgrounds: [$($background:literal),* $(,)?],
        samples: [$($sample:literal),* $(,)?],
        models: [$($model:literal),* $(,)?] $(,)?
    ) => {
        /// The label font (DejaVu Sans; licence in `assets/fonts/`).
        pub const LABEL_FONT: &str = $font;

        /// The photographs backgrounds are cropped from (sources and licences in
        /// `assets/backgrounds/`).
        pub const BACKGROUNDS: &[&str] = &[$($background),*];

        /// Photographs with markers the studio offers to try the detector on (sources and
        /// licences in `assets/samples/`).
        pub const SAMPLES: &[&str] = &[$($sample),*];

        /// The detector's shipped weights (`crate::detect`'s stage 1 and each layout's stage 2;
        /// how each was trained: BENCHMARKS.md, "Training").
        pub const MODELS: &[&str] = &[$($model),*];

        #[cfg(not(target_arch = "wasm32"))]
        fn embedded(path: &str) -> Option<&'static [u8]> {
            match path {
                $font => Some(include_bytes!(concat!("../../assets/", $font))),
                $($background => Some(include_bytes!(concat!("../../assets/", $background))),)*
                $($sample => Some(include_bytes!(concat!("../../assets/", $sample))),)*
                $($model => Some(include_bytes!(concat!("../../assets/", $model))),)*
                _ => None,
            }
        }
    };
}

assets!(
    font: "fonts/DejaVuSans.ttf",
    backgrounds: [
        "backgrounds/astronaut.png",
        "backgrounds/brick.png",
        "backgrounds/camera.png",
        "backgrounds/chelsea.png",
        "backgrounds/coffee.png",
        "backgrounds/grass.png",
        "backgrounds/gravel.png",
        "backgrounds/rocket.png",
    ],
    samples: [
        "samples/aruco-6x6_250-tutorial.jpg",
        "samples/apriltag-36h11-swarmathon.jpg",
        "samples/apriltag-xo-36h11-synthetic.png",
    ],
    models: [
        "models/square.stage1.bin",
        "models/square.verifier.bin",
        "models/grid-6-bw.stage2.bin",
        "models/grid-7-bw.stage2.bin",
        "models/grid-8-bw.stage2.bin",
        "models/apriltag-xo-36h11.stage2.bin",
        "models/topotag-like.stage2.bin",
        "models/quaternary-6x6.stage2.bin",
        "models/apriltag-xa-36h11.stage2.bin",
        "models/apriltag-standard41h12.stage2.bin",
        "models/apriltag-circle21h7.stage2.bin",
        "models/runetag.stage2.bin",
    ],
);

/// Every file [`file`] serves: what the browser build fetches.
pub fn all() -> impl Iterator<Item = &'static str> {
    (std::iter::once(LABEL_FONT))
        .chain(BACKGROUNDS.iter().copied())
        .chain(SAMPLES.iter().copied())
        .chain(MODELS.iter().copied())
}

/// The bytes of asset `path` (one of [`all`]).
///
/// # Panics
/// On a path not in [`all`], and in the browser build before [`provide`] has handed it over:
/// both are mistakes in the program, not in its input.
pub fn file(path: &str) -> &'static [u8] {
    source::get(path).unwrap_or_else(|| panic!("asset {path} is not loaded ({})", source::WHERE))
}

#[cfg(not(target_arch = "wasm32"))]
mod source {
    pub const WHERE: &str = "not one of the embedded files";
    pub fn get(path: &str) -> Option<&'static [u8]> {
        super::embedded(path)
    }
}

#[cfg(target_arch = "wasm32")]
mod source {
    use std::collections::HashMap;
    use std::sync::OnceLock;

    pub const WHERE: &str = "the page hands the fetched assets over with assets::provide first";

    pub static PROVIDED: OnceLock<HashMap<String, &'static [u8]>> = OnceLock::new();

    pub fn get(path: &str) -> Option<&'static [u8]> {
        PROVIDED.get()?.get(path).copied()
    }
}

/// Why [`provide`] refused the files handed over.
#[derive(Debug, thiserror::Error)]
pub enum AssetError {
    #[error("asset {0} is missing")]
    Missing(&'static str),
    #[error("the assets were handed over already")]
    Twice,
}

/// Hands the fetched files (path, bytes) to the browser build; every one of [`all`] must be
/// among them. The bytes live as long as the page: they are read for every sheet and scene.
#[cfg(target_arch = "wasm32")]
pub fn provide(files: Vec<(String, Vec<u8>)>) -> Result<(), AssetError> {
    let files: std::collections::HashMap<String, &'static [u8]> = (files.into_iter())
        .map(|(path, bytes)| (path, &*Box::leak(bytes.into_boxed_slice())))
        .collect();
    if let Some(missing) = all().find(|path| !files.contains_key(*path)) {
        return Err(AssetError::Missing(missing));
    }
    source::PROVIDED.set(files).map_err(|_| AssetError::Twice)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_listed_asset_is_embedded_and_is_what_its_name_says() {
        assert!(
            file(LABEL_FONT).starts_with(&[0, 1, 0, 0]),
            "a TrueType font"
        );
        for path in BACKGROUNDS.iter().copied() {
            assert!(file(path).starts_with(b"\x89PNG"), "{path}");
        }
        for path in SAMPLES.iter().copied() {
            assert!(
                crate::image::decode(file(path), &Default::default()).is_ok(),
                "{path}"
            );
        }
        for path in MODELS.iter().copied() {
            assert!(file(path).starts_with(b"TAGSMITH"), "{path}");
        }
        assert_eq!(all().count(), 24);
    }

    #[test]
    #[should_panic(expected = "asset fonts/missing.ttf is not loaded")]
    fn an_unknown_asset_is_a_clear_panic() {
        file("fonts/missing.ttf");
    }
}
