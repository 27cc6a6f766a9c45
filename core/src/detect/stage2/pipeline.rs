//! The stage-2 pipeline on an image: warp the ROI to a patch, run the network, extract and sort
//! the keypoints, decode the ID, map the keypoints back to the image, solve the pose; then once
//! more from the ROI the first pass's keypoints give (docs/ARCHITECTURE.md §9.6: the paper's result
//! is stable after two iterations).

use super::anchors::{PatchSpec, RawOutputs};
use super::decode::{read_patch, PatchReading};
use super::model_file::{self, ModelError, ModelHeader};
use super::net::{NetConfig, Outputs, PlainStage2, Stage2Net};
use super::normalise_patch;
use crate::detect::refine::{refine_marker, Lens, RefineMode, RefineReport, TemplateCache};
use crate::detect::{DetectedKeypoint, Scores};
use crate::family::{Assignment, Decoded, Family};
use crate::geometry::{warp_bilinear, Camera, Homography, Quad};
use crate::image::GrayImage;
use crate::pose::{covariance, marker_plane_points, solve_planar, PnpSolution, PointNoise};
use burn::tensor::activation::softmax;
use burn::tensor::{Device, Tensor};
use serde::Serialize;
use std::path::Path;

/// A ROI that does not decode is read once more from where its keypoints place the marker when
/// that moves a corner at least this far (less changes the patch by under a pixel).
const MIN_RETRY_MOVE_PX: f64 = 1.0;

/// Reads from the last one's keypoints at most, while none decodes and each moves the ROI: a
/// ROI further off closes in over several (stage 2 alone on jittered steep dev ROIs: 1 round
/// 123 of 160, 3 rounds 127; dev noise sweeps 357 → 360 of 390).
const RETRY_ROUNDS: usize = 3;

/// The ROIs of one batch read again from their keypoints at most, the first ones (stage 1's best
/// first): each costs up to [`RETRY_ROUNDS`] more passes, and a cluttered scene sends dozens of
/// ROIs that decode nothing, nearly all of whose keypoints still fit half the template (scenes
/// OpenCV drew, `bench/foreign.py`: 31 per image, 25 decodes from 4 353 more passes). The
/// development sets' reads from keypoints all came from the first six of their batch.
pub(super) const MAX_RETRIED_ROIS: usize = 6;

/// A patch's read: the marker, or where it does not decode, the ROI its keypoints place.
type Readout = Result<Stage2Result, Option<Quad>>;

/// The network's outputs on one image's quads, by weights and quad, kept while the families of
/// a detection read the same proposals. Families of one layout can be given one model (a user's
/// designs that differ only in their codebooks; the codebook is not the network's business),
/// and then a quad costs one pass whatever the number of such families: each decodes the same
/// outputs against its own codebook. Valid for one image: its keys do not name the image.
#[derive(Default)]
pub(crate) struct PassMemo {
    outputs: std::collections::HashMap<(u64, [u64; 8]), RawOutputs>,
}

impl PassMemo {
    fn key(weights: u64, roi: &Quad) -> (u64, [u64; 8]) {
        (
            weights,
            std::array::from_fn(|k| roi[k / 2][k % 2].to_bits()),
        )
    }
}

/// Says, of the ROIs the keypoints of failed passes placed, which may be read again.
pub(crate) type RetryGate<'a> = &'a dyn Fn(&[Quad]) -> Vec<bool>;

/// A loaded model, ready to run on patches and images.
pub struct Stage2 {
    /// The folded network as plain loops: what detection runs.
    net: PlainStage2,
    pub config: NetConfig,
    pub spec: PatchSpec,
    pub header: ModelHeader,
    family: Family,
    templates: TemplateCache,
    /// Which weights and layout these are: two `Stage2`s with one key compute the same outputs
    /// on the same patch (the key of a [`PassMemo`]).
    pass_key: u64,
}

/// How stage 2 reads a ROI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReadOptions {
    /// Network passes (2 is the paper's setting; the second starts from the first's keypoints,
    /// also where the first decoded nothing, if the alignment is on to confirm that read).
    pub iterations: usize,
    pub refine: RefineMode,
    /// The ROIs of one batch that decode nothing read again from where their keypoints place
    /// the marker, at most (the first ones of the batch).
    pub retried_rois: usize,
}

impl Default for ReadOptions {
    fn default() -> Self {
        Self {
            iterations: 2,
            refine: RefineMode::Full,
            retried_rois: MAX_RETRIED_ROIS,
        }
    }
}

