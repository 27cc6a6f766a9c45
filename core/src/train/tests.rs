use super::stage2::data::make_sample;
use super::stage2::loss::{losses, Batch};
use super::{train_keypoints as train, Event, TrainConfig};
use crate::builtin;
use crate::detect::stage2::anchors::PatchSpec;
use crate::detect::stage2::net::NetConfig;
use crate::detect::stage2::Stage2;
use crate::synth::image_seed;
use burn::optim::{AdamConfig, GradientsParams};
use burn::tensor::Device;
use std::sync::atomic::{AtomicBool, Ordering};

/// A small network learns a handful of fixed patches: the loss falls tenfold within seconds, so
/// the targets, losses and gradients fit together.
#[test]
fn a_tiny_model_overfits_a_few_patches() {
    let family = builtin::get("apriltag-36h11").unwrap().unwrap();
    let spec = PatchSpec::for_family(&family);
    let samples: Vec<_> = (0..2)
        .map(|i| make_sample(&family, &spec, image_seed(7, i), 0.0).unwrap())
        .collect();
    let device = Device::flex().autodiff();
    device.seed(3);
    let config = NetConfig {
        classes: 3,
        width: 8,
        patch: spec.size as usize,
    };
    let mut net = config.init(&device);
    let mut optim = AdamConfig::new().init();
    let batch = Batch::new(&samples, config.classes, spec.size as usize, &device);
    let mut first = None;
    let mut last = f32::MAX;
    let mut steps = 0;
    // Stops as soon as the loss is a tenth of the first: the test takes seconds. The seed is
    // the backend's, which the other tests' networks draw from at the same time, so the
    // weights it starts from vary from run to run: the cap leaves room for a slow start.
    while steps < 1500 && first.is_none_or(|f: f32| last >= f / 10.0) {
        let (loss, terms) = losses(net.forward(batch.input.clone()), &batch);
        first.get_or_insert(terms.total);
        last = terms.total;
        let grads = GradientsParams::from_grads(loss.backward(), &net);
        net = optim.step(5e-3, net, grads);
        steps += 1;
    }
    let first = first.unwrap();
    assert!(
        last < first / 10.0,
        "loss {first} → {last} in {steps} steps"
    );
}

fn tiny(steps: u64) -> TrainConfig {
    TrainConfig {
        steps,
        batch: 2,
        width: 8,
        checkpoint_every: 2,
        validate_every: 2,
        validation_patches: 2,
        ..TrainConfig::default()
    }
}

/// A run stopped after a checkpoint and resumed ends with the same weights as a run that was
/// never interrupted, and its model file loads for its family only.
#[test]
fn training_resumes_from_its_checkpoint() {
    // On one thread of its own: rayon splits a reduction further when other tests keep the
    // shared pool busy, so the first run of a busy test process summed in another order and
    // differed from the others by 0.1 (two uninterrupted runs as much as a resumed one).
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(resumed_training_matches_uninterrupted_training);
}

