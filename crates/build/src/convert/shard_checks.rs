//! The sharded conversion's own files checked from bytes, exactly as `convert --part` and
//! `merge` check them after reading (what the `plan`, `part` and `samples` fuzz targets drive).

use super::ConvertError;
use super::plan::Plan;
use std::path::Path;

/// Parses and checks plan bytes (`plan.json` in messages).
pub fn check_plan_bytes(plan: &[u8]) -> Result<(), ConvertError> {
    Plan::from_bytes(Path::new("plan.json"), plan).map(|_| ())
}

/// Parses and checks part-file bytes against the plan bytes `plan`.
pub fn check_part_bytes(plan: &[u8], part: &[u8]) -> Result<(), ConvertError> {
    let plan_path = Path::new("plan.json");
    let p = Plan::from_bytes(plan_path, plan)?;
    super::merge::check_part(&p, plan_path, Path::new("part.json"), part).map(|_| ())
}

/// Parses and checks samples-file bytes against the plan bytes `plan`.
pub fn check_samples_bytes(plan: &[u8], samples: &[u8]) -> Result<(), ConvertError> {
    let p = Plan::from_bytes(Path::new("plan.json"), plan)?;
    super::part::check_samples(&p, Path::new("samples.json"), samples).map(|_| ())
}
