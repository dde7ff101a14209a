//! Integration tests of `splat2tiles_io`: the shared real scenes, PLY round trips across
//! encodings and property orders, SPZ v2/v3/v4 from a test-only encoder, and hostile inputs.

use crate::common::{Rng, scenes};
use std::io::Write;

use splat2tiles_core::splat::{Splat, Splats, logit, normalize_quat, sh::SH_C0};
use splat2tiles_io::{
    InputFormat, PlyEncoding, ReadError, ReadErrorKind, Scene, read_bytes, read_path, write_ply,
};

// ---------------------------------------------------------------------------------------------
// Helpers

/// Seeded random splats with non-zero higher SH, within SPZ-encodable ranges.
fn random_splats(n: usize, degree: u8, seed: u64) -> Splats {
    let mut r = Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    let mut s = Splats::new(degree);
    for _ in 0..n {
        let q = normalize_quat([0; 4].map(|_| r.range(-1.0, 1.0) as f32));
        let splat = Splat {
            position: [0; 3].map(|_| r.range(-100.0, 100.0)),
            scale: [0; 3].map(|_| r.range(-5.0, 0.5).exp() as f32),
            rotation: q,
            opacity: r.range(0.02, 0.98) as f32,
            sh0: [0; 3].map(|_| r.range(-1.0, 1.0) as f32),
        };
        let rest: Vec<[f32; 3]> = (0..s.rest_per_splat())
            .map(|_| [0; 3].map(|_| r.range(-0.5, 0.5) as f32))
            .collect();
        s.push(splat, &rest);
    }
    s
}

/// The trainer properties of splat `i` as (name, value), in the canonical trainer order,
/// computed independently of the crate's writer.
fn trainer_values(s: &Splats, i: usize) -> Vec<(String, f64)> {
    let mut v: Vec<(String, f64)> = Vec::new();
    let p = s.positions[i];
    for (n, x) in ["x", "y", "z"].iter().zip(p) {
        v.push((n.to_string(), x));
    }
    for n in ["nx", "ny", "nz"] {
        v.push((n.to_string(), 0.0));
    }
    for c in 0..3 {
        v.push((format!("f_dc_{c}"), s.sh0[i][c] as f64));
    }
    let rest = s.rest_of(i);
    for c in 0..3 {
        for (j, t) in rest.iter().enumerate() {
            v.push((format!("f_rest_{}", c * rest.len() + j), t[c] as f64));
        }
    }
    v.push(("opacity".into(), logit(s.opacities[i]) as f64));
    for c in 0..3 {
        v.push((format!("scale_{c}"), (s.scales[i][c] as f64).ln()));
    }
    let [x, y, z, w] = s.rotations[i];
    for (n, q) in ["rot_0", "rot_1", "rot_2", "rot_3"]
        .iter()
        .zip([w, x, y, z])
    {
        v.push((n.to_string(), q as f64));
    }
    v
}

/// A test-only PLY emitter: any encoding, properties permuted by `order`, positions as `double`
/// when `double_pos`, an extra `face` element with a list after the vertices.
fn emit_ply(s: &Splats, enc: PlyEncoding, order: &[usize], double_pos: bool) -> Vec<u8> {
    let names: Vec<String> = if s.is_empty() {
        Vec::new()
    } else {
        trainer_values(s, 0).into_iter().map(|(n, _)| n).collect()
    };
    let is_pos = |n: &str| double_pos && matches!(n, "x" | "y" | "z");
    let fmt = match enc {
        PlyEncoding::Ascii => "ascii",
        PlyEncoding::BinaryLittleEndian => "binary_little_endian",
        PlyEncoding::BinaryBigEndian => "binary_big_endian",
    };
    let mut out = format!(
        "ply\nformat {fmt} 1.0\ncomment made by a test\nobj_info x\nelement vertex {}\n",
        s.len()
    );
    for &k in order {
        let ty = if is_pos(&names[k]) { "double" } else { "float" };
        out += &format!("property {ty} {}\n", names[k]);
    }
    out += "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let mut b = out.into_bytes();
    for i in 0..s.len() {
        let vals = trainer_values(s, i);
        let mut line = Vec::new();
        for &k in order {
            let (n, v) = &vals[k];
            match enc {
                PlyEncoding::Ascii if is_pos(n) => line.push(format!("{v}")),
                PlyEncoding::Ascii => line.push(format!("{}", *v as f32)),
                PlyEncoding::BinaryLittleEndian if is_pos(n) => b.extend(v.to_le_bytes()),
                PlyEncoding::BinaryLittleEndian => b.extend((*v as f32).to_le_bytes()),
                PlyEncoding::BinaryBigEndian if is_pos(n) => b.extend(v.to_be_bytes()),
                PlyEncoding::BinaryBigEndian => b.extend((*v as f32).to_be_bytes()),
            }
        }
        if enc == PlyEncoding::Ascii {
            b.extend(line.join(" ").as_bytes());
            b.push(b'\n');
        }
    }
    match enc {
        PlyEncoding::Ascii => b.extend(b"3 0 1 2\n"),
        PlyEncoding::BinaryLittleEndian => {
            b.push(2);
            b.extend(0i32.to_le_bytes());
            b.extend(1i32.to_le_bytes());
        }
        PlyEncoding::BinaryBigEndian => {
            b.push(2);
            b.extend(0i32.to_be_bytes());
            b.extend(1i32.to_be_bytes());
        }
    }
    b
}