/// A marker decoded from one ROI.
#[derive(Debug, Clone, Serialize)]
pub struct Stage2Result {
    pub id: usize,
    /// Clockwise angle in degrees by which the marker is turned relative to the ROI's order.
    pub rotation_deg: f64,
    pub corrected_errors: usize,
    pub fixed_mismatches: usize,
    /// The family's ROI points in the image, canonical order, from all keypoints.
    pub corners: Quad,
    pub keypoints: Vec<DetectedKeypoint>,
    /// Template keypoints with no detection matched to them.
    pub missing: usize,
    /// Passes that decoded (the second refines the first; a failed second pass keeps the
    /// first). A first pass that decoded nothing, read again from its keypoints, is not
    /// counted: `from_keypoints` says so.
    pub iterations: usize,
    /// Every pass tried decoded this ID (a pass that decodes another ID or nothing breaks it;
    /// `iterations` counts only the passes that decoded).
    pub passes_agree: bool,
    /// The first pass over the ROI given decoded nothing, and this read started from the ROI
    /// its keypoints placed; the alignment with the rendering accepted its frame.
    pub from_keypoints: bool,
    /// The alignment against the rendering (`--refine full`).
    pub refinement: Option<RefineReport>,
    #[serde(skip)]
    pub pose: Option<PnpSolution>,
}

impl Stage2Result {
    /// The read's scores in the detections file, with the ROI's `roi` score.
    pub fn scores(&self, roi: f64, cell_read: bool) -> Scores {
        let confidence = if self.keypoints.is_empty() {
            0.0
        } else {
            self.keypoints.iter().map(|k| k.confidence).sum::<f64>() / self.keypoints.len() as f64
        };
        Scores {
            roi,
            keypoints: confidence,
            corrected_errors: self.corrected_errors,
            reprojection_rms_px: self.pose.as_ref().map(|p| p.rms_px),
            cell_read,
        }
    }
}

impl Stage2 {
    pub fn load(path: &Path, family: &Family) -> Result<Self, ModelError> {
        let device = Device::flex();
        let (net, header) = model_file::load(path, family, &device)?;
        Ok(Self::new(&net, header, family))
    }

    /// The shipped weights that read `family` ([`super::shipped_model_for`]: a built-in's own,
    /// or those of its layout); `None` when none do.
    pub fn shipped(family: &Family) -> Option<Result<Self, ModelError>> {
        let (asset, bytes) = super::shipped_model_for(family)?;
        let name = format!("shipped weights assets/{asset} for {}", family.name());
        Some(Self::from_bytes(bytes, &name, family))
    }

    pub fn from_bytes(bytes: &[u8], name: &str, family: &Family) -> Result<Self, ModelError> {
        let device = Device::flex();
        let (net, header) = model_file::from_bytes(bytes, name, family, &device)?;
        Ok(Self::new(&net, header, family))
    }

    fn new(net: &Stage2Net, header: ModelHeader, family: &Family) -> Self {
        let spec = PatchSpec {
            size: header.net.patch as u32,
            ..PatchSpec::for_family(family)
        };
        let identity = format!(
            "{} {} {}",
            header.weights_fnv, header.family_hash, header.net.patch
        );
        Self {
            net: net.plain(),
            config: header.net,
            spec,
            pass_key: crate::detect::model_file::fnv1a(identity.as_bytes()),
            header,
            family: family.clone(),
            templates: TemplateCache::default(),
        }
    }

    /// Whether `other` computes the same network outputs (same weights, layout and patch), so
    /// that one pass serves both.
    pub fn shares_passes_with(&self, other: &Stage2) -> bool {
        self.pass_key == other.pass_key
    }

    /// Network outputs for patches of `spec.size`².
    pub fn run_patches(&self, patches: &[GrayImage]) -> Vec<RawOutputs> {
        // Two halves on the two cores rather than one batch whose layers burn spreads over
        // both: that spreading gains little on a few 128-px patches (see `stage1::bands`).
        // Each patch's outputs are its own whatever its batch.
        if patches.len() >= 2 {
            let (a, b) = patches.split_at(patches.len() / 2);
            let (mut a, b) = rayon::join(|| self.run_batch(a), || self.run_batch(b));
            a.extend(b);
            return a;
        }
        self.run_batch(patches)
    }

    fn run_batch(&self, patches: &[GrayImage]) -> Vec<RawOutputs> {
        let p = self.spec.size as usize;
        (patches.iter())
            .map(|patch| self.net.outputs(&normalise_patch(patch), p))
            .collect()
    }

    /// The patch a ROI (the family's ROI points 0–3 in the image, in order) warps to.
    pub fn warp(&self, image: &GrayImage, roi: &Quad) -> Option<(GrayImage, Homography)> {
        let to_image = self.to_image(roi)?;
        Some((self.warp_by(image, &to_image), to_image))
    }

