use super::model_file::{from_bytes, to_bytes};
use super::net::NetConfig;
use super::*;
use crate::detect::model_file::ModelError;
use burn::module::Module;

/// A dark square on a light page: the quad around it, rectified, puts the square in the middle
/// and the page in the margin.
#[test]
fn the_rectified_patch_frames_the_quad_with_its_margin() {
    let mut image = GrayImage::new(200, 150, 230);
    for y in 40..100 {
        for x in 70..130 {
            image.pixels[y * 200 + x] = 20;
        }
    }
    let quad = Quad([[70.0, 40.0], [130.0, 40.0], [130.0, 100.0], [70.0, 100.0]]);
    let side = 32;
    let patch = rectified(&image, &quad, side).unwrap();
    let at = |u: usize, v: usize| patch.pixels[v * side + u];
    assert!(at(16, 16) < 40, "centre {}", at(16, 16));
    let inside = (MARGIN * side as f64).ceil() as usize + 1;
    assert!(at(inside, inside) < 40 && at(side - 1 - inside, side - 1 - inside) < 40);
    let outside = (MARGIN * side as f64).floor() as usize - 2;
    assert!(at(outside, 16) > 200 && at(16, side - 1 - outside) > 200);
    assert!(rectified(&image, &Quad([[0.0, 0.0]; 4]), side).is_none());
}

#[test]
fn a_model_file_round_trips_and_names_a_bad_patch_side() {
    let device = burn::tensor::Device::flex();
    let config = NetConfig {
        width: 16,
        patch: 32,
    };
    let bytes = to_bytes(config.init(&device), &config, &["x".into()], 7).unwrap();
    let (_, header) = from_bytes(&bytes, "v.bin", &device).unwrap();
    assert_eq!((header.net, header.steps), (config, 7));
    let field = b"\"patch\":32";
    let at = (bytes.windows(field.len()))
        .position(|w| w == field)
        .expect("the header names the patch side");
    let mut bad = bytes.clone();
    bad[at + field.len() - 1] = b'0';
    match from_bytes(&bad, "v.bin", &device) {
        Err(ModelError::BadField { field, path, .. }) => {
            assert_eq!((field, path.as_str()), ("net.patch", "v.bin"))
        }
        other => panic!("expected a bad net.patch, got {:?}", other.map(|_| ())),
    }
}

/// Scores come one per quad, in order, as probabilities; a quad no homography maps scores 0.
#[test]
fn scores_are_one_probability_per_quad() {
    let device = burn::tensor::Device::flex();
    let config = NetConfig {
        width: 16,
        patch: 32,
    };
    let verifier = Verifier::of_network(&config.init(&device).valid(), config);
    let image = GrayImage::new(64, 64, 100);
    let good = Quad([[10.0, 10.0], [50.0, 12.0], [48.0, 50.0], [12.0, 48.0]]);
    let scores = verifier.scores(&image, &[good, Quad([[5.0, 5.0]; 4]), good]);
    assert_eq!(scores.len(), 3);
    assert!(scores[0] > 0.0 && scores[0] < 1.0);
    assert_eq!(scores[1], 0.0);
    assert_eq!(scores[0], scores[2]);
}

mod shipped {
    use super::*;
    use crate::detect::stage2::shipped_families;
    use crate::family::designs::random_square;
    use crate::family::Family;
    use crate::synth::{synthesize, BackgroundKind, Mode, SynthConfig};
    use rand::{Rng, SeedableRng};

    fn shipped() -> Verifier {
        Verifier::shipped()
            .expect("this build ships a verifier")
            .expect("the shipped verifier loads")
    }

    /// One marker of `family` on a plain page, lightly blurred and noisy as a camera sees it,
    /// and its true outline.
    fn marker_on_a_page(family: &Family, seed: u64) -> (GrayImage, Quad) {
        let mut config = SynthConfig::new(Mode::Quad);
        (config.width, config.height) = (192, 160);
        config.markers = [1, 1];
        config.quad_side = [0.35, 0.5];
        config.background = BackgroundKind::Plain;
        let sample = synthesize(family, &config, seed).unwrap();
        let roi = Quad::try_from(&sample.truth.markers[0].roi[..]).unwrap();
        (sample.image, roi)
    }

    fn min_score() -> f32 {
        VerifierParams::default().min_score
    }

    /// A square marker of any family passes, built-in or designed at random: the verifier
    /// belongs to no family.
    #[test]
    fn a_marker_of_every_shipped_family_and_of_a_random_design_passes() {
        let verifier = shipped();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let random: Vec<Family> = (0..40)
            .filter_map(|i| {
                Family::from_spec(random_square(i, &mut |k| rng.random_range(0..k))).ok()
            })
            .take(3)
            .collect();
        assert_eq!(random.len(), 3);
        // A ROI inside a dark frame (41h12's, circle21h7's) outlines no marker, and the verifier
        // does not judge those families' quads.
        let builtin = shipped_families()
            .map(|name| crate::builtin::get(name).unwrap().unwrap())
            .filter(|family| crate::detect::outline::Outline::new(family).is_none());
        for family in builtin.chain(random) {
            for seed in [1, 2] {
                let (image, roi) = marker_on_a_page(&family, seed);
                let score = verifier.scores(&image, &[roi])[0];
                assert!(
                    score >= min_score(),
                    "{} (seed {seed}): scored {score}",
                    family.name()
                );
            }
        }
    }

    /// A checkerboard's outline, and a quad across a marker's inside, frame no marker.
    #[test]
    fn a_checkerboard_and_a_marker_s_inside_are_turned_away() {
        let verifier = shipped();
        let mut page = GrayImage::new(200, 200, 210);
        let (x0, y0, cell) = (40usize, 50usize, 18usize);
        for y in 0..6 * cell {
            for x in 0..6 * cell {
                if (x / cell + y / cell) % 2 == 0 {
                    page.pixels[(y0 + y) * 200 + x0 + x] = 25;
                }
            }
        }
        let (a, b) = (
            (x0 as f64, y0 as f64),
            ((x0 + 6 * cell) as f64, (y0 + 6 * cell) as f64),
        );
        let board = Quad([[a.0, a.1], [b.0, a.1], [b.0, b.1], [a.0, b.1]]);
        let score = verifier.scores(&page, &[board])[0];
        assert!(score < min_score(), "the checkerboard scored {score}");

        let family = crate::builtin::get("apriltag-36h11").unwrap().unwrap();
        let (image, roi) = marker_on_a_page(&family, 3);
        let inside = roi.scaled(0.35);
        let score = verifier.scores(&image, &[inside])[0];
        assert!(
            score < min_score(),
            "a quad inside the marker scored {score}"
        );
    }
}
