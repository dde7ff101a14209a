//! The refined cut a camera needs: REPLACE selection by screen-space error over each tile's
//! bounding sphere, skipping tiles whose sphere is outside the view, shared by client and scoring.

pub use crate::geometry::box_sphere;
use glam::DVec3;
use splat2tiles_core::camera::Camera;

/// A tile tree as the selection sees it (indices into the caller's tile list).
pub trait CutTree {
    /// Root tiles.
    fn roots(&self) -> &[usize];
    /// Child tiles of `i`.
    fn children(&self, i: usize) -> &[usize];
    /// World-space bounding sphere (centre, radius), if known.
    fn sphere(&self, i: usize) -> Option<(DVec3, f64)>;
    /// Geometric error in metres.
    fn geometric_error(&self, i: usize) -> f64;
    /// Whether the tile has content to draw.
    fn has_content(&self, i: usize) -> bool;
}

/// The cut for `cam`: a tile is refined when `geometricError * fy / (distance to its sphere)`
/// exceeds `max_sse`, `may_refine(i)` agrees (asked for every such tile, leaves included; the
/// client says no while subtree files below it are unread) and it has children; otherwise it is
/// selected if it has content. With
/// `frustum_cull`, tiles whose sphere misses the camera's viewing pyramid are skipped. Tiles come
/// out in depth-first order.
pub fn select_cut(
    tree: &impl CutTree,
    cam: &Camera,
    max_sse: f64,
    frustum_cull: bool,
    mut may_refine: impl FnMut(usize) -> bool,
) -> Vec<usize> {
    let eye = cam.center();
    let rot_t = cam.rotation().transpose();
    let mut out = vec![];
    let mut stack: Vec<usize> = tree.roots().iter().rev().copied().collect();
    while let Some(i) = stack.pop() {
        let distance = match tree.sphere(i) {
            Some((c, r)) => {
                if frustum_cull && !sphere_in_view(cam, rot_t * (c - eye), r) {
                    continue;
                }
                (c.distance(eye) - r).max(1e-9)
            }
            None => 1e-9,
        };
        let sse = tree.geometric_error(i) * cam.fy / distance;
        let kids = tree.children(i);
        // Asked for every tile over the limit, leaves too (the client collects the unread
        // subtree files below a leaf of the tiles it has read).
        let refine = sse > max_sse && may_refine(i);
        if refine && !kids.is_empty() {
            stack.extend(kids.iter().rev().copied());
        } else if tree.has_content(i) {
            out.push(i);
        }
    }
    out
}

/// One tile of an ADD (layered) selection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AddPick {
    /// The tile.
    pub tile: usize,
    /// Index of its parent's pick in the same list (always earlier); `None` for a root.
    pub parent: Option<usize>,
    /// Its blend factor: 1 for a root, else `layers::blend::blend_factor` of the parent's
    /// screen-space error (LapisGS eq. 4 over SSE).
    pub blend: f32,
}

