//! Writing a tile's quality variants: every requested encoding of one tile's splats, with the
//! utility of each measured by rendering or estimated from its losses.

pub mod curve;
pub mod estimate;
pub mod measure;
pub mod utility;

pub use utility::utilities;

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde_json::{Value, json};
use splat2tiles_core::splat::Splats;
use splat2tiles_tiles::encode::GlbError;
use splat2tiles_tiles::encode::storage_order::{aligned_to_best, in_storage_order};
use splat2tiles_tiles::tiling::{Scheme, TileKey};

/// The format side of the variants (names, options, decoders, URIs), re-exported so that one
/// path names everything about variants in the build.
pub use splat2tiles_tiles::variants::*;

/// What the per-tile writer reports for the subtree metadata and the conversion report.
#[derive(Debug, Clone, PartialEq)]
pub struct ContentFacts {
    /// Splats in the tile.
    pub splat_count: u32,
    /// Bytes of each variant's glb (0: not written), in [`ALL`] order.
    pub variant_bytes: [u32; 4],
    /// Utility of each variant (`utility::utilities`; 1 for Best; -1: not measured).
    pub variant_utility: [f32; 4],
    /// Seconds spent encoding each variant.
    pub encode_seconds: [f64; 4],
    /// Bytes of all files written for the tile.
    pub bytes: u64,
    /// The estimated utilities' losses at a grid of viewing distances, when they are estimated
    /// after the tree is built ([`curve::loss_curve`]; `None`: read the files back instead).
    pub utility_curve: Option<curve::LossCurve>,
}

/// Why a tile's contents could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ContentError {
    /// A file could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A variant could not be encoded.
    #[error("tile {key:?}, variant {variant}: {source}")]
    Encode {
        /// The tile.
        key: TileKey,
        /// The variant.
        variant: &'static str,
        /// Why.
        source: GlbError,
    },
}

/// Which tile `write_tile_contents` writes: its place in the tree and what its splats are.
#[derive(Debug, Clone, Copy)]
pub struct TileSlot {
    /// Subdivision scheme (for the content URIs).
    pub scheme: Scheme,
    /// The tile.
    pub key: TileKey,
    /// Its splats are merged LOD splats (Low then keeps [`LOW_SPZ_PARENT`]'s step).
    pub parent: bool,
}

