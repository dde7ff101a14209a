//! The completeness rule of a tile tree: no cut that a REPLACE traversal can make, at any
//! screen-space threshold, stops at a tile without content while content lies below it.
//!
//! The explicit and implicit walks record every tile ([`CutTile`], parents before children);
//! [`check`] then finds the tiles without content that have content below them and are not
//! shadowed by their parent. A traversal stops at a tile once its geometric error projects under
//! the threshold, which happens from far enough for every finite error, and then draws nothing of
//! its region. Only a tile whose parent has the same bounding volume (in the same frame), a
//! geometric error no larger than its own and REPLACE refinement is always refined with it: its
//! screen-space error equals the parent's for every camera.

use super::context::Ctx;
use super::issues::Issue;
use super::volume::Volume;

pub(crate) use super::context::CutTile;

/// Most tiles one tileset document records for the rule (about 300 MB); past it the rule is
/// not checked for that document.
pub(crate) const MAX_TILES: usize = 1 << 21;

/// Records `t` in the walk of the current document; its index, or `None` once [`MAX_TILES`]
/// are recorded (the rule is then skipped).
pub(crate) fn record(ctx: &mut Ctx<'_>, t: CutTile) -> Option<usize> {
    if ctx.cut.len() >= MAX_TILES {
        ctx.cut_truncated = true;
        return None;
    }
    ctx.cut.push(t);
    Some(ctx.cut.len() - 1)
}

/// Whether `a` and `b` are the same volume, up to 1e-9 of its size.
fn same_volume(a: &Volume, b: &Volume) -> bool {
    let close = |x: &[f64], y: &[f64]| {
        let scale = x.iter().chain(y).fold(1e-12f64, |m, v| m.max(v.abs()));
        x.iter().zip(y).all(|(p, q)| (p - q).abs() <= 1e-9 * scale)
    };
    match (a, b) {
        (Volume::Box { c: c1, axes: a1 }, Volume::Box { c: c2, axes: a2 }) => {
            let flat = |c: &glam::DVec3, ax: &[glam::DVec3; 3]| {
                let mut v = c.to_array().to_vec();
                ax.iter().for_each(|x| v.extend(x.to_array()));
                v
            };
            close(&flat(c1, a1), &flat(c2, a2))
        }
        (Volume::Region(r1), Volume::Region(r2)) => close(r1, r2),
        (Volume::Sphere { c: c1, r: r1 }, Volume::Sphere { c: c2, r: r2 }) => {
            close(&[c1.x, c1.y, c1.z, *r1], &[c2.x, c2.y, c2.z, *r2])
        }
        _ => false,
    }
}

/// Whether tile `t`, without content, is always refined together with its parent `p`.
fn shadowed(t: &CutTile, p: &CutTile) -> bool {
    let same_place = match (&t.volume, &p.volume) {
        (Some(a), Some(b)) => same_volume(a, b) && t.world == p.world,
        _ => false,
    };
    let error_ok = match (t.error, p.error) {
        (Some(e), Some(pe)) => e >= pe,
        _ => false,
    };
    p.replace && same_place && error_ok
}

/// Reports, in one TILE_WITHOUT_CONTENT_ENDS_REFINEMENT warning, every tile of `tiles` (parents
/// before children) that a REPLACE traversal can stop at with content below it undrawn.
pub(crate) fn check(ctx: &mut Ctx<'_>, tiles: &[CutTile]) {
    if std::mem::take(&mut ctx.cut_truncated) {
        return;
    }
    let mut below = vec![false; tiles.len()];
    for i in (0..tiles.len()).rev() {
        if let Some(p) = tiles[i].parent
            && (tiles[i].content || below[i])
        {
            below[p] = true;
        }
    }
    let bad: Vec<usize> = (0..tiles.len())
        .filter(|&i| {
            let t = &tiles[i];
            !t.content && below[i] && t.replace && t.parent.is_none_or(|p| !shadowed(t, &tiles[p]))
        })
        .collect();
    let Some(&first) = bad.first() else {
        return;
    };
    let t = &tiles[first];
    let error = t.error.map_or("no valid".into(), |e| format!("{e}"));
    ctx.push(Issue::TILE_WITHOUT_CONTENT_ENDS_REFINEMENT(
        t.path.clone(),
        format!(
            "{} tiles without content have content below them and can end a REPLACE traversal \
             (from wherever their geometric error projects under the screen-space threshold, \
             nothing of their region is drawn); first: this tile (geometric error {error}). Give \
             each a level-of-detail content, or its parent's bounding volume and geometric error",
            bad.len()
        ),
    ));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ValidateOptions;
    use glam::{DMat4, DVec3};

    fn unit_box(size: f64) -> Option<Volume> {
        Some(Volume::Box {
            c: DVec3::ZERO,
            axes: [DVec3::X * size, DVec3::Y * size, DVec3::Z * size],
        })
    }

    fn tile(parent: Option<usize>, content: bool, size: f64, error: f64) -> CutTile {
        CutTile {
            path: format!("t{parent:?}{content}"),
            parent,
            content,
            volume: unit_box(size),
            world: DMat4::IDENTITY,
            error: Some(error),
            replace: true,
        }
    }

    fn codes(tiles: &[CutTile]) -> usize {
        let opts = ValidateOptions::default();
        let mut ctx = Ctx::new(std::path::PathBuf::from("/nonexistent"), &opts);
        check(&mut ctx, tiles);
        ctx.issues.len()
    }

    #[test]
    fn contentless_tiles_with_content_below_are_reported_unless_shadowed() {
        // Root with content, a contentless child with a smaller box over a leaf: a hole.
        let hole = [
            tile(None, true, 10.0, 8.0),
            tile(Some(0), false, 2.0, 4.0),
            tile(Some(1), true, 1.0, 0.0),
        ];
        assert_eq!(codes(&hole), 1);
        // The same child with its parent's box and error: refined with it.
        let mut chain = hole.clone();
        chain[1] = tile(Some(0), false, 10.0, 8.0);
        assert_eq!(codes(&chain), 0);
        // A smaller error than the parent's, same box: it can stop where the parent refines.
        chain[1].error = Some(7.0);
        assert_eq!(codes(&chain), 1);
        // A contentless root over content, and a contentless leaf (nothing below): only the root.
        let root = [tile(None, false, 10.0, 8.0), tile(Some(0), true, 1.0, 0.0)];
        assert_eq!(codes(&root), 1);
        assert_eq!(codes(&[tile(None, false, 1.0, 0.0)]), 0);
        // Under ADD the rule does not judge.
        let mut add = hole.clone();
        add[1].replace = false;
        assert_eq!(codes(&add), 0);
        // No valid error or volume: never shadowed.
        chain[1].error = None;
        assert_eq!(codes(&chain), 1);
    }
}
