//! Scene updates as a batch: a drawable inserted and removed before the driver takes the batch
//! is never handed out, so a burst of downloads the memory budget evicts again costs no upload.
//!
//! Frames can be seconds apart (a CPU-rasterised WebGL2 canvas) while responses keep arriving:
//! without this, every tile downloaded and evicted between two frames was uploaded to the GPU
//! and faded out, and the renderer's slot pool grew to the whole burst.

use super::SceneUpdate;
use std::collections::HashSet;

/// Drops every update of a scene id that is both inserted and removed within `batch`; all other
/// updates keep their order.
pub fn coalesce(batch: Vec<SceneUpdate>) -> Vec<SceneUpdate> {
    let inserted: HashSet<u64> = batch
        .iter()
        .filter_map(|u| match u {
            SceneUpdate::Insert { tile, .. } => Some(*tile),
            _ => None,
        })
        .collect();
    let gone: HashSet<u64> = batch
        .iter()
        .filter_map(|u| match u {
            SceneUpdate::Remove { tile } if inserted.contains(tile) => Some(*tile),
            _ => None,
        })
        .collect();
    if gone.is_empty() {
        return batch;
    }
    batch
        .into_iter()
        .filter(|u| {
            let id = match u {
                SceneUpdate::Insert { tile, .. }
                | SceneUpdate::Append { tile, .. }
                | SceneUpdate::Remove { tile } => tile,
            };
            !gone.contains(id)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalog::Level;
    use glam::DMat4;
    use splat2tiles_core::splat::Splats;
    use splat2tiles_tiles::tiling::TileKey;

    fn insert(tile: u64) -> SceneUpdate {
        SceneUpdate::Insert {
            tile,
            key: TileKey::ROOT,
            level: Level::Best,
            splats: Splats::default(),
            tile_to_world: DMat4::IDENTITY,
        }
    }

    fn ids(b: &[SceneUpdate]) -> Vec<(char, u64)> {
        b.iter()
            .map(|u| match u {
                SceneUpdate::Insert { tile, .. } => ('i', *tile),
                SceneUpdate::Append { tile, .. } => ('a', *tile),
                SceneUpdate::Remove { tile } => ('r', *tile),
            })
            .collect()
    }

    #[test]
    fn an_object_inserted_and_removed_in_one_batch_vanishes_others_stay_in_order() {
        let batch = vec![
            SceneUpdate::Remove { tile: 1 }, // shown in an earlier batch: stays
            insert(2),
            SceneUpdate::Append {
                tile: 2,
                splats: Splats::default(),
            },
            insert(3),
            SceneUpdate::Remove { tile: 2 }, // evicted before any frame drew it
            insert(4),
        ];
        assert_eq!(ids(&coalesce(batch)), vec![('r', 1), ('i', 3), ('i', 4)]);
        // Nothing to drop: unchanged.
        let b = vec![insert(5), SceneUpdate::Remove { tile: 6 }];
        assert_eq!(ids(&coalesce(b)), vec![('i', 5), ('r', 6)]);
    }
}
