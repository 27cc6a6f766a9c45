//! Refinement against the rendering (docs/ARCHITECTURE.md §9.10). Once stage 2 has decoded a
//! marker, Tagsmith knows exactly what it should look like: the family renders that ID. The
//! homography from the marker to the image is refined by aligning that rendering with the
//! full-resolution image: Gauss–Newton over the image's own pixels near the marker's edges (the
//! image is never interpolated, so there is no pull towards whole pixels), with a photometric gain
//! and offset and the image's blur as parameters (the model interpolates between two blur levels
//! of the template, and a lens blurs by pixels, so the blur in marker units follows the local
//! scale), coarse to fine over the template's blur pyramid, and Huber weights against specular
//! spots and small occluders. It uses the rendering only, so every family the model expresses
//! (grids, glyphs, rings) is refined by the same code.
//!
//! When the alignment does not lower the residual, moves too far, or leaves many pixels that the
//! template does not explain (a wrong ID, half the marker hidden), the stage-2 result is kept and
//! the report says why.

pub mod template;

use crate::geometry::{Camera, Homography, Quad};
use crate::image::GrayImage;
use crate::io::Stopwatch;
use nalgebra::{DMatrix, Matrix3, SMatrix, SVector};
use serde::{Deserialize, Serialize};
pub use template::Template;
use template::EDGE;

/// How far `detect` goes beyond the network's keypoints.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RefineMode {
    /// The network's keypoints as they are; the pose from them.
    None,
    /// The keypoints re-fitted with the family's geometry (one homography through all of them),
    /// so that the pose uses every keypoint's position without its individual noise.
    Keypoints,
    /// The homography aligned with the image against the family's rendering of the decoded ID.
    #[default]
    Full,
}

impl RefineMode {
    pub const NAMES: [&'static str; 3] = ["none", "keypoints", "full"];

    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Keypoints => "keypoints",
            Self::Full => "full",
        }
    }
}

impl std::str::FromStr for RefineMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "none" => Ok(Self::None),
            "keypoints" => Ok(Self::Keypoints),
            "full" => Ok(Self::Full),
            _ => Err(format!(
                "unknown refinement {s:?}: expected one of {}",
                Self::NAMES.join(", ")
            )),
        }
    }
}

/// The plane the homography maps marker units to, and from it to image pixels.
#[derive(Debug, Clone, Copy)]
pub enum Lens<'a> {
    /// The homography maps to pixels directly (no camera known).
    Pixels,
    /// The homography maps to undistorted normalised coordinates; the camera's distortion takes
    /// them to pixels, so a wide-angle lens does not bend the model.
    Camera(&'a Camera),
}

impl Lens<'_> {
    pub fn to_image(&self, q: [f64; 2]) -> [f64; 2] {
        match self {
            Lens::Pixels => q,
            Lens::Camera(c) => c.project([q[0], q[1], 1.0]),
        }
    }

    pub fn from_image(&self, p: [f64; 2]) -> [f64; 2] {
        match self {
            Lens::Pixels => p,
            Lens::Camera(c) => c.normalise(p),
        }
    }
}

/// What the refinement did, for the detection's output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RefineReport {
    /// True when the refined homography replaced stage 2's.
    pub refined: bool,
    /// Why stage 2's result was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kept_because: Option<String>,
    /// RMS photometric residual (gray levels) at the end, and from stage 2's homography.
    pub residual: f64,
    pub start_residual: f64,
    /// Share of the compared pixels the rendering does not explain.
    pub outliers: f64,
    /// Largest move of a ROI corner, pixels.
    pub shift_px: f64,
    /// The image's fitted blur (Gaussian σ, pixels; the mean over directions).
    pub blur_px: f64,
    /// The image's noise (σ, gray levels), measured in the template's flat regions.
    pub noise: f64,
    pub iterations: usize,
    /// Time of the alignment, and of rendering the template (0 when it was cached), ms.
    #[serde(default)]
    pub time_ms: f64,
    #[serde(default)]
    pub render_ms: f64,
}

/// The result of [`refine`]: the homography to use and its uncertainty.
#[derive(Debug, Clone)]
pub struct Refined {
    /// Marker units → the lens plane; stage 2's when the refinement was refused.
    pub homography: Homography,
    /// Covariance of the 8 homography update parameters at the end (see [`Refined::jacobian`]);
    /// `None` when refused.
    pub covariance: Option<SMatrix<f64, 8, 8>>,
    pub report: RefineReport,
    centre: [f64; 2],
}

/// A refinement that moves a ROI corner by more than this share of the ROI side is a divergence.
const MAX_SHIFT: f64 = 0.1;
/// More unexplained samples than this: another ID, or a marker partly hidden.
const MAX_OUTLIERS: f64 = 0.15;
/// The template blur the alignment starts from, pixels: wider than stage 2's keypoint error.
const COARSE_BLUR_PX: f64 = 2.0;
/// ... and at most this share of the smallest keypoint (a third of a grid cell).
const MAX_COARSE_FEATURE: f64 = 0.33;
/// Template levels sharper than this are not tried: sampling a 0.1-px edge is aliasing.
const FINEST_BLUR_PX: f64 = 0.1;

/// Image pixels the alignment uses, at most, all near the marker's edges: more add time faster
/// than they add accuracy.
const MAX_PIXELS: f64 = 8000.0;
/// The share of the pixels the coarse levels use.
const COARSE_SHARE: f64 = 0.2;
/// The share that measures the residual before and after.
const STATISTICS_SHARE: f64 = 0.5;

