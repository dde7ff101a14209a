//! Trainer PLY reader: our own header parser (all PLY scalar types, list properties in other
//! elements, comments), then a bulk decode of the vertex records by a name -> (offset, type) table.
//!
//! Binary bodies are decoded in parallel chunks of fixed-size records, with a dedicated path for
//! the usual all-float little-endian layout; ascii bodies are parsed line by line (one element
//! instance per line). Every size is checked against the input before anything is allocated.

use rayon::prelude::*;

use super::error::{Ctx, ReadError, ReadErrorKind};
use super::ply_header::{Element, Header, PropKind, Scalar, holdable, parse_header};
use super::{InputFormat, Locator, PlyEncoding, Scene};
use splat2tiles_core::splat::{self, Splats, sh_rest_count};

/// Records decoded per parallel task.
const CHUNK: usize = 8192;

/// Where one needed value sits in a vertex record: byte offset (binary) or value index (ascii).
#[derive(Debug, Clone, Copy)]
struct Field {
    off: usize,
    ty: Scalar,
}

/// The vertex record layout: the fixed fields and the higher SH in output order.
#[derive(Debug)]
struct Layout {
    /// x y z, f_dc_0..2, opacity, scale_0..2, rot_0..3.
    fixed: [Field; 14],
    /// f_rest fields reordered to glTF order: coefficient j, channel c -> file index c*n + j.
    rest: Vec<Field>,
    degree: u8,
    /// Record size in bytes (binary).
    stride: usize,
}

impl Layout {
    fn all_f32(&self) -> bool {
        self.fixed
            .iter()
            .chain(&self.rest)
            .all(|f| f.ty == Scalar::F32)
    }
}

const FIXED_NAMES: [&str; 14] = [
    "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
    "rot_0", "rot_1", "rot_2", "rot_3",
];

/// Builds the layout of the vertex element; `ascii` makes offsets value indices.
fn layout(cx: &Ctx, el: &Element, ascii: bool) -> Result<Layout, ReadError> {
    let mut offsets = Vec::with_capacity(el.props.len());
    let mut off = 0usize;
    for (i, p) in el.props.iter().enumerate() {
        let PropKind::Scalar(s) = p.kind else {
            return Err(cx.at(
                p.at,
                ReadErrorKind::Unsupported(format!(
                    "list property '{}' in the vertex element",
                    p.name
                )),
            ));
        };
        offsets.push(Field {
            off: if ascii { i } else { off },
            ty: s,
        });
        off += s.size();
    }
    let find = |name: &str| el.props.iter().position(|p| p.name == name);
    let missing: Vec<String> = FIXED_NAMES
        .iter()
        .filter(|n| find(n).is_none())
        .map(|n| n.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(cx.at(el.at, ReadErrorKind::MissingProperty(missing)));
    }
    let fixed = FIXED_NAMES.map(|n| offsets[find(n).expect("checked above")]);
    let n_rest = el
        .props
        .iter()
        .filter(|p| p.name.strip_prefix("f_rest_").is_some())
        .count();
    let degree = match n_rest {
        0 => 0,
        9 => 1,
        24 => 2,
        45 => 3,
        k => return Err(cx.at(el.at, ReadErrorKind::BadShCount(k))),
    };
    let mut file_rest = Vec::with_capacity(n_rest);
    for k in 0..n_rest {
        let name = format!("f_rest_{k}");
        let i = find(&name).ok_or_else(|| {
            cx.at(
                el.at,
                ReadErrorKind::MissingProperty(vec![format!(
                    "{name} (f_rest_* must be numbered 0..{})",
                    n_rest - 1
                )]),
            )
        })?;
        file_rest.push(offsets[i]);
    }
    let per = sh_rest_count(degree);
    debug_assert_eq!(per * 3, n_rest);
    let mut rest = Vec::with_capacity(n_rest);
    for j in 0..per {
        for c in 0..3 {
            rest.push(file_rest[c * per + j]);
        }
    }
    Ok(Layout {
        fixed,
        rest,
        degree,
        stride: off,
    })
}

/// A source of values for one vertex.
trait Src {
    fn f32(&self, f: Field) -> f32;
    fn f64(&self, f: Field) -> f64;
}

/// A little-endian record whose needed fields are all f32.
struct LeF32<'a>(&'a [u8]);

