//! `S2T_gaussian_splatting_compression_codebook` tiles: the codebook payload (`super::codebook`)
//! as bufferView 0 under `KHR_gaussian_splatting`, accessors without bufferView; its reader.

use super::codebook::{CodebookOptions, decode_payload, encode_payload};
use super::glb::GlbError;
use super::gltf::S2T_GAUSSIAN_SPLATTING_CODEBOOK;
use super::spz2::{compressed_content, compressed_glb, compressed_payload};
use super::storage_order::in_caller_order;
use super::tile::check_writable;
use splat2tiles_core::splat::Splats;

/// Writes `splats` (positions made relative to `centre`) as a codebook tile, and the splats it
/// decodes to, in the caller's order.
pub fn write_codebook_glb(
    splats: &Splats,
    centre: [f64; 3],
    node_matrix: [f64; 16],
    opts: &CodebookOptions,
) -> Result<(Vec<u8>, Splats), GlbError> {
    check_writable(splats, centre)?;
    let (payload, order) = encode_payload(splats, centre, opts);
    let decoded =
        decode_payload(&payload).map_err(|e| GlbError::invalid("/bufferViews/0", e.to_string()))?;
    let glb = compressed_glb(
        &decoded,
        payload,
        node_matrix,
        S2T_GAUSSIAN_SPLATTING_CODEBOOK,
        false,
    )?;
    Ok((glb, in_caller_order(&decoded, &order)))
}

/// The codebook payload of a glb, if it has the extension.
pub fn codebook_payload(bytes: &[u8]) -> Result<Option<Vec<u8>>, GlbError> {
    compressed_payload(bytes, S2T_GAUSSIAN_SPLATTING_CODEBOOK)
}

/// The splats (tile-relative, payload order) of a codebook payload.
pub(crate) fn codebook_splats(payload: &[u8]) -> Result<Splats, GlbError> {
    decode_payload(payload).map_err(|e| GlbError::invalid("/bufferViews/0", e.to_string()))
}

/// Decodes a codebook tile: splats (tile-relative, payload order) and node matrix.
pub fn read_codebook_glb(bytes: &[u8]) -> Result<(Splats, [f64; 16]), GlbError> {
    let c = compressed_content(bytes, &[S2T_GAUSSIAN_SPLATTING_CODEBOOK])?
        .ok_or_else(|| GlbError::invalid("/meshes/0/primitives/0", "no codebook extension"))?;
    Ok((codebook_splats(&c.payload)?, c.matrix))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode::tile::IDENTITY;
    use crate::variants::decode_variant;
    use splat2tiles_core::splat::Splat;

    #[test]
    fn a_codebook_tile_reads_back_as_written() {
        let mut s = Splats::new(1);
        for i in 0..500 {
            let t = i as f64 * 0.01;
            s.push(
                Splat {
                    position: [100.0 + t, 200.0 - t, 300.0 + t * t],
                    scale: [0.02, 0.03, 0.01 + t as f32 * 0.01],
                    rotation: [0.0, 0.0, 0.0, 1.0],
                    opacity: 0.5,
                    sh0: [0.1, -0.2, t as f32],
                },
                &[[0.05, -0.05, 0.0]; 3],
            );
        }
        let mut m = IDENTITY;
        m[12] = 7.0;
        let (glb, decoded) =
            write_codebook_glb(&s, [100.0, 200.0, 300.0], m, &CodebookOptions::default()).unwrap();
        let (read, matrix) = decode_variant(&glb).unwrap();
        assert_eq!(matrix, m);
        assert_eq!(read.len(), 500);
        // The reader's splats are the writer's decoded ones, reordered.
        let mut a: Vec<[f64; 3]> = decoded.positions.clone();
        let mut b: Vec<[f64; 3]> = read.positions.clone();
        a.sort_by(|x, y| x.partial_cmp(y).unwrap());
        b.sort_by(|x, y| x.partial_cmp(y).unwrap());
        assert_eq!(a, b);
        for (p, q) in decoded.positions.iter().zip(&s.positions) {
            assert!((p[0] + 100.0 - q[0]).abs() < 0.01);
        }
        assert!(
            write_codebook_glb(&Splats::new(0), [0.0; 3], m, &CodebookOptions::default()).is_err()
        );
    }
}
