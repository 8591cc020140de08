//! Typed access to one TOML table with error messages that name the file, the table
//! and the field.

use std::fmt::Display;
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, Error, Result};
use glam::{DVec3, Vec3};
use toml::Value;

/// What every error message starts with: the scene file, and where relative paths
/// resolve.
pub(crate) struct Source<'a> {
    pub file: &'a Path,
}

impl Source<'_> {
    /// An error about the whole file (no table).
    pub fn error(&self, message: impl Display) -> Error {
        anyhow!("{}: {message}", self.file.display())
    }

    /// `path` from the scene file resolved against the scene file's directory.
    pub fn resolve(&self, path: &str) -> PathBuf {
        let path = Path::new(path);
        match self.file.parent() {
            Some(dir) if path.is_relative() => dir.join(path),
            _ => path.to_path_buf(),
        }
    }
}

/// The TOML type name of `value`, for "expected X, found Y" messages.
pub(crate) fn type_name(value: &Value) -> &'static str {
    match value {
        Value::String(_) => "a string",
        Value::Integer(_) => "an integer",
        Value::Float(_) => "a float",
        Value::Boolean(_) => "a boolean",
        Value::Datetime(_) => "a datetime",
        Value::Array(_) => "an array",
        Value::Table(_) => "a table",
    }
}

/// A number (integer or float) as f64.
fn as_number(value: &Value) -> Option<f64> {
    match value {
        Value::Integer(i) => Some(*i as f64),
        Value::Float(f) => Some(*f),
        _ => None,
    }
}

/// One TOML table being read: `name` is how errors refer to it (e.g. `[[light]] #2
/// (type = "point")`).
pub(crate) struct Fields<'a> {
    pub source: &'a Source<'a>,
    pub name: String,
    map: &'a toml::Table,
}

impl<'a> Fields<'a> {
    /// Wraps `map`, rejecting every key not in `allowed`.
    pub fn new(
        source: &'a Source<'a>,
        name: String,
        map: &'a toml::Table,
        allowed: &[&str],
    ) -> Result<Self> {
        let fields = Self { source, name, map };
        let mut unknown: Vec<&String> = map
            .keys()
            .filter(|key| !allowed.contains(&key.as_str()))
            .collect();
        unknown.sort();
        if let Some(key) = unknown.first() {
            return Err(fields.error(
                key,
                format!("unknown field; valid fields here: {}", allowed.join(", ")),
            ));
        }
        Ok(fields)
    }

    /// An error about `field` of this table.
    pub fn error(&self, field: &str, message: impl Display) -> Error {
        anyhow!(
            "{}: {}: field `{field}`: {message}",
            self.source.file.display(),
            self.name
        )
    }

    pub fn has(&self, key: &str) -> bool {
        self.map.contains_key(key)
    }

    /// Whether `key` is given as a table.
    pub fn is_table(&self, key: &str) -> bool {
        matches!(self.map.get(key), Some(Value::Table(_)))
    }

    fn required<T>(&self, key: &str, value: Option<T>) -> Result<T> {
        value.ok_or_else(|| self.error(key, "missing required field"))
    }

    fn wrong_type(&self, key: &str, expected: &str, found: &Value) -> Error {
        self.error(
            key,
            format!("expected {expected}, found {}", type_name(found)),
        )
    }

    /// A finite number, as f64.
    pub fn opt_f64(&self, key: &str) -> Result<Option<f64>> {
        let Some(value) = self.map.get(key) else {
            return Ok(None);
        };
        let number = as_number(value).ok_or_else(|| self.wrong_type(key, "a number", value))?;
        check_finite_f32(number).map_err(|message| self.error(key, message))?;
        Ok(Some(number))
    }

    /// A finite number in `range` (inclusive), as f32.
    pub fn f32_in(
        &self,
        key: &str,
        default: Option<f32>,
        range: RangeInclusive<f64>,
    ) -> Result<f32> {
        let value = match self.opt_f64(key)? {
            Some(value) => value,
            None => return self.required(key, default),
        };
        if !range.contains(&value) {
            return Err(self.error(
                key,
                format!(
                    "{} is out of range, must be in [{}, {}]",
                    show(value),
                    range.start(),
                    range.end()
                ),
            ));
        }
        // The renderer sees the f32: check it too.
        let v32 = value as f32;
        if !range.contains(&f64::from(v32)) {
            return Err(self.error(
                key,
                format!(
                    "{value} becomes {v32} as a 32-bit float, out of range [{}, {}]",
                    range.start(),
                    range.end()
                ),
            ));
        }
        Ok(v32)
    }

