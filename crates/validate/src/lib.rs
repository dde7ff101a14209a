//! `splat2tiles validate`: checks a 3D Tiles 1.1 implicit tileset of `KHR_gaussian_splatting`
//! glb tiles (JSON, subtrees, availability, metadata, every glb) and reports issues as data.
//!
//! Design after CesiumGS/3d-tiles-validator: findings are [`Issue`] values from one constructor
//! per code ([`issues`]), one validator function per spec object that keeps going after a
//! failure, and a [`Report`] that serialises like that validator's JSON report. Every rule, its
//! code and the spec sentence it enforces are listed in `spec/validation.md`.

mod content;
mod context;
mod cut;
mod declarations;
mod glb_buffers;
mod gltf_core;
mod gltf_materials;
pub mod issues;
mod json;
mod layered;
mod legacy;
mod legacy_tables;
mod metadata;
pub mod report;
mod splat_primitive;
mod subtree_file;
mod tileset;
mod uri;
mod volume;

pub use context::ValidateOptions;
pub use issues::{CATALOGUE, Issue, Severity};
pub use report::Report;

use context::Ctx;
use std::path::{Path, PathBuf};

/// Why validation could not run at all (exit code 2).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ValidateError {
    /// `tileset.json` itself could not be read (missing, not a regular file, or larger than
    /// `--max-decompressed-mib`).
    #[error(transparent)]
    Unreadable(#[from] splat2tiles_io::BoundedReadError),
}

/// Validates the tileset at `path` (a `tileset.json`, or a folder holding one) and everything
/// it references.
pub fn validate_tileset(path: &Path, opts: &ValidateOptions) -> Result<Report, ValidateError> {
    let file = if path.is_dir() {
        path.join("tileset.json")
    } else {
        path.to_path_buf()
    };
    let kind = splat2tiles_io::FileKind::new("tileset JSON", opts.max_decompressed_bytes);
    let bytes = splat2tiles_io::read_file(&file, kind)?;
    let dir = match file.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = file.file_name().map_or_else(
        || "tileset.json".into(),
        |n| n.to_string_lossy().into_owned(),
    );
    Ok(run(&bytes, &dir, Some((&file, name)), opts))
}

/// Validates `tileset.json` bytes whose URIs resolve inside `dir`.
pub fn validate_tileset_bytes(bytes: &[u8], dir: &Path, opts: &ValidateOptions) -> Report {
    run(bytes, dir, None, opts)
}

/// Validates tileset JSON bytes; `file` is the file they came from (for cycles) and its name.
fn run(bytes: &[u8], dir: &Path, file: Option<(&Path, String)>, opts: &ValidateOptions) -> Report {
    let mut ctx = Ctx::new(dir.to_path_buf(), opts);
    let layered_from = file.as_ref().map(|(path, _)| path.to_path_buf());
    if let Some((path, name)) = file {
        // Issue paths name the file relative to the root (`--root` may be a parent folder).
        ctx.file = uri::lexical(path)
            .strip_prefix(&ctx.root)
            .map_or(name, |p| p.display().to_string());
        if let Ok(real) = std::fs::canonicalize(path) {
            ctx.visited.insert(real.clone());
            ctx.chain.push(real);
        }
    }
    let name = ctx.file.clone();
    let mut parsed = false;
    if let Some(bytes) = ctx.decompress(bytes.to_vec(), &name)
        && let Some(v) = json::parse(&mut ctx, &bytes, &name)
    {
        parsed = true;
        tileset::tileset(&mut ctx, &v, glam::DMat4::IDENTITY);
        if let Some(path) = &layered_from {
            layered::validate(&mut ctx, path);
        }
    }
    // Refused for its size or depth, the file was JSON: those are findings (exit 1), while a
    // file that is not JSON at all (or a broken compressed stream) could not be read.
    let over_limits = ctx
        .issues
        .last()
        .is_some_and(|i| matches!(i.code.as_str(), "JSON_TOO_LARGE" | "JSON_NESTING_TOO_DEEP"));
    let mut report = Report::new(ctx.issues);
    report.unreadable = !parsed && !over_limits;
    report
}

/// Validates one glb on its own (framing, accessors, `KHR_gaussian_splatting` rules).
pub fn validate_glb_bytes(bytes: &[u8], opts: &ValidateOptions) -> Report {
    let mut ctx = Ctx::new(PathBuf::from("/nonexistent-validate-root"), opts);
    if let Some(bytes) = ctx.decompress(bytes.to_vec(), "content.glb") {
        content::validate_glb(&mut ctx, &bytes, "content.glb", opts.check_extent);
    }
    Report::new(ctx.issues)
}

/// Validates one `.subtree` file on its own as the root subtree of a minimal implicit tileset
/// with the given scheme and `subtree_levels` (framing, buffers, availability).
pub fn validate_subtree_bytes(
    bytes: &[u8],
    octree: bool,
    subtree_levels: u32,
    opts: &ValidateOptions,
) -> Report {
    let dir = PathBuf::from("/nonexistent-validate-root");
    let tileset = serde_json::json!({
        "asset": {"version": "1.1"}, "geometricError": 1.0,
        "root": {
            "boundingVolume": {"box": [0,0,0, 1,0,0, 0,1,0, 0,0,1]},
            "geometricError": 1.0, "refine": "REPLACE",
            "implicitTiling": {
                "subdivisionScheme": if octree { "OCTREE" } else { "QUADTREE" },
                "subtreeLevels": subtree_levels, "availableLevels": subtree_levels,
                "subtrees": {"uri": "0.subtree"}
            }
        }
    });
    let mut ctx = Ctx::new(dir.clone(), opts);
    ctx.memory = Some((dir.join("0.subtree"), bytes.to_vec()));
    // Only the root subtree is read: children are not present, templates map to "0.subtree".
    tileset::tileset(&mut ctx, &tileset, glam::DMat4::IDENTITY);
    let issues = ctx
        .issues
        .into_iter()
        .filter(|i| i.code != "TEMPLATE_URI_MISSING_VARIABLE_NAME")
        .collect();
    Report::new(issues)
}
