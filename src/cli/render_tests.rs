//! The `render` and `compare` subcommands: argument resolution, a render through an injected scene
//! reader (scene files arrive with the io module), and `compare` through the binary.

#[path = "../../tests/common/scenes.rs"]
#[allow(dead_code)]
mod scenes;

use std::path::{Path, PathBuf};

use super::{
    CompareArgs, RenderArgs, compare_images, default_up_axis, format_compare, run_compare,
    run_render,
};
use glam::DVec3;
use splat2tiles_render::view::resolve_camera;
use splat2tiles_render::{Image, auto_views_with};

fn args(out: PathBuf) -> RenderArgs {
    RenderArgs {
        input: PathBuf::from("scene.splat"),
        camera: None,
        auto_view: Some(0),
        width: Some(64),
        height: Some(48),
        fov: 50.0,
        up_axis: None,
        sh_degree: None,
        background: "0,0,0".into(),
        output: out,
        max_sse: 16.0,
    }
}

#[test]
fn up_axis_defaults_by_format() {
    assert_eq!(default_up_axis(Path::new("a.ply")), -DVec3::Y);
    assert_eq!(default_up_axis(Path::new("a.SPLAT")), -DVec3::Y);
    assert_eq!(default_up_axis(Path::new("a.spz")), DVec3::Y);
}

#[test]
fn camera_specs_resolve() {
    let dir = tempfile::tempdir().unwrap();
    let mut a = args(dir.path().join("o.png"));
    let (lo, hi) = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let bounds = Some((lo, hi));
    let cam = resolve_camera(&a.camera_request(), -DVec3::Y, bounds).unwrap();
    assert_eq!(cam, auto_views_with(lo, hi, -DVec3::Y, 64, 48, 50.0)[0]);
    a.auto_view = Some(8);
    assert!(resolve_camera(&a.camera_request(), -DVec3::Y, bounds).is_err());
    a.auto_view = None;
    a.camera = Some("look-at:0,0,-5:0,0,0".into());
    let cam = resolve_camera(&a.camera_request(), -DVec3::Y, bounds).unwrap();
    assert_eq!(cam.center(), DVec3::new(0.0, 0.0, -5.0));
    a.camera = Some("look-at:0,0:0,0,0".into());
    assert!(resolve_camera(&a.camera_request(), -DVec3::Y, bounds).is_err());
    // An explicit up wins over the scene's; geo: places the eye in ECEF.
    a.camera = Some("look-at:0,0,-5:0,0,0:1,0,0".into());
    let cam = resolve_camera(&a.camera_request(), -DVec3::Y, bounds).unwrap();
    assert!(
        (cam.rotation().y_axis + DVec3::X).length() < 1e-12,
        "image down is -up"
    );
    a.camera = Some("geo:0,0,10:90,0".into());
    let cam = resolve_camera(&a.camera_request(), -DVec3::Y, bounds).unwrap();
    assert!((cam.center() - DVec3::new(6_378_147.0, 0.0, 0.0)).length() < 1e-6);
    assert!(
        (cam.rotation().z_axis - DVec3::Y).length() < 1e-12,
        "heading 90: east"
    );
    for bad in ["geo:0,91,0:0,0", "look-at:0,0,0:1,1,1:0,0,0", "geo:0,0,0"] {
        a.camera = Some(bad.into());
        let e = resolve_camera(&a.camera_request(), -DVec3::Y, bounds).unwrap_err();
        assert!(format!("{e:#}").contains(bad), "{bad}: {e:#}");
    }
    // cameras.json with an id, resized to the requested width/height.
    let json = dir.path().join("cameras.json");
    std::fs::write(
        &json,
        r#"[{"id":0,"img_name":"a","width":640,"height":480,"position":[0,0,0],
        "rotation":[[1,0,0],[0,1,0],[0,0,1]],"fx":500,"fy":500},
        {"id":3,"img_name":"b","width":640,"height":480,"position":[1,2,3],
        "rotation":[[1,0,0],[0,1,0],[0,0,1]],"fx":400,"fy":410}]"#,
    )
    .unwrap();
    a.camera = Some(format!("{}#3", json.display()));
    a.width = Some(320);
    a.height = Some(240);
    let cam = resolve_camera(&a.camera_request(), -DVec3::Y, bounds).unwrap();
    assert_eq!(cam.center(), DVec3::new(1.0, 2.0, 3.0));
    assert_eq!((cam.width, cam.fx, cam.fy), (320, 200.0, 205.0));
    a.camera = Some(format!("{}#9", json.display()));
    assert!(resolve_camera(&a.camera_request(), -DVec3::Y, bounds).is_err());
}

#[test]
fn render_then_compare() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.png");
    let scene = scenes::random_cloud(500, 1, DVec3::ZERO, 4);
    let ply = dir.path().join("cloud.ply");
    splat2tiles_io::write_ply(&scene, std::fs::File::create(&ply).unwrap()).unwrap();
    let mut a = args(out.clone());
    a.input = ply;
    run_render(&a).unwrap();
    let img = Image::load_png(&out).unwrap();
    assert_eq!((img.width, img.height), (64, 48));
    assert!(img.data.iter().any(|&v| v > 0.0), "the cloud is in view");
    let (s, p, _) = compare_images(&out, &out, None).unwrap();
    assert_eq!((s, p), (1.0, f64::INFINITY));
    assert_eq!(
        format_compare(s, p, None, true),
        r#"{"psnr":null,"ssim":1.0}"#
    );
    run_compare(&CompareArgs {
        a: out.clone(),
        b: out.clone(),
        json: false,
        background: Some("0,0,0".into()),
    })
    .unwrap();
    // A background outside [0, 1] is refused, naming the option.
    let e = run_compare(&CompareArgs {
        a: out.clone(),
        b: out.clone(),
        json: false,
        background: Some("0,2,0".into()),
    })
    .unwrap_err();
    assert!(format!("{e:#}").contains("--background"), "{e:#}");
    // Reader errors propagate.
    a.input = dir.path().join("missing.ply");
    assert!(run_render(&a).is_err());
}
