//! The request-ordering check on a small generated city (`sim::stream_city`, the shared scenes of
//! `data/scenes/README.md` as blocks): the real client over the simulated transport at
//! 10 Mbit/s along synthetic street walks; cache hits over first-time entries into the needed cut
//! (`sim::score`, from the whole tileset) must be clearly higher with the oracle than reactive.

use crate::common;

use splat2tiles_lab::sim::misses::{MissBreakdown, breakdown};
use splat2tiles_lab::sim::score::{Ratio, Truth, cache_hits, held_tiles, tick_views};
use splat2tiles_lab::sim::session::{SessionOptions, run_session};
use splat2tiles_lab::sim::stream_city::{CitySpec, StreetGrid, build_city, street_walk};
use splat2tiles_lab::sim::transport::NetModel;
use splat2tiles_stream::client::{ClientConfig, PredictorKind};
use splat2tiles_stream::predict::Oracle;

fn chr(
    truth: &Truth,
    cfg: &ClientConfig,
    dir: &std::path::Path,
    oracle: bool,
    grid: &StreetGrid,
) -> (Ratio, MissBreakdown) {
    let mut total = Ratio::default();
    let mut why = MissBreakdown::default();
    for seed in [17u64, 18, 19] {
        let trace = street_walk(grid, seed, 40.0);
        let opts = SessionOptions {
            predictor: oracle.then(|| {
                Box::new(Oracle {
                    trace: trace.poses.clone(),
                }) as Box<dyn splat2tiles_stream::predict::Predictor + Send>
            }),
            ..SessionOptions::default()
        };
        let log = run_session(
            dir,
            cfg.clone(),
            &trace.poses,
            &NetModel::constant(10.0, 0.04),
            opts,
        );
        let needed = truth.needed_per_tick(cfg, &log);
        let resident = held_tiles(&log);
        let views = tick_views(&log, needed.iter().map(Vec::as_slice), &resident);
        let c = cache_hits(&views);
        total.hits += c.first.hits;
        total.n += c.first.n;
        why.add(&breakdown(&log, &views));
    }
    (total, why)
}

#[test]
fn oracle_beats_reactive_on_first_time_entries_in_a_small_city() {
    let scenes = common::scenes();
    let tmp = tempfile::tempdir().unwrap();
    let spec = CitySpec::small();
    let city = build_city(&scenes, &tmp.path().join("city"), &spec, None).unwrap();
    let truth = Truth::load(&city.dir.join("tileset.json")).unwrap();
    let cfg = CitySpec::small_client;
    let reactive = chr(
        &truth,
        &cfg(PredictorKind::Reactive),
        &city.dir,
        false,
        &city.grid,
    );
    let oracle = chr(
        &truth,
        &cfg(PredictorKind::Reactive),
        &city.dir,
        true,
        &city.grid,
    );
    let ((reactive, why_r), (oracle, why_o)) = (reactive, oracle);
    for (name, w) in [("reactive", &why_r), ("oracle", &why_o)] {
        eprintln!(
            "{name}: {} misses of {} first-time entries: evicted {}, in flight {}, refused {}, \
             late {}, never requested {}; outside the client's view {}, ancestor held {}; \
             in the first 5 s {}",
            w.misses,
            w.entries,
            w.evicted,
            w.in_flight,
            w.refused,
            w.late,
            w.never,
            w.outside_client_view,
            w.ancestor_held,
            w.at_s.iter().filter(|&&t| t < 5.0).count()
        );
    }
    assert!(
        reactive.n >= 200 && oracle.n >= 200,
        "too few entries to compare"
    );
    let (r, o) = (reactive.rate().unwrap(), oracle.rate().unwrap());
    // The oracle needs no pose history, so it never falls back to reactive (it did for 5 s and
    // scored 192/262 = 0.73 with every miss in those 5 s); what it misses now is the cold start
    // (the link still busy with the first view), nothing later. 238/262 = 0.908 before the
    // churn fixes (in-flight downloads kept, missing tiles before upgrades,
    // earliest-deadline-first preemption), 244/262 = 0.931 after, 252/262 = 0.962 with imminent
    // prefetches before repairs of missed tiles.
    assert!(o >= 0.95, "oracle {o:.3} below 0.95");
    assert!(r <= 0.1, "reactive {r:.3} above 0.1");
    let late = why_o.at_s.iter().filter(|&&t| t >= 5.0).count();
    assert!(
        late <= 2,
        "oracle missed {late} entries after the first 5 s"
    );
}

