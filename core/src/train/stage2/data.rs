//! Stage 2's training patches.
//!
//! Sample `i` of a run is a pure function of (run seed, i): either the synthesiser's patch mode
//! (the ROI mapped to a random quad, a_i within a seventh of the template's side of the family's
//! margin: U[0.05, 0.25] at 0.15; blur, noise, lighting) or, for a share of the samples, a patch
//! cut from a steep camera view ([`camera_cut`]); then a turn of the whole patch by a random
//! multiple of 90°, because stage 1's ROI starts at whichever corner it sees first.

use crate::detect::stage2::anchors::{encode, PatchSpec, Targets};
use crate::detect::stage2::normalise_patch;
use crate::family::Family;
use crate::geometry::{bounding_box, warp_bilinear, Homography, Quad};
use crate::image::GrayImage;
use crate::synth::{ring_turn, synthesize, KeypointTruth, MarkerTruth, Mode, SynthConfig};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The share of training patches cut from camera views when a run does not say otherwise.
/// Patch mode draws the marker at patch resolution under mild perspective; a steep view of a
/// small marker reaches stage 2 as a patch stretched ~10× along one axis, which patch mode never
/// shows it (docs/BENCHMARKS-HISTORY.md, "Before: stage 2 trained on steep camera views, and stricter reads").
pub const DEFAULT_CAMERA_SHARE: f64 = 0.3;

/// How far away a camera cut's marker stands. Far steep slivers (35–60 px long, 9–16 px wide)
/// read from true ROIs with 0 corrections but missed or needed 3–5 once their corners moved by
/// 2–4 % of the side (`detect-set --roi-noise`), and the first camera cuts (10–60 cm) drew few of
/// them (docs/BENCHMARKS-HISTORY.md, "Before: stage 2 fine-tuned on far steep cuts …").
const CUT_DISTANCE_M: [f64; 2] = [0.1, 0.8];

/// The scale of a camera cut's ROI error (pixels; the error is about normal with a standard
/// deviation drawn up to this).
const CUT_ROI_ERROR_PX: f64 = 2.0;

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

/// A uniform number in [0, 1) from `seed`, independent of the synthesiser's own draws.
fn unit(seed: u64, salt: u64) -> f64 {
    let mixed = (seed ^ salt).wrapping_mul(0xD1B5_4A32_D192_ED03);
    (mixed >> 11) as f64 / (1u64 << 53) as f64
}

/// The patch of sample `seed`: cut from a camera view with probability `camera_share`.
pub fn make_sample(
    family: &Family,
    spec: &PatchSpec,
    seed: u64,
    camera_share: f64,
) -> Result<PatchSample, String> {
    let cut = if unit(seed, 0xC0FF_EE00) < camera_share {
        camera_cut(family, spec, seed)?
    } else {
        None
    };
    let (image, truth) = match cut {
        Some(cut) => cut,
        None => patch_mode(family, spec, seed)?,
    };
    Ok(turned(family, spec, seed, image, truth))
}

fn patch_mode(
    family: &Family,
    spec: &PatchSpec,
    seed: u64,
) -> Result<(GrayImage, MarkerTruth), String> {
    let mut config = SynthConfig::new(Mode::Patch);
    config.width = spec.size;
    config.height = spec.size;
    let sample = synthesize(family, &config, seed).map_err(|e| e.to_string())?;
    let truth = sample
        .truth
        .markers
        .into_iter()
        .next()
        .ok_or("the synthesiser placed no marker in the patch")?;
    Ok((sample.image, truth))
}

