//! The one error type of the commands, and the one place that decides its exit code.
//!
//! Core's typed errors convert with `?` (`From`), each classified once here; core's plain-message
//! errors and the CLI's own checks name their kind at the call site with [`Classify`] or
//! [`bad_input!`] / [`failure!`]. [`Concerning`] puts the option or file an error is about in
//! front of a typed error without changing its kind.

use std::fmt;
use tagsmith::codebook::GenerateError;
use tagsmith::detect::stage2::model_file::ModelError;
use tagsmith::eval::EvalError;
use tagsmith::geometry::{CalibrationError, GeometryError};
use tagsmith::image::{ImageError, ImageErrorKind};
use tagsmith::render::opencv::OpenCvError;
use tagsmith::render::sheet::SheetError;
use tagsmith::render::RenderError;
use tagsmith::synth::SynthError;
use tagsmith::FamilyError;

/// A command failure: bad input (exit 2) or a failure to produce output (exit 1).
#[derive(Debug)]
pub enum CliError {
    BadInput(anyhow::Error),
    Failed(anyhow::Error),
}

impl CliError {
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::BadInput(_) => 2,
            CliError::Failed(_) => 1,
        }
    }

    pub(crate) fn bad_input(e: impl fmt::Display) -> Self {
        CliError::BadInput(flatten(e))
    }

    pub(crate) fn failure(e: impl fmt::Display) -> Self {
        CliError::Failed(flatten(e))
    }

    /// An input that could not be read, its message led by `what`: bad input when the file is
    /// at fault (missing, not a regular file, too large; [`tagsmith::io::is_bad_input`]), a
    /// failure when the machine is.
    pub(crate) fn reading(what: impl fmt::Display, e: std::io::Error) -> Self {
        if tagsmith::io::is_bad_input(&e) {
            CliError::bad_input(format_args!("{what}: {e}"))
        } else {
            CliError::failure(format_args!("{what}: {e}"))
        }
    }

    /// The same kind of error, its message led by `what` (`--ids: …`, `camera.yml: …`).
    pub(crate) fn concerning(self, what: impl fmt::Display) -> Self {
        match self {
            CliError::BadInput(e) => CliError::bad_input(format_args!("{what}: {e:#}")),
            CliError::Failed(e) => CliError::failure(format_args!("{what}: {e:#}")),
        }
    }
}

/// The error as the one line it prints. Core's errors already write their causes (and the file
/// they concern) into their message; keeping them as a chain of sources as well made `{:#}`
/// print those causes twice.
fn flatten(e: impl fmt::Display) -> anyhow::Error {
    anyhow::Error::msg(format!("{e:#}"))
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CliError::BadInput(e) | CliError::Failed(e) => {
                if f.alternate() {
                    write!(f, "{e:#}")
                } else {
                    write!(f, "{e}")
                }
            }
        }
    }
}

/// A family that does not load is the user's family (or a built-in, which the tests keep valid).
impl From<FamilyError> for CliError {
    fn from(e: FamilyError) -> Self {
        CliError::bad_input(e)
    }
}

/// Everything but encoding is a request that cannot be drawn (an ID, a size, a page).
impl From<RenderError> for CliError {
    fn from(e: RenderError) -> Self {
        match e {
            RenderError::Encode(_) => CliError::failure(e),
            _ => CliError::bad_input(e),
        }
    }
}

/// The model file is the user's (`--model`), or shipped weights that do not fit the family.
impl From<ModelError> for CliError {
    fn from(e: ModelError) -> Self {
        CliError::bad_input(e)
    }
}

/// An image that cannot be read is the user's file, unless the system failed to read it.
impl From<ImageError> for CliError {
    fn from(e: ImageError) -> Self {
        match &e.kind {
            ImageErrorKind::TooLarge { .. } => {
                CliError::bad_input(format_args!("{e} (raise it with --max-pixels)"))
            }
            kind if kind.is_bad_input() => CliError::bad_input(e),
            _ => CliError::failure(e),
        }
    }
}

/// A checkpoint that cannot be resumed is the user's folder; the rest is the run failing.
impl From<tagsmith::train::TrainError> for CliError {
    fn from(e: tagsmith::train::TrainError) -> Self {
        match e {
            tagsmith::train::TrainError::Checkpoint(_) => CliError::bad_input(e),
            _ => CliError::failure(e),
        }
    }
}

impl From<GeometryError> for CliError {
    fn from(e: GeometryError) -> Self {
        CliError::bad_input(e)
    }
}

/// Generation parameters come from the command line and the user's family.
impl From<GenerateError> for CliError {
    fn from(e: GenerateError) -> Self {
        CliError::bad_input(e)
    }
}

/// The family given is not one OpenCV can read.
impl From<OpenCvError> for CliError {
    fn from(e: OpenCvError) -> Self {
        CliError::bad_input(e)
    }
}

/// `--page` and `--ids` as typed.
impl From<SheetError> for CliError {
    fn from(e: SheetError) -> Self {
        CliError::bad_input(e)
    }
}

/// The user's calibration file.
impl From<CalibrationError> for CliError {
    fn from(e: CalibrationError) -> Self {
        CliError::bad_input(e)
    }
}

