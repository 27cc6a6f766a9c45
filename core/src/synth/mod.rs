//! On-the-fly training images with exact ground truth (docs/ARCHITECTURE.md §8), deterministic per
//! seed.
//!
//! Three modes: `quad` (stage-1 scenes, markers placed by random quadrilaterals), `camera` (a
//! pinhole camera at a random 6-DoF pose; ground-truth pose included) and `patch` (stage-2 patches:
//! the ROI mapped to a random quad ((a1,a2),(1−a3,a4),(1−a5,1−a6),(a7,1−a8)), a_i ~ U[a − s/7,
//! a + s/7] around the family's template margin a, with s = 1 − 2a the template's side: U[0.05,
//! 0.25] at the default margin).

pub mod augment;
mod background;
pub mod contact;

use crate::family::marker_plane_points;
use crate::family::Family;
use crate::geometry::{bounding_box, Camera, GeometryError, Homography, Pose, PoseJson};
use crate::image::GrayImage;
use crate::render::{marker_scene, raster, RenderError, SceneOptions};
use augment::{draw, AugmentRanges};
use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// A scene that cannot be synthesised; each names the value that failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SynthError {
    #[error("image size {width}×{height} must be 16 to 8192 px")]
    ImageSize { width: u32, height: u32 },
    /// The camera (field of view) or a marker placement that does not determine a homography.
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error("the placement of marker {id} is degenerate")]
    DegeneratePlacement { id: usize },
    #[error("a scene needs at least one family")]
    NoFamily,
}

/// A float image, 0 = black, 1 = white; pixel centres at integer coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct Canvas {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<f32>,
}

