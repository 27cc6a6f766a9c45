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
#[test]
fn targets_decode_to_the_ground_truth() {
    for name in [
        "apriltag-36h11",
        "apriltag-xo-36h11",
        "topotag-like",
        "runetag",
    ] {
        let family = builtin::get(name).unwrap().unwrap();
        let spec = PatchSpec::for_family(&family);
        let mut config = SynthConfig::new(Mode::Patch);
        config.width = spec.size;
        config.height = spec.size;
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

/// A new design of two categories starts from the shipped grid model wherever its network fits
/// (any grid size); more categories (XO's frame and two glyphs, quaternary cells) need a network
/// of their own.
#[cfg(feature = "detect")]
#[test]
fn two_category_designs_fine_tune_from_the_grid_model_and_others_do_not() {
    let get = |name: &str| builtin::get(name).unwrap().unwrap();
    for name in ["apriltag-16h5", "aruco-5x5_100", "apriltag-36h11"] {
        assert!(super::fine_tune_start(&get(name)).is_some(), "{name}");
    }
    for name in ["apriltag-xo-36h11", "quaternary-6x6"] {
        assert!(super::fine_tune_start(&get(name)).is_none(), "{name}");
    }
}
