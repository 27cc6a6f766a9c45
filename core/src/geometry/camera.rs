//! Pinhole camera with OpenCV's radial–tangential distortion (k1, k2, p1, p2, k3), so that
//! calibrations from OpenCV import as they are. Pixel coordinates follow OpenCV: the centre of the
//! top-left pixel is (0, 0).

use super::GeometryError;
use serde::{Deserialize, Serialize};

/// An OpenCV calibration file that does not give a camera; each names the key or value that
/// failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrationError {
    #[error("no {key} in the file")]
    MissingKey { key: &'static str },
    #[error("{key} has no data: [ ... ]")]
    NoData { key: &'static str },
    #[error("{key}: unterminated data")]
    Unterminated { key: &'static str },
    #[error("{key}: {value:?} is not a number")]
    NotANumber { key: &'static str, value: String },
    #[error("camera_matrix has {values} values, expected 9")]
    MatrixSize { values: usize },
    #[error(
        "distortion_coefficients has {terms} terms; only OpenCV's first five (k1, k2, p1, p2, k3) are modelled"
    )]
    DistortionTerms { terms: usize },
    #[error("the file has no image_width/image_height; give the image size")]
    NoImageSize,
    #[error(transparent)]
    Invalid(#[from] GeometryError),
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// OpenCV order: k1, k2, p1, p2, k3.
    #[serde(default)]
    pub distortion: [f64; 5],
}

impl Camera {
    /// A distortion-free guess from the image size and the diagonal field of view, principal point
    /// at the image centre (the paper's benchmark camera: 1280×960, 98°).
    pub fn from_diagonal_fov(width: u32, height: u32, fov_deg: f64) -> Result<Self, GeometryError> {
        if width == 0 || height == 0 {
            return Err(GeometryError::BadCamera("the image size must be positive"));
        }
        if !(fov_deg.is_finite() && fov_deg > 0.0 && fov_deg < 180.0) {
            return Err(GeometryError::BadCamera(
                "the field of view must be between 0° and 180°",
            ));
        }
        let diagonal = (width as f64).hypot(height as f64);
        let f = diagonal / 2.0 / (fov_deg.to_radians() / 2.0).tan();
        Ok(Self {
            width,
            height,
            fx: f,
            fy: f,
            cx: (width as f64 - 1.0) / 2.0,
            cy: (height as f64 - 1.0) / 2.0,
            distortion: [0.0; 5],
        })
    }

    /// Reads an OpenCV calibration file (`cv::FileStorage` YAML with `camera_matrix` and
    /// `distortion_coefficients`, as written by OpenCV's calibration tools). The image size comes
    /// from `image_width`/`image_height`, or from `size` when the file has none.
    pub fn from_opencv_yaml(
        text: &str,
        size: Option<(u32, u32)>,
    ) -> Result<Self, CalibrationError> {
        let k = opencv_matrix(text, "camera_matrix")?;
        if k.len() != 9 {
            return Err(CalibrationError::MatrixSize { values: k.len() });
        }
        let d = opencv_matrix(text, "distortion_coefficients").unwrap_or_default();
        if d.len() > 5 && d[5..].iter().any(|&v| v != 0.0) {
            return Err(CalibrationError::DistortionTerms { terms: d.len() });
        }
        let mut distortion = [0.0; 5];
        for (slot, v) in distortion.iter_mut().zip(&d) {
            *slot = *v;
        }
        let scalar = |key: &str| {
            text.lines().find_map(|l| {
                l.trim()
                    .strip_prefix(key)?
                    .strip_prefix(':')?
                    .trim()
                    .parse::<u32>()
                    .ok()
            })
        };
        let (width, height) = match (scalar("image_width"), scalar("image_height"), size) {
            (Some(w), Some(h), _) => (w, h),
            (_, _, Some(s)) => s,
            _ => return Err(CalibrationError::NoImageSize),
        };
        let camera = Self {
            width,
            height,
            fx: k[0],
            fy: k[4],
            cx: k[2],
            cy: k[5],
            distortion,
        };
        camera.validate()?;
        Ok(camera)
    }

    pub fn validate(&self) -> Result<(), GeometryError> {
        let finite = [self.fx, self.fy, self.cx, self.cy]
            .iter()
            .chain(&self.distortion)
            .all(|v| v.is_finite());
        if !finite {
            return Err(GeometryError::BadCamera(
                "a parameter is not a finite number",
            ));
        }
        if !(self.fx > 0.0 && self.fy > 0.0) {
            return Err(GeometryError::BadCamera("focal lengths must be positive"));
        }
        Ok(())
    }

    /// Applies the distortion to normalised image coordinates (x/z, y/z).
    pub fn distort(&self, p: [f64; 2]) -> [f64; 2] {
        let [k1, k2, p1, p2, k3] = self.distortion;
        let [x, y] = p;
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        [
            x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
        ]
    }

    /// Camera-frame point (metres, z forward) → pixel.
    pub fn project(&self, p: [f64; 3]) -> [f64; 2] {
        let d = self.distort([p[0] / p[2], p[1] / p[2]]);
        [self.fx * d[0] + self.cx, self.fy * d[1] + self.cy]
    }

    /// Pixel → undistorted normalised coordinates, by fixed-point iteration on the distortion
    /// model (as OpenCV's `undistortPoints`), refined until it reprojects to 1e-12.
    pub fn normalise(&self, pixel: [f64; 2]) -> [f64; 2] {
        let target = [
            (pixel[0] - self.cx) / self.fx,
            (pixel[1] - self.cy) / self.fy,
        ];
        if self.distortion == [0.0; 5] {
            return target;
        }
        let mut p = target;
        for _ in 0..50 {
            let d = self.distort(p);
            let err = [d[0] - target[0], d[1] - target[1]];
            p = [p[0] - err[0], p[1] - err[1]];
            if err[0].abs().max(err[1].abs()) < 1e-12 {
                break;
            }
        }
        p
    }
}

/// The `data: [...]` numbers of an `!!opencv-matrix` entry.
fn opencv_matrix(text: &str, key: &'static str) -> Result<Vec<f64>, CalibrationError> {
    let start = text
        .find(&format!("{key}:"))
        .ok_or(CalibrationError::MissingKey { key })?;
    let rest = &text[start..];
    let open = rest
        .find("data:")
        .and_then(|d| rest[d..].find('[').map(|b| d + b + 1));
    let open = open.ok_or(CalibrationError::NoData { key })?;
    let close = rest[open..]
        .find(']')
        .ok_or(CalibrationError::Unterminated { key })?
        + open;
    rest[open..close]
        .split(',')
        .map(|v| {
            v.trim()
                .parse::<f64>()
                .map_err(|_| CalibrationError::NotANumber {
                    key,
                    value: v.trim().into(),
                })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shared(file: &str) -> String {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../shared/realimages/opencv_aruco_tutorial")
            .join(file);
        std::fs::read_to_string(path).unwrap()
    }

    /// Projections of three points through the calibration in `tutorial_camera_charuco.yml`
    /// (k3 = 2.95, a strong model), computed by OpenCV 5.0.0's `cv2.projectPoints`.
    #[test]
    fn opencv_calibrations_import_and_project_as_opencv_does() {
        let c = Camera::from_opencv_yaml(&shared("tutorial_camera_charuco.yml"), None).unwrap();
        assert_eq!((c.width, c.height), (640, 480));
        assert!(
            (c.fx - 452.510_722_196_376_7).abs() < 1e-9
                && (c.distortion[4] - 2.954_258_940_681_008).abs() < 1e-12
        );
        let expected = [
            ([0.1, -0.05, 1.0], [363.0079490373761, 254.88535279421745]),
            ([-0.3, 0.2, 0.8], [147.11504559528254, 392.52888892800337]),
            ([0.25, 0.18, 0.6], [508.1486926268699, 416.21652955575263]),
        ];
        for (p, q) in expected {
            let ours = c.project(p);
            assert!(
                (ours[0] - q[0]).abs() < 1e-6 && (ours[1] - q[1]).abs() < 1e-6,
                "{ours:?} vs {q:?}"
            );
        }
        // A file without the image size needs it from the caller.
        let params = shared("tutorial_camera_params.yml");
        let e = Camera::from_opencv_yaml(&params, None).unwrap_err();
        assert_eq!(e, CalibrationError::NoImageSize);
        assert!(e.to_string().contains("image size"));
        let c = Camera::from_opencv_yaml(&params, Some((640, 480))).unwrap();
        assert!((c.fy - 628.156).abs() < 1e-9 && (c.distortion[2] - 0.00754589).abs() < 1e-12);
        assert_eq!(
            Camera::from_opencv_yaml("nothing here", None),
            Err(CalibrationError::MissingKey {
                key: "camera_matrix"
            })
        );
        let bad = "camera_matrix: !!opencv-matrix\n  data: [ 1, x ]";
        assert_eq!(
            Camera::from_opencv_yaml(bad, None).unwrap_err().to_string(),
            "camera_matrix: \"x\" is not a number"
        );
    }

    #[test]
    fn the_papers_camera_has_the_right_focal_length() {
        let c = Camera::from_diagonal_fov(1280, 960, 98.0).unwrap();
        // half diagonal 800 px over tan(49°)
        assert!((c.fx - 800.0 / 49f64.to_radians().tan()).abs() < 1e-9);
        assert!(Camera::from_diagonal_fov(1280, 960, 180.0).is_err());
        assert!(Camera::from_diagonal_fov(0, 960, 90.0).is_err());
    }

    #[test]
    fn normalise_inverts_project_with_distortion() {
        let mut c = Camera::from_diagonal_fov(640, 480, 90.0).unwrap();
        c.distortion = [-0.28, 0.09, 0.001, -0.0005, -0.01];
        for p in [[0.1, -0.05, 1.0], [-0.3, 0.2, 0.8], [0.0, 0.0, 2.0]] {
            let px = c.project(p);
            let n = c.normalise(px);
            assert!(
                (n[0] - p[0] / p[2]).abs() < 1e-9 && (n[1] - p[1] / p[2]).abs() < 1e-9,
                "{n:?}"
            );
        }
    }
}
