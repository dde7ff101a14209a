//! Utilities measured once the tree is built: every content tile's written variants decoded and
//! compared with its Best at the tile's real switching distance (spec/quality-variants.md).

use std::path::Path;

use rayon::prelude::*;

use super::curve::LossCurve;
use super::utility::{ViewSetup, utilities};
use super::{ALL, ContentError, Variant, VariantOptions, content_uri, decode_variant, estimate};
use splat2tiles_core::splat::Splats;
use splat2tiles_tiles::encode::storage_order::aligned_to_best;
use splat2tiles_tiles::tiling::{Scheme, TileKey};

/// Reads and decodes one written variant of a tile under `dir`.
fn read_variant(
    dir: &Path,
    scheme: Scheme,
    key: TileKey,
    v: Variant,
) -> Result<(Splats, [f64; 16]), ContentError> {
    let path = dir.join(content_uri(scheme, key, v));
    let glb = std::fs::read(&path).map_err(|source| ContentError::Io { path, source })?;
    decode_variant(&glb).map_err(|source| ContentError::Encode {
        key,
        variant: v.name(),
        source,
    })
}

/// The utility of each variant of one tile (in [`ALL`] order; 1 for Best, -1 for a variant not
/// written), viewed at geometric error `error` (the tile's own, a leaf's parent's; not
/// positive: unknown): estimated from `curve` when the writer made one (and utilities are not
/// rendered), else from its variants read back from `dir`.
pub fn tile_utilities(
    dir: &Path,
    scheme: Scheme,
    key: TileKey,
    error: f64,
    curve: Option<&LossCurve>,
    opts: &VariantOptions,
) -> Result<[f32; 4], ContentError> {
    let mut out = [-1.0f32; 4];
    out[Variant::Best.index()] = 1.0;
    let written = opts.written();
    let others: Vec<Variant> = ALL
        .into_iter()
        .filter(|v| *v != Variant::Best && written.contains(v))
        .collect();
    if others.is_empty() {
        return Ok(out);
    }
    if let Some(curve) = curve.filter(|_| !opts.utility_renders) {
        for v in others {
            // Not compared: not the same splats as Best, as `estimated_utilities` scores it.
            out[v.index()] = curve.utility(v.index(), error).unwrap_or(0.0) as f32;
        }
        return Ok(out);
    }
    let (best, node) = read_variant(dir, scheme, key, Variant::Best)?;
    let decoded = others
        .iter()
        .map(|&v| read_variant(dir, scheme, key, v).map(|d| d.0))
        .collect::<Result<Vec<_>, _>>()?;
    // Splat for splat against Best (High and Medium are stored in Morton order); a variant that
    // does not hold Best's splats stays as read and scores 0.
    let decoded: Vec<Splats> = decoded
        .into_iter()
        .map(|d| aligned_to_best(&d, &best).unwrap_or(d))
        .collect();
    let refs: Vec<&Splats> = decoded.iter().collect();
    let u = match ViewSetup::around(&best, super::up_in_source(node), error) {
        None => vec![1.0; refs.len()],
        Some(setup) if opts.utility_renders => utilities(&best, &refs, &setup),
        Some(setup) => estimate::estimated_utilities(&best, &refs, &setup),
    };
    for (v, u) in others.iter().zip(u) {
        out[v.index()] = u as f32;
    }
    Ok(out)
}

/// [`tile_utilities`] of every `(key, error, curve)` in `tiles` (in parallel), in that order.
pub fn measure_utilities(
    dir: &Path,
    scheme: Scheme,
    tiles: &[(TileKey, f64, Option<&LossCurve>)],
    opts: &VariantOptions,
) -> Result<Vec<[f32; 4]>, ContentError> {
    tiles
        .par_iter()
        .map(|&(key, error, curve)| tile_utilities(dir, scheme, key, error, curve, opts))
        .collect()
}
