//! Blackbody emission of pyro media (`temperature`, `blackbody_scale`): the linear sRGB
//! radiance of a blackbody at T kelvin,
//!
//! RGB(T) = max(0, M · ∫ B_λ(T) (x̄, ȳ, z̄)(λ) dλ), λ from 360 to 830 nm,
//!
//! with B_λ Planck's spectral radiance in W/(m²·sr·nm), x̄ȳz̄ the CIE 1931 2° observer
//! ([`crate::cie1931`]) and M the XYZ → linear sRGB (D65) matrix of IEC 61966-2-1 (no
//! chromatic adaptation). [`blackbody_rgb`] integrates it (the trapezoid rule at every
//! nanometre); the renderers read [`BlackbodyTable`], RGB(T)/T tabulated uniformly in
//! 1/T, where ln RGB is nearly linear (Wien: RGB ∝ exp(−c/λkT)), so that linear
//! interpolation errs by the same few 1e-5 at 400 K as at 40 000 K, and RGB/T tends to the
//! Rayleigh–Jeans limit as T → ∞. Below [`BLACKBODY_MIN_KELVIN`] the radiance (under
//! 2e-16 W/(m²·sr)) is taken as 0.

use std::sync::OnceLock;

use anyhow::{bail, Result};
use glam::{DMat3, DVec3};

use crate::cie1931::{CIE_1931_XYZ, CIE_FIRST_NM, CIE_STEP_NM};
use crate::fields::MAX_RADIOMETRIC;
use crate::types::Temperature;

/// Planck's constant (J·s), the speed of light (m/s) and Boltzmann's constant (J/K), exact
/// in the SI since 2019.
const PLANCK_H: f64 = 6.626_070_15e-34;
const LIGHT_C: f64 = 299_792_458.0;
const BOLTZMANN_K: f64 = 1.380_649e-23;

/// Temperatures below this emit nothing (RGB(400 K) < 2e-16 W/(m²·sr)).
pub const BLACKBODY_MIN_KELVIN: f64 = 400.0;
/// Entries of [`BlackbodyTable`].
pub const BLACKBODY_TABLE_LEN: usize = 4096;

/// XYZ → linear sRGB (D65), IEC 61966-2-1.
fn xyz_to_srgb() -> DMat3 {
    DMat3::from_cols_array(&[
        3.2406, -0.9689, 0.0557, // column X
        -1.5372, 1.8758, -0.2040, // column Y
        -0.4986, 0.0415, 1.0570, // column Z
    ])
}

/// (x̄, ȳ, z̄) at `nm` (360..=830), linear between the table's 5 nm rows.
fn cie_xyz(nm: u32) -> DVec3 {
    let i = ((nm - CIE_FIRST_NM) / CIE_STEP_NM) as usize;
    let f = f64::from((nm - CIE_FIRST_NM) % CIE_STEP_NM) / f64::from(CIE_STEP_NM);
    let row = |i: usize| DVec3::from(CIE_1931_XYZ[i].map(f64::from));
    if f == 0.0 {
        row(i)
    } else {
        row(i).lerp(row(i + 1), f)
    }
}

/// Planck's spectral radiance at `nm` nanometres and `kelvin`, in W/(m²·sr·nm).
pub fn planck(nm: f64, kelvin: f64) -> f64 {
    let lambda = nm * 1e-9;
    let x = PLANCK_H * LIGHT_C / (lambda * BOLTZMANN_K * kelvin);
    2.0 * PLANCK_H * LIGHT_C * LIGHT_C / lambda.powi(5) / x.exp_m1() * 1e-9
}

/// The colour integral ∫ w(λ) (x̄, ȳ, z̄)(λ) dλ over 360..830 nm by the trapezoid rule at
/// every nanometre, in linear sRGB, negative channels clamped to 0.
fn integrate(w: impl Fn(f64) -> f64) -> DVec3 {
    let last = CIE_FIRST_NM + CIE_STEP_NM * (CIE_1931_XYZ.len() as u32 - 1);
    let xyz = (CIE_FIRST_NM..=last).fold(DVec3::ZERO, |sum, nm| {
        let weight = if nm == CIE_FIRST_NM || nm == last {
            0.5
        } else {
            1.0
        };
        sum + cie_xyz(nm) * (weight * w(f64::from(nm)))
    });
    (xyz_to_srgb() * xyz).max(DVec3::ZERO)
}

/// RGB(T) in W/(m²·sr), integrated (see the module docs); 0 below
/// [`BLACKBODY_MIN_KELVIN`] and for NaN.
pub fn blackbody_rgb(kelvin: f64) -> DVec3 {
    if kelvin.is_nan() || kelvin < BLACKBODY_MIN_KELVIN {
        return DVec3::ZERO;
    }
    integrate(|nm| planck(nm, kelvin))
}

/// lim RGB(T)/T as T → ∞ (Rayleigh–Jeans: B_λ → 2ckT/λ⁴).
fn rayleigh_jeans_per_kelvin() -> DVec3 {
    integrate(|nm| {
        let lambda = nm * 1e-9;
        2.0 * LIGHT_C * BOLTZMANN_K / lambda.powi(4) * 1e-9
    })
}

