//! Reading inputs as regular files of a bounded size ([`read_input`]); writing files atomically:
//! a reader (or a crash) never sees a half-written output; floats that JSON cannot hold
//! ([`json_float`]); and a [`Stopwatch`] for per-stage timings.

use std::io::{Read, Write};
use std::path::Path;

/// The most a text input (family, camera, set, detections, checkpoint file) may hold: the
/// largest real one, a benchmark set of a thousand images, is a few MB.
pub const MAX_TEXT_BYTES: u64 = 64 << 20;

/// The most a model file may hold: the shipped models are under 1 MB, the widest network the
/// trainer builds a few tens of MB.
pub const MAX_MODEL_BYTES: u64 = 256 << 20;

/// Opens `path` for reading if it is a regular file (a symlink to one counts).
///
/// A FIFO would block the open until some writer appears, a device (`/dev/zero`) never ends and
/// a folder has no bytes: each is refused with [`std::io::ErrorKind::InvalidInput`] and a message
/// naming what it is, before anything waits on it.
pub fn open_input(path: &Path) -> std::io::Result<std::fs::File> {
    refuse_unless_regular(&std::fs::metadata(path)?)?;
    let file = std::fs::File::open(path)?;
    // The path may have been swapped between the check and the open.
    refuse_unless_regular(&file.metadata()?)?;
    Ok(file)
}

/// The whole of a regular file of at most `limit` bytes ([`open_input`]); a larger one is refused
/// with [`std::io::ErrorKind::FileTooLarge`] before it is read.
pub fn read_input(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    let file = open_input(path)?;
    let size = file.metadata()?.len();
    let too_large = || {
        std::io::Error::new(
            std::io::ErrorKind::FileTooLarge,
            format!("the file is over the limit of {} MB", limit >> 20),
        )
    };
    if size > limit {
        return Err(too_large());
    }
    let mut bytes = Vec::new();
    bytes.try_reserve_exact(size as usize).map_err(|_| {
        std::io::Error::new(
            std::io::ErrorKind::OutOfMemory,
            format!("no memory for {size} bytes"),
        )
    })?;
    // The file may grow while it is read: never past the limit.
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large());
    }
    Ok(bytes)
}

/// [`read_input`] as UTF-8 text; other bytes are refused with
/// [`std::io::ErrorKind::InvalidData`].
pub fn read_input_text(path: &Path, limit: u64) -> std::io::Result<String> {
    String::from_utf8(read_input(path, limit)?).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "the file is not UTF-8 text (byte {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

/// Whether an error from [`read_input`] or [`open_input`] is the input's fault (missing, not a
/// regular file, too large, not text, not readable by this user) rather than the machine's (a
/// disk that failed half-way, memory).
pub fn is_bad_input(e: &std::io::Error) -> bool {
    use std::io::ErrorKind as K;
    matches!(
        e.kind(),
        K::NotFound
            | K::PermissionDenied
            | K::IsADirectory
            | K::NotADirectory
            | K::InvalidInput
            | K::InvalidData
            | K::FileTooLarge
            | K::UnexpectedEof
    )
}

fn refuse_unless_regular(meta: &std::fs::Metadata) -> std::io::Result<()> {
    let kind = meta.file_type();
    if kind.is_file() {
        return Ok(());
    }
    if kind.is_dir() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "it is a folder, not a file",
        ));
    }
    #[cfg(unix)]
    let what = {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            "a FIFO (named pipe)"
        } else if kind.is_char_device() || kind.is_block_device() {
            "a device"
        } else if kind.is_socket() {
            "a socket"
        } else {
            "not a regular file"
        }
    };
    #[cfg(not(unix))]
    let what = "not a regular file";
    Err(std::io::Error::new(
        std::io::ErrorKind::InvalidInput,
        format!("it is {what}; only regular files are read"),
    ))
}

