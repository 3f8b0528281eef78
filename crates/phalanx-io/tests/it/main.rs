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

/// The shared benchmark maps in `../shared/maps/movingai` beside the checkout, when present
/// (`PHALANX_MAPS` overrides).
pub(crate) fn shared_maps() -> Option<PathBuf> {
    let beside = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/maps/movingai");
    let dir = std::env::var_os("PHALANX_MAPS").map_or(beside, PathBuf::from);
    dir.is_dir().then_some(dir)
}
