//! Integration tests of phalanx-io.
