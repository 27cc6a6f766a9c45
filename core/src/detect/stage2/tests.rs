use super::anchors::{encode, extract, PatchSpec, RawOutputs};
use super::sort::{observed, read_slots, sort_to_template};
use crate::builtin;
use crate::family::{decode, decode_soft};
use crate::synth::{synthesize, KeypointTruth, Mode, SynthConfig};

/// Turns patch coordinates by 90° clockwise (y down) `quarter` times, as rotating the patch's
/// pixels would.
fn turn(p: [f64; 2], size: u32, quarter: usize) -> [f64; 2] {
    (0..quarter).fold(p, |[x, y], _| [size as f64 - 1.0 - y, x])
}

/// Encoding the ground truth as targets and decoding what a perfect network would output gives
/// back every keypoint at its exact position with its category, and the marker's ID, for grids
/// and rings, upright and turned.
/// Synthesis of single-marker patches the size of `spec`'s.
fn patches_of(spec: &PatchSpec) -> SynthConfig {
    let mut config = SynthConfig::new(Mode::Patch);
    config.width = spec.size;
    config.height = spec.size;
    config
}

#[test]
fn targets_decode_to_the_ground_truth() {
    for name in [
        "apriltag-36h11",
        "apriltag-xo-36h11",
        "topotag-like",
        "runetag",
        // Data cells outside the frame, in the margin round its ROI.
        "apriltag-standard41h12",
    ] {
        let family = builtin::get(name).unwrap().unwrap();
        let spec = PatchSpec::for_family(&family);
        assert_eq!(spec.margin, family.spec().roi.margin, "{name}");
        let config = patches_of(&spec);
        for seed in 0..6u64 {
            let sample = synthesize(&family, &config, seed).unwrap();
            let truth = &sample.truth.markers[0];
            // Rings admit slot shifts, not quarter turns: their ROI fixes the orientation.
            let quarter = if family.is_grid() {
                seed as usize % 4
            } else {
                0
            };
            let keypoints: Vec<KeypointTruth> = truth
                .keypoints
                .iter()
                .map(|k| {
                    let [x, y] = turn([k.x, k.y], spec.size, quarter);
                    KeypointTruth { x, y, ..k.clone() }
                })
                .collect();
            let roi: Vec<[f64; 2]> = truth
                .roi
                .iter()
                .map(|&p| turn(p, spec.size, quarter))
                .collect();
            let outline: Vec<[f64; 2]> = truth
                .mask
                .iter()
                .map(|&p| turn(p, spec.size, quarter))
                .collect();
            let targets = encode(&spec, &keypoints, &roi, &outline);
            let classes = family.categories().len() + 1;
            let raw = RawOutputs::from_targets(&targets, classes);
            let found = extract(&spec, &raw, 0.5);
            assert_eq!(found.len(), keypoints.len(), "{name} seed {seed}");
            let corners = raw.template_corners(&spec);
            let sorted = sort_to_template(&family, &found, &corners)
                .unwrap_or_else(|| panic!("{name} seed {seed}: {corners:?} {:?}", &roi));
            let read = observed(&family, &sorted, &found);
            let decoded = decode(&family, &read, Some(0)).unwrap();
            assert_eq!(decoded.id, truth.id, "{name} seed {seed}");
            assert_eq!(decoded.corrected_errors, 0);
            // A network that is sure of every cell gives every read slot full reliability, and
            // the soft decoder agrees with the hard one.
            let (soft_read, reliability) = read_slots(&family, &sorted, &found);
            assert_eq!(soft_read, read);
            for (r, rel) in read.iter().zip(&reliability) {
                assert_eq!(
                    *rel,
                    if r.is_some() { 1.0 } else { 0.0 },
                    "{name} seed {seed}"
                );
            }
            assert_eq!(
                decode_soft(&family, &read, &reliability, Some(0)),
                Some(decoded)
            );
            // Canonical keypoint i is seen at slot perm[i].
            let perm = &family.rotations()[decoded.rotation].keypoint_perm;
            for (i, k) in keypoints.iter().enumerate() {
                let f = &found[sorted.slots[perm[i]].expect("every keypoint is matched")];
                assert_eq!(f.category, k.category, "{name} seed {seed} keypoint {i}");
                assert!(
                    (f.pos[0] - k.x).abs() < 1e-4 && (f.pos[1] - k.y).abs() < 1e-4,
                    "{name} seed {seed} keypoint {i}: {:?} vs ({}, {})",
                    f.pos,
                    k.x,
                    k.y
                );
            }
            assert!(targets.positives() >= keypoints.len());
            assert!(targets.mask.contains(&1.0) && targets.mask.contains(&0.0));
        }
    }
}

