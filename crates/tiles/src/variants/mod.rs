//! Quality variants of a tile (Best / High / Medium / Low, TileSplat Table 6): the per-tile
//! writer shared by leaves and LOD parents, their decoders, measured utilities and metadata.

use std::collections::HashMap;

use glam::{DMat3, DMat4, DVec3};

use serde_json::{Value, json};

use crate::encode::GlbError;
use crate::encode::gltf::EXT_MESHOPT_COMPRESSION;
use crate::encode::meshopt::{
    HIGH, MEDIUM, decompress_meshopt_glb, write_meshopt_glb, write_meshopt_glb_and_decoded,
    write_meshopt_glb_stored,
};
use crate::encode::read_tile_glb;
use crate::encode::spz_rotation::RotationFit;
use crate::encode::spz2::{
    SpzOptions, write_spz2_glb, write_spz2_glb_and_decoded, write_spz2_glb_as_given_and_decoded,
};
use crate::encode::tile::{TileLayout, try_write_tile_glb};
use crate::tiling::load::{
    LoadedTileset, expand_template, implicit_root, parse_subtree_tiles, resolve_inside,
};
use crate::tiling::{Scheme, TileKey};
use splat2tiles_core::splat::Splats;

/// One quality level of a tile.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Variant {
    /// Lossless float, interleaved prefix-renderable layout (`KHR_gaussian_splatting` only).
    Best,
    /// `EXT_meshopt_compression`, fine quantization (filters EXPONENTIAL / QUATERNION).
    High,
    /// `EXT_meshopt_compression`, coarse quantization.
    Medium,
    /// `KHR_gaussian_splatting_compression_spz_2` (SPZ v2), SH up to degree 1.
    Low,
}

splat2tiles_core::named!(Variant {
    Best => ("best", "Lossless float, interleaved prefix-renderable layout (`KHR_gaussian_splatting` only)."),
    High => ("high", "`EXT_meshopt_compression`, fine quantization (filters EXPONENTIAL / QUATERNION)."),
    Medium => ("medium", "`EXT_meshopt_compression`, coarse quantization."),
    Low => ("low", "`KHR_gaussian_splatting_compression_spz_2` (SPZ v2), SH up to degree 1."),
});

/// Every variant, in metadata array order.
pub const ALL: [Variant; 4] = [Variant::Best, Variant::High, Variant::Medium, Variant::Low];

/// SPZ settings of the Low variant of a leaf tile: SH degree at most 1 (at SH3 input: 28 B/splat
/// before gzip); positions with the coarsest step that is at most 1/3 of the tile's median
/// smallest scale, between 12 and 18 bits of its largest |coordinate| (the finer bits SPZ's 24
/// would hold cost bytes for no visible change; BENCHMARKS.md "Low's position step follows the
/// splats' size"). Parents: [`LOW_SPZ_PARENT`].
pub const LOW_SPZ: SpzOptions = SpzOptions {
    max_sh_degree: 1,
    sh1_bits: 5,
    sh_rest_bits: 4,
    position_bits: 18,
    scale_divisor: 3,
    min_position_bits: 12,
    rotation_fit: RotationFit::Covariance,
};

/// Low's settings for a parent tile (merged LOD splats): 18 bits of the tile's largest
/// |coordinate| whatever the splats' size. On the shared scenes the size rule of [`LOW_SPZ`]
/// cost parents 2.4-13x the rendered utility per byte saved that it cost leaves (BENCHMARKS.md
/// "Low's position step follows the splats' size").
pub const LOW_SPZ_PARENT: SpzOptions = SpzOptions {
    scale_divisor: 0,
    ..LOW_SPZ
};

