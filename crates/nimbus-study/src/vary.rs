//! What a study varies: the `--vary KEY=V1,V2,...` lists, the keys they accept and how
//! each sets the scene ([`apply`]), their cartesian product, the series that
//! configurations fall into, and the `--baseline` series.

use anyhow::{anyhow, bail, ensure, Result};
use nimbus_scene::{BoxEstimator, Scene, VolumeIntegrator};

/// The keys `--vary` (and `--baseline`) accept besides the ReSTIR knobs, in the order
/// [`apply`] lists them.
const GENERAL_KEYS: [&str; 7] = [
    "box_estimator",
    "spp",
    "box_samples",
    "frames",
    "seed",
    "max_bounces",
    "volume",
];

/// Every key `--vary` accepts: [`GENERAL_KEYS`], then the fields of
/// `[integrator.restir]` (the scene crate's list, so the two cannot drift apart).
pub fn keys() -> Vec<&'static str> {
    GENERAL_KEYS
        .iter()
        .chain(nimbus_scene::RESTIR_KEYS)
        .copied()
        .collect()
}

/// The keys that buy accuracy with time: configurations differing only in these form
/// one series (one polyline of the plot).
pub(super) const KNOB_KEYS: [&str; 3] = ["spp", "frames", "box_samples"];

/// The keys that change what the image converges to (the integrand), so that each of
/// their values needs its own reference: `max_bounces` (K, the scattering orders
/// summed). The others change how it is estimated: the estimators and `volume` (the
/// same integral), spp, frames and seeds (how many samples, which ones), and the
/// ReSTIR knobs (unbiased reuse). An animated scene's frames are scene frames, so a
/// study of one refuses `--vary frames` (each frame has its own reference).
pub(super) const INTEGRAND_KEYS: [&str; 1] = ["max_bounces"];

/// The `[integrator] volume` names of the scene format.
const VOLUME_INTEGRATORS: [(&str, VolumeIntegrator); 2] = [
    ("restir", VolumeIntegrator::Restir),
    ("baseline", VolumeIntegrator::Baseline),
];

