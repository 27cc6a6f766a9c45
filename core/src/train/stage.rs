//! What a detector stage brings to the shared training loop ([`super::train`]): its network, its
//! samples, its loss, its validation and its model file. The loop owns everything else —
//! optimiser, learning-rate schedule, data workers, checkpoints, resume, events, report — so a
//! new stage implements this trait and gets all of it.

use crate::geometry::Quad;
use crate::image::GrayImage;
use burn::module::Module;
use burn::tensor::{Device, Tensor};
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::fmt::Debug;

pub trait TrainStage: Send + Sync + 'static {
    /// The network, on the autodiff device.
    type Net: Module;
    type Sample: Send + 'static;
    /// Validation figures (a plain struct of numbers: it is written to checkpoints and reports).
    type Metrics: Copy + Debug + PartialEq + Serialize + DeserializeOwned;
    /// The loss broken into its terms.
    type Terms: Copy + Debug + Default + PartialEq + Serialize + DeserializeOwned;
    /// What the report says about the network (its configuration, its input size).
    type Info: Clone + Debug + PartialEq + Serialize + DeserializeOwned;

    /// What the run trains for, as reports name it: a family's name, or what a family-free
    /// stage finds.
    fn subject(&self) -> String;
    /// A hash of what the network's outputs mean (a family's [`family_hash`]), for the report.
    ///
    /// [`family_hash`]: crate::detect::stage2::model_file::family_hash
    fn subject_hash(&self) -> String;
    fn info(&self) -> Self::Info;
    /// Multiply-accumulates per input.
    fn macs(&self) -> u64;
    /// Fresh weights (the device is seeded by the loop).
    fn init(&self, device: &Device) -> Self::Net;
    /// The sample of `seed`; runs on the data workers' threads.
    fn sample(&self, seed: u64) -> Result<Self::Sample, String>;
    fn loss(
        &self,
        net: &Self::Net,
        samples: &[Self::Sample],
        device: &Device,
    ) -> (Tensor<1>, Self::Terms);
    /// The total loss in `terms` (a run whose loss is not finite has diverged and stops).
    fn total(terms: &Self::Terms) -> f64;
    /// A fixed, seeded validation set of `size` samples: the same for every run of a family, so
    /// figures compare across runs.
    fn validation_set(&self, size: usize) -> Result<Vec<Self::Sample>, String>;
    /// The figures of the network in inference mode on the validation set.
    fn validate(&self, net: &Self::Net, set: &[Self::Sample]) -> Self::Metrics;
    /// The network in inference mode (batch norm on its running statistics).
    fn inference(&self, net: &Self::Net) -> Self::Net;
    /// The model file of the network after `step` steps.
    fn model_bytes(&self, net: Self::Net, step: u64) -> Result<Vec<u8>, String>;
    /// A model file written by [`TrainStage::model_bytes`], back on the autodiff device; `name`
    /// names it in errors.
    fn load_model(&self, bytes: &[u8], name: &str, device: &Device) -> Result<Self::Net, String>;
    /// The sample as the studio shows it: with its ground truth, or, given the network in
    /// inference mode, with what the network finds in it.
    fn picture(&self, sample: &Self::Sample, net: Option<&Self::Net>) -> Picture;
}

/// A sample drawn for a person: the network's input image and marks in its pixels (pixel
/// centres at whole coordinates).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Picture {
    #[serde(skip)]
    pub image: GrayImage,
    /// Keypoints and the category each carries.
    pub keypoints: Vec<([f64; 2], usize)>,
    /// Marker outlines (ROIs), corner 0 first.
    pub outlines: Vec<Quad>,
}
