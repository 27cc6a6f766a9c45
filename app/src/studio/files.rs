//! Where the studio reads and writes files. The desktop uses native dialogs and the disk, a
//! browser uploads and downloads, tests use a folder; the rest of the studio sees only
//! [`FileAccess`].

use std::path::{Path, PathBuf};

/// What an opened file is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Purpose {
    #[default]
    Family,
    /// A standard code table (OpenCV or AprilTag 3 JSON) for the design's codebook.
    CodeTable,
    /// A photograph or rendering for the Detect panel.
    Image,
}

/// The largest image file the studio reads into memory: an uncompressed 16-bit RGBA image of
/// the decoder's default 64 megapixels fits.
pub const MAX_IMAGE_BYTES: u64 = 512 << 20;

/// Extensions the image reader decodes.
pub const IMAGE_EXTENSIONS: &[&str] = tagsmith::image::EXTENSIONS;

impl Purpose {
    /// The open dialog's filter: its name and extensions.
    pub fn filter(self) -> (&'static str, &'static [&'static str]) {
        match self {
            Purpose::Family | Purpose::CodeTable => ("JSON", &["json"]),
            Purpose::Image => ("Images", IMAGE_EXTENSIONS),
        }
    }

    /// The most bytes a file for this purpose may hold: [`MAX_IMAGE_BYTES`] for an image,
    /// [`tagsmith::io::MAX_TEXT_BYTES`] for a family or code table.
    pub fn limit(self) -> u64 {
        match self {
            Purpose::Family | Purpose::CodeTable => tagsmith::io::MAX_TEXT_BYTES,
            Purpose::Image => MAX_IMAGE_BYTES,
        }
    }
}

/// Whether a file's name says it is an image (a dropped file is routed by it).
pub fn is_image_name(name: &str) -> bool {
    tagsmith::image::has_image_name(Path::new(name))
}

/// A file the user opened (or dropped, or that sits in the user's family folder).
#[derive(Debug, Clone, PartialEq)]
pub struct OpenedFile {
    pub purpose: Purpose,
    /// What to call it in messages: the path on the desktop, the file name in a browser.
    pub name: String,
    /// Where it lives on disk, when it does (saving writes back there).
    pub path: Option<PathBuf>,
    pub bytes: Vec<u8>,
}

pub trait FileAccess {
    /// Saves under a name the user confirms (a dialog on the desktop, a download in a browser).
    /// Returns where it went, or `None` when the user cancelled.
    fn save_as(&mut self, suggested_name: &str, bytes: &[u8]) -> Result<Option<String>, String>;
    /// Overwrites a file the studio already knows, atomically (a crash mid-write keeps the old
    /// file). Where files have no path (a browser), this is a download like `save_as`.
    fn save_to(&mut self, path: &Path, bytes: &[u8]) -> Result<String, String>;
    /// Asks for a file; it arrives later through `take_opened`.
    fn request_open(&mut self, purpose: Purpose);
    fn take_opened(&mut self) -> Vec<OpenedFile>;
    /// The folder of the user's own families, if this platform has one.
    fn user_folder(&self) -> Option<PathBuf>;
    /// A file dropped on the window: read now (desktop) or soon (browser), it then arrives
    /// through `take_opened` as a family file.
    fn accept_dropped(&mut self, file: egui::DroppedFileHandle) -> Result<(), String>;
}

/// Reads a picked file: a regular file of at most [`Purpose::limit`] bytes
/// ([`tagsmith::io::read_input`]; a FIFO would block the studio, a device never end). A file
/// that cannot be read arrives empty, under a name that says why, so that loading it reports the
/// problem like any other bad file.
#[cfg(not(target_arch = "wasm32"))]
fn read_file(path: PathBuf, purpose: Purpose) -> OpenedFile {
    match tagsmith::io::read_input(&path, purpose.limit()) {
        Ok(bytes) => OpenedFile {
            purpose,
            name: path.display().to_string(),
            path: Some(path),
            bytes,
        },
        Err(e) => OpenedFile {
            purpose,
            name: format!("{}: {e}", path.display()),
            path: None,
            bytes: Vec::new(),
        },
    }
}

/// Reads a dropped file where reading is synchronous (everywhere but a browser): one that is on
/// disk as [`read_file`] does (a regular file of bounded size: a dropped FIFO would block the
/// window), otherwise through its handle.
#[cfg(not(target_arch = "wasm32"))]
fn read_dropped(file: &egui::DroppedFileHandle) -> Result<OpenedFile, String> {
    let path = file.path().to_path_buf();
    let name = path.display().to_string();
    let bytes = if path.is_absolute() && std::fs::symlink_metadata(&path).is_ok() {
        // Routed by its name once read: an image's limit for an image, a family's otherwise.
        let purpose = if is_image_name(&name) {
            Purpose::Image
        } else {
            Purpose::Family
        };
        tagsmith::io::read_input(&path, purpose.limit()).map_err(|e| format!("{name}: {e}"))?
    } else {
        file.bytes().map_err(|e| format!("{name}: {e}"))?
    };
    Ok(OpenedFile {
        purpose: Purpose::Family,
        name,
        path: path.is_absolute().then_some(path),
        bytes,
    })
}

/// Reads every `*.json` in the user's folder; unreadable files are reported by the caller when
/// they fail to parse, so a broken file never hides the others.
pub fn user_families(files: &dyn FileAccess) -> Vec<OpenedFile> {
    let Some(dir) = files.user_folder() else {
        return Vec::new();
    };
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return Vec::new();
    };
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    paths.sort();
    paths
        .into_iter()
        .filter_map(|p| {
            // A FIFO or device named *.json in the folder must not hang the studio's start.
            let bytes = tagsmith::io::read_input(&p, tagsmith::io::MAX_TEXT_BYTES).ok()?;
            Some(OpenedFile {
                purpose: Purpose::Family,
                name: p.display().to_string(),
                path: Some(p),
                bytes,
            })
        })
        .collect()
}