#[test]
fn patch_sizes_keep_keypoints_two_anchors_apart() {
    for name in builtin::names() {
        let family = builtin::get(name).unwrap().unwrap();
        let spec = PatchSpec::for_family(&family);
        let expected = if family.is_grid() { 128 } else { 256 };
        assert_eq!(spec.size, expected, "{name}");
    }
}

/// The reliability the soft decoder erases by is the read category's share of the votes of the
/// categories its slot admits: an AprilTag-XO data cell voted 0.5 frame, 0.3 X, 0.2 O reads X
/// with 0.6 (the frame look is not a symbol's).
#[test]
fn reliability_is_the_share_among_admitted_categories() {
    use super::anchors::Found;
    use super::sort::Sorted;
    let family = builtin::get("apriltag-xo-36h11").unwrap().unwrap();
    let code_slot = family.code_keypoints()[0];
    let mut slots = vec![None; family.keypoints().len()];
    slots[code_slot] = Some(0);
    let sorted = Sorted {
        slots,
        to_patch: crate::geometry::Homography(nalgebra::Matrix3::identity()),
    };
    let (zero, one) = (family.symbol_category(0), family.symbol_category(1));
    let frame = (0..family.categories().len())
        .find(|&c| c != zero && c != one)
        .unwrap();
    let mut votes = vec![0.0; family.categories().len()];
    votes[frame] = 0.5;
    votes[zero] = 0.3;
    votes[one] = 0.2;
    let found = [Found {
        pos: [0.0, 0.0],
        category: frame,
        confidence: 0.5,
        votes,
    }];
    let (read, reliability) = read_slots(&family, &sorted, &found);
    assert_eq!(read[code_slot], Some(zero));
    assert!((reliability[code_slot] - 0.6).abs() < 1e-12);
    assert_eq!(read.iter().flatten().count(), 1);
    assert!(reliability
        .iter()
        .enumerate()
        .all(|(i, &r)| i == code_slot || r == 0.0));
}

/// A new design starts from a shipped model whose network fits it whole (the grid model for two
/// categories of any grid size, the XO model for a frame and two glyphs), else from the grid
/// model with a fresh class head (quaternary cells); a ring design from the ring model, whole or
/// with a class head of its own (RuneTag+'s orientation marks are a third category).
#[cfg(feature = "detect")]
#[test]
fn new_designs_fine_tune_from_the_shipped_model_that_fits_them() {
    let get = |name: &str| builtin::get(name).unwrap().unwrap();
    let start =
        |name: &str| super::fine_tune_start(&get(name)).map(|s| (s.asset, s.fresh_class_head));
    let grid = "models/grid-8-bw.stage2.bin";
    for name in ["apriltag-16h5", "aruco-5x5_100", "apriltag-36h11"] {
        assert_eq!(start(name), Some((grid, false)), "{name}");
    }
    for name in ["apriltag-xa-36h11", "topotag-like"] {
        assert_eq!(
            start(name),
            Some(("models/apriltag-xo-36h11.stage2.bin", false)),
            "{name}"
        );
    }
    assert_eq!(start("quaternary-6x6"), Some((grid, true)));
    let rings = "models/runetag.stage2.bin";
    assert_eq!(start("runetag"), Some((rings, false)));
    assert_eq!(start("runetag-plus"), Some((rings, true)));
}

