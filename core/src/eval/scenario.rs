//! A scenario: the conditions of one user's scene (print size, camera, distances, angles, light,
//! blur, motion, noise, background), and which of them to sweep. It is saved as JSON beside the
//! user's families; `tagsmith eval generate --scenario` renders it as a benchmark set and the
//! design comparison ([`super::designs`]) renders the same scenes for every family.
//!
//! Each swept condition takes its listed values one at a time while the others are drawn from
//! their ranges; every value of one sweep sees the same scenes (poses, light, noise seeds), so a
//! curve's steps differ by the swept condition alone.

use super::set::Group;
use crate::geometry::Camera;
use crate::synth::augment::AugmentRanges;
use crate::synth::{image_seed, BackgroundKind, Mode, SynthConfig};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A condition a scenario can sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Condition {
    /// Camera to marker, metres.
    Distance,
    /// The marker turned away from the camera, degrees.
    Angle,
    /// Out-of-focus blur, Gaussian sigma in pixels.
    Blur,
    /// Motion blur, kernel length in pixels.
    Motion,
    /// Sensor noise, Gaussian sigma in gray levels.
    Noise,
    /// The light on the marker: the gray level its white shows (its black stays in range).
    Light,
}

impl Condition {
    pub const ALL: [Condition; 6] = [
        Condition::Distance,
        Condition::Angle,
        Condition::Blur,
        Condition::Motion,
        Condition::Noise,
        Condition::Light,
    ];

    /// The axis label of a plot against it.
    pub fn label(self) -> &'static str {
        match self {
            Condition::Distance => "distance (m)",
            Condition::Angle => "view angle (°)",
            Condition::Blur => "blur sigma (px)",
            Condition::Motion => "motion blur (px)",
            Condition::Noise => "noise sigma (gray levels)",
            Condition::Light => "marker white (gray level)",
        }
    }

    /// The JSON name, as in a scenario file and the CSV.
    pub fn name(self) -> &'static str {
        match self {
            Condition::Distance => "distance",
            Condition::Angle => "angle",
            Condition::Blur => "blur",
            Condition::Motion => "motion",
            Condition::Noise => "noise",
            Condition::Light => "light",
        }
    }

    /// The values a scenario may give it (inclusive).
    fn limits(self) -> (f64, f64) {
        match self {
            Condition::Distance => (0.01, 100.0),
            Condition::Angle => (0.0, 85.0),
            Condition::Blur => (0.0, 20.0),
            Condition::Motion => (0.0, 60.0),
            Condition::Noise => (0.0, 300.0),
            Condition::Light => (1.0, 255.0),
        }
    }
}

/// One condition and the values it takes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sweep {
    pub condition: Condition,
    pub values: Vec<f64>,
}

/// The camera: its image size and either its focal length in pixels or its diagonal field of
/// view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioCamera {
    pub width: u32,
    pub height: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub focal_px: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov_deg: Option<f64>,
}

