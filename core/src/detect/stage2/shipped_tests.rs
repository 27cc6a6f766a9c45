//! The shipped weights on whole images: a marker rendered by a pinhole camera at a known pose,
//! with sensor noise and blur, found from a rough ROI.

use super::ReadOptions;
use super::Stage2;
use super::{shipped_model, shipped_model_for};
use crate::builtin;
use crate::detect::plain_net::largest_difference;
use crate::detect::refine::RefineMode;
use crate::geometry::Quad;
use crate::pose::Pose;
use crate::synth::{synthesize, Mode, SynthConfig};

#[test]
fn shipped_36h11_weights_decode_a_noisy_marker_and_its_pose() {
    decodes_noisy_markers("apriltag-36h11");
}

#[test]
fn shipped_xo_weights_decode_a_noisy_marker_and_its_pose() {
    decodes_noisy_markers("apriltag-xo-36h11");
}

#[test]
fn shipped_aruco_weights_decode_a_noisy_marker_and_its_pose() {
    decodes_noisy_markers("aruco-6x6_250");
}

/// The grid model never saw ARToolKitPlus's codes: it reads them by the layout it shares with
/// the two families it was trained on.
#[test]
fn the_grid_model_decodes_artoolkitplus_markers_it_was_not_trained_on() {
    decodes_noisy_markers("artoolkitplus-bch");
}

#[test]
fn the_grid_model_decodes_aruco_mip_markers_it_was_not_trained_on() {
    decodes_noisy_markers("aruco-mip-36h12");
}

#[test]
fn the_6x6_grid_model_decodes_noisy_16h5_and_4x4_markers_and_their_poses() {
    decodes_noisy_markers("apriltag-16h5");
    decodes_noisy_markers("aruco-4x4_50");
}

#[test]
fn the_7x7_grid_model_decodes_noisy_25h9_and_5x5_markers_and_their_poses() {
    decodes_noisy_markers("apriltag-25h9");
    decodes_noisy_markers("aruco-5x5_100");
}

#[test]
fn shipped_xa_weights_decode_a_noisy_marker_and_its_pose() {
    decodes_noisy_markers("apriltag-xa-36h11");
}

/// TopoTag-like's model, fine-tuned from the XO model: a 9 × 9 black square whose vertex cells
/// carry a disc or a ring.
#[test]
fn the_topotag_model_decodes_a_noisy_marker_and_its_pose() {
    decodes_noisy_markers("topotag-like");
}

/// tagStandard41h12's model, fine-tuned from the 8 × 8 grid model on a patch whose margin holds
/// the data cells outside the black frame, round the ROI inside it.
#[test]
fn the_standard41h12_model_decodes_a_noisy_marker_and_its_pose() {
    decodes_noisy_markers("apriltag-standard41h12");
}

/// tagCircle21h7's model, fine-tuned from 41h12's.
#[test]
fn the_circle21h7_model_decodes_a_noisy_marker_and_its_pose() {
    decodes_noisy_markers("apriltag-circle21h7");
}

/// Quaternary 6×6's model, fine-tuned from the grid model's trunk with a fresh class head: four
/// cell shapes and the orientation mark.
#[test]
fn the_quaternary_model_decodes_a_noisy_marker_and_its_pose() {
    decodes_noisy_markers("quaternary-6x6");
}

/// A user's family that is not built in, with a code table of its own on a layout a shipped
/// model was trained on (a 7 × 7 grid: 5 × 5 data cells), reads with that model and no training.
#[test]
fn a_users_grid_family_with_its_own_codes_reads_with_the_model_of_its_layout() {
    let mut spec = renamed("aruco-5x5_100", "my-5x5");
    spec.codebook.codes = spec.codebook.codes[50..].iter().rev().cloned().collect();
    let family = crate::Family::from_spec(spec).unwrap();
    let (asset, _) = shipped_model_for(&family).expect("the 7 × 7 grid model");
    assert_eq!(asset, "models/grid-7-bw.stage2.bin");
    assert!(shipped_model(family.name()).is_none());
    decodes_noisy_markers_of(&family);
    // On a dark background its white cells are not what the model learned.
    let mut dark = family.spec().clone();
    dark.background = "#303030".into();
    assert!(shipped_model_for(&crate::Family::from_spec(dark).unwrap()).is_none());
    // A layout no shipped model learned (a 9 × 9 grid with a 7 × 7 ROI) has none.
    let mut spec = renamed("apriltag-standard41h12", "my-41h12");
    spec.roi.points = vec![[1.0, 1.0], [8.0, 1.0], [8.0, 8.0], [1.0, 8.0]];
    let family = crate::Family::from_spec(spec).unwrap();
    assert!(shipped_model_for(&family).is_none());
}

