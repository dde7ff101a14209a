//! Reads a KHR_gaussian_splatting glb written by another tool (npm `@playcanvas/splat-transform`
//! 2.7.1, from `data/scenes/plant.splat`); needs `npm ci --prefix tests/js` once.

use std::path::Path;
use std::process::Command;

use splat2tiles_tiles::encode::read_tile_glb;

#[test]
fn reads_splat_transform_glb() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let cli = root.join("tests/js/node_modules/@playcanvas/splat-transform/bin/cli.mjs");
    assert!(
        cli.is_file(),
        "{} is missing: run `npm ci --prefix tests/js` (needs Node >= 20)",
        cli.display()
    );
    let scene = root.join("data/scenes/plant.splat");
    assert!(scene.is_file(), "{} is missing", scene.display());
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("plant.glb");
    let out = Command::new("node")
        .arg(&cli)
        .arg("-q")
        .arg(&scene)
        .arg(&glb)
        .output()
        .expect("cannot run `node` (install Node >= 20)");
    assert!(
        out.status.success(),
        "splat-transform failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let d = read_tile_glb(&std::fs::read(&glb).unwrap()).unwrap();
    let s = &d.splats;
    assert_eq!(s.len(), 113_648);
    assert_eq!(d.generator.as_deref(), Some("splat-transform 2.7.1"));
    assert_eq!(d.color_space, "srgb_rec709_display");
    assert_eq!(s.sh_degree, 0, ".splat carries no higher SH");
    for (i, q) in s.rotations.iter().enumerate() {
        let n: f64 = q.iter().map(|&v| v as f64 * v as f64).sum::<f64>().sqrt();
        assert!((n - 1.0).abs() < 1e-4, "splat {i}: |q| = {n}");
    }
    assert!(s.opacities.iter().all(|a| (0.0..=1.0).contains(a)));
    assert!(s.scales.iter().flatten().all(|&v| v >= 0.0));
    assert!(s.sh0.iter().flatten().all(|v| v.is_finite()));
    assert!(s.positions.iter().flatten().all(|v| v.is_finite()));
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
}
