//! Binary `.subtree` files of 3D Tiles 1.1 implicit tiling: availability bitstreams (LSB first,
//! Morton order), tile and content metadata property tables, 8-byte aligned; writer and reader.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// `"subt"` read as a little-endian u32.
pub const SUBTREE_MAGIC: u32 = 0x7462_7573;

/// Availability of tiles, contents or child subtrees: a bitstream or a constant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "camelCase")]
pub struct Availability {
    /// Index of the bufferView holding the bitstream.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bitstream: Option<u32>,
    /// 0 (none available) or 1 (all available).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub constant: Option<u8>,
    /// Number of set bits.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub available_count: Option<u64>,
}

/// A buffer of the subtree (buffer 0 without `uri` is the binary chunk).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Buffer {
    /// External file, absent for the internal chunk.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uri: Option<String>,
    /// Length in bytes.
    pub byte_length: u64,
    /// Optional name.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

/// A slice of a buffer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct BufferView {
    /// Buffer index.
    pub buffer: u32,
    /// Offset in the buffer (a multiple of 8).
    pub byte_offset: u64,
    /// Length in bytes.
    pub byte_length: u64,
    /// Optional name.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

/// One property column of a property table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct PropertyTableProperty {
    /// bufferView holding the values.
    pub values: u32,
}

/// A property table: one row per available tile (or content), in increasing tile index.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct PropertyTable {
    /// Class in the tileset schema.
    pub class: String,
    /// Number of rows.
    pub count: u64,
    /// Columns by property name.
    pub properties: BTreeMap<String, PropertyTableProperty>,
}

/// The JSON chunk of a subtree.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "camelCase")]
pub struct SubtreeJson {
    /// Buffers.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub buffers: Vec<Buffer>,
    /// Buffer views.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub buffer_views: Vec<BufferView>,
    /// Property tables for tile and content metadata.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub property_tables: Vec<PropertyTable>,
    /// Which tiles exist.
    pub tile_availability: Availability,
    /// Which tiles have content, one per content layer.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub content_availability: Vec<Availability>,
    /// Which child subtrees exist.
    pub child_subtree_availability: Availability,
    /// Property table of tile metadata.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tile_metadata: Option<u32>,
    /// Property tables of content metadata, one per content layer.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub content_metadata: Option<Vec<u32>>,
}

/// A column of metadata values (one entry per row; arrays flattened).
#[derive(Debug, Clone, PartialEq)]
pub enum Column {
    /// FLOAT64 values.
    F64(Vec<f64>),
    /// UINT32 values.
    U32(Vec<u32>),
    /// FLOAT32 values.
    F32(Vec<f32>),
    /// UINT64 values.
    U64(Vec<u64>),
}

