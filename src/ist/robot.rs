//! A robot's trees: every selected link's, from the cache where it holds a valid entry, built
//! (and stored) otherwise, links in parallel. Links whose solids are the same in their own frames
//! (one cache key: a mesh file shared by a left and a right arm and mirrored through the joint
//! frames, a link a mimic joint doubles) are packed once: the first of them in the model's order
//! builds or loads the tree, and the others take it under their own names.

use std::collections::HashMap;

use rayon::prelude::*;
use serde::Serialize;

use super::cache::{self, TreeCache};
use super::error::IstError;
use super::link::build_link;
use super::link_tree::LinkTree;
use super::options::BuildOptions;
use crate::robot::{LinkGeometry, RobotModel};

/// Where a link's tree came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Origin {
    Built,
    Cache,
    /// The tree of another link of this build whose solid is the same (its name in
    /// [`build_links`]'s result is the link's own).
    Shared,
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
    let links: Vec<&LinkGeometry> = (model.links.iter())
        .filter(|link| selected(&link.name))
        .collect();
    let keys: Vec<[u8; 32]> = links.par_iter().map(|l| cache::key(l, options)).collect();
    // Each link's solid is built (or loaded) by the first link with its key.
    let mut first = HashMap::new();
    let owner: Vec<usize> = (keys.iter().enumerate())
        .map(|(i, key)| *first.entry(*key).or_insert(i))
        .collect();
    let owners: Vec<usize> = (0..links.len()).filter(|&i| owner[i] == i).collect();
    let trees: Vec<(LinkTree, Origin)> = owners
        .par_iter()
        .map(|&i| tree_of(links[i], &keys[i], options, cache, done))
        .collect::<Result<_, _>>()?;
    let tree_of_owner: HashMap<usize, usize> =
        (owners.iter().enumerate()).map(|(t, &i)| (i, t)).collect();
    Ok((0..links.len())
        .map(|i| {
            let (tree, origin) = &trees[tree_of_owner[&owner[i]]];
            if owner[i] == i {
                return (tree.clone(), *origin);
            }
            done(&links[i].name);
            let shared = LinkTree {
                link: links[i].name.clone(),
                ..tree.clone()
            };
            (shared, Origin::Shared)
        })
        .collect())
}

/// `link`'s tree under `key`: from the cache where it holds a valid entry, else built,
/// validated and stored.
fn tree_of(
    link: &LinkGeometry,
    key: &[u8; 32],
    options: &BuildOptions,
    cache: Option<&TreeCache>,
    done: &(dyn Fn(&str) + Sync),
) -> Result<(LinkTree, Origin), IstError> {
    if let Some(cache) = cache {
        match cache.load(key, &link.name) {
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
        if let Err(e) = cache.store(key, &tree) {
            log::warn!("{e}");
        }
    }
    done(&link.name);
    Ok((tree, Origin::Built))
}
