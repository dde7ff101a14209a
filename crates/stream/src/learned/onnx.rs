//! The few parts of an ONNX file the trajectory model needs: its graph's nodes (operator, inputs,
//! integer attributes) and its float initializers, decoded with `prost` from hand-declared messages.
//!
//! Only the fields used are declared (prost skips the others); field numbers are `onnx.proto`'s.

use prost::Message;
use std::collections::HashMap;

/// ONNX `ModelProto` (only the graph).
#[derive(Clone, PartialEq, Message)]
struct ModelProto {
    #[prost(message, optional, tag = "7")]
    graph: Option<GraphProto>,
}

/// ONNX `GraphProto` (nodes and initializers).
#[derive(Clone, PartialEq, Message)]
struct GraphProto {
    #[prost(message, repeated, tag = "1")]
    node: Vec<NodeProto>,
    #[prost(message, repeated, tag = "5")]
    initializer: Vec<TensorProto>,
}

/// ONNX `NodeProto`.
#[derive(Clone, PartialEq, Message)]
struct NodeProto {
    #[prost(string, repeated, tag = "1")]
    input: Vec<String>,
    #[prost(string, repeated, tag = "2")]
    output: Vec<String>,
    #[prost(string, tag = "4")]
    op_type: String,
    #[prost(message, repeated, tag = "5")]
    attribute: Vec<AttributeProto>,
}

/// ONNX `AttributeProto` (name, integer, integers, string).
#[derive(Clone, PartialEq, Message)]
struct AttributeProto {
    #[prost(string, tag = "1")]
    name: String,
    #[prost(int64, tag = "3")]
    i: i64,
    #[prost(bytes = "vec", tag = "4")]
    s: Vec<u8>,
    #[prost(int64, repeated, tag = "8")]
    ints: Vec<i64>,
}

/// ONNX `TensorProto` (dims, type, float data either packed or raw little-endian).
#[derive(Clone, PartialEq, Message)]
struct TensorProto {
    #[prost(int64, repeated, tag = "1")]
    dims: Vec<i64>,
    #[prost(int32, tag = "2")]
    data_type: i32,
    #[prost(float, repeated, tag = "4")]
    float_data: Vec<f32>,
    #[prost(string, tag = "8")]
    name: String,
    #[prost(bytes = "vec", tag = "9")]
    raw_data: Vec<u8>,
}

/// ONNX's `TensorProto.DataType.FLOAT`.
const FLOAT: i32 = 1;

/// Most dimensions accepted on a tensor.
const MAX_DIMS: usize = 8;

/// A float tensor: its shape and values (row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct Tensor {
    /// Dimensions.
    pub dims: Vec<usize>,
    /// Values, `dims` row-major.
    pub data: Vec<f32>,
}

/// A graph node: operator, input and output names, integer and integer-list attributes.
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// ONNX operator (`Conv`, `LSTM`, ...).
    pub op: String,
    /// Input value names (an empty name: an omitted optional input).
    pub inputs: Vec<String>,
    /// Output value names.
    pub outputs: Vec<String>,
    /// Attributes by name: integers as a one-element list, integer lists as they are.
    pub ints: HashMap<String, Vec<i64>>,
    /// String attributes by name.
    pub strings: HashMap<String, String>,
}

/// The nodes (in graph order) and float initializers (by name) of an ONNX model.
#[derive(Debug, Clone, Default)]
pub struct Graph {
    /// Nodes in graph order.
    pub nodes: Vec<Node>,
    /// Float initializers by name.
    pub tensors: HashMap<String, Tensor>,
}