impl ScenarioCamera {
    fn diagonal_fov_deg(&self) -> f64 {
        match (self.focal_px, self.fov_deg) {
            (Some(f), _) => {
                let diagonal = (self.width as f64).hypot(self.height as f64);
                2.0 * (diagonal / 2.0 / f).atan().to_degrees()
            }
            (None, Some(fov)) => fov,
            (None, None) => f64::NAN,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// What the user calls the scene (tables and plots carry it).
    pub name: String,
    /// The printed marker's side (its outer black square), mm.
    pub side_mm: f64,
    pub camera: ScenarioCamera,
    /// Camera to marker, metres.
    pub distance_m: [f64; 2],
    /// The marker turned away from the camera, degrees.
    pub angle_deg: [f64; 2],
    /// Gray levels (0–255) the marker's black and white show: the light on it.
    pub black_level: [f64; 2],
    pub white_level: [f64; 2],
    /// Out-of-focus blur (Gaussian sigma, px).
    pub blur_px: [f64; 2],
    /// Motion blur kernel length (px; under 2 is still).
    pub motion_px: [f64; 2],
    /// Sensor noise (Gaussian sigma, gray levels).
    pub noise_sigma: [f64; 2],
    pub background: BackgroundKind,
    pub markers_per_image: u32,
    /// Conditions swept one at a time; empty renders `scenes` scenes from the ranges.
    #[serde(default)]
    pub sweeps: Vec<Sweep>,
    /// Scenes per swept value (per scenario without sweeps).
    pub scenes: u32,
    pub seed: u64,
}

/// A scenario value out of range, named by its JSON path.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {message}")]
pub struct BadField {
    pub field: String,
    pub message: String,
}

fn bad(field: impl Into<String>, message: impl Into<String>) -> BadField {
    BadField {
        field: field.into(),
        message: message.into(),
    }
}

/// The most scenes one scenario may render (per family).
pub const MAX_SCENES: u64 = super::set::MAX_SET_IMAGES;

/// The nearest a marker may be, in print sizes: nearer, a turned marker's far corners pass
/// behind the camera and its outline folds.
pub const NEAREST_SIDES: f64 = 1.5;

fn near_message(distance_m: f64, nearest_m: f64) -> String {
    format!(
        "{distance_m} m is nearer than {nearest_m} m, {NEAREST_SIDES}× the print size: a turned \
         marker that near passes behind the camera"
    )
}

/// One scene of a scenario: its group (the swept value), how it renders and its seed.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub group: Group,
    pub config: SynthConfig,
    pub seed: u64,
}

impl Scenario {
    /// The paper's XO study as a scenario: a 5 cm marker on the benchmark camera (1280×960,
    /// 98° diagonal) at `distance_m`, turned 0–60°, swept over blur and angle.
    pub fn example(distance_m: f64) -> Self {
        Self {
            name: format!("paper camera at {:.0} cm", distance_m * 100.0),
            side_mm: 50.0,
            camera: ScenarioCamera {
                width: 1280,
                height: 960,
                focal_px: None,
                fov_deg: Some(98.0),
            },
            distance_m: [distance_m, distance_m],
            angle_deg: [0.0, 60.0],
            black_level: [20.0, 40.0],
            white_level: [200.0, 235.0],
            blur_px: [0.0, 0.5],
            motion_px: [0.0, 0.0],
            noise_sigma: [2.0, 2.0],
            background: BackgroundKind::Clutter,
            markers_per_image: 1,
            sweeps: vec![Sweep {
                condition: Condition::Angle,
                values: vec![0.0, 20.0, 40.0, 60.0, 75.0],
            }],
            scenes: 20,
            seed: 0,
        }
    }