/// A size or field of view that cannot be drawn is the request's; rendering keeps its own kinds.
impl From<SynthError> for CliError {
    fn from(e: SynthError) -> Self {
        match e {
            SynthError::Render(e) => e.into(),
            SynthError::ImageSize { .. }
            | SynthError::Geometry(_)
            | SynthError::DegeneratePlacement { .. }
            | SynthError::NoFamily => CliError::bad_input(e),
        }
    }
}

/// A set or detections file that cannot be read or does not fit is the user's; a set that cannot
/// be written is a failure.
impl From<EvalError> for CliError {
    fn from(e: EvalError) -> Self {
        match e {
            EvalError::Synth(e) => e.into(),
            EvalError::Write { .. } | EvalError::Encode { .. } => CliError::failure(e),
            // A disk that fails half-way through a set is the machine's fault, not the set's.
            EvalError::Read { ref source, .. } if !tagsmith::io::is_bad_input(source) => {
                CliError::failure(e)
            }
            EvalError::BadSide { .. }
            | EvalError::Read { .. }
            | EvalError::Json { .. }
            | EvalError::UnknownImage { .. }
            | EvalError::TooLarge { .. }
            | EvalError::BadSet { .. }
            | EvalError::BadScenario { .. }
            | EvalError::BadDetections { .. } => CliError::bad_input(e),
        }
    }
}

/// Puts what a typed error is about in front of its message; its kind stays the one its `From`
/// gives.
pub(crate) trait Concerning<T> {
    fn concerning(self, what: impl fmt::Display) -> Result<T>;
}

impl<T, E: Into<CliError>> Concerning<T> for std::result::Result<T, E> {
    fn concerning(self, what: impl fmt::Display) -> Result<T> {
        self.map_err(|e| e.into().concerning(what))
    }
}

/// Names the kind of an error at the call site, for errors whose type does not tell it (core's
/// plain messages, I/O wrapped with context).
pub(crate) trait Classify<T> {
    /// The input is fine but the output could not be produced: exit 1.
    fn failure(self) -> Result<T>;
}

impl<T, E: fmt::Display> Classify<T> for std::result::Result<T, E> {
    fn failure(self) -> Result<T> {
        self.map_err(CliError::failure)
    }
}

/// A bad-input error from a format string, like `anyhow!`.
macro_rules! bad_input {
    ($($arg:tt)*) => {
        $crate::cli::error::CliError::bad_input(format_args!($($arg)*))
    };
}

/// A failure from a format string, like `anyhow!`.
macro_rules! failure {
    ($($arg:tt)*) => {
        $crate::cli::error::CliError::failure(format_args!($($arg)*))
    };
}

pub(crate) use {bad_input, failure};

pub(crate) type Result<T> = std::result::Result<T, CliError>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cause_written_into_the_message_prints_once() {
        let e = ModelError::Io {
            path: "m.bin".into(),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        };
        let e = CliError::from(e);
        assert_eq!(e.exit_code(), 2);
        assert_eq!(format!("{e:#}"), "m.bin: no such file");
    }

    #[test]
    fn typed_errors_are_classified_once_here() {
        let encode = CliError::from(RenderError::Encode("full disk".into()));
        assert_eq!(encode.exit_code(), 1);
        assert_eq!(CliError::from(RenderError::BadSize(-1.0)).exit_code(), 2);
        assert_eq!(
            CliError::from(FamilyError::single("layout", "wrong")).exit_code(),
            2
        );
    }

    #[test]
    fn new_core_errors_are_classified_by_variant() {
        let write = EvalError::Write {
            path: "set/images/000000.png".into(),
            source: std::io::Error::other("disk full"),
        };
        assert_eq!(CliError::from(write).exit_code(), 1);
        let unknown = EvalError::UnknownImage {
            file: "x.png".into(),
        };
        assert_eq!(CliError::from(unknown).exit_code(), 2);
        let encode = SynthError::Render(RenderError::Encode("no memory".into()));
        assert_eq!(CliError::from(EvalError::Synth(encode)).exit_code(), 1);
        let size = SynthError::ImageSize {
            width: 8,
            height: 8,
        };
        assert_eq!(CliError::from(size).exit_code(), 2);
        assert_eq!(CliError::from(SheetError::NoIds).exit_code(), 2);
    }

    #[test]
    fn concerning_leads_the_message_and_keeps_the_kind() {
        let r: std::result::Result<(), SheetError> = Err(SheetError::NoIds);
        let e = r.concerning("--ids").unwrap_err();
        assert_eq!(e.exit_code(), 2);
        assert_eq!(format!("{e:#}"), "--ids: no IDs given");
        let r: std::result::Result<(), EvalError> = Err(EvalError::Write {
            path: "s/set.json".into(),
            source: std::io::Error::other("disk full"),
        });
        let e = r.concerning("eval").unwrap_err();
        assert_eq!(
            (e.exit_code(), e.to_string()),
            (1, "eval: s/set.json: disk full".into())
        );
    }

    #[test]
    fn context_chains_keep_their_causes() {
        use anyhow::Context as _;
        let r: std::result::Result<(), std::io::Error> = Err(std::io::Error::other("disk full"));
        let e = r.context("cannot write x.svg").failure().unwrap_err();
        assert_eq!(e.exit_code(), 1);
        assert_eq!(format!("{e:#}"), "cannot write x.svg: disk full");
    }
}