impl Src for LeF32<'_> {
    #[inline(always)]
    fn f32(&self, f: Field) -> f32 {
        let b = &self.0[f.off..f.off + 4];
        f32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }
    #[inline(always)]
    fn f64(&self, f: Field) -> f64 {
        self.f32(f) as f64
    }
}

/// Any binary record.
struct AnyBin<'a> {
    rec: &'a [u8],
    be: bool,
}

impl Src for AnyBin<'_> {
    #[inline(always)]
    fn f32(&self, f: Field) -> f32 {
        self.f64(f) as f32
    }
    #[inline(always)]
    fn f64(&self, f: Field) -> f64 {
        f.ty.read(&self.rec[f.off..], self.be)
    }
}

/// Parsed ascii values of one line.
struct Vals<'a>(&'a [f64]);

impl Src for Vals<'_> {
    fn f32(&self, f: Field) -> f32 {
        self.0[f.off] as f32
    }
    fn f64(&self, f: Field) -> f64 {
        self.0[f.off]
    }
}

/// Output slots of one splat.
struct Out<'a> {
    pos: &'a mut [f64; 3],
    scale: &'a mut [f32; 3],
    rot: &'a mut [f32; 4],
    opacity: &'a mut f32,
    sh0: &'a mut [f32; 3],
    rest: &'a mut [f32],
}

/// What converting one vertex had to note.
#[derive(Debug, Clone, Copy, Default)]
struct Notes {
    /// Quaternions replaced by the identity.
    repaired: usize,
    /// Finite log-scales whose `exp` overflows f32.
    overflowed: usize,
}

impl std::ops::Add for Notes {
    type Output = Notes;
    fn add(self, o: Notes) -> Notes {
        Notes {
            repaired: self.repaired + o.repaired,
            overflowed: self.overflowed + o.overflowed,
        }
    }
}

/// Converts one vertex into the model's conventions; notes a quaternion replaced by the
/// identity and a finite log-scale that overflows.
#[inline(always)]
fn convert<S: Src>(s: &S, lay: &Layout, o: Out<'_>) -> Notes {
    let f = &lay.fixed;
    *o.pos = [s.f64(f[0]), s.f64(f[1]), s.f64(f[2])];
    *o.sh0 = [s.f32(f[3]), s.f32(f[4]), s.f32(f[5])];
    *o.opacity = splat::sigmoid(s.f32(f[6]));
    let log_scale = [s.f32(f[7]), s.f32(f[8]), s.f32(f[9])];
    *o.scale = log_scale.map(f32::exp);
    let overflowed = log_scale
        .iter()
        .zip(o.scale.iter())
        .any(|(l, e)| l.is_finite() && !e.is_finite());
    let q = [s.f32(f[11]), s.f32(f[12]), s.f32(f[13]), s.f32(f[10])];
    let repaired = q.iter().any(|v| !v.is_finite()) || q.iter().all(|v| *v == 0.0);
    *o.rot = splat::normalize_quat(q);
    for (d, fld) in o.rest.iter_mut().zip(&lay.rest) {
        *d = s.f32(*fld);
    }
    Notes {
        repaired: repaired as usize,
        overflowed: overflowed as usize,
    }
}

/// Reads a PLY file (starting with `ply\n`).
pub(crate) fn read(cx: &Ctx, bytes: &[u8]) -> Result<Scene, ReadError> {
    let h = parse_header(cx, bytes)?;
    let Some(vi) = h.elements.iter().position(|e| e.name == "vertex") else {
        return Err(cx.header(h.end_at, "no 'vertex' element in the header"));
    };
    let ascii = h.encoding == PlyEncoding::Ascii;
    let lay = layout(cx, &h.elements[vi], ascii)?;
    let v = &h.elements[vi];
    let total = bytes.len() as u64;
    cx.check_memory(v.at, holdable(&h, v, total), lay.degree, total)?;
    let (splats, locator, notes) = if ascii {
        read_ascii(cx, bytes, &h, vi, &lay)?
    } else {
        read_binary(cx, bytes, &h, vi, &lay)?
    };
    Ok(Scene {
        splats,
        format: InputFormat::Ply {
            encoding: h.encoding,
        },
        locator,
        repaired_rotations: notes.repaired,
        overflowed_scales: notes.overflowed,
    })
}

