//! Stage 2 of the learned detector: a rough marker ROI → a rectified patch → every keypoint with
//! its category → sorted to the family's template → ID, rotation, corrected errors → keypoints in
//! the image → pose.
//!
//! [`anchors`] (patch geometry, target encoding and output decoding), [`sort`] (template fit) and
//! [`decode`] (the chain from network outputs to an ID, shared by inference and validation) are
//! plain Rust; the network ([`net`]), the model file ([`model_file`]) and the pipeline on an image
//! ([`pipeline`]) need the `detect` feature (burn).

pub mod anchors;
pub mod decode;
pub mod sort;

#[cfg(feature = "detect")]
pub mod model_file;
#[cfg(feature = "detect")]
pub mod net;
#[cfg(feature = "detect")]
pub mod pipeline;

#[cfg(feature = "detect")]
pub use crate::detect::blocks::Contrast;
#[cfg(feature = "detect")]
pub(crate) use pipeline::{PassMemo, RetryGate};
#[cfg(feature = "detect")]
pub use pipeline::{ReadOptions, Stage2, Stage2Result};

/// The 8 × 8 black-and-white grid's weights (a one-cell black border round 6 × 6 data cells),
/// trained on AprilTag 36h11's and ArUco 6x6_250's codes together: both families ship them, so a
/// detection of both reads each quad with one network pass (`PassMemo`; BENCHMARKS.md, "One
/// model for one layout").
const GRID_8_BLACK_WHITE: &str = "models/grid-8-bw.stage2.bin";

/// The 6 × 6 black-and-white grid's weights (4 × 4 data cells), fine-tuned from the 8 × 8 grid's
/// on AprilTag 16h5's and ArUco 4x4_50's codes together (BENCHMARKS.md, "Every family
/// detecting").
const GRID_6_BLACK_WHITE: &str = "models/grid-6-bw.stage2.bin";

/// The 7 × 7 grid's (5 × 5 data cells), fine-tuned the same way on AprilTag 25h9's and ArUco
/// 5x5_100's codes.
const GRID_7_BLACK_WHITE: &str = "models/grid-7-bw.stage2.bin";

/// Stage-2 weights shipped in `assets/models/` for built-in families, by family name: the
/// asset each family's model is ([`crate::assets`]).
const SHIPPED: &[(&str, &str)] = &[
    ("apriltag-16h5", GRID_6_BLACK_WHITE),
    ("apriltag-25h9", GRID_7_BLACK_WHITE),
    ("apriltag-36h11", GRID_8_BLACK_WHITE),
    ("apriltag-xo-36h11", "models/apriltag-xo-36h11.stage2.bin"),
    // Fine-tuned from the XO model: the same frame, an X for 0 and a filled triangle for 1.
    ("apriltag-xa-36h11", "models/apriltag-xa-36h11.stage2.bin"),
    ("aruco-4x4_50", GRID_6_BLACK_WHITE),
    ("aruco-5x5_100", GRID_7_BLACK_WHITE),
    ("aruco-6x6_250", GRID_8_BLACK_WHITE),
    // Never trained on: the same layout as the two above, each read with its own codebook.
    ("aruco-mip-36h12", GRID_8_BLACK_WHITE),
    ("artoolkitplus-bch", GRID_8_BLACK_WHITE),
    // Fine-tuned from the XO model (three categories too: a black ground, a disc, a ring).
    ("topotag-like", "models/topotag-like.stage2.bin"),
    // The grid model's trunk with a class head of its own (five categories).
    ("quaternary-6x6", "models/quaternary-6x6.stage2.bin"),
    // The 8 × 8 grid model fine-tuned on a patch with a wider margin: data cells lie outside the
    // black frame, round the ROI inside it.
    (
        "apriltag-standard41h12",
        "models/apriltag-standard41h12.stage2.bin",
    ),
    // Fine-tuned from 41h12's: the same frame and margin, without the corner cells.
    (
        "apriltag-circle21h7",
        "models/apriltag-circle21h7.stage2.bin",
    ),
    // Rings: a 256-px patch, one keypoint per slot, trained on the ring turned anywhere within
    // its ROI (the ring search fixes no turn).
    ("runetag", RINGS),
];

/// RuneTag's: three rings of 43 slots.
const RINGS: &str = "models/runetag.stage2.bin";

/// The built-in families with shipped stage-2 weights.
pub fn shipped_families() -> impl Iterator<Item = &'static str> {
    SHIPPED.iter().map(|(name, _)| *name)
}

/// The families a detection reads when none are named (`tagsmith detect`, the Detect panel's
/// ticks, the Python `Detector`): a short list, not every family with weights, because each
/// further family costs its decoding, alignment and cell reads on every image, even where it
/// shares the network's passes (BENCHMARKS.md, "Every family detecting", has the cost); the
/// others are read when named.
pub const DEFAULT_FAMILIES: &[&str] = &["apriltag-36h11", "apriltag-xo-36h11", "aruco-6x6_250"];

