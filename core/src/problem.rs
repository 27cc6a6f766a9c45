//! A problem found in an input file, located by its JSON path: what validation of families and
//! codebooks reports, so a message can name the field that is wrong.

/// One thing wrong with an input, at a JSON path such as `layout.cells[3]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    pub path: String,
    pub message: String,
}

impl Problem {
    pub fn new(path: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            message: message.into(),
        }
    }
}
