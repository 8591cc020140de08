//! What a study varies: the `--vary KEY=V1,V2,...` lists, the keys they accept and the
//! scene fields they set ([`field_override`]: the scene parser checks every value), their
//! cartesian product, the series that configurations fall into, and the `--baseline`
//! series.

use anyhow::{anyhow, bail, ensure, Result};
use nimbus_scene::FieldOverride;

/// The keys `--vary` (and `--baseline`) accept besides the ReSTIR knobs, with the scene
/// table that holds each.
const GENERAL_KEYS: [(&str, &str); 7] = [
    ("box_estimator", "integrator"),
    ("spp", "render"),
    ("box_samples", "integrator"),
    ("frames", "render"),
    ("seed", "render"),
    ("max_bounces", "integrator"),
    ("volume", "integrator"),
];

/// Every key `--vary` accepts: [`GENERAL_KEYS`], then the fields of
/// `[integrator.restir]` (the scene crate's list, so the two cannot drift apart).
pub fn keys() -> Vec<&'static str> {
    GENERAL_KEYS
        .iter()
        .map(|(key, _)| *key)
        .chain(nimbus_scene::RESTIR_KEYS.iter().copied())
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

/// The scene-format field that `key` sets: `render.spp`, `integrator.volume`,
/// `integrator.restir.candidates`, ...
fn field_path(key: &str) -> Option<String> {
    if let Some((_, table)) = GENERAL_KEYS.iter().find(|(k, _)| *k == key) {
        return Some(format!("{table}.{key}"));
    }
    nimbus_scene::RESTIR_KEYS
        .contains(&key)
        .then(|| format!("integrator.restir.{key}"))
}

/// The override that sets `key` = `value` in the scene's tables before they are
/// validated, so that a varied value passes exactly the checks the same value written in
/// the scene file passes (ranges, choices, and what one field means for another), and no
/// list of valid values is kept twice. `origin` names where the value came from in error
/// messages (`--vary spp=0`, `--reference-spp 0`). The value is read as `--set` reads
/// one: TOML, or a bare word as a string (`baseline`, `auto`).
pub(super) fn field_override(key: &str, value: &str, origin: String) -> Result<FieldOverride> {
    let path = field_path(key)
        .ok_or_else(|| anyhow!("unknown key {key:?}; valid keys: {}", keys().join(", ")))?;
    let mut o = FieldOverride::parse(&format!("{path}={}", value.trim()))
        .map_err(|e| anyhow!("{origin}: {e:#}"))?;
    o.origin = Some(origin);
    Ok(o)
}

/// The overrides of one assignment, in its order, each named `--vary KEY=VALUE`.
pub(super) fn overrides(assignment: &[(String, String)]) -> Result<Vec<FieldOverride>> {
    assignment
        .iter()
        .map(|(k, v)| field_override(k, v, format!("--vary {k}={v}")))
        .collect()
}

/// One `--vary KEY=V1,V2,...`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct Vary {
    pub(super) key: String,
    pub(super) values: Vec<String>,
}

