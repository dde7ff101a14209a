//! Every output of `splat2tiles convert` on the shared scenes, in every
//! profile with every quality variant written (and georeferenced), validates with 0 errors and
//! 0 warnings. Variant files are found through the tileset's `splatVariants` metadata.

use crate::common::*;
use std::process::Command;

#[test]
fn converter_outputs_validate_clean_in_every_profile_and_variant() {
    let tmp = tempfile::tempdir().unwrap();
    let mut cases = vec![];
    for name in ["plant.splat", "donut_fused_sh0.ply", "biker.spz"] {
        for profile in ["default", "cesium"] {
            cases.push((
                format!("{name}-{profile}"),
                vec![
                    scene(name).display().to_string(),
                    "--profile".into(),
                    profile.into(),
                    "--variants".into(),
                    "all".into(),
                    "--max-splats".into(),
                    "20000".into(),
                ],
            ));
        }
    }
    cases.push((
        "plant-georeferenced".into(),
        vec![
            scene("plant.splat").display().to_string(),
            "--origin".into(),
            "2.2945,48.8584,35".into(),
            "--variants".into(),
            "all".into(),
        ],
    ));
    for (label, args) in cases {
        let out = tmp.path().join(&label);
        let o = Command::new(bin())
            .arg("convert")
            .args(&args)
            .arg("-o")
            .arg(&out)
            .arg("-q")
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{label}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let o = Command::new(bin())
            .arg("validate")
            .arg(out.join("tileset.json"))
            .arg("--json")
            .output()
            .unwrap();
        let report: serde_json::Value = serde_json::from_slice(&o.stdout)
            .unwrap_or_else(|e| panic!("{label}: report is JSON: {e}"));
        assert_eq!(o.status.code(), Some(0), "{label}: {report}");
        assert_eq!(report["numErrors"], 0, "{label}: {report}");
        assert_eq!(report["numWarnings"], 0, "{label}: {report}");
        // The variant files were visited: compressed ones are reported as not value-checked
        // (notes folded under each content's CONTENT_VALIDATION_INFO).
        let issues: Vec<&serde_json::Value> = report["issues"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|i| std::iter::once(i).chain(i["causes"].as_array().into_iter().flatten()))
            .collect();
        assert!(
            issues
                .iter()
                .any(|i| i["path"].as_str().unwrap_or("").contains("/low/")
                    || i["message"].as_str().unwrap_or("").contains("compression")),
            "{label}: Low variant files were checked"
        );
    }
}