fn write_to_vec(s: &Splats) -> Vec<u8> {
    let mut v = Vec::new();
    write_ply(s, &mut v).expect("write to a Vec");
    v
}

fn rel_close(a: f32, b: f32, tol: f32) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

/// Asserts `got` reproduces `want` (positions within f32 rounding, the rest within `tol`).
fn assert_splats_close(got: &Splats, want: &Splats, tol: f32) {
    assert_eq!(got.len(), want.len(), "splat count");
    assert_eq!(got.sh_degree, want.sh_degree, "SH degree");
    got.check_lengths();
    for i in 0..want.len() {
        for a in 0..3 {
            let (g, w) = (got.positions[i][a], want.positions[i][a]);
            assert!(
                (g - w).abs() <= 1e-6 * (1.0 + w.abs()),
                "pos {i}.{a}: {g} vs {w}"
            );
            assert!(
                rel_close(got.scales[i][a], want.scales[i][a], tol),
                "scale {i}.{a}"
            );
            assert!(rel_close(got.sh0[i][a], want.sh0[i][a], tol), "sh0 {i}.{a}");
        }
        for a in 0..4 {
            assert!(
                rel_close(got.rotations[i][a], want.rotations[i][a], tol),
                "rot {i}.{a}"
            );
        }
        assert!(
            rel_close(got.opacities[i], want.opacities[i], tol),
            "opacity {i}"
        );
        for (j, (g, w)) in got.rest_of(i).iter().zip(want.rest_of(i)).enumerate() {
            for c in 0..3 {
                assert!(
                    rel_close(g[c], w[c], tol),
                    "rest {i}.{j}.{c}: {} vs {}",
                    g[c],
                    w[c]
                );
            }
        }
    }
}

/// Asserts two scenes are bit-identical, printing only the first difference.
fn assert_same(got: &Splats, want: &Splats, what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: count");
    assert_eq!(got.sh_degree, want.sh_degree, "{what}: degree");
    for i in 0..want.len() {
        assert_eq!(got.get(i), want.get(i), "{what}: splat {i}");
        assert_eq!(got.rest_of(i), want.rest_of(i), "{what}: splat {i} SH");
    }
}

/// Sanity of a real scene: finite values, unit quaternions, opacity in [0,1], scales >= 0, and
/// mostly displayable DC colours.
fn assert_sane(scene: &Scene) {
    let s = &scene.splats;
    s.check_lengths();
    assert_eq!(s.first_non_finite(), None, "non-finite splat");
    let mut in_range = 0usize;
    for i in 0..s.len() {
        let q = s.rotations[i];
        let n: f32 = q.iter().map(|v| v * v).sum();
        assert!((n - 1.0).abs() < 1e-4, "quat {i} not unit: {q:?}");
        assert!((0.0..=1.0).contains(&s.opacities[i]), "opacity {i}");
        assert!(s.scales[i].iter().all(|v| *v >= 0.0), "scale {i}");
        let rgb = s.sh0[i].map(|c| SH_C0 * c + 0.5);
        if rgb.iter().all(|c| (-0.5..=1.5).contains(c)) {
            in_range += 1;
        }
    }
    assert!(
        in_range * 100 >= s.len() * 95,
        "{in_range} of {} colours plausible",
        s.len()
    );
}

/// Asserts the error has `kind`, and that its message starts with `name: loc`.
fn assert_err(e: &ReadError, kind: fn(&ReadErrorKind) -> bool, name: &str, loc: &str) {
    assert!(kind(e.kind()), "unexpected kind: {e} ({:?})", e.kind());
    let msg = e.to_string();
    assert!(
        msg.starts_with(&format!("{name}: {loc}")),
        "message '{msg}' lacks '{name}: {loc}'"
    );
    assert!(!msg.contains('\n'), "message is one line: {msg}");
}

fn ply_header(props: &[&str], count: &str) -> String {
    let mut h = format!("ply\nformat binary_little_endian 1.0\nelement vertex {count}\n");
    for p in props {
        h += &format!("property float {p}\n");
    }
    h + "end_header\n"
}

const REQUIRED: [&str; 14] = [
    "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
    "rot_0", "rot_1", "rot_2", "rot_3",
];

// ---------------------------------------------------------------------------------------------
// Shared real scenes

#[test]
fn reads_plant_splat() {
    let scene = read_path(&scenes().join("plant.splat")).expect("plant.splat");
    assert_eq!(scene.splats.len(), 113_648);
    assert_eq!(scene.format, InputFormat::Splat);
    assert_eq!(scene.splats.sh_degree, 0);
    assert_eq!(scene.locator.describe(2), "byte 64");
    assert_sane(&scene);
}

