//! Editing a family spec: every change the studio's designer makes is one [`Edit`] applied here, so
//! the UI holds no model logic and the CLI or tests can replay the same edits. An edit keeps the
//! spec consistent where it can (a renamed category is renamed in the legend and the extras too; a
//! layout change that alters the code length replaces the codebook with a placeholder) and leaves
//! everything else to validation ([`super::Family::from_spec`]), whose problems the designer shows
//! next to the control that caused them. [`History`] keeps undo and redo.

use super::designs::framed_cells;
use super::spec::*;
use crate::codebook::Codebook;
use std::collections::VecDeque;

/// What a grid cell holds.
#[derive(Debug, Clone, PartialEq)]
pub enum CellValue {
    /// A code symbol (the next position in row-major code order).
    Symbol,
    /// No keypoint; nothing drawn.
    Empty,
    /// A fixed keypoint of this category.
    Fixed(String),
}

#[derive(Debug, Clone, PartialEq)]
pub enum Edit {
    SetName(String),
    SetTitle(String),
    /// A square grid of `size` cells with a frame `border` cells wide of category `frame`, all other
    /// cells code symbols; the ROI becomes the frame's outer corners.
    SetGrid {
        size: u32,
        border: u32,
        frame: String,
    },
    SetCell {
        row: u32,
        col: u32,
        value: CellValue,
    },
    /// Concentric rings of `slots` dot positions each (RuneTag-style); radii in marker units.
    SetRings {
        radii: Vec<f64>,
        slots: u32,
        dot_radius_ratio: f64,
        start_angle_deg: f64,
    },
    SetQuietZone(f64),
    SetDescription(String),
    /// Where the design comes from (credits, licences of imported tables).
    SetSource(String),
    /// Page colour around and between the keypoints, as `#rrggbb`.
    SetBackground(String),
    AddCategory {
        name: String,
        role: Role,
    },
    RemoveCategory(String),
    RenameCategory {
        from: String,
        to: String,
    },
    SetRole {
        category: String,
        role: Role,
    },
    SetPrimitives {
        category: String,
        primitives: Vec<Primitive>,
    },
    SetRoi(Vec<[f64; 2]>),
    SetKeypointSet(KeypointSet),
    AddExtra(ExtraKeypoint),
    RemoveExtra(usize),
    SetCodebook(CodebookSpec),
    SetMarkerSide(f64),
    SetPrintLabels(bool),
    /// How far beyond the ROI the rectified template reaches (docs/ARCHITECTURE.md §6.3, a = 0.15
    /// by default).
    SetRoiMargin(f64),
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EditError {
    #[error("no category named {0:?}")]
    NoCategory(String),
    #[error("a category named {0:?} already exists")]
    Exists(String),
    #[error("category {name:?} is still used by {uses} keypoint(s); change those first")]
    InUse { name: String, uses: usize },
    #[error("{0}")]
    Layout(String),
}

/// Applies an edit, returning the new spec (the old one is untouched).
pub fn apply(spec: &FamilySpec, edit: &Edit) -> Result<FamilySpec, EditError> {
    let mut s = spec.clone();
    let code_len_before = code_len(&s);
    match edit {
        Edit::SetName(n) => s.name = n.clone(),
        Edit::SetTitle(t) => s.title = t.clone(),
        Edit::SetGrid {
            size,
            border,
            frame,
        } => set_grid(&mut s, *size, *border, frame)?,
        Edit::SetCell { row, col, value } => set_cell(&mut s, *row, *col, value)?,
        Edit::SetRings {
            radii,
            slots,
            dot_radius_ratio,
            start_angle_deg,
        } => set_rings(&mut s, radii, *slots, *dot_radius_ratio, *start_angle_deg)?,
        Edit::SetDescription(d) => s.description = d.clone(),
        Edit::SetSource(text) => s.source = text.clone(),
        Edit::SetBackground(b) => s.background = b.clone(),
        Edit::SetPrintLabels(on) => s.print.labels = *on,
        Edit::SetRoiMargin(m) => s.roi.margin = *m,
        Edit::SetQuietZone(q) => match &mut s.layout {
            Layout::Grid(g) => g.quiet_zone = *q,
            Layout::Rings(r) => r.quiet_zone = *q,
        },
        Edit::AddCategory { name, role } => {
            if index(&s, name).is_some() {
                return Err(EditError::Exists(name.clone()));
            }
            s.categories.push(Category {
                name: name.clone(),
                role: *role,
                primitives: Vec::new(),
            });
        }
        Edit::RemoveCategory(name) => {
            let i = index(&s, name).ok_or_else(|| EditError::NoCategory(name.clone()))?;
            let uses = uses(&s, name);
            if uses > 0 {
                return Err(EditError::InUse {
                    name: name.clone(),
                    uses,
                });
            }
            s.categories.remove(i);
            if let Layout::Grid(g) = &mut s.layout {
                g.legend.retain(|_, v| v != name);
            }
        }
        Edit::RenameCategory { from, to } => {
            let i = index(&s, from).ok_or_else(|| EditError::NoCategory(from.clone()))?;
            if from != to && index(&s, to).is_some() {
                return Err(EditError::Exists(to.clone()));
            }
            s.categories[i].name = to.clone();
            if let Layout::Grid(g) = &mut s.layout {
                g.legend
                    .values_mut()
                    .filter(|v| *v == from)
                    .for_each(|v| *v = to.clone());
            }
            s.extra
                .iter_mut()
                .filter(|e| &e.category == from)
                .for_each(|e| e.category = to.clone());
        }
        Edit::SetRole { category, role } => {
            let i = index(&s, category).ok_or_else(|| EditError::NoCategory(category.clone()))?;
            s.categories[i].role = *role;
        }
        Edit::SetPrimitives {
            category,
            primitives,
        } => {
            let i = index(&s, category).ok_or_else(|| EditError::NoCategory(category.clone()))?;
            s.categories[i].primitives = primitives.clone();
        }
        Edit::SetRoi(points) => s.roi.points = points.clone(),
        Edit::SetKeypointSet(k) => s.keypoint_set = k.clone(),
        Edit::AddExtra(e) => s.extra.push(e.clone()),
        Edit::RemoveExtra(i) => {
            if *i >= s.extra.len() {
                return Err(EditError::Layout(format!("there is no extra keypoint {i}")));
            }
            s.extra.remove(*i);
        }
        Edit::SetCodebook(c) => s.codebook = c.clone(),
        Edit::SetMarkerSide(mm) => s.print.marker_side_mm = *mm,
    }
    let q = s
        .categories
        .iter()
        .filter(|c| matches!(c.role, Role::Symbol(_)))
        .count();
    let len = code_len(&s);
    // The old codes no longer fit the layout: keep one all-zero code so the design still renders
    // while the user generates or imports a codebook for it.
    if len != code_len_before && len > 0 && q >= 2 && !matches!(edit, Edit::SetCodebook(_)) {
        s.codebook = Codebook::from_codes(q, len, vec![vec![0; len]], None, None)
            .to_spec(None, "placeholder: generate or import a codebook");
    }
    Ok(s)
}

fn index(s: &FamilySpec, name: &str) -> Option<usize> {
    s.categories.iter().position(|c| c.name == name)
}

/// Keypoints drawn with a category as fixed keypoints (grid legend cells and extras).
fn uses(s: &FamilySpec, name: &str) -> usize {
    let cells = match &s.layout {
        Layout::Grid(g) => {
            let keys: Vec<char> = g
                .legend
                .iter()
                .filter(|(_, v)| *v == name)
                .filter_map(|(k, _)| k.chars().next())
                .collect();
            g.cells
                .iter()
                .flat_map(|r| r.chars())
                .filter(|c| keys.contains(c))
                .count()
        }
        Layout::Rings(_) => 0,
    };
    cells + s.extra.iter().filter(|e| e.category == name).count()
}

/// Number of code symbols the layout has.
fn code_len(s: &FamilySpec) -> usize {
    let layout = match &s.layout {
        Layout::Grid(g) => g
            .cells
            .iter()
            .flat_map(|r| r.chars())
            .filter(|&c| c == '.')
            .count(),
        Layout::Rings(r) => r.radii.len() * r.slots as usize,
    };
    layout + s.extra.iter().filter(|e| e.category == ".").count()
}

/// The legend character for a category, adding one when it has none.
fn legend_key(g: &mut GridLayout, category: &str) -> char {
    if let Some((k, _)) = g.legend.iter().find(|(_, v)| *v == category) {
        return k.chars().next().expect("legend keys are one character");
    }
    let taken: Vec<char> = g.legend.keys().filter_map(|k| k.chars().next()).collect();
    let preferred = category
        .chars()
        .next()
        .filter(|c| c.is_ascii_alphanumeric());
    let key = preferred
        .into_iter()
        .chain('a'..='z')
        .chain('A'..='Z')
        .chain('0'..='9')
        .find(|c| !taken.contains(c) && *c != '.' && *c != '-')
        .expect("a family has fewer than 62 fixed categories");
    g.legend.insert(key.to_string(), category.to_string());
    key
}

fn set_grid(s: &mut FamilySpec, size: u32, border: u32, frame: &str) -> Result<(), EditError> {
    if index(s, frame).is_none() {
        return Err(EditError::NoCategory(frame.to_string()));
    }
    if size == 0 || 2 * border >= size {
        return Err(EditError::Layout(format!(
            "a {size}×{size} grid cannot have a {border}-cell border and data inside"
        )));
    }
    let quiet_zone = match &s.layout {
        Layout::Grid(g) => g.quiet_zone,
        Layout::Rings(_) => 1.0,
    };
    let mut g = GridLayout {
        size,
        cells: Vec::new(),
        legend: Default::default(),
        quiet_zone,
    };
    let key = legend_key(&mut g, frame);
    let n = size as usize;
    let b = border as usize;
    g.cells = if border == 1 {
        framed_cells(n, key)
    } else {
        (0..n)
            .map(|r| {
                (0..n)
                    .map(|c| {
                        if r < b || c < b || r >= n - b || c >= n - b {
                            key
                        } else {
                            '.'
                        }
                    })
                    .collect()
            })
            .collect()
    };
    s.layout = Layout::Grid(g);
    let side = size as f64;
    s.roi.points = vec![[0.0, 0.0], [side, 0.0], [side, side], [0.0, side]];
    Ok(())
}

fn set_rings(
    s: &mut FamilySpec,
    radii: &[f64],
    slots: u32,
    dot_radius_ratio: f64,
    start_angle_deg: f64,
) -> Result<(), EditError> {
    if radii.is_empty() || slots == 0 {
        return Err(EditError::Layout(
            "a ring layout needs at least one ring with at least one slot".into(),
        ));
    }
    let quiet_zone = match &s.layout {
        Layout::Rings(r) => r.quiet_zone,
        Layout::Grid(_) => 0.2,
    };
    let switching = matches!(s.layout, Layout::Grid(_));
    s.layout = Layout::Rings(RingsLayout {
        radii: radii.to_vec(),
        slots,
        dot_radius_ratio,
        start_angle_deg,
        quiet_zone,
    });
    // Grid cell keys mean nothing on rings; the ROI of a fresh ring design is the square around
    // the outer ring, which the designer then refines by clicking.
    if switching {
        let r = radii.iter().cloned().fold(0.0, f64::max);
        s.roi.points = vec![[-r, -r], [r, -r], [r, r], [-r, r]];
        if let KeypointSet::Custom(_) = s.keypoint_set {
            s.keypoint_set = KeypointSet::All;
        }
    }
    Ok(())
}

fn set_cell(s: &mut FamilySpec, row: u32, col: u32, value: &CellValue) -> Result<(), EditError> {
    if let CellValue::Fixed(name) = value {
        if index(s, name).is_none() {
            return Err(EditError::NoCategory(name.clone()));
        }
    }
    let Layout::Grid(g) = &mut s.layout else {
        return Err(EditError::Layout("cells exist in grid layouts only".into()));
    };
    if row >= g.size || col >= g.size || g.cells.len() != g.size as usize {
        return Err(EditError::Layout(format!(
            "cell ({row}, {col}) is outside the {0}×{0} grid",
            g.size
        )));
    }
    let ch = match value {
        CellValue::Symbol => '.',
        CellValue::Empty => '-',
        CellValue::Fixed(name) => legend_key(g, name),
    };
    let line = &mut g.cells[row as usize];
    let mut chars: Vec<char> = line.chars().collect();
    if chars.len() != g.size as usize {
        return Err(EditError::Layout(format!(
            "row {row} of the cell map is malformed"
        )));
    }
    chars[col as usize] = ch;
    *line = chars.into_iter().collect();
    Ok(())
}

/// Undo and redo over whole specs (family files are small), keeping the last `limit` edits.
#[derive(Debug, Clone)]
pub struct History {
    current: FamilySpec,
    past: VecDeque<FamilySpec>,
    future: Vec<FamilySpec>,
    limit: usize,
    /// The group of the last edit, while it may still absorb the next one (see `apply_grouped`).
    open_group: Option<String>,
}

impl History {
    pub const DEFAULT_LIMIT: usize = 50;

