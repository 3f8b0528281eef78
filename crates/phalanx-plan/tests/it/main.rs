//! Integration tests of phalanx-plan's space-time A*, CBS and ECBS: validity (the
//! `phalanx_core::validate` oracle), optimality against a brute-force joint search on tiny
//! instances, unsolvable and budget outcomes, determinism.

mod brute;
mod cbs_tests;
mod figures;
mod fixture;
mod slow;
