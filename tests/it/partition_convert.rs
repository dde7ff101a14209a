//! `convert --partition views:DIR`: the tree DP's plan shapes the leaf levels (finer where the
//! tuning traces look, the output still validates), and a test-split trace is refused (exit 2).

use crate::common;

use glam::DVec3;
use splat2tiles_stream::geom::ViewPose;
use splat2tiles_stream::trace::Trace;
use splat2tiles_tiles::tiling::load::load_tileset;
use std::path::Path;
use std::process::Command;

/// A trace of `seed` (its split follows the seed: 0 train, 17 test) looking at the scene's
/// (0, 0) corner from just outside it.
fn corner_trace(seed: u64, split: &str) -> Trace {
    let poses = (0..24)
        .map(|i| {
            let t = i as f64 / 12.0;
            let pos = DVec3::new(-2.0 + 0.1 * i as f64, -2.0, 8.0);
            ViewPose::looking_at(t, pos, DVec3::new(12.0, 12.0, 0.0))
        })
        .collect();
    Trace {
        headers: [
            ("splat2tiles-trace", "1"),
            ("scene", "random"),
            ("kind", "walk"),
            ("seed", &seed.to_string()),
            ("split", split),
        ]
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect(),
        poses,
    }
}

fn convert(input: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(common::bin())
        .arg("convert")
        .arg(input)
        .arg("-o")
        .arg(out)
        .args([
            "--up-axis",
            "+z",
            "--scheme",
            "quadtree",
            "--max-splats",
            "2000",
        ])
        .args(["--variants", "best", "--no-utility", "-q"])
        .args(extra)
        .output()
        .unwrap()
}

/// (level, box centre) of every leaf (geometric error 0) with content.
fn leaves(out: &Path) -> Vec<(u32, DVec3)> {
    let ts = load_tileset(&out.join("tileset.json")).unwrap();
    ts.tiles
        .iter()
        .filter(|t| t.content.is_some() && t.geometric_error == 0.0)
        .map(|t| {
            let b = t.bounding_box.unwrap();
            (t.key.level, DVec3::new(b[0], b[1], b[2]))
        })
        .collect()
}

#[test]
fn the_plan_refines_where_the_views_look_and_the_output_validates() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("scene.ply");
    common::write_ply_file(&input, &common::random_splats(20_000, 0, 100.0, 3));
    let views = tmp.path().join("views");
    std::fs::create_dir(&views).unwrap();
    std::fs::write(views.join("a.csv"), corner_trace(0, "train").to_csv()).unwrap();

    let base = tmp.path().join("base");
    let o = convert(&input, &base, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let planned = tmp.path().join("planned");
    let arg = format!("views:{}", views.display());
    let o = convert(
        &input,
        &planned,
        &[
            "--partition",
            &arg,
            "--partition-depth",
            "6",
            "--partition-range",
            "40",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    common::assert_valid_with_extents(&planned);

    let (b, p) = (leaves(&base), leaves(&planned));
    let near = |l: &[(u32, DVec3)]| l.iter().filter(|(_, c)| c.x < 25.0 && c.y < 25.0).count();
    let far = |l: &[(u32, DVec3)]| l.iter().filter(|(_, c)| c.x > 60.0 && c.y > 60.0).count();
    assert!(
        near(&p) > near(&b),
        "near leaves {} vs uniform {}",
        near(&p),
        near(&b)
    );
    assert_eq!(far(&p), far(&b), "no view looks at the far corner");
    let total = |l: &[(u32, DVec3)]| l.len();
    assert!(total(&p) > total(&b));
}

#[test]
fn a_test_split_trace_is_refused_and_nothing_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("scene.ply");
    common::write_ply_file(&input, &common::random_splats(500, 0, 10.0, 4));
    let views = tmp.path().join("views");
    std::fs::create_dir(&views).unwrap();
    std::fs::write(views.join("a.csv"), corner_trace(0, "train").to_csv()).unwrap();
    std::fs::write(views.join("b.csv"), corner_trace(17, "test").to_csv()).unwrap();
    let out = tmp.path().join("out");
    let o = convert(
        &input,
        &out,
        &["--partition", &format!("views:{}", views.display())],
    );
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("b.csv") && err.contains("test trace"), "{err}");
    assert!(!out.exists());
    let o = convert(&input, &out, &["--partition", "cams"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!out.exists());
}
