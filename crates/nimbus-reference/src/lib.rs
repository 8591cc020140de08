//! CPU oracles for Nimbus.

pub(crate) mod common;
pub mod grid;
pub mod mc;
pub mod quadrature;
