//! The forward pass of `tools/tcn/train.py`'s `Net` (TCN encoder, 2-layer LSTM decoder, Gaussian
//! heads) in plain Rust, with the weights of its ONNX export; the same code natively and in wasm.
//!
//! Exactly the exported graph: input normalisation, causal dilated convolution blocks (weight norm
//! already folded by the export), the last step's features repeated into the LSTMs, the heads;
//! or, for `--arch lstm` (the LSTM-only baseline), a 2-layer LSTM encoder instead of the blocks.

use super::onnx::{Graph, Tensor};

/// Most residual blocks, channels and LSTM units accepted (bounds every allocation of a model).
const MAX_BLOCKS: usize = 16;
const MAX_WIDTH: usize = 1024;
const MAX_KERNEL: usize = 16;

/// One causal dilated convolution (`[out][in][k]` weights, bias).
#[derive(Debug, Clone)]
struct CausalConv {
    cin: usize,
    cout: usize,
    k: usize,
    dilation: usize,
    w: Vec<f32>,
    b: Vec<f32>,
}

impl CausalConv {
    /// `out[o][t] = b[o] + sum_i,j w[o][i][j] * x[i][t - (k-1-j) d]` (zero before the start):
    /// PyTorch's Conv1d padded by (k-1)d on both sides with the right side sliced off.
    fn apply(&self, x: &[f32], steps: usize, out: &mut Vec<f32>) {
        out.clear();
        out.resize(self.cout * steps, 0.0);
        for o in 0..self.cout {
            let row = &mut out[o * steps..(o + 1) * steps];
            row.fill(self.b[o]);
            for i in 0..self.cin {
                let xi = &x[i * steps..(i + 1) * steps];
                for j in 0..self.k {
                    let w = self.w[(o * self.cin + i) * self.k + j];
                    let shift = (self.k - 1 - j) * self.dilation;
                    if shift >= steps {
                        continue;
                    }
                    for (r, v) in row[shift..].iter_mut().zip(xi) {
                        *r += w * v;
                    }
                }
            }
        }
    }
}

/// A residual block: two convolutions with ReLU, a 1x1 convolution on the skip path where the
/// channel count changes, ReLU of the sum.
#[derive(Debug, Clone)]
struct Block {
    c1: CausalConv,
    c2: CausalConv,
    res: Option<CausalConv>,
}

/// One LSTM layer in ONNX's layout: gates (i, o, f, c) stacked, `w` `[4h][in]`, `r` `[4h][h]`,
/// `bias` the sum of ONNX's input and recurrent biases.
#[derive(Debug, Clone)]
struct Lstm {
    input: usize,
    hidden: usize,
    w: Vec<f32>,
    r: Vec<f32>,
    bias: Vec<f32>,
}

impl Lstm {
    /// Runs the layer over `steps` inputs (`x` `[steps][input]`, or one input repeated when
    /// `repeat`) from a zero state; returns the hidden states `[steps][hidden]`.
    fn run(&self, x: &[f32], steps: usize, repeat: bool) -> Vec<f32> {
        let h4 = 4 * self.hidden;
        let project = |xt: &[f32]| -> Vec<f32> {
            (0..h4)
                .map(|g| {
                    let w = &self.w[g * self.input..(g + 1) * self.input];
                    self.bias[g] + dot(w, xt)
                })
                .collect()
        };
        let fixed = repeat.then(|| project(&x[..self.input]));
        let mut h = vec![0.0f32; self.hidden];
        let mut c = vec![0.0f32; self.hidden];
        let mut out = Vec::with_capacity(steps * self.hidden);
        let mut gates = vec![0.0f32; h4];
        for t in 0..steps {
            match &fixed {
                Some(f) => gates.copy_from_slice(f),
                None => gates.copy_from_slice(&project(&x[t * self.input..(t + 1) * self.input])),
            }
            for (g, v) in gates.iter_mut().enumerate() {
                *v += dot(&self.r[g * self.hidden..(g + 1) * self.hidden], &h);
            }
            let n = self.hidden;
            for j in 0..n {
                let i = sigmoid(gates[j]);
                let o = sigmoid(gates[n + j]);
                let f = sigmoid(gates[2 * n + j]);
                let cand = gates[3 * n + j].tanh();
                c[j] = f * c[j] + i * cand;
                h[j] = o * c[j].tanh();
            }
            out.extend_from_slice(&h);
        }
        out
    }
}

