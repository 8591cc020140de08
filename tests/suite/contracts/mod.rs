//! What the code promises itself: record layouts and pipeline contracts against the
//! compiled SPIR-V, memory footprints against what passes create, work counters against
//! their pinned baseline.

mod budget;
mod contract;
mod counters;
mod layout;