/// Sets `key` = `value` on `scene`. Returns the `box_samples` override for
/// [`plan::build`](nimbus::plan::build) when the key is `box_samples` (the scene's field
/// is set as well).
///
/// Errors name the key and list what it accepts; the message is meant to be prefixed
/// with the flag it came from.
pub(super) fn apply(scene: &mut Scene, key: &str, value: &str) -> Result<Option<u32>> {
    let value = value.trim();
    match key {
        "box_estimator" => {
            scene.integrator.box_estimator = BoxEstimator::ALL
                .into_iter()
                .find(|e| e.name() == value)
                .ok_or_else(|| {
                    let names: Vec<_> = BoxEstimator::ALL.iter().map(|e| e.name()).collect();
                    anyhow!(
                        "box_estimator: unknown estimator {value:?}; valid: {}",
                        names.join(", ")
                    )
                })?;
        }
        "spp" => scene.render.spp = parse_count(key, value, 65_536)?,
        "box_samples" => {
            let n = parse_count(key, value, 65_536)?;
            scene.integrator.box_samples = n;
            return Ok(Some(n));
        }
        "frames" => scene.render.frames = parse_count(key, value, 1_000_000)?,
        "seed" => {
            scene.render.seed = value
                .parse()
                .map_err(|_| anyhow!("seed: {value:?} is not an unsigned 64-bit integer"))?;
        }
        "max_bounces" => scene.integrator.max_bounces = parse_count(key, value, 1024)?,
        "volume" => {
            scene.integrator.volume = VOLUME_INTEGRATORS
                .into_iter()
                .find(|(name, _)| *name == value)
                .map(|(_, v)| v)
                .ok_or_else(|| {
                    let names: Vec<_> = VOLUME_INTEGRATORS.iter().map(|(n, _)| *n).collect();
                    anyhow!(
                        "volume: unknown integrator {value:?}; valid: {}",
                        names.join(", ")
                    )
                })?;
        }
        "candidates" => scene.integrator.restir.candidates = parse_count(key, value, 4096)?,
        "temporal" => scene.integrator.restir.temporal = parse_bool(key, value)?,
        "temporal_limit" => {
            scene.integrator.restir.temporal_limit = parse_count(key, value, 1024)?;
        }
        "temporal_limit_moving" => {
            scene.integrator.restir.temporal_limit_moving = parse_count(key, value, 1024)?;
        }
        "spatial_neighbors" => {
            scene.integrator.restir.spatial_neighbors =
                parse_range(key, value, 0, nimbus_scene::MAX_SPATIAL_NEIGHBORS)?;
        }
        "spatial_radius_px" => {
            scene.integrator.restir.spatial_radius_px = match value.parse::<f32>() {
                _ if value == "auto" => None,
                Ok(r) if (0.0..=16384.0).contains(&r) => Some(r),
                _ => bail!("{key}: {value:?} is not a number in [0, 16384] or auto"),
            };
        }
        "spatial_when" => {
            scene.integrator.restir.spatial_when = match value {
                "always" => nimbus_scene::SpatialWhen::Always,
                "camera_moves" => nimbus_scene::SpatialWhen::CameraMoves,
                "camera_or_density" => nimbus_scene::SpatialWhen::CameraOrDensity,
                _ => bail!(
                    "{key}: unknown choice {value:?}; valid: always, camera_moves, camera_or_density"
                ),
            };
        }
        "spatial_rounds" => {
            scene.integrator.restir.spatial_rounds = parse_range(key, value, 0, 16)?;
        }
        "emission" => {
            scene.integrator.restir.fold_emission = match value {
                "separate" => false,
                "folded" => true,
                _ => bail!("{key}: unknown choice {value:?}; valid: separate, folded"),
            };
        }
        "spatial_max_history" => {
            scene.integrator.restir.spatial_max_history = match value.parse::<f32>() {
                Ok(r) if (0.0..=1025.0).contains(&r) => r,
                _ => bail!("{key}: {value:?} is not a number in [0, 1025]"),
            };
        }
        "spatial_feature_tolerance" => {
            scene.integrator.restir.spatial_feature_tolerance = match value.parse::<f32>() {
                Ok(r) if (0.0..=1.0).contains(&r) => r,
                _ => bail!("{key}: {value:?} is not a number in [0, 1]"),
            };
        }
        "spatial_anchor" => scene.integrator.restir.spatial_anchor = parse_bool(key, value)?,
        "reuse" => {
            scene.integrator.restir.reuse = match value {
                "direction" => nimbus_scene::ReuseMode::Direction,
                "vertex" => nimbus_scene::ReuseMode::Vertex,
                _ => bail!("{key}: unknown reuse {value:?}; valid: direction, vertex"),
            };
        }
        "mip_candidates" => {
            scene.integrator.restir.mip_candidates = parse_range(key, value, 0, 16)?
        }
        "mip_indirect" => scene.integrator.restir.mip_indirect = parse_level(key, value)?,
        "mip_reuse" => scene.integrator.restir.mip_reuse = parse_level(key, value)?,
        "final_transmittance" => {
            scene.integrator.restir.final_ratio_tracking = match value {
                "analytic" => false,
                "ratio" => true,
                _ => bail!("{key}: unknown transmittance {value:?}; valid: analytic, ratio"),
            };
        }
        "mis" => {
            scene.integrator.restir.mis = match value {
                "talbot" => nimbus_scene::MisMode::Talbot,
                "pairwise" => nimbus_scene::MisMode::Pairwise,
                _ => bail!("{key}: unknown MIS {value:?}; valid: talbot, pairwise"),
            };
        }
        "spatial_shift" => {
            scene.integrator.restir.spatial_shift = match value {
                "distance" => nimbus_scene::SpatialShift::Distance,
                "optical_depth" => nimbus_scene::SpatialShift::OpticalDepth,
                _ => bail!("{key}: unknown shift {value:?}; valid: distance, optical_depth"),
            };
        }
        "env_reuse" => {
            scene.integrator.restir.env_reuse = match value {
                "map" => nimbus_scene::EnvReuse::Map,
                "world" => nimbus_scene::EnvReuse::World,
                _ => bail!("{key}: unknown choice {value:?}; valid: map, world"),
            };
        }
        "temporal_history" => {
            scene.integrator.restir.temporal_history = match value {
                "spatial" => nimbus_scene::HistoryMode::Spatial,
                "temporal" => nimbus_scene::HistoryMode::Temporal,
                _ => bail!("{key}: unknown history {value:?}; valid: spatial, temporal"),
            };
        }
        "nee" => {
            scene.integrator.restir.nee = match value {
                "auto" => nimbus_scene::NeeMode::Auto,
                "one" => nimbus_scene::NeeMode::One,
                "split" => nimbus_scene::NeeMode::Split,
                _ => {
                    bail!("{key}: unknown next-event estimation {value:?}; valid: auto, one, split")
                }
            };
        }
        "direct" => {
            scene.integrator.restir.direct = match value {
                "each_walk" => nimbus_scene::DirectMode::EachWalk,
                "escape" => nimbus_scene::DirectMode::Escape,
                _ => bail!("{key}: unknown direct candidate {value:?}; valid: each_walk, escape"),
            };
        }
        "candidate_tracking" => {
            scene.integrator.restir.candidate_tracking = match value {
                "auto" => nimbus_scene::CandidateTracking::Auto,
                "delta" => nimbus_scene::CandidateTracking::Delta,
                "regular" => nimbus_scene::CandidateTracking::Regular,
                _ => bail!("{key}: unknown tracking {value:?}; valid: auto, delta, regular"),
            };
        }
        "pc_fetch" => {
            scene.integrator.restir.pc_fetch = match value {
                "auto" => nimbus_scene::DensityFetch::Auto,
                "image" => nimbus_scene::DensityFetch::Image,
                "buffer" => nimbus_scene::DensityFetch::Buffer,
                _ => bail!("{key}: unknown place {value:?}; valid: auto, image, buffer"),
            };
        }
        "target" => {
            scene.integrator.restir.target = match value {
                "luminance" => nimbus_scene::TargetScalar::Luminance,
                "sum" => nimbus_scene::TargetScalar::Sum,
                "max" => nimbus_scene::TargetScalar::Max,
                _ => bail!("{key}: unknown target {value:?}; valid: luminance, sum, max"),
            };
        }
        "camera_emission" => {
            scene.integrator.restir.camera_emission = match value {
                "reservoir" => nimbus_scene::CameraEmission::Reservoir,
                "stratified" => nimbus_scene::CameraEmission::Stratified,
                _ => bail!("{key}: unknown choice {value:?}; valid: reservoir, stratified"),
            };
        }
        "temporal_reprojection" => {
            scene.integrator.restir.temporal_reprojection = match value {
                "path" => nimbus_scene::TemporalReprojection::Path,
                "aligned" => nimbus_scene::TemporalReprojection::Aligned,
                _ => bail!("{key}: unknown choice {value:?}; valid: path, aligned"),
            };
        }
        "sigma_star_floor" => {
            scene.integrator.restir.sigma_star_floor = match value.parse::<f32>() {
                Ok(f) if (0.0..=1.0).contains(&f) => f,
                _ => bail!("{key}: {value:?} is not a number in [0, 1]"),
            };
        }
        _ => bail!("unknown key {key:?}; valid keys: {}", keys().join(", ")),
    }
    Ok(None)
}