#[cfg(not(target_arch = "wasm32"))]
fn write(path: &Path, bytes: &[u8]) -> Result<String, String> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    tagsmith::io::write_atomic(path, bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(path.display().to_string())
}

/// Files in one folder, no dialogs: `save_as` writes there under the suggested name and
/// `request_open` takes the next queued path. Tests drive the studio through this; it is also
/// what a headless or scripted session would use.
#[cfg(not(target_arch = "wasm32"))]
pub struct FolderFiles {
    pub folder: PathBuf,
    pub user_folder: Option<PathBuf>,
    pub to_open: Vec<PathBuf>,
    opened: Vec<OpenedFile>,
}

#[cfg(not(target_arch = "wasm32"))]
impl FolderFiles {
    pub fn new(folder: impl Into<PathBuf>) -> Self {
        Self {
            folder: folder.into(),
            user_folder: None,
            to_open: Vec::new(),
            opened: Vec::new(),
        }
    }
}

#[cfg(not(target_arch = "wasm32"))]
impl FileAccess for FolderFiles {
    fn save_as(&mut self, suggested_name: &str, bytes: &[u8]) -> Result<Option<String>, String> {
        write(&self.folder.join(suggested_name), bytes).map(Some)
    }

    fn save_to(&mut self, path: &Path, bytes: &[u8]) -> Result<String, String> {
        write(path, bytes)
    }

    fn request_open(&mut self, purpose: Purpose) {
        if !self.to_open.is_empty() {
            let path = self.to_open.remove(0);
            self.opened.push(read_file(path, purpose));
        }
    }

    fn take_opened(&mut self) -> Vec<OpenedFile> {
        std::mem::take(&mut self.opened)
    }

    fn user_folder(&self) -> Option<PathBuf> {
        self.user_folder.clone()
    }

    fn accept_dropped(&mut self, file: egui::DroppedFileHandle) -> Result<(), String> {
        self.opened.push(read_dropped(&file)?);
        Ok(())
    }
}

/// The desktop: native dialogs (rfd) and atomic writes.
#[cfg(not(target_arch = "wasm32"))]
pub struct NativeFiles {
    user_folder: Option<PathBuf>,
    opened: Vec<OpenedFile>,
}

#[cfg(not(target_arch = "wasm32"))]
impl NativeFiles {
    pub fn new(user_folder: Option<PathBuf>) -> Self {
        Self {
            user_folder,
            opened: Vec::new(),
        }
    }
}

#[cfg(not(target_arch = "wasm32"))]
impl FileAccess for NativeFiles {
    fn save_as(&mut self, suggested_name: &str, bytes: &[u8]) -> Result<Option<String>, String> {
        let mut dialog = rfd::FileDialog::new().set_file_name(suggested_name);
        if let Some(ext) = Path::new(suggested_name)
            .extension()
            .and_then(|e| e.to_str())
        {
            dialog = dialog.add_filter(ext.to_uppercase(), &[ext]);
        }
        match dialog.save_file() {
            Some(path) => write(&path, bytes).map(Some),
            None => Ok(None),
        }
    }

    fn save_to(&mut self, path: &Path, bytes: &[u8]) -> Result<String, String> {
        write(path, bytes)
    }

    fn request_open(&mut self, purpose: Purpose) {
        let (name, extensions) = purpose.filter();
        let picked = rfd::FileDialog::new()
            .add_filter(name, extensions)
            .pick_file();
        if let Some(path) = picked {
            self.opened.push(read_file(path, purpose));
        }
    }

    fn take_opened(&mut self) -> Vec<OpenedFile> {
        std::mem::take(&mut self.opened)
    }

    fn user_folder(&self) -> Option<PathBuf> {
        self.user_folder.clone()
    }

    fn accept_dropped(&mut self, file: egui::DroppedFileHandle) -> Result<(), String> {
        self.opened.push(read_dropped(&file)?);
        Ok(())
    }
}