    /// A finite number with `check` (returns a complaint for a bad value).
    pub fn f32_with(
        &self,
        key: &str,
        default: Option<f32>,
        check: impl Fn(f64) -> Option<String>,
    ) -> Result<f32> {
        let value = match self.opt_f64(key)? {
            Some(value) => value,
            None => return self.required(key, default),
        };
        if let Some(message) = check(value) {
            return Err(self.error(key, format!("{} is out of range, {message}", show(value))));
        }
        // The renderer sees the f32: check it too (179.999999999 rounds to 180).
        let v32 = value as f32;
        if let Some(message) = check(f64::from(v32)) {
            return Err(self.error(
                key,
                format!(
                    "{value} becomes {v32} as a 32-bit float, which is out of range: {message}"
                ),
            ));
        }
        Ok(v32)
    }

    /// An integer in `range`, or `default` when absent (required when `default` is
    /// `None`).
    pub fn int_in(
        &self,
        key: &str,
        default: Option<i64>,
        range: RangeInclusive<i64>,
    ) -> Result<i64> {
        let value = match self.map.get(key) {
            Some(Value::Integer(i)) => *i,
            Some(other) => return Err(self.wrong_type(key, "an integer", other)),
            None => return self.required(key, default),
        };
        if !range.contains(&value) {
            return Err(self.error(
                key,
                format!(
                    "{value} is out of range, must be in [{}, {}]",
                    range.start(),
                    range.end()
                ),
            ));
        }
        Ok(value)
    }

    /// An integer in `range` that fits a u32.
    pub fn u32_in(
        &self,
        key: &str,
        default: Option<u32>,
        range: RangeInclusive<u32>,
    ) -> Result<u32> {
        let range = i64::from(*range.start())..=i64::from(*range.end());
        let value = self.int_in(key, default.map(i64::from), range)?;
        u32::try_from(value).map_err(|_| self.error(key, "does not fit in 32 bits"))
    }

    /// An integer in `range`, or the string `"auto"` (`None`); absent gives `default`.
    pub fn u32_or_auto(
        &self,
        key: &str,
        default: Option<u32>,
        range: RangeInclusive<u32>,
    ) -> Result<Option<u32>> {
        match self.map.get(key) {
            None => Ok(default),
            Some(Value::String(s)) if s == "auto" => Ok(None),
            Some(Value::String(s)) => Err(self.error(
                key,
                format!(
                    "\"{s}\" is not \"auto\" or an integer in [{}, {}]",
                    range.start(),
                    range.end()
                ),
            )),
            Some(Value::Integer(_)) => self.u32_in(key, None, range).map(Some),
            Some(other) => Err(self.wrong_type(key, "an integer or \"auto\"", other)),
        }
    }

    /// A number in `range`, or `"auto"` (`None`); `default` when absent.
    pub fn f32_or_auto(
        &self,
        key: &str,
        default: Option<f32>,
        range: RangeInclusive<f64>,
    ) -> Result<Option<f32>> {
        match self.map.get(key) {
            None => Ok(default),
            Some(Value::String(s)) if s == "auto" => Ok(None),
            Some(Value::String(s)) => Err(self.error(
                key,
                format!(
                    "\"{s}\" is not \"auto\" or a number in [{}, {}]",
                    range.start(),
                    range.end()
                ),
            )),
            Some(Value::Integer(_) | Value::Float(_)) => self.f32_in(key, None, range).map(Some),
            Some(other) => Err(self.wrong_type(key, "a number or \"auto\"", other)),
        }
    }

    pub fn opt_bool(&self, key: &str) -> Result<Option<bool>> {
        match self.map.get(key) {
            Some(Value::Boolean(b)) => Ok(Some(*b)),
            Some(other) => Err(self.wrong_type(key, "a boolean (true or false)", other)),
            None => Ok(None),
        }
    }

    /// `true`, `false` or the string `"auto"` (`None`); absent gives `default`.
    pub fn bool_or_auto(&self, key: &str, default: Option<bool>) -> Result<Option<bool>> {
        match self.map.get(key) {
            None => Ok(default),
            Some(Value::Boolean(b)) => Ok(Some(*b)),
            Some(Value::String(s)) if s == "auto" => Ok(None),
            Some(Value::String(s)) => {
                Err(self.error(key, format!("\"{s}\" is not true, false or \"auto\"")))
            }
            Some(other) => Err(self.wrong_type(key, "a boolean or \"auto\"", other)),
        }
    }