    /// The map from patch pixels to the image that warps `roi` to the patch.
    fn to_image(&self, roi: &Quad) -> Option<Homography> {
        Homography::from_points(&self.spec.template_corners()[..], &roi[..]).ok()
    }

    fn warp_by(&self, image: &GrayImage, to_image: &Homography) -> GrayImage {
        let size = self.spec.size;
        // Outside the image: mid-gray, which the per-patch normalisation maps to about zero.
        warp_bilinear(image, to_image, size, size, 128)
    }

    /// Decodes the marker in `roi`; the pose needs a camera and the marker's side in metres
    /// (the family's ROI side).
    pub fn detect(
        &self,
        image: &GrayImage,
        roi: &Quad,
        options: &ReadOptions,
        camera: Option<(&Camera, f64)>,
    ) -> Option<Stage2Result> {
        let first = self
            .first_passes(image, std::slice::from_ref(roi), options)
            .pop()??;
        self.continue_from(image, first, options, camera)
    }

    /// The first pass over many ROIs at once: one batch through the network, which costs less
    /// per ROI than one at a time (the full detector's proposals). With two passes or more, a
    /// ROI that does not decode is read again where the keypoints the network found place the
    /// template (up to [`RETRY_ROUNDS`] times): a ROI a few pixels off at a steep marker's
    /// corner reads nothing, but those keypoints frame the marker better than it did (dev 36h11
    /// Difficult views of 60–75° with jittered ROIs: 104 → 127 of 160 read).
    pub fn first_passes(
        &self,
        image: &GrayImage,
        rois: &[Quad],
        options: &ReadOptions,
    ) -> Vec<Option<Stage2Result>> {
        self.first_passes_counted(image, rois, options).0
    }

    /// [`Stage2::first_passes`] and the network passes they took.
    pub fn first_passes_counted(
        &self,
        image: &GrayImage,
        rois: &[Quad],
        options: &ReadOptions,
    ) -> (Vec<Option<Stage2Result>>, usize) {
        self.first_passes_shared(image, rois, options, &mut PassMemo::default(), None)
    }

    /// [`Stage2::first_passes_counted`] taking the outputs of quads another family with the same
    /// weights read already from `memo` (and leaving its own there): the passes counted are
    /// those run. A retry goes ahead only where `retry_gate` (if any) says yes to the ROI the
    /// keypoints placed.
    pub(crate) fn first_passes_shared(
        &self,
        image: &GrayImage,
        rois: &[Quad],
        options: &ReadOptions,
        memo: &mut PassMemo,
        retry_gate: Option<RetryGate>,
    ) -> (Vec<Option<Stage2Result>>, usize) {
        let mut passes = 0;
        // Retries only where the alignment with the rendering can confirm the frame such a
        // read ends with (`continue_from`).
        let confirmable = options.iterations >= 2 && options.refine == RefineMode::Full;
        let retry_rounds = if confirmable { RETRY_ROUNDS } else { 0 };
        let mut results: Vec<Option<Stage2Result>> = vec![None; rois.len()];
        let (mut pending, mut pending_rois): (Vec<usize>, Vec<_>) =
            (0..rois.len()).zip(rois.iter().copied()).unzip();
        for round in 0..=retry_rounds {
            if pending.is_empty() {
                break;
            }
            let (mut still_pending, mut still_rois) = (Vec::new(), Vec::new());
            let (outcomes, ran) = self.read_batch(image, &pending_rois, memo);
            passes += ran;
            for ((i, last), outcome) in pending.into_iter().zip(&pending_rois).zip(outcomes) {
                match outcome {
                    Ok(r) => {
                        results[i] = Some(Stage2Result {
                            from_keypoints: round > 0,
                            ..r
                        })
                    }
                    Err(Some(roi))
                        if roi.largest_corner_move(last) >= MIN_RETRY_MOVE_PX
                            && (round > 0 || still_pending.len() < options.retried_rois) =>
                    {
                        still_pending.push(i);
                        still_rois.push(roi);
                    }
                    Err(_) => {}
                }
            }
            if let Some(gate) =
                retry_gate.filter(|_| round < retry_rounds && !still_rois.is_empty())
            {
                let open = gate(&still_rois);
                let kept = (still_pending.into_iter().zip(still_rois)).zip(open);
                (still_pending, still_rois) = kept.filter(|(_, o)| *o).map(|(p, _)| p).unzip();
            }
            (pending, pending_rois) = (still_pending, still_rois);
        }
        (results, passes)
    }

