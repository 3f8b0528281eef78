//! Integration tests of phalanx-io: round trips on real MovingAI files, the libMRP YAML
//! formats, the file helpers, every kind of bad input, and parsers that never panic.

mod bad_input;
mod files;
mod map;
mod no_panic;
mod scen;
mod yaml;

use std::path::PathBuf;

/// The checked-in fixtures, `test-data/movingai` at the workspace root.
pub(crate) fn test_data() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../test-data/movingai")
}

/// More MovingAI benchmark maps, the readers' own fixtures (`tests/maps`: four maps the
/// benchmark's `test-data/movingai` set does not hold).
pub(crate) fn more_maps() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/maps")
}
