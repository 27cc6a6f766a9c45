use super::data::make_sample;
use super::validate::score;
use super::*;
use crate::detect::stage1::Stage1;

/// Stage 1's ROI recall on scenes of designs it never saw in training against the same figure
/// on the training families' validation scenes (BENCHMARKS.md, "Training", stage 1):
/// `cargo test --release -p tagsmith --features learn --lib never_saw -- --ignored --nocapture`.
#[test]
#[ignore = "a benchmark: 400 scenes through the shipped stage 1 (about a minute)"]
fn stage1_finds_markers_of_designs_it_never_saw() {
    let stage1 = Stage1::shipped().unwrap();
    let options = ProposeOptions::default();
    let run = |families: &[Family], seed: u64| {
        let set: Vec<_> = (0..200)
            .map(|i| make_sample(families, seed + i).unwrap())
            .collect();
        let proposals: Vec<_> = set
            .iter()
            .map(|s| stage1.propose(&s.image, &options))
            .collect();
        score(&set, &proposals)
    };
    // Another seed than the training designs': other grid sizes, glyphs and codes.
    let unseen = random_designs(8, 0xC0FF_EE00);
    let trained = RoiStage::new(32).unwrap().families;
    let (a, b) = (run(&unseen, 1 << 40), run(&trained, 1 << 41));
    println!("unseen designs: {a:?}\ntraining families: {b:?}");
    assert!(
        a.recall >= 0.8 * b.recall,
        "unseen {:.3} vs trained {:.3}",
        a.recall,
        b.recall
    );
}

#[test]
fn a_small_markers_mask_weighs_more_than_a_large_ones() {
    use crate::detect::stage1::targets::{encode, MarkerQuad};
    let square = |x: f64, y: f64, side: f64| {
        let corners = [[x, y], [x + side, y], [x + side, y + side], [x, y + side]];
        MarkerQuad {
            corners: crate::geometry::Quad(corners),
            outline: corners.to_vec(),
        }
    };
    // 16 px: 16 cells at stride 4, weight sqrt(64 / 16) = 2; 96 px: 576 cells, weight 1.
    let quads = [square(8.0, 8.0, 16.0), square(120.0, 120.0, 96.0)];
    let targets = encode(256, 256, &quads);
    let weights = super::data::mask_weights(&targets, &quads);
    let at = |x: usize, y: usize| weights[(y / 4) * targets.columns + x / 4];
    assert_eq!(at(14, 14), 2.0, "inside the small marker");
    assert_eq!(at(160, 160), 1.0, "inside the large marker");
    assert_eq!(at(80, 80), 1.0, "background");
    // A sliver of 2 cells is held at the most weight.
    let sliver = [square(40.0, 40.0, 6.0)];
    let targets = encode(256, 256, &sliver);
    let weights = super::data::mask_weights(&targets, &sliver);
    assert_eq!(weights.iter().copied().fold(0.0f32, f32::max), 4.0);
}