/// Aligns `template` with `image`, starting from `start` (marker units → lens plane); `roi` are
/// the family's ROI points in marker units (for the move and the centre).
pub fn refine(
    image: &GrayImage,
    template: &Template,
    lens: Lens,
    start: &Homography,
    roi: &Quad,
) -> Refined {
    let centre = roi.centre();
    let refused = |reason: String, report: Option<RefineReport>| Refined {
        homography: *start,
        covariance: None,
        report: RefineReport {
            refined: false,
            kept_because: Some(reason),
            ..report.unwrap_or(RefineReport {
                refined: false,
                kept_because: None,
                residual: f64::NAN,
                start_residual: f64::NAN,
                outliers: f64::NAN,
                shift_px: 0.0,
                blur_px: f64::NAN,
                noise: f64::NAN,
                iterations: 0,
                time_ms: 0.0,
                render_ms: 0.0,
            })
        },
        centre,
    };
    let mut aligner = Aligner {
        image,
        template,
        lens,
        hc: start.0 * translation(centre),
        roi: roi.map(|p| [p[0] - centre[0], p[1] - centre[1]]),
        centre,
        pixels: Vec::new(),
        share: COARSE_SHARE,
        gain: 1.0,
        offset: 0.0,
        blur: [1.0, 1.0, 0.0],
        ppu: 1.0,
        noise: 2.0,
        iterations: 0,
        scratch: Scratch::default(),
    };
    (aligner.pixels, aligner.scratch) = WORKSPACE.with(|w| w.take());
    let Some(ppu) = pixels_per_unit(lens, &start.0, centre) else {
        return refused("the start homography is degenerate".into(), None);
    };
    aligner.ppu = ppu;
    let blur_px = |k: usize| template.levels[k].blur_units * ppu;
    let levels = template.levels.len();
    // The first level blurs by about stage 2's error, but never by more than a third of the
    // smallest keypoint: on a small marker a 2-px blur would wash the cells into one gray.
    let max_coarse = MAX_COARSE_FEATURE * template.feature_size;
    let coarse = (0..levels)
        .find(|&k| {
            blur_px(k) >= COARSE_BLUR_PX
                || template
                    .levels
                    .get(k + 1)
                    .is_none_or(|l| l.blur_units > max_coarse)
        })
        .unwrap_or(levels - 1);
    // A level blurred by less than a texel is interpolated with an error that depends on where
    // the edge falls between texels.
    let finest = (0..=coarse)
        .find(|&k| {
            let l = &template.levels[k];
            blur_px(k) >= FINEST_BLUR_PX && l.blur_units * l.texels_per_unit >= 0.9
        })
        .unwrap_or(coarse);
    // Image pixels merged in blocks until the template has enough texels per block.
    let block = (ppu * template::TEXELS_PER_PIXEL / template.texels_per_unit)
        .log2()
        .ceil()
        .max(0.0)
        .exp2() as usize;
    aligner.collect_pixels(blur_px(coarse), block, coarse);
    aligner.noise = aligner.estimate_noise(coarse);
    let v = blur_px(coarse).powi(2);
    aligner.blur = [v, v, 0.0];
    if !aligner.fit_photometric(coarse) {
        return refused("the marker is outside the image".into(), None);
    }
    let start_hc = aligner.hc;
    let mut chosen = coarse;
    // Levels two apart (the blur halving each time) until the image's blur is reached.
    for k in (finest..=coarse)
        .rev()
        .filter(|k| (coarse - k) % 2 == 0 || *k == finest)
    {
        aligner.clamp_variance(k);
        chosen = k;
        // Coarse levels only bring the start closer: a twentieth of a pixel is close enough.
        if !aligner.gauss_newton(k, 2, 0.05) {
            return refused("the alignment diverged".into(), None);
        }
        // Stop at the first level no blurrier than the image: the fit then interpolates
        // between it and the next, blurrier one. (The coarse level only brings the start
        // closer: its blur estimate is not trusted.)
        if k < coarse && blur_px(k) <= aligner.variance().sqrt() {
            break;
        }
    }
    // The next sharper level may still fit better than the one the halving stopped at.
    if chosen > finest
        && (coarse - chosen) % 2 == 0
        && blur_px(chosen - 1) <= aligner.variance().sqrt()
    {
        chosen -= 1;
        aligner.clamp_variance(chosen);
    }
    aligner.share = 1.0;
    if !aligner.gauss_newton(chosen, 8, 3e-3) {
        return refused("the alignment diverged".into(), None);
    }
    // The residual before and after, gain and offset fitted anew for each (the Gauss–Newton
    // state's own gain would favour the end), on half the pixels: enough to compare them.
    aligner.share = STATISTICS_SHARE;
    let Some(end) = aligner.statistics(chosen) else {
        return refused("the marker left the image".into(), None);
    };
    let shift_px = aligner.shift_from(&start_hc);
    let side_px = aligner.roi_side_px();
    let (blur_px, iterations) = (aligner.variance().sqrt(), aligner.iterations);
    let end_hc = std::mem::replace(&mut aligner.hc, start_hc);
    let before = aligner.residual(chosen);
    let report = RefineReport {
        refined: true,
        kept_because: None,
        residual: end.rms,
        start_residual: before.map_or(f64::NAN, |(_, rms)| rms),
        outliers: end.outliers,
        shift_px,
        blur_px,
        noise: aligner.noise,
        iterations,
        time_ms: 0.0,
        render_ms: 0.0,
    };
    // (A NaN shift is a divergence too.)
    if shift_px.is_nan() || shift_px > MAX_SHIFT * side_px {
        return refused(
            format!("the alignment moved a corner {shift_px:.1} px, over a tenth of the side"),
            Some(report),
        );
    }
    if end.outliers > MAX_OUTLIERS {
        return refused(
            format!(
                "{:.0} % of the marker does not look like the rendering of ID {} (occluded or \
                 another marker)",
                100.0 * end.outliers,
                template.id
            ),
            Some(report),
        );
    }
    if let Some((start_cost, _)) = before {
        if end.cost >= start_cost {
            return refused(
                "the alignment did not lower the residual".into(),
                Some(report),
            );
        }
    }
    Refined {
        homography: Homography(end_hc * translation([-centre[0], -centre[1]])),
        covariance: end.covariance,
        report,
        centre,
    }
}

