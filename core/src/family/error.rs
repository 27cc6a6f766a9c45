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

/// Most problems an error prints; the rest are counted. A generated file with a systematic mistake
/// (every one of a million codes too short) would otherwise print a million lines that say the same.
pub const MAX_SHOWN_PROBLEMS: usize = 100;

impl fmt::Display for FamilyError {
    /// One line per problem, `file: json.path: what is wrong`, as compilers print errors.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let file = self
            .file
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "<family>".to_string());
        for (i, p) in self.problems.iter().take(MAX_SHOWN_PROBLEMS).enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            let path = if p.path.is_empty() { "." } else { &p.path };
            write!(f, "{file}: {path}: {}", p.message)?;
        }
        if self.problems.len() > MAX_SHOWN_PROBLEMS {
            write!(
                f,
                "\n{file}: and {} more problems",
                self.problems.len() - MAX_SHOWN_PROBLEMS
            )?;
        }
        Ok(())
    }
}

impl std::error::Error for FamilyError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flood_of_problems_prints_the_first_and_a_count() {
        let problems = (0..1_000_000)
            .map(|i| Problem::new(format!("codebook.codes[{i}]"), "too short"))
            .collect();
        let text = FamilyError::new(problems).in_file("f.json").to_string();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), MAX_SHOWN_PROBLEMS + 1);
        assert_eq!(lines[0], "f.json: codebook.codes[0]: too short");
        assert_eq!(
            lines[MAX_SHOWN_PROBLEMS],
            "f.json: and 999900 more problems"
        );
    }
}