/// A patch cut from a 640×480 camera view (98° diagonal) of one marker 3–10 cm wide, 10–80 cm
/// away (the harness camera's 20–160 cm at 1280×960: down to 13 px across) and turned 40–80° away,
/// as the detector cuts it: the ROI (off by a random error of up to about two pixels, as stage 1's,
/// the traced quads' and the frame fit's are on a sliver) warped onto the patch's template corners.
/// `None` when the marker does not lie whole in the view.
fn camera_cut(
    family: &Family,
    spec: &PatchSpec,
    seed: u64,
) -> Result<Option<(GrayImage, MarkerTruth)>, String> {
    let mut config = SynthConfig::new(Mode::Camera);
    config.width = 640;
    config.height = 480;
    config.markers = [1, 1];
    config.distance_m = CUT_DISTANCE_M;
    config.view_angle_deg = [40.0, 80.0];
    let sample = synthesize(family, &config, seed).map_err(|e| e.to_string())?;
    let Some(truth) = sample.truth.markers.into_iter().next() else {
        return Ok(None);
    };
    let (w, h) = (config.width as f64, config.height as f64);
    let inside = |p: &[f64; 2]| p[0] >= 0.0 && p[1] >= 0.0 && p[0] < w && p[1] < h;
    if truth.roi.len() < 4 || !truth.roi.iter().all(inside) {
        return Ok(None);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5EED_0FC0);
    let Some(seen_roi) = ring_roi_turned(family, &truth.roi, &mut rng) else {
        return Ok(None);
    };
    let sigma = rng.random_range(0.0..CUT_ROI_ERROR_PX);
    let roi = Quad(std::array::from_fn(|i| {
        let [x, y] = seen_roi[i];
        // A sum of uniforms is close enough to a normal error here.
        let mut off = || (0..3).map(|_| rng.random_range(-1.0..1.0)).sum::<f64>() * sigma;
        [x + off(), y + off()]
    }));
    let Ok(to_image) = Homography::from_points(&spec.template_corners()[..], &roi[..]) else {
        return Ok(None);
    };
    let Some(to_patch) = to_image.inverse() else {
        return Ok(None);
    };
    let patch = warp_bilinear(&sample.image, &to_image, spec.size, spec.size, 128);
    let truth = MarkerTruth {
        roi: seen_roi,
        ..truth
    };
    let truth = mapped(truth, |p| to_patch.apply(p));
    let bbox = bounding_box(&truth.mask);
    let truth = MarkerTruth { bbox, ..truth };
    Ok(Some((patch, truth)))
}

/// The ROI a ring search may give a cyclic ring marker whose true ROI is `roi`: the same
/// square round its outer ring, turned about its centre by a random angle (the ring's ellipse
/// fixes no turn). Other families' ROIs are returned as they are, drawing no random number.
/// `None` when the ROI is degenerate.
fn ring_roi_turned(
    family: &Family,
    roi: &[[f64; 2]],
    rng: &mut ChaCha8Rng,
) -> Option<Vec<[f64; 2]>> {
    if !family.is_cyclic_ring() {
        return Some(roi.to_vec());
    }
    let units = family.roi_points();
    let to_image = Homography::from_points(&units[..4], &roi[..4]).ok()?;
    let turned = Homography(to_image.0 * ring_turn(family, rng));
    Some(units[..4].iter().map(|&p| turned.apply(p)).collect())
}

/// The truth's ROI, outline and keypoints moved by `at` (the box is left as it is).
fn mapped(truth: MarkerTruth, at: impl Fn([f64; 2]) -> [f64; 2]) -> MarkerTruth {
    MarkerTruth {
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
    }
}