impl Refined {
    /// The 2n × 2n covariance (x, y interleaved) of the image positions of marker points `at`
    /// (marker units), from the alignment's covariance; `None` when refused.
    pub fn point_covariance(&self, lens: Lens, at: &[[f64; 2]]) -> Option<DMatrix<f64>> {
        let c = self.covariance?;
        let mut j = DMatrix::zeros(2 * at.len(), 8);
        for (i, &u) in at.iter().enumerate() {
            let d = self.jacobian(lens, u);
            for k in 0..8 {
                j[(2 * i, k)] = d[0][k];
                j[(2 * i + 1, k)] = d[1][k];
            }
        }
        let c = DMatrix::from_fn(8, 8, |r, k| c[(r, k)]);
        Some(&j * c * j.transpose())
    }

    /// Derivative of the image position of marker point `u` (marker units) with respect to the 8
    /// update parameters the covariance is given in: rows x and y.
    pub fn jacobian(&self, lens: Lens, u: [f64; 2]) -> [[f64; 8]; 2] {
        let hc = self.homography.0 * translation(self.centre);
        let uc = [u[0] - self.centre[0], u[1] - self.centre[1]];
        let mut j = [[0.0; 8]; 2];
        for k in 0..8 {
            let eps = 1e-7;
            let mut d = [0.0; 8];
            d[k] = eps;
            let plus = lens.to_image(apply(&(hc * update(&d)), uc));
            d[k] = -eps;
            let minus = lens.to_image(apply(&(hc * update(&d)), uc));
            j[0][k] = (plus[0] - minus[0]) / (2.0 * eps);
            j[1][k] = (plus[1] - minus[1]) / (2.0 * eps);
        }
        j
    }
}

/// Templates already rendered, by family, ID and texel density: markers recur from frame to frame,
/// and rendering one costs more than aligning it. Bounded by memory, least recently used first
/// out: a template of a large marker is several megabytes, and a benchmark set or a long video
/// sees hundreds of IDs (a count limit of 256 let `detect-set` grow past a gigabyte).
pub struct TemplateCache {
    inner: std::sync::Mutex<CacheInner>,
    budget_bytes: usize,
}

impl Default for TemplateCache {
    fn default() -> Self {
        Self::with_budget(Self::BUDGET_BYTES)
    }
}

type TemplateKey = (String, usize, u32);

#[derive(Default)]
struct CacheInner {
    /// Each template with when it was last used.
    templates: std::collections::HashMap<TemplateKey, (std::sync::Arc<Template>, u64)>,
    bytes: usize,
    clock: u64,
}

impl TemplateCache {
    /// Bytes of templates kept at most, by default.
    pub const BUDGET_BYTES: usize = 192 << 20;

    pub fn with_budget(budget_bytes: usize) -> Self {
        Self {
            inner: Default::default(),
            budget_bytes,
        }
    }

    pub fn get(
        &self,
        family: &crate::family::Family,
        id: usize,
        texels_per_unit: f64,
    ) -> Result<std::sync::Arc<Template>, crate::render::scene::RenderError> {
        let key = (family.name().to_string(), id, texels_per_unit as u32);
        {
            let mut inner = self.lock();
            inner.clock += 1;
            let now = inner.clock;
            if let Some((t, used)) = inner.templates.get_mut(&key) {
                *used = now;
                return Ok(t.clone());
            }
        }
        let template = std::sync::Arc::new(Template::render(family, id, texels_per_unit)?);
        let mut inner = self.lock();
        inner.clock += 1;
        let now = inner.clock;
        let bytes = template.bytes();
        if let Some((old, _)) = inner.templates.insert(key, (template.clone(), now)) {
            // Rendered twice at once by two threads: the first copy goes.
            inner.bytes -= old.bytes();
        }
        inner.bytes += bytes;
        while inner.bytes > self.budget_bytes && inner.templates.len() > 1 {
            let oldest = inner
                .templates
                .iter()
                .min_by_key(|(_, (_, used))| *used)
                .map(|(k, _)| k.clone());
            let Some(oldest) = oldest else { break };
            if let Some((t, _)) = inner.templates.remove(&oldest) {
                inner.bytes -= t.bytes();
            }
        }
        Ok(template)
    }