/// Writes every requested variant of one tile under `dir` and measures their utilities.
///
/// `splats` hold positions in the source frame S; `centre_s` is subtracted (in f64) and
/// `node_matrix` maps the tile-relative S frame into glTF's y-up frame.
pub fn write_tile_contents(
    dir: &Path,
    slot: TileSlot,
    splats: &Splats,
    centre_s: [f64; 3],
    node_matrix: [f64; 16],
    opts: &VariantOptions,
) -> Result<ContentFacts, ContentError> {
    let TileSlot {
        scheme,
        key,
        parent,
    } = slot;
    let mut facts = ContentFacts {
        splat_count: splats.len() as u32,
        variant_bytes: [0; 4],
        variant_utility: [-1.0; 4],
        encode_seconds: [0.0; 4],
        bytes: 0,
        utility_curve: None,
    };
    let mut decoded: Vec<(Variant, Splats)> = vec![];
    // Deferred estimates: every written variant decoded here, Best as the reference.
    let curve = opts.deferred_utility() && !opts.utility_renders;
    let mut written: [Option<Splats>; 4] = Default::default();
    // High, Medium and Low store the tile in Morton order: ordered and gathered once for all of
    // them (the writers' own ordering gives the same bytes), after the checks that name the
    // caller's splat index. The estimate compares them with Best in that order too (its sums
    // do not depend on the order), so nothing is put back in the caller's order.
    let written_variants = opts.written();
    let stored = match written_variants.iter().find(|v| **v != Variant::Best) {
        Some(v) => {
            splat2tiles_tiles::encode::tile::check_writable(splats, centre_s).map_err(
                |source| ContentError::Encode {
                    key,
                    variant: v.name(),
                    source,
                },
            )?;
            Some(in_storage_order(splats, centre_s, splats.sh_degree).1)
        }
        None => None,
    };
    for v in written_variants {
        let t = Instant::now();
        let encoded = match &stored {
            Some(s) if v != Variant::Best => {
                let low = if parent { &LOW_SPZ_PARENT } else { &LOW_SPZ };
                v.encode_stored(s, centre_s, node_matrix, curve, low)
            }
            // Best, from the caller's splats; its reader returns the tile-relative splats
            // (`Variant::encode_decoded`), the estimate's reference in the others' order.
            _ => v.encode(splats, centre_s, node_matrix).map(|g| {
                let reference = || relative(stored.as_ref().unwrap_or(splats), centre_s);
                (g, curve.then(reference))
            }),
        };
        let (glb, dec) = encoded.map_err(|source| ContentError::Encode {
            key,
            variant: v.name(),
            source,
        })?;
        written[v.index()] = dec;
        facts.encode_seconds[v.index()] = t.elapsed().as_secs_f64();
        let path = dir.join(content_uri(scheme, key, v));
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|source| ContentError::Io {
                path: parent.to_path_buf(),
                source,
            })?;
        }
        std::fs::write(&path, &glb).map_err(|source| ContentError::Io {
            path: path.clone(),
            source,
        })?;
        facts.variant_bytes[v.index()] = glb.len() as u32;
        facts.bytes += glb.len() as u64;
        if opts.measure_utility && !opts.deferred_utility() && v != Variant::Best {
            let s = decode_variant(&glb)
                .map_err(|source| ContentError::Encode {
                    key,
                    variant: v.name(),
                    source,
                })?
                .0;
            decoded.push((v, s));
        }
    }
    if let Some(best) = written[Variant::Best.index()].take() {
        let mut candidates: [Option<&Splats>; 4] = [None; 4];
        for (c, w) in candidates.iter_mut().zip(&written).skip(1) {
            *c = w.as_ref();
        }
        facts.utility_curve = curve::loss_curve(&best, up_in_source(node_matrix), &candidates);
    }
    if opts.measure_utility {
        facts.variant_utility[Variant::Best.index()] = 1.0;
        if !decoded.is_empty() {
            let reference = relative(splats, centre_s);
            let up = up_in_source(node_matrix);
            // High and Medium are stored in Morton order: lined up with Best splat for splat.
            let aligned: Vec<Splats> = decoded
                .iter()
                .map(|(_, s)| aligned_to_best(s, &reference).unwrap_or_else(|| s.clone()))
                .collect();
            let refs: Vec<&Splats> = aligned.iter().collect();
            let u = match utility::ViewSetup::around(&reference, up, 0.0) {
                None => vec![1.0; refs.len()],
                Some(setup) if opts.utility_renders => utilities(&reference, &refs, &setup),
                Some(setup) => estimate::estimated_utilities(&reference, &refs, &setup),
            };
            for ((v, _), u) in decoded.iter().zip(u) {
                facts.variant_utility[v.index()] = u as f32;
            }
        }
    }
    Ok(facts)
}

