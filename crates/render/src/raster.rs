//! The exact 3DGS forward pass (Kerbl et al. 2023) on the CPU: EWA projection, 16x16 tile binning,
//! depth sort and front-to-back compositing, following the reference CUDA rasterizer's rules.
//!
//! Per splat (f64 until the camera-space position and 2D covariance are formed):
//! 1. skip it when any value is NaN/Inf, or when its camera-space depth `z <= near` (0.2, as the
//!    reference's `in_frustum`);
//! 2. `Sigma = A R S S^T R^T A^T` (A = linear part of the instance's model matrix, R from the
//!    normalised quaternion, S = diag(scale)), `Sigma' = J W Sigma W^T J^T + 0.3 I` with the
//!    perspective Jacobian J evaluated at the centre whose `x/z`, `y/z` are clamped to 1.3 times
//!    the half field of view (the reference's guard for splats far off screen);
//! 3. radius `ceil(k sqrt(lambda_max))` with `k = 3` and `lambda_max = mid + sqrt(max(0.1,
//!    mid^2 - det))`; the splat is binned into every 16x16 tile its square `[centre +- radius]`
//!    touches (integer truncation as in the reference) and skipped when it touches none;
//! 4. colour = SH up to the degree asked, for the direction from the camera centre to the splat
//!    centre expressed in the splat's own frame, plus 0.5, negatives clamped to 0.
//!
//! Per pixel (f32, pixel centres at integer coordinates as in the reference): for the tile's
//! splats in ascending depth, `power = -0.5 d^T conic d`; skip when `power > 0`; `alpha =
//! min(0.99, opacity exp(power))`; skip when `alpha < 1/255`; stop (without adding this splat) when
//! `T (1 - alpha) < 1e-4`; else `C += alpha T c`, `T *= 1 - alpha`. Finally `C += T background`.

use glam::{DMat3, DMat4, DVec3};
use rayon::prelude::*;

use super::image::Image;
use splat2tiles_core::camera::Camera;
use splat2tiles_core::splat::{Splats, sh};

/// Side of a screen tile in pixels (the reference's BLOCK_X/BLOCK_Y).
pub const TILE: u32 = 16;
/// Near-plane depth: splats whose camera-space z is at most this are culled (reference value).
pub const NEAR_Z: f64 = 0.2;
/// Low-pass filter added to the diagonal of every 2D covariance, in pixels squared.
pub const LOW_PASS: f64 = 0.3;
/// Largest alpha a fragment may have.
pub const ALPHA_MAX: f32 = 0.99;
/// Fragments with a smaller alpha are skipped.
pub const ALPHA_MIN: f32 = 1.0 / 255.0;
/// Default early-termination threshold on transmittance.
pub const T_MIN: f32 = 1e-4;

/// How splats are ordered front to back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DepthSort {
    /// Exact order by camera-space depth (ties broken by what the splats draw, then input
    /// order): the reference.
    Exact,
    /// Depth quantised into this many equal buckets between the nearest and farthest visible
    /// splat, input order inside a bucket (what counting-sort web viewers do).
    Buckets(u32),
}

/// Knobs of the renderer. [`RenderOptions::default`] is the exact reference.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Colour behind everything (default black).
    pub background: [f32; 3],
    /// Highest SH degree evaluated (default 3: everything the scene has).
    pub max_sh_degree: u8,
    /// Footprint radius in standard deviations of the larger 2D axis (default 3).
    pub footprint_sigma: f64,
    /// Depth ordering (default exact).
    pub sort: DepthSort,
    /// Early termination: a pixel stops once its transmittance would fall below this (1e-4).
    pub min_transmittance: f32,
    /// Near-plane depth (default [`NEAR_Z`]).
    pub near: f64,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            background: [0.0; 3],
            max_sh_degree: 3,
            footprint_sigma: 3.0,
            sort: DepthSort::Exact,
            min_transmittance: T_MIN,
            near: NEAR_Z,
        }
    }
}