impl Variant {
    /// Lower-case name, used in URIs (`tiles/{name}/...`) and metadata.
    pub fn name(self) -> &'static str {
        match self {
            Variant::Best => "best",
            Variant::High => "high",
            Variant::Medium => "medium",
            Variant::Low => "low",
        }
    }

    /// Index in the metadata arrays.
    pub fn index(self) -> usize {
        self as usize
    }

    /// The container format, in words (tileset metadata `variantFormats`).
    pub fn format(self) -> &'static str {
        match self {
            Variant::Best => "KHR_gaussian_splatting float32, interleaved (spec/prefix-layout.md)",
            Variant::High => "KHR_gaussian_splatting + EXT_meshopt_compression (high bit depths)",
            Variant::Medium => "KHR_gaussian_splatting + EXT_meshopt_compression (low bit depths)",
            Variant::Low => "KHR_gaussian_splatting_compression_spz_2 (SPZ v2, SH <= 1)",
        }
    }

    /// Encodes `splats` (positions in S, made relative to `centre`) as this variant's glb.
    pub fn encode(
        self,
        splats: &Splats,
        centre: [f64; 3],
        node_matrix: [f64; 16],
    ) -> Result<Vec<u8>, GlbError> {
        match self {
            Variant::Best => {
                try_write_tile_glb(splats, centre, node_matrix, TileLayout::Interleaved)
            }
            Variant::High => write_meshopt_glb(splats, centre, node_matrix, &HIGH),
            Variant::Medium => write_meshopt_glb(splats, centre, node_matrix, &MEDIUM),
            Variant::Low => write_spz2_glb(splats, centre, node_matrix, &LOW_SPZ),
        }
    }

    /// [`Self::encode`] and the tile-relative splats a reader decodes from the glb
    /// ([`decode_variant`]), the meshopt ones without decoding the vertex codec.
    pub fn encode_decoded(
        self,
        splats: &Splats,
        centre: [f64; 3],
        node_matrix: [f64; 16],
    ) -> Result<(Vec<u8>, Splats), GlbError> {
        let level = match self {
            Variant::High => &HIGH,
            Variant::Medium => &MEDIUM,
            Variant::Low => {
                return write_spz2_glb_and_decoded(splats, centre, node_matrix, &LOW_SPZ);
            }
            Variant::Best => {
                // Best is lossless: its reader returns the tile-relative f32 positions and the
                // other attributes as given (`tests::best_decodes_to_the_relative_splats`), so
                // the decode is skipped (it was about 3% of a `--variants all` conversion).
                let glb = self.encode(splats, centre, node_matrix)?;
                return Ok((glb, relative(splats, centre)));
            }
        };
        write_meshopt_glb_and_decoded(splats, centre, node_matrix, level)
    }

    /// [`Self::encode`] of High, Medium or Low for a tile already in storage order (`stored`,
    /// `encode::storage_order`): the same glb, and when `decode` the decoded splats in `stored`'s
    /// order. Best is prefix-rendered, so `write_tile_contents` never stores it this way; here it
    /// is encoded as given.
    pub fn encode_stored(
        self,
        stored: &Splats,
        centre: [f64; 3],
        node_matrix: [f64; 16],
        decode: bool,
        low: &SpzOptions,
    ) -> Result<(Vec<u8>, Option<Splats>), GlbError> {
        match self {
            Variant::High => write_meshopt_glb_stored(stored, centre, node_matrix, &HIGH, decode),
            Variant::Medium => {
                write_meshopt_glb_stored(stored, centre, node_matrix, &MEDIUM, decode)
            }
            Variant::Low => write_spz2_glb_as_given_and_decoded(stored, centre, node_matrix, low)
                .map(|(g, d)| (g, decode.then_some(d))),
            Variant::Best => self
                .encode(stored, centre, node_matrix)
                .map(|g| (g, decode.then(|| relative(stored, centre)))),
        }
    }
}

/// Which clients the tileset is written for.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Profile {
    /// Standards first: default content Best (needs only `KHR_gaussian_splatting`).
    #[default]
    Default,
    /// CesiumJS: default content SPZ_2 (Low) and the `3DTILES_content_gltf` declaration.
    Cesium,
}

splat2tiles_core::named!(Profile {
    Default => ("default", "Standards first: default content Best (needs only `KHR_gaussian_splatting`)."),
    Cesium => ("cesium", "CesiumJS: default content SPZ_2 (Low) and the `3DTILES_content_gltf` declaration."),
});

impl Profile {
    /// The variant a tile's `content.uri` points at.
    pub fn default_variant(self) -> Variant {
        match self {
            Profile::Default => Variant::Best,
            Profile::Cesium => Variant::Low,
        }
    }
}