    /// Every value checked, the first one out of range named by its JSON path.
    pub fn validate(&self) -> Result<(), BadField> {
        let range = |field: &str, r: [f64; 2], lo: f64, hi: f64| -> Result<(), BadField> {
            if !(r.iter().all(|v| v.is_finite() && (lo..=hi).contains(v))) {
                return Err(bad(
                    field,
                    format!("{r:?}: each end must be in [{lo}, {hi}]"),
                ));
            }
            if r[0] > r[1] {
                return Err(bad(
                    field,
                    format!("{r:?}: the first end is above the second"),
                ));
            }
            Ok(())
        };
        if self.name.trim().is_empty() {
            return Err(bad("name", "is empty; name the scene"));
        }
        if !(self.side_mm.is_finite() && (1.0..=1000.0).contains(&self.side_mm)) {
            return Err(bad(
                "side_mm",
                format!("{} must be in [1, 1000]", self.side_mm),
            ));
        }
        let c = &self.camera;
        for (field, v) in [("camera.width", c.width), ("camera.height", c.height)] {
            if !(16..=8192).contains(&v) {
                return Err(bad(field, format!("{v} must be in [16, 8192]")));
            }
        }
        match (c.focal_px, c.fov_deg) {
            (Some(_), Some(_)) | (None, None) => {
                return Err(bad("camera", "give one of focal_px or fov_deg"));
            }
            (Some(f), None) if !(f.is_finite() && f > 0.0 && f <= 1e6) => {
                return Err(bad("camera.focal_px", format!("{f} must be in (0, 1e6]")));
            }
            (Some(f), None) if !(1.0..179.0).contains(&c.diagonal_fov_deg()) => {
                return Err(bad(
                    "camera.focal_px",
                    format!(
                        "{f} px gives a {:.1}° diagonal field of view at {}×{}; it must be in (1, 179)",
                        c.diagonal_fov_deg(),
                        c.width,
                        c.height
                    ),
                ));
            }
            (None, Some(fov)) if !(fov.is_finite() && fov > 1.0 && fov < 179.0) => {
                return Err(bad("camera.fov_deg", format!("{fov} must be in (1, 179)")));
            }
            _ => {}
        }
        let limits = |c: Condition| c.limits();
        let (d, a, l) = (
            limits(Condition::Distance),
            limits(Condition::Angle),
            limits(Condition::Light),
        );
        range("distance_m", self.distance_m, d.0, d.1)?;
        let nearest = NEAREST_SIDES * self.side_mm / 1000.0;
        let too_near = |v: f64| v < nearest;
        if too_near(self.distance_m[0]) {
            return Err(bad("distance_m", near_message(self.distance_m[0], nearest)));
        }
        range("angle_deg", self.angle_deg, a.0, a.1)?;
        range("black_level", self.black_level, 0.0, 255.0)?;
        range("white_level", self.white_level, l.0, l.1)?;
        if self.white_level[0] <= self.black_level[1] {
            return Err(bad(
                "white_level",
                format!(
                    "{:?} must lie above black_level {:?}: a marker needs contrast",
                    self.white_level, self.black_level
                ),
            ));
        }
        let b = limits(Condition::Blur);
        range("blur_px", self.blur_px, b.0, b.1)?;
        let m = limits(Condition::Motion);
        range("motion_px", self.motion_px, m.0, m.1)?;
        let n = limits(Condition::Noise);
        range("noise_sigma", self.noise_sigma, n.0, n.1)?;
        if !(1..=20).contains(&self.markers_per_image) {
            return Err(bad(
                "markers_per_image",
                format!("{} must be in [1, 20]", self.markers_per_image),
            ));
        }
        if self.scenes == 0 {
            return Err(bad("scenes", "must be at least 1"));
        }
        let mut seen = Vec::new();
        for (i, s) in self.sweeps.iter().enumerate() {
            if seen.contains(&s.condition) {
                return Err(bad(
                    format!("sweeps[{i}].condition"),
                    format!("{} is swept twice", s.condition.name()),
                ));
            }
            seen.push(s.condition);
            if s.values.is_empty() || s.values.len() > 50 {
                return Err(bad(
                    format!("sweeps[{i}].values"),
                    format!("{} values; give 1 to 50", s.values.len()),
                ));
            }
            let (lo, hi) = s.condition.limits();
            for (k, v) in s.values.iter().enumerate() {
                if !(v.is_finite() && (lo..=hi).contains(v)) {
                    return Err(bad(
                        format!("sweeps[{i}].values[{k}]"),
                        format!("{v} must be in [{lo}, {hi}] for {}", s.condition.name()),
                    ));
                }
                if s.values[..k].contains(v) {
                    return Err(bad(
                        format!("sweeps[{i}].values[{k}]"),
                        format!("{v} is listed twice"),
                    ));
                }
                if s.condition == Condition::Distance && too_near(*v) {
                    return Err(bad(
                        format!("sweeps[{i}].values[{k}]"),
                        near_message(*v, nearest),
                    ));
                }
                if s.condition == Condition::Light && *v <= self.black_level[1] {
                    return Err(bad(
                        format!("sweeps[{i}].values[{k}]"),
                        format!("{v} must lie above black_level {:?}", self.black_level),
                    ));
                }
            }
        }
        let total = self.scene_count();
        if total > MAX_SCENES {
            return Err(bad(
                "scenes",
                format!("{total} scenes in all is more than {MAX_SCENES}; give fewer per value"),
            ));
        }
        Ok(())
    }