/// An integer in min..=max.
fn parse_range(key: &str, value: &str, min: u32, max: u32) -> Result<u32> {
    match value.parse::<u32>() {
        Ok(n) if (min..=max).contains(&n) => Ok(n),
        _ => bail!("{key}: {value:?} is not an integer in {min}..={max}"),
    }
}

/// A mip level 0..=16, or `auto` (`None`: chosen from the volume's content).
fn parse_level(key: &str, value: &str) -> Result<Option<u32>> {
    if value == "auto" {
        return Ok(None);
    }
    parse_range(key, value, 0, 16).map(Some)
}

/// `true` or `false`.
fn parse_bool(key: &str, value: &str) -> Result<bool> {
    match value {
        "true" => Ok(true),
        "false" => Ok(false),
        _ => bail!("{key}: {value:?} is not true or false"),
    }
}

/// An integer in 1..=max.
fn parse_count(key: &str, value: &str, max: u32) -> Result<u32> {
    match value.parse::<u32>() {
        Ok(n) if (1..=max).contains(&n) => Ok(n),
        _ => bail!("{key}: {value:?} is not an integer in 1..={max}"),
    }
}

/// One `--vary KEY=V1,V2,...`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct Vary {
    pub(super) key: String,
    pub(super) values: Vec<String>,
}

