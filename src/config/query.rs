//! The parameters of the query and the trees it walks: the query options (`mode`,
//! `max_distance`, the self filter, the per-link minima, the backend and its crossovers), the
//! levels' thresholds they depend on (`warn_distance`, `stop_distance`, `hysteresis`, m), the
//! packing budget of the tree build, and which links are measured.

use yaml_rust2::Yaml;

use super::error::ConfigError;
use super::values::Values;
use crate::ist::BuildOptions;
use crate::query::{Backend, LinkSelection, Mode, QueryOptions};

/// The levels' thresholds, m: WARN below `warn`, ERROR (and the stop) below `stop`, each left
/// `hysteresis` beyond.
pub(super) struct Thresholds {
    pub warn_m: f64,
    pub stop_m: f64,
    pub hysteresis_m: f64,
}

/// The query options, and the thresholds read among them (the per-link range defaults to
/// `warn_distance + hysteresis`).
pub(super) fn query_options(v: &Values) -> Result<(QueryOptions, Thresholds), ConfigError> {
    let mode = v.choice::<Mode>("mode", "mode")?;
    let max_distance_m = match v.raw("max_distance", "max_distance") {
        Yaml::Real(s) if s == ".inf" => f64::INFINITY,
        _ => v.distance("max_distance", "max_distance")?,
    } as f32;
    let t = thresholds(v)?;
    let query = QueryOptions {
        mode,
        max_distance_m,
        self_filter_padding_m: v
            .bool("self_filter", "self_filter")?
            .then(|| v.distance("self_filter_padding", "self_filter_padding"))
            .transpose()?
            .map(|x| x as f32),
        per_link: v.bool("per_link", "per_link")?,
        per_link_range_m: match v.raw("per_link_range", "per_link_range") {
            Yaml::Null => (t.warn_m + t.hysteresis_m) as f32,
            Yaml::Real(s) if s == ".inf" => f32::INFINITY,
            _ => v.distance("per_link_range", "per_link_range")? as f32,
        },
        link_ranges_m: Vec::new(),
        backend: v.choice::<Backend>("backend", "backend")?,
        gpu_min_points: v.whole("gpu_min_points")?,
        gpu_min_depth_pixels: v.whole("gpu_min_depth_pixels")?,
    };
    Ok((query, t))
}

/// `warn_distance`, `stop_distance` (not above it) and `hysteresis`.
fn thresholds(v: &Values) -> Result<Thresholds, ConfigError> {
    let warn_m = v.distance("warn_distance", "warn_distance")?;
    let stop_m = v.distance("stop_distance", "stop_distance")?;
    if stop_m > warn_m {
        return Err(Values::bad(
            "stop_distance",
            format!("{stop_m} m is above warn_distance {warn_m} m"),
        ));
    }
    Ok(Thresholds {
        warn_m,
        stop_m,
        hysteresis_m: v.distance("hysteresis", "hysteresis")?,
    })
}

/// A padding that reaches the stop threshold would filter an obstacle at the stop distance as
/// "robot": the stop could never be raised by it. (Compared in f32, the precision the query
/// filters in.)
pub(super) fn check_self_filter_padding(
    query: &QueryOptions,
    t: &Thresholds,
) -> Result<(), ConfigError> {
    let (stop_distance_m, hysteresis_m) = (t.stop_m, t.hysteresis_m);
    match query.self_filter_padding_m {
        Some(padding) if padding >= (stop_distance_m - hysteresis_m) as f32 => Err(Values::bad(
            "self_filter_padding",
            format!(
                "{padding} m must stay below stop_distance − hysteresis \
                 ({stop_distance_m} − {hysteresis_m} m): a point filtered as the robot \
                 could never raise the stop"
            ),
        )),
        _ => Ok(()),
    }
}

/// The packing budget of the tree build: `max_spheres`, `start_spheres`, `target_gap`,
/// `target_gap_per_m`.
pub(super) fn build_options(v: &Values) -> Result<BuildOptions, ConfigError> {
    let mut build = BuildOptions::default();
    build.packing.max_spheres = v.count("max_spheres")?;
    build.packing.start_spheres = v.count("start_spheres")?;
    let target_gap = v.distance("target_gap", "target_gap")?;
    if !(target_gap > 0.0 && target_gap.is_finite()) {
        return Err(Values::bad(
            "target_gap",
            "must be a positive number of metres",
        ));
    }
    build.packing.target_gap_m = target_gap as f32;
    build.packing.target_gap_per_m = v.distance("target_gap_per_m", "target_gap_per_m")? as f32;
    Ok(build)
}

/// `links`, `exclude_links` and `convex_hull_links`; `objects` are the attached objects.
pub(super) fn selection(v: &Values, objects: &[String]) -> Result<LinkSelection, ConfigError> {
    Ok(LinkSelection {
        // An attached object is a link the list cannot have named.
        include: match v.strings("links")? {
            l if l.is_empty() => l,
            l => l.into_iter().chain(objects.iter().cloned()).collect(),
        },
        exclude: v.strings("exclude_links")?,
        convex_hull: v.strings("convex_hull_links")?,
    })
}