/// Counters and stage timings from one render.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RenderStats {
    /// Splats over all instances.
    pub splats: usize,
    /// Splats skipped for holding NaN/Inf (or belonging to a non-finite model matrix).
    pub non_finite: usize,
    /// Splats that reached at least one tile.
    pub visible: usize,
    /// (splat, tile) pairs after binning.
    pub tile_pairs: usize,
    /// Wall time of projection (culling, covariance, SH), ms.
    pub project_ms: f64,
    /// Wall time of the depth sort, ms.
    pub sort_ms: f64,
    /// Wall time of binning and compositing, ms.
    pub composite_ms: f64,
}

/// A splat after projection: what binning and compositing need.
#[derive(Debug, Clone, Copy)]
struct Projected {
    depth: f64,
    gid: u64,
    rect: [u32; 4],
    hot: Hot,
}

/// Per-fragment data, packed for the pixel loop.
#[derive(Debug, Clone, Copy)]
struct Hot {
    xy: [f32; 2],
    conic: [f32; 3],
    opacity: f32,
    color: [f32; 3],
    /// Below this `power`, `opacity * exp(power) < 1/255` for sure: skip without the exp.
    power_min: f32,
    /// Conservative pixel-centre box `[x0, y0, x1, y1]` outside which `alpha < 1/255`.
    abox: [f32; 4],
}

/// Per-instance constants for projection.
struct InstanceFrame {
    /// Camera-from-model linear part (W A).
    m: DMat3,
    /// Camera-from-model translation (W (t - c)), formed relative to the camera centre.
    b: DVec3,
    /// Camera centre in the model frame (for SH directions), when the model is invertible.
    c_local: Option<DVec3>,
    /// Camera-to-world rotation: for a singular model the SH direction falls back to the world
    /// direction (camera-space centre rotated back to world).
    rot_world_from_cam: DMat3,
}

/// Renders `instances` (each a splat set and the model matrix taking its frame to world) seen by
/// `camera`.
pub fn render(instances: &[(&Splats, DMat4)], camera: &Camera, opts: &RenderOptions) -> Image {
    render_with_stats(instances, camera, opts).0
}

/// One splat set whose frame is the world frame.
pub fn render_splats(splats: &Splats, camera: &Camera, opts: &RenderOptions) -> Image {
    render(&[(splats, DMat4::IDENTITY)], camera, opts)
}

/// [`render`] plus counters.
pub fn render_with_stats(
    instances: &[(&Splats, DMat4)],
    camera: &Camera,
    opts: &RenderOptions,
) -> (Image, RenderStats) {
    let (w, h) = (camera.width, camera.height);
    let mut stats = RenderStats::default();
    if w == 0 || h == 0 {
        return (Image::filled(w, h, opts.background), stats);
    }
    let grid = [w.div_ceil(TILE), h.div_ceil(TILE)];

    // 1. Project every splat of every instance (order-preserving parallel collect).
    let clock = std::time::Instant::now();
    let mut projected: Vec<Projected> = Vec::new();
    let mut gid_base = 0u64;
    for &(splats, model) in instances {
        splats.check_lengths();
        let n = splats.len();
        stats.splats += n;
        let Some(frame) = instance_frame(model, camera) else {
            stats.non_finite += n;
            gid_base += n as u64;
            continue;
        };
        let part: Vec<Option<Projected>> = (0..n)
            .into_par_iter()
            .map(|i| project_one(splats, i, &frame, camera, opts, grid, gid_base + i as u64))
            .collect();
        stats.non_finite += (0..n).filter(|&i| !splats.is_finite(i)).count();
        projected.extend(part.into_iter().flatten());
        gid_base += n as u64;
    }
    stats.visible = projected.len();
    stats.project_ms = clock.elapsed().as_secs_f64() * 1e3;

    // 2. Depth order, deterministic: keys are unique thanks to the global index.
    let clock = std::time::Instant::now();
    sort_front_to_back(&mut projected, opts.sort);
    stats.sort_ms = clock.elapsed().as_secs_f64() * 1e3;
    let clock = std::time::Instant::now();
    let rects: Vec<[u32; 4]> = projected.iter().map(|p| p.rect).collect();
    let hot: Vec<Hot> = projected.iter().map(|p| p.hot).collect();
    drop(projected);

    // 3. Per band of tile rows: bin, then composite its tiles in parallel.
    let bands: Vec<(Vec<f32>, usize)> = (0..grid[1])
        .into_par_iter()
        .map(|ty| render_band(ty, grid, w, h, &rects, &hot, opts))
        .collect();
    let mut data = Vec::with_capacity(w as usize * h as usize * 3);
    for (band, pairs) in bands {
        data.extend_from_slice(&band);
        stats.tile_pairs += pairs;
    }
    stats.composite_ms = clock.elapsed().as_secs_f64() * 1e3;
    (
        Image {
            width: w,
            height: h,
            data,
        },
        stats,
    )
}

