//! The PLY header: scalar and list property types, elements, and the parser (bounded to
//! [`MAX_HEADER_BYTES`], linear in the number of properties), plus the declared-size check.

use super::PlyEncoding;
use super::error::{Ctx, ReadError};

/// Longest header we accept (trainer headers are about 1.5 kB).
pub(crate) const MAX_HEADER_BYTES: usize = 1 << 20;

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    pub(super) fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// Reads one value from the start of `b` (at least `size()` bytes).
    #[inline(always)]
    pub(super) fn read(self, b: &[u8], be: bool) -> f64 {
        macro_rules! num {
            ($t:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                (if be {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }) as f64
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => num!(i16, 2),
            Scalar::U16 => num!(u16, 2),
            Scalar::I32 => num!(i32, 4),
            Scalar::U32 => num!(u32, 4),
            Scalar::F32 => num!(f32, 4),
            Scalar::F64 => num!(f64, 8),
        }
    }
}

/// A property: a scalar, or a list (count type, item type).
#[derive(Debug, Clone)]
pub(super) enum PropKind {
    Scalar(Scalar),
    List(Scalar, Scalar),
}

#[derive(Debug, Clone)]
pub(super) struct Property {
    pub(super) name: String,
    pub(super) kind: PropKind,
    /// Byte offset of its header line.
    pub(super) at: u64,
}

#[derive(Debug, Clone)]
pub(super) struct Element {
    pub(super) name: String,
    pub(super) count: u64,
    pub(super) props: Vec<Property>,
    /// Byte offset of its header line.
    pub(super) at: u64,
}

impl Element {
    /// Record size when every property is a scalar.
    pub(super) fn fixed_size(&self) -> Option<usize> {
        self.props.iter().try_fold(0usize, |acc, p| match p.kind {
            PropKind::Scalar(s) => acc.checked_add(s.size()),
            PropKind::List(..) => None,
        })
    }
}

#[derive(Debug)]
pub(super) struct Header {
    pub(super) encoding: PlyEncoding,
    pub(super) elements: Vec<Element>,
    /// Offset of the first body byte.
    pub(super) body: usize,
    /// Offset of the `end_header` line.
    pub(super) end_at: u64,
    /// Number of header lines (the body starts on line `lines + 1`).
    pub(super) lines: u64,
}

pub(super) fn parse_header(cx: &Ctx, bytes: &[u8]) -> Result<Header, ReadError> {
    let limit = bytes.len().min(MAX_HEADER_BYTES);
    let mut pos = 0usize;
    let mut line_no = 0u64;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    // Property names of the current element (a set: headers with tens of thousands of
    // properties must not take quadratic time).
    let mut names: std::collections::HashSet<String> = std::collections::HashSet::new();
    loop {
        let at = pos as u64;
        let Some(nl) = bytes[pos..limit].iter().position(|&b| b == b'\n') else {
            return Err(cx.header(
                at,
                format!("no 'end_header' line within the first {limit} bytes"),
            ));
        };
        let raw = &bytes[pos..pos + nl];
        pos += nl + 1;
        line_no += 1;
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        let line =
            std::str::from_utf8(raw).map_err(|_| cx.header(at, "header line is not text"))?;
        let mut tok = line.split_ascii_whitespace();
        let Some(key) = tok.next() else { continue };
        let rest: Vec<&str> = tok.collect();
        match key {
            "ply" if line_no == 1 => {}
            "comment" | "obj_info" => {}
            "format" => {
                if encoding.is_some() {
                    return Err(cx.header(at, "second 'format' line"));
                }
                let enc = match rest.first().copied() {
                    Some("ascii") => PlyEncoding::Ascii,
                    Some("binary_little_endian") => PlyEncoding::BinaryLittleEndian,
                    Some("binary_big_endian") => PlyEncoding::BinaryBigEndian,
                    other => {
                        return Err(
                            cx.header(at, format!("unknown PLY format {:?}", other.unwrap_or("")))
                        );
                    }
                };
                if rest.get(1).copied() != Some("1.0") || rest.len() != 2 {
                    return Err(cx.header(at, format!("unsupported format line '{line}'")));
                }
                encoding = Some(enc);
            }
            "element" => {
                let [name, count] = rest[..] else {
                    return Err(cx.header(at, format!("malformed element line '{line}'")));
                };
                let count: u64 = count
                    .parse()
                    .map_err(|_| cx.header(at, format!("bad element count '{count}'")))?;
                if elements.iter().any(|e| e.name == name) {
                    return Err(cx.header(at, format!("second element named '{name}'")));
                }
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                    at,
                });
                names.clear();
            }
            "property" => {
                let Some(el) = elements.last_mut() else {
                    return Err(cx.header(at, "property before any element"));
                };
                let bad_type = |t: &str| cx.header(at, format!("unknown property type '{t}'"));
                let (kind, name) = match rest[..] {
                    ["list", ct, it, name] => {
                        let c = Scalar::parse(ct).ok_or_else(|| bad_type(ct))?;
                        let i = Scalar::parse(it).ok_or_else(|| bad_type(it))?;
                        if matches!(c, Scalar::F32 | Scalar::F64) {
                            return Err(
                                cx.header(at, format!("list count type '{ct}' is not an integer"))
                            );
                        }
                        (PropKind::List(c, i), name)
                    }
                    [ty, name] if ty != "list" => (
                        PropKind::Scalar(Scalar::parse(ty).ok_or_else(|| bad_type(ty))?),
                        name,
                    ),
                    _ => return Err(cx.header(at, format!("malformed property line '{line}'"))),
                };
                if !names.insert(name.to_string()) {
                    return Err(cx.header(
                        at,
                        format!("duplicate property '{name}' in element '{}'", el.name),
                    ));
                }
                el.props.push(Property {
                    name: name.to_string(),
                    kind,
                    at,
                });
            }
            "end_header" => {
                let Some(encoding) = encoding else {
                    return Err(cx.header(at, "no 'format' line before 'end_header'"));
                };
                return Ok(Header {
                    encoding,
                    elements,
                    body: pos,
                    end_at: at,
                    lines: line_no,
                });
            }
            other => return Err(cx.header(at, format!("unknown header keyword '{other}'"))),
        }
    }
}

/// Checks the vertex count the header in `head` (the file's first bytes) declares against the
/// memory limit, for a file of `total` bytes, before the body is read.
pub(crate) fn check_declared(cx: &Ctx, head: &[u8], total: u64) -> Result<(), ReadError> {
    let h = parse_header(cx, head)?;
    let Some(v) = h.elements.iter().find(|e| e.name == "vertex") else {
        return Err(cx.header(h.end_at, "no 'vertex' element in the header"));
    };
    let rest = v
        .props
        .iter()
        .filter(|p| p.name.starts_with("f_rest_"))
        .count();
    let degree = match rest {
        45.. => 3,
        24.. => 2,
        9.. => 1,
        _ => 0,
    };
    cx.check_memory(v.at, holdable(&h, v, total), degree, total)
}

/// The vertex count that matters for memory: the declared one, or fewer when a file of `total`
/// bytes cannot hold that many records (the reader then reports the truncation).
pub(super) fn holdable(h: &Header, v: &Element, total: u64) -> u64 {
    let per = if h.encoding == PlyEncoding::Ascii {
        2 * v.props.len() as u64
    } else {
        v.fixed_size().unwrap_or(1) as u64
    };
    v.count.min(total / per.max(1))
}