fn resumed_training_matches_uninterrupted_training() {
    let family = builtin::get("apriltag-16h5").unwrap().unwrap();
    let straight = tempfile::tempdir().unwrap();
    let never = AtomicBool::new(false);
    let report = train(
        &family,
        &tiny(4),
        straight.path(),
        false,
        &never,
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(report.steps, 4);
    assert_eq!(report.validation.len(), 2);

    let interrupted = tempfile::tempdir().unwrap();
    let stop = AtomicBool::new(false);
    let mut events = Vec::new();
    train(
        &family,
        &tiny(4),
        interrupted.path(),
        false,
        &stop,
        &mut |e| {
            if matches!(e, Event::Checkpointed { step: 2 }) {
                stop.store(true, Ordering::Relaxed);
            }
            events.push(e);
        },
    )
    .unwrap();
    assert!(events
        .iter()
        .any(|e| matches!(e, Event::Checkpointed { step: 2 })));
    assert!(!events
        .iter()
        .any(|e| matches!(e, Event::Step { step: 3, .. })));
    let resumed = train(
        &family,
        &tiny(4),
        interrupted.path(),
        true,
        &never,
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(resumed.resumed_from, Some(2));
    assert_eq!(resumed.steps, 4);

    let a = std::fs::read(straight.path().join("model.bin")).unwrap();
    let b = std::fs::read(interrupted.path().join("model.bin")).unwrap();
    let again = tempfile::tempdir().unwrap();
    train(&family, &tiny(4), again.path(), false, &never, &mut |_| {}).unwrap();
    let c = std::fs::read(again.path().join("model.bin")).unwrap();
    // Threaded reductions make runs equal to rounding, not bit for bit: compare outputs.
    let spec = PatchSpec::for_family(&family);
    let patch = make_sample(&family, &spec, 99, 0.0).unwrap().image;
    let outputs = |bytes: &[u8]| {
        Stage2::from_bytes(bytes, "model.bin", &family)
            .unwrap()
            .run_patches(std::slice::from_ref(&patch))
            .pop()
            .unwrap()
    };
    let (oa, ob, oc) = (outputs(&a), outputs(&b), outputs(&c));
    let diff = |x: &crate::detect::stage2::anchors::RawOutputs,
                y: &crate::detect::stage2::anchors::RawOutputs| {
        x.offsets
            .iter()
            .flatten()
            .zip(y.offsets.iter().flatten())
            .map(|(p, q)| (p - q).abs())
            .fold(0.0f32, f32::max)
    };
    eprintln!(
        "straight vs straight {}, straight vs resumed {}",
        diff(&oa, &oc),
        diff(&oa, &ob)
    );
    assert!(
        diff(&oa, &ob) < 1e-3,
        "resumed weights differ from uninterrupted ones"
    );
    Stage2::from_bytes(&a, "model.bin", &family).unwrap();
    let other = builtin::get("apriltag-36h11").unwrap().unwrap();
    let err = Stage2::from_bytes(&a, "model.bin", &other)
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("trained for family \"apriltag-16h5\""),
        "{err}"
    );
    let mut damaged = a.clone();
    let last = damaged.len() - 10;
    damaged[last] ^= 0x40;
    let err = Stage2::from_bytes(&damaged, "model.bin", &family)
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("corrupt"), "{err}");
    let err = Stage2::from_bytes(b"PNG", "x.bin", &family)
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("not a Tagsmith stage-2 model"), "{err}");
}

/// A validation that finds nothing has NaN keypoint errors (no keypoint to measure); the
/// checkpoint written after it must still resume, and the report must keep the NaN.
#[test]
fn a_run_whose_validation_found_nothing_resumes() {
    use super::checkpoint;
    use super::stage2::validate::Metrics;
    let family = builtin::get("apriltag-16h5").unwrap().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let never = AtomicBool::new(false);
    train(&family, &tiny(2), dir.path(), false, &never, &mut |_| {}).unwrap();
    // The state as a validation that found nothing leaves it (what `validate::score` returns
    // then), written the way the loop writes it.
    let path = dir.path().join("checkpoint.bin");
    let mut state = checkpoint::load::<Metrics>(&path).unwrap();
    state.meta.validation[0].1 = Metrics {
        patches: 2,
        keypoint_rms_px: f64::NAN,
        keypoint_median_px: f64::NAN,
        ..Metrics::default()
    };
    checkpoint::save(&path, &state.model, &state.optimiser, &state.meta).unwrap();
    let resumed = train(&family, &tiny(4), dir.path(), true, &never, &mut |_| {}).unwrap();
    assert_eq!(resumed.resumed_from, Some(2));
    assert!(resumed.validation[0].1.keypoint_rms_px.is_nan());
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("report.json")).unwrap()).unwrap();
    assert_eq!(report["validation"][0][1]["keypoint_rms_px"], "NaN");
}

