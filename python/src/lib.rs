//! Tagsmith for Python: the detector on NumPy arrays, families, rendering and sheets.
//!
//! The module is `tagsmith._tagsmith`; the `tagsmith` package (python/tagsmith) re-exports it with
//! its docstrings and type stubs. Every error a user can cause becomes `ValueError`, `TypeError` or
//! `FileNotFoundError` carrying the command line's message; a fault of ours becomes `RuntimeError`,
//! never a panic across the boundary.

mod arrays;
mod detection;
mod detector;
mod errors;
mod family;

use pyo3::prelude::*;

#[pymodule]
fn _tagsmith(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // As the command line does: without it detection is several per cent slower (BENCHMARKS.md,
    // "Python package and scale-out"). TAGSMITH_KEEP_MALLOC=1 leaves the process's allocator alone.
    if std::env::var_os("TAGSMITH_KEEP_MALLOC").is_none_or(|v| v != "1") {
        tagsmith::detect::memory::keep_large_buffers();
    }
    m.add_class::<detector::Detector>()?;
    m.add_class::<detector::Tracker>()?;
    m.add_class::<detection::Detection>()?;
    m.add_class::<family::Family>()?;
    m.add_function(wrap_pyfunction!(family::families, m)?)?;
    m.add_function(wrap_pyfunction!(family::detectable_families, m)?)?;
    m.add_function(wrap_pyfunction!(arrays::to_gray, m)?)?;
    m.add_function(wrap_pyfunction!(arrays::imread, m)?)?;
    Ok(())
}
