//! Frustum-box visibility (TileSplat's corner test, the usual plane test, SGSS's projection test
//! and an exact separating-axis test), screen-space error and hierarchical culling.
//!
//! TileSplat App. D: a box is visible "if any OBB corner is on the positive side of all frustum
//! planes" ([`VisTest::CornerAny`]; it misses boxes that cross the frustum with no corner inside).
//! SGSS sec. 3.3: camera-space corners (eq. 8) projected on the xy, xz and yz planes against the
//! view pyramid's projections ([`VisTest::Sgss`]). [`VisTest::Planes`] culls a box only when it
//! lies wholly outside one plane (conservative, fast); [`VisTest::Exact`] is the full SAT.

use super::catalog::TileCatalog;
use super::geom::{Frustum, Intrinsics, Obb, ViewPose};
use glam::{DVec2, DVec3};

/// Which frustum-box test to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VisTest {
    /// Culled only when wholly outside one of the 6 planes (conservative; the default).
    Planes,
    /// TileSplat: visible iff a corner is inside all planes.
    CornerAny,
    /// SGSS: projections on the camera's xy, xz, yz planes all overlap the pyramid's.
    Sgss,
    /// Exact separating-axis test of the box against the frustum polyhedron.
    Exact,
}

impl VisTest {
    /// Whether `b` intersects `f` under this test.
    pub fn visible(self, f: &Frustum, b: &Obb) -> bool {
        match self {
            VisTest::Planes => planes_test(f, b),
            VisTest::CornerAny => b.corners().iter().any(|&c| f.contains(c)),
            VisTest::Sgss => sgss_test(f, b),
            VisTest::Exact => exact_test(f, b),
        }
    }

    /// Name for tables.
    pub fn name(self) -> &'static str {
        match self {
            VisTest::Planes => "planes (conservative)",
            VisTest::CornerAny => "TileSplat corner",
            VisTest::Sgss => "SGSS projections",
            VisTest::Exact => "exact SAT",
        }
    }
}

/// Plane test with the box's projected radius per plane (equivalent to "all 8 corners outside").
pub fn planes_test(f: &Frustum, b: &Obb) -> bool {
    f.planes.iter().all(|(n, d)| {
        let r: f64 = b.half.iter().map(|h| n.dot(*h).abs()).sum();
        n.dot(b.center) + d >= -r
    })
}

fn project_overlap(axis: DVec3, a: &[DVec3], b: &[DVec3]) -> bool {
    if axis.length_squared() < 1e-20 {
        return true;
    }
    let range = |pts: &[DVec3]| {
        pts.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| {
            let v = axis.dot(*p);
            (lo.min(v), hi.max(v))
        })
    };
    let (a0, a1) = range(a);
    let (b0, b1) = range(b);
    let eps = 1e-9 * (1.0 + a1.abs().max(b1.abs()));
    a0 <= b1 + eps && b0 <= a1 + eps
}

/// Exact SAT of two convex polyhedra (box, frustum) in camera coordinates: 3 + 5 face normals and
/// 3 x 6 edge cross products.
pub fn exact_test(f: &Frustum, b: &Obb) -> bool {
    let fc = f.camera_corners();
    let bc: Vec<DVec3> = b.corners().iter().map(|&c| f.to_camera(c)).collect();
    let bax: Vec<DVec3> = b
        .half
        .iter()
        .map(|h| DVec3::new(h.dot(f.axes[0]), h.dot(f.axes[1]), h.dot(f.axes[2])))
        .collect();
    let (tx, ty) = (f.tx, f.ty);
    let face = [
        DVec3::Z,
        DVec3::new(1.0, 0.0, -tx),
        DVec3::new(1.0, 0.0, tx),
        DVec3::new(0.0, 1.0, -ty),
        DVec3::new(0.0, 1.0, ty),
    ];
    let edges = [
        DVec3::X,
        DVec3::Y,
        DVec3::new(tx, ty, 1.0),
        DVec3::new(-tx, ty, 1.0),
        DVec3::new(tx, -ty, 1.0),
        DVec3::new(-tx, -ty, 1.0),
    ];
    // Degenerate (flat) boxes: use any axis that is non-zero; flat axes give no separating plane
    // of their own, but their normal (cross of the other two) does.
    let mut box_normals: Vec<DVec3> = bax.clone();
    box_normals.push(bax[0].cross(bax[1]));
    box_normals.push(bax[1].cross(bax[2]));
    box_normals.push(bax[2].cross(bax[0]));
    face.iter()
        .chain(box_normals.iter())
        .all(|&ax| project_overlap(ax, &fc, &bc))
        && bax.iter().all(|&be| {
            edges
                .iter()
                .all(|&fe| project_overlap(be.cross(fe), &fc, &bc))
        })
}

