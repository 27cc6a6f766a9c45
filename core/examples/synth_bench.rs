//! Synthesis throughput, in memory, on every core (as training uses it): stage-1 scenes and
//! stage-2 patches per second. `cargo run --release -p tagsmith --example synth_bench [FAMILY] [N]`

use rayon::prelude::*;
use std::time::Instant;
use tagsmith::geometry::{warp_bilinear, Homography};
use tagsmith::synth::{image_seed, synthesize, Mode, SynthConfig};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map_or("apriltag-36h11", |s| s.as_str());
    let n: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(400);
    let family = tagsmith::builtin::get(name)
        .expect("a built-in family")
        .expect("valid");
    for mode in [Mode::Quad, Mode::Patch] {
        let config = SynthConfig::new(mode);
        let mut rates = Vec::new();
        for round in 0..5u64 {
            let start = Instant::now();
            let markers: usize = (0..n)
                .into_par_iter()
                .map(|i| {
                    synthesize(&family, &config, image_seed(round, i))
                        .unwrap()
                        .truth
                        .markers
                        .len()
                })
                .sum();
            let secs = start.elapsed().as_secs_f64();
            assert!(markers > 0);
            rates.push(n as f64 / secs);
        }
        rates.sort_by(f64::total_cmp);
        println!(
            "{name} {:?} {}×{}: median {:.0} images/s (min {:.0}, max {:.0}) over 5 rounds of {n}, {} threads",
            mode, config.width, config.height, rates[2], rates[0], rates[4], rayon::current_num_threads()
        );
    }
    warp_timing(&family);
}

/// Stage-2 patch extraction: a perspective warp of a 1280×960 camera image into a square patch,
/// one thread, median of 9 rounds of 200 warps.
fn warp_timing(family: &tagsmith::Family) {
    let mut config = SynthConfig::new(Mode::Camera);
    config.markers = [1, 1];
    let sample = synthesize(family, &config, 1).unwrap();
    let roi = &sample.truth.markers[0].roi;
    for size in [128u32, 256] {
        let s = size as f64;
        let template = [
            [0.15 * s, 0.15 * s],
            [0.85 * s, 0.15 * s],
            [0.85 * s, 0.85 * s],
            [0.15 * s, 0.85 * s],
        ];
        let patch_to_image = Homography::from_points(&template, &roi[..4]).unwrap();
        let mut times = Vec::new();
        for _ in 0..9 {
            let start = Instant::now();
            for _ in 0..200 {
                std::hint::black_box(warp_bilinear(&sample.image, &patch_to_image, size, size, 0));
            }
            times.push(start.elapsed().as_secs_f64() / 200.0 * 1e6);
        }
        times.sort_by(f64::total_cmp);
        println!("warp 1280×960 → {size}×{size} patch: median {:.0} µs (min {:.0}, max {:.0}), one thread", times[4], times[0], times[8]);
    }
}
