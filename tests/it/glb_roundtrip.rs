//! Splat tile glb round trips (write -> read, SH degrees 0..3), layout checks, other writers'
//! layouts (strides, offsets, quantised types) and malformed glbs that must fail without panics.

use crate::common::Rng;
use splat2tiles_core::splat::{Splat, Splats, normalize_quat};
use splat2tiles_tiles::encode::glb::{GlbError, parse_json, read_glb, write_gltf_glb};
use splat2tiles_tiles::encode::gltf::{
    Accessor, AccessorType, Buffer, BufferView, ComponentType, Gltf, KhrGaussianSplatting, Mesh,
    Node, Primitive, PrimitiveExtensions, Scene,
};
use splat2tiles_tiles::encode::tile::{self, IDENTITY, sh_attribute};
use splat2tiles_tiles::encode::{read_tile_glb, write_tile_glb};

fn scene(degree: u8, n: usize, seed: u64) -> Splats {
    let mut r = Rng(seed | 1);
    let mut s = Splats::with_capacity(degree, n);
    for _ in 0..n {
        let q = [0; 4].map(|_| r.range(-1.0, 1.0) as f32);
        let splat = Splat {
            position: [
                r.range(1000.0, 1010.0),
                r.range(-2005.0, -1995.0),
                r.range(-1.0, 1.0),
            ],
            scale: [0; 3].map(|_| r.range(0.0, 0.5) as f32),
            rotation: normalize_quat(q),
            opacity: r.f() as f32,
            sh0: [0; 3].map(|_| r.range(-2.0, 2.0) as f32),
        };
        let rest: Vec<[f32; 3]> = (0..s.rest_per_splat())
            .map(|_| [0; 3].map(|_| r.range(-0.5, 0.5) as f32))
            .collect();
        s.push(splat, &rest);
    }
    s
}

const CENTRE: [f64; 3] = [1005.125, -2000.5, 0.25];
/// A y-down source frame into glTF y-up plus a translation (column-major).
const MATRIX: [f64; 16] = [
    1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1005.125, 0.25, 2000.5, 1.0,
];

fn doc_of(glb: &[u8]) -> Gltf {
    parse_json(&read_glb(glb).unwrap()).unwrap()
}

fn bits<const N: usize>(v: &[[f32; N]]) -> Vec<[u32; N]> {
    v.iter().map(|a| a.map(f32::to_bits)).collect()
}

#[test]
fn round_trip_all_sh_degrees() {
    for degree in 0..=3u8 {
        let s = scene(degree, 257, 7 + degree as u64);
        let glb = write_tile_glb(&s, CENTRE, MATRIX);
        let d = read_tile_glb(&glb).unwrap_or_else(|e| panic!("degree {degree}: {e}"));
        assert!(d.warnings.is_empty(), "degree {degree}: {:?}", d.warnings);
        assert_eq!(d.splats.sh_degree, degree);
        assert_eq!(d.splats.len(), s.len());
        let want: Vec<[f64; 3]> = s
            .positions
            .iter()
            .map(|p| [0, 1, 2].map(|a| ((p[a] - CENTRE[a]) as f32) as f64))
            .collect();
        assert_eq!(d.splats.positions, want, "degree {degree}: positions");
        assert_eq!(bits(&d.splats.scales), bits(&s.scales));
        assert_eq!(bits(&d.splats.rotations), bits(&s.rotations));
        assert_eq!(bits(&d.splats.sh0), bits(&s.sh0));
        assert_eq!(bits(&d.splats.sh_rest), bits(&s.sh_rest));
        let op: Vec<u32> = s.opacities.iter().map(|v| v.to_bits()).collect();
        let dop: Vec<u32> = d.splats.opacities.iter().map(|v| v.to_bits()).collect();
        assert_eq!(dop, op);
        assert_eq!(d.node_matrix, MATRIX);
        assert_eq!(d.color_space, tile::COLOR_SPACE_SRGB);
        assert_eq!(d.kernel, "ellipse");
        assert!(d.has_color0);
        assert_eq!(d.generator.as_deref(), Some(tile::GENERATOR));
        if degree == 3 {
            assert!(s.sh_rest.iter().flatten().any(|&v| v != 0.0));
        }
    }
}