#[test]
fn reads_donut_ply() {
    let scene = read_path(&scenes().join("donut_fused_sh0.ply")).expect("donut ply");
    assert_eq!(scene.splats.len(), 45_624);
    assert_eq!(
        scene.format,
        InputFormat::Ply {
            encoding: PlyEncoding::BinaryLittleEndian
        }
    );
    assert_eq!(scene.repaired_rotations, 0);
    assert_sane(&scene);
    // Writing and reading the real scene again reproduces it.
    let again = read_bytes("donut.ply", &write_to_vec(&scene.splats)).expect("re-read");
    assert_splats_close(&again.splats, &scene.splats, 1e-5);
}

#[test]
fn reads_biker_spz_v4() {
    let scene = read_path(&scenes().join("biker.spz")).expect("biker.spz");
    let s = &scene.splats;
    assert_eq!(s.len(), 152_746);
    assert_eq!(scene.format, InputFormat::Spz { version: 4 });
    assert_eq!(scene.format.default_up_axis(), "+y");
    assert_eq!(scene.locator.describe(7), "splat 7");
    assert_sane(&scene);
    // A real capture: centres span metres, not kilometres or nothing; sizes are small.
    let (lo, hi) = s.bounds().expect("non-empty");
    let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    assert!((0.5..2048.0).contains(&extent), "extent {extent}");
    let mut sc: Vec<f32> = s.scales.iter().map(|v| v[0]).collect();
    sc.sort_by(f32::total_cmp);
    let median = sc[sc.len() / 2];
    assert!(
        median > 1e-4 && median < 0.5 * extent as f32,
        "median scale {median}"
    );
    // Smallest-three decoding yields varied orientations, not all identity.
    let non_identity = s.rotations.iter().filter(|q| q[3].abs() < 0.99).count();
    assert!(
        non_identity > s.len() / 2,
        "{non_identity} non-identity rotations"
    );
}

// ---------------------------------------------------------------------------------------------
// PLY round trips and encodings

#[test]
fn sh3_round_trips_through_the_writer() {
    let s = random_splats(500, 3, 1);
    assert!(
        s.sh_rest.iter().flatten().any(|v| v.abs() > 0.1),
        "higher SH present"
    );
    let bytes = write_to_vec(&s);
    let scene = read_bytes("sh3.ply", &bytes).expect("read back");
    assert_eq!(scene.splats.sh_degree, 3);
    assert_splats_close(&scene.splats, &s, 2e-6);
    // Header lists exactly the trainer layout.
    let text = String::from_utf8_lossy(&bytes[..bytes.len().min(2000)]).to_string();
    assert!(text.contains("property float nz\nproperty float f_dc_0\n"));
    assert!(text.contains("property float f_rest_44\nproperty float opacity\n"));
}

#[test]
fn every_sh_degree_round_trips() {
    for d in 0..=3 {
        let s = random_splats(40, d, 10 + d as u64);
        let scene = read_bytes("d.ply", &write_to_vec(&s)).expect("read back");
        assert_splats_close(&scene.splats, &s, 2e-6);
    }
}

#[test]
fn f_rest_is_read_channel_major() {
    // One splat whose f_rest_k = k: channel c, coefficient j must land at rest[j][c] = c*15 + j.
    let mut props: Vec<String> = REQUIRED.iter().map(|s| s.to_string()).collect();
    props.extend((0..45).map(|k| format!("f_rest_{k}")));
    let refs: Vec<&str> = props.iter().map(|s| s.as_str()).collect();
    let mut b = ply_header(&refs, "1").into_bytes();
    let mut vals = vec![0f32; 14];
    vals[10] = 1.0; // rot_0 = w
    vals.extend((0..45).map(|k| k as f32));
    for v in vals {
        b.extend(v.to_le_bytes());
    }
    let s = read_bytes("cm.ply", &b).expect("reads").splats;
    for j in 0..15 {
        for c in 0..3 {
            assert_eq!(s.sh_rest[j][c], (c * 15 + j) as f32, "coef {j} channel {c}");
        }
    }
}

#[test]
fn ascii_big_endian_and_shuffled_decode_identically() {
    let s = random_splats(64, 3, 2);
    let reference = read_bytes("ref.ply", &write_to_vec(&s))
        .expect("ref")
        .splats;
    let n = trainer_values(&s, 0).len();
    let straight: Vec<usize> = (0..n).collect();
    let mut shuffled = straight.clone();
    let mut r = Rng(77);
    for i in (1..n).rev() {
        shuffled.swap(i, (r.f() * (i + 1) as f64) as usize);
    }
    assert_ne!(shuffled, straight);
    for enc in [
        PlyEncoding::Ascii,
        PlyEncoding::BinaryBigEndian,
        PlyEncoding::BinaryLittleEndian,
    ] {
        for order in [&straight, &shuffled] {
            let bytes = emit_ply(&s, enc, order, false);
            let scene = read_bytes("enc.ply", &bytes).unwrap_or_else(|e| panic!("{enc:?}: {e}"));
            assert_eq!(scene.format, InputFormat::Ply { encoding: enc });
            // Identical to the writer's own file: same f32 values, same conversions.
            assert_same(
                &scene.splats,
                &reference,
                &format!("{enc:?}, order {order:?}"),
            );
        }
    }
}