/// What to write per tile.
#[derive(Debug, Clone, PartialEq)]
pub struct VariantOptions {
    /// Target clients.
    pub profile: Profile,
    /// Variants to write (the profile's default is always added).
    pub variants: Vec<Variant>,
    /// Store utilities; otherwise they are stored as -1.
    pub measure_utility: bool,
    /// Measure them by rendering (`utility::utilities`, 8 views per variant and tile: the
    /// definition, about 10x the conversion) instead of the calibrated estimate
    /// (`estimate::estimated_utilities`, no renders).
    pub utility_renders: bool,
}

impl Default for VariantOptions {
    fn default() -> Self {
        VariantOptions {
            profile: Profile::Default,
            variants: vec![Variant::Best],
            measure_utility: true,
            utility_renders: false,
        }
    }
}

impl VariantOptions {
    /// The variants written, in metadata order, the default one included.
    pub fn written(&self) -> Vec<Variant> {
        let d = self.profile.default_variant();
        ALL.into_iter()
            .filter(|v| *v == d || self.variants.contains(v))
            .collect()
    }
    /// Whether utilities are measured after the tree is built, from the written files at each
    /// tile's real switching distance (`splat2tiles_build::variants::measure`): when they are measured,
    /// Best (the reference) is written and some other variant is. Otherwise the writer measures
    /// them at once, viewed at `splat2tiles_build::variants::utility::VIEW_ERROR_PER_RADIUS` times the tile's radius.
    pub fn deferred_utility(&self) -> bool {
        let w = self.written();
        self.measure_utility && w.contains(&Variant::Best) && w.len() > 1
    }
}

/// URI (relative to the tileset) of a variant's content: `tiles/{variant}/{level}/{x}/{y}[/{z}].glb`.
pub fn content_uri(scheme: Scheme, key: TileKey, variant: Variant) -> String {
    expand_template(&uri_template(scheme, variant), key)
}

/// URI template of a variant's contents (implicit tiling variables).
pub fn uri_template(scheme: Scheme, variant: Variant) -> String {
    match scheme {
        Scheme::Octree => format!("tiles/{}/{{level}}/{{x}}/{{y}}/{{z}}.glb", variant.name()),
        Scheme::Quadtree => format!("tiles/{}/{{level}}/{{x}}/{{y}}.glb", variant.name()),
    }
}

/// `splats` with `centre` subtracted from the positions (the tile-relative frame).
pub fn relative(splats: &Splats, centre: [f64; 3]) -> Splats {
    let mut s = splats.clone();
    for p in &mut s.positions {
        for a in 0..3 {
            p[a] = (p[a] - centre[a]) as f32 as f64;
        }
    }
    s
}

/// The source-frame direction that the node matrix maps onto glTF's +y (3D Tiles' up).
pub fn up_in_source(node_matrix: [f64; 16]) -> DVec3 {
    let m = DMat3::from_mat4(DMat4::from_cols_array(&node_matrix));
    (m.transpose() * DVec3::Y).normalize_or(DVec3::Y)
}

/// Decodes any variant's glb (plain, interleaved, meshopt, SPZ_2 or codebook) into tile-relative splats
/// and the node matrix.
pub fn decode_variant(glb: &[u8]) -> Result<(Splats, [f64; 16]), GlbError> {
    use crate::encode::gltf::{KHR_GAUSSIAN_SPLATTING_SPZ_2, S2T_GAUSSIAN_SPLATTING_CODEBOOK};
    let children = [
        KHR_GAUSSIAN_SPLATTING_SPZ_2,
        S2T_GAUSSIAN_SPLATTING_CODEBOOK,
    ];
    if let Some(c) = crate::encode::spz2::compressed_content(glb, &children)? {
        let splats = if c.extension == KHR_GAUSSIAN_SPLATTING_SPZ_2 {
            crate::encode::spz2::spz2_splats(&c.payload)?
        } else {
            crate::encode::codebook_glb::codebook_splats(&c.payload)?
        };
        return Ok((splats, c.matrix));
    }
    let plain = decompress_meshopt_glb(glb)?;
    let t = read_tile_glb(&plain)?;
    Ok((t.splats, t.node_matrix))
}