/// Bytes, downloads per tile and held utility of one session on a district dolly at 200 Mbit/s.
fn dolly_session(
    dir: &std::path::Path,
    truth: &Truth,
    grid: &StreetGrid,
    prefetch: splat2tiles_stream::client::Prefetch,
) -> (u64, usize, Ratio) {
    use splat2tiles_lab::experiments::simulate_thrift::district_dolly;
    use splat2tiles_lab::sim::transport::Outcome;
    let trace = district_dolly(grid, 1);
    let oracle = Box::new(Oracle {
        trace: trace.poses.clone(),
    }) as Box<dyn splat2tiles_stream::predict::Predictor + Send>;
    let cfg = ClientConfig {
        prefetch,
        ..CitySpec::small_client(PredictorKind::Reactive)
    };
    let opts = SessionOptions {
        predictor: Some(oracle),
        ..SessionOptions::default()
    };
    let log = run_session(
        dir,
        cfg.clone(),
        &trace.poses,
        &NetModel::constant(200.0, 0.04),
        opts,
    );
    let mut done: std::collections::HashMap<_, usize> = std::collections::HashMap::new();
    for r in log.requests.iter().filter(|r| r.outcome == Outcome::Done) {
        if let Some(k) = r.key {
            *done.entry(k).or_default() += 1;
        }
    }
    let needed = truth.needed_per_tick(&cfg, &log);
    let resident = held_tiles(&log);
    let views = tick_views(&log, needed.iter().map(Vec::as_slice), &resident);
    let bytes = log.ticks.last().map_or(0, |t| t.bytes_down);
    let twice = done.values().filter(|&&n| n > 1).count();
    (bytes, twice, cache_hits(&views).first)
}

#[test]
fn thrifty_prefetch_fetches_less_than_eager_and_never_climbs_for_nothing() {
    use splat2tiles_stream::client::Prefetch;
    let scenes = common::scenes();
    let tmp = tempfile::tempdir().unwrap();
    let city = build_city(&scenes, &tmp.path().join("city"), &CitySpec::small(), None).unwrap();
    let truth = Truth::load(&city.dir.join("tileset.json")).unwrap();
    let run = |p: Prefetch| dolly_session(&city.dir, &truth, &city.grid, p);
    let (eager, eager_twice, eager_chr) = run(Prefetch::EAGER);
    let (thrifty, thrifty_twice, thrifty_chr) = run(Prefetch::THRIFTY);
    let once = Prefetch {
        upgrade_gain: f64::INFINITY,
        ..Prefetch::THRIFTY
    };
    let (never, never_twice, _) = run(once);
    eprintln!(
        "eager {eager} B ({eager_twice} tiles downloaded twice or more, CHR {eager_chr:?}); \
         thrifty {thrifty} B ({thrifty_twice}, {thrifty_chr:?}); no upgrades {never} B \
         ({never_twice})"
    );
    // Eager climbs the variant ladder on a fast link (Low or High first, Best later); thrifty
    // fetches a held tile again only for a visible gain, and with no upgrades never.
    assert!(
        eager_twice > 0,
        "eager downloaded no tile twice: the check says nothing"
    );
    assert!(
        thrifty_twice < eager_twice,
        "{thrifty_twice} vs {eager_twice}"
    );
    assert_eq!(never_twice, 0);
    assert!(
        never <= thrifty && thrifty < eager,
        "{never} {thrifty} {eager}"
    );
    // With the oracle at 200 Mbit/s the 1.5 s horizon still covers every first-time entry
    // that eager's 10 s does.
    assert!(
        thrifty_chr.hits >= eager_chr.hits,
        "{thrifty_chr:?} {eager_chr:?}"
    );
}

