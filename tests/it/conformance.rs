//! Conformance suite of `splat2tiles validate`: every case under `conformance/cases/` (a
//! `case.json` naming a generated base tileset, a mutation and the exact expected codes) is run.
//!
//! Bases are converted at test time into a temp dir (nothing large is committed); a mutation is a
//! named Rust function below that breaks exactly one rule of a copy of the base. The test fails on
//! any difference between the multiset of ERROR/WARNING codes and `expected`.

use crate::common;

use serde_json::{Value, json};
use splat2tiles_build::convert::{ConvertOptions, SchemeChoice, convert};
use splat2tiles_core::frame::geo::Geodetic;
use splat2tiles_tiles::encode::glb::{read_glb, write_glb};
use splat2tiles_validate::{ValidateOptions, validate_tileset};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

fn cases_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("conformance/cases")
}

/// Scratch folder shared by the whole run.
fn scratch() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| tempfile::tempdir().expect("tempdir"))
        .path()
}

fn opts(
    max: usize,
    scheme: SchemeChoice,
    levels: Option<u32>,
    origin: Option<&str>,
) -> ConvertOptions {
    ConvertOptions {
        max_splats_per_tile: max,
        scheme,
        subtree_levels: levels,
        origin: origin.map(|o| Geodetic::parse(o).expect("origin")),
        progress: None,
        ..ConvertOptions::default()
    }
}

/// Converts base `name` once per run; returns its folder.
fn base(name: &str) -> PathBuf {
    static BUILT: OnceLock<Mutex<HashMap<String, PathBuf>>> = OnceLock::new();
    let built = BUILT.get_or_init(|| Mutex::new(HashMap::new()));
    let mut map = built.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(p) = map.get(name) {
        return p.clone();
    }
    let out = scratch().join("bases").join(name);
    let gen_ply = |n: usize, deg: u8, seed: u64| {
        let p = scratch().join(format!("{name}.ply"));
        common::write_ply_file(&p, &common::random_splats(n, deg, 10.0, seed));
        p
    };
    if name == "lapis_import" {
        // 3 LapisGS-like levels (300 / 1000 / 3000 splats): every level keeps the previous
        // one's splats and changes the opacity of half of them.
        let all = common::random_splats(3000, 1, 10.0, 31);
        let mut prev: Option<splat2tiles_core::splat::Splats> = None;
        let mut files = vec![];
        for (k, n) in [300usize, 1000, 3000].into_iter().enumerate() {
            let mut s = all.select(&(0..n).collect::<Vec<_>>());
            if let Some(p) = &prev {
                for i in 0..p.len() {
                    s.opacities[i] = if (i + k) % 2 == 0 {
                        0.05 + 0.9 * ((i * 37 + k * 11) % 100) as f32 / 100.0
                    } else {
                        p.opacities[i]
                    };
                }
            }
            let f = scratch().join(format!("lapis{k}.ply"));
            common::write_ply_file(&f, &s);
            files.push(f);
            prev = Some(s);
        }
        let o = ConvertOptions {
            layers: true,
            ..opts(400, SchemeChoice::Octree, Some(2), None)
        };
        splat2tiles_build::convert::import_lapisgs(&files, &out, &o)
            .unwrap_or_else(|e| panic!("importing base {name}: {e}"));
        map.insert(name.to_string(), out.clone());
        return out;
    }
    let (input, o) = match name {
        "small_octree" => (
            gen_ply(6000, 1, 7),
            opts(400, SchemeChoice::Octree, Some(2), None),
        ),
        "layered_octree" => (
            gen_ply(6000, 1, 7),
            ConvertOptions {
                layers: true,
                ..opts(400, SchemeChoice::Octree, Some(2), None)
            },
        ),
        "small_quadtree" => (
            gen_ply(6000, 1, 8),
            opts(400, SchemeChoice::Quadtree, Some(2), None),
        ),
        "single" => (
            gen_ply(200, 0, 9),
            opts(1000, SchemeChoice::Octree, None, None),
        ),
        "sh3_octree" => (
            gen_ply(2000, 3, 10),
            opts(300, SchemeChoice::Octree, Some(2), None),
        ),
        "georef_generated" => (
            gen_ply(3000, 2, 11),
            opts(400, SchemeChoice::Auto, Some(3), Some("-122.4,37.8,10")),
        ),
        "plant" => (
            common::scene("plant.splat"),
            opts(32_768, SchemeChoice::Auto, None, None),
        ),
        "plant_quadtree" => (
            common::scene("plant.splat"),
            opts(32_768, SchemeChoice::Quadtree, None, None),
        ),
        "plant_georef" => (
            common::scene("plant.splat"),
            opts(32_768, SchemeChoice::Auto, None, Some("2.2945,48.8584,35")),
        ),
        "donut" => (
            common::scene("donut_fused_sh0.ply"),
            opts(32_768, SchemeChoice::Auto, None, None),
        ),
        "biker" => (
            common::scene("biker.spz"),
            opts(32_768, SchemeChoice::Octree, None, None),
        ),
        other => panic!("unknown base '{other}'"),
    };
    convert(&input, &out, &o).unwrap_or_else(|e| panic!("converting base {name}: {e}"));
    map.insert(name.to_string(), out.clone());
    out
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let t = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &t);
        } else {
            std::fs::copy(e.path(), &t).unwrap();
        }
    }
}

/// A copy of a base tileset that mutations edit.
struct Ts {
    dir: PathBuf,
}