#[test]
fn double_positions_keep_f64_precision() {
    let mut s = random_splats(8, 0, 3);
    for p in &mut s.positions {
        p[0] += 6_378_137.123_456_789;
    }
    for enc in [
        PlyEncoding::BinaryLittleEndian,
        PlyEncoding::BinaryBigEndian,
        PlyEncoding::Ascii,
    ] {
        let order: Vec<usize> = (0..trainer_values(&s, 0).len()).collect();
        let got = read_bytes("dbl.ply", &emit_ply(&s, enc, &order, true)).expect("reads");
        for (g, w) in got.splats.positions.iter().zip(&s.positions) {
            assert_eq!(g, w, "{enc:?}: f64 positions exact");
        }
    }
}

#[test]
fn ascii_locator_names_lines() {
    let s = random_splats(3, 0, 4);
    let order: Vec<usize> = (0..trainer_values(&s, 0).len()).collect();
    let scene = read_bytes("a.ply", &emit_ply(&s, PlyEncoding::Ascii, &order, false)).unwrap();
    // ply, format, comment, obj_info, element, 17 properties, element face, list, end_header.
    assert_eq!(scene.locator.describe(0), "line 26");
    assert_eq!(scene.locator.describe(2), "line 28");
}

#[test]
fn zero_and_nan_quaternions_are_repaired_and_counted_nan_elsewhere_kept() {
    let mut b = ply_header(&REQUIRED, "3").into_bytes();
    let rows: [[f32; 14]; 3] = [
        [
            0.0, 0.0, 0.0, 0.1, 0.1, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
        ],
        [
            f32::NAN,
            0.0,
            0.0,
            0.1,
            0.1,
            0.1,
            0.0,
            0.0,
            0.0,
            0.0,
            2.0,
            0.0,
            0.0,
            0.0,
        ],
        [
            0.0,
            0.0,
            0.0,
            0.1,
            0.1,
            0.1,
            0.0,
            0.0,
            0.0,
            0.0,
            f32::NAN,
            1.0,
            0.0,
            0.0,
        ],
    ];
    for r in rows {
        for v in r {
            b.extend(v.to_le_bytes());
        }
    }
    let scene = read_bytes("q.ply", &b).expect("reads");
    assert_eq!(scene.repaired_rotations, 2);
    assert_eq!(scene.splats.rotations[0], [0.0, 0.0, 0.0, 1.0]);
    assert_eq!(scene.splats.rotations[1], [0.0, 0.0, 0.0, 1.0]);
    assert!(
        scene.splats.positions[1][0].is_nan(),
        "NaN positions are kept"
    );
    assert_eq!(scene.splats.first_non_finite(), Some(1));
    let hdr = ply_header(&REQUIRED, "3").len();
    assert_eq!(scene.locator.describe(1), format!("byte {}", hdr + 56));
}

#[test]
fn zero_splat_ply_reads_cleanly() {
    let b = ply_header(&REQUIRED, "0");
    let scene = read_bytes("zero.ply", b.as_bytes()).expect("zero splats are fine");
    assert!(scene.splats.is_empty());
    let e = emit_ply(&Splats::new(0), PlyEncoding::Ascii, &[], false);
    // No vertex properties at all: the reader must say which are missing.
    let err = read_bytes("e.ply", &e).unwrap_err();
    assert_err(
        &err,
        |k| matches!(k, ReadErrorKind::MissingProperty(_)),
        "e.ply",
        "byte 55: ",
    );
    // The writer's empty file reads back as empty.
    let scene = read_bytes("w.ply", &write_to_vec(&Splats::new(2))).expect("empty writer output");
    assert_eq!((scene.splats.len(), scene.splats.sh_degree), (0, 2));
}

#[test]
fn unknown_properties_are_ignored() {
    let mut props = vec!["nx", "ny", "nz", "confidence"];
    props.extend(REQUIRED);
    let mut b = ply_header(&props, "1").into_bytes();
    for i in 0..18 {
        b.extend((if i == 14 { 1.0f32 } else { 0.5 }).to_le_bytes());
    }
    let s = read_bytes("u.ply", &b).expect("reads").splats;
    assert_eq!(s.positions[0], [0.5, 0.5, 0.5]);
}

// ---------------------------------------------------------------------------------------------
// SPZ from a test-only encoder

fn q8(v: f32) -> u8 {
    v.round().clamp(0.0, 255.0) as u8
}