fn instance_frame(model: DMat4, camera: &Camera) -> Option<InstanceFrame> {
    if !model.is_finite() {
        return None;
    }
    let a = DMat3::from_mat4(model);
    let t = model.w_axis.truncate();
    let c = camera.center();
    let cam_from_world = camera.rotation().transpose();
    let det = a.determinant();
    let c_local = (det.is_finite() && det.abs() > 1e-300)
        .then(|| a.inverse() * (c - t))
        .filter(|v| v.is_finite());
    Some(InstanceFrame {
        m: cam_from_world * a,
        b: cam_from_world * (t - c),
        c_local,
        rot_world_from_cam: camera.rotation(),
    })
}

/// Rotation matrix of a quaternion `[x, y, z, w]`, normalised in f64 (zero/non-finite: identity).
fn quat_matrix(q: [f32; 4]) -> DMat3 {
    let [x, y, z, w] = q.map(|v| v as f64);
    let n2 = x * x + y * y + z * z + w * w;
    if !(n2.is_finite() && n2 > 0.0) {
        return DMat3::IDENTITY;
    }
    let s = 2.0 / n2;
    let (xx, yy, zz) = (x * x * s, y * y * s, z * z * s);
    let (xy, xz, yz) = (x * y * s, x * z * s, y * z * s);
    let (wx, wy, wz) = (w * x * s, w * y * s, w * z * s);
    DMat3::from_cols(
        DVec3::new(1.0 - yy - zz, xy + wz, xz - wy),
        DVec3::new(xy - wz, 1.0 - xx - zz, yz + wx),
        DVec3::new(xz + wy, yz - wx, 1.0 - xx - yy),
    )
}