/// Whether a glb uses `EXT_meshopt_compression` (High / Medium).
pub fn is_meshopt(glb: &[u8]) -> bool {
    crate::encode::glb::read_glb(glb)
        .ok()
        .and_then(|c| crate::encode::glb::parse_json(&c).ok())
        .is_some_and(|d| {
            d.extensions_used
                .iter()
                .any(|e| e == EXT_MESHOPT_COMPRESSION)
        })
}

pub use crate::tiling::variant_schema::{VARIANTS_CLASS, schema_properties};

/// `3DTILES_content_gltf` of the Cesium profile: both splat extensions used and required.
pub fn cesium_content_gltf() -> Value {
    let exts = [
        crate::encode::gltf::KHR_GAUSSIAN_SPLATTING,
        crate::encode::gltf::KHR_GAUSSIAN_SPLATTING_SPZ_2,
    ];
    json!({ "3DTILES_content_gltf": { "extensionsUsed": exts, "extensionsRequired": exts } })
}

/// One row of the per-variant table: totals over every content tile of a tileset.
#[derive(Debug, Clone, PartialEq)]
pub struct VariantRow {
    /// The variant.
    pub variant: Variant,
    /// Tiles holding this variant.
    pub tiles: usize,
    /// Splats over those tiles.
    pub splats: u64,
    /// Bytes over those tiles (from the metadata).
    pub bytes: u64,
    /// Mean utility over the tiles where it was measured (NaN if none).
    pub mean_utility: f64,
    /// Worst utility (NaN if none).
    pub worst_utility: f64,
}

impl VariantRow {
    /// Bytes per splat.
    pub fn bytes_per_splat(&self) -> f64 {
        self.bytes as f64 / self.splats.max(1) as f64
    }
}

/// Per-tile variant metadata of a tileset: key -> (splat count, bytes, utilities), read from
/// the subtrees' content property tables.
pub fn content_variant_metadata(ts: &LoadedTileset) -> HashMap<TileKey, (u32, [u32; 4], [f32; 4])> {
    let mut out = HashMap::new();
    let Ok(root) = implicit_root(ts.tileset.clone()) else {
        return out;
    };
    let roots = ts
        .tiles
        .iter()
        .map(|t| t.key)
        .filter(|k| k.level % root.subtree_levels == 0);
    for key in roots {
        let uri = expand_template(&root.subtree_template, key);
        let Some(path) = resolve_inside(&ts.dir, &uri) else {
            continue;
        };
        let Ok(bytes) = std::fs::read(&path) else {
            continue;
        };
        let Ok(st) = parse_subtree_tiles(&root, key, &bytes) else {
            continue;
        };
        for t in st.tiles {
            if let (Some(count), Some(bytes), Some(util)) =
                (t.splat_count, t.variant_bytes, t.variant_utility)
            {
                out.insert(t.key, (count, bytes, util));
            }
        }
    }
    out
}

/// The per-variant table of a tileset (for `splat2tiles stats`): tiles, splats, bytes and
/// utilities per variant, from the content metadata.
pub fn variant_table(ts: &LoadedTileset) -> Vec<VariantRow> {
    let meta = content_variant_metadata(ts);
    ALL.iter()
        .map(|&v| {
            let i = v.index();
            let mut row = VariantRow {
                variant: v,
                tiles: 0,
                splats: 0,
                bytes: 0,
                mean_utility: f64::NAN,
                worst_utility: f64::NAN,
            };
            let mut us = vec![];
            for (count, bytes, util) in meta.values() {
                if bytes[i] == 0 {
                    continue;
                }
                row.tiles += 1;
                row.splats += *count as u64;
                row.bytes += bytes[i] as u64;
                if util[i] >= 0.0 {
                    us.push(util[i] as f64);
                }
            }
            if !us.is_empty() {
                row.mean_utility = us.iter().sum::<f64>() / us.len() as f64;
                row.worst_utility = us.iter().copied().fold(f64::INFINITY, f64::min);
            }
            row
        })
        .collect()
}