/// The six SPZ arrays of `s` (positions, alphas, colours, scales, rotations, SH).
fn spz_arrays(s: &Splats, version: u32) -> [Vec<u8>; 6] {
    let mut a: [Vec<u8>; 6] = Default::default();
    for i in 0..s.len() {
        for p in s.positions[i] {
            let f = (p * 4096.0).round() as i32;
            a[0].extend(&f.to_le_bytes()[..3]);
        }
        a[1].push(q8(s.opacities[i] * 255.0));
        for c in s.sh0[i] {
            a[2].push(q8((c * 0.15 + 0.5) * 255.0));
        }
        for v in s.scales[i] {
            a[3].push(q8((v.ln() + 10.0) * 16.0));
        }
        let q = s.rotations[i];
        if version == 2 {
            let sign = if q[3] < 0.0 { -1.0 } else { 1.0 };
            for v in &q[..3] {
                a[4].push(q8(v * sign * 127.5 + 127.5));
            }
        } else {
            let big = (0..4)
                .max_by(|&x, &y| q[x].abs().total_cmp(&q[y].abs()))
                .unwrap();
            let negate = q[big] < 0.0;
            let mut comp = big as u32;
            for (k, v) in q.iter().enumerate() {
                if k != big {
                    let neg = ((*v < 0.0) ^ negate) as u32;
                    let mag = (511.0 * v.abs() / std::f32::consts::FRAC_1_SQRT_2).round() as u32;
                    comp = (comp << 10) | (neg << 9) | mag.min(511);
                }
            }
            a[4].extend(comp.to_le_bytes());
        }
        for t in s.rest_of(i) {
            for c in t {
                a[5].push(q8(c * 128.0 + 128.0));
            }
        }
    }
    a
}

fn spz_header16(s: &Splats, version: u32, flags: u8) -> Vec<u8> {
    let mut h = b"NGSP".to_vec();
    h.extend(version.to_le_bytes());
    h.extend((s.len() as u32).to_le_bytes());
    h.extend([s.sh_degree, 12, flags, 0]);
    h
}

fn gzip(b: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(b).unwrap();
    e.finish().unwrap()
}

fn spz_legacy(s: &Splats, version: u32) -> Vec<u8> {
    let mut raw = spz_header16(s, version, 0);
    for a in spz_arrays(s, version) {
        raw.extend(a);
    }
    gzip(&raw)
}

fn spz_v4(s: &Splats) -> Vec<u8> {
    let arrays = spz_arrays(s, 4);
    let streams: Vec<(Vec<u8>, usize)> = arrays
        .iter()
        .take(if s.sh_degree > 0 { 6 } else { 5 })
        .map(|a| (zstd::bulk::compress(a, 3).unwrap(), a.len()))
        .collect();
    let mut f = b"NGSP".to_vec();
    f.extend(4u32.to_le_bytes());
    f.extend((s.len() as u32).to_le_bytes());
    f.extend([s.sh_degree, 12, 0, streams.len() as u8]);
    f.extend(32u32.to_le_bytes());
    f.extend([0u8; 12]);
    for (c, raw) in &streams {
        f.extend((c.len() as u64).to_le_bytes());
        f.extend((*raw as u64).to_le_bytes());
    }
    for (c, _) in &streams {
        f.extend(c);
    }
    f
}

/// Checks an SPZ decode against the source within the format's quantisation.
fn assert_spz_close(got: &Splats, want: &Splats) {
    assert_eq!(got.len(), want.len());
    assert_eq!(got.sh_degree, want.sh_degree);
    for i in 0..want.len() {
        for a in 0..3 {
            assert!((got.positions[i][a] - want.positions[i][a]).abs() <= 0.5 / 4096.0 + 1e-9);
            let r = got.scales[i][a] / want.scales[i][a];
            assert!((0.96..1.04).contains(&r), "scale ratio {r}");
            assert!((got.sh0[i][a] - want.sh0[i][a]).abs() < 0.014, "sh0");
        }
        assert!(
            (got.opacities[i] - want.opacities[i]).abs() < 0.0025,
            "opacity"
        );
        let dot: f32 = (0..4)
            .map(|k| got.rotations[i][k] * want.rotations[i][k])
            .sum();
        assert!(
            dot.abs() > 0.995,
            "rotation {i}: {:?} vs {:?}",
            got.rotations[i],
            want.rotations[i]
        );
        for (g, w) in got.rest_of(i).iter().zip(want.rest_of(i)) {
            for c in 0..3 {
                assert!(
                    (g[c] - w[c]).abs() <= 0.5 / 128.0 + 1e-6,
                    "sh rest {} vs {}",
                    g[c],
                    w[c]
                );
            }
        }
    }
}

#[test]
fn spz_v2_gzip_decodes() {
    let s = random_splats(300, 2, 5);
    let scene = read_bytes("t.spz", &spz_legacy(&s, 2)).expect("v2");
    assert_eq!(scene.format, InputFormat::Spz { version: 2 });
    assert_spz_close(&scene.splats, &s);
}

#[test]
fn spz_v3_smallest_three_decodes() {
    let s = random_splats(300, 3, 6);
    let scene = read_bytes("t.spz", &spz_legacy(&s, 3)).expect("v3");
    assert_eq!(scene.format, InputFormat::Spz { version: 3 });
    assert_spz_close(&scene.splats, &s);
}