/// Parses `KEY=V1,V2,...`: a known key (see [`keys`]) and a non-empty list of distinct,
/// non-empty values. The values themselves are checked by [`apply`].
pub(super) fn parse_vary(text: &str) -> Result<Vary> {
    let (key, values) = text
        .split_once('=')
        .ok_or_else(|| anyhow!("expected KEY=V1,V2,... (e.g. spp=1,4,16), got {text:?}"))?;
    let key = key.trim();
    ensure!(
        keys().contains(&key),
        "unknown key {key:?}; valid keys: {}",
        keys().join(", ")
    );
    ensure!(
        !values.trim().is_empty(),
        "{key}: the list of values is empty (expected {key}=V1,V2,...)"
    );
    let mut list: Vec<String> = Vec::new();
    for v in values.split(',') {
        let v = v.trim();
        ensure!(!v.is_empty(), "{key}: empty value in {values:?}");
        ensure!(
            !list.iter().any(|x| x == v),
            "{key}: value {v:?} is repeated"
        );
        list.push(v.to_owned());
    }
    Ok(Vary {
        key: key.to_owned(),
        values: list,
    })
}

/// One configuration: the (key, value) of every `--vary`, in `--vary` order.
pub(super) type Assignment = Vec<(String, String)>;

/// The cartesian product of the `--vary` lists, the first list outermost. No lists
/// give one empty assignment (the scene as it is).
pub(super) fn cartesian(varies: &[Vary]) -> Vec<Assignment> {
    let mut out: Vec<Assignment> = vec![Vec::new()];
    for vary in varies {
        out = out
            .into_iter()
            .flat_map(|prefix| {
                vary.values.iter().map(move |v| {
                    let mut a = prefix.clone();
                    a.push((vary.key.clone(), v.clone()));
                    a
                })
            })
            .collect();
    }
    out
}

/// The part of an assignment that names its series: every pair whose key is not a
/// knob ([`KNOB_KEYS`]).
pub(super) fn series_key(assignment: &[(String, String)]) -> Assignment {
    assignment
        .iter()
        .filter(|(k, _)| !KNOB_KEYS.contains(&k.as_str()))
        .cloned()
        .collect()
}

/// A series' name, `key=value key=value`, or `all configurations` when nothing but
/// knobs varies.
pub(super) fn series_label(series: &[(String, String)]) -> String {
    if series.is_empty() {
        "all configurations".to_owned()
    } else {
        format_pairs(series)
    }
}

pub(super) fn format_pairs(pairs: &[(String, String)]) -> String {
    let parts: Vec<String> = pairs.iter().map(|(k, v)| format!("{k}={v}")).collect();
    parts.join(" ")
}

/// Groups configurations into series: (series key, indices into `assignments`), in
/// order of first appearance.
pub(super) fn group_series(assignments: &[Assignment]) -> Vec<(Assignment, Vec<usize>)> {
    let mut groups: Vec<(Assignment, Vec<usize>)> = Vec::new();
    for (i, a) in assignments.iter().enumerate() {
        let key = series_key(a);
        match groups.iter_mut().find(|(k, _)| *k == key) {
            Some((_, members)) => members.push(i),
            None => groups.push((key, vec![i])),
        }
    }
    groups
}