    /// One network batch over those of `rois` not in `memo`: each one's result, or where it does
    /// not decode, the ROI its keypoints place (when enough fit the template); and the patches
    /// the network ran on.
    fn read_batch(
        &self,
        image: &GrayImage,
        rois: &[Quad],
        memo: &mut PassMemo,
    ) -> (Vec<Readout>, usize) {
        let to_images: Vec<Option<Homography>> = rois.iter().map(|r| self.to_image(r)).collect();
        let (mut patches, mut keys) = (Vec::new(), Vec::new());
        let mut queued = std::collections::HashSet::new();
        for (roi, to_image) in rois.iter().zip(&to_images) {
            let key = PassMemo::key(self.pass_key, roi);
            if let Some(to_image) = to_image {
                if !memo.outputs.contains_key(&key) && queued.insert(key) {
                    patches.push(self.warp_by(image, to_image));
                    keys.push(key);
                }
            }
        }
        let ran = patches.len();
        if ran > 0 {
            memo.outputs
                .extend(keys.into_iter().zip(self.run_patches(&patches)));
        }
        let readouts = (rois.iter().zip(&to_images))
            .map(|(roi, to_image)| {
                let to_image = to_image.as_ref().ok_or(None)?;
                let raw = &memo.outputs[&PassMemo::key(self.pass_key, roi)];
                self.read_outputs(raw, to_image)
            })
            .collect();
        (readouts, ran)
    }

    /// The passes after the first (each from the last one's keypoints), the alignment against
    /// the rendering and the pose.
    pub fn continue_from(
        &self,
        image: &GrayImage,
        first: Stage2Result,
        options: &ReadOptions,
        camera: Option<(&Camera, f64)>,
    ) -> Option<Stage2Result> {
        let mut roi = first.corners;
        let from_keypoints = first.from_keypoints;
        let mut passes_agree = true;
        let mut result = first;
        for pass in 1..options.iterations.max(1) {
            match self.pass(image, &roi) {
                Some(mut r) => {
                    passes_agree &= r.id == result.id;
                    r.iterations = pass + 1;
                    roi = r.corners;
                    result = r;
                }
                None => {
                    passes_agree = false;
                    break;
                }
            }
        }
        result.passes_agree = passes_agree;
        result.from_keypoints = from_keypoints;
        let lens = camera.map_or(Lens::Pixels, |(c, _)| Lens::Camera(c));
        let kps = self.family.keypoints();
        let canonical: Vec<[f64; 2]> = result.keypoints.iter().map(|k| kps[k.index].pos).collect();
        let mut aligned = None;
        if options.refine != RefineMode::None {
            // One homography through all keypoints, in the lens plane: the family's geometry
            // replaces each keypoint's own noise.
            let plane: Vec<[f64; 2]> = result
                .keypoints
                .iter()
                .map(|k| lens.from_image([k.x, k.y]))
                .collect();
            if let Ok(mut h) = Homography::from_points(&canonical, &plane) {
                if options.refine == RefineMode::Full {
                    if let Ok(refined) =
                        refine_marker(image, &self.family, result.id, lens, &h, &self.templates)
                    {
                        result.refinement = Some(refined.report.clone());
                        if refined.report.refined {
                            h = refined.homography;
                            aligned = Some(refined);
                        }
                    }
                }
                for k in &mut result.keypoints {
                    [k.x, k.y] = lens.to_image(h.apply(kps[k.index].pos));
                }
                let roi = self.family.roi_points();
                result.corners = Quad(std::array::from_fn(|j| lens.to_image(h.apply(roi[j]))));
            }
        }
        // A read from a failed first pass's keypoints stands only where the alignment with
        // the rendering accepted its frame: from a ROI 15 px off at a corner, such a read of a
        // dim real tag decoded with no correction but a corner 5 px off, and took the place of
        // a better read (swarmathon `34139872896`); 13 of 14 right reads of this kind under
        // dev noise were aligned.
        if from_keypoints && aligned.is_none() {
            return None;
        }
        if let Some((camera, side_m)) = camera {
            let object = marker_plane_points(&self.family, side_m, &canonical);
            let pixels: Vec<[f64; 2]> = result.keypoints.iter().map(|k| [k.x, k.y]).collect();
            result.pose = solve_planar(camera, &object, &pixels).ok();
            let points = aligned.and_then(|a| a.point_covariance(lens, &canonical));
            if let (Some(pose), Some(points)) = (result.pose.as_mut(), points) {
                // The points all come from one aligned homography: their noise is the
                // alignment's, not the (near-zero) reprojection residual.
                pose.covariance =
                    covariance(camera, &object, &pose.pose, PointNoise::Covariance(&points));
            }
        }
        Some(result)
    }