#[test]
fn spz_v4_with_sh_decodes() {
    let s = random_splats(300, 1, 7);
    let scene = read_bytes("t.spz", &spz_v4(&s)).expect("v4");
    assert_eq!(scene.format, InputFormat::Spz { version: 4 });
    assert_spz_close(&scene.splats, &s);
}

// ---------------------------------------------------------------------------------------------
// Hostile input: each names the file and the byte offset or line

#[test]
fn bad_empty_file() {
    let e = read_bytes("empty.ply", b"").unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::Empty),
        "empty.ply",
        "empty file",
    );
}

#[test]
fn bad_unknown_format() {
    let e = read_bytes("mystery.bin", b"\x00\x01\x02\x03 not a scene").unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::UnknownFormat(_)),
        "mystery.bin",
        "byte 0: ",
    );
    assert!(e.to_string().contains("00 01 02 03"), "{e}");
    let e = read_bytes("fake.spz", b"PK\x03\x04zip").unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::UnknownFormat(_)),
        "fake.spz",
        "byte 0: ",
    );
}

#[test]
fn bad_truncated_body() {
    let mut b = write_to_vec(&random_splats(10, 1, 8));
    let body_start = b.len() - 10 * (17 + 9) * 4;
    b.truncate(b.len() - 5);
    let e = read_bytes("cut.ply", &b).unwrap_err();
    assert_err(
        &e,
        |k| {
            matches!(
                k,
                ReadErrorKind::Truncated {
                    expected: 1040,
                    actual: 1035,
                    ..
                }
            )
        },
        "cut.ply",
        &format!("byte {body_start}: "),
    );
    assert!(
        e.to_string().contains("expected 1040 bytes, found 1035"),
        "{e}"
    );
}

#[test]
fn bad_count_larger_than_file() {
    let b = ply_header(&REQUIRED, "3").into_bytes();
    let mut b2 = b.clone();
    b2.extend([0u8; 56 * 2]);
    let e = read_bytes("short.ply", &b2).unwrap_err();
    assert_err(
        &e,
        |k| {
            matches!(
                k,
                ReadErrorKind::Truncated {
                    expected: 168,
                    actual: 112,
                    ..
                }
            )
        },
        "short.ply",
        &format!("byte {}: ", b.len()),
    );
}

#[test]
fn bad_count_smaller_than_file_is_trailing_data() {
    let b = ply_header(&REQUIRED, "1").into_bytes();
    let mut b2 = b.clone();
    b2.extend([0u8; 56 + 7]);
    let e = read_bytes("long.ply", &b2).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::TrailingData { extra: 7, .. }),
        "long.ply",
        &format!("byte {}: ", b.len() + 56),
    );
}

#[test]
fn bad_absurd_count_is_refused_before_allocating() {
    let mut b = ply_header(&REQUIRED, "4000000000").into_bytes();
    b.resize(1024, 0);
    let start = ply_header(&REQUIRED, "4000000000").len();
    let e = read_bytes("huge.ply", &b).unwrap_err();
    assert_err(
        &e,
        |k| {
            matches!(
                k,
                ReadErrorKind::Truncated {
                    expected: 224_000_000_000,
                    ..
                }
            )
        },
        "huge.ply",
        &format!("byte {start}: "),
    );
    // Overflowing products are refused too.
    let b = ply_header(&REQUIRED, "18446744073709551615");
    let e = read_bytes("ovf.ply", b.as_bytes()).unwrap_err();
    assert!(matches!(e.kind(), ReadErrorKind::Truncated { .. }), "{e}");
    // And ascii.
    let t =
        ply_header(&REQUIRED, "4000000000").replace("binary_little_endian", "ascii") + "1 2 3\n";
    let e = read_bytes("huge_ascii.ply", t.as_bytes()).unwrap_err();
    assert!(
        matches!(
            e.kind(),
            ReadErrorKind::Truncated { .. } | ReadErrorKind::BadRecord(_)
        ),
        "{e}"
    );
}

#[test]
fn bad_missing_required_properties() {
    let props: Vec<&str> = REQUIRED
        .iter()
        .copied()
        .filter(|p| *p != "opacity" && *p != "rot_3")
        .collect();
    let b = ply_header(&props, "0");
    let e = read_bytes("miss.ply", b.as_bytes()).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::MissingProperty(v) if v == &["opacity", "rot_3"]),
        "miss.ply",
        "byte 36: ",
    );
    assert!(
        e.to_string()
            .ends_with("missing required properties opacity, rot_3"),
        "{e}"
    );
}

#[test]
fn bad_sh_count() {
    let mut props: Vec<String> = REQUIRED.iter().map(|s| s.to_string()).collect();
    props.extend((0..10).map(|k| format!("f_rest_{k}")));
    let refs: Vec<&str> = props.iter().map(|s| s.as_str()).collect();
    let e = read_bytes("sh.ply", ply_header(&refs, "0").as_bytes()).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::BadShCount(10)),
        "sh.ply",
        "byte 36: ",
    );
    assert!(e.to_string().contains("10 f_rest_*"), "{e}");
    // Right count, wrong numbering.
    props.truncate(14);
    props.extend((1..=9).map(|k| format!("f_rest_{k}")));
    let refs: Vec<&str> = props.iter().map(|s| s.as_str()).collect();
    let e = read_bytes("sh.ply", ply_header(&refs, "0").as_bytes()).unwrap_err();
    assert!(e.to_string().contains("f_rest_0"), "{e}");
}

