//! Stage 2's training patches.
//!
//! Sample `i` of a run is a pure function of (run seed, i): the synthesiser's patch mode (the ROI
//! mapped to a random quad, a_i ~ U[0.05, 0.25], blur, noise, lighting) then a turn of the whole
//! patch by a random multiple of 90°, because stage 1's ROI starts at whichever corner it sees
//! first.

use crate::detect::stage2::anchors::{encode, PatchSpec, Targets};
use crate::detect::stage2::normalise_patch;
use crate::family::Family;
use crate::image::GrayImage;
use crate::synth::{synthesize, KeypointTruth, MarkerTruth, Mode, SynthConfig};

/// One training patch with its targets.
pub struct PatchSample {
    pub image: GrayImage,
    /// [`normalise_patch`] of the image: the network's input.
    pub input: Vec<f32>,
    pub targets: Targets,
    /// Ground truth in the patch as turned.
    pub truth: MarkerTruth,
}

/// Turns a point by 90° clockwise (y down) `quarter` times in a `size`² patch.
fn turn(p: [f64; 2], size: u32, quarter: u64) -> [f64; 2] {
    (0..quarter).fold(p, |[x, y], _| [size as f64 - 1.0 - y, x])
}

fn turn_image(image: &GrayImage, quarter: u64) -> GrayImage {
    let mut img = image.clone();
    for _ in 0..quarter {
        let n = img.width as usize;
        let mut out = GrayImage::new(img.width, img.height, 0);
        for y in 0..n {
            for x in 0..n {
                out.pixels[x * n + (n - 1 - y)] = img.pixels[y * n + x];
            }
        }
        img = out;
    }
    img
}

/// The patch of sample `seed`.
pub fn make_sample(family: &Family, spec: &PatchSpec, seed: u64) -> Result<PatchSample, String> {
    let mut config = SynthConfig::new(Mode::Patch);
    config.width = spec.size;
    config.height = spec.size;
    let sample = synthesize(family, &config, seed).map_err(|e| e.to_string())?;
    // Only layouts that map onto themselves under a quarter turn (grids) can be seen turned by
    // one; ring markers' ROI fixes their orientation.
    let turns = family
        .rotations()
        .iter()
        .any(|r| (r.angle_deg - 90.0).abs() < 1e-9);
    let quarter = if turns {
        seed.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 62
    } else {
        0
    };
    let truth = sample
        .truth
        .markers
        .into_iter()
        .next()
        .ok_or("the synthesiser placed no marker in the patch")?;
    let at = |p: [f64; 2]| turn(p, spec.size, quarter);
    let truth = MarkerTruth {
        roi: truth.roi.iter().map(|&p| at(p)).collect(),
        mask: truth.mask.iter().map(|&p| at(p)).collect(),
        keypoints: truth
            .keypoints
            .iter()
            .map(|k| {
                let [x, y] = at([k.x, k.y]);
                KeypointTruth { x, y, ..k.clone() }
            })
            .collect(),
        ..truth
    };
    let regressed: Vec<KeypointTruth> = family
        .regressed_keypoints()
        .iter()
        .map(|&i| truth.keypoints[i].clone())
        .collect();
    let targets = encode(spec, &regressed, &truth.roi, &truth.mask);
    let image = turn_image(&sample.image, quarter);
    Ok(PatchSample {
        input: normalise_patch(&image),
        image,
        targets,
        truth,
    })
}
