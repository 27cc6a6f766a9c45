//! The design being edited: its spec, undo history, where it is saved and whether it has unsaved
//! changes. Every change goes through `tagsmith::family::edit`; validation is the core's.

use std::path::PathBuf;
use tagsmith::family::edit::{Edit, EditError, History};
use tagsmith::family::{Family, FamilyError, FamilySpec};

pub struct Design {
    history: History,
    /// Where the design was loaded from or last saved (desktop); `None` until first saved.
    pub path: Option<PathBuf>,
    /// The spec as last saved or loaded, to tell whether there are unsaved changes.
    saved: Option<FamilySpec>,
    /// The current spec, validated.
    validation: Result<Family, FamilyError>,
    /// The last spec that validated, so the preview stays up while a change is being fixed.
    last_valid: Option<Family>,
    /// Bumped by every change; previews are cached per revision.
    pub revision: u64,
}

impl Design {
    /// A design that starts from `spec`; `saved` says whether that spec is already on disk.
    pub fn new(spec: FamilySpec, path: Option<PathBuf>, saved: bool) -> Self {
        let validation = Family::from_spec(spec.clone());
        let last_valid = validation.as_ref().ok().cloned();
        Self {
            saved: saved.then(|| spec.clone()),
            history: History::new(spec),
            path,
            validation,
            last_valid,
            revision: 0,
        }
    }

    /// A design brought back from storage: `saved` is the spec as it was last saved, if ever.
    pub fn restore(spec: FamilySpec, path: Option<PathBuf>, saved: Option<FamilySpec>) -> Self {
        let mut d = Self::new(spec, path, false);
        d.saved = saved;
        d
    }

    pub fn saved_spec(&self) -> Option<&FamilySpec> {
        self.saved.as_ref()
    }

    pub fn spec(&self) -> &FamilySpec {
        self.history.current()
    }

    pub fn validation(&self) -> &Result<Family, FamilyError> {
        &self.validation
    }

    /// The family to preview: the current one if it validates, else the last that did.
    pub fn preview_family(&self) -> Option<&Family> {
        self.validation.as_ref().ok().or(self.last_valid.as_ref())
    }

    /// Problems whose JSON path starts with one of `prefixes` (to show next to a control).
    pub fn problems_at(&self, prefixes: &[&str]) -> Vec<String> {
        match &self.validation {
            Ok(_) => Vec::new(),
            Err(e) => e
                .problems
                .iter()
                .filter(|p| prefixes.iter().any(|pre| p.path.starts_with(pre)))
                .map(|p| format!("{}: {}", p.path, p.message))
                .collect(),
        }
    }

    pub fn is_dirty(&self) -> bool {
        self.saved.as_ref() != Some(self.spec())
    }

    pub fn mark_saved(&mut self, path: Option<PathBuf>) {
        self.saved = Some(self.spec().clone());
        if path.is_some() {
            self.path = path;
        }
    }

    pub fn apply(&mut self, edit: &Edit) -> Result<(), EditError> {
        self.history.apply(edit)?;
        self.revalidate();
        Ok(())
    }

    /// One step of a continuous gesture (a dragged slider): the whole gesture is one undo step.
    pub fn apply_grouped(&mut self, edit: &Edit, group: &str) -> Result<(), EditError> {
        self.history.apply_grouped(edit, group)?;
        self.revalidate();
        Ok(())
    }

    pub fn end_gesture(&mut self) {
        self.history.end_group();
    }

    pub fn undo(&mut self) -> bool {
        let done = self.history.undo();
        if done {
            self.revalidate();
        }
        done
    }

    pub fn redo(&mut self) -> bool {
        let done = self.history.redo();
        if done {
            self.revalidate();
        }
        done
    }

    pub fn undo_steps(&self) -> usize {
        self.history.can_undo()
    }

    pub fn redo_steps(&self) -> usize {
        self.history.can_redo()
    }

    fn revalidate(&mut self) {
        self.validation = Family::from_spec(self.spec().clone());
        if let Ok(f) = &self.validation {
            self.last_valid = Some(f.clone());
        }
        self.revision += 1;
    }

    /// The file name a save suggests.
    pub fn file_name(&self) -> String {
        self.path
            .as_ref()
            .and_then(|p| p.file_name())
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| format!("{}.json", self.spec().name))
    }
}