/// Parses `KEY=V1,V2,...`: a known key (see [`keys`]) and a non-empty list of distinct,
/// non-empty values. The values themselves are checked by the scene parser
/// ([`field_override`]).
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

    use nimbus_scene::{BoxEstimator, VolumeIntegrator};

    use super::*;

    /// The default scene with `pairs` set as `--vary` sets them.
    fn scene_with(pairs: &[(&str, &str)]) -> Result<nimbus_scene::Scene> {
        let given = overrides(&assignment(pairs))?;
        nimbus_scene::parse_str_with(nimbus::DEFAULT_SCENE, Path::new("window.toml"), &given)
    }

    #[test]
    fn overrides_set_each_key_and_the_parser_lists_valid_values() {
        let s = scene_with(&[
            ("box_estimator", "reds"),
            ("spp", "8"),
            ("box_samples", "24"),
            ("frames", "3"),
            ("seed", "9223372036854775807"),
            ("max_bounces", "4"),
            ("volume", "baseline"),
        ])
        .unwrap();
        assert_eq!(s.integrator.box_estimator, BoxEstimator::Reds);
        assert_eq!((s.render.spp, s.render.frames), (8, 3));
        assert_eq!(s.integrator.box_samples, 24);
        assert_eq!(s.render.seed, i64::MAX as u64);
        assert_eq!(s.integrator.max_bounces, 4);
        assert_eq!(s.integrator.volume, VolumeIntegrator::Baseline);

        let cases = [
            ("box_estimator", "RM", "mcwvds"),
            ("spp", "0", "spp"),
            ("spp", "many", "spp"),
            ("box_samples", "70000", "box_samples"),
            ("seed", "-1", "seed"),
            ("seed", "18446744073709551615", "seed"),
            ("volume", "pt", "baseline"),
            ("spatial_radius_px", "-1", "spatial_radius_px"),
            ("exposure", "2", "valid keys: box_estimator"),
        ];
        for (key, value, needle) in cases {
            let message = format!("{:#}", scene_with(&[(key, value)]).unwrap_err());
            assert!(message.contains(needle), "{key}={value}: {message}");
            if key != "exposure" {
                assert!(
                    message.contains(&format!("--vary {key}={value}")),
                    "{key}={value}: {message}"
                );
            }
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
            ("candidates_settled", "2"),
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
            ("shade_cache", "false"),
            ("still_target", "reuse"),
            ("temporal_history", "temporal"),
            ("sigma_star_floor", "0.25"),
            ("nee", "one"),
            ("direct", "escape"),
            ("candidate_tracking", "regular"),
            ("pc_fetch", "image"),
            ("density_fetch", "buffer"),
            ("target", "sum"),
            ("camera_emission", "reservoir"),
            ("temporal_reprojection", "path"),
            ("temporal_shift", "optical_depth"),
        ];
        assert_eq!(values.len(), keys().len());
        for (key, _) in values {
            assert!(keys().contains(&key), "{key}");
        }
        let s = scene_with(&values).unwrap();
        let r = &s.integrator.restir;
        assert_eq!(
            (
                r.candidates,
                r.temporal,
                r.temporal_limit,
                r.spatial_neighbors
            ),
            (8, Some(false), Some(20), 0)
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
        assert_eq!(r.density_fetch, nimbus_scene::DensityFetch::Buffer);
        assert_eq!(r.target, nimbus_scene::TargetScalar::Sum);
        assert_eq!(r.camera_emission, nimbus_scene::CameraEmission::Reservoir);
        assert_eq!(
            r.temporal_reprojection,
            nimbus_scene::TemporalReprojection::Path
        );
        assert_eq!(r.temporal_shift, nimbus_scene::TemporalShift::OpticalDepth);
        assert_eq!(r.env_reuse, nimbus_scene::EnvReuse::World);
        assert_eq!(
            (r.spatial_shift, r.spatial_max_history),
            (nimbus_scene::SpatialShift::OpticalDepth, 8.0)
        );
        assert_eq!((r.spatial_feature_tolerance, r.spatial_anchor), (0.3, true));
        assert!(!r.shade_cache);
        assert_eq!(r.still_target, nimbus_scene::StillTarget::Reuse);
        assert_eq!(
            scene_with(&[("spatial_radius_px", "auto")])
                .unwrap()
                .integrator
                .restir
                .spatial_radius_px,
            None
        );
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
            ("shade_cache", "sometimes"),
            ("still_target", "fresh"),
            ("nee", "all"),
            ("direct", "never"),
            ("candidate_tracking", "ratio"),
            ("spatial_when", "density_moves"),
            ("target", "rgb"),
            ("camera_emission", "marched"),
            ("temporal_reprojection", "motion"),
            ("temporal_shift", "tau"),
        ] {
            assert!(scene_with(&[(key, value)]).is_err(), "{key}={value}");
        }
        for (value, when) in [
            ("camera_moves", nimbus_scene::SpatialWhen::CameraMoves),
            (
                "camera_or_density",
                nimbus_scene::SpatialWhen::CameraOrDensity,
            ),
        ] {
            let s = scene_with(&[("spatial_when", value)]).unwrap();
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