/// The sample turned by its quarter turns, with its targets.
fn turned(
    family: &Family,
    spec: &PatchSpec,
    seed: u64,
    image: GrayImage,
    truth: MarkerTruth,
) -> PatchSample {
    // Layouts that map onto themselves under a quarter turn (grids) are seen turned by one, and
    // so is a ring family with one rotation: its orientation marks on the ROI's corners fix
    // the ROI only up to which mark comes first (the detector's sort tries all four). A cyclic
    // ring family is already turned anywhere within its ROI.
    let turns = family
        .rotations()
        .iter()
        .any(|r| (r.angle_deg - 90.0).abs() < 1e-9)
        || family.is_ring_turned_by_marks();
    let quarter = if turns {
        seed.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 62
    } else {
        0
    };
    let truth = mapped(truth, |p| turn(p, spec.size, quarter));
    let regressed: Vec<KeypointTruth> = family
        .regressed_keypoints()
        .iter()
        .map(|&i| truth.keypoints[i].clone())
        .collect();
    let targets = encode(spec, &regressed, &truth.roi, &truth.mask);
    let image = turn_image(&image, quarter);
    PatchSample {
        input: normalise_patch(&image),
        image,
        targets,
        truth,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin;
    use crate::synth::image_seed;

    fn samples(share: f64) -> Vec<PatchSample> {
        let family = builtin::get("apriltag-36h11").unwrap().unwrap();
        let spec = PatchSpec::for_family(&family);
        (0..16)
            .map(|i| make_sample(&family, &spec, image_seed(11, i), share).unwrap())
            .collect()
    }

    /// The largest distance from a truth ROI corner to the nearest template corner.
    fn off_template(sample: &PatchSample, spec: &PatchSpec) -> f64 {
        sample.truth.roi[..4]
            .iter()
            .map(|p| {
                spec.template_corners()
                    .iter()
                    .map(|t| (p[0] - t[0]).hypot(p[1] - t[1]))
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max)
    }

    /// Camera cuts are what the detector warps: the marker's ROI sits on the template corners
    /// (within the simulated ROI error), where patch mode places it anywhere in its margin.
    #[test]
    fn camera_cuts_put_the_roi_where_the_detector_warps_it() {
        let spec = PatchSpec::default();
        let cuts = samples(1.0);
        let near = cuts.iter().filter(|s| off_template(s, &spec) < 6.0).count();
        // A view that does not fit the image falls back to patch mode, and a sliver's ROI error
        // of a pixel or two across its width is ten times that on the patch.
        assert!(
            near >= 9,
            "{near} of 16 camera cuts on the template corners"
        );
        let drawn = samples(0.0);
        let near = drawn
            .iter()
            .filter(|s| off_template(s, &spec) < 6.0)
            .count();
        assert!(
            near <= 4,
            "{near} of 16 patch-mode samples on the template corners"
        );
    }

    /// A cyclic ring marker reaches stage 2 at whatever turn the ring search leaves it: its
    /// patches, drawn and cut alike, show it turned all round the circle within its ROI.
    #[test]
    fn ring_patches_show_the_marker_at_every_turn_within_the_roi() {
        let family = builtin::get("runetag").unwrap().unwrap();
        let spec = PatchSpec::for_family(&family);
        for share in [0.0, 1.0] {
            let set: Vec<PatchSample> = (0..16)
                .map(|i| make_sample(&family, &spec, image_seed(5, i), share).unwrap())
                .collect();
            // The first keypoint's direction from the ROI's centre, against its top edge's.
            let mut resultant = [0.0f64; 2];
            // Turns kept near the patch's axes (a placement retried until the paper fits) show
            // as the mean of cos 4θ near 1; turns all round the circle leave it near nought.
            let mut axial = 0.0f64;
            for sample in &set {
                let roi = &sample.truth.roi;
                let centre = [
                    roi[..4].iter().map(|p| p[0]).sum::<f64>() / 4.0,
                    roi[..4].iter().map(|p| p[1]).sum::<f64>() / 4.0,
                ];
                let top = [(roi[0][0] + roi[1][0]) / 2.0, (roi[0][1] + roi[1][1]) / 2.0];
                let k = &sample.truth.keypoints[0];
                let angle = (k.y - centre[1]).atan2(k.x - centre[0])
                    - (top[1] - centre[1]).atan2(top[0] - centre[0]);
                axial += (4.0 * angle).cos() / set.len() as f64;
                resultant[0] += angle.cos() / set.len() as f64;
                resultant[1] += angle.sin() / set.len() as f64;
            }
            let spread = resultant[0].hypot(resultant[1]);
            assert!(
                spread < 0.5,
                "camera share {share}: turns cluster ({spread:.2})"
            );
            assert!(
                axial < 0.5,
                "camera share {share}: turns kept near the axes ({axial:.2})"
            );
        }
    }

    /// RuneTag+'s patches show it at all four quarter turns: the detector's ROI starts at
    /// whichever of its four orientation marks.
    #[test]
    fn ring_patches_with_orientation_marks_show_every_quarter_turn() {
        let family = builtin::get("runetag-plus").unwrap().unwrap();
        let spec = PatchSpec::for_family(&family);
        let mut first_corners = std::collections::BTreeSet::new();
        for i in 0..16 {
            let sample = make_sample(&family, &spec, image_seed(7, i), 0.0).unwrap();
            let p = sample.truth.roi[0];
            let nearest = (spec.template_corners().iter().enumerate())
                .min_by(|a, b| {
                    let d = |t: &[f64; 2]| (p[0] - t[0]).hypot(p[1] - t[1]);
                    d(a.1).total_cmp(&d(b.1))
                })
                .unwrap()
                .0;
            first_corners.insert(nearest);
        }
        assert_eq!(first_corners.len(), 4, "{first_corners:?}");
    }

    /// The truth keypoints of a camera cut land on their cells: black cells read darker than
    /// white ones, as in patch mode (a wrong mapping would mix them).
    #[test]
    fn camera_cut_keypoints_sit_on_their_cells() {
        let contrast = |set: &[PatchSample]| {
            let mut sums = [[0.0; 2]; 2];
            for s in set {
                for k in s
                    .truth
                    .keypoints
                    .iter()
                    .filter(|k| k.visible && k.category < 2)
                {
                    let (x, y) = (k.x.round() as u32, k.y.round() as u32);
                    if x < s.image.width && y < s.image.height {
                        sums[k.category][0] += s.image.get(x, y) as f64;
                        sums[k.category][1] += 1.0;
                    }
                }
            }
            sums[0][0] / sums[0][1] - sums[1][0] / sums[1][1]
        };
        let (cut, drawn) = (contrast(&samples(1.0)), contrast(&samples(0.0)));
        assert!(drawn.abs() > 40.0, "patch mode: {drawn}");
        assert!(
            cut.signum() == drawn.signum() && cut.abs() > 20.0,
            "camera cuts {cut}, patch mode {drawn}"
        );
    }
}
