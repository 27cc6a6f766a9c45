//! Training patches, synthesised on the fly in worker threads ahead of the optimiser.
//!
//! Sample `i` of a run is a pure function of (run seed, i): the synthesiser's patch mode (the ROI
//! mapped to a random quad, a_i ~ U[0.05, 0.25], blur, noise, lighting) then a turn of the whole
//! patch by a random multiple of 90°, because stage 1's ROI starts at whichever corner it sees
//! first. Batches are handed out strictly in sample order whatever thread made them, so a run
//! resumed at step s sees exactly the batches an uninterrupted run would have seen: the data
//! stream's "random state" is the next sample index.

use crate::detect::stage2::anchors::{encode, PatchSpec, Targets};
use crate::detect::stage2::normalise_patch;
use crate::family::Family;
use crate::image::GrayImage;
use crate::synth::{image_seed, synthesize, KeypointTruth, MarkerTruth, Mode, SynthConfig};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// One training patch with its targets.
pub struct PatchSample {
    pub image: GrayImage,
    /// [`normalise_patch`] of the image: the network's input.
    pub input: Vec<f32>,
    pub targets: Targets,
    /// Ground truth in the patch as turned.
    pub truth: MarkerTruth,
}

/// Turns a point by 90° clockwise (y down) `quarter` times in a `size`² patch.
fn turn(p: [f64; 2], size: u32, quarter: u64) -> [f64; 2] {
    (0..quarter).fold(p, |[x, y], _| [size as f64 - 1.0 - y, x])
}

fn turn_image(image: &GrayImage, quarter: u64) -> GrayImage {
    let mut img = image.clone();
    for _ in 0..quarter {
        let n = img.width as usize;
        let mut out = GrayImage::new(img.width, img.height, 0);
        for y in 0..n {
            for x in 0..n {
                out.pixels[x * n + (n - 1 - y)] = img.pixels[y * n + x];
            }
        }
        img = out;
    }
    img
}

/// The patch of sample `seed`.
pub fn make_sample(family: &Family, spec: &PatchSpec, seed: u64) -> Result<PatchSample, String> {
    let mut config = SynthConfig::new(Mode::Patch);
    config.width = spec.size;
    config.height = spec.size;
    let sample = synthesize(family, &config, seed)?;
    // Only layouts that map onto themselves under a quarter turn (grids) can be seen turned by
    // one; ring markers' ROI fixes their orientation.
    let turns = family
        .rotations()
        .iter()
        .any(|r| (r.angle_deg - 90.0).abs() < 1e-9);
    let quarter = if turns {
        seed.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 62
    } else {
        0
    };
    let truth = sample
        .truth
        .markers
        .into_iter()
        .next()
        .ok_or("the synthesiser placed no marker in the patch")?;
    let at = |p: [f64; 2]| turn(p, spec.size, quarter);
    let truth = MarkerTruth {
        roi: truth.roi.iter().map(|&p| at(p)).collect(),
        mask: truth.mask.iter().map(|&p| at(p)).collect(),
        keypoints: truth
            .keypoints
            .iter()
            .map(|k| {
                let [x, y] = at([k.x, k.y]);
                KeypointTruth { x, y, ..k.clone() }
            })
            .collect(),
        ..truth
    };
    let regressed: Vec<KeypointTruth> = family
        .regressed_keypoints()
        .iter()
        .map(|&i| truth.keypoints[i].clone())
        .collect();
    let targets = encode(spec, &regressed, &truth.roi, &truth.mask);
    let image = turn_image(&sample.image, quarter);
    Ok(PatchSample {
        input: normalise_patch(&image),
        image,
        targets,
        truth,
    })
}

/// Worker threads synthesising samples `first, first + 1, …` of a run, delivered in order.
pub struct Loader {
    rx: Option<Receiver<(u64, Result<PatchSample, String>)>>,
    next: u64,
    pending: BTreeMap<u64, Result<PatchSample, String>>,
    stop: Arc<AtomicBool>,
    workers: Vec<JoinHandle<()>>,
    /// Time spent blocked waiting for samples.
    pub waited: Duration,
}

impl Loader {
    pub fn start(
        family: &Family,
        spec: PatchSpec,
        seed: u64,
        first: u64,
        threads: usize,
        ahead: usize,
    ) -> Self {
        let (tx, rx) = sync_channel(ahead.max(1));
        let counter = Arc::new(AtomicU64::new(first));
        let stop = Arc::new(AtomicBool::new(false));
        let workers = (0..threads.max(1))
            .map(|_| {
                let (tx, counter, stop, family) =
                    (tx.clone(), counter.clone(), stop.clone(), family.clone());
                std::thread::spawn(move || {
                    while !stop.load(Ordering::Relaxed) {
                        let i = counter.fetch_add(1, Ordering::Relaxed);
                        let sample = make_sample(&family, &spec, image_seed(seed, i));
                        if tx.send((i, sample)).is_err() {
                            break;
                        }
                    }
                })
            })
            .collect();
        Self {
            rx: Some(rx),
            next: first,
            pending: BTreeMap::new(),
            stop,
            workers,
            waited: Duration::ZERO,
        }
    }

    /// The next `n` samples in order.
    pub fn batch(&mut self, n: usize) -> Result<Vec<PatchSample>, String> {
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            if let Some(s) = self.pending.remove(&self.next) {
                out.push(s?);
                self.next += 1;
                continue;
            }
            let start = Instant::now();
            let (i, s) = self
                .rx
                .as_ref()
                .and_then(|rx| rx.recv().ok())
                .ok_or("the data workers stopped")?;
            self.waited += start.elapsed();
            self.pending.insert(i, s);
        }
        Ok(out)
    }
}

impl Drop for Loader {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Dropping the receiver fails the workers' pending sends, so they stop.
        self.rx = None;
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}