    /// Templates held now and their bytes.
    pub fn usage(&self) -> (usize, usize) {
        let inner = self.lock();
        (inner.templates.len(), inner.bytes)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, CacheInner> {
        // A panic while holding the lock leaves a valid map: keep using it.
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Refines the marker ID `id` of `family` seen through `start` (marker units → lens plane):
/// renders (or reuses) its template at the density the marker's size in the image needs, then
/// [`refine`]s.
pub fn refine_marker(
    image: &GrayImage,
    family: &crate::family::Family,
    id: usize,
    lens: Lens,
    start: &Homography,
    cache: &TemplateCache,
) -> Result<Refined, crate::render::scene::RenderError> {
    let roi = family.roi_points();
    let roi = Quad(std::array::from_fn(|i| roi[i]));
    // A degenerate start is refused by `refine`; any density will do for it.
    let ppu = pixels_per_unit(lens, &start.0, roi.centre()).unwrap_or(1.0);
    let tpu = Template::texels_for(family, ppu);
    let clock = Stopwatch::start();
    let template = cache.get(family, id, tpu)?;
    let render_ms = clock.ms();
    let clock = Stopwatch::start();
    let mut refined = refine(image, &template, lens, start, &roi);
    refined.report.time_ms = clock.ms();
    refined.report.render_ms = render_ms;
    Ok(refined)
}

/// An image pixel the alignment compares: its gray level and its position on the lens plane.
#[derive(Debug, Clone, Copy)]
struct Pixel {
    value: f64,
    plane: [f64; 2],
    /// A hash in [0, 1): the pixels with a rank below `Aligner::share` are used.
    rank: f64,
}

struct Aligner<'a> {
    image: &'a GrayImage,
    template: &'a Template,
    lens: Lens<'a>,
    /// Centred marker units → lens plane.
    hc: Matrix3<f64>,
    /// ROI corners, centred marker units.
    roi: Quad,
    /// The ROI's centre, marker units.
    centre: [f64; 2],
    pixels: Vec<Pixel>,
    /// The share of `pixels` in use: coarse levels, which only bring the start closer, need
    /// fewer.
    share: f64,
    gain: f64,
    offset: f64,
    /// The image's blur as a Gaussian covariance in pixels² (xx, yy, xy): a lens blurs by the
    /// same pixels everywhere, which on a tilted marker is more marker units on the far side and
    /// along the tilt than across it; motion blurs along one direction. Mapped to marker units
    /// through the local Jacobian J of the homography, C = J⁻¹ C_px J⁻ᵀ, the model at a pixel is
    /// gain · (T + (tr C / 2 − σ²) · ∂T/∂σ² + ½ tr((C − tr C / 2 · I) ∇²T)) + offset, σ the
    /// level's blur: its isotropic part interpolates between two levels, the rest is first order.
    blur: [f64; 3],
    /// Pixels per marker unit at the ROI's centre, at the start.
    ppu: f64,
    noise: f64,
    iterations: usize,
    /// Buffers of the residual, kept between calls (and between alignments, see
    /// [`WORKSPACE`]).
    scratch: Scratch,
}

thread_local! {
    /// The buffers of the last alignment on this thread, for the next: a large marker's pixels
    /// are half a megabyte, and fresh ones came as zeroed pages from the system on every call.
    static WORKSPACE: std::cell::Cell<(Vec<Pixel>, Scratch)> = Default::default();
}

impl Drop for Aligner<'_> {
    fn drop(&mut self) {
        let buffers = (
            std::mem::take(&mut self.pixels),
            std::mem::take(&mut self.scratch),
        );
        WORKSPACE.with(|w| w.set(buffers));
    }
}

#[derive(Default)]
struct Scratch {
    /// [`Aligner::residual`]'s pixel values and model values.
    values: Vec<f64>,
    models: Vec<f64>,
}

/// Sums over pixels of the model's value t and the pixel's i, for the least-squares gain and
/// offset.
#[derive(Default)]
struct PhotometricSums {
    n: f64,
    st: f64,
    si: f64,
    stt: f64,
    sti: f64,
}

impl PhotometricSums {
    fn add(&mut self, t: f64, i: f64) {
        self.n += 1.0;
        self.st += t;
        self.si += i;
        self.stt += t * t;
        self.sti += t * i;
    }
}

/// See [`Aligner::model_context`].
struct ModelContext {
    k: usize,
    /// Lens plane → centred marker units.
    inverse: Matrix3<f64>,
    threshold2: f64,
    level_variance: f64,
    plane_per_px: [f64; 2],
}

/// The model at one pixel (see [`Aligner::model_at`]).
struct Sample {
    /// Centred marker point.
    uc: [f64; 2],
    template: template::Lookup,
    /// Before gain and offset.
    model: f64,
    /// By the blur covariance's xx, yy and xy.
    blur_derivatives: [f64; 3],
}

struct Statistics {
    /// Huber cost per pixel.
    cost: f64,
    rms: f64,
    outliers: f64,
    /// Of the 8 homography parameters (filled by `statistics` only: the steps do not need it).
    covariance: Option<SMatrix<f64, 8, 8>>,
    /// Weighted residual variance per degree of freedom.
    residual_variance: f64,
}

/// Parameters: 8 of the homography update, then gain, offset and the image's blur covariance.
const P: usize = 13;

type Normal = (SMatrix<f64, P, P>, SVector<f64, P>);

impl Aligner<'_> {
    fn pixel(&self, uc: [f64; 2]) -> [f64; 2] {
        self.lens.to_image(apply(&self.hc, uc))
    }

    fn inside(&self, p: [f64; 2]) -> bool {
        p[0] >= 0.0
            && p[1] >= 0.0
            && p[0] <= self.image.width as f64 - 1.0
            && p[1] <= self.image.height as f64 - 1.0
    }

    /// Marker units → the aligner's frame, centred on the ROI (keeps the normal equations well
    /// conditioned whatever the family's coordinates).
    fn centred(&self, u: [f64; 2]) -> [f64; 2] {
        [u[0] - self.centre[0], u[1] - self.centre[1]]
    }

    fn roi_side_px(&self) -> f64 {
        let p = self.roi.map(|c| self.pixel(c));
        (0..4)
            .map(|i| {
                let (a, b) = (p[i], p[(i + 1) % 4]);
                (a[0] - b[0]).hypot(a[1] - b[1])
            })
            .sum::<f64>()
            / 4.0
    }

    fn shift_from(&self, other: &Matrix3<f64>) -> f64 {
        self.roi
            .iter()
            .map(|&c| {
                let a = self.pixel(c);
                let b = self.lens.to_image(apply(other, c));
                (a[0] - b[0]).hypot(a[1] - b[1])
            })
            .fold(0.0, f64::max)
    }

