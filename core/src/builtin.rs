//! The built-in families (the JSON files in `families/`), compiled into the library so that the
//! CLI, the studio and the web build have them without a file system.

use crate::family::{from_json_str, Family, FamilyError};

macro_rules! families {
    ($($name:literal),* $(,)?) => {
        /// (name, JSON text) of every built-in family.
        pub const SOURCES: &[(&str, &str)] = &[
            $(($name, include_str!(concat!("../../families/", $name, ".json")))),*
        ];
    };
}

families!(
    "apriltag-16h5",
    "apriltag-25h9",
    "apriltag-36h11",
    "aruco-4x4_50",
    "aruco-5x5_100",
    "aruco-6x6_250",
    "aruco-mip-36h12",
    "artoolkitplus-bch",
    "apriltag-standard41h12",
    "apriltag-circle21h7",
    "apriltag-xo-36h11",
    "apriltag-xa-36h11",
    "quaternary-6x6",
    "runetag",
    "runetag-plus",
    "topotag-like",
);

/// Names of the built-in families.
pub fn names() -> impl Iterator<Item = &'static str> {
    SOURCES.iter().map(|(n, _)| *n)
}

/// Loads a built-in family by name.
pub fn get(name: &str) -> Option<Result<Family, FamilyError>> {
    SOURCES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(n, json)| from_json_str(json).map_err(|e| e.in_file(format!("families/{n}.json"))))
}
