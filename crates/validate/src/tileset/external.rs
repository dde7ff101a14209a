//! External tilesets (3D Tiles 1.1 "External tilesets"): a content that is itself a tileset JSON
//! is validated in full, relative to its own folder, with cycle detection and a depth limit.

use crate::context::Ctx;
use crate::issues::{Issue, Severity};
use crate::json;
use glam::DMat4;
use std::path::Path;

/// Validates the external tileset `file` (bytes already read) named by `uri` at `path`; its
/// issues become the causes of one EXTERNAL_TILESET_* issue.
pub(crate) fn external(
    ctx: &mut Ctx<'_>,
    file: &Path,
    bytes: &[u8],
    uri: &str,
    path: &str,
    world: DMat4,
) {
    let real = std::fs::canonicalize(file).unwrap_or_else(|_| file.to_path_buf());
    if let Some(i) = ctx.chain.iter().position(|p| *p == real) {
        let loop_len = ctx.chain.len() - i;
        ctx.push(Issue::EXTERNAL_TILESET_CYCLE(
            path,
            if loop_len == 1 {
                format!("'{uri}' is the tileset that refers to it: a cycle")
            } else {
                format!(
                    "'{uri}' is already being validated {loop_len} external tilesets up: a cycle"
                )
            },
        ));
        return;
    }
    if ctx.chain.len() > ctx.opts.max_external_depth {
        ctx.push(Issue::EXTERNAL_TILESET_TOO_DEEP(
            path,
            format!(
                "'{uri}' would be external tileset level {}: deeper than {}; not opened",
                ctx.chain.len(),
                ctx.opts.max_external_depth
            ),
        ));
        return;
    }
    if !ctx.visited.insert(real.clone()) {
        // Referenced before (not in a cycle): its issues were reported the first time; what it
        // uses still counts for this referring tileset.
        if let Some(found) = ctx.found_in.get(&real).cloned() {
            ctx.found_below.extend(found);
        }
        return;
    }
    let outer_below = std::mem::take(&mut ctx.found_below);
    let name = file
        .strip_prefix(&ctx.root)
        .map(|p| p.display().to_string())
        .unwrap_or_else(|_| uri.to_string());
    let dir = file.parent().map(Path::to_path_buf).unwrap_or_default();
    let saved_dir = std::mem::replace(&mut ctx.dir, dir);
    let saved_file = std::mem::replace(&mut ctx.file, name.clone());
    let saved_issues = std::mem::take(&mut ctx.issues);
    let saved_variants = std::mem::take(&mut ctx.variant_templates);
    let saved_gltf = ctx.gltf_undeclared;
    ctx.chain.push(real.clone());

    if let Some(v) = json::parse(ctx, bytes, &name) {
        super::tileset(ctx, &v, world);
    }

    // `tileset` left what this external tileset and those below it use in found_below.
    let found = std::mem::replace(&mut ctx.found_below, outer_below);
    ctx.found_below.extend(found.iter().cloned());
    ctx.found_in.insert(real.clone(), found);
    ctx.chain.pop();
    ctx.variant_templates = saved_variants;
    ctx.gltf_undeclared = saved_gltf;
    ctx.file = saved_file;
    ctx.dir = saved_dir;
    let causes = std::mem::replace(&mut ctx.issues, saved_issues);
    let worst = causes.iter().map(|i| i.severity).min();
    let summary = |what: &str| format!("external tileset '{uri}' has {what} (see causes)");
    let issue = match worst {
        None => return,
        Some(Severity::Error) => Issue::EXTERNAL_TILESET_VALIDATION_ERROR(path, summary("errors")),
        Some(Severity::Warning) => {
            Issue::EXTERNAL_TILESET_VALIDATION_WARNING(path, summary("warnings"))
        }
        Some(Severity::Info) => Issue::EXTERNAL_TILESET_VALIDATION_INFO(path, summary("notes")),
    };
    // Pushed directly: its causes were already counted against the issue limit.
    ctx.issues.push(issue.with_causes(causes));
}