/// The weights of a model fine-tuned for a design of other categories: the trunk is the model's,
/// the class head has the design's classes, and the header says so.
#[cfg(feature = "detect")]
#[test]
fn a_fine_tune_across_categories_keeps_the_trunk_and_sizes_the_class_head() {
    use burn::tensor::{Device, Tensor};
    let family = builtin::get("quaternary-6x6").unwrap().unwrap();
    let start = super::fine_tune_start(&family).unwrap();
    let device = Device::flex();
    let (net, header) =
        super::model_file::to_fine_tune(start.bytes(), start.asset, &family, &device).unwrap();
    assert_eq!(header.net.classes, family.categories().len() + 1);
    let patch = header.net.patch;
    let out = net.forward(Tensor::zeros([1, 1, patch, patch], &device));
    assert_eq!(out.logits.dims()[1], family.categories().len() + 1);
    // The rest of the network is the shipped one: the same mask for the same patch.
    let grid = builtin::get("apriltag-36h11").unwrap().unwrap();
    let (shipped, _) =
        super::model_file::from_bytes(start.bytes(), start.asset, &grid, &device).unwrap();
    let patch_in = || {
        Tensor::<4>::random(
            [1, 1, patch, patch],
            burn::tensor::Distribution::Default,
            &device,
        )
    };
    let x = patch_in();
    let a = net
        .forward(x.clone())
        .mask
        .into_data()
        .try_to_vec::<f32>()
        .unwrap();
    let b = shipped
        .forward(x)
        .mask
        .into_data()
        .try_to_vec::<f32>()
        .unwrap();
    let largest = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max);
    assert!(largest < 1e-4, "{largest}");
    // A patch of another size is refused, naming the field.
    let rings = builtin::get("runetag").unwrap().unwrap();
    let err = super::model_file::to_fine_tune(start.bytes(), start.asset, &rings, &device)
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("net.patch"), "{err}");
}

/// Every built-in with shipped weights reads with a model the build embeds (and the browser
/// fetches): a model missing from `assets::MODELS` would fail only where it is asked for.
#[cfg(feature = "detect")]
#[test]
fn every_shipped_model_is_a_listed_asset_for_its_family() {
    for name in super::shipped_families() {
        let family = builtin::get(name).unwrap().unwrap();
        let (asset, _) = super::shipped_model_for(&family).unwrap_or_else(|| panic!("{name}"));
        assert!(crate::assets::MODELS.contains(&asset), "{name}: {asset}");
    }
    for start in ["apriltag-36h11", "apriltag-xo-36h11", "quaternary-6x6"]
        .map(|name| super::fine_tune_start(&builtin::get(name).unwrap().unwrap()).unwrap())
    {
        assert!(
            crate::assets::MODELS.contains(&start.asset),
            "{}",
            start.asset
        );
    }
}

/// A RuneTag patch whose network found only the dots still reads its ID: the template places
/// the empty slots and nothing there reads as empty. A grid's light cells are not read so.
#[test]
fn ring_slots_with_nothing_found_read_as_empty() {
    use super::decode::read_patch;
    use super::sort::absent_category;
    assert_eq!(
        absent_category(&builtin::get("apriltag-36h11").unwrap().unwrap()),
        None
    );
    let family = builtin::get("runetag").unwrap().unwrap();
    let empty = absent_category(&family).expect("RuneTag's empty slot");
    let spec = PatchSpec::for_family(&family);
    let config = patches_of(&spec);
    for seed in 0..4u64 {
        let sample = synthesize(&family, &config, seed).unwrap();
        let truth = &sample.truth.markers[0];
        let dots: Vec<KeypointTruth> = (truth.keypoints.iter())
            .filter(|k| k.category != empty)
            .cloned()
            .collect();
        assert!(dots.len() < truth.keypoints.len());
        let targets = encode(&spec, &dots, &truth.roi, &truth.mask);
        let raw = RawOutputs::from_targets(&targets, family.categories().len() + 1);
        let reading = read_patch(&family, &spec, &raw).expect("the dots place the template");
        let decoded = reading.decoded.expect("decodes");
        assert_eq!(decoded.id, truth.id, "seed {seed}");
    }
}