#[test]
fn json_layout_min_max_and_alignment() {
    let s = scene(3, 101, 99);
    let glb = write_tile_glb(&s, CENTRE, MATRIX);
    assert_eq!(glb.len() % 4, 0);
    let chunks = read_glb(&glb).unwrap();
    assert_eq!(chunks.json.len() % 4, 0);
    assert_eq!(chunks.bin_offset % 4, 0);
    let doc = parse_json(&chunks).unwrap();
    assert_eq!(doc.extensions_used, vec!["KHR_gaussian_splatting"]);
    assert!(doc.extensions_required.is_empty());
    assert_eq!(doc.nodes.len(), 1);
    assert_eq!(doc.nodes[0].matrix, Some(MATRIX));
    let prim = &doc.meshes[0].primitives[0];
    assert_eq!(prim.mode, Some(0));
    let ext = prim
        .extensions
        .as_ref()
        .unwrap()
        .gaussian_splatting
        .as_ref()
        .unwrap();
    assert_eq!(ext.kernel.as_deref(), Some("ellipse"));
    assert_eq!(ext.color_space.as_deref(), Some("srgb_rec709_display"));
    // 4 base + SH0 + 15 higher + COLOR_0.
    assert_eq!(prim.attributes.len(), 21);
    for l in 1..=3u8 {
        for c in 0..=2 * l {
            assert!(prim.attributes.contains_key(&sh_attribute(l, c)));
        }
    }
    let color = &doc.accessors[prim.attributes["COLOR_0"] as usize];
    assert_eq!(
        (color.component_type, color.normalized, color.kind),
        (5121, true, AccessorType::Vec4)
    );
    for v in &doc.buffer_views {
        assert_eq!(v.byte_offset % 4, 0);
        assert_eq!(v.target, Some(34962));
    }
    assert_eq!(doc.buffers[0].byte_length % 4, 0);
    // min/max equal the extremes of the f32 values actually stored.
    let pos = &doc.accessors[prim.attributes["POSITION"] as usize];
    let rel: Vec<[f32; 3]> = s
        .positions
        .iter()
        .map(|p| [0, 1, 2].map(|a| (p[a] - CENTRE[a]) as f32))
        .collect();
    for a in 0..3 {
        let lo = rel.iter().map(|p| p[a]).fold(f32::INFINITY, f32::min);
        let hi = rel.iter().map(|p| p[a]).fold(f32::NEG_INFINITY, f32::max);
        assert_eq!(pos.min.as_ref().unwrap()[a], lo as f64);
        assert_eq!(pos.max.as_ref().unwrap()[a], hi as f64);
    }
}

#[test]
fn identity_matrix_is_omitted_and_read_back() {
    let s = scene(0, 3, 5);
    let glb = write_tile_glb(&s, [0.0; 3], IDENTITY);
    assert_eq!(doc_of(&glb).nodes[0].matrix, None);
    assert_eq!(read_tile_glb(&glb).unwrap().node_matrix, IDENTITY);
}

/// Rebuilds a glb after editing its JSON (keeping the BIN chunk).
fn edited(glb: &[u8], edit: impl FnOnce(&mut Gltf)) -> Vec<u8> {
    let chunks = read_glb(glb).unwrap();
    let mut doc = parse_json(&chunks).unwrap();
    edit(&mut doc);
    write_gltf_glb(&doc, chunks.bin).unwrap()
}

fn attr(doc: &Gltf, name: &str) -> usize {
    doc.meshes[0].primitives[0].attributes[name] as usize
}