fn hull(mut p: Vec<DVec2>) -> Vec<DVec2> {
    p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut h: Vec<DVec2> = Vec::with_capacity(p.len() * 2);
    for pass in 0..2 {
        let start = h.len();
        let iter: Box<dyn Iterator<Item = &DVec2>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in iter {
            while h.len() >= start + 2 && cross(h[h.len() - 2], h[h.len() - 1], q) <= 0.0 {
                h.pop();
            }
            h.push(q);
        }
        h.pop();
    }
    h
}

fn polys_overlap(a: &[DVec2], b: &[DVec2]) -> bool {
    let axes = |p: &[DVec2]| -> Vec<DVec2> {
        (0..p.len())
            .map(|i| (p[(i + 1) % p.len()] - p[i]).perp())
            .collect()
    };
    let mut all = axes(a);
    all.extend(axes(b));
    if a.len() == 2 {
        all.push(a[1] - a[0]);
    }
    if b.len() == 2 {
        all.push(b[1] - b[0]);
    }
    all.iter().all(|&ax| {
        if ax.length_squared() < 1e-24 {
            return true;
        }
        let r = |p: &[DVec2]| {
            p.iter().fold((f64::MAX, f64::MIN), |(lo, hi), q| {
                let v = ax.dot(*q);
                (lo.min(v), hi.max(v))
            })
        };
        let (a0, a1) = r(a);
        let (b0, b1) = r(b);
        a0 <= b1 + 1e-9 && b0 <= a1 + 1e-9
    })
}

/// SGSS's test: the view pyramid (apex at the camera, base at the far plane; the near plane is
/// dropped as the paper does) and the box projected on the camera's xy, xz and yz planes.
pub fn sgss_test(f: &Frustum, b: &Obb) -> bool {
    let c: Vec<DVec3> = b.corners().iter().map(|&p| f.to_camera(p)).collect();
    let (fx, fy, z) = (f.far * f.tx, f.far * f.ty, f.far);
    let o = DVec2::ZERO;
    type Proj = fn(DVec3) -> DVec2;
    let planes: [(Proj, Vec<DVec2>); 3] = [
        (
            |p| DVec2::new(p.x, p.y),
            vec![
                DVec2::new(-fx, -fy),
                DVec2::new(fx, -fy),
                DVec2::new(fx, fy),
                DVec2::new(-fx, fy),
            ],
        ),
        (
            |p| DVec2::new(p.x, p.z),
            vec![o, DVec2::new(fx, z), DVec2::new(-fx, z)],
        ),
        (
            |p| DVec2::new(p.y, p.z),
            vec![o, DVec2::new(fy, z), DVec2::new(-fy, z)],
        ),
    ];
    planes.iter().all(|(proj, pyr)| {
        let h = hull(c.iter().map(|&p| proj(p)).collect());
        polys_overlap(&h, pyr)
    })
}

/// Screen-space error in pixels of a tile of geometric error `ge` seen from `eye`.
pub fn screen_space_error(ge: f64, b: &Obb, eye: DVec3, k: &Intrinsics) -> f64 {
    ge * k.focal_px() / b.distance(eye).max(1e-6)
}

/// Hierarchical culling with REPLACE refinement: from the roots, subtrees whose box fails `test`
/// are skipped; a visible tile is refined into its children while its screen-space error exceeds
/// `max_sse` or it has no content; every visible tile reached and not refined that has content
/// is returned (indices in visiting order).
pub fn cull_hierarchical(
    cat: &TileCatalog,
    pose: &ViewPose,
    k: &Intrinsics,
    max_sse: f64,
    test: VisTest,
    out: &mut Vec<usize>,
) {
    let f = Frustum::new(pose, k);
    let mut stack: Vec<usize> = cat.roots.iter().rev().copied().collect();
    while let Some(i) = stack.pop() {
        let t = &cat.tiles[i];
        if !test.visible(&f, &t.bbox) {
            continue;
        }
        let refine = !t.children.is_empty()
            && (!t.has_content
                || screen_space_error(t.geometric_error, &t.bbox, pose.pos, k) > max_sse);
        if refine {
            stack.extend(t.children.iter().rev().copied());
        } else if t.has_content {
            out.push(i);
        }
    }
}