fn project_one(
    splats: &Splats,
    i: usize,
    f: &InstanceFrame,
    cam: &Camera,
    opts: &RenderOptions,
    grid: [u32; 2],
    gid: u64,
) -> Option<Projected> {
    if !splats.is_finite(i) {
        return None;
    }
    let opacity = splats.opacities[i];
    // alpha = opacity * exp(power) <= opacity: below 1/255 it never shows (reference result).
    if opacity.is_nan() || opacity < ALPHA_MIN {
        return None;
    }
    let p = DVec3::from(splats.positions[i]);
    let pv = f.m * p + f.b;
    if pv.z.is_nan() || pv.z <= opts.near {
        return None;
    }
    let (fx, fy) = (cam.fx, cam.fy);
    let (wf, hf) = (cam.width as f64, cam.height as f64);
    // Jacobian at the centre clamped to 1.3x the half field of view (generalised to an
    // off-centre principal point: the frustum widened by 0.3 half-widths on each side).
    let ext_x = 0.3 * wf / (2.0 * fx);
    let ext_y = 0.3 * hf / (2.0 * fy);
    let txtz = (pv.x / pv.z).clamp(-cam.cx / fx - ext_x, (wf - cam.cx) / fx + ext_x);
    let tytz = (pv.y / pv.z).clamp(-cam.cy / fy - ext_y, (hf - cam.cy) / fy + ext_y);
    let z = pv.z;
    let j0 = DVec3::new(fx / z, 0.0, -fx * txtz / z);
    let j1 = DVec3::new(0.0, fy / z, -fy * tytz / z);
    // T = W A R S; rows of J T give Sigma' = (J T)(J T)^T without forming Sigma.
    let r = quat_matrix(splats.rotations[i]);
    let s = splats.scales[i].map(|v| v as f64);
    let t = f.m * r;
    let cols = [t.x_axis * s[0], t.y_axis * s[1], t.z_axis * s[2]];
    let g0 = DVec3::new(j0.dot(cols[0]), j0.dot(cols[1]), j0.dot(cols[2]));
    let g1 = DVec3::new(j1.dot(cols[0]), j1.dot(cols[1]), j1.dot(cols[2]));
    let a0 = g0.length_squared();
    let c0 = g1.length_squared();
    let b = g0.dot(g1);
    let a = a0 + LOW_PASS;
    let c = c0 + LOW_PASS;
    // det = a c - b^2, with the cancelling part as |g0 x g1|^2 (Lagrange), always > 0.
    let det = g0.cross(g1).length_squared() + LOW_PASS * (a0 + c0) + LOW_PASS * LOW_PASS;
    if !(det.is_finite() && det > 0.0 && a.is_finite() && c.is_finite() && b.is_finite()) {
        return None;
    }
    let conic = [c / det, -b / det, a / det];
    let mid = 0.5 * (a + c);
    let lambda = mid + (mid * mid - det).max(0.1).sqrt();
    let radius = (opts.footprint_sigma * lambda.sqrt()).ceil();
    // Pixel-centre coordinates: pixel i's centre is at i (reference `ndc2Pix`).
    let u = fx * pv.x / pv.z + cam.cx - 0.5;
    let v = fy * pv.y / pv.z + cam.cy - 0.5;
    if !(u.is_finite() && v.is_finite() && radius.is_finite()) {
        return None;
    }
    let tile = TILE as f64;
    let to_tile = |x: f64, n: u32| ((x / tile) as i64).clamp(0, n as i64) as u32;
    let rect = [
        to_tile(u - radius, grid[0]),
        to_tile(v - radius, grid[1]),
        to_tile(u + radius + tile - 1.0, grid[0]),
        to_tile(v + radius + tile - 1.0, grid[1]),
    ];
    if rect[0] >= rect[2] || rect[1] >= rect[3] {
        return None;
    }
    // View direction in the splat's frame: p_local - camera centre in the model frame.
    let dir = match f.c_local {
        Some(cl) => p - cl,
        None => f.rot_world_from_cam * pv,
    };
    let dir = dir.normalize_or_zero();
    let deg = splats.sh_degree.min(opts.max_sh_degree);
    let color = sh::eval_color(
        deg,
        splats.sh0[i],
        splats.rest_of(i),
        [dir.x as f32, dir.y as f32, dir.z as f32],
    );
    let conic32 = conic.map(|v| v as f32);
    // alpha >= 1/255 needs d^T conic d <= k2 = 2 ln(255 opacity); that ellipse's bounding box has
    // half-extents sqrt(k2 a), sqrt(k2 c). Widened so f32 rounding can never cut a fragment.
    let k2 = 2.0 * (opacity as f64 / ALPHA_MIN as f64).ln().max(0.0);
    let hx = (k2 * a).sqrt() * (1.0 + 1e-3) + 0.01;
    let hy = (k2 * c).sqrt() * (1.0 + 1e-3) + 0.01;
    let abox = [u - hx, v - hy, u + hx, v + hy].map(|e| e as f32);
    Some(Projected {
        depth: z,
        gid,
        rect,
        hot: Hot {
            xy: [u as f32, v as f32],
            conic: conic32,
            opacity,
            color,
            power_min: (ALPHA_MIN / opacity).ln() - 1e-3,
            abox,
        },
    })
}

