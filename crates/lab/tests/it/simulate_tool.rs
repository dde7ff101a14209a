//! `simulate --tileset --trace`: the tool on the converted plant (a folder and the same folder
//! over HTTP give the same numbers) and on a small city against the city experiment's path.

use crate::common;

use clap::Parser;
use splat2tiles_build::convert::{ConvertOptions, convert};
use splat2tiles_lab::experiments::SimulateArgs;
use splat2tiles_lab::experiments::simulate_city::{BUDGET, session};
use splat2tiles_lab::experiments::simulate_tool::{ToolRun, run_tool};
use splat2tiles_lab::sim::report::{needed_cuts, session_numbers};
use splat2tiles_lab::sim::score::Truth;
use splat2tiles_lab::sim::session::RequestLog;
use splat2tiles_lab::sim::stream_city::{CitySpec, build_city, street_walk};
use splat2tiles_lab::sim::transport::NetModel;
use splat2tiles_stream::catalog::Level;
use splat2tiles_stream::client::ClientConfig;
use splat2tiles_stream::plan::Planner;
use splat2tiles_stream::trace::Trace;
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::variants::{Variant, VariantOptions};
use std::collections::HashMap;
use std::path::Path;

/// `splat2tiles-lab simulate`'s arguments.
#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    args: SimulateArgs,
}

fn args(list: &[&str]) -> SimulateArgs {
    let mut v = vec!["simulate"];
    v.extend_from_slice(list);
    Cli::try_parse_from(v).expect("options parse").args
}

fn tool(list: &[&str]) -> anyhow::Result<ToolRun> {
    run_tool(&args(list))
}

fn json(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("report.json")).expect("report.json");
    serde_json::from_str(&text).expect("report.json parses")
}

