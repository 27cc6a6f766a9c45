//! Property tests of the detector against hostile input: arbitrary images of any size through the
//! whole detector, arbitrary quads (subnormal, huge, degenerate, crossed) through the quad check
//! and stage 2, and mutated model bytes through both loaders. Each case must end in a value or a
//! clear error — no panic, no hang — within a time budget.
//!
//! Cases come from `arbtest`, seeded so that a failure is reproducible from the seed it prints.
#![cfg(feature = "detect")]

use std::time::{Duration, Instant};
use tagsmith::detect::stage1::Stage1;
use tagsmith::detect::stage2::{ReadOptions, Stage2};
use tagsmith::detect::Detector;
use tagsmith::image::GrayImage;

/// One case may take this long (test build, a loaded machine): a hang overshoots it by far.
const CASE_BUDGET: Duration = Duration::from_secs(10);

fn family() -> tagsmith::Family {
    tagsmith::builtin::get("apriltag-36h11").unwrap().unwrap()
}

/// A coordinate a hostile caller might give.
fn wild_coordinate(u: &mut arbitrary::Unstructured) -> arbitrary::Result<f64> {
    Ok(match u.int_in_range(0..=7)? {
        0 => 5e-324,
        1 => f64::NAN,
        2 => f64::INFINITY,
        3 => 1e300,
        4 => -u.int_in_range(0..=2000)? as f64,
        _ => u.int_in_range(0..=400)? as f64 + u.int_in_range(0..=99)? as f64 / 100.0,
    })
}

#[test]
fn images_of_any_size_and_content_detect_without_a_panic() {
    let detector = Detector::shipped(vec![family()]).unwrap();
    let mut cases = 0;
    arbtest::arbtest(|u| {
        let width = u.int_in_range(1..=300)?;
        let height = u.int_in_range(1..=300)?;
        let mut image = GrayImage::new(width, height, u.arbitrary()?);
        // Blocks of random gray, so that edges and corner-like spots occur.
        for _ in 0..u.int_in_range(0..=12)? {
            let (x0, y0) = (
                u.int_in_range(0..=width - 1)?,
                u.int_in_range(0..=height - 1)?,
            );
            let (w, h) = (
                u.int_in_range(1..=width - x0)?,
                u.int_in_range(1..=height - y0)?,
            );
            let value: u8 = u.arbitrary()?;
            for y in y0..y0 + h {
                for x in x0..x0 + w {
                    image.pixels[(y * width + x) as usize] = value;
                }
            }
        }
        let clock = Instant::now();
        let _ = detector.detect(&image);
        assert!(clock.elapsed() < CASE_BUDGET, "{width}×{height}");
        cases += 1;
        Ok(())
    })
    .budget(Duration::from_secs(8));
    assert!(cases > 0);
}

#[test]
fn hostile_quads_are_refused_or_read_never_hang() {
    let family = family();
    let stage2 = Stage2::from_bytes(
        tagsmith::detect::stage2::shipped_model("apriltag-36h11").unwrap(),
        "shipped",
        &family,
    )
    .unwrap();
    let image = GrayImage::new(320, 240, 128);
    let mut refused = 0;
    arbtest::arbtest(|u| {
        let mut quad = tagsmith::geometry::Quad::default();
        for p in quad.iter_mut() {
            *p = [wild_coordinate(u)?, wild_coordinate(u)?];
        }
        let clock = Instant::now();
        if quad.check().is_err() {
            refused += 1;
        } else {
            let _ = stage2.detect(&image, &quad, &ReadOptions::default(), None);
        }
        let homography = tagsmith::geometry::homography::Homography::from_points(
            &quad[..],
            &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        );
        let _ = homography;
        assert!(clock.elapsed() < CASE_BUDGET, "{quad:?}");
        Ok(())
    })
    .budget(Duration::from_secs(5));
    assert!(refused > 0);
}

#[test]
fn mutated_model_files_load_or_fail_with_an_error() {
    let family = family();
    let stage2_bytes = tagsmith::detect::stage2::shipped_model("apriltag-36h11").unwrap();
    let stage1_bytes = tagsmith::detect::stage1::pipeline::shipped_stage1();
    arbtest::arbtest(|u| {
        let stage1 = u.arbitrary::<bool>()?;
        let mut bytes = if stage1 { stage1_bytes } else { stage2_bytes }.to_vec();
        // Most changes land in the JSON header, where a field read wrong does harm.
        for _ in 0..u.int_in_range(1..=4)? {
            let reach = if u.arbitrary::<bool>()? {
                600
            } else {
                bytes.len()
            };
            let i = u.int_in_range(0..=reach.min(bytes.len()) - 1)?;
            match u.int_in_range(0..=2)? {
                0 => bytes[i] = u.arbitrary()?,
                1 => bytes[i] = b"0123456789-.e"[u.choose_index(13)?],
                _ => bytes.truncate(i),
            }
            if bytes.is_empty() {
                break;
            }
        }
        let clock = Instant::now();
        if stage1 {
            let _ = Stage1::from_bytes(&bytes, "mutated stage 1");
        } else {
            let _ = Stage2::from_bytes(&bytes, "mutated stage 2", &family);
        }
        assert!(clock.elapsed() < CASE_BUDGET);
        Ok(())
    })
    .budget(Duration::from_secs(5));
}