    /// The pixels around the template's support as the start homography places it, with a
    /// margin for the start's error; thinned by a hash of the position when there are many
    /// (a regular pattern would sample every edge at the same phase).
    fn collect_pixels(&mut self, margin_px: f64, block: usize, band_level: usize) {
        let [x0, y0, x1, y1] = self.template.support;
        let corners = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]].map(|u| self.pixel(self.centred(u)));
        let [lo_x, lo_y, hi_x, hi_y] = crate::geometry::bounding_box(&corners);
        let margin = margin_px + 3.0;
        let (lo_x, lo_y) = ((lo_x - margin).max(0.0), (lo_y - margin).max(0.0));
        let hi_x = (hi_x + margin).min(self.image.width as f64 - 1.0);
        let hi_y = (hi_y + margin).min(self.image.height as f64 - 1.0);
        self.pixels.clear();
        if !(lo_x <= hi_x && lo_y <= hi_y) {
            return;
        }
        let (lo_x, lo_y, hi_x, hi_y) = (
            lo_x.ceil() as usize,
            lo_y.ceil() as usize,
            hi_x.floor() as usize,
            hi_y.floor() as usize,
        );
        let (bw, bh) = ((hi_x - lo_x + 1) / block, (hi_y - lo_y + 1) / block);
        let w = self.image.width as usize;
        let norm = 1.0 / (block * block) as f64;
        let half = (block - 1) as f64 / 2.0;
        let Some(inverse) = self.hc.try_inverse() else {
            return;
        };
        let level = &self.template.levels[band_level];
        let threshold = EDGE * level.max_gradient;
        // Thinned by a hash of the position (a regular pattern would sample every edge at the
        // same phase): first the box, to about twice the wanted count, then the band.
        let area = (bw * bh) as f64;
        let mut keep = (2.0 * MAX_PIXELS / area).min(1.0);
        let mut band = std::mem::take(&mut self.pixels);
        band.clear();
        // Most candidates are flat and dropped: without distortion, pixels map to marker units
        // by one homography, stepped along the row, and only the band's pixels are undistorted.
        let undistorted = match self.lens {
            Lens::Pixels => Some(Matrix3::identity()),
            Lens::Camera(c) if c.distortion == [0.0; 5] => Some(Matrix3::new(
                1.0 / c.fx,
                0.0,
                -c.cx / c.fx,
                0.0,
                1.0 / c.fy,
                -c.cy / c.fy,
                0.0,
                0.0,
                1.0,
            )),
            Lens::Camera(_) => None,
        };
        let to_marker = undistorted.map(|k| translation(self.centre) * inverse * k);
        // Where the template's level is in the image (undistorted lenses): a block whose centre
        // falls outside it cannot be in the band, and a tilted or turned marker leaves much of
        // its bounding box outside.
        let level_quad = undistorted.and_then(|_| {
            let t = level.texels_per_unit;
            let [ox, oy] = self.template.origin;
            let (ex, ey) = (ox + level.width as f64 / t, oy + level.height as f64 / t);
            let corners = [[ox, oy], [ex, oy], [ex, ey], [ox, ey]].map(|u| self.centred(u));
            // All four in front of the camera, or no quad.
            let depth =
                |u: [f64; 2]| self.hc[(2, 0)] * u[0] + self.hc[(2, 1)] * u[1] + self.hc[(2, 2)];
            let first = depth(corners[0]).signum();
            corners
                .iter()
                .all(|&u| depth(u).signum() == first && depth(u) != 0.0)
                .then(|| Quad(corners.map(|u| self.pixel(u))))
        });
        for by in 0..bh {
            let y = lo_y + by * block;
            let row = to_marker.map(|g| {
                let start = g * nalgebra::Vector3::new(lo_x as f64 + half, y as f64 + half, 1.0);
                (start, g.column(0) * block as f64)
            });
            let (first, last) = match level_quad.map(|q| row_span(&q, y as f64 + half)) {
                // (A pixel of slack for the rounding of the quad's corners.)
                Some(Some((from, to))) => (
                    ((from - 1.0 - half - lo_x as f64) / block as f64)
                        .ceil()
                        .max(0.0) as usize,
                    ((to + 1.0 - half - lo_x as f64) / block as f64 + 1.0).clamp(0.0, bw as f64)
                        as usize,
                ),
                Some(None) => continue,
                None => (0, bw),
            };
            for bx in first..last {
                if keep < 1.0 && spread(bx, by) >= keep {
                    continue;
                }
                let x = lo_x + bx * block;
                let pixel = [x as f64 + half, y as f64 + half];
                let u = match row {
                    Some((start, step)) => {
                        let q = start + step * bx as f64;
                        [q[0] / q[2], q[1] / q[2]]
                    }
                    None => {
                        let uc = apply(&inverse, self.lens.from_image(pixel));
                        [uc[0] + self.centre[0], uc[1] + self.centre[1]]
                    }
                };
                // The band of the coarsest level used holds every finer level's band.
                let Some(t) = self.template.lookup_edge(band_level, u) else {
                    continue;
                };
                if t.gradient[0] * t.gradient[0] + t.gradient[1] * t.gradient[1]
                    < threshold * threshold
                {
                    continue;
                }
                let mut sum = 0u32;
                for yy in y..y + block {
                    for xx in x..x + block {
                        sum += self.image.pixels[yy * w + xx] as u32;
                    }
                }
                // A block integrates its pixels: its centre is its position.
                let rank = spread(bx + 7919, by + 104_729);
                band.push(Pixel {
                    value: sum as f64 * norm,
                    plane: self.lens.from_image(pixel),
                    rank,
                });
            }
        }
        keep = (MAX_PIXELS / band.len().max(1) as f64).min(1.0);
        band.retain(|p| p.rank < keep);
        for p in &mut band {
            p.rank /= keep;
        }
        self.pixels = band;
        // Each share's pixels first, still in image order within (the template's texels are
        // then read in order): a share is a prefix, not a test per pixel whose outcome the
        // processor cannot predict.
        let bucket =
            |rank: f64| usize::from(rank >= COARSE_SHARE) + usize::from(rank >= STATISTICS_SHARE);
        self.pixels.sort_by_key(|p| bucket(p.rank));
    }

    /// The pixels of the share in use (see [`Aligner::collect_pixels`] for their order).
    fn in_use(&self) -> &[Pixel] {
        debug_assert!([COARSE_SHARE, STATISTICS_SHARE, 1.0].contains(&self.share));
        let end = self.pixels.partition_point(|p| p.rank < self.share);
        &self.pixels[..end]
    }

    /// The image's noise: differences between neighbouring pixels where the template is flat.
    fn estimate_noise(&self, k: usize) -> f64 {
        let level = &self.template.levels[k];
        let mut diffs: Vec<f64> = Vec::with_capacity(level.flat.len() * 2);
        for &u in &level.flat {
            let p = self.pixel(self.centred(u));
            let p = [p[0].round(), p[1].round()];
            if !self.inside(p)
                || p[0] + 1.0 > self.image.width as f64 - 1.0
                || p[1] + 1.0 > self.image.height as f64 - 1.0
            {
                continue;
            }
            let at = |x: f64, y: f64| self.image.get(x as u32, y as u32) as f64;
            let v = at(p[0], p[1]);
            diffs.push((v - at(p[0] + 1.0, p[1])).abs());
            diffs.push((v - at(p[0], p[1] + 1.0)).abs());
        }
        if diffs.is_empty() {
            return 2.0;
        }
        let mid = diffs.len() / 2;
        let (_, median, _) = diffs.select_nth_unstable_by(mid, f64::total_cmp);
        // MAD of a difference of two pixels: σ·√2·0.6745. Quantisation keeps it above ~1.
        (*median / (std::f64::consts::SQRT_2 * 0.6745)).max(1.0)
    }

    /// Each compared pixel with the template there, for level `k` at the current estimate.
    fn visit(&self, k: usize, mut f: impl FnMut(&Pixel, &Sample)) {
        let Some(at) = self.model_context(k) else {
            return;
        };
        for px in self.in_use() {
            if let Some(sample) = self.model_at(&at, px) {
                f(px, &sample);
            }
        }
    }

    /// What [`Aligner::model_at`] needs from level `k` and the current estimate.
    fn model_context(&self, k: usize) -> Option<ModelContext> {
        let level = &self.template.levels[k];
        let threshold = EDGE * level.max_gradient;
        Some(ModelContext {
            k,
            inverse: self.hc.try_inverse()?,
            threshold2: threshold * threshold,
            level_variance: level.blur_units.powi(2),
            plane_per_px: match self.lens {
                Lens::Pixels => [1.0, 1.0],
                Lens::Camera(c) => [1.0 / c.fx, 1.0 / c.fy],
            },
        })
    }

    /// The model at one pixel: `None` where the template is flat or the pixel falls outside its
    /// support. Inlined into each loop over the pixels (a call per pixel cost a tenth of the
    /// time, and kept the arithmetic off the wider instructions of the caller).
    #[inline(always)]
    fn model_at(&self, at: &ModelContext, px: &Pixel) -> Option<Sample> {
        let g = &at.inverse;
        let [sx0, sy0, sx1, sy1] = self.template.support;
        let q = px.plane;
        // One division per pixel: the marker point and, below, how it moves per pixel.
        let s = 1.0 / (g[(2, 0)] * q[0] + g[(2, 1)] * q[1] + g[(2, 2)]);
        let uc = [
            (g[(0, 0)] * q[0] + g[(0, 1)] * q[1] + g[(0, 2)]) * s,
            (g[(1, 0)] * q[0] + g[(1, 1)] * q[1] + g[(1, 2)]) * s,
        ];
        let u = [uc[0] + self.centre[0], uc[1] + self.centre[1]];
        if !(u[0] >= sx0 && u[0] <= sx1 && u[1] >= sy0 && u[1] <= sy1) {
            return None;
        }
        let t = self.template.lookup_edge(at.k, u)?;
        if t.gradient[0] * t.gradient[0] + t.gradient[1] * t.gradient[1] < at.threshold2 {
            return None;
        }
        // M = d(marker unit)/d(pixel) here (the lens's distortion left out: it barely changes M
        // across a marker), the derivative of the inverse homography: row r is
        // (G_r − u_r G_2) / (G_2 · q), per pixel through the focal lengths.
        let (sx, sy) = (s * at.plane_per_px[0], s * at.plane_per_px[1]);
        let m00 = (g[(0, 0)] - uc[0] * g[(2, 0)]) * sx;
        let m01 = (g[(0, 1)] - uc[0] * g[(2, 1)]) * sy;
        let m10 = (g[(1, 0)] - uc[1] * g[(2, 0)]) * sx;
        let m11 = (g[(1, 1)] - uc[1] * g[(2, 1)]) * sy;
        // C_u = cxx·m0 m0ᵀ + cyy·m1 m1ᵀ + cxy·(m0 m1ᵀ + m1 m0ᵀ), m0 and m1 M's columns; each
        // term's effect on the model: its half trace times the slope towards the next level,
        // plus its traceless part against the template's second derivatives.
        let effect = |e00: f64, e11: f64, e01: f64| {
            0.5 * (e00 + e11) * t.blur_slope + 0.5 * (e00 - e11) * t.half_difference + e01 * t.cross
        };
        let d = [
            effect(m00 * m00, m10 * m10, m00 * m10),
            effect(m01 * m01, m11 * m11, m01 * m11),
            effect(2.0 * m00 * m01, 2.0 * m10 * m11, m00 * m11 + m10 * m01),
        ];
        let [cxx, cyy, cxy] = self.blur;
        let model =
            t.value - at.level_variance * t.blur_slope + cxx * d[0] + cyy * d[1] + cxy * d[2];
        Some(Sample {
            uc,
            template: t,
            model,
            blur_derivatives: d,
        })
    }

    /// Gain and offset by least squares at the current homography and blur.
    fn fit_photometric(&mut self, k: usize) -> bool {
        let mut sums = PhotometricSums::default();
        self.visit(k, |px, sample| sums.add(sample.model, px.value));
        self.set_photometric(&sums)
    }

    /// Gain and offset from the sums of the model's values and the pixels'.
    fn set_photometric(&mut self, sums: &PhotometricSums) -> bool {
        let &PhotometricSums {
            n,
            st,
            si,
            stt,
            sti,
        } = sums;
        let var = stt - st * st / n.max(1.0);
        if n < 50.0 || var <= 1e-9 {
            return false;
        }
        self.gain = (sti - st * si / n) / var;
        self.offset = (si - self.gain * st) / n;
        self.gain.is_finite() && self.offset.is_finite()
    }

    fn huber_threshold(&self) -> f64 {
        (2.5 * self.noise).max(0.1 * self.gain.abs() * 255.0)
    }

    fn outlier_threshold(&self) -> f64 {
        (4.0 * self.noise).max(0.3 * self.gain.abs() * 255.0)
    }

    /// Normal equations of the 8 warp, 2 photometric and 1 blur parameters at the current
    /// estimate. The model is the template at H⁻¹(pixel); moving H by (I + D) moves the marker
    /// point a pixel sees by −D u, hence the template's gradient in the warp columns.
    fn normal_equations(&self, k: usize) -> Option<(Normal, Statistics)> {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the processor has the features the function is compiled for.
            return unsafe { self.normal_equations_avx2(k) };
        }
        self.normal_equations_portable(k)
    }

    /// [`Aligner::normal_equations`] compiled for processors with AVX2 and FMA (most x86-64
    /// since 2013; the default target is the 2003 baseline): twice the lanes in the dot
    /// products and fused multiply-adds in every pixel's model.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn normal_equations_avx2(&self, k: usize) -> Option<(Normal, Statistics)> {
        self.normal_equations_portable(k)
    }

    #[inline(always)]
    fn normal_equations_portable(&self, k: usize) -> Option<(Normal, Statistics)> {
        let (huber, outlier) = (self.huber_threshold(), self.outlier_threshold());
        let (mut n, mut cost, mut sq, mut outliers, mut wsum) = (0usize, 0.0, 0.0, 0usize, 0.0);
        let gain = self.gain;
        // The Jacobian column by column (one contiguous array per parameter) for a chunk of
        // pixels, then the chunk's JᵀWJ as dot products: a pixel's 91 products, accumulated row
        // by row, took a third of the time, and the columns of every pixel at once (a megabyte)
        // were read 14 times from beyond the first-level cache.
        let mut columns = [[0f64; CHUNK]; P];
        let (mut weights, mut weighted_residuals) = ([0f64; CHUNK], [0f64; CHUNK]);
        let mut a = SMatrix::<f64, P, P>::zeros();
        let mut g = [0f64; P];
        let mut filled = 0;
        let at = self.model_context(k)?;
        for px in self.in_use() {
            let Some(Sample {
                uc,
                template: t,
                model,
                blur_derivatives: d,
            }) = self.model_at(&at, px)
            else {
                continue;
            };
            let r = px.value - (gain * model + self.offset);
            let ar = r.abs();
            let w = if ar <= huber { 1.0 } else { huber / ar };
            cost += huber_cost(r, huber);
            sq += r * r;
            wsum += w * r * r;
            outliers += usize::from(ar > outlier);
            let [x, y] = uc;
            let ga = [t.gradient[0] * gain, t.gradient[1] * gain];
            let j = [
                ga[0] * x,
                ga[0] * y,
                ga[0],
                ga[1] * x,
                ga[1] * y,
                ga[1],
                -(ga[0] * x + ga[1] * y) * x,
                -(ga[0] * x + ga[1] * y) * y,
                -model,
                -1.0,
                -gain * d[0],
                -gain * d[1],
                -gain * d[2],
            ];
            for (column, v) in columns.iter_mut().zip(j) {
                column[filled] = v;
            }
            weights[filled] = w;
            weighted_residuals[filled] = w * r;
            filled += 1;
            n += 1;
            if filled == CHUNK {
                accumulate(
                    &columns,
                    &weights,
                    &weighted_residuals,
                    CHUNK,
                    &mut a,
                    &mut g,
                );
                filled = 0;
            }
        }
        accumulate(
            &columns,
            &weights,
            &weighted_residuals,
            filled,
            &mut a,
            &mut g,
        );
        if n < 50 {
            return None;
        }
        for r in 0..P {
            for c in 0..r {
                a[(r, c)] = a[(c, r)];
            }
        }
        let nf = n as f64;
        let stats = Statistics {
            cost: cost / nf,
            rms: (sq / nf).sqrt(),
            outliers: outliers as f64 / nf,
            covariance: None,
            residual_variance: wsum / (nf - P as f64).max(1.0),
        };
        Some(((a, SVector::from(g)), stats))
    }

    /// Gauss–Newton with Huber weights (IRLS) at level `k`, until a step moves no ROI corner by
    /// `tolerance_px`; false when it diverges.
    fn gauss_newton(&mut self, k: usize, max_iterations: usize, tolerance_px: f64) -> bool {
        for _ in 0..max_iterations {
            let Some(((a, g), _)) = self.normal_equations(k) else {
                return false;
            };
            let mut damped = a;
            for i in 0..P {
                damped[(i, i)] += 1e-9 * a[(i, i)].max(1e-12);
            }
            let Some(step) = damped.lu().solve(&(-g)) else {
                return false;
            };
            if step.iter().any(|v| !v.is_finite()) {
                return false;
            }
            let d: [f64; 8] = std::array::from_fn(|i| step[i]);
            let before = self.hc;
            self.hc *= update(&d);
            self.gain += step[8];
            self.offset += step[9];
            for (b, s) in self.blur.iter_mut().zip(&step.as_slice()[10..]) {
                *b += s;
            }
            self.clamp_variance(k);
            self.iterations += 1;
            if self.shift_from(&before) < tolerance_px {
                break;
            }
        }
        self.hc.iter().all(|v| v.is_finite())
    }

    /// The image's blur as one variance, pixels²: the mean over directions.
    fn variance(&self) -> f64 {
        0.5 * (self.blur[0] + self.blur[1])
    }

    /// Keeps the image's blur where level `k`'s blur terms can model it: its mean variance from
    /// half the level's to the next level's and half as far again, positive in every direction.
    fn clamp_variance(&mut self, k: usize) {
        let levels = &self.template.levels;
        let level = (levels[k].blur_units * self.ppu).powi(2);
        let next = levels
            .get(k + 1)
            .map_or(2.0 * level, |l| (l.blur_units * self.ppu).powi(2));
        let mean = self.variance();
        let target = mean.clamp(0.5 * level, next + 0.5 * (next - level));
        if mean > 0.0 && mean.is_finite() {
            let scale = target / mean;
            self.blur[0] *= scale;
            self.blur[1] *= scale;
            self.blur[2] *= scale;
        } else {
            self.blur = [target, target, 0.0];
        }
        self.blur[0] = self.blur[0].max(0.1 * level);
        self.blur[1] = self.blur[1].max(0.1 * level);
        let most = 0.95 * (self.blur[0] * self.blur[1]).sqrt();
        self.blur[2] = self.blur[2].clamp(-most, most);
    }

    /// The Huber cost per pixel and the RMS residual at the current homography, gain and offset
    /// re-fitted: what [`Aligner::statistics`] says without the normal equations, for the start.
    fn residual(&mut self, k: usize) -> Option<(f64, f64)> {
        // One visit: the pixels' and the model's values are kept for the second pass.
        let mut scratch = std::mem::take(&mut self.scratch);
        let (values, models) = (&mut scratch.values, &mut scratch.models);
        values.clear();
        models.clear();
        self.visit(k, |px, sample| {
            values.push(px.value);
            models.push(sample.model);
        });
        let mut sums = PhotometricSums::default();
        for (&v, &t) in values.iter().zip(models.iter()) {
            sums.add(t, v);
        }
        let fitted = self.set_photometric(&sums);
        let huber = self.huber_threshold();
        let (gain, offset) = (self.gain, self.offset);
        let (mut cost, mut sq) = (0.0, 0.0);
        for (v, m) in values.iter().zip(models.iter()) {
            let r = v - (gain * m + offset);
            cost += huber_cost(r, huber);
            sq += r * r;
        }
        let n = values.len() as f64;
        self.scratch = scratch;
        fitted.then(|| (cost / n, (sq / n).sqrt()))
    }

    /// Residual statistics at the current homography, with gain and offset re-fitted.
    fn statistics(&mut self, k: usize) -> Option<Statistics> {
        if !self.fit_photometric(k) {
            return None;
        }
        let ((a, _), mut stats) = self.normal_equations(k)?;
        stats.covariance = a
            .try_inverse()
            .map(|inv| inv.fixed_view::<8, 8>(0, 0).into_owned() * stats.residual_variance);
        Some(stats)
    }
}