/// The ADD (layered) selection for `cam`: every tile reached from the roots is selected (if it
/// has content); a tile whose screen-space error exceeds `max_sse`, and for which `may_refine`
/// agrees, brings in its children, each with the blend factor of that error
/// (`spec/layered-content.md`, "Drawing"). Same error and culling rules as [`select_cut`];
/// parents come before their children, siblings in child order. A tile without content ends
/// its branch (a layer needs its parent's layer).
pub fn select_add(
    tree: &impl CutTree,
    cam: &Camera,
    max_sse: f64,
    frustum_cull: bool,
    mut may_refine: impl FnMut(usize) -> bool,
) -> Vec<AddPick> {
    let eye = cam.center();
    let rot_t = cam.rotation().transpose();
    let mut out: Vec<AddPick> = tree
        .roots()
        .iter()
        .map(|&tile| AddPick {
            tile,
            parent: None,
            blend: 1.0,
        })
        .collect();
    let mut keep = vec![];
    let mut next = 0;
    while next < out.len() {
        let i = out[next].tile;
        let distance = match tree.sphere(i) {
            Some((c, r)) => {
                if frustum_cull && !sphere_in_view(cam, rot_t * (c - eye), r) {
                    next += 1;
                    continue;
                }
                (c.distance(eye) - r).max(1e-9)
            }
            None => 1e-9,
        };
        if !tree.has_content(i) {
            next += 1;
            continue;
        }
        keep.push(next);
        let sse = tree.geometric_error(i) * cam.fy / distance;
        if sse > max_sse && may_refine(i) {
            let blend = crate::layers::blend::blend_factor(sse, max_sse);
            for &c in tree.children(i) {
                out.push(AddPick {
                    tile: c,
                    parent: Some(next),
                    blend,
                });
            }
        }
        next += 1;
    }
    // Drop the culled and empty picks, renumbering the parents.
    let mut new_index = vec![usize::MAX; out.len()];
    for (n, &k) in keep.iter().enumerate() {
        new_index[k] = n;
    }
    keep.iter()
        .map(|&k| AddPick {
            parent: out[k].parent.map(|p| new_index[p]),
            ..out[k]
        })
        .collect()
}

/// Whether a sphere (centre in camera coordinates: x right, y down, z forward) meets the
/// camera's viewing pyramid (side planes through the image borders, in front of the camera).
pub fn sphere_in_view(cam: &Camera, c: DVec3, r: f64) -> bool {
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat4;

    /// A root with two children side by side along x, each with content.
    struct Two;
    impl CutTree for Two {
        fn roots(&self) -> &[usize] {
            &[0]
        }
        fn children(&self, i: usize) -> &[usize] {
            if i == 0 { &[1, 2] } else { &[] }
        }
        fn sphere(&self, i: usize) -> Option<(DVec3, f64)> {
            Some(match i {
                0 => (DVec3::ZERO, 2.0),
                1 => (DVec3::new(-1.0, 0.0, 0.0), 1.0),
                _ => (DVec3::new(1.0, 0.0, 0.0), 1.0),
            })
        }
        fn geometric_error(&self, i: usize) -> f64 {
            if i == 0 { 1.0 } else { 0.0 }
        }
        fn has_content(&self, _: usize) -> bool {
            true
        }
    }

    fn cam_at(eye: DVec3, target: DVec3) -> Camera {
        Camera::from_pose(
            64,
            64,
            60.0,
            splat2tiles_core::camera::look_at_pose(eye, target, DVec3::Z),
        )
    }

    #[test]
    fn near_refines_far_does_not_and_culls_what_is_behind() {
        let near = cam_at(DVec3::new(0.0, -5.0, 0.0), DVec3::ZERO);
        assert_eq!(select_cut(&Two, &near, 1.0, true, |_| true), vec![1, 2]);
        // Refinement vetoed: the parent stands in.
        assert_eq!(select_cut(&Two, &near, 1.0, true, |_| false), vec![0]);
        let far = cam_at(DVec3::new(0.0, -5000.0, 0.0), DVec3::ZERO);
        assert_eq!(select_cut(&Two, &far, 1.0, true, |_| true), vec![0]);
        // Looking away along -y from y = -5: everything is behind the camera.
        let away = cam_at(DVec3::new(0.0, -5.0, 0.0), DVec3::new(0.0, -10.0, 0.0));
        assert!(select_cut(&Two, &away, 1.0, true, |_| true).is_empty());
        assert_eq!(select_cut(&Two, &away, 1.0, false, |_| true), vec![1, 2]);
    }

    #[test]
    fn box_sphere_encloses_the_box() {
        let b = [1.0, 2.0, 3.0, 1.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 3.0];
        let (c, r) = box_sphere(&b, &DMat4::IDENTITY);
        assert!((c - DVec3::new(1.0, 2.0, 3.0)).length() < 1e-12);
        assert!((r - 14f64.sqrt()).abs() < 1e-12);
    }
}
