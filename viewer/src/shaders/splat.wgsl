// Instanced 3DGS splats for WebGL2-class devices: attributes from paged texture arrays
// (textureLoad only, no storage buffers), one 4-vertex strip per sorted splat, premultiplied alpha.
// The projection follows splat2tiles' CPU reference (crates/render/src/raster.rs) step by step.

struct Frame {
    // width, height, unused, unused (pixels)
    viewport: vec4<f32>,
    // fx, fy, cx, cy (pixels; principal point in continuous image coordinates)
    focal: vec4<f32>,
    // Jacobian clamp of x/z (lo, hi) and y/z (lo, hi): 1.3x the half field of view
    lim: vec4<f32>,
    // near z, footprint sigma, largest footprint (pixels) before a splat is dropped, unused
    params: vec4<f32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;
// x, y, z (tile-local), opacity
@group(0) @binding(1) var t_pos: texture_2d_array<f32>;
// block 0: unit quaternion x, y, z, w; block 1: scale x, y, z, tile row
@group(0) @binding(2) var t_shape: texture_2d_array<f32>;
// block j: SH floats 4j..4j+3 (coefficient-major RGB, DC first)
@group(0) @binding(3) var t_sh: texture_2d_array<f32>;
// per tile, 5 texels: camera-from-tile rows 0..2 (xyz linear, w translation), camera centre in
// the tile frame + fade alpha, SH degree
@group(0) @binding(4) var t_tiles: texture_2d<f32>;

const PAGE_ROW: u32 = 128u;
const PAGE_BITS: u32 = 14u;
const TILES_PER_ROW: i32 = 256;
const TILE_TEXELS: i32 = 5;
const ALPHA_MIN: f32 = 0.003921569; // 1/255
const ALPHA_MAX: f32 = 0.99;
const LOW_PASS: f32 = 0.3;

const SH_C0: f32 = 0.2820948;
const SH_C1: f32 = 0.48860252;
const SH_C2_0: f32 = 1.0925485;
const SH_C2_1: f32 = -1.0925485;
const SH_C2_2: f32 = 0.31539157;
const SH_C2_3: f32 = -1.0925485;
const SH_C2_4: f32 = 0.5462742;
const SH_C3_0: f32 = -0.5900436;
const SH_C3_1: f32 = 2.8906114;
const SH_C3_2: f32 = -0.4570458;
const SH_C3_3: f32 = 0.37317633;
const SH_C3_4: f32 = -0.4570458;
const SH_C3_5: f32 = 1.4453057;
const SH_C3_6: f32 = -0.5900436;

struct VOut {
    @builtin(position) pos: vec4<f32>,
    // offset of this corner from the splat centre, pixels
    @location(0) d: vec2<f32>,
    @location(1) @interpolate(flat) conic: vec3<f32>,
    // colour (not premultiplied) and opacity
    @location(2) @interpolate(flat) color: vec4<f32>,
};

fn culled() -> VOut {
    var o: VOut;
    // Outside the clip volume (z > w): the whole strip is dropped.
    o.pos = vec4<f32>(0.0, 0.0, 2.0, 1.0);
    o.d = vec2<f32>(0.0, 0.0);
    o.conic = vec3<f32>(0.0, 0.0, 0.0);
    o.color = vec4<f32>(0.0, 0.0, 0.0, 0.0);
    return o;
}

fn sh_texel(x: i32, y: i32, page: i32, j: i32) -> vec4<f32> {
    return textureLoad(t_sh, vec2<i32>(x + j * i32(PAGE_ROW), y), page, 0);
}

fn sh_color(x: i32, y: i32, page: i32, deg: i32, d: vec3<f32>) -> vec3<f32> {
    let t0 = sh_texel(x, y, page, 0);
    var c = SH_C0 * t0.xyz;
    if (deg >= 1) {
        let t1 = sh_texel(x, y, page, 1);
        let t2 = sh_texel(x, y, page, 2);
        let k1 = vec3<f32>(t0.w, t1.xy);
        let k2 = vec3<f32>(t1.zw, t2.x);
        let k3 = t2.yzw;
        c += -SH_C1 * d.y * k1 + SH_C1 * d.z * k2 - SH_C1 * d.x * k3;
        if (deg >= 2) {
            let t3 = sh_texel(x, y, page, 3);
            let t4 = sh_texel(x, y, page, 4);
            let t5 = sh_texel(x, y, page, 5);
            let t6 = sh_texel(x, y, page, 6);
            let k4 = t3.xyz;
            let k5 = vec3<f32>(t3.w, t4.xy);
            let k6 = vec3<f32>(t4.zw, t5.x);
            let k7 = t5.yzw;
            let k8 = t6.xyz;
            let xx = d.x * d.x;
            let yy = d.y * d.y;
            let zz = d.z * d.z;
            let xy = d.x * d.y;
            let yz = d.y * d.z;
            let xz = d.x * d.z;
            c += SH_C2_0 * xy * k4 + SH_C2_1 * yz * k5 + SH_C2_2 * (2.0 * zz - xx - yy) * k6
                + SH_C2_3 * xz * k7 + SH_C2_4 * (xx - yy) * k8;
            if (deg >= 3) {
                let t7 = sh_texel(x, y, page, 7);
                let t8 = sh_texel(x, y, page, 8);
                let t9 = sh_texel(x, y, page, 9);
                let t10 = sh_texel(x, y, page, 10);
                let t11 = sh_texel(x, y, page, 11);
                let k9 = vec3<f32>(t6.w, t7.xy);
                let k10 = vec3<f32>(t7.zw, t8.x);
                let k11 = t8.yzw;
                let k12 = t9.xyz;
                let k13 = vec3<f32>(t9.w, t10.xy);
                let k14 = vec3<f32>(t10.zw, t11.x);
                let k15 = t11.yzw;
                c += SH_C3_0 * d.y * (3.0 * xx - yy) * k9 + SH_C3_1 * xy * d.z * k10
                    + SH_C3_2 * d.y * (4.0 * zz - xx - yy) * k11
                    + SH_C3_3 * d.z * (2.0 * zz - 3.0 * xx - 3.0 * yy) * k12
                    + SH_C3_4 * d.x * (4.0 * zz - xx - yy) * k13
                    + SH_C3_5 * d.z * (xx - yy) * k14 + SH_C3_6 * d.x * (xx - 3.0 * yy) * k15;
            }
        }
    }
    return max(c + vec3<f32>(0.5, 0.5, 0.5), vec3<f32>(0.0, 0.0, 0.0));
}

@vertex
fn vs_main(@builtin(vertex_index) vi: u32, @location(0) slot: u32) -> VOut {
    let page = i32(slot >> PAGE_BITS);
    let local = slot & ((1u << PAGE_BITS) - 1u);
    let sx = i32(local % PAGE_ROW);
    let sy = i32(local / PAGE_ROW);
    let p4 = textureLoad(t_pos, vec2<i32>(sx, sy), page, 0);
    let q = textureLoad(t_shape, vec2<i32>(sx, sy), page, 0);
    let s4 = textureLoad(t_shape, vec2<i32>(sx + i32(PAGE_ROW), sy), page, 0);
    let tile = i32(s4.w);
    let tx = (tile % TILES_PER_ROW) * TILE_TEXELS;
    let ty = tile / TILES_PER_ROW;
    let m0 = textureLoad(t_tiles, vec2<i32>(tx, ty), 0);
    let m1 = textureLoad(t_tiles, vec2<i32>(tx + 1, ty), 0);
    let m2 = textureLoad(t_tiles, vec2<i32>(tx + 2, ty), 0);
    let cl = textureLoad(t_tiles, vec2<i32>(tx + 3, ty), 0);
    let misc = textureLoad(t_tiles, vec2<i32>(tx + 4, ty), 0);

    let opacity = p4.w * cl.w;
    if (!(opacity >= ALPHA_MIN)) {
        return culled();
    }
    let p = p4.xyz;
    let pv = vec3<f32>(dot(m0.xyz, p) + m0.w, dot(m1.xyz, p) + m1.w, dot(m2.xyz, p) + m2.w);
    let z = pv.z;
    if (!(z > frame.params.x)) {
        return culled();
    }
    let fx = frame.focal.x;
    let fy = frame.focal.y;
    let txtz = clamp(pv.x / z, frame.lim.x, frame.lim.y);
    let tytz = clamp(pv.y / z, frame.lim.z, frame.lim.w);
    let j0 = vec3<f32>(fx / z, 0.0, -fx * txtz / z);
    let j1 = vec3<f32>(0.0, fy / z, -fy * tytz / z);

    // Rotation of the (unit, normalised on upload) quaternion, columns as the reference's.
    let n2 = dot(q, q);
    let s = 2.0 / n2;
    let xx = q.x * q.x * s;
    let yy = q.y * q.y * s;
    let zz = q.z * q.z * s;
    let xy = q.x * q.y * s;
    let xz = q.x * q.z * s;
    let yz = q.y * q.z * s;
    let wx = q.w * q.x * s;
    let wy = q.w * q.y * s;
    let wz = q.w * q.z * s;
    let r0 = vec3<f32>(1.0 - yy - zz, xy + wz, xz - wy);
    let r1 = vec3<f32>(xy - wz, 1.0 - xx - zz, yz + wx);
    let r2 = vec3<f32>(xz + wy, yz - wx, 1.0 - xx - yy);
    // W (camera-from-tile linear part) times R's columns, scaled: T = W R S.
    let w_r0 = vec3<f32>(dot(m0.xyz, r0), dot(m1.xyz, r0), dot(m2.xyz, r0));
    let w_r1 = vec3<f32>(dot(m0.xyz, r1), dot(m1.xyz, r1), dot(m2.xyz, r1));
    let w_r2 = vec3<f32>(dot(m0.xyz, r2), dot(m1.xyz, r2), dot(m2.xyz, r2));
    let fmax = max(fx, fy);
    // Footprint bound before any square: drop splats too large for f32 (and for the screen).
    let ext = max(max(length(w_r0) * abs(s4.x), length(w_r1) * abs(s4.y)), length(w_r2) * abs(s4.z))
        * fmax * 3.0 / z;
    if (!(ext < frame.params.z)) {
        return culled();
    }
    let c0 = w_r0 * s4.x;
    let c1 = w_r1 * s4.y;
    let c2 = w_r2 * s4.z;
    let g0 = vec3<f32>(dot(j0, c0), dot(j0, c1), dot(j0, c2));
    let g1 = vec3<f32>(dot(j1, c0), dot(j1, c1), dot(j1, c2));
    let a0 = dot(g0, g0);
    let cc0 = dot(g1, g1);
    let b = dot(g0, g1);
    let a = a0 + LOW_PASS;
    let c = cc0 + LOW_PASS;
    let gx = cross(g0, g1);
    let det = dot(gx, gx) + LOW_PASS * (a0 + cc0) + LOW_PASS * LOW_PASS;
    let conic = vec3<f32>(c / det, -b / det, a / det);
    let mid = 0.5 * (a + c);
    let lambda = mid + sqrt(max(0.1, mid * mid - det));
    let radius = ceil(frame.params.y * sqrt(lambda));
    // Centre in framebuffer coordinates (pixel i's centre at i + 0.5).
    let u = fx * pv.x / z + frame.focal.z;
    let v = fy * pv.y / z + frame.focal.w;
    let w = frame.viewport.x;
    let h = frame.viewport.y;
    if (u + radius < 0.0 || u - radius > w || v + radius < 0.0 || v - radius > h) {
        return culled();
    }

    // SH direction: splat centre minus the camera centre, both in the tile frame.
    let dv = p - cl.xyz;
    let dl = length(dv);
    var dir = vec3<f32>(0.0, 0.0, 0.0);
    if (dl > 0.0) {
        dir = dv / dl;
    }
    let rgb = sh_color(sx, sy, page, i32(misc.x), dir);

    let corner = vec2<f32>(f32(vi & 1u) * 2.0 - 1.0, f32((vi >> 1u) & 1u) * 2.0 - 1.0);
    let off = corner * radius;
    let px = vec2<f32>(u, v) + off;
    var o: VOut;
    o.pos = vec4<f32>(px.x / w * 2.0 - 1.0, 1.0 - px.y / h * 2.0, 0.5, 1.0);
    o.d = off;
    o.conic = conic;
    o.color = vec4<f32>(rgb, opacity);
    return o;
}

@fragment
fn fs_main(i: VOut) -> @location(0) vec4<f32> {
    let d = i.d;
    let power = -0.5 * (i.conic.x * d.x * d.x + i.conic.z * d.y * d.y) - i.conic.y * d.x * d.y;
    if (power > 0.0) {
        discard;
    }
    let alpha = min(ALPHA_MAX, i.color.a * exp(power));
    if (alpha < ALPHA_MIN) {
        discard;
    }
    return vec4<f32>(i.color.rgb * alpha, alpha);
}
