//! Studio GUI tests (egui_kittest).
