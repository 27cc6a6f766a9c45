//! The one error type of the commands, and the one place that decides its exit code.
//!
//! Core's typed errors convert with `?` (`From`), each classified once here; core's plain-message
//! errors and the CLI's own checks name their kind at the call site with [`Classify`] or
//! [`bad_input!`] / [`failure!`].

use std::fmt;
use tagsmith::detect::stage2::model_file::ModelError;
use tagsmith::geometry::GeometryError;
use tagsmith::image::{ImageError, ImageErrorKind};
use tagsmith::render::RenderError;
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

/// Names the kind of an error at the call site, for errors whose type does not tell it (core's
/// plain messages, I/O wrapped with context).
pub(crate) trait Classify<T> {
    /// The input is wrong: exit 2.
    fn bad_input(self) -> Result<T>;
    /// The input is fine but the output could not be produced: exit 1.
    fn failure(self) -> Result<T>;
}

impl<T, E: fmt::Display> Classify<T> for std::result::Result<T, E> {
    fn bad_input(self) -> Result<T> {
        self.map_err(CliError::bad_input)
    }

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
    fn context_chains_keep_their_causes() {
        use anyhow::Context as _;
        let r: std::result::Result<(), std::io::Error> = Err(std::io::Error::other("disk full"));
        let e = r.context("cannot write x.svg").failure().unwrap_err();
        assert_eq!(e.exit_code(), 1);
        assert_eq!(format!("{e:#}"), "cannot write x.svg: disk full");
    }
}
