//! The Tagsmith studio as a library, so that the desktop binary, the web build and the GUI tests
//! run the same code.

pub mod settings;
pub mod studio;

#[cfg(target_arch = "wasm32")]
pub mod web;