/// Trailing bytes or an edited step are caught by the checksum, named by the file.
#[test]
fn a_damaged_or_edited_checkpoint_is_refused() {
    let family = builtin::get("apriltag-16h5").unwrap().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let never = AtomicBool::new(false);
    train(&family, &tiny(2), dir.path(), false, &never, &mut |_| {}).unwrap();
    let path = dir.path().join("checkpoint.bin");
    let good = std::fs::read(&path).unwrap();
    let text = String::from_utf8_lossy(&good);
    let at = text
        .find("\"step\":2")
        .expect("the step is in the JSON state");
    let mut edited = good.clone();
    edited[at + 7] = b'1';
    let mut trailing = good.clone();
    trailing.extend_from_slice(b"garbage");
    for bytes in [edited, trailing, good[..good.len() / 2].to_vec()] {
        std::fs::write(&path, &bytes).unwrap();
        let err = train(&family, &tiny(4), dir.path(), true, &never, &mut |_| {})
            .unwrap_err()
            .to_string();
        assert!(err.contains("checkpoint.bin"), "{err}");
        assert!(err.contains("damaged"), "{err}");
    }
}

/// A folder that cannot be written is reported before the first step.
#[cfg(unix)]
#[test]
fn an_unwritable_output_folder_fails_before_training() {
    let family = builtin::get("apriltag-16h5").unwrap().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let blocked = dir.path().join("file-not-folder");
    std::fs::write(&blocked, b"x").unwrap();
    let never = AtomicBool::new(false);
    let mut steps = 0;
    let err = train(
        &family,
        &tiny(2),
        &blocked.join("run"),
        false,
        &never,
        &mut |e| {
            if matches!(e, Event::Step { .. }) {
                steps += 1;
            }
        },
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("file-not-folder"), "{err}");
    assert_eq!(steps, 0);
}

/// A second run into a folder another run holds stops before anything, naming the folder and its
/// lock file; once the first lets go, the folder is free again (as after a killed run: the
/// system drops a dead process's locks).
#[test]
fn a_folder_in_use_by_another_run_is_refused_at_once() {
    use super::{OutDir, TrainError, LOCK_FILE};
    let family = builtin::get("apriltag-16h5").unwrap().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let held = OutDir(dir.path().to_path_buf()).lock().unwrap();
    let never = AtomicBool::new(false);
    let mut events = 0;
    let err = train(&family, &tiny(2), dir.path(), false, &never, &mut |_| {
        events += 1
    })
    .unwrap_err();
    assert!(matches!(err, TrainError::InUse(_)), "{err}");
    let text = err.to_string();
    assert!(
        text.starts_with(&format!(
            "{} is in use by another training run",
            dir.path().display()
        )) && text.contains(LOCK_FILE),
        "{text}"
    );
    assert_eq!(events, 0);
    assert!(!dir.path().join("checkpoint.bin").exists());
    drop(held);
    drop(OutDir(dir.path().to_path_buf()).lock().unwrap());
}

/// `--out` naming a file is the request's mistake, named as such, whether the file is the folder
/// itself or lies above it.
#[test]
fn an_output_folder_that_is_a_file_is_refused() {
    use super::TrainError;
    let family = builtin::get("apriltag-16h5").unwrap().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("notes.txt");
    std::fs::write(&file, b"x").unwrap();
    let never = AtomicBool::new(false);
    for out in [file.clone(), file.join("run")] {
        let err = train(&family, &tiny(2), &out, false, &never, &mut |_| {}).unwrap_err();
        assert!(matches!(err, TrainError::NotAFolder(_)), "{err}");
        assert!(err.to_string().contains("notes.txt"), "{err}");
    }
    assert_eq!(std::fs::read(&file).unwrap(), b"x");
}

/// A checkpoint that is a FIFO (or a folder) is refused when resuming, never waited on.
#[cfg(unix)]
#[test]
fn a_checkpoint_that_is_not_a_regular_file_is_refused_without_waiting() {
    use super::TrainError;
    let family = builtin::get("apriltag-16h5").unwrap().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let checkpoint = dir.path().join("checkpoint.bin");
    let made = std::process::Command::new("mkfifo")
        .arg(&checkpoint)
        .status();
    if !made.is_ok_and(|s| s.success()) {
        std::fs::create_dir(&checkpoint).unwrap();
    }
    let never = AtomicBool::new(false);
    let err = train(&family, &tiny(2), dir.path(), true, &never, &mut |_| {}).unwrap_err();
    assert!(matches!(err, TrainError::Checkpoint(_)), "{err}");
    assert!(err.to_string().contains("checkpoint.bin"), "{err}");
}