    pub fn new(spec: FamilySpec) -> Self {
        Self {
            current: spec,
            past: VecDeque::new(),
            future: Vec::new(),
            limit: Self::DEFAULT_LIMIT,
            open_group: None,
        }
    }

    pub fn current(&self) -> &FamilySpec {
        &self.current
    }

    /// Applies an edit; on success it becomes undoable and clears the redo list.
    pub fn apply(&mut self, edit: &Edit) -> Result<(), EditError> {
        self.open_group = None;
        self.push(edit)
    }

    /// Applies an edit that continues a gesture (dragging a size slider sends one edit per frame):
    /// consecutive edits of the same `group` are one undo step. `end_group` closes the gesture.
    pub fn apply_grouped(&mut self, edit: &Edit, group: &str) -> Result<(), EditError> {
        if self.open_group.as_deref() == Some(group) && !self.past.is_empty() {
            let next = apply(&self.current, edit)?;
            self.current = next;
            self.future.clear();
            return Ok(());
        }
        self.push(edit)?;
        self.open_group = Some(group.to_string());
        Ok(())
    }

    pub fn end_group(&mut self) {
        self.open_group = None;
    }

    fn push(&mut self, edit: &Edit) -> Result<(), EditError> {
        let next = apply(&self.current, edit)?;
        if next != self.current {
            self.past
                .push_back(std::mem::replace(&mut self.current, next));
            if self.past.len() > self.limit {
                self.past.pop_front();
            }
            self.future.clear();
        }
        Ok(())
    }

    pub fn undo(&mut self) -> bool {
        self.open_group = None;
        match self.past.pop_back() {
            Some(prev) => {
                self.future.push(std::mem::replace(&mut self.current, prev));
                true
            }
            None => false,
        }
    }

    pub fn redo(&mut self) -> bool {
        self.open_group = None;
        match self.future.pop() {
            Some(next) => {
                self.past
                    .push_back(std::mem::replace(&mut self.current, next));
                true
            }
            None => false,
        }
    }

    pub fn can_undo(&self) -> usize {
        self.past.len()
    }

    pub fn can_redo(&self) -> usize {
        self.future.len()
    }
}

#[cfg(test)]
mod tests;