#[test]
fn bad_list_property_in_vertex() {
    let h = ply_header(&REQUIRED, "0")
        .replace("end_header", "property list uchar float extra\nend_header");
    let e = read_bytes("list.ply", h.as_bytes()).unwrap_err();
    assert!(matches!(e.kind(), ReadErrorKind::Unsupported(_)), "{e}");
    assert!(e.to_string().starts_with("list.ply: byte "), "{e}");
}

#[test]
fn bad_header_lines() {
    let cases = [
        ("ply\nformat binary_middle_endian 1.0\n", "byte 4: "),
        (
            "ply\nformat ascii 1.0\nelement vertex many\nend_header\n",
            "byte 21: ",
        ),
        (
            "ply\nformat ascii 1.0\nproperty float x\nend_header\n",
            "byte 21: ",
        ),
        (
            "ply\nformat ascii 1.0\nfrobnicate\nend_header\n",
            "byte 21: ",
        ),
        ("ply\nelement vertex 0\nend_header\n", "byte 21: "),
    ];
    for (text, loc) in cases {
        let e = read_bytes("hdr.ply", text.as_bytes()).unwrap_err();
        assert_err(
            &e,
            |k| matches!(k, ReadErrorKind::BadHeader(_)),
            "hdr.ply",
            loc,
        );
    }
}

fn ascii_ply(rows: &[&str]) -> String {
    let mut t =
        ply_header(&REQUIRED, &rows.len().to_string()).replace("binary_little_endian", "ascii");
    for r in rows {
        t += r;
        t.push('\n');
    }
    t
}

const ROW: &str = "1 2 3 0.1 0.2 0.3 0 0 0 0 1 0 0 0";

#[test]
fn bad_ascii_too_few_values() {
    let e = read_bytes("few.ply", ascii_ply(&[ROW, "1 2 3"]).as_bytes()).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::BadRecord(_)),
        "few.ply",
        "line 20: ",
    );
    assert!(
        e.to_string()
            .contains("expected 14 values for a vertex, found 3"),
        "{e}"
    );
}

#[test]
fn bad_ascii_too_many_values() {
    let row = format!("{ROW} 9");
    let e = read_bytes("many.ply", ascii_ply(&[&row]).as_bytes()).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::BadRecord(_)),
        "many.ply",
        "line 19: ",
    );
}

#[test]
fn bad_ascii_unparseable_number() {
    let row = ROW.replace("0.2", "0.2x");
    let e = read_bytes("nan.ply", ascii_ply(&[ROW, ROW, &row]).as_bytes()).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::BadRecord(_)),
        "nan.ply",
        "line 21: ",
    );
    assert!(
        e.to_string()
            .contains("property 'f_dc_1': cannot parse '0.2x'"),
        "{e}"
    );
}

#[test]
fn bad_ascii_missing_and_trailing_lines() {
    let t = ascii_ply(&[ROW, ROW]);
    let cut = t.rsplit_once(ROW).unwrap().0.to_string();
    let e = read_bytes("cut.ply", cut.as_bytes()).unwrap_err();
    assert_err(
        &e,
        |k| {
            matches!(
                k,
                ReadErrorKind::Truncated {
                    expected: 2,
                    actual: 1,
                    ..
                }
            )
        },
        "cut.ply",
        "line 20: ",
    );
    let e = read_bytes("extra.ply", (t + "junk\n").as_bytes()).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::TrailingData { .. }),
        "extra.ply",
        "line 21: ",
    );
}

#[test]
fn bad_splat_length() {
    let e = read_bytes("odd.splat", &[0u8; 70]).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::Truncated { .. }),
        "odd.splat",
        "byte 64: ",
    );
}

#[test]
fn bad_spz_truncated_stream() {
    let s = random_splats(50, 0, 9);
    let mut raw = spz_header16(&s, 2, 0);
    for a in spz_arrays(&s, 2) {
        raw.extend(a);
    }
    raw.truncate(raw.len() - 10);
    let e = read_bytes("short.spz", &gzip(&raw)).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::Truncated { .. }),
        "short.spz",
        "byte ",
    );
    assert!(e.to_string().contains("(decompressed)"), "{e}");
    // A cut compressed stream is a decompression error without an offset.
    let full = spz_legacy(&s, 2);
    let e = read_bytes("cutgz.spz", &full[..full.len() / 2]).unwrap_err();
    assert!(
        matches!(
            e.kind(),
            ReadErrorKind::Decompress(_) | ReadErrorKind::Truncated { .. }
        ),
        "{e}"
    );
    assert!(e.to_string().starts_with("cutgz.spz: "), "{e}");
}

