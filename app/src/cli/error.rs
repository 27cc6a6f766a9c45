//! The one error type of the commands and the one place that turns it into an exit code.

use std::fmt;

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

pub(crate) fn bad(e: impl Into<anyhow::Error>) -> CliError {
    CliError::BadInput(e.into())
}

pub(crate) fn failed(e: impl Into<anyhow::Error>) -> CliError {
    CliError::Failed(e.into())
}

pub(crate) type Result<T> = std::result::Result<T, CliError>;
