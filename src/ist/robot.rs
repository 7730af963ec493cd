//! A robot's trees: every selected link's, from the cache where it holds a valid entry, built
//! (and stored) otherwise, links in parallel.

use rayon::prelude::*;
use serde::Serialize;

use super::cache::{self, TreeCache};
use super::error::IstError;
use super::link::build_link;
use super::link_tree::LinkTree;
use super::options::BuildOptions;
use crate::robot::RobotModel;

/// Where a link's tree came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Origin {
    Built,
    Cache,
}

/// Trees of every link with collision geometry, from the cache where it holds a valid entry,
/// built, validated (and stored) otherwise: the cache holds validated trees only; `done` is called as each link finishes. Links are built in
/// parallel, and each packing is parallel inside.
pub fn build_robot(
    model: &RobotModel,
    options: &BuildOptions,
    cache: Option<&TreeCache>,
    done: &(dyn Fn(&str) + Sync),
) -> Result<Vec<(LinkTree, Origin)>, IstError> {
    build_links(model, &|_| true, options, cache, done)
}

/// As [`build_robot`], for the links whose name passes `selected` only.
pub fn build_links(
    model: &RobotModel,
    selected: &(dyn Fn(&str) -> bool + Sync),
    options: &BuildOptions,
    cache: Option<&TreeCache>,
    done: &(dyn Fn(&str) + Sync),
) -> Result<Vec<(LinkTree, Origin)>, IstError> {
    model
        .links
        .par_iter()
        .filter(|link| selected(&link.name))
        .map(|link| {
            let key = cache::key(link, options);
            if let Some(cache) = cache {
                match cache.load(&key, &link.name) {
                    Ok(Some(tree)) => {
                        done(&link.name);
                        return Ok((tree, Origin::Cache));
                    }
                    Ok(None) => {}
                    Err(e) => log::warn!("{e}; rebuilding link {}", link.name),
                }
            }
            let tree = build_link(link, options)?;
            if let Some(cache) = cache {
                if let Err(e) = cache.store(&key, &tree) {
                    log::warn!("{e}");
                }
            }
            done(&link.name);
            Ok((tree, Origin::Built))
        })
        .collect()
}