#[test]
fn malformed_glbs_give_their_errors() {
    let glb = write_tile_glb(&scene(1, 10, 3), CENTRE, MATRIX);

    let mut bad = glb.clone();
    bad[0] = b'x';
    assert!(matches!(
        read_tile_glb(&bad),
        Err(GlbError::BadMagic { .. })
    ));

    assert!(matches!(
        read_tile_glb(&glb[..7]),
        Err(GlbError::Truncated { offset: 0, .. })
    ));

    let mut bad = glb.clone();
    let bin_header = 20 + u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    bad[bin_header..bin_header + 4].copy_from_slice(&(1u32 << 30).to_le_bytes());
    match read_tile_glb(&bad) {
        Err(GlbError::ChunkPastEnd { offset, .. }) => assert_eq!(offset, bin_header as u64),
        other => panic!("expected ChunkPastEnd, got {other:?}"),
    }

    let mut bad = glb.clone();
    bad[20] = b'[';
    assert!(matches!(read_tile_glb(&bad), Err(GlbError::Json { .. })));
    // A JSON that parses but does not match the schema is a Json error too.
    let mut bad = glb.clone();
    let text = std::str::from_utf8(&bad[20..bin_header])
        .unwrap()
        .to_string();
    let broken = text.replacen("\"componentType\":5126", "\"componentType\":\"x\" ", 1);
    assert_eq!(broken.len(), text.len());
    bad[20..bin_header].copy_from_slice(broken.as_bytes());
    match read_tile_glb(&bad) {
        Err(GlbError::Json { offset, .. }) => assert!(offset > 20 && offset < bin_header as u64),
        other => panic!("expected Json, got {other:?}"),
    }

    let doc = doc_of(&glb);
    let rot = attr(&doc, tile::ATTR_ROTATION);
    let bad = edited(&glb, |d| d.accessors[rot].count = 11);
    assert_path(read_tile_glb(&bad), &format!("/accessors/{rot}/count"));
    let bad = edited(&glb, |d| d.accessors[rot].byte_offset = 4);
    assert_path(read_tile_glb(&bad), &format!("/accessors/{rot}"));
    let bad = edited(&glb, |d| d.accessors[rot].count = u64::MAX);
    assert!(read_tile_glb(&bad).is_err());
    let pos = attr(&doc, "POSITION");
    let bad = edited(&glb, |d| {
        d.accessors.iter_mut().for_each(|a| a.count = 1 << 40)
    });
    assert_path(read_tile_glb(&bad), &format!("/accessors/{pos}"));
    let view = doc.accessors[rot].buffer_view.unwrap() as usize;
    let bad = edited(&glb, |d| {
        d.buffer_views[view].byte_offset = d.buffers[0].byte_length
    });
    assert_path(read_tile_glb(&bad), &format!("/bufferViews/{view}"));
    let bad = edited(&glb, |d| d.buffers[0].byte_length += 1000);
    assert_path(read_tile_glb(&bad), "/buffers/0/byteLength");

    let bad = edited(&glb, |d| d.meshes[0].primitives[0].mode = Some(4));
    assert_path(read_tile_glb(&bad), "/meshes/0/primitives/0/mode");
    let bad = edited(&glb, |d| d.meshes[0].primitives[0].mode = None);
    assert_path(read_tile_glb(&bad), "/meshes/0/primitives/0/mode");

    let bad = edited(&glb, |d| {
        d.meshes[0].primitives[0]
            .attributes
            .remove(tile::ATTR_SCALE);
    });
    assert_path(read_tile_glb(&bad), "/meshes/0/primitives/0/attributes");
    let sh0 = attr(&doc, &sh_attribute(0, 0));
    let bad = edited(&glb, |d| {
        d.accessors[sh0].component_type = 5121;
        d.accessors[sh0].normalized = true;
    });
    assert_path(
        read_tile_glb(&bad),
        &format!("/accessors/{sh0}/componentType"),
    );
    let bad = edited(&glb, |d| {
        d.extensions_required.push("EXT_meshopt_compression".into())
    });
    assert!(matches!(
        read_tile_glb(&bad),
        Err(GlbError::Unsupported { .. })
    ));
    let bad = edited(&glb, |d| d.nodes[0].children = vec![0]);
    assert_path(read_tile_glb(&bad), "/nodes/0");
}