/// Checks `--baseline KEY=VALUE` against the varied keys; the default is
/// `box_estimator=rm` when box_estimator is varied over rm.
pub(super) fn resolve_baseline(
    text: Option<&str>,
    varies: &[Vary],
) -> Result<Option<(String, String)>> {
    let Some(text) = text else {
        let default = varies
            .iter()
            .find(|v| v.key == "box_estimator")
            .filter(|v| v.values.iter().any(|x| x == "rm"));
        return Ok(default.map(|v| (v.key.clone(), "rm".to_owned())));
    };
    let (key, value) = text
        .split_once('=')
        .map(|(k, v)| (k.trim(), v.trim()))
        .ok_or_else(|| anyhow!("--baseline {text}: expected KEY=VALUE, e.g. box_estimator=rm"))?;
    let series_keys: Vec<&str> = varies
        .iter()
        .map(|v| v.key.as_str())
        .filter(|k| !KNOB_KEYS.contains(k))
        .collect();
    ensure!(
        !KNOB_KEYS.contains(&key),
        "--baseline {text}: {key} is a knob that buys accuracy with time (it runs along each \
         series); the baseline picks a series by one of the varied keys {}",
        if series_keys.is_empty() {
            "(none is varied; vary e.g. box_estimator)".to_owned()
        } else {
            series_keys.join(", ")
        }
    );
    let Some(vary) = varies.iter().find(|v| v.key == key) else {
        bail!(
            "--baseline {text}: {key:?} is not varied; the baseline must be one value of a \
             varied key ({})",
            if series_keys.is_empty() {
                "none is varied besides knobs".to_owned()
            } else {
                series_keys.join(", ")
            }
        );
    };
    ensure!(
        vary.values.iter().any(|v| v == value),
        "--baseline {text}: {value:?} is not among the varied values of {key} ({})",
        vary.values.join(", ")
    );
    Ok(Some((key.to_owned(), value.to_owned())))
}

