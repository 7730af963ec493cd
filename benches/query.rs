//! Criterion benchmarks of the query (`cargo bench --bench query`): the Panda and the real Kinect
//! cloud of ../shared at SCENARIO.md's `ready` pose, every mode with and without per-link
//! minima, beside peer (b) and the touch-every-point floor. `ist_monitor bench query` gives the
//! full error-against-time sweep; this is the quick, statistically careful check of one setting.

use criterion::{criterion_group, criterion_main, Criterion};
#[path = "../src/bin/ist_monitor/bench/scenes.rs"]
mod scenes;

use scenes::{load_scenario, ScenarioName};

/// `../shared` beside the checkout.
const SHARED: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared");
use ist_monitor::ist::{build_robot, cache::TreeCache, BuildOptions};
use ist_monitor::query::{peers, Engine, LinkSelection, Mode, QueryOptions};

fn query(c: &mut Criterion) {
    let shared = std::path::Path::new(SHARED);
    if !shared.join("robots").is_dir() {
        eprintln!("skipped: {} is absent", shared.display());
        return;
    }
    let demo = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let scenario = load_scenario(shared, demo, ScenarioName::Kinect).expect("scenario");
    let cache = TreeCache::at(None);
    let trees: Vec<_> = build_robot(
        &scenario.model,
        &BuildOptions::default(),
        Some(&cache),
        &|_| {},
    )
    .expect("trees")
    .into_iter()
    .map(|(t, _)| t)
    .collect();
    let mut engine =
        Engine::new(&scenario.model, &trees, &LinkSelection::default()).expect("engine");
    let case = &scenario.cases[0];
    let (points, sensor, poses) = (&case.points, case.root_from_sensor, &case.link_poses);
    let mut group = c.benchmark_group("kinect_panda_ready");
    group.bench_function("floor_touch_every_point", |b| {
        b.iter(|| peers::touch_every_point(points))
    });
    for mode in [Mode::Fast, Mode::Certified, Mode::Exact] {
        for per_link in [false, true] {
            let options = QueryOptions {
                mode,
                per_link,
                ..QueryOptions::default()
            };
            let name = format!("{mode:?}{}", if per_link { "_per_link" } else { "" });
            group.bench_function(name.to_lowercase(), |b| {
                b.iter(|| {
                    engine
                        .query(points, &sensor, poses, &options)
                        .expect("query")
                })
            });
        }
    }
    group.bench_function("peer_b_parry_shared_bound", |b| {
        b.iter(|| peers::exact_shared_bound(&engine, points, &sensor, poses))
    });
    group.finish();
}

criterion_group!(benches, query);
criterion_main!(benches);