impl Ts {
    fn tileset(&self) -> Value {
        serde_json::from_slice(&std::fs::read(self.dir.join("tileset.json")).unwrap()).unwrap()
    }
    fn set_tileset(&self, v: &Value) {
        std::fs::write(
            self.dir.join("tileset.json"),
            serde_json::to_vec_pretty(v).unwrap(),
        )
        .unwrap();
    }
    fn edit_tileset(&self, f: impl FnOnce(&mut Value)) {
        let mut v = self.tileset();
        f(&mut v);
        self.set_tileset(&v);
    }
    fn glbs(&self) -> Vec<PathBuf> {
        common::files_under(&self.dir.join("tiles"), "glb")
    }
    fn glb(&self) -> PathBuf {
        self.glbs().into_iter().next().expect("a glb")
    }
    fn subtrees(&self) -> Vec<PathBuf> {
        common::files_under(&self.dir.join("subtrees"), "subtree")
    }
    fn root_subtree(&self) -> PathBuf {
        self.subtrees()
            .into_iter()
            .find(|p| p.starts_with(self.dir.join("subtrees/0")))
            .expect("root subtree")
    }
    /// A subtree whose child subtree availability is constant 0.
    fn leaf_subtree(&self) -> PathBuf {
        self.subtrees()
            .into_iter()
            .rev()
            .find(|p| read_subtree(p).0["childSubtreeAvailability"]["constant"] == json!(0))
            .expect("leaf subtree")
    }
    /// Bits of tile availability and of child subtree availability in one subtree.
    fn counts(&self) -> (usize, usize) {
        let v = self.tileset();
        let it = &v["root"]["implicitTiling"];
        let l = it["subtreeLevels"].as_u64().unwrap() as u32;
        let n: usize = if it["subdivisionScheme"] == "OCTREE" {
            8
        } else {
            4
        };
        ((n.pow(l) - 1) / (n - 1), n.pow(l))
    }
    /// Edits a glb's JSON, keeping its BIN chunk.
    fn edit_glb(&self, f: impl FnOnce(&mut Value)) {
        let p = self.glb();
        let bytes = std::fs::read(&p).unwrap();
        let c = read_glb(&bytes).unwrap();
        let mut v: Value = serde_json::from_slice(c.json).unwrap();
        f(&mut v);
        let out = write_glb(&serde_json::to_vec(&v).unwrap(), c.bin).unwrap();
        std::fs::write(&p, out).unwrap();
    }
    /// Writes `val` into component `comp` of element 0 of attribute `attr` of the first glb.
    fn poke_glb(&self, attr: &str, comp: usize, val: f32) {
        let p = self.glb();
        let mut bytes = std::fs::read(&p).unwrap();
        let c = read_glb(&bytes).unwrap();
        let v: Value = serde_json::from_slice(c.json).unwrap();
        let ai = v["meshes"][0]["primitives"][0]["attributes"][attr]
            .as_u64()
            .unwrap() as usize;
        let acc = &v["accessors"][ai];
        let view = &v["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
        let at = c.bin_offset
            + view["byteOffset"].as_u64().unwrap_or(0) as usize
            + acc["byteOffset"].as_u64().unwrap_or(0) as usize
            + comp * 4;
        bytes[at..at + 4].copy_from_slice(&val.to_le_bytes());
        std::fs::write(&p, bytes).unwrap();
    }
}

/// Rewrites availability `key` of a subtree as a fresh bitstream after `f` edits its bits.
fn set_availability(
    j: &mut Value,
    bin: &mut Vec<u8>,
    key: &str,
    len: usize,
    f: impl FnOnce(&mut Vec<bool>),
) {
    let a = j[key].clone();
    let mut bits: Vec<bool> = match a["constant"].as_u64() {
        Some(c) => vec![c == 1; len],
        None => {
            let v = a["bitstream"].as_u64().unwrap() as usize;
            let off = j["bufferViews"][v]["byteOffset"].as_u64().unwrap() as usize;
            (0..len)
                .map(|i| (bin[off + i / 8] >> (i % 8)) & 1 == 1)
                .collect()
        }
    };
    f(&mut bits);
    let mut packed = vec![0u8; len.div_ceil(8)];
    for (i, b) in bits.iter().enumerate() {
        if *b {
            packed[i / 8] |= 1 << (i % 8);
        }
    }
    let off = bin.len();
    bin.extend_from_slice(&packed);
    while !bin.len().is_multiple_of(8) {
        bin.push(0);
    }
    let views = j["bufferViews"].as_array_mut().unwrap();
    views.push(json!({"buffer": 0, "byteOffset": off, "byteLength": packed.len()}));
    let view = views.len() - 1;
    j["buffers"][0]["byteLength"] = json!(bin.len());
    j[key] = json!({"bitstream": view, "availableCount": bits.iter().filter(|b| **b).count()});
}

/// A subtree file's JSON and binary chunk.
fn read_subtree(p: &Path) -> (Value, Vec<u8>) {
    let b = std::fs::read(p).unwrap();
    let jl = u64::from_le_bytes(b[8..16].try_into().unwrap()) as usize;
    let bl = u64::from_le_bytes(b[16..24].try_into().unwrap()) as usize;
    (
        serde_json::from_slice(&b[24..24 + jl]).unwrap(),
        b[24 + jl..24 + jl + bl].to_vec(),
    )
}

/// Frames a subtree with `pad` as JSON padding byte up to `align` bytes.
fn frame_subtree(json: &Value, bin: &[u8], pad: u8, extra_pad: usize) -> Vec<u8> {
    let mut j = serde_json::to_vec(json).unwrap();
    while !j.len().is_multiple_of(8) {
        j.push(pad);
    }
    j.extend(std::iter::repeat_n(pad, extra_pad));
    let mut out = Vec::new();
    out.extend_from_slice(&0x7462_7573u32.to_le_bytes());
    out.extend_from_slice(&1u32.to_le_bytes());
    out.extend_from_slice(&(j.len() as u64).to_le_bytes());
    out.extend_from_slice(&(bin.len() as u64).to_le_bytes());
    out.extend_from_slice(&j);
    out.extend_from_slice(bin);
    out
}

fn edit_subtree(p: &Path, f: impl FnOnce(&mut Value, &mut Vec<u8>)) {
    let (mut j, mut bin) = read_subtree(p);
    f(&mut j, &mut bin);
    std::fs::write(p, frame_subtree(&j, &bin, b' ', 0)).unwrap();
}

/// Byte range in the binary chunk of the tile-metadata column `prop`, and the row count.
fn column(j: &Value, prop: &str) -> (usize, usize) {
    let t = j["tileMetadata"].as_u64().unwrap() as usize;
    let table = &j["propertyTables"][t];
    let view = &j["bufferViews"][table["properties"][prop]["values"].as_u64().unwrap() as usize];
    (
        view["byteOffset"].as_u64().unwrap() as usize,
        table["count"].as_u64().unwrap() as usize,
    )
}

/// First row of the root subtree's tile table whose geometric error is 0 (a leaf with content).
fn leaf_row(j: &Value, bin: &[u8]) -> usize {
    let (off, n) = column(j, "geometricError");
    (0..n)
        .find(|r| f64::from_le_bytes(bin[off + r * 8..off + r * 8 + 8].try_into().unwrap()) == 0.0)
        .expect("a leaf row")
}

fn set_f64(bin: &mut [u8], at: usize, v: f64) {
    bin[at..at + 8].copy_from_slice(&v.to_le_bytes());
}

/// Extension name of layered content.
const LAYER: &str = "SPLAT2TILES_layer";

/// The `n`-th (in path order) content glb of `level` of a layered base.
fn layer_glb(t: &Ts, level: u32, n: usize) -> PathBuf {
    let under = t.dir.join(format!("tiles/best/{level}"));
    let mut all: Vec<PathBuf> = t
        .glbs()
        .into_iter()
        .filter(|p| p.starts_with(&under))
        .collect();
    all.sort();
    all.into_iter().nth(n).expect("a layer glb")
}

/// Edits one glb's JSON, keeping its BIN chunk.
fn edit_glb_at(p: &Path, f: impl FnOnce(&mut Value)) {
    let bytes = std::fs::read(p).unwrap();
    let c = read_glb(&bytes).unwrap();
    let mut v: Value = serde_json::from_slice(c.json).unwrap();
    f(&mut v);
    let out = write_glb(&serde_json::to_vec(&v).unwrap(), c.bin).unwrap();
    std::fs::write(p, out).unwrap();
}

/// Writes `val` into delta `i` of a layer's parentOpacityDelta accessor.
fn poke_delta(p: &Path, i: usize, val: f32) {
    let mut bytes = std::fs::read(p).unwrap();
    let c = read_glb(&bytes).unwrap();
    let v: Value = serde_json::from_slice(c.json).unwrap();
    let a = v["meshes"][0]["primitives"][0]["extensions"][LAYER]["parentOpacityDelta"]
        .as_u64()
        .unwrap() as usize;
    let acc = &v["accessors"][a];
    let view = &v["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
    let at = c.bin_offset
        + view["byteOffset"].as_u64().unwrap_or(0) as usize
        + acc["byteOffset"].as_u64().unwrap_or(0) as usize
        + i * 4;
    bytes[at..at + 4].copy_from_slice(&val.to_le_bytes());
    std::fs::write(p, bytes).unwrap();
}

/// A level-2 layer of the `lapis_import` base with an `ancestorOpacityDeltas` entry stored
/// sparse with at least 2 values: its path, the entry's accessor and the JSON.
fn lapis_sparse(t: &Ts) -> (PathBuf, usize, Value) {
    let under = t.dir.join("tiles/best/2");
    let mut all: Vec<PathBuf> = t
        .glbs()
        .into_iter()
        .filter(|p| p.starts_with(&under))
        .collect();
    all.sort();
    for p in all {
        let bytes = std::fs::read(&p).unwrap();
        let c = read_glb(&bytes).unwrap();
        let v: Value = serde_json::from_slice(c.json).unwrap();
        let e = &v["meshes"][0]["primitives"][0]["extensions"][LAYER]["ancestorOpacityDeltas"][0];
        if let Some(a) = e["accessor"].as_u64() {
            let acc = &v["accessors"][a as usize];
            if acc["sparse"]["count"].as_u64().unwrap_or(0) >= 2 {
                return (p, a as usize, v);
            }
        }
    }
    panic!("no level-2 layer with a sparse ancestor accessor of 2+ values")
}

/// Writes `val` into word `k` of the sparse `part` (`indices` or `values`) of accessor `a`.
fn poke_sparse(p: &Path, a: usize, v: &Value, part: &str, k: usize, val: [u8; 4]) {
    let mut bytes = std::fs::read(p).unwrap();
    let c = read_glb(&bytes).unwrap();
    let sp = &v["accessors"][a]["sparse"][part];
    let view = &v["bufferViews"][sp["bufferView"].as_u64().unwrap() as usize];
    let at = c.bin_offset
        + view["byteOffset"].as_u64().unwrap_or(0) as usize
        + sp["byteOffset"].as_u64().unwrap_or(0) as usize
        + k * 4;
    bytes[at..at + 4].copy_from_slice(&val);
    std::fs::write(p, bytes).unwrap();
}

/// Moves the TILE_BOUNDING_BOX of a leaf 1000 m along x, away from its splats.
fn move_leaf_box(t: &Ts) {
    edit_subtree(&t.leaf_subtree(), |j, bin| {
        let r = leaf_row(j, bin);
        let (off, _) = column(j, "boundingBox");
        let at = off + r * 12 * 8;
        let x = f64::from_le_bytes(bin[at..at + 8].try_into().unwrap());
        set_f64(bin, at, x + 1000.0);
    });
}

/// Replaces the glb at `p` by the codebook variant of its splats (`spec/codebook-variant.md`);
/// returns where its payload starts in the file and its splat count.
fn codebook_content(p: &Path) -> (usize, u32) {
    use splat2tiles_tiles::encode::codebook_glb::write_codebook_glb;
    let (rel, m) = splat2tiles_tiles::variants::decode_variant(&std::fs::read(p).unwrap()).unwrap();
    let glb = write_codebook_glb(&rel, [0.0; 3], m, &Default::default())
        .unwrap()
        .0;
    std::fs::write(p, &glb).unwrap();
    let at = glb.windows(4).position(|w| w == b"S2TC").unwrap();
    (at, rel.len() as u32)
}

/// Writes `val` at payload byte `offset` of the codebook glb `p` (payload at `cb.0`); an empty
/// `val` instead makes the positions section one byte longer than the payload holds.
fn poke_codebook(cb: &(usize, u32), p: &Path, offset: usize, val: &[u8]) {
    let mut bytes = std::fs::read(p).unwrap();
    if val.is_empty() {
        let payload = splat2tiles_tiles::encode::codebook_glb::codebook_payload(&bytes)
            .unwrap()
            .unwrap();
        let sizes = splat2tiles_tiles::encode::codebook::section_sizes(&payload).unwrap();
        let table = payload.len() - sizes.iter().sum::<usize>() - 4 * sizes.len();
        let grown = (payload.len() - table) as u32;
        bytes[cb.0 + table..cb.0 + table + 4].copy_from_slice(&grown.to_le_bytes());
    } else {
        bytes[cb.0 + offset..cb.0 + offset + val.len()].copy_from_slice(val);
    }
    std::fs::write(p, bytes).unwrap();
}

type Mutation = fn(&Ts);

#[expect(
    clippy::too_many_lines,
    reason = "one entry per conformance case: a table, not logic"
)]
fn mutations() -> BTreeMap<&'static str, Mutation> {
    let mut m: BTreeMap<&'static str, Mutation> = BTreeMap::new();
    m.insert("none", |_| {});
    m.insert("gzip_everything", |t| {
        use std::io::Write;
        let mut files = vec![t.dir.join("tileset.json")];
        files.extend(t.glbs());
        files.extend(t.subtrees());
        for f in files {
            let raw = std::fs::read(&f).unwrap();
            let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
            gz.write_all(&raw).unwrap();
            std::fs::write(&f, gz.finish().unwrap()).unwrap();
        }
    });
    // tileset.json
    m.insert("tileset_json_truncated", |t| {
        let b = std::fs::read(t.dir.join("tileset.json")).unwrap();
        std::fs::write(t.dir.join("tileset.json"), &b[..b.len() / 2]).unwrap();
    });
    m.insert("asset_missing", |t| {
        t.edit_tileset(|v| {
            v.as_object_mut().unwrap().remove("asset");
        })
    });
    m.insert("asset_version_unknown", |t| {
        t.edit_tileset(|v| v["asset"]["version"] = json!("2.0"))
    });
    m.insert("root_geometric_error_negative", |t| {
        t.edit_tileset(|v| v["root"]["geometricError"] = json!(-1.0))
    });
    m.insert("root_error_larger_than_tileset", |t| {
        t.edit_tileset(|v| {
            let e = v["geometricError"].as_f64().unwrap();
            v["root"]["geometricError"] = json!(e * 2.0 + 1.0);
        })
    });
    m.insert("root_refine_missing", |t| {
        t.edit_tileset(|v| {
            v["root"].as_object_mut().unwrap().remove("refine");
        })
    });
    m.insert("refine_invalid", |t| {
        t.edit_tileset(|v| v["root"]["refine"] = json!("MERGE"))
    });
    m.insert("bounding_volume_missing", |t| {
        t.edit_tileset(|v| {
            v["root"].as_object_mut().unwrap().remove("boundingVolume");
        })
    });
    m.insert("box_wrong_length", |t| {
        t.edit_tileset(|v| {
            v["root"]["boundingVolume"]["box"]
                .as_array_mut()
                .unwrap()
                .pop();
        })
    });
    m.insert("box_degenerate", |t| {
        t.edit_tileset(|v| {
            let b = v["root"]["boundingVolume"]["box"].as_array_mut().unwrap();
            for x in b.iter_mut().skip(3) {
                *x = json!(0.0);
            }
        })
    });
    m.insert("region_south_above_north", |t| {
        t.edit_tileset(|v| {
            v["root"]["boundingVolume"] = json!({"region": [-1.0, 0.5, 1.0, -0.5, 0.0, 10.0]});
        })
    });
    m.insert("sphere_on_implicit_root", |t| {
        t.edit_tileset(|v| {
            v["root"]["boundingVolume"] = json!({"sphere": [0.0, 0.0, 0.0, 1000.0]});
        })
    });
    m.insert("sphere_negative_radius", |t| {
        t.edit_tileset(|v| {
            v["root"]["boundingVolume"] = json!({"sphere": [0.0, 0.0, 0.0, -1.0]});
        })
    });
    m.insert("transform_wrong_length", |t| {
        t.edit_tileset(|v| v["root"]["transform"] = json!(vec![1.0; 15]))
    });
    m.insert("transform_singular", |t| {
        t.edit_tileset(|v| v["root"]["transform"] = json!(vec![0.0; 16]))
    });
    m.insert("implicit_root_children", |t| {
        t.edit_tileset(|v| {
            let child = json!({"boundingVolume": v["root"]["boundingVolume"].clone(), "geometricError": 0.0});
            v["root"]["children"] = json!([child]);
        })
    });
    m.insert("implicit_root_metadata", |t| {
        t.edit_tileset(|v| v["root"]["metadata"] = json!({"class": "tile"}))
    });
    m.insert("implicit_content_bounding_volume", |t| {
        t.edit_tileset(|v| {
            v["root"]["content"]["boundingVolume"] = v["root"]["boundingVolume"].clone();
        })
    });
    m.insert("subdivision_scheme_invalid", |t| {
        t.edit_tileset(|v| v["root"]["implicitTiling"]["subdivisionScheme"] = json!("KDTREE"))
    });
    m.insert("subtree_levels_zero", |t| {
        t.edit_tileset(|v| v["root"]["implicitTiling"]["subtreeLevels"] = json!(0))
    });
    m.insert("template_invalid_variable", |t| {
        // Quadtree content template gains {z} (always 0): files renamed so only the template is wrong.
        t.edit_tileset(|v| {
            let uri = json!("tiles/best/{level}/{x}/{y}{z}.glb");
            v["root"]["content"]["uri"] = uri.clone();
            // Keep the variant metadata pointing at the renamed Best files.
            if v["metadata"]["properties"]["variantUris"].is_array() {
                v["metadata"]["properties"]["variantUris"][0] = uri;
            }
        });
        for g in t.glbs() {
            let stem = g.file_stem().unwrap().to_string_lossy().into_owned();
            std::fs::rename(&g, g.with_file_name(format!("{stem}0.glb"))).unwrap();
        }
    });
    m.insert("template_missing_variable", |t| {
        t.edit_tileset(|v| v["root"]["content"]["uri"] = json!("tiles/best/0/{x}/{y}/{z}.glb"))
    });
    m.insert("uri_escapes_root", |t| {
        t.edit_tileset(|v| v["root"]["content"]["uri"] = json!("../tiles/{level}/{x}/{y}/{z}.glb"))
    });
    m.insert("uri_absolute", |t| {
        t.edit_tileset(|v| {
            v["root"]["content"]["uri"] = json!("/tmp/tiles/{level}/{x}/{y}/{z}.glb")
        })
    });
    m.insert("uri_remote", |t| {
        t.edit_tileset(|v| {
            v["root"]["content"]["uri"] = json!("https://example.com/{level}/{x}/{y}/{z}.glb")
        })
    });
    m.insert("subtree_uri_escapes_root", |t| {
        t.edit_tileset(|v| {
            let u = v["root"]["implicitTiling"]["subtrees"]["uri"]
                .as_str()
                .unwrap()
                .to_string();
            v["root"]["implicitTiling"]["subtrees"]["uri"] = json!(format!("../{u}"));
        })
    });
    m.insert("subtree_uri_without_z", |t| {
        t.edit_tileset(|v| {
            v["root"]["implicitTiling"]["subtrees"]["uri"] =
                json!("subtrees/{level}/{x}/{y}.subtree")
        })
    });
    m.insert("subtrees_uri_not_string", |t| {
        t.edit_tileset(|v| v["root"]["implicitTiling"]["subtrees"]["uri"] = json!(17))
    });
    m.insert("subdivision_scheme_not_string", |t| {
        t.edit_tileset(|v| v["root"]["implicitTiling"]["subdivisionScheme"] = json!(8))
    });
    m.insert("subtree_levels_string", |t| {
        t.edit_tileset(|v| v["root"]["implicitTiling"]["subtreeLevels"] = json!("2"))
    });
    m.insert("box_element_string", |t| {
        t.edit_tileset(|v| v["root"]["boundingVolume"]["box"][3] = json!("10"))
    });
    m.insert("extension_required_not_used", |t| {
        t.edit_tileset(|v| v["extensionsRequired"] = json!(["3DTILES_content_gltf"]))
    });
    m.insert("schema_id_invalid", |t| {
        t.edit_tileset(|v| v["schema"]["id"] = json!("1bad id"))
    });
    m.insert("schema_semantic_wrong_count", |t| {
        t.edit_tileset(|v| {
            v["schema"]["classes"]["tile"]["properties"]["boundingBox"]["count"] = json!(11)
        })
    });
    m.insert("schema_type_invalid", |t| {
        t.edit_tileset(|v| {
            v["schema"]["classes"]["splatContent"]["properties"]["splatCount"]["type"] =
                json!("INTEGER")
        })
    });
    // subtrees
    m.insert("subtree_bad_magic", |t| {
        let p = t.root_subtree();
        let mut b = std::fs::read(&p).unwrap();
        b[0..4].copy_from_slice(b"sbut");
        std::fs::write(&p, b).unwrap();
    });
    m.insert("subtree_bad_version", |t| {
        let p = t.root_subtree();
        let mut b = std::fs::read(&p).unwrap();
        b[4] = 2;
        std::fs::write(&p, b).unwrap();
    });
    m.insert("subtree_truncated", |t| {
        let p = t.root_subtree();
        let b = std::fs::read(&p).unwrap();
        std::fs::write(&p, &b[..b.len() - 8]).unwrap();
    });
    m.insert("subtree_json_padded_with_nul", |t| {
        let p = t.root_subtree();
        let (j, bin) = read_subtree(&p);
        let mut text = serde_json::to_vec(&j).unwrap();
        let pad = 8 - text.len() % 8;
        text.extend(std::iter::repeat_n(0u8, pad));
        let mut out = frame_subtree(&json!({}), &[], b' ', 0)[..24].to_vec();
        out[8..16].copy_from_slice(&(text.len() as u64).to_le_bytes());
        out[16..24].copy_from_slice(&(bin.len() as u64).to_le_bytes());
        out.extend_from_slice(&text);
        out.extend_from_slice(&bin);
        std::fs::write(&p, out).unwrap();
    });
    m.insert("subtree_json_length_unaligned", |t| {
        let p = t.root_subtree();
        let (j, bin) = read_subtree(&p);
        std::fs::write(&p, frame_subtree(&j, &bin, b' ', 4)).unwrap();
    });
    m.insert("subtree_bufferview_misaligned", |t| {
        edit_subtree(&t.root_subtree(), |j, bin| {
            // Move the last view's data 4 bytes later.
            let views = j["bufferViews"].as_array_mut().unwrap();
            let (i, _) = views
                .iter()
                .enumerate()
                .max_by_key(|(_, v)| v["byteOffset"].as_u64().unwrap())
                .unwrap();
            let off = views[i]["byteOffset"].as_u64().unwrap() as usize;
            views[i]["byteOffset"] = json!(off + 4);
            bin.splice(off..off, [0u8; 4]);
            bin.extend([0u8; 4]);
            j["buffers"][0]["byteLength"] = json!(bin.len());
        })
    });
    m.insert("availability_count_wrong", |t| {
        edit_subtree(&t.root_subtree(), |j, _| {
            let c = j["tileAvailability"]["availableCount"].as_u64().unwrap();
            j["tileAvailability"]["availableCount"] = json!(c + 1);
        })
    });
    m.insert("availability_bit_without_parent", |t| {
        let (n, _) = t.counts();
        edit_subtree(&t.root_subtree(), |j, bin| {
            // Clear the root tile's bit: every available level-1 tile then lacks its parent.
            set_availability(j, bin, "tileAvailability", n, |bits| bits[0] = false);
        })
    });
    m.insert("availability_constant_not_binary", |t| {
        edit_subtree(&t.leaf_subtree(), |j, _| {
            j["childSubtreeAvailability"]["constant"] = json!(2);
        })
    });
    m.insert("availability_both_bitstream_and_constant", |t| {
        edit_subtree(&t.root_subtree(), |j, _| {
            j["tileAvailability"]["constant"] = json!(1);
            j["tileAvailability"]["bitstream"] = json!(0);
        })
    });
    m.insert("child_subtree_missing", |t| {
        let leaf = t.leaf_subtree();
        std::fs::remove_file(leaf).unwrap();
    });
    m.insert("child_subtree_unreferenced", |t| {
        let (_, n) = t.counts();
        edit_subtree(&t.root_subtree(), |j, bin| {
            set_availability(j, bin, "childSubtreeAvailability", n, |bits| {
                let i = bits.iter().position(|b| *b).expect("a child subtree");
                bits[i] = false;
            });
        })
    });
    m.insert("property_table_count_wrong", |t| {
        edit_subtree(&t.root_subtree(), |j, _| {
            let i = j["tileMetadata"].as_u64().unwrap() as usize;
            let c = j["propertyTables"][i]["count"].as_u64().unwrap();
            j["propertyTables"][i]["count"] = json!(c - 1);
        })
    });
    m.insert("property_table_values_short", |t| {
        edit_subtree(&t.root_subtree(), |j, _| {
            let i = j["tileMetadata"].as_u64().unwrap() as usize;
            let v = j["propertyTables"][i]["properties"]["geometricError"]["values"]
                .as_u64()
                .unwrap() as usize;
            let l = j["bufferViews"][v]["byteLength"].as_u64().unwrap();
            j["bufferViews"][v]["byteLength"] = json!(l - 8);
        })
    });
    m.insert("property_table_unknown_class", |t| {
        edit_subtree(&t.root_subtree(), |j, _| {
            let i = j["tileMetadata"].as_u64().unwrap() as usize;
            j["propertyTables"][i]["class"] = json!("nope");
        })
    });
    m.insert("metadata_geometric_error_negative", |t| {
        edit_subtree(&t.leaf_subtree(), |j, bin| {
            let r = leaf_row(j, bin);
            let (off, _) = column(j, "geometricError");
            set_f64(bin, off + r * 8, -1.0);
        })
    });
    m.insert("metadata_child_error_larger_than_parent", |t| {
        edit_subtree(&t.leaf_subtree(), |j, bin| {
            let r = leaf_row(j, bin);
            let (off, _) = column(j, "geometricError");
            set_f64(bin, off + r * 8, 1.0e9);
        })
    });
    m.insert("metadata_box_degenerate", |t| {
        edit_subtree(&t.leaf_subtree(), |j, bin| {
            let r = leaf_row(j, bin);
            let (off, _) = column(j, "boundingBox");
            for k in 3..12 {
                set_f64(bin, off + (r * 12 + k) * 8, 0.0);
            }
        })
    });
    m.insert("content_outside_box", move_leaf_box);
    // glb contents
    m.insert("content_file_missing", |t| {
        std::fs::remove_file(t.glb()).unwrap()
    });
    m.insert("content_compression_bomb", |t| {
        use std::io::Write;
        let mut enc = zstd::stream::write::Encoder::new(Vec::new(), 3).unwrap();
        let zeros = vec![0u8; 1 << 20];
        for _ in 0..64 {
            enc.write_all(&zeros).unwrap();
        }
        std::fs::write(t.glb(), enc.finish().unwrap()).unwrap();
    });
    m.insert("glb_truncated", |t| {
        let b = std::fs::read(t.glb()).unwrap();
        std::fs::write(t.glb(), &b[..b.len() - 16]).unwrap();
    });
    m.insert("glb_bad_magic", |t| {
        let mut b = std::fs::read(t.glb()).unwrap();
        b[0] = b'x';
        std::fs::write(t.glb(), b).unwrap();
    });
    m.insert("glb_json_invalid", |t| {
        let mut b = std::fs::read(t.glb()).unwrap();
        b[20] = b'x';
        std::fs::write(t.glb(), b).unwrap();
    });
    m.insert("glb_mode_triangles", |t| {
        t.edit_glb(|v| v["meshes"][0]["primitives"][0]["mode"] = json!(4))
    });
    m.insert("glb_kernel_missing", |t| {
        t.edit_glb(|v| {
            v["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"]
                .as_object_mut()
                .unwrap()
                .remove("kernel");
        })
    });
    m.insert("glb_color_space_invalid", |t| {
        t.edit_glb(|v| {
            v["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"]["colorSpace"] =
                json!("acescg");
        })
    });
    m.insert("glb_extension_not_in_used", |t| {
        t.edit_glb(|v| v["extensionsUsed"] = json!([]))
    });
    m.insert("glb_child_extension_not_in_used", |t| {
        t.edit_glb(|v| {
            v["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"]["extensions"] =
                json!({"EXT_splat_future": {}});
        })
    });
    m.insert("glb_no_splat_primitive", |t| {
        t.edit_glb(|v| {
            v["meshes"][0]["primitives"][0]
                .as_object_mut()
                .unwrap()
                .remove("extensions");
        })
    });
    m.insert("glb_accessor_count_mismatch", |t| {
        t.edit_glb(|v| {
            let a = v["meshes"][0]["primitives"][0]["attributes"]["KHR_gaussian_splatting:OPACITY"]
                .as_u64()
                .unwrap() as usize;
            let c = v["accessors"][a]["count"].as_u64().unwrap();
            v["accessors"][a]["count"] = json!(c - 1);
        })
    });
    m.insert("glb_accessor_out_of_bounds", |t| {
        t.edit_glb(|v| {
            let a = v["meshes"][0]["primitives"][0]["attributes"]["KHR_gaussian_splatting:OPACITY"]
                .as_u64()
                .unwrap() as usize;
            // One whole record (the stride of an interleaved view, else 4 bytes) past its
            // start: the last element then ends outside the bufferView.
            let bv = v["accessors"][a]["bufferView"].as_u64().unwrap() as usize;
            let offset = v["accessors"][a]["byteOffset"].as_u64().unwrap_or(0);
            let step = v["bufferViews"][bv]["byteStride"].as_u64().unwrap_or(4);
            v["accessors"][a]["byteOffset"] = json!(offset + step);
        })
    });
    m.insert("glb_accessor_misaligned", |t| {
        t.edit_glb(|v| {
            let a = v["meshes"][0]["primitives"][0]["attributes"]["KHR_gaussian_splatting:OPACITY"]
                .as_u64()
                .unwrap() as usize;
            v["accessors"][a]["byteOffset"] = json!(2);
        })
    });
    m.insert("glb_bufferview_past_buffer", |t| {
        t.edit_glb(|v| {
            let a = v["meshes"][0]["primitives"][0]["attributes"]["KHR_gaussian_splatting:OPACITY"]
                .as_u64()
                .unwrap() as usize;
            let bv = v["accessors"][a]["bufferView"].as_u64().unwrap() as usize;
            v["bufferViews"][bv]["byteLength"] = json!(1u64 << 40);
        })
    });
    m.insert("glb_position_min_max_missing", |t| {
        t.edit_glb(|v| {
            let a = v["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
                .as_u64()
                .unwrap() as usize;
            v["accessors"][a].as_object_mut().unwrap().remove("min");
        })
    });
    m.insert("glb_position_max_wrong", |t| {
        t.edit_glb(|v| {
            let a = v["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
                .as_u64()
                .unwrap() as usize;
            let x = v["accessors"][a]["max"][0].as_f64().unwrap();
            v["accessors"][a]["max"][0] = json!(x + 1.0);
        })
    });
    m.insert("glb_codebook", |t| {
        codebook_content(&t.glb());
    });
    m.insert("codebook_content_outside_box", |t| {
        for g in t.glbs() {
            codebook_content(&g);
        }
        move_leaf_box(t);
    });
    m.insert("glb_codebook_bad_magic", |t| {
        poke_codebook(&codebook_content(&t.glb()), &t.glb(), 0, b"XXXX")
    });
    m.insert("glb_codebook_count_short", |t| {
        let n = codebook_content(&t.glb());
        poke_codebook(&n, &t.glb(), 8, &(n.1 - 1).to_le_bytes())
    });
    m.insert("glb_codebook_section_past_end", |t| {
        poke_codebook(&codebook_content(&t.glb()), &t.glb(), 0, &[])
    });
    m.insert("glb_opacity_above_one", |t| {
        t.poke_glb("KHR_gaussian_splatting:OPACITY", 0, 1.5)
    });
    m.insert("glb_scale_log_space", |t| {
        t.poke_glb("KHR_gaussian_splatting:SCALE", 0, -3.0)
    });
    m.insert("glb_rotation_not_unit", |t| {
        t.poke_glb("KHR_gaussian_splatting:ROTATION", 3, 2.0)
    });
    m.insert("glb_position_nan", |t| t.poke_glb("POSITION", 0, f32::NAN));
    m.insert("glb_sh_partial_degree", |t| {
        t.edit_glb(|v| {
            v["meshes"][0]["primitives"][0]["attributes"]
                .as_object_mut()
                .unwrap()
                .remove("KHR_gaussian_splatting:SH_DEGREE_1_COEF_1");
        })
    });
    m.insert("glb_sh_degree_0_missing", |t| {
        t.edit_glb(|v| {
            v["meshes"][0]["primitives"][0]["attributes"]
                .as_object_mut()
                .unwrap()
                .remove("KHR_gaussian_splatting:SH_DEGREE_0_COEF_0");
        })
    });
    m.insert("glb_scale_missing", |t| {
        t.edit_glb(|v| {
            v["meshes"][0]["primitives"][0]["attributes"]
                .as_object_mut()
                .unwrap()
                .remove("KHR_gaussian_splatting:SCALE");
        })
    });
    m.insert("glb_sh_normalized", |t| t.edit_glb(|v| {
        let a = v["meshes"][0]["primitives"][0]["attributes"]["KHR_gaussian_splatting:SH_DEGREE_0_COEF_0"].as_u64().unwrap() as usize;
        v["accessors"][a]["normalized"] = json!(true);
    }));
    m.insert("meshopt_marked_view_not_decoded", |t| {
        t.poke_glb("KHR_gaussian_splatting:OPACITY", 0, 5.0);
        t.edit_glb(|v| {
            let a = v["meshes"][0]["primitives"][0]["attributes"]["KHR_gaussian_splatting:OPACITY"].as_u64().unwrap() as usize;
            let bv = v["accessors"][a]["bufferView"].as_u64().unwrap() as usize;
            v["bufferViews"][bv]["extensions"] = json!({"EXT_meshopt_compression": {"buffer": 0, "byteLength": 4, "count": 1, "byteStride": 4, "mode": "ATTRIBUTES"}});
            v["extensionsUsed"].as_array_mut().unwrap().push(json!("EXT_meshopt_compression"));
        })
    });
    m.insert("spz2_style_tile_not_decoded", |t| {
        t.edit_glb(|v| {
            // SPZ_2 layout: accessors without bufferView, DC colour in COLOR_0 (deviation D1).
            for a in v["accessors"].as_array_mut().unwrap() {
                a.as_object_mut().unwrap().remove("bufferView");
            }
            let p = &mut v["meshes"][0]["primitives"][0];
            p["attributes"]
                .as_object_mut()
                .unwrap()
                .remove("KHR_gaussian_splatting:SH_DEGREE_0_COEF_0");
            p["attributes"]
                .as_object_mut()
                .unwrap()
                .retain(|k, _| !k.contains("SH_DEGREE"));
            p["extensions"]["KHR_gaussian_splatting"]["extensions"] =
                json!({"KHR_gaussian_splatting_compression_spz_2": {"bufferView": 0}});
            v["extensionsUsed"]
                .as_array_mut()
                .unwrap()
                .push(json!("KHR_gaussian_splatting_compression_spz_2"));
        })
    });
    m.insert("glb_unknown_splat_attribute", |t| {
        t.edit_glb(|v| {
            let a = v["meshes"][0]["primitives"][0]["attributes"]["KHR_gaussian_splatting:OPACITY"]
                .clone();
            v["meshes"][0]["primitives"][0]["attributes"]["KHR_gaussian_splatting:GLOW"] = a;
        })
    });
    m.insert("subtree_property_tables_empty", |t| {
        edit_subtree(&t.leaf_subtree(), |j, _| {
            j["propertyTables"] = json!([]);
            j.as_object_mut().unwrap().remove("tileMetadata");
            j.as_object_mut().unwrap().remove("contentMetadata");
        })
    });
    // URIs, symbolic links
    m.insert("percent_encoded_folder", |t| {
        std::fs::rename(t.dir.join("tiles"), t.dir.join("my tiles")).unwrap();
        retarget_content(t, "my%20tiles/best/{level}/{x}/{y}/{z}.glb");
    });
    m.insert("uri_percent_dot_dot", |t| {
        retarget_content(t, "tiles/%2e%2e/%2E%2E/tiles/best/{level}/{x}/{y}/{z}.glb");
    });
    m.insert("symlink_to_etc_passwd", |t| symlink_glb(t, "/etc/passwd"));
    m.insert("symlink_to_dev_zero", |t| symlink_glb(t, "/dev/zero"));
    m.insert("deep_explicit_tree", |t| deep_tree(t, 200));
    m.insert("deep_json_nesting", |t| deep_tree(t, 2000));
    // other content
    m.insert("plain_glb_content", |t| plain_glb(t, |_| {}));
    m.insert("plain_glb_accessor_view_missing", |t| {
        plain_glb(t, |v| v["accessors"][0]["bufferView"] = json!(99))
    });
    m.insert("plain_glb_accessor_out_of_bounds", |t| {
        plain_glb(t, |v| v["accessors"][0]["byteOffset"] = json!(1 << 20))
    });
    m.insert("plain_glb_component_type_invalid", |t| {
        plain_glb(t, |v| v["accessors"][0]["componentType"] = json!(5127))
    });
    m.insert("plain_glb_attribute_counts_differ", |t| {
        plain_glb(t, |v| {
            let last = v["accessors"].as_array().unwrap().len() - 1;
            let n = v["accessors"][last]["count"].as_u64().unwrap();
            v["accessors"][last]["count"] = json!(n - 1);
        })
    });
    m.insert("plain_glb_position_min_max_missing", |t| {
        plain_glb(t, |v| {
            let a = v["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
                .as_u64()
                .unwrap() as usize;
            let acc = v["accessors"][a].as_object_mut().unwrap();
            acc.remove("min");
            acc.remove("max");
        })
    });
    m.insert("plain_glb_normalized_float", |t| {
        plain_glb(t, |v| {
            let a = v["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
                .as_u64()
                .unwrap() as usize;
            v["accessors"][a]["normalized"] = json!(true);
        })
    });
    m.insert("plain_glb_indices_float", |t| {
        plain_glb(t, |v| {
            let a = v["meshes"][0]["primitives"][0]["attributes"]["POSITION"].clone();
            v["meshes"][0]["primitives"][0]["indices"] = a;
        })
    });
    m.insert("plain_glb_mode_invalid", |t| {
        plain_glb(t, |v| v["meshes"][0]["primitives"][0]["mode"] = json!(9))
    });
    m.insert("plain_glb_node_cycle", |t| {
        plain_glb(t, |v| {
            v["nodes"][0]["children"] = json!([1]);
            v["nodes"]
                .as_array_mut()
                .unwrap()
                .push(json!({"children": [0]}));
        })
    });
    m.insert("plain_glb_material_and_light", |t| {
        plain_glb(t, |v| {
            add_material(v, json!({"pbrMetallicRoughness": {"metallicFactor": 0.5}}));
            add_light(v, json!({"type": "spot", "spot": {"outerConeAngle": 0.5}}));
        })
    });
    m.insert("plain_glb_metallic_factor_above_one", |t| {
        plain_glb(t, |v| {
            add_material(v, json!({"pbrMetallicRoughness": {"metallicFactor": 2.0}}))
        })
    });
    m.insert("plain_glb_base_color_texture_missing", |t| {
        plain_glb(t, |v| {
            add_material(
                v,
                json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 3}}}),
            )
        })
    });
    m.insert("plain_glb_alpha_mode_invalid", |t| {
        plain_glb(t, |v| add_material(v, json!({"alphaMode": "opaque"})))
    });
    m.insert("plain_glb_spot_cone_inverted", |t| {
        plain_glb(t, |v| {
            add_light(
                v,
                json!({"type": "spot", "spot": {"innerConeAngle": 0.6, "outerConeAngle": 0.3}}),
            )
        })
    });
    m.insert("plain_glb_light_missing", |t| {
        plain_glb(t, |v| {
            add_light(v, json!({"type": "point"}));
            v["nodes"][0]["extensions"]["KHR_lights_punctual"]["light"] = json!(4);
        })
    });
    m.insert("plain_glb_scene_node_missing", |t| {
        plain_glb(t, |v| v["scenes"][0]["nodes"] = json!([7]))
    });
    m.insert("table_value_above_max", |t| {
        t.edit_tileset(|v| {
            for class in v["schema"]["classes"].as_object_mut().unwrap().values_mut() {
                if let Some(p) = class["properties"].get_mut("splatCount") {
                    p["max"] = json!(1);
                }
            }
        })
    });
    m.insert("version_1_0", |t| {
        t.edit_tileset(|v| v["asset"]["version"] = json!("1.0"))
    });
    m.insert("zip_content", |t| {
        std::fs::write(t.dir.join("a.3tz"), b"PK\x03\x04\x14\x00\x00\x00\x00\x00").unwrap();
    });
    m.insert("b3dm_batch_table_valid", |t| {
        let ft = r#"{"BATCH_LENGTH":2,"RTC_CENTER":[1,2,3]}"#;
        write_legacy_tables(
            t,
            b"b3dm",
            1,
            (ft, r#"{"height":[1.5,2.5]}"#),
            &glb_payload(true),
            0,
        )
    });
    m.insert("b3dm_batch_table_short_array", |t| {
        let ft = r#"{"BATCH_LENGTH":2}"#;
        write_legacy_tables(
            t,
            b"b3dm",
            1,
            (ft, r#"{"height":[1.5]}"#),
            &glb_payload(true),
            0,
        )
    });
    m.insert("b3dm_batch_table_binary_past_end", |t| {
        let bt = r#"{"id":{"byteOffset":0,"componentType":"UNSIGNED_INT","type":"SCALAR"}}"#;
        write_legacy_tables(
            t,
            b"b3dm",
            1,
            (r#"{"BATCH_LENGTH":2}"#, bt),
            &glb_payload(true),
            0,
        )
    });
    m.insert("i3dm_normal_up_without_right", |t| {
        let ft = r#"{"INSTANCES_LENGTH":1,"POSITION":[0,0,0],"NORMAL_UP":[0,0,1]}"#;
        write_legacy(t, b"i3dm", 1, ft, true, 0)
    });
    m.insert("b3dm_glb_version_3", |t| {
        let mut glb = glb_payload(true);
        glb[4] = 3;
        write_legacy_tables(t, b"b3dm", 1, (r#"{"BATCH_LENGTH":0}"#, ""), &glb, 0)
    });
    m.insert("i3dm_gltf_by_uri", |t| {
        let ft = r#"{"INSTANCES_LENGTH":1,"POSITION":[0,0,0]}"#;
        write_legacy_tables(t, b"i3dm", 1, (ft, ""), b"triangle.gltf   ", 0)
    });
    m.insert("i3dm_gltf_uri_missing", |t| {
        let ft = r#"{"INSTANCES_LENGTH":1,"POSITION":[0,0,0]}"#;
        write_legacy_tables(t, b"i3dm", 1, (ft, ""), b"missing.glb\0\0\0\0\0", 0)
    });
    m.insert("pnts_feature_property_unknown", |t| {
        write_pnts(
            t,
            r#"{"POINTS_LENGTH":2,"POSITION":{"byteOffset":0},"COLOUR":[1,2]}"#,
            24,
        )
    });
    m.insert("zip_3tz_valid", |t| write_3tz(t, Some(1.0)));
    m.insert("zip_3tz_inner_error", |t| write_3tz(t, Some(-1.0)));
    m.insert("zip_3tz_without_tileset", |t| write_3tz(t, None));
    m.insert("b3dm_valid", |t| {
        write_legacy(t, b"b3dm", 1, r#"{"BATCH_LENGTH":0}"#, true, 0)
    });
    m.insert("root_subtree_missing", |t| {
        std::fs::remove_file(t.dir.join("subtrees/0/0/0/0.subtree")).unwrap();
    });
    m.insert("b3dm_glb_padded", |t| {
        std::fs::write(t.dir.join("content.b3dm"), padded_b3dm()).unwrap();
    });
    m.insert("cmpt_with_b3dm_and_glb", |t| {
        // Inner tiles: a b3dm whose glb is followed by padding, then a glb (8-byte aligned).
        let glb = write_glb(br#"{"asset":{"version":"2.0"}}"#, None).unwrap();
        let inner = [padded_b3dm(), glb];
        let total = 16 + inner.iter().map(Vec::len).sum::<usize>();
        let mut out = b"cmpt".to_vec();
        out.extend_from_slice(&1u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(inner.len() as u32).to_le_bytes());
        for tile in &inner {
            assert!(out.len().is_multiple_of(8));
            out.extend_from_slice(tile);
        }
        std::fs::write(t.dir.join("content.cmpt"), out).unwrap();
    });
    m.insert("b3dm_version_2", |t| {
        write_legacy(t, b"b3dm", 2, r#"{"BATCH_LENGTH":0}"#, true, 0)
    });
    m.insert("b3dm_length_wrong", |t| {
        write_legacy(t, b"b3dm", 1, r#"{"BATCH_LENGTH":0}"#, true, 8)
    });
    m.insert("b3dm_batch_length_missing", |t| {
        write_legacy(t, b"b3dm", 1, "{}", true, 0)
    });
    m.insert("pnts_positions", |t| {
        write_pnts(t, r#"{"POINTS_LENGTH":2,"POSITION":{"byteOffset":0}}"#, 24)
    });
    m.insert("pnts_position_past_binary", |t| {
        write_pnts(t, r#"{"POINTS_LENGTH":2,"POSITION":{"byteOffset":0}}"#, 16)
    });
    m.insert("pnts_position_misaligned", |t| {
        write_pnts(t, r#"{"POINTS_LENGTH":1,"POSITION":{"byteOffset":2}}"#, 16)
    });
    m.insert("pnts_position_missing", |t| {
        write_legacy(t, b"pnts", 1, r#"{"POINTS_LENGTH":0}"#, false, 0)
    });
    // Layered content (spec/layered-content.md), base `layered_octree`.
    m.insert("layered_refine_replace", |t| {
        t.edit_tileset(|v| v["root"]["refine"] = json!("REPLACE"))
    });
    m.insert("layered_base_not_a_layer", |t| {
        edit_glb_at(&layer_glb(t, 0, 0), |v| {
            let p = &mut v["meshes"][0]["primitives"][0]["extensions"];
            p.as_object_mut().unwrap().remove(LAYER);
        })
    });
    m.insert("layered_child_without_extension", |t| {
        edit_glb_at(&layer_glb(t, 1, 0), |v| {
            let p = &mut v["meshes"][0]["primitives"][0]["extensions"];
            p.as_object_mut().unwrap().remove(LAYER);
        })
    });
    m.insert("layered_level_mismatch", |t| {
        edit_glb_at(&layer_glb(t, 1, 0), |v| {
            v["meshes"][0]["primitives"][0]["extensions"][LAYER]["level"] = json!(5);
        })
    });
    m.insert("layered_delta_count_short", |t| {
        edit_glb_at(&layer_glb(t, 1, 0), |v| {
            let a = v["meshes"][0]["primitives"][0]["extensions"][LAYER]["parentOpacityDelta"]
                .as_u64()
                .unwrap() as usize;
            let n = v["accessors"][a]["count"].as_u64().unwrap();
            v["accessors"][a]["count"] = json!(n - 1);
        })
    });
    m.insert("layered_delta_not_finite", |t| {
        poke_delta(&layer_glb(t, 1, 0), 0, f32::NAN)
    });
    // Format v2 (base `lapis_import`).
    m.insert("lapis_ancestor_level_not_above_parent", |t| {
        let (p, _, _) = lapis_sparse(t);
        edit_glb_at(&p, |v| {
            v["meshes"][0]["primitives"][0]["extensions"][LAYER]["ancestorOpacityDeltas"][0]
                ["level"] = json!(1);
        })
    });
    m.insert("lapis_ancestor_level_u32_max", |t| {
        let (p, _, _) = lapis_sparse(t);
        edit_glb_at(&p, |v| {
            v["meshes"][0]["primitives"][0]["extensions"][LAYER]["ancestorOpacityDeltas"][0]
                ["level"] = json!(u32::MAX);
        })
    });
    m.insert("lapis_ancestor_count_one_more", |t| {
        let (p, a, _) = lapis_sparse(t);
        edit_glb_at(&p, |v| {
            let n = v["accessors"][a]["count"].as_u64().unwrap();
            v["accessors"][a]["count"] = json!(n + 1);
        })
    });
    m.insert("lapis_sparse_index_out_of_range", |t| {
        let (p, a, v) = lapis_sparse(t);
        let n = v["accessors"][a]["sparse"]["count"].as_u64().unwrap() as usize;
        poke_sparse(&p, a, &v, "indices", n - 1, 1_000_000u32.to_le_bytes());
    });
    m.insert("lapis_sparse_indices_not_increasing", |t| {
        let (p, a, v) = lapis_sparse(t);
        poke_sparse(&p, a, &v, "indices", 1, 0u32.to_le_bytes());
    });
    m.insert("lapis_ancestor_delta_sum_below_minus_one", |t| {
        let (p, a, v) = lapis_sparse(t);
        poke_sparse(&p, a, &v, "values", 0, (-5.0f32).to_le_bytes());
    });
    m.insert("lapis_ancestor_delta_raises_above_one", |t| {
        let (p, a, v) = lapis_sparse(t);
        poke_sparse(&p, a, &v, "values", 0, 1000.0f32.to_le_bytes());
    });
    m.insert("layered_deltas_sum_below_minus_one", |t| {
        poke_delta(&layer_glb(t, 1, 0), 0, -1.0);
        poke_delta(&layer_glb(t, 1, 1), 0, -1.0);
    });
    m
}

/// Turns the first glb into a plain glTF (no splat extension) and applies `f` to its JSON.
/// Gives the first primitive of a plain glb the material `m` (as material 0).
fn add_material(v: &mut Value, m: Value) {
    v["materials"] = json!([m]);
    v["meshes"][0]["primitives"][0]["material"] = json!(0);
}

/// Declares `KHR_lights_punctual` with the one light `l`, placed by node 0.
fn add_light(v: &mut Value, l: Value) {
    v["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    v["extensions"]["KHR_lights_punctual"] = json!({"lights": [l]});
    v["nodes"][0]["extensions"]["KHR_lights_punctual"] = json!({"light": 0});
}

fn plain_glb(t: &Ts, f: impl FnOnce(&mut Value)) {
    t.edit_glb(|v| {
        let prim = v["meshes"][0]["primitives"][0].as_object_mut().unwrap();
        prim.remove("extensions");
        prim.insert("mode".into(), json!(0));
        v.as_object_mut().unwrap().remove("extensionsUsed");
        v.as_object_mut().unwrap().remove("extensionsRequired");
        f(v);
    })
}

/// Points the implicit content template (and the Best variant's) at `uri`.
fn retarget_content(t: &Ts, uri: &str) {
    t.edit_tileset(|v| {
        v["root"]["content"]["uri"] = json!(uri);
        if v["metadata"]["properties"]["variantUris"].is_array() {
            v["metadata"]["properties"]["variantUris"][0] = json!(uri);
        }
    });
}

/// Replaces the first glb by a symbolic link to `target` (outside the tileset folder).
fn symlink_glb(t: &Ts, target: &str) {
    let g = t.glb();
    std::fs::remove_file(&g).unwrap();
    std::os::unix::fs::symlink(target, &g).unwrap();
}

/// Replaces the root of a `files` tileset by a chain of `levels` explicit tiles.
fn deep_tree(t: &Ts, levels: usize) {
    // serde_json would refuse to write (and read) this depth itself: build the text by hand.
    let mut text = String::from(r#"{"asset":{"version":"1.1"},"geometricError":2.0,"root":"#);
    let open = r#"{"boundingVolume":{"box":[0,0,0,10,0,0,0,10,0,0,0,10]},"geometricError":1.0,"refine":"REPLACE","children":["#;
    for _ in 1..levels {
        text.push_str(open);
    }
    text.push_str(
        r#"{"boundingVolume":{"box":[0,0,0,10,0,0,0,10,0,0,0,10]},"geometricError":0.0}"#,
    );
    for _ in 1..levels {
        text.push_str("]}");
    }
    text.push('}');
    std::fs::write(t.dir.join("tileset.json"), text).unwrap();
}

/// Writes `content.<magic>` (a 3D Tiles 1.0 tile with feature table JSON `ft` and, when `glb`,
/// an embedded minimal glb) into a `files` tileset; `extra` bytes beyond byteLength.
/// A b3dm whose glb (52 bytes, so 4 mod 8) is followed by 4 zero bytes that bring the tile's
/// byteLength to a multiple of 8, as the b3dm layout asks.
/// Writes `a.3tz`: a zip holding `tileset.json` (stored; its root geometric error `root_error`,
/// no tileset when `None`) whose root content is `triangle.gltf` (deflated) with its buffer
/// `triangle.bin` (stored): the two compression methods 3tz writers use.
fn write_3tz(t: &Ts, root_error: Option<f64>) {
    use std::io::Write;
    use zip::write::SimpleFileOptions;
    let pos: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let gltf = json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "buffers": [{"uri": "triangle.bin", "byteLength": pos.len()}],
        "bufferViews": [{"buffer": 0, "byteLength": pos.len()}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}]
    });
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let stored = SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    let deflated =
        SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    if let Some(e) = root_error {
        let inner = json!({
            "asset": {"version": "1.1"}, "geometricError": 10.0,
            "root": {"boundingVolume": {"box": [0.5, 0.5, 0, 0.5, 0, 0, 0, 0.5, 0, 0, 0, 0.5]},
                     "geometricError": e, "refine": "REPLACE",
                     "content": {"uri": "triangle.gltf"}}
        });
        zip.start_file("tileset.json", stored).unwrap();
        zip.write_all(&serde_json::to_vec(&inner).unwrap()).unwrap();
    }
    zip.start_file("triangle.gltf", deflated).unwrap();
    zip.write_all(&serde_json::to_vec(&gltf).unwrap()).unwrap();
    zip.start_file("triangle.bin", stored).unwrap();
    zip.write_all(&pos).unwrap();
    let bytes = zip.finish().unwrap().into_inner();
    std::fs::write(t.dir.join("a.3tz"), bytes).unwrap();
}

fn padded_b3dm() -> Vec<u8> {
    // A 29-byte JSON chunk, padded to 32: a 52-byte glb.
    let mut glb = write_glb(br#"{"asset": {"version": "2.0"}}"#, None).unwrap();
    assert_eq!(glb.len() % 8, 4, "the glb needs padding");
    let ft = br#"{"BATCH_LENGTH":0}  "#;
    assert!((28 + ft.len()).is_multiple_of(8));
    glb.extend_from_slice(&[0; 4]);
    let total = 28 + ft.len() + glb.len();
    let mut out = b"b3dm".to_vec();
    out.extend_from_slice(&1u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(ft.len() as u32).to_le_bytes());
    out.extend_from_slice(&[0u8; 12]);
    out.extend_from_slice(ft);
    out.extend_from_slice(&glb);
    out
}

/// A pnts with feature table JSON `ft` (padded) and `binary` zero bytes of feature table binary.
fn write_pnts(t: &Ts, ft: &str, binary: usize) {
    let mut ft = ft.as_bytes().to_vec();
    while !(28 + ft.len()).is_multiple_of(8) {
        ft.push(b' ');
    }
    let total = 28 + ft.len() + binary;
    let mut out = b"pnts".to_vec();
    out.extend_from_slice(&1u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(ft.len() as u32).to_le_bytes());
    out.extend_from_slice(&(binary as u32).to_le_bytes());
    out.extend_from_slice(&[0u8; 8]);
    out.extend_from_slice(&ft);
    out.extend(std::iter::repeat_n(0u8, binary));
    std::fs::write(t.dir.join("content.pnts"), out).unwrap();
}

fn write_legacy(t: &Ts, magic: &[u8; 4], version: u32, ft: &str, glb: bool, extra: usize) {
    write_legacy_tables(t, magic, version, (ft, ""), &glb_payload(glb), extra)
}

/// An empty glb (`glb`) or nothing.
fn glb_payload(glb: bool) -> Vec<u8> {
    if glb {
        write_glb(br#"{"asset":{"version":"2.0"}}"#, None).unwrap()
    } else {
        vec![]
    }
}

/// A b3dm / i3dm / pnts with the feature table JSON `tables.0` and the batch table JSON
/// `tables.1` (each padded with spaces to 8 bytes; no binary parts), then `payload` (an embedded
/// glb, or for an i3dm a glTF URI: gltfFormat 0), then `extra` zero bytes.
fn write_legacy_tables(
    t: &Ts,
    magic: &[u8; 4],
    version: u32,
    (ft, bt): (&str, &str),
    payload: &[u8],
    extra: usize,
) {
    let header = if magic == b"i3dm" { 32 } else { 28 };
    let mut ft = ft.as_bytes().to_vec();
    while !(header + ft.len()).is_multiple_of(8) {
        ft.push(b' ');
    }
    let mut bt = bt.as_bytes().to_vec();
    while !bt.len().is_multiple_of(8) {
        bt.push(b' ');
    }
    let total = header + ft.len() + bt.len() + payload.len();
    let mut out = Vec::new();
    out.extend_from_slice(magic);
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(ft.len() as u32).to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(bt.len() as u32).to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    if header == 32 {
        let gltf_format = u32::from(payload.starts_with(b"glTF"));
        out.extend_from_slice(&gltf_format.to_le_bytes());
    }
    out.extend_from_slice(&ft);
    out.extend_from_slice(&bt);
    out.extend_from_slice(payload);
    out.extend(std::iter::repeat_n(0u8, extra));
    let name = format!("content.{}", String::from_utf8_lossy(magic));
    std::fs::write(t.dir.join(name), out).unwrap();
}

#[derive(serde::Deserialize)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
struct Case {
    description: String,
    base: String,
    mutation: String,
    #[serde(default)]
    options: Options,
    expected: Vec<String>,
}

#[derive(serde::Deserialize, Default)]
#[serde(rename_all = "camelCase", deny_unknown_fields)]
struct Options {
    #[serde(default)]
    allow_remote: bool,
    /// The tileset to validate, relative to the case copy (default `tileset.json`).
    #[serde(default)]
    tileset: Option<String>,
    /// `--root`, relative to the case copy.
    #[serde(default)]
    root: Option<String>,
    /// `--max-external-depth`.
    #[serde(default)]
    max_external_depth: Option<usize>,
}

fn load_cases() -> Vec<(String, Case)> {
    let mut out = Vec::new();
    for kind in ["valid", "invalid"] {
        let mut dirs: Vec<_> = std::fs::read_dir(cases_dir().join(kind))
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .collect();
        dirs.sort();
        for d in dirs {
            let text = std::fs::read_to_string(d.join("case.json")).unwrap();
            let case: Case =
                serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", d.display()));
            assert!(!case.description.is_empty());
            assert_eq!(kind == "valid", case.expected.is_empty(), "{}", d.display());
            out.push((
                format!("{kind}/{}", d.file_name().unwrap().to_string_lossy()),
                case,
            ));
        }
    }
    out
}

#[test]
fn corpus_has_at_least_40_cases_and_every_mutation_is_used() {
    let cases = load_cases();
    assert!(cases.len() >= 40, "only {} conformance cases", cases.len());
    let m = mutations();
    for (name, c) in &cases {
        assert!(
            m.contains_key(c.mutation.as_str()),
            "{name}: unknown mutation {}",
            c.mutation
        );
    }
    for k in m.keys() {
        assert!(
            cases.iter().any(|(_, c)| c.mutation == *k),
            "mutation {k} has no case"
        );
    }
}

#[test]
fn every_case_gives_exactly_its_expected_codes() {
    let m = mutations();
    let mut failures = Vec::new();
    let cases = load_cases();
    let valid = cases
        .iter()
        .filter(|(n, _)| n.starts_with("valid/"))
        .count();
    eprintln!(
        "running {} cases ({valid} valid, {} invalid)",
        cases.len(),
        cases.len() - valid
    );
    for (name, case) in cases {
        let dir = scratch().join("cases").join(&name);
        // Base `files`: the case's own hand-written tileset in `files/` (small JSON only).
        let from = if case.base == "files" {
            cases_dir().join(&name).join("files")
        } else {
            base(&case.base)
        };
        copy_dir(&from, &dir);
        let t = Ts { dir: dir.clone() };
        m[case.mutation.as_str()](&t);
        let defaults = ValidateOptions::default();
        let opts = ValidateOptions {
            allow_remote: case.options.allow_remote,
            root: case.options.root.as_ref().map(|r| dir.join(r)),
            max_external_depth: case
                .options
                .max_external_depth
                .unwrap_or(defaults.max_external_depth),
            ..defaults
        };
        let tileset = dir.join(case.options.tileset.as_deref().unwrap_or("tileset.json"));
        let report = validate_tileset(&tileset, &opts).expect("readable");
        let mut expected = case.expected.clone();
        expected.sort();
        if report.codes() != expected {
            failures.push(format!(
                "{name}:\n  expected: {expected:?}\n  actual:   {:?}\n{}",
                report.codes(),
                report.to_text(&name)
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