/// Writes `bytes` to a temporary file beside `path`, flushes it to disk, then renames it over
/// `path`. On any error the previous content of `path` is untouched.
///
/// A symlink stays a symlink: the file it points to is written. A FIFO or a device is written
/// through, never replaced by a regular file; a folder is refused. Temporary files that a killed
/// run left in the folder are removed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let path = &follow_symlinks(path)?;
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => {
            return Err(std::io::Error::new(
                std::io::ErrorKind::IsADirectory,
                "it is a folder, not a file",
            ))
        }
        Ok(m) if !m.is_file() => {
            // A pipe or a device: the reader on the other side wants the bytes, and renaming a
            // file over the node would destroy it.
            let mut node = std::fs::OpenOptions::new().write(true).open(path)?;
            return node.write_all(bytes);
        }
        _ => {}
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    remove_stale_temporaries(dir);
    let mut tmp = tempfile::Builder::new()
        .prefix(&format!("{TEMP_PREFIX}{}-", std::process::id()))
        .suffix(TEMP_SUFFIX)
        .tempfile_in(dir)?;
    tmp.write_all(bytes)?;
    // Temporary files are private (0600); an output file should be as readable as any other,
    // or keep the mode of the file it replaces.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(path).map_or(0o644, |m| m.permissions().mode());
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(mode))?;
    }
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}

/// Serde for `f64`/`f32` fields that may be NaN or infinite (`#[serde(with =
/// "crate::io::json_float")]`): finite values are plain JSON numbers, the others the strings
/// `"NaN"`, `"inf"`, `"-inf"` (JSON has no such numbers; serde_json would write `null` and then
/// refuse to read it back).
pub mod json_float {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<F: Float, S: Serializer>(v: &F, s: S) -> Result<S::Ok, S::Error> {
        let x = v.to_f64();
        if x.is_finite() {
            v.serialize_finite(s)
        } else if x.is_nan() {
            s.serialize_str("NaN")
        } else if x > 0.0 {
            s.serialize_str("inf")
        } else {
            s.serialize_str("-inf")
        }
    }

    pub fn deserialize<'de, F: Float, D: Deserializer<'de>>(d: D) -> Result<F, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Repr {
            Number(f64),
            Text(String),
            // Files written before this encoding hold `null` where the value was NaN.
            Null(()),
        }
        let v = match Repr::deserialize(d)? {
            Repr::Number(v) => v,
            Repr::Null(()) => f64::NAN,
            Repr::Text(t) => match t.as_str() {
                "NaN" => f64::NAN,
                "inf" => f64::INFINITY,
                "-inf" => f64::NEG_INFINITY,
                other => {
                    return Err(serde::de::Error::custom(format!(
                    "{other:?} is not a number (expected a number, \"NaN\", \"inf\" or \"-inf\")"
                )))
                }
            },
        };
        Ok(F::from_f64(v))
    }

    /// The float types the module serves; finite values keep their own width in JSON.
    pub trait Float: Copy {
        fn to_f64(self) -> f64;
        fn from_f64(v: f64) -> Self;
        fn serialize_finite<S: Serializer>(self, s: S) -> Result<S::Ok, S::Error>;
    }
    impl Float for f64 {
        fn to_f64(self) -> f64 {
            self
        }
        fn from_f64(v: f64) -> Self {
            v
        }
        fn serialize_finite<S: Serializer>(self, s: S) -> Result<S::Ok, S::Error> {
            s.serialize_f64(self)
        }
    }
    impl Float for f32 {
        fn to_f64(self) -> f64 {
            self as f64
        }
        fn from_f64(v: f64) -> Self {
            v as f32
        }
        fn serialize_finite<S: Serializer>(self, s: S) -> Result<S::Ok, S::Error> {
            s.serialize_f32(self)
        }
    }
}

const TEMP_PREFIX: &str = ".tagsmith-";
const TEMP_SUFFIX: &str = ".tmp";

/// Where a chain of symlinks ends (the path itself when it is not one); the end need not exist.
fn follow_symlinks(path: &Path) -> std::io::Result<std::path::PathBuf> {
    let mut current = path.to_path_buf();
    // The kernel's own limit on a chain (ELOOP).
    for _ in 0..40 {
        match std::fs::symlink_metadata(&current) {
            Ok(m) if m.file_type().is_symlink() => {
                let target = std::fs::read_link(&current)?;
                current = match current.parent() {
                    Some(parent) if target.is_relative() => parent.join(target),
                    _ => target,
                };
            }
            _ => return Ok(current),
        }
    }
    Err(std::io::Error::other("too many levels of symbolic links"))
}