/// An assignment from string pairs, for tests.
#[cfg(test)]
pub(super) fn assignment(items: &[(&str, &str)]) -> Assignment {
    items
        .iter()
        .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
        .collect()
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn scene() -> Scene {
        nimbus_scene::parse_str(nimbus::DEFAULT_SCENE, Path::new("window.toml")).unwrap()
    }

    #[test]
    fn parse_vary_reads_key_and_values() {
        let v = parse_vary("box_estimator= rm, reds ,mcds").unwrap();
        assert_eq!(v.key, "box_estimator");
        assert_eq!(v.values, ["rm", "reds", "mcds"]);
        assert_eq!(parse_vary("spp=4").unwrap().values, ["4"]);
    }

    #[test]
    fn parse_vary_errors_name_the_problem() {
        let cases = [
            ("spp", "KEY=V1,V2"),
            ("colour=1,2", "valid keys: box_estimator, spp"),
            ("spp=", "empty"),
            ("spp= ", "empty"),
            ("spp=1,,4", "empty value"),
            ("spp=1,4,1", "\"1\" is repeated"),
        ];
        for (text, needle) in cases {
            let message = format!("{:#}", parse_vary(text).unwrap_err());
            assert!(message.contains(needle), "{text}: {message}");
        }
    }

    #[test]
    fn apply_sets_each_key_and_lists_valid_values() {
        let mut s = scene();
        assert_eq!(apply(&mut s, "box_estimator", "reds").unwrap(), None);
        assert_eq!(s.integrator.box_estimator, BoxEstimator::Reds);
        assert_eq!(apply(&mut s, "spp", "8").unwrap(), None);
        assert_eq!(s.render.spp, 8);
        assert_eq!(apply(&mut s, "box_samples", "24").unwrap(), Some(24));
        assert_eq!(s.integrator.box_samples, 24);
        apply(&mut s, "frames", "3").unwrap();
        assert_eq!(s.render.frames, 3);
        apply(&mut s, "seed", "18446744073709551615").unwrap();
        assert_eq!(s.render.seed, u64::MAX);
        apply(&mut s, "max_bounces", "4").unwrap();
        assert_eq!(s.integrator.max_bounces, 4);
        apply(&mut s, "volume", "baseline").unwrap();
        assert_eq!(s.integrator.volume, VolumeIntegrator::Baseline);

        let cases = [
            ("box_estimator", "RM", "mcwvds, reds, rees, rm, mcds, me"),
            ("spp", "0", "spp: \"0\" is not an integer in 1..=65536"),
            ("spp", "many", "spp"),
            ("box_samples", "70000", "1..=65536"),
            ("seed", "-1", "seed"),
            ("volume", "pt", "restir, baseline"),
            ("exposure", "2", "valid keys: box_estimator"),
        ];
        for (key, value, needle) in cases {
            let message = format!("{:#}", apply(&mut s, key, value).unwrap_err());
            assert!(message.contains(needle), "{key}={value}: {message}");
        }
    }

    #[test]
    fn every_key_is_settable() {
        let values = [
            ("box_estimator", "rm"),
            ("spp", "2"),
            ("box_samples", "2"),
            ("frames", "2"),
            ("seed", "2"),
            ("max_bounces", "2"),
            ("volume", "restir"),
            ("candidates", "8"),
            ("temporal", "false"),
            ("temporal_limit", "20"),
            ("temporal_limit_moving", "3"),
            ("spatial_neighbors", "0"),
            ("spatial_radius_px", "2.5"),
            ("spatial_rounds", "2"),
            ("reuse", "vertex"),
            ("mip_candidates", "0"),
            ("mip_indirect", "3"),
            ("mip_reuse", "2"),
            ("final_transmittance", "ratio"),
            ("mis", "pairwise"),
            ("spatial_shift", "optical_depth"),
            ("env_reuse", "world"),
            ("spatial_when", "always"),
            ("emission", "folded"),
            ("spatial_max_history", "8"),
            ("spatial_feature_tolerance", "0.3"),
            ("spatial_anchor", "true"),
            ("temporal_history", "temporal"),
            ("sigma_star_floor", "0.25"),
            ("nee", "one"),
            ("direct", "escape"),
            ("candidate_tracking", "regular"),
            ("pc_fetch", "image"),
            ("target", "sum"),
            ("camera_emission", "reservoir"),
            ("temporal_reprojection", "path"),
        ];
        assert_eq!(values.len(), keys().len());
        let mut s = scene();
        for (key, value) in values {
            assert!(keys().contains(&key));
            apply(&mut s, key, value).unwrap();
        }
        let r = &s.integrator.restir;
        assert_eq!(
            (
                r.candidates,
                r.temporal,
                r.temporal_limit,
                r.spatial_neighbors
            ),
            (8, false, 20, 0)
        );
        assert_eq!(r.temporal_limit_moving, 3);
        assert_eq!((r.spatial_radius_px, r.spatial_rounds), (Some(2.5), 2));
        assert_eq!(r.spatial_when, nimbus_scene::SpatialWhen::Always);
        assert!(r.fold_emission);
        assert_eq!(r.reuse, nimbus_scene::ReuseMode::Vertex);
        assert_eq!(
            (r.mip_candidates, r.mip_indirect, r.mip_reuse),
            (0, Some(3), Some(2))
        );
        assert!(r.final_ratio_tracking);
        assert_eq!(r.nee, nimbus_scene::NeeMode::One);
        assert_eq!(r.direct, nimbus_scene::DirectMode::Escape);
        assert_eq!(
            r.candidate_tracking,
            nimbus_scene::CandidateTracking::Regular
        );
        assert_eq!(r.pc_fetch, nimbus_scene::DensityFetch::Image);
        assert_eq!(r.target, nimbus_scene::TargetScalar::Sum);
        assert_eq!(r.camera_emission, nimbus_scene::CameraEmission::Reservoir);
        assert_eq!(
            r.temporal_reprojection,
            nimbus_scene::TemporalReprojection::Path
        );
        assert_eq!(r.env_reuse, nimbus_scene::EnvReuse::World);
        assert_eq!(
            (r.spatial_shift, r.spatial_max_history),
            (nimbus_scene::SpatialShift::OpticalDepth, 8.0)
        );
        assert_eq!((r.spatial_feature_tolerance, r.spatial_anchor), (0.3, true));
        for (key, value) in [
            ("temporal", "yes"),
            ("reuse", "path"),
            ("spatial_neighbors", "65"),
            ("final_transmittance", "exact"),
            ("mis", "balance"),
            ("temporal_history", "both"),
            ("sigma_star_floor", "1.5"),
            ("spatial_feature_tolerance", "2"),
            ("spatial_anchor", "1.5"),
            ("nee", "all"),
            ("direct", "never"),
            ("candidate_tracking", "ratio"),
            ("spatial_when", "density_moves"),
            ("target", "rgb"),
            ("camera_emission", "marched"),
            ("temporal_reprojection", "motion"),
        ] {
            assert!(apply(&mut s, key, value).is_err(), "{key}={value}");
        }
        for (value, when) in [
            ("camera_moves", nimbus_scene::SpatialWhen::CameraMoves),
            (
                "camera_or_density",
                nimbus_scene::SpatialWhen::CameraOrDensity,
            ),
        ] {
            apply(&mut s, "spatial_when", value).unwrap();
            assert_eq!(s.integrator.restir.spatial_when, when);
        }
    }

    #[test]
    fn cartesian_product_has_the_first_list_outermost() {
        let varies = [
            parse_vary("box_estimator=rm,reds").unwrap(),
            parse_vary("spp=1,4,16").unwrap(),
        ];
        let all = cartesian(&varies);
        assert_eq!(all.len(), 6);
        assert_eq!(all[0], assignment(&[("box_estimator", "rm"), ("spp", "1")]));
        assert_eq!(
            all[2],
            assignment(&[("box_estimator", "rm"), ("spp", "16")])
        );
        assert_eq!(
            all[3],
            assignment(&[("box_estimator", "reds"), ("spp", "1")])
        );
        assert_eq!(cartesian(&[]), vec![Vec::new()]);
    }

    #[test]
    fn series_share_everything_but_the_knobs() {
        let varies = [
            parse_vary("spp=1,4").unwrap(),
            parse_vary("box_estimator=rm,reds").unwrap(),
            parse_vary("box_samples=8,16").unwrap(),
            parse_vary("max_bounces=1,2").unwrap(),
        ];
        let all = cartesian(&varies);
        let groups = group_series(&all);
        assert_eq!(groups.len(), 4);
        for (key, members) in &groups {
            assert_eq!(members.len(), 4);
            for &i in members {
                assert_eq!(series_key(&all[i]), *key);
            }
        }
        assert_eq!(series_label(&groups[0].0), "box_estimator=rm max_bounces=1");
        let only_knobs = cartesian(&[parse_vary("spp=1,2").unwrap()]);
        let groups = group_series(&only_knobs);
        assert_eq!(groups, vec![(Vec::new(), vec![0, 1])]);
        assert_eq!(series_label(&groups[0].0), "all configurations");
    }

    #[test]
    fn baseline_must_name_a_varied_series_value() {
        let varies = [
            parse_vary("box_estimator=rm,reds").unwrap(),
            parse_vary("spp=1,4").unwrap(),
        ];
        assert_eq!(
            resolve_baseline(None, &varies).unwrap(),
            Some(("box_estimator".to_owned(), "rm".to_owned()))
        );
        assert_eq!(
            resolve_baseline(Some("box_estimator=reds"), &varies).unwrap(),
            Some(("box_estimator".to_owned(), "reds".to_owned()))
        );
        assert_eq!(resolve_baseline(None, &varies[1..]).unwrap(), None);
        for (text, needle) in [
            ("box_estimator", "KEY=VALUE"),
            ("spp=1", "knob"),
            ("box_estimator=mcds", "rm, reds"),
            ("seed=1", "not varied"),
        ] {
            let message = format!("{:#}", resolve_baseline(Some(text), &varies).unwrap_err());
            assert!(message.contains("--baseline"), "{message}");
            assert!(message.contains(needle), "{text}: {message}");
        }
    }
}