/// The Huber loss of residual `r` with threshold `huber`: quadratic inside, linear beyond.
#[inline(always)]
fn huber_cost(r: f64, huber: f64) -> f64 {
    let ar = r.abs();
    if ar <= huber {
        0.5 * r * r
    } else {
        huber * (ar - 0.5 * huber)
    }
}

/// Pixels per chunk of the normal equations: the chunk's 13 columns (26 kB) stay in the
/// first-level cache.
const CHUNK: usize = 256;

/// Adds the first `n` pixels of a chunk to JᵀWJ (upper triangle) and JᵀWr.
#[inline(always)]
fn accumulate(
    columns: &[[f64; CHUNK]; P],
    weights: &[f64; CHUNK],
    weighted_residuals: &[f64; CHUNK],
    n: usize,
    a: &mut SMatrix<f64, P, P>,
    g: &mut [f64; P],
) {
    let mut weighted = [0f64; CHUNK];
    for r in 0..P {
        let jr = &columns[r][..n];
        g[r] += dot(jr, &weighted_residuals[..n]);
        for ((o, &j), &w) in weighted.iter_mut().zip(jr).zip(weights) {
            *o = j * w;
        }
        for c in r..P {
            a[(r, c)] += dot(&weighted[..n], &columns[c][..n]);
        }
    }
}

