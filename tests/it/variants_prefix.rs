//! Prefix-renderable Best tiles: the first k splats decoded from a truncated download equal the
//! first k splats of the full tile, for many cut points (inside the JSON, inside a splat, exact).

use crate::common;

use crate::common::*;
use splat2tiles_core::splat::Splats;
use splat2tiles_tiles::encode::read_tile_glb;
use splat2tiles_tiles::encode::tile::{TileLayout, try_write_tile_glb};
use splat2tiles_tiles::encode::{decode_prefix, prefix::prefix_layout};

fn assert_prefix_matches(full: &Splats, part: &Splats, k: usize) {
    assert_eq!(part.len(), k);
    assert_eq!(part.sh_degree, full.sh_degree);
    let r = full.rest_per_splat();
    for i in 0..k {
        assert_eq!(part.get(i), full.get(i), "splat {i}");
        assert_eq!(part.rest_of(i), full.rest_of(i), "SH of splat {i}");
    }
    let _ = r;
}

fn check_tile(splats: &Splats, centre: [f64; 3]) {
    let glb = try_write_tile_glb(splats, centre, IDENTITY_M, TileLayout::Interleaved).unwrap();
    let full = read_tile_glb(&glb).unwrap().splats;
    assert_eq!(full.len(), splats.len());
    let layout = prefix_layout(&glb).unwrap().expect("complete header");
    let n = layout.count;
    // Before the JSON chunk and BIN header are complete: nothing, nothing consumed.
    for cut in [0, 5, 19, 40, layout.first_record - 9] {
        let (s, used) = decode_prefix(&glb[..cut]).unwrap();
        assert_eq!((s.len(), used), (0, 0), "cut {cut}");
    }
    let mut cuts = vec![layout.first_record, glb.len()];
    for k in [1usize, 2, 7, n / 3, n / 2, n - 1] {
        let at = layout.first_record + k * layout.stride;
        cuts.extend([at - 1, at, at + 1, at + layout.stride / 2]);
    }
    for cut in cuts.into_iter().filter(|&c| c <= glb.len()) {
        let (part, used) = decode_prefix(&glb[..cut]).unwrap();
        let k = ((cut - layout.first_record) / layout.stride).min(n);
        assert_prefix_matches(&full, &part, k);
        assert_eq!(used, layout.first_record + k * layout.stride, "cut {cut}");
        assert!(used <= cut);
    }
    // Streaming: chunks of odd sizes, keeping the cut-off bytes for the next chunk.
    let mut have = Vec::new();
    let mut decoded = 0;
    for chunk in glb.chunks(997) {
        have.extend_from_slice(chunk);
        let (part, _) = decode_prefix(&have).unwrap();
        assert!(part.len() >= decoded);
        decoded = part.len();
    }
    assert_eq!(decoded, n);
}

const IDENTITY_M: [f64; 16] = splat2tiles_tiles::encode::tile::IDENTITY;

#[test]
fn prefixes_hold_the_leading_splats_sh3() {
    let s = random_splats(500, 3, 5.0, 7);
    check_tile(&s, [2.5, 2.5, 1.5]);
}

#[test]
fn prefixes_hold_the_leading_splats_sh0_and_sh1() {
    check_tile(&random_splats(300, 0, 2.0, 3), [1.0, 1.0, 0.5]);
    check_tile(&random_splats(77, 1, 2.0, 5), [0.0; 3]);
}

#[test]
fn prefixes_of_a_real_scene_tile() {
    let plant = common::splat_file::read_splat("plant.splat");
    let idx: Vec<usize> = (0..4000).collect();
    check_tile(&plant.select(&idx), [0.0; 3]);
}

#[test]
fn separate_layout_is_refused_for_prefix_decoding() {
    let s = random_splats(10, 0, 1.0, 9);
    let glb = try_write_tile_glb(&s, [0.0; 3], IDENTITY_M, TileLayout::Separate).unwrap();
    assert!(decode_prefix(&glb).is_err());
}