fn assert_path(r: Result<splat2tiles_tiles::encode::DecodedTile, GlbError>, want: &str) {
    match r {
        Err(GlbError::Invalid { path, .. }) => assert_eq!(path, want),
        other => panic!("expected Invalid at {want}, got {other:?}"),
    }
}

#[test]
fn damaged_bytes_never_panic() {
    let glb = write_tile_glb(&scene(1, 2, 11), CENTRE, MATRIX);
    for n in 0..glb.len() {
        assert!(read_tile_glb(&glb[..n]).is_err());
    }
    for i in 0..glb.len() {
        for v in [0u8, 0xff, b'9', b'"'] {
            let mut bad = glb.clone();
            bad[i] = v;
            let _ = read_tile_glb(&bad);
        }
    }
}

fn put_f32(bin: &mut [u8], at: usize, v: f32) {
    bin[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

/// A glb as another writer might lay it out: one interleaved, strided bufferView at an offset,
/// accessor byteOffsets, quantised rotation / scale / opacity, a partial SH degree 2, no SH0
/// (COLOR_0 fallback), a TRS node under a parent.
#[test]
#[expect(
    clippy::too_many_lines,
    reason = "one glb written by hand, field by field, then read back"
)]
fn reads_strided_quantised_layouts() {
    let n = 3usize;
    // Interleaved element: pos f32x3 (0), rot i16x4 norm (12), scale u8x3 (20), pad, opacity
    // u16 norm (24), pad, color u8x4 norm (28) => stride 32; the view starts 8 bytes in.
    let stride = 32;
    let mut bin = vec![0u8; 8 + stride * n + 36 * n];
    for i in 0..n {
        let e = 8 + i * stride;
        for a in 0..3 {
            put_f32(&mut bin, e + 4 * a, (i * 10 + a) as f32);
        }
        // Quaternion (0, 0, 0.6, 0.8) as shorts.
        let q = [
            0i16,
            0,
            (0.6f32 * 32767.0).round() as i16,
            (0.8f32 * 32767.0).round() as i16,
        ];
        for (c, v) in q.iter().enumerate() {
            bin[e + 12 + 2 * c..e + 14 + 2 * c].copy_from_slice(&v.to_le_bytes());
        }
        bin[e + 20..e + 23].copy_from_slice(&[1, 2, 3]);
        bin[e + 24..e + 26].copy_from_slice(&u16::MAX.to_le_bytes());
        bin[e + 28..e + 32].copy_from_slice(&[255, 188, 0, 255]);
    }
    // SH degree 1 as three float VEC3 in a second view; degree 2 has one coefficient only.
    let sh_at = 8 + stride * n;
    for j in 0..9 * n {
        put_f32(&mut bin, sh_at + 4 * j, j as f32);
    }
    let f = |view: u32, off: u64, ct: ComponentType, norm: bool, kind: AccessorType| Accessor {
        buffer_view: Some(view),
        byte_offset: off,
        component_type: ct.code(),
        normalized: norm,
        count: n as u64,
        kind,
        min: None,
        max: None,
        sparse: None,
        name: None,
    };
    use AccessorType::*;
    use ComponentType::*;
    let accessors = vec![
        f(0, 0, F32, false, Vec3),
        f(0, 12, I16, true, Vec4),
        f(0, 20, U8, false, Vec3),
        f(0, 24, U16, true, Scalar),
        f(0, 28, U8, true, Vec4),
        f(1, 0, F32, false, Vec3),
        f(1, 12, F32, false, Vec3),
        f(1, 24, F32, false, Vec3),
        f(1, 0, F32, false, Vec3),
    ];
    let mut attributes = std::collections::BTreeMap::new();
    for (i, name) in [
        "POSITION".to_string(),
        tile::ATTR_ROTATION.into(),
        tile::ATTR_SCALE.into(),
        tile::ATTR_OPACITY.into(),
        "COLOR_0".into(),
        sh_attribute(1, 0),
        sh_attribute(1, 1),
        sh_attribute(1, 2),
        sh_attribute(2, 0),
    ]
    .into_iter()
    .enumerate()
    {
        attributes.insert(name, i as u32);
    }
    attributes.insert("_CUSTOM".into(), 0);
    let doc = Gltf {
        asset: splat2tiles_tiles::encode::gltf::Asset {
            version: "2.0".into(),
            ..Default::default()
        },
        scene: Some(0),
        scenes: vec![Scene {
            nodes: vec![1],
            name: None,
        }],
        nodes: vec![
            Node {
                mesh: Some(0),
                translation: Some([5.0, 0.0, 0.0]),
                ..Default::default()
            },
            Node {
                children: vec![0],
                scale: Some([2.0, 2.0, 2.0]),
                ..Default::default()
            },
        ],
        meshes: vec![Mesh {
            primitives: vec![Primitive {
                attributes,
                mode: Some(0),
                extensions: Some(PrimitiveExtensions {
                    gaussian_splatting: Some(KhrGaussianSplatting {
                        kernel: Some("ellipse".into()),
                        color_space: Some("srgb_rec709_display".into()),
                        ..Default::default()
                    }),
                    other: Default::default(),
                }),
                ..Default::default()
            }],
            name: None,
        }],
        accessors,
        buffer_views: vec![
            BufferView {
                buffer: 0,
                byte_offset: 8,
                byte_length: (stride * n) as u64,
                byte_stride: Some(stride as u32),
                ..Default::default()
            },
            BufferView {
                buffer: 0,
                byte_offset: sh_at as u64,
                byte_length: (36 * n) as u64,
                byte_stride: Some(36),
                ..Default::default()
            },
        ],
        buffers: vec![Buffer {
            byte_length: bin.len() as u64,
            ..Default::default()
        }],
        extensions_used: vec!["KHR_gaussian_splatting".into()],
        ..Default::default()
    };
    let glb = write_gltf_glb(&doc, Some(&bin)).unwrap();
    let d = read_tile_glb(&glb).unwrap();
    let s = &d.splats;
    assert_eq!(s.len(), n);
    assert_eq!(s.positions[2], [20.0, 21.0, 22.0]);
    let q = s.rotations[1];
    assert!(
        (q[2] - 0.6).abs() < 1e-4 && (q[3] - 0.8).abs() < 1e-4,
        "{q:?}"
    );
    assert_eq!(s.scales[0], [1.0, 2.0, 3.0]);
    assert_eq!(s.opacities, vec![1.0; 3]);
    // SH degree 1 only (degree 2 is partial), coefficients from the strided view.
    assert_eq!(s.sh_degree, 1);
    assert_eq!(
        s.rest_of(1),
        &[[9.0, 10.0, 11.0], [12.0, 13.0, 14.0], [15.0, 16.0, 17.0]]
    );
    assert!(
        d.warnings.iter().any(|w| w.contains("SH degree 2")),
        "{:?}",
        d.warnings
    );
    // SH0 from COLOR_0: linear 1.0 -> display 1.0; linear 188/255 -> display ~0.874; 0 -> 0.
    assert!(d.warnings.iter().any(|w| w.contains("COLOR_0")));
    let c = splat2tiles_core::splat::sh::dc_color(s.sh0[0]);
    assert!((c[0] - 1.0).abs() < 1e-5 && c[2].abs() < 1e-5, "{c:?}");
    assert!((c[1] - 0.8742).abs() < 1e-3, "{c:?}");
    // World matrix = parent scale 2 * child translation 5.
    assert_eq!(d.node_matrix[0], 2.0);
    assert_eq!(d.node_matrix[12], 10.0);

    // A stride smaller than the element is refused with the view's path.
    let bad = edited(&glb, |d| d.buffer_views[0].byte_stride = Some(8));
    assert_path(read_tile_glb(&bad), "/bufferViews/0/byteStride");
}