    pub fn opt_str(&self, key: &str) -> Result<Option<&'a str>> {
        match self.map.get(key) {
            Some(Value::String(s)) => Ok(Some(s.as_str())),
            Some(other) => Err(self.wrong_type(key, "a string", other)),
            None => Ok(None),
        }
    }

    /// One of `names` (a string), mapped to its value; absent gives `default`.
    pub fn choice<T: Copy>(&self, key: &str, default: Option<T>, names: &[(&str, T)]) -> Result<T> {
        let Some(name) = self.opt_str(key)? else {
            return self.required(key, default);
        };
        names
            .iter()
            .find(|(candidate, _)| *candidate == name)
            .map(|(_, value)| *value)
            .ok_or_else(|| {
                let valid: Vec<String> = names.iter().map(|(n, _)| format!("\"{n}\"")).collect();
                self.error(
                    key,
                    format!(
                        "unknown value \"{name}\"; valid values: {}",
                        valid.join(", ")
                    ),
                )
            })
    }

    /// An array of exactly `N` finite numbers.
    pub fn opt_numbers<const N: usize>(&self, key: &str) -> Result<Option<[f64; N]>> {
        let Some(value) = self.map.get(key) else {
            return Ok(None);
        };
        parse_numbers(value)
            .map(Some)
            .map_err(|message| self.error(key, message))
    }

    /// A 3-vector (array of 3 numbers) in f64, or `default`.
    pub fn vec3_f64(&self, key: &str, default: Option<DVec3>) -> Result<DVec3> {
        match self.opt_numbers::<3>(key)? {
            Some(v) => Ok(DVec3::from_array(v)),
            None => self.required(key, default),
        }
    }

    /// A 3-vector (array of 3 numbers), or `default`.
    pub fn vec3(&self, key: &str, default: Option<Vec3>) -> Result<Vec3> {
        Ok(self.vec3_f64(key, default.map(|v| v.as_dvec3()))?.as_vec3())
    }

    /// Rotation angles in degrees (an array of 3 numbers), or `default`. An angle past
    /// one turn is reduced to within one, exactly (f64 `%`): the renderer's rotation is
    /// f32, whose sine of a huge argument is noise unrelated to the f64 one the overlap
    /// test uses (`rotation_deg = [1e30, 0, 0]` placed the box one way for the overlap
    /// test and another for the renderer). Angles within one turn are kept bit for bit.
    pub fn angles_deg(&self, key: &str, default: Option<DVec3>) -> Result<DVec3> {
        let v = self.vec3_f64(key, default)?;
        Ok(DVec3::from_array(
            v.to_array().map(crate::types::reduce_degrees),
        ))
    }

    /// One angle in degrees, or `default`: any finite number (see
    /// [`Fields::opt_f64`]), NOT reduced (the caller decides: a keyframe's angle is
    /// interpolated unwrapped).
    pub fn angle_deg(&self, key: &str, default: Option<f64>) -> Result<f64> {
        match self.opt_f64(key)? {
            Some(a) => Ok(a),
            None => self.required(key, default),
        }
    }

    /// A unit direction: an array of 3 numbers that is not the zero vector, normalized.
    pub fn direction(&self, key: &str, default: Option<DVec3>) -> Result<DVec3> {
        let v = self.vec3_f64(key, default)?;
        let length = v.length();
        if length == 0.0 || !length.is_finite() {
            return Err(self.error(key, "must not be the zero vector"));
        }
        Ok(v / length)
    }

    /// A colour: a number x (meaning [x, x, x]) or an array of 3 numbers, each checked
    /// by `check`.
    pub fn color(
        &self,
        key: &str,
        default: Option<Vec3>,
        check: impl Fn(f64) -> Option<String>,
    ) -> Result<Vec3> {
        let rgb = match self.map.get(key) {
            None => return self.required(key, default),
            Some(value) => match as_number(value) {
                Some(x) => {
                    check_finite_f32(x).map_err(|message| self.error(key, message))?;
                    [x; 3]
                }
                None if matches!(value, Value::Array(_)) => {
                    parse_numbers::<3>(value).map_err(|message| self.error(key, message))?
                }
                None => {
                    return Err(self.wrong_type(
                        key,
                        "a colour (a number or an array of 3 numbers)",
                        value,
                    ))
                }
            },
        };
        for (channel, x) in rgb.iter().enumerate() {
            if let Some(message) = check(*x) {
                return Err(self.error(
                    key,
                    format!("component {channel} is {}, {message}", show(*x)),
                ));
            }
            let x32 = *x as f32;
            if let Some(message) = check(f64::from(x32)) {
                return Err(self.error(
                    key,
                    format!("component {channel} is {x}, which becomes {x32} as a 32-bit float: {message}"),
                ));
            }
        }
        Ok(DVec3::from_array(rgb).as_vec3())
    }

    pub fn opt_table(&self, key: &str) -> Result<Option<&'a toml::Table>> {
        match self.map.get(key) {
            Some(Value::Table(t)) => Ok(Some(t)),
            Some(other) => Err(self.wrong_type(key, "a table", other)),
            None => Ok(None),
        }
    }

    /// An array of tables (`[[key]]`), empty when absent.
    pub fn tables(&self, key: &str) -> Result<Vec<&'a toml::Table>> {
        match self.map.get(key) {
            None => Ok(Vec::new()),
            Some(Value::Array(items)) => items
                .iter()
                .enumerate()
                .map(|(i, item)| match item {
                    Value::Table(t) => Ok(t),
                    other => Err(self.error(
                        key,
                        format!(
                            "expected an array of tables ([[{key}]]), item {} is {}",
                            i + 1,
                            type_name(other)
                        ),
                    )),
                })
                .collect(),
            Some(other) => {
                Err(self.wrong_type(key, &format!("an array of tables ([[{key}]])"), other))
            }
        }
    }

    /// The raw value of `key`.
    pub fn value(&self, key: &str) -> Option<&'a Value> {
        self.map.get(key)
    }
}