impl Canvas {
    pub fn new(width: u32, height: u32, value: f32) -> Self {
        Self {
            width,
            height,
            pixels: vec![value; width as usize * height as usize],
        }
    }
    pub fn get(&self, x: u32, y: u32) -> f32 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }
    pub fn set(&mut self, x: u32, y: u32, v: f32) {
        self.pixels[y as usize * self.width as usize + x as usize] = v;
    }
    /// Bilinear sample, clamped at the borders.
    pub fn sample(&self, x: f32, y: f32) -> f32 {
        crate::image::bilinear(self.width, self.height, x, y, |i| self.pixels[i])
    }
    pub fn clamp(&mut self) {
        self.pixels.iter_mut().for_each(|p| *p = p.clamp(0.0, 1.0));
    }
    pub fn to_gray(&self) -> GrayImage {
        GrayImage {
            width: self.width,
            height: self.height,
            pixels: self
                .pixels
                .iter()
                .map(|p| (p.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
                .collect(),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    Quad,
    Camera,
    Patch,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SynthConfig {
    pub mode: Mode,
    pub width: u32,
    pub height: u32,
    /// Markers per scene (quad and camera modes).
    pub markers: [u32; 2],
    /// Camera mode: diagonal field of view, marker side (m), distance (m) and view angle (deg).
    pub fov_deg: f64,
    pub side_m: [f64; 2],
    pub distance_m: [f64; 2],
    pub view_angle_deg: [f64; 2],
    /// Quad mode: a marker's side as a fraction of the image's shorter side.
    #[serde(default = "default_quad_side")]
    pub quad_side: [f64; 2],
    pub augment: AugmentRanges,
    /// Seeds the sensor noise separately: the same image seed with another noise seed renders the
    /// same scene with fresh noise (jitter sets).
    #[serde(default)]
    pub noise_seed: Option<u64>,
    /// Draws each marker's pose, its ID and the scene's look (levels, light, blur, noise) from
    /// streams of their own, so that one seed renders the same scene for every family: a design
    /// comparison shows each design the same poses, light and noise. Off, one stream draws them
    /// all, as the sets made before it was added were drawn.
    #[serde(default)]
    pub shared_scene: bool,
    /// What the markers lie on.
    #[serde(default)]
    pub background: BackgroundKind,
}

/// A scene's background.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BackgroundKind {
    /// Photo-like textures and clutter (the training distribution).
    #[default]
    Clutter,
    /// One even gray: a marker on a wall or a sheet of paper.
    Plain,
}

/// How far apart a shared scene keeps its markers, in ROI box sizes (room for any family's quiet
/// zone and drawn area beyond its ROI).
const SHARED_SCENE_MARGIN: f64 = 0.35;

/// The gray level of a plain background (0–1).
const PLAIN_BACKGROUND: f32 = 0.6;

fn default_quad_side() -> [f64; 2] {
    [0.15, 0.55]
}

impl SynthConfig {
    /// Defaults per mode: 320×320 stage-1 scenes, 1280×960 camera images at 98° (the paper's
    /// benchmark camera), 128×128 stage-2 patches.
    pub fn new(mode: Mode) -> Self {
        let (width, height) = match mode {
            Mode::Quad => (320, 320),
            Mode::Camera => (1280, 960),
            Mode::Patch => (128, 128),
        };
        Self {
            mode,
            width,
            height,
            markers: [1, 3],
            fov_deg: 98.0,
            side_m: [0.03, 0.1],
            distance_m: [0.1, 1.0],
            view_angle_deg: [0.0, 75.0],
            quad_side: default_quad_side(),
            augment: AugmentRanges::default(),
            noise_seed: None,
            shared_scene: false,
            background: BackgroundKind::Clutter,
        }
    }
}

/// Ground truth of one keypoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KeypointTruth {
    pub x: f64,
    pub y: f64,
    pub category: usize,
    /// The code symbol this keypoint carries, if it is a symbol keypoint.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub symbol: Option<u8>,
    /// Inside the image.
    pub visible: bool,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseTruth {
    /// Marker frame (OpenCV ArUco's) → camera frame.
    #[serde(flatten)]
    pub pose: PoseJson,
    pub side_m: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MarkerTruth {
    pub id: usize,
    /// The marker's family in a scene of several ([`synthesize_mixed`]); otherwise the truth's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub family: Option<String>,
    /// Axis-aligned box of the marker's drawn area (quiet zone excluded): x0, y0, x1, y1.
    pub bbox: [f64; 4],
    /// The family's ROI points in the image, in order.
    pub roi: Vec<[f64; 2]>,
    pub keypoints: Vec<KeypointTruth>,
    /// Outline of the marker's drawn area (the segmentation mask as a polygon).
    pub mask: Vec<[f64; 2]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pose: Option<PoseTruth>,
}

/// Augmentation values actually applied to an image.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Applied {
    pub blur_sigma: f32,
    pub noise_sigma: f32,
    pub motion_blur: Option<(u32, f32)>,
    /// (marker ID, kernel length, angle) of each marker blurred on its own.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub marker_motion_blur: Vec<(usize, u32, f32)>,
    pub spotlight_gain: Option<f32>,
    pub barrel_k1: Option<f64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    pub family: String,
    pub mode: Mode,
    pub seed: u64,
    pub width: u32,
    pub height: u32,
    pub markers: Vec<MarkerTruth>,
    pub applied: Applied,
    /// Camera mode: the intrinsics used (distortion = the barrel distortion applied).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub camera: Option<Camera>,
}

pub struct Sample {
    pub image: GrayImage,
    pub truth: Truth,
}

/// The seed of image `index` of a run seeded with `seed`.
pub fn image_seed(seed: u64, index: u64) -> u64 {
    seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(index)
}

/// A marker's placement: marker units → undistorted image pixels.
struct Placement {
    to_image: Homography,
    /// Where the ROI is taken from when it is not `to_image` (a cyclic ring marker drawn turned
    /// within a ROI that stays put, see [`ring_turn`]).
    roi_to_image: Option<Homography>,
    pose: Option<(Pose, f64)>,
}

impl Placement {
    /// Marker units → image for the ROI (and the outline that must fit the image).
    fn roi_map(&self) -> &Homography {
        self.roi_to_image.as_ref().unwrap_or(&self.to_image)
    }
}

pub fn synthesize(family: &Family, config: &SynthConfig, seed: u64) -> Result<Sample, SynthError> {
    synthesize_mixed(&[family], config, seed)
}

/// A scene whose markers come from several families: marker `i` is of `families[i % len]`.
/// Each marker's truth names its family when there is more than one.
pub fn synthesize_mixed(
    families: &[&Family],
    config: &SynthConfig,
    seed: u64,
) -> Result<Sample, SynthError> {
    let family = *families.first().ok_or(SynthError::NoFamily)?;
    if config.width < 16 || config.height < 16 || config.width > 8192 || config.height > 8192 {
        return Err(SynthError::ImageSize {
            width: config.width,
            height: config.height,
        });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let aug = &config.augment;
    let mut canvas = match config.background {
        BackgroundKind::Clutter => background::procedural(&mut rng, config.width, config.height),
        BackgroundKind::Plain => Canvas::new(config.width, config.height, PLAIN_BACKGROUND),
    };
    // With a shared scene the IDs and the look have streams of their own: their draws depend on
    // the family (codebook size, marker outline) and would shift every draw after them.
    let stream = |k: u64| ChaCha8Rng::seed_from_u64(image_seed(seed ^ 0x5CE4E, k));
    let mut ids = config.shared_scene.then(|| stream(1));
    let camera = Camera::from_diagonal_fov(config.width, config.height, config.fov_deg)?;

    let count = match config.mode {
        Mode::Patch => 1,
        _ => rng.random_range(config.markers[0]..=config.markers[1].max(config.markers[0])),
    };
    let mut placed: Vec<(usize, Placement, [f64; 4], &Family)> = Vec::new();
    for index in 0..count {
        let family = families[index as usize % families.len()];
        for attempt in 0..30 {
            let placement = match config.mode {
                Mode::Quad => place_quad(family, &mut rng, config),
                Mode::Patch => place_patch(family, &mut rng, config),
                Mode::Camera => place_camera(family, &mut rng, config, &camera),
            }?;
            // A shared scene keeps a pose by the ROI alone, which designs of one print size share.
            let outline = if config.shared_scene {
                roi4(family)
                    .iter()
                    .map(|&p| placement.to_image.apply(p))
                    .collect()
            } else {
                // A ring turned within its ROI is drawn where its unturned self would be; the
                // corners of its paper may then leave a patch, which clips them.
                project_outline(family, placement.roi_map())
            };
            let b = bounding_box(&outline);
            let inside = b[0] >= 0.0
                && b[1] >= 0.0
                && b[2] < config.width as f64
                && b[3] < config.height as f64;
            // A shared scene keeps markers apart by their ROI boxes grown by a margin no family
            // sets: a design's drawn area and quiet zone must not decide where the others go.
            let apart = |r: [f64; 4]| {
                let m = if config.shared_scene {
                    SHARED_SCENE_MARGIN * (r[2] - r[0]).max(r[3] - r[1])
                } else {
                    0.0
                };
                [r[0] - m, r[1] - m, r[2] + m, r[3] + m]
            };
            let g = apart(b);
            let overlaps = placed.iter().any(|(_, _, o, _)| {
                let o = apart(*o);
                g[0] < o[2] && o[0] < g[2] && g[1] < o[3] && o[1] < g[3]
            });
            // Markers stay whole inside the image; a camera placement that never fits (a marker
            // larger than the view) is kept partly outside on the last try rather than dropped.
            let last_try = attempt == 29 && config.mode == Mode::Camera;
            if (inside || last_try) && !overlaps {
                let id = ids
                    .as_mut()
                    .unwrap_or(&mut rng)
                    .random_range(0..family.codebook().len());
                placed.push((id, placement, b, family));
                break;
            }
        }
    }
    let mut rng = if config.shared_scene { stream(2) } else { rng };
    let mut applied = Applied::default();
    for (id, placement, region, family) in &placed {
        let black = draw(&mut rng, aug.marker_black) / 255.0;
        let white = draw(&mut rng, aug.marker_white) / 255.0;
        let balance = [
            draw(&mut rng, aug.white_balance),
            draw(&mut rng, aug.white_balance),
            draw(&mut rng, aug.white_balance),
        ];
        draw_marker(
            &mut canvas,
            family,
            *id,
            &placement.to_image,
            black,
            white.max(black),
            balance,
        )?;
        if aug.marker_motion_blur_probability > 0.0
            && rng.random_bool(aug.marker_motion_blur_probability)
        {
            let length = rng.random_range(
                aug.motion_blur_length[0]
                    ..=aug.motion_blur_length[1].max(aug.motion_blur_length[0]),
            );
            let angle = draw(&mut rng, aug.motion_blur_angle_deg).to_radians();
            let m = length as f64;
            augment::motion_blur_region(
                &mut canvas,
                [region[0] - m, region[1] - m, region[2] + m, region[3] + m],
                length,
                angle,
            );
            applied.marker_motion_blur.push((*id, length, angle));
        }
    }
    if rng.random_bool(aug.spotlight_probability) {
        let gain = draw(&mut rng, aug.spotlight_gain);
        augment::spotlight(&mut canvas, &mut rng, gain);
        applied.spotlight_gain = Some(gain);
    }
    applied.blur_sigma = draw(&mut rng, aug.blur_sigma);
    augment::gaussian_blur(&mut canvas, applied.blur_sigma);
    if rng.random_bool(aug.motion_blur_probability) {
        let length = rng.random_range(
            aug.motion_blur_length[0]..=aug.motion_blur_length[1].max(aug.motion_blur_length[0]),
        );
        let angle = draw(&mut rng, aug.motion_blur_angle_deg).to_radians();
        augment::motion_blur(&mut canvas, length, angle);
        applied.motion_blur = Some((length, angle));
    }
    // Barrel distortion moves pixels; the ground truth goes through the same model below.
    let mut lens = camera;
    if config.mode != Mode::Patch && rng.random_bool(aug.barrel_probability) {
        let k1 = rng.random_range(aug.barrel_k1[0]..=aug.barrel_k1[1]);
        lens.distortion[0] = k1;
        canvas = distort_canvas(&canvas, &lens);
        applied.barrel_k1 = Some(k1);
    }
    // A shared scene's noise has a stream of its own too: whether a motion blur was drawn (a
    // swept value) must not change the noise of the scene.
    let mut shared_noise = config.shared_scene.then(|| stream(3));
    applied.noise_sigma = draw(shared_noise.as_mut().unwrap_or(&mut rng), aug.noise_sigma);
    let mut noise_rng = config
        .noise_seed
        .map(ChaCha8Rng::seed_from_u64)
        .or(shared_noise);
    augment::noise(
        &mut canvas,
        noise_rng.as_mut().unwrap_or(&mut rng),
        applied.noise_sigma,
    );

    let to_pixel = |p: [f64; 2]| distort_point(&lens, p);
    let markers = placed
        .iter()
        .map(|(id, placement, _, f)| {
            let mut truth = marker_truth(f, *id, placement, &to_pixel, config);
            if families.len() > 1 {
                truth.family = Some(f.name().to_string());
            }
            truth
        })
        .collect();
    Ok(Sample {
        image: canvas.to_gray(),
        truth: Truth {
            family: family.name().to_string(),
            mode: config.mode,
            seed,
            width: config.width,
            height: config.height,
            markers,
            applied,
            camera: (config.mode == Mode::Camera).then_some(lens),
        },
    })
}

fn roi4(family: &Family) -> Vec<[f64; 2]> {
    family.roi_points()[..4].to_vec()
}

fn place_quad(
    family: &Family,
    rng: &mut ChaCha8Rng,
    c: &SynthConfig,
) -> Result<Placement, GeometryError> {
    let (w, h) = (c.width as f64, c.height as f64);
    let [lo, hi] = c.quad_side;
    let side = if hi > lo {
        rng.random_range(lo..hi)
    } else {
        lo
    } * w.min(h);
    let (cx, cy) = (rng.random_range(0.0..w), rng.random_range(0.0..h));
    let angle = rng.random_range(0.0..std::f64::consts::TAU);
    let (s, co) = angle.sin_cos();
    let quad: Vec<[f64; 2]> = [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]
        .iter()
        .map(|p| {
            let (jx, jy) = (rng.random_range(-0.15..0.15), rng.random_range(-0.15..0.15));
            let (x, y) = ((p[0] + jx) * side, (p[1] + jy) * side);
            [cx + co * x - s * y, cy + s * x + co * y]
        })
        .collect();
    let to_image = Homography::from_points(&roi4(family), &quad)?;
    Ok(Placement {
        to_image,
        roi_to_image: None,
        pose: None,
    })
}

fn place_patch(
    family: &Family,
    rng: &mut ChaCha8Rng,
    c: &SynthConfig,
) -> Result<Placement, GeometryError> {
    // The ROI's corners land within a seventh of the template's side of the template's own
    // corners: a ROI of a family with a wide margin (data cells outside it) jitters less, so
    // that its drawing stays in the patch.
    let margin = family.spec().roi.margin;
    let jitter = (1.0 - 2.0 * margin) / 7.0;
    let mut a = [0.0; 8];
    a.iter_mut()
        .for_each(|v| *v = rng.random_range(margin - jitter..margin + jitter));
    let (w, h) = (c.width as f64, c.height as f64);
    let quad = [
        [a[0] * w, a[1] * h],
        [(1.0 - a[2]) * w, a[3] * h],
        [(1.0 - a[4]) * w, (1.0 - a[5]) * h],
        [a[6] * w, (1.0 - a[7]) * h],
    ];
    let to_image = Homography::from_points(&roi4(family), &quad)?;
    let turn = ring_turn(family, rng);
    Ok(Placement {
        to_image: Homography(to_image.0 * turn),
        roi_to_image: (turn != nalgebra::Matrix3::identity()).then_some(to_image),
        pose: None,
    })
}

/// A turn of a cyclic ring marker about its centre, anywhere round the circle (identity for
/// other families, which draw no random number for it). The ring search finds a ring's ROI from
/// its ellipse at whatever turn, so the patch shows the marker, its paper and its code turned
/// within a ROI that stays on the template's corners; a network shown only upright rings misses
/// most of their dots once they are turned by an eighth.
pub(crate) fn ring_turn(family: &Family, rng: &mut ChaCha8Rng) -> nalgebra::Matrix3<f64> {
    if !family.is_cyclic_ring() {
        return nalgebra::Matrix3::identity();
    }
    let (s, c) = rng
        .random_range(-std::f64::consts::PI..std::f64::consts::PI)
        .sin_cos();
    nalgebra::Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

fn place_camera(
    family: &Family,
    rng: &mut ChaCha8Rng,
    c: &SynthConfig,
    camera: &Camera,
) -> Result<Placement, GeometryError> {
    let side = rng.random_range(c.side_m[0]..=c.side_m[1]);
    let distance = rng.random_range(c.distance_m[0]..=c.distance_m[1]);
    let view = rng
        .random_range(c.view_angle_deg[0]..=c.view_angle_deg[1])
        .to_radians();
    let pose = random_pose(rng, camera, distance, view);
    Ok(Placement {
        to_image: camera_homography(family, camera, &pose, side),
        roi_to_image: None,
        pose: Some((pose, side)),
    })
}

/// A marker at `distance` metres, turned `view` radians away from facing the camera, spun
/// in-plane at random, somewhere in the field of view. The turn is measured from the optical
/// axis; off the image centre the line of sight is up to ~25° from it, and a marker turned 75°
/// away from the axis towards the image's edge would show the camera its back (drawn mirrored: no
/// camera sees a printed marker so). Such a turn is drawn again about another axis, until the
/// marker is within [`MAX_LINE_OF_SIGHT_DEG`] of its line of sight; poses that face the camera
/// are drawn exactly as before.
pub fn random_pose(rng: &mut ChaCha8Rng, camera: &Camera, distance: f64, view: f64) -> Pose {
    let facing = Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let tilt_about = |axis: f64| Rotation3::new(Vector3::new(axis.cos(), axis.sin(), 0.0) * view);
    let tilt = tilt_about(rng.random_range(0.0..std::f64::consts::TAU));
    let spin = Rotation3::from_axis_angle(
        &Vector3::z_axis(),
        rng.random_range(0.0..std::f64::consts::TAU),
    );
    // A direction within the central 60 % of the image.
    let (u, v) = (
        rng.random_range(0.2..0.8) * camera.width as f64,
        rng.random_range(0.2..0.8) * camera.height as f64,
    );
    let ray = Vector3::new(
        (u - camera.cx) / camera.fx,
        (v - camera.cy) / camera.fy,
        1.0,
    )
    .normalize();
    let mut rotation = tilt * facing * spin;
    // The printed side's normal against the direction back to the camera.
    let min_cos = MAX_LINE_OF_SIGHT_DEG.to_radians().cos();
    for _ in 0..64 {
        if -(rotation * Vector3::z()).dot(&ray) >= min_cos {
            break;
        }
        rotation = tilt_about(rng.random_range(0.0..std::f64::consts::TAU)) * facing * spin;
    }
    Pose {
        rotation,
        translation: ray * distance,
    }
}

/// The furthest a synthesised marker is turned from its line of sight, in degrees: beyond it a
/// marker is a line a few pixels wide (and past 90° its back).
pub const MAX_LINE_OF_SIGHT_DEG: f64 = 85.0;

/// Marker units → undistorted pixels for a marker `side_m` metres wide at `pose`: K · [r1 r2 t]
/// composed with the marker-unit → metric plane map.
pub fn camera_homography(family: &Family, camera: &Camera, pose: &Pose, side_m: f64) -> Homography {
    let k = Matrix3::new(
        camera.fx, 0.0, camera.cx, 0.0, camera.fy, camera.cy, 0.0, 0.0, 1.0,
    );
    let r = pose.rotation.matrix();
    let plane = Matrix3::from_columns(&[
        r.column(0).into_owned(),
        r.column(1).into_owned(),
        pose.translation,
    ]);
    // Marker units → plane metres, from three reference points of the affine map.
    let refs = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
    let m = marker_plane_points(family, side_m, &refs);
    let a = Matrix3::new(
        m[1][0] - m[0][0],
        m[2][0] - m[0][0],
        m[0][0],
        m[1][1] - m[0][1],
        m[2][1] - m[0][1],
        m[0][1],
        0.0,
        0.0,
        1.0,
    );
    Homography(k * plane * a)
}

/// The marker's drawn area (quiet zone excluded) as a polygon, 8 points per side so that it
/// bends with lens distortion.
fn outline_units(family: &Family) -> Vec<[f64; 2]> {
    let e = family.extent();
    let corners = [
        [e.min[0], e.min[1]],
        [e.max[0], e.min[1]],
        [e.max[0], e.max[1]],
        [e.min[0], e.max[1]],
    ];
    (0..4)
        .flat_map(|i| {
            let (a, b) = (corners[i], corners[(i + 1) % 4]);
            (0..8).map(move |k| {
                let t = k as f64 / 8.0;
                [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]
            })
        })
        .collect()
}

fn project_outline(family: &Family, h: &Homography) -> Vec<[f64; 2]> {
    outline_units(family).iter().map(|&p| h.apply(p)).collect()
}

/// Draws a marker (quiet zone included) through `to_image`, its black at `black` and white at
/// `white`, from a raster at about the on-image resolution.
#[allow(clippy::too_many_arguments)]
fn draw_marker(
    canvas: &mut Canvas,
    family: &Family,
    id: usize,
    to_image: &Homography,
    black: f32,
    white: f32,
    balance: [f32; 3],
) -> Result<(), SynthError> {
    let scene = marker_scene(
        family,
        id,
        SceneOptions {
            side_mm: Some(family.roi_side()),
            quiet_zone: None,
        },
    )?;
    // scene mm == marker units here (scale 1); area with quiet zone in marker units:
    let area = family.extent().grow(family.quiet_zone());
    let corners = [
        [area.min[0], area.min[1]],
        [area.max[0], area.min[1]],
        [area.max[0], area.max[1]],
        [area.min[0], area.max[1]],
    ];
    let img: Vec<[f64; 2]> = corners.iter().map(|&p| to_image.apply(p)).collect();
    let longest = (0..4)
        .map(|i| (img[i][0] - img[(i + 1) % 4][0]).hypot(img[i][1] - img[(i + 1) % 4][1]))
        .fold(0.0, f64::max);
    // A whole number of raster pixels per marker unit: the rasteriser places edges to a quarter
    // of its pixel, so cell edges off the pixel grid moved by up to ⅛ raster pixel — on both
    // sides of the marker the same way at a given scale, which made every rendered marker a
    // little smaller or larger than its ground truth (0.1 px at 50 cm).
    let px_per_unit = (1.25 * longest / area.width().max(area.height()))
        .ceil()
        .clamp(2.0, (4096.0 / area.width().max(area.height())).floor());
    let pixmap = raster::rasterize(&scene, px_per_unit)?;
    let (pw, ph) = (pixmap.width() as usize, pixmap.height() as usize);
    let (scale_x, scale_y) = (pw as f64 / area.width(), ph as f64 / area.height());
    // Luminance of the white-balanced colours (Rec. 709), clamped to the paper's white.
    let gray: Vec<f32> = pixmap
        .pixels()
        .iter()
        .map(|p| {
            let (r, g, b) = (
                p.red() as f32 * balance[0],
                p.green() as f32 * balance[1],
                p.blue() as f32 * balance[2],
            );
            (crate::image::luminance(r, g, b) / 255.0).min(1.0)
        })
        .collect();
    let from_image = to_image
        .inverse()
        .ok_or(SynthError::DegeneratePlacement { id })?;
    let b = bounding_box(&img);
    let (x0, y0) = (b[0].floor().max(0.0) as u32, b[1].floor().max(0.0) as u32);
    let (x1, y1) = (
        (b[2].ceil() as i64).min(canvas.width as i64 - 1),
        (b[3].ceil() as i64).min(canvas.height as i64 - 1),
    );
    for y in y0 as i64..=y1 {
        for x in x0 as i64..=x1 {
            let p = from_image.apply([x as f64, y as f64]);
            if p[0] < area.min[0] || p[1] < area.min[1] || p[0] > area.max[0] || p[1] > area.max[1]
            {
                continue;
            }
            // Raster pixel centres sit at +0.5; the raster's size was rounded to whole pixels, so
            // its true scale is its size over the area's.
            let rx = ((p[0] - area.min[0]) * scale_x - 0.5) as f32;
            let ry = ((p[1] - area.min[1]) * scale_y - 0.5) as f32;
            let v = crate::image::bilinear(pw as u32, ph as u32, rx, ry, |i| gray[i]);
            canvas.set(x as u32, y as u32, black + (white - black) * v);
        }
    }
    Ok(())
}

/// Undistorted pixel → distorted pixel through the lens model.
fn distort_point(lens: &Camera, p: [f64; 2]) -> [f64; 2] {
    if lens.distortion == [0.0; 5] {
        return p;
    }
    let d = lens.distort([(p[0] - lens.cx) / lens.fx, (p[1] - lens.cy) / lens.fy]);
    [lens.fx * d[0] + lens.cx, lens.fy * d[1] + lens.cy]
}

/// Each output (distorted) pixel takes the undistorted image where the lens model says it comes
/// from.
fn distort_canvas(src: &Canvas, lens: &Camera) -> Canvas {
    let mut out = Canvas::new(src.width, src.height, 0.0);
    for y in 0..src.height {
        for x in 0..src.width {
            let n = lens.normalise([x as f64, y as f64]);
            let (u, v) = (lens.fx * n[0] + lens.cx, lens.fy * n[1] + lens.cy);
            out.set(x, y, src.sample(u as f32, v as f32));
        }
    }
    out
}

fn marker_truth(
    family: &Family,
    id: usize,
    placement: &Placement,
    to_pixel: &dyn Fn([f64; 2]) -> [f64; 2],
    c: &SynthConfig,
) -> MarkerTruth {
    let project = |p: [f64; 2]| to_pixel(placement.to_image.apply(p));
    let categories = family
        .keypoint_categories(id)
        .expect("IDs are drawn from the codebook");
    let keypoints = family
        .keypoints()
        .iter()
        .zip(categories)
        .map(|(k, category)| {
            let [x, y] = project(k.pos);
            KeypointTruth {
                x,
                y,
                category,
                symbol: family
                    .category_symbol(category)
                    .filter(|_| matches!(k.assignment, crate::family::Assignment::Symbol(_))),
                visible: x >= 0.0
                    && y >= 0.0
                    && x <= c.width as f64 - 1.0
                    && y <= c.height as f64 - 1.0,
            }
        })
        .collect();
    let mask: Vec<[f64; 2]> = outline_units(family).into_iter().map(project).collect();
    MarkerTruth {
        id,
        family: None,
        bbox: bounding_box(&mask),
        roi: family
            .roi_points()
            .iter()
            .map(|&p| to_pixel(placement.roi_map().apply(p)))
            .collect(),
        keypoints,
        mask,
        pose: placement.pose.map(|(pose, side_m)| PoseTruth {
            pose: PoseJson::from(&pose),
            side_m,
        }),
    }
}

#[cfg(test)]
mod tests;