/// Skips one element's binary data starting at `pos`; returns the new position.
fn skip_binary(
    cx: &Ctx,
    bytes: &[u8],
    pos: usize,
    el: &Element,
    be: bool,
) -> Result<usize, ReadError> {
    let remaining = (bytes.len() - pos) as u64;
    if let Some(size) = el.fixed_size() {
        let need = el.count.checked_mul(size as u64);
        return match need {
            Some(need) if need <= remaining => Ok(pos + need as usize),
            _ => Err(cx.at(
                pos as u64,
                ReadErrorKind::Truncated {
                    what: format!("element '{}' ({} x {size} bytes)", el.name, el.count),
                    unit: "bytes",
                    expected: need.unwrap_or(u64::MAX),
                    actual: remaining,
                },
            )),
        };
    }
    // Lists: walk instance by instance; each consumes at least one byte, so the walk is bounded
    // by the file size.
    let mut p = pos;
    let short = |p: usize, i: u64| {
        cx.at(
            p as u64,
            ReadErrorKind::Truncated {
                what: format!(
                    "element '{}' instance {i} of {} runs past the end",
                    el.name, el.count
                ),
                unit: "bytes",
                expected: (p - pos) as u64 + 1,
                actual: remaining,
            },
        )
    };
    for i in 0..el.count {
        for prop in &el.props {
            match prop.kind {
                PropKind::Scalar(s) => {
                    p = p
                        .checked_add(s.size())
                        .filter(|e| *e <= bytes.len())
                        .ok_or_else(|| short(p, i))?;
                }
                PropKind::List(c, it) => {
                    let end = p
                        .checked_add(c.size())
                        .filter(|e| *e <= bytes.len())
                        .ok_or_else(|| short(p, i))?;
                    let n = c.read(&bytes[p..], be);
                    if n < 0.0 {
                        return Err(cx.header(
                            p as u64,
                            format!("negative list length {n} in '{}.{}'", el.name, prop.name),
                        ));
                    }
                    p = (n as usize)
                        .checked_mul(it.size())
                        .and_then(|b| end.checked_add(b))
                        .filter(|e| *e <= bytes.len())
                        .ok_or_else(|| short(p, i))?;
                }
            }
        }
    }
    Ok(p)
}

fn read_binary(
    cx: &Ctx,
    bytes: &[u8],
    h: &Header,
    vi: usize,
    lay: &Layout,
) -> Result<(Splats, Locator, Notes), ReadError> {
    let be = h.encoding == PlyEncoding::BinaryBigEndian;
    let mut pos = h.body;
    for el in &h.elements[..vi] {
        pos = skip_binary(cx, bytes, pos, el, be)?;
    }
    let v = &h.elements[vi];
    let remaining = (bytes.len() - pos) as u64;
    let need = v.count.checked_mul(lay.stride as u64);
    let need = match need {
        Some(n) if n <= remaining => n as usize,
        _ => {
            return Err(cx.at(
                pos as u64,
                ReadErrorKind::Truncated {
                    what: format!("vertex data ({} vertices x {} bytes)", v.count, lay.stride),
                    unit: "bytes",
                    expected: need.unwrap_or(u64::MAX),
                    actual: remaining,
                },
            ));
        }
    };
    let n = v.count as usize;
    let start = pos;
    let body = &bytes[pos..pos + need];
    pos += need;
    for el in &h.elements[vi + 1..] {
        pos = skip_binary(cx, bytes, pos, el, be)?;
    }
    if pos != bytes.len() {
        return Err(cx.at(
            pos as u64,
            ReadErrorKind::TrailingData {
                extra: (bytes.len() - pos) as u64,
                unit: "bytes",
                what: format!("element ('{}')", h.elements.last().map_or("", |e| &e.name)),
            },
        ));
    }
    let (splats, repaired) = decode_binary(body, n, lay, be);
    let locator = Locator::Records {
        start: start as u64,
        stride: lay.stride as u64,
    };
    Ok((splats, locator, repaired))
}

