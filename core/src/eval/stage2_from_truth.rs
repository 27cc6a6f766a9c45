//! Stage 2 measured on its own: each true ROI of an image moved by stage-1-like noise, then read
//! by the stage-2 pipeline — a [`BenchDetector`] the harness's runner times like any other.

use crate::detect::refine::RefineReport;
use crate::detect::stage2::{ReadOptions, Stage2};
use crate::detect::{BenchDetector, Detection};
use crate::geometry::{Camera, Quad};
use crate::image::GrayImage;
use crate::pose::PoseJson;
use crate::synth::Truth;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub struct Stage2FromTruth {
    model: Stage2,
    /// Each ROI corner moves by up to this fraction of the marker side in x and y (uniform).
    roi_noise: f64,
    options: ReadOptions,
    camera: Camera,
    side_m: f64,
    rng: ChaCha8Rng,
    rois: Vec<Quad>,
    refinements: Vec<RefineReport>,
}

impl Stage2FromTruth {
    pub fn new(
        model: Stage2,
        roi_noise: f64,
        options: ReadOptions,
        camera: Camera,
        side_m: f64,
        seed: u64,
    ) -> Self {
        Self {
            model,
            roi_noise,
            options,
            camera,
            side_m,
            rng: ChaCha8Rng::seed_from_u64(seed),
            rois: Vec::new(),
            refinements: Vec::new(),
        }
    }

    /// What the refinement did on every marker read so far.
    pub fn refinements(&self) -> &[RefineReport] {
        &self.refinements
    }
}

impl BenchDetector for Stage2FromTruth {
    fn name(&self) -> String {
        format!(
            "tagsmith-stage2 ({} passes, refine {:?}, ROI noise ±{} side)",
            self.options.iterations, self.options.refine, self.roi_noise
        )
    }

    fn observe_truth(&mut self, truth: &Truth) {
        let rng = &mut self.rng;
        let noise = self.roi_noise;
        self.rois = truth
            .markers
            .iter()
            .map(|m| {
                let side = (m.roi[1][0] - m.roi[0][0]).hypot(m.roi[1][1] - m.roi[0][1]);
                let r = noise * side;
                Quad(std::array::from_fn(|j| {
                    [
                        m.roi[j][0] + rng.random_range(-r..=r),
                        m.roi[j][1] + rng.random_range(-r..=r),
                    ]
                }))
            })
            .collect();
    }

    fn detect(&mut self, image: &GrayImage) -> Vec<Detection> {
        let camera = Some((&self.camera, self.side_m));
        let found: Vec<_> = self
            .rois
            .iter()
            .filter_map(|roi| self.model.detect(image, roi, &self.options, camera))
            .collect();
        self.refinements
            .extend(found.iter().filter_map(|d| d.refinement.clone()));
        found
            .into_iter()
            .map(|d| Detection {
                // How many corrections each read needed is what tells two stage-2 models apart
                // on far steep markers, where both still read. The ROI is the truth's: score 1.
                scores: Some(d.scores(1.0, false)),
                ..Detection::plain(d.id, d.corners, d.pose.map(|p| PoseJson::from(&p.pose)))
            })
            .collect()
    }
}
