// A real head trace (data/navigation-traces/, EyeNavGS, Ding et al. 2025, arXiv:2506.02380,
// Apache-2.0) placed in a generated city as a street-level walk: the trace's horizontal positions
// scaled and centred on a point of the city, eye height above the city's ground, head turns kept.
//
// Placement (the trace is Unity: y up, left-handed, camera looking along +z of its quaternion):
//   city x = cx + scale * (x - x_mid)      city y = cy + scale * (z - z_mid)
//   city z = ground + eye + (y - y_first)  (head bob and crouch unscaled)
// where (x_mid, z_mid) is the centre of the trace's horizontal bounding box. Directions map the
// same way, (x, y, z)_unity -> (x, z, y)_city: a mirror, which turns Unity's left-handed frame into
// the city's right-handed z-up frame, so a left turn in the recording is a left turn in the city.
import fs from 'node:fs';

/** Largest trace file read (the shared traces are under 100 kB). */
const MAX_TRACE_BYTES = 16 << 20;

/** Reads `t_s,x,y,z,qx,qy,qz,qw` rows; errors name the file and line. */
export function readTrace(file) {
  const size = fs.statSync(file).size;
  if (size > MAX_TRACE_BYTES) throw new Error(`${file}: ${size} bytes, more than a trace (${MAX_TRACE_BYTES})`);
  const lines = fs.readFileSync(file, 'utf8').split(/\r?\n/);
  if (lines[0].trim() !== 't_s,x,y,z,qx,qy,qz,qw') {
    throw new Error(`${file}:1: expected the header t_s,x,y,z,qx,qy,qz,qw, got '${lines[0]}'`);
  }
  const rows = [];
  for (let i = 1; i < lines.length; i++) {
    if (!lines[i].trim()) continue;
    const v = lines[i].split(',').map(Number);
    if (v.length !== 8 || !v.every(Number.isFinite)) {
      throw new Error(`${file}:${i + 1}: expected 8 finite numbers, got '${lines[i]}'`);
    }
    rows.push({ t: v[0], p: [v[1], v[2], v[3]], q: [v[4], v[5], v[6], v[7]] });
  }
  if (rows.length < 2) throw new Error(`${file}: fewer than 2 samples`);
  return rows;
}

/** `v` rotated by unit quaternion `q` (x, y, z, w). */
function rotate([qx, qy, qz, qw], [vx, vy, vz]) {
  // t = 2 q_vec x v; v' = v + w t + q_vec x t
  const tx = 2 * (qy * vz - qz * vy);
  const ty = 2 * (qz * vx - qx * vz);
  const tz = 2 * (qx * vy - qy * vx);
  return [
    vx + qw * tx + (qy * tz - qz * ty),
    vy + qw * ty + (qz * tx - qx * tz),
    vz + qw * tz + (qx * ty - qy * tx),
  ];
}

/** Unity (x, y, z) -> city (x, z, y). */
const toCity = ([x, y, z]) => [x, z, y];

/**
 * City-frame poses `{ t, eye, target, up, spec }` of `rows` (see the top comment), `spec` being
 * the viewer's `look-at:` camera text; `place` = `{ cx, cy, ground, eye, scale, transform }`,
 * where `transform` (the root matrix of a georeferenced city, or null) takes the spec to the
 * world while `eye`, `target` and `up` stay in the city's frame.
 */
export function placeTrace(rows, { cx, cy, ground, eye, scale, transform = null }) {
  let [x0, x1, z0, z1] = [Infinity, -Infinity, Infinity, -Infinity];
  for (const r of rows) {
    x0 = Math.min(x0, r.p[0]);
    x1 = Math.max(x1, r.p[0]);
    z0 = Math.min(z0, r.p[2]);
    z1 = Math.max(z1, r.p[2]);
  }
  const [xm, zm, y0] = [(x0 + x1) / 2, (z0 + z1) / 2, rows[0].p[1]];
  const f = (v) => v.toFixed(4);
  return rows.map((r) => {
    const n = Math.hypot(...r.q) || 1;
    const q = r.q.map((c) => c / n);
    const e = [cx + scale * (r.p[0] - xm), cy + scale * (r.p[2] - zm), ground + eye + (r.p[1] - y0)];
    const fwd = toCity(rotate(q, [0, 0, 1]));
    const up = toCity(rotate(q, [0, 1, 0]));
    const target = e.map((c, i) => c + fwd[i]);
    const [we, wt, wu] = transform
      ? [apply(transform, e), apply(transform, target), apply(transform, up, 0)]
      : [e, target, up];
    return {
      t: r.t - rows[0].t,
      eye: e,
      target,
      up,
      spec: `look-at:${we.map(f)}:${wt.map(f)}:${wu.map(f)}`,
    };
  });
}

