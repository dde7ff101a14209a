//! Tileset geometry shared by the renderer, the viewers, the client and the evaluations: content
//! matrices, up, bounds, auto-view framing, box corners, screen-space error, REPLACE selection.

use std::path::PathBuf;

use glam::DVec3;
use splat2tiles_core::camera::Camera;
use splat2tiles_core::splat::Splats;

use crate::tiling::load::LoadedTileset;

/// Bounds of the finite splat centres, `None` when there are none.
pub fn finite_bounds(splats: &Splats) -> Option<(DVec3, DVec3)> {
    let mut it = splats
        .positions
        .iter()
        .map(|&p| DVec3::from(p))
        .filter(|p| p.is_finite());
    let first = it.next()?;
    Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
}

/// Tile contents with their world matrices, as selected for one camera.
pub type Instances = Vec<(Splats, glam::DMat4)>;

/// Rounds of [`frame_centres`]: each frames the splat centres the previous camera's tiles hold
/// (finer tiles as the camera comes closer); they settle in two or three.
const FRAMING_ROUNDS: usize = 4;

/// Auto-view framing of a tileset's splat centres, as a scene file's auto view frames its own:
/// from `cam` (framed on the root's bounding volume), take the contents `instances_for` selects,
/// frame their centres' bounds with `frame`, and repeat until the camera stays put. Returns the
/// camera and the contents it selects.
pub fn frame_centres<E>(
    mut cam: Camera,
    mut instances_for: impl FnMut(&Camera) -> Result<Instances, E>,
    mut frame: impl FnMut((DVec3, DVec3)) -> Result<Camera, E>,
) -> Result<(Camera, Instances), E> {
    let mut instances = instances_for(&cam)?;
    for _ in 0..FRAMING_ROUNDS {
        let Some(bounds) = centre_bounds(&instances) else {
            break;
        };
        let next = frame(bounds)?;
        let moved = (next.center() - cam.center()).length();
        if moved <= 1e-9 * (1.0 + cam.center().length()) {
            break;
        }
        cam = next;
        instances = instances_for(&cam)?;
    }
    Ok((cam, instances))
}

/// World-space bounds of the finite splat centres of `instances`, `None` when there are none.
pub fn centre_bounds(instances: &[(Splats, glam::DMat4)]) -> Option<(DVec3, DVec3)> {
    instances
        .iter()
        .flat_map(|(s, m)| {
            s.positions
                .iter()
                .map(move |&p| m.transform_point3(DVec3::from(p)))
        })
        .filter(|p| p.is_finite())
        .fold(None, |acc: Option<(DVec3, DVec3)>, p| {
            Some(acc.map_or((p, p), |(lo, hi)| (lo.min(p), hi.max(p))))
        })
}