/// A built-in's spec under a name no built-in has: what a user's copy of it is.
fn renamed(builtin: &str, name: &str) -> crate::family::FamilySpec {
    let mut spec = builtin::get(builtin).unwrap().unwrap().spec().clone();
    spec.name = name.into();
    spec
}

/// One 5 cm marker seen by a pinhole camera in the distance and view-angle ranges, with this
/// sensor noise and blur, and no spotlight, motion blur or lens distortion: the network's
/// reading alone decides what is read.
fn one_marker_scene(
    distance_m: [f64; 2],
    view_angle_deg: [f64; 2],
    noise_sigma: f32,
    blur_sigma: f32,
) -> SynthConfig {
    let mut config = SynthConfig::new(Mode::Camera);
    config.markers = [1, 1];
    config.side_m = [0.05, 0.05];
    config.distance_m = distance_m;
    config.view_angle_deg = view_angle_deg;
    config.augment.noise_sigma = [noise_sigma, noise_sigma];
    config.augment.blur_sigma = [blur_sigma, blur_sigma];
    config.augment.spotlight_probability = 0.0;
    config.augment.motion_blur_probability = 0.0;
    config.augment.marker_motion_blur_probability = 0.0;
    config.augment.barrel_probability = 0.0;
    config
}

fn decodes_noisy_markers(name: &str) {
    decodes_noisy_markers_of(&builtin::get(name).unwrap().unwrap());
}

fn decodes_noisy_markers_of(family: &crate::Family) {
    let family = family.clone();
    let (_, bytes) = shipped_model_for(&family).expect("the weights are shipped");
    let model = Stage2::from_bytes(bytes, "shipped", &family).unwrap();
    let mut config = one_marker_scene([0.25, 0.4], [0.0, 45.0], 4.0, 0.6);
    config.augment.marker_black = [20.0, 50.0];
    config.augment.marker_white = [190.0, 235.0];
    for seed in 0..4 {
        let sample = synthesize(&family, &config, seed).unwrap();
        let truth = &sample.truth.markers[0];
        let camera = sample.truth.camera.unwrap();
        let t = truth.pose.as_ref().unwrap();
        let expected = Pose::from(&t.pose);
        // A stage-1-like ROI: each corner off by up to 4 % of the side, starting at another
        // corner (the marker appears turned).
        let side = (truth.roi[1][0] - truth.roi[0][0]).hypot(truth.roi[1][1] - truth.roi[0][1]);
        let jitter = [[0.04, -0.03], [-0.02, 0.04], [0.03, 0.02], [-0.04, -0.01]];
        let start = seed as usize % 4;
        let roi = Quad(std::array::from_fn(|j| {
            let p = truth.roi[(j + start) % 4];
            [p[0] + jitter[j][0] * side, p[1] + jitter[j][1] * side]
        }));
        let mut errors = Vec::new();
        for refine in [RefineMode::None, RefineMode::Full] {
            let options = ReadOptions {
                refine,
                ..ReadOptions::default()
            };
            let found = model
                .detect(&sample.image, &roi, &options, Some((&camera, t.side_m)))
                .unwrap_or_else(|| panic!("seed {seed}: not decoded"));
            assert_eq!(found.id, truth.id, "seed {seed}");
            // Nearly all of them (60 of 36h11's 64).
            let all = family.keypoints().len();
            assert!(
                found.keypoints.len() * 16 >= all * 15,
                "seed {seed}: {} of {all} keypoints",
                found.keypoints.len()
            );
            let pose = found.pose.expect("a pose from all keypoints").pose;
            errors.push((
                pose.position_error(&expected) * 1000.0,
                pose.rotation_error_deg(&expected),
                found.refinement,
            ));
        }
        let (position_mm, rotation_deg, _) = errors[0];
        assert!(
            position_mm < 5.0 && rotation_deg < 2.0,
            "seed {seed}: stage 2 alone, position error {position_mm:.2} mm, rotation error \
             {rotation_deg:.2}°"
        );
        // Aligned with the rendering, a tenth of stage 2's bounds.
        let (position_mm, rotation_deg, ref refinement) = errors[1];
        assert!(
            position_mm < 0.5 && rotation_deg < 0.2,
            "seed {seed}: refined, position error {position_mm:.3} mm, rotation error \
             {rotation_deg:.3}°, {refinement:?}"
        );
    }
}