fn sort_front_to_back(p: &mut [Projected], mode: DepthSort) {
    match mode {
        // Equal depths (splats at one position: duplicates, or a grid such as SPZ's) are put in
        // the order of what they draw, so that an image depends on the set of splats and not on
        // their order in the file (which the variants' storage order changes); the index last.
        DepthSort::Exact => p.par_sort_unstable_by(|a, b| {
            a.depth
                .total_cmp(&b.depth)
                .then_with(|| drawn_key(&a.hot).cmp(&drawn_key(&b.hot)))
                .then(a.gid.cmp(&b.gid))
        }),
        DepthSort::Buckets(n) => {
            let n = n.max(1) as f64;
            let lo = p.iter().map(|q| q.depth).fold(f64::INFINITY, f64::min);
            let hi = p.iter().map(|q| q.depth).fold(f64::NEG_INFINITY, f64::max);
            let scale = if hi > lo { n / (hi - lo) } else { 0.0 };
            let bucket = |d: f64| (((d - lo) * scale) as u64).min(n as u64 - 1);
            p.par_sort_unstable_by_key(|q| (bucket(q.depth), q.gid));
        }
    }
}

/// What a projected splat draws, as bits: two splats with equal keys composite alike in
/// either order.
fn drawn_key(h: &Hot) -> [u32; 9] {
    [
        h.opacity, h.color[0], h.color[1], h.color[2], h.conic[0], h.conic[1], h.conic[2], h.xy[0],
        h.xy[1],
    ]
    .map(f32::to_bits)
}

/// Bins the splats touching tile row `ty`, composites its tiles; returns the band's pixels
/// (rows `16 ty ..`, full width) and the number of (splat, tile) pairs.
fn render_band(
    ty: u32,
    grid: [u32; 2],
    w: u32,
    h: u32,
    rects: &[[u32; 4]],
    hot: &[Hot],
    opts: &RenderOptions,
) -> (Vec<f32>, usize) {
    let mut lists: Vec<Vec<u32>> = vec![Vec::new(); grid[0] as usize];
    let (ylo, yhi) = ((ty * TILE) as f32, (ty * TILE + TILE - 1) as f32);
    for (k, (r, g)) in rects.iter().zip(hot).enumerate() {
        // The reference's tile rectangle, narrowed to tiles where alpha can reach 1/255 (a
        // pure saving: the skipped (splat, tile) pairs contribute nothing).
        if r[1] <= ty && ty < r[3] && g.abox[1] <= yhi && g.abox[3] >= ylo {
            let t0 = ((g.abox[0] / TILE as f32).floor().max(0.0) as u32).max(r[0]);
            let t1 = (((g.abox[2] / TILE as f32).floor() + 1.0).max(0.0) as u32).min(r[2]);
            for list in lists.iter_mut().take(t1 as usize).skip(t0 as usize) {
                list.push(k as u32);
            }
        }
    }
    let pairs = lists.iter().map(Vec::len).sum();
    let y0 = ty * TILE;
    let rows = TILE.min(h - y0);
    let tiles: Vec<Vec<f32>> = lists
        .par_iter()
        .enumerate()
        .map(|(tx, list)| {
            let x0 = tx as u32 * TILE;
            let cols = TILE.min(w - x0);
            composite_tile(x0, y0, cols, rows, list, hot, opts)
        })
        .collect();
    let mut band = vec![0f32; (rows * w * 3) as usize];
    for (tx, tile) in tiles.iter().enumerate() {
        let x0 = tx * TILE as usize;
        let cols = TILE.min(w - x0 as u32) as usize;
        for r in 0..rows as usize {
            let dst = (r * w as usize + x0) * 3;
            band[dst..dst + cols * 3].copy_from_slice(&tile[r * cols * 3..(r + 1) * cols * 3]);
        }
    }
    (band, pairs)
}

