//! What commands and benches set up the same way: the trees of a robot (built, or loaded from
//! the cache) and the monitor of a config, each with a progress line on a terminal while the
//! packing runs (seconds to minutes for a new robot, milliseconds from the cache).

use std::path::Path;

use anyhow::Result;

use ist_monitor::config::Config;
use ist_monitor::ist::cache::TreeCache;
use ist_monitor::ist::{self, BuildOptions, LinkTree, Origin};
use ist_monitor::monitor::Monitor;
use ist_monitor::robot::RobotModel;

/// The trees of every link, built or loaded from `cache`, with a progress bar on a terminal.
pub fn build_trees(
    model: &RobotModel,
    options: &BuildOptions,
    cache: Option<&TreeCache>,
) -> Result<Vec<(LinkTree, Origin)>> {
    let bar = indicatif::ProgressBar::new(model.links.len() as u64).with_message("links");
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} {msg} {pos}/{len} [{elapsed}] {wide_bar}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let trees = ist::build_robot(model, options, cache, &|_| bar.inc(1))?;
    bar.finish_and_clear();
    Ok(trees)
}

/// [`build_trees`] through the cache in `dir` (or the default cache folder), trees only.
pub fn cached_trees(
    model: &RobotModel,
    options: &BuildOptions,
    dir: Option<&Path>,
) -> Result<Vec<LinkTree>> {
    let cache = TreeCache::at(dir);
    Ok(build_trees(model, options, Some(&cache))?
        .into_iter()
        .map(|(t, _)| t)
        .collect())
}

/// The monitor of a config, with a progress line while its trees are built or loaded.
pub fn monitor_from_config(config: Config) -> Result<Monitor> {
    let bar = indicatif::ProgressBar::new_spinner();
    let monitor = Monitor::new(config, &|link| {
        bar.set_message(format!("inner sphere trees: {link}"));
        bar.tick();
    });
    bar.finish_and_clear();
    Ok(monitor?)
}