/// Removes `.tagsmith-PID-*.tmp` files whose writer is gone (a killed process): on Linux when its
/// process no longer exists, elsewhere (and for names without a PID) once an hour old.
fn remove_stale_temporaries(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let Some(middle) = name
            .strip_prefix(TEMP_PREFIX)
            .and_then(|n| n.strip_suffix(TEMP_SUFFIX))
        else {
            continue;
        };
        let pid = middle.split('-').next().and_then(|p| p.parse::<u32>().ok());
        let writer_gone = match pid {
            Some(pid) if Path::new("/proc/self").exists() => {
                pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists()
            }
            _ => false,
        };
        let old = entry
            .metadata()
            .and_then(|m| m.modified())
            .ok()
            .and_then(|t| t.elapsed().ok())
            .is_some_and(|age| age.as_secs() > 3600);
        if writer_gone || old {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// A folder made for one run's output, with the folders above it that did not exist yet. Dropped
/// without [`CreatedDir::keep`] (the run failed), it removes the topmost folder it created with
/// everything in it, so a failed run leaves no empty or partial output behind; folders that were
/// there before are never removed.
#[must_use = "dropping it removes the folder again"]
pub struct CreatedDir {
    created: Option<std::path::PathBuf>,
}

impl CreatedDir {
    /// `create_dir_all(path)`, remembering the first missing ancestor.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        let created = path
            .ancestors()
            .take_while(|p| !p.as_os_str().is_empty() && !p.exists())
            .last()
            .map(Path::to_path_buf);
        std::fs::create_dir_all(path)?;
        Ok(Self { created })
    }

    /// The run succeeded: the folders stay.
    pub fn keep(mut self) {
        self.created = None;
    }
}

impl Drop for CreatedDir {
    fn drop(&mut self) {
        if let Some(dir) = self.created.take() {
            // Best effort: the run's own error is the one to report.
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_created_folder_is_removed_unless_kept_and_an_old_one_stays() {
        let dir = tempfile::tempdir().unwrap();
        let deep = dir.path().join("new/set/images");
        drop(CreatedDir::create(&deep).unwrap());
        assert!(!dir.path().join("new").exists());

        CreatedDir::create(&deep).unwrap().keep();
        assert!(deep.exists());

        std::fs::write(deep.join("old.png"), b"x").unwrap();
        drop(CreatedDir::create(&deep).unwrap());
        assert!(deep.join("old.png").exists());
        drop(CreatedDir::create(&deep.join("more")).unwrap());
        assert!(!deep.join("more").exists() && deep.join("old.png").exists());
    }

    use super::*;

    #[test]
    fn replaces_content_and_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.txt");
        write_atomic(&path, b"first").unwrap();
        write_atomic(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn non_finite_floats_round_trip_through_json() {
        #[derive(serde::Serialize, serde::Deserialize, PartialEq, Debug)]
        struct M {
            #[serde(with = "json_float")]
            a: f64,
            #[serde(with = "json_float")]
            b: f32,
        }
        for (a, b) in [
            (f64::NAN, 1.5f32),
            (f64::INFINITY, f32::NEG_INFINITY),
            (0.25, f32::NAN),
        ] {
            let text = serde_json::to_string(&M { a, b }).unwrap();
            let back: M = serde_json::from_str(&text).unwrap();
            assert!(back.a == a || (a.is_nan() && back.a.is_nan()), "{text}");
            assert!(back.b == b || (b.is_nan() && back.b.is_nan()), "{text}");
        }
        // What earlier checkpoints hold for NaN.
        let old: M = serde_json::from_str(r#"{"a": null, "b": 2}"#).unwrap();
        assert!(old.a.is_nan() && old.b == 2.0);
        assert!(serde_json::from_str::<M>(r#"{"a": "many", "b": 2}"#).is_err());
    }

    #[cfg(unix)]
    #[test]
    fn a_symlink_stays_a_symlink_and_its_target_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("real.txt");
        std::fs::write(&target, b"old").unwrap();
        let link = dir.path().join("link.txt");
        std::os::unix::fs::symlink("real.txt", &link).unwrap();
        let is_symlink = |p: &Path| {
            std::fs::symlink_metadata(p)
                .unwrap()
                .file_type()
                .is_symlink()
        };
        write_atomic(&link, b"new").unwrap();
        assert!(is_symlink(&link));
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
        // A dangling link creates its target.
        let dangling = dir.path().join("dangling.txt");
        std::os::unix::fs::symlink("made.txt", &dangling).unwrap();
        write_atomic(&dangling, b"x").unwrap();
        assert!(is_symlink(&dangling));
        assert_eq!(std::fs::read(dir.path().join("made.txt")).unwrap(), b"x");
    }

    #[cfg(unix)]
    #[test]
    fn a_device_is_written_through_not_replaced() {
        let null = Path::new("/dev/null");
        if !null.exists() {
            return;
        }
        write_atomic(null, b"discarded").unwrap();
        use std::os::unix::fs::FileTypeExt;
        assert!(std::fs::metadata(null)
            .unwrap()
            .file_type()
            .is_char_device());
        // /dev/full takes nothing: an error, and the node is still a device.
        let full = Path::new("/dev/full");
        if full.exists() {
            assert!(write_atomic(full, b"x").is_err());
            assert!(std::fs::metadata(full)
                .unwrap()
                .file_type()
                .is_char_device());
        }
    }

    #[test]
    fn a_folder_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let err = write_atomic(dir.path(), b"x").unwrap_err();
        assert_eq!(err.kind(), std::io::ErrorKind::IsADirectory);
    }

    #[test]
    fn temporaries_of_a_killed_writer_are_removed_by_the_next_write() {
        let dir = tempfile::tempdir().unwrap();
        // PID 0 is never a user process; an hour-old nameless one is stale too.
        let dead = dir.path().join(".tagsmith-0-abc.tmp");
        std::fs::write(&dead, b"half").unwrap();
        let ours = dir
            .path()
            .join(format!(".tagsmith-{}-live.tmp", std::process::id()));
        std::fs::write(&ours, b"in progress").unwrap();
        write_atomic(&dir.path().join("out.txt"), b"x").unwrap();
        if Path::new("/proc/self").exists() {
            assert!(!dead.exists());
        }
        assert!(
            ours.exists(),
            "a live writer's temporary file is left alone"
        );
    }

    #[test]
    fn inputs_are_regular_files_of_bounded_size() {
        let dir = tempfile::tempdir().unwrap();
        let small = dir.path().join("small.json");
        std::fs::write(&small, b"{}").unwrap();
        assert_eq!(read_input(&small, 2).unwrap(), b"{}");
        let err = read_input(&small, 1).unwrap_err();
        assert_eq!(err.kind(), std::io::ErrorKind::FileTooLarge);
        assert!(is_bad_input(&err));
        let err = read_input(dir.path(), 100).unwrap_err();
        assert_eq!(err.kind(), std::io::ErrorKind::IsADirectory);
        std::fs::write(&small, [0xff, 0xfe]).unwrap();
        let err = read_input_text(&small, 100).unwrap_err();
        assert!(
            is_bad_input(&err) && err.to_string().contains("UTF-8"),
            "{err}"
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_device_or_a_fifo_is_refused_without_waiting() {
        if Path::new("/dev/zero").exists() {
            let err = read_input(Path::new("/dev/zero"), 100).unwrap_err();
            assert!(err.to_string().contains("a device"), "{err}");
            assert!(is_bad_input(&err));
        }
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            // Opening a FIFO with no writer would block forever.
            let err = open_input(&fifo).unwrap_err();
            assert!(err.to_string().contains("FIFO"), "{err}");
        }
    }

    #[test]
    fn a_missing_directory_is_an_error_not_a_panic() {
        let dir = tempfile::tempdir().unwrap();
        assert!(write_atomic(&dir.path().join("no/such/dir/out.txt"), b"x").is_err());
    }
}

/// Wall time since it started, for the per-stage timings detections report. Browsers give std no
/// monotonic clock (`std::time::Instant::now` panics there); `web_time` reads `performance.now()`
/// there and is std's `Instant` elsewhere.
#[derive(Debug, Clone, Copy)]
pub struct Stopwatch {
    started: web_time::Instant,
}

impl Stopwatch {
    pub fn start() -> Self {
        Self {
            started: web_time::Instant::now(),
        }
    }

    /// Milliseconds since [`Stopwatch::start`].
    pub fn ms(&self) -> f64 {
        self.started.elapsed().as_secs_f64() * 1e3
    }
}