impl Column {
    fn bytes(&self) -> Vec<u8> {
        match self {
            Column::F64(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Column::U32(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Column::F32(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Column::U64(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
        }
    }
}

/// Metadata rows for one property table.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// Class name in the schema.
    pub class: String,
    /// Number of rows.
    pub count: u64,
    /// Columns by property name.
    pub columns: Vec<(String, Column)>,
}

/// Everything one subtree file says, as plain data.
#[derive(Debug, Clone, PartialEq)]
pub struct SubtreeData {
    /// Tile availability, `(N^L - 1)/(N - 1)` bits.
    pub tiles: Vec<bool>,
    /// Content availability (one content layer), same length as `tiles`.
    pub contents: Vec<bool>,
    /// Child subtree availability, `N^L` bits.
    pub child_subtrees: Vec<bool>,
    /// Tile metadata rows (available tiles in increasing index), if any.
    pub tile_metadata: Option<Table>,
    /// Content metadata rows (available contents in increasing index), if any.
    pub content_metadata: Option<Table>,
}

/// Number of tiles in a subtree of `levels` levels with `arity` children per tile.
pub fn tile_count(arity: u64, levels: u32) -> u64 {
    (arity.pow(levels) - 1) / (arity - 1)
}

/// Index of a tile inside its subtree: level offset plus Morton index (level relative).
pub fn tile_index(arity: u64, level: u32, morton: u64) -> u64 {
    tile_count(arity, level) + morton
}

fn pack_bits(bits: &[bool]) -> Vec<u8> {
    let mut out = vec![0u8; bits.len().div_ceil(8)];
    for (i, &b) in bits.iter().enumerate() {
        if b {
            out[i >> 3] |= 1 << (i & 7);
        }
    }
    out
}

/// Reads bit `i` of an LSB-first bitstream.
pub fn bit(bytes: &[u8], i: usize) -> bool {
    (bytes[i >> 3] >> (i & 7)) & 1 == 1
}

struct BinBuilder {
    bin: Vec<u8>,
    views: Vec<BufferView>,
}

impl BinBuilder {
    fn add(&mut self, bytes: &[u8]) -> u32 {
        let offset = self.bin.len() as u64;
        self.bin.extend_from_slice(bytes);
        while !self.bin.len().is_multiple_of(8) {
            self.bin.push(0);
        }
        self.views.push(BufferView {
            buffer: 0,
            byte_offset: offset,
            byte_length: bytes.len() as u64,
            name: None,
        });
        (self.views.len() - 1) as u32
    }

    fn availability(&mut self, bits: &[bool]) -> Availability {
        let count = bits.iter().filter(|b| **b).count() as u64;
        if count == 0 || count == bits.len() as u64 {
            Availability {
                bitstream: None,
                constant: Some(u8::from(count > 0)),
                available_count: Some(count),
            }
        } else {
            Availability {
                bitstream: Some(self.add(&pack_bits(bits))),
                constant: None,
                available_count: Some(count),
            }
        }
    }

    fn table(&mut self, t: &Table) -> PropertyTable {
        let properties = t
            .columns
            .iter()
            .map(|(name, col)| {
                let values = self.add(&col.bytes());
                (name.clone(), PropertyTableProperty { values })
            })
            .collect();
        PropertyTable {
            class: t.class.clone(),
            count: t.count,
            properties,
        }
    }
}

/// Encodes a subtree as a binary `.subtree` file.
pub fn write_subtree(data: &SubtreeData) -> Vec<u8> {
    let mut b = BinBuilder {
        bin: Vec::new(),
        views: Vec::new(),
    };
    let tile_availability = b.availability(&data.tiles);
    let content_availability = vec![b.availability(&data.contents)];
    let child_subtree_availability = b.availability(&data.child_subtrees);
    let mut property_tables = Vec::new();
    let mut tile_metadata = None;
    let mut content_metadata = None;
    if let Some(t) = &data.tile_metadata {
        property_tables.push(b.table(t));
        tile_metadata = Some((property_tables.len() - 1) as u32);
    }
    if let Some(t) = &data.content_metadata {
        property_tables.push(b.table(t));
        content_metadata = Some(vec![(property_tables.len() - 1) as u32]);
    }
    let json = SubtreeJson {
        buffers: if b.bin.is_empty() {
            vec![]
        } else {
            vec![Buffer {
                uri: None,
                byte_length: b.bin.len() as u64,
                name: None,
            }]
        },
        buffer_views: b.views,
        property_tables,
        tile_availability,
        content_availability,
        child_subtree_availability,
        tile_metadata,
        content_metadata,
    };
    let mut json_bytes = serde_json::to_vec(&json).expect("subtree JSON serialises");
    while !json_bytes.len().is_multiple_of(8) {
        json_bytes.push(b' ');
    }
    let mut out = Vec::with_capacity(24 + json_bytes.len() + b.bin.len());
    out.extend_from_slice(&SUBTREE_MAGIC.to_le_bytes());
    out.extend_from_slice(&1u32.to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u64).to_le_bytes());
    out.extend_from_slice(&(b.bin.len() as u64).to_le_bytes());
    out.extend_from_slice(&json_bytes);
    out.extend_from_slice(&b.bin);
    out
}

/// Why a subtree file could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SubtreeError {
    /// The file is shorter than its header or its declared chunks.
    #[error("byte {offset}: {what}")]
    Framing {
        /// Byte offset of the problem.
        offset: u64,
        /// What is wrong.
        what: String,
    },
    /// The JSON chunk does not parse as subtree JSON.
    #[error("byte 24: subtree JSON: {0}")]
    Json(String),
}

/// A parsed subtree file: its JSON and its binary chunk.
#[derive(Debug, Clone, PartialEq)]
pub struct Subtree {
    /// The JSON chunk.
    pub json: SubtreeJson,
    /// The binary chunk (may be empty).
    pub bin: Vec<u8>,
    /// Declared JSON chunk length.
    pub json_byte_length: u64,
}

impl Subtree {
    /// The bytes of bufferView `i` of the internal buffer, if in range.
    pub fn view(&self, i: u32) -> Option<&[u8]> {
        let v = self.json.buffer_views.get(i as usize)?;
        if v.buffer != 0 {
            return None;
        }
        let start = usize::try_from(v.byte_offset).ok()?;
        let end = start.checked_add(usize::try_from(v.byte_length).ok()?)?;
        self.bin.get(start..end)
    }

