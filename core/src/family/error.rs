//! Errors of loading and validating a family: every problem names the file and the JSON path.

use std::fmt;
use std::path::PathBuf;

pub use crate::problem::Problem;

/// A family that could not be loaded: the file (when there is one) and every problem found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FamilyError {
    pub file: Option<PathBuf>,
    pub problems: Vec<Problem>,
}

impl FamilyError {
    pub fn new(problems: Vec<Problem>) -> Self {
        Self {
            file: None,
            problems,
        }
    }

    pub fn single(path: impl Into<String>, message: impl Into<String>) -> Self {
        Self::new(vec![Problem::new(path, message)])
    }

    pub fn in_file(mut self, file: impl Into<PathBuf>) -> Self {
        self.file = Some(file.into());
        self
    }
}

impl fmt::Display for FamilyError {
    /// One line per problem, `file: json.path: what is wrong`, as compilers print errors.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let file = self
            .file
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "<family>".to_string());
        for (i, p) in self.problems.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            let path = if p.path.is_empty() { "." } else { &p.path };
            write!(f, "{file}: {path}: {}", p.message)?;
        }
        Ok(())
    }
}

impl std::error::Error for FamilyError {}