#[test]
fn bad_spz_gzip_bomb_stops_at_the_declared_size() {
    // A header for 100 points followed by 64 MiB of zeros: reading stops one byte past the
    // declared arrays and calls it a decompression bomb (not "1 unexpected bytes").
    let s = random_splats(100, 0, 10);
    let mut raw = spz_header16(&s, 2, 0);
    raw.resize(16 + (64 << 20), 0);
    let bomb = gzip(&raw);
    assert!(bomb.len() < 1 << 20);
    let e = read_bytes("bomb.spz", &bomb).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::Decompress(m) if m.contains("decompression bomb")),
        "bomb.spz",
        &format!("byte {}: ", 16 + 100 * 19),
    );
}

#[test]
fn bad_spz_point_counts() {
    // More points than a stream of this size could ever inflate to.
    let mut h = spz_header16(&Splats::new(0), 2, 0);
    h[8..12].copy_from_slice(&60_000_000u32.to_le_bytes());
    let e = read_bytes("claim.spz", &gzip(&h)).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::Decompress(_)),
        "claim.spz",
        "byte 8: ",
    );
    // Beyond the absolute limit.
    h[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    let e = read_bytes("many.spz", &gzip(&h)).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::TooMany { .. }),
        "many.spz",
        "byte 8: ",
    );
}

#[test]
fn bad_spz_v4_toc() {
    let s = random_splats(20, 0, 11);
    let good = spz_v4(&s);
    assert!(read_bytes("ok.spz", &good).is_ok());
    // Uncompressed size in the TOC disagreeing with the point count.
    let mut b = good.clone();
    b[32 + 8] ^= 1;
    let e = read_bytes("toc.spz", &b).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::BadHeader(_)),
        "toc.spz",
        "byte 40: ",
    );
    // Truncated file.
    let e = read_bytes("cut.spz", &good[..good.len() - 3]).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::Truncated { .. }),
        "cut.spz",
        "byte ",
    );
    // Trailing garbage.
    let mut b = good.clone();
    b.extend(b"xyz");
    let e = read_bytes("tail.spz", &b).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::TrailingData { extra: 3, .. }),
        "tail.spz",
        &format!("byte {}: ", good.len()),
    );
    // A stream that inflates to more than the TOC says is stopped.
    let mut b = spz_v4(&s);
    let big = zstd::bulk::compress(&vec![0u8; 1 << 20], 3).unwrap();
    let toc_end = 32 + 5 * 16;
    let first = u64::from_le_bytes(b[32..40].try_into().unwrap()) as usize;
    b.splice(toc_end..toc_end + first, big.iter().copied());
    b[32..40].copy_from_slice(&(big.len() as u64).to_le_bytes());
    let e = read_bytes("zbomb.spz", &b).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::Decompress(_)),
        "zbomb.spz",
        &format!("byte {toc_end}: "),
    );
    // Bad stream count for the SH degree.
    let mut b = good;
    b[15] = 6;
    let e = read_bytes("n.spz", &b).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::BadHeader(_)),
        "n.spz",
        "byte 15: ",
    );
}

#[test]
fn bad_spz_version() {
    let mut h = spz_header16(&Splats::new(0), 9, 0);
    h.resize(64, 0);
    let e = read_bytes("v9.spz", &h).unwrap_err();
    assert_err(
        &e,
        |k| matches!(k, ReadErrorKind::Unsupported(_)),
        "v9.spz",
        "byte 4: ",
    );
}

#[test]
fn read_path_reports_missing_files() {
    let e = read_path(std::path::Path::new("/nonexistent/scene.ply")).unwrap_err();
    assert!(matches!(e.kind(), ReadErrorKind::Io(_)));
    assert!(e.to_string().starts_with("/nonexistent/scene.ply: "), "{e}");
}

#[test]
fn mutated_and_truncated_inputs_never_panic() {
    // Every prefix and many byte flips of small valid files must give Ok or Err, never a panic.
    let s = random_splats(6, 1, 12);
    let order: Vec<usize> = (0..trainer_values(&s, 0).len()).collect();
    let mut splat_file = Vec::new();
    for i in 0..4u8 {
        splat_file.extend([i; 32]);
    }
    let inputs: Vec<(&str, Vec<u8>)> = vec![
        ("m.ply", write_to_vec(&s)),
        ("m.ply", emit_ply(&s, PlyEncoding::Ascii, &order, false)),
        (
            "m.ply",
            emit_ply(&s, PlyEncoding::BinaryBigEndian, &order, true),
        ),
        ("m.spz", spz_legacy(&s, 3)),
        ("m.spz", spz_v4(&s)),
        ("m.splat", splat_file),
    ];
    let mut r = Rng(99);
    for (name, good) in &inputs {
        for cut in 0..good.len() {
            let _ = read_bytes(name, &good[..cut]);
        }
        for _ in 0..300 {
            let mut b = good.clone();
            for _ in 0..1 + (r.f() * 4.0) as usize {
                let at = (r.f() * b.len() as f64) as usize;
                b[at] = (r.f() * 256.0) as u8;
            }
            if let Err(e) = read_bytes(name, &b) {
                assert!(e.to_string().starts_with(&format!("{name}: ")), "{e}");
            }
        }
    }
}