/// Why [`load_instances`] could not give the splats of a content.
#[derive(Debug, thiserror::Error)]
pub enum ContentError {
    /// The content file could not be read (missing, too large, not a regular file).
    #[error(transparent)]
    Read(#[from] splat2tiles_io::BoundedReadError),
    /// A tile content file is not a glb of splats in any variant.
    #[error("{path}: cannot decode the tile: {source}")]
    Decode {
        /// File.
        path: PathBuf,
        /// Decoding error.
        source: crate::encode::glb::GlbError,
    },
}

/// Reads and decodes the contents at `paths` (any variant: plain, meshopt or SPZ_2), each with
/// its content-to-world matrix.
pub fn load_instances(ts: &LoadedTileset, paths: &[PathBuf]) -> Result<Instances, ContentError> {
    paths
        .iter()
        .map(|p| {
            let bytes = splat2tiles_io::read_file(p, crate::tiling::load::CONTENT_FILE)?;
            let (splats, node) =
                crate::variants::decode_variant(&bytes).map_err(|source| ContentError::Decode {
                    path: p.clone(),
                    source,
                })?;
            Ok((splats, content_model(ts, &node)))
        })
        .collect()
}

/// World matrix of a tile's content: root transform, then glTF y-up -> 3D Tiles z-up, then the
/// glb node matrix.
pub fn content_model(ts: &LoadedTileset, node: &[f64; 16]) -> glam::DMat4 {
    let y_to_z = glam::DMat4::from_mat3(splat2tiles_core::frame::y_up_to_z_up());
    ts.root_transform * y_to_z * glam::DMat4::from_cols_array(node)
}

/// The tileset's up direction in world coordinates (+z of the root frame).
pub fn tileset_up(ts: &LoadedTileset) -> DVec3 {
    ts.root_transform
        .transform_vector3(DVec3::Z)
        .try_normalize()
        .unwrap_or(DVec3::Z)
}

/// World-space (after the root transform) axis-aligned bounds of the root's tight box.
pub fn tileset_bounds(ts: &LoadedTileset) -> Option<(DVec3, DVec3)> {
    let root = &ts.tiles[ts.root_index()?];
    let corners = box_corners(root.bounding_box.as_ref()?);
    let pts: Vec<DVec3> = corners
        .iter()
        .map(|c| ts.root_transform.transform_point3(*c))
        .collect();
    let lo = pts.iter().fold(DVec3::splat(f64::MAX), |a, p| a.min(*p));
    let hi = pts.iter().fold(DVec3::splat(f64::MIN), |a, p| a.max(*p));
    Some((lo, hi))
}

/// The 8 corners of a 3D Tiles box (centre + three half-axis vectors).
pub fn box_corners(b: &[f64; 12]) -> [DVec3; 8] {
    let c = DVec3::new(b[0], b[1], b[2]);
    let axes = [
        DVec3::new(b[3], b[4], b[5]),
        DVec3::new(b[6], b[7], b[8]),
        DVec3::new(b[9], b[10], b[11]),
    ];
    std::array::from_fn(|i| {
        let s = |k: usize| if i >> k & 1 == 1 { 1.0 } else { -1.0 };
        c + axes[0] * s(0) + axes[1] * s(1) + axes[2] * s(2)
    })
}

/// Screen-space error (pixels) of tile `i` seen by `cam`: geometric error * focal / distance
/// from the eye to its box's bounding sphere (1e-9 inside it or without a box).
pub fn tile_sse(ts: &LoadedTileset, i: usize, cam: &Camera) -> f64 {
    let t = &ts.tiles[i];
    let distance = t
        .bounding_box
        .as_ref()
        .map(|b| {
            let (centre, radius) = box_sphere(b, &ts.root_transform);
            (centre.distance(cam.center()) - radius).max(1e-9)
        })
        .unwrap_or(1e-9);
    t.geometric_error * cam.fy / distance
}

/// REPLACE-refinement selection: from the root, a tile is refined into its children while its
/// screen-space error (geometric error * focal / distance to its box) exceeds `max_sse` pixels;
/// the content of every tile reached and not refined is drawn.
pub fn select_tiles(ts: &LoadedTileset, cam: &Camera, max_sse: f64) -> Vec<PathBuf> {
    let children = ts.children();
    let Some(root) = ts.root_index() else {
        return vec![];
    };
    let mut out = vec![];
    let mut stack = vec![root];
    while let Some(i) = stack.pop() {
        let t = &ts.tiles[i];
        let sse = tile_sse(ts, i, cam);
        match children.get(&t.key) {
            Some(kids) if sse > max_sse => stack.extend(kids.iter().copied()),
            _ => out.extend(t.content.clone()),
        }
    }
    out.sort();
    out
}

/// World-space bounding sphere of a 3D Tiles box (`[centre, x half-axis, y, z]`) under `m`:
/// the centre of the transformed corners and the farthest corner's distance.
pub fn box_sphere(b: &[f64; 12], m: &glam::DMat4) -> (DVec3, f64) {
    let corners = crate::geometry::box_corners(b).map(|c| m.transform_point3(c));
    let centre = corners.iter().copied().sum::<DVec3>() / 8.0;
    let radius = corners
        .iter()
        .map(|c| c.distance(centre))
        .fold(0.0, f64::max);
    (centre, radius)
}