/// The tileset-level metadata entity (`tileset.metadata`) for these options.
pub fn tileset_metadata(scheme: Scheme, opts: &VariantOptions) -> Value {
    let written = opts.written();
    let uris: Vec<String> = ALL
        .iter()
        .map(|&v| {
            if written.contains(&v) {
                uri_template(scheme, v)
            } else {
                String::new()
            }
        })
        .collect();
    json!({
        "class": VARIANTS_CLASS,
        "properties": {
            "variantNames": ALL.iter().map(|v| v.name()).collect::<Vec<_>>(),
            "variantUris": uris,
            "variantFormats": ALL.iter().map(|v| v.format()).collect::<Vec<_>>(),
            "defaultVariant": opts.profile.default_variant().index(),
            "utilityMethod": if opts.utility_renders { utility::METHOD } else { estimate::METHOD },
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use splat2tiles_core::splat::Splat;
    use splat2tiles_tiles::encode::read_tile_glb;
    use splat2tiles_tiles::encode::spz2::spz2_payload;

    /// Low's position step: a leaf's follows its splats' size, a parent's keeps 18 bits of its
    /// largest |coordinate| (the SPZ header's fractional bits, byte 13 of the raw stream).
    #[test]
    fn parents_keep_the_fine_low_step() {
        let mut s = Splats::with_capacity(0, 64);
        for i in 0..64 {
            let f = i as f64 / 63.0;
            s.push(
                Splat {
                    position: [f - 0.5, 0.5 - f, (f * 7.0).sin() * 0.5],
                    scale: [0.01; 3],
                    rotation: [0.0, 0.0, 0.0, 1.0],
                    opacity: 0.8,
                    sh0: [0.1, 0.2, 0.3],
                },
                &[],
            );
        }
        let opts = VariantOptions {
            variants: vec![Variant::Low],
            measure_utility: false,
            ..VariantOptions::default()
        };
        let key = TileKey {
            level: 0,
            x: 0,
            y: 0,
            z: 0,
        };
        let fb = |parent: bool| {
            let dir = tempfile::tempdir().unwrap();
            let slot = TileSlot {
                scheme: Scheme::Octree,
                key,
                parent,
            };
            write_tile_contents(
                dir.path(),
                slot,
                &s,
                [0.0; 3],
                splat2tiles_tiles::encode::tile::IDENTITY,
                &opts,
            )
            .unwrap();
            let glb = std::fs::read(dir.path().join(content_uri(
                Scheme::Octree,
                key,
                Variant::Low,
            )))
            .unwrap();
            let payload = spz2_payload(&glb).unwrap().expect("SPZ payload");
            let mut raw = vec![];
            std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(&payload[..]), &mut raw)
                .unwrap();
            raw[13]
        };
        let max_abs = 0.5;
        let fine = splat2tiles_tiles::encode::spz2::position_fractional_bits(max_abs, 18);
        let by_size = splat2tiles_tiles::encode::spz2::spz_fractional_bits(&s, max_abs, &LOW_SPZ);
        assert!(by_size < fine, "{by_size} {fine}");
        assert_eq!(fb(false), by_size);
        assert_eq!(fb(true), fine);
    }

    /// What [`Variant::encode_decoded`] returns for Best without decoding is what the reader
    /// decodes from the glb, bit for bit, at every SH degree and far from the centre.
    #[test]
    fn best_decodes_to_the_relative_splats() {
        let mut rng = splat2tiles_core::rng::SplitMix64::new(0x9E37_79B9_7F4A_7C15u64);
        let mut f = move || rng.f64();
        for degree in 0..=3u8 {
            let mut s = Splats::with_capacity(degree, 200);
            let k = splat2tiles_core::splat::sh_rest_count(degree);
            for _ in 0..200 {
                let splat = Splat {
                    position: [6.4e6 + f() * 50.0, -3.0e5 + f(), f() * 1e-3],
                    scale: [1e-4 + f() as f32, f() as f32 * 3.0 + 1e-6, 0.01],
                    rotation: splat2tiles_core::splat::normalize_quat([
                        f() as f32 - 0.5,
                        f() as f32,
                        -(f() as f32),
                        0.3,
                    ]),
                    opacity: f() as f32,
                    sh0: [f() as f32 - 0.5, 2.0 * f() as f32, -(f() as f32)],
                };
                let rest: Vec<[f32; 3]> = (0..k).map(|_| [f() as f32 - 0.5; 3]).collect();
                s.push(splat, &rest);
            }
            let centre = [6.4e6 + 25.0, -3.0e5, 0.0];
            let (glb, decoded) = Variant::Best
                .encode_decoded(&s, centre, splat2tiles_tiles::encode::tile::IDENTITY)
                .unwrap();
            let read = read_tile_glb(&glb).unwrap().splats;
            assert_eq!(decoded, read, "SH degree {degree}");
        }
    }
}
