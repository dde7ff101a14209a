//! The codebook variant's tiles (`S2T_gaussian_splatting_compression_codebook`) under `validate`:
//! a written tile passes, and each malformed payload is the error that names what is wrong.

use crate::common::*;
use splat2tiles_tiles::encode::codebook_glb::{codebook_payload, write_codebook_glb};
use splat2tiles_tiles::encode::tile::IDENTITY;
use splat2tiles_validate::{ValidateOptions, validate_glb_bytes};

/// A codebook tile of 3000 SH1 splats and where its payload starts in the glb.
fn tile() -> (Vec<u8>, usize) {
    let s = random_splats(3000, 1, 5.0, 4);
    let glb = write_codebook_glb(&s, [0.0; 3], IDENTITY, &Default::default())
        .unwrap()
        .0;
    let payload = codebook_payload(&glb).unwrap().unwrap();
    let at = glb
        .windows(4)
        .position(|w| w == b"S2TC")
        .expect("payload in the BIN chunk");
    assert_eq!(&glb[at..at + payload.len()], &payload[..]);
    (glb, at)
}

fn codes(glb: &[u8]) -> Vec<String> {
    let r = validate_glb_bytes(glb, &ValidateOptions::default());
    r.codes()
}

#[test]
fn a_written_codebook_tile_validates_without_errors() {
    let (glb, _) = tile();
    let r = validate_glb_bytes(&glb, &ValidateOptions::default());
    assert_eq!(r.num_errors, 0, "{:?}", r.codes());
    assert_eq!(r.num_warnings, 0, "{:?}", r.codes());
}

#[test]
fn malformed_codebook_payloads_are_errors() {
    let (glb, at) = tile();
    let poke = |offset: usize, bytes: &[u8]| {
        let mut g = glb.clone();
        g[at + offset..at + offset + bytes.len()].copy_from_slice(bytes);
        codes(&g)
    };
    let invalid = ["SPLAT_CODEBOOK_PAYLOAD_INVALID".to_string()];
    // Magic, version, a NaN grid step, 40 grid bits, a huge count.
    assert_eq!(poke(0, b"XXXX"), invalid);
    assert_eq!(poke(4, &[9]), invalid);
    assert_eq!(poke(24, &f32::NAN.to_le_bytes()), invalid);
    assert_eq!(poke(28, &[40]), invalid);
    assert_eq!(poke(8, &u32::MAX.to_le_bytes()), invalid);
    // Fewer splats than the accessors declare still decode: the count differs.
    assert_eq!(
        poke(8, &2999u32.to_le_bytes()),
        ["SPLAT_CODEBOOK_COUNT_MISMATCH".to_string()]
    );
}