impl Graph {
    /// Decodes an ONNX model (`bytes` bounded by the caller); `name` is used in errors.
    pub fn decode(bytes: &[u8], name: &str) -> Result<Graph, String> {
        let model = ModelProto::decode(bytes)
            .map_err(|e| format!("{name}: not an ONNX model ({} bytes): {e}", bytes.len()))?;
        let graph = model
            .graph
            .ok_or_else(|| format!("{name}: an ONNX model without a graph"))?;
        let mut tensors = HashMap::new();
        for t in graph.initializer {
            let what = format!("{name}: initializer '{}'", t.name);
            let tensor = float_tensor(t.dims, t.data_type, t.float_data, &t.raw_data, &what)?;
            if tensors.insert(t.name.clone(), tensor).is_some() {
                return Err(format!("{what} appears twice"));
            }
        }
        let nodes = graph
            .node
            .into_iter()
            .map(|n| Node {
                ints: n
                    .attribute
                    .iter()
                    .map(|a| {
                        let v = if a.ints.is_empty() {
                            vec![a.i]
                        } else {
                            a.ints.clone()
                        };
                        (a.name.clone(), v)
                    })
                    .collect(),
                strings: n
                    .attribute
                    .iter()
                    .filter(|a| !a.s.is_empty())
                    .map(|a| (a.name.clone(), String::from_utf8_lossy(&a.s).into_owned()))
                    .collect(),
                op: n.op_type,
                inputs: n.input,
                outputs: n.output,
            })
            .collect();
        Ok(Graph { nodes, tensors })
    }

    /// The initializer `key`, which must have shape `dims`.
    pub fn tensor(&self, key: &str, dims: &[usize], name: &str) -> Result<&Tensor, String> {
        let t = self.tensors.get(key).ok_or_else(|| {
            format!("{name}: no initializer '{key}' (not the TCN of tools/tcn/train.py)")
        })?;
        if t.dims != dims {
            return Err(format!(
                "{name}: initializer '{key}' has shape {:?}, expected {dims:?}",
                t.dims
            ));
        }
        Ok(t)
    }

    /// The first node of operator `op` with `input` as its input number `slot`.
    pub fn node_with_input(&self, op: &str, slot: usize, input: &str) -> Option<&Node> {
        self.nodes
            .iter()
            .find(|n| n.op == op && n.inputs.get(slot).map(String::as_str) == Some(input))
    }
}

/// A float tensor from its proto fields, its element count checked against its dims.
fn float_tensor(
    dims: Vec<i64>,
    data_type: i32,
    float_data: Vec<f32>,
    raw: &[u8],
    what: &str,
) -> Result<Tensor, String> {
    if data_type != FLOAT {
        return Err(format!("{what}: data type {data_type}, expected float (1)"));
    }
    if dims.len() > MAX_DIMS {
        return Err(format!("{what}: {} dimensions", dims.len()));
    }
    let mut count = 1usize;
    let mut shape = Vec::with_capacity(dims.len());
    for &d in &dims {
        let d = usize::try_from(d).map_err(|_| format!("{what}: dimension {d}"))?;
        count = count
            .checked_mul(d)
            .ok_or_else(|| format!("{what}: dimensions {dims:?} overflow"))?;
        shape.push(d);
    }
    // Either field holds the values; both are already bounded by the decoded file's size.
    let data = if !raw.is_empty() {
        if raw.len() != count.saturating_mul(4) {
            return Err(format!(
                "{what}: {} bytes of data for shape {dims:?} ({count} floats)",
                raw.len()
            ));
        }
        raw.chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    } else {
        if float_data.len() != count {
            return Err(format!(
                "{what}: {} floats for shape {dims:?} ({count} expected)",
                float_data.len()
            ));
        }
        float_data
    };
    Ok(Tensor { dims: shape, data })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raw_and_packed_float_tensors_are_read_and_checked_against_their_dims() {
        let raw: Vec<u8> = [1.0f32, -2.5]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let t = float_tensor(vec![2, 1], FLOAT, vec![], &raw, "t").unwrap();
        assert_eq!(t.data, [1.0, -2.5]);
        assert_eq!(t.dims, [2, 1]);
        let t = float_tensor(vec![3], FLOAT, vec![1.0, 2.0, 3.0], &[], "t").unwrap();
        assert_eq!(t.data, [1.0, 2.0, 3.0]);
        assert!(float_tensor(vec![3], FLOAT, vec![], &raw, "t").is_err());
        assert!(float_tensor(vec![2], 7, vec![], &raw, "t").is_err());
        assert!(float_tensor(vec![-1], FLOAT, vec![], &raw, "t").is_err());
        assert!(float_tensor(vec![i64::MAX, i64::MAX], FLOAT, vec![], &raw, "t").is_err());
    }
}