/// Decodes `n` fixed-size vertex records in parallel chunks.
fn decode_binary(body: &[u8], n: usize, lay: &Layout, be: bool) -> (Splats, Notes) {
    let k = lay.rest.len();
    let mut s = Splats {
        positions: vec![[0.0; 3]; n],
        scales: vec![[0.0; 3]; n],
        rotations: vec![[0.0; 4]; n],
        opacities: vec![0.0; n],
        sh0: vec![[0.0; 3]; n],
        sh_degree: lay.degree,
        sh_rest: vec![[0.0; 3]; n * (k / 3)],
    };
    let fast = !be && lay.all_f32();
    let nchunks = n.div_ceil(CHUNK);
    // With no higher SH, zip against one empty slot per chunk so the zip keeps its length.
    let mut dummy = Vec::new();
    let (rest_buf, rest_chunk): (&mut [f32], usize) = if k == 0 {
        dummy.resize(nchunks, 0.0f32);
        (&mut dummy, 1)
    } else {
        (s.sh_rest.as_flattened_mut(), CHUNK * k)
    };
    let stride = lay.stride;
    let repaired = (
        s.positions.par_chunks_mut(CHUNK),
        s.scales.par_chunks_mut(CHUNK),
        s.rotations.par_chunks_mut(CHUNK),
        s.opacities.par_chunks_mut(CHUNK),
        s.sh0.par_chunks_mut(CHUNK),
        rest_buf.par_chunks_mut(rest_chunk),
        body.par_chunks(CHUNK * stride),
    )
        .into_par_iter()
        .map(|(p, sc, r, o, d, rest, recs)| {
            let mut notes = Notes::default();
            for i in 0..p.len() {
                let rec = &recs[i * stride..(i + 1) * stride];
                let out = Out {
                    pos: &mut p[i],
                    scale: &mut sc[i],
                    rot: &mut r[i],
                    opacity: &mut o[i],
                    sh0: &mut d[i],
                    rest: if k == 0 {
                        &mut []
                    } else {
                        &mut rest[i * k..(i + 1) * k]
                    },
                };
                notes = notes
                    + if fast {
                        convert(&LeF32(rec), lay, out)
                    } else {
                        convert(&AnyBin { rec, be }, lay, out)
                    };
            }
            notes
        })
        .reduce(Notes::default, |a, b| a + b);
    (s, repaired)
}

/// A binary PLY whose vertex records can be decoded in chunks straight from the file (the
/// out-of-core converter's reader): every element is fixed-size and the sizes add up exactly.
#[derive(Debug)]
pub(crate) struct BinaryPlan {
    lay: Layout,
    be: bool,
    /// Body encoding.
    pub(crate) encoding: PlyEncoding,
    /// Byte offset of the first vertex record.
    pub(crate) start: u64,
    /// Vertex records.
    pub(crate) count: u64,
    /// Record size in bytes.
    pub(crate) stride: usize,
}

/// The chunked-read plan of a binary PLY of `total` bytes whose header lies in `head`; `None`
/// when the file is ascii, has list elements, or its sizes do not add up (the whole-file reader
/// then reads it or names what is wrong).
pub(crate) fn binary_plan(
    cx: &Ctx,
    head: &[u8],
    total: u64,
) -> Result<Option<BinaryPlan>, ReadError> {
    let h = parse_header(cx, head)?;
    if h.encoding == PlyEncoding::Ascii {
        return Ok(None);
    }
    let Some(vi) = h.elements.iter().position(|e| e.name == "vertex") else {
        return Ok(None);
    };
    let lay = layout(cx, &h.elements[vi], false)?;
    let size_of = |el: &Element| -> Option<u64> { el.count.checked_mul(el.fixed_size()? as u64) };
    let mut start = h.body as u64;
    for el in &h.elements[..vi] {
        let Some(s) = size_of(el).and_then(|s| s.checked_add(start)) else {
            return Ok(None);
        };
        start = s;
    }
    let mut end = h.elements[vi]
        .count
        .checked_mul(lay.stride as u64)
        .and_then(|s| s.checked_add(start));
    for el in &h.elements[vi + 1..] {
        end = end.and_then(|e| e.checked_add(size_of(el)?));
    }
    if end != Some(total) {
        return Ok(None);
    }
    Ok(Some(BinaryPlan {
        be: h.encoding == PlyEncoding::BinaryBigEndian,
        encoding: h.encoding,
        start,
        count: h.elements[vi].count,
        stride: lay.stride,
        lay,
    }))
}

impl BinaryPlan {
    /// SH degree of the records.
    pub(crate) fn degree(&self) -> u8 {
        self.lay.degree
    }
}