/// The shipped models a new design's stage 2 can be fine-tuned from, in the order they are
/// preferred: the grid model (two categories), the XO model (a frame and two glyphs) and the
/// ring model (dots round rings, on the larger patch).
#[cfg(feature = "detect")]
const FINE_TUNE_MODELS: &[&str] = &[
    GRID_8_BLACK_WHITE,
    "models/apriltag-xo-36h11.stage2.bin",
    RINGS,
];

/// Where a new design's stage 2 starts when fine-tuned ([`fine_tune_start`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FineTuneStart {
    /// The shipped model, as an asset path (`models/….stage2.bin`).
    pub asset: &'static str,
    /// Whether its class head starts fresh: the design's categories are not as many as the
    /// model's ([`model_file::to_fine_tune`]).
    pub fresh_class_head: bool,
}

impl FineTuneStart {
    pub fn bytes(&self) -> &'static [u8] {
        crate::assets::file(self.asset)
    }
}

/// The shipped model a new design's stage 2 is fine-tuned from: one whose network fits it
/// whole (as many categories, the same patch side), else the grid model with a fresh class head
/// where the patch side fits. What the trunk learned of frames, cells and perspective carries
/// over, so a few thousand steps do what a fresh network needs ten thousand for (BENCHMARKS.md,
/// "Every family detecting"). A ring design starts from the ring model the same way. `None`:
/// the design's patch is a size no shipped model has (dense keypoints); it trains from fresh
/// weights.
#[cfg(feature = "detect")]
pub fn fine_tune_start(family: &crate::Family) -> Option<FineTuneStart> {
    // Read once: the Train panel asks on every frame.
    static NETS: std::sync::OnceLock<Vec<Option<net::NetConfig>>> = std::sync::OnceLock::new();
    let nets = NETS.get_or_init(|| {
        (FINE_TUNE_MODELS.iter())
            .map(|asset| {
                let bytes = crate::assets::file(asset);
                Some(model_file::read_header(bytes, asset).ok()?.0.net)
            })
            .collect()
    });
    let candidates = || {
        FINE_TUNE_MODELS
            .iter()
            .zip(nets)
            .filter_map(|(a, n)| Some((*a, n.as_ref()?)))
    };
    let whole =
        candidates().find(|(asset, net)| model_file::check_network(net, asset, family).is_ok());
    if let Some((asset, _)) = whole {
        return Some(FineTuneStart {
            asset,
            fresh_class_head: false,
        });
    }
    let (asset, _) =
        candidates().find(|(asset, net)| model_file::check_patch(net, asset, family).is_ok())?;
    Some(FineTuneStart {
        asset,
        fresh_class_head: true,
    })
}

/// The shipped stage-2 model file of a built-in family, if it has one.
pub fn shipped_model(family: &str) -> Option<&'static [u8]> {
    SHIPPED
        .iter()
        .find(|(name, _)| *name == family)
        .map(|(_, asset)| crate::assets::file(asset))
}

/// The shipped stage-2 model that reads `family`, with the asset it is: a built-in's own, or
/// for a family not built in, the model trained on its layout (the same cells, categories,
/// keypoints and ROI: [`model_file::family_hash`], on the same background). The network never
/// sees a codebook, so a user's grid design with a code table of its own reads with no training,
/// as ArUco MIP 36h12 and ARToolKitPlus read on the model of 36h11 and 6x6_250. A family named
/// like a built-in but drawn otherwise gets none.
#[cfg(feature = "detect")]
pub fn shipped_model_for(family: &crate::Family) -> Option<(&'static str, &'static [u8])> {
    /// A shipped model's layout and the background of the built-ins it reads.
    struct Layout {
        asset: &'static str,
        hash: String,
        background: String,
    }
    // Read once: the studio asks while it draws.
    static LAYOUTS: std::sync::OnceLock<Vec<Layout>> = std::sync::OnceLock::new();
    let layouts = LAYOUTS.get_or_init(|| {
        let mut layouts: Vec<Layout> = Vec::new();
        for (name, asset) in SHIPPED {
            if layouts.iter().any(|l| l.asset == *asset) {
                continue;
            }
            let header = model_file::read_header(crate::assets::file(asset), asset);
            if let (Ok((header, _)), Some(Ok(builtin))) = (header, crate::builtin::get(name)) {
                layouts.push(Layout {
                    asset,
                    hash: header.family_hash,
                    background: builtin.spec().background.clone(),
                });
            }
        }
        layouts
    });
    let hash = model_file::family_hash(family);
    let fits = |l: &&Layout| l.hash == hash && l.background == family.spec().background;
    let own = SHIPPED.iter().find(|(name, _)| *name == family.name());
    let layout = match own {
        Some((_, asset)) => layouts.iter().find(|l| l.asset == *asset).filter(fits)?,
        None => layouts.iter().find(fits)?,
    };
    Some((layout.asset, crate::assets::file(layout.asset)))
}

/// The network's input: each patch standardised to zero mean and unit contrast, so the marker's
/// gray levels and lighting (black is not 0, white not 255 in the training data) do not matter.
#[cfg(feature = "detect")]
pub fn normalise_patch(patch: &crate::image::GrayImage) -> Vec<f32> {
    Contrast::of(patch).normalise(patch)
}

#[cfg(all(test, feature = "learn"))]
mod shipped_tests;
#[cfg(test)]
mod tests;