    /// Expands an availability to `len` booleans; `None` if its bitstream is missing or short.
    pub fn bits(&self, a: &Availability, len: usize) -> Option<Vec<bool>> {
        match (a.bitstream, a.constant) {
            (Some(v), _) => {
                let bytes = self.view(v)?;
                if bytes.len() < len.div_ceil(8) {
                    return None;
                }
                Some((0..len).map(|i| bit(bytes, i)).collect())
            }
            (None, Some(c)) => Some(vec![c == 1; len]),
            (None, None) => None,
        }
    }
}

/// Parses a binary `.subtree` file, checking the header and chunk framing (not the semantics:
/// that is the validator's job).
pub fn read_subtree(bytes: &[u8]) -> Result<Subtree, SubtreeError> {
    let framing = |offset: u64, what: String| SubtreeError::Framing { offset, what };
    if bytes.len() < 24 {
        return Err(framing(
            0,
            format!("{} bytes is shorter than the 24-byte header", bytes.len()),
        ));
    }
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
    let u64_at = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().expect("8 bytes"));
    if u32_at(0) != SUBTREE_MAGIC {
        return Err(framing(
            0,
            format!("magic {:#010x} is not \"subt\"", u32_at(0)),
        ));
    }
    if u32_at(4) != 1 {
        return Err(framing(4, format!("version {} is not 1", u32_at(4))));
    }
    let json_len = u64_at(8);
    let bin_len = u64_at(16);
    let total = 24u64
        .checked_add(json_len)
        .and_then(|t| t.checked_add(bin_len));
    if total.is_none_or(|t| t > bytes.len() as u64) {
        return Err(framing(
            8,
            format!(
                "declared JSON ({json_len}) and binary ({bin_len}) lengths run past the end of the {}-byte file",
                bytes.len()
            ),
        ));
    }
    let json_end = 24 + json_len as usize;
    let json: SubtreeJson = serde_json::from_slice(&bytes[24..json_end])
        .map_err(|e| SubtreeError::Json(e.to_string()))?;
    let bin = bytes[json_end..json_end + bin_len as usize].to_vec();
    Ok(Subtree {
        json,
        bin,
        json_byte_length: json_len,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_indices() {
        assert_eq!(tile_count(4, 1), 1);
        assert_eq!(tile_count(4, 3), 21);
        assert_eq!(tile_count(8, 2), 9);
        assert_eq!(tile_index(8, 1, 7), 8);
        assert_eq!(tile_index(4, 2, 0), 5);
    }

    #[test]
    fn round_trip_with_bitstreams_constants_and_tables() {
        let n = tile_count(4, 2) as usize; // 5 tiles
        let tiles = vec![true, true, false, true, false];
        let contents = vec![false, true, false, true, false];
        let child_subtrees = vec![false; 16];
        let data = SubtreeData {
            tiles: tiles.clone(),
            contents: contents.clone(),
            child_subtrees,
            tile_metadata: Some(Table {
                class: "tile".into(),
                count: 3,
                columns: vec![("geometricError".into(), Column::F64(vec![4.0, 0.0, 0.0]))],
            }),
            content_metadata: Some(Table {
                class: "content".into(),
                count: 2,
                columns: vec![("splatCount".into(), Column::U32(vec![10, 20]))],
            }),
        };
        let bytes = write_subtree(&data);
        assert_eq!(bytes.len() % 8, 0);
        let s = read_subtree(&bytes).unwrap();
        assert_eq!(s.json_byte_length % 8, 0);
        for v in &s.json.buffer_views {
            assert_eq!(v.byte_offset % 8, 0);
        }
        assert_eq!(s.bits(&s.json.tile_availability, n).unwrap(), tiles);
        assert_eq!(
            s.bits(&s.json.content_availability[0], n).unwrap(),
            contents
        );
        assert_eq!(s.json.child_subtree_availability.constant, Some(0));
        assert_eq!(s.json.tile_availability.available_count, Some(3));
        let t = &s.json.property_tables[s.json.tile_metadata.unwrap() as usize];
        let col = s.view(t.properties["geometricError"].values).unwrap();
        assert_eq!(f64::from_le_bytes(col[0..8].try_into().unwrap()), 4.0);
        let c = &s.json.property_tables[s.json.content_metadata.as_ref().unwrap()[0] as usize];
        let col = s.view(c.properties["splatCount"].values).unwrap();
        assert_eq!(u32::from_le_bytes(col[4..8].try_into().unwrap()), 20);
    }

    #[test]
    fn bit_order_is_lsb_first() {
        let bits = [
            true, false, false, false, false, false, false, false, false, true,
        ];
        assert_eq!(pack_bits(&bits), vec![0x01, 0x02]);
    }

    #[test]
    fn framing_errors_never_panic() {
        assert!(matches!(
            read_subtree(&[]),
            Err(SubtreeError::Framing { offset: 0, .. })
        ));
        let mut good = write_subtree(&SubtreeData {
            tiles: vec![true],
            contents: vec![true],
            child_subtrees: vec![false; 8],
            tile_metadata: None,
            content_metadata: None,
        });
        let mut bad = good.clone();
        bad[0] = b'x';
        assert!(matches!(
            read_subtree(&bad),
            Err(SubtreeError::Framing { offset: 0, .. })
        ));
        let mut bad = good.clone();
        bad[4] = 2;
        assert!(matches!(
            read_subtree(&bad),
            Err(SubtreeError::Framing { offset: 4, .. })
        ));
        let mut bad = good.clone();
        bad[8..16].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(matches!(
            read_subtree(&bad),
            Err(SubtreeError::Framing { offset: 8, .. })
        ));
        good.truncate(30);
        assert!(read_subtree(&good).is_err());
    }
}