/// A number for a message: plain when short, in scientific notation when very large or
/// small (1e38 rather than 39 digits).
pub(crate) fn show(x: f64) -> String {
    let a = x.abs();
    if a != 0.0 && !(1e-4..1e7).contains(&a) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// Rejects NaN, infinities and values too large for f32.
fn check_finite_f32(x: f64) -> std::result::Result<(), String> {
    if !x.is_finite() {
        return Err(format!("must be a finite number, found {x}"));
    }
    if !(x as f32).is_finite() {
        return Err(format!("{x} is too large for 32-bit floats"));
    }
    Ok(())
}

/// An array of exactly `N` finite numbers.
pub(crate) fn parse_numbers<const N: usize>(
    value: &Value,
) -> std::result::Result<[f64; N], String> {
    let Value::Array(items) = value else {
        return Err(format!(
            "expected an array of {N} numbers, found {}",
            type_name(value)
        ));
    };
    if items.len() != N {
        return Err(format!(
            "expected an array of {N} numbers, found {} elements",
            items.len()
        ));
    }
    let mut out = [0.0; N];
    for (i, item) in items.iter().enumerate() {
        let x = as_number(item).ok_or_else(|| {
            format!(
                "expected an array of {N} numbers, element {i} is {}",
                type_name(item)
            )
        })?;
        check_finite_f32(x).map_err(|message| format!("element {i}: {message}"))?;
        out[i] = x;
    }
    Ok(out)
}

/// Complaint for a value that must be >= 0.
pub(crate) fn non_negative(x: f64) -> Option<String> {
    (x < 0.0).then(|| "must be >= 0".to_string())
}

/// Largest radiometric input (irradiance W/m², radiance W/(m²·sr), intensity W/sr,
/// emission), after any scale. Pixel values are accumulated as sums of x and x² in f32:
/// this leaves a factor of 1e7 for geometry (a point light a millimetre away) before x²
/// summed over a million frames could overflow.
pub const MAX_RADIOMETRIC: f64 = 1e12;

/// Complaint for a radiometric value outside [0, [`MAX_RADIOMETRIC`]].
pub(crate) fn radiometric(x: f64) -> Option<String> {
    (!(0.0..=MAX_RADIOMETRIC).contains(&x))
        .then(|| format!("must be >= 0 and <= {MAX_RADIOMETRIC:e} (the largest radiometric input)"))
}

/// Complaint for a value outside [0, 1].
pub(crate) fn unit_interval(x: f64) -> Option<String> {
    (!(0.0..=1.0).contains(&x)).then(|| "must be in [0, 1]".to_string())
}

/// Complaint for a value outside (lo, hi).
pub(crate) fn open_interval(lo: f64, hi: f64) -> impl Fn(f64) -> Option<String> {
    move |x| (!(x > lo && x < hi)).then(|| format!("must be in ({lo}, {hi}) (exclusive)"))
}

/// Complaint for a length outside (0, max].
pub(crate) fn positive_up_to(max: f64) -> impl Fn(f64) -> Option<String> {
    move |x| (!(x > 0.0 && x <= max)).then(|| format!("must be > 0 and <= {max}"))
}
