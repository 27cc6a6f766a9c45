use super::data::make_sample;
use super::validate::score;
use super::*;
use crate::detect::stage1::Stage1;

/// Stage 1's ROI recall on scenes of designs it never saw in training against the same figure
/// on the training families' validation scenes (BENCHMARKS.md, "Stage 1 on unseen designs"):
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