/// Folding the batch norms and running the folded network as plain loops (what every
/// detection runs) must not change what the shipped network computes; a folded network written to a model file is refused on loading, not read as
/// a different function.
#[test]
fn folded_batch_norms_compute_what_the_shipped_network_does() {
    use super::model_file;
    use burn::tensor::{Device, Tensor, TensorData};
    let family = builtin::get("aruco-6x6_250").unwrap().unwrap();
    let bytes = shipped_model(family.name()).unwrap();
    let device = Device::flex();
    let (net, header) = model_file::from_bytes(bytes, "shipped", &family, &device).unwrap();
    let p = header.net.patch;
    // A patch with structure at every scale: cells, edges and a gradient.
    let pixels: Vec<f32> = (0..p * p)
        .map(|i| {
            let (x, y) = (i % p, i / p);
            let cell = ((x / 16 + y / 16) % 2) as f32 * 1.6 - 0.8;
            cell + (x as f32 / p as f32 - 0.5) * 0.4 + ((x * 7 + y * 13) % 5) as f32 * 0.05
        })
        .collect();
    let input = || Tensor::<4>::from_data(TensorData::new(pixels.clone(), [1, 1, p, p]), &device);
    let flat = |t: Tensor<4>| t.into_data().try_to_vec::<f32>().unwrap();
    let outputs = |net: &super::net::Stage2Net| {
        let o = net.forward(input());
        [
            flat(o.logits),
            flat(o.offsets),
            flat(o.mask),
            flat(o.template),
        ]
    };
    let before = outputs(&net);
    // The plain form (what detection runs) against burn's outputs as the pipeline reads them.
    let want = super::pipeline::raw_outputs(net.forward(input()), header.net.classes).remove(0);
    let got = net.plain().outputs(&pixels, p);
    assert_eq!(got.classes, want.classes);
    let worst = largest_difference;
    let flat2 = |v: &[[f32; 2]]| v.iter().flatten().copied().collect::<Vec<f32>>();
    assert!(
        worst(&got.probs, &want.probs) <= 1e-4,
        "class probabilities"
    );
    assert!(
        worst(&flat2(&got.offsets), &flat2(&want.offsets)) <= 1e-4,
        "offsets"
    );
    assert!(
        worst(&flat2(&got.template), &flat2(&want.template)) <= 1e-4,
        "template"
    );
    let folded = net.fold_batch_norms();
    for (a, b) in before.iter().zip(outputs(&folded)) {
        let largest = a.iter().fold(1.0f32, |m, v| m.max(v.abs()));
        let worst = largest_difference(a, &b);
        assert!(worst <= 1e-4 * largest, "outputs differ by {worst}");
    }
    let saved = model_file::to_bytes(folded, &header.net, &family, 1).unwrap();
    let refused = model_file::from_bytes(&saved, "folded", &family, &device);
    assert!(
        refused.is_err(),
        "a folded network loaded as an unfolded one"
    );
}

