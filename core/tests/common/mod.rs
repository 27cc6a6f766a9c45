//! Helpers shared by the library's integration tests.

use serde_json::Value;

/// A built-in family file, as shipped, parsed to JSON for editing.
pub fn builtin(name: &str) -> Value {
    let (_, text) = tagsmith::builtin::SOURCES
        .iter()
        .find(|(n, _)| *n == name)
        .unwrap();
    serde_json::from_str(text).unwrap()
}
