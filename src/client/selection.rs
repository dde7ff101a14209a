//! View selection: the REPLACE selection by screen-space error restricted to the frustum, the
//! subtree files it would refine into, and camera poses in the tileset frame.

use super::*;

impl StreamClient {
    /// World matrix of a tile's content given its glb node matrix.
    pub(super) fn tile_to_world(&self, node: &[f64; 16]) -> DMat4 {
        self.tile_to_world_base * DMat4::from_cols_array(node)
    }

    /// The view set of a camera: REPLACE selection by screen-space error over the bounding
    /// sphere (as `select_tiles`), skipping subtrees whose sphere is outside the frustum; plus
    /// the unread subtree files the selection would refine into (the tile above them is
    /// selected until they are read).
    pub(super) fn select(&self, cam: &Camera) -> (Vec<usize>, Vec<TileKey>) {
        let eye = cam.center();
        let rot_t = cam.rotation().transpose();
        let mut out = vec![];
        let mut wants = vec![];
        let mut stack: Vec<usize> = self.catalog.roots.iter().rev().copied().collect();
        while let Some(i) = stack.pop() {
            let t = &self.catalog.tiles[i];
            let distance = match self.info[i].sphere {
                Some((c, r)) => {
                    if self.cfg.frustum_cull && !sphere_in_view(cam, rot_t * (c - eye), r) {
                        continue;
                    }
                    (c.distance(eye) - r).max(1e-9)
                }
                None => 1e-9,
            };
            let sse = t.geometric_error * cam.fy / distance;
            let refine = sse > self.cfg.max_sse;
            let before = wants.len();
            if refine && let Some(below) = self.by_leaf.get(&t.key) {
                wants.extend(below.iter().copied().filter(|k| {
                    self.subtrees
                        .get(k)
                        .is_some_and(|s| !s.loaded && !s.given_up)
                }));
            }
            if refine && wants.len() == before && !t.children.is_empty() {
                stack.extend(t.children.iter().rev().copied());
            } else if t.has_content {
                out.push(i);
            }
        }
        (out, wants)
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

/// Whether a sphere (centre in camera coordinates: x right, y down, z forward) meets the
/// camera's viewing pyramid (side planes through the image borders, in front of the camera).
pub(super) fn sphere_in_view(cam: &Camera, c: DVec3, r: f64) -> bool {
    if c.z < -r {
        return false;
    }
    let (w, h) = (cam.width as f64, cam.height as f64);
    // Inward-facing side planes through the origin: n . p <= 0 inside.
    let planes = [
        DVec3::new(cam.fx, 0.0, -(w - cam.cx)),
        DVec3::new(-cam.fx, 0.0, -cam.cx),
        DVec3::new(0.0, cam.fy, -(h - cam.cy)),
        DVec3::new(0.0, -cam.fy, -cam.cy),
    ];
    planes.iter().all(|n| n.normalize_or_zero().dot(c) <= r)
}