/** Horizontal path length of placed poses (metres in the city). */
export function pathLength(poses) {
  let d = 0;
  for (let i = 1; i < poses.length; i++) {
    d += Math.hypot(poses[i].eye[0] - poses[i - 1].eye[0], poses[i].eye[1] - poses[i - 1].eye[1]);
  }
  return d;
}

/** WGS84 semi-major axis (m) and first eccentricity squared. */
const WGS84_A = 6378137.0;
const WGS84_E2 = 6.69437999014e-3;

/** ECEF (m) of geodetic `lon`, `lat` (radians) and ellipsoidal `h` (m). */
function ecefOf(lon, lat, h) {
  const n = WGS84_A / Math.sqrt(1 - WGS84_E2 * Math.sin(lat) ** 2);
  return [
    (n + h) * Math.cos(lat) * Math.cos(lon),
    (n + h) * Math.cos(lat) * Math.sin(lon),
    (n * (1 - WGS84_E2) + h) * Math.sin(lat),
  ];
}

/** `m` (column-major 4x4) applied to point `p`, or to direction `p` when `w` is 0. */
function apply(m, [x, y, z], w = 1) {
  return [0, 1, 2].map((r) => m[r] * x + m[4 + r] * y + m[8 + r] * z + m[12 + r] * w);
}

/** The local frame's coordinates of world point `p`, for a rigid (rotation + translation) `m`. */
function toLocal(m, p) {
  const d = [0, 1, 2].map((r) => p[r] - m[12 + r]);
  // Rigid: the inverse rotation is the transpose.
  return [0, 1, 2].map((c) => m[4 * c] * d[0] + m[4 * c + 1] * d[1] + m[4 * c + 2] * d[2]);
}

/**
 * The city's centre and ground in its tileset's root frame (z up): `{ cx, cy, ground, transform }`.
 * A local city: the root box (`boundingVolume.box`, centre + three half axes), ground = its lowest
 * z, `transform` null. A georeferenced city (root `transform` onto the Earth, a `region` or a box):
 * the same in the root's local east-north-up frame, with `transform` the root matrix that takes
 * the placed poses to the world (ECEF) for the viewer's `look-at:` specs.
 */
export function cityFrame(tileset) {
  const root = tileset?.root;
  const bv = root?.boundingVolume ?? {};
  const id = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
  const t = root?.transform;
  if (t !== undefined && !(Array.isArray(t) && t.length === 16 && t.every(Number.isFinite))) {
    throw new Error('tileset.json: the root transform is not 16 finite numbers');
  }
  const transform = t && !t.every((v, i) => v === id[i]) ? t : null;
  const finite = (a, n) => Array.isArray(a) && a.length === n && a.every(Number.isFinite);
  if (finite(bv.box, 12)) {
    const box = bv.box;
    const dz = Math.abs(box[5]) + Math.abs(box[8]) + Math.abs(box[11]);
    return { cx: box[0], cy: box[1], ground: box[2] - dz, transform };
  }
  if (finite(bv.region, 6) && transform) {
    // Region: west, south, east, north (radians), min and max height (m), in world coordinates.
    const [w, s, e, n, h0] = bv.region;
    const c = toLocal(transform, ecefOf((w + e) / 2, (s + n) / 2, h0));
    return { cx: c[0], cy: c[1], ground: c[2], transform };
  }
  throw new Error(
    'tileset.json: the root has neither a boundingVolume.box nor a region with a root transform',
  );
}
