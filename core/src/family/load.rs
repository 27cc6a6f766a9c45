//! Reading and writing family JSON.

use super::spec::{FamilySpec, GridLayout, RingsLayout};
use super::{Family, FamilyError, Problem};
use std::path::Path;

/// Largest family file accepted ([`crate::io::MAX_TEXT_BYTES`], 64 MB); a codebook of 100 000
/// codes of 1024 bits fits in well under this.
const MAX_FILE_BYTES: usize = crate::io::MAX_TEXT_BYTES as usize;

/// Parses and validates a family from JSON text. Errors carry JSON paths but no file name.
pub fn from_json_str(text: &str) -> Result<Family, FamilyError> {
    if text.len() > MAX_FILE_BYTES {
        return Err(FamilyError::single(
            "",
            format!(
                "file is {} bytes, over the limit of {MAX_FILE_BYTES}",
                text.len()
            ),
        ));
    }
    let de = &mut serde_json::Deserializer::from_str(text);
    let spec: FamilySpec = serde_path_to_error::deserialize(de).map_err(|e| {
        let path = e.path().to_string();
        let path = if path == "." { String::new() } else { path };
        let problem = match path.as_str() {
            "layout" => layout_problem(text),
            _ => None,
        };
        FamilyError::new(vec![
            problem.unwrap_or_else(|| Problem::new(path, e.into_inner().to_string()))
        ])
    })?;
    Family::from_spec(spec)
}

/// serde reads a tagged enum through a buffer and loses the path inside it; reading the layout
/// object again as its variant's struct finds the field that is wrong.
fn layout_problem(text: &str) -> Option<Problem> {
    let root: serde_json::Value = serde_json::from_str(text).ok()?;
    let mut layout = root.get("layout")?.clone();
    let kind = layout.as_object_mut()?.remove("type")?;
    let result = match kind.as_str()? {
        "grid" => serde_path_to_error::deserialize::<_, GridLayout>(layout).map(drop),
        "rings" => serde_path_to_error::deserialize::<_, RingsLayout>(layout).map(drop),
        _ => return None,
    };
    let e = result.err()?;
    let inner = e.path().to_string();
    let path = if inner == "." {
        "layout".to_string()
    } else {
        format!("layout.{inner}")
    };
    Some(Problem::new(path, e.into_inner().to_string()))
}

/// Reads, parses and validates a family file; errors name the file. Only a regular file of at
/// most [`crate::io::MAX_TEXT_BYTES`] is read ([`crate::io::read_input_text`]): a FIFO, a device
/// or a folder is refused before anything waits on it.
pub fn load_file(path: &Path) -> Result<Family, FamilyError> {
    let text = crate::io::read_input_text(path, crate::io::MAX_TEXT_BYTES)
        .map_err(|e| FamilyError::single("", format!("cannot read it: {e}")).in_file(path))?;
    from_json_str(&text).map_err(|e| e.in_file(path))
}

/// Pretty JSON of a spec, as written to family files (2-space indent, trailing newline).
pub fn to_json_string(spec: &FamilySpec) -> String {
    let mut s = serde_json::to_string_pretty(spec).expect("a family spec always serialises");
    s.push('\n');
    s
}

/// The JSON Schema of the family format, generated from the spec types.
pub fn schema_json() -> String {
    let schema = schemars::schema_for!(FamilySpec);
    let mut s = serde_json::to_string_pretty(&schema).expect("a schema always serialises");
    s.push('\n');
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_family_file_that_is_not_a_regular_file_is_refused_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let err = load_file(dir.path()).unwrap_err().to_string();
        assert!(err.contains(&dir.path().display().to_string()), "{err}");
        assert!(err.contains("folder"), "{err}");
        #[cfg(unix)]
        {
            let fifo = dir.path().join("family.json");
            let made = std::process::Command::new("mkfifo").arg(&fifo).status();
            if made.is_ok_and(|s| s.success()) {
                // Reading a FIFO with no writer would block forever.
                let err = load_file(&fifo).unwrap_err().to_string();
                assert!(err.contains("family.json") && err.contains("FIFO"), "{err}");
            }
            if Path::new("/dev/zero").exists() {
                let err = load_file(Path::new("/dev/zero")).unwrap_err().to_string();
                assert!(err.contains("/dev/zero") && err.contains("device"), "{err}");
            }
        }
        let binary = dir.path().join("binary.json");
        std::fs::write(&binary, [b'{', 0xff, b'}']).unwrap();
        let err = load_file(&binary).unwrap_err().to_string();
        assert!(
            err.contains("binary.json") && err.contains("UTF-8"),
            "{err}"
        );
    }
}