/// Appends to `out` the centres of the vertex records that start every `step` bytes of `recs`
/// (`step` at least the stride): the positions [`decode_chunk`] gives, other fields undecoded.
pub(crate) fn decode_positions(
    plan: &BinaryPlan,
    recs: &[u8],
    step: usize,
    out: &mut Vec<[f64; 3]>,
) {
    let f = &plan.lay.fixed;
    let fast = !plan.be && f[..3].iter().all(|f| f.ty == Scalar::F32);
    out.par_extend(
        recs.par_chunks_exact(step.max(plan.stride))
            .with_min_len(4096)
            .map(|rec| {
                if fast {
                    let s = LeF32(rec);
                    [s.f64(f[0]), s.f64(f[1]), s.f64(f[2])]
                } else {
                    let s = AnyBin { rec, be: plan.be };
                    [s.f64(f[0]), s.f64(f[1]), s.f64(f[2])]
                }
            }),
    );
}

/// Decodes whole vertex records `recs` (a multiple of the plan's stride) into splats; returns
/// them with the counts of repaired quaternions and overflowed scales.
pub(crate) fn decode_chunk(plan: &BinaryPlan, recs: &[u8]) -> (Splats, usize, usize) {
    let n = recs.len() / plan.stride;
    let (s, notes) = decode_binary(&recs[..n * plan.stride], n, &plan.lay, plan.be);
    (s, notes.repaired, notes.overflowed)
}

/// Iterates over body lines with their 1-based numbers, skipping blank ones.
struct Lines<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: u64,
}

impl<'a> Lines<'a> {
    fn next_line(&mut self) -> Option<(u64, &'a [u8])> {
        while self.pos < self.bytes.len() {
            let rest = &self.bytes[self.pos..];
            let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
            let raw = &rest[..len];
            self.pos += (len + 1).min(rest.len());
            self.line += 1;
            if raw.iter().any(|b| !b.is_ascii_whitespace()) {
                return Some((self.line, raw));
            }
        }
        None
    }
}