/// A local HTTP server of `dir` (the `splat2tiles serve` library) for the test's lifetime.
struct Served {
    url: String,
    stop: splat2tiles_serve::StopHandle,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Drop for Served {
    fn drop(&mut self) {
        self.stop.stop();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn serve(dir: &Path) -> Served {
    let mount = splat2tiles_serve::Mount::new("/", dir).unwrap();
    let server = splat2tiles_serve::Server::bind(
        vec![mount],
        splat2tiles_serve::ServeOptions {
            bind: std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST),
            port: 0,
            quiet: true,
            threads: 4,
            per_address: 4,
        },
    )
    .unwrap();
    let url = format!("http://{}/tileset.json", server.addr());
    let stop = server.stop_handle();
    let thread = Some(std::thread::spawn(move || server.run()));
    Served { url, stop, thread }
}

#[test]
fn simulate_tool_on_the_plant_from_a_folder_and_over_http() {
    let tmp = tempfile::tempdir().unwrap();
    let plant = tmp.path().join("plant");
    let opts = ConvertOptions {
        max_splats_per_tile: 8192,
        subtree_levels: Some(2),
        variants: VariantOptions {
            variants: vec![Variant::Best, Variant::Low],
            measure_utility: false,
            ..VariantOptions::default()
        },
        ..ConvertOptions::default()
    };
    convert(&common::scene("plant.splat"), &plant, &opts).expect("convert plant.splat");
    let trace = common::repo().join("traces/plant_dolly.csv");
    let (trace, plant_s) = (trace.to_str().unwrap(), plant.to_str().unwrap());
    let common_opts = [
        "--trace",
        trace,
        "--bandwidth",
        "10Mbit",
        "--rtt",
        "40ms",
        "--predictor",
        "linear",
        "--budget",
        "32MiB",
    ];
    let local_dir = tmp.path().join("local");
    let mut list = vec![
        "--tileset",
        plant_s,
        "--report-dir",
        local_dir.to_str().unwrap(),
    ];
    list.extend(common_opts);
    list.extend(["--quality-hz", "0.5"]);
    let t0 = std::time::Instant::now();
    let run = tool(&list).expect("simulate the plant folder");
    eprintln!(
        "local run with quality: {:.1} s",
        t0.elapsed().as_secs_f64()
    );
    let n = run.numbers;
    // The dolly: 20 s at 12 Hz, the whole plant in view from the start.
    assert_eq!(run.log.ticks.len(), 241);
    assert!(
        n.chr.initial.n > 10,
        "cold start entries {:?}",
        n.chr.initial
    );
    assert!(
        (1_000_000..50_000_000).contains(&n.bytes_down),
        "{} bytes",
        n.bytes_down
    );
    assert!(n.waste.tiles > 10 && n.waste.wasted_tiles <= n.waste.tiles);
    assert!(
        n.warm_at > 0.04 && n.warm_at < 20.0,
        "warm-up {}",
        n.warm_at
    );
    assert!(
        n.stall_ticks < run.log.ticks.len(),
        "{} stalls",
        n.stall_ticks
    );
    assert_eq!((run.log.errors, n.evictions), (0, 0));
    // Quality at 0.5 Hz: 11 samples in [0, 1], the last (all received) at full quality.
    assert_eq!(run.quality.len(), 11);
    assert!(run.quality.iter().all(|&(_, q)| (0.0..=1.0).contains(&q)));
    assert!(run.quality.last().unwrap().1 > 0.99, "{:?}", run.quality);
    let (cold, _) = run.tgq.as_ref().expect("TGQ with quality");
    assert!(cold.is_some_and(|s| s < 5.0), "cold-start TGQ {cold:?}");
    for f in ["report.md", "report.json", "bytes.svg", "quality.svg"] {
        let text = std::fs::read_to_string(local_dir.join(f)).unwrap();
        assert!(text.len() > 200, "{f}: {text}");
    }
    let md = std::fs::read_to_string(local_dir.join("report.md")).unwrap();
    assert!(
        md.contains("| CHR, cold start (first non-empty cut) |"),
        "{md}"
    );
    assert!(md.contains("stalled ticks"), "{md}");
    let local = json(&local_dir);
    assert_eq!(local["results"]["bytes_received"], n.bytes_down);
    assert_eq!(local["inputs"]["tileset"], plant_s);

    // The same folder over HTTP: the same decisions and numbers (no quality this time).
    let served = serve(&plant);
    let http_dir = tmp.path().join("http");
    let mut list = vec![
        "--tileset",
        &served.url,
        "--report-dir",
        http_dir.to_str().unwrap(),
    ];
    list.extend(common_opts);
    list.extend(["--quality-hz", "0"]);
    let remote = tool(&list).expect("simulate the served plant");
    drop(served);
    assert_eq!(
        relative_requests(&remote, &http_dir.join("mirror")),
        relative_requests(&run, &plant)
    );
    let mut a = local["results"].clone();
    let mut b = json(&http_dir)["results"].clone();
    for v in [&mut a, &mut b] {
        let o = v.as_object_mut().unwrap();
        o.remove("tgq");
        o.remove("quality_over_time");
    }
    assert_eq!(a, b);
    assert!(!http_dir.join("quality.svg").exists());
    assert!(!http_dir.join("mirror").exists(), "the mirror is removed");
    assert_eq!(json(&http_dir)["inputs"]["tileset"], served_url(&remote));
}

/// The session's requests with their URLs relative to the tileset folder `dir`.
fn relative_requests(run: &ToolRun, dir: &Path) -> Vec<RequestLog> {
    let prefix = format!("{}/", dir.display());
    let mut out = run.log.requests.clone();
    for r in &mut out {
        assert!(r.url.starts_with(&prefix), "{} outside {prefix}", r.url);
        r.url = r.url[prefix.len()..].to_string();
    }
    assert!(out.len() > 10, "{} requests", out.len());
    out
}

fn served_url(run: &ToolRun) -> String {
    run.inputs.source.clone()
}

#[test]
fn simulate_tool_refuses_bad_input_with_the_culprit_named() {
    let tmp = tempfile::tempdir().unwrap();
    let rep = tmp.path().join("r");
    let rep = rep.to_str().unwrap();
    let missing = tmp.path().join("none.csv");
    let bad_line = tmp.path().join("bad.csv");
    std::fs::write(
        &bad_line,
        "# splat2tiles-trace: 1\nt,x,y,z,yaw_deg,pitch_deg\n0,0,0,0,0,0\n1,2,3\n",
    )
    .unwrap();
    // The tileset is checked first: an empty folder is refused by name.
    let err = tool(&["--tileset", rep, "--trace", "x.csv", "--report-dir", rep]).unwrap_err();
    assert!(format!("{err:#}").contains("tileset.json"), "{err:#}");
    let plant = tmp.path().join("plant");
    let opts = ConvertOptions {
        max_splats_per_tile: 65536,
        ..ConvertOptions::default()
    };
    convert(&common::scene("plant.splat"), &plant, &opts).expect("convert plant.splat");
    let p = plant.to_str().unwrap();
    let cases: [(Vec<&str>, String); 6] = [
        (
            vec!["--trace", missing.to_str().unwrap()],
            "none.csv".into(),
        ),
        (
            vec!["--trace", bad_line.to_str().unwrap()],
            "bad.csv: line 4".into(),
        ),
        (vec!["--bandwidth", "fast"], "--bandwidth 'fast'".into()),
        (
            vec!["--predictor", "psychic"],
            "--predictor 'psychic'".into(),
        ),
        (vec!["--planner", "nope"], "--planner 'nope'".into()),
        (vec!["--prefetch", "soon"], "--prefetch 'soon'".into()),
    ];
    let good = common::repo().join("traces/plant_dolly.csv");
    default_anchor(&plant, rep);
    for (extra, want) in cases {
        let mut list = vec!["--tileset", p, "--report-dir", rep];
        if !extra.contains(&"--trace") {
            list.extend(["--trace", good.to_str().unwrap()]);
        }
        list.extend(extra);
        let err = format!("{:#}", tool(&list).unwrap_err());
        assert!(err.contains(&want), "{list:?}: {err}");
    }
}

/// An EyeNavGS trace without `--anchor` starts at the centre of the content bounds, at their
/// lowest z plus the eye height.
fn default_anchor(plant: &Path, rep: &str) {
    let csv = plant.parent().unwrap().join("eyenav.csv");
    let rows: String = (0..=24)
        .map(|k| format!("{},0.1,1.6,0,0,0,0,1\n", k as f64 / 12.0))
        .collect();
    std::fs::write(&csv, format!("t_s,x,y,z,qx,qy,qz,qw\n{rows}")).unwrap();
    let run = tool(&[
        "--tileset",
        plant.to_str().unwrap(),
        "--trace",
        csv.to_str().unwrap(),
        "--eye-height",
        "0.5",
        "--quality-hz",
        "0",
        "--report-dir",
        rep,
    ])
    .expect("an EyeNavGS trace");
    let ts = splat2tiles_tiles::tiling::load::load_tileset(&plant.join("tileset.json")).unwrap();
    let (lo, hi) =
        splat2tiles_stream::catalog::TileCatalog::from_loaded(&ts.tiles, |_| Some(1)).bounds();
    let want = glam::DVec3::new(0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), lo.z + 0.5);
    let p = run.inputs.trace.poses[0].pos;
    assert!((p - want).length() < 1e-9, "{p} vs {want}");
    assert_eq!(run.log.ticks.len(), 25);
}

#[test]
fn simulate_tool_matches_the_city_experiment() {
    let scenes = common::scenes();
    let tmp = tempfile::tempdir().unwrap();
    let city = build_city(&scenes, &tmp.path().join("city"), &CitySpec::small(), None).unwrap();
    let walk = street_walk(&city.grid, 17, 30.0);
    let csv = tmp.path().join("walk.csv");
    std::fs::write(&csv, walk.to_csv()).unwrap();
    let tr = Trace::from_csv(&std::fs::read_to_string(&csv).unwrap()).unwrap();
    assert_eq!(tr.poses.len(), walk.poses.len());
    assert!((tr.poses[5].pos - walk.poses[5].pos).length() < 1e-3);
    // The city experiment's inputs: its needed cuts, Low bytes and link.
    let truth = Truth::load(&city.dir.join("tileset.json")).unwrap();
    let needed: Vec<Vec<TileKey>> = needed_cuts(&truth, &ClientConfig::default(), &tr.poses);
    let ts = splat2tiles_tiles::tiling::load::load_tileset(&city.dir.join("tileset.json")).unwrap();
    let low: HashMap<TileKey, u64> = splat2tiles_tiles::variants::content_variant_metadata(&ts)
        .into_iter()
        .map(|(k, (_, b, _))| (k, b[Level::Low.index()] as u64))
        .collect();
    let net = NetModel::constant(10.0, 0.04);
    assert_eq!(BUDGET, 32 << 20);
    for p in ["reactive", "linear", "oracle"] {
        let t0 = std::time::Instant::now();
        let rep = tmp.path().join(p);
        let run = tool(&[
            "--tileset",
            city.dir.to_str().unwrap(),
            "--trace",
            csv.to_str().unwrap(),
            "--predictor",
            p,
            "--planner",
            "dc-dp",
            "--budget",
            "32MiB",
            "--bandwidth",
            "10Mbit",
            "--rtt",
            "40ms",
            "--quality-hz",
            "0",
            "--report-dir",
            rep.to_str().unwrap(),
        ])
        .unwrap();
        let log = session(&city.dir, &tr, p, Planner::Dp, &net, BUDGET);
        let want = session_numbers(&log, &needed, &low, &net);
        eprintln!(
            "{p}: CHR first-time {:?}, after warm-up {:?}, {} B ({:.1} s)",
            want.chr.first,
            want.chr.warm,
            want.bytes_down,
            t0.elapsed().as_secs_f64()
        );
        assert!(want.chr.first.n > 0, "{p}: the walk enters tiles");
        assert_eq!(run.log.requests, log.requests, "{p}");
        assert_eq!(run.numbers, want, "{p}");
        let j = json(&rep);
        assert_eq!(
            j["results"]["chr"]["first_time"]["hits"],
            want.chr.first.hits
        );
        assert_eq!(
            j["results"]["chr"]["after_warm_up"]["entries"],
            want.chr.warm.n
        );
    }
}

#[test]
fn simulate_tool_places_an_eyenav_trace() {
    use splat2tiles_lab::experiments::simulate_tool::read_trace;
    use splat2tiles_stream::eyenav::Placement;
    let tmp = tempfile::tempdir().unwrap();
    let csv = tmp.path().join("user1_scene.csv");
    // Unity frame (y up): walking 1 m along Unity +z (our +y) in 1 s, head at a constant 1.6 m,
    // looking along +z.
    let mut text = String::from("t_s,x,y,z,qx,qy,qz,qw\n");
    for k in 0..=12 {
        let t = k as f64 / 12.0;
        text.push_str(&format!("{t},0,1.6,{t},0,0,0,1\n"));
    }
    std::fs::write(&csv, &text).unwrap();
    let pl = Placement {
        anchor: glam::DVec3::new(10.0, 20.0, 3.0),
        heading_deg: 90.0,
        ..Placement::default()
    };
    let tr = read_trace(&csv, &pl).unwrap();
    assert_eq!(tr.poses.len(), 13);
    let (a, b) = (tr.poses[0], tr.poses[12]);
    assert!(
        (a.pos - glam::DVec3::new(10.0, 20.0, 4.7)).length() < 1e-9,
        "{a:?}"
    );
    // Turned by 90 degrees: +y becomes -x.
    assert!(
        (b.pos - glam::DVec3::new(9.0, 20.0, 4.7)).length() < 1e-9,
        "{b:?}"
    );
    assert!(
        (a.yaw.to_degrees() - 180.0).abs() < 1e-6,
        "{}",
        a.yaw.to_degrees()
    );
    // A malformed row is refused with the file and the line.
    std::fs::write(&csv, text + "2.0,0,1.6\n").unwrap();
    let err = format!("{:#}", read_trace(&csv, &pl).unwrap_err());
    assert!(
        err.contains("user1_scene.csv") && err.contains("line 15"),
        "{err}"
    );
}