/// A steep marker's ROI off at its corners by a tenth of its longest side (stage 1's quads on
/// far steep views): where the first pass decodes nothing, the pass from the keypoints it found
/// reads most of the rest, none as another ID.
#[test]
fn a_roi_off_at_a_steep_markers_corners_reads_from_the_keypoints_found() {
    let family = builtin::get("apriltag-36h11").unwrap().unwrap();
    let model =
        Stage2::from_bytes(shipped_model(family.name()).unwrap(), "shipped", &family).unwrap();
    let config = one_marker_scene([0.4, 0.6], [60.0, 70.0], 3.0, 0.5);
    // One pass: the first alone, so no read from its keypoints either.
    let single = ReadOptions {
        iterations: 1,
        refine: RefineMode::Full,
        ..ReadOptions::default()
    };
    let twice = ReadOptions {
        iterations: 2,
        ..single
    };
    let (mut first_only, mut with_retry) = (0, 0);
    let seeds = 48;
    for seed in 0..seeds {
        let sample = synthesize(&family, &config, 1000 + seed).unwrap();
        let truth = &sample.truth.markers[0];
        let roi = pushed_roi(&truth.roi, seed);
        let read = |options: &ReadOptions| {
            let found = model.detect(&sample.image, &roi, options, None)?;
            assert_eq!(found.id, truth.id, "seed {seed}: another ID");
            Some(found)
        };
        let first = read(&single);
        if let Some(found) = read(&twice) {
            // Said so where the first pass decoded nothing, and then confirmed by the
            // alignment with the rendering.
            assert_eq!(found.from_keypoints, first.is_none(), "seed {seed}");
            if found.from_keypoints {
                assert!(found.refinement.is_some_and(|r| r.refined), "seed {seed}");
            }
            with_retry += 1;
        }
        first_only += usize::from(first.is_some());
    }
    // Measured: 31 of 48 by the first pass, 41 with the reads from its keypoints (38 with one).
    assert!(
        with_retry >= first_only + 5,
        "first pass {first_only}, with the pass from its keypoints {with_retry} of {seeds}"
    );
}

/// A ROI off at each corner by a tenth of the marker's longest side, each its own way (`seed`
/// turns the directions).
fn pushed_roi(r: &[[f64; 2]], seed: u64) -> Quad {
    let side = (0..4)
        .map(|j| (r[(j + 1) % 4][0] - r[j][0]).hypot(r[(j + 1) % 4][1] - r[j][1]))
        .fold(0.0, f64::max);
    let push = side / 10.0;
    let angle = |j: usize| (seed as f64 * 1.7 + j as f64 * 2.3) % std::f64::consts::TAU;
    Quad(std::array::from_fn(|j| {
        [
            r[j][0] + push * angle(j).cos(),
            r[j][1] + push * angle(j).sin(),
        ]
    }))
}

/// The reads from the keypoints are bounded per batch: a cluttered scene sends dozens of ROIs
/// that decode nothing, and each would cost up to three more passes. The first ones of a batch
/// (stage 1's best) are still read again; past them, a ROI gets its first pass only.
#[test]
fn a_batch_reads_only_its_first_rois_again_from_their_keypoints() {
    use super::pipeline::MAX_RETRIED_ROIS;
    let family = builtin::get("apriltag-36h11").unwrap().unwrap();
    let model =
        Stage2::from_bytes(shipped_model(family.name()).unwrap(), "shipped", &family).unwrap();
    let config = one_marker_scene([0.4, 0.6], [60.0, 70.0], 3.0, 0.5);
    let options = ReadOptions {
        iterations: 2,
        refine: RefineMode::Full,
        ..ReadOptions::default()
    };
    // A ROI that only a read from its keypoints decodes (the test above: about ten in 48).
    let (sample, roi) = (0..48)
        .find_map(|seed| {
            let sample = synthesize(&family, &config, 1000 + seed).unwrap();
            let roi = pushed_roi(&sample.truth.markers[0].roi, seed);
            let alone = model
                .first_passes(&sample.image, &[roi], &options)
                .pop()??;
            alone.from_keypoints.then_some((sample, roi))
        })
        .expect("no ROI of 48 read only from its keypoints");
    let id = sample.truth.markers[0].id;
    let batch = vec![roi; MAX_RETRIED_ROIS + 2];
    let reads = model.first_passes(&sample.image, &batch, &options);
    for (k, read) in reads.iter().enumerate() {
        if k < MAX_RETRIED_ROIS {
            let read = read
                .as_ref()
                .unwrap_or_else(|| panic!("ROI {k} not read again"));
            assert!(read.from_keypoints && read.id == id, "ROI {k}");
        } else {
            assert!(
                read.is_none(),
                "ROI {k} of the batch read again from its keypoints"
            );
        }
    }
}
