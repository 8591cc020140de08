//! Renders against the regression images in `assets/golden/` (regenerate one with
//! `NIMBUS_UPDATE_GOLDEN=1 cargo test --test suite <test>` and say why), and the tests of
//! the golden-image harness itself.

mod image_harness;
mod render_box;
mod restir_golden;