fn read_ascii(
    cx: &Ctx,
    bytes: &[u8],
    h: &Header,
    vi: usize,
    lay: &Layout,
) -> Result<(Splats, Locator, Notes), ReadError> {
    let mut lines = Lines {
        bytes,
        pos: h.body,
        line: h.lines,
    };
    let eof = |lines: &Lines, el: &Element, found: u64| {
        cx.line(
            lines.line + 1,
            ReadErrorKind::Truncated {
                what: format!("element '{}' ends early", el.name),
                unit: "lines",
                expected: el.count,
                actual: found,
            },
        )
    };
    for el in &h.elements[..vi] {
        for i in 0..el.count {
            lines.next_line().ok_or_else(|| eof(&lines, el, i))?;
        }
    }
    let v = &h.elements[vi];
    let nprops = v.props.len();
    // A vertex line holds at least one character per value plus a separator each.
    let min_line = (2 * nprops).max(1) as u64;
    let remaining = (bytes.len() - lines.pos) as u64;
    let cap = v.count.min(remaining / min_line + 1) as usize;
    let mut s = Splats::with_capacity(lay.degree, cap);
    let mut line_of = Vec::with_capacity(cap);
    let mut vals = vec![0.0f64; nprops];
    let k = lay.rest.len();
    let mut rest = vec![0.0f32; k];
    let mut repaired = Notes::default();
    for i in 0..v.count {
        let (ln, raw) = lines.next_line().ok_or_else(|| eof(&lines, v, i))?;
        let text = std::str::from_utf8(raw)
            .map_err(|_| cx.line(ln, ReadErrorKind::BadRecord("line is not text".into())))?;
        let mut n = 0usize;
        for tok in text.split_ascii_whitespace() {
            if n < nprops {
                // A float property holds what an f32 holds: parse it as one (no double rounding).
                let parsed = match v.props[n].kind {
                    PropKind::Scalar(Scalar::F32) => tok.parse::<f32>().map(f64::from),
                    _ => tok.parse::<f64>(),
                };
                vals[n] = parsed.map_err(|_| {
                    cx.line(
                        ln,
                        ReadErrorKind::BadRecord(format!(
                            "property '{}': cannot parse '{tok}' as a number",
                            v.props[n].name
                        )),
                    )
                })?;
            }
            n += 1;
        }
        if n != nprops {
            return Err(cx.line(
                ln,
                ReadErrorKind::BadRecord(format!(
                    "expected {nprops} values for a vertex, found {n}"
                )),
            ));
        }
        let mut one = splat::Splat {
            position: [0.0; 3],
            scale: [0.0; 3],
            rotation: [0.0; 4],
            opacity: 0.0,
            sh0: [0.0; 3],
        };
        let out = Out {
            pos: &mut one.position,
            scale: &mut one.scale,
            rot: &mut one.rotation,
            opacity: &mut one.opacity,
            sh0: &mut one.sh0,
            rest: &mut rest,
        };
        repaired = repaired + convert(&Vals(&vals), lay, out);
        s.push(one, rest.as_chunks::<3>().0);
        line_of.push(ln);
    }
    for el in &h.elements[vi + 1..] {
        for i in 0..el.count {
            lines.next_line().ok_or_else(|| eof(&lines, el, i))?;
        }
    }
    if let Some((ln, _)) = lines.next_line() {
        let mut extra = 1;
        while lines.next_line().is_some() {
            extra += 1;
        }
        return Err(cx.line(
            ln,
            ReadErrorKind::TrailingData {
                extra,
                unit: "lines",
                what: format!("element ('{}')", h.elements.last().map_or("", |e| &e.name)),
            },
        ));
    }
    Ok((s, Locator::Lines(line_of), repaired))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::read_bytes;

    fn header(fmt: &str, extra: &str) -> String {
        let mut h = format!("ply\nformat {fmt} 1.0\ncomment hi\n{extra}element vertex 1\n");
        for n in FIXED_NAMES {
            h += &format!("property float {n}\n");
        }
        h += "end_header\n";
        h
    }

    #[test]
    fn scalar_types_read_both_endians() {
        let b = [0xff, 0xfe, 0, 0, 0, 0, 0, 0];
        assert_eq!(Scalar::I8.read(&b, false), -1.0);
        assert_eq!(Scalar::U8.read(&b, false), 255.0);
        assert_eq!(Scalar::I16.read(&b, false), -257.0);
        assert_eq!(Scalar::I16.read(&b, true), -2.0);
        assert_eq!(Scalar::U16.read(&b, true), 65534.0);
        assert_eq!(Scalar::parse("float64"), Some(Scalar::F64));
        assert_eq!(Scalar::parse("long"), None);
    }

    #[test]
    fn skips_elements_with_lists_before_vertex() {
        // A 'face' element with a list before the vertices must be walked, not assumed fixed.
        let mut b = header(
            "binary_little_endian",
            "element face 2\nproperty list uchar int vertex_indices\n",
        )
        .into_bytes();
        b.extend([1u8, 0, 0, 0, 0, 2, 1, 0, 0, 0, 2, 0, 0, 0]);
        let vals: [f32; 14] = [
            1.0, 2.0, 3.0, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0,
        ];
        for v in vals {
            b.extend(v.to_le_bytes());
        }
        let s = read_bytes("f.ply", &b).expect("reads");
        assert_eq!(s.splats.positions, vec![[1.0, 2.0, 3.0]]);
        assert_eq!(s.splats.opacities, vec![0.5]);
        assert_eq!(s.splats.rotations, vec![[0.0, 0.0, 0.0, 1.0]]);
        assert_eq!(s.locator.describe(0), format!("byte {}", b.len() - 56));
        // One byte short in the list walk.
        let e = read_bytes("f.ply", &b[..b.len() - 1]).unwrap_err();
        assert!(matches!(e.kind(), ReadErrorKind::Truncated { .. }), "{e}");
    }

    #[test]
    fn header_errors_name_the_line_offset() {
        let b = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float128 x\nend_header\n";
        let e = read_bytes("h.ply", b).unwrap_err();
        assert!(matches!(e.kind(), ReadErrorKind::BadHeader(_)));
        assert!(
            e.to_string()
                .starts_with("h.ply: byte 53: unknown property type"),
            "{e}"
        );
        let e = read_bytes("h.ply", b"ply\nformat ascii 1.0\nelement vertex 1\n").unwrap_err();
        assert!(e.to_string().contains("no 'end_header'"), "{e}");
    }

    #[test]
    fn ascii_with_other_elements_and_crlf() {
        let mut t = header("ascii", "element camera 1\nproperty float fx\n").replace('\n', "\r\n");
        t += "500\r\n1 2 3 0 0 0 0 0 0 0 1 0 0 0\r\n\r\n";
        let s = read_bytes("a.ply", t.as_bytes()).expect("reads");
        assert_eq!(s.splats.len(), 1);
        // 21 header lines, the camera on line 22.
        assert_eq!(s.locator.describe(0), "line 23");
    }
}