/// A browser: uploads through rfd's file input, saves as downloads.
#[cfg(target_arch = "wasm32")]
#[derive(Default)]
pub struct WebFiles {
    opened: std::rc::Rc<std::cell::RefCell<Vec<OpenedFile>>>,
}

#[cfg(target_arch = "wasm32")]
impl WebFiles {
    fn download(name: &str, bytes: &[u8]) -> Result<(), String> {
        use wasm_bindgen::JsCast;
        let fail = |e: wasm_bindgen::JsValue| format!("download of {name} failed: {e:?}");
        let parts = js_sys::Array::of1(&js_sys::Uint8Array::from(bytes));
        let blob = web_sys::Blob::new_with_u8_array_sequence(&parts).map_err(fail)?;
        let url = web_sys::Url::create_object_url_with_blob(&blob).map_err(fail)?;
        let document = web_sys::window()
            .and_then(|w| w.document())
            .ok_or("no document")?;
        let link: web_sys::HtmlAnchorElement = document
            .create_element("a")
            .map_err(fail)?
            .dyn_into()
            .map_err(|_| "not an anchor element".to_string())?;
        link.set_href(&url);
        link.set_download(name);
        link.click();
        web_sys::Url::revoke_object_url(&url).map_err(fail)?;
        Ok(())
    }
}

#[cfg(target_arch = "wasm32")]
impl FileAccess for WebFiles {
    fn save_as(&mut self, suggested_name: &str, bytes: &[u8]) -> Result<Option<String>, String> {
        Self::download(suggested_name, bytes)?;
        Ok(Some(format!("downloaded {suggested_name}")))
    }

    fn save_to(&mut self, path: &Path, bytes: &[u8]) -> Result<String, String> {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "family.json".into());
        Self::download(&name, bytes)?;
        Ok(format!("downloaded {name}"))
    }

    fn request_open(&mut self, purpose: Purpose) {
        let inbox = self.opened.clone();
        wasm_bindgen_futures::spawn_local(async move {
            let (name, extensions) = purpose.filter();
            let picked = rfd::AsyncFileDialog::new()
                .add_filter(name, extensions)
                .pick_file()
                .await;
            if let Some(file) = picked {
                let bytes = file.read().await;
                inbox.borrow_mut().push(OpenedFile {
                    purpose,
                    name: file.file_name(),
                    path: None,
                    bytes,
                });
            }
        });
    }

    fn take_opened(&mut self) -> Vec<OpenedFile> {
        std::mem::take(&mut *self.opened.borrow_mut())
    }

    fn user_folder(&self) -> Option<PathBuf> {
        None
    }

    fn accept_dropped(&mut self, file: egui::DroppedFileHandle) -> Result<(), String> {
        let inbox = self.opened.clone();
        wasm_bindgen_futures::spawn_local(async move {
            let name = file.path().display().to_string();
            match file.bytes_async().await {
                Ok(bytes) => inbox.borrow_mut().push(OpenedFile {
                    purpose: Purpose::Family,
                    name,
                    path: None,
                    bytes,
                }),
                Err(e) => log::error!("{name}: {e}"),
            }
        });
        Ok(())
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    fn mkfifo(path: &Path) -> bool {
        let made = std::process::Command::new("mkfifo").arg(path).status();
        made.is_ok_and(|s| s.success())
    }

    /// A FIFO picked, dropped or lying in the families folder would block the window on its
    /// first read: it arrives empty under a name that says why, or not at all.
    #[test]
    fn a_fifo_is_never_read() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("family.json");
        if !mkfifo(&fifo) {
            return;
        }
        let mut files = FolderFiles::new(dir.path());
        files.to_open.push(fifo.clone());
        files.request_open(Purpose::Family);
        let opened = files.take_opened();
        assert_eq!(opened.len(), 1);
        assert!(
            opened[0].bytes.is_empty() && opened[0].name.contains("FIFO"),
            "{:?}",
            opened[0].name
        );

        #[derive(Debug)]
        struct Dropped(PathBuf);
        impl egui::DroppedFile for Dropped {
            fn path(&self) -> &Path {
                &self.0
            }
            fn bytes(&self) -> Result<Vec<u8>, String> {
                panic!("a file on disk is read through its path")
            }
        }
        let handle: egui::DroppedFileHandle = std::sync::Arc::new(Dropped(fifo.clone()));
        let err = files.accept_dropped(handle).unwrap_err();
        assert!(err.contains("family.json") && err.contains("FIFO"), "{err}");

        std::fs::write(dir.path().join("good.json"), b"{}").unwrap();
        files.user_folder = Some(dir.path().to_path_buf());
        let listed: Vec<String> = user_families(&files).into_iter().map(|f| f.name).collect();
        assert_eq!(listed.len(), 1, "{listed:?}");
        assert!(listed[0].ends_with("good.json"));
    }
}
