//! View selection: the REPLACE (or, for layered tilesets, ADD) selection by screen-space error
//! restricted to the frustum, the subtree files it would refine into, and camera poses.

use super::*;
use splat2tiles_tiles::select::{AddPick, CutTree, select_add, select_cut};

impl StreamClient {
    /// World matrix of a tile's content given its glb node matrix.
    pub(super) fn tile_to_world(&self, node: &[f64; 16]) -> DMat4 {
        self.tile_to_world_base * DMat4::from_cols_array(node)
    }

    /// The view set of a camera: [`select_cut`] over the tiles read so far (a layered
    /// tileset: the tiles of [`Self::select_layers`]); plus the unread subtree files the
    /// selection would refine into (the tile above them is selected until they are read).
    pub(super) fn select(&self, cam: &Camera) -> (Vec<usize>, Vec<TileKey>) {
        if self.layered {
            let (picks, wants) = self.select_layers(cam);
            return (picks.iter().map(|p| p.tile).collect(), wants);
        }
        let mut wants = vec![];
        let view = select_cut(
            &ClientTree(self),
            cam,
            self.cfg.max_sse,
            self.cfg.frustum_cull,
            |i| self.subtrees_read_below(i, &mut wants),
        );
        (view, wants)
    }

    /// The layers a camera needs ([`select_add`] over the tiles read so far: every tile
    /// reached, children with the blend factor of their parent's error), parents first; plus
    /// the unread subtree files below.
    pub(super) fn select_layers(&self, cam: &Camera) -> (Vec<AddPick>, Vec<TileKey>) {
        let mut wants = vec![];
        let picks = select_add(
            &ClientTree(self),
            cam,
            self.cfg.max_sse,
            self.cfg.frustum_cull,
            |i| self.subtrees_read_below(i, &mut wants),
        );
        (picks, wants)
    }

    /// Whether every subtree file below tile `i` is read; the unread ones (not given up) are
    /// added to `wants`.
    fn subtrees_read_below(&self, i: usize, wants: &mut Vec<TileKey>) -> bool {
        let before = wants.len();
        if let Some(below) = self.by_leaf.get(&self.catalog.tiles[i].key) {
            wants.extend(below.iter().copied().filter(|k| {
                self.subtrees
                    .get(k)
                    .is_some_and(|s| !s.loaded && !s.given_up)
            }));
        }
        wants.len() == before
    }

    pub(super) fn pose_of(&self, cam: &Camera) -> ViewPose {
        let m = self.inv_root * cam.world_from_camera;
        let pos = m.w_axis.truncate();
        let fwd = m.transform_vector3(DVec3::Z).normalize_or(DVec3::X);
        ViewPose {
            t: self.now,
            pos,
            yaw: fwd.y.atan2(fwd.x),
            pitch: fwd.z.clamp(-1.0, 1.0).asin(),
        }
    }
}

pub(super) fn camera_ok(c: &Camera) -> bool {
    c.world_from_camera.is_finite()
        && c.fx.is_finite()
        && c.fy.is_finite()
        && c.fx > 0.0
        && c.fy > 0.0
        && c.width > 0
        && c.height > 0
}

/// The client's catalog as the shared selection sees it.
struct ClientTree<'a>(&'a StreamClient);

impl CutTree for ClientTree<'_> {
    fn roots(&self) -> &[usize] {
        &self.0.catalog.roots
    }
    fn children(&self, i: usize) -> &[usize] {
        &self.0.catalog.tiles[i].children
    }
    fn sphere(&self, i: usize) -> Option<(DVec3, f64)> {
        self.0.info[i].sphere
    }
    fn geometric_error(&self, i: usize) -> f64 {
        self.0.catalog.tiles[i].geometric_error
    }
    fn has_content(&self, i: usize) -> bool {
        self.0.catalog.tiles[i].has_content
    }
}