    /// Scenes per family: `scenes` per swept value, or `scenes` without sweeps.
    pub fn scene_count(&self) -> u64 {
        let values: u64 = self.sweeps.iter().map(|s| s.values.len() as u64).sum();
        self.scenes as u64 * values.max(1)
    }

    /// The camera scoring and pose use: a pinhole from the diagonal field of view.
    pub fn camera(&self) -> Camera {
        Camera::from_diagonal_fov(
            self.camera.width,
            self.camera.height,
            self.camera.diagonal_fov_deg(),
        )
        .expect("a validated scenario's camera is valid")
    }

    fn base_config(&self) -> SynthConfig {
        let mut c = SynthConfig::new(Mode::Camera);
        c.width = self.camera.width;
        c.height = self.camera.height;
        c.fov_deg = self.camera.diagonal_fov_deg();
        c.markers = [self.markers_per_image; 2];
        let side = self.side_mm / 1000.0;
        c.side_m = [side, side];
        c.distance_m = self.distance_m;
        c.view_angle_deg = self.angle_deg;
        let f = |r: [f64; 2]| [r[0] as f32, r[1] as f32];
        let mut a = AugmentRanges::none();
        a.marker_black = f(self.black_level);
        a.marker_white = f(self.white_level);
        a.blur_sigma = f(self.blur_px);
        a.noise_sigma = f(self.noise_sigma);
        set_motion(&mut a, self.motion_px);
        c.augment = a;
        c.shared_scene = true;
        c.background = self.background;
        c
    }

    /// Every scene, sweep by sweep and value by value. A validated scenario's scenes render.
    pub fn scenes(&self) -> Vec<Scene> {
        let base = self.base_config();
        let mut out = Vec::new();
        if self.sweeps.is_empty() {
            for k in 0..self.scenes {
                out.push(Scene {
                    group: Group::Scenario {
                        condition: None,
                        value: 0.0,
                    },
                    config: base.clone(),
                    seed: image_seed(self.seed, k as u64),
                });
            }
        }
        for (i, sweep) in self.sweeps.iter().enumerate() {
            // One stream of scenes per sweep, the same for each of its values.
            let sweep_seed = image_seed(self.seed ^ 0x5_EE9, i as u64 + 1);
            // In ascending order, so rows and curves run along the axis.
            let mut values = sweep.values.clone();
            values.sort_by(f64::total_cmp);
            for value in values {
                let mut config = base.clone();
                apply(&mut config, sweep.condition, value);
                for k in 0..self.scenes {
                    out.push(Scene {
                        group: Group::Scenario {
                            condition: Some(sweep.condition),
                            value,
                        },
                        config: config.clone(),
                        seed: image_seed(sweep_seed, k as u64),
                    });
                }
            }
        }
        out
    }

    /// Reads and checks a scenario file (a regular file of at most [`crate::io::MAX_TEXT_BYTES`]);
    /// errors name the file and the field.
    pub fn load(path: &Path) -> Result<Self, super::EvalError> {
        let text =
            crate::io::read_input_text(path, crate::io::MAX_TEXT_BYTES).map_err(|source| {
                super::EvalError::Read {
                    path: path.to_path_buf(),
                    source,
                }
            })?;
        let de = &mut serde_json::Deserializer::from_str(&text);
        let scenario: Scenario =
            serde_path_to_error::deserialize(de).map_err(|e| super::EvalError::BadScenario {
                path: path.to_path_buf(),
                field: e.path().to_string(),
                message: e.inner().to_string(),
            })?;
        scenario
            .validate()
            .map_err(|e| super::EvalError::BadScenario {
                path: path.to_path_buf(),
                field: e.field,
                message: e.message,
            })?;
        Ok(scenario)
    }