/// First-time CHR of `kind` over a street walk, a flight and a human session (the first of the
/// tuning split's val scenes) placed in the small city, 40 s each at 10 Mbit/s.
fn chr_of(truth: &Truth, dir: &std::path::Path, grid: &StreetGrid, kind: PredictorKind) -> Ratio {
    use splat2tiles_lab::sim::stream_city::{NAVIGATION_DIR, flight, human_traces};
    use splat2tiles_stream::split::Split;
    let nav = common::repo().join(NAVIGATION_DIR);
    let human = human_traces(grid, &nav, Split::Val).unwrap().swap_remove(0);
    let mut total = Ratio::default();
    for trace in [street_walk(grid, 17, 40.0), flight(grid, 37, 40.0), human] {
        let cfg = CitySpec::small_client(kind);
        let poses: Vec<_> = trace
            .poses
            .iter()
            .filter(|p| p.t <= 40.0)
            .copied()
            .collect();
        let log = run_session(
            dir,
            cfg.clone(),
            &poses,
            &NetModel::constant(10.0, 0.04),
            SessionOptions::default(),
        );
        let needed = truth.needed_per_tick(&cfg, &log);
        let resident = held_tiles(&log);
        let views = tick_views(&log, needed.iter().map(Vec::as_slice), &resident);
        let c = cache_hits(&views);
        total.hits += c.first.hits;
        total.n += c.first.n;
    }
    total
}

/// The learned view predictor ranks above linear extrapolation, and linear above reactive, on
/// the small city: a regression of the model or of how the client uses its turned views shows.
#[test]
fn learned_beats_linear_beats_reactive_in_a_small_city() {
    let tmp = tempfile::tempdir().unwrap();
    let city = build_city(
        &common::scenes(),
        &tmp.path().join("city"),
        &CitySpec::small(),
        None,
    )
    .unwrap();
    let truth = Truth::load(&city.dir.join("tileset.json")).unwrap();
    let [learned, linear, reactive] = [
        PredictorKind::Learned,
        PredictorKind::Linear,
        PredictorKind::Reactive,
    ]
    .map(|k| chr_of(&truth, &city.dir, &city.grid, k));
    eprintln!("first-time CHR: learned {learned:?}, linear {linear:?}, reactive {reactive:?}");
    let rate = |r: Ratio| r.rate().unwrap();
    assert!(learned.n >= 200, "too few entries: {learned:?}");
    assert!(
        rate(learned) >= rate(linear) + 0.05,
        "learned {learned:?} vs linear {linear:?}"
    );
    assert!(
        rate(linear) >= rate(reactive) + 0.05,
        "linear {linear:?} vs reactive {reactive:?}"
    );
}

/// The committed view model is what fitting the city's tuning split gives (no test-split trace
/// can enter: the tuning set refuses them), weight for weight.
#[test]
fn the_committed_view_model_refits_from_the_tuning_split_alone() {
    use splat2tiles_lab::sim::learn::{fit, tuning_samples};
    use splat2tiles_lab::sim::stream_city::{NAVIGATION_DIR, city_sources, trace_set, tuning_set};
    use splat2tiles_stream::learned::ViewModel;
    use splat2tiles_stream::split::{Split, TuningSet, split_of};
    let spec = CitySpec::default();
    let grid = StreetGrid::of(
        &city_sources(&common::scenes(), spec.stride).unwrap(),
        &spec.layout(),
    );
    let nav = common::repo().join(NAVIGATION_DIR);
    let set = tuning_set(&grid, &nav).unwrap();
    for t in set.train().iter().chain(set.val()) {
        assert_ne!(split_of(t).unwrap(), Split::Test);
    }
    let test = trace_set(&grid, &nav, Split::Test).unwrap();
    assert!(TuningSet::new().admit(test[0].clone()).is_err());
    let committed = ViewModel::committed();
    let (train, val) = tuning_samples(&set, 0.25);
    let refit = fit(&train, &val, 1e-3, &committed.trained_on);
    let close = |a: &[Vec<f64>], b: &[Vec<f64>]| {
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .all(|(x, y)| (x - y).abs() <= 1e-9 * (1.0 + x.abs()))
    };
    assert!(close(&refit.yaw, &committed.yaw), "yaw weights differ");
    assert!(
        close(&refit.pitch, &committed.pitch),
        "pitch weights differ"
    );
    assert!(
        close(&refit.forward, &committed.forward),
        "forward weights differ"
    );
    assert!(close(&refit.left, &committed.left), "left weights differ");
    assert!(
        close(&refit.yaw_spread, &committed.yaw_spread),
        "spread weights differ"
    );
}