/// A linear head on the decoder's states: `[hidden][out]` weights (ONNX MatMul layout), bias.
#[derive(Debug, Clone)]
struct Head {
    w: Vec<f32>,
    b: Vec<f32>,
}

impl Head {
    /// `b + h W` for one decoder state `h`.
    fn apply(&self, h: &[f32], outputs: usize) -> Vec<f32> {
        (0..outputs)
            .map(|j| {
                self.b[j]
                    + h.iter()
                        .enumerate()
                        .map(|(i, v)| v * self.w[i * outputs + j])
                        .sum::<f32>()
            })
            .collect()
    }
}

fn dot(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// The whole network with its weights.
#[derive(Debug, Clone)]
pub struct Net {
    inputs: usize,
    outputs: usize,
    xm: Vec<f32>,
    xs: Vec<f32>,
    ym: Vec<f32>,
    ys: Vec<f32>,
    blocks: Vec<Block>,
    /// The 2-layer LSTM encoder of `train.py --arch lstm` (the LSTM-only baseline), when there
    /// are no TCN blocks.
    enc_lstm: Option<[Lstm; 2]>,
    dec: [Lstm; 2],
    mu: Head,
    lv: Head,
}

/// `n` as a bounded width.
fn width(n: usize, what: &str, name: &str) -> Result<usize, String> {
    if n == 0 || n > MAX_WIDTH {
        return Err(format!("{name}: {what} {n}, expected 1..={MAX_WIDTH}"));
    }
    Ok(n)
}

impl Net {
    /// The network of `graph` (a `train.py --arch tcn` export) for `inputs` input and `outputs`
    /// output channels per step; `name` is used in errors.
    pub fn from_graph(
        graph: &Graph,
        inputs: usize,
        outputs: usize,
        name: &str,
    ) -> Result<Net, String> {
        let vec = |key: &str, n: usize| -> Result<Vec<f32>, String> {
            Ok(graph.tensor(key, &[n], name)?.data.clone())
        };
        let (xm, xs, ym, ys) = (
            vec("xm", inputs)?,
            vec("xs", inputs)?,
            vec("ym", outputs)?,
            vec("ys", outputs)?,
        );
        if xs.iter().chain(&ys).any(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(format!("{name}: a normalisation scale is not positive"));
        }
        let mut blocks = vec![];
        let mut cin = inputs;
        while graph
            .tensors
            .contains_key(&format!("enc.{}.c1.conv.weight", blocks.len()))
        {
            if blocks.len() == MAX_BLOCKS {
                return Err(format!("{name}: more than {MAX_BLOCKS} TCN blocks"));
            }
            let b = blocks.len();
            let c1 = conv(graph, &format!("enc.{b}.c1.conv"), cin, None, name)?;
            let c2 = conv(
                graph,
                &format!("enc.{b}.c2.conv"),
                c1.cout,
                Some(c1.cout),
                name,
            )?;
            let res = if graph.tensors.contains_key(&format!("enc.{b}.res.weight")) {
                Some(conv(
                    graph,
                    &format!("enc.{b}.res"),
                    cin,
                    Some(c1.cout),
                    name,
                )?)
            } else if cin != c1.cout {
                return Err(format!(
                    "{name}: block {b} changes channels without enc.{b}.res"
                ));
            } else {
                None
            };
            cin = c1.cout;
            blocks.push(Block { c1, c2, res });
        }
        let lstms: Vec<&super::onnx::Node> =
            graph.nodes.iter().filter(|n| n.op == "LSTM").collect();
        // TCN: the decoder's 2 LSTM nodes; LSTM-only: the encoder's 2, then the decoder's.
        let want = if blocks.is_empty() { 4 } else { 2 };
        if lstms.len() != want {
            return Err(format!(
                "{name}: {} TCN blocks and {} LSTM nodes; expected train.py's TCN (blocks and \
                 the 2-layer LSTM decoder) or its LSTM-only model (4 LSTM nodes)",
                blocks.len(),
                lstms.len()
            ));
        }
        let enc_lstm = if blocks.is_empty() {
            let e0 = lstm(graph, lstms[0], inputs, name)?;
            let e1 = lstm(graph, lstms[1], e0.hidden, name)?;
            cin = e1.hidden;
            Some([e0, e1])
        } else {
            None
        };
        let lstms = &lstms[want - 2..];
        let l0 = lstm(graph, lstms[0], cin, name)?;
        let l1 = lstm(graph, lstms[1], l0.hidden, name)?;
        let hidden = l1.hidden;
        let mu = head(graph, "mu.bias", hidden, outputs, name)?;
        let lv = head(graph, "lv.bias", hidden, outputs, name)?;
        Ok(Net {
            inputs,
            outputs,
            xm,
            xs,
            ym,
            ys,
            blocks,
            enc_lstm,
            dec: [l0, l1],
            mu,
            lv,
        })
    }

    /// Runs the network on `x` (`steps x inputs` row-major, raw features) for `future` output
    /// steps: means and log-variances, `future x outputs` row-major each.
    pub fn forward(&self, x: &[f32], steps: usize, future: usize) -> (Vec<f32>, Vec<f32>) {
        // Normalised, channel-major ([channel][time]) as the convolutions read it.
        let mut a = vec![0.0f32; self.inputs * steps];
        for t in 0..steps {
            for c in 0..self.inputs {
                a[c * steps + t] = (x[t * self.inputs + c] - self.xm[c]) / self.xs[c];
            }
        }
        let (mut h1, mut h2, mut skip) = (vec![], vec![], vec![]);
        for b in &self.blocks {
            b.c1.apply(&a, steps, &mut h1);
            h1.iter_mut().for_each(|v| *v = v.max(0.0));
            b.c2.apply(&h1, steps, &mut h2);
            let r = match &b.res {
                Some(res) => {
                    res.apply(&a, steps, &mut skip);
                    &skip
                }
                None => &a,
            };
            // relu(relu(c2) + skip)
            let sum: Vec<f32> = h2
                .iter()
                .zip(r)
                .map(|(h, s)| (h.max(0.0) + s).max(0.0))
                .collect();
            a = sum;
        }
        let ctx: Vec<f32> = match &self.enc_lstm {
            Some([e0, e1]) => {
                // Row-major ([time][channel]) as the LSTM reads it; the last step's state.
                let z: Vec<f32> = (0..steps * self.inputs)
                    .map(|k| a[(k % self.inputs) * steps + k / self.inputs])
                    .collect();
                let s = e1.run(&e0.run(&z, steps, false), steps, false);
                s[(steps - 1) * e1.hidden..].to_vec()
            }
            None => {
                let channels = self.blocks.last().map_or(self.inputs, |b| b.c2.cout);
                (0..channels).map(|c| a[c * steps + steps - 1]).collect()
            }
        };
        let s1 = self.dec[0].run(&ctx, future, true);
        let s2 = self.dec[1].run(&s1, future, false);
        let hidden = self.dec[1].hidden;
        let mut mean = Vec::with_capacity(future * self.outputs);
        let mut logvar = Vec::with_capacity(future * self.outputs);
        for t in 0..future {
            let h = &s2[t * hidden..(t + 1) * hidden];
            for (j, v) in self.mu.apply(h, self.outputs).into_iter().enumerate() {
                mean.push(v * self.ys[j] + self.ym[j]);
            }
            for (j, v) in self.lv.apply(h, self.outputs).into_iter().enumerate() {
                logvar.push(v + 2.0 * self.ys[j].ln());
            }
        }
        (mean, logvar)
    }
}

/// The convolution with weight `{key}.weight` `[out][cin][k]` and bias `{key}.bias`; its
/// dilation and padding from its Conv node (padding must be the causal (k-1)d).
fn conv(
    graph: &Graph,
    key: &str,
    cin: usize,
    cout: Option<usize>,
    name: &str,
) -> Result<CausalConv, String> {
    let wkey = format!("{key}.weight");
    let w: &Tensor = graph
        .tensors
        .get(&wkey)
        .ok_or_else(|| format!("{name}: no initializer '{wkey}'"))?;
    let [o, i, k] = w.dims[..] else {
        return Err(format!(
            "{name}: '{wkey}' has shape {:?}, expected [out, in, k]",
            w.dims
        ));
    };
    let cout = cout.unwrap_or(width(o, "conv channels", name)?);
    if o != cout || i != cin || k == 0 || k > MAX_KERNEL {
        return Err(format!(
            "{name}: '{wkey}' has shape {:?}, expected [{cout}, {cin}, 1..={MAX_KERNEL}]",
            w.dims
        ));
    }
    let b = graph.tensor(&format!("{key}.bias"), &[cout], name)?;
    let node = graph
        .node_with_input("Conv", 1, &wkey)
        .ok_or_else(|| format!("{name}: no Conv node reads '{wkey}'"))?;
    let attr = |a: &str, default: Vec<i64>| node.ints.get(a).cloned().unwrap_or(default);
    let dil = attr("dilations", vec![1]);
    let dilation = match dil[..] {
        [d] if (1..=1024).contains(&d) => d as usize,
        _ => return Err(format!("{name}: Conv of '{wkey}' has dilations {dil:?}")),
    };
    let pad = ((k - 1) * dilation) as i64;
    let pads = attr("pads", vec![0, 0]);
    let group = attr("group", vec![1]);
    let strides = attr("strides", vec![1]);
    if pads != [pad, pad] || group != [1] || strides != [1] {
        return Err(format!(
            "{name}: Conv of '{wkey}' has pads {pads:?}, group {group:?}, strides {strides:?}; \
             expected the causal [{pad}, {pad}], 1, 1"
        ));
    }
    Ok(CausalConv {
        cin,
        cout,
        k,
        dilation,
        w: w.data.clone(),
        b: b.data.clone(),
    })
}

/// An LSTM layer from its node: weights W `[1, 4h, input]`, R `[1, 4h, h]`, B `[1, 8h]`,
/// forward, default activations, zero initial state (as `nn.LSTM` without one).
fn lstm(graph: &Graph, node: &super::onnx::Node, input: usize, name: &str) -> Result<Lstm, String> {
    let hidden = match node.ints.get("hidden_size").map(|v| &v[..]) {
        Some(&[h]) if h > 0 => width(h as usize, "LSTM hidden size", name)?,
        _ => return Err(format!("{name}: an LSTM node without hidden_size")),
    };
    let dir = node
        .strings
        .get("direction")
        .map_or("forward", String::as_str);
    let custom = ["activations", "activation_alpha", "activation_beta", "clip"]
        .iter()
        .any(|a| node.ints.contains_key(*a));
    let zero = |a: &str| node.ints.get(a).is_none_or(|v| v[..] == [0]);
    let extra_inputs = node.inputs.get(4).is_some_and(|s| !s.is_empty()) || node.inputs.len() > 7;
    if dir != "forward" || custom || !zero("input_forget") || !zero("layout") || extra_inputs {
        return Err(format!(
            "{name}: an LSTM node other than train.py's (forward, default activations, no \
             sequence lengths or peepholes)"
        ));
    }
    let get = |slot: usize, dims: &[usize]| -> Result<Vec<f32>, String> {
        let key = node
            .inputs
            .get(slot)
            .ok_or_else(|| format!("{name}: an LSTM node without input {slot}"))?;
        Ok(graph.tensor(key, dims, name)?.data.clone())
    };
    let w = get(1, &[1, 4 * hidden, input])?;
    let r = get(2, &[1, 4 * hidden, hidden])?;
    let b2 = get(3, &[1, 8 * hidden])?;
    let bias = (0..4 * hidden)
        .map(|g| b2[g] + b2[4 * hidden + g])
        .collect();
    Ok(Lstm {
        input,
        hidden,
        w,
        r,
        bias,
    })
}

/// The head whose bias is `bias_key`: the MatMul feeding the Add that adds it.
fn head(
    graph: &Graph,
    bias_key: &str,
    hidden: usize,
    outputs: usize,
    name: &str,
) -> Result<Head, String> {
    let b = graph.tensor(bias_key, &[outputs], name)?.data.clone();
    let add = graph
        .node_with_input("Add", 0, bias_key)
        .or_else(|| graph.node_with_input("Add", 1, bias_key))
        .ok_or_else(|| format!("{name}: no Add node reads '{bias_key}'"))?;
    let matmul = graph
        .nodes
        .iter()
        .find(|n| n.op == "MatMul" && n.outputs.iter().any(|o| add.inputs.contains(o)))
        .ok_or_else(|| format!("{name}: no MatMul feeds the Add of '{bias_key}'"))?;
    let key = matmul
        .inputs
        .get(1)
        .ok_or_else(|| format!("{name}: a MatMul without weights"))?;
    let w = graph.tensor(key, &[hidden, outputs], name)?.data.clone();
    Ok(Head { w, b })
}
