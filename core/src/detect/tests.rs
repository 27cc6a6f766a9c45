use super::anchors::{encode, extract, PatchSpec, RawOutputs};
use super::sort::{observed, sort_to_template};
use crate::builtin;
use crate::codebook::decode;
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