/// Front-to-back compositing of one tile; returns `rows x cols` RGB values.
///
/// Splat-major: each fragment visits only the pixels of its alpha box, and every pixel sees its
/// fragments in list order, so the result is the per-pixel loop's to the bit.
fn composite_tile(
    x0: u32,
    y0: u32,
    cols: u32,
    rows: u32,
    list: &[u32],
    hot: &[Hot],
    opts: &RenderOptions,
) -> Vec<f32> {
    let n = (cols * rows) as usize;
    let t_min = opts.min_transmittance;
    let mut trans = vec![1.0f32; n];
    let mut acc = vec![[0f32; 3]; n];
    let mut done = vec![false; n];
    let mut alive = n;
    let (xmax, ymax) = ((x0 + cols - 1) as f32, (y0 + rows - 1) as f32);
    for &k in list {
        let g = &hot[k as usize];
        let xa = g.abox[0].ceil().max(x0 as f32);
        let xb = g.abox[2].floor().min(xmax);
        let ya = g.abox[1].ceil().max(y0 as f32);
        let yb = g.abox[3].floor().min(ymax);
        if !(xa <= xb && ya <= yb) {
            continue;
        }
        for py in ya as u32..=yb as u32 {
            let row = ((py - y0) * cols) as usize;
            let dy = g.xy[1] - py as f32;
            for px in xa as u32..=xb as u32 {
                let i = row + (px - x0) as usize;
                if done[i] {
                    continue;
                }
                let dx = g.xy[0] - px as f32;
                let power =
                    -0.5 * (g.conic[0] * dx * dx + g.conic[2] * dy * dy) - g.conic[1] * dx * dy;
                if power > 0.0 || power < g.power_min {
                    continue;
                }
                let alpha = (g.opacity * power.exp()).min(ALPHA_MAX);
                if alpha < ALPHA_MIN {
                    continue;
                }
                let t = trans[i];
                let test_t = t * (1.0 - alpha);
                if test_t < t_min {
                    done[i] = true;
                    alive -= 1;
                    continue;
                }
                for (a, col) in acc[i].iter_mut().zip(g.color) {
                    *a += col * alpha * t;
                }
                trans[i] = test_t;
            }
        }
        if alive == 0 {
            break;
        }
    }
    let bg = opts.background;
    let mut out = Vec::with_capacity(n * 3);
    for (c, t) in acc.iter().zip(&trans) {
        for ch in 0..3 {
            out.push(c[ch] + t * bg[ch]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use splat2tiles_core::splat::Splat;

    /// The reference's rules with no shortcuts: every pixel walks every sorted splat whose tile
    /// rectangle holds the pixel's tile, computing exp for each.
    fn naive(splats: &Splats, cam: &Camera, opts: &RenderOptions) -> Image {
        let grid = [cam.width.div_ceil(TILE), cam.height.div_ceil(TILE)];
        let frame = instance_frame(DMat4::IDENTITY, cam).unwrap();
        let mut p: Vec<Projected> = (0..splats.len())
            .filter_map(|i| project_one(splats, i, &frame, cam, opts, grid, i as u64))
            .collect();
        sort_front_to_back(&mut p, opts.sort);
        let mut img = Image::filled(cam.width, cam.height, [0.0; 3]);
        for py in 0..cam.height {
            for px in 0..cam.width {
                let (tx, ty) = (px / TILE, py / TILE);
                let mut t = 1.0f32;
                let mut c = [0f32; 3];
                for q in &p {
                    let r = q.rect;
                    if !(r[0] <= tx && tx < r[2] && r[1] <= ty && ty < r[3]) {
                        continue;
                    }
                    let g = &q.hot;
                    let (dx, dy) = (g.xy[0] - px as f32, g.xy[1] - py as f32);
                    let power =
                        -0.5 * (g.conic[0] * dx * dx + g.conic[2] * dy * dy) - g.conic[1] * dx * dy;
                    if power > 0.0 {
                        continue;
                    }
                    let alpha = (g.opacity * power.exp()).min(ALPHA_MAX);
                    if alpha < ALPHA_MIN {
                        continue;
                    }
                    let test_t = t * (1.0 - alpha);
                    if test_t < opts.min_transmittance {
                        break;
                    }
                    for (a, col) in c.iter_mut().zip(g.color) {
                        *a += col * alpha * t;
                    }
                    t = test_t;
                }
                let i = ((py * cam.width + px) * 3) as usize;
                for (ch, a) in c.iter().enumerate() {
                    img.data[i + ch] = a + t * opts.background[ch];
                }
            }
        }
        img
    }

    #[test]
    fn optimised_paths_equal_the_naive_reference_bit_for_bit() {
        let mut state = 12345u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut s = Splats::new(0);
        for k in 0..600 {
            // Opacities down to just above 1/255, anisotropic, some large, some tiny.
            let big = if k % 50 == 0 { 3.0 } else { 1.0 };
            s.push(
                Splat {
                    position: [4.0 * next() - 2.0, 3.0 * next() - 1.5, 2.0 + 4.0 * next()],
                    scale: [0.2 * next() * big, 0.05 * next(), 0.1 * next() * big]
                        .map(|v| v as f32),
                    rotation: [next() - 0.5, next() - 0.5, next() - 0.5, next() - 0.5]
                        .map(|v| v as f32),
                    opacity: if k % 7 == 0 {
                        0.004 + 0.002 * next() as f32
                    } else {
                        next() as f32
                    },
                    sh0: [next(), next(), next()].map(|v| (3.0 * v - 1.5) as f32),
                },
                &[],
            );
        }
        let cam = Camera::look_at(
            75,
            53,
            60.0,
            DVec3::new(0.0, 0.0, -1.0),
            DVec3::new(0.0, 0.0, 4.0),
            -DVec3::Y,
        );
        for opts in [
            RenderOptions::default(),
            RenderOptions {
                background: [0.3, 0.1, 0.7],
                min_transmittance: 0.05,
                ..Default::default()
            },
            RenderOptions {
                footprint_sigma: 2.0,
                sort: DepthSort::Buckets(16),
                ..Default::default()
            },
        ] {
            let fast = render_splats(&s, &cam, &opts);
            let slow = naive(&s, &cam, &opts);
            assert!(fast.data == slow.data, "{opts:?}");
            assert!(fast.data.iter().any(|&v| v > 0.0));
        }
    }

    #[test]
    fn splats_at_one_position_render_alike_in_any_order() {
        // Pairs of splats sharing a position (equal depths) with different colours and shapes:
        // the image must not depend on which of a pair comes first in the input.
        let mut s = Splats::new(0);
        for k in 0..40 {
            let p = [0.1 * (k % 8) as f64 - 0.35, 0.1 * (k / 8) as f64 - 0.2, 3.0];
            for (c, sc) in [([1.5f32, -0.5, 0.2], 0.06f32), ([-0.8, 1.2, 0.9], 0.03)] {
                s.push(
                    Splat {
                        position: p,
                        scale: [sc, 0.5 * sc, sc],
                        rotation: [0.0, 0.0, 0.0, 1.0],
                        opacity: 0.7,
                        sh0: c,
                    },
                    &[],
                );
            }
        }
        let swapped: Vec<usize> = (0..s.len()).map(|i| i ^ 1).collect();
        let t = s.select(&swapped);
        let cam = Camera::look_at(
            64,
            48,
            60.0,
            DVec3::ZERO,
            DVec3::new(0.0, 0.0, 3.0),
            -DVec3::Y,
        );
        let opts = RenderOptions::default();
        let a = render_splats(&s, &cam, &opts);
        assert!(a.data.iter().any(|&v| v > 0.0));
        assert!(a.data == render_splats(&t, &cam, &opts).data);
        assert!(a.data == naive(&t, &cam, &opts).data);
    }

    #[test]
    fn quat_matrix_is_rotation_and_sign_free() {
        let q = [0.3f32, -0.2, 0.5, 0.7];
        let m = quat_matrix(q);
        let n = quat_matrix(q.map(|v| -v));
        assert_eq!(m, n, "q and -q give bit-identical matrices");
        assert!((m.transpose() * m).abs_diff_eq(DMat3::IDENTITY, 1e-12));
        assert!((m.determinant() - 1.0).abs() < 1e-12);
        // 90 degrees about z maps x to y.
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let rz = quat_matrix([0.0, 0.0, h, h]);
        assert!((rz * DVec3::X - DVec3::Y).length() < 1e-7);
        assert_eq!(quat_matrix([0.0; 4]), DMat3::IDENTITY);
    }
}
