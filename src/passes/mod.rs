//! One module per pass: each creates its pipeline and records its dispatch.

pub mod baseline;
pub mod crepuscular;
pub mod restir;
