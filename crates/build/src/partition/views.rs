//! The view distribution of the partition cost: camera poses (from tuning-split navigation traces
//! or training cameras) turned into the basic cuboids each view needs (frustum vs cell, exact SAT).
//!
//! Traces only come through [`splat2tiles_stream::split::TuningSet`], so no test trace can shape a
//! partition that the evaluation later streams.

use super::cost::View;
use super::grid::Grid;
use glam::DVec3;
use splat2tiles_stream::geom::{Frustum, Intrinsics, Obb, ViewPose};
use splat2tiles_stream::split::TuningSet;
use splat2tiles_stream::trace::Trace;
use splat2tiles_stream::visibility::{exact_test, planes_test};

/// Where the grid lies in the tileset frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridBox {
    /// Minimum corner.
    pub lo: DVec3,
    /// Maximum corner.
    pub hi: DVec3,
}

impl GridBox {
    /// World box of cell `c` of `grid`.
    pub fn cell(&self, grid: &Grid, c: [u32; 3]) -> Obb {
        let size = (self.hi - self.lo) / DVec3::from(grid.dims.map(|d| d as f64));
        let lo = self.lo + DVec3::from(c.map(|v| v as f64)) * size;
        Obb::aabb(lo, lo + size)
    }
}

/// The cells of `grid` (placed at `gb`) that a camera at `pose` with `k` sees: every cell whose box
/// meets the frustum (near to `k.far`). `k.far` is the distance up to which the view needs full
/// detail.
pub fn needed_cells(grid: &Grid, gb: &GridBox, pose: &ViewPose, k: &Intrinsics) -> Vec<u32> {
    let f = Frustum::new(pose, k);
    let world_corners: Vec<DVec3> = f
        .camera_corners()
        .iter()
        .map(|c| f.apex + f.axes[0] * c.x + f.axes[1] * c.y + f.axes[2] * c.z)
        .collect();
    let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    for c in &world_corners {
        lo = lo.min(*c);
        hi = hi.max(*c);
    }
    // Cell range of the frustum's bounding box, clamped to the grid.
    let size = (gb.hi - gb.lo) / DVec3::from(grid.dims.map(|d| d as f64));
    let range = |a: usize| -> Option<(u32, u32)> {
        let n = grid.dims[a] as f64;
        let s = size[a].max(f64::MIN_POSITIVE);
        let a0 = ((lo[a] - gb.lo[a]) / s).floor().max(0.0);
        let a1 = ((hi[a] - gb.lo[a]) / s).floor().min(n - 1.0);
        (a0 <= a1 && a0.is_finite() && a1.is_finite()).then_some((a0 as u32, a1 as u32))
    };
    let (Some(rx), Some(ry), Some(rz)) = (range(0), range(1), range(2)) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for z in rz.0..=rz.1 {
        for y in ry.0..=ry.1 {
            for x in rx.0..=rx.1 {
                let b = gb.cell(grid, [x, y, z]);
                if planes_test(&f, &b) && exact_test(&f, &b) {
                    out.push(grid.index([x, y, z]) as u32);
                }
            }
        }
    }
    out
}

/// Equally likely views from poses (SGSS used the training cameras this way).
pub fn views_of_poses(grid: &Grid, gb: &GridBox, poses: &[ViewPose], k: &Intrinsics) -> Vec<View> {
    poses
        .iter()
        .map(|p| View {
            weight: 1.0,
            cells: needed_cells(grid, gb, p, k),
        })
        .collect()
}

/// Poses of `traces` sampled every `every_s` seconds (the first pose of each trace included).
pub fn sample_poses(traces: &[Trace], every_s: f64) -> Vec<ViewPose> {
    let mut out = Vec::new();
    for t in traces {
        let mut next = f64::MIN;
        for p in &t.poses {
            if p.t >= next {
                out.push(*p);
                next = p.t + every_s.max(0.0);
            }
        }
    }
    out
}

/// `k` with a trace's `fov_y_deg` / `aspect` headers applied (clamped to sane ranges).
pub fn trace_intrinsics(t: &Trace, k: &Intrinsics) -> Intrinsics {
    let mut kt = *k;
    if let Some(f) = t.header("fov_y_deg").and_then(|s| s.parse::<f64>().ok()) {
        kt.fov_y_deg = f.clamp(1.0, 179.0);
    }
    if let Some(a) = t.header("aspect").and_then(|s| s.parse::<f64>().ok()) {
        kt.aspect = a.clamp(0.05, 20.0);
    }
    kt
}

/// The views of a tuning set's train and val traces, sampled every `every_s` seconds; each
/// trace's intrinsics come from its `fov_y_deg` / `aspect` headers when present.
pub fn views_of_tuning_set(
    set: &TuningSet,
    grid: &Grid,
    gb: &GridBox,
    every_s: f64,
    k: &Intrinsics,
) -> Vec<View> {
    let mut out = Vec::new();
    for t in set.train().iter().chain(set.val()) {
        let kt = trace_intrinsics(t, k);
        let poses = sample_poses(std::slice::from_ref(t), every_s);
        out.extend(views_of_poses(grid, gb, &poses, &kt));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_camera_sees_the_cells_in_front_of_it_up_to_its_range() {
        // 8 x 8 x 1 cells of 10 m; camera at the west edge looking east at mid height.
        let g = Grid::new([8, 8, 1], vec![1; 64]).unwrap();
        let gb = GridBox {
            lo: DVec3::ZERO,
            hi: DVec3::new(80.0, 80.0, 10.0),
        };
        let pose = ViewPose::looking_at(
            0.0,
            DVec3::new(-1.0, 40.0, 5.0),
            DVec3::new(10.0, 40.0, 5.0),
        );
        let k = Intrinsics {
            far: 25.0,
            ..Intrinsics::default()
        };
        let cells = needed_cells(&g, &gb, &pose, &k);
        let xs: Vec<u32> = cells.iter().map(|&i| g.coords(i as usize)[0]).collect();
        assert!(!cells.is_empty());
        assert!(
            xs.iter().all(|&x| x <= 2),
            "range 25 m from x = -1 reaches x < 24: {xs:?}"
        );
        assert!(cells.contains(&(g.index([0, 4, 0]) as u32)));
        assert!(cells.contains(&(g.index([2, 3, 0]) as u32)));
        // Looking away sees nothing.
        let back = ViewPose::looking_at(
            0.0,
            DVec3::new(-1.0, 40.0, 5.0),
            DVec3::new(-10.0, 40.0, 5.0),
        );
        assert!(needed_cells(&g, &gb, &back, &k).is_empty());
    }

    #[test]
    fn sampling_keeps_one_pose_per_interval() {
        let poses: Vec<ViewPose> = (0..25)
            .map(|i| ViewPose {
                t: i as f64 / 12.0,
                pos: DVec3::ZERO,
                yaw: 0.0,
                pitch: 0.0,
            })
            .collect();
        let t = Trace {
            headers: vec![],
            poses,
        };
        assert_eq!(sample_poses(std::slice::from_ref(&t), 1.0).len(), 3);
        assert_eq!(sample_poses(&[t], 0.0).len(), 25);
    }
}