    /// Writes the scenario as pretty JSON, atomically.
    pub fn save(&self, path: &Path) -> Result<(), super::EvalError> {
        let json = serde_json::to_string_pretty(self).expect("a scenario serialises");
        crate::io::write_atomic(path, json.as_bytes()).map_err(|source| super::EvalError::Write {
            path: path.to_path_buf(),
            source,
        })
    }
}

fn set_motion(a: &mut AugmentRanges, px: [f64; 2]) {
    if px[1] < 2.0 {
        a.motion_blur_probability = 0.0;
        return;
    }
    a.motion_blur_probability = 1.0;
    a.motion_blur_length = [px[0].round() as u32, px[1].round() as u32];
}

/// Fixes one condition at `value` in a scene's configuration.
fn apply(c: &mut SynthConfig, condition: Condition, value: f64) {
    let point = [value as f32, value as f32];
    match condition {
        Condition::Distance => c.distance_m = [value, value],
        Condition::Angle => c.view_angle_deg = [value, value],
        Condition::Blur => c.augment.blur_sigma = point,
        Condition::Motion => set_motion(&mut c.augment, [value, value]),
        Condition::Noise => c.augment.noise_sigma = point,
        Condition::Light => c.augment.marker_white = point,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scenario_round_trips_through_its_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("warehouse.json");
        let mut s = Scenario::example(0.3);
        s.camera = ScenarioCamera {
            width: 640,
            height: 480,
            focal_px: Some(600.0),
            fov_deg: None,
        };
        s.background = BackgroundKind::Plain;
        s.save(&path).unwrap();
        assert_eq!(Scenario::load(&path).unwrap(), s);
    }

    #[test]
    fn bad_values_are_refused_with_the_field_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.json");
        type Spoil = fn(&mut serde_json::Value);
        let cases: [(&str, Spoil); 9] = [
            ("distance_m", |v| {
                v["distance_m"] = serde_json::json!([2.0, 1.0])
            }),
            ("camera", |v| {
                v["camera"]["focal_px"] = serde_json::json!(700.0)
            }),
            ("white_level", |v| {
                v["white_level"] = serde_json::json!([30.0, 40.0])
            }),
            ("sweeps[0].values[1]", |v| {
                v["sweeps"][0]["values"][1] = serde_json::json!(95.0)
            }),
            ("scenes", |v| v["scenes"] = serde_json::json!(0)),
            ("distance_m", |v| {
                v["distance_m"] = serde_json::json!([0.05, 0.3])
            }),
            ("sweeps[0].values[2]", |v| {
                v["sweeps"][0]["values"] = serde_json::json!([10.0, 20.0, 10.0])
            }),
            (
                "camera.focal_px",
                |v| {
                    v["camera"] = serde_json::json!({"width": 640, "height": 480, "focal_px": 1e-9})
                },
            ),
            ("sweeps[0].condition", |v| {
                v["sweeps"][0]["condition"] = serde_json::json!("zoom")
            }),
        ];
        for (field, spoil) in cases {
            let mut v = serde_json::to_value(Scenario::example(0.1)).unwrap();
            spoil(&mut v);
            std::fs::write(&path, v.to_string()).unwrap();
            let e = Scenario::load(&path).unwrap_err().to_string();
            assert!(
                e.starts_with(&format!("{}: {field}", path.display())),
                "{field}: {e}"
            );
        }
    }

    #[test]
    fn each_value_of_a_sweep_sees_the_same_scenes() {
        let s = Scenario::example(0.3);
        let scenes = s.scenes();
        assert_eq!(scenes.len() as u64, s.scene_count());
        let first: Vec<u64> = scenes[..20].iter().map(|s| s.seed).collect();
        let second: Vec<u64> = scenes[20..40].iter().map(|s| s.seed).collect();
        assert_eq!(first, second);
        assert_ne!(scenes[0].config, scenes[20].config);
        assert_eq!(scenes[20].config.view_angle_deg, [20.0, 20.0]);
    }
}