/// RGB(T)/T at [`BLACKBODY_TABLE_LEN`] points uniform in u = 1/T from 0 (T = ∞, the
/// Rayleigh–Jeans limit) to 1/[`BLACKBODY_MIN_KELVIN`]: entry i is at
/// u = i / ((LEN − 1) · MIN_KELVIN). The GPU reads it as a vec4 per entry (alpha 0).
pub struct BlackbodyTable {
    pub entries: Vec<[f32; 4]>,
    exact: Vec<DVec3>,
}

impl BlackbodyTable {
    /// The table, computed once per process.
    pub fn get() -> &'static BlackbodyTable {
        static TABLE: OnceLock<BlackbodyTable> = OnceLock::new();
        TABLE.get_or_init(|| {
            let last = (BLACKBODY_TABLE_LEN - 1) as f64;
            let exact: Vec<DVec3> = (0..BLACKBODY_TABLE_LEN)
                .map(|i| match i {
                    0 => rayleigh_jeans_per_kelvin(),
                    _ => {
                        let kelvin = BLACKBODY_MIN_KELVIN * last / i as f64;
                        blackbody_rgb(kelvin) / kelvin
                    }
                })
                .collect();
            let entries = exact
                .iter()
                .map(|v| [v.x as f32, v.y as f32, v.z as f32, 0.0])
                .collect();
            BlackbodyTable { entries, exact }
        })
    }

    /// RGB(T) as the renderers interpolate it (the GPU in f32, this in f64): 0 below
    /// [`BLACKBODY_MIN_KELVIN`] or for NaN; +inf stays +inf.
    pub fn rgb(&self, kelvin: f64) -> DVec3 {
        if kelvin.is_nan() || kelvin < BLACKBODY_MIN_KELVIN {
            return DVec3::ZERO;
        }
        let x = BLACKBODY_MIN_KELVIN * (BLACKBODY_TABLE_LEN - 1) as f64 / kelvin;
        let i = (x as usize).min(BLACKBODY_TABLE_LEN - 2);
        let per_kelvin = self.exact[i].lerp(self.exact[i + 1], x - i as f64);
        per_kelvin * kelvin
    }
}

impl Temperature {
    /// T in kelvin at a grid value `value`.
    pub fn kelvin(&self, value: f64) -> f64 {
        f64::from(self.offset) + f64::from(self.scale) * value
    }

    /// Le at a grid value `value`: `blackbody_scale` · RGB(T), as the renderers
    /// interpolate RGB ([`BlackbodyTable::rgb`]).
    pub fn radiance(&self, value: f64) -> DVec3 {
        BlackbodyTable::get().rgb(self.kelvin(value)) * f64::from(self.blackbody_scale)
    }

    /// Refuses a grid whose largest value `max` (at `voxel`, described as the caller
    /// likes) glows brighter than [`MAX_RADIOMETRIC`] (or not finitely). `what` names
    /// the grid, e.g. `"scenes/a.toml: [[medium]] #1 > temperature"`. RGB(T) grows with
    /// T and `scale` ≥ 0, so the largest value is the brightest.
    pub fn check_brightest(&self, max: f32, voxel: &str, what: &str) -> Result<()> {
        let le = self.radiance(f64::from(max)).max_element();
        if le.is_nan() || le > MAX_RADIOMETRIC {
            bail!(
                "{what}: value {max} at {voxel} is {} K, where field `blackbody_scale` × \
                 RGB(T) = {le:e} W/(m²·sr); emitted radiance must be <= {MAX_RADIOMETRIC:e} \
                 (lower `blackbody_scale`, `temperature_scale` or `temperature_offset`)",
                self.kelvin(f64::from(max))
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The anchor: RGB(6500 K) ≈ (4.69, 4.43, 4.66) · 10⁶ W/(m²·sr).
    #[test]
    fn rgb_at_6500_kelvin_matches_the_published_value() {
        let rgb = blackbody_rgb(6500.0) / 1e6;
        let want = DVec3::new(4.69, 4.43, 4.66);
        assert!((rgb - want).abs().max_element() < 0.006, "{rgb}");
    }

    #[test]
    fn the_table_interpolates_within_1e_4_from_400_kelvin_to_a_million() {
        let table = BlackbodyTable::get();
        let mut kelvin = BLACKBODY_MIN_KELVIN;
        while kelvin < 1e6 {
            let (exact, looked_up) = (blackbody_rgb(kelvin), table.rgb(kelvin));
            for c in 0..3 {
                // Channels clamped to 0 may cross zero inside an interval: compare them
                // against the largest channel.
                let err = (looked_up[c] - exact[c]).abs() / exact.max_element();
                assert!(err < 1e-4, "{kelvin} K channel {c}: {looked_up} vs {exact}");
            }
            kelvin *= 1.0137;
        }
    }

    #[test]
    fn below_the_cut_nan_and_infinity_stay_defined() {
        let table = BlackbodyTable::get();
        assert_eq!(table.rgb(399.9), DVec3::ZERO);
        assert_eq!(table.rgb(f64::NAN), DVec3::ZERO);
        assert_eq!(table.rgb(-5.0), DVec3::ZERO);
        assert!(!table.rgb(f64::INFINITY).is_finite());
        assert!(blackbody_rgb(BLACKBODY_MIN_KELVIN).max_element() < 2e-16);
        assert!(table
            .entries
            .iter()
            .flatten()
            .all(|v| v.is_finite() && *v >= 0.0));
    }
}