/// Σ aᵢbᵢ with eight independent partial sums, which the compiler turns into vector
/// instructions (one running sum would wait on each addition in turn).
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut partial = [0f64; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for i in 0..8 {
            partial[i] += x[i] * y[i];
        }
    }
    partial.iter().sum::<f64>() + tail
}

/// Image pixels per marker unit at marker point `at` through `h` (marker units → lens plane):
/// the square root of the local area ratio; `None` for a degenerate homography.
fn pixels_per_unit(lens: Lens, h: &Matrix3<f64>, at: [f64; 2]) -> Option<f64> {
    let pixel = |du: f64, dv: f64| lens.to_image(apply(h, [at[0] + du, at[1] + dv]));
    let (o, x, y) = (pixel(0.0, 0.0), pixel(1.0, 0.0), pixel(0.0, 1.0));
    let cross = (x[0] - o[0]) * (y[1] - o[1]) - (x[1] - o[1]) * (y[0] - o[0]);
    let s = cross.abs().sqrt();
    (s.is_finite() && s > 1e-6).then_some(s)
}

/// The x extent of a convex quadrilateral on the row at height `y`; `None` when the row misses it.
fn row_span(quad: &Quad, y: f64) -> Option<(f64, f64)> {
    let mut span: Option<(f64, f64)> = None;
    for i in 0..4 {
        let (a, b) = (quad[i], quad[(i + 1) % 4]);
        if (a[1] - y) * (b[1] - y) > 0.0 || a[1] == b[1] {
            continue;
        }
        let x = a[0] + (y - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
        span = Some(span.map_or((x, x), |(lo, hi)| (lo.min(x), hi.max(x))));
    }
    span
}

/// A well-mixed number in [0, 1) from a position (SplitMix64's finaliser).
fn spread(x: usize, y: usize) -> f64 {
    let mut z = ((x as u64) << 32 | y as u64).wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// Small homography change D in centred marker units: (I + D).
fn update(d: &[f64; 8]) -> Matrix3<f64> {
    Matrix3::new(
        1.0 + d[0],
        d[1],
        d[2],
        d[3],
        1.0 + d[4],
        d[5],
        d[6],
        d[7],
        1.0,
    )
}

fn translation(t: [f64; 2]) -> Matrix3<f64> {
    Matrix3::new(1.0, 0.0, t[0], 0.0, 1.0, t[1], 0.0, 0.0, 1.0)
}

fn apply(h: &Matrix3<f64>, p: [f64; 2]) -> [f64; 2] {
    let q = h * nalgebra::Vector3::new(p[0], p[1], 1.0);
    [q[0] / q[2], q[1] / q[2]]
}

#[cfg(test)]
mod tests;
