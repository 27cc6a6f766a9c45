//! How the library's errors reach Python: bad input as `ValueError` (or `FileNotFoundError` for a
//! path that does not exist), with the message the command line prints; a panic, which would be a
//! fault of ours, as `RuntimeError` naming what was being done.

use pyo3::exceptions::{PyFileNotFoundError, PyRuntimeError, PyValueError};
use pyo3::PyErr;
use std::path::Path;

pub fn bad_input(message: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(message.to_string())
}

/// `FileNotFoundError` (errno ENOENT, the path as its filename) when `path` does not exist.
pub fn require_exists(path: &Path, what: &str) -> Result<(), PyErr> {
    if path.exists() {
        return Ok(());
    }
    Err(PyFileNotFoundError::new_err((
        2,
        format!("{what} {}: no such file", path.display()),
        path.display().to_string(),
    )))
}

/// Runs `work`, turning a panic into `RuntimeError`: the interpreter goes on, and the message says
/// which input to report.
pub fn no_panic<T>(doing: &str, work: impl FnOnce() -> T) -> Result<T, PyErr> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)).map_err(|panic| {
        let what = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        PyRuntimeError::new_err(format!(
            "internal error while {doing} ({what}); please report it with this input"
        ))
    })
}