    fn pass(&self, image: &GrayImage, roi: &Quad) -> Option<Stage2Result> {
        (self
            .read_batch(image, std::slice::from_ref(roi), &mut PassMemo::default())
            .0)
            .pop()?
            .ok()
    }

    /// Post-processing of one patch's outputs (`to_image` maps patch pixels to the image): the
    /// marker, or where it does not decode, the ROI its keypoints place in the image when
    /// enough of them fit the template to place it.
    fn read_outputs(&self, raw: &RawOutputs, to_image: &Homography) -> Readout {
        let family = &self.family;
        let reading = read_patch(family, &self.spec, raw).ok_or(None)?;
        let Some(decoded) = reading.decoded else {
            let enough = 2 * reading.sorted.matched() >= family.regressed_keypoints().len();
            let roi = family.roi_points();
            let to_patch = &reading.sorted.to_patch;
            return Err(enough.then(|| {
                Quad(std::array::from_fn(|j| {
                    to_image.apply(to_patch.apply(roi[j]))
                }))
            }));
        };
        self.result_of(&reading, decoded, to_image).ok_or(None)
    }

    fn result_of(
        &self,
        reading: &PatchReading,
        decoded: Decoded,
        to_image: &Homography,
    ) -> Option<Stage2Result> {
        let family = &self.family;
        let (found, sorted, read) = (&reading.found, &reading.sorted, &reading.read);
        let rotation = &family.rotations()[decoded.rotation];
        let kps = family.keypoints();
        let keypoints: Vec<DetectedKeypoint> = (0..kps.len())
            .filter_map(|i| {
                let slot = rotation.keypoint_perm[i];
                let f = &found[sorted.slots[slot]?];
                let category = read[slot]?;
                let [x, y] = to_image.apply(f.pos);
                Some(DetectedKeypoint {
                    index: i,
                    x,
                    y,
                    category,
                    // Frame cells may be drawn with a symbol's category; only code keypoints
                    // carry a symbol.
                    symbol: matches!(kps[i].assignment, Assignment::Symbol(_))
                        .then(|| family.category_symbol(category))
                        .flatten(),
                    confidence: f.confidence,
                })
            })
            .collect();
        let canonical: Vec<[f64; 2]> = keypoints.iter().map(|k| kps[k.index].pos).collect();
        let pixels: Vec<[f64; 2]> = keypoints.iter().map(|k| [k.x, k.y]).collect();
        let to_pixels = Homography::from_points(&canonical, &pixels).ok()?;
        let roi = family.roi_points();
        let corners = Quad(std::array::from_fn(|j| to_pixels.apply(roi[j])));
        Some(Stage2Result {
            id: decoded.id,
            rotation_deg: rotation.angle_deg,
            corrected_errors: decoded.corrected_errors,
            fixed_mismatches: decoded.fixed_mismatches,
            corners,
            missing: family.regressed_keypoints().len() - keypoints.len(),
            keypoints,
            iterations: 1,
            passes_agree: true,
            from_keypoints: false,
            refinement: None,
            pose: None,
        })
    }
}

/// Batch outputs → per-patch plain numbers (class probabilities per anchor, offsets, template).
pub fn raw_outputs(out: Outputs, classes: usize) -> Vec<RawOutputs> {
    let [n, _, g, _] = out.logits.dims();
    let a = g * g;
    let probs = to_vec(softmax(out.logits, 1).permute([0, 2, 3, 1]));
    let offsets = to_vec(out.offsets.permute([0, 2, 3, 1]));
    // N × (x, y) × row × col → N × row × col × (x, y): flat anchor order TL, TR, BL, BR.
    let template = to_vec(out.template.permute([0, 2, 3, 1]));
    (0..n)
        .map(|i| {
            let t = &template[i * 8..(i + 1) * 8];
            let at = |flat: usize| [t[flat * 2], t[flat * 2 + 1]];
            RawOutputs {
                probs: probs[i * a * classes..(i + 1) * a * classes].to_vec(),
                classes,
                offsets: offsets[i * a * 2..(i + 1) * a * 2]
                    .chunks(2)
                    .map(|c| [c[0], c[1]])
                    .collect(),
                template: [at(0), at(1), at(3), at(2)],
            }
        })
        .collect()
}

fn to_vec<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .expect("float tensors read back as f32")
}

/// The template head's targets in the network's flat 2 × 2 order (TL, TR, BL, BR).
pub fn template_flat(corners: &[[f32; 2]; 4]) -> [f32; 8] {
    let order = [0, 1, 3, 2];
    std::array::from_fn(|k| corners[order[k / 2]][k % 2])
}
